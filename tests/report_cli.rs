//! `furfit report` on fits made by `furfit fit`: pairing fits with the data they recorded,
//! edited and multi-channel fits, and never replacing files furfit did not write.

mod common;
use common::fit::*;
use std::path::Path;

/// A species whose profile cannot be read any more: `report` still writes what it can but
/// exits non-zero, naming what it skipped (a missing plot must not pass as success).
#[test]
fn report_fails_when_a_part_is_skipped() {
    let tmp = tempfile::tempdir().unwrap();
    make_species(tmp.path(), "mouse");
    fit(tmp.path(), "mouse", "fits/mouse.json", "1");
    let prof = tmp.path().join("measurements/mouse/profile.csv");
    let mut text = std::fs::read_to_string(&prof).unwrap();
    text.push_str("0,0,0,not-a-number\n");
    std::fs::write(&prof, text).unwrap();
    let o = furfit()
        .current_dir(tmp.path())
        .arg("report")
        .output()
        .unwrap();
    fails_with(o, &["skipped mouse", "profile.csv"]);
    assert!(tmp.path().join("reports/nrmse.md").exists());
}

/// A fit made from other files than `measurements/<species>/`: the report plots the data
/// the fit recorded (so a broken `measurements/<species>/` does not stop its Fig. 11) and
/// does not pair that fit with the folder's model-vs-simulation entry.
#[test]
fn report_uses_the_data_a_fit_recorded() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    fit_lab_mouse(root);
    let o = furfit().current_dir(root).arg("report").output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let mvs = std::fs::read_to_string(root.join("reports/model_vs_simulation.md")).unwrap();
    let row = mvs.lines().find(|l| l.starts_with("| mouse |")).unwrap();
    assert!(row.contains("(no fit of this data)"), "{row}");
    // Fig. 11 reads lab/mouse.csv: the species folder's profile may break without it
    // being skipped (the model-vs-simulation entry, which reads the folder, is).
    let prof = root.join("measurements/mouse/profile.csv");
    let mut text = std::fs::read_to_string(&prof).unwrap();
    text.push_str("0,0,0,not-a-number\n");
    std::fs::write(&prof, text).unwrap();
    let o = furfit().current_dir(root).arg("report").output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!err.contains("fig11"), "{err}");
    assert!(err.contains("model_vs_simulation"), "{err}");
}

/// The report checks the data against the SHA-256 digests the fit recorded: changed data,
/// or a species folder standing in for missing files with other data, is not plotted
/// under the fit (the report names it and fails).
#[test]
fn report_refuses_data_that_changed_since_the_fit() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    fit_lab_mouse(root);
    // Edited after the fit (one more valid row): refused.
    let lab = root.join("lab/mouse.csv");
    let mut text = std::fs::read_to_string(&lab).unwrap();
    text.push_str("30,65,0,0.5\n");
    std::fs::write(&lab, text).unwrap();
    let o = furfit().current_dir(root).arg("report").output().unwrap();
    fails_with(o, &["fig11", "lab/mouse.csv", "SHA-256"]);
    // Gone: measurements/mouse/ holds other data (theta_i -20, 20), so refused too.
    std::fs::remove_file(&lab).unwrap();
    let o = furfit().current_dir(root).arg("report").output().unwrap();
    fails_with(o, &["fig11", "measurements/mouse", "SHA-256"]);
}

/// model_vs_simulation pairs a species folder with its fit only while the folder holds the
/// data the fit was made from (the digests fig11 checks too).
#[test]
fn model_vs_simulation_drops_a_fit_of_changed_data() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    make_species(root, "mouse");
    fit(root, "mouse", "fits/mouse.json", "1");
    let row = || {
        let mvs = std::fs::read_to_string(root.join("reports/model_vs_simulation.md")).unwrap();
        mvs.lines()
            .find(|l| l.starts_with("| mouse |"))
            .unwrap()
            .to_string()
    };
    let o = furfit().current_dir(root).arg("report").output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(row().ends_with('%') || row().contains("% |"), "{}", row());
    assert!(!row().contains("refit"), "{}", row());
    let prof = root.join("measurements/mouse/profile.csv");
    let mut text = std::fs::read_to_string(&prof).unwrap();
    text.push_str("20,65,0,0.5\n");
    std::fs::write(&prof, text).unwrap();
    let _ = furfit()
        .current_dir(root)
        .args(["report", "--force"])
        .output()
        .unwrap();
    assert!(
        row().contains("(the data changed since the fit: refit)"),
        "{}",
        row()
    );
}

