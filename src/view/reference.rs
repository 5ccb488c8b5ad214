//! The path-traced reference of the viewer's swatch: the very fibers the shells were cut
//! from ([`super::shells::grow`], copied by whole tiles around the tile), traced by the
//! renderer's integrator ([`crate::render::integrator::Integrator`], far-field BCSDF)
//! under the same light. The renderer is the fur model's (`yan2017`).
//!
//! Lights: the sky is `render`'s own gradient environment; the order-4 lobe, which the
//! renderer has no environment for, is sampled per path as a directional light drawn from
//! the lobe (`pdf ∝ ((1 + cos g) / 2)^4`: `cos g = 2 u^(1/5) - 1`) with the lobe's total
//! irradiance, an unbiased estimate of the same environment.
//!
//! `single` keeps single scattering only (what the PRT computes): one bounce of NEE for
//! the lobe, one BCSDF-sampled bounce to the sky.

use super::lights::{self, Kind, Light};
use super::sh;
use super::{shells, still, View, ViewData};
use crate::model::LobeSet;
use crate::params::FurParams;
use crate::render::bsdf::{FiberBsdf, Mode, Tint};
use crate::render::bvh::Bvh;
use crate::render::integrator::{Integrator, PathResult};
use crate::render::math::V3;
use crate::render::scene::{DirectionalLight, Environment};
use crate::render::Image;
use rand::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use rayon::prelude::*;
use std::sync::Arc;

/// How the reference is traced.
#[derive(Clone, Debug)]
pub struct RefSettings {
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
    /// Samples per pixel.
    pub spp: usize,
    /// Seed of the pixels' random streams.
    pub seed: u64,
    /// Single scattering only, what the PRT computes (module doc).
    pub single: bool,
    /// Shadow rays (and, to the sky, bounce rays) meet the fibers; off (with `single`):
    /// every fiber sees the whole light, to compare with the PRT's `--shadowing off`.
    pub shadows: bool,
    /// Fibers rooted this far around the tile are traced (tile units).
    pub margin: f64,
}

/// The traced geometry: shared by the references of one swatch.
pub fn geometry(data: &ViewData, margin: f64) -> Bvh {
    let fibers = shells::grow(&data.fur);
    Bvh::build(shells::segments(&data.fur, &fibers, margin))
}

/// Trace the reference of `params` (tinted by `tint`) under `light`.
pub fn render(
    bvh: &Bvh,
    data: &ViewData,
    params: &FurParams,
    tint: Tint,
    light: &Light,
    view: &View,
    s: &RefSettings,
) -> crate::Result<Image> {
    params.validate()?;
    let mut bsdf = FiberBsdf::new(params, tint, LobeSet::ALL);
    bsdf.far_table = Some(Arc::new(bsdf.tabulate_far()));
    bsdf.build_select_table();
    let cam = still::camera(data, view, s.width, s.height);
    let rot = lights::orientation(view.light_elev_deg, view.light_azim_deg);
    let (env, lobe) = match light.kind {
        Kind::Lobe(e) => (Environment::constant(0.0), Some(e)),
        Kind::Sky { top, bottom } => {
            if (view.light_elev_deg - 90.0).abs() > 1e-9 {
                return Err(crate::Error::Invalid(
                    "the reference traces the sky upright only (light elevation 90)".into(),
                ));
            }
            (Environment { top, bottom }, None)
        }
    };
    if !s.shadows {
        if !s.single {
            return Err(crate::Error::Invalid(
                "the unshadowed reference is single scattering only".into(),
            ));
        }
        return Ok(unshadowed(bvh, &bsdf, &cam, env, lobe, &rot, s));
    }
    let depth = match (s.single, lobe.is_some()) {
        (true, true) => 1,
        (true, false) => 2,
        (false, _) => 16,
    };
    let base = Integrator {
        bvh,
        light_tree: None,
        bsdf: &bsdf,
        camera: &cam,
        light: None,
        env,
        mode: Mode::Far,
        max_depth: depth,
        roulette_from: 2,
        footprint_scale: 1.0,
        secondary_spread: 1.0,
        env_nee: false,
    };
    Ok(per_pixel(s, |px, py, rng| {
        let mut integ = base_copy(&base);
        if let Some(e) = lobe {
            integ.light = Some(DirectionalLight {
                dir: lobe_dir(&rot, rng),
                irradiance: e,
            });
        }
        let (jx, jy): (f64, f64) = (rng.random(), rng.random());
        let res: PathResult = integ.trace(px + jx, py + jy, rng, None);
        res.beauty
    }))
}

/// The mean of `s.spp` samples `sample(px, py, rng)` per pixel, each pixel's generator
/// seeded from `s.seed` and its index (the same image on any thread count).
fn per_pixel(
    s: &RefSettings,
    sample: impl Fn(f64, f64, &mut Xoshiro256PlusPlus) -> [f64; 3] + Sync,
) -> Image {
    let rows: Vec<Vec<[f64; 3]>> = (0..s.height)
        .into_par_iter()
        .map(|py| {
            (0..s.width)
                .map(|px| {
                    let idx = (py * s.width + px) as u64;
                    let mut rng = Xoshiro256PlusPlus::seed_from_u64(
                        s.seed ^ idx.wrapping_mul(0x9E37_79B9_7F4A_7C15),
                    );
                    let mut acc = [0.0; 3];
                    for _ in 0..s.spp {
                        let v = sample(px as f64, py as f64, &mut rng);
                        (0..3).for_each(|c| acc[c] += v[c]);
                    }
                    acc.map(|v| v / s.spp as f64)
                })
                .collect()
        })
        .collect();
    Image {
        width: s.width,
        height: s.height,
        data: rows.into_iter().flatten().collect(),
    }
}

