//! Monte Carlo generator of the medulla scattering tables `C^N` and `C^M`
//! (seed paper Sec. 3, Fig. 4; MODEL.md "Medulla scattering tables").
//!
//! The medulla is an infinite cylinder of radius 1 whose scattering coefficient is its
//! optical radius `tau` (scattering events per medulla radius), index-matched to its
//! surroundings (no refraction or reflection at its boundary), non-absorbing (absorption is
//! applied analytically by the model, seed Eq. 20), with a Henyey-Greenstein phase function
//! of anisotropy `g`. Photons walk in 3-D; the cross section is the unit disk in the
//! `(x, y)` plane and the fiber axis is `z`.
//!
//! Geometry (see [`crate::model::medulla`] for the conventions the model relies on): a
//! photon enters travelling in direction `(-cos theta_i, 0, -sin theta_i)` (plane direction
//! angle `pi`) at plane position `(sqrt(1 - x^2), -x)`, where `x` in `[-1, 1]` is the signed
//! entry offset. The exit azimuth is `psi = atan2(d_y, d_x)` of the exit direction `d`
//! (`psi = 0` straight back toward the light, `|psi| = pi` straight on) and the exit
//! inclination is `theta_r = asin(d_z)`; an unscattered photon would leave with
//! `theta_r = -theta_i` (the specular cone, as for the paper's `M_p`).
//!
//! Variance reduction: *forced first collision*. Every path is made to scatter: the first
//! collision is sampled from the exponential truncated to the chord and the path carries
//! the weight `P_s = 1 - exp(-tau L)` (`L` the 3-D chord length). Hence the scattered
//! fraction of `C^N` is exact (`1 - exp(-2 tau sqrt(1 - x^2))` at `theta_i = 0`) and only the
//! *shape* of the exit distribution carries Monte Carlo noise. The tables store that shape
//! (a density integrating to 1); the model multiplies `C^N` back by the analytic `P_s`.
//! At `tau = 0` the shape is the well-defined limit `tau -> 0`: a single scattering event
//! placed uniformly along the chord (no photon ever needs a fallback density).
//!
//! Determinism: every table configuration (one `(tau, g, x)` or `(tau, g, theta_i)` cell)
//! has its own `Xoshiro256PlusPlus` stream seeded from `(seed, table, cell index)` with
//! SplitMix64, runs sequentially, and rayon only distributes whole cells whose results are
//! collected into fixed slots. The output is therefore bit-identical for a given seed and
//! path budget regardless of thread count. The shipped tables come from
//! `furfit tables build --seed 2017 --paths 16000` (see [`crate::model::medulla`] for the
//! measured time and errors).

use crate::model::cp::{cp_als, CpModel, CpOptions, Tensor};
use crate::model::medulla::{CpTable, MedullaTables};
use rand::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use rayon::prelude::*;
use std::f64::consts::{FRAC_PI_2, PI};
use std::sync::Arc;

/// Scattering events after which a walk is stopped and the photon is scored with its
/// current direction. A walk this long has probability far below the MC noise for every
/// grid point (`tau <= 20`): the mean number of events is about `tau^2 (1 - g) + tau`.
const MAX_EVENTS: usize = 200_000;

/// `v` (increasing) with the midpoint of every neighbouring pair inserted.
fn with_midpoints(v: &[f64]) -> Vec<f64> {
    let mut out = Vec::with_capacity(2 * v.len());
    for (i, &a) in v.iter().enumerate() {
        if i > 0 {
            out.push(0.5 * (v[i - 1] + a));
        }
        out.push(a);
    }
    out
}

/// Table grid: the axes of `C^N` (`tau x g x x x psi`) and `C^M`
/// (`tau x g x theta_i x theta_r`, one tensor per side).
#[derive(Clone, Debug, PartialEq)]
pub struct McGrid {
    /// Optical radius of the medulla, increasing, starting at 0.
    pub tau: Vec<f64>,
    /// Henyey-Greenstein anisotropy, increasing, inside (-1, 1).
    pub g: Vec<f64>,
    /// Entry offset `x` in `[0, 1]` (negative offsets by symmetry `C^N(x,psi)=C^N(-x,-psi)`).
    pub x: Vec<f64>,
    /// Number of uniform `psi` bins over `(-pi, pi]`.
    pub n_psi: usize,
    /// Incident inclination in `[0, pi/2]` (radians; negative by symmetry).
    pub theta_i: Vec<f64>,
    /// Number of uniform `theta_r` bins over `[-pi/2, pi/2]`.
    pub n_theta_r: usize,
}

impl McGrid {
    /// The grid of the shipped tables: 35 `tau` in `[0, 20]` (dense near 0),
    /// 31 `g` in `[-0.9, 0.95]` (dense near the forward peak), 16 `x` in `[0, 1]`
    /// (`sin`-spaced, dense near the rim where the chord changes fast), 180 `psi` bins
    /// (2 deg), 16 `theta_i` in `[0, 90]` deg (6 deg step), 90 `theta_r` bins (2 deg).
    pub fn standard() -> Self {
        // Nodes of the first shipped grid (18 tau, 16 g) with their midpoints inserted:
        // `tables info --on-grid` showed linear interpolation between those nodes adding
        // as much error as the compression itself.
        let tau = with_midpoints(&[
            0.0, 0.05, 0.1, 0.2, 0.35, 0.5, 0.75, 1.0, 1.35, 1.75, 2.25, 3.0, 4.0, 5.5, 7.5, 10.0,
            14.0, 20.0,
        ]);
        let g = with_midpoints(&[
            -0.9, -0.7, -0.5, -0.3, -0.15, 0.0, 0.15, 0.3, 0.45, 0.6, 0.7, 0.8, 0.85, 0.9, 0.93,
            0.95,
        ]);
        let x = (0..16)
            .map(|k| (k as f64 / 15.0 * FRAC_PI_2).sin())
            .collect();
        let theta_i = (0..16).map(|k| (k as f64 * 6.0).to_radians()).collect();
        McGrid {
            tau,
            g,
            x,
            n_psi: 180,
            theta_i,
            n_theta_r: 90,
        }
    }

