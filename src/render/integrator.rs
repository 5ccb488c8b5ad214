//! Path tracing with multiple scattering between fibers: next-event estimation to the
//! directional light (a delta light: no MIS), Russian roulette from the third vertex
//! ([`Integrator::roulette_from`]), per-lobe AOVs split at the first fiber vertex. The
//! environment is reached by BCSDF sampling alone unless [`Integrator::env_nee`] also
//! samples it at every vertex (uniform sphere, MIS with BCSDF sampling by the power
//! heuristic). That is off by default: on the test lock it costs a shadow ray and two pdf
//! evaluations per vertex, and those rays mostly cross the whole lock, while the BCSDF
//! sampler already follows the lobes that weigh the smooth environment. Measured
//! (`furfit render-convergence` without and with `--env-nee`, red fox, one after the other
//! on 2026-11-28; `reports/render_convergence.md` and `reports/env_nee/`): RMSE^2 x seconds
//! 9.0e-3 near / 6.3e-3 multi-scale without it, 1.25e-2 / 1.12e-2 with it.
//!
//! Pixel footprint (seed Eq. 27): each ray carries a cone, width `w0 + t * spread`.
//! Primary rays start with `w0 = 0` and `spread` = one pixel's angle, and the coverage is
//! `C_fiber = (w_camera . w_lookat) * width / r_fiber` (the seed replaces `w_fiber` by the
//! camera ray, as we do). After a fiber scattering the lobes are tens of degrees wide, so
//! secondary rays get `spread = secondary_spread` (1 rad by default) and in practice see the
//! far field. `footprint_scale` multiplies every coverage (0 = near field everywhere,
//! huge = far field everywhere) for tests and studies.

use super::bsdf::{
    lobe_sum, BsdfSample, CameraSide, FiberBsdf, Frame, HRange, LobeRgb, MisPrep, Mode, MIN_COS,
};
use super::bvh::{Bvh, DirTree};
use super::math::{luminance, Rgb, V3};
use super::qmc::{PixelSample, SOBOL_DEPTHS};
use super::scene::{Camera, DirectionalLight, Environment};
use crate::model::multiscale;
use rand::Rng;
use rand_xoshiro::Xoshiro256PlusPlus;
use std::f64::consts::PI;

/// What a path needs of a fiber's BCSDF (units and arguments: [`super::bsdf`]'s module
/// doc): the fur model's [`FiberBsdf`], or another model's near field through the model
/// interface ([`super::model_bsdf::ModelBsdf`]).
pub trait Bcsdf: Sync {
    /// What sampling and the MIS pdf share at one vertex, from `theta_o` alone.
    type Side: Copy;
    /// The MIS pdf's state at one vertex.
    type Mis: Copy;
    /// The per-vertex state of camera side `theta_o`, shared by sampling and the MIS pdf.
    fn camera_side(&self, theta_o: f64) -> Self::Side;
    /// Per-lobe values for camera-side `theta_o`, light side `(theta, phi)`, offsets `hr`.
    fn eval(&self, theta_o: f64, theta: f64, phi: f64, hr: HRange) -> LobeRgb;
    /// The MIS pdf's state at one vertex over the offsets `hr`.
    fn mis_prepare(&self, side: &Self::Side, hr: HRange) -> Self::Mis;
    /// The pdf MIS weighs a direction by (`(theta, phi)` measure).
    fn pdf_mis_prepared(&self, mp: &Self::Mis, theta: f64, phi: f64) -> f64;
    /// A light-side direction from four uniforms, its weight `value / pdf`.
    fn sample(&self, side: &Self::Side, hr: HRange, u: [f64; 4]) -> Option<BsdfSample>;
}

