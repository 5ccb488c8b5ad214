//! `furfit fit` refusing bad input and bad options: clear errors, named bounds, and checks
//! made before any fitting work (or any file written).

mod common;
use common::fit::*;

#[test]
fn all_invalid_profile_is_a_clear_error() {
    let tmp = tempfile::tempdir().unwrap();
    let p = tmp.path().join("dead.csv");
    let mut text = String::from("theta_i,theta_r,phi,value\n");
    for (i, tr) in [-30, 0, 30].iter().enumerate() {
        text.push_str(&format!(
            "0,{tr},{},{}\n",
            10 * i,
            if i == 0 { "0" } else { "-1" }
        ));
    }
    std::fs::write(&p, text).unwrap();
    let o = furfit()
        .current_dir(tmp.path())
        .args(["fit", "dead.csv"])
        .output()
        .unwrap();
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("no valid sample"), "{err}");
    assert!(!tmp.path().join("fits/dead.json").exists());
}

#[test]
fn bad_fix_is_rejected_with_its_bound() {
    let tmp = tempfile::tempdir().unwrap();
    let o = furfit()
        .current_dir(tmp.path())
        .args(["fit", "x.csv", "--fix", "kappa=1.5"])
        .output()
        .unwrap();
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("kappa") && err.contains("[0, 1)"), "{err}");
}

/// The output must be a .json and may replace only an earlier fit: not a profile, not the
/// species' metadata.json (the true parameters), which survive byte for byte.
#[test]
fn fit_refuses_to_overwrite_data() {
    let tmp = tempfile::tempdir().unwrap();
    make_species(tmp.path(), "mouse");
    let input = tmp.path().join("measurements/mouse/profile.csv");
    let meta = tmp.path().join("measurements/mouse/metadata.json");
    let (before, meta_before) = (
        std::fs::read(&input).unwrap(),
        std::fs::read(&meta).unwrap(),
    );
    let o = fit_cmd(tmp.path())
        .arg("measurements/mouse/profile.csv")
        .args(["--out", "measurements/mouse/profile.csv"])
        .output()
        .unwrap();
    fails_with(o, &["profile.csv", "must end in .json"]);
    let o = fit_cmd(tmp.path())
        .arg("measurements/mouse")
        .args(["--out", "measurements/mouse/metadata.json"])
        .output()
        .unwrap();
    fails_with(o, &["metadata.json", "refusing"]);
    assert_eq!(std::fs::read(&input).unwrap(), before);
    assert_eq!(std::fs::read(&meta).unwrap(), meta_before);
    // An earlier fit is replaced.
    for _ in 0..2 {
        let o = fit_cmd(tmp.path())
            .arg("measurements/mouse")
            .args(["--out", "x.json"])
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
}

/// Too few samples for the unknowns, --weighted without sigmas, and a parameter fixed twice
/// are errors that say why.
#[test]
fn fit_refuses_underdetermined_unweightable_and_double_fix() {
    let tmp = tempfile::tempdir().unwrap();
    std::fs::write(
        tmp.path().join("few.csv"),
        "theta_i,theta_r,phi,value\n0,0,0,1\n0,10,0,2\n0,20,0,0.5\n",
    )
    .unwrap();
    let o = fit_cmd(tmp.path()).arg("few.csv").output().unwrap();
    fails_with(o, &["3 valid sample", "10 free parameter"]);
    assert!(!tmp.path().join("fits/few.json").exists());

    make_species(tmp.path(), "mouse");
    let o = fit_cmd(tmp.path())
        .args(["measurements/mouse", "--weighted"])
        .output()
        .unwrap();
    fails_with(o, &["--weighted", "sigma"]);

    let o = fit_cmd(tmp.path())
        .args([
            "measurements/mouse",
            "--fix",
            "kappa=0.5",
            "--fix",
            "kappa=0.6",
        ])
        .output()
        .unwrap();
    fails_with(o, &["kappa", "twice"]);
}

/// An axis option that no input reads is refused before any fit (it used to be recorded in
/// the fit file as if applied).
#[test]
fn fit_refuses_an_axis_option_no_input_reads() {
    let tmp = tempfile::tempdir().unwrap();
    make_species(tmp.path(), "mouse");
    let o = fit_cmd(tmp.path())
        .args([
            "measurements/mouse/profile.csv",
            "--flip-phi",
            "--phi-offset",
            "90",
        ])
        .args(["--theta-i", "45", "--out", "fits/x.json"])
        .output()
        .unwrap();
    fails_with(
        o,
        &["--theta-i was given but no input is a lone .npy or Yan"],
    );
    assert!(!tmp.path().join("fits/x.json").exists());
}

/// `fit --all` checks every output before the first fit: a non-fit file in the way of the
/// last species used to stop the run after all the others were fitted.
#[test]
fn fit_all_checks_every_output_first() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    make_species(root, "mouse");
    make_species(root, "zebra");
    std::fs::create_dir_all(root.join("fits")).unwrap();
    std::fs::write(root.join("fits/zebra.json"), "{\"mine\": true}").unwrap();
    let o = furfit()
        .current_dir(root)
        .args(["fit", "--all", "--starts", "8", "--lm-starts", "1"])
        .output()
        .unwrap();
    fails_with(o, &["zebra.json", "not a furfit fit file"]);
    assert!(!root.join("fits/mouse.json").exists());
}

