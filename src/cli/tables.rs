//! `furfit tables build|info`: rebuild the medulla scattering tables from scratch
//! (Monte Carlo + CP-ALS, [`crate::model::medulla_mc`]) or check a tables file against
//! fresh Monte Carlo estimates.

use crate::model::medulla::{MedullaTables, MAGIC};
use crate::model::medulla_mc::{self, BuildOptions, McBudget};
use anyhow::{bail, Context};
use std::io::Read;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(clap::Args, Debug)]
/// Arguments of `furfit tables` (its `--help` text is the [`super::Command`] variant's).
pub struct Args {
    #[command(subcommand)]
    /// `build`, `info` or `strand`.
    pub command: TablesCommand,
}

#[derive(clap::Subcommand, Debug)]
/// The subcommands of `furfit tables`.
pub enum TablesCommand {
    /// Rebuild the C^N / C^M tables by Monte Carlo and compress them with CP-ALS.
    Build(BuildArgs),
    /// Print size, ranks and hold-out errors of a tables file.
    Info(InfoArgs),
    /// Train the Strand energy network (`--medulla-energy strand`) from fresh Monte Carlo.
    Strand(super::tables_strand::StrandArgs),
}

#[derive(clap::Args, Debug)]
/// Arguments of `furfit tables build`.
pub struct BuildArgs {
    /// RNG seed (the shipped file uses 2017).
    #[arg(long, allow_negative_numbers = true, default_value_t = 2017)]
    pub seed: u64,
    /// Nominal photon paths per table cell (optically thick cells stop earlier).
    #[arg(long, allow_negative_numbers = true, default_value_t = 16_000)]
    pub paths: usize,
    /// Use exactly this CP rank for every tensor instead of trying 16, 32, 48.
    #[arg(long, allow_negative_numbers = true)]
    pub rank: Option<usize>,
    /// Relative L2 error at which the rank search stops, in (0, 1).
    #[arg(long, default_value_t = 0.03, allow_negative_numbers = true, value_parser = super::number)]
    pub target_error: f64,
    /// Output file (.bin); an existing file is replaced only if it is a tables file.
    #[arg(long, default_value = "assets/medulla_tables.bin")]
    pub out: PathBuf,
    /// Use the tiny test grid (for quick checks).
    #[arg(long, hide = true)]
    pub tiny: bool,
}

#[derive(clap::Args, Debug)]
/// Arguments of `furfit tables info`.
pub struct InfoArgs {
    /// Tables file (default: the tables built into the binary).
    #[arg(long)]
    pub file: Option<PathBuf>,
    /// Number of random hold-out points per table (0: skip the Monte Carlo check).
    #[arg(long, allow_negative_numbers = true, default_value_t = 12)]
    pub holdout: usize,
    /// Photon paths per hold-out point.
    #[arg(long, allow_negative_numbers = true, default_value_t = 200_000)]
    pub paths: usize,
    /// Put the hold-out points on table nodes (no interpolation error).
    #[arg(long)]
    pub on_grid: bool,
    /// Seed of the hold-out Monte Carlo (must differ from the build seed).
    #[arg(long, allow_negative_numbers = true, default_value_t = 777)]
    pub seed: u64,
}

/// Run `furfit tables`.
pub fn run(args: Args) -> anyhow::Result<()> {
    match args.command {
        TablesCommand::Build(a) => build(a),
        TablesCommand::Info(a) => info(a),
        TablesCommand::Strand(a) => super::tables_strand::run(a),
    }
}

/// Check before the (long) build that writing `out` loses nothing and can succeed: a `.bin`
/// file path in a folder that takes files, and an existing file there must be a tables
/// file itself (its magic bytes).
fn check_out(out: &Path) -> anyhow::Result<()> {
    if !out
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("bin"))
    {
        bail!(
            "--out {}: a tables file must end in .bin (default assets/medulla_tables.bin)",
            out.display()
        );
    }
    // Writable, as the other long jobs check first (a refused write came after the whole
    // build; audit, 2026-12-02).
    crate::io::probe_file_writable(out)?;
    if out.symlink_metadata().is_ok() {
        let mut head = [0u8; 8];
        let tables = std::fs::File::open(out)
            .and_then(|mut f| f.read_exact(&mut head))
            .is_ok()
            && &head == MAGIC;
        if !tables {
            bail!(
                "--out {}: exists and is not a medulla tables file: not replaced (move it \
                 away first)",
                out.display()
            );
        }
    }
    Ok(())
}

