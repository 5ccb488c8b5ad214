//! End to end: `furfit export`. Bad input (unknown format, a file that is no fit, a fit
//! whose data are gone, a value a renderer cannot hold, an output in the way) is refused
//! with a message naming it and writes nothing; the pbrt-v4 scene of every shipped
//! species parses back to the fit's values; the committed `exports/` are what the
//! command writes now; a yan2017 fit states what its export costs.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn furfit(dir: &Path) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_furfit"));
    c.current_dir(dir);
    c
}

fn export(dir: &Path, params: &str, to: &str, out: &str, force: bool) -> Output {
    let mut c = furfit(dir);
    c.args(["export", "--params", params, "--to", to, "--out", out]);
    if force {
        c.arg("--force");
    }
    c.output().unwrap()
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

/// A hand-made chiang2016 fit file (no data: only what export reads of a Chiang fit).
fn chiang_fit(dir: &Path, name: &str, eta: f64, sigma_a: f64) -> String {
    let v = serde_json::json!({
        "model": "chiang2016",
        "species": name,
        "nrmse": 0.05,
        "exposure": 1.5,
        "params": {"eta": eta, "beta_m": 0.3, "beta_n": 0.4, "alpha": 2.0, "sigma_a": sigma_a},
    });
    let p = format!("{name}.json");
    std::fs::write(dir.join(&p), serde_json::to_string_pretty(&v).unwrap()).unwrap();
    p
}

fn shipped() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(root().join("fits/chiang2016"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "json"))
        .collect();
    v.sort();
    v
}

#[test]
fn unknown_format_and_non_fits_are_refused_writing_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let fit = chiang_fit(dir.path(), "fox", 1.55, 0.5);
    let o = export(dir.path(), &fit, "arnold", "a.ass", false);
    assert!(!o.status.success());
    let e = text(&o.stderr);
    assert!(
        e.contains("unknown export format 'arnold'") && e.contains("mitsuba"),
        "{e}"
    );
    // A parameter file is not a fit: it has no NRMSE to state.
    let v = serde_json::json!({"model": "chiang2016", "params": {"eta": 1.55, "beta_m": 0.3, "beta_n": 0.4, "alpha": 2.0, "sigma_a": 0.5}});
    std::fs::write(dir.path().join("p.json"), v.to_string()).unwrap();
    let o = export(dir.path(), "p.json", "pbrt", "p.pbrt", false);
    assert!(!o.status.success());
    assert!(
        text(&o.stderr).contains("has no 'nrmse'"),
        "{}",
        text(&o.stderr)
    );
    // A model furfit does not know.
    let v = serde_json::json!({"model": "blinn1977", "params": {}, "nrmse": 0.1});
    std::fs::write(dir.path().join("b.json"), v.to_string()).unwrap();
    let o = export(dir.path(), "b.json", "pbrt", "b.pbrt", false);
    assert!(!o.status.success());
    assert!(
        text(&o.stderr).contains("unknown model 'blinn1977'"),
        "{}",
        text(&o.stderr)
    );
    for f in ["a.ass", "p.pbrt", "b.pbrt"] {
        assert!(!dir.path().join(f).exists(), "{f}");
    }
}

/// A yan2017 fit is exported through its data's angles: without them it cannot be, and
/// the error says why.
#[test]
fn other_model_fit_without_its_data_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(root().join("fits/cat.json")).unwrap())
            .unwrap();
    v["data"]["files"][0]["path"] = "gone/profile.csv".into();
    v["data"]["files"][0]["from_fit"] = "gone/profile.csv".into();
    std::fs::write(dir.path().join("cat.json"), v.to_string()).unwrap();
    let o = export(dir.path(), "cat.json", "mitsuba", "cat.xml", false);
    assert!(!o.status.success());
    let e = text(&o.stderr);
    assert!(
        e.contains("yan2017 fit is exported by fitting chiang2016") && e.contains("cannot be read"),
        "{e}"
    );
    assert!(!dir.path().join("cat.xml").exists());
}

#[test]
fn values_a_renderer_cannot_hold_are_refused_or_clamped_by_name() {
    let dir = tempfile::tempdir().unwrap();
    // eta 1 + 1e-9 is 1 in Mitsuba's single precision, where int_ior == ext_ior throws.
    let fit = chiang_fit(dir.path(), "glass", 1.0 + 1e-9, 0.5);
    let o = export(dir.path(), &fit, "mitsuba", "g.xml", false);
    assert!(!o.status.success());
    let e = text(&o.stderr);
    assert!(
        e.contains("parameter 'eta'") && e.contains("single precision"),
        "{e}"
    );
    assert!(!dir.path().join("g.xml").exists());
    // Blender's Absorption Coefficient socket holds at most 1000: clamped, and said.
    let fit = chiang_fit(dir.path(), "ink", 1.55, 2500.0);
    let o = export(dir.path(), &fit, "cycles", "ink.py", false);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let out = text(&o.stdout);
    assert!(
        out.contains("note: sigma_a (Absorption Coefficient) 2500")
            && out.contains("written as 1000"),
        "{out}"
    );
    let script = std::fs::read_to_string(dir.path().join("ink.py")).unwrap();
    assert!(
        script.contains("# note: sigma_a (Absorption Coefficient) 2500"),
        "{script}"
    );
    assert!(
        script.contains("\"sigma_a\": (1000, 1000, 1000)"),
        "{script}"
    );
}

