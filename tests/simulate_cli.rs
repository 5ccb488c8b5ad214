//! End-to-end runs of `furfit simulate` on a tiny grid.

use std::process::Command;

mod common;

fn furfit() -> Command {
    Command::new(env!("CARGO_BIN_EXE_furfit"))
}

#[test]
fn simulate_writes_labelled_csv_and_metadata() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("fox");
    let status = furfit()
        .args([
            "simulate",
            "--params",
            "red-fox",
            "--theta-i",
            "0,30",
            "--theta-r",
            "-40:40:10",
            "--phi",
            "-180:180:30",
            "--paths",
            "20000",
            "--seed",
            "3",
            "--threads",
            "2",
            "--floor",
            "1e-3",
            "--wedge",
            "5",
            "--drop",
            "0.05",
            "--out",
        ])
        .arg(&out)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&status.stderr);
    assert!(status.status.success(), "stderr: {stderr}");
    // --out did not exist: the run says it made it, as every command does.
    assert!(
        stderr.contains(&format!("note: created folder {}", out.display())),
        "stderr: {stderr}"
    );
    let csv = std::fs::read_to_string(out.join("profile.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert!(lines.contains(&"# synthetic: true"));
    assert!(lines
        .iter()
        .any(|l| l.starts_with("# command: furfit simulate")));
    let header = lines.iter().position(|l| !l.starts_with('#')).unwrap();
    assert_eq!(lines[header], "theta_i,theta_r,phi,value,sigma");
    let rows = &lines[header + 1..];
    // 2 theta_i x 9 theta_r x 12 phi samples, each a full row (-180:180:30 names 12
    // directions: -180 and 180 are one, kept once as 180).
    assert_eq!(rows.len(), 2 * 9 * 12);
    let mut valid = 0;
    for r in rows {
        let f: Vec<&str> = r.split(',').collect();
        assert_eq!(f.len(), 5, "{r}");
        let v: f64 = f[3].parse().unwrap();
        assert!(v >= 0.0);
        if v > 0.0 {
            valid += 1;
            let s: f64 = f[4].parse().unwrap();
            assert!(s >= 0.0);
        }
    }
    assert!(valid > 100, "{valid} valid samples");
    // The occluded cone around the light: theta_r = theta_i = 30, phi = 0 is invalid.
    assert!(rows.iter().any(|r| r.starts_with("30,30,0,0,")));
    let md: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("metadata.json")).unwrap()).unwrap();
    assert_eq!(md["synthetic"], serde_json::Value::Bool(true));
    assert_eq!(md["seed"], 3);
    assert_eq!(md["params"]["kappa"], 0.86);
    assert!(md["command"].as_str().unwrap().contains("--paths 20000"));
}

#[test]
fn simulate_rejects_bad_options() {
    let dir = tempfile::tempdir().unwrap();
    for bad in [
        vec!["--params", "no-such-fiber"],
        vec!["--params", "cat", "--ellipse", "1.5"],
        vec!["--params", "cat", "--theta-i", "95"],
        vec!["--params", "cat", "--drop", "1.2"],
    ] {
        let o = furfit()
            .arg("simulate")
            .args(&bad)
            .args(["--paths", "1000", "--out"])
            .arg(dir.path())
            .output()
            .unwrap();
        assert!(!o.status.success(), "{bad:?} should fail");
        assert!(!String::from_utf8_lossy(&o.stderr).is_empty());
    }
}

/// A tiny, fast `furfit simulate` run writing into `out`, with extra arguments.
fn tiny_run(out: &std::path::Path, extra: &[&str]) -> std::process::Output {
    furfit()
        .args([
            "simulate",
            "--params",
            "red-fox",
            "--theta-i",
            "0,30",
            "--theta-r",
            "-40:40:10",
            "--phi",
            "-180:180:60",
            "--paths",
            "20000",
            "--threads",
            "1",
            "--wedge",
            "5",
            "--out",
        ])
        .arg(out)
        .args(extra)
        .output()
        .unwrap()
}

