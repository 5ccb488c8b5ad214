//! End-to-end runs of `furfit inspect` on the example files.

use std::path::{Path, PathBuf};
use std::process::Command;

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name)
}

fn inspect(args: &[&std::ffi::OsStr]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_furfit"))
        .arg("inspect")
        .args(args)
        .output()
        .unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn inspect_csv_npz_and_yan_examples() {
    let csv = data("example.csv");
    let npz = data("example.npz");
    let yan = data("yan_theta30.txt");
    let (ok, out, err) = inspect(&[csv.as_os_str(), npz.as_os_str(), yan.as_os_str()]);
    assert!(ok, "stderr: {err}");
    // CSV and its npz twin: 24 samples, 2 invalid (hand-counted in tests/data/example.csv).
    assert_eq!(
        out.matches("samples  24 (22 valid, 2 invalid), 8 with sigma")
            .count(),
        2,
        "{out}"
    );
    assert!(
        out.contains("format   csv") && out.contains("format   npz"),
        "{out}"
    );
    assert!(
        out.contains("theta_i  2 distinct, 0 .. 30 deg, step 30 deg"),
        "{out}"
    );
    assert!(
        out.contains("theta_r  3 distinct, -30 .. 30 deg, step 30 deg"),
        "{out}"
    );
    assert!(
        out.contains("phi      4 distinct, 0 .. 180 deg, step 60 deg"),
        "{out}"
    );
    assert!(
        out.contains("species: test fiber (hand-made example)"),
        "{out}"
    );
    // Yan: 12 rows, two `?`; phi 0, 90, 180, 270 -> -90 .. 180 step 90.
    assert!(out.contains("format   yan-2015 text"), "{out}");
    assert!(out.contains("samples  12 (10 valid, 2 invalid)"), "{out}");
    assert!(
        out.contains("phi      4 distinct, -90 .. 180 deg, step 90 deg"),
        "{out}"
    );
}

#[test]
fn inspect_yan_with_theta_i_option() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("no_theta.txt");
    std::fs::write(&p, "0 0 1\n90 0 2\n").unwrap();
    let (ok, _, err) = inspect(&[p.as_os_str()]);
    assert!(!ok && err.contains("no incident angle"), "{err}");
    let (ok, out, err) = inspect(&[p.as_os_str(), "--theta-i".as_ref(), "-20".as_ref()]);
    assert!(ok, "{err}");
    assert!(
        out.contains("theta_i  1 distinct, -20 .. -20 deg, step -"),
        "{out}"
    );
}

#[test]
fn inspect_bad_file_fails_with_location_but_reports_the_rest() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.csv");
    std::fs::write(&bad, "theta_i,theta_r,phi,value\n0,0,0,1\n0,zero,0,1\n").unwrap();
    let good = data("example.csv");
    let (ok, out, err) = inspect(&[bad.as_os_str(), good.as_os_str()]);
    assert!(!ok);
    assert!(err.contains("bad.csv:3: column 2 (theta_r)"), "{err}");
    assert!(err.contains("1 of 2 file(s)"), "{err}");
    // The good file is still inspected.
    assert!(out.contains("samples  24"), "{out}");
}

/// A reader that stops early (`furfit inspect ... | head -1`) closes the pipe: the command
/// must still finish cleanly (exit 0, no panic message), not die on the failed write.
#[test]
fn closed_stdout_is_not_a_panic() {
    let csv = data("example.csv");
    let mut child = Command::new(env!("CARGO_BIN_EXE_furfit"))
        .arg("inspect")
        .arg(&csv)
        .arg(&csv)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Close the read end before the child writes anything.
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success(),
        "status {:?}, stderr: {err}",
        out.status
    );
    assert!(!err.contains("panicked"), "{err}");
}

