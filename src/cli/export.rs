//! `furfit export`: a fit as a Mitsuba 3, pbrt-v4, Blender Cycles or MaterialX material
//! ([`crate::export`]).

use crate::export::{self, Format, Material, Origin};
use anyhow::Context;
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// The fit file (`furfit fit`): a chiang2016 fit is mapped exactly; a fit of another
    /// model (yan2017, ...) is exported as the closest chiang2016 material to its
    /// prediction at its data's angles, and the NRMSE that costs is printed.
    #[arg(long)]
    pub params: PathBuf,
    /// Target: mitsuba (Mitsuba 3 `<bsdf type="hair">` XML), pbrt (pbrt-v4 `Material
    /// "hair"`), cycles (a Blender Python script building the Principled Hair BSDF),
    /// materialx (a `.mtlx` document with `chiang_hair_bsdf`).
    #[arg(long)]
    pub to: String,
    /// Output file.
    #[arg(long)]
    pub out: PathBuf,
    /// Folder of the measurements a non-Chiang fit's data are looked for in when its
    /// recorded paths no longer hold them (`<folder>/<species>/`).
    #[arg(long, default_value = "measurements")]
    pub measurements: PathBuf,
    /// Replace --out if it is an earlier furfit export (without it an existing file is
    /// never replaced; other files not even with it).
    #[arg(long)]
    pub force: bool,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let format = Format::parse(&a.to).context("--to")?;
    export::check_out(&a.out, a.force).context("--out")?;
    let m = Material::from_fit(&a.params, &a.measurements)
        .with_context(|| format!("--params {}", a.params.display()))?;
    let written = export::write(&m, format)?;
    crate::io::write_atomic(&a.out, written.text.as_bytes())?;
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
    outln!("wrote {} ({})", a.out.display(), format.name());
    Ok(())
}
