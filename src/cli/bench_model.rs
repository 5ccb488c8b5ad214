//! `furfit bench-model`: far-field error vs evaluation time against Gauss-Legendre.

use std::path::PathBuf;

#[derive(clap::Args, Debug)]
/// Arguments of `furfit bench-model` (its `--help` text is the [`super::Command`]
/// variant's).
pub struct Args {
    /// Output directory for far_field_error_vs_time.{csv,png,svg,md}.
    #[arg(long, default_value = "reports")]
    pub out: PathBuf,
    /// Only print the grid-synthesis throughput; writes nothing.
    #[arg(long, conflicts_with_all = ["out", "force"])]
    pub synth_only: bool,
    /// Every model side by side: far-field throughput, then a blind fit on --species; writes nothing.
    #[arg(long, conflicts_with_all = ["out", "force", "synth_only"])]
    pub models: bool,
    /// Fit wall time against samples and theta_i rows: writes
    /// fit_scaling.{csv,png,svg,md} into --out (minutes).
    #[arg(long, conflicts_with_all = ["synth_only", "models"])]
    pub fit_scaling: bool,
    /// With --models or --fit-scaling: the species folder the fits run on.
    #[arg(long, default_value = "measurements/red-fox")]
    pub species: PathBuf,
    /// Replace existing output files that furfit did not write (or that changed since).
    #[arg(long)]
    pub force: bool,
}

/// Run `furfit bench-model`.
pub fn run(a: Args) -> anyhow::Result<()> {
    if a.models {
        crate::report::zoo_bench::throughput(&mut |line| outln!("{line}"));
        crate::report::zoo_bench::fits(&a.species, &mut |line| outln!("{line}"))?;
        return Ok(());
    }
    if a.fit_scaling {
        super::prepare_out_dir(&a.out)?;
        let paths = ["csv", "png", "svg", "md"].map(|e| a.out.join(format!("fit_scaling.{e}")));
        crate::io::check_replaceable(&paths, a.force)?;
        std::fs::create_dir_all(&a.out).map_err(|e| crate::Error::io(&a.out, e))?;
        crate::report::fit_scaling::run(&a.out, &a.species, &mut |line| outln!("{line}"))?;
        return Ok(());
    }
    if a.synth_only {
        crate::report::far_error::synth_throughput(&mut |line| outln!("{line}"));
        return Ok(());
    }
    // The sweep takes minutes: a bad --out fails first, naming the path.
    super::prepare_out_dir(&a.out)?;
    let paths =
        ["csv", "png", "svg", "md"].map(|e| a.out.join(format!("far_field_error_vs_time.{e}")));
    crate::io::check_replaceable(&paths, a.force)?;
    std::fs::create_dir_all(&a.out).map_err(|e| crate::Error::io(&a.out, e))?;
    crate::report::far_error::run(&a.out, &mut |line| outln!("{line}"))?;
    Ok(())
}
