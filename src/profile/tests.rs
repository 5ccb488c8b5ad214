use std::path::{Path, PathBuf};

use super::*;
use crate::text::quoted;

#[test]
fn sample_count_limit_names_file_and_line() {
    assert!(check_sample_count(2, 3, Path::new("a.csv"), 9).is_ok());
    let e = check_sample_count(3, 3, Path::new("a.csv"), 9)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("a.csv") && e.contains("line 9: more than 3 samples"),
        "{e}"
    );
}

fn at(theta_i: f64, theta_r: f64, phi: f64) -> Sample {
    Sample::new(theta_i, theta_r, phi, 1.0)
}

/// An unnamed channel merged with named ones used to land silently in the first named
/// channel; now it is an error naming both files. Unnamed parts still merge together.
#[test]
fn merge_refuses_unnamed_with_named_channels() {
    let part = |src: &str, channels: &[&str], phi: f64| Profile {
        samples: vec![at(0.0, 10.0, phi)],
        channels: channels.iter().map(|c| c.to_string()).collect(),
        source: Some(src.into()),
        ..Default::default()
    };
    let e = merge(vec![
        part("rg.csv", &["r"], 0.0),
        part("plain.csv", &[], 5.0),
    ])
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("plain.csv") && e.contains("rg.csv") && e.contains('r'),
        "{e}"
    );
    let (m, _) = merge(vec![part("a.csv", &[], 0.0), part("b.csv", &[], 5.0)]).unwrap();
    assert_eq!((m.samples.len(), m.channels.len()), (2, 0));
}

/// A clash across a merge names the channel by name: `g` is channel 0 of its own files
/// and channel 1 of the merged profile, neither of which the reader can see.
#[test]
fn merge_conflict_names_the_channel() {
    let part = |src: &str, channels: &[&str], value: f64| {
        let mut s = at(0.0, 10.0, 5.0);
        s.value = value;
        Profile {
            samples: vec![s],
            channels: channels.iter().map(|c| c.to_string()).collect(),
            source: Some(src.into()),
            ..Default::default()
        }
    };
    let e = merge(vec![
        part("r.csv", &["r"], 1.0),
        part("g1.csv", &["g"], 1.0),
        part("g2.csv", &["g"], 2.0),
    ])
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("duplicate sample (theta_i 0, theta_r 10, phi 5, channel g) with"),
        "{e}"
    );
}

/// A clash between two files of a merge names both rows by file and line (the files
/// of each part are renumbered into the merged profile's list), and a sample made in
/// memory by its part's source.
#[test]
fn merge_conflict_names_file_and_line_of_both_rows() {
    let part = |file: &str, lines: &[u32], value: f64| Profile {
        samples: lines
            .iter()
            .enumerate()
            .map(|(k, &line)| {
                let mut s = Sample::new(0.0, 10.0, 5.0 * k as f64, value);
                s.origin = Origin { file: 0, line };
                s
            })
            .collect(),
        source: Some(file.into()),
        files: vec![file.into()],
        ..Default::default()
    };
    let e = merge(vec![
        part("a.csv", &[3], 1.0),
        part("b.csv", &[4, 9], 1.0),
        part("c.csv", &[6, 8], 2.0),
    ])
    .unwrap_err()
    .to_string();
    assert!(
        e.starts_with("c.csv line 6: duplicate sample (theta_i 0, theta_r 10, phi 0")
            && e.ends_with("the first copy is in a.csv line 3"),
        "{e}"
    );
    let (m, collapsed) =
        merge(vec![part("a.csv", &[3], 1.0), part("b.csv", &[4, 9], 1.0)]).unwrap();
    assert_eq!(collapsed, 1);
    assert_eq!(m.origin_of(&m.samples[1]).as_deref(), Some("b.csv line 9"));
    let mut memory = part("x", &[0], 2.0);
    memory.files.clear();
    let e = merge(vec![part("a.csv", &[3], 1.0), memory])
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("x: duplicate") && e.ends_with("in a.csv line 3"),
        "{e}"
    );
}