#[test]
fn simulate_file_extension_picks_the_format() {
    let dir = tempfile::tempdir().unwrap();
    // One folder each: a folder holds one simulation (its metadata.json describes it).
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    for (out, name) in [(&a, "p.csv"), (&b, "p.npz")] {
        let o = tiny_run(out, &["--file", name]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    // A folder that exists gets no note of its creation.
    let again = tiny_run(&a, &["--file", "p.csv", "--force"]);
    let stderr = String::from_utf8_lossy(&again.stderr);
    assert!(
        again.status.success() && !stderr.contains("created folder"),
        "{stderr}"
    );
    let opts = furfit::profile::LoadOptions::default();
    let csv = furfit::profile::load_full(&a.join("p.csv"), &opts).unwrap();
    let npz = furfit::profile::load_full(&b.join("p.npz"), &opts).unwrap();
    assert_eq!(npz.format, furfit::profile::Format::Npz);
    assert!(std::fs::read(b.join("p.npz")).unwrap().starts_with(b"PK"));
    // Same seed, same numbers, whichever format holds them.
    assert_eq!(csv.profile.samples.len(), 2 * 9 * 6);
    assert_eq!(npz.profile.samples, csv.profile.samples);
    assert!(npz.profile.is_synthetic());
    // Invalid samples (the occluded wedge at theta_r = theta_i = 30, phi = 0) too.
    assert!(csv.profile.n_invalid() > 0 && csv.profile.n_valid() > 0);
}

#[test]
fn simulate_refuses_other_extensions_and_paths_outside_out() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("a").join("sim");
    for (name, why) in [
        ("p.txt", ".csv or .npz"),
        ("p.npy", ".csv or .npz"),
        ("profile", ".csv or .npz"),
        ("../escape.csv", "plain file name"),
        ("sub/p.csv", "plain file name"),
    ] {
        let o = tiny_run(&out, &["--file", name]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "--file {name} should fail");
        assert!(
            err.contains(why) && err.contains(name),
            "--file {name}: {err}"
        );
    }
    // Refused before any work: nothing was written, inside --out or next to it.
    assert!(!out.exists());
    assert!(!dir.path().join("a").join("escape.csv").exists());
}

#[test]
fn simulate_writes_profile_and_metadata_or_neither() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("simx");
    // metadata.json cannot be written (a directory is in the way): no profile either.
    std::fs::create_dir_all(out.join("metadata.json")).unwrap();
    let o = tiny_run(&out, &[]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(err.contains("metadata.json"), "{err}");
    let left: Vec<_> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(
        left,
        ["metadata.json"],
        "profile or temporaries left behind"
    );
    // An existing profile from an earlier run is kept as it was.
    std::fs::write(out.join("profile.csv"), "earlier run").unwrap();
    assert!(!tiny_run(&out, &[]).status.success());
    assert_eq!(
        std::fs::read_to_string(out.join("profile.csv")).unwrap(),
        "earlier run"
    );
}

#[test]
fn simulate_refuses_a_one_point_detector_grid() {
    let dir = tempfile::tempdir().unwrap();
    let o = furfit()
        .args(["simulate", "--params", "red-fox", "--theta-i", "0"])
        .args(["--theta-r", "0", "--phi", "0", "--paths", "1000", "--out"])
        .arg(dir.path().join("one"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "a one-point grid should fail");
    assert!(
        err.contains("--theta-r has a single value") && err.contains("at least two values"),
        "{err}"
    );
    assert!(!dir.path().join("one").exists());
}

#[test]
fn simulate_help_shows_the_paths_default() {
    let o = furfit().args(["simulate", "--help"]).output().unwrap();
    let help = String::from_utf8_lossy(&o.stdout);
    let line = help
        .lines()
        .find(|l| l.trim_start().starts_with("--paths"))
        .unwrap_or_default();
    assert!(line.contains("[default: 4000000]"), "{help}");
    // The default does not count as giving --paths: --rel-noise alone is accepted, the
    // two together are not.
    let dir = tempfile::tempdir().unwrap();
    let o = furfit()
        .args(["simulate", "--params", "red-fox", "--rel-noise", "0.5"])
        .args(["--paths", "1000", "--out"])
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("cannot be used with"));
}

#[test]
fn simulate_refuses_a_grid_above_the_sample_limit() {
    let dir = tempfile::tempdir().unwrap();
    let o = furfit()
        .args(["simulate", "--params", "red-fox", "--theta-i", "0,15,30"])
        .args(["--theta-r", "-90:90:0.01", "--phi", "-180:180:0.01"])
        .args(["--paths", "1000", "--out"])
        .arg(dir.path().join("big"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{err}");
    // 3 x 18001 x 36000 (-180 and 180 are one direction), with the limit.
    let limit = furfit::grid::MAX_GRID_SAMPLES.to_string();
    assert!(
        err.contains("1944108000 samples") && err.contains(&limit),
        "{err}"
    );
    assert!(!dir.path().join("big").exists());
}

/// `--theta-i` takes a list in any order and drops repeats, as `synth` does (incidence
/// angles are not detector bins, so they need not be sorted).
#[test]
fn simulate_theta_i_drops_repeats_in_any_order() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("dup");
    let o = furfit()
        .args(["simulate", "--params", "red-fox", "--theta-i", "30,0,0,-0"])
        .args(["--theta-r", "-40:40:40", "--phi", "-180:180:90"])
        .args(["--paths", "2000", "--threads", "1", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let csv = std::fs::read_to_string(out.join("profile.csv")).unwrap();
    let rows: Vec<&str> = csv
        .lines()
        .filter(|l| !l.starts_with('#'))
        .skip(1)
        .collect();
    // 2 distinct theta_i x 3 theta_r x 4 phi.
    assert_eq!(rows.len(), 2 * 3 * 4);
    assert!(rows[0].starts_with("30,") && rows.last().unwrap().starts_with("0,"));
}

/// An existing profile or metadata.json is replaced only with --force, and only when the
/// folder's metadata.json records an earlier furfit simulate run: lab data is never lost.
#[test]
fn simulate_replaces_only_its_own_earlier_output_and_only_with_force() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("sim");
    assert!(tiny_run(&out, &[]).status.success());
    let first = std::fs::read(out.join("profile.csv")).unwrap();
    let o = tiny_run(&out, &["--seed", "9"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("--force"), "{err}");
    assert_eq!(std::fs::read(out.join("profile.csv")).unwrap(), first);
    let o = tiny_run(&out, &["--seed", "9", "--force"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_ne!(std::fs::read(out.join("profile.csv")).unwrap(), first);
    // --force replaces only the profile the record describes: not a lab file copied in,
    // and no second profile beside a record of the first.
    let measured = "theta_i,theta_r,phi,value\n0,0,0,1\n";
    std::fs::write(out.join("lab.csv"), measured).unwrap();
    for name in ["lab.csv", "p.npz"] {
        let o = tiny_run(&out, &["--file", name, "--force"]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            !o.status.success() && err.contains("describes"),
            "{name}: {err}"
        );
    }
    assert_eq!(
        std::fs::read_to_string(out.join("lab.csv")).unwrap(),
        measured
    );
    assert!(!out.join("p.npz").exists());

    // A lab folder: a profile with no simulate record beside it.
    let lab = dir.path().join("lab");
    std::fs::create_dir_all(&lab).unwrap();
    let measured = "# source: lab goniometer\ntheta_i,theta_r,phi,value\n0,0,0,1\n";
    std::fs::write(lab.join("profile.csv"), measured).unwrap();
    for extra in [&[][..], &["--force"]] {
        let o = tiny_run(&lab, extra);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && err.contains("profile.csv"), "{err}");
    }
    assert_eq!(
        std::fs::read_to_string(lab.join("profile.csv")).unwrap(),
        measured
    );
    assert!(!lab.join("metadata.json").exists());

    // A user's own data put in place of the simulated profile (the record beside it
    // still says simulate): refused even with --force (audit, 2026-11-28).
    std::fs::write(out.join("profile.csv"), measured).unwrap();
    let o = tiny_run(&out, &["--force"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("was changed since furfit simulate wrote it"),
        "{err}"
    );
    assert_eq!(
        std::fs::read_to_string(out.join("profile.csv")).unwrap(),
        measured
    );
}

/// One path per angle gives every bin it hits a standard error of 0, and no run may
/// overflow the path total: both refused before any work.
#[test]
fn simulate_refuses_path_counts_without_an_error_estimate_or_beyond_the_limit() {
    let dir = tempfile::tempdir().unwrap();
    for (paths, needle) in [
        ("1", "--paths must be at least 2"),
        ("18446744073709551615", "--paths must be at most 1e12"),
    ] {
        let o = furfit()
            .args(["simulate", "--params", "red-fox", "--theta-i", "0"])
            .args([
                "--theta-r",
                "-40:40:10",
                "--phi",
                "-180:180:60",
                "--paths",
                paths,
            ])
            .arg("--out")
            .arg(dir.path().join("s"))
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{err}");
        assert!(err.contains(needle), "{err}");
    }
}

/// A run whose every sample is invalid is written (its metadata says why) but warned of.
#[test]
fn simulate_warns_when_no_sample_is_valid() {
    let dir = tempfile::tempdir().unwrap();
    let o = tiny_run(&dir.path().join("s"), &["--drop", "0.999999"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("warning: no sample of"), "{err}");
    // Not a terminal here: plain progress lines stand in for the hidden bar.
    assert!(
        err.contains("simulate: 100 % (40000 of 40000 paths)"),
        "{err}"
    );
}

/// A folder no file can be created in fails before the simulation (`/proc` refuses new
/// files even to root).
#[cfg(target_os = "linux")]
#[test]
fn simulate_refuses_an_unwritable_out_before_the_run() {
    let o = tiny_run(std::path::Path::new("/proc/furfit-no"), &[]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("cannot be written"), "{err}");
    // Nothing was traced: no tally line.
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(!out.contains("exited"), "{out}");
}

/// `--threads` has render's bound (100000 hung spawning threads). `--out` is left out, so
/// without the bound the run fails fast on the missing option instead of hanging.
#[test]
fn simulate_threads_are_bounded() {
    let o = furfit()
        .args(["simulate", "--params", "red-fox", "--threads", "100000"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("--threads") && err.contains("100000") && err.contains("0..=1024"),
        "{err}"
    );
}

/// A negative value reaches the option's own check (which names its bound), not clap's
/// "unexpected argument".
#[test]
fn simulate_negative_values_name_their_bound() {
    let dir = tempfile::tempdir().unwrap();
    for (flag, v, bound) in [
        ("--floor", "-0.1", "[0, 1)"),
        ("--drop", "-0.1", "[0, 1)"),
        ("--noise-above", "-1", "[0, 1)"),
        ("--wedge", "-5", "[0, 90)"),
        ("--mult-noise", "-1", ">= 0"),
        ("--shot-photons", "-1", "> 0"),
        ("--ellipse", "-0.5", "[0.01, 1]"),
        // A section flatter than the tracer handles: 1e-300 crashed it (exit 101).
        ("--ellipse", "1e-300", "[0.01, 1]"),
        ("--medulla-eta", "-1.5", "(1, 3]"),
        ("--rel-noise", "-0.1", "(0, 1)"),
    ] {
        let o = furfit()
            .args(["simulate", "--params", "red-fox", "--theta-i", "0"])
            .args(["--theta-r", "-10,10", "--phi", "-10,10"])
            .args([flag, v, "--out"])
            .arg(dir.path().join("s"))
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{flag}: {err}");
        assert!(err.contains(flag) && err.contains(bound), "{flag}: {err}");
    }
    assert!(!dir.path().join("s").exists());
}

/// `--max-paths` bounds the `--rel-noise` pilot too (it traced 524288 paths per angle
/// whatever the bound), and a bound below the usual floor of 65536 is kept, not a panic.
#[test]
fn rel_noise_pilot_respects_max_paths() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("s");
    let o = furfit()
        .args(["simulate", "--params", "red-fox", "--theta-i", "0,30"])
        .args([
            "--theta-r",
            "-40:40:10",
            "--phi",
            "-180:180:30",
            "--threads",
            "1",
        ])
        .args(["--rel-noise", "0.001", "--max-paths", "3000", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("pilot: 3000 paths/angle"), "{err}");
    assert!(err.contains("-> 3000 paths/angle"), "{err}");
    // The cap stops it short of the target, which it says (it wrote a noisier profile
    // unsaid; audit, 2026-12-02), and nothing else warns.
    let warnings: Vec<&str> = err.lines().filter(|l| l.contains("warning")).collect();
    assert_eq!(warnings.len(), 1, "{err}");
    assert!(
        warnings[0].starts_with("warning: --rel-noise 0.001 needs about")
            && warnings[0].contains("--max-paths 3000 stops it short"),
        "{err}"
    );
    let md: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("metadata.json")).unwrap()).unwrap();
    assert_eq!(md["paths_per_theta_i"], 3000);
    assert_eq!(md["rel_noise_setting"]["pilot_paths"], 3000);
    let o = furfit()
        .args(["simulate", "--params", "red-fox", "--rel-noise", "0.01"])
        .args(["--max-paths", "0", "--out"])
        .arg(dir.path().join("zero"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("--max-paths must be in 2..=1e12, found 0"),
        "{err}"
    );
}

/// `--max-paths` only bounds `--rel-noise`: given without it, a warning says so.
#[test]
fn max_paths_without_rel_noise_is_said() {
    let dir = tempfile::tempdir().unwrap();
    let o = tiny_run(&dir.path().join("s"), &["--max-paths", "1000"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains(
            "warning: --max-paths only bounds --rel-noise: ignored (--paths sets the count)"
        ),
        "{err}"
    );
    let o = tiny_run(&dir.path().join("t"), &[]);
    assert!(!String::from_utf8_lossy(&o.stderr).contains("warning"));
}

/// A multi-channel fit is simulated one channel per run: the primary (top-level) channel
/// by default, said on stderr and recorded, or the one `--channel` names.
#[test]
fn simulate_says_which_channel_of_a_fit_it_runs() {
    let dir = tempfile::tempdir().unwrap();
    let fit = common::rgb_fit(dir.path());
    let run = |extra: &[&str], out: &str| {
        furfit()
            .args(["simulate", "--params"])
            .arg(&fit)
            .args(["--theta-i", "0", "--theta-r", "-10:10:10", "--phi", "0,90"])
            .args(["--paths", "2000", "--threads", "1", "--out"])
            .arg(dir.path().join(out))
            .args(extra)
            .output()
            .unwrap()
    };
    let meta = |out: &str| -> serde_json::Value {
        let text = std::fs::read_to_string(dir.path().join(out).join("metadata.json")).unwrap();
        serde_json::from_str(&text).unwrap()
    };
    let o = run(&[], "primary");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("simulating its primary channel r"), "{err}");
    let m = meta("primary");
    assert_eq!(m["channel_of_fit"], "r");
    assert_eq!(m["params"]["sigma_c_a"], 0.1);
    let o = run(&["--channel", "b"], "blue");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let m = meta("blue");
    assert_eq!(m["channel_of_fit"], "b");
    assert_eq!(m["params"]["sigma_c_a"], 1.6);
    let o = run(&["--channel", "x"], "x");
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("has channels r, g, b"));
}
