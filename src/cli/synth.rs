//! `furfit synth`: synthesize a profile from parameters on an angle grid.

use crate::grid::{check_grid_size, parse_phi_grid, parse_theta_grid};
use crate::models::Integral;
use crate::synth;
use anyhow::{bail, Context};
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
/// Arguments of `furfit synth` (its `--help` text is the [`super::Command`] variant's).
pub struct Args {
    /// Parameters: a preset name (e.g. red-fox), a parameter JSON or a fit JSON (of any
    /// model: the file names it).
    #[arg(long)]
    pub params: String,
    /// Model of a preset, or the model the file must be of: yan2017 (default), marschner2003, chiang2016.
    #[arg(long)]
    pub model: Option<String>,
    /// Incident inclinations, degrees (`start:stop:step` or a comma list).
    #[arg(long = "theta-i", allow_hyphen_values = true)]
    pub theta_i: String,
    /// Outgoing inclinations, degrees.
    #[arg(long = "theta-r", allow_hyphen_values = true)]
    pub theta_r: String,
    /// Relative azimuths, degrees.
    #[arg(long, allow_hyphen_values = true)]
    pub phi: String,
    /// Integral over the fiber offset: far (far field) or near-quadrature (the slow reference).
    #[arg(long, default_value = "far")]
    pub integral: String,
    /// Lobes to include, by the model's names (yan2017: R,TT,TRT,TTs,TRTs), or all.
    #[arg(long, default_value = "all")]
    pub lobes: String,
    /// The channel of a multi-channel fit, or `all` (default: one output channel per fitted channel).
    #[arg(long)]
    pub channel: Option<String>,
    /// Exposure scale k (default: the parameter file's, else 1).
    #[arg(long, allow_negative_numbers = true, value_parser = super::number)]
    pub exposure: Option<f64>,
    #[command(flatten)]
    /// Far-field accuracy options.
    pub far: super::FarArgs,
    /// Output file (.csv or .npz; the extension picks the format).
    #[arg(long)]
    pub out: PathBuf,
    /// Replace --out if it is an earlier furfit synth profile (never other files).
    #[arg(long)]
    pub force: bool,
}

/// Check before any work that writing `out` loses nothing: a file path whose extension
/// picks a profile format; an existing file is replaced only with `force` and only if its
/// `source` metadata says `furfit synth` wrote it.
fn check_out(out: &Path, force: bool) -> anyhow::Result<()> {
    crate::io::check_out_file(out)?;
    crate::profile::save_format(out)?;
    if out.symlink_metadata().is_err() {
        return Ok(());
    }
    if !force {
        bail!(
            "{}: exists; synth would replace it (give --force to replace an earlier furfit \
             synth profile, or choose another path)",
            out.display()
        );
    }
    let earlier = crate::profile::load(out, &Default::default())
        .is_ok_and(|p| p.meta("source") == Some(synth::SOURCE));
    if !earlier {
        bail!(
            "{}: exists and is not a profile written by furfit synth: not replaced, even \
             with --force (move it away first)",
            out.display()
        );
    }
    Ok(())
}

/// Run `furfit synth`.
pub fn run(a: Args) -> anyhow::Result<()> {
    check_out(&a.out, a.force).context("--out")?;
    let want = a.model.as_deref().map(crate::models::by_name).transpose()?;
    let (params, file_k, json) = super::load_model_params(&a.params, want)?;
    let model = params.model;
    let fitted = match &json {
        Some(v) => crate::models::fit_channels(v, &a.params)?,
        None => Vec::new(),
    };
    // (name, parameters, exposure) per output channel.
    let channels =
        synth::output_channels(params, file_k, &fitted, a.channel.as_deref(), &a.params)?;
    if channels.len() > 1 {
        let names: Vec<&str> = fitted.iter().map(|c| c.name.as_str()).collect();
        eprintln!(
            "note: {} has channels {}: one output channel each (--channel NAME for one)",
            a.params,
            names.join(", ")
        );
    }
    for (_, p, _) in &channels {
        for n in model.notes(&p.values) {
            eprintln!("note: {n}");
        }
    }
    let ti = parse_theta_grid("--theta-i", &a.theta_i)?;
    let tr = parse_theta_grid("--theta-r", &a.theta_r)?;
    let phi = parse_phi_grid("--phi", &a.phi)?;
    check_grid_size(ti.len(), tr.len(), phi.len(), channels.len())?;
    super::note_radian_grids(&[("--theta-i", &ti), ("--theta-r", &tr), ("--phi", &phi)]);
    for (what, g, lim) in [
        ("--theta-i", &ti, 90.0),
        ("--theta-r", &tr, 90.0),
        ("--phi", &phi, 180.0),
    ] {
        crate::grid::check_angles(what, g, lim)?;
    }
    let kind = Integral::parse(&a.integral).context("--integral")?;
    let lobes = model.parse_lobes(&a.lobes).context("--lobes")?;
    if let Some(k) = a.exposure {
        synth::check_exposure("--exposure", k)?;
    }
    let opts = a.far.options()?;
    let unused = (kind != Integral::Far).then(|| format!("--integral {}", kind.name()));
    for w in a.far.ignored(&opts, unused.as_deref()) {
        eprintln!("warning: {w}");
    }
    let t0 = std::time::Instant::now();
    let mut prof = match channels.as_slice() {
        [(name, p, k)] => {
            let mut prof = synth::synthesize(
                p,
                &ti,
                &tr,
                &phi,
                kind,
                lobes,
                a.exposure.unwrap_or(*k),
                &opts,
            );
            if !name.is_empty() {
                prof.set_meta("channel_of_fit", name.clone());
            }
            prof
        }
        many => synth::synthesize_channels(many, &ti, &tr, &phi, kind, lobes, a.exposure, &opts),
    };
    let dt = t0.elapsed().as_secs_f64();
    // Name where the exposure came from: the option, or the parameter file's key.
    let source = if a.exposure.is_some() {
        "--exposure".to_string()
    } else {
        format!("the exposure of {}", a.params)
    };
    let exposure = |c: usize| a.exposure.unwrap_or(channels[c.min(channels.len() - 1)].2);
    let tail_underflows = synth::check_values(&prof, &exposure, &source)?;
    if tail_underflows > 0 {
        eprintln!(
            "note: at this exposure {tail_underflows} value(s) below {:e} of their channel's peak fall below the normal f64 range ({:e}) and keep fewer significant bits",
            synth::UNDERFLOW_TAIL,
            f64::MIN_POSITIVE
        );
    }
    for (key, c) in &prof.metadata {
        if key.starts_with("capped_slices") && !c.starts_with("0 ") {
            eprintln!(
                "note: {c} far-field slices hit the refinement limit; their values are not guaranteed to --tol (recorded as {key} in the file)"
            );
        }
    }
    prof.set_meta("command", super::command_line());
    // Every check passed (the exposure's needs the values): only now is a folder made.
    super::prepare_out_dir(&crate::io::parent_dir(&a.out))?;
    synth::save(&a.out, &prof)?;
    let n = prof.samples.len();
    outln!(
        "wrote {} samples ({} theta_i x {} theta_r x {} phi{}, model {}, {} integral) to {} in {:.3} s ({:.3e} samples/s)",
        n,
        ti.len(),
        tr.len(),
        phi.len(),
        if prof.channels.len() > 1 {
            format!(" x {} channels", prof.channels.len())
        } else {
            String::new()
        },
        model.name(),
        kind.name(),
        a.out.display(),
        dt,
        n as f64 / dt.max(1e-12)
    );
    Ok(())
}