/// A direction of the lobe light (density `(1 + cos) ^ 4` about its axis, `rot` the
/// light's rotation), from two uniforms of `rng`.
fn lobe_dir(rot: &sh::Mat3, rng: &mut Xoshiro256PlusPlus) -> V3 {
    let (u1, u2): (f64, f64) = (rng.random(), rng.random());
    let c = 2.0 * u1.powf(0.2) - 1.0;
    let r = (1.0 - c * c).max(0.0).sqrt();
    let a = std::f64::consts::TAU * u2;
    let d = sh::mat_vec(rot, [r * a.cos(), c, r * a.sin()]);
    V3::new(d[0], d[1], d[2]).normalized()
}

/// Single scattering with nothing in the light's way: the first fiber on the camera ray
/// (`bvh`), lit by the whole lobe (directions drawn from it, as [`render`]) or the whole
/// sky (BCSDF-sampled directions, not traced): what the integrator's first vertex does
/// without its shadow and bounce rays.
fn unshadowed(
    bvh: &Bvh,
    bsdf: &FiberBsdf,
    cam: &crate::render::scene::Camera,
    env: Environment,
    lobe: Option<[f64; 3]>,
    rot: &sh::Mat3,
    s: &RefSettings,
) -> Image {
    use crate::render::bsdf::{lobe_sum, Frame, HRange, MIN_COS};
    per_pixel(s, |px, py, rng| {
        let (jx, jy): (f64, f64) = (rng.random(), rng.random());
        let dir = cam.ray_dir(px + jx, py + jy);
        let Some(hit) = bvh.intersect(cam.eye, dir, 0.0, f64::INFINITY, None) else {
            return env.radiance(dir);
        };
        let frame = Frame::new(hit.u, -dir);
        let theta_o = frame.to_local(-dir).0;
        let hr = HRange::Span(-1.0, 1.0);
        if let Some(e) = lobe {
            let (tl, pl) = frame.to_local(lobe_dir(rot, rng));
            let mn = lobe_sum(&bsdf.eval(theta_o, tl, pl, hr));
            let k = 1.0 / tl.cos().max(MIN_COS);
            return [0, 1, 2].map(|c| mn[c] * e[c] * k);
        }
        let side = bsdf.camera_side(theta_o);
        let u = [rng.random(), rng.random(), rng.random(), rng.random()];
        match bsdf.sample(&side, hr, u) {
            Some(smp) => {
                let w = lobe_sum(&smp.weight);
                let le = env.radiance(frame.to_world(smp.theta, smp.phi));
                [0, 1, 2].map(|c| w[c] * le[c])
            }
            None => [0.0; 3],
        }
    })
}

fn base_copy<'a>(b: &Integrator<'a>) -> Integrator<'a> {
    Integrator {
        bvh: b.bvh,
        light_tree: b.light_tree,
        bsdf: b.bsdf,
        camera: b.camera,
        light: b.light,
        env: b.env,
        mode: b.mode,
        max_depth: b.max_depth,
        roulette_from: b.roulette_from,
        footprint_scale: b.footprint_scale,
        secondary_spread: b.secondary_spread,
        env_nee: b.env_nee,
    }
}

/// Pixels whose camera ray meets the base plane inside `[-inset, 1 + inset]^2`: far
/// enough inside the traced fibers that light from the sides is as the shells assume.
pub fn mask(data: &ViewData, view: &View, width: usize, height: usize, inset: f64) -> Vec<bool> {
    let cam = still::camera(data, view, width, height);
    (0..width * height)
        .map(|i| {
            let d = cam.ray_dir((i % width) as f64 + 0.5, (i / width) as f64 + 0.5);
            if d.y >= 0.0 {
                return false;
            }
            let p = cam.eye + d * (-cam.eye.y / d.y);
            let inside = |v: f64| v >= -inset && v <= 1.0 + inset;
            inside(p.x) && inside(p.z)
        })
        .collect()
}

/// RMSE relative to the mean of `b` over masked pixels, after a `k x k` box filter of
/// both (blocks with any pixel outside the mask are left out).
pub fn relative_rmse(a: &Image, b: &Image, mask: &[bool], k: usize) -> f64 {
    let (w, h) = (a.width / k, a.height / k);
    let (mut se, mut sum, mut n) = (0.0, 0.0, 0usize);
    for by in 0..h {
        for bx in 0..w {
            let idx = |x: usize, y: usize| (by * k + y) * a.width + bx * k + x;
            if (0..k * k).any(|i| !mask[idx(i % k, i / k)]) {
                continue;
            }
            for c in 0..3 {
                let avg = |img: &Image| {
                    (0..k * k)
                        .map(|i| img.data[idx(i % k, i / k)][c])
                        .sum::<f64>()
                        / (k * k) as f64
                };
                let (va, vb) = (avg(a), avg(b));
                se += (va - vb).powi(2);
                sum += vb;
                n += 1;
            }
        }
    }
    if n == 0 {
        return f64::NAN;
    }
    (se / n as f64).sqrt() / (sum / n as f64)
}

/// Ratio of the mean of `a` to the mean of `b` over masked pixels (RGB summed): the
/// overall bias, free of the pixel-level differences of geometry and noise.
pub fn mean_ratio(a: &Image, b: &Image, mask: &[bool]) -> f64 {
    let (mut sa, mut sb) = (0.0, 0.0);
    for (i, m) in mask.iter().enumerate() {
        if *m {
            sa += a.data[i].iter().sum::<f64>();
            sb += b.data[i].iter().sum::<f64>();
        }
    }
    sa / sb
}