/// The global stage's counts are bounded, named with their bound, and checked before the
/// data is even read (`--starts 1000000000` aborted on a failed allocation).
#[test]
fn fit_start_counts_are_bounded_before_any_work() {
    let tmp = tempfile::tempdir().unwrap();
    for (args, needles) in [
        (
            ["--starts", "1000000000"],
            ["--starts 1000000000", "at most 1000000"],
        ),
        (
            ["--lm-starts", "1025"],
            ["--lm-starts 1025", "at most 1024"],
        ),
        (
            ["--subsample", "10000001"],
            ["--subsample 10000001", "at most 10000000"],
        ),
    ] {
        let o = furfit()
            .current_dir(tmp.path())
            .args(["fit", "missing.csv", "--out", "o.json"])
            .args(args)
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(1), "{args:?}");
        fails_with(o, &needles);
    }
    assert!(!tmp.path().join("o.json").exists());
}

/// `--threads` has render's bound (100000 hung spawning threads). The run also has an
/// error of its own (`--lm-starts 0`), so without the bound it fails fast, without the name.
#[test]
fn fit_threads_are_bounded() {
    let o = furfit()
        .args([
            "fit",
            "missing.csv",
            "--lm-starts",
            "0",
            "--threads",
            "100000",
        ])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    fails_with(o, &["--threads", "100000", "0..=1024"]);
}

/// `--out dd.json/` (a trailing slash) is refused before the data is fitted, not by the
/// OS ("Not a directory") after the whole fit.
#[test]
fn fit_refuses_an_out_naming_a_directory_first() {
    let tmp = tempfile::tempdir().unwrap();
    make_species(tmp.path(), "mouse");
    let o = fit_cmd(tmp.path())
        .args(["measurements/mouse", "--out", "dd.json/"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1));
    assert!(
        o.stdout.is_empty(),
        "{}",
        String::from_utf8_lossy(&o.stdout)
    );
    fails_with(o, &["dd.json/", "names a directory, expected a file path"]);
}