/// Any finite phi in [-360, 360] reads in every format (a CSV's 270 was "out of range
/// [-180, 180]"), wrapped to (-180, 180] after the convention options; values already
/// there keep their bits, so files still round-trip exactly.
#[test]
fn read_phi_takes_one_turn_and_wraps_after_the_offset() {
    let none = LoadOptions::default();
    let r = |v: f64, o: &LoadOptions| read_phi("phi", v, o);
    for (v, want) in [
        (270.0, -90.0),
        (360.0, 0.0),
        (-360.0, 0.0),
        (-180.0, 180.0),
        (355.0, -5.0),
        (-270.0, 90.0),
    ] {
        assert_eq!(r(v, &none), Ok(want), "{v}");
    }
    for v in [0.1, -179.99999999999997, 1.0 / 3.0, 180.0, -0.0] {
        assert_eq!(r(v, &none).unwrap().to_bits(), (v + 0.0).to_bits(), "{v}");
    }
    let e = r(360.5, &none).unwrap_err();
    assert!(e.contains("out of range [-360, 360]"), "{e}");
    assert!(r(f64::NAN, &none).unwrap_err().contains("finite"));
    // The offset applies before the wrap: 270 - 180 = 90 (a range check before the
    // offset refused it), and flip then offset: -270 + 0 -> 90.
    let off = LoadOptions {
        phi_offset: -180.0,
        ..Default::default()
    };
    assert_eq!(r(270.0, &off), Ok(90.0));
    let flip = LoadOptions {
        flip_phi: true,
        ..Default::default()
    };
    assert_eq!(r(270.0, &flip), Ok(90.0));
}

/// Two files of a folder read with one --theta-i clash: the error names both files and
/// the direction, and says --theta-i applied to every Yan file (no hint otherwise).
#[test]
fn folder_clash_under_theta_i_says_it_applies_to_every_yan_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("f0.txt"), "0 10 1\n").unwrap();
    std::fs::write(d.join("f20.txt"), "0 10 2\n").unwrap();
    let opts = LoadOptions {
        theta_i: Some(vec![30.0]),
        ..Default::default()
    };
    let e = load_dir(d, &opts).unwrap_err().to_string();
    assert!(
        e.contains(
            "f20.txt:1: column 3 (value): duplicate sample (theta_i 30, theta_r 10, phi 0) with"
        ) && e.contains("first copy is in")
            && e.contains("f0.txt:1: column 3 (value);")
            && e.contains("--theta-i 30 applies to every Yan-2015 file"),
        "{e}"
    );
    // Without --theta-i (each file says its angle) there is no such hint.
    std::fs::write(d.join("f0.txt"), "# theta_i: 30\n0 10 1\n").unwrap();
    std::fs::write(d.join("f20.txt"), "# theta_i: 30\n0 10 2\n").unwrap();
    let e = load_dir(d, &LoadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("duplicate sample") && !e.contains("--theta-i"),
        "{e}"
    );
}

#[test]
fn radians_look_alike_warns() {
    let prof = |s: Vec<Sample>| Profile {
        samples: s,
        ..Default::default()
    };
    let w =
        radians_warning(&prof(vec![at(0.0, -0.785, 0.5), at(0.52, 0.785, -3.1)])).expect("radians");
    assert!(w.starts_with("warning:") && w.contains("radians"), "{w}");
    assert!(w.contains("largest |angle| 3.1)"), "{w}");
    // Degrees, all zero, or empty: no warning.
    assert!(radians_warning(&prof(vec![at(0.0, 0.0, 0.0), at(0.0, 3.0, 10.0)])).is_none());
    assert!(radians_warning(&prof(vec![at(0.0, 0.0, 0.0)])).is_none());
    assert!(radians_warning(&prof(Vec::new())).is_none());
    // Through the loader, as a note.
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("rad.csv");
    std::fs::write(
        &f,
        "theta_i,theta_r,phi,value\n0,0.785,0,1\n0,-0.785,1.5,2\n",
    )
    .unwrap();
    let l = load_full(&f, &LoadOptions::default()).unwrap();
    assert!(
        l.notes.iter().any(|n| n.contains("look like radians")),
        "{:?}",
        l.notes
    );
}

