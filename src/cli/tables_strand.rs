//! `furfit tables strand`: train the Strand energy network ([`crate::render::strand`]) from
//! fresh Monte Carlo and write its weights and `reports/energy.md`.

use crate::render::strand::{StrandMlp, MAGIC, N_WEIGHTS};
use crate::render::strand_train::{dataset, errors, predict, train};
use anyhow::bail;
use std::path::PathBuf;
use std::time::Instant;

#[derive(clap::Args, Debug)]
/// Arguments of `furfit tables strand`.
pub struct StrandArgs {
    /// RNG seed of the training and held-out points, the Monte Carlo and the initial weights.
    #[arg(long, allow_negative_numbers = true, default_value_t = 2025)]
    pub seed: u64,
    /// Training points (random fibers and inclinations).
    #[arg(long, allow_negative_numbers = true, default_value_t = 1200)]
    pub train: usize,
    /// Held-out points (another seed's stream), for the error report.
    #[arg(long, allow_negative_numbers = true, default_value_t = 200)]
    pub holdout: usize,
    /// Photon paths per point.
    #[arg(long, allow_negative_numbers = true, default_value_t = 4000)]
    pub paths: usize,
    /// Full-batch Adam steps.
    #[arg(long, allow_negative_numbers = true, default_value_t = 4000)]
    pub epochs: usize,
    /// Weights file to write (.bin).
    #[arg(long, default_value = "assets/strand_mlp.bin")]
    pub out: PathBuf,
    /// Error report to write.
    #[arg(long, default_value = "reports/energy.md")]
    pub report: PathBuf,
}

/// Run `furfit tables strand`.
pub fn run(a: StrandArgs) -> anyhow::Result<()> {
    if a.train < 10 || a.holdout < 1 || a.paths < 2 || a.epochs < 1 {
        bail!("--train >= 10, --holdout >= 1, --paths >= 2 and --epochs >= 1 are needed");
    }
    if !a
        .out
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("bin"))
    {
        bail!(
            "--out {}: the weights file must end in .bin",
            a.out.display()
        );
    }
    if let Ok(b) = std::fs::read(&a.out) {
        if b.len() < 8 || &b[..8] != MAGIC {
            bail!(
                "--out {}: exists and is not a Strand weights file: not replaced",
                a.out.display()
            );
        }
    }
    crate::io::probe_file_writable(&a.out)?;
    let t0 = Instant::now();
    let data = dataset(a.train, a.paths, a.seed)?;
    let hold = dataset(a.holdout, a.paths, a.seed ^ 0x0F1D_0000_5EED_0001)?;
    let mc_s = t0.elapsed().as_secs_f64();
    let t1 = Instant::now();
    let mlp = train(&data, a.epochs, a.seed).rounded();
    let train_s = t1.elapsed().as_secs_f64();
    let (tmax, tmed) = errors(&mlp, &data);
    let (hmax, hmed) = errors(&mlp, &hold);
    let mut se: Vec<f64> = hold.iter().map(|s| s.se).collect();
    se.sort_by(f64::total_cmp);
    let worst = hold
        .iter()
        .max_by(|x, y| {
            (predict(&mlp, x) - x.albedo)
                .abs()
                .total_cmp(&(predict(&mlp, y) - y.albedo).abs())
        })
        .copied();
    let bytes = mlp.to_bytes();
    crate::io::write_atomic(&a.out, &bytes)?;
    let mut md = String::from("# Strand energy network: error against held-out Monte Carlo\n\n");
    md += &format!(
        "Command: `furfit tables strand --seed {} --train {} --holdout {} --paths {} --epochs {} --out {}` ({})\n\n",
        a.seed, a.train, a.holdout, a.paths, a.epochs, a.out.display(), crate::TOOL_VERSION
    );
    md += &format!(
        "The network (6-16-16-1, tanh, {N_WEIGHTS} weights, {} bytes as f32 with header and \
checksum) maps `(eta, kappa, sigma_m_s, sigma_m_a, g, theta)` to the physical directional \
albedo of a clear-cortex fiber, `exp(-sigma_m_a softplus(z))` (exactly 1 without medulla \
absorption). Targets: the virtual goniometer's tracer, {} paths a point (median standard \
error of a held-out target {:.4}, largest {:.4}). Training: {} points, full-batch Adam, {} \
steps. Domain: eta 1.1-2.0, kappa 0.05-0.99, sigma_m_s 0-10, sigma_m_a 0.001-5 (log-uniform \
in 1 + sigma), g -0.9-0.9, theta 0-89 degrees.\n\n",
        bytes.len(),
        a.paths,
        se[se.len() / 2],
        se[se.len() - 1],
        a.train,
        a.epochs
    );
    md += "| set | points | max abs error | median abs error |\n|---|---|---|---|\n";
    md += &format!("| training | {} | {tmax:.4} | {tmed:.4} |\n", data.len());
    md += &format!("| held out | {} | {hmax:.4} | {hmed:.4} |\n\n", hold.len());
    if let Some(w) = worst {
        let [eta, kappa, sms, sma, g, th] = w.raw;
        md += &format!(
            "Worst held-out point: eta {eta:.3}, kappa {kappa:.3}, sigma_m_s {sms:.3}, \
sigma_m_a {sma:.3}, g {g:.3}, theta {:.1} deg: MC {:.4} +- {:.4}, network {:.4}.\n\n",
            th.to_degrees(),
            w.albedo,
            w.se,
            predict(&mlp, &w)
        );
    }
    md += &format!(
        "The errors include the targets' own Monte Carlo noise (median {:.4}). Monte Carlo \
took {mc_s:.0} s, training {train_s:.0} s on this machine.\n",
        se[se.len() / 2]
    );
    crate::io::write_atomic(&a.report, md.as_bytes())?;
    outln!(
        "wrote {} ({} bytes) and {}",
        a.out.display(),
        bytes.len(),
        a.report.display()
    );
    outln!("held-out error max {hmax:.4} median {hmed:.4}");
    // The file read back is the file written.
    StrandMlp::load(&a.out)?;
    Ok(())
}
