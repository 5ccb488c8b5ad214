//! Stability report of the far field (filled in below).

use std::path::Path;

/// Totals of a stability run.
#[derive(Clone, Debug, Default)]
pub struct StabilitySummary {
    pub n_evaluations: usize,
    pub n_nonfinite: usize,
    pub n_negative: usize,
}

/// Run the adversarial sweep and write `stability.md` / `stability.csv` into `out`.
pub fn run(out: &Path, log: &mut dyn FnMut(&str)) -> crate::Result<StabilitySummary> {
    let _ = (out, log);
    Err(crate::Error::Invalid(
        "stability report not built yet".into(),
    ))
}
