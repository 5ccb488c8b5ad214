//! The fiber BCSDF as the renderer uses it: evaluation in RGB, importance sampling and the
//! exact pdf of that sampling. All physics comes from [`crate::model`]; this file only
//! arranges the model's terms (M_p, A_p, D_p) for light transport.
//!
//! # Frame and arguments
//! At a hit the fiber tangent `u` (root to tip) and the direction toward the camera `w_o`
//! define the local frame `(v, w, u)`, right-handed, `v` = `w_o` projected on the normal
//! plane, so `phi_o = 0`. A direction has `theta = asin(d . u)` (out of the normal plane)
//! and `phi = atan2(d . w, d . v)`, MODEL.md's conventions.
//!
//! The model describes light entering the fiber at offset `h` from direction `theta_i`.
//! A camera ray that hits the fiber at offset `h_o` (see [`super::bvh`]) follows the same
//! internal path as light entering there from the camera side (reciprocity of the ray
//! paths), so the renderer queries the azimuthal part with the **camera side as the
//! model's incident side**: `phi := phi_light - phi_o`, `h := h_o`, and `theta_d` (even in
//! the swap). The longitudinal part takes the light as incident, as a goniometer sample
//! does (MODEL.md): `M(theta_i := theta_light, theta_r := theta_o)`. For R, TT, TRT the
//! order does not matter (`M_p` depends on `theta_i + theta_r`), but the scattered lobes'
//! `M_s` (the `C^M` tables) is not reciprocal: read the other way round it differed from
//! the fitted lobe by 2-7x at oblique angles (red fox, light at 60 degrees, camera at 0:
//! 0.458 against 0.201), so a render would not show the scattered lobes that were fitted.
//!
//! # Units: the renderer's BCSDF
//! Seed Eq. 1 gives `L_o = ∫ L_i S cos(theta_i) dw_i` with `cos(theta_i)` the fiber's
//! projected width toward the light and, by seed Eq. 12, `S = sum_p M_p N_p / cos^2 theta_i`.
//! Hence per unit solid angle the integrand is
//! `f cos = sum_p M_p N_p / cos theta_i`, and in the `(theta, phi)` measure
//! (`dw = cos theta dtheta dphi`) it is just `sum_p M_p N_p`, the value a goniometer
//! measures (MODEL.md). Consequences used throughout:
//! * a directional light of irradiance `E` contributes `E * sum M N / cos theta_l`;
//! * a sampled direction has weight `f cos / pdf_w = sum M N / pdf_(theta,phi)` (the cosine
//!   cancels exactly);
//! * the albedo is `∫∫ sum M_p N_p dtheta dphi`, equal to `sum_p A_p` times the part of
//!   each `M_p` inside `[-90°, 90°]` when `A_p` does not vary with `theta_d` — the white
//!   furnace test checks `<= 1` and `≈ A_0 + A_1 + A_2` with `kappa = 0`. The scattered
//!   lobes break the bound: their `M_s` is normalised over the exit inclination, and read
//!   here over the light's it can hold up to about 2 ([`MedullaEnergy`]; `conserve` caps
//!   it at 1).
//!
//! `cos theta_light` is floored at [`MIN_COS`] (a light exactly along the fiber).
//!
//! # Sampling (seed Sec. 6)
//! 1. `h`: near field uses the hit's `h`; far field / multi-scale draw `h` uniformly in
//!    `[h1, h2]`.
//! 2. Lobe `l` with probability ∝ its energy, averaged over RGB: for R/TT/TRT
//!    `A_l(h) * (mass of M_l inside the domain)` at the camera side's specular `theta_d`
//!    (`theta_d = -theta_o`); for TTs/TRTs the column mass of `M_s` times the mean of
//!    `A^s_l(h) * C^N scattered fraction` at quantiles of that column (the path at `h` may
//!    miss the medulla at the specular `theta_d` and meet it at the ones `M_s` draws). The
//!    probabilities depend only on `(theta_o, h)`, so the mixture pdf below is exact. A
//!    render reads them (and the scattered lobes' frame of step 3) from a table bilinear
//!    in `(theta_o, h)` ([`super::select`]): sampler and pdf read the same values, so the
//!    pdf stays exact; only the efficiency of the lobe choice is approximated.
//! 3. Unscattered lobes: `theta` from `M_l` (a Gaussian) **truncated to [-90°, 90°]** by
//!    inverse-CDF sampling (pdf = Gaussian / in-domain mass; when that mass is < 1e-10 the
//!    lobe falls back to uniform `theta`, pdf `1/pi`); then `phi` from the wrapped Gaussian
//!    `D_l` about `Phi_l(h)` at the sampled `theta_d` (pdf = the model's `D_l` exactly).
//!    Scattered lobes sample the medulla tables: `psi` from `C^N(x, .)` and
//!    `phi = Phi^s_p + psi`, with `x` and `Phi^s_p` the energy-weighted mean over the
//!    quantile paths of step 2 (they depend on `theta_d` through `eta'`, which is not
//!    known before `theta` is drawn), then `theta` from `M_s(., theta_o, phi)` = the
//!    front/back blend of `C^M` (seed Eq. 19) read down a column (light side unknown,
//!    camera side given) — `MedullaSampler::sample_cn` / `sample_cm_incident`, whose pdfs
//!    are exact for the piecewise-linear table densities. One frame for all `theta_d`
//!    only costs efficiency away from it; the pdf is exact for what is drawn.
//! 4. pdf: the full mixture `sum_l P_l pdf_l(theta, phi | h)` in the `(theta, phi)` measure.
//!
//! For far field and multi-scale the marginal over `h` has no closed form. The renderer
//! therefore treats `h` as one more sampled dimension: the continuation weight is
//! `sum M N(h) / pdf(theta, phi | h)` (near field at the sampled `h` over its exact
//! conditional pdf). With `h` uniform on `[h1, h2]` the pair `(h, direction)` has density
//! `pdf(direction | h) / (h2 - h1)` and the far/multi-scale value is the `h`-average of the
//! near field (seed Eq. 26), so this weight is an unbiased estimate of the far/multi-scale
//! integrand over its sampling density.
//! MIS weights against environment sampling only need to sum to one per direction, so
//! they use [`FiberBsdf::pdf_mis`], a deterministic 4-point midpoint average of the
//! conditional pdf over `[h1, h2]`; the light and environment estimators evaluate the
//! analytic far/multi-scale BCSDF (the point of the far field: no noise from `h`), read
//! from the per-render table of [`super::ntable`] when one is set (`far_table`), else from
//! the model's engine per query.

