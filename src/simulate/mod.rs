//! The virtual goniometer: explicit Monte Carlo ray tracing of photons through a 3-D
//! double-cylinder fur fiber, binned like a goniometer. It makes the synthetic
//! `measurements/` and is deliberately independent of the analytic model in
//! [`crate::model`] (it shares only [`FurParams`] and the Fresnel functions of
//! [`crate::model::fresnel`]).
//!
//! # Physics (each choice stated here)
//! - **Fiber.** An infinite cylinder along `u = +z` (root -> tip) with unit radius and a
//!   concentric medulla of radius `kappa`. Optional elliptical cross-section: the axis ratio
//!   `e` (minor/major, Marschner et al. 2003's eccentricity `a`) with the area of the unit
//!   circle (semi-axes `1/sqrt(e)`, `sqrt(e)`), the medulla the same ellipse scaled by
//!   `kappa`, averaged over a uniformly random rotation of the fiber about its axis.
//!   Optional medulla IOR `eta_m` (default `eta`, index matched as MODEL.md assumes; when it
//!   differs the medulla boundary is a smooth Fresnel interface, chosen stochastically).
//! - **Light.** A collimated beam from `theta_i` (MODEL.md frames: `theta` out of the normal
//!   plane, + toward the tip). Each path hits the fiber at an offset `h` uniform over the
//!   fiber's full projected width (for the ellipse, the projected width at that rotation),
//!   so the output is the *far field* (MODEL.md: `1/2 * integral dh`).
//! - **Frames of the detector.** The light lies at azimuth `phi_i` (0 for the circle); an
//!   exit direction `w` has `theta_r = asin(w_z)` and `phi = atan2(w_y, w_x) - phi_i`
//!   wrapped to (-pi, pi]: `phi = 0` is backscatter, `|phi| = pi` forward. With the impact
//!   point at `y = h`, a smooth R reflection goes to `phi = +2 asin(h)`; MODEL.md writes
//!   `-2 gamma_i`, the mirror convention for `h`. Far-field output is symmetric in `h`,
//!   so both agree.
//! - **Cuticle.** At every cuticle interaction (entering, and every internal hit of the
//!   outer boundary) the surface normal is the geometric normal tilted toward the tip by
//!   `alpha/2 + s_m N(0,1)` and around the axis by `s_n N(0,1)`. A mirror reflection turns a
//!   normal tilt `t` into a direction change `2t`, so `alpha/2` puts the R lobe at
//!   `theta_r = -theta_i + alpha` (MODEL.md / seed Table 2; Marschner's "shift 2 x scale
//!   angle" with `alpha` meaning the lobe shift) and `s_m = beta_m/2`, `s_n = beta_n/2`
//!   give the single-reflection R lobe a longitudinal std ~ `beta_m` and an azimuthal std
//!   ~ `beta_n` (small-angle). This holds at the centre of the fiber; the scale is a real
//!   cone, so a ray meeting it at azimuthal incidence `gamma` is deflected longitudinally by
//!   only `asin(cos(gamma) sin(2t))`: averaged over the width (Fresnel favours grazing
//!   `gamma`) the R lobe's shift and width are ~0.6-0.8 of `alpha`, `beta_m`. This is a
//!   real difference from the analytic model (which shifts every `h` by `alpha`); fits to
//!   these data should be expected to return a smaller `alpha`/`beta_m` than simulated.
//!   Refraction turns a ray by less than reflection does: a tilt `t` deflects a transmitted
//!   ray by about `(1 - 1/eta) t` entering and `(eta - 1) t` leaving (small angles), so TT's
//!   azimuthal spread is about `0.33 beta_n` at `eta = 1.55`, where MODEL.md gives the
//!   unscattered lobe `p` a variance `(p + 1) beta_n^2` (TT: `1.41 beta_n`). Measured (audit,
//!   2026-11-28, kappa 0): beta_n 1 -> 40 deg moves the goniometer's forward TT peak by 6 %
//!   (0.353 -> 0.332) and the model's by half (0.354 -> 0.187). So fits to these data
//!   match the goniometer's narrow TT with a small `beta_n` (red fox and springbok run to
//!   the bound): a difference of the two physics, not missing information. Likewise the
//!   exact facet optics put TT and TRT's longitudinal shifts near `-(eta - 1) alpha` and
//!   `-(2 eta - 1) alpha` where MODEL.md has `-alpha/2` and `-3 alpha/2` (TRT peak at
//!   theta_r -17.5 deg against the model's -12 for `alpha = 8`, theta_i 0), which pulls
//!   fitted `alpha` too.
//!   The same tilted micro-normal is used for internal hits of the cuticle, so repeated
//!   internal reflections are steered along the axis and can end up guided (total internal
//!   reflection along the fiber); absorption and Russian roulette end those paths. The interface reflects
//!   with the pile-of-plates probability `F = l f / (1 + (l-1) f)` of the *exact 3-D* Fresnel
//!   reflectance `f` at the micro-normal, transmits (Snell, at the micro-normal) with
//!   `1 - F`; the choice is stochastic (analog). A micro-normal that faces away from the ray
//!   or would send it through the real surface the wrong way is redrawn (no explicit
//!   shadowing/masking model).
//! - **Interior.** Beer-Lambert absorption `sigma_c_a` along 3-D path lengths in the cortex
//!   and `sigma_m_a` in the medulla, applied as *weights* (`w *= exp(-sigma l)`). In the
//!   medulla free flights are sampled with `sigma_m_s` alone (analog scattering), the phase
//!   function is Henyey-Greenstein with `g`. Paths leave and re-enter the medulla and bounce
//!   inside any number of times; after 6 events a path whose weight is below 0.1 plays
//!   Russian roulette (survives with probability `w/0.1`, then carries 0.1: unbiased). A path
//!   still inside after [`trace::MAX_EVENTS`] events or [`trace::MAX_CUTICLE_HITS`] cuticle
//!   interactions, or farther than [`trace::GUIDED_LENGTH`] radii along the axis, is light
//!   guided along the fiber; it
//!   leaves far from the lit spot, so it is tallied as `guided`, not detected.
//! - **Detector.** Exit directions are binned in `(theta_r, phi)`; each bin is centred on
//!   its grid value with the width of the grid step (for uneven lists, the distance
//!   to the nearer neighbour, so each bin stays centred on its value; the end bins are
//!   symmetric: [`bins`]). `phi` bins wrap around the circle without overlapping, so a grid
//!   holding both -180 and 180 fills both with the same light. The value of a bin is
//!   `(energy in the bin) / (launched energy) / (dtheta_r dphi)` in radians^2: a density
//!   per radian of `theta_r` and per radian of `phi` of outgoing energy per unit incident
//!   energy, which is what MODEL.md's goniometer sample `k sum_p M_p N_p` predicts (M_p per
//!   radian of `theta_r`, N_p per radian of `phi`). It is NOT divided by `cos theta_r`:
//!   integrating it over `theta_r` and `phi` gives the exitant fraction (<= 1). Each bin's
//!   standard error (`sigma`) comes from the per-path weights (sum and sum of squares).
//! - **Determinism.** Paths are split into fixed chunks of [`CHUNK`] paths; chunk `c` of
//!   incidence angle `i` has its own Xoshiro256++ stream seeded from `(seed, i, c)`. Chunks
//!   run in parallel (rayon; as many at once as their bins' memory allows) and are summed
//!   in chunk order, so the output depends only on
//!   the seed and path count, not on the thread count.
//!
//! Measurement effects (noise models, detector floor, occluded wedge, dropped samples) are
//! in [`measure`]; the CSV and metadata writers in [`output`]; a whole `furfit simulate`
//! run from parsed options in [`job`].