impl Bcsdf for FiberBsdf {
    type Side = CameraSide;
    type Mis = MisPrep;
    fn camera_side(&self, theta_o: f64) -> CameraSide {
        FiberBsdf::camera_side(self, theta_o)
    }
    fn eval(&self, theta_o: f64, theta: f64, phi: f64, hr: HRange) -> LobeRgb {
        FiberBsdf::eval(self, theta_o, theta, phi, hr)
    }
    fn mis_prepare(&self, side: &CameraSide, hr: HRange) -> MisPrep {
        FiberBsdf::mis_prepare(self, side, hr)
    }
    fn pdf_mis_prepared(&self, mp: &MisPrep, theta: f64, phi: f64) -> f64 {
        FiberBsdf::pdf_mis_prepared(self, mp, theta, phi)
    }
    fn sample(&self, side: &CameraSide, hr: HRange, u: [f64; 4]) -> Option<BsdfSample> {
        FiberBsdf::sample(self, side, hr, u)
    }
}

/// Everything a path needs, borrowed.
pub struct Integrator<'a, B: Bcsdf = FiberBsdf> {
    /// The fibers' acceleration structure.
    pub bvh: &'a Bvh,
    /// Shadow-ray tree along `light`'s direction ([`DirTree`]); `None` uses `bvh`.
    pub light_tree: Option<&'a DirTree>,
    /// The fibers' BCSDF.
    pub bsdf: &'a B,
    /// The camera primary rays start from.
    pub camera: &'a Camera,
    /// The key light, if any.
    pub light: Option<DirectionalLight>,
    /// The environment (sky) light.
    pub env: Environment,
    /// Which scale of the model the BCSDF queries use.
    pub mode: Mode,
    /// Fiber vertices a path may have at most.
    pub max_depth: usize,
    /// First vertex (0-based) after which a path may be ended by Russian roulette, with
    /// survival probability `min(max throughput, 0.95)` and the throughput divided by it
    /// (unbiased). 2 in renders; `>= max_depth` turns roulette off (tests compare both).
    pub roulette_from: usize,
    /// Multiplier of every footprint coverage (module doc): 0 near field everywhere, huge
    /// far field everywhere.
    pub footprint_scale: f64,
    /// Cone spread (radians) of rays after a fiber scattering (module doc; 1 by default).
    pub secondary_spread: f64,
    /// Also sample the environment at every vertex (next-event estimation with MIS).
    pub env_nee: bool,
}

/// Radiance of one camera path, split into beauty and per-lobe AOVs.
#[derive(Clone, Copy, Debug, Default)]
pub struct PathResult {
    /// Radiance of the whole path.
    pub beauty: Rgb,
    /// Radiance per lobe of the first fiber vertex, indexed by
    /// [`crate::model::Lobe::index`].
    pub lobes: [Rgb; 5],
    /// Rays traced (closest-hit and shadow).
    pub rays: u64,
}

fn power_heuristic(a: f64, b: f64) -> f64 {
    let (a2, b2) = (a * a, b * b);
    if a2 + b2 > 0.0 {
        a2 / (a2 + b2)
    } else {
        0.0
    }
}

/// The four uniforms of the BCSDF sample at vertex `depth`: from the pixel's streams
/// ([`super::qmc`]) at the first [`SOBOL_DEPTHS`] vertices, else from `rng`.
fn bsdf_uniforms(
    strata: Option<&PixelSample>,
    depth: usize,
    rng: &mut Xoshiro256PlusPlus,
) -> [f64; 4] {
    match strata {
        Some(q) if depth < SOBOL_DEPTHS => {
            let d = depth as u32;
            let ([a, b], [c, e]) = (q.pair(1 + 2 * d, rng), q.pair(2 + 2 * d, rng));
            [a, b, c, e]
        }
        _ => [rng.random(), rng.random(), rng.random(), rng.random()],
    }
}

/// Where the last BCSDF sample came from, to compute its MIS pdf on an env hit.
struct PrevSample<B: Bcsdf> {
    theta: f64,
    phi: f64,
    /// The vertex's MIS state, if its environment sample already prepared it.
    mis: Option<B::Mis>,
    side: B::Side,
    hr: HRange,
}