use super::ishair::{self, CauchyTheta, Sampling};
use super::math::{Rgb, V3};
use super::ntable::FarTable;
use super::select::{SelectTable, Selection};
use crate::model::azimuthal::{self, medulla_offset, wrap_angle};
use crate::model::far::FarOptions;
use crate::model::geometry::PathGeometry;
use crate::model::{geometry, longitudinal, multiscale, FurModel, Lobe, LobeSet, LobeValues};
use crate::params::FurParams;
use std::f64::consts::{FRAC_PI_2, PI, SQRT_2};
use std::sync::Arc;

/// Floor for `cos theta` of a light direction.
pub const MIN_COS: f64 = 1e-3;

/// Truncated-Gaussian mass below which a lobe samples `theta` uniformly instead.
const MIN_MASS: f64 = 1e-10;

/// Which scale of the model a shading query uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// The near field at the hit's offset `h` (seed Sec. 4).
    Near,
    /// The far field, averaged over `h` (seed Sec. 5.1).
    Far,
    /// Near or far by the pixel footprint's coverage of the fiber: the offset range of seed
    /// Eq. 26, its width from Eq. 27 (seed Sec. 5.2).
    Multiscale,
}

impl Mode {
    /// Parse `near`, `far` or `multiscale` (`--mode`).
    pub fn parse(s: &str) -> crate::Result<Mode> {
        match s.to_ascii_lowercase().as_str() {
            "near" => Ok(Mode::Near),
            "far" => Ok(Mode::Far),
            "multiscale" | "multi-scale" | "ms" => Ok(Mode::Multiscale),
            _ => Err(crate::Error::Invalid(format!(
                "unknown mode '{s}' (expected near, far or multiscale)"
            ))),
        }
    }
    /// The `--mode` name, as [`Mode::parse`] reads it.
    pub fn name(self) -> &'static str {
        match self {
            Mode::Near => "near",
            Mode::Far => "far",
            Mode::Multiscale => "multiscale",
        }
    }
}

/// The azimuthal offsets one shading query covers.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum HRange {
    /// Near field at one offset.
    At(f64),
    /// Multi-scale over `[h1, h2]` (seed Eq. 26); `Span(-1, 1)` is the far field (Eq. 22).
    Span(f64, f64),
}

impl HRange {
    /// Multi-scale range for a hit at `h` with pixel coverage `c` (seed Eq. 27, in units of
    /// `h`): [`multiscale::offset_range`]; a width below 1e-6 is the near field.
    pub fn footprint(h: f64, c: f64) -> HRange {
        let (h1, h2) = multiscale::offset_range(h, c);
        if h2 - h1 < 1e-6 {
            HRange::At(h)
        } else {
            HRange::Span(h1, h2)
        }
    }
}

/// How the renderer reads the scattered lobes' longitudinal term `M_s` (seed Eq. 19's
/// `C^M` tables, normalised over the exit inclination for each incident one).
///
/// A path tracer gathers at a fixed camera side over the light's inclination, i.e. down a
/// column of `C^M`, and `C^M` is not reciprocal: a column's mass is not 1 (red fox preset:
/// 1.50 front and 1.81 back at `theta_o = 0`, 0.83 and 0.59 at 60 degrees). So a fiber with
/// a medulla returns more light than it receives under a uniform environment, and each
/// bounce between fibers gains again (`tests/render_scene.rs`: a lossless fiber in a white
/// furnace renders at 1.40).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MedullaEnergy {
    /// The default: the scattered lobes as fitted, scaled per camera-side inclination so
    /// the fiber's directional albedo equals the physical one ([`super::strand`]): a
    /// lossless fiber returns what it receives, the lobe shapes are the fitted ones.
    #[default]
    Strand,
    /// `M_s` exactly as fitted (the light incident, as a goniometer sample): the render
    /// shows the lobes the fit measured, and the gain above.
    Fit,
    /// `M_s` divided by its column's mass `∫ M_s(theta, theta_o, phi) dtheta` where that
    /// exceeds 1: no light is gained, at the price of dimmer scattered lobes than fitted
    /// (by that mass) where a column holds more than 1.
    Conserve,
}

impl MedullaEnergy {
    /// Parse `strand`, `fit` or `conserve` (`--medulla-energy`).
    pub fn parse(s: &str) -> crate::Result<MedullaEnergy> {
        match s.trim().to_ascii_lowercase().as_str() {
            "strand" => Ok(MedullaEnergy::Strand),
            "fit" => Ok(MedullaEnergy::Fit),
            "conserve" => Ok(MedullaEnergy::Conserve),
            other => Err(crate::Error::Invalid(format!(
                "unknown medulla energy '{other}' (expected strand, fit or conserve)"
            ))),
        }
    }

    /// The `--medulla-energy` name, as [`MedullaEnergy::parse`] reads it.
    pub fn name(self) -> &'static str {
        match self {
            MedullaEnergy::Strand => "strand",
            MedullaEnergy::Fit => "fit",
            MedullaEnergy::Conserve => "conserve",
        }
    }
}

/// Per-lobe, per-channel values (`[lobe][channel]`).
pub type LobeRgb = [[f64; 3]; 5];

/// Sum over the lobes, per channel: the value a path carries.
pub fn lobe_sum(v: &LobeRgb) -> Rgb {
    let mut s = [0.0; 3];
    for l in v {
        for c in 0..3 {
            s[c] += l[c];
        }
    }
    s
}

/// The colour of the fiber: per-channel absorption `sigma_c_a`, `sigma_m_a` (scattering,
/// geometry and roughness are shared by the channels).
///
/// The default is a eumelanin-like tint: the relative eumelanin absorption at R, G, B of
/// d'Eon et al. 2011 / Chiang et al. 2016 (`0.419 : 0.697 : 1.37`), normalised so the
/// green channel keeps the fitted value. A fit with r, g, b channels gives each channel
/// its own fitted absorption ([`Tint::Absorption`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Tint {
    /// Ratios r, g, b applied to both absorption coefficients of the parameters.
    Ratios([f64; 3]),
    /// Absorption per channel r, g, b, replacing the parameters' own.
    Absorption {
        /// Cortex absorption `sigma_c_a` per channel, per unit radius.
        sigma_c_a: [f64; 3],
        /// Medulla absorption `sigma_m_a` per channel, per unit radius.
        sigma_m_a: [f64; 3],
    },
}

