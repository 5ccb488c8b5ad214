//! End to end: `furfit synth` writes a CSV profile that reads back to the library's
//! prediction, and bad input fails with a message.

use std::process::Command;

mod common;
use common::rgb_fit;

fn furfit() -> Command {
    Command::new(env!("CARGO_BIN_EXE_furfit"))
}

/// `synth` of the cat preset on the smallest grid (one theta pair, two phi): quick runs for
/// option and output checks.
fn tiny_synth() -> Command {
    synth_tiny_grid("cat".as_ref())
}

/// `synth --params params` on the smallest grid.
fn synth_tiny_grid(params: &std::ffi::OsStr) -> Command {
    let mut c = furfit();
    c.args(["synth", "--params"]).arg(params).args([
        "--theta-i",
        "0",
        "--theta-r",
        "0",
        "--phi",
        "0,90",
    ]);
    c
}

#[test]
fn synth_csv_round_trip_matches_library_prediction() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("fox.csv");
    let st = furfit()
        .args([
            "synth",
            "--params",
            "red-fox",
            "--theta-i",
            "0,30",
            "--theta-r",
            "-40:40:20",
            "--phi",
            "-180:180:45",
            "--exposure",
            "2.5",
            "--out",
        ])
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    let text = std::fs::read_to_string(&out).unwrap();
    let mut meta = Vec::new();
    let mut rows = Vec::new();
    let mut header = None;
    for line in text.lines() {
        if let Some(m) = line.strip_prefix("# ") {
            meta.push(m.to_string());
        } else if header.is_none() {
            header = Some(line.to_string());
        } else {
            let v: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
            rows.push(v);
        }
    }
    assert_eq!(header.as_deref(), Some("theta_i,theta_r,phi,value"));
    assert!(meta.iter().any(|m| m == "synthetic: true"));
    assert!(meta.iter().any(|m| m.starts_with("params: ")));
    // -180:180:45 names 8 directions: -180 and 180 are one (kept once, as 180).
    assert_eq!(rows.len(), 2 * 5 * 8);
    // Read back equals the library's prediction bit for bit (shortest round-trip
    // formatting), times the exposure.
    let p = furfit::FurParams::preset("red-fox").unwrap();
    let model = furfit::model::FurModel::new(&p);
    let pts: Vec<(f64, f64, f64)> = rows
        .iter()
        .map(|r| (r[0].to_radians(), r[1].to_radians(), r[2].to_radians()))
        .collect();
    let pred = furfit::synth::predict(
        &model,
        &pts,
        furfit::model::LobeSet::ALL,
        &furfit::model::far::FarOptions::default(),
    );
    for (r, v) in rows.iter().zip(&pred) {
        assert_eq!(r[3], 2.5 * v.sum(), "row {r:?}");
        assert!(r[3] > 0.0);
    }
}