pub mod job;
pub mod measure;
pub mod optics;
pub mod output;
pub mod trace;

use crate::error::{Error, Num, Result};
use crate::FurParams;
use rand::SeedableRng;
use rand_xoshiro::Xoshiro256PlusPlus;
use rayon::prelude::*;
use std::f64::consts::{FRAC_PI_2, PI, TAU};
use trace::{trace_path, Fiber, Outcome};

/// Paths per deterministic chunk (one RNG stream each).
pub const CHUNK: u64 = 1 << 15;

/// What to simulate. Angles in degrees (file units), as on the command line.
#[derive(Clone, Debug)]
pub struct SimSettings {
    /// The fiber's parameters.
    pub params: FurParams,
    /// Incidence angles, degrees.
    pub theta_i: Vec<f64>,
    /// Detector `theta_r` bin centres, degrees.
    pub theta_r: Vec<f64>,
    /// Detector `phi` bin centres, degrees.
    pub phi: Vec<f64>,
    /// Paths traced per incidence angle.
    pub paths: u64,
    /// Seed of the path streams (one per [`CHUNK`]).
    pub seed: u64,
    /// Elliptical cross-section axis ratio (None or 1 = circle).
    pub ellipse: Option<f64>,
    /// Medulla IOR (None = equal to eta).
    pub medulla_eta: Option<f64>,
    /// Zero micro-roughness (test switch; bounds keep beta > 0 in parameter files).
    pub smooth: bool,
}

