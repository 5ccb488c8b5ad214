//! `furfit se-calibration`: do the fit's standard errors match the spread of its estimates?

use std::path::PathBuf;

#[derive(clap::Args, Debug)]
/// Arguments of `furfit se-calibration` (its `--help` text is the [`super::Command`]
/// variant's).
pub struct Args {
    /// Output directory for se_calibration.{md,csv}.
    #[arg(long, default_value = "reports")]
    pub out: PathBuf,
    /// Noisy replicates per noise model (each a full fit of 3720 samples, ~6 s on two cores).
    #[arg(long, allow_negative_numbers = true, default_value_t = 40)]
    pub reps: usize,
    /// Replace existing output files that furfit did not write (or that changed since).
    #[arg(long)]
    pub force: bool,
}

/// Run `furfit se-calibration`.
pub fn run(a: Args) -> anyhow::Result<()> {
    // Before the folder is probed (which creates it): a refused run leaves nothing.
    crate::report::se_calibration::check_reps(a.reps)?;
    super::prepare_out_dir(&a.out)?;
    let paths = ["se_calibration.md", "se_calibration.csv"].map(|n| a.out.join(n));
    crate::io::check_replaceable(&paths, a.force)?;
    let written = crate::report::se_calibration::run(&a.out, a.reps, &mut |l| eprintln!("{l}"))?;
    for p in written {
        outln!("wrote {}", p.display());
    }
    Ok(())
}