#[test]
fn utf16_text_is_named() {
    let d = tempfile::tempdir().unwrap();
    for (name, bom) in [("a.csv", [0xFFu8, 0xFE]), ("b.txt", [0xFE, 0xFF])] {
        let p = d.path().join(name);
        let mut bytes = bom.to_vec();
        for ch in "theta_i,theta_r,phi,value\n".encode_utf16() {
            bytes.extend(if bom[0] == 0xFF {
                ch.to_le_bytes()
            } else {
                ch.to_be_bytes()
            });
        }
        std::fs::write(&p, bytes).unwrap();
        let e = load(&p, &LoadOptions::default()).unwrap_err().to_string();
        assert!(
            e.contains(&format!("{name}:1:")) && e.contains("UTF-16"),
            "{e}"
        );
    }
}

#[test]
fn folder_skips_prose_txt_but_not_a_bad_yan_file() {
    assert!(looks_like_yan(b"# theta_i: 30\n\n0 10 1.5\n"));
    assert!(looks_like_yan(b"\xef\xbb\xbf-90 5 ?\r"));
    assert!(!looks_like_yan(b"Measured by A. Lab, 2015.\n0 10 1\n"));
    assert!(!looks_like_yan(b"# only comments\n"));
    // A long text is quoted cut, with its length.
    let long = "x".repeat(10_000);
    assert_eq!(
        quoted(&long),
        format!("'{}...' (10000 characters)", "x".repeat(80))
    );
    assert_eq!(quoted("a\u{feff}"), "'a\\u{feff}'");
    // A notes file is prose however its first line begins (a number and a unit, a
    // date); a profile is one whatever the typo in its first row or header, as its
    // other rows show.
    for first in [
        "1. Calibrate lamp",
        "12 June 2017",
        "2017 notes",
        "June 12, 2017",
        "3 of 5 fibres broke",
        "Phi and theta",
        "Value of phi",
        "20 C freezer",
        "5 V supply",
        "3 x 5 fibres",
        "2017 06 12",
        "1,5 mm hairs",
    ] {
        let notes = format!("{first}\nFox fiber 3, combed.\nSee a.csv.\n");
        assert!(!looks_like_yan(notes.as_bytes()), "{notes}");
    }
    for first in [
        "0 l0 1",
        "0 10deg 1",
        "0 10 abc",
        "0 ten 1",
        "l0 10 1",
        "0 NA 1",
        "phi theta valu",
        "phi theta vlaue",
        "ph theta value",
        "phi theta value extra",
        "0 10 1 5 6",
    ] {
        let data = format!("{first}\n0 20 1.5\n0 30 ?\n");
        assert!(looks_like_yan(data.as_bytes()), "{data}");
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("a.csv"), "theta_i,theta_r,phi,value\n0,10,20,1\n").unwrap();
    std::fs::write(d.join("notes.txt"), "Fox fiber 3, combed.\nSee a.csv.\n").unwrap();
    let l = load_dir(d, &LoadOptions::default()).unwrap();
    assert_eq!(l.profile.samples.len(), 1);
    assert!(
        l.notes
            .contains(&"skipped notes.txt: not a Yan-2015 profile".to_string()),
        "{:?}",
        l.notes
    );
    // A file above the size limit is refused before it is read (a sparse file: no
    // disk used).
    let big = d.join("big.npz");
    std::fs::File::create(&big)
        .unwrap()
        .set_len(MAX_FILE_BYTES + 1)
        .unwrap();
    let e = load(&big, &LoadOptions::default()).unwrap_err().to_string();
    assert!(
        e.contains("a profile file may hold at most 1073741824 bytes"),
        "{e}"
    );
    std::fs::remove_file(&big).unwrap();
    // Data a user may have meant to include is named in a note, not read.
    std::fs::create_dir(d.join("sub")).unwrap();
    std::fs::write(
        d.join("sub/b.csv"),
        "theta_i,theta_r,phi,value\n0,10,30,1\n",
    )
    .unwrap();
    std::fs::write(d.join(".c.csv"), "theta_i,theta_r,phi,value\n0,10,40,1\n").unwrap();
    std::fs::create_dir(d.join(".git")).unwrap();
    let l = load_dir(d, &LoadOptions::default()).unwrap();
    assert_eq!(l.profile.samples.len(), 1);
    for note in [
        "skipped sub/: subfolders are not read",
        "skipped .c.csv: hidden file",
    ] {
        assert!(l.notes.contains(&note.to_string()), "{:?}", l.notes);
    }
    assert!(!l.notes.iter().any(|n| n.contains(".git")), "{:?}", l.notes);
    // Named on its own it is still read as Yan, and fails.
    let e = load(&d.join("notes.txt"), &LoadOptions::default()).unwrap_err();
    assert!(e.to_string().contains("notes.txt:1:"), "{e}");
    // A Yan file with a genuine bad row (after good ones) is still an error.
    std::fs::write(d.join("y.txt"), "# theta_i: 0\n0 10 1\n5 10 x\n").unwrap();
    let e = load_dir(d, &LoadOptions::default()).unwrap_err();
    assert!(e.to_string().contains("y.txt:3:"), "{e}");
    // So is one whose FIRST row has a typo: read and reported, never skipped.
    for first in ["0 10 1,5", "0, 10, 1", "0 10 1 7"] {
        std::fs::write(d.join("y.txt"), format!("# theta_i: 0\n{first}\n5 10 2\n")).unwrap();
        let e = load_dir(d, &LoadOptions::default()).unwrap_err();
        assert!(e.to_string().contains("y.txt:2:"), "{first}: {e}");
    }
}