#[test]
fn existing_output_is_replaced_only_with_force_and_only_an_export() {
    let dir = tempfile::tempdir().unwrap();
    let fit = chiang_fit(dir.path(), "fox", 1.55, 0.5);
    assert!(export(dir.path(), &fit, "mitsuba", "fox.xml", false)
        .status
        .success());
    let first = std::fs::read_to_string(dir.path().join("fox.xml")).unwrap();
    let fit2 = chiang_fit(dir.path(), "fox", 1.6, 0.5);
    let o = export(dir.path(), &fit2, "mitsuba", "fox.xml", false);
    assert!(!o.status.success());
    assert!(text(&o.stderr).contains("--force"), "{}", text(&o.stderr));
    assert_eq!(
        std::fs::read_to_string(dir.path().join("fox.xml")).unwrap(),
        first
    );
    assert!(export(dir.path(), &fit2, "mitsuba", "fox.xml", true)
        .status
        .success());
    assert!(std::fs::read_to_string(dir.path().join("fox.xml"))
        .unwrap()
        .contains("name=\"int_ior\" value=\"1.6\""));
    std::fs::write(dir.path().join("scene.xml"), "<scene version=\"3.0.0\"/>\n").unwrap();
    let o = export(dir.path(), &fit, "mitsuba", "scene.xml", true);
    assert!(!o.status.success());
    assert!(text(&o.stderr).contains("not a file written by furfit export"));
    assert_eq!(
        std::fs::read_to_string(dir.path().join("scene.xml")).unwrap(),
        "<scene version=\"3.0.0\"/>\n"
    );
}

/// pbrt-v4 has no package to load a scene with: the block of every shipped species is
/// parsed back (pbrt's tokens) and every value must be the fit file's, bit for bit.
#[test]
fn pbrt_export_of_every_species_parses_back_to_its_fit() {
    let dir = tempfile::tempdir().unwrap();
    for fit in shipped() {
        let out = dir.path().join("x.pbrt");
        let o = export(
            &root(),
            fit.to_str().unwrap(),
            "pbrt",
            out.to_str().unwrap(),
            true,
        );
        assert!(o.status.success(), "{}", text(&o.stderr));
        let v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&fit).unwrap()).unwrap();
        let p = &v["params"];
        let block = std::fs::read_to_string(&out).unwrap();
        let parsed = furfit::export::pbrt::parse_params(&block, "Material").unwrap();
        assert!(block.contains("Material \"hair\""));
        let get = |name: &str| -> Vec<f64> {
            let (_, _, vals) = parsed
                .iter()
                .find(|(_, n, _)| n == name)
                .unwrap_or_else(|| panic!("{name} in {}", fit.display()));
            vals.iter().map(|x| x.parse().unwrap()).collect()
        };
        for key in ["eta", "beta_m", "beta_n", "alpha"] {
            assert_eq!(
                get(key),
                vec![p[key].as_f64().unwrap()],
                "{key} {}",
                fit.display()
            );
        }
        assert_eq!(get("sigma_a"), vec![p["sigma_a"].as_f64().unwrap(); 3]);
        assert_eq!(parsed.len(), 5);
    }
}

/// `exports/` holds what `furfit export` writes now for every shipped species and format
/// (the marker line, which names the build, aside).
#[test]
fn committed_exports_are_current() {
    let dir = tempfile::tempdir().unwrap();
    let strip = |s: &str| -> Vec<String> {
        s.lines()
            .filter(|l| !l.contains(furfit::export::MARKER))
            .map(str::to_string)
            .collect()
    };
    for fit in shipped() {
        let stem = fit.file_stem().unwrap().to_string_lossy().into_owned();
        let rel = format!("fits/chiang2016/{stem}.json");
        for f in furfit::export::Format::ALL {
            let name = format!("{stem}.{}", f.extension());
            let out = dir.path().join(&name);
            let o = export(&root(), &rel, f.name(), out.to_str().unwrap(), true);
            assert!(o.status.success(), "{}", text(&o.stderr));
            let now = std::fs::read_to_string(&out).unwrap();
            let committed = root().join("exports").join(f.name()).join(&name);
            let was = std::fs::read_to_string(&committed)
                .unwrap_or_else(|e| panic!("{}: {e}", committed.display()));
            assert_eq!(
                strip(&was),
                strip(&now),
                "{} is stale: regenerate exports/ (reports/export.md)",
                committed.display()
            );
        }
    }
}

