//! End-to-end runs of `furfit tables build|info` on the tiny test grid.
use std::process::Command;

fn furfit() -> Command {
    Command::new(env!("CARGO_BIN_EXE_furfit"))
}

#[test]
fn build_then_info_tiny_tables() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("t.bin");
    let run = |seed: &str| {
        let o = furfit()
            .args(["tables", "build", "--tiny", "--paths", "300", "--rank", "3"])
            .args(["--seed", seed, "--out"])
            .arg(&out)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let text = String::from_utf8_lossy(&o.stdout).into_owned();
        assert!(
            text.contains("CP-ALS C^N") && text.contains("rank  3"),
            "{text}"
        );
        std::fs::read(&out).unwrap()
    };
    let a = run("5");
    assert_eq!(a, run("5"), "same seed, same bytes");
    let o = furfit()
        .args([
            "tables",
            "info",
            "--holdout",
            "1",
            "--paths",
            "2000",
            "--file",
        ])
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("rank  3") && text.contains("MC noise"),
        "{text}"
    );

    // A corrupt file is an error naming the file, not a panic.
    let bad = dir.path().join("bad.bin");
    std::fs::write(&bad, &a[..a.len() / 2]).unwrap();
    let o = furfit()
        .args(["tables", "info", "--holdout", "0", "--file"])
        .arg(&bad)
        .output()
        .unwrap();
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("bad.bin") && err.contains("medulla tables"),
        "{err}"
    );
}

/// `build --out` must be a `.bin` path and replaces only a tables file (it overwrote a CSV
/// with binary table data), checked before the Monte Carlo.
#[test]
fn build_replaces_only_tables_files() {
    let dir = tempfile::tempdir().unwrap();
    let build = |out: &std::path::Path| {
        furfit()
            .args([
                "tables", "build", "--tiny", "--paths", "1", "--rank", "1", "--out",
            ])
            .arg(out)
            .output()
            .unwrap()
    };
    let csv = dir.path().join("s1copy.csv");
    let bin = dir.path().join("notes.bin");
    let text = "theta_i,theta_r,phi,value\n0,0,0,1\n";
    for (out, needle) in [
        (&csv, "must end in .bin"),
        (&bin, "not a medulla tables file"),
    ] {
        std::fs::write(out, text).unwrap();
        let o = build(out);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{err}");
        assert!(err.contains("--out") && err.contains(needle), "{err}");
        assert!(
            o.stdout.is_empty(),
            "{}",
            String::from_utf8_lossy(&o.stdout)
        );
        assert_eq!(std::fs::read_to_string(out).unwrap(), text);
    }
    // A tables file is replaced.
    let t = dir.path().join("t.bin");
    assert!(build(&t).status.success());
    let o = build(&t);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// `--target-error` is a relative error in (0, 1): NaN, negative, 0 and 1 are refused
/// before any Monte Carlo, naming the option (a NaN was accepted).
#[test]
fn target_error_is_bounded() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("t.bin");
    for bad in ["NaN", "-1", "0", "1"] {
        let o = furfit()
            .args([
                "tables",
                "build",
                "--tiny",
                "--paths",
                "1",
                "--target-error",
                bad,
                "--out",
            ])
            .arg(&out)
            .output()
            .unwrap();
        assert!(!o.status.success(), "{bad}");
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(e.contains("--target-error"), "{bad}: {e}");
        assert!(!out.exists());
    }
}