#[test]
fn convention_options_apply_to_csv_and_npz_like_yan() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("c.csv");
    std::fs::write(&csv, "theta_i,theta_r,phi,value\n10,20,30,1\n10,-5,170,2\n").unwrap();
    let opts = LoadOptions {
        flip_phi: true,
        phi_offset: -160.0,
        flip_theta_r: true,
        ..Default::default()
    };
    let got = |p: &Profile| -> Vec<(f64, f64, f64)> {
        let mut v: Vec<_> = p
            .samples
            .iter()
            .map(|s| (s.theta_i, s.theta_r, s.phi))
            .collect();
        v.sort_by(|a, b| a.partial_cmp(b).unwrap());
        v
    };
    // -30 - 160 = -190 -> 170; -170 - 160 = -330 -> 30.
    let want = vec![(10.0, -20.0, 170.0), (10.0, 5.0, 30.0)];
    let mut want_sorted = want.clone();
    want_sorted.sort_by(|a, b| a.partial_cmp(b).unwrap());
    let c = load(&csv, &opts).unwrap();
    assert_eq!(got(&c), want_sorted);
    let npz = dir.path().join("c.npz");
    save(&npz, &load(&csv, &LoadOptions::default()).unwrap()).unwrap();
    assert_eq!(got(&load(&npz, &opts).unwrap()), want_sorted);
    // The Yan reader gives the same for the same rows.
    let yan = dir.path().join("c.txt");
    std::fs::write(&yan, "# theta_i: 10\n30 20 1\n170 -5 2\n").unwrap();
    assert_eq!(got(&load(&yan, &opts).unwrap()), want_sorted);
    // Without options nothing changes.
    assert_eq!(got(&load(&csv, &LoadOptions::default()).unwrap()), {
        let mut v = vec![(10.0, 20.0, 30.0), (10.0, -5.0, 170.0)];
        v.sort_by(|a, b| a.partial_cmp(b).unwrap());
        v
    });
}

