//! The far field's options ([`FarOptions`]): segments, culling, tolerance, the scattered
//! step.

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
