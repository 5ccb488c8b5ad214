//! `furfit render` and `furfit render-convergence` on bad input: every option that sizes or
//! lights the work is bounded and named in the error, and output paths are checked before
//! anything is rendered or written.

use std::path::Path;
use std::process::{Command, Output};

mod common;

fn furfit(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_furfit"))
        .args(args)
        .output()
        .unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// A refused run: an ordinary error exit (not an abort), stderr names `flag`.
#[track_caller]
fn refused(o: &Output, flag: &str) {
    assert!(
        matches!(o.status.code(), Some(1 | 2)),
        "{flag}: status {:?}, stderr {}",
        o.status,
        stderr(o)
    );
    assert!(stderr(o).contains(flag), "{flag}: {}", stderr(o));
}

/// `args`, then each of `defaults` whose flag `extra` does not give (clap refuses a flag
/// given twice, which would hide what a test checks), then `extra`.
fn with_defaults(args: &[&str], defaults: &[(&str, &str)], extra: &[&str]) -> Output {
    let mut a: Vec<&str> = args.to_vec();
    for (f, v) in defaults {
        if !extra
            .iter()
            .any(|e| e == f || e.starts_with(&format!("{f}=")))
        {
            a.push(f);
            if !v.is_empty() {
                a.push(v);
            }
        }
    }
    a.extend_from_slice(extra);
    furfit(&a)
}

fn render(dir: &Path, extra: &[&str]) -> Output {
    let out = dir.join("r.png");
    let defaults = [
        ("--params", "red-fox"),
        ("--size", "8x8"),
        ("--spp", "1"),
        ("--fibers", "20"),
        ("--threads", "1"),
        ("--no-aovs", ""),
        ("--out", out.to_str().unwrap()),
    ];
    with_defaults(&["render"], &defaults, extra)
}

/// The smallest render: quick runs for option and output checks.
const SMALLEST: [&str; 8] = [
    "--size",
    "8x8",
    "--spp",
    "1",
    "--fibers",
    "20",
    "--threads",
    "1",
];

/// `render --all` of the fits in `fits` at the smallest settings, the sheet at `sheet`.
fn render_all(fits: &Path, sheet: &Path, extra: &[&str]) -> Output {
    let mut args = vec!["render", "--all", "--fits-dir", fits.to_str().unwrap()];
    args.extend_from_slice(&SMALLEST);
    args.extend_from_slice(&["--out", sheet.to_str().unwrap()]);
    args.extend_from_slice(extra);
    furfit(&args)
}

fn fit_file() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fits/red-fox.json")
}

