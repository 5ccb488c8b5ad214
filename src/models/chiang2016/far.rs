//! The far field of Chiang 2016: the near field averaged over the camera ray's offset,
//! `N̄_p(theta_o, phi) = 1/2 integral_{-1}^{1} A_p(h) N_p(phi; h) dh`, on a goniometer
//! grid.
//!
//! In `gamma = asin(h)` the integrand `1/2 A_p cos(gamma) N_p(phi - Phi(p, gamma))` is
//! smooth everywhere, the TRT caustic included (it is a caustic only in `Phi`). Each slice
//! of one `theta_o` lays Gauss-Legendre panels over `gamma` in [0, pi/2], each spanning at
//! most [`PANEL_PHI`] logistic scales of `Phi` and [`PANEL_GAMMA`] radians of `gamma`, and
//! keeps the nodes `(Phi_j, w_j)` of both halves (the integrand is even under
//! `h -> -h, phi -> -phi`). Any `phi` then costs one logistic per node within
//! [`WINDOW`] scales of it (binary search on the sorted `Phi_j`). The contract is that of
//! the fur model's tolerance mode: within 1e-4 of each lobe's peak of the adaptive
//! Gauss-Kronrod reference ([`near_quadrature`]); measured 1e-13 for narrow lobes and
//! 1.1e-5 at `beta_n = 1`, where the trimmed logistic's kink at `|x| = pi` (it is wrapped,
//! not periodic in its derivative) falls inside a panel (tests).

use super::lobes::{self, Slice, P_MAX};
use crate::model::quadrature::{adaptive_gk, GaussLegendre};
use crate::models::{Factored, SlicePlan as Plan};
use std::f64::consts::{FRAC_PI_2, PI};

/// Largest change of `Phi` over one panel, in logistic scales `s`.
pub const PANEL_PHI: f64 = 1.5;
/// Largest panel in `gamma` (radians): resolves `A_p`'s variation when `s` is wide.
pub const PANEL_GAMMA: f64 = 0.2;
/// Gauss-Legendre points per panel.
pub const PANEL_NODES: usize = 8;
/// Nodes farther than this many scales from `phi` are skipped: the logistic's tail there
/// is below `e^-28 = 7e-13` of its peak.
pub const WINDOW: f64 = 28.0;

/// The quadrature nodes of one `theta_o` slice: per lobe p < 3, `(Phi_j, w_j)` sorted by
/// `Phi_j` in [-pi, pi), with `w_j = 1/2 A_p cos(gamma_j) dgamma_j`; and the residual's
/// `N̄_3 = 1/(2 pi) 1/2 integral A_3 dh`.
#[derive(Clone, Debug)]
pub struct SliceNodes {
    lobes: [Vec<(f64, f64)>; P_MAX],
    residual: f64,
    s: f64,
    norm: f64,
}

impl SliceNodes {
    /// The nodes of `slice` for the logistic scale `s`.
    pub fn new(slice: &Slice, s: f64) -> SliceNodes {
        let gl = GaussLegendre::cached(PANEL_NODES);
        let mut residual = 0.0;
        let lobes = std::array::from_fn(|p| {
            let mut nodes = Vec::new();
            for (a, b) in panels(slice, p, s) {
                let (c, r) = (0.5 * (a + b), 0.5 * (b - a));
                for (x, w) in gl.nodes.iter().zip(&gl.weights) {
                    let g = c + r * x;
                    let att = slice.attenuation(g);
                    // 1/2 dh over h in [-1, 1], the half [0, 1] counted for both signs.
                    let wg = 0.5 * w * r * g.cos();
                    if p == 0 {
                        residual += 2.0 * wg * att[P_MAX];
                    }
                    let phi = lobes::wrap(slice.phi(p, g));
                    nodes.push((phi, wg * att[p]));
                    nodes.push((lobes::wrap(-phi), wg * att[p]));
                }
            }
            nodes.sort_by(|x, y| x.0.total_cmp(&y.0));
            nodes
        });
        SliceNodes {
            lobes,
            residual: residual / (2.0 * PI),
            s,
            norm: lobes::trimmed_norm(s),
        }
    }

    /// `N̄_p(phi)` of the four lobes (the residual's is constant in `phi`).
    pub fn eval(&self, phi: f64) -> [f64; P_MAX + 1] {
        let mut out = [0.0; P_MAX + 1];
        let w = (WINDOW * self.s).min(PI);
        for (p, nodes) in self.lobes.iter().enumerate() {
            let mut sum = 0.0;
            let mut add = |lo: f64, hi: f64| {
                let i0 = nodes.partition_point(|n| n.0 < lo);
                let i1 = nodes.partition_point(|n| n.0 < hi);
                for &(ph, wt) in &nodes[i0..i1] {
                    sum += wt * lobes::logistic(lobes::wrap(phi - ph), self.s);
                }
            };
            if w >= PI {
                add(-PI, PI);
            } else {
                let (lo, hi) = (lobes::wrap(phi - w), lobes::wrap(phi + w));
                if lo <= hi {
                    add(lo, hi);
                } else {
                    add(lo, PI);
                    add(-PI, hi);
                }
            }
            out[p] = sum / self.norm;
        }
        out[P_MAX] = self.residual;
        out
    }
}