    /// A tiny grid for tests (a few cells, coarse bins).
    pub fn tiny() -> Self {
        McGrid {
            tau: vec![0.0, 0.5, 2.0],
            g: vec![-0.5, 0.0, 0.8],
            x: vec![0.0, 0.5, 0.9, 1.0],
            n_psi: 24,
            theta_i: vec![0.0, 0.6, FRAC_PI_2],
            n_theta_r: 12,
        }
    }

    /// Number of `C^N` cells.
    pub fn n_cn_cells(&self) -> usize {
        self.tau.len() * self.g.len() * self.x.len()
    }

    /// Number of `C^M` cells (both sides come from one cell).
    pub fn n_cm_cells(&self) -> usize {
        self.tau.len() * self.g.len() * self.theta_i.len()
    }
}

/// Path budget of one cell: `paths` photons, but a cell stops early (after at least
/// `min_paths`) once its walks have used `event_budget` scattering events, so the optically
/// thick cells (hundreds of events per path) do not dominate the run time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct McBudget {
    /// Nominal photon paths per cell.
    pub paths: usize,
    /// Paths a cell runs at least, whatever its event count.
    pub min_paths: usize,
    /// Scattering events after which a cell stops (once it has `min_paths`).
    pub event_budget: u64,
}

impl McBudget {
    /// Budget scaled from a nominal path count.
    pub fn from_paths(paths: usize) -> Self {
        McBudget {
            paths,
            min_paths: (paths / 8).max(1),
            event_budget: paths as u64 * 12,
        }
    }
}

/// SplitMix64 finaliser: decorrelates seeds of neighbouring cells.
fn splitmix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// RNG of one cell: `table` distinguishes C^N (1), C^M (2) and hold-out runs.
pub fn cell_rng(seed: u64, table: u64, cell: u64) -> Xoshiro256PlusPlus {
    let s = splitmix(splitmix(splitmix(seed) ^ table.wrapping_mul(0xA24B_AED4_963E_E407)) ^ cell);
    Xoshiro256PlusPlus::seed_from_u64(s)
}

/// Sample the cosine of the Henyey-Greenstein scattering angle (relative to the forward
/// direction) from a uniform `u` in `[0, 1)`.
pub fn hg_sample_cos(g: f64, u: f64) -> f64 {
    if g.abs() < 1e-4 {
        return 1.0 - 2.0 * u;
    }
    let s = (1.0 - g * g) / (1.0 - g + 2.0 * g * u);
    ((1.0 + g * g - s * s) / (2.0 * g)).clamp(-1.0, 1.0)
}

/// Rotate unit direction `d` by the polar angle with cosine `cos_t` and azimuth `phi`.
fn scatter_dir(d: [f64; 3], cos_t: f64, phi: f64) -> [f64; 3] {
    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    let (sp, cp) = phi.sin_cos();
    let [dx, dy, dz] = d;
    let n = if dz.abs() > 0.999_999 {
        [sin_t * cp, sin_t * sp, dz.signum() * cos_t]
    } else {
        let den = (1.0 - dz * dz).sqrt();
        [
            sin_t * (dx * dz * cp - dy * sp) / den + dx * cos_t,
            sin_t * (dy * dz * cp + dx * sp) / den + dy * cos_t,
            -sin_t * cp * den + dz * cos_t,
        ]
    };
    let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    [n[0] / len, n[1] / len, n[2] / len]
}

/// Distance along `d` from plane position `p` (inside the unit disk) to the cylinder wall.
fn dist_to_wall(p: [f64; 2], d: [f64; 3]) -> f64 {
    let a = d[0] * d[0] + d[1] * d[1];
    if a < 1e-300 {
        return f64::INFINITY;
    }
    let b = p[0] * d[0] + p[1] * d[1];
    let c = (p[0] * p[0] + p[1] * p[1] - 1.0).min(0.0);
    let disc = (b * b - a * c).max(0.0).sqrt();
    // Numerically stable larger root of a t^2 + 2 b t + c = 0.
    if b <= 0.0 {
        (-b + disc) / a
    } else {
        let q = b + disc;
        if q > 0.0 {
            -c / q
        } else {
            0.0
        }
    }
}

/// Depth along a chord of length `chord` of the forced first collision: the exponential of
/// rate `tau` truncated to `[0, chord]`, by inverting its CDF
/// `(1 - exp(-tau t)) / (1 - exp(-tau chord))` at the uniform `u`; uniform in the
/// `tau -> 0` limit.
fn first_collision(tau: f64, chord: f64, u: f64) -> f64 {
    if tau > 0.0 {
        let ps = -(-tau * chord).exp_m1();
        (-(-u * ps).ln_1p() / tau).min(chord)
    } else {
        u * chord
    }
}

/// One photon: forced first collision on the chord, then a free walk until it leaves.
/// Returns the exit direction and the number of scattering events.
fn photon<R: Rng>(rng: &mut R, tau: f64, g: f64, x: f64, theta_i: f64) -> ([f64; 3], u64) {
    let (st, ct) = theta_i.sin_cos();
    let ct = ct.max(1e-9);
    let d0 = [-ct, 0.0, -st];
    let half = (1.0 - x * x).max(0.0).sqrt();
    let chord3 = 2.0 * half / ct;
    let t = first_collision(tau, chord3, rng.random());
    let mut p = [half + t * d0[0], -x];
    let mut d = d0;
    let mut events = 0u64;
    loop {
        // Scatter.
        let cos_t = hg_sample_cos(g, rng.random());
        let phi = 2.0 * PI * rng.random::<f64>();
        d = scatter_dir(d, cos_t, phi);
        events += 1;
        if tau <= 0.0 || events as usize >= MAX_EVENTS {
            return (d, events);
        }
        let wall = dist_to_wall(p, d);
        let s = -(1.0 - rng.random::<f64>()).ln() / tau;
        if s >= wall {
            return (d, events);
        }
        p = [p[0] + s * d[0], p[1] + s * d[1]];
        // Guard against round-off pushing the point outside the disk.
        let r2 = p[0] * p[0] + p[1] * p[1];
        if r2 > 1.0 {
            let r = r2.sqrt();
            p = [p[0] / r, p[1] / r];
        }
    }
}