#[test]
fn axis_options_must_be_used_by_some_input() {
    let o = |ti: bool, tr: bool, ph: bool| LoadOptions {
        theta_i: ti.then(|| vec![0.0]),
        theta_r: tr.then(|| vec![0.0]),
        phi: ph.then(|| vec![0.0]),
        ..Default::default()
    };
    let e = o(true, false, false)
        .check_used(&[Format::Csv, Format::Npz])
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("--theta-i was given but no input is a lone .npy or Yan"),
        "{e}"
    );
    assert!(o(true, false, false)
        .check_used(&[Format::Csv, Format::Yan])
        .is_ok());
    let e = o(true, false, true)
        .check_used(&[Format::Yan])
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("--phi was given but no input is a lone .npy"),
        "{e}"
    );
    assert!(o(true, true, true).check_used(&[Format::Npy]).is_ok());
    assert!(o(false, false, false).check_used(&[Format::Csv]).is_ok());
}

#[test]
fn measured_field_rules() {
    let nan = f64::NAN;
    let inf = f64::INFINITY;
    // Invalid-but-kept values and absent optional fields pass.
    for v in [1.0, 0.0, -2.0, nan] {
        assert_eq!(check_measured(v, None, None), Ok(()));
    }
    assert_eq!(check_measured(1.0, Some(0.0), Some(-30.0)), Ok(()));
    let field = |v, s, p| check_measured(v, s, p).unwrap_err().0;
    assert_eq!(field(inf, None, None), Field::Value);
    assert_eq!(field(-inf, None, None), Field::Value);
    for s in [-5.0, inf, -inf, nan] {
        assert_eq!(field(1.0, Some(s), None), Field::Sigma, "sigma {s}");
    }
    // phi_i is an angle: out of range is an error like phi's (1e9 was accepted).
    for p in [inf, nan, 1e9, -360.5] {
        assert_eq!(field(1.0, None, Some(p)), Field::PhiI, "phi_i {p}");
    }
    assert_eq!(check_measured(1.0, None, Some(360.0)), Ok(()));
    assert!(check_channel_name("650nm").is_ok());
    assert!(check_channel_name("").is_err());
    assert!(check_channel_name("  ").is_err());
    let (_, msg) = check_measured(1.0, Some(-5.0), None).unwrap_err();
    assert!(msg.contains("sigma must be finite and >= 0"), "{msg}");
}

/// A species folder's Yan file with a column-name line and/or a `# theta_i:` line is a
/// profile: read (the `phi theta value` header skipped) or, with a header the reader
/// does not take, an error naming file, line and column; it was skipped with a note,
/// silently dropping its data from the fit.
#[test]
fn folder_reads_yan_files_with_a_column_name_line() {
    assert!(looks_like_yan(b"# theta_i: 0\nphi theta value\n0 10 1\n"));
    assert!(looks_like_yan(b"Phi(deg)\tTheta(deg)\tValue\n0 10 1\n"));
    // Prose first, but a theta_i line further down.
    assert!(looks_like_yan(b"Fox, fiber 3.\n# theta_i: 20\n"));
    assert!(!looks_like_yan(b"The phi sweep was noisy.\n0 10 1\n"));
    // A notes line naming two columns in a sentence is prose (review M7).
    assert!(!looks_like_yan(b"phi and theta were swapped\n0 10 1\n"));
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("ti0.txt"), "# theta_i: 0\nphi theta value\n0 10 1\n").unwrap();
    std::fs::write(d.join("ti20.txt"), "# theta_i: 20\n0 10 2\n").unwrap();
    std::fs::write(d.join("notes.txt"), "Fox fiber 3, combed.\n").unwrap();
    let l = load_dir(d, &LoadOptions::default()).unwrap();
    assert_eq!(l.profile.samples.len(), 2);
    assert_eq!(l.files.len(), 2, "{:?}", l.files);
    assert_eq!(l.notes, vec!["skipped notes.txt: not a Yan-2015 profile"]);
    // A header in another order: the folder's load fails on it, naming the place.
    std::fs::write(d.join("ti0.txt"), "# theta_i: 0\ntheta phi value\n0 10 1\n").unwrap();
    let e = load_dir(d, &LoadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("ti0.txt:2: column 1: column-name line"), "{e}");
    // Prose with a theta_i line is read, and its error reported.
    std::fs::write(d.join("ti0.txt"), "Fiber 3\n# theta_i: 0\n0 10 1\n").unwrap();
    let e = load_dir(d, &LoadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("ti0.txt:1: column 3: expected 3 fields"), "{e}");
}