/// Panels `[a, b]` over `gamma` in [0, pi/2] for lobe `p`: each step the largest that
/// keeps `|Phi(b) - Phi(a)| <= PANEL_PHI s` (first guessed from `Phi'` and `Phi''`, so a
/// caustic, where `Phi' = 0`, gets steps of `sqrt(2 PANEL_PHI s / |Phi''|)`) and
/// `b - a <= PANEL_GAMMA`.
fn panels(slice: &Slice, p: usize, s: f64) -> Vec<(f64, f64)> {
    let target = PANEL_PHI * s;
    let mut out = Vec::new();
    let mut a = 0.0f64;
    // Floor of a step: rounding of gamma near pi/2 (reached only for s below ~1e-13).
    let min_step = 1e-12;
    while a < FRAC_PI_2 {
        let d1 = slice.dphi(p, a).abs();
        let d2 = slice.ddphi(p, a).abs();
        let mut step = PANEL_GAMMA
            .min(target / d1.max(1e-300))
            .min((2.0 * target / d2.max(1e-300)).sqrt())
            .min(FRAC_PI_2 - a);
        let pa = slice.phi(p, a);
        loop {
            let b = (a + step).min(FRAC_PI_2);
            let dphi = (slice.phi(p, b) - pa).abs();
            if dphi <= target * 1.000001 || step <= min_step {
                break;
            }
            step *= (0.9 * target / dphi).clamp(0.2, 0.9);
        }
        let b = (a + step.max(min_step)).min(FRAC_PI_2);
        out.push((a, b));
        a = b;
    }
    out
}

/// The far field of lobe `p` at one `(theta_o, phi)` by adaptive Gauss-Kronrod over
/// `gamma` in [-pi/2, pi/2] (relative tolerance `rel`): the reference the node sums are
/// tested against, and `Integral::NearQuadrature`. Its initial intervals (`8 / s` of
/// them, 64 to 4096) are narrow enough that each peak of width `s / |Phi'|` (`|Phi'| <=
/// 6`) is sampled by Kronrod's nodes before bisection starts.
pub fn near_quadrature(slice: &Slice, p: usize, phi: f64, s: f64, rel: f64) -> f64 {
    let n = ((8.0 / s).ceil() as usize).clamp(64, 4096);
    let pts: Vec<f64> = (0..=n)
        .map(|k| -FRAC_PI_2 + PI * k as f64 / n as f64)
        .collect();
    adaptive_gk(
        |g| 0.5 * g.cos() * lobes::azimuthal_near(slice, p, g, phi, s),
        &pts,
        rel,
        1e-300,
        20_000,
    )
    .value
}

/// Parameters as the far field reads them (internal units, validated at the boundary).
#[derive(Clone, Copy, Debug)]
pub struct Chiang {
    pub eta: f64,
    pub beta_m: f64,
    pub beta_n: f64,
    pub alpha: f64,
    pub sigma_a: f64,
}

impl Factored<{ P_MAX + 1 }> for Chiang {
    fn from_params(p: &[f64]) -> Chiang {
        use super::{ALPHA, BETA_M, BETA_N, ETA, SIGMA_A};
        Chiang {
            eta: p[ETA],
            beta_m: p[BETA_M],
            beta_n: p[BETA_N],
            alpha: p[ALPHA],
            sigma_a: p[SIGMA_A],
        }
    }

    /// `beta_m` and `alpha` reach only `M_p`.
    const LONGITUDINAL: &'static [usize] = &[super::BETA_M, super::ALPHA];

    /// `N̄_p` of every slice (`theta_o`) and `|phi|` of `plan`.
    fn azimuthal_terms(&self, plan: &Plan) -> Vec<Vec<[f64; P_MAX + 1]>> {
        use rayon::prelude::*;
        let s = lobes::logistic_scale(self.beta_n);
        plan.slices
            .par_iter()
            .zip(&plan.phis)
            .map(|(&tr, phis)| {
                let nodes = SliceNodes::new(&Slice::new(self.eta, self.sigma_a, tr), s);
                phis.iter().map(|&ph| nodes.eval(ph)).collect()
            })
            .collect()
    }

    /// `cos(theta_i) M_p(theta_i, theta_o)` of every pair of `plan`.
    fn longitudinal_terms(&self, plan: &Plan) -> Vec<[f64; P_MAX + 1]> {
        let v = lobes::variances(self.beta_m);
        plan.pairs
            .iter()
            .map(|&(ti, tr)| {
                let m = lobes::longitudinal_lobes(ti, tr, self.alpha, &v);
                m.map(|x| x * ti.cos())
            })
            .collect()
    }
}
