//! `furfit synth`: synthesize a profile from parameters on an angle grid.

use crate::grid::{check_grid_size, parse_phi_grid, parse_theta_grid};
use crate::model::far::{FarOptions, SCATTERED_STEP_STRICT};
use crate::model::LobeSet;
use crate::synth::{self, ModelKind};
use crate::FurParams;
use anyhow::Context;
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Parameters: a preset name (e.g. red-fox), a parameter JSON or a fit JSON.
    #[arg(long)]
    pub params: String,
    /// Incident inclinations, degrees (`start:stop:step` or a comma list).
    #[arg(long = "theta-i", allow_hyphen_values = true)]
    pub theta_i: String,
    /// Outgoing inclinations, degrees.
    #[arg(long = "theta-r", allow_hyphen_values = true)]
    pub theta_r: String,
    /// Relative azimuths, degrees.
    #[arg(long, allow_hyphen_values = true)]
    pub phi: String,
    /// Azimuthal integral: `far` (piecewise analytic) or `near-quadrature` (reference).
    #[arg(long, default_value = "far")]
    pub model: String,
    /// Lobes to include: R,TT,TRT,TTs,TRTs or all.
    #[arg(long, default_value = "all")]
    pub lobes: String,
    /// Exposure scale k (default: the parameter file's, else 1).
    #[arg(long)]
    pub exposure: Option<f64>,
    /// Initial segments `N,M` (unscattered, scattered); default 8,5.
    #[arg(long)]
    pub segments: Option<String>,
    /// Refinement tolerance (relative to the lobe peak); `none` for the paper's fixed
    /// segmentation. Default 1e-4.
    #[arg(long)]
    pub tol: Option<String>,
    /// Tolerance mode: largest change of the scattered direction per node-quadrature
    /// segment, in radians, or `strict` (0.001). Only the one-bin TRTs segments at a
    /// caustic of the scattered direction use node quadrature (elsewhere the medulla
    /// table is integrated exactly), so the default 0.15 leaves them whole.
    #[arg(long)]
    pub scattered_step: Option<String>,
    /// Output file (.csv).
    #[arg(long)]
    pub out: PathBuf,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let (params, file_k) = FurParams::load(&a.params)?;
    for n in crate::model::FurModel::table_notes(&params) {
        eprintln!("note: {n}");
    }
    let ti = parse_theta_grid("--theta-i", &a.theta_i)?;
    let tr = parse_theta_grid("--theta-r", &a.theta_r)?;
    let phi = parse_phi_grid("--phi", &a.phi)?;
    check_grid_size(ti.len(), tr.len(), phi.len())?;
    for (what, g, lim) in [
        ("--theta-i", &ti, 90.0),
        ("--theta-r", &tr, 90.0),
        ("--phi", &phi, 180.0),
    ] {
        if let Some(v) = g.iter().find(|v| v.abs() > lim) {
            anyhow::bail!("{what}: angle {v} is outside [-{lim}, {lim}] degrees");
        }
    }
    let kind = ModelKind::parse(&a.model)?;
    let lobes = LobeSet::parse(&a.lobes)?;
    let exposure = a.exposure.unwrap_or(file_k);
    if !(exposure.is_finite() && exposure > 0.0) {
        anyhow::bail!("--exposure must be a finite number > 0, got {exposure}");
    }
    let mut opts = FarOptions::default();
    if let Some(s) = &a.segments {
        let parts: Vec<&str> = s.split(',').collect();
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
        match parts.as_slice() {
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
    if let Some(t) = &a.tol {
        opts.tol = if t.eq_ignore_ascii_case("none") {
            None
        } else {
            let v: f64 = t
                .parse()
                .with_context(|| format!("--tol '{t}' is not a number"))?;
            if !(v > 0.0 && v < 1.0) {
                anyhow::bail!("--tol must be in (0, 1) or 'none', got {v}");
            }
            Some(v)
        };
    }
    if let Some(t) = &a.scattered_step {
        opts.scattered_step = if t.eq_ignore_ascii_case("strict") {
            SCATTERED_STEP_STRICT
        } else {
            let v: f64 = t
                .parse()
                .with_context(|| format!("--scattered-step '{t}' is not a number"))?;
            if !(v > 0.0 && v <= 1.0) {
                anyhow::bail!("--scattered-step must be in (0, 1] radians or 'strict', got {v}");
            }
            v
        };
    }
    let t0 = std::time::Instant::now();
    let mut prof = synth::synthesize(&params, &ti, &tr, &phi, kind, lobes, exposure, &opts);
    let dt = t0.elapsed().as_secs_f64();
    let cmd: Vec<String> = std::env::args().collect();
    prof.set_meta("command", cmd.join(" "));
    synth::save(&a.out, &prof)?;
    let n = prof.samples.len();
    outln!(
        "wrote {} samples ({} theta_i x {} theta_r x {} phi, model {}) to {} in {:.3} s ({:.3e} samples/s)",
        n,
        ti.len(),
        tr.len(),
        phi.len(),
        kind.name(),
        a.out.display(),
        dt,
        n as f64 / dt.max(1e-12)
    );
    Ok(())
}
