//! One `furfit render` run from parsed options: the output files of every image planned
//! and checked before any render ([`plan`]), the scene built once, each set of parameters
//! rendered and written (PNG, linear EXR, per-lobe AOVs) and, for several, a labelled
//! contact sheet ([`run`]). The command line only parses and prints.

use super::bsdf::Tint;
use super::{output, render_scene, RenderOutput, RenderSettings, Scene};
use crate::error::{Error, Result};
use crate::model::Lobe;
use crate::params::FurParams;
use std::path::{Path, PathBuf};

/// One image of a run: a set of parameters and where it comes from.
#[derive(Clone, Debug)]
pub struct RenderJob {
    /// The image's name (a fit's file stem): in messages, the contact sheet and, with
    /// several, the file name.
    pub name: String,
    /// The parameters rendered.
    pub params: JobParams,
    /// The fit file's r, g, b channels' colour, when it has them.
    pub colour: Option<Tint>,
    /// Where the parameters come from (for the images' text).
    pub about: String,
}

/// The parameters of one image: the fur model's (rendered by [`super::bsdf`], every
/// option read), or another model's per channel r, g, b (rendered through the model
/// interface, [`super::render_model_scene`]: near field, all lobes, no AOVs).
#[derive(Clone, Debug)]
pub enum JobParams {
    /// The fur model's ten parameters (every renderer option applies).
    Fur(FurParams),
    /// Another model's parameters for the r, g and b channels (internal units).
    Model(Box<[crate::models::ModelParams; 3]>),
}

impl JobParams {
    /// The `params` JSON (file units) the images record; a model's channels that differ
    /// as `{"r": .., "g": .., "b": ..}`.
    pub fn to_json_value(&self) -> serde_json::Value {
        match self {
            JobParams::Fur(p) => p.to_json_value(),
            JobParams::Model(rgb) if rgb[0] == rgb[1] && rgb[1] == rgb[2] => rgb[0].to_json_value(),
            JobParams::Model(rgb) => serde_json::json!({
                "r": rgb[0].to_json_value(),
                "g": rgb[1].to_json_value(),
                "b": rgb[2].to_json_value(),
            }),
        }
    }

    /// The model's name.
    pub fn model(&self) -> &'static str {
        match self {
            JobParams::Fur(_) => "yan2017",
            JobParams::Model(rgb) => rgb[0].model.name(),
        }
    }
}

/// What a run takes besides its images: the settings and the output options.
#[derive(Clone, Debug)]
pub struct BatchOptions {
    /// The render settings (every option checked).
    pub settings: RenderSettings,
    /// The output PNG, or with `sheet` the contact sheet (each image then beside it, as
    /// `<name>.png`).
    pub out: PathBuf,
    /// Several images and a contact sheet (`--all`).
    pub sheet: bool,
    /// Write the per-lobe AOV images.
    pub aovs: bool,
    /// Replace existing output files that furfit did not write.
    pub force: bool,
    /// Exposure of the PNGs (EV).
    pub exposure: f64,
    /// `--tint` as given: it replaces a fit's own colour.
    pub tint: Option<String>,
    /// The parameters come from fit files (`--fit`, `--all`): an image without r, g, b
    /// channels is said to get the default tint.
    pub from_fits: bool,
    /// The command line the images record.
    pub command: String,
}

/// The output files of a run, checked ([`plan`]).
#[derive(Clone, Debug)]
pub struct Plan {
    /// Each image's output PNG, in the order of the jobs.
    pub outs: Vec<PathBuf>,
    /// The folders the files go to, for the caller to prepare
    /// ([`crate::io::probe_writable`]) before the renders.
    pub dirs: Vec<PathBuf>,
}

/// What one output file of a render holds.
#[derive(Clone, Copy)]
enum OutFile {
    /// The tone-mapped beauty PNG.
    Png,
    /// The linear beauty EXR.
    Exr,
    /// A lobe's tone-mapped AOV PNG.
    Aov(Lobe),
    /// A lobe's linear AOV EXR (for compositing: the lobes' EXRs add up to the fiber
    /// radiance of the beauty EXR; the background is in no lobe).
    AovExr(Lobe),
}

/// `out` with its stem extended by `suffix` and the extension `ext`
/// (`fox.png`, `_R`, `exr` -> `fox_R.exr`).
pub fn with_suffix(out: &Path, suffix: &str, ext: &str) -> PathBuf {
    let stem = out
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "render".into());
    out.with_file_name(format!("{stem}{suffix}.{ext}"))
}

