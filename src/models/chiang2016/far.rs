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
use crate::models::dual::{Dual, Real};
use crate::models::factored::Factored;
use crate::models::points::SlicePlan as Plan;
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
///
/// Generic over [`Real`]: `SliceNodes<Dual<3>>` carries the derivatives of the nodes'
/// positions and weights with respect to `(eta, beta_n, sigma_a)`, the panels' moving
/// ends included, so that [`SliceNodes::eval_gradient`] differentiates exactly the sum
/// [`SliceNodes::eval`] computes (as a finite difference that crosses no panel decision
/// sees it).
#[derive(Clone, Debug)]
pub struct SliceNodes<T = f64> {
    lobes: [Vec<(T, T)>; P_MAX],
    residual: T,
    s: T,
    norm: T,
}

impl<T: Real> SliceNodes<T> {
    /// The nodes of `slice` for the logistic scale `s`.
    pub fn new(slice: &Slice<T>, s: T) -> SliceNodes<T> {
        let gl = GaussLegendre::cached(PANEL_NODES);
        let mut residual = T::cst(0.0);
        let lobes = std::array::from_fn(|p| {
            let mut nodes = Vec::new();
            for (a, b) in panels(slice, p, s) {
                let (c, r) = ((a + b) * 0.5, (b - a) * 0.5);
                for (&x, &w) in gl.nodes.iter().zip(&gl.weights) {
                    let g = c + r * x;
                    let att = slice.attenuation(g);
                    // 1/2 dh over h in [-1, 1], the half [0, 1] counted for both signs.
                    let wg = r * (0.5 * w) * g.cos();
                    if p == 0 {
                        residual += wg * 2.0 * att[P_MAX];
                    }
                    let phi = wrap(slice.phi(p, g));
                    nodes.push((phi, wg * att[p]));
                    nodes.push((wrap(-phi), wg * att[p]));
                }
            }
            nodes.sort_by(|x, y| x.0.value().total_cmp(&y.0.value()));
            nodes
        });
        SliceNodes {
            lobes,
            residual: residual / (2.0 * PI),
            s,
            norm: lobes::trimmed_norm(s),
        }
    }

    /// The node ranges of lobe `p` within [`WINDOW`] scales of `phi`: one range, or two
    /// where the window wraps around +-pi.
    fn window(&self, p: usize, phi: f64) -> [std::ops::Range<usize>; 2] {
        let nodes = &self.lobes[p];
        let range = |lo: f64, hi: f64| {
            nodes.partition_point(|n| n.0.value() < lo)..nodes.partition_point(|n| n.0.value() < hi)
        };
        let w = (WINDOW * self.s.value()).min(PI);
        if w >= PI {
            [range(-PI, PI), 0..0]
        } else {
            let (lo, hi) = (lobes::wrap(phi - w), lobes::wrap(phi + w));
            if lo <= hi {
                [range(lo, hi), 0..0]
            } else {
                [range(lo, PI), range(-PI, hi)]
            }
        }
    }
}

/// [`lobes::wrap`] of a value, its derivatives kept (a shift by a multiple of `2 pi`).
fn wrap<T: Real>(x: T) -> T {
    x.with_value(lobes::wrap(x.value()))
}

impl SliceNodes<Dual<3>> {
    /// [`SliceNodes::eval`] with the derivatives of each `N̄_p(phi)` (the values are the
    /// same arithmetic). The logistic is differentiated by hand, the hot loop of a
    /// Jacobian: with `e = exp(-|x| / s)`, `L = e / (s (1 + e)^2)` and
    /// `t = (1 - e) / (1 + e)`, `dL/dx = -sign(x) t L / s` and
    /// `dL/ds = L (|x| t / s - 1) / s`; `x = phi - Phi_j` moves with the node.
    pub fn eval_gradient(&self, phi: f64) -> [Dual<3>; P_MAX + 1] {
        let mut out = [Dual::<3>::cst(0.0); P_MAX + 1];
        let s = self.s.v;
        for (p, nodes) in self.lobes.iter().enumerate() {
            // sum w L; sum (dw L - w dL/dx dPhi); sum w dL/ds.
            let (mut sum, mut grad, mut by_s) = (0.0, [0.0; 3], 0.0);
            for range in self.window(p, phi) {
                for (ph, wt) in &nodes[range] {
                    let x = lobes::wrap(phi - ph.v);
                    let ax = x.abs();
                    // As lobes::logistic, operation for operation.
                    let e = (-ax / s).exp();
                    let l = e / (s * (1.0 + e) * (1.0 + e));
                    let t = (1.0 - e) / (1.0 + e);
                    let wl_x = wt.v * (-x.signum() * t * l / s);
                    sum += wt.v * l;
                    by_s += wt.v * l * (ax * t / s - 1.0) / s;
                    for ((g, dw), dphi) in grad.iter_mut().zip(wt.g).zip(ph.g) {
                        *g += dw * l - wl_x * dphi;
                    }
                }
            }
            let mut n = Dual { v: sum, g: grad };
            for k in 0..3 {
                n.g[k] += by_s * self.s.g[k];
            }
            out[p] = n / self.norm;
        }
        out[P_MAX] = self.residual;
        out
    }
}

