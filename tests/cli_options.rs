//! Command-line options a command cannot use are refused with a message that names them,
//! before any work, instead of being ignored or misread (audit, 2026-12-02).
use std::process::Command;

fn furfit(args: &[&str]) -> (bool, String, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_furfit"))
        .args(args)
        .output()
        .unwrap();
    (
        o.status.success(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// A negative number after an option is read as its value, so the range check says what
/// is wrong (clap took `-0.1` for an unknown flag `-0`).
#[test]
fn negative_values_reach_the_range_checks() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("p.csv");
    std::fs::write(&csv, "theta_i,theta_r,phi,value\n30,10,0,1\n").unwrap();
    let csv = csv.to_str().unwrap();
    let out = dir.path().join("f.json");
    let out = out.to_str().unwrap();
    let synth_out = dir.path().join("s.csv");
    let synth_out = synth_out.to_str().unwrap();
    for (args, want) in [
        (
            vec!["fit", csv, "--out", out, "--floor", "-0.1"],
            "-0.1 is outside [0, 1)",
        ),
        (
            vec!["fit", csv, "--out", out, "--tol", "-1"],
            "--tol must be in",
        ),
        (
            vec!["fit", csv, "--out", out, "--seed", "-1"],
            "'-1' for '--seed",
        ),
        (
            vec!["fit", csv, "--out", out, "--starts", "-1"],
            "'-1' for '--starts",
        ),
        (
            vec![
                "synth",
                "--params",
                "cat",
                "--theta-i",
                "0",
                "--theta-r",
                "0",
                "--phi",
                "0",
                "--tol",
                "-1",
                "--out",
                synth_out,
            ],
            "--tol must be in",
        ),
    ] {
        let (ok, _, err) = furfit(&args);
        assert!(!ok, "{args:?}");
        assert!(err.contains(want), "{args:?}: {err}");
        assert!(!err.contains("unexpected argument"), "{args:?}: {err}");
    }
    assert!(!dir.path().join("f.json").exists());
}

/// Options that only apply to another mode of the command are errors, not ignored.
#[test]
fn options_of_another_mode_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("p.csv");
    std::fs::write(&csv, "theta_i,theta_r,phi,value\n30,10,0,1\n").unwrap();
    let csv = csv.to_str().unwrap();
    for (args, want) in [
        (vec!["fit", csv, "--measurements", "m"], "--all"),
        (
            vec!["fit", csv, "--out", "a.json", "--fits", "f"],
            "cannot be used with",
        ),
        (
            vec!["simulate", "--bench", "--paths", "10"],
            "cannot be used with",
        ),
        (
            vec!["simulate", "--bench", "--params", "dog"],
            "cannot be used with",
        ),
    ] {
        let (ok, out, err) = furfit(&args);
        assert!(!ok, "{args:?}");
        assert!(err.contains(want), "{args:?}: {err}");
        assert!(out.is_empty(), "{args:?}: {out}");
    }
    // A refused hold-out seed prints no summary first.
    let (ok, out, err) = furfit(&["tables", "info", "--seed", "2017", "--holdout", "1"]);
    assert!(!ok && err.contains("--seed must differ"), "{err}");
    assert!(out.is_empty(), "{out}");
}