impl std::fmt::Display for Tint {
    /// How the colour was made, for the images' provenance text.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Tint::Ratios(r) => write!(
                f,
                "absorption tinted by r:g:b ratios {:.3}:{:.3}:{:.3}",
                r[0], r[1], r[2]
            ),
            Tint::Absorption {
                sigma_c_a,
                sigma_m_a,
            } => write!(
                f,
                "per-channel absorption sigma_c_a r,g,b {:.4},{:.4},{:.4}, sigma_m_a {:.4},{:.4},{:.4}",
                sigma_c_a[0], sigma_c_a[1], sigma_c_a[2], sigma_m_a[0], sigma_m_a[1], sigma_m_a[2]
            ),
        }
    }
}

impl Default for Tint {
    fn default() -> Self {
        Tint::Ratios([0.419 / 0.697, 1.0, 1.37 / 0.697])
    }
}

impl Tint {
    /// No tint: every channel has the parameters' own absorption.
    pub const GREY: Tint = Tint::Ratios([1.0, 1.0, 1.0]);

    /// `params` with channel `c`'s absorption.
    pub fn apply(&self, params: &FurParams, c: usize) -> FurParams {
        let mut p = *params;
        match self {
            Tint::Ratios(r) => {
                p.sigma_c_a *= r[c];
                p.sigma_m_a *= r[c];
            }
            Tint::Absorption {
                sigma_c_a,
                sigma_m_a,
            } => {
                p.sigma_c_a = sigma_c_a[c];
                p.sigma_m_a = sigma_m_a[c];
            }
        }
        p
    }

    /// Bit patterns identifying the tint (a cache key).
    pub fn key(&self) -> [u64; 7] {
        let (tag, a, b) = match *self {
            Tint::Ratios(r) => (0, r, [0.0; 3]),
            Tint::Absorption {
                sigma_c_a,
                sigma_m_a,
            } => (1, sigma_c_a, sigma_m_a),
        };
        let mut k = [tag; 7];
        for i in 0..3 {
            k[1 + i] = a[i].to_bits();
            k[4 + i] = b[i].to_bits();
        }
        k
    }

    /// The colour of a fit's channels ([`crate::params::fit_channels`]) when they are
    /// named r, g, b (or red, green, blue; any case): each channel's fitted absorption.
    /// `None` for a fit without such channels.
    pub fn from_fit_channels(channels: &[crate::params::FitChannel]) -> Option<Tint> {
        let mut found: [Option<FurParams>; 3] = [None; 3];
        for ch in channels {
            let slot = match ch.name.to_ascii_lowercase().as_str() {
                "r" | "red" => 0,
                "g" | "green" => 1,
                "b" | "blue" => 2,
                _ => continue,
            };
            found[slot] = Some(ch.params);
        }
        let [Some(r), Some(g), Some(b)] = found else {
            return None;
        };
        Some(Tint::Absorption {
            sigma_c_a: [r.sigma_c_a, g.sigma_c_a, b.sigma_c_a],
            sigma_m_a: [r.sigma_m_a, g.sigma_m_a, b.sigma_m_a],
        })
    }
}

/// A sampled light-side direction.
#[derive(Clone, Copy, Debug)]
pub struct BsdfSample {
    /// Light-side inclination (radians, from the normal plane).
    pub theta: f64,
    /// Light-side azimuth relative to the camera side's (radians).
    pub phi: f64,
    /// The offset the sample was drawn at.
    pub h: f64,
    /// The lobe the sample was drawn from.
    pub lobe: Lobe,
    /// `sum M N` per lobe at the sampled `h` over the conditional pdf: the per-lobe parts
    /// of the sample weight `f cos / pdf_w`.
    pub weight: LobeRgb,
    /// Conditional pdf in the `(theta, phi)` measure.
    pub pdf: f64,
}

/// The truncated Gaussians `M_l` of the unscattered lobes for one `theta_o`: centre, width
/// and [`trunc_tails`] (zero for the other lobes).
#[derive(Clone, Copy, Debug)]
struct TruncM {
    mu: [f64; 5],
    s: [f64; 5],
    tails: [(f64, f64); 5],
}

impl TruncM {
    /// Mass of lobe `i`'s `M_l` inside [-pi/2, pi/2].
    #[inline]
    fn mass(&self, i: usize) -> f64 {
        let (qa, qb) = self.tails[i];
        qa - qb
    }
}

/// The camera side of a path vertex: what the sampler and its pdf need from `theta_o`
/// alone (the truncated `M_l`, [`FiberBsdf::camera_side`]). A vertex builds it once for its
/// BCSDF sample and its MIS pdf.
#[derive(Clone, Copy, Debug)]
pub struct CameraSide {
    theta_o: f64,
    m: TruncM,
    /// ISHair's truncated Cauchy in `theta` per unscattered lobe ([`super::ishair`]).
    cauchy: [CauchyTheta; 5],
}

/// Quantile nodes of `M_s` at which [`FiberBsdf::scattered_selection`] reads the scattered
/// lobes' energy.
const SCATTER_NODES: usize = 5;

/// Midpoints of the span averaged by [`FiberBsdf::pdf_mis`].
const MIS_POINTS: usize = 4;

/// [`FiberBsdf::pdf_mis`]'s camera-side state at one vertex ([`FiberBsdf::mis_prepare`]).
#[derive(Clone, Copy, Debug)]
pub struct MisPrep {
    side: CameraSide,
    /// Offsets in use: 1 (near field) or [`MIS_POINTS`] (span).
    n: usize,
    hs: [f64; MIS_POINTS],
    sels: [Selection; MIS_POINTS],
}

/// RGB fiber BCSDF of one parameter set.
#[derive(Clone, Debug)]
pub struct FiberBsdf {
    models: [FurModel; 3],
    lobes: LobeSet,
    /// How the scattered lobes' `M_s` is read ([`MedullaEnergy`]).
    pub medulla_energy: MedullaEnergy,
    /// Options of the far field / multi-scale integration (culling, tolerance).
    pub far_opts: FarOptions,
    /// Tabulated far field / multi-scale term ([`super::ntable`]); `None` evaluates the
    /// model's analytic engine per query (exact, ~1 ms each).
    pub far_table: Option<Arc<FarTable>>,
    /// Tabulated lobe selection of the sampler ([`super::select`]); `None` computes it
    /// exactly per query.
    pub select: Option<Arc<SelectTable>>,
    /// Scale of the scattered lobes per camera-side inclination and channel
    /// ([`MedullaEnergy::Strand`], [`super::strand`]); `None` leaves them as fitted.
    pub energy: Option<Arc<super::strand::EnergyScale>>,
    /// The sampler's proposal ([`Sampling`]); sample and pdf follow it alike.
    pub sampling: Sampling,
}

