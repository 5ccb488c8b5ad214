//! `furfit inspect <file>...`: per file, the format, sample counts (valid / invalid), the
//! distinct values, range and most common step of each angle, channels, metadata and any
//! loader notes. Every file is inspected even if an earlier one fails; each failure is
//! printed to stderr and the command exits non-zero if any file failed, or if an axis
//! option (`--theta-i`, `--theta-r`, `--phi`) was given that no file read.

use crate::profile;
use crate::profile::summary::{AxisStats, Summary};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Profile files (.csv, .npy, .npz, Yan-2015 .txt/.dat) or species directories.
    #[arg(required = true)]
    pub files: Vec<PathBuf>,
    #[command(flatten)]
    pub load: super::LoadArgs,
}

fn axis_line(name: &str, a: &Option<AxisStats>) -> String {
    match a {
        None => format!("  {name:<8} -"),
        Some(a) => format!(
            "  {name:<8} {} distinct, {} .. {} deg, {}",
            a.distinct,
            a.min,
            a.max,
            match (a.step, a.even) {
                (None, _) => "step -".into(),
                (Some(s), true) => format!("step {s} deg"),
                (Some(s), false) => format!("most common step {s} deg (uneven)"),
            }
        ),
    }
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let opts = args.load.to_options()?;
    let mut failed = 0;
    let mut formats = Vec::new();
    for (k, path) in args.files.iter().enumerate() {
        let loaded = if path.is_dir() {
            profile::load_dir(path, &opts)
        } else {
            profile::load_full(path, &opts)
        };
        let l = match loaded {
            Ok(l) => l,
            Err(e) => {
                eprintln!("error: {e}");
                failed += 1;
                continue;
            }
        };
        formats.extend(l.files.iter().map(|f| f.format));
        if k > 0 {
            outln!();
        }
        let p = &l.profile;
        let s = Summary::of(p);
        outln!("{}", path.display());
        outln!("  format   {}", l.format.name());
        outln!(
            "  samples  {} ({} valid, {} invalid){}",
            s.n_samples,
            s.n_valid,
            s.n_invalid,
            if s.n_sigma > 0 {
                format!(", {} with sigma", s.n_sigma)
            } else {
                String::new()
            }
        );
        outln!("{}", axis_line("theta_i", &s.theta_i));
        outln!("{}", axis_line("theta_r", &s.theta_r));
        outln!("{}", axis_line("phi", &s.phi));
        if p.channels.is_empty() {
            outln!("  channels 1 (unnamed)");
        } else {
            let list: Vec<String> = p
                .channels
                .iter()
                .zip(&s.valid_per_channel)
                .map(|(c, n)| format!("{c} ({n} valid)"))
                .collect();
            outln!("  channels {}: {}", p.channels.len(), list.join(", "));
        }
        if p.metadata.is_empty() {
            outln!("  metadata -");
        } else {
            outln!("  metadata");
            for (key, v) in &p.metadata {
                outln!("    {key}: {v}");
            }
        }
        if p.is_synthetic() {
            outln!("  (synthetic data)");
        }
        for n in &l.notes {
            outln!("  note: {n}");
        }
    }
    if failed > 0 {
        anyhow::bail!("{failed} of {} file(s) could not be read", args.files.len());
    }
    opts.check_used(&formats)?;
    Ok(())
}