impl<B: Bcsdf> Integrator<'_, B> {
    fn hrange(&self, h: f64, width: f64, radius: f64, cos_look: f64) -> HRange {
        match self.mode {
            Mode::Near => HRange::At(h),
            Mode::Far => HRange::Span(-1.0, 1.0),
            Mode::Multiscale => {
                // The scale folded into the cosine keeps the product's rounding as before.
                let cos = self.footprint_scale * cos_look;
                HRange::footprint(h, multiscale::pixel_coverage(cos, width, radius))
            }
        }
    }

    /// Trace one path through image position (`px`, `py`). With `strata` the BCSDF samples
    /// of the first [`SOBOL_DEPTHS`] vertices take their uniforms from its streams
    /// ([`super::qmc`]), every other number from `rng`.
    pub fn trace(
        &self,
        px: f64,
        py: f64,
        rng: &mut Xoshiro256PlusPlus,
        strata: Option<&PixelSample>,
    ) -> PathResult {
        let mut res = PathResult::default();
        let cam = self.camera;
        let mut dir = cam.ray_dir(px, py);
        let cos_look = dir.dot(cam.forward);
        let mut origin = cam.eye;
        let mut thr: Rgb = [1.0; 3];
        let mut split: Option<[f64; 5]> = None;
        let mut prev: Option<PrevSample<B>> = None;
        let mut skip = None;
        let (mut w0, mut spread) = (0.0, cam.pixel_angle());
        let env_nee = self.env_nee && !self.env.is_black();
        let p_env = 1.0 / (4.0 * PI);

        for depth in 0..self.max_depth {
            res.rays += 1;
            let hit = match self.bvh.intersect(origin, dir, 0.0, f64::INFINITY, skip) {
                Some(h) => h,
                None => {
                    let le = self.env.radiance(dir);
                    let w = match &prev {
                        // Without environment NEE, BCSDF sampling is its only estimator.
                        Some(s) if env_nee => {
                            let cos = s.theta.cos().max(MIN_COS);
                            let mis = s
                                .mis
                                .unwrap_or_else(|| self.bsdf.mis_prepare(&s.side, s.hr));
                            let pb = self.bsdf.pdf_mis_prepared(&mis, s.theta, s.phi) / cos;
                            power_heuristic(pb, p_env)
                        }
                        _ => 1.0,
                    };
                    let c = [0, 1, 2].map(|i| thr[i] * le[i] * w);
                    self.add(&mut res, depth, split.as_ref(), c);
                    break;
                }
            };
            let wo = -dir;
            let frame = Frame::new(hit.u, wo);
            let theta_o = frame.to_local(wo).0;
            let side = self.bsdf.camera_side(theta_o);
            let width = w0 + hit.t * spread;
            let hr = self.hrange(
                hit.h,
                width,
                hit.radius,
                if depth == 0 { cos_look } else { 1.0 },
            );
            let skip_me = Some(hit.fiber);
            let mut mis: Option<B::Mis> = None;

            // Next-event estimation: directional light.
            if let Some(light) = &self.light {
                res.rays += 1;
                let blocked = match self.light_tree {
                    Some(t) => {
                        debug_assert!(t.dir() == light.dir);
                        self.bvh
                            .occluded_along(t, hit.p, 0.0, f64::INFINITY, skip_me)
                    }
                    None => self
                        .bvh
                        .occluded(hit.p, light.dir, 0.0, f64::INFINITY, skip_me),
                };
                if !blocked {
                    let (tl, pl) = frame.to_local(light.dir);
                    let mn = self.bsdf.eval(theta_o, tl, pl, hr);
                    let k = 1.0 / tl.cos().max(MIN_COS);
                    let e = [0, 1, 2].map(|c| light.irradiance[c] * thr[c] * k);
                    self.add_lobes(&mut res, depth, split.as_ref(), &mn, e);
                }
            }
            // Next-event estimation: environment, MIS with BCSDF sampling.
            if env_nee {
                let (u1, u2): (f64, f64) = (rng.random(), rng.random());
                let z = 1.0 - 2.0 * u1;
                let r = (1.0 - z * z).max(0.0).sqrt();
                let a = 2.0 * PI * u2;
                let ld = V3::new(r * a.cos(), z, r * a.sin());
                res.rays += 1;
                if !self.bvh.occluded(hit.p, ld, 0.0, f64::INFINITY, skip_me) {
                    let (tl, pl) = frame.to_local(ld);
                    let mn = self.bsdf.eval(theta_o, tl, pl, hr);
                    if lobe_sum(&mn).iter().any(|v| *v > 0.0) {
                        let cos = tl.cos().max(MIN_COS);
                        let mp = mis.get_or_insert_with(|| self.bsdf.mis_prepare(&side, hr));
                        let pb = self.bsdf.pdf_mis_prepared(mp, tl, pl) / cos;
                        let w = power_heuristic(p_env, pb);
                        let le = self.env.radiance(ld);
                        let e = [0, 1, 2].map(|c| le[c] * thr[c] * w / (cos * p_env));
                        self.add_lobes(&mut res, depth, split.as_ref(), &mn, e);
                    }
                }
            }

            // Continue the path by sampling the BCSDF.
            let u = bsdf_uniforms(strata, depth, rng);
            let s = match self.bsdf.sample(&side, hr, u) {
                Some(s) => s,
                None => break,
            };
            let wsum = lobe_sum(&s.weight);
            if depth == 0 {
                let tot = luminance(wsum);
                if tot > 0.0 {
                    split = Some([0, 1, 2, 3, 4].map(|l| luminance(s.weight[l]) / tot));
                }
            }
            for c in 0..3 {
                thr[c] *= wsum[c];
            }
            let m = thr[0].max(thr[1]).max(thr[2]);
            if m.is_nan() || m <= 0.0 || !m.is_finite() {
                break;
            }
            if depth >= self.roulette_from {
                let q = m.min(0.95);
                if rng.random::<f64>() >= q {
                    break;
                }
                for t in thr.iter_mut() {
                    *t /= q;
                }
            }
            dir = frame.to_world(s.theta, s.phi).normalized();
            origin = hit.p;
            skip = skip_me;
            prev = Some(PrevSample {
                theta: s.theta,
                phi: s.phi,
                mis,
                side,
                hr,
            });
            w0 = width;
            spread = self.secondary_spread;
        }
        res
    }

    /// Add a per-lobe contribution `mn[l] * scale`.
    fn add_lobes(
        &self,
        res: &mut PathResult,
        depth: usize,
        split: Option<&[f64; 5]>,
        mn: &LobeRgb,
        scale: Rgb,
    ) {
        let mut tot = [0.0; 3];
        for l in 0..5 {
            for c in 0..3 {
                let v = mn[l][c] * scale[c];
                tot[c] += v;
                if depth == 0 {
                    res.lobes[l][c] += v;
                }
            }
        }
        for c in 0..3 {
            res.beauty[c] += tot[c];
        }
        if depth > 0 {
            self.split_add(res, split, tot);
        }
    }

    /// Add radiance reaching the camera; `depth == 0` with no fiber is background.
    fn add(&self, res: &mut PathResult, depth: usize, split: Option<&[f64; 5]>, c: Rgb) {
        for i in 0..3 {
            res.beauty[i] += c[i];
        }
        if depth > 0 {
            self.split_add(res, split, c);
        }
    }

    fn split_add(&self, res: &mut PathResult, split: Option<&[f64; 5]>, c: Rgb) {
        if let Some(f) = split {
            for l in 0..5 {
                for i in 0..3 {
                    res.lobes[l][i] += f[l] * c[i];
                }
            }
        }
    }
}