impl SimSettings {
    /// Check the options that the parameter bounds do not cover.
    pub fn validate(&self) -> Result<()> {
        self.params.validate()?;
        let bad = |m: String| Err(Error::Invalid(m));
        if self.paths < 2 {
            // One path gives every bin it hits a standard error of 0 (audit, 2026-11-28).
            return bad(format!(
                "--paths must be at least 2 (each sample's standard error is the spread over \
                 paths), found {}",
                self.paths
            ));
        }
        if self.paths > MAX_PATHS {
            return bad(format!(
                "--paths must be at most {MAX_PATHS:e} per incidence angle (days of tracing at \
                 ~1e6 paths/s), found {:e}",
                self.paths as f64
            ));
        }
        if self.theta_i.is_empty() || self.theta_r.is_empty() || self.phi.is_empty() {
            return bad("empty angle grid".into());
        }
        for (what, v, lim) in [
            ("--theta-i", &self.theta_i, 90.0),
            ("--theta-r", &self.theta_r, 90.0),
            ("--phi", &self.phi, 180.0),
        ] {
            if let Some(x) = v.iter().find(|x| x.abs() > lim) {
                return bad(format!(
                    "{what}: {} is outside [-{lim}, {lim}] degrees",
                    Num(*x)
                ));
            }
            // Detector bins need sorted centres; incidence angles only need to be distinct.
            if what != "--theta-i" && v.windows(2).any(|w| w[1] <= w[0]) {
                return bad(format!("{what}: values must be strictly increasing"));
            }
        }
        let mut seen = std::collections::HashSet::new();
        if let Some(x) = self
            .theta_i
            .iter()
            .find(|x| !seen.insert((*x + 0.0).to_bits()))
        {
            return bad(format!("--theta-i: {} is given twice", Num(*x)));
        }
        // A detector bin is as wide as the spacing of its axis's centres (bins), so
        // one centre has no width of its own; refuse it rather than invent one.
        for (what, v) in [("--theta-r", &self.theta_r), ("--phi", &self.phi)] {
            if let [x] = v[..] {
                return bad(format!(
                    "{what} has a single value ({}): detector bins are centred on the grid \
                     values and as wide as their spacing, so {what} needs at least two values \
                     (e.g. {what} -1,0,1 gives 0 a 1-degree bin)",
                    Num(x)
                ));
            }
        }
        crate::grid::check_grid_size(self.theta_i.len(), self.theta_r.len(), self.phi.len(), 1)?;
        if self.theta_i.iter().any(|x| x.abs() >= 90.0) {
            return bad("--theta-i must be inside (-90, 90) degrees".into());
        }
        // Hair and fur sections are about 0.5-1 (Marschner 2003). Far flatter sections
        // break the tracer's ellipse intersections (1e-300 crashed, 1e-100 sent a fifth
        // of the light into a "guided" state); 0.01 still conserves energy.
        if let Some(e) = self.ellipse {
            if !(e.is_finite() && (ELLIPSE_MIN..=1.0).contains(&e)) {
                return bad(format!(
                    "--ellipse {}: the axis ratio (minor/major) must be in [{ELLIPSE_MIN}, 1]",
                    Num(e)
                ));
            }
        }
        if let Some(m) = self.medulla_eta {
            if !(m.is_finite() && m > 1.0 && m <= 3.0) {
                return bad(format!("--medulla-eta {}: must be in (1, 3]", Num(m)));
            }
        }
        Ok(())
    }