/// The same samples written otherwise (another build's number formatting and tool line,
/// e.g. the recorded simulate command re-run) are still the fit's data: the report plots
/// them (the fit records each file's samples' SHA-256 beside its bytes').
#[test]
fn report_accepts_the_same_samples_written_otherwise() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    make_species(root, "mouse");
    fit(root, "mouse", "fits/mouse.json", "1");
    let prof = root.join("measurements/mouse/profile.csv");
    let text = std::fs::read_to_string(&prof).unwrap();
    // Values as 1.5e-1 instead of 0.15, and a tool line of another build.
    let rewritten: String = text
        .lines()
        .map(|l| match l.rsplit_once(',') {
            Some((head, v)) if !l.starts_with('#') && v.parse::<f64>().is_ok() => {
                format!("{head},{:e}\n", v.parse::<f64>().unwrap())
            }
            _ => format!("{l}\n"),
        })
        .collect::<String>()
        .replacen("# ", "# tool: furfit 9.9 (git other)\n# ", 1);
    assert_ne!(rewritten, text);
    std::fs::write(&prof, rewritten).unwrap();
    let o = furfit().current_dir(root).arg("report").output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(root.join("reports/fig11_mouse.png").exists());
}

/// Two fits of one species (`mouse.json`, `mouse-v2.json`) get their own figures and
/// table columns, named by their files.
#[test]
fn report_keeps_two_fits_of_one_species_apart() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    make_species(root, "mouse");
    fit(root, "mouse", "fits/mouse.json", "1");
    fit(root, "mouse", "fits/mouse-v2.json", "2");
    let o = furfit().current_dir(root).arg("report").output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for f in ["fig11_mouse.png", "fig11_mouse-v2.png"] {
        assert!(root.join("reports").join(f).exists(), "{f}");
    }
    let md = std::fs::read_to_string(root.join("reports/nrmse.md")).unwrap();
    let head = md.lines().find(|l| l.starts_with("| parameter |")).unwrap();
    assert!(
        head.contains(" mouse |") && head.contains(" mouse-v2 |"),
        "{head}"
    );
}

/// A fit file edited by hand (a parameter tried out) is reported with the NRMSE of the
/// parameters it now holds, recomputed on its data, and a note; an untouched one keeps its
/// own figure. furfit's ledger, which `render --out fits/...` leaves in the fits folder, is
/// not taken for a fit (audit, 2026-11-28: it stopped `report` and `render --all`).
#[test]
fn report_recomputes_the_nrmse_of_an_edited_fit_and_skips_the_ledger() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    make_species(root, "mouse");
    let v = fit(root, "mouse", "fits/mouse.json", "1");
    let fitted = v["nrmse"].as_f64().unwrap();
    let row = |root: &Path| -> String {
        let md = std::fs::read_to_string(root.join("reports/nrmse.md")).unwrap();
        md.lines()
            .find(|l| l.starts_with("| NRMSE (this fit)"))
            .unwrap()
            .to_string()
    };
    let o = furfit().current_dir(root).arg("report").output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(row(root).contains(&format!("{:.1}%", 100.0 * fitted)));
    let md = std::fs::read_to_string(root.join("reports/nrmse.md")).unwrap();
    assert!(!md.contains("records NRMSE"), "{md}");
    // A ledger in the fits folder (written there by furfit itself).
    std::fs::write(root.join("fits/.furfit-outputs.json"), r#"{"files": {}}"#).unwrap();
    let mut edited = v.clone();
    edited["params"]["eta"] = serde_json::json!(2.5);
    std::fs::write(root.join("fits/mouse.json"), edited.to_string()).unwrap();
    let o = furfit().current_dir(root).arg("report").output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(!err.contains(".furfit-outputs.json"), "{err}");
    assert!(err.contains("records NRMSE"), "{err}");
    let shown = row(root);
    assert!(
        !shown.contains(&format!("{:.1}%", 100.0 * fitted)),
        "{shown}"
    );
    let mvs = std::fs::read_to_string(root.join("reports/model_vs_simulation.md")).unwrap();
    assert!(mvs.contains("Note: mouse: the file records NRMSE"), "{mvs}");
    // The recomputed value is the NRMSE of a fit holding every parameter at the edited
    // values (only the exposure solved, as the NRMSE's optimal exposure).
    let vals: Vec<f64> = furfit::ParamId::ALL
        .iter()
        .map(|id| edited["params"][id.spec().name].as_f64().unwrap())
        .collect();
    let mut c = fit_cmd(root);
    c.args(["measurements/mouse", "--out", "check.json"]);
    fix_all_but(&mut c, &vals.try_into().unwrap(), &[]);
    let o = c.output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let check: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(root.join("check.json")).unwrap()).unwrap();
    let want = check["nrmse"].as_f64().unwrap();
    assert!(
        shown.contains(&format!("{:.1}%", 100.0 * want)),
        "{shown} vs {want}"
    );
    // model_vs_simulation takes fits/mouse.json, not an edited copy named before it.
    std::fs::write(root.join("fits/mouse.json"), v.to_string()).unwrap();
    std::fs::write(root.join("fits/a-edit.json"), edited.to_string()).unwrap();
    let o = furfit().current_dir(root).arg("report").output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let mvs = std::fs::read_to_string(root.join("reports/model_vs_simulation.md")).unwrap();
    let mouse = mvs.lines().find(|l| l.starts_with("| mouse |")).unwrap();
    assert!(
        mouse.ends_with(&format!("| {:.2}% |", 100.0 * fitted)),
        "{mouse}"
    );
    std::fs::remove_file(root.join("fits/a-edit.json")).unwrap();
    // A negative recorded NRMSE, or a floor outside [0, 1), is refused as unreadable.
    for (key, bad, why) in [("nrmse", -0.5, "non-negative"), ("floor", 2.0, "[0, 1)")] {
        let mut broken = v.clone();
        if key == "floor" {
            broken["data"]["floor"] = serde_json::json!(bad);
        } else {
            broken[key] = serde_json::json!(bad);
        }
        std::fs::write(root.join("fits/mouse.json"), broken.to_string()).unwrap();
        let o = furfit().current_dir(root).arg("report").output().unwrap();
        fails_with(o, &["mouse.json", why]);
    }
}