/// Radians with phi written 0..2 pi (phi up to 6.28 > 3.2) got no warning.
#[test]
fn radians_with_phi_to_two_pi_warn() {
    let prof = |s: Vec<Sample>| Profile {
        samples: s,
        ..Default::default()
    };
    let w = radians_warning(&prof(vec![at(0.0, -1.2, 0.0), at(0.52, 1.2, 6.02)])).expect("radians");
    assert!(
        w.contains("within +-pi/2 and every phi within +-2 pi")
            && w.contains("largest |theta| 1.2, largest |phi| 6.02)")
            && w.contains("look like radians"),
        "{w}"
    );
    // At the slack's edge, still; beyond it (a theta of 2 deg, a phi of 7), not.
    assert!(radians_warning(&prof(vec![at(0.0, 1.58, 0.0), at(0.0, 0.0, -6.29)])).is_some());
    assert!(radians_warning(&prof(vec![at(0.0, 2.0, 0.0), at(0.0, 0.0, 6.0)])).is_none());
    assert!(radians_warning(&prof(vec![at(0.0, 1.0, 0.0), at(0.0, 0.0, 7.0)])).is_none());
    // One direction is no sweep to judge.
    assert!(radians_warning(&prof(vec![at(0.5, 1.0, 6.0), at(0.5, 1.0, 6.0)])).is_none());
}

/// Copies of one direction that differ by rounding (two synth grids: a few ulp) are
/// one sample; a difference a measurement could show is still a clash.
#[test]
fn copies_equal_to_rounding_merge_and_others_clash() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // `values` of one direction as the rows of `name`.
    let write = |name: &str, values: &[&str]| {
        let rows: String = values.iter().map(|v| format!("0,-10,90,{v}\n")).collect();
        std::fs::write(d.join(name), format!("theta_i,theta_r,phi,value\n{rows}")).unwrap();
    };
    write("a.csv", &["0.06136276893559789"]);
    write("b.csv", &["0.061362768935597896"]);
    let p = load_dir(d, &LoadOptions::default()).unwrap();
    assert_eq!(p.profile.samples.len(), 1);
    assert_eq!(p.profile.samples[0].value, 0.06136276893559789);
    write("b.csv", &["0.0613627689357"]);
    let e = load_dir(d, &LoadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("with a different value"), "{e}");
    // Within one file too, and a valid sample is not called a no-signal marker.
    std::fs::remove_file(d.join("b.csv")).unwrap();
    write("a.csv", &["0.06136276893559789", "0.061362768935597896"]);
    let l = load_dir(d, &LoadOptions::default()).unwrap();
    assert_eq!(l.profile.samples.len(), 1);
    assert!(
        l.notes.iter().all(|n| !n.contains("no-signal")),
        "{:?}",
        l.notes
    );
    // An infinity is close only to itself.
    assert!(close_f64(f64::INFINITY, f64::INFINITY) && !close_f64(f64::INFINITY, 1e300));
}