fn build(a: BuildArgs) -> anyhow::Result<()> {
    if a.paths == 0 {
        anyhow::bail!("--paths must be positive");
    }
    // A relative L2 error: NaN would never stop the rank search at a good rank.
    if !(a.target_error > 0.0 && a.target_error < 1.0) {
        anyhow::bail!(
            "--target-error must be in (0, 1), got {}",
            crate::error::Num(a.target_error)
        );
    }
    check_out(&a.out)?;
    let mut opts = BuildOptions::standard(a.seed, a.paths);
    if a.tiny {
        opts.grid = medulla_mc::McGrid::tiny();
        opts.budget = McBudget::from_paths(a.paths);
    }
    if let Some(r) = a.rank {
        if r == 0 {
            anyhow::bail!("--rank must be positive");
        }
        opts.ranks = vec![r];
    }
    opts.target_error = a.target_error;
    let cells = opts.grid.n_cn_cells() + opts.grid.n_cm_cells();
    let bar = indicatif::ProgressBar::new(cells as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{elapsed_precise} [{bar:40}] {pos}/{len} cells (eta {eta})",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let t0 = Instant::now();
    let raw = medulla_mc::simulate_tables(&opts.grid, opts.seed, opts.budget, &|| bar.inc(1));
    bar.finish();
    let t_mc = t0.elapsed().as_secs_f64();
    outln!(
        "Monte Carlo: {} cells, {} paths, {} scattering events, {:.1} s",
        cells,
        raw.total_paths,
        raw.total_events,
        t_mc
    );
    outln!(
        "MC noise of the raw tensors (relative L2, even/odd half split): C^N {:.4}, \
         C^M front {:.4}, C^M back {:.4} (the floor under any CP error below)",
        raw.noise_rel[0],
        raw.noise_rel[1],
        raw.noise_rel[2]
    );
    let t1 = Instant::now();
    let (tables, _trials, chosen) = medulla_mc::compress_tables(&raw, &opts, &mut |t| {
        outln!(
            "CP-ALS {:<10} rank {:>2}: relative L2 error {:.4} ({} sweeps)",
            t.table,
            t.rank,
            t.rel_error,
            t.iterations
        )
    });
    let t_cp = t1.elapsed().as_secs_f64();
    let bytes = tables.to_bytes();
    crate::io::write_atomic(&a.out, &bytes)
        .with_context(|| format!("writing {}", a.out.display()))?;
    outln!(
        "ranks C^N {} / C^M front {} / C^M back {}; CP {:.1} s; total {:.1} s",
        chosen[0],
        chosen[1],
        chosen[2],
        t_cp,
        t0.elapsed().as_secs_f64()
    );
    outln!(
        "wrote {} ({} bytes, sha256 {})",
        a.out.display(),
        bytes.len(),
        crate::io::sha256_hex(&bytes)
    );
    Ok(())
}

fn info(a: InfoArgs) -> anyhow::Result<()> {
    let (tables, size, name) = match &a.file {
        Some(p) => {
            let t = MedullaTables::load(p)?;
            let size = std::fs::metadata(p).map(|m| m.len()).unwrap_or(0) as usize;
            (t, size, p.display().to_string())
        }
        None => {
            let t = MedullaTables::builtin().clone();
            let size = t.to_bytes().len();
            (t, size, "built-in tables".to_string())
        }
    };
    // Refused before anything is printed.
    if a.holdout > 0 && a.seed == tables.seed {
        anyhow::bail!("--seed must differ from the build seed {}", tables.seed);
    }
    outln!(
        "{name}: {size} bytes, build seed {}, {} nominal paths/cell",
        tables.seed,
        tables.paths
    );
    for (label, t) in [
        ("C^N", &tables.cn),
        ("C^M front", &tables.cm[0]),
        ("C^M back", &tables.cm[1]),
    ] {
        outln!(
            "  {:<10} rank {:>2}, grid {} x {} x {} x {}, tau in [{}, {}], g in [{}, {}]",
            label,
            t.rank,
            t.axes[0].len(),
            t.axes[1].len(),
            t.axes[2].len(),
            t.axes[3].len(),
            t.axes[0][0],
            t.axes[0].last().unwrap(),
            t.axes[1][0],
            t.axes[1].last().unwrap()
        );
    }
    if a.holdout == 0 {
        return Ok(());
    }
    let t0 = Instant::now();
    let pts = medulla_mc::holdout(&tables, a.holdout, a.seed, a.paths, a.on_grid);
    outln!(
        "hold-out: {} random {} points per table, {} fresh paths each (seed {}), {:.1} s",
        a.holdout,
        if a.on_grid {
            "on-grid (nearest node)"
        } else {
            "off-grid"
        },
        a.paths,
        a.seed,
        t0.elapsed().as_secs_f64()
    );
    outln!(
        "  {:<10} {:>7} {:>6} {:>8} {:>9} {:>9} {:>9}",
        "table",
        "tau",
        "g",
        "x/th_i",
        "relL2",
        "max",
        "MC noise"
    );
    for p in &pts {
        let coord = if p.table == "C^N" {
            format!("{:.3}", p.coord)
        } else {
            format!("{:.1}d", p.coord.to_degrees())
        };
        outln!(
            "  {:<10} {:>7.3} {:>6.3} {:>8} {:>9.4} {:>9.4} {:>9.4}",
            p.table,
            p.tau,
            p.g,
            coord,
            p.rel_l2,
            p.max_rel,
            p.noise_l2
        );
    }
    for table in ["C^N", "C^M front", "C^M back"] {
        let sel: Vec<_> = pts.iter().filter(|p| p.table == table).collect();
        if sel.is_empty() {
            continue;
        }
        let rms = |f: &dyn Fn(&&medulla_mc::HoldoutPoint) -> f64| {
            (sel.iter().map(|p| f(p).powi(2)).sum::<f64>() / sel.len() as f64).sqrt()
        };
        let maxof =
            |f: &dyn Fn(&&medulla_mc::HoldoutPoint) -> f64| sel.iter().map(f).fold(0.0, f64::max);
        // Compression + interpolation error net of the MC noise (errors add in quadrature).
        let net = (rms(&|p| p.rel_l2).powi(2) - rms(&|p| p.noise_l2).powi(2))
            .max(0.0)
            .sqrt();
        outln!(
            "  {:<10} relL2 rms {:.4} (worst {:.4}), max-err worst {:.4}, MC noise rms {:.4}, \
             table error net of noise ~{:.4}",
            table,
            rms(&|p| p.rel_l2),
            maxof(&|p| p.rel_l2),
            maxof(&|p| p.max_rel),
            rms(&|p| p.noise_l2),
            net
        );
    }
    Ok(())
}