/// The convention options convert a CSV as they do a Yan file; an axis option that no
/// input reads is an error naming it, not silently ignored, and given before any output.
#[test]
fn inspect_applies_conventions_to_csv_and_refuses_unused_axes() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("lab.csv");
    std::fs::write(
        &p,
        "theta_i,theta_r,phi,value\n0,10,0,1\n0,20,30,2\n0,30,60,3\n",
    )
    .unwrap();
    let args = |extra: &[&str]| -> Vec<std::ffi::OsString> {
        let mut v = vec![p.clone().into_os_string()];
        v.extend(extra.iter().map(Into::into));
        v
    };
    let run = |a: Vec<std::ffi::OsString>| {
        let refs: Vec<&std::ffi::OsStr> = a.iter().map(|s| s.as_os_str()).collect();
        inspect(&refs)
    };
    let (ok, out, err) = run(args(&[
        "--flip-phi",
        "--phi-offset",
        "90",
        "--flip-theta-r",
    ]));
    assert!(ok, "{err}");
    // phi 0, 30, 60 -> 90, 60, 30; theta_r negated.
    assert!(
        out.contains("phi      3 distinct, 30 .. 90 deg, step 30 deg"),
        "{out}"
    );
    assert!(out.contains("theta_r  3 distinct, -30 .. -10 deg"), "{out}");
    for (opt, val, needle) in [
        (
            "--theta-i",
            "45",
            "--theta-i was given but no input is a lone .npy or Yan",
        ),
        (
            "--theta-r",
            "0:10:10",
            "--theta-r was given but no input is a lone .npy",
        ),
        ("--phi", "0", "--phi was given but no input is a lone .npy"),
        // More than a turn is a typo, not a convention (1e17 wrapped to rounding noise).
        ("--phi-offset", "1e17", "--phi-offset 1e17: must be within"),
    ] {
        let (ok, out, err) = run(args(&[opt, val]));
        assert!(!ok && err.contains(needle), "{opt}: {err}");
        // Refused before any summary (it printed the whole summary, then failed).
        assert!(out.is_empty(), "{opt}: {out}");
    }
}

/// A profile whose angles all lie within +-3.2 loads, with a warning that it looks like
/// radians.
#[test]
fn inspect_warns_about_radians() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("rad.csv");
    std::fs::write(
        &p,
        "theta_i,theta_r,phi,value\n0.5,-0.785,0,1\n0.5,0.785,3.14,2\n",
    )
    .unwrap();
    let (ok, out, err) = inspect(&[p.as_os_str()]);
    assert!(ok, "{err}");
    assert!(
        out.contains("note: warning: every theta_i, theta_r and phi lies within +-3.2")
            && out.contains("look like radians"),
        "{out}"
    );
}

/// An axis whose values are not evenly spaced says its step is only the most common one
/// (theta_i 0, 15, 45 printed "step 15 deg"), or, when no step repeats, gives their range.
#[test]
fn inspect_labels_uneven_steps() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("uneven.csv");
    std::fs::write(
        &p,
        "theta_i,theta_r,phi,value\n0,0,0,1\n15,10,0,1\n30,20,0,1\n60,30,0,1\n",
    )
    .unwrap();
    let (ok, out, err) = inspect(&[p.as_os_str()]);
    assert!(ok, "{err}");
    assert!(
        out.contains("theta_i  4 distinct, 0 .. 60 deg, most common step 15 deg (uneven)"),
        "{out}"
    );
    assert!(
        out.contains("theta_r  4 distinct, 0 .. 30 deg, step 10 deg\n"),
        "{out}"
    );
    std::fs::write(
        &p,
        "theta_i,theta_r,phi,value\n0,0,0,1\n15,10,0,1\n45,20,0,1\n",
    )
    .unwrap();
    let (ok, out, err) = inspect(&[p.as_os_str()]);
    assert!(ok, "{err}");
    assert!(
        out.contains("theta_i  3 distinct, 0 .. 45 deg, uneven steps 15..30 deg\n"),
        "{out}"
    );
    // Values 4e-15 apart are near-duplicates, not a "step 0 deg".
    std::fs::write(
        &p,
        "theta_i,theta_r,phi,value\n0,0,20,1\n0,0,20.000000000000004,1\n",
    )
    .unwrap();
    let (ok, out, err) = inspect(&[p.as_os_str()]);
    assert!(ok, "{err}");
    assert!(
        out.contains(
            "phi      2 distinct, 20 .. 20.000000000000004 deg, step -; 1 near-duplicate \
             pair(s) closer than 5e-10 deg, e.g. 20 and 20.000000000000004\n"
        ),
        "{out}"
    );
}