/// Upper-tail masses `(Q(-pi/2), Q(pi/2))` of the normal (`mu`, `s`) reflected so its
/// centre is <= 0 (which keeps the erfc tails precise); the mass inside [-pi/2, pi/2] is
/// their difference.
#[inline]
fn trunc_tails(mu: f64, s: f64) -> (f64, f64) {
    let m = -mu.abs();
    let z = |x: f64| (x - m) / (s * SQRT_2);
    let qa = 0.5 * puruspe::erfc(z(-FRAC_PI_2));
    let zb = z(FRAC_PI_2);
    // qb is only ever used in `qa - qb`. For zb > 6 it is below erfc(6) / 2 = 1.1e-17,
    // under half the spacing of doubles just below any qa >= 0.25 (>= 1.39e-17), so that
    // difference is exactly qa: skip the erfc (most lobes at most theta_o).
    let qb = if zb > 6.0 && qa >= 0.25 {
        0.0
    } else {
        0.5 * puruspe::erfc(zb)
    };
    (qa, qb)
}

/// Inverse-CDF sample of the normal (`mu`, `s`) truncated to [-pi/2, pi/2], from its
/// [`trunc_tails`] `(qa, qb)`.
fn trunc_sample(mu: f64, s: f64, (qa, qb): (f64, f64), u: f64) -> f64 {
    let sign = if mu > 0.0 { -1.0 } else { 1.0 };
    let m = -mu.abs();
    let qq = qa - u * (qa - qb);
    let x = m + s * SQRT_2 * puruspe::inverfc(2.0 * qq);
    sign * x.clamp(-FRAC_PI_2, FRAC_PI_2)
}

impl FiberBsdf {
    /// The BCSDF of `params` per channel under `tint`, restricted to `lobes` (medulla
    /// energy as fitted, no Strand scale).
    pub fn new(params: &FurParams, tint: Tint, lobes: LobeSet) -> FiberBsdf {
        let models = [0, 1, 2].map(|c| FurModel::new(&tint.apply(params, c)));
        let lobes = lobes.intersect(models[0].active_lobes());
        FiberBsdf {
            models,
            lobes,
            medulla_energy: MedullaEnergy::Fit,
            far_opts: FarOptions::default(),
            far_table: None,
            select: None,
            energy: None,
            // The sampler the BCSDF's own tests pin down; renders set theirs
            // (`RenderSettings::sampling`, ISHair by default).
            sampling: Sampling::Lobes,
        }
    }

    /// Tabulate the far field / multi-scale term for fast [`Self::eval_span`] (run inside
    /// the render's thread pool; uses the current `far_opts`). Set it as `far_table`.
    pub fn tabulate_far(&self) -> FarTable {
        FarTable::build(&self.models, self.lobes, &self.far_opts)
    }

    /// The lobes this BCSDF evaluates (requested ∩ active: scattered lobes are left out
    /// when `kappa = 0` or `sigma_m_s = 0`).
    pub fn lobes(&self) -> LobeSet {
        self.lobes
    }

    /// The fur model of channel `c` (0, 1, 2 for r, g, b), its absorption tinted.
    pub fn model(&self, c: usize) -> &FurModel {
        &self.models[c]
    }

    /// `M_p N_p` per lobe and channel for camera-side `theta_o` and light-side
    /// (`theta`, `phi`) (see module doc for the argument mapping).
    pub fn eval(&self, theta_o: f64, theta: f64, phi: f64, hr: HRange) -> LobeRgb {
        match hr {
            HRange::At(h) => self.eval_near(theta_o, theta, phi, h),
            HRange::Span(h1, h2) => self.eval_span(theta_o, theta, phi, h1, h2),
        }
    }

    /// Near field: the model's `M_p` and `D_p` once, `A_p` per channel.
    pub fn eval_near(&self, theta_o: f64, theta: f64, phi: f64, h: f64) -> LobeRgb {
        let at = self.near_point(theta_o, theta, phi, h);
        self.eval_near_at(&at, theta_o, theta, phi)
    }

    /// The path at (`theta_d`, `h`) and its unscattered `D_l` at `phi`.
    fn near_point(&self, theta_o: f64, theta: f64, phi: f64, h: f64) -> NearPoint {
        let td = geometry::theta_d(theta_o, theta);
        let geo = self.models[0].azimuthal(td).geometry(h);
        self.near_point_at(td, geo, phi)
    }

    /// [`Self::near_point`] with the path at `theta_d` already traced.
    fn near_point_at(&self, td: f64, geo: PathGeometry, phi: f64) -> NearPoint {
        let d = self.unscattered_d(&geo, phi);
        NearPoint { td, geo, d }
    }

    /// `D_l(h, phi)` of the unscattered lobes at one path (the wrapped Gaussian about
    /// `Phi_l(h)`, seed Eq. 7): the near-field value and the sampling pdf share it.
    fn unscattered_d(&self, geo: &PathGeometry, phi: f64) -> [f64; 5] {
        let beta_n = self.models[0].params.beta_n;
        let mut d = [0.0; 5];
        for l in self.lobes.iter().filter(|l| !l.is_scattered()) {
            d[l.index()] = azimuthal::d_p(l.p(), geo, phi, beta_n);
        }
        d
    }

    /// The azimuthal proposal densities of the unscattered lobes at one path: the model's
    /// `D_l` for [`Sampling::Lobes`], ISHair's Cauchy about `Phi_l(h)` of the same width.
    fn proposal_d(&self, geo: &PathGeometry, phi: f64) -> [f64; 5] {
        if self.sampling != Sampling::Ishair {
            return self.unscattered_d(geo, phi);
        }
        let beta_n = self.models[0].params.beta_n;
        let mut d = [0.0; 5];
        for l in self.lobes.iter().filter(|l| !l.is_scattered()) {
            let c = azimuthal::phi_p(l.p(), geo);
            d[l.index()] = ishair::pdf_phi(c, azimuthal::beta_p(l.p(), beta_n), phi);
        }
        d
    }

    /// [`Self::eval_near`] at a prepared [`NearPoint`].
    fn eval_near_at(&self, at: &NearPoint, theta_o: f64, theta: f64, phi: f64) -> LobeRgb {
        let m0 = &self.models[0];
        let m = self.longitudinal(theta_o, theta, phi);
        let s0 = m0.azimuthal(at.td);
        let geo = &at.geo;
        let mut out = [[0.0; 3]; 5];
        let mut md = [0.0; 5];
        for l in self.lobes.iter() {
            let ml = m.get(l);
            if ml != 0.0 {
                md[l.index()] = ml
                    * if l.is_scattered() {
                        s0.distribution(l, geo, phi)
                    } else {
                        at.d[l.index()]
                    };
            }
        }
        for (c, a) in self.attenuation_rgb(at.td, geo).iter().enumerate() {
            for l in self.lobes.iter() {
                out[l.index()][c] = a.get(l) * md[l.index()];
            }
        }
        self.scale_scattered(theta_o, &mut out);
        out
    }

