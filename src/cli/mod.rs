//! Command-line interface: one file per subcommand, each a thin layer that parses
//! arguments, calls the library and prints. Errors go to stderr with a non-zero exit.
// Doc comments on clap arguments are `--help` text, not Markdown: `<species>` stays.
#![allow(rustdoc::invalid_html_tags)]

use crate::model::far::{FarOptions, SCATTERED_STEP_STRICT};
use crate::FurParams;
use clap::{Parser, Subcommand};
use std::io::Write;
use std::sync::atomic::{AtomicBool, Ordering};

/// `println!` for the subcommands, but a closed stdout (`furfit inspect ... | head`) is not
/// an error of the job: printing stops quietly and the work (the files it writes) goes on,
/// where `println!` would panic.
macro_rules! outln {
    () => {
        $crate::cli::out_line(format_args!(""))
    };
    ($($t:tt)*) => {
        $crate::cli::out_line(format_args!($($t)*))
    };
}

/// Set once stdout refuses a write; later lines are dropped.
static STDOUT_CLOSED: AtomicBool = AtomicBool::new(false);

/// Write one line to stdout (see [`outln`]).
pub(crate) fn out_line(args: std::fmt::Arguments) {
    if STDOUT_CLOSED.load(Ordering::Relaxed) {
        return;
    }
    let mut out = std::io::stdout().lock();
    if let Err(e) = writeln!(out, "{args}").and_then(|()| out.flush()) {
        STDOUT_CLOSED.store(true, Ordering::Relaxed);
        if e.kind() != std::io::ErrorKind::BrokenPipe {
            eprintln!("warning: stdout: {e}; further output dropped");
        }
    }
}

/// Loader options shared by the commands that read profiles (`inspect`, `fit`): axis
/// grids for files that lack them (an axis option no input reads is an error) and angle
/// convention conversions applied to every format.
#[derive(clap::Args, Debug, Clone, Default)]
pub struct LoadArgs {
    /// Incident angle (deg) of Yan-2015 files without `# theta_i:`; a lone .npy's theta_i axis grid.
    #[arg(long, allow_hyphen_values = true)]
    pub theta_i: Option<String>,
    /// theta_r axis grid (deg) of a lone .npy, e.g. `-60:60:2`. An error without a lone .npy.
    #[arg(long, allow_hyphen_values = true)]
    pub theta_r: Option<String>,
    /// phi axis grid (deg) of a lone .npy, e.g. `-180:180:2`. An error without a lone .npy.
    #[arg(long, allow_hyphen_values = true)]
    pub phi: Option<String>,
    /// Degrees in [-360, 360] added to every file's phi (after --flip-phi), any format.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true, value_parser = number)]
    pub phi_offset: f64,
    /// Negate every file's phi (any format; applied before --phi-offset).
    #[arg(long)]
    pub flip_phi: bool,
    /// Negate every file's theta_r (any format).
    #[arg(long)]
    pub flip_theta_r: bool,
}

impl LoadArgs {
    /// The loader options these arguments give; an out-of-range `--phi-offset` is an error.
    pub fn to_options(&self) -> anyhow::Result<crate::profile::LoadOptions> {
        // One turn either way covers every convention; beyond, a typo (or 1e17, whose
        // wrap is rounding noise) would silently rotate the data.
        if !(self.phi_offset.is_finite() && self.phi_offset.abs() <= 360.0) {
            anyhow::bail!(
                "--phi-offset {}: must be within [-360, 360] degrees",
                crate::error::Num(self.phi_offset)
            );
        }
        let grid = |what: &str, g: &Option<String>| -> anyhow::Result<Option<Vec<f64>>> {
            Ok(match g {
                Some(t) => Some(crate::grid::parse_grid(what, t)?),
                None => None,
            })
        };
        Ok(crate::profile::LoadOptions {
            theta_i: grid("--theta-i", &self.theta_i)?,
            theta_r: grid("--theta-r", &self.theta_r)?,
            phi: grid("--phi", &self.phi)?,
            phi_offset: self.phi_offset,
            flip_phi: self.flip_phi,
            flip_theta_r: self.flip_theta_r,
            theta_i_for_npy: false,
        })
    }
}

/// Parse an image size `WxH` (or `WXH`) given to option `opt` (e.g. `--size`); each side
/// must be in `1..=max` and the whole at most `max_pixels`. Shared by `render` and `render-convergence` so both read and
/// refuse sizes alike.
pub fn parse_size(
    opt: &str,
    s: &str,
    max: usize,
    max_pixels: usize,
) -> anyhow::Result<(usize, usize)> {
    let bad = || anyhow::anyhow!("{opt} '{s}': expected WxH with width and height in 1..={max}");
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(bad)?;
    let side = |v: &str| {
        v.trim()
            .parse::<usize>()
            .ok()
            .filter(|n| (1..=max).contains(n))
    };
    match (side(w), side(h)) {
        (Some(w), Some(h)) if w * h <= max_pixels => Ok((w, h)),
        (Some(w), Some(h)) => Err(anyhow::anyhow!(
            "{opt} '{s}': {} pixels, more than the limit of {max_pixels} (e.g. 4096x4096)",
            w * h
        )),
        _ => Err(bad()),
    }
}