/// `--weighted` on data without sigmas names the species once ("fitting s1: s1: s1.csv"
/// before), and with `--all` fails before the species ahead of it are fitted.
#[test]
fn weighted_without_sigma_fails_first_naming_the_species_once() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    make_species(root, "zebra");
    std::fs::copy(
        root.join("measurements/zebra/profile.csv"),
        root.join("s1.csv"),
    )
    .unwrap();
    let o = fit_cmd(root)
        .args(["s1.csv", "--weighted", "--out", "s1.json"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    fails_with(o, &["--weighted needs a sigma > 0"]);
    assert!(
        err.starts_with("error: fitting s1: s1.csv: --weighted"),
        "{err}"
    );
    // It names the first such sample (in angle order: make_species's lowest angles), with
    // its file and line, and that line is the sample.
    assert!(
        err.contains(
            "the first (in angle order) at theta_i -20, theta_r -60, phi -165 (no sigma, s1.csv line 15)"
        ),
        "{err}"
    );
    let text = std::fs::read_to_string(root.join("s1.csv")).unwrap();
    assert!(
        text.lines().nth(14).unwrap().starts_with("-20,-60,-165,"),
        "{text}"
    );
    // A species with sigmas ahead of zebra (without): nothing is fitted.
    let text = std::fs::read_to_string(root.join("s1.csv")).unwrap();
    let with_sigma: Vec<String> = text
        .lines()
        .map(|l| match l {
            l if l.starts_with('#') => l.to_string(),
            "theta_i,theta_r,phi,value" => format!("{l},sigma"),
            l => format!("{l},0.01"),
        })
        .collect();
    std::fs::create_dir_all(root.join("measurements/mouse")).unwrap();
    std::fs::write(
        root.join("measurements/mouse/profile.csv"),
        with_sigma.join("\n") + "\n",
    )
    .unwrap();
    let o = fit_cmd(root)
        .args(["--all", "--weighted"])
        .output()
        .unwrap();
    fails_with(o, &["fitting zebra: ", "--weighted needs a sigma > 0"]);
    assert!(!root.join("fits/mouse.json").exists());
}

/// Two Yan-2015 files without `# theta_i:` lines, fitted together with one `--theta-i`,
/// clash at the same direction: the error names both files with their lines and the
/// direction, and says `--theta-i` applies to every Yan file (the likely cause).
#[test]
fn clashing_yan_files_under_one_theta_i_get_the_hint() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    std::fs::write(root.join("f0.txt"), "0 10 1\n5 10 1\n").unwrap();
    std::fs::write(root.join("f20.txt"), "0 10 2\n").unwrap();
    let o = fit_cmd(root)
        .args(["f0.txt", "f20.txt", "--theta-i", "30", "--out", "f.json"])
        .output()
        .unwrap();
    fails_with(
        o,
        &[
            "f20.txt:1: column 3 (value): duplicate sample (theta_i 30, theta_r 10, phi 0) with",
            "the first copy is in f0.txt:1: column 3 (value);",
            "--theta-i 30 applies to every Yan-2015 file",
        ],
    );
    assert!(!root.join("f.json").exists());
}

/// `fit --all` names every species whose data do not load in one run (not one per run),
/// and says which folders it passed over for holding no profile file; nothing is fitted.
#[test]
fn fit_all_names_every_bad_species_and_the_folders_passed_over() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    for sp in ["mouse", "vole", "zebra"] {
        make_species(root, sp);
    }
    for sp in ["mouse", "zebra"] {
        std::fs::write(
            root.join("measurements").join(sp).join("metadata.json"),
            "{\"synthetic\": tru}",
        )
        .unwrap();
    }
    std::fs::create_dir_all(root.join("measurements/notes")).unwrap();
    // A hidden folder without data (version control) is passed over unsaid.
    std::fs::create_dir_all(root.join("measurements/.git")).unwrap();
    let o = furfit()
        .current_dir(root)
        .args(["fit", "--all", "--starts", "8", "--lm-starts", "1"])
        .output()
        .unwrap();
    fails_with(
        o.clone(),
        &["fitting mouse:", "fitting zebra:", "metadata.json:1:"],
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!err.contains("fitting vole:"), "{err}");
    assert!(
        err.contains("notes: not a species folder (no profile file"),
        "{err}"
    );
    assert!(!err.contains(".git"), "{err}");
    assert!(!root.join("fits/vole.json").exists());
}

/// An output folder no file can be created in fails before the fit, not after it
/// (`/proc` refuses new files even to root, who ignores permission bits).
#[cfg(target_os = "linux")]
#[test]
fn fit_refuses_an_unwritable_out_before_fitting() {
    let tmp = tempfile::tempdir().unwrap();
    make_species(tmp.path(), "mouse");
    let o = fit_cmd(tmp.path())
        .args(["measurements/mouse", "--out", "/proc/furfit-no/x.json"])
        .output()
        .unwrap();
    assert!(
        o.stdout.is_empty(),
        "{}",
        String::from_utf8_lossy(&o.stdout)
    );
    fails_with(
        o,
        &[
            "/proc/furfit-no/x.json",
            "cannot be written",
            "nothing was run",
        ],
    );
}
