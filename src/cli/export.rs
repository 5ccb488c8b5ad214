//! `furfit export`: a fit as a Mitsuba 3, pbrt-v4, Blender Cycles or MaterialX material
//! ([`crate::export`]).

use crate::export::{self, Format, Material, Origin};
use anyhow::Context;
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
/// Arguments of `furfit export` (its `--help` text is the [`super::Command`] variant's).
pub struct Args {
    /// The fit file; a non-chiang2016 fit is exported as the closest chiang2016 material (NRMSE printed).
    #[arg(long)]
    pub params: PathBuf,
    /// Target: mitsuba, pbrt (pbrt-v4), cycles (a Blender Python script) or materialx.
    #[arg(long)]
    pub to: String,
    /// Output file.
    #[arg(long)]
    pub out: PathBuf,
    /// Where a non-Chiang fit's data are looked for (`<folder>/<species>/`) if not at their recorded paths.
    #[arg(long, default_value = "measurements")]
    pub measurements: PathBuf,
    /// Write a whole test-lock scene around the material (mitsuba, pbrt).
    #[arg(long)]
    pub scene: bool,
    /// Replace --out if it is an earlier furfit export (never other files).
    #[arg(long)]
    pub force: bool,
}

/// Run `furfit export`.
pub fn run(a: Args) -> anyhow::Result<()> {
    let format = Format::parse(&a.to).context("--to")?;
    if a.scene && !matches!(format, Format::Mitsuba | Format::Pbrt) {
        anyhow::bail!(
            "--scene writes Mitsuba 3 and pbrt-v4 scenes; --to {} writes a material only",
            format.name()
        );
    }
    export::check_out(&a.out, a.force).context("--out")?;
    let curves = export::scene::curves_path(&a.out);
    if a.scene && format == Format::Mitsuba {
        export::check_out_curves(&curves, a.force).context("--scene")?;
    }
    let m = Material::from_fit(&a.params, &a.measurements)
        .with_context(|| format!("--params {}", a.params.display()))?;
    let written = if a.scene {
        write_scene(&m, format, &a.out, &curves)?
    } else {
        let w = export::write(&m, format)?;
        crate::io::write_atomic(&a.out, w.text.as_bytes())?;
        w
    };
    if let Origin::Approximated {
        model,
        cost,
        samples,
        ..
    } = &m.origin
    {
        outln!(
            "{}: closest chiang2016 material to the {model} fit: NRMSE {:.3}% against its prediction at {samples} data angles (the cost of the export)",
            m.name,
            100.0 * cost
        );
    }
    outln!(
        "{}: eta={} beta_m={} beta_n={} alpha={} deg sigma_a={} (per unit radius, r, g, b)",
        m.name,
        crate::error::Num(m.eta),
        crate::error::Num(m.beta_m),
        crate::error::Num(m.beta_n),
        crate::error::Num(m.alpha_deg),
        m.sigma_a
            .map(|s| crate::error::Num(s).to_string())
            .join(", ")
    );
    for n in m.notes.iter().chain(&written.notes) {
        outln!("  note: {n}");
    }
    outln!(
        "wrote {} ({}{})",
        a.out.display(),
        format.name(),
        if a.scene { " scene" } else { "" }
    );
    if a.scene && format == Format::Mitsuba {
        outln!("wrote {} (the lock's curves)", curves.display());
    }
    Ok(())
}

/// Write the scene of `m` for `format` to `out` (and Mitsuba's curves to `curves`), as
/// one group: both land or neither.
fn write_scene(
    m: &Material,
    format: Format,
    out: &std::path::Path,
    curves: &std::path::Path,
) -> anyhow::Result<export::Written> {
    let lock = export::scene::Lock::preview();
    let stem = out
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "scene".into());
    Ok(match format {
        Format::Mitsuba => {
            let name = curves.file_name().unwrap().to_string_lossy().into_owned();
            let (w, c) = export::scene::mitsuba(m, &lock, &name)?;
            crate::io::write_atomic_all(&[
                (out.to_path_buf(), w.text.clone().into_bytes()),
                (curves.to_path_buf(), c.into_bytes()),
            ])?;
            w
        }
        _ => {
            let w = export::scene::pbrt(m, &lock, &format!("{stem}.exr"))?;
            crate::io::write_atomic(out, w.text.as_bytes())?;
            w
        }
    })
}
