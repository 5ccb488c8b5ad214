//! `furfit render` of a model other than the fur model, through the model interface
//! (`FiberModel::render_bsdf`): the chiang2016 near field in a white furnace, and the
//! command end to end on a shipped chiang2016 fit.

use furfit::models::{by_name, ModelParams};
use furfit::render::bsdf::Mode;
use furfit::render::scene::{Environment, StrandSpec};
use furfit::render::{render_model_scene, CameraSpec, RenderOutput, RenderSettings, Scene};
use std::path::Path;
use std::process::{Command, Output};

fn chiang(sigma_a: f64) -> [ModelParams; 3] {
    let p = ModelParams::from_file_units(
        by_name("chiang2016").unwrap(),
        &[1.55, 0.3, 0.3, 2.0, sigma_a],
    )
    .unwrap();
    [p.clone(), p.clone(), p]
}

/// A white furnace (constant environment 1, no key light), near field, zoomed onto a
/// lock of 300 fibers so that most pixels see fibers.
fn furnace(env_nee: bool) -> RenderSettings {
    RenderSettings {
        width: 24,
        height: 24,
        spp: 8,
        seed: 5,
        threads: 2,
        mode: Mode::Near,
        light: None,
        env: Environment::constant(1.0),
        env_nee,
        max_depth: 256,
        // No Russian roulette: a path's value is then its product of sample weights.
        roulette_from: 256,
        camera: CameraSpec {
            dist: 1.2,
            ..Default::default()
        },
        strand: StrandSpec {
            fibers: 300,
            ..Default::default()
        },
        ..RenderSettings::default()
    }
}

/// The green channel of the pixels whose camera ray met a fiber (their lobe AOVs, split
/// at the first fiber vertex, are not all zero).
fn fiber_pixels(r: &RenderOutput) -> Vec<f64> {
    (0..r.beauty.data.len())
        .filter(|&i| r.lobes.iter().any(|l| l.data[i][1] != 0.0))
        .map(|i| r.beauty.data[i][1])
        .collect()
}

fn mean_se(v: &[f64]) -> (f64, f64) {
    let mean = v.iter().sum::<f64>() / v.len() as f64;
    let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / v.len() as f64;
    (mean, (var / v.len() as f64).sqrt())
}

/// A lossless chiang2016 fiber (`sigma_a = 0`: the `A_p` sum to 1) in a white furnace
/// returns exactly what it receives: every sample weight is 1, so with BCSDF sampling
/// alone and no roulette each path is worth exactly 1 once it escapes (a path still
/// inside the lock after 256 vertices, or a draw of zero density, is worth 0): every
/// pixel <= 1 + 1e-9 and their mean >= 0.999. With environment NEE + MIS the per-path
/// values vary, and the mean of the fiber pixels is 1 within 4 standard errors. The
/// same furnace with `sigma_a = 0.5` is far below 1 (the check sees the fibers).
#[test]
fn lossless_chiang_lock_in_a_white_furnace_returns_one() {
    let s = furnace(false);
    let scene = Scene::build(&s.strand);
    let r = render_model_scene(&scene, &chiang(0.0), &s).unwrap();
    let fiber = fiber_pixels(&r);
    assert!(fiber.len() > 300, "{} fiber pixels", fiber.len());
    let max = r.beauty.max_value();
    assert!(max <= 1.0 + 1e-9, "max {max}");
    let (mean, _) = mean_se(&fiber);
    assert!(mean >= 0.999, "mean {mean}");

    let r = render_model_scene(&scene, &chiang(0.0), &furnace(true)).unwrap();
    let (mean, se) = mean_se(&fiber_pixels(&r));
    assert!(
        (mean - 1.0).abs() <= 4.0 * se + 1e-9,
        "env NEE: mean {mean} se {se}"
    );

    let r = render_model_scene(&scene, &chiang(0.5), &s).unwrap();
    let (mean, _) = mean_se(&fiber_pixels(&r));
    assert!(mean < 0.9, "absorbing: mean {mean}");
}