/// A species folder whose profile carries no label but whose `metadata.json` says the data
/// is synthetic (DATA.md: the folder's metadata file says what the data is): inspect and
/// fit label it synthetic, from the folder and from a file named inside it alike; without
/// that file the data count as measured, and inspect says so.
#[test]
fn folder_metadata_labels_data_synthetic() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("deer");
    std::fs::create_dir(&dir).unwrap();
    let mut csv = String::from("theta_i,theta_r,phi,value\n");
    for (k, phi) in [0, 60, 120, 180].iter().enumerate() {
        csv.push_str(&format!("0,10,{phi},{}\n", 1.0 + k as f64));
    }
    std::fs::write(dir.join("profile.csv"), csv).unwrap();
    let file = dir.join("profile.csv");
    let (ok, out, err) = inspect(&[dir.as_os_str()]);
    assert!(ok, "{err}");
    assert!(
        out.contains("data     not marked synthetic, treated as measured (no synthetic label"),
        "{out}"
    );

    std::fs::write(
        dir.join("metadata.json"),
        r#"{"synthetic": true, "source": "furfit synth + noise"}"#,
    )
    .unwrap();
    for arg in [dir.as_os_str(), file.as_os_str()] {
        let (ok, out, err) = inspect(&[arg]);
        assert!(ok, "{err}");
        assert!(out.contains("data     synthetic"), "{out}");
        assert!(
            out.contains("metadata.json labels the data synthetic"),
            "{out}"
        );
    }
    // A broken metadata file is an error naming it and the line, for the folder and for a
    // file in it alike (it may be what labels the data synthetic).
    std::fs::write(dir.join("metadata.json"), "{\"synthetic\": tru}").unwrap();
    for arg in [dir.as_os_str(), file.as_os_str()] {
        let (ok, _, err) = inspect(&[arg]);
        assert!(!ok);
        assert!(err.contains("metadata.json:1:"), "{err}");
    }
}

/// phi written in 0..360 reads in every format (CSV, npz, lone .npy, Yan), wrapped to
/// (-180, 180] after `--phi-offset`; a CSV's 270 and an npz's `np.arange(0, 360, 5.)` were
/// "out of range [-180, 180]", and the offset could not rescue them.
#[test]
fn inspect_reads_phi_0_to_360_in_every_format() {
    use ndarray::{Array1, ArrayD, IxDyn};
    use ndarray_npy::{NpzWriter, WriteNpyExt};
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let phis: Vec<f64> = (0..72).map(|k| 5.0 * k as f64).collect();
    let mut csv = String::from("theta_i,theta_r,phi,value\n");
    let mut yan = String::from("# theta_i: 0\n");
    for p in &phis {
        csv.push_str(&format!("0,10,{p},1\n"));
        yan.push_str(&format!("{p} 10 1\n"));
    }
    std::fs::write(d.join("a.csv"), csv).unwrap();
    std::fs::write(d.join("a.txt"), yan).unwrap();
    let value = ArrayD::<f64>::from_elem(IxDyn(&[1, 1, 72]), 1.0);
    let mut w = NpzWriter::new(std::fs::File::create(d.join("a.npz")).unwrap());
    w.add_array("theta_i", &Array1::from(vec![0.0])).unwrap();
    w.add_array("theta_r", &Array1::from(vec![10.0])).unwrap();
    w.add_array("phi", &Array1::from(phis.clone())).unwrap();
    w.add_array("value", &value).unwrap();
    w.finish().unwrap();
    value
        .write_npy(std::fs::File::create(d.join("a.npy")).unwrap())
        .unwrap();
    let names = ["a.csv", "a.npz", "a.txt", "a.npy"];
    let run = |extra: &[&str]| {
        let mut args: Vec<std::ffi::OsString> =
            names.iter().map(|n| d.join(n).into_os_string()).collect();
        args.extend(["--theta-i", "0", "--theta-r", "10", "--phi", "0:355:5"].map(Into::into));
        args.extend(extra.iter().map(Into::into));
        let refs: Vec<&std::ffi::OsStr> = args.iter().map(|s| s.as_os_str()).collect();
        inspect(&refs)
    };
    let (ok, out, err) = run(&[]);
    assert!(ok, "{err}");
    assert_eq!(
        out.matches("phi      72 distinct, -175 .. 180 deg, step 5 deg")
            .count(),
        4,
        "{out}"
    );
    // The offset applies before the wrap, alike in every format.
    let (ok, out, err) = run(&["--phi-offset", "-180"]);
    assert!(ok, "{err}");
    assert_eq!(
        out.matches("phi      72 distinct, -175 .. 180 deg, step 5 deg")
            .count(),
        4,
        "{out}"
    );
    // One row: 270 with --phi-offset -180 is 90.
    std::fs::write(d.join("b.csv"), "theta_i,theta_r,phi,value\n0,0,270,1\n").unwrap();
    let b = d.join("b.csv");
    let (ok, out, err) = inspect(&[b.as_os_str(), "--phi-offset".as_ref(), "-180".as_ref()]);
    assert!(ok, "{err}");
    assert!(out.contains("phi      1 distinct, 90 .. 90 deg"), "{out}");
}