/// Largest `--threads` of every command: rayon spawns them all up front, so a huge count
/// would exhaust the process's threads, or hang spawning them, before any work.
pub const MAX_THREADS: usize = 1024;

/// A number option: the syntax of a profile file's numbers, so a nonzero value below the
/// f64 range (`1e-400`, which would read as 0) is refused as a file's is
/// ([`crate::text::parse_number`]).
pub fn number(s: &str) -> Result<f64, String> {
    crate::text::parse_number(s.trim())
}

/// [`crate::io::probe_writable`], saying when it created the folder.
pub fn prepare_out_dir(dir: &std::path::Path) -> crate::Result<()> {
    if crate::io::probe_writable(dir)? {
        note_created_folder(dir);
    }
    Ok(())
}

/// The note every command prints when it created an output folder.
pub fn note_created_folder(dir: &std::path::Path) {
    eprintln!("note: created folder {}", dir.display());
}

/// A number in [0, 1) (a fraction of a peak).
pub fn unit_fraction(s: &str) -> Result<f64, String> {
    let v = number(s)?;
    if (0.0..1.0).contains(&v) {
        Ok(v)
    } else {
        Err(format!("{} is outside [0, 1)", crate::error::Num(v)))
    }
}

/// The parser of every command's `--threads` (0 = all cores), so all bound it alike.
pub fn threads_parser() -> clap::builder::RangedU64ValueParser<usize> {
    clap::builder::RangedU64ValueParser::new().range(0..=MAX_THREADS as u64)
}

/// Far-field settings of `synth` and `fit` (one parser, so the two agree).
#[derive(clap::Args, Debug, Clone, Default)]
pub struct FarArgs {
    /// Initial far-field segments `N,M` (unscattered, scattered); default 8,5.
    #[arg(long, allow_negative_numbers = true)]
    pub segments: Option<String>,
    /// Far-field tolerance relative to each lobe's peak (default 1e-4, >= 1e-8); `none`: fixed segments.
    #[arg(long, allow_negative_numbers = true)]
    pub tol: Option<String>,
    /// Largest scattered-direction change per node-quadrature segment, radians, or `strict`; default 0.15.
    #[arg(long, allow_negative_numbers = true)]
    pub scattered_step: Option<String>,
}

impl FarArgs {
    /// One-line warnings for the options given that change nothing: all of them when the
    /// far field is not evaluated (`unused`: why not, e.g. `--model near-quadrature`),
    /// `--scattered-step` when `opts` has no tolerance mode (`--tol none`).
    pub fn ignored(&self, opts: &FarOptions, unused: Option<&str>) -> Vec<String> {
        let given: Vec<&str> = [
            ("--segments", self.segments.is_some()),
            ("--tol", self.tol.is_some()),
            ("--scattered-step", self.scattered_step.is_some()),
        ]
        .into_iter()
        .filter_map(|(f, g)| g.then_some(f))
        .collect();
        match unused {
            Some(why) if !given.is_empty() => vec![format!(
                "{} only {} the far field, which {why} does not use: ignored",
                given.join(", "),
                if given.len() == 1 {
                    "affects"
                } else {
                    "affect"
                }
            )],
            None if opts.tol.is_none() && self.scattered_step.is_some() => vec![
                "--scattered-step only acts in the tolerance mode: ignored with --tol none".into(),
            ],
            _ => Vec::new(),
        }
    }