/// Only the near field: another mode is refused naming the model.
#[test]
fn a_model_render_is_near_field() {
    let mut s = furnace(false);
    s.mode = Mode::Multiscale;
    let scene = Scene::build(&StrandSpec {
        fibers: 4,
        ..Default::default()
    });
    let e = render_model_scene(&scene, &chiang(0.3), &s)
        .unwrap_err()
        .to_string();
    assert!(e.contains("chiang2016") && e.contains("near"), "{e}");
}

fn furfit(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_furfit"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(args)
        .output()
        .unwrap()
}

fn png_text(path: &Path, key: &str) -> String {
    let dec = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = dec.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    reader.next_frame(&mut buf).unwrap();
    reader.finish().unwrap();
    reader
        .info()
        .utf8_text
        .iter()
        .find(|t| t.keyword == key)
        .map(|t| t.get_text().unwrap())
        .unwrap_or_else(|| panic!("no {key} in {}", path.display()))
}

/// 8-bit RGB(A) pixels of a PNG and its channel count.
fn png_pixels(path: &Path) -> (Vec<u8>, usize) {
    let dec = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = dec.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    buf.truncate(info.buffer_size());
    (buf, info.color_type.samples())
}

/// `furfit render --fit fits/chiang2016/red-fox.json` renders the Chiang fit (the file
/// names its model): the PNG says so (model, near field, grey from its one channel, its
/// parameters), is not blank (the lock's pixels differ from the background by more than
/// 20 levels) and is grey as Mitsuba renders the export (r = g = b in every pixel).
#[test]
fn render_of_a_chiang_fit_end_to_end() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("fox.png");
    let o = furfit(&[
        "render",
        "--fit",
        "fits/chiang2016/red-fox.json",
        "--size",
        "16x16",
        "--spp",
        "2",
        "--fibers",
        "400",
        "--cam-dist",
        "1.5",
        "--threads",
        "2",
        "--out",
        out.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("rendered near field"), "{err}");
    let d = png_text(&out, "Description");
    assert!(
        d.contains("chiang2016 fit file fits/chiang2016/red-fox.json (species red-fox")
            && d.contains("; model chiang2016; mode near, 16x16, 2 spp")
            && d.contains("lobes R,TT,TRT,TRRT+")
            && d.contains("colour: grey"),
        "{d}"
    );
    let c = png_text(&out, "Comment");
    assert!(c.contains("\"sigma_a\"") && c.contains("\"beta_n\""), "{c}");
    let (px, n) = png_pixels(&out);
    assert_eq!(px.len(), 16 * 16 * n);
    let (lo, hi) = px
        .chunks(n)
        .fold((255u8, 0u8), |(lo, hi), p| (lo.min(p[1]), hi.max(p[1])));
    assert!(hi - lo > 20, "blank image: green in {lo}..={hi}");
    assert!(
        px.chunks(n).all(|p| p[0] == p[1] && p[1] == p[2]),
        "not grey"
    );
    assert!(out.with_extension("exr").is_file());
    assert!(
        !dir.path().join("fox_R.png").exists(),
        "AOVs of the fur model's lobes"
    );
}

/// A model without a renderer BSDF is refused, naming it and what can be rendered, and
/// nothing is written; `--tint` (the fur model's absorption ratios) is refused for a
/// chiang2016 fit.
#[test]
fn render_refuses_what_it_cannot_render() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("m.png");
    let o = furfit(&[
        "render",
        "--fit",
        "fits/marschner2003/red-fox.json",
        "--size",
        "4x4",
        "--spp",
        "1",
        "--fibers",
        "4",
        "--out",
        out.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(
        err.contains("cannot render model marschner2003")
            && err.contains("no renderer BSDF")
            && err.contains("yan2017, chiang2016"),
        "{err}"
    );
    assert!(!out.exists());
    let o = furfit(&[
        "render",
        "--fit",
        "fits/chiang2016/red-fox.json",
        "--size",
        "4x4",
        "--spp",
        "1",
        "--fibers",
        "4",
        "--tint",
        "melanin",
        "--out",
        out.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("--tint melanin"),
        "{err}"
    );
    assert!(!out.exists());
}
