//! End to end: the model interface on the command line. `fit --model`, `synth --model`
//! and the fit file's `model` key; bad input names the model and the parameter, and
//! writes nothing.

use std::path::Path;
use std::process::{Command, Output};

fn furfit(dir: &Path) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_furfit"));
    c.current_dir(dir);
    c
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A small synthetic profile of `params` (a preset or file) of `model` at `out`.
fn synth(dir: &Path, params: &str, model: &str, out: &str) -> Output {
    furfit(dir)
        .args(["synth", "--params", params, "--model", model])
        .args([
            "--theta-i",
            "0,30",
            "--theta-r",
            "-60:60:10",
            "--phi",
            "-180:180:15",
        ])
        .args(["--out", out])
        .output()
        .unwrap()
}

#[test]
fn unknown_model_is_refused_and_nothing_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let o = synth(dir.path(), "red-fox", "blinn1977", "a.csv");
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(
        e.contains("unknown model 'blinn1977'") && e.contains("yan2017"),
        "{e}"
    );
    assert!(!dir.path().join("a.csv").exists());
    let o = synth(dir.path(), "red-fox", "yan2017", "p.csv");
    assert!(o.status.success(), "{}", stderr(&o));
    let o = furfit(dir.path())
        .args(["fit", "p.csv", "--model", "blinn1977"])
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("unknown model 'blinn1977'"),
        "{}",
        stderr(&o)
    );
    assert!(!dir.path().join("fits").exists());
}

#[test]
fn a_parameter_out_of_its_bound_names_model_and_parameter() {
    let dir = tempfile::tempdir().unwrap();
    for m in furfit::models::MODELS {
        // The first parameter just past its upper bound (or below its lower one).
        let s = &m.specs()[0];
        let bad = if s.upper.is_finite() {
            s.upper + 1.0
        } else {
            s.lower - 1.0
        };
        let mut v = m.presets()[0].values.to_vec();
        v[0] = bad;
        let obj: serde_json::Map<String, serde_json::Value> = m
            .specs()
            .iter()
            .zip(&v)
            .map(|(s, x)| (s.name.to_string(), (*x).into()))
            .collect();
        let mut json = serde_json::Value::Object(obj);
        json["model"] = m.name().into();
        std::fs::write(dir.path().join("bad.json"), json.to_string()).unwrap();
        let o = synth(dir.path(), "bad.json", m.name(), "b.csv");
        assert!(!o.status.success());
        let e = stderr(&o);
        assert!(
            e.contains(s.name) && e.contains("hard bound") && e.contains(m.name()),
            "{}: {e}",
            m.name()
        );
        assert!(!dir.path().join("b.csv").exists());
    }
}

/// A fit file records its model; synth reads the model from it; a file of one model given
/// to another is refused naming both; render (the fur model's) refuses another model's.
#[test]
fn fit_files_name_their_model_and_others_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let o = synth(dir.path(), "mouse", "yan2017", "m.csv");
    assert!(o.status.success(), "{}", stderr(&o));
    let o = furfit(dir.path())
        .args([
            "fit",
            "m.csv",
            "--model",
            "yan2017",
            "--starts",
            "4",
            "--lm-starts",
            "1",
        ])
        .args(["--out", "m.json"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("m.json")).unwrap()).unwrap();
    assert_eq!(v["model"], "yan2017");
    // A file of another model, given to a command of the fur model or to another --model.
    let mut other = v.clone();
    other["model"] = "marschner2003".into();
    std::fs::write(dir.path().join("o.json"), other.to_string()).unwrap();
    let o = furfit(dir.path())
        .args(["render", "--params", "o.json", "--out", "r.png"])
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("of model \"marschner2003\""),
        "{}",
        stderr(&o)
    );
    assert!(!dir.path().join("r.png").exists());
    for m in furfit::models::MODELS
        .iter()
        .filter(|m| m.name() != "yan2017")
    {
        let o = synth(dir.path(), "m.json", m.name(), "x.csv");
        assert!(!o.status.success());
        let e = stderr(&o);
        assert!(e.contains("yan2017") && e.contains(m.name()), "{e}");
        assert!(!dir.path().join("x.csv").exists());
    }
}