    /// The far-field options these arguments ask for (defaults: [`FarOptions::default`]).
    pub fn options(&self) -> anyhow::Result<FarOptions> {
        use anyhow::Context;
        let mut opts = FarOptions::default();
        if let Some(s) = &self.segments {
            let parse = |t: &str| -> anyhow::Result<usize> {
                let n: usize = t
                    .trim()
                    .parse()
                    .with_context(|| format!("--segments '{s}': '{t}' is not a count"))?;
                if n == 0 || n > 4096 {
                    anyhow::bail!("--segments '{s}': counts must be in 1..=4096");
                }
                Ok(n)
            };
            match s.split(',').collect::<Vec<_>>().as_slice() {
                [n] => {
                    opts.n_unscattered = parse(n)?;
                    opts.n_scattered = opts.n_unscattered;
                }
                [n, m] => {
                    opts.n_unscattered = parse(n)?;
                    opts.n_scattered = parse(m)?;
                }
                _ => anyhow::bail!("--segments '{s}': expected N or N,M"),
            }
        }
        if let Some(t) = &self.tol {
            opts.tol = if t.trim().eq_ignore_ascii_case("none") {
                None
            } else {
                let v = number(t).map_err(|m| anyhow::anyhow!("--tol: {m}"))?;
                if !(MIN_TOL..1.0).contains(&v) {
                    let why = if v > 0.0 && v < MIN_TOL {
                        format!(
                            " (below {} the refinement runs into its split limit and slows a \
                             hundredfold without reaching it)",
                            crate::error::Num(MIN_TOL)
                        )
                    } else {
                        String::new()
                    };
                    anyhow::bail!(
                        "--tol must be in [{}, 1) or 'none', got {}{why}",
                        crate::error::Num(MIN_TOL),
                        crate::error::Num(v)
                    );
                }
                Some(v)
            };
        }
        if let Some(t) = &self.scattered_step {
            opts.scattered_step = if t.trim().eq_ignore_ascii_case("strict") {
                SCATTERED_STEP_STRICT
            } else {
                let v = number(t).map_err(|m| anyhow::anyhow!("--scattered-step: {m}"))?;
                if !(v > 0.0 && v <= 1.0) {
                    anyhow::bail!(
                        "--scattered-step must be in (0, 1] radians or 'strict', got {}",
                        crate::error::Num(v)
                    );
                }
                v
            };
        }
        Ok(opts)
    }
}

/// `a` as one shell word: unchanged when it holds only characters no shell treats
/// specially, else in single quotes (an embedded `'` as `'\''`), or where it holds a
/// control character (a line break would end a file's `# command:` line) in bash's
/// `$'...'` quoting with the character escaped.
pub(crate) fn shell_quote(a: &str) -> String {
    if a.chars().any(char::is_control) {
        let mut out = String::from("$'");
        for c in a.chars() {
            match c {
                '\\' => out.push_str("\\\\"),
                '\'' => out.push_str("\\'"),
                '\n' => out.push_str("\\n"),
                '\r' => out.push_str("\\r"),
                '\t' => out.push_str("\\t"),
                // Each UTF-8 byte as \xHH: bash's \uHHHH goes through the locale, and
                // under LC_ALL=C a C1 control (U+0080..U+009F) came back as its escape.
                c if c.is_control() => {
                    let mut buf = [0u8; 4];
                    for b in c.encode_utf8(&mut buf).bytes() {
                        out.push_str(&format!("\\x{b:02x}"));
                    }
                }
                c => out.push(c),
            }
        }
        out.push('\'');
        return out;
    }
    if !a.is_empty()
        && a.chars()
            .all(|c| c.is_ascii_alphanumeric() || "-_./:,=+".contains(c))
    {
        a.to_string()
    } else {
        format!("'{}'", a.replace('\'', "'\\''"))
    }
}

/// [`FurParams::load_json`] for a command's `--params` (or `--init`), saying first when a
/// file of that name is read in place of the preset of that name
/// ([`crate::params::preset_shadow_note`]).
pub(crate) fn load_params(
    spec: &str,
) -> crate::Result<(FurParams, f64, Option<serde_json::Value>)> {
    if let Some(n) = crate::params::preset_shadow_note(spec) {
        eprintln!("{n}");
    }
    FurParams::load_json(spec)
}

/// [`crate::models::ModelParams::load`] for a command's `--params` (or `--init`) of the
/// model `want` (default: the file's own, or the default model for a preset), saying
/// first when a file of that name is read in place of the preset of that name.
pub(crate) fn load_model_params(
    spec: &str,
    want: Option<&'static dyn crate::models::FiberModel>,
) -> crate::Result<(crate::models::ModelParams, f64, Option<serde_json::Value>)> {
    if let Some(n) = crate::params::preset_shadow_note(spec) {
        eprintln!("{n}");
    }
    crate::models::ModelParams::load(spec, want)
}

/// Print [`crate::grid::radians_note`] for each of a command's angle grids.
pub(crate) fn note_radian_grids(grids: &[(&str, &[f64])]) {
    for (what, g) in grids {
        if let Some(n) = crate::grid::radians_note(what, g) {
            eprintln!("{n}");
        }
    }
}

/// This run's command line as files record it (`# command:`), ready to paste into a
/// shell: `argv[0]` as plain `furfit` (reproducible anywhere), every argument quoted as
/// needed ([`shell_quote`]).
pub(crate) fn command_line() -> String {
    std::iter::once("furfit".to_string())
        .chain(std::env::args().skip(1).map(|x| shell_quote(&x)))
        .collect::<Vec<_>>()
        .join(" ")
}