/// Histograms of one cell split into two halves (even and odd paths) so that the MC
/// noise can be estimated; `w` is the total weight of each half.
#[derive(Clone, Debug, Default)]
pub struct HalfHists {
    /// Weighted histogram of the even paths.
    pub a: Vec<f64>,
    /// Weighted histogram of the odd paths.
    pub b: Vec<f64>,
    /// Total weight of the even paths.
    pub wa: f64,
    /// Total weight of the odd paths.
    pub wb: f64,
    /// Paths traced into the cell.
    pub paths: usize,
    /// Scattering events those paths took.
    pub events: u64,
}

impl HalfHists {
    fn new(n: usize) -> Self {
        HalfHists {
            a: vec![0.0; n],
            b: vec![0.0; n],
            ..Default::default()
        }
    }
    /// Density (per unit of the binned variable, bin width `dx`) from both halves.
    pub fn density(&self, dx: f64) -> Vec<f64> {
        let w = self.wa + self.wb;
        self.a
            .iter()
            .zip(&self.b)
            .map(|(a, b)| if w > 0.0 { (a + b) / (w * dx) } else { 0.0 })
            .collect()
    }
    /// Densities of the two halves separately.
    pub fn half_densities(&self, dx: f64) -> (Vec<f64>, Vec<f64>) {
        let f = |h: &[f64], w: f64| -> Vec<f64> {
            h.iter()
                .map(|v| if w > 0.0 { v / (w * dx) } else { 0.0 })
                .collect()
        };
        (f(&self.a, self.wa), f(&self.b, self.wb))
    }
}

/// Bin of `psi` in `(-pi, pi]` among `n` uniform bins starting at `-pi`.
fn psi_bin(psi: f64, n: usize) -> usize {
    (((psi + PI) / (2.0 * PI) * n as f64) as usize).min(n - 1)
}

/// Bin of `theta` in `[-pi/2, pi/2]` among `n` uniform bins.
fn theta_bin(theta: f64, n: usize) -> usize {
    (((theta + FRAC_PI_2) / PI * n as f64).max(0.0) as usize).min(n - 1)
}

/// Monte Carlo estimate of the `C^N` shape at `(tau, g, x)`: histogram of the exit azimuth
/// `psi` over `n_psi` bins of photons entering at `theta_i = 0` that scattered at least once.
pub fn simulate_cn<R: Rng>(
    rng: &mut R,
    tau: f64,
    g: f64,
    x: f64,
    n_psi: usize,
    budget: McBudget,
) -> HalfHists {
    let mut h = HalfHists::new(n_psi);
    while h.paths < budget.paths && (h.paths < budget.min_paths || h.events < budget.event_budget) {
        let (d, ev) = photon(rng, tau, g, x, 0.0);
        h.events += ev;
        let k = psi_bin(d[1].atan2(d[0]), n_psi);
        if h.paths.is_multiple_of(2) {
            h.a[k] += 1.0;
            h.wa += 1.0;
        } else {
            h.b[k] += 1.0;
            h.wb += 1.0;
        }
        h.paths += 1;
    }
    h
}

/// Monte Carlo estimate of the `C^M` shapes at `(tau, g, theta_i)`: histograms of the exit
/// inclination `theta_r` (`n_theta_r` bins) for the front (`|psi| < pi/2`) and back
/// (`|psi| >= pi/2`) sides, for a collimated beam (entry offset uniform over `[-1, 1]`,
/// sampled stratified over `[0, 1]` by the `x -> -x` symmetry that leaves the sides
/// unchanged), each photon weighted by its forced-collision scattering probability.
pub fn simulate_cm<R: Rng>(
    rng: &mut R,
    tau: f64,
    g: f64,
    theta_i: f64,
    n_theta_r: usize,
    budget: McBudget,
) -> (HalfHists, HalfHists) {
    let mut front = HalfHists::new(n_theta_r);
    let mut back = HalfHists::new(n_theta_r);
    let ct = theta_i.cos().max(1e-9);
    // Stratify x over `strata` equal slices of [0, 1].
    let strata = 64usize;
    let mut n = 0usize;
    let mut events = 0u64;
    while n < budget.paths && (n < budget.min_paths || events < budget.event_budget) {
        let x = ((n % strata) as f64 + rng.random::<f64>()) / strata as f64;
        let half = (1.0 - x * x).max(0.0).sqrt();
        let w = if tau > 0.0 {
            -(-tau * 2.0 * half / ct).exp_m1()
        } else {
            half
        };
        let (d, ev) = photon(rng, tau, g, x, theta_i);
        events += ev;
        let psi = d[1].atan2(d[0]);
        let th = d[2].clamp(-1.0, 1.0).asin();
        let k = theta_bin(th, n_theta_r);
        let h = if psi.abs() < FRAC_PI_2 {
            &mut front
        } else {
            &mut back
        };
        if (n / strata).is_multiple_of(2) {
            h.a[k] += w;
            h.wa += w;
        } else {
            h.b[k] += w;
            h.wb += w;
        }
        n += 1;
    }
    for h in [&mut front, &mut back] {
        h.paths = n;
        h.events = events;
    }
    (front, back)
}

/// Densities of a `C^M` side; a side that received no weight at all falls back to the
/// isotropic cos-law density `cos(theta_r) / 2` (integrates to 1 over `[-pi/2, pi/2]`).
pub fn cm_density(h: &HalfHists, n_theta_r: usize) -> Vec<f64> {
    let dt = PI / n_theta_r as f64;
    if h.wa + h.wb > 0.0 {
        h.density(dt)
    } else {
        (0..n_theta_r)
            .map(|k| {
                // Bin average of cos/2 over the bin.
                let a = -FRAC_PI_2 + k as f64 * dt;
                ((a + dt).sin() - a.sin()) / (2.0 * dt)
            })
            .collect()
    }
}

