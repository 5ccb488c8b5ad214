//! `furfit stability`: adversarial stability sweep of the far field.

use std::path::PathBuf;

#[derive(clap::Args, Debug)]
/// Arguments of `furfit stability` (its `--help` text is the [`super::Command`] variant's).
pub struct Args {
    /// Output directory for stability.md, stability.csv (the fur model) and
    /// stability_models.csv (the other models).
    #[arg(long, default_value = "reports")]
    pub out: PathBuf,
    /// Replace existing output files that furfit did not write (or that changed since).
    #[arg(long)]
    pub force: bool,
}

/// Run `furfit stability`.
pub fn run(a: Args) -> anyhow::Result<()> {
    // The sweep takes minutes (162 s on two cores for the committed report): a bad --out
    // fails first.
    super::prepare_out_dir(&a.out)?;
    let paths = ["stability.md", "stability.csv", "stability_models.csv"].map(|n| a.out.join(n));
    crate::io::check_replaceable(&paths, a.force)?;
    let summary = crate::report::stability::run(&a.out, &mut |line| outln!("{line}"))?;
    if summary.n_nonfinite > 0 || summary.n_negative > 0 {
        anyhow::bail!(
            "{} NaN/Inf and {} negative values in {} evaluations",
            summary.n_nonfinite,
            summary.n_negative,
            summary.n_evaluations
        );
    }
    Ok(())
}
