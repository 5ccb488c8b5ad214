//! `furfit se-calibration`: option errors come before any work or any folder is made.

use std::process::Command;

#[test]
fn too_few_replicates_are_refused_before_the_folder_is_made() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("deep").join("er");
    let o = Command::new(env!("CARGO_BIN_EXE_furfit"))
        .args(["se-calibration", "--reps", "1", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("--reps must be at least 2, got 1"), "{err}");
    assert!(!tmp.path().join("deep").exists());
}