    /// Apply the [`MedullaEnergy::Strand`] scale (when set) to the scattered lobes.
    #[inline]
    fn scale_scattered(&self, theta_o: f64, out: &mut LobeRgb) {
        if let Some(e) = self.energy.as_deref() {
            for c in 0..3 {
                let k = e.at(theta_o, c);
                out[Lobe::TTs.index()][c] *= k;
                out[Lobe::TRTs.index()][c] *= k;
            }
        }
    }

    /// Far field / multi-scale: `M_p` times the model's `N_p` averaged over `[h1, h2]`
    /// (seed Eqs. 22, 26; [`crate::model::AzimuthalSlice::far`] for `[-1, 1]`,
    /// [`crate::model::AzimuthalSlice::multiscale`] otherwise), per channel.
    pub fn eval_span(&self, theta_o: f64, theta: f64, phi: f64, h1: f64, h2: f64) -> LobeRgb {
        let m = self.longitudinal(theta_o, theta, phi);
        let td = geometry::theta_d(theta_o, theta);
        let full = h1 <= -1.0 && h2 >= 1.0;
        let mut out = [[0.0; 3]; 5];
        if let Some(t) = self.far_table.as_deref().filter(|t| t.serves(h1, h2)) {
            for (c, n) in t.eval_rgb(td, phi, h1, h2).iter().enumerate() {
                for l in self.lobes.iter() {
                    out[l.index()][c] = m.get(l) * n.get(l);
                }
            }
            self.scale_scattered(theta_o, &mut out);
            return out;
        }
        for c in 0..3 {
            let slice = self.models[c].azimuthal(td);
            let n = if full {
                slice.far(phi, self.lobes, &self.far_opts)
            } else {
                slice.multiscale(phi, h1, h2, self.lobes, &self.far_opts)
            };
            for l in self.lobes.iter() {
                out[l.index()][c] = m.get(l) * n.get(l);
            }
        }
        self.scale_scattered(theta_o, &mut out);
        out
    }

    /// `M_p` of the lobes for camera-side `theta_o` and light-side (`theta`, `phi`): the
    /// model's, the light as the incident side (module doc), with the scattered lobes'
    /// `M_s` divided by its column's mass where that exceeds 1 under
    /// [`MedullaEnergy::Conserve`].
    pub(crate) fn longitudinal(&self, theta_o: f64, theta: f64, phi: f64) -> LobeValues {
        let mut m = self.models[0].longitudinal(theta, theta_o, phi, self.lobes);
        if self.medulla_energy == MedullaEnergy::Conserve {
            let mass = self.models[0]
                .medulla()
                .map_or(1.0, |med| med.sampler().column_mass(theta_o, phi));
            if mass > 1.0 {
                for l in [Lobe::TTs, Lobe::TRTs] {
                    m.set(l, m.get(l) / mass);
                }
            }
        }
        m
    }

    /// Lobe selection probabilities at (`theta_o`, `h`) (module doc, step 2).
    pub fn lobe_probs(&self, theta_o: f64, h: f64) -> [f64; 5] {
        self.lobe_selection(theta_o, h).probs
    }

    /// The whole lobe selection at (`theta_o`, `h`): probabilities and the scattered
    /// lobes' frame (from the table when one is set).
    pub fn lobe_selection(&self, theta_o: f64, h: f64) -> Selection {
        self.select_at(&self.camera_side(theta_o), h)
    }

    /// The camera side of a vertex ([`CameraSide`]): the truncated `M_l` of the
    /// unscattered lobes, which depend on `theta_o` only.
    pub fn camera_side(&self, theta_o: f64) -> CameraSide {
        let mut m = TruncM {
            mu: [0.0; 5],
            s: [1.0; 5],
            tails: [(0.0, 0.0); 5],
        };
        let mut cauchy = [CauchyTheta::default(); 5];
        for l in self.lobes.iter().filter(|l| !l.is_scattered()) {
            let i = l.index();
            let (mu, s) = self.m_params(l, theta_o);
            m.mu[i] = mu;
            m.s[i] = s;
            m.tails[i] = trunc_tails(mu, s);
            if self.sampling == Sampling::Ishair {
                cauchy[i] = CauchyTheta::new(mu, s);
            }
        }
        CameraSide { theta_o, m, cauchy }
    }

    /// The lobe selection at offset `h` of a camera side: from the per-render table when
    /// one is set, else exact.
    fn select_at(&self, side: &CameraSide, h: f64) -> Selection {
        match &self.select {
            Some(t) => t.lookup(side.theta_o, h),
            None => self.selection(side, h),
        }
    }

    /// Per-channel attenuations at one path of slice `theta_d`: the cuticle depends on eta
    /// and l only, which the channels share (the tint scales absorption), so one Fresnel
    /// term serves the three.
    pub(crate) fn attenuation_rgb(&self, theta_d: f64, geo: &PathGeometry) -> [LobeValues; 3] {
        let f = self.models[0].azimuthal(theta_d).cuticle(geo);
        std::array::from_fn(|c| {
            self.models[c]
                .azimuthal(theta_d)
                .attenuation_with(f, geo, self.lobes)
        })
    }

    /// Exact lobe selection at offset `h` (module doc, step 2): energy per lobe on the
    /// camera side, averaged over the channels, and the scattered lobes' frame.
    fn selection(&self, side: &CameraSide, h: f64) -> Selection {
        let theta_o = side.theta_o;
        let geo = self.models[0].azimuthal(-theta_o).geometry(h);
        let mut w = [0.0; 5];
        for a in self.attenuation_rgb(-theta_o, &geo) {
            for l in self.lobes.iter().filter(|l| !l.is_scattered()) {
                w[l.index()] += a.get(l) / 3.0;
            }
        }
        for l in self.lobes.iter().filter(|l| !l.is_scattered()) {
            w[l.index()] *= side.m.mass(l.index()).max(MIN_MASS);
        }
        let (ws, x_med, phi_s) = self.scattered_selection(theta_o, h, geo);
        // The Strand scale multiplies the scattered lobes' energy (up to ~10x near the
        // poles, where the fitted ones carry little): without it there they were chosen
        // too rarely and came as rare large weights.
        let k = self
            .energy
            .as_deref()
            .map_or(1.0, |e| (0..3).map(|c| e.at(theta_o, c)).sum::<f64>() / 3.0);
        for l in self.lobes.iter().filter(|l| l.is_scattered()) {
            w[l.index()] = ws[l.p() - 1] * k;
        }
        let sum: f64 = w.iter().sum();
        Selection {
            probs: if sum > 0.0 {
                w.map(|x| x / sum)
            } else {
                [0.0; 5]
            },
            x_med,
            phi_s,
        }
    }

