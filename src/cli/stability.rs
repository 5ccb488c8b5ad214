//! `furfit stability`: adversarial stability sweep of the far field.

use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Output directory for stability.md and stability.csv.
    #[arg(long, default_value = "reports")]
    pub out: PathBuf,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    // The sweep takes a minute and more: a bad --out fails first.
    crate::io::check_out_dir(&a.out)?;
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