/// A clash between two files names each copy as a single file's own duplicate error
/// does: `FILE:LINE: column N (value)` for a CSV or Yan row, `FILE: array 'value' index
/// [i, j, k]` for a grid cell (it said `FILE line N`, and only `FILE` for a cell).
#[test]
fn clash_across_files_names_column_and_cell_of_both_copies() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let grid = |name: &str, v: f64| {
        let mut p = Profile::default();
        for (k, phi) in [0.0, 10.0, 20.0].into_iter().enumerate() {
            p.samples
                .push(Sample::new(30.0, -10.0, phi, 1.0 + k as f64));
            p.samples.push(Sample::new(30.0, 5.0, phi, v + k as f64));
        }
        save(&d.join(name), &p).unwrap();
    };
    grid("a.npz", 1.0);
    grid("b.npz", 2.0);
    let e = load_dir(d, &LoadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains(
            "b.npz: array 'value' index [0, 1, 0]: duplicate sample (theta_i 30, theta_r 5, \
             phi 0) with a different value (1 vs 2); the first copy is in "
        ) && e.ends_with("a.npz: array 'value' index [0, 1, 0]"),
        "{e}"
    );
    std::fs::remove_file(d.join("b.npz")).unwrap();
    std::fs::write(
        d.join("c.csv"),
        "# x\nvalue,phi,theta_r,theta_i\n3,20,5,30\n9,10,5,30\n",
    )
    .unwrap();
    let e = load_dir(d, &LoadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("c.csv:4: column 1 (value): duplicate sample (theta_i 30, theta_r 5, phi 10)")
            && e.ends_with("a.npz: array 'value' index [0, 1, 1]"),
        "{e}"
    );
    // A grid cell elsewhere (a --weighted message) is named by its index too.
    let l = load_full(&d.join("a.npz"), &LoadOptions::default()).unwrap();
    let name = l.profile.origin_of(&l.profile.samples[5]).unwrap();
    assert!(name.ends_with("a.npz index [0, 1, 2]"), "{name}");
    let g = Layout::Grid {
        shape: vec![2, 3, 4, 2],
        sigma: false,
        phi_i: false,
    };
    assert_eq!(g.cell(Origin::at_cell(47)), Some(vec![1, 2, 3, 1]));
    assert_eq!(g.cell(Origin::at_cell(48)), None);
    assert_eq!(g.cell(Origin::default()), None);
    // A lone .npy is one unnamed array: its cells are named by index alone.
    let files = [PathBuf::from("v.npy"), PathBuf::from("w.npz")];
    let layouts = [
        Layout::Grid {
            shape: vec![2, 1, 1],
            sigma: false,
            phi_i: false,
        },
        Layout::Grid {
            shape: vec![2, 1, 1],
            sigma: true,
            phi_i: false,
        },
    ];
    let at = |file| Origin { file, line: 2 };
    assert_eq!(
        place_text(&files, &layouts, at(0), Field::Value).unwrap(),
        "v.npy: index [1, 0, 0]"
    );
    assert_eq!(
        place_text(&files, &layouts, at(1), Field::Value).unwrap(),
        "w.npz: array 'value' index [1, 0, 0]"
    );
    // A clash in sigma names the sigma array, one in phi_i the value array of a file
    // without a phi_i array.
    assert_eq!(
        place_text(&files, &layouts, at(1), Field::Sigma).unwrap(),
        "w.npz: array 'sigma' index [1, 0, 0]"
    );
    assert_eq!(
        place_text(&files, &layouts, at(1), Field::PhiI).unwrap(),
        "w.npz: array 'value' index [1, 0, 0]"
    );
}

/// An npz renamed .csv (or .txt) is named as binary: its zip bytes were echoed as the
/// "header".
#[test]
fn zip_or_npy_under_a_text_name_is_named_binary() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut p = Profile::default();
    p.samples.push(Sample::new(0.0, 10.0, 0.0, 1.0));
    let npz = npz::to_bytes(&p).unwrap();
    for name in ["fake.csv", "fake.txt"] {
        std::fs::write(d.join(name), &npz).unwrap();
        let e = load(&d.join(name), &LoadOptions::default())
            .unwrap_err()
            .to_string();
        assert!(
            e.ends_with(&format!(
                "{name}: binary file (looks like a zip/npz archive; a NumPy grid is read \
                 when named .npz), not a text profile"
            )),
            "{e}"
        );
    }
    std::fs::write(d.join("v.csv"), b"\x93NUMPY\x01\x00").unwrap();
    let e = load(&d.join("v.csv"), &LoadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("binary file (looks like a NumPy .npy array"),
        "{e}"
    );
}