    /// The scattered lobes' part of [`Self::selection`]: their energies (TTs, TRTs) and
    /// frame (`x`, `Phi^s_p`) at offset `h`, `geo` being the path at the specular
    /// `theta_d = -theta_o`.
    ///
    /// `M_s` spreads over a wide range of light inclinations, and whether the path at `h`
    /// meets the medulla depends on `theta_d` (through `eta'`): near the rim a path misses
    /// it at the specular `theta_d` and meets it at steeper ones (`fur()` of the tests,
    /// `theta_o` 0.4, `h` -0.79: `A^s` 0 at `theta_d` -0.4, 0.66 at -0.82). Read at the
    /// specular `theta_d` alone the lobe got probability 0 there, and its light was found
    /// only through the other lobes' pdfs, as rare huge weights. So the energy of lobe `p`
    /// is the expectation over the light inclinations the lobe samples: the column mass of
    /// `M_s(., theta_o, Phi^s_p)` times the mean of `A^s_p * scattered fraction` at
    /// [`SCATTER_NODES`] equal-mass quantiles of that column. The frame is the nodes'
    /// energy-weighted mean (circular for `Phi^s_p`; the specular path's when no node has
    /// energy): it moves continuously with (`theta_o`, `h`), so the bilinear selection
    /// table interpolates it faithfully. The node of largest energy, the first choice,
    /// jumped between nodes and the table's blends of two frames sampled far from the lobe.
    fn scattered_selection(
        &self,
        theta_o: f64,
        h: f64,
        geo: PathGeometry,
    ) -> ([f64; 2], f64, [f64; 2]) {
        let kappa = self.models[0].params.kappa;
        let frame = |g: &PathGeometry| {
            (
                medulla_offset(g, kappa),
                [1, 2].map(|p| azimuthal::phi_s_p(p, g)),
            )
        };
        let spec = frame(&geo);
        let Some(med) = self.models[0].medulla() else {
            return ([0.0; 2], spec.0, spec.1);
        };
        let sm = med.sampler();
        let mut energy = [0.0; 2];
        // Energy-weighted sums of the nodes' frames: x, and (cos, sin) of each Phi^s_p.
        let (mut x_sum, mut rot) = (0.0, [[0.0; 2]; 2]);
        for l in self.lobes.iter().filter(|l| l.is_scattered()) {
            let i = l.p() - 1;
            let phi = spec.1[i];
            let mass = sm.column_mass(theta_o, phi);
            for k in 0..SCATTER_NODES {
                let u = (k as f64 + 0.5) / SCATTER_NODES as f64;
                let td = geometry::theta_d(theta_o, sm.sample_cm_incident(theta_o, phi, u).0);
                let g = self.models[0].azimuthal(td).geometry(h);
                let frac = med.scattered_fraction(medulla_offset(&g, kappa));
                let a: f64 = self.attenuation_rgb(td, &g).iter().map(|a| a.get(l)).sum();
                let e = mass * frac * a / (3.0 * SCATTER_NODES as f64);
                energy[i] += e;
                let (x, phis) = frame(&g);
                x_sum += e * x;
                rot[i][0] += e * phis[i].cos();
                rot[i][1] += e * phis[i].sin();
            }
        }
        let total = energy[0] + energy[1];
        if total <= 0.0 {
            return (energy, spec.0, spec.1);
        }
        let phi_s = [0, 1].map(|i| {
            if energy[i] > 0.0 {
                rot[i][1].atan2(rot[i][0])
            } else {
                spec.1[i]
            }
        });
        (energy, x_sum / total, phi_s)
    }

    /// Tabulate the lobe selection ([`super::select`]) for this render.
    pub fn build_select_table(&mut self) {
        let table = SelectTable::build(|theta_o, h| self.selection(&self.camera_side(theta_o), h));
        self.select = Some(Arc::new(table));
    }

    /// Centre and width of the truncated Gaussian `M_l` for camera side `theta_o`.
    fn m_params(&self, l: Lobe, theta_o: f64) -> (f64, f64) {
        let p = &self.models[0].params;
        let (a, b) = longitudinal::shift_width(l.p(), p.alpha, p.beta_m);
        (-theta_o + a, b)
    }

    /// Mixture pdf with prepared lobe data, `(theta, phi)` measure, averaged over the
    /// offsets `hs` (`sels[k]` the lobe selection at `hs[k]`). Terms that do not depend on `h` (the
    /// slice at `theta_d`, `M_s` of the scattered lobes) are computed once.
    fn pdf_prepared(
        &self,
        side: &CameraSide,
        sels: &[Selection],
        hs: &[f64],
        theta: f64,
        phi: f64,
    ) -> f64 {
        if self.sampling == Sampling::Uniform {
            return ishair::uniform_pdf(theta);
        }
        let slice = self.models[0].azimuthal(geometry::theta_d(side.theta_o, theta));
        let mut q = PdfQuery::new(self, side, theta, phi);
        let mut total = 0.0;
        for (sel, &h) in sels.iter().zip(hs) {
            let d = self.proposal_d(&slice.geometry(h), phi);
            total += q.at(sel, &d);
        }
        total / sels.len() as f64
    }

    /// Mixture pdf conditional on `h`, `(theta, phi)` measure: `sum_l P_l pdf_l`, with
    /// `pdf_l` the truncated `M_l` times the wrapped Gaussian `D_l` (unscattered) or the
    /// table densities `C^N` (in `psi`) times `M_s` (in `theta`) (scattered).
    pub fn pdf_at(&self, theta_o: f64, theta: f64, phi: f64, h: f64) -> f64 {
        let side = self.camera_side(theta_o);
        let sel = self.select_at(&side, h);
        self.pdf_prepared(&side, &[sel], &[h], theta, phi)
    }

