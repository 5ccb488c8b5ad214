//! `furfit stability`: adversarial stability sweep of the far field.

use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Output directory for stability.md and stability.csv.
    #[arg(long, default_value = "reports")]
    pub out: PathBuf,
    /// Replace existing output files that furfit did not write (or that changed since).
    #[arg(long)]
    pub force: bool,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    // The sweep takes minutes (162 s on two cores for the committed report): a bad --out
    // fails first.
    super::prepare_out_dir(&a.out)?;
    let paths = ["stability.md", "stability.csv"].map(|n| a.out.join(n));
    crate::io::check_replaceable(&paths, a.force)?;
    let summary = crate::report::stability::run(&a.out, &mut |line| outln!("{line}"))?;
    if summary.n_nonfinite > 0 {
        anyhow::bail!(
            "{} NaN/Inf values in {} evaluations",
            summary.n_nonfinite,
            summary.n_evaluations
        );
    }
    Ok(())
}
