//! Reference integrator of the far field / multi-scale integral (tests and reports only):
//! adaptive Gauss-Kronrod of the near field `A_p(h) D_p(h, phi)` over `h`, about 1e-10
//! relative. It shares nothing with the piecewise-analytic evaluator except the near-field
//! model itself ([`AzimuthalSlice::near`]) and, where the medulla's extinction is steep,
//! the evaluator's mesh toward the medulla edge (`engine::build::medulla_layer_h`: breakpoints
//! only, which place the quadrature but not its values; a test checks the reference there
//! against an integral in another variable), so it is an independent check of the closed
//! forms.
//!
//! Known blind spots (a black-box accuracy search, 2026-11-28, against a denser reference):
//! spikes within ~1e-9 of `h = +-1` (tiny `l` with tiny `beta_n`; at `eta' -> 1` it counts
//! one of TT's two grazing spikes); the far field was right in the cases seen.
//!
//! It integrates in `u = asin h` (`dh = cos u du`), which removes the square-root endpoint
//! behaviour at `h -> ±1`, and starts from breakpoints at every place the integrand is not
//! smooth or is sharply peaked: `h = 0`, the medulla edge `|h| = kappa eta'`, the TRT caustic,
//! and every root of `Phi_p(u) = phi + 2 pi k` (with a few lobe widths around it), so that a
//! 0.1 degree lobe cannot be stepped over.
#![allow(clippy::needless_range_loop)] // fixed-size per-lobe arrays read clearer indexed

use crate::model::azimuthal::beta_p;
use crate::model::quadrature::adaptive_gk;
use crate::model::{AzimuthalSlice, Lobe, LobeSet};
use std::f64::consts::{FRAC_PI_2, PI, TAU};

/// Relative tolerance the reference aims at (the adaptive GK stops at this estimate).
pub const REFERENCE_REL_TOL: f64 = 1e-10;