    /// The fiber the tracer walks, with the geometry extras.
    pub fn fiber(&self) -> Fiber {
        Fiber::new(&self.params, self.ellipse, self.medulla_eta, self.smooth)
    }
}

/// Most paths per incidence angle (the run's path total must also fit a `u64`).
pub const MAX_PATHS: u64 = 1_000_000_000_000;

/// Smallest `--ellipse` axis ratio (see [`SimSettings::validate`]).
pub const ELLIPSE_MIN: f64 = 0.01;

/// Detector bins `(lo, hi)` (radians) for grid centres (degrees, ascending): each bin is
/// centred on its value, with half-width half the gap to its nearer neighbour, so a uniform
/// grid gets bins as wide as its step and no bin reaches past half the gap on either side
/// of its value (bins reaching half-way to each neighbour were centred off their labels
/// beside a gap and read a density averaged over it; audit, 2026-11-28). A value far from
/// both neighbours still gets a wide bin: `-40,-30,10` gives 10 the bin (-10, 30), since
/// its nearer neighbour is 40 degrees away. End bins are symmetric. With
/// `cyclic` (phi) neighbours are taken around the circle, so bins never overlap there and
/// never cover more than 360 degrees in all (`-170,170` gave two 340-degree bins that
/// counted the light twice); a value at the same azimuth as another (-180 and 180) shares
/// its bin. A single value gets a 1-degree bin ([`SimSettings::validate`] refuses a
/// single-value axis, whose width would be arbitrary).
pub fn bins(centres_deg: &[f64], cyclic: bool) -> Vec<(f64, f64)> {
    let c: Vec<f64> = centres_deg.iter().map(|x| x.to_radians()).collect();
    let n = c.len();
    if n == 1 {
        let h = 0.5f64.to_radians();
        return vec![(c[0] - h, c[0] + h)];
    }
    // Gap from c[i] to its neighbour below / above: the next value, or around the circle
    // (cyclic) the last / first one, skipping a value at the same azimuth (-180 beside
    // 180, an ulp apart after the radian conversion; only across the wrap, so close but
    // distinct values keep their own narrow bins).
    let gap = |i: usize, up: bool| -> Option<f64> {
        let step = |k: usize| if up { (k + 1) % n } else { (k + n - 1) % n };
        let mut k = i;
        for _ in 0..n - 1 {
            k = step(k);
            let wraps = if up { k <= i } else { k >= i };
            if !wraps {
                return Some(if up { c[k] - c[i] } else { c[i] - c[k] });
            }
            if !cyclic {
                return None;
            }
            let d = if up { c[k] - c[i] } else { c[i] - c[k] } + TAU;
            if d.abs() > 1e-9 && (d - TAU).abs() > 1e-9 {
                return Some(d);
            }
        }
        None
    };
    (0..n)
        .map(|i| {
            let (lo_gap, hi_gap) = (gap(i, false), gap(i, true));
            // Two gaps equal up to rounding (a uniform grid, its cyclic wrap included)
            // count as one: the edges are then the midpoints between neighbours, as they
            // always were, and an end bin takes its inner gap.
            let equal = |a: f64, b: f64| (a - b).abs() <= 1e-9 * a.max(b);
            let (lo, hi) = (i > 0, i + 1 < n);
            let half = 0.5
                * match (lo_gap, hi_gap) {
                    (Some(a), Some(b)) if equal(a, b) => {
                        if hi {
                            b
                        } else {
                            a
                        }
                    }
                    (Some(a), Some(b)) => a.min(b),
                    (Some(a), None) | (None, Some(a)) => a,
                    (None, None) => TAU,
                };
            let edge_lo = match lo_gap {
                Some(g) if lo && equal(0.5 * g, half) => 0.5 * (c[i - 1] + c[i]),
                _ => c[i] - half,
            };
            let edge_hi = match hi_gap {
                Some(g) if hi && equal(0.5 * g, half) => 0.5 * (c[i] + c[i + 1]),
                _ => c[i] + half,
            };
            (edge_lo, edge_hi)
        })
        .collect()
}