/// The files one render writes: the PNG, the linear EXR beside it and the AOVs.
fn outputs(out: &Path, s: &RenderSettings, aovs: bool) -> Vec<(OutFile, PathBuf)> {
    let mut v = vec![
        (OutFile::Png, out.to_path_buf()),
        (OutFile::Exr, with_suffix(out, "", "exr")),
    ];
    if aovs {
        for l in Lobe::ALL.into_iter().filter(|&l| s.lobes.contains(l)) {
            v.push((
                OutFile::Aov(l),
                with_suffix(out, &format!("_{}", l.name()), "png"),
            ));
            v.push((
                OutFile::AovExr(l),
                with_suffix(out, &format!("_{}", l.name()), "exr"),
            ));
        }
    }
    v
}

/// Every output path of the run, checked before the (possibly long) renders, so a bad
/// `out` fails at once, before anything is written (a render that fails later still
/// leaves the images finished before it): no two images' files collide, each can be
/// written and replaced.
pub fn plan(o: &BatchOptions, jobs: &[RenderJob]) -> Result<Plan> {
    let outs: Vec<PathBuf> = jobs
        .iter()
        .map(|j| {
            if o.sheet {
                o.out.with_file_name(format!("{}.png", j.name))
            } else {
                o.out.clone()
            }
        })
        .collect();
    let mut taken: Vec<(PathBuf, &str)> = Vec::new();
    if o.sheet {
        taken.push((o.out.clone(), "the contact sheet"));
    }
    for (j, out) in jobs.iter().zip(&outs) {
        let name = j.name.as_str();
        let aovs = o.aovs && matches!(j.params, JobParams::Fur(_));
        for (_, p) in outputs(out, &o.settings, aovs) {
            if let Some((_, owner)) = taken.iter().find(|(q, _)| *q == p) {
                return Err(Error::Invalid(format!(
                    "--out {}: {} of fit '{name}' would overwrite {owner}; rename the fit \
                     or choose another --out",
                    o.out.display(),
                    p.display()
                )));
            }
            taken.push((p, name));
        }
    }
    for (p, _) in &taken {
        crate::io::check_out_file(p)?;
    }
    let planned: Vec<PathBuf> = taken.iter().map(|(p, _)| p.clone()).collect();
    crate::io::check_replaceable(&planned, o.force)?;
    let mut dirs: Vec<PathBuf> = planned.iter().map(|p| crate::io::parent_dir(p)).collect();
    dirs.dedup();
    Ok(Plan { outs, dirs })
}

/// Render and write every image of `jobs` to the outputs of `plan` (and with `o.sheet`
/// the contact sheet). `say` gets the result lines (stdout), `note` the notes (stderr).
pub fn run(
    o: &BatchOptions,
    jobs: &[RenderJob],
    plan: &Plan,
    mut say: impl FnMut(&str),
    mut note: impl FnMut(&str),
) -> Result<()> {
    let s = &o.settings;
    let built = std::time::Instant::now();
    let scene = Scene::build(&s.strand);
    // Said apart: each image's wall time below covers its own setup and tracing only.
    say(&format!(
        "scene: {} fibers, {} segments, built in {:.2} s; {}x{} at {} spp, mode {}",
        s.strand.fibers,
        scene.bvh.segments().len(),
        built.elapsed().as_secs_f64(),
        s.width,
        s.height,
        s.spp,
        s.mode.name()
    ));
    let mut tiles = Vec::new();
    for (job, out) in jobs.iter().zip(&plan.outs) {
        let r = render_one(o, &scene, job, out, &mut say, &mut note)?;
        tiles.push((job.name.clone(), r.beauty));
    }
    if o.sheet {
        let about: Vec<String> = jobs
            .iter()
            .map(|j| format!("{}: {}", j.name, j.about))
            .collect();
        let params: Vec<String> = jobs
            .iter()
            .map(|j| format!("{}: {}", j.name, j.params.to_json_value()))
            .collect();
        let text = [
            ("Software", crate::TOOL_VERSION.to_string()),
            ("Source", o.command.clone()),
            (
                "Description",
                format!(
                    "contact sheet rendered by furfit, mode {}, {} spp, seed {}, medulla energy {}: {}",
                    s.mode.name(),
                    s.spp,
                    s.seed,
                    s.medulla_energy.name(),
                    about.join("; ")
                ),
            ),
            ("Comment", format!("parameters {}", params.join("; "))),
        ];
        output::write_contact_sheet(&tiles, o.exposure, &text, &o.out)?;
        say(&format!("wrote contact sheet {}", o.out.display()));
    }
    Ok(())
}