impl AzimuthalSlice<'_> {
    /// Reference value of `integral_{h1}^{h2} A_l(h) D_l(h, phi) dh` for one lobe
    /// (no normalisation). `h1 <= h2` in [-1, 1].
    pub fn reference_integral(&self, phi: f64, h1: f64, h2: f64, lobe: Lobe) -> f64 {
        let (h1, h2) = (h1.clamp(-1.0, 1.0), h2.clamp(-1.0, 1.0));
        if h2 <= h1 || !self.model.active_lobes().contains(lobe) {
            return 0.0;
        }
        let (u1, u2) = (h1.asin(), h2.asin());
        let mut pts = vec![u1, u2];
        let n_uniform = 32;
        for k in 1..n_uniform {
            pts.push(u1 + (u2 - u1) * k as f64 / n_uniform as f64);
        }
        pts.push(0.0);
        let kappa = self.model.params.kappa;
        let edge = kappa * self.eta_prime;
        if edge < 1.0 {
            pts.push(edge.asin());
            pts.push(-edge.asin());
            // The steep extinction layer inside the edge, as the far field meshes it.
            for h in super::engine::build::medulla_layer_h(self) {
                pts.push(h.asin());
                pts.push(-h.asin());
            }
        }
        if !lobe.is_scattered() {
            let p = lobe.p();
            if p == 2 {
                if let Some(uc) = self.trt_caustic_u() {
                    pts.push(uc);
                    pts.push(-uc);
                }
            }
            let bp = beta_p(p, self.model.params.beta_n);
            // Roots of Phi_p(u) = phi + 2 pi k on a fine scan, refined by bisection.
            let m = 4096;
            let phi_at = |u: f64| self.phi_unscattered(p, u);
            let mut prev_u = u1;
            let mut prev = phi_at(u1);
            for j in 1..=m {
                let u = u1 + (u2 - u1) * j as f64 / m as f64;
                let cur = phi_at(u);
                let (lo, hi) = (prev.min(cur), prev.max(cur));
                let kmin = ((lo - phi) / TAU).ceil() as i64;
                let kmax = ((hi - phi) / TAU).floor() as i64;
                for k in kmin..=kmax {
                    let target = phi + TAU * k as f64;
                    let (mut a, mut b) = (prev_u, u);
                    let fa = prev - target;
                    for _ in 0..60 {
                        let c = 0.5 * (a + b);
                        if (phi_at(c) - target) * fa > 0.0 {
                            a = c;
                        } else {
                            b = c;
                        }
                    }
                    let r = 0.5 * (a + b);
                    let slope = self.dphi_du(p, r).abs().max(1e-6);
                    let w = bp / slope;
                    for s in [-8.0, -3.0, -1.0, 0.0, 1.0, 3.0, 8.0] {
                        pts.push(r + s * w);
                    }
                }
                prev_u = u;
                prev = cur;
            }
        }
        pts.retain(|&u| u >= u1 && u <= u2 && u.is_finite());
        pts.sort_by(|a, b| a.partial_cmp(b).unwrap());
        pts.dedup();
        let set = LobeSet::only(lobe);
        // The path from gamma_i = u itself, as the far field's nodes: cos gamma_i = cos u
        // stays exact where h = sin u rounds to 1 (within ~1e-8 of grazing, where
        // sqrt(1 - h^2) = 0 would put a spurious F = 1 layer at eta -> 1, l -> 0).
        let f = |u: f64| {
            let geo = self.geometry_at_gamma_i(u);
            self.near_at(&geo, phi, set).get(lobe) * geo.cos_gamma_i
        };
        // Absolute floor: 1e-12 of the lobe's mean over phi, (integral A dh) / (2 pi), which
        // is a lower bound of its peak; so tails far below the peak do not stall the
        // refinement.
        let mean = crate::model::quadrature::GaussLegendre::cached(128).integrate(u1, u2, |u| {
            let geo = self.geometry_at_gamma_i(u);
            self.attenuation(&geo, set).get(lobe) * geo.cos_gamma_i
        }) / TAU;
        adaptive_gk(f, &pts, REFERENCE_REL_TOL, 1e-12 * mean, 100_000).value
    }

    /// Reference far field `N_l(phi) = 1/2 integral_{-1}^{1} A D dh` for the lobes in `lobes`.
    pub fn far_reference(&self, phi: f64, lobes: LobeSet) -> crate::model::LobeValues {
        let mut out = crate::model::LobeValues::default();
        for l in lobes.intersect(self.model.active_lobes()).iter() {
            out.set(l, 0.5 * self.reference_integral(phi, -1.0, 1.0, l));
        }
        out
    }

    /// Reference multi-scale `1/(h2 - h1) integral_{h1}^{h2} A D dh` (seed Eq. 26).
    pub fn multiscale_reference(
        &self,
        phi: f64,
        h1: f64,
        h2: f64,
        lobes: LobeSet,
    ) -> crate::model::LobeValues {
        let (h1, h2) = (h1.min(h2), h1.max(h2));
        let mut out = crate::model::LobeValues::default();
        for l in lobes.intersect(self.model.active_lobes()).iter() {
            out.set(l, self.reference_integral(phi, h1, h2, l) / (h2 - h1));
        }
        out
    }

    /// Unwrapped exit azimuth `Phi_p` as a function of `u = gamma_i = asin h` (Eq. 15).
    pub fn phi_unscattered(&self, p: usize, u: f64) -> f64 {
        let gt = (u.sin() / self.eta_prime).asin();
        2.0 * p as f64 * gt - 2.0 * u + p as f64 * PI
    }

    /// `dPhi_p/du = 2 p cos u / (eta' cos gamma_t) - 2`.
    pub fn dphi_du(&self, p: usize, u: f64) -> f64 {
        let st = u.sin() / self.eta_prime;
        let ct = (1.0 - st * st).max(1e-300).sqrt();
        2.0 * p as f64 * u.cos() / (self.eta_prime * ct) - 2.0
    }

    /// The TRT caustic `dPhi_2/du = 0` at `cos^2 u = (eta'^2 - 1) / 3` (exists for `eta' < 2`),
    /// as `u` in (0, pi/2).
    pub fn trt_caustic_u(&self) -> Option<f64> {
        let c2 = (self.eta_prime * self.eta_prime - 1.0) / 3.0;
        if c2 > 0.0 && c2 < 1.0 {
            let u = c2.sqrt().acos();
            (u > 0.0 && u < FRAC_PI_2).then_some(u)
        } else {
            None
        }
    }
}