/// Index of the bin holding `x`, if any (bins ascending and disjoint, half-open `[lo, hi)`).
#[inline]
fn find_bin(bins: &[(f64, f64)], x: f64) -> Option<usize> {
    let k = bins.partition_point(|b| b.0 <= x);
    (k > 0 && x < bins[k - 1].1).then(|| k - 1)
}

/// The detector: bins `(lo, hi)` in theta_r and phi, radians.
#[derive(Clone, Debug)]
pub struct Detector {
    /// `theta_r` bins `(lo, hi)`, radians, clipped to the poles.
    pub theta_bins: Vec<(f64, f64)>,
    /// `phi` bins `(lo, hi)`, radians.
    pub phi_bins: Vec<(f64, f64)>,
}

impl Detector {
    /// `theta_r` bins are clipped to `[-90, 90]` degrees: an end bin centred at +-90 would
    /// otherwise reach past the pole, where no exit direction lies, and its value (energy
    /// over the bin's width) would read about half the density.
    pub fn new(theta_r_deg: &[f64], phi_deg: &[f64]) -> Self {
        let theta_bins = bins(theta_r_deg, false)
            .into_iter()
            .map(|(a, b)| {
                (
                    a.clamp(-FRAC_PI_2, FRAC_PI_2),
                    b.clamp(-FRAC_PI_2, FRAC_PI_2),
                )
            })
            .collect();
        Detector {
            theta_bins,
            phi_bins: bins(phi_deg, true),
        }
    }
    /// Number of `theta_r` bins.
    pub fn n_theta(&self) -> usize {
        self.theta_bins.len()
    }
    /// Number of `phi` bins.
    pub fn n_phi(&self) -> usize {
        self.phi_bins.len()
    }
    /// Solid-angle-free bin area dtheta_r * dphi (radians^2) of bin (j, k).
    pub fn area(&self, j: usize, k: usize) -> f64 {
        (self.theta_bins[j].1 - self.theta_bins[j].0) * (self.phi_bins[k].1 - self.phi_bins[k].0)
    }

    /// Call `f(flat_index)` for every bin the exit (theta_r, phi) falls into (phi wraps:
    /// the shifted copies phi +- 2 pi are tried too).
    #[inline]
    pub fn deposit(&self, theta_r: f64, phi: f64, mut f: impl FnMut(usize)) {
        let Some(j) = find_bin(&self.theta_bins, theta_r) else {
            return;
        };
        let np = self.n_phi();
        for shift in [0.0, 2.0 * PI, -2.0 * PI] {
            if let Some(k) = find_bin(&self.phi_bins, phi + shift) {
                f(j * np + k);
            }
        }
    }
}

/// Energy tallies of one incidence angle (fractions of launched energy).
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct Tally {
    /// Paths traced.
    pub paths: u64,
    /// Energy that left the fiber (anywhere).
    pub exited: f64,
    /// Energy that left and fell into some detector bin.
    pub binned: f64,
    /// Energy guided along the fiber (still inside after the event cap).
    pub guided: f64,
    /// Number of medulla scattering events.
    pub scatter_events: u64,
    /// Wall time in seconds.
    pub seconds: f64,
}

