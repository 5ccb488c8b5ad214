//! The viewer page in headless Chromium (Debian's `chromium`, software GL: SwiftShader
//! through ANGLE), driven by Chromium's own `--dump-dom` and `--screenshot`: the page
//! loads without console messages and reports itself ready, its canvas is not blank, its
//! pixels match `furfit view --still` of the same view, and switching species or light
//! changes the picture.
//!
//! Skipped when no Chromium is found, unless `FURFIT_REQUIRE_RENDERERS=1` (set by
//! `.ci/run`), where that fails. `FURFIT_CHROMIUM` names the browser binary.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

/// Small images: SwiftShader on two shared cores draws 32 shells at ~0.5 us a fragment.
const W: u32 = 240;
const H: u32 = 180;
const FITS: [&str; 2] = ["fits/red-fox.json", "fits/chiang2016/deer.json"];
/// A view lighter than the default (fewer fibers, 64^2 texels), same code paths.
const OPTS: [&str; 6] = ["--res", "64", "--fibers", "1500", "--dirs", "6x12"];

fn required() -> bool {
    std::env::var("FURFIT_REQUIRE_RENDERERS").is_ok_and(|v| v == "1")
}

fn chromium() -> Result<PathBuf, String> {
    let candidates: Vec<String> = match std::env::var("FURFIT_CHROMIUM") {
        Ok(p) => vec![p],
        Err(_) => ["chromium", "chromium-browser", "google-chrome"]
            .map(String::from)
            .to_vec(),
    };
    for c in &candidates {
        if Command::new(c)
            .arg("--version")
            .output()
            .is_ok_and(|o| o.status.success())
        {
            return Ok(PathBuf::from(c));
        }
    }
    Err(format!(
        "no Chromium ({} not found; apt-get install chromium)",
        candidates.join(", ")
    ))
}

/// The browser, or `None` (skip) when it is absent and not required.
fn browser() -> Option<PathBuf> {
    match chromium() {
        Ok(p) => Some(p),
        Err(why) if required() => panic!("FURFIT_REQUIRE_RENDERERS=1 but {why}"),
        Err(why) => {
            eprintln!("skipped: {why}");
            None
        }
    }
}