/// A yan2017 fit becomes the closest chiang2016 material; the command and the file both
/// state the NRMSE it costs, and it is the cost of a real fit (finite, below 100 %).
#[test]
fn yan_fit_export_states_its_cost() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("fox.xml");
    let o = export(
        &root(),
        "fits/red-fox.json",
        "mitsuba",
        out.to_str().unwrap(),
        false,
    );
    assert!(o.status.success(), "{}", text(&o.stderr));
    let stdout = text(&o.stdout);
    let line = stdout
        .lines()
        .find(|l| l.contains("closest chiang2016 material to the yan2017 fit"))
        .unwrap_or_else(|| panic!("{stdout}"));
    let pct: f64 = line
        .split("NRMSE ")
        .nth(1)
        .unwrap()
        .split('%')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!(pct.is_finite() && pct > 0.0 && pct < 100.0, "{line}");
    let xml = std::fs::read_to_string(&out).unwrap();
    assert!(
        xml.contains(&format!("export cost: NRMSE {pct:.3}%")),
        "{xml}"
    );
    assert!(xml.contains("<bsdf version=\"3.0.0\" type=\"hair\""));
}

/// `--scene`: pbrt-v4 gets one file with the material (every value the fit's), the
/// camera, both lights and one curve per fiber of the preview's lock; Mitsuba gets the
/// scene and its curve file (which `--force` replaces only when it reads as one); the
/// material-only formats refuse it.
#[test]
fn scenes_hold_the_material_and_the_lock() {
    let dir = tempfile::tempdir().unwrap();
    let fit = chiang_fit(dir.path(), "fox", 1.55, 0.5);
    let o = furfit(dir.path())
        .args([
            "export", "--params", &fit, "--to", "pbrt", "--scene", "--out", "fox.pbrt",
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o.stderr));
    let scene = std::fs::read_to_string(dir.path().join("fox.pbrt")).unwrap();
    let m = furfit::export::pbrt::parse_params(&scene, "Material").unwrap();
    let get = |name: &str| -> Vec<f64> {
        m.iter()
            .find(|(_, n, _)| n == name)
            .map(|(_, _, v)| v.iter().map(|x| x.parse().unwrap()).collect())
            .unwrap_or_else(|| panic!("{name}"))
    };
    assert_eq!(get("eta"), vec![1.55]);
    assert_eq!(get("beta_m"), vec![0.3]);
    assert_eq!(get("beta_n"), vec![0.4]);
    assert_eq!(get("alpha"), vec![2.0]);
    assert_eq!(get("sigma_a"), vec![0.5; 3]);
    let fibers = furfit::render::scene::StrandSpec::default().fibers;
    assert_eq!(scene.matches("Shape \"curve\"").count(), fibers);
    for d in [
        "LookAt",
        "Camera \"perspective\"",
        "LightSource \"distant\"",
        "LightSource \"infinite\"",
        "WorldBegin",
    ] {
        assert!(scene.contains(d), "{d}");
    }
    let o = furfit(dir.path())
        .args([
            "export", "--params", &fit, "--to", "mitsuba", "--scene", "--out", "fox.xml",
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o.stderr));
    let xml = std::fs::read_to_string(dir.path().join("fox.xml")).unwrap();
    assert!(
        xml.contains("<shape type=\"bsplinecurve\">") && xml.contains("value=\"fox.curves.txt\"")
    );
    assert!(
        xml.contains("<bsdf type=\"hair\" id=\"furfit_fox\">")
            && xml.contains("<ref id=\"furfit_fox\"/>")
    );
    let curves = std::fs::read_to_string(dir.path().join("fox.curves.txt")).unwrap();
    assert_eq!(curves.split("\n\n").count(), fibers);
    // The curve file in the way: refused without --force; a foreign one even with it.
    std::fs::remove_file(dir.path().join("fox.xml")).unwrap();
    let again = |force: bool| {
        let mut c = furfit(dir.path());
        c.args([
            "export", "--params", &fit, "--to", "mitsuba", "--scene", "--out", "fox.xml",
        ]);
        if force {
            c.arg("--force");
        }
        c.output().unwrap()
    };
    assert!(!again(false).status.success());
    assert!(again(true).status.success());
    std::fs::write(dir.path().join("fox.curves.txt"), "my notes\n").unwrap();
    let o = again(true);
    assert!(!o.status.success());
    assert!(text(&o.stderr).contains("not a curve file written by furfit export"));
    let o = furfit(dir.path())
        .args([
            "export", "--params", &fit, "--to", "cycles", "--scene", "--out", "fox.py",
        ])
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(text(&o.stderr).contains("--scene writes Mitsuba 3 and pbrt-v4 scenes"));
    assert!(!dir.path().join("fox.py").exists());
}