#[cfg(test)]
mod quote_tests {
    use super::shell_quote;

    #[test]
    fn shell_quote_leaves_plain_words_and_quotes_the_rest() {
        assert_eq!(shell_quote("-180:180:2"), "-180:180:2");
        assert_eq!(shell_quote("fits/red-fox.json"), "fits/red-fox.json");
        assert_eq!(shell_quote("R, TT"), "'R, TT'");
        assert_eq!(shell_quote("it's"), "'it'\\''s'");
        assert_eq!(shell_quote(""), "''");
        assert_eq!(shell_quote("a$b"), "'a$b'");
        // A line break would split a file's `# command:` line: bash's $'...' form.
        assert_eq!(shell_quote("x\ny.csv"), "$'x\\ny.csv'");
        assert_eq!(shell_quote("it's\t\\"), "$'it\\'s\\t\\\\'");
        assert_eq!(shell_quote("\u{7}F"), "$'\\x07F'");
        assert_eq!(shell_quote("\u{85}z"), "$'\\xc2\\x85z'");
    }
}

pub mod bench_model;
pub mod export;
pub mod fit;
pub mod furnace;
pub mod inspect;
pub mod render;
pub mod render_convergence;
pub mod report;
pub mod se_calibration;
pub mod simulate;
pub mod stability;
pub mod synth;
pub mod tables;
pub mod tables_strand;
pub mod view;
mod view_decompose;

/// furfit: fit the 5-lobe fur BCSDF to goniometric profiles, report, check and preview.
#[derive(Parser, Debug)]
#[command(name = "furfit", version = concat!(env!("CARGO_PKG_VERSION"), " (git ", env!("FURFIT_GIT_REV"), ")"), about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    /// The subcommand to run.
    pub command: Command,
}

#[derive(Subcommand, Debug)]
/// The subcommands; each variant's doc comment is its `--help` summary.
pub enum Command {
    /// Print sample counts, angle ranges, channels and metadata of profile files.
    Inspect(inspect::Args),
    /// Build or check the medulla scattering tables (C^N, C^M).
    Tables(tables::Args),
    /// Path-trace a preview of fur on the built-in test lock.
    Render(Box<render::Args>),
    /// Convergence (RMSE vs spp/time per BCSDF scale) and culling studies of the renderer.
    RenderConvergence(render_convergence::Args),
    /// Synthesize a profile from parameters on an angle grid (far field or quadrature).
    Synth(Box<synth::Args>),
    /// Adversarial stability sweep of the far field (2-3 min on two cores); writes reports/stability.{md,csv}.
    Stability(stability::Args),
    /// Far-field error vs evaluation time against Gauss-Legendre quadrature.
    BenchModel(bench_model::Args),
    /// Fit the ten parameters to profiles; writes fits/<species>.json.
    Fit(Box<fit::Args>),
    /// Write NRMSE tables, Fig-11-style figures, error-vs-time and model-vs-simulation reports.
    Report(report::Args),
    /// Virtual goniometer: Monte Carlo ray tracing through a 3-D fiber -> synthetic profile.
    Simulate(Box<simulate::Args>),
    /// Standard-error calibration: replicated noisy fits against their standard errors; writes reports/se_calibration.{md,csv}.
    SeCalibration(se_calibration::Args),
    /// Export a fit as a Mitsuba 3, pbrt-v4, Blender Cycles or MaterialX hair material.
    Export(export::Args),
    /// White furnace: directional albedo over theta of the renderer's BCSDF.
    Furnace(furnace::Args),
    /// Write a real-time WebGL2 viewer of fits (shell textures + PRT), serve it, or render its still.
    View(Box<view::Args>),
}

/// The smallest `--tol`: at 1e-9 the cat preset's refinement already hits its split limit
/// on some `theta_d` slices, at 1e-10 red fox's on every one, and the run slows 100x.
pub const MIN_TOL: f64 = 1e-8;

/// Parse the command line, run, print errors; the exit code says whether it worked.
pub fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    crate::io::install_interrupt_cleanup();
    let result = match cli.command {
        Command::Inspect(a) => inspect::run(a),
        Command::Tables(a) => tables::run(a),
        Command::Synth(a) => synth::run(*a),
        Command::Stability(a) => stability::run(a),
        Command::BenchModel(a) => bench_model::run(a),
        Command::Fit(a) => fit::run(*a),
        Command::Report(a) => report::run(a),
        Command::Simulate(a) => simulate::run(*a),
        Command::Render(a) => render::run(*a),
        Command::RenderConvergence(a) => render_convergence::run(a),
        Command::SeCalibration(a) => se_calibration::run(a),
        Command::Export(a) => export::run(a),
        Command::Furnace(a) => furnace::run(a),
        Command::View(a) => view::run(*a),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