impl SliceNodes {
    /// `N̄_p(phi)` of the four lobes (the residual's is constant in `phi`).
    pub fn eval(&self, phi: f64) -> [f64; P_MAX + 1] {
        let mut out = [0.0; P_MAX + 1];
        for (p, nodes) in self.lobes.iter().enumerate() {
            let mut sum = 0.0;
            for range in self.window(p, phi) {
                for &(ph, wt) in &nodes[range] {
                    sum += wt * lobes::logistic(lobes::wrap(phi - ph), self.s);
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
///
/// Generic over [`Real`]: the panels' ends move with `s` and `eta` (through `Phi`), and
/// their derivatives are those of the branch each decision took.
fn panels<T: Real>(slice: &Slice<T>, p: usize, s: T) -> Vec<(T, T)> {
    let target = s * PANEL_PHI;
    let mut out = Vec::new();
    let mut a = T::cst(0.0);
    let c = T::cst;
    // Floor of a step: rounding of gamma near pi/2 (reached only for s below ~1e-13).
    let min_step = 1e-12;
    while a.value() < FRAC_PI_2 {
        let d1 = slice.dphi(p, a).abs();
        let d2 = slice.ddphi(p, a).abs();
        let mut step = c(PANEL_GAMMA)
            .min(target / d1.max(c(1e-300)))
            .min((target * 2.0 / d2.max(c(1e-300))).sqrt())
            .min(c(FRAC_PI_2) - a);
        let pa = slice.phi(p, a);
        loop {
            let b = (a + step).min(c(FRAC_PI_2));
            let dphi = (slice.phi(p, b) - pa).abs();
            if dphi.value() <= target.value() * 1.000001 || step.value() <= min_step {
                break;
            }
            step *= (target * 0.9 / dphi).clamp(0.2, 0.9);
        }
        let b = (a + step.max(c(min_step))).min(c(FRAC_PI_2));
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
    /// Index of refraction of the fiber.
    pub eta: f64,
    /// Longitudinal roughness, in (0, 1] (d'Eon's variance map applies at evaluation).
    pub beta_m: f64,
    /// Azimuthal roughness, in (0, 1] (the logistic scale follows from it).
    pub beta_n: f64,
    /// Cuticle scale tilt, radians.
    pub alpha: f64,
    /// Absorption per unit fiber radius.
    pub sigma_a: f64,
}

impl Factored<{ P_MAX + 1 }> for Chiang {
    fn from_params(p: &[f64]) -> Chiang {
        use super::specs::{ALPHA, BETA_M, BETA_N, ETA, SIGMA_A};
        Chiang {
            eta: p[ETA],
            beta_m: p[BETA_M],
            beta_n: p[BETA_N],
            alpha: p[ALPHA],
            sigma_a: p[SIGMA_A],
        }
    }

    /// `beta_m` and `alpha` reach only `M_p`.
    const LONGITUDINAL: &'static [usize] = &[super::specs::BETA_M, super::specs::ALPHA];

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

    /// Forward-mode derivatives ([`Dual`]) by `(eta, beta_n, sigma_a)` through the slice
    /// set-up, the panels and the node weights, and the logistic sums differentiated by
    /// hand ([`SliceNodes::eval_gradient`]): about 1.5 times one evaluation of the terms
    /// for all three, where finite differences take three.
    fn azimuthal_gradients(&self, plan: &Plan) -> Option<Vec<Vec<[f64; P_MAX + 1]>>> {
        use super::specs::{BETA_N, ETA, SIGMA_A};
        use rayon::prelude::*;
        const BY: [usize; 3] = [ETA, BETA_N, SIGMA_A];
        let k = super::specs::SPECS.len();
        let eta = Dual::<3>::variable(self.eta, 0);
        let sigma_a = Dual::<3>::variable(self.sigma_a, 2);
        let s = lobes::logistic_scale(Dual::<3>::variable(self.beta_n, 1));
        Some(
            plan.slices
                .par_iter()
                .zip(&plan.phis)
                .map(|(&tr, phis)| {
                    let nodes = SliceNodes::new(&Slice::new(eta, sigma_a, tr), s);
                    let mut out = vec![[0.0; P_MAX + 1]; phis.len() * k];
                    for (f, &ph) in phis.iter().enumerate() {
                        let n = nodes.eval_gradient(ph);
                        for (j, &param) in BY.iter().enumerate() {
                            out[f * k + param] = n.map(|x| x.g[j]);
                        }
                    }
                    out
                })
                .collect(),
        )
    }

    /// Forward-mode derivatives ([`Dual`]) by `(beta_m, alpha)`.
    fn longitudinal_gradients(&self, plan: &Plan) -> Option<Vec<[f64; P_MAX + 1]>> {
        use super::specs::{ALPHA, BETA_M};
        let k = super::specs::SPECS.len();
        let v = lobes::variances(Dual::<2>::variable(self.beta_m, 0));
        let alpha = Dual::<2>::variable(self.alpha, 1);
        let mut out = vec![[0.0; P_MAX + 1]; plan.pairs.len() * k];
        for (i, &(ti, tr)) in plan.pairs.iter().enumerate() {
            let m = lobes::longitudinal_lobes(ti, tr, alpha, &v);
            let c = ti.cos();
            out[i * k + BETA_M] = m.map(|x| x.g[0] * c);
            out[i * k + ALPHA] = m.map(|x| x.g[1] * c);
        }
        Some(out)
    }
}