/// Raw (uncompressed) tables: `cn[((it * ng + ig) * nx + ix) * n_psi + k]` is the `C^N`
/// shape density per radian; `cm[side][((it * ng + ig) * nti + ii) * n_theta_r + k]` the
/// `C^M` density per radian (side 0 front, 1 back).
#[derive(Clone, Debug)]
pub struct RawTables {
    /// The `(tau, g, x)` and `(tau, g, theta_i)` grid the tables are on.
    pub grid: McGrid,
    /// The `C^N` shape densities, per radian of exit azimuth `psi`.
    pub cn: Vec<f64>,
    /// The `C^M` densities per radian of `theta_r`, front (0) and back (1) side.
    pub cm: [Vec<f64>; 2],
    /// Scattering events over all cells.
    pub total_events: u64,
    /// Photon paths over all cells.
    pub total_paths: u64,
    /// Estimated relative L2 Monte Carlo noise of each raw tensor (C^N, C^M front,
    /// C^M back) from the even/odd half split: the floor under any CP error against it.
    pub noise_rel: [f64; 3],
}

/// Squared noise of a cell's full density estimate: `sum_k ((a_k - b_k) / 2)^2` from the
/// two half densities (each half has twice the variance of the full estimate).
fn half_noise2(h: &HalfHists, dx: f64) -> f64 {
    if h.wa <= 0.0 || h.wb <= 0.0 {
        return 0.0;
    }
    let (a, b) = h.half_densities(dx);
    a.iter()
        .zip(&b)
        .map(|(x, y)| 0.25 * (x - y) * (x - y))
        .sum()
}

/// Run the Monte Carlo for the whole grid. `progress` is called once per finished cell
/// (from worker threads).
pub fn simulate_tables(
    grid: &McGrid,
    seed: u64,
    budget: McBudget,
    progress: &(dyn Fn() + Sync),
) -> RawTables {
    let (nt, ng, nx, nti) = (
        grid.tau.len(),
        grid.g.len(),
        grid.x.len(),
        grid.theta_i.len(),
    );
    let dpsi = 2.0 * PI / grid.n_psi as f64;
    let cn_cells: Vec<(Vec<f64>, f64, u64, u64)> = (0..nt * ng * nx)
        .into_par_iter()
        .map(|c| {
            let (it, ig, ix) = (c / (ng * nx), (c / nx) % ng, c % nx);
            let mut rng = cell_rng(seed, 1, c as u64);
            let h = simulate_cn(
                &mut rng,
                grid.tau[it],
                grid.g[ig],
                grid.x[ix],
                grid.n_psi,
                budget,
            );
            progress();
            (
                h.density(dpsi),
                half_noise2(&h, dpsi),
                h.events,
                h.paths as u64,
            )
        })
        .collect();
    #[allow(clippy::type_complexity)]
    let cm_cells: Vec<(Vec<f64>, Vec<f64>, [f64; 2], u64, u64)> = (0..nt * ng * nti)
        .into_par_iter()
        .map(|c| {
            let (it, ig, ii) = (c / (ng * nti), (c / nti) % ng, c % nti);
            let mut rng = cell_rng(seed, 2, c as u64);
            let (f, b) = simulate_cm(
                &mut rng,
                grid.tau[it],
                grid.g[ig],
                grid.theta_i[ii],
                grid.n_theta_r,
                budget,
            );
            progress();
            let dt = PI / grid.n_theta_r as f64;
            (
                cm_density(&f, grid.n_theta_r),
                cm_density(&b, grid.n_theta_r),
                [half_noise2(&f, dt), half_noise2(&b, dt)],
                f.events,
                f.paths as u64,
            )
        })
        .collect();
    let mut total_events = 0;
    let mut total_paths = 0;
    let mut cn = Vec::with_capacity(nt * ng * nx * grid.n_psi);
    let mut noise2 = [0.0; 3];
    for (d, n2, e, p) in cn_cells {
        cn.extend(d);
        noise2[0] += n2;
        total_events += e;
        total_paths += p;
    }
    let mut front = Vec::with_capacity(nt * ng * nti * grid.n_theta_r);
    let mut back = Vec::with_capacity(nt * ng * nti * grid.n_theta_r);
    for (f, b, n2, e, p) in cm_cells {
        front.extend(f);
        back.extend(b);
        noise2[1] += n2[0];
        noise2[2] += n2[1];
        total_events += e;
        total_paths += p;
    }
    let rel = |n2: f64, v: &[f64]| (n2 / v.iter().map(|x| x * x).sum::<f64>().max(1e-300)).sqrt();
    let noise_rel = [
        rel(noise2[0], &cn),
        rel(noise2[1], &front),
        rel(noise2[2], &back),
    ];
    RawTables {
        grid: grid.clone(),
        noise_rel,
        cn,
        cm: [front, back],
        total_events,
        total_paths,
    }
}

/// Options of [`build_tables`].
#[derive(Clone, Debug)]
pub struct BuildOptions {
    /// The table grid.
    pub grid: McGrid,
    /// Seed of every cell's random stream.
    pub seed: u64,
    /// Photon paths per cell.
    pub budget: McBudget,
    /// Ranks tried for each tensor, increasing; the smallest whose relative L2 error is at
    /// most `target_error` is kept (else the last one).
    pub ranks: Vec<usize>,
    /// Relative L2 error of the CP fit at which a rank is good enough.
    pub target_error: f64,
    /// Most ALS sweeps of each CP fit.
    pub max_iter: usize,
}

impl BuildOptions {
    /// The shipped configuration for a given seed and nominal paths per cell.
    pub fn standard(seed: u64, paths: usize) -> Self {
        BuildOptions {
            grid: McGrid::standard(),
            seed,
            budget: McBudget::from_paths(paths),
            ranks: vec![16, 32, 48],
            target_error: 0.03,
            max_iter: 150,
        }
    }
}