    /// The camera-side state of [`Self::pdf_mis`] at one vertex: a path queries the MIS
    /// pdf twice per vertex (environment sample, escaped continuation) with the same
    /// `theta_o` and footprint, so it prepares once.
    pub fn mis_prepare(&self, side: &CameraSide, hr: HRange) -> MisPrep {
        let (hs, n) = match hr {
            HRange::At(h) => ([h; MIS_POINTS], 1),
            HRange::Span(h1, h2) => (
                std::array::from_fn(|k| h1 + (k as f64 + 0.5) / MIS_POINTS as f64 * (h2 - h1)),
                MIS_POINTS,
            ),
        };
        MisPrep {
            side: *side,
            n,
            hs,
            sels: std::array::from_fn(|k| {
                if k < n {
                    self.select_at(side, hs[k])
                } else {
                    Selection::default()
                }
            }),
        }
    }

    /// [`Self::pdf_mis`] from a [`MisPrep`].
    pub fn pdf_mis_prepared(&self, mp: &MisPrep, theta: f64, phi: f64) -> f64 {
        self.pdf_prepared(&mp.side, &mp.sels[..mp.n], &mp.hs[..mp.n], theta, phi)
    }

    /// pdf used for MIS weights: exact for the near field; for a span, the 4-point
    /// midpoint average of [`Self::pdf_at`] (any deterministic function of the direction
    /// keeps MIS unbiased; see module doc).
    pub fn pdf_mis(&self, theta_o: f64, theta: f64, phi: f64, hr: HRange) -> f64 {
        self.pdf_mis_prepared(
            &self.mis_prepare(&self.camera_side(theta_o), hr),
            theta,
            phi,
        )
    }

    /// Draw a light-side direction with four uniforms (module doc). `None` when no lobe
    /// carries energy.
    pub fn sample(&self, side: &CameraSide, hr: HRange, u: [f64; 4]) -> Option<BsdfSample> {
        let theta_o = side.theta_o;
        let (h, u1) = match hr {
            HRange::At(h) => (h, u[0]),
            HRange::Span(h1, h2) => (h1 + u[0] * (h2 - h1), u[1]),
        };
        if self.sampling == Sampling::Uniform {
            return self.sample_uniform(side, h, u);
        }
        // In span mode u[1] picks the lobe; in near mode u[0] does and u[1] is free.
        let sel = self.select_at(side, h);
        let probs = sel.probs;
        let mut acc = 0.0;
        let mut lobe = None;
        for l in self.lobes.iter() {
            acc += probs[l.index()];
            if probs[l.index()] > 0.0 && u1 < acc {
                lobe = Some(l);
                break;
            }
        }
        let lobe = match lobe {
            Some(l) => l,
            None => self
                .lobes
                .iter()
                .filter(|l| probs[l.index()] > 0.0)
                .last()?,
        };
        let (theta, phi, path) = if lobe.is_scattered() {
            // psi from C^N at the sampling frame's offset, then theta_r from M_s at that
            // phi (the front/back blend of Eq. 19 needs phi first).
            let sm = self.models[0].medulla()?.sampler();
            let (psi, _) = sm.sample_cn(sel.x_med, u[3]);
            let phi = wrap_angle(sel.phi_s[lobe.p() - 1] + psi);
            let (theta, _) = sm.sample_cm_incident(theta_o, phi, u[2]);
            (theta, phi, None)
        } else {
            let (i, m) = (lobe.index(), &side.m);
            let ish = self.sampling == Sampling::Ishair;
            let theta = if ish {
                side.cauchy[i].sample(u[2])
            } else if m.mass(i) < MIN_MASS {
                PI * (u[2] - 0.5)
            } else {
                trunc_sample(m.mu[i], m.s[i], m.tails[i], u[2])
            };
            let td = geometry::theta_d(theta_o, theta);
            let slice = self.models[0].azimuthal(td);
            let geo = slice.geometry(h);
            let sigma = azimuthal::beta_p(lobe.p(), self.models[0].params.beta_n);
            let centre = azimuthal::phi_p(lobe.p(), &geo);
            let phi = if ish {
                ishair::sample_phi(centre, sigma, u[3])
            } else {
                let z =
                    SQRT_2 * puruspe::inverf((2.0 * u[3] - 1.0).clamp(-1.0 + 1e-16, 1.0 - 1e-16));
                // D_p is a Gaussian of width beta_p about Phi_p(h) (Eqs. 7, 15).
                wrap_angle(centre + sigma * z)
            };
            (theta, phi, Some((td, geo)))
        };
        // The pdf and the near-field value share the path (traced once) and its D_l.
        let at = match path {
            Some((td, geo)) => self.near_point_at(td, geo, phi),
            None => self.near_point(theta_o, theta, phi, h),
        };
        let d = if self.sampling == Sampling::Ishair {
            self.proposal_d(&at.geo, phi)
        } else {
            at.d
        };
        let pdf = PdfQuery::new(self, side, theta, phi).at(&sel, &d);
        if pdf.is_nan() || pdf <= 0.0 || !pdf.is_finite() {
            return None;
        }
        let mut weight = self.eval_near_at(&at, theta_o, theta, phi);
        for l in weight.iter_mut() {
            for c in l.iter_mut() {
                *c /= pdf;
            }
        }
        Some(BsdfSample {
            theta,
            phi,
            h,
            lobe,
            weight,
            pdf,
        })
    }
}

impl FiberBsdf {
    /// [`Sampling::Uniform`]: a direction uniform over the sphere (u[2], u[3]) at offset
    /// `h`; the lobe reported is the one of largest weight (for the AOV split only).
    fn sample_uniform(&self, side: &CameraSide, h: f64, u: [f64; 4]) -> Option<BsdfSample> {
        let (theta, phi) = ishair::uniform_sample(u[2], u[3]);
        let pdf = ishair::uniform_pdf(theta);
        if pdf <= 0.0 {
            return None;
        }
        let mut weight = self.eval_near(side.theta_o, theta, phi, h);
        let lum = |l: &[f64; 3]| l.iter().sum::<f64>();
        let best = (0..5).max_by(|&a, &b| lum(&weight[a]).total_cmp(&lum(&weight[b])))?;
        let lobe = self
            .lobes
            .iter()
            .find(|l| l.index() == best)
            .unwrap_or(Lobe::R);
        weight.iter_mut().flatten().for_each(|c| *c /= pdf);
        Some(BsdfSample {
            theta,
            phi,
            h,
            lobe,
            weight,
            pdf,
        })
    }
}

/// A near-field query's path: `theta_d`, the geometry at `h` and the unscattered `D_l`.
struct NearPoint {
    td: f64,
    geo: PathGeometry,
    d: [f64; 5],
}

