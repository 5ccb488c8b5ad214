//! Far-field error vs time report (filled in below).

use std::path::Path;

/// Run the benchmark and write `far_field_error_vs_time.{csv,png,svg}` into `out`.
pub fn run(out: &Path, log: &mut dyn FnMut(&str)) -> crate::Result<()> {
    let _ = (out, log);
    Err(crate::Error::Invalid(
        "bench-model report not built yet".into(),
    ))
}