#[test]
fn synth_rejects_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.csv");
    // A one-sample synth of `params` with `extra` options.
    let synth = |params: &str, extra: &[&str]| {
        furfit()
            .args(["synth", "--params", params, "--theta-i", "0"])
            .args(["--theta-r", "0", "--phi", "0"])
            .args(extra)
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap()
    };
    let st = synth("no-such-animal", &[]);
    assert!(!st.status.success());
    assert!(String::from_utf8_lossy(&st.stderr).contains("no-such-animal"));
    let st = synth("cat", &["--lobes", "R,XX"]);
    assert!(!st.status.success());
    assert!(String::from_utf8_lossy(&st.stderr).contains("XX"));
    // A negative exposure reaches synth's own check (clap took it for a flag).
    let st = synth("cat", &["--exposure", "-1"]);
    assert_eq!(st.status.code(), Some(1));
    let err = String::from_utf8_lossy(&st.stderr);
    assert!(
        err.contains("--exposure must be a finite number > 0"),
        "{err}"
    );
    assert!(!out.exists());
    // An exposure that underflows the values is blamed on where it came from: the option,
    // or the parameter file's `exposure` key (the message named --exposure for both).
    let params = dir.path().join("p.json");
    let mut v = furfit::FurParams::preset("cat").unwrap().to_json_value();
    v["exposure"] = serde_json::json!(1e-320);
    std::fs::write(&params, v.to_string()).unwrap();
    let st = synth(params.to_str().unwrap(), &[]);
    let err = String::from_utf8_lossy(&st.stderr);
    assert!(
        err.contains("the exposure of") && err.contains("p.json") && err.contains("underflows"),
        "{err}"
    );
    let st = synth("cat", &["--exposure", "3e-308"]);
    let err = String::from_utf8_lossy(&st.stderr);
    assert!(err.contains("--exposure: the value"), "{err}");
    assert!(!out.exists());
    // A tolerance the refinement cannot reach (the audit's 1e-300 ran a fit for minutes).
    let st = synth("cat", &["--tol", "1e-300"]);
    assert_eq!(st.status.code(), Some(1));
    let err = String::from_utf8_lossy(&st.stderr);
    assert!(err.contains("--tol must be in [1e-8, 1)"), "{err}");
    // Out of range the other way: no talk of the split limit.
    let err = String::from_utf8_lossy(&synth("cat", &["--tol", "1"]).stderr).into_owned();
    assert!(
        err.contains("got 1") && !err.contains("split limit"),
        "{err}"
    );
    assert!(synth("cat", &["--tol", "1e-8"]).status.success());
    std::fs::remove_file(&out).unwrap();
    // A phi grid a profile file could not hold, and grid values as written (0.3, not
    // 0.30000000000000004).
    let grid_synth = |theta_r: &str, phi: &str| {
        furfit()
            .args(["synth", "--params", "cat", "--theta-i", "0"])
            .args(["--theta-r", theta_r, "--phi", phi, "--out"])
            .arg(&out)
            .output()
            .unwrap()
    };
    let st = grid_synth("0", "0:720:10");
    let err = String::from_utf8_lossy(&st.stderr);
    assert!(err.contains("outside [-360, 360]"), "{err}");
    assert!(!out.exists());
    assert!(grid_synth("0:0.5:0.1", "0").status.success());
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(
        text.contains(",0.3,") && !text.contains("0000000"),
        "{text}"
    );
}

/// `--scattered-step strict` reaches the library's strict far field bit for bit (so the
/// flag is wired), differs from the default where TTs/TRTs contribute, and a bad step is
/// refused before anything is written.
#[test]
fn synth_scattered_step_strict_and_bad_values() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("strict.csv");
    let run = |step: &str, out: &std::path::Path| {
        furfit()
            .args(["synth", "--params", "red-fox", "--theta-i", "20"])
            .args([
                "--theta-r",
                "-30",
                "--phi",
                "-180:180:30",
                "--lobes",
                "TTs,TRTs",
            ])
            .arg(format!("--scattered-step={step}"))
            .arg("--out")
            .arg(out)
            .output()
            .unwrap()
    };
    let st = run("strict", &out);
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    let text = std::fs::read_to_string(&out).unwrap();
    let rows: Vec<Vec<f64>> = text
        .lines()
        .filter(|l| !l.starts_with('#') && !l.starts_with("theta_i"))
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), 12);
    let model = furfit::model::FurModel::new(&furfit::FurParams::preset("red-fox").unwrap());
    let pts: Vec<(f64, f64, f64)> = rows
        .iter()
        .map(|r| (r[0].to_radians(), r[1].to_radians(), r[2].to_radians()))
        .collect();
    let lobes = furfit::model::LobeSet::SCATTERED;
    let strict = furfit::model::far::FarOptions::strict();
    let want = furfit::synth::predict(&model, &pts, lobes, &strict);
    let default = furfit::synth::predict(&model, &pts, lobes, &Default::default());
    let mut differs = false;
    for ((r, s), d) in rows.iter().zip(&want).zip(&default) {
        assert_eq!(r[3], s.sum(), "row {r:?}");
        differs |= s.sum() != d.sum();
    }
    assert!(differs, "strict step changed nothing");
    for bad in ["0", "-0.1", "2", "fine"] {
        let out = dir.path().join("bad.csv");
        let st = run(bad, &out);
        assert!(!st.status.success(), "--scattered-step {bad} accepted");
        assert!(
            String::from_utf8_lossy(&st.stderr).contains("--scattered-step"),
            "{}",
            String::from_utf8_lossy(&st.stderr)
        );
        assert!(!out.exists());
    }
}