/// One CP fit tried during a build.
#[derive(Clone, Debug)]
pub struct RankTrial {
    /// `C^N`, `C^M front` or `C^M back`.
    pub table: &'static str,
    /// CP rank tried.
    pub rank: usize,
    /// Relative L2 error of the fit against the raw tensor.
    pub rel_error: f64,
    /// ALS sweeps it took.
    pub iterations: usize,
}

/// Everything a build produced besides the tables themselves.
#[derive(Clone, Debug)]
pub struct BuildReport {
    /// Every CP fit tried, in order.
    pub trials: Vec<RankTrial>,
    /// Rank kept for `C^N`, `C^M` front and `C^M` back.
    pub chosen: [usize; 3],
    /// Photon paths over all cells.
    pub total_paths: u64,
    /// Scattering events over all cells.
    pub total_events: u64,
}

fn cp_fit(
    name: &'static str,
    tensor: &Tensor,
    opts: &BuildOptions,
    trials: &mut Vec<RankTrial>,
    log: &mut dyn FnMut(&RankTrial),
) -> CpModel {
    let mut best: Option<CpModel> = None;
    for &rank in &opts.ranks {
        let (m, hist) = cp_als(
            tensor,
            &CpOptions {
                rank,
                max_iter: opts.max_iter,
                tol: 1e-7,
                seed: opts.seed ^ rank as u64,
            },
        );
        let trial = RankTrial {
            table: name,
            rank,
            rel_error: m.rel_error(tensor),
            iterations: hist.len(),
        };
        log(&trial);
        let done = trial.rel_error <= opts.target_error;
        trials.push(trial);
        best = Some(m);
        if done {
            break;
        }
    }
    best.expect("at least one rank is tried")
}

fn to_cp_table(m: &CpModel, axes: [Vec<f64>; 4]) -> CpTable {
    let f = m.folded_factors(0);
    CpTable {
        rank: m.rank,
        axes,
        factors: [f[0].clone(), f[1].clone(), f[2].clone(), f[3].clone()],
    }
}

/// Bin centres of `n` uniform bins on `[lo, hi]`.
pub fn bin_centres(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    let d = (hi - lo) / n as f64;
    (0..n).map(|k| lo + (k as f64 + 0.5) * d).collect()
}

/// Raw tables -> CP-compressed [`MedullaTables`] (factors rounded to f32 as in the file).
pub fn compress_tables(
    raw: &RawTables,
    opts: &BuildOptions,
    log: &mut dyn FnMut(&RankTrial),
) -> (MedullaTables, Vec<RankTrial>, [usize; 3]) {
    let gr = &raw.grid;
    let (nt, ng) = (gr.tau.len(), gr.g.len());
    let mut trials = Vec::new();
    let cn_t = Tensor::new(vec![nt, ng, gr.x.len(), gr.n_psi], raw.cn.clone());
    let cn = cp_fit("C^N", &cn_t, opts, &mut trials, log);
    let dims_m = vec![nt, ng, gr.theta_i.len(), gr.n_theta_r];
    let front = cp_fit(
        "C^M front",
        &Tensor::new(dims_m.clone(), raw.cm[0].clone()),
        opts,
        &mut trials,
        log,
    );
    let back = cp_fit(
        "C^M back",
        &Tensor::new(dims_m, raw.cm[1].clone()),
        opts,
        &mut trials,
        log,
    );
    let psi = bin_centres(-PI, PI, gr.n_psi);
    let tr = bin_centres(-FRAC_PI_2, FRAC_PI_2, gr.n_theta_r);
    let axes_n = [gr.tau.clone(), gr.g.clone(), gr.x.clone(), psi];
    let axes_m = [gr.tau.clone(), gr.g.clone(), gr.theta_i.clone(), tr];
    let chosen = [cn.rank, front.rank, back.rank];
    let tables = MedullaTables {
        cn: Arc::new(to_cp_table(&cn, axes_n)),
        cm: [
            Arc::new(to_cp_table(&front, axes_m.clone())),
            Arc::new(to_cp_table(&back, axes_m)),
        ],
        seed: opts.seed,
        paths: opts.budget.paths as u64,
    }
    .rounded();
    (tables, trials, chosen)
}

/// Monte Carlo + CP-ALS: the whole `furfit tables build`. Deterministic for given options.
pub fn build_tables(
    opts: &BuildOptions,
    progress: &(dyn Fn() + Sync),
    log: &mut dyn FnMut(&RankTrial),
) -> (MedullaTables, BuildReport) {
    let raw = simulate_tables(&opts.grid, opts.seed, opts.budget, progress);
    let (tables, trials, chosen) = compress_tables(&raw, opts, log);
    (
        tables,
        BuildReport {
            trials,
            chosen,
            total_paths: raw.total_paths,
            total_events: raw.total_events,
        },
    )
}

/// One hold-out comparison of the compressed tables against a fresh Monte Carlo estimate.
#[derive(Clone, Debug)]
pub struct HoldoutPoint {
    /// "C^N", "C^M front" or "C^M back".
    pub table: &'static str,
    /// Medulla optical radius `tau` of the cell.
    pub tau: f64,
    /// Henyey-Greenstein anisotropy of the cell.
    pub g: f64,
    /// `x` for C^N, `theta_i` (radians) for C^M.
    pub coord: f64,
    /// `||table - mc|| / ||mc||` over the bins of the normalised shape.
    pub rel_l2: f64,
    /// `max |table - mc| / max mc`.
    pub max_rel: f64,
    /// Estimated relative L2 noise of the fresh estimate: `||half_a - half_b|| / 2 / ||mc||`
    /// (the two halves each have twice the variance of the full estimate).
    pub noise_l2: f64,
}