fn furfit(args: &[&str]) {
    let o = Command::new(env!("CARGO_BIN_EXE_furfit"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .arg("view")
        .args(args)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// The page, written once for all tests of this file.
fn page() -> &'static Path {
    static DIR: OnceLock<tempfile::TempDir> = OnceLock::new();
    DIR.get_or_init(|| {
        let d = tempfile::tempdir().unwrap();
        let mut a = vec![
            "--params",
            FITS[0],
            FITS[1],
            "--out",
            d.path().to_str().unwrap(),
            "--force",
        ];
        a.extend_from_slice(&OPTS);
        furfit(&a);
        d
    })
    .path()
}

/// Run Chromium on the page with `hash`; returns (stdout, stderr).
fn run(browser: &Path, hash: &str, mode: &str) -> (String, String) {
    let profile = tempfile::tempdir().unwrap();
    let url = format!(
        "file://{}/index.html#w={W}&h={H}&ui=0{hash}",
        page().display()
    );
    let o = Command::new(browser)
        .args([
            "--headless=new",
            "--no-sandbox",
            "--use-angle=swiftshader",
            "--enable-unsafe-swiftshader",
            "--hide-scrollbars",
            "--no-first-run",
            "--enable-logging=stderr",
            "--v=0",
            &format!("--user-data-dir={}", profile.path().display()),
            &format!("--window-size={W},{H}"),
            mode,
            &url,
        ])
        .output()
        .unwrap();
    (
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// The page's messages to the console (Chromium logs them as `CONSOLE`); the page itself
/// writes none, so any is an error or a warning.
fn console(stderr: &str) -> Vec<&str> {
    stderr.lines().filter(|l| l.contains(":CONSOLE")).collect()
}

fn screenshot(browser: &Path, hash: &str) -> image::RgbImage {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("shot.png");
    let (_, err) = run(browser, hash, &format!("--screenshot={}", png.display()));
    assert!(console(&err).is_empty(), "console: {:?}", console(&err));
    image::open(&png)
        .unwrap_or_else(|e| panic!("no screenshot ({e}): {err}"))
        .to_rgb8()
}

fn still(species: &str, light: &str) -> image::RgbImage {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("still.png");
    let size = format!("{W}x{H}");
    let mut a = vec![
        "--params",
        FITS[0],
        FITS[1],
        "--still",
        "--species",
        species,
        "--light",
        light,
        "--size",
        &size,
        "--out",
        png.to_str().unwrap(),
    ];
    a.extend_from_slice(&OPTS);
    furfit(&a);
    image::open(&png).unwrap().to_rgb8()
}

/// Mean and 99th percentile of the absolute difference over pixels and channels (8-bit).
fn diff(a: &image::RgbImage, b: &image::RgbImage) -> (f64, u8) {
    assert_eq!(a.dimensions(), b.dimensions());
    let mut d: Vec<u8> = a
        .as_raw()
        .iter()
        .zip(b.as_raw())
        .map(|(x, y)| x.abs_diff(*y))
        .collect();
    let mean = d.iter().map(|&v| v as f64).sum::<f64>() / d.len() as f64;
    d.sort_unstable();
    (mean, d[d.len() * 99 / 100])
}

#[test]
fn page_loads_draws_matches_still_and_switches() {
    let Some(b) = browser() else { return };
    // Loads: no console message, and the page's own status says it drew.
    let (dom, err) = run(&b, "", "--dump-dom");
    assert!(console(&err).is_empty(), "console: {:?}", console(&err));
    assert!(
        dom.contains(">ready<"),
        "status not ready: {}",
        dom.lines()
            .filter(|l| l.contains("status"))
            .collect::<Vec<_>>()
            .join("\n")
    );
    assert!(
        dom.contains("red-fox") && dom.contains("chiang2016"),
        "species list"
    );

    let shot = screenshot(&b, "");
    // Not blank: many distinct colours (a dark fur at 240x180 has ~400), not one.
    let mut colours: Vec<[u8; 3]> = shot.pixels().map(|p| p.0).collect();
    colours.sort_unstable();
    colours.dedup();
    assert!(
        colours.len() > 50,
        "{} distinct colours: blank canvas?",
        colours.len()
    );

    // Matches --still. The page filters 8-bit texels on the GPU and accumulates in half
    // floats; the still does both in f32. Measured (SwiftShader, Chromium 156,
    // 2026-12-07): mean <= 0.11 levels, 99th percentile <= 1. Allowed: mean 1.5, 99 % 8
    // levels, room for another GL's filtering precision while a wrong coefficient,
    // rotation or shell order moves the mean by tens of levels.
    let (mean, p99) = diff(&shot, &still("0", "lobe"));
    eprintln!("page vs still (species 0, lobe): mean {mean:.3}, p99 {p99}");
    assert!(
        mean < 1.5 && p99 <= 8,
        "page vs still: mean {mean:.2}, p99 {p99}"
    );

    // Switching species and light changes the picture (each still matches, too).
    let other = screenshot(&b, "&species=1");
    let (m_species, _) = diff(&shot, &other);
    assert!(
        m_species > 4.0,
        "species switch changed only {m_species:.2} levels"
    );
    let (mean, p99) = diff(&other, &still("1", "lobe"));
    eprintln!("page vs still (species 1, lobe): mean {mean:.3}, p99 {p99}; switch {m_species:.2}");
    assert!(
        mean < 1.5 && p99 <= 8,
        "species 1: page vs still: mean {mean:.2}, p99 {p99}"
    );
    let sky = screenshot(&b, "&light=sky");
    let (m_light, _) = diff(&shot, &sky);
    assert!(
        m_light > 4.0,
        "light switch changed only {m_light:.2} levels"
    );
    let (mean, p99) = diff(&sky, &still("0", "sky"));
    eprintln!("page vs still (species 0, sky): mean {mean:.3}, p99 {p99}; switch {m_light:.2}");
    assert!(
        mean < 1.5 && p99 <= 8,
        "sky: page vs still: mean {mean:.2}, p99 {p99}"
    );
}