/// Repeated inclinations are written once (a profile holds each direction once), a grid
/// beyond the sample limit is refused before any allocation, and g beyond the medulla
/// tables' range is flagged on stderr.
#[test]
fn synth_dedups_grids_limits_size_and_notes_table_range() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("d.csv");
    let st = furfit()
        .args(["synth", "--params", "red-fox", "--theta-i", "0,0,-0"])
        .args(["--theta-r", "10,10", "--phi", "-180:180:90", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    let p = furfit::profile::load(&out, &Default::default()).unwrap();
    assert_eq!(p.samples.len(), 4, "1 theta_i x 1 theta_r x 4 phi");

    let big = dir.path().join("big.csv");
    let st = furfit()
        .args(["synth", "--params", "red-fox", "--theta-i", "0:90:1"])
        .args(["--theta-r", "-90:90:0.1", "--phi", "-180:180:0.1", "--out"])
        .arg(&big)
        .output()
        .unwrap();
    assert!(!st.status.success());
    let err = String::from_utf8_lossy(&st.stderr);
    assert!(err.contains("samples") && err.contains("limit"), "{err}");
    assert!(!big.exists());

    let mut v = furfit::FurParams::preset("red-fox")
        .unwrap()
        .to_json_value();
    v["g"] = serde_json::json!(0.97);
    let pf = dir.path().join("g.json");
    std::fs::write(&pf, v.to_string()).unwrap();
    let st = furfit()
        .args(["synth", "--params"])
        .arg(&pf)
        .args(["--theta-i", "0", "--theta-r", "0", "--phi", "0", "--out"])
        .arg(dir.path().join("g.csv"))
        .output()
        .unwrap();
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    let err = String::from_utf8_lossy(&st.stderr);
    assert!(err.contains("g = 0.97") && err.contains("range"), "{err}");
}

/// Long jobs check `--out` before the work: a path under a regular file fails at once,
/// naming the file in the way (stability used to fail after its 90 s sweep).
#[test]
fn long_jobs_refuse_an_out_under_a_file_first() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("regular");
    std::fs::write(&file, "x").unwrap();
    for (cmd, out) in [
        (&["stability"][..], file.join("r")),
        (&["bench-model"], file.join("r")),
        (&["report"], file.join("r")),
        (&["fit", "measurements/red-fox"], file.join("f.json")),
    ] {
        let o = Command::new(env!("CARGO_BIN_EXE_furfit"))
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .args(cmd)
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{cmd:?} should fail");
        // Only the up-front check words it so (a failure after the work would be the
        // OS error "Not a directory").
        assert!(err.contains("regular is not a directory"), "{cmd:?}: {err}");
    }
}

