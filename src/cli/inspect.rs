//! `furfit inspect <file>...`

use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Profile files (.csv, .npy, .npz, Yan-2015 .txt).
    #[arg(required = true)]
    pub files: Vec<PathBuf>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    anyhow::bail!(
        "inspect is not built yet ({} file(s) given)",
        args.files.len()
    )
}
