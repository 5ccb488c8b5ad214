//! `furfit report [--fits fits/] [--measurements measurements/] [--out reports/]`

use std::path::PathBuf;

#[derive(clap::Args, Debug)]
/// Arguments of `furfit report` (its `--help` text is the [`super::Command`] variant's).
pub struct Args {
    /// Folder of the fur model's fit files; its subfolders `<model>/` hold the other models' fits.
    #[arg(long, default_value = "fits")]
    pub fits: PathBuf,
    /// Folder of species folders (for model_vs_simulation.md, and a fit's data not found elsewhere).
    #[arg(long, default_value = "measurements")]
    pub measurements: PathBuf,
    /// Output folder.
    #[arg(long, default_value = "reports")]
    pub out: PathBuf,
    /// Replace existing output files that furfit did not write (or that changed since).
    #[arg(long)]
    pub force: bool,
}

/// Run `furfit report`.
pub fn run(a: Args) -> anyhow::Result<()> {
    // The fits first: a refused run leaves no empty --out folder behind.
    let (fits, mut unread) = crate::fit::file::read_fits(&a.fits)?;
    // The Table-4 report is the fur model's: another model's fit in its folder is listed,
    // not tabled (its place is <fits>/<model>/, which the model comparison reads).
    let default = crate::models::default_model().name();
    let (fits, others): (Vec<_>, Vec<_>) = fits
        .into_iter()
        .partition(|f| f.params.model.name() == default);
    for f in others {
        unread.push((
            f.path
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default(),
            format!(
                "a fit of {}: the Table-4 report is of {default} fits; move it to {}",
                f.params.model.name(),
                crate::fit::batch::model_dir(&a.fits, f.params.model).display()
            ),
        ));
    }
    if fits.is_empty() {
        anyhow::bail!("{}: no {default} fit file", a.fits.display());
    }
    super::prepare_out_dir(&a.out)?;
    let mut sum =
        crate::report::nrmse::write_fit_reports(&fits, &unread, &a.measurements, &a.out, a.force)?;
    // The model comparison, when fits of more than one model are there.
    let (by_model, not_compared) = crate::report::compare::read_all(&a.fits);
    if by_model.len() > 1 {
        let species: Vec<String> = by_model
            .iter()
            .flat_map(|(_, f)| f.iter().map(|f| f.label()))
            .collect();
        crate::io::check_replaceable(&crate::report::compare::outputs(&species, &a.out), a.force)?;
        let (written, skipped) =
            crate::report::compare::write(&by_model, &a.fits, &a.measurements, &a.out)?;
        sum.written.extend(written);
        sum.skipped.extend(skipped);
        sum.notes.extend(
            not_compared
                .into_iter()
                .map(|(f, why)| format!("{f}: {why}")),
        );
    }
    for p in &sum.written {
        outln!("wrote {}", p.display());
    }
    for (s, why) in &sum.skipped {
        eprintln!("skipped {s}: {why}");
    }
    for (p, why) in &sum.removed {
        eprintln!("removed {} ({why})", p.display());
    }
    for n in &sum.notes {
        eprintln!("note: {n}");
    }
    if !sum.skipped.is_empty() {
        // The other reports are written, but a missing plot or row must not pass as
        // success (scripts check the exit status).
        anyhow::bail!(
            "{} report part(s) skipped (see above); the rest is written",
            sum.skipped.len()
        );
    }
    Ok(())
}
