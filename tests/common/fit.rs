//! The tiny synthesized species, `furfit fit` runs and output checks shared by
//! `fit_cli.rs`, `fit_cli_refusals.rs` and `report_cli.rs`.

use std::path::Path;
use std::process::Command;

pub fn furfit() -> Command {
    Command::new(env!("CARGO_BIN_EXE_furfit"))
}

/// A tiny synthetic species folder: 2 theta_i x 13 theta_r x 25 phi from the far-field
/// model at the mouse preset (phi from -165: -180 and 180 are the same azimuth, and the
/// loader rejects the pair when their values differ in the last bit), via `furfit synth`, plus a metadata.json with the truth.
pub fn make_species(root: &Path, species: &str) {
    let dir = root.join("measurements").join(species);
    std::fs::create_dir_all(&dir).unwrap();
    let out = furfit()
        .args([
            "synth",
            "--params",
            "mouse",
            "--theta-i",
            "-20,20",
            "--theta-r",
            "-60:60:10",
            "--phi",
            "-165:180:15",
            "--exposure",
            "3.5",
            "--out",
        ])
        .arg(dir.join("profile.csv"))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "synth failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let truth = furfit::FurParams::preset("mouse").unwrap().to_json_value();
    std::fs::write(
        dir.join("metadata.json"),
        serde_json::to_string(&serde_json::json!({"synthetic": true, "params": truth})).unwrap(),
    )
    .unwrap();
}

pub fn fit(root: &Path, species: &str, out: &str, seed: &str) -> serde_json::Value {
    let o = furfit()
        .current_dir(root)
        .args(["fit"])
        .arg(Path::new("measurements").join(species))
        .args([
            "--out",
            out,
            "--seed",
            seed,
            "--starts",
            "16",
            "--lm-starts",
            "2",
            "--threads",
            "2",
        ])
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "fit failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    // stderr is a pipe here, not a terminal: the stages are logged one line each (a
    // spinner would draw nothing), so a long fit in a batch log shows where it is.
    let err = String::from_utf8_lossy(&o.stderr);
    for stage in ["global stage: scoring", "multi-start LM:"] {
        assert!(
            err.lines()
                .any(|l| l.starts_with(&format!("{species}: {stage}")) && l.ends_with(" s]")),
            "no '{stage}' line on stderr:\n{err}"
        );
    }
    let text = std::fs::read_to_string(root.join(out)).unwrap();
    serde_json::from_str(&text).unwrap()
}

/// Remove wall-clock fields (documented as the only non-deterministic ones).
pub fn strip_times(v: &mut serde_json::Value) {
    let s = v["solver"].as_object_mut().unwrap();
    for k in ["wall_time_s", "model_time_s", "model_time_share"] {
        assert!(s.remove(k).is_some(), "missing solver.{k}");
    }
    for t in v["trace"].as_array_mut().unwrap() {
        assert!(t.as_object_mut().unwrap().remove("time_s").is_some());
    }
}

pub fn fit_cmd(root: &Path) -> Command {
    let mut c = furfit();
    c.current_dir(root)
        .args(["fit", "--starts", "8", "--lm-starts", "1", "--threads", "1"]);
    c
}

/// `--fix NAME=VALUE` for every parameter except those in `free`, at `values` (file units).
pub fn fix_all_but(c: &mut Command, values: &[f64; 10], free: &[furfit::ParamId]) {
    for id in furfit::ParamId::ALL {
        if !free.contains(&id) {
            c.args([
                "--fix",
                &format!("{}={}", id.spec().name, values[id.index()]),
            ]);
        }
    }
}

pub fn fails_with(o: std::process::Output, needles: &[&str]) {
    assert!(!o.status.success(), "expected a failure");
    let err = String::from_utf8_lossy(&o.stderr);
    for n in needles {
        assert!(err.contains(n), "'{n}' not in: {err}");
    }
    assert!(!err.contains("panicked"), "{err}");
}

/// `measurements/mouse/` (theta_i -20, 20) and a fit `fits/mouse.json` made from other
/// data of the same species, `lab/mouse.csv` (theta_i 0, 30).
pub fn fit_lab_mouse(root: &Path) {
    make_species(root, "mouse");
    std::fs::create_dir_all(root.join("lab")).unwrap();
    let o = furfit()
        .current_dir(root)
        .args(["synth", "--params", "mouse", "--theta-i", "0,30"])
        .args(["--theta-r", "-60:60:10", "--phi", "-165:180:15"])
        .args(["--out", "lab/mouse.csv"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = fit_cmd(root)
        .args(["lab/mouse.csv", "--out", "fits/mouse.json"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}