/// `report` run from another directory (`--fits`, `--measurements`, `--out` given): the
/// fits' recorded relative paths are found from the project folder above `fits/`, so
/// each fit is still paired with its data.
#[test]
fn report_from_another_directory_finds_the_recorded_data() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path().join("project");
    make_species(&root, "mouse");
    fit(&root, "mouse", "fits/mouse.json", "1");
    let elsewhere = tmp.path().join("elsewhere");
    std::fs::create_dir_all(&elsewhere).unwrap();
    let o = furfit()
        .current_dir(&elsewhere)
        .arg("report")
        .arg("--fits")
        .arg(root.join("fits"))
        .arg("--measurements")
        .arg(root.join("measurements"))
        .arg("--out")
        .arg(root.join("reports"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let mvs = std::fs::read_to_string(root.join("reports/model_vs_simulation.md")).unwrap();
    let row = mvs.lines().find(|l| l.starts_with("| mouse |")).unwrap();
    assert!(!row.contains("no fit"), "{row}");
}

/// `report` replaces its own earlier outputs, but neither a user's file of an output's
/// name nor an output the user edited since; nothing is written then, and `--force`
/// replaces them.
#[test]
fn report_never_replaces_a_file_furfit_did_not_write() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    fit_lab_mouse(root);
    let report = |extra: &[&str]| {
        furfit()
            .current_dir(root)
            .arg("report")
            .args(extra)
            .output()
            .unwrap()
    };
    let o = report(&[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        report(&[]).status.success(),
        "a rerun replaces its own outputs"
    );
    let table = root.join("reports/nrmse.md");
    std::fs::write(&table, "my table\n").unwrap();
    let fig = root.join("reports/fig11_mouse.png");
    let fig_before = std::fs::read(&fig).unwrap();
    let o = report(&[]);
    fails_with(o, &["nrmse.md", "changed since furfit wrote it", "--force"]);
    assert_eq!(std::fs::read_to_string(&table).unwrap(), "my table\n");
    assert_eq!(std::fs::read(&fig).unwrap(), fig_before);
    let o = report(&["--force"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_ne!(std::fs::read_to_string(&table).unwrap(), "my table\n");
}

/// A report killed part-way (Ctrl-C, a crash) has recorded every file it wrote in the
/// ledger as it went, so the next run replaces them without --force (the ledger was
/// written only at the end, and the rerun refused the killed run's own files).
#[test]
fn report_killed_part_way_reruns_without_force() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    fit_lab_mouse(root);
    let mut child = furfit()
        .current_dir(root)
        .arg("report")
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    // Written after nrmse.md was written and recorded: killed once it appears, the run
    // has recorded the table (a kill between a write and its record is not tested).
    let later = root.join("reports/fit_error_vs_time.csv");
    let last = root.join("reports/model_vs_simulation.md");
    let t0 = std::time::Instant::now();
    while !later.exists() && t0.elapsed().as_secs() < 60 {
        std::thread::sleep(std::time::Duration::from_millis(1));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let cut_short = !last.exists();
    let ledger =
        std::fs::read_to_string(root.join("reports/.furfit-outputs.json")).unwrap_or_default();
    if cut_short {
        assert!(ledger.contains("nrmse.md"), "{ledger}");
    } else {
        eprintln!("the report finished before it was killed: only the rerun is checked");
    }
    let o = furfit().current_dir(root).arg("report").output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// A fit of r, g, b channels gets a column and a Fig. 11 per channel in the report, and
/// parameters held by `--fix` are marked as such (not shown like fitted values).
#[test]
fn report_shows_every_channel_and_marks_fixed_parameters() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    let mouse = furfit::FurParams::preset("mouse").unwrap();
    let mut rows = String::from("theta_i,theta_r,phi,value,channel\n");
    for (ch, scale) in [("r", 0.5), ("g", 1.0), ("b", 2.0)] {
        let mut p = mouse;
        p.sigma_c_a *= scale;
        std::fs::write(
            root.join(format!("{ch}.json")),
            p.to_json_value().to_string(),
        )
        .unwrap();
        let out = root.join(format!("{ch}.csv"));
        let o = furfit()
            .args(["synth", "--params"])
            .arg(root.join(format!("{ch}.json")))
            .args([
                "--theta-i",
                "0,30",
                "--theta-r",
                "-60:60:10",
                "--phi",
                "-180:180:20",
            ])
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        for l in std::fs::read_to_string(&out).unwrap().lines() {
            if !l.starts_with('#') && !l.starts_with("theta_i") {
                rows.push_str(&format!("{l},{ch}\n"));
            }
        }
    }
    std::fs::create_dir_all(root.join("fits")).unwrap();
    std::fs::write(root.join("rgb.csv"), rows).unwrap();
    let truth = mouse.to_file_units();
    let mut c = fit_cmd(root);
    c.arg("rgb.csv").args(["--out", "fits/rgb.json"]);
    fix_all_but(&mut c, &truth, &[furfit::ParamId::SigmaCA]);
    let o = c.output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stdout).contains("fixed (--fix): eta, kappa"));
    let o = furfit().current_dir(root).arg("report").output().unwrap();
    // model_vs_simulation has no species folder here: only that part may be missing.
    let csv = std::fs::read_to_string(root.join("reports/nrmse.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some("row,unit,rgb-r,rgb-g,rgb-b"), "{csv}");
    let sca: Vec<f64> = csv
        .lines()
        .find(|l| l.starts_with("sigma_c_a,"))
        .unwrap()
        .split(',')
        .skip(2)
        .map(|v| v.parse().unwrap())
        .collect();
    for (v, scale) in sca.iter().zip([0.5, 1.0, 2.0]) {
        let want = mouse.to_file_units()[furfit::ParamId::SigmaCA.index()] * scale;
        // Noise-free data of the fitter's own model: recovered to ~1e-6.
        assert!((v / want - 1.0).abs() < 1e-4, "{v} vs {want}");
    }
    let fixed = csv.lines().find(|l| l.starts_with("fixed,")).unwrap();
    assert!(fixed.contains("eta;kappa;alpha"), "{fixed}");
    let md = std::fs::read_to_string(root.join("reports/nrmse.md")).unwrap();
    let eta = md.lines().find(|l| l.starts_with("| eta |")).unwrap();
    assert_eq!(eta.matches("(fixed)").count(), 3, "{eta}");
    assert!(!md
        .lines()
        .any(|l| l.starts_with("| sigma_c_a") && l.contains("fixed")));
    for ch in ["r", "g", "b"] {
        assert!(
            root.join(format!("reports/fig11_rgb-{ch}.png")).exists(),
            "{o:?}"
        );
    }
}

/// Data whose synthetic label comes after the fit (a metadata.json added to the folder,
/// the profile unchanged) are reported as synthetic in nrmse.md too, not as unmarked data.
#[test]
fn report_labels_data_synthetic_when_the_label_came_after_the_fit() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    make_species(root, "mouse");
    let dir = root.join("measurements/mouse");
    // No label in the profile (its # lines dropped) nor in the folder.
    let csv = dir.join("profile.csv");
    let text: String = std::fs::read_to_string(&csv)
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with('#'))
        .map(|l| format!("{l}\n"))
        .collect();
    std::fs::write(&csv, text).unwrap();
    std::fs::remove_file(dir.join("metadata.json")).unwrap();
    fit(root, "mouse", "fits/mouse.json", "1");
    let report = || {
        let o = furfit()
            .current_dir(root)
            .args(["report", "--force"])
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        std::fs::read_to_string(root.join("reports/nrmse.md")).unwrap()
    };
    let md = report();
    assert!(
        md.contains("These fits ran on data not marked synthetic (treated as measured"),
        "{md}"
    );
    std::fs::write(dir.join("metadata.json"), r#"{"synthetic": true}"#).unwrap();
    let md = report();
    assert!(md.contains("SYNTHETIC data"), "{md}");
}

/// A fit that left samples out below its `--floor`: nrmse.md says how many, and
/// model_vs_simulation's NRMSE at truth covers the same samples as the fit's NRMSE (it
/// covered every valid sample, whatever the fit used).
#[test]
fn report_counts_samples_below_the_floor_and_compares_like_with_like() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    make_species(root, "mouse");
    // 2 % of the peak leaves out a part of the mouse's tails (checked below).
    let o = fit_cmd(root)
        .args(["measurements/mouse", "--floor", "0.02"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(root.join("fits/mouse.json")).unwrap())
            .unwrap();
    let (valid, below, used) = (
        v["data"]["n_valid"].as_u64().unwrap(),
        v["data"]["n_below_floor"].as_u64().unwrap(),
        v["data"]["n_used"].as_u64().unwrap(),
    );
    assert!(below > 0 && used == valid - below, "{}", v["data"]);
    let o = furfit().current_dir(root).arg("report").output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let md = std::fs::read_to_string(root.join("reports/nrmse.md")).unwrap();
    let want = format!(
        "| samples used (valid, >= floor x peak) | - | {used} of {valid} ({below} below 0.02 x peak left out) |"
    );
    assert!(md.contains(&want), "no '{want}' in\n{md}");
    let mvs = std::fs::read_to_string(root.join("reports/model_vs_simulation.md")).unwrap();
    let row = mvs.lines().find(|l| l.starts_with("| mouse |")).unwrap();
    assert!(
        row.starts_with(&format!(
            "| mouse | SYNTHETIC | {used} ({below} below the floor left out) |"
        )),
        "{row}"
    );
}

/// After a species' data change, `report` draws no figure of it: the earlier run's
/// figure is removed (it would stand for data it no longer shows), `nrmse.md` says its
/// column was not checked against its data, and the run exits 1. A run refused for its
/// inputs (no fit files) leaves no empty output folder.
#[test]
fn report_removes_a_stale_figure_and_makes_no_folder_for_refused_inputs() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    make_species(root, "mouse");
    fit(root, "mouse", "fits/mouse.json", "7");
    let report = || {
        furfit()
            .current_dir(root)
            .args(["report"])
            .output()
            .unwrap()
    };
    assert!(report().status.success());
    let fig = root.join("reports/fig11_mouse.png");
    assert!(fig.exists());
    let data = root.join("measurements/mouse/profile.csv");
    let text = std::fs::read_to_string(&data).unwrap();
    // One value changed: the recorded SHA-256 no longer matches.
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let last = lines.len() - 1;
    lines[last] = lines[last].replacen(",0.", ",0.9", 1);
    std::fs::write(&data, lines.join("\n") + "\n").unwrap();
    let o = report();
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("removed") && err.contains("fig11_mouse.png"),
        "{err}"
    );
    assert!(!fig.exists() && !root.join("reports/fig11_mouse.svg").exists());
    let md = std::fs::read_to_string(root.join("reports/nrmse.md")).unwrap();
    assert!(
        md.contains("Not checked against their data") && md.contains("- mouse:"),
        "{md}"
    );
    // No fit files: refused before the output folder is made.
    std::fs::create_dir(root.join("nofits")).unwrap();
    let o = furfit()
        .current_dir(root)
        .args(["report", "--fits", "nofits", "--out", "fresh"])
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(!root.join("fresh").exists());
}