fn compare(table: &[f64], h: &HalfHists, dx: f64) -> (f64, f64, f64) {
    let mc = h.density(dx);
    let (a, b) = h.half_densities(dx);
    let norm = mc.iter().map(|v| v * v).sum::<f64>().sqrt().max(1e-300);
    let maxv = mc.iter().cloned().fold(0.0, f64::max).max(1e-300);
    let l2 = table
        .iter()
        .zip(&mc)
        .map(|(t, m)| (t - m) * (t - m))
        .sum::<f64>()
        .sqrt();
    let mx = table
        .iter()
        .zip(&mc)
        .map(|(t, m)| (t - m).abs())
        .fold(0.0, f64::max);
    let noise = a
        .iter()
        .zip(&b)
        .map(|(x, y)| (x - y) * (x - y))
        .sum::<f64>()
        .sqrt()
        / 2.0;
    (l2 / norm, mx / maxv, noise / norm)
}

/// Compare `tables` with fresh Monte Carlo estimates at `n` random off-grid points per
/// table (RNG `seed`, `paths` photons each): `tau = tau_max u^2` (denser near 0),
/// `g` uniform over the axis, `x` uniform in `[-1, 1]`, `theta_i` uniform in
/// `[-pi/2, pi/2]`. The MC histograms use the table's own bins.
///
/// With `on_grid`, each random coordinate is moved to its nearest table node (the sign of
/// `x` and `theta_i` kept): there the tables interpolate nothing, so the error is the CP
/// compression plus the build's own Monte Carlo noise, and the difference to the
/// off-grid error is what interpolation between nodes adds.
pub fn holdout(
    tables: &MedullaTables,
    n: usize,
    seed: u64,
    paths: usize,
    on_grid: bool,
) -> Vec<HoldoutPoint> {
    let tn = &*tables.cn;
    let tm = &*tables.cm[0];
    let tau_max = *tn.axes[0].last().unwrap();
    let (g_lo, g_hi) = (tn.axes[1][0], *tn.axes[1].last().unwrap());
    let n_psi = tn.axes[3].len();
    let n_tr = tm.axes[3].len();
    let budget = McBudget {
        paths,
        min_paths: paths,
        event_budget: u64::MAX,
    };
    let mut pts: Vec<HoldoutPoint> = (0..2 * n)
        .into_par_iter()
        .flat_map_iter(|c| {
            let mut rng = cell_rng(seed, 3, c as u64);
            let snap = |axis: &[f64], v: f64| {
                if !on_grid {
                    return v;
                }
                let a = v.abs();
                let near = axis
                    .iter()
                    .copied()
                    .min_by(|p, q| (p - a).abs().total_cmp(&(q - a).abs()))
                    .unwrap_or(a);
                near.copysign(v)
            };
            let u: f64 = rng.random();
            // At tau = 0 nothing scatters (C^N = 0), so the shape cannot be compared that
            // way: the on-grid points use the smallest positive node instead.
            let tau =
                snap(&tn.axes[0], tau_max * u * u).max(if on_grid { tn.axes[0][1] } else { 0.0 });
            let g_raw = g_lo + (g_hi - g_lo) * rng.random::<f64>();
            // g may be negative: snap to the nearest node itself, not by magnitude.
            let g = if on_grid {
                tn.axes[1]
                    .iter()
                    .copied()
                    .min_by(|p, q| (p - g_raw).abs().total_cmp(&(q - g_raw).abs()))
                    .unwrap_or(g_raw)
            } else {
                g_raw
            };
            let slice = tables.slice(tau, g);
            let mut out = Vec::new();
            if c < n {
                let x = snap(&tn.axes[2], 2.0 * rng.random::<f64>() - 1.0);
                let h = simulate_cn(&mut rng, tau, g, x, n_psi, budget);
                let ps = crate::model::medulla::scatter_probability(tau, x);
                let t: Vec<f64> = bin_centres(-PI, PI, n_psi)
                    .iter()
                    .map(|&psi| if ps > 0.0 { slice.cn(x, psi) / ps } else { 0.0 })
                    .collect();
                let (rel_l2, max_rel, noise_l2) = compare(&t, &h, 2.0 * PI / n_psi as f64);
                out.push(HoldoutPoint {
                    table: "C^N",
                    tau,
                    g,
                    coord: x,
                    rel_l2,
                    max_rel,
                    noise_l2,
                });
            } else {
                let ti = snap(&tm.axes[2], PI * (rng.random::<f64>() - 0.5));
                let (f, b) = simulate_cm(&mut rng, tau, g, ti, n_tr, budget);
                for (name, side, h) in [
                    ("C^M front", crate::model::medulla::Side::Front, f),
                    ("C^M back", crate::model::medulla::Side::Back, b),
                ] {
                    let t: Vec<f64> = bin_centres(-FRAC_PI_2, FRAC_PI_2, n_tr)
                        .iter()
                        .map(|&tr| slice.cm(ti, tr, side))
                        .collect();
                    let (rel_l2, max_rel, noise_l2) = compare(&t, &h, PI / n_tr as f64);
                    out.push(HoldoutPoint {
                        table: name,
                        tau,
                        g,
                        coord: ti,
                        rel_l2,
                        max_rel,
                        noise_l2,
                    });
                }
            }
            out
        })
        .collect();
    pts.sort_by(|a, b| a.table.cmp(b.table));
    pts
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hg_mean_cosine_is_g() {
        // Mean of cos over 200k samples; the std dev of cos is <= 1 so the standard error
        // is <= 1/sqrt(200k) = 0.0022; 0.01 is > 4 sigma.
        let mut rng = cell_rng(1, 9, 0);
        for g in [-0.7, 0.0, 0.4, 0.9] {
            let n = 200_000;
            let m: f64 = (0..n).map(|_| hg_sample_cos(g, rng.random())).sum::<f64>() / n as f64;
            assert!((m - g).abs() < 0.01, "g {g}: mean cos {m}");
        }
    }

    #[test]
    fn tiny_tau_single_scatter_is_isotropic_azimuth_for_g0() {
        // tau -> 0, g = 0, x = 0: a single isotropic scattering on the diameter. The exit
        // azimuth of an isotropic 3-D direction is uniform, so the density is 1/(2 pi) per
        // radian in every one of 12 bins. With 120k photons each bin holds ~10k, relative
        // std dev 1%; 5% is a 5-sigma bound.
        let mut rng = cell_rng(3, 9, 0);
        let h = simulate_cn(&mut rng, 1e-6, 0.0, 0.0, 12, McBudget::from_paths(120_000));
        let d = h.density(2.0 * PI / 12.0);
        for v in d {
            assert!((v * 2.0 * PI - 1.0).abs() < 0.05, "{v}");
        }
    }

    #[test]
    fn forward_peak_for_strong_g() {
        // g = 0.95, thin medulla: photons keep going forward, so most density sits near
        // |psi| = pi (the last and first bins) and very little straight back.
        let mut rng = cell_rng(4, 9, 0);
        let h = simulate_cn(&mut rng, 0.05, 0.95, 0.0, 36, McBudget::from_paths(20_000));
        let d = h.density(2.0 * PI / 36.0);
        assert!(d[0] + d[35] > 20.0 * (d[17] + d[18]));
    }

    #[test]
    fn scattered_weight_matches_analytic_in_thin_limit() {
        // Analog (non-forced) check of the scattered fraction: count photons whose first
        // free flight ends inside the chord, for tau = 0.01. Probability
        // p = 1 - exp(-2 tau sqrt(1 - x^2)) ~ 0.0173 at x = 0.3; with 400k trials the
        // binomial std error is sqrt(p/n) / p = 1.2% relative; allow 5% (4 sigma).
        let mut rng = cell_rng(5, 9, 0);
        let (tau, x) = (0.01f64, 0.3f64);
        let chord = 2.0 * (1.0 - x * x).sqrt();
        let n = 400_000;
        let hits = (0..n)
            .filter(|_| -(1.0 - rng.random::<f64>()).ln() / tau < chord)
            .count();
        let p = 1.0 - (-tau * chord).exp();
        let est = hits as f64 / n as f64;
        assert!((est / p - 1.0).abs() < 0.05, "{est} vs {p}");
    }

    #[test]
    fn cm_slices_integrate_to_one() {
        let mut rng = cell_rng(6, 9, 0);
        let (f, b) = simulate_cm(&mut rng, 1.0, 0.3, 0.5, 30, McBudget::from_paths(4000));
        for h in [f, b] {
            let d = cm_density(&h, 30);
            let s: f64 = d.iter().sum::<f64>() * PI / 30.0;
            // Exact up to round-off: density = bin weight / (total weight * width).
            assert!((s - 1.0).abs() < 1e-9, "{s}");
        }
    }

    #[test]
    fn wall_distance() {
        assert!((dist_to_wall([0.0, 0.0], [1.0, 0.0, 0.0]) - 1.0).abs() < 1e-12);
        assert!((dist_to_wall([0.5, 0.0], [-1.0, 0.0, 0.0]) - 1.5).abs() < 1e-12);
        // A tilted direction travels 1/cos further.
        let c = 0.6f64;
        let s = (1.0 - c * c).sqrt();
        assert!((dist_to_wall([0.0, 0.0], [c, 0.0, s]) - 1.0 / c).abs() < 1e-12);
        assert!(dist_to_wall([1.0, 0.0], [1.0, 0.0, 0.0]).abs() < 1e-12);
    }

    /// From any point inside the disk, in any direction with a plane component, the wall
    /// distance lands on the wall (`|p + t d_xy| = 1`) ahead of the photon, in both root
    /// branches (moving outward, `b > 0`, and inward). 1e-12: a few roundings of O(1)
    /// terms.
    #[test]
    fn wall_distance_lands_on_the_wall_from_anywhere_inside() {
        for ip in 0..7 {
            for ia in 0..12 {
                let (r, a) = (ip as f64 / 7.0, ia as f64 * 0.5 + 0.1);
                let p = [r * a.cos(), r * a.sin()];
                for id in 0..16 {
                    let (b, dz) = (id as f64 * 0.4 + 0.05, [0.0, 0.6, -0.95][id % 3]);
                    let s = (1.0f64 - dz * dz).sqrt();
                    let d = [s * b.cos(), s * b.sin(), dz];
                    let t = dist_to_wall(p, d);
                    let e = [p[0] + t * d[0], p[1] + t * d[1]];
                    let r2 = e[0] * e[0] + e[1] * e[1];
                    assert!(t >= 0.0, "p {p:?} d {d:?}: t {t}");
                    assert!(
                        (r2 - 1.0).abs() < 1e-12,
                        "p {p:?} d {d:?}: |p + t d|^2 = {r2}"
                    );
                }
            }
        }
    }

    /// A scattering event turns the direction by exactly the sampled polar angle (unit
    /// result, `n . d = cos_t`), and azimuths half a turn apart are mirror images about
    /// `d` (`n(phi) + n(phi + pi) = 2 cos_t d`), so the azimuth runs around the cone. Also
    /// at the poles, where the frame changes. 1e-12: round-off of unit-length products.
    #[test]
    fn scatter_dir_turns_by_the_sampled_angle_around_a_cone() {
        let unit = |v: [f64; 3]| {
            let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            [v[0] / l, v[1] / l, v[2] / l]
        };
        let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        let dirs = [
            [-1.0, 0.0, 0.0],
            unit([0.3, -0.5, 0.8]),
            unit([-0.2, 0.6, -0.8]),
            unit([0.0, 1.0, -0.1]),
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
        ];
        for d in dirs {
            for cos_t in [-0.9, -0.2, 0.0, 0.5, 0.97] {
                for k in 0..8 {
                    let phi = k as f64 * 0.785 + 0.2;
                    let n = scatter_dir(d, cos_t, phi);
                    let m = scatter_dir(d, cos_t, phi + PI);
                    assert!((dot(n, n) - 1.0).abs() < 1e-12, "{d:?}: not unit");
                    assert!(
                        (dot(n, d) - cos_t).abs() < 1e-12,
                        "{d:?} {cos_t}: cos {}",
                        dot(n, d)
                    );
                    for c in 0..3 {
                        let mirror = n[c] + m[c] - 2.0 * cos_t * d[c];
                        assert!(mirror.abs() < 1e-12, "{d:?} {cos_t} {phi}: {mirror}");
                    }
                }
            }
        }
    }

    /// The forced first collision follows the truncated exponential: its CDF at the
    /// sampled depth gives back `u`, from a thin to an optically very thick chord. 1e-12:
    /// `exp_m1` / `ln_1p` keep relative round-off at a few ulps even for `tau t << 1`.
    #[test]
    fn first_collision_inverts_the_truncated_exponential() {
        for (tau, chord) in [(1e-3, 2.0), (0.5, 1.2), (5.0, 2.0), (300.0, 0.4)] {
            for k in 0..20 {
                let u = k as f64 / 20.0 + 0.01;
                let t = first_collision(tau, chord, u);
                assert!((0.0..=chord).contains(&t), "tau {tau}: t {t}");
                let cdf = (-tau * t).exp_m1() / (-tau * chord).exp_m1();
                assert!((cdf - u).abs() < 1e-12, "tau {tau} u {u}: cdf {cdf}");
            }
        }
        // tau = 0: uniform along the chord.
        assert_eq!(first_collision(0.0, 1.5, 0.25), 0.375);
    }

    /// Every C^M path carries its forced-collision probability `P_s = 1 - exp(-tau L)`,
    /// `L = 2 sqrt(1 - x^2) / cos theta_i` the 3-D chord at offset `x`, with `x` stratified
    /// uniform over `[0, 1]`: the mean weight per path is the collimated beam's scattered
    /// fraction `int_0^1 P_s(x) dx` (here at a slant, where the 3-D chord is 1.9x the
    /// plane one). Reference: midpoint rule in `x = sin a` (smooth integrand, 1e5 nodes,
    /// error ~1e-10). Stratified over 64 slices, 6400 paths came within 1.1e-5 relative
    /// at this seed; 2e-3 leaves room for any seed, and a chord without its
    /// `1 / cos theta_i` is 28% off.
    #[test]
    fn cm_mean_weight_is_the_slanted_beams_scattered_fraction() {
        let (tau, theta_i) = (0.5f64, 1.0f64);
        let mut rng = cell_rng(7, 9, 0);
        let budget = McBudget {
            paths: 6400,
            min_paths: 6400,
            event_budget: u64::MAX,
        };
        let (f, b) = simulate_cm(&mut rng, tau, 0.3, theta_i, 18, budget);
        let mean = (f.wa + f.wb + b.wa + b.wb) / f.paths as f64;
        let n = 100_000;
        let exact: f64 = (0..n)
            .map(|k| {
                let a = (k as f64 + 0.5) / n as f64 * FRAC_PI_2;
                let l = 2.0 * a.cos() / theta_i.cos();
                -(-tau * l).exp_m1() * a.cos()
            })
            .sum::<f64>()
            * FRAC_PI_2
            / n as f64;
        assert!((mean / exact - 1.0).abs() < 2e-3, "{mean} vs {exact}");
    }

    /// A thin medulla scattering strongly forward sends a slanted beam on, around the
    /// plane direction it came in (the back side, `|psi| >= pi/2`) and along the specular
    /// cone `theta_r = -theta_i`: far more weight on the back side than the front, and the
    /// back density peaks in the bin holding `-theta_i` (or a neighbour: the HG peak at
    /// g = 0.95 deflects by 18 deg on average, the bins are 4 deg).
    #[test]
    fn cm_forward_scattering_leaves_on_the_back_side_along_the_cone() {
        let (theta_i, nb) = (0.6f64, 45usize);
        let mut rng = cell_rng(8, 9, 0);
        let (f, b) = simulate_cm(
            &mut rng,
            0.05,
            0.95,
            theta_i,
            nb,
            McBudget::from_paths(20_000),
        );
        let (wf, wb) = (f.wa + f.wb, b.wa + b.wb);
        assert!(wb > 10.0 * wf, "back {wb} vs front {wf}");
        let d = cm_density(&b, nb);
        let k = (0..nb).max_by(|&i, &j| d[i].total_cmp(&d[j])).unwrap();
        // Bin k spans theta_r in [-pi/2 + k pi/nb, ...): computed here, not by theta_bin,
        // so the test also checks the binning's orientation.
        let k_cone = ((FRAC_PI_2 - theta_i) / PI * nb as f64) as usize;
        assert!(k.abs_diff(k_cone) <= 1, "peak bin {k}, cone bin {k_cone}");
    }

    /// Optically thick and isotropic, light diffuses back out near where it entered. The
    /// entry point at offset `x` has its outward normal at `psi = -asin x` (the side of
    /// the paper's R lobe for positive `h`), so the MC density there is well above its
    /// mirror image `+asin x` and far above straight on. The same check as the shipped
    /// tables' (`medulla::tests`), here on the walk itself with multiple scattering.
    /// 8000 paths over 36 bins: ~220 per bin, 7% noise, against factors of 1.5 and 3.
    #[test]
    fn thick_medulla_walk_reflects_around_the_entry_normal() {
        let (x, nb) = (0.7f64, 36usize);
        let mut rng = cell_rng(9, 9, 0);
        let budget = McBudget {
            paths: 8000,
            min_paths: 8000,
            event_budget: u64::MAX,
        };
        let h = simulate_cn(&mut rng, 10.0, 0.0, x, nb, budget);
        let d = h.density(2.0 * PI / nb as f64);
        let at = |psi: f64| d[psi_bin(psi, nb)];
        let (n, m, fwd) = (at(-x.asin()), at(x.asin()), at(PI));
        assert!(n > 1.5 * m, "{n} vs mirror {m}");
        assert!(n > 3.0 * fwd, "{n} vs forward {fwd}");
    }
}
