//! Far-field and multi-scale azimuthal scattering (seed Sec. 5, Eqs. 22-26 and Appendix).
//!
//! `N_p(phi) = 1/2 integral_{-1}^{1} A_p(h) D_p(h, phi) dh` (Eq. 22) and the multi-scale
//! `1/(h2 - h1) integral_{h1}^{h2} A_p D_p dh` (Eq. 26).

pub mod closed_form;
#[allow(missing_docs)] // docs: pending (file being split/rewritten)
mod engine;
mod reference;

pub use engine::{BitsMap, Decisions, FarSlice, LobeWork, SliceStats, CULL_SIGMAS};

pub use reference::REFERENCE_REL_TOL;

use crate::model::quadrature::GaussLegendre;
use crate::model::{AzimuthalSlice, FurModel, LobeSet, LobeValues};
use std::f64::consts::FRAC_PI_2;

/// Options of the piecewise-analytic far field.
///
/// The default is the tolerance-driven mode (`tol = Some(1e-4)`, starting from the paper's
/// 8 / 5 segments, culling on): segments whose closed-form fits are worse than `tol` of the
/// lobe's scale are bisected, so stiff parameters (tiny `beta_n`, the TRT caustic, grazing
/// `theta_d`) stay accurate at a cost only where needed. [`FarOptions::paper`] is the
/// paper's fixed segmentation (8 unscattered, 5 scattered, Sec. 5.1 "Validation").
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FarOptions {
    /// Initial segments of h in [0, 1] for R, TT, TRT (`h_i = sqrt(i/n)`).
    pub n_unscattered: usize,
    /// Initial segments of the medulla-reaching offsets for TTs, TRTs.
    pub n_scattered: usize,
    /// Skip segments whose lobe cannot reach `phi` (the paper's "Acceleration"), with a
    /// window wide enough that nothing above 1e-12 of the peak is lost.
    pub cull: bool,
    /// Refine segments until the fit error is at most `tol` of the lobe's peak scale.
    pub tol: Option<f64>,
    /// Tolerance mode, scattered lobes near a caustic of `Phi^s_p` (TRTs, where
    /// `dPhi^s/du` changes sign): the largest change of the scattered direction across one
    /// node-quadrature segment, at `tol = 1e-4` (scaled by `(tol / 1e-4)^(1/3)` for other
    /// tolerances). Elsewhere the tolerance mode integrates `C^N`'s piecewise-linear `psi`
    /// structure exactly, and only segments spanning at most one `psi` bin (2 degrees) are
    /// left to node quadrature, whose quadratic cannot follow the table's kinks. The
    /// default [`SCATTERED_STEP`] is wider than those segments (no effect);
    /// [`SCATTERED_STEP_STRICT`] subdivides them.
    pub scattered_step: f64,
}

/// Default [`FarOptions::scattered_step`] (radians).
pub const SCATTERED_STEP: f64 = 0.15;
/// A fine [`FarOptions::scattered_step`] for the node-quadrature segments at `Phi^s`
/// caustics (`tol_mode_meets_1e_4_on_stiff_cases_and_presets`; `reports/stability.md`, strict
/// column).
pub const SCATTERED_STEP_STRICT: f64 = 0.001;

impl Default for FarOptions {
    fn default() -> Self {
        FarOptions {
            n_unscattered: 8,
            n_scattered: 5,
            cull: true,
            tol: Some(1e-4),
            scattered_step: SCATTERED_STEP,
        }
    }
}

impl FarOptions {
    /// The paper's fixed segmentation: 8 segments for unscattered lobes, 5 for scattered,
    /// culling on, no refinement.
    pub fn paper() -> Self {
        FarOptions {
            n_unscattered: 8,
            n_scattered: 5,
            cull: true,
            tol: None,
            scattered_step: SCATTERED_STEP,
        }
    }

    /// The default tolerance mode with the strict scattered step
    /// ([`SCATTERED_STEP_STRICT`]).
    pub fn strict() -> Self {
        FarOptions {
            scattered_step: SCATTERED_STEP_STRICT,
            ..FarOptions::default()
        }
    }
}

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