/// A folder mixing formats says so (it showed the first file's format only).
#[test]
fn inspect_names_every_format_of_a_mixed_folder() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("a.csv"), "theta_i,theta_r,phi,value\n0,10,0,1\n").unwrap();
    std::fs::write(d.join("b.txt"), "# theta_i: 30\n0 10 1\n").unwrap();
    let (ok, out, err) = inspect(&[d.as_os_str()]);
    assert!(ok, "{err}");
    assert!(out.contains("format   mixed: csv, yan-2015 text"), "{out}");
}

/// A lone .npy (its theta_i axis given by --theta-i) beside a Yan file with its own
/// `# theta_i:` line: the Yan file keeps its line, with a note (it was "a Yan-2015 file
/// holds one incident angle; --theta-i gave 2 values", so the two could not be read
/// together). Without the .npy, the disagreement stays an error.
#[test]
fn theta_i_for_a_lone_npy_leaves_a_headed_yan_file_alone() {
    use ndarray::{ArrayD, IxDyn};
    use ndarray_npy::WriteNpyExt;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    ArrayD::<f64>::from_elem(IxDyn(&[2, 1, 2]), 1.0)
        .write_npy(std::fs::File::create(d.join("v.npy")).unwrap())
        .unwrap();
    std::fs::write(d.join("y.txt"), "# theta_i: 45\nphi theta value\n0 10 1\n").unwrap();
    let (npy, yan) = (d.join("v.npy"), d.join("y.txt"));
    let grids = ["--theta-i", "0,30", "--theta-r", "10", "--phi", "0,90"];
    let mut args = vec![npy.as_os_str(), yan.as_os_str()];
    args.extend(grids.iter().map(std::ffi::OsStr::new));
    let (ok, out, err) = inspect(&args);
    assert!(ok, "{err}");
    assert!(
        out.contains("theta_i  1 distinct, 45 .. 45 deg")
            && out.contains(
                "note: --theta-i 0,30 (the lone .npy's axis) ignored: line 1 gives this \
                 file's theta_i, 45"
            ),
        "{out}"
    );
    let (ok, _, err) = inspect(&[yan.as_os_str(), "--theta-i".as_ref(), "30".as_ref()]);
    assert!(!ok);
    assert!(
        err.contains("y.txt:1: theta_i comment: the file says theta_i 45 but --theta-i is 30"),
        "{err}"
    );
}

/// A file labelled `synthetic: false` is labelled measured, and inspect says so (it said
/// "no synthetic label in the file").
#[test]
fn inspect_names_an_explicit_measured_label() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("lab.csv");
    std::fs::write(
        &p,
        "# synthetic: false\ntheta_i,theta_r,phi,value\n0,10,0,1\n0,10,30,2\n",
    )
    .unwrap();
    let (ok, out, err) = inspect(&[p.as_os_str()]);
    assert!(ok, "{err}");
    assert!(
        out.contains("  data     labelled measured (synthetic: false)\n"),
        "{out}"
    );
}