/// Render one image and write its files (all or none), with its notes and lines.
fn render_one(
    o: &BatchOptions,
    scene: &Scene,
    job: &RenderJob,
    out: &Path,
    say: &mut impl FnMut(&str),
    note: &mut impl FnMut(&str),
) -> Result<RenderOutput> {
    let name = &job.name;
    let p = match &job.params {
        JobParams::Fur(p) => p,
        JobParams::Model(rgb) => return render_one_model(o, scene, job, rgb, out, say, note),
    };
    for n in crate::model::FurModel::model_notes(p) {
        note(&format!("note: {name}: {n}"));
    }
    // An explicit --tint wins; else a fit's own r, g, b absorption, else the default.
    let mut s = o.settings.clone();
    match (&job.colour, &o.tint) {
        (Some(t), None) => {
            s.tint = *t;
            note(&format!(
                "note: {name}: colour from the fit's r, g, b channel absorption"
            ));
        }
        (Some(_), Some(t)) => note(&format!(
            "note: {name}: --tint {t} replaces the fit's r, g, b absorption"
        )),
        // Said of fits only: a preset or parameter file has no channels to look for.
        (None, None) if o.from_fits => note(&format!(
            "note: {name}: no r, g, b channels in {}: default eumelanin-like tint of \
             its primary channel's absorption (--tint)",
            job.about
        )),
        (None, _) => {}
    }
    let r = render_scene(scene, p, &s)?;
    write_one(o, &s, job, &r, out, o.aovs, say, note)?;
    Ok(r)
}

/// [`render_one`] for another model than the fur model: its renderer BSDF, near field,
/// every lobe; its colour is its fit's r, g, b channels or, for one channel, grey (as the
/// exports give Mitsuba 3 and the other renderers: one `sigma_a` for r, g and b).
fn render_one_model(
    o: &BatchOptions,
    scene: &Scene,
    job: &RenderJob,
    rgb: &[crate::models::ModelParams; 3],
    out: &Path,
    say: &mut impl FnMut(&str),
    note: &mut impl FnMut(&str),
) -> Result<RenderOutput> {
    let (name, model) = (&job.name, rgb[0].model);
    if model
        .render_bsdf([&rgb[0].values, &rgb[1].values, &rgb[2].values])
        .is_none()
    {
        return Err(Error::Invalid(format!(
            "furfit render cannot render model {}: it has no renderer BSDF (renderable: {})",
            model.name(),
            super::renderable_models().join(", ")
        )));
    }
    if let Some(t) = o.tint.as_deref().filter(|t| !matches!(*t, "grey" | "gray")) {
        return Err(Error::Invalid(format!(
            "--tint {t} scales the fur model's absorption; a {} fit renders its own r, g, b \
             channels, or grey for one channel",
            model.name()
        )));
    }
    let mut s = o.settings.clone();
    if s.mode != super::bsdf::Mode::Near {
        note(&format!(
            "note: {name}: model {} is rendered near field (the hit's own offset, as pbrt-v4 \
             and Mitsuba 3 render hair): --mode {} is the fur model's",
            model.name(),
            s.mode.name()
        ));
        s.mode = super::bsdf::Mode::Near;
    }
    for n in model.notes(&rgb[1].values) {
        note(&format!("note: {name}: {n}"));
    }
    if o.aovs {
        note(&format!(
            "note: {name}: no per-lobe AOVs for model {} (they are the fur model's lobes)",
            model.name()
        ));
    }
    let r = super::render_model_scene(scene, rgb, &s)?;
    write_one(o, &s, job, &r, out, false, say, note)?;
    Ok(r)
}