/// The mixture pdf at one light-side direction (`theta`, `phi`), for one or several
/// offsets: the parts that do not depend on `h` (the truncated `M_l` pdf in `theta`, `M_s`
/// of the scattered lobes) are computed once.
struct PdfQuery<'a> {
    bsdf: &'a FiberBsdf,
    sampler: Option<&'a crate::model::medulla::MedullaSampler>,
    theta_o: f64,
    theta: f64,
    phi: f64,
    /// Truncated `M_l` pdf in `theta` (from `theta_o` only).
    pt: [f64; 5],
    cm: Option<f64>,
}

impl<'a> PdfQuery<'a> {
    fn new(bsdf: &'a FiberBsdf, side: &CameraSide, theta: f64, phi: f64) -> Self {
        let m = &side.m;
        let ish = bsdf.sampling == Sampling::Ishair;
        let pt = std::array::from_fn(|i| {
            let mass = m.mass(i);
            if ish {
                side.cauchy[i].pdf(theta)
            } else if mass < MIN_MASS {
                1.0 / PI
            } else {
                longitudinal::gaussian(theta, m.mu[i], m.s[i]) / mass
            }
        });
        PdfQuery {
            bsdf,
            sampler: bsdf.models[0].medulla().map(|m| m.sampler()),
            theta_o: side.theta_o,
            theta,
            phi,
            pt,
            cm: None,
        }
    }

    /// `sum_l P_l pdf_l` at the offset whose lobe selection is `sel` and unscattered
    /// `D_l` are `d`.
    fn at(&mut self, sel: &Selection, d: &[f64; 5]) -> f64 {
        let mut pdf = 0.0;
        for l in self.bsdf.lobes.iter() {
            let i = l.index();
            if sel.probs[i] <= 0.0 {
                continue;
            }
            let v = if l.is_scattered() {
                match self.sampler {
                    Some(sm) => {
                        let (theta_o, theta, phi) = (self.theta_o, self.theta, self.phi);
                        let cm = *self
                            .cm
                            .get_or_insert_with(|| sm.pdf_cm_incident(theta_o, theta, phi));
                        sm.pdf_cn(sel.x_med, wrap_angle(phi - sel.phi_s[l.p() - 1])) * cm
                    }
                    None => 0.0,
                }
            } else {
                self.pt[i] * d[i]
            };
            pdf += sel.probs[i] * v;
        }
        pdf
    }
}

/// Local shading frame at a hit (module doc): `v` along the camera-side direction's
/// normal-plane projection, `w = u x v`.
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    /// The fiber tangent, root to tip.
    pub u: V3,
    /// The camera direction projected on the normal plane (`phi = 0`).
    pub v: V3,
    /// `u x v`, completing the right-handed frame.
    pub w: V3,
}

impl Frame {
    /// The frame of tangent `u` (unit) and camera-side direction `wo`; any normal-plane `v`
    /// when `wo` runs along the fiber.
    pub fn new(u: V3, wo: V3) -> Frame {
        let mut v = wo - u * wo.dot(u);
        if v.length() < 1e-9 {
            // Looking along the fiber: any normal-plane direction.
            let a = if u.x.abs() < 0.9 {
                V3::new(1.0, 0.0, 0.0)
            } else {
                V3::new(0.0, 1.0, 0.0)
            };
            v = a - u * a.dot(u);
        }
        let v = v.normalized();
        Frame {
            u,
            v,
            w: u.cross(v),
        }
    }

    /// `(theta, phi)` of a unit world direction.
    pub fn to_local(&self, d: V3) -> (f64, f64) {
        (
            d.dot(self.u).clamp(-1.0, 1.0).asin(),
            d.dot(self.w).atan2(d.dot(self.v)),
        )
    }

    /// The unit world direction of local `(theta, phi)`: the inverse of
    /// [`Frame::to_local`].
    pub fn to_world(&self, theta: f64, phi: f64) -> V3 {
        let (st, ct) = theta.sin_cos();
        let (sp, cp) = phi.sin_cos();
        self.v * (ct * cp) + self.w * (ct * sp) + self.u * st
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The skipped tail changes nothing: `qa - qb` is bit-identical to the difference with
    /// the tail computed, across centres and widths that take either branch.
    #[test]
    fn trunc_tails_skip_is_exact() {
        let mut skipped = 0;
        for i in 0..400 {
            let mu = -3.0 + 6.0 * (i as f64 * 0.618_033_988_75).fract();
            let s = 0.01 + 1.2 * (i as f64 * 0.414_213_562_37).fract();
            let (qa, qb) = trunc_tails(mu, s);
            let full = 0.5 * puruspe::erfc((FRAC_PI_2 + mu.abs()) / (s * SQRT_2));
            assert_eq!((qa - qb).to_bits(), (qa - full).to_bits(), "mu {mu} s {s}");
            skipped += usize::from(qb == 0.0 && full > 0.0);
        }
        // Both branches must be exercised (43 of the 400 cases skip).
        assert!(skipped > 20 && skipped < 380, "{skipped}");
    }

    /// `trunc_sample` is the exact inverse of the truncated normal's CDF on
    /// [-pi/2, pi/2], for centres of either sign and widths from narrow to wider than the
    /// domain (where both tails hold several percent of the mass, as for a rough TRT lobe):
    /// `F(x(u)) = u` at evenly spread `u` (`1 - u` for a centre above 0, which is sampled
    /// mirrored so the erfc tails stay precise). The erfc / inverfc round trip is good to ~1e-13
    /// here; 1e-9 is far below the error of dropping a tail (>= 1e-3 for these cases).
    #[test]
    fn trunc_sample_inverts_the_truncated_cdf() {
        for (mu, s) in [
            (0.3, 1.0),
            (-0.4, 1.5),
            (1.2, 0.4),
            (-1.5, 0.05),
            (0.0, 0.8),
        ] {
            let cdf = |x: f64| 0.5 * puruspe::erfc(-(x - mu) / (s * SQRT_2));
            let (lo, hi) = (cdf(-FRAC_PI_2), cdf(FRAC_PI_2));
            let tails = trunc_tails(mu, s);
            assert!(
                ((tails.0 - tails.1) - (hi - lo)).abs() < 1e-12,
                "mass {mu} {s}"
            );
            for k in 0..200 {
                let u = (k as f64 + 0.5) / 200.0;
                let x = trunc_sample(mu, s, tails, u);
                assert!(x.abs() <= FRAC_PI_2, "{x}");
                let f = (cdf(x) - lo) / (hi - lo);
                let want = if mu > 0.0 { 1.0 - u } else { u };
                assert!((f - want).abs() < 1e-9, "mu {mu} s {s} u {u}: F(x) = {f}");
            }
        }
    }
}