/// Raw detector counts of one incidence angle: per-bin sum of weights and of squares.
#[derive(Clone, Debug)]
struct Accum {
    sum: Vec<f64>,
    sum2: Vec<f64>,
    exited: f64,
    binned: f64,
    guided: f64,
    scatter_events: u64,
}

impl Accum {
    fn new(n: usize) -> Self {
        Accum {
            sum: vec![0.0; n],
            sum2: vec![0.0; n],
            exited: 0.0,
            binned: 0.0,
            guided: 0.0,
            scatter_events: 0,
        }
    }
    fn add(&mut self, o: &Accum) {
        for (a, b) in self.sum.iter_mut().zip(&o.sum) {
            *a += b;
        }
        for (a, b) in self.sum2.iter_mut().zip(&o.sum2) {
            *a += b;
        }
        self.exited += o.exited;
        self.binned += o.binned;
        self.guided += o.guided;
        self.scatter_events += o.scatter_events;
    }
}

/// The simulated profile before measurement effects: `value[i][j][k]` (theta_i, theta_r,
/// phi, flattened row-major) and its Monte Carlo standard error.
#[derive(Clone, Debug)]
pub struct SimResult {
    /// Incidence angles, degrees.
    pub theta_i: Vec<f64>,
    /// `theta_r` bin centres, degrees.
    pub theta_r: Vec<f64>,
    /// `phi` bin centres, degrees.
    pub phi: Vec<f64>,
    /// Fraction of launched energy exiting into each bin per unit `dtheta_r dphi`
    /// (radians^2), row-major in (theta_i, theta_r, phi).
    pub value: Vec<f64>,
    /// Monte Carlo standard error of each value.
    pub sigma: Vec<f64>,
    /// Energy tallies per incidence angle.
    pub tally: Vec<Tally>,
}

impl SimResult {
    /// Flat index of bin `(i, j, k)` in `value`.
    pub fn index(&self, i: usize, j: usize, k: usize) -> usize {
        (i * self.theta_r.len() + j) * self.phi.len() + k
    }
}

/// Median relative standard error (`sigma / value`) over the bins whose value is at least
/// `above * peak` (peak over the whole profile); `None` when nothing was detected.
pub fn median_rel_noise(r: &SimResult, above: f64) -> Option<f64> {
    let peak = r.value.iter().cloned().fold(0.0, f64::max);
    if peak <= 0.0 {
        return None;
    }
    let mut rel: Vec<f64> = r
        .value
        .iter()
        .zip(&r.sigma)
        .filter(|(v, _)| **v > 0.0 && **v >= above * peak)
        .map(|(v, s)| s / v)
        .collect();
    if rel.is_empty() {
        return None;
    }
    rel.sort_by(|a, b| a.total_cmp(b));
    Some(rel[rel.len() / 2])
}