/// `--out` is checked before any work: a directory or an extension that picks no format
/// is refused, and an existing file is replaced only with `--force` and only if synth
/// wrote it (a measured profile is not replaced, even with `--force`).
#[test]
fn synth_replaces_only_its_own_profiles_and_only_with_force() {
    let dir = tempfile::tempdir().unwrap();
    let synth = |out: &std::path::Path, extra: &[&str]| {
        tiny_synth()
            .args(extra)
            .arg("--out")
            .arg(out)
            .output()
            .unwrap()
    };
    let refused = |o: &std::process::Output, needles: &[&str]| {
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{err}");
        for n in needles {
            assert!(err.contains(n), "'{n}' not in {err}");
        }
        assert!(
            o.stdout.is_empty(),
            "{}",
            String::from_utf8_lossy(&o.stdout)
        );
    };
    let out = dir.path().join("s.csv");
    assert!(synth(&out, &[]).status.success());
    let first = std::fs::read(&out).unwrap();
    refused(
        &synth(&out, &["--exposure", "2"]),
        &["--out", "s.csv", "exists", "--force"],
    );
    assert_eq!(std::fs::read(&out).unwrap(), first);
    let o = synth(&out, &["--exposure", "2", "--force"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_ne!(std::fs::read(&out).unwrap(), first);

    // A measured profile (no synth source) stays, with or without --force.
    let lab = dir.path().join("profile.csv");
    let text = "# species: dog\ntheta_i,theta_r,phi,value\n0,0,0,1.5\n0,0,90,0.5\n";
    std::fs::write(&lab, text).unwrap();
    for extra in [&[][..], &["--force"]] {
        refused(&synth(&lab, extra), &["profile.csv", "exists"]);
        assert_eq!(std::fs::read_to_string(&lab).unwrap(), text);
    }
    refused(
        &synth(&lab, &["--force"]),
        &["not a profile written by furfit synth"],
    );

    std::fs::create_dir(dir.path().join("d.csv")).unwrap();
    refused(
        &synth(&dir.path().join("d.csv"), &[]),
        &["--out", "directory"],
    );
    refused(
        &synth(&dir.path().join("s.json"), &[]),
        &["--out", "'.json'", ".csv or .npz"],
    );
    assert!(!dir.path().join("s.json").exists());
}

/// Far-field options that change nothing are said on stderr (they were silently
/// ignored): all of them with `--integral near-quadrature`, `--scattered-step` with
/// `--tol none`; the far field's own use of them is quiet.
#[test]
fn synth_warns_about_ignored_far_field_options() {
    let dir = tempfile::tempdir().unwrap();
    let run = |extra: &[&str]| {
        let o = tiny_synth()
            .args(["--force", "--out"])
            .arg(dir.path().join("w.csv"))
            .args(extra)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    let err = run(&[
        "--integral",
        "near-quadrature",
        "--tol",
        "1e-3",
        "--segments",
        "4",
    ]);
    assert_eq!(
        err,
        "warning: --segments, --tol only affect the far field, which --integral \
         near-quadrature does not use: ignored\n"
    );
    // One option: "affects" (it read "--tol only affect").
    assert_eq!(
        run(&["--integral", "near-quadrature", "--tol", "1e-3"]),
        "warning: --tol only affects the far field, which --integral near-quadrature does not \
         use: ignored\n"
    );
    let err = run(&["--tol", "none", "--scattered-step", "strict"]);
    assert_eq!(
        err,
        "warning: --scattered-step only acts in the tolerance mode: ignored with --tol none\n"
    );
    assert_eq!(run(&["--tol", "1e-3", "--scattered-step", "strict"]), "");
    assert_eq!(run(&["--tol", "none", "--segments", "4"]), "");
}

fn csv_values(path: &std::path::Path) -> Vec<(String, f64)> {
    let p = furfit::profile::load(path, &Default::default()).unwrap();
    p.samples
        .iter()
        .map(|s| {
            let name = p.channels.get(s.channel).cloned().unwrap_or_default();
            (name, s.value)
        })
        .collect()
}

/// `synth` of a multi-channel fit writes every channel, each from its own parameters and
/// exposure (not the primary's for all), and says so; `--channel` picks one.
#[test]
fn synth_writes_every_channel_of_a_multi_channel_fit() {
    let dir = tempfile::tempdir().unwrap();
    let fit = rgb_fit(dir.path());
    let run = |extra: &[&str], out: &str| {
        let mut c = synth_tiny_grid(fit.as_os_str());
        c.args(extra).arg("--out").arg(dir.path().join(out));
        c.output().unwrap()
    };
    let o = run(&[], "all.csv");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("has channels r, g, b: one output channel each"),
        "{err}"
    );
    let all = csv_values(&dir.path().join("all.csv"));
    assert_eq!(all.len(), 6, "{all:?}");
    let o = run(&["--channel", "g"], "g.csv");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let g = csv_values(&dir.path().join("g.csv"));
    let all_g: Vec<f64> = all.iter().filter(|(n, _)| n == "g").map(|v| v.1).collect();
    // The same computation for the same channel: equal to the last bit.
    assert_eq!(all_g, g.iter().map(|v| v.1).collect::<Vec<_>>());
    let text = std::fs::read_to_string(dir.path().join("g.csv")).unwrap();
    assert!(text.contains("# channel_of_fit: g"), "{text}");
    // The channels differ (absorption 0.1 / 0.4 / 1.6, exposure 2 / 3 / 5): the g channel
    // is not the r channel rescaled or copied.
    let all_r: Vec<f64> = all.iter().filter(|(n, _)| n == "r").map(|v| v.1).collect();
    assert!(
        (all_g[0] / all_r[0] - 1.5).abs() > 1e-3,
        "{all_g:?} {all_r:?}"
    );
    // g alone equals a parameter file of g's parameters at exposure 3.
    let mut pg = furfit::FurParams::preset("cat").unwrap().to_json_value();
    pg["sigma_c_a"] = serde_json::json!(0.4);
    let pfile = dir.path().join("g_params.json");
    std::fs::write(&pfile, pg.to_string()).unwrap();
    let mut c = synth_tiny_grid(pfile.as_os_str());
    c.args(["--exposure", "3", "--out"])
        .arg(dir.path().join("pg.csv"));
    assert!(c.output().unwrap().status.success());
    let pgv: Vec<f64> = csv_values(&dir.path().join("pg.csv"))
        .iter()
        .map(|v| v.1)
        .collect();
    assert_eq!(pgv, all_g);

    let o = run(&["--channel", "x"], "x.csv");
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("--channel x") && err.contains("has channels r, g, b"),
        "{err}"
    );
    let mut c = tiny_synth();
    c.args(["--channel", "r", "--out"])
        .arg(dir.path().join("cat.csv"));
    let o = c.output().unwrap();
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("not a fit of named channels"));

    // A fit of one named channel: `--channel` takes its name, and the output keeps it
    // with or without `--channel` (it was refused and dropped; audit, 2026-12-02).
    let mut one: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&fit).unwrap()).unwrap();
    one.as_object_mut().unwrap().remove("channels");
    let one_path = dir.path().join("r_only.json");
    std::fs::write(&one_path, one.to_string()).unwrap();
    for (extra, out) in [(&["--channel", "r"][..], "r1.csv"), (&[][..], "r2.csv")] {
        let mut c = synth_tiny_grid(one_path.as_os_str());
        c.args(extra).arg("--out").arg(dir.path().join(out));
        let o = c.output().unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let text = std::fs::read_to_string(dir.path().join(out)).unwrap();
        assert!(text.contains("# channel_of_fit: r"), "{text}");
        let r: Vec<f64> = csv_values(&dir.path().join(out))
            .iter()
            .map(|v| v.1)
            .collect();
        assert_eq!(r, all_r, "{out}");
    }
    let mut c = synth_tiny_grid(one_path.as_os_str());
    c.args(["--channel", "g", "--out"])
        .arg(dir.path().join("g1.csv"));
    let o = c.output().unwrap();
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("has channels r"), "{err}");
}

