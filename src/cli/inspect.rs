//! `furfit inspect <file>...`: per file, the format, sample counts (valid / invalid), the
//! distinct values, range and most common step of each angle, channels, metadata and any
//! loader notes. Every file is inspected even if an earlier one fails; each failure is
//! printed to stderr and the command exits non-zero if any file failed, or if an axis
//! option (`--theta-i`, `--theta-r`, `--phi`) was given that no file read.

use crate::error::Num;
use crate::profile;
use crate::profile::summary::{AxisStats, Summary, STEPS_PER_DEG};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
/// Arguments of `furfit inspect` (its `--help` text is the [`super::Command`] variant's).
pub struct Args {
    /// Profile files (.csv, .npy, .npz, Yan-2015 .txt/.dat) or species directories.
    #[arg(required = true)]
    pub files: Vec<PathBuf>,
    #[command(flatten)]
    /// How profile files are read.
    pub load: super::LoadArgs,
}

fn axis_line(name: &str, a: &Option<AxisStats>) -> String {
    match a {
        None => format!("  {name:<8} -"),
        Some(a) => format!(
            "  {name:<8} {} distinct, {} .. {} deg, {}{}",
            a.distinct,
            Num(a.min),
            Num(a.max),
            match (a.step, a.even, a.step_range) {
                (None, ..) => "step -".into(),
                (Some(s), true, _) => format!("step {} deg", Num(s)),
                // No step repeats: none is "most common".
                (Some(_), false, Some((lo, hi))) if !a.step_repeats => {
                    format!("uneven steps {}..{} deg", Num(lo), Num(hi))
                }
                (Some(s), false, _) => format!("most common step {} deg (uneven)", Num(s)),
            },
            match a.near_pair {
                Some((x, y)) => format!(
                    "; {} near-duplicate pair(s) closer than {:e} deg, e.g. {} and {}",
                    a.near_duplicates,
                    0.5 / STEPS_PER_DEG,
                    Num(x),
                    Num(y)
                ),
                None => String::new(),
            }
        ),
    }
}

/// What inspect prints about one loaded path, line by line.
fn describe(path: &std::path::Path, l: &profile::Loaded) -> Vec<String> {
    let p = &l.profile;
    let s = Summary::of(p);
    // A folder may mix formats: name each, in the order first read.
    let mut formats: Vec<&str> = Vec::new();
    for f in &l.files {
        if !formats.contains(&f.format.name()) {
            formats.push(f.format.name());
        }
    }
    if formats.is_empty() {
        formats.push(l.format.name());
    }
    let mut out = vec![
        path.display().to_string(),
        format!(
            "  format   {}",
            if formats.len() > 1 {
                format!("mixed: {}", formats.join(", "))
            } else {
                formats[0].to_string()
            }
        ),
        format!(
            "  samples  {} ({} valid, {} invalid){}",
            s.n_samples,
            s.n_valid,
            s.n_invalid,
            if s.n_sigma > 0 {
                format!(", {} with sigma", s.n_sigma)
            } else {
                String::new()
            }
        ),
        axis_line("theta_i", &s.theta_i),
        axis_line("theta_r", &s.theta_r),
        axis_line("phi", &s.phi),
    ];
    if p.channels.is_empty() {
        out.push("  channels 1 (unnamed)".into());
    } else {
        let list: Vec<String> = p
            .channels
            .iter()
            .zip(&s.valid_per_channel)
            .map(|(c, n)| format!("{c} ({n} valid)"))
            .collect();
        out.push(format!(
            "  channels {}: {}",
            p.channels.len(),
            list.join(", ")
        ));
    }
    if p.metadata.is_empty() {
        out.push("  metadata -".into());
    } else {
        out.push("  metadata".into());
        for (key, v) in &p.metadata {
            out.push(format!("    {key}: {v}"));
        }
    }
    // Said either way: reports label their data by the same test.
    let dir = if path.is_dir() {
        path.to_path_buf()
    } else {
        crate::io::parent_dir(path)
    };
    out.push(if p.is_synthetic() {
        "  data     synthetic".into()
    } else if let Some(label) = profile::provenance::measured_label(p, &dir) {
        format!("  data     labelled measured ({label})")
    } else {
        "  data     not marked synthetic, treated as measured (no synthetic label in the file or its folder's metadata.json)".into()
    });
    for n in &l.notes {
        out.push(format!("  note: {n}"));
    }
    out
}

/// Run `furfit inspect`.
pub fn run(args: Args) -> anyhow::Result<()> {
    // Loaded apart but in one run: a lone .npy among them makes --theta-i its axis.
    let opts = args.load.to_options()?.for_inputs(&args.files);
    let mut failed = 0;
    let mut formats = Vec::new();
    // Described first, printed after the axis options are checked (as fit does), so an
    // option no input reads fails before any summary; profiles are dropped as they go.
    let mut reports = Vec::new();
    for path in &args.files {
        let loaded = if path.is_dir() {
            profile::load_dir(path, &opts)
        } else {
            profile::load_full(path, &opts)
        };
        match loaded {
            Ok(l) => {
                formats.extend(l.files.iter().map(|f| f.format));
                reports.push(describe(path, &l));
            }
            Err(e) => {
                eprintln!("error: {e}");
                failed += 1;
            }
        }
    }
    // With a file unread its format is unknown: the read error is the one to report.
    if failed == 0 {
        opts.check_used(&formats)?;
    }
    for (k, lines) in reports.iter().enumerate() {
        if k > 0 {
            outln!();
        }
        for line in lines {
            outln!("{line}");
        }
    }
    if failed > 0 {
        anyhow::bail!("{failed} of {} file(s) could not be read", args.files.len());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::profile::Sample;

    /// Steps that never repeat (theta_i 0, 10, 25, 45) are given as a range, not as a
    /// "most common step 10 deg"; a step that does repeat keeps that wording.
    #[test]
    fn axis_line_gives_the_range_of_steps_that_never_repeat() {
        let at = |v: &[f64]| -> Vec<Sample> {
            v.iter().map(|&t| Sample::new(t, 0.0, 0.0, 1.0)).collect()
        };
        let a = AxisStats::of(&at(&[0.0, 10.0, 25.0, 45.0]), |s| s.theta_i);
        assert_eq!(
            axis_line("theta_i", &a),
            "  theta_i  4 distinct, 0 .. 45 deg, uneven steps 10..20 deg"
        );
        let a = AxisStats::of(&at(&[0.0, 10.0, 20.0, 45.0]), |s| s.theta_i);
        assert!(
            axis_line("theta_i", &a).ends_with("most common step 10 deg (uneven)"),
            "{a:?}"
        );
    }
}