/// Seed of chunk `c` of incidence angle `i` (SplitMix64 finaliser over the triple).
pub fn chunk_seed(seed: u64, i: u64, c: u64) -> u64 {
    let mut z = seed
        .wrapping_add(0x9E37_79B9_7F4A_7C15u64.wrapping_mul(i.wrapping_add(1)))
        .wrapping_add(0xD1B5_4A32_D192_ED03u64.wrapping_mul(c.wrapping_add(1)));
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Wrap an angle to (-pi, pi].
#[inline]
pub fn wrap_pi(x: f64) -> f64 {
    let mut y = x % (2.0 * PI);
    if y <= -PI {
        y += 2.0 * PI;
    } else if y > PI {
        y -= 2.0 * PI;
    }
    y
}

/// Exit direction -> (theta_r, phi) in radians (MODEL.md frames).
#[inline]
pub fn exit_angles(e: &trace::Exit) -> (f64, f64) {
    let th = e.dir[2].clamp(-1.0, 1.0).asin();
    let ph = wrap_pi(e.dir[1].atan2(e.dir[0]) - e.phi_i);
    (th, ph)
}

fn run_chunk(fiber: &Fiber, det: &Detector, theta_i: f64, n: u64, seed: u64) -> Accum {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    let mut acc = Accum::new(det.n_theta() * det.n_phi());
    for _ in 0..n {
        match trace_path(fiber, theta_i, &mut rng) {
            Outcome::Exit(e) => {
                acc.exited += e.weight;
                acc.scatter_events += e.scatters as u64;
                let (th, ph) = exit_angles(&e);
                let mut first = true;
                det.deposit(th, ph, |b| {
                    acc.sum[b] += e.weight;
                    acc.sum2[b] += e.weight * e.weight;
                    if first {
                        acc.binned += e.weight;
                        first = false;
                    }
                });
            }
            Outcome::Absorbed => {}
            Outcome::Guided(w) => acc.guided += w,
        }
    }
    acc
}

/// Memory the detector accumulators of the chunks in flight may take (bytes).
const ACCUM_BUDGET: usize = 512 << 20;

/// How many chunks run at once: 4 per thread to balance the load, but no more than fit
/// [`ACCUM_BUDGET`] (each holds two f64 per detector bin, so on a fine grid 4 per thread
/// would need gigabytes), and at least 1. Sums are still taken in chunk order, so the
/// output does not depend on it.
fn chunks_in_flight(threads: usize, bins: usize) -> u64 {
    let fit = ACCUM_BUDGET / (16 * bins.max(1));
    (4 * threads.max(1)).min(fit).max(1) as u64
}

/// Run the virtual goniometer. `progress(done_paths)` is called after each batch of chunks
/// (from the calling thread). Uses the current rayon pool.
pub fn simulate(s: &SimSettings, mut progress: impl FnMut(u64)) -> Result<SimResult> {
    s.validate()?;
    let fiber = s.fiber();
    let det = Detector::new(&s.theta_r, &s.phi);
    let nb = det.n_theta() * det.n_phi();
    let n_chunks = s.paths.div_ceil(CHUNK);
    let batch = chunks_in_flight(rayon::current_num_threads(), nb);
    let mut value = Vec::with_capacity(s.theta_i.len() * nb);
    let mut sigma = Vec::with_capacity(s.theta_i.len() * nb);
    let mut tally = Vec::new();
    let mut done = 0u64;
    for (i, &ti) in s.theta_i.iter().enumerate() {
        let t0 = std::time::Instant::now();
        let theta_i = ti.to_radians();
        let mut total = Accum::new(nb);
        let mut c0 = 0u64;
        while c0 < n_chunks {
            let c1 = (c0 + batch).min(n_chunks);
            let parts: Vec<Accum> = (c0..c1)
                .into_par_iter()
                .map(|c| {
                    let n = CHUNK.min(s.paths - c * CHUNK);
                    run_chunk(&fiber, &det, theta_i, n, chunk_seed(s.seed, i as u64, c))
                })
                .collect();
            for p in &parts {
                total.add(p);
            }
            done += (c1 * CHUNK).min(s.paths) - (c0 * CHUNK).min(s.paths);
            progress(done);
            c0 = c1;
        }
        let n = s.paths as f64;
        for j in 0..det.n_theta() {
            for k in 0..det.n_phi() {
                let b = j * det.n_phi() + k;
                let area = det.area(j, k);
                let mean = total.sum[b] / n;
                let var = (total.sum2[b] / n - mean * mean).max(0.0) / n;
                value.push(mean / area);
                sigma.push(var.sqrt() / area);
            }
        }
        tally.push(Tally {
            paths: s.paths,
            exited: total.exited / n,
            binned: total.binned / n,
            guided: total.guided / n,
            scatter_events: total.scatter_events,
            seconds: t0.elapsed().as_secs_f64(),
        });
    }
    Ok(SimResult {
        theta_i: s.theta_i.clone(),
        theta_r: s.theta_r.clone(),
        phi: s.phi.clone(),
        value,
        sigma,
        tally,
    })
}

#[cfg(test)]
mod tests;