/// The recorded `# command:` pastes back into a shell: arguments with spaces are quoted,
/// argv[0] is plain `furfit`.
#[test]
fn synth_records_a_runnable_command() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("lt.csv");
    let o = tiny_synth()
        .args(["--lobes", "R, TT", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(&out).unwrap();
    let cmd = text
        .lines()
        .find_map(|l| l.strip_prefix("# command: "))
        .unwrap();
    assert!(
        cmd.starts_with("furfit synth --params cat ") && cmd.contains(" --lobes 'R, TT' --out "),
        "{cmd}"
    );
}

/// An exposure that overflows a value is an error, not a profile with `inf` in it (which
/// the loaders refuse); nothing is written.
#[test]
fn synth_refuses_an_exposure_that_overflows() {
    let dir = tempfile::tempdir().unwrap();
    let mut p = furfit::FurParams::preset("cat").unwrap().to_json_value();
    p["beta_m"] = serde_json::json!(0.01);
    let alpha = p["alpha"].as_f64().unwrap();
    let pfile = dir.path().join("sharp.json");
    std::fs::write(&pfile, p.to_string()).unwrap();
    let out = dir.path().join("o.csv");
    // theta_r at the R lobe's centre (-theta_i + alpha): M_R ~ 2000 there, so the value
    // exceeds 1 and 1e308 times it overflows.
    let o = furfit()
        .args(["synth", "--params"])
        .arg(&pfile)
        .args([
            "--theta-i",
            "0",
            "--theta-r",
            &format!("{alpha}"),
            "--phi",
            "0",
        ])
        .args(["--exposure", "1e308", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("--exposure") && err.contains("overflows"),
        "{err}"
    );
    assert!(!out.exists());
}

/// A parameter file `p.json` in `dir` holding `json`.
fn params_file(dir: &std::path::Path, json: &str) -> std::path::PathBuf {
    let p = dir.join("p.json");
    std::fs::write(&p, json).unwrap();
    p
}

/// A parameter file of heavy absorption and a near-index-matched fiber, whose far tails
/// fall below the normal f64 range.
fn heavy_absorption(dir: &std::path::Path) -> std::path::PathBuf {
    params_file(
        dir,
        r#"{"eta":1.05,"kappa":0.999,"alpha":2,"beta_m":3,"beta_n":0.3,"sigma_c_a":30,"sigma_m_s":0.5,"sigma_m_a":20,"g":0.9,"l":5}"#,
    )
}

/// A value the model itself gives below the normal range (TRT's far tail under heavy
/// absorption: ~4e-320 at theta_i -80, theta_r -85) is written as it is at exposure 1; it
/// was refused as an exposure underflow. It loads back as a valid sample.
#[test]
fn synth_writes_the_models_own_subnormal_values() {
    let dir = tempfile::tempdir().unwrap();
    let params = heavy_absorption(dir.path());
    let out = dir.path().join("t.csv");
    let o = Command::new(env!("CARGO_BIN_EXE_furfit"))
        .arg("synth")
        .arg("--params")
        .arg(&params)
        .args([
            "--theta-i",
            "-80",
            "--theta-r",
            "-85",
            "--phi",
            "-180:180:3",
        ])
        .args(["--lobes", "TRT", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let p = furfit::profile::load(&out, &Default::default()).unwrap();
    let tiny = p
        .samples
        .iter()
        .filter(|s| s.value > 0.0 && s.value < f64::MIN_POSITIVE)
        .count();
    assert!(
        tiny > 0,
        "no subnormal value written; the test no longer reaches the case"
    );
}

/// An exposure small enough to underflow the values is refused (it wrote all-zero, i.e.
/// invalid, or few-bit subnormal values); nothing is written.
#[test]
fn synth_refuses_an_exposure_that_underflows() {
    let dir = tempfile::tempdir().unwrap();
    // 1e-320 is itself subnormal; 1e-307 is not, but the cat's values (~0.06) times it are.
    for k in ["1e-320", "1e-307"] {
        let out = dir.path().join(format!("u{k}.csv"));
        let o = tiny_synth()
            .args(["--exposure", k, "--out"])
            .arg(&out)
            .output()
            .unwrap();
        assert!(!o.status.success(), "{k}");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            err.contains("--exposure") && err.contains("underflow"),
            "{k}: {err}"
        );
        assert!(!out.exists());
    }
}

/// Absorption near the f64 limit at grazing theta_d: TT and TRT are 0, R is finite. The
/// far field's log-attenuation overflowed to -inf and its linear fits gave NaN (reported as
/// an exposure overflow); it now agrees with the near-field quadrature to the tolerance.
#[test]
fn synth_survives_absorption_near_the_f64_limit() {
    let dir = tempfile::tempdir().unwrap();
    let params = params_file(
        dir.path(),
        r#"{"eta":1.49,"kappa":0.86,"alpha":2.64,"beta_m":9.45,"beta_n":17.63,"sigma_c_a":1e300,"sigma_m_s":3.15,"sigma_m_a":0.21,"g":0.79,"l":0.68}"#,
    );
    let values = |model: &str| -> Vec<f64> {
        let out = dir.path().join(format!("{model}.csv"));
        let o = Command::new(env!("CARGO_BIN_EXE_furfit"))
            .arg("synth")
            .arg("--params")
            .arg(&params)
            .args(["--theta-i", "-90", "--theta-r", "90", "--phi", "0,90,180"])
            .args(["--integral", model, "--out"])
            .arg(&out)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let p = furfit::profile::load(&out, &Default::default()).unwrap();
        p.samples.iter().map(|s| s.value).collect()
    };
    let (far, near) = (values("far"), values("near-quadrature"));
    let peak = near.iter().cloned().fold(0.0, f64::max);
    assert!(peak > 0.1, "{near:?}");
    for (f, n) in far.iter().zip(&near) {
        // The far field's tolerance is 1e-4 of the peak; the quadrature's far below.
        assert!((f - n).abs() <= 1e-4 * peak, "far {far:?} vs near {near:?}");
    }
}

/// A signal while `synth` writes its output: the hidden temporary beside the target is
/// removed and the run dies of the signal (so a shell loop around it stops too); the
/// target is not created. (Before, a half-written `.big.csv.tmp-<pid>` stayed until the next
/// write to that path.)
#[test]
fn interrupt_removes_the_temporary() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("big.csv");
    // ~2.6M samples: seconds of writing, so the temporary is seen well before the end.
    let mut child = Command::new(env!("CARGO_BIN_EXE_furfit"))
        .args(["synth", "--params", "red-fox", "--theta-i", "0"])
        .args(["--theta-r=-90:90:0.5", "--phi=-180:180:0.05", "--out"])
        .arg(&out)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let temp = || {
        std::fs::read_dir(dir.path())
            .unwrap()
            .flatten()
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .find(|n| n.starts_with(".big.csv.tmp-"))
    };
    let start = std::time::Instant::now();
    while temp().is_none() {
        assert!(
            child.try_wait().unwrap().is_none(),
            "synth finished before its temporary was seen"
        );
        assert!(start.elapsed().as_secs() < 120, "no temporary after 120 s");
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    // SIGTERM, not SIGINT: a test run started as a background job inherits SIGINT
    // ignored, which furfit rightly keeps (the clean-clone run did so). The handler is
    // the same for both.
    let killed = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    let status = child.wait().unwrap();
    use std::os::unix::process::ExitStatusExt;
    assert_eq!(status.signal(), Some(15), "{status:?}");
    assert_eq!(temp(), None, "the temporary was left behind");
    assert!(!out.exists());
}

/// `--channel all` is the documented default, so it is accepted for a single set of
/// parameters too (a preset), giving the same file as leaving it out.
#[test]
fn channel_all_of_a_single_set_is_the_default() {
    let dir = tempfile::tempdir().unwrap();
    let run = |extra: &[&str], out: &str| {
        let mut c = tiny_synth();
        c.args(extra).arg("--out").arg(dir.path().join(out));
        c.output().unwrap()
    };
    let o = run(&["--channel", "all"], "all.csv");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(run(&[], "plain.csv").status.success());
    let values = |f: &str| {
        std::fs::read_to_string(dir.path().join(f))
            .unwrap()
            .lines()
            .filter(|l| !l.starts_with('#'))
            .map(String::from)
            .collect::<Vec<_>>()
    };
    assert_eq!(values("all.csv"), values("plain.csv"));
}

/// A file named like a preset is read, and a note says so (it used to pass for the
/// preset unsaid).
#[test]
fn a_file_named_like_a_preset_is_read_with_a_note() {
    let dir = tempfile::tempdir().unwrap();
    let mut p = furfit::FurParams::preset("cat").unwrap().to_json_value();
    p["sigma_c_a"] = serde_json::json!(0.9);
    std::fs::write(dir.path().join("human"), p.to_string()).unwrap();
    let o = furfit()
        .current_dir(dir.path())
        .args([
            "synth",
            "--params",
            "human",
            "--theta-i",
            "0",
            "--theta-r",
            "0",
        ])
        .args(["--phi", "0", "--out", "h.csv"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("'human' is read from the file of that name here, not the preset"),
        "{err}"
    );
    let text = std::fs::read_to_string(dir.path().join("h.csv")).unwrap();
    assert!(text.contains("\"sigma_c_a\":0.9"), "{text}");
}

/// An exposure that pushes only a deep tail (below 1e-12 of the peak) under the normal
/// range writes the profile with a note; a grid used to be refused over such samples.
#[test]
fn synth_notes_an_exposure_that_underflows_only_a_deep_tail() {
    let dir = tempfile::tempdir().unwrap();
    let params = heavy_absorption(dir.path());
    let out = dir.path().join("t.csv");
    // Values span ~0.65 down to ~6e-24 here: at 1e-287 the peak stays normal, the tail not.
    let o = furfit()
        .arg("synth")
        .arg("--params")
        .arg(&params)
        .args(["--theta-i=-80,0", "--theta-r=-85:85:5", "--phi=-180:180:3"])
        .args(["--exposure", "1e-287", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("value(s) below 1e-12 of their channel's peak fall below the normal"),
        "{err}"
    );
    assert!(out.exists());
}

/// An output folder is made only once every option is checked (a refused run left it
/// behind), and when it is made, stderr says so.
#[test]
fn output_folder_is_made_after_the_checks_and_said() {
    let dir = tempfile::tempdir().unwrap();
    for (i, bad) in [
        ["--lobes", "XX"],
        ["--integral", "nope"],
        ["--exposure", "-1"],
        ["--exposure", "1e-400"],
    ]
    .iter()
    .enumerate()
    {
        let out = dir.path().join(format!("n{i}/a/s.csv"));
        let st = tiny_synth()
            .args(bad)
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap();
        assert!(!st.status.success(), "{bad:?}");
        assert!(!dir.path().join(format!("n{i}")).exists(), "{bad:?}");
    }
    let out = dir.path().join("made/s.csv");
    let st = tiny_synth().arg("--out").arg(&out).output().unwrap();
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    let err = String::from_utf8_lossy(&st.stderr);
    assert!(err.contains("note: created folder"), "{err}");
    assert!(out.exists());
}