/// The fits folder as users keep it (audit, 2026-11-28): a damaged fit file is skipped
/// and listed while the others are reported; a fit file named for another species gets a
/// note; a figure of a fit no longer there is removed; the data is found through the
/// path recorded relative to the fit file when the report runs elsewhere; two fits that
/// would write one figure are refused, naming both.
#[test]
fn report_copes_with_the_fits_folder_as_users_keep_it() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    make_species(root, "mouse");
    fit(root, "mouse", "fits/mouse.json", "1");
    std::fs::copy(root.join("fits/mouse.json"), root.join("fits/vole.json")).unwrap();
    std::fs::write(root.join("fits/broken.json"), "{\"nrmse\":").unwrap();
    let o = furfit().current_dir(root).arg("report").output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(!o.status.success(), "{err}");
    assert!(
        err.contains("skipped broken.json: not read: fits/broken.json:1"),
        "{err}"
    );
    assert!(
        err.contains("fits/vole.json records species 'mouse'"),
        "{err}"
    );
    let md = std::fs::read_to_string(root.join("reports/nrmse.md")).unwrap();
    assert!(
        md.contains("## Fit files not read") && md.contains("- broken.json"),
        "{md}"
    );
    assert!(md.contains("| parameter | unit | mouse | vole |"), "{md}");
    assert!(root.join("reports/fig11_vole.png").is_file());

    std::fs::remove_file(root.join("fits/broken.json")).unwrap();
    std::fs::remove_file(root.join("fits/vole.json")).unwrap();
    let o = furfit().current_dir(root).arg("report").output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains(
            "removed reports/fig11_vole.png (a figure of a fit no longer in the fits folder)"
        ),
        "{err}"
    );
    assert!(!root.join("reports/fig11_vole.png").exists());
    assert!(root.join("reports/fig11_mouse.png").is_file());
    // Another command's output of such a name, recorded in the same ledger, is not one of
    // report's figures: it stays (review, 2026-11-28).
    let o = furfit()
        .current_dir(root)
        .args(["render", "--params", "mouse", "--size", "8x8", "--spp", "1"])
        .args([
            "--fibers",
            "20",
            "--no-aovs",
            "--out",
            "reports/fig11_mine.png",
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = furfit().current_dir(root).arg("report").output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "{err}");
    assert!(root.join("reports/fig11_mine.png").is_file(), "{err}");

    // A fit written into a project of its own (deep/fits/) from the root: a report run in
    // deep/ finds the data only through the path recorded relative to the fit file.
    fit(root, "mouse", "deep/fits/mouse.json", "1");
    let o = furfit()
        .current_dir(root.join("deep"))
        .args(["report", "--measurements", "/nonexistent-furfit"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "{err}");
    assert!(root.join("deep/reports/fig11_mouse.png").is_file());

    // Another project with its own, different measurements/mouse: the path as recorded
    // exists there but holds other data, so the report falls back to the fit's own data
    // through from_fit instead of skipping the figure (review, 2026-11-28).
    let other = root.join("other/measurements/mouse");
    std::fs::create_dir_all(&other).unwrap();
    let mut text = std::fs::read_to_string(root.join("measurements/mouse/profile.csv")).unwrap();
    text.push_str("20,65,0,0.5\n");
    std::fs::write(other.join("profile.csv"), text).unwrap();
    let o = furfit()
        .current_dir(root.join("other"))
        .args(["report", "--fits", "../fits", "--out", "rep"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "{err}");
    assert!(root.join("other/rep/fig11_mouse.png").is_file());

    // A fit file damaged after its figure was made: skipped, and its figure is kept.
    std::fs::copy(root.join("fits/mouse.json"), root.join("fits/vole.json")).unwrap();
    let o = furfit().current_dir(root).arg("report").output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    std::fs::write(root.join("fits/vole.json"), "{").unwrap();
    let o = furfit().current_dir(root).arg("report").output().unwrap();
    assert!(!o.status.success());
    assert!(root.join("reports/fig11_vole.png").is_file());
    std::fs::remove_file(root.join("fits/vole.json")).unwrap();

    // mouse-a.json (one channel) and a.json... here: two files, one label.
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(root.join("fits/mouse.json")).unwrap())
            .unwrap();
    let ch = |name: &str| {
        let mut c = v.clone();
        c["data"]["channel"] = name.into();
        c
    };
    let (a, b) = (ch("a"), ch("b"));
    v["channels"] = serde_json::json!([a, b]);
    std::fs::write(root.join("fits/x.json"), v.to_string()).unwrap();
    std::fs::copy(root.join("fits/mouse.json"), root.join("fits/x-a.json")).unwrap();
    let o = furfit().current_dir(root).arg("report").output().unwrap();
    fails_with(o, &["fits/x.json", "'x-a'", "fits/x-a.json", "rename one"]);
}