#[test]
fn scene_size_and_sample_counts_are_bounded() {
    let dir = tempfile::tempdir().unwrap();
    for (flag, v) in [
        // 20 M fibers aborted on a failed allocation; 1e9 asked for terabytes.
        ("--fibers", "20000000"),
        ("--fibers", "1000000000"),
        // Was silently raised to 1.
        ("--fibers", "0"),
        ("--max-depth", "0"),
        ("--max-depth", "100000"),
        // Was accepted and ran for ever.
        ("--spp", "18446744073709551615"),
        ("--spp", "2000000"),
        ("--spp", "0"),
        ("--threads", "100000"),
    ] {
        let o = render(dir.path(), &[flag, v]);
        refused(&o, flag);
    }
    assert!(!dir.path().join("r.png").exists());
    // The bounds themselves are accepted.
    let o = render(dir.path(), &["--max-depth", "1", "--fibers", "1"]);
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn exposure_and_radiances_are_finite_and_bounded() {
    let dir = tempfile::tempdir().unwrap();
    // Each of these used to exit 0 with an all-black PNG.
    for (flag, v) in [
        ("--exposure", "nan"),
        ("--exposure", "1e308"),
        ("--exposure", "-1e308"),
        ("--exposure", "inf"),
        ("--env", "1e308"),
        ("--env", "0.3,1e308"),
        ("--env", "-1"),
        ("--light-intensity", "1e308"),
        ("--light-intensity", "nan"),
        ("--footprint-scale", "inf"),
    ] {
        let o = render(dir.path(), &[&format!("{flag}={v}")]);
        refused(&o, flag);
    }
    assert!(!dir.path().join("r.png").exists());
    let o = render(dir.path(), &["--exposure=-64", "--env", "1e6"]);
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn size_parser_is_shared_and_names_the_option() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("r.png");
    for size in ["axb", "8x", "0x8", "9000x8", "8"] {
        let o = furfit(&[
            "render",
            "--params",
            "red-fox",
            "--size",
            size,
            "--out",
            out.to_str().unwrap(),
        ]);
        refused(&o, "--size");
        assert!(stderr(&o).contains("1..=8192"), "{}", stderr(&o));
    }
    // Each side allowed, the whole too large (~20 GB): refused before allocating.
    let o = furfit(&[
        "render",
        "--params",
        "red-fox",
        "--size",
        "8192x8192",
        "--out",
        out.to_str().unwrap(),
    ]);
    refused(&o, "--size");
    assert!(stderr(&o).contains("more than the limit"), "{}", stderr(&o));
    let rc = dir.path().join("rc");
    for (flag, v) in [("--size", "axb"), ("--frame", "16xb"), ("--frame", "0x16")] {
        let o = furfit(&["render-convergence", flag, v, "--out", rc.to_str().unwrap()]);
        refused(&o, flag);
    }
    assert!(!rc.exists());
}

#[test]
fn fits_dir_requires_all() {
    let dir = tempfile::tempdir().unwrap();
    let o = render(dir.path(), &["--fits-dir", "fits"]);
    refused(&o, "--all");
    assert!(!dir.path().join("r.png").exists());
}

#[test]
fn render_checks_output_paths_before_rendering() {
    let dir = tempfile::tempdir().unwrap();
    let regular = dir.path().join("regular");
    std::fs::write(&regular, "keep").unwrap();
    let o = render(
        dir.path(),
        &["--out", regular.join("a.png").to_str().unwrap()],
    );
    assert!(!o.status.success());
    // Refused up front (no scene was built) with the real reason, not "File exists".
    assert!(stderr(&o).contains("not a directory"), "{}", stderr(&o));
    assert!(stdout(&o).is_empty(), "{}", stdout(&o));

    // --all: the contact sheet's path is a directory, so no species file may be written.
    let fits = dir.path().join("fits");
    std::fs::create_dir(&fits).unwrap();
    for n in ["a.json", "sheet.json"] {
        std::fs::copy(fit_file(), fits.join(n)).unwrap();
    }
    let out = dir.path().join("out");
    std::fs::create_dir_all(out.join("contact.png")).unwrap();
    let all = |sheet: &str| render_all(&fits, &out.join(sheet), &[]);
    let o = all("contact.png");
    assert!(!o.status.success());
    assert!(stderr(&o).contains("contact.png"), "{}", stderr(&o));
    assert!(stdout(&o).is_empty(), "{}", stdout(&o));
    // A sheet path named like a fit's render (fit sheet.json -> sheet.png) clashes with it:
    // refused before any render, whether that path is a directory or free.
    std::fs::create_dir(out.join("sheet.png")).unwrap();
    let o = all("sheet.png");
    assert!(!o.status.success());
    assert!(stderr(&o).contains("sheet.png"), "{}", stderr(&o));
    // ... and when it is free (the sheet would overwrite that fit's render).
    std::fs::remove_dir(out.join("sheet.png")).unwrap();
    let o = all("sheet.png");
    assert!(!o.status.success());
    assert!(stderr(&o).contains("contact sheet"), "{}", stderr(&o));
    let left: Vec<_> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    assert_eq!(left, ["contact.png"], "files written before the error");
    // A free sheet path renders every fit and the sheet.
    let o = all("sheet2.png");
    assert!(o.status.success(), "{}", stderr(&o));
    for f in ["a.png", "a.exr", "sheet.png", "sheet_R.png", "sheet2.png"] {
        assert!(out.join(f).is_file(), "{f}");
    }
}

fn convergence(out: &Path, extra: &[&str]) -> Output {
    let mut defaults = vec![
        ("--size", "8X8"),
        ("--frame", "64x64"),
        ("--max-spp", "1"),
        ("--threads", "1"),
        ("--out", out.to_str().unwrap()),
    ];
    // The culling study refuses these (it does not use them).
    if !extra.contains(&"--culling-study") {
        defaults.extend([("--ref-spp", "2"), ("--repeats", "1")]);
        // The noise budget compares its own two modes.
        if !extra.contains(&"--noise-budget") {
            defaults.push(("--modes", "near"));
        }
    }
    with_defaults(&["render-convergence"], &defaults, extra)
}

#[test]
fn render_convergence_validates_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let rc = dir.path().join("rc");
    for (extra, flag) in [
        // Rendered the references, wrote a header-only CSV, then failed.
        (&["--max-spp", "0", "--ref-spp", "4"][..], "--max-spp"),
        (&["--max-spp", "4", "--ref-spp", "4"], "--ref-spp"),
        (&["--ref-spp", "18446744073709551615"], "--ref-spp"),
        (&["--repeats", "0"], "--repeats"),
        (&["--modes", "near,near"], "--modes"),
        (&["--modes", "near,bogus"], "--modes"),
        // Options the culling study ignores conflict with it (refused by the parser,
        // whatever their value).
        (&["--culling-study", "--modes", "bogus"], "--modes"),
        (&["--culling-study", "--repeats", "1"], "--repeats"),
        (&["--threads", "100000"], "--threads"),
    ] {
        let o = convergence(&rc, extra);
        refused(&o, flag);
        assert!(stdout(&o).is_empty(), "{flag}: {}", stdout(&o));
    }
    assert!(!rc.exists(), "files written by a refused run");
    // --out under a regular file: refused before the references are rendered.
    let regular = dir.path().join("regular");
    std::fs::write(&regular, "keep").unwrap();
    let o = convergence(&regular.join("rc"), &[]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("not a directory"), "{}", stderr(&o));
    assert!(stdout(&o).is_empty(), "{}", stdout(&o));
    // One of the report's files is a directory: refused up front, none written.
    std::fs::create_dir_all(rc.join("render_convergence.md")).unwrap();
    let o = convergence(&rc, &[]);
    assert!(!o.status.success());
    assert!(stdout(&o).is_empty(), "{}", stdout(&o));
    assert!(!rc.join("render_convergence.csv").exists());
    // The smallest valid run (`8X8` as `render` accepts it) writes the whole report.
    std::fs::remove_dir(rc.join("render_convergence.md")).unwrap();
    let o = convergence(&rc, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    for f in ["csv", "png", "svg", "md"] {
        assert!(rc.join(format!("render_convergence.{f}")).is_file(), "{f}");
    }
}

/// Negative values of the options that take them (the documented default of
/// `--light-dir` among them) reach the parser, not clap's "unexpected argument '-2'";
/// out of range, the option's own check names its bound.
#[test]
fn negative_values_are_read() {
    let dir = tempfile::tempdir().unwrap();
    let o = render(
        dir.path(),
        &[
            "--exposure",
            "-2",
            "--cam-elev",
            "-10",
            "--cam-azim",
            "-45",
            "--light-dir",
            "-0.5,0.6,0.62",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(dir.path().join("r.png").exists());
    std::fs::remove_file(dir.path().join("r.png")).unwrap();
    for (flag, v, bound) in [
        ("--cam-dist", "-1", "> 0"),
        ("--fov", "-5", "(0, 170)"),
        ("--light-intensity", "-1", "0..="),
        ("--footprint-scale", "-1", ">= 0"),
        ("--env", "-1,0.1", "0..="),
    ] {
        let o = render(dir.path(), &[flag, v]);
        refused(&o, flag);
        assert!(stderr(&o).contains(bound), "{flag}: {}", stderr(&o));
    }
    assert!(!dir.path().join("r.png").exists());
}

/// The reports state the thread count the renders ran on, not a hard-coded "2 cores,
/// other jobs running".
#[test]
fn convergence_reports_state_their_threads() {
    let dir = tempfile::tempdir().unwrap();
    let rc = dir.path().join("rc");
    let o = convergence(&rc, &["--threads", "3"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let md = std::fs::read_to_string(rc.join("render_convergence.md")).unwrap();
    assert!(md.contains("wall time on 3 thread(s)"), "{md}");
    assert!(!md.contains("cores") && !md.contains("other jobs"), "{md}");
    let o = convergence(&rc, &["--culling-study"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let md = std::fs::read_to_string(rc.join("render_culling.md")).unwrap();
    assert!(md.contains("1 thread(s)"), "{md}");
    assert!(!md.contains("machine shared"), "{md}");
}

/// The noise budget writes one row per lighting, refuses the options it does not read,
/// and leaves the convergence report's files alone.
#[test]
fn noise_budget_reports_each_lighting() {
    let dir = tempfile::tempdir().unwrap();
    let rc = dir.path().join("rc");
    for flag in ["--modes", "--env-nee"] {
        let mut extra = vec!["--noise-budget", flag];
        if flag == "--modes" {
            extra.push("near");
        }
        let o = convergence(&rc, &extra);
        refused(&o, flag);
    }
    assert!(!rc.exists(), "files written by a refused run");
    let o = convergence(
        &rc,
        &[
            "--noise-budget",
            "--repeats",
            "2",
            "--max-spp",
            "4",
            "--ref-spp",
            "8",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let md = std::fs::read_to_string(rc.join("render_noise_budget.md")).unwrap();
    assert!(md.contains("--noise-budget --params red-fox"), "{md}");
    assert!(md.contains("1 thread(s)"), "{md}");
    for row in [
        "| key light + environment, multiple scattering (the default scene) | ",
        "| key light only, multiple scattering | ",
        "| key light only, direct (first fiber vertex) | ",
    ] {
        assert_eq!(md.matches(row).count(), 1, "{row}: {md}");
    }
    // Each row has near, multi-scale and far inefficiencies, then two speedups.
    let rows: Vec<&str> = md
        .lines()
        .filter(|l| l.starts_with("| key light"))
        .collect();
    assert_eq!(rows.len(), 3, "{md}");
    for r in rows {
        assert_eq!(r.matches(" | ").count(), 5, "{r}");
        assert_eq!(r.matches("x (").count(), 2, "{r}");
    }
    assert!(!rc.join("render_convergence.md").exists());
}

/// Options the chosen mode does not read are said on stderr, not silently ignored.
#[test]
fn render_warns_about_options_its_mode_ignores() {
    let dir = tempfile::tempdir().unwrap();
    let o = render(
        dir.path(),
        &["--mode", "near", "--exact-far", "--footprint-scale", "2"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        stderr(&o),
        "warning: --footprint-scale only acts in --mode multiscale: ignored with --mode near\n\
         warning: --exact-far: --mode near never evaluates the far field: ignored\n"
    );
    let o = render(dir.path(), &["--exact-far", "--footprint-scale", "0"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains(
            "warning: --exact-far: --mode multiscale with --footprint-scale 0 never \
             evaluates the far field: ignored"
        ),
        "{}",
        stderr(&o)
    );
    let o = render(dir.path(), &["--exact-far", "--footprint-scale", "2"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!stderr(&o).contains("warning"), "{}", stderr(&o));
}

/// `render` replaces only its own earlier outputs: a user's file of an output's name (here
/// an AOV of `--all`, never named on the command line) survives byte for byte, nothing is
/// rendered, and `--force` replaces it. A second render over the first needs no force.
#[test]
fn render_never_replaces_a_file_furfit_did_not_write() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let out = d.join("r.png");
    let o = render(d, &["--out", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    // Its own output: replaced without --force.
    let o = render(d, &["--out", out.to_str().unwrap(), "--seed", "2"]);
    assert!(o.status.success(), "{}", stderr(&o));
    // A user's file among the outputs of `render --all` (red-fox's R AOV).
    let fits = d.join("fits");
    std::fs::create_dir_all(&fits).unwrap();
    std::fs::copy(fit_file(), fits.join("red-fox.json")).unwrap();
    let sheet = d.join("sheet.png");
    let mine = d.join("red-fox_R.png");
    std::fs::write(&mine, b"my notes").unwrap();
    let all = |extra: &[&str]| render_all(&fits, &sheet, extra);
    let o = all(&[]);
    refused(&o, "red-fox_R.png");
    assert!(
        stderr(&o).contains("not written by furfit"),
        "{}",
        stderr(&o)
    );
    assert_eq!(std::fs::read(&mine).unwrap(), b"my notes");
    assert!(!sheet.exists() && !d.join("red-fox.png").exists());
    let o = all(&["--force"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_ne!(std::fs::read(&mine).unwrap(), b"my notes");
    // Now furfit's: a rerun without --force is fine.
    assert!(all(&[]).status.success());
}

/// The PNG text chunks (keyword -> text) of a file.
fn png_text(path: &Path) -> Vec<(String, String)> {
    let dec = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = dec.read_info().unwrap();
    // Text after the image data is read with it.
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    reader.next_frame(&mut buf).unwrap();
    reader.finish().unwrap();
    reader
        .info()
        .utf8_text
        .iter()
        .map(|t| (t.keyword.clone(), t.get_text().unwrap()))
        .collect()
}

/// Renders carry what made them: the furfit version, the command, the source of the
/// parameters (a fit says it was fitted to synthetic data), the mode and sampling, and the
/// parameters; an AOV names its lobe; the contact sheet lists its fits.
#[test]
fn renders_carry_their_provenance_in_png_text() {
    let dir = tempfile::tempdir().unwrap();
    let fit = fit_file();
    let out = dir.path().join("fox.png");
    let mut args = vec!["render", "--fit", fit.to_str().unwrap()];
    args.extend_from_slice(&SMALLEST);
    args.extend_from_slice(&["--mode", "far", "--out", out.to_str().unwrap()]);
    let o = furfit(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    let get = |path: &Path, key: &str| {
        png_text(path)
            .into_iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v)
            .unwrap_or_else(|| panic!("no {key} in {}", path.display()))
    };
    assert!(get(&out, "Software").starts_with("furfit "));
    assert!(get(&out, "Source").starts_with("furfit render --fit "));
    let d = get(&out, "Description");
    assert!(
        d.starts_with("image rendered by furfit from fit file ")
            && d.contains("species red-fox, fitted to SYNTHETIC data")
            && d.contains("mode far, 8x8, 1 spp, seed ")
            && d.contains("lobes R,TT,TRT,TTs,TRTs, medulla energy strand; colour: absorption tinted by r:g:b ratios"),
        "{d}"
    );
    assert!(get(&out, "Comment").contains("\"sigma_c_a\""));
    // The linear EXR beside it carries the same in its header.
    let meta = exr::meta::MetaData::read_from_file(out.with_extension("exr"), false).unwrap();
    let layer = &meta.headers[0].own_attributes;
    let comments = layer.comments.as_ref().unwrap().to_string();
    assert!(
        comments.starts_with("linear image rendered by furfit from fit file ")
            && comments.contains("SYNTHETIC"),
        "{comments}"
    );
    assert!(layer
        .software_name
        .as_ref()
        .is_some_and(|s| s.to_string().starts_with("furfit ")));
    let aov = dir.path().join("fox_TT.png");
    assert!(get(&aov, "Description").starts_with("TT lobe AOV rendered by furfit"));

    let fits = dir.path().join("fits");
    std::fs::create_dir(&fits).unwrap();
    std::fs::copy(&fit, fits.join("red-fox.json")).unwrap();
    let sheet = dir.path().join("sheet.png");
    let o = render_all(&fits, &sheet, &["--no-aovs"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let d = get(&sheet, "Description");
    assert!(
        d.starts_with("contact sheet rendered by furfit")
            && d.contains("red-fox: fit file ")
            && d.contains("SYNTHETIC"),
        "{d}"
    );
    assert!(get(&sheet, "Comment").starts_with("parameters red-fox: {"));
}

/// A fit whose channels are not r, g, b (wavelengths): the default tint is said to apply,
/// naming the channels the fit has.
#[test]
fn render_names_channels_it_cannot_colour_from() {
    let dir = tempfile::tempdir().unwrap();
    let rgb = common::rgb_fit(dir.path());
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&rgb).unwrap()).unwrap();
    for (i, nm) in ["650nm", "550nm", "450nm"].iter().enumerate() {
        v["channels"][i]["data"]["channel"] = serde_json::json!(nm);
    }
    v["data"]["channel"] = serde_json::json!("650nm");
    let fit = dir.path().join("nm.json");
    std::fs::write(&fit, v.to_string()).unwrap();
    let out = dir.path().join("nm.png");
    let mut args = vec!["render", "--fit", fit.to_str().unwrap(), "--no-aovs"];
    args.extend_from_slice(&SMALLEST);
    args.extend_from_slice(&["--out", out.to_str().unwrap()]);
    let o = furfit(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("no r, g, b channels in parameter file")
            && stderr(&o).contains("(channels 650nm, 550nm, 450nm)"),
        "{}",
        stderr(&o)
    );
}

/// `--cam-elev` is bounded to [-90, 90] (past the pole the camera flipped over without a
/// word); `--light-dir` keeps its direction however large or small its components (they
/// used to overflow or underflow when normalised) and refuses zero.
#[test]
fn camera_elevation_and_light_direction_are_checked() {
    let dir = tempfile::tempdir().unwrap();
    for v in ["91", "-90.5", "1e9", "nan", "inf"] {
        let o = render(dir.path(), &[&format!("--cam-elev={v}")]);
        refused(&o, "--cam-elev");
        assert!(stderr(&o).contains("-90..=90"), "{}", stderr(&o));
    }
    let o = render(dir.path(), &["--light-dir=0,0,0"]);
    refused(&o, "--light-dir");
    assert!(!dir.path().join("r.png").exists());
    let pixels = |name: &str, extra: &[&str]| {
        let out = dir.path().join(name);
        let o = render(
            dir.path(),
            &[extra, &["--out", out.to_str().unwrap()]].concat(),
        );
        assert!(o.status.success(), "{}", stderr(&o));
        image::open(&out).unwrap().to_rgb8().into_raw()
    };
    assert_eq!(
        pixels("big.png", &["--light-dir", "1e200,1e200,0"]),
        pixels("ref.png", &["--light-dir", "1,1,0"])
    );
    assert_eq!(
        pixels("tiny.png", &["--light-dir", "1e-320,0,0"]),
        pixels("ref1.png", &["--light-dir", "1,0,0"])
    );
    // The bounds themselves render.
    pixels("top.png", &["--cam-elev", "90"]);
    pixels("bottom.png", &["--cam-elev=-90"]);
}

/// A lobe named twice is refused, as a mode named twice in render-convergence --modes is;
/// a directory given as --fit is called one.
#[test]
fn repeated_lobes_and_a_fit_directory_are_refused_clearly() {
    let dir = tempfile::tempdir().unwrap();
    let o = render(dir.path(), &["--lobes", "R,R"]);
    refused(&o, "--lobes");
    assert!(stderr(&o).contains("R given twice"), "{}", stderr(&o));
    let o = render(dir.path(), &["--lobes", "TT,trt,TRT"]);
    refused(&o, "TRT given twice");
    let d = dir.path().to_str().unwrap();
    let out = dir.path().join("f.png");
    let o = furfit(&["render", "--fit", d, "--out", out.to_str().unwrap()]);
    refused(&o, "--fit");
    assert!(stderr(&o).contains("is a directory"), "{}", stderr(&o));
    assert!(!stderr(&o).contains("no such"), "{}", stderr(&o));
    assert!(!out.exists() && !dir.path().join("r.png").exists());
}

/// With --no-aovs, files with the AOV names are noted as not part of the render; only
/// the ones furfit wrote (in the ledger, unchanged) are called an earlier render's. A
/// user's own file was called "from an earlier render".
#[test]
fn stale_aov_note_claims_only_furfits_own_files() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let mine = d.join("mine_TT.png");
    std::fs::write(&mine, "hi").unwrap();
    let out = d.join("mine.png");
    let o = render(d, &["--out", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(!e.contains("earlier render"), "{e}");
    assert!(
        e.contains("mine_TT.png has an AOV's name but is not part of this render"),
        "{e}"
    );
    assert_eq!(std::fs::read(&mine).unwrap(), b"hi");
    // furfit's own AOVs, then a --no-aovs render: those are an earlier render's.
    let out = d.join("own.png");
    let mut args = vec!["render", "--params", "red-fox", "--lobes", "TT"];
    args.extend_from_slice(&SMALLEST);
    args.extend_from_slice(&["--out", out.to_str().unwrap()]);
    assert!(furfit(&args).status.success());
    let o = render(d, &["--out", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(
        e.contains("from an earlier render are not part of this one and no longer match"),
        "{e}"
    );
    assert!(!e.contains("AOV's name"), "{e}");
}

/// The same render gives the same EXR bytes (the header's attributes came out in a
/// different order from run to run), and the EXR header keeps a non-Latin-1 path in the
/// recorded command as UTF-8 (it became `??`); its comments say the pixels are linear.
#[test]
fn exr_is_deterministic_utf8_and_says_it_is_linear() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp
        .path()
        .join("\u{65e5}\u{672c} dir")
        .join("fox \u{fc}.png");
    let exr = out.with_extension("exr");
    let mut runs = Vec::new();
    for _ in 0..3 {
        let o = render(tmp.path(), &["--out", out.to_str().unwrap(), "--seed", "3"]);
        assert!(o.status.success(), "{}", stderr(&o));
        runs.push(std::fs::read(&exr).unwrap());
    }
    assert!(runs.iter().all(|r| *r == runs[0]), "EXR bytes differ");
    let meta = exr::meta::MetaData::read_from_file(&exr, false).unwrap();
    let layer = &meta.headers[0].own_attributes;
    let utf8 = |t: &exr::meta::attribute::Text| String::from_utf8(t.as_slice().to_vec());
    let source = layer
        .other
        .get(&exr::meta::attribute::Text::from("furfitSource"))
        .unwrap();
    let exr::meta::attribute::AttributeValue::Text(source) = source else {
        panic!("{source:?}")
    };
    let source = utf8(source).expect("UTF-8");
    assert!(
        source.contains("\u{65e5}\u{672c} dir/fox \u{fc}.png"),
        "{source}"
    );
    let comments = utf8(layer.comments.as_ref().unwrap()).unwrap();
    assert!(
        comments.contains("linear scene radiance") && !comments.contains("sRGB"),
        "{comments}"
    );
    // The PNG keeps its tone map and exposure.
    let png = png_text(&out);
    let d = &png.iter().find(|(k, _)| k == "Description").unwrap().1;
    assert!(d.contains("ACES tone map, sRGB, exposure 0 EV"), "{d}");
}
