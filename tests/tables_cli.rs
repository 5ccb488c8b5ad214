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
