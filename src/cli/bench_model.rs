//! `furfit bench-model`: far-field error vs evaluation time against Gauss-Legendre.

use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Output directory for far_field_error_vs_time.{csv,png,svg}.
    #[arg(long, default_value = "reports")]
    pub out: PathBuf,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    std::fs::create_dir_all(&a.out)?;
    crate::report::far_error::run(&a.out, &mut |line| println!("{line}"))?;
    Ok(())
}
