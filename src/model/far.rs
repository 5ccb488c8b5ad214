//! Far-field and multi-scale azimuthal scattering (seed Sec. 5, Eqs. 22-26 and Appendix).
//!
//! `N_p(phi) = 1/2 integral_{-1}^{1} A_p(h) D_p(h, phi) dh` (Eq. 22) and the multi-scale
//! `1/(h2 - h1) integral_{h1}^{h2} A_p D_p dh` (Eq. 26).

pub mod closed_form;
mod engine;
mod options;
mod reference;

pub use engine::{BitsMap, Decisions, FarSlice, LobeWork, SliceStats, CULL_SIGMAS};
pub use options::{FarOptions, SCATTERED_STEP, SCATTERED_STEP_STRICT};

pub use reference::REFERENCE_REL_TOL;

use crate::model::quadrature::GaussLegendre;
use crate::model::{AzimuthalSlice, FurModel, LobeSet, LobeValues};
use std::f64::consts::FRAC_PI_2;

impl<'a> AzimuthalSlice<'a> {
    /// Precompute the far field at this `theta_d` for evaluation at many `phi`
    /// ([`FarSlice::eval`]); [`AzimuthalSlice::far`] equals `far_slice(..).eval(phi)`
    /// (building only what reaches `phi`).
    pub fn far_slice(&self, lobes: LobeSet, opts: &FarOptions) -> FarSlice<'a> {
        FarSlice::far(self, lobes, opts)
    }

    /// Far-field azimuthal scattering `N_p(phi)` (seed Eq. 22) for the lobes in `lobes`.
    pub fn far(&self, phi: f64, lobes: LobeSet, opts: &FarOptions) -> LobeValues {
        FarSlice::far_at(self, lobes, opts, phi)
    }

    /// Multi-scale azimuthal scattering over `[h1, h2]` (seed Eq. 26).
    pub fn multiscale(
        &self,
        phi: f64,
        h1: f64,
        h2: f64,
        lobes: LobeSet,
        opts: &FarOptions,
    ) -> LobeValues {
        let (a, b) = (h1.clamp(-1.0, 1.0), h2.clamp(-1.0, 1.0));
        let (h1, h2) = (a.min(b), a.max(b));
        if h2 - h1 < 1e-12 {
            // The limit of Eq. 26 for a vanishing range is the near field (Sec. 5.2).
            return self.near(0.5 * (h1 + h2), phi, lobes);
        }
        FarSlice::range_at(self, (h1, h2), lobes, opts, phi)
    }

    /// Plain Gauss-Legendre quadrature of the near field with `n` points in
    /// `u = asin h` over [-pi/2, pi/2] (the baseline the closed forms are compared with).
    pub fn far_gl(&self, phi: f64, n: usize, lobes: LobeSet) -> LobeValues {
        let gl = GaussLegendre::cached(n);
        let mut out = LobeValues::default();
        for (x, w) in gl.nodes.iter().zip(&gl.weights) {
            let u = FRAC_PI_2 * x;
            let v = self.near(u.sin(), phi, lobes);
            let c = 0.5 * w * FRAC_PI_2 * u.cos();
            for i in 0..5 {
                out.0[i] += c * v.0[i];
            }
        }
        out
    }
}

impl FurModel {
    /// Far-field BCSDF per lobe: `M_p(theta_i, theta_r) N_p(phi)` (no exposure).
    pub fn eval_far(
        &self,
        theta_i: f64,
        theta_r: f64,
        phi: f64,
        lobes: LobeSet,
        opts: &FarOptions,
    ) -> LobeValues {
        let lobes = lobes.intersect(self.active_lobes());
        let m = self.longitudinal(theta_i, theta_r, phi, lobes);
        let n = self
            .azimuthal(crate::model::geometry::theta_d(theta_i, theta_r))
            .far(phi, lobes, opts);
        m.mul(&n)
    }

    /// Multi-scale BCSDF per lobe over offsets `[h1, h2]`: `M_p N_p^{[h1,h2]}(phi)`.
    #[allow(clippy::too_many_arguments)]
    pub fn eval_multiscale(
        &self,
        theta_i: f64,
        theta_r: f64,
        phi: f64,
        h1: f64,
        h2: f64,
        lobes: LobeSet,
        opts: &FarOptions,
    ) -> LobeValues {
        let lobes = lobes.intersect(self.active_lobes());
        let m = self.longitudinal(theta_i, theta_r, phi, lobes);
        let n = self
            .azimuthal(crate::model::geometry::theta_d(theta_i, theta_r))
            .multiscale(phi, h1, h2, lobes, opts);
        m.mul(&n)
    }
}

#[cfg(test)]
mod tests;