/// Write one render's files (all or none) and say so.
#[allow(clippy::too_many_arguments)]
fn write_one(
    o: &BatchOptions,
    s: &RenderSettings,
    job: &RenderJob,
    r: &RenderOutput,
    out: &Path,
    aovs: bool,
    say: &mut impl FnMut(&str),
    note: &mut impl FnMut(&str),
) -> Result<()> {
    let name = &job.name;
    say(&format!(
        "{name}: {:.2} s wall ({:.2} s setup + {:.2} s tracing), {} rays, \
         {:.3} Mrays/s (tracing)",
        r.setup_seconds + r.seconds,
        r.setup_seconds,
        r.seconds,
        r.rays,
        r.rays_per_second() / 1e6
    ));
    // The PNG, the EXR and the AOVs are written as one: all or none.
    let files = outputs(out, s, aovs)
        .into_iter()
        .map(|(image, path)| {
            let text = |what: &str, linear: bool| image_text(o, s, job, what, linear);
            let bytes = match image {
                OutFile::Png => {
                    output::png_bytes(&r.beauty, o.exposure, &text("image", false), &path)?
                }
                OutFile::Exr => output::exr_bytes(&r.beauty, &text("linear image", true), &path)?,
                OutFile::Aov(l) => output::png_bytes(
                    &r.lobes[l.index()],
                    o.exposure,
                    &text(&format!("{} lobe AOV", l.name()), false),
                    &path,
                )?,
                OutFile::AovExr(l) => output::exr_bytes(
                    &r.lobes[l.index()],
                    &text(&format!("{} lobe linear AOV", l.name()), true),
                    &path,
                )?,
            };
            Ok((path, bytes))
        })
        .collect::<Result<Vec<_>>>()?;
    crate::io::write_outputs(&files)?;
    let written: Vec<PathBuf> = files.into_iter().map(|(p, _)| p).collect();
    for n in stale_aov_notes(out, &written) {
        note(&format!("note: {n}"));
    }
    say(&format!("wrote {} (+ .exr)", out.display()));
    if aovs {
        say(&format!(
            "wrote per-lobe AOVs {} (+ linear .exr)",
            with_suffix(out, "_<lobe>", "png").display()
        ));
    }
    Ok(())
}

/// What made an image, in its PNG's text chunks or EXR's header (`s`: the settings it
/// was rendered with). The EXRs hold linear radiance (`linear`): the tone map and
/// exposure are the PNGs' only.
fn image_text(
    o: &BatchOptions,
    s: &RenderSettings,
    job: &RenderJob,
    what: &str,
    linear: bool,
) -> Vec<(&'static str, String)> {
    let (lobes, medulla, colour) = match &job.params {
        JobParams::Fur(_) => (
            s.lobes
                .iter()
                .map(|l| l.name())
                .collect::<Vec<_>>()
                .join(","),
            format!(", medulla energy {}", s.medulla_energy.name()),
            s.tint.to_string(),
        ),
        JobParams::Model(rgb) => (
            rgb[0].model.lobe_names().join(","),
            String::new(),
            if rgb[0] == rgb[1] && rgb[1] == rgb[2] {
                "grey (one channel's parameters for r, g and b)".to_string()
            } else {
                "the fit's r, g, b channels".to_string()
            },
        ),
    };
    vec![
        ("Software", crate::TOOL_VERSION.to_string()),
        ("Source", o.command.clone()),
        (
            "Description",
            format!(
                "{what} rendered by furfit from {}; model {}; mode {}, {}x{}, {} spp, \
                 seed {}, lobes {lobes}{medulla}; colour: {colour}; {}",
                job.about,
                job.params.model(),
                s.mode.name(),
                s.width,
                s.height,
                s.spp,
                s.seed,
                if linear {
                    "linear scene radiance (the ACES tone map and --exposure apply \
                     to the PNGs only)"
                        .to_string()
                } else {
                    format!("ACES tone map, sRGB, exposure {} EV", o.exposure)
                }
            ),
        ),
        (
            "Comment",
            format!("parameters {}", job.params.to_json_value()),
        ),
    ]
}

/// Notes on files with the AOV names of `out` that this render did not write (`written`;
/// --no-aovs, other --lobes): they are left as they are (deleting is not this command's
/// to do), but do not go with the new image. Only a file the ledger lists unchanged is
/// called furfit's earlier render; any other is just named as not part of this one.
fn stale_aov_notes(out: &Path, written: &[PathBuf]) -> Vec<String> {
    let (ours, others): (Vec<PathBuf>, Vec<PathBuf>) = Lobe::ALL
        .into_iter()
        .flat_map(|l| ["png", "exr"].map(|ext| with_suffix(out, &format!("_{}", l.name()), ext)))
        .filter(|p| p.exists() && !written.contains(p))
        .partition(|p| crate::io::check_replaceable(std::slice::from_ref(p), false).is_ok());
    let list = |v: &[PathBuf]| {
        v.iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
            .join(", ")
    };
    let mut notes = Vec::new();
    if !ours.is_empty() {
        let one = ours.len() == 1;
        notes.push(format!(
            "{} from an earlier render {} not part of this one and no longer {} {}",
            list(&ours),
            if one { "is" } else { "are" },
            if one { "matches" } else { "match" },
            out.display()
        ));
    }
    if !others.is_empty() {
        notes.push(format!(
            "{} {} an AOV's name but {} not part of this render (not a furfit output \
             recorded in the ledger, or changed since)",
            list(&others),
            if others.len() == 1 { "has" } else { "have" },
            if others.len() == 1 { "is" } else { "are" },
        ));
    }
    notes
}
