//! One test per malformed-input kind: each error must name the file and the line and column
//! (text formats) or the array (npz).

use furfit::profile::{self, LoadOptions};
use ndarray::{Array1, ArrayD, IxDyn};
use ndarray_npy::{NpzWriter, WriteNpyExt};
use std::io::Write;
use std::path::PathBuf;

struct Tmp {
    dir: tempfile::TempDir,
}

impl Tmp {
    fn new() -> Tmp {
        Tmp {
            dir: tempfile::tempdir().unwrap(),
        }
    }
    fn write(&self, name: &str, bytes: &[u8]) -> PathBuf {
        let p = self.dir.path().join(name);
        std::fs::write(&p, bytes).unwrap();
        p
    }
}

/// Load `text` as `name` and return the error message (the test fails if it loads).
fn err_of(name: &str, bytes: &[u8], opts: &LoadOptions) -> String {
    let t = Tmp::new();
    let p = t.write(name, bytes);
    match profile::load(&p, opts) {
        Ok(pr) => panic!(
            "{name} loaded ({} samples) but should fail",
            pr.samples.len()
        ),
        Err(e) => e.to_string(),
    }
}

fn csv_err(text: &str) -> String {
    err_of("bad.csv", text.as_bytes(), &LoadOptions::default())
}

/// The message must start `<dir>/bad.csv:<line>: <column>`.
fn assert_at(msg: &str, file: &str, line: usize, column: &str) {
    let want = format!("{file}:{line}: {column}");
    assert!(msg.contains(&want), "expected '{want}' in: {msg}");
}

const HEAD: &str = "# species: x\ntheta_i,theta_r,phi,value\n";

#[test]
fn csv_non_number() {
    let e = csv_err(&format!("{HEAD}0,0,0,1\n0,0,abc,1\n"));
    assert_at(&e, "bad.csv", 4, "column 3 (phi)");
    assert!(e.contains("'abc' is not a number"), "{e}");
    let e = csv_err(&format!("{HEAD}0,0,0,1x\n"));
    assert_at(&e, "bad.csv", 3, "column 4 (value)");
}

#[test]
fn csv_nan_or_infinite_angle() {
    let e = csv_err(&format!("{HEAD}0,nan,0,1\n"));
    assert_at(&e, "bad.csv", 3, "column 2 (theta_r)");
    assert!(e.contains("finite"), "{e}");
    let e = csv_err(&format!("{HEAD}inf,0,0,1\n"));
    assert_at(&e, "bad.csv", 3, "column 1 (theta_i)");
    let e = csv_err(&format!("{HEAD}0,0,,1\n"));
    assert_at(&e, "bad.csv", 3, "column 3 (phi)");
}

#[test]
fn csv_angle_out_of_range() {
    let e = csv_err(&format!("{HEAD}90.5,0,0,1\n"));
    assert_at(&e, "bad.csv", 3, "column 1 (theta_i)");
    assert!(e.contains("out of range"), "{e}");
    // phi may be written in [-360, 360] (e.g. 0..360) and is wrapped; beyond is an error.
    let e = csv_err(&format!("{HEAD}0,0,-180,1\n0,0,360.001,1\n"));
    assert_at(&e, "bad.csv", 4, "column 3 (phi)");
    assert!(e.contains("out of range [-360, 360]"), "{e}");
}

#[test]
fn csv_infinite_value() {
    let e = csv_err(&format!("{HEAD}0,0,0,inf\n"));
    assert_at(&e, "bad.csv", 3, "column 4 (value)");
    // 1e400 parses to inf: the message says why a finite-looking number is refused.
    let e = csv_err(&format!("{HEAD}0,0,0,1\n0,0,10,1e400\n"));
    assert_at(&e, "bad.csv", 4, "column 4 (value)");
    assert!(e.contains("beyond the f64 range"), "{e}");
}

#[test]
fn csv_missing_required_column() {
    let e = csv_err("# a: b\n\ntheta_i,theta_r,value,sigma\n0,0,1,0.1\n");
    assert_at(&e, "bad.csv", 3, "column 'phi'");
    assert!(e.contains("missing"), "{e}");
}

#[test]
fn csv_duplicate_column_in_header() {
    let e = csv_err("theta_i,theta_r,phi,value,PHI\n0,0,0,1,0\n");
    assert_at(&e, "bad.csv", 1, "column 5 (phi)");
}

#[test]
fn csv_duplicate_sample_with_different_value() {
    // -180 and 180 are the same direction, so these two rows clash: on the phi column,
    // saying it is a wrap.
    let e = csv_err(&format!("{HEAD}0,10,180,1\n0,10,0,2\n0,10,-180,1.5\n"));
    assert_at(&e, "bad.csv", 5, "column 3 (phi)");
    assert!(
        e.contains("phi -180 wraps to 180, which line 3 already holds with a different value"),
        "{e}"
    );
    // Written alike: on the value column.
    let e = csv_err(&format!("{HEAD}0,10,20,1\n0,10,20,2\n"));
    assert_at(&e, "bad.csv", 4, "column 4 (value)");
    assert!(e.contains("line 3") && e.contains("different value"), "{e}");
}

#[test]
fn csv_empty_file_and_header_only() {
    for text in ["", "\n\n", "# only: metadata\n# more: x\n"] {
        let e = csv_err(text);
        assert!(e.contains("bad.csv") && e.contains("empty file"), "{e}");
    }
    let e = csv_err("# a: b\ntheta_i,theta_r,phi,value\n\n");
    assert!(e.contains("bad.csv") && e.contains("line 2"), "{e}");
}

#[test]
fn csv_wrong_field_count() {
    let e = csv_err(&format!("{HEAD}0,0,0,1\n0,0,0,1,5\n"));
    assert_at(&e, "bad.csv", 4, "column 5");
    assert!(e.contains("expected 4 fields"), "{e}");
}

#[test]
fn unknown_extension() {
    let e = err_of("x.xlsx", b"abc", &LoadOptions::default());
    assert!(
        e.contains("x.xlsx") && e.contains("unknown profile format"),
        "{e}"
    );
}

// ---- npz ----

fn npy_bytes<A: WriteNpyExt>(a: &A) -> Vec<u8> {
    let mut v = Vec::new();
    a.write_npy(&mut v).unwrap();
    v
}

/// An uncompressed zip from (entry name, bytes) pairs, written with the `zip` crate so
/// entries can be broken on purpose.
fn zip_of(entries: &[(&str, Vec<u8>)]) -> Vec<u8> {
    zip_with(entries, zip::CompressionMethod::Stored)
}

fn zip_with(entries: &[(&str, Vec<u8>)], method: zip::CompressionMethod) -> Vec<u8> {
    let mut w = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
    for (name, bytes) in entries {
        w.start_file(
            *name,
            zip::write::SimpleFileOptions::default().compression_method(method),
        )
        .unwrap();
        w.write_all(bytes).unwrap();
    }
    w.finish().unwrap().into_inner()
}

fn axes() -> Vec<(&'static str, Vec<u8>)> {
    vec![
        ("theta_i.npy", npy_bytes(&Array1::from(vec![0.0, 30.0]))),
        (
            "theta_r.npy",
            npy_bytes(&Array1::from(vec![-30.0, 0.0, 30.0])),
        ),
        (
            "phi.npy",
            npy_bytes(&Array1::from(vec![0.0, 90.0, 180.0, -90.0])),
        ),
    ]
}

fn value(shape: &[usize]) -> Vec<u8> {
    npy_bytes(&ArrayD::<f64>::from_elem(IxDyn(shape), 1.0))
}

fn npz_err(entries: &[(&str, Vec<u8>)]) -> String {
    err_of("bad.npz", &zip_of(entries), &LoadOptions::default())
}

#[test]
fn npz_well_formed_baseline_loads() {
    // The helpers above make a loadable archive; the tests below break one thing each.
    let mut e = axes();
    e.push(("value.npy", value(&[2, 3, 4])));
    let t = Tmp::new();
    let p = t.write("ok.npz", &zip_of(&e));
    let pr = profile::load(&p, &LoadOptions::default()).unwrap();
    assert_eq!(pr.samples.len(), 24);
}

#[test]
fn npz_compressed_like_savez_compressed_loads() {
    let mut e = axes();
    e.push(("value.npy", value(&[2, 3, 4])));
    let bytes = zip_with(&e, zip::CompressionMethod::Deflated);
    let t = Tmp::new();
    let p = t.write("c.npz", &bytes);
    let pr = profile::load(&p, &LoadOptions::default()).unwrap();
    assert_eq!(pr.samples.len(), 24);
    // A corrupted deflate stream is an error naming the array, not a panic.
    let mut bad = bytes.clone();
    let k = bad.len() / 2;
    for b in &mut bad[k - 20..k] {
        *b ^= 0x5a;
    }
    let t2 = Tmp::new();
    let p2 = t2.write("c.npz", &bad);
    assert!(profile::load(&p2, &LoadOptions::default()).is_err());
}

#[test]
fn npz_truncated_archive() {
    let mut e = axes();
    e.push(("value.npy", value(&[2, 3, 4])));
    let full = zip_of(&e);
    let msg = err_of("bad.npz", &full[..full.len() / 2], &LoadOptions::default());
    assert!(
        msg.contains("bad.npz") && msg.contains("truncated or corrupt"),
        "{msg}"
    );
    let msg = err_of(
        "bad.npz",
        b"PK\x03\x04 definitely not a zip",
        &LoadOptions::default(),
    );
    assert!(msg.contains("bad.npz"), "{msg}");
}

#[test]
fn npz_truncated_array() {
    let mut e = axes();
    let v = value(&[2, 3, 4]);
    e.push(("value.npy", v[..v.len() - 8].to_vec()));
    let msg = npz_err(&e);
    assert!(
        msg.contains("bad.npz: array 'value'") && msg.contains("truncated"),
        "{msg}"
    );
}

#[test]
fn npz_wrong_shape() {
    let mut e = axes();
    e.push(("value.npy", value(&[2, 3, 5])));
    let msg = npz_err(&e);
    assert!(
        msg.contains("bad.npz: array 'value'") && msg.contains("wrong shape [2, 3, 5]"),
        "{msg}"
    );
    let mut e = axes();
    e.push(("value.npy", value(&[2, 3, 4])));
    e.push(("sigma.npy", value(&[2, 3, 4, 1])));
    let msg = npz_err(&e);
    assert!(
        msg.contains("array 'sigma'") && msg.contains("wrong shape"),
        "{msg}"
    );
}

#[test]
fn npz_missing_array() {
    let mut e = axes();
    e.remove(2);
    e.push(("value.npy", value(&[2, 3, 4])));
    let msg = npz_err(&e);
    assert!(
        msg.contains("bad.npz: array 'phi'") && msg.contains("missing"),
        "{msg}"
    );
}

#[test]
fn npz_wrong_dtype() {
    let mut e = axes();
    e.push((
        "value.npy",
        npy_bytes(&ArrayD::<i32>::zeros(IxDyn(&[2, 3, 4]))),
    ));
    let msg = npz_err(&e);
    assert!(
        msg.contains("array 'value'") && msg.contains("wrong dtype"),
        "{msg}"
    );
}

#[test]
fn npz_bad_axis_value() {
    let mut e = axes();
    e[1].1 = npy_bytes(&Array1::from(vec![-30.0, f64::NAN, 95.0]));
    e.push(("value.npy", value(&[2, 3, 4])));
    let msg = npz_err(&e);
    assert!(
        msg.contains("array 'theta_r'") && msg.contains("element 1"),
        "{msg}"
    );
    let mut e = axes();
    e[1].1 = npy_bytes(&Array1::from(vec![-30.0, 0.0, 95.0]));
    e.push(("value.npy", value(&[2, 3, 4])));
    let msg = npz_err(&e);
    assert!(
        msg.contains("array 'theta_r'") && msg.contains("out of range"),
        "{msg}"
    );
}

#[test]
fn npz_conflicting_cells_for_one_direction() {
    // phi axis with both -180 and 180: same direction, different values -> error.
    let mut e = axes();
    e[2].1 = npy_bytes(&Array1::from(vec![-180.0, 0.0, 90.0, 180.0]));
    let mut v = ArrayD::<f64>::from_elem(IxDyn(&[2, 3, 4]), 1.0);
    v[[0, 0, 3]] = 2.0;
    e.push(("value.npy", npy_bytes(&v)));
    let msg = npz_err(&e);
    // Named on the phi axis as a wrap, with the 3 indices of the 3-D value array.
    assert!(
        msg.contains(
            "array 'phi': element 3: phi 180 and phi -180 on element 0 are the same direction"
        ) && msg.contains("cells [0, 0, 0] and [0, 0, 3]"),
        "{msg}"
    );
}

#[test]
fn npz_via_numpy_names_without_suffix() {
    // Entries named without ".npy" are accepted too (NumPy's lookup does the same).
    let mut e: Vec<(&str, Vec<u8>)> = axes()
        .into_iter()
        .map(|(n, b)| (n.trim_end_matches(".npy"), b))
        .collect();
    e.push(("value", value(&[2, 3, 4])));
    let t = Tmp::new();
    let p = t.write("ok.npz", &zip_of(&e));
    assert_eq!(
        profile::load(&p, &LoadOptions::default())
            .unwrap()
            .samples
            .len(),
        24
    );
}

#[test]
fn npz_writer_itself_loads() {
    let mut w = NpzWriter::new(std::io::Cursor::new(Vec::new()));
    w.add_array("theta_i", &Array1::from(vec![0.0])).unwrap();
    w.add_array("theta_r", &Array1::from(vec![0.0])).unwrap();
    w.add_array("phi", &Array1::from(vec![0.0])).unwrap();
    w.add_array(
        "value",
        &ArrayD::<f32>::from_elem(IxDyn(&[1, 1, 1]), 0.5f32),
    )
    .unwrap();
    let bytes = w.finish().unwrap().into_inner();
    let t = Tmp::new();
    let p = t.write("f32.npz", &bytes);
    let pr = profile::load(&p, &LoadOptions::default()).unwrap();
    assert_eq!(pr.samples[0].value, 0.5);
}

// ---- Yan ----

fn yan_opts() -> LoadOptions {
    LoadOptions {
        theta_i: Some(vec![15.0]),
        ..Default::default()
    }
}

#[test]
fn yan_question_mark_is_an_invalid_sample() {
    let t = Tmp::new();
    let p = t.write("y.txt", b"0 0 1\n10 0 ?\n20 0 -1\n");
    let pr = profile::load(&p, &yan_opts()).unwrap();
    assert_eq!(pr.samples.len(), 3);
    assert_eq!(pr.n_invalid(), 2);
    assert!(pr.samples[1].value.is_nan());
    // `?` only stands for a whole value; `?5` or a `?` angle is a bad token.
    let e = err_of("y.txt", b"0 0 1\n10 0 ?5\n", &yan_opts());
    assert_at(&e, "y.txt", 2, "column 3 (value)");
    let e = err_of("y.txt", b"? 0 1\n", &yan_opts());
    assert_at(&e, "y.txt", 1, "column 1 (phi)");
}

#[test]
fn yan_bad_token() {
    let e = err_of(
        "y.txt",
        b"# theta_i: 10\n0 0 1\n\n10 abc 1\n",
        &LoadOptions::default(),
    );
    assert_at(&e, "y.txt", 4, "column 2 (theta)");
    assert!(e.contains("'abc' is not a number"), "{e}");
    let e = err_of("y.txt", b"# theta_i: ten\n0 0 1\n", &LoadOptions::default());
    assert_at(&e, "y.txt", 1, "theta_i");
    let e = err_of("y.txt", b"0 0 1\n1 2\n", &yan_opts());
    assert_at(&e, "y.txt", 2, "column 3");
}

#[test]
fn yan_duplicate_and_missing_theta_i() {
    let e = err_of("y.txt", b"0 0 1\n360 0 2\n", &yan_opts());
    assert_at(&e, "y.txt", 2, "column 1 (phi)");
    assert!(e.contains("phi 360 wraps to 0, which line 1"), "{e}");
    let e = err_of("y.txt", b"0 0 1\n0 0 2\n", &yan_opts());
    assert_at(&e, "y.txt", 2, "column 3 (value)");
    let e = err_of("y.txt", b"0 0 1\n", &LoadOptions::default());
    assert!(
        e.contains("y.txt") && e.contains("no incident angle"),
        "{e}"
    );
}

#[test]
fn lone_npy_needs_axes_and_checks_them() {
    let v = value(&[2, 3, 4]);
    let e = err_of("v.npy", &v, &LoadOptions::default());
    assert!(e.contains("v.npy") && e.contains("--theta-i"), "{e}");
    let e = err_of("v.npy", &v[..v.len() - 1], &LoadOptions::default());
    assert!(
        e.contains("v.npy: array 'value'") && e.contains("truncated"),
        "{e}"
    );
}

/// An npz whose `value` is all 1.0 except `name` (an extra array when not `value`), which
/// holds `bad` at cell [1, 2, 3] (theta_i 30, theta_r 30, phi -90).
fn npz_with_bad_cell(name: &str, bad: f64) -> String {
    let mut e = axes();
    let mut v = ArrayD::<f64>::from_elem(IxDyn(&[2, 3, 4]), 1.0);
    if name == "value" {
        v[[1, 2, 3]] = bad;
    } else {
        let mut x = ArrayD::<f64>::from_elem(IxDyn(&[2, 3, 4]), 0.5);
        x[[1, 2, 3]] = bad;
        e.push((
            if name == "sigma" {
                "sigma.npy"
            } else {
                "phi_i.npy"
            },
            npy_bytes(&x),
        ));
    }
    e.push(("value.npy", npy_bytes(&v)));
    npz_err(&e)
}

#[test]
fn npz_infinite_value_is_an_error_not_an_invalid_sample() {
    for bad in [f64::INFINITY, f64::NEG_INFINITY] {
        let msg = npz_with_bad_cell("value", bad);
        assert!(
            msg.contains("bad.npz: array 'value'")
                && msg.contains("index [1, 2, 3]")
                && msg.contains("infinite"),
            "{msg}"
        );
    }
}

#[test]
fn npz_sigma_and_phi_i_follow_the_csv_rules() {
    for bad in [-5.0, f64::INFINITY] {
        let msg = npz_with_bad_cell("sigma", bad);
        assert!(
            msg.contains("bad.npz: array 'sigma'")
                && msg.contains("index [1, 2, 3]")
                && msg.contains("sigma must be finite and >= 0"),
            "{msg}"
        );
    }
    let msg = npz_with_bad_cell("phi_i", f64::INFINITY);
    assert!(
        msg.contains("bad.npz: array 'phi_i'")
            && msg.contains("index [1, 2, 3]")
            && msg.contains("finite"),
        "{msg}"
    );
}

#[test]
fn lone_npy_infinite_value() {
    let mut v = ArrayD::<f64>::from_elem(IxDyn(&[1, 1, 2]), 1.0);
    v[[0, 0, 1]] = f64::INFINITY;
    let opts = LoadOptions {
        theta_i: Some(vec![0.0]),
        theta_r: Some(vec![0.0]),
        phi: Some(vec![0.0, 10.0]),
        ..Default::default()
    };
    let e = err_of("v.npy", &npy_bytes(&v), &opts);
    assert!(
        e.contains("v.npy: array 'value'") && e.contains("index [0, 0, 1]"),
        "{e}"
    );
}

#[test]
fn csv_unterminated_quote() {
    let e = csv_err(&format!("{HEAD}0,0,0,1\n0,0,0,\"1\n"));
    assert_at(&e, "bad.csv", 4, "column 4 (value)");
    assert!(e.contains("unterminated"), "{e}");
}

#[test]
fn csv_empty_channel() {
    let e = csv_err("theta_i,theta_r,phi,value,channel\n0,0,0,1,r\n0,0,0,1,  \n");
    assert_at(&e, "bad.csv", 3, "column 5 (channel)");
    assert!(e.contains("empty channel name"), "{e}");
}

#[test]
fn npz_empty_channel_name() {
    let mut e = axes();
    e.push(("value.npy", value(&[2, 3, 4, 2])));
    let meta = br#"{"channels": ["r", ""]}"#.to_vec();
    e.push(("meta_json.npy", npy_bytes(&Array1::from(meta))));
    let msg = npz_err(&e);
    assert!(
        msg.contains("bad.npz: array 'meta_json'")
            && msg.contains("channels[1]")
            && msg.contains("empty channel name"),
        "{msg}"
    );
}

/// Two channels with one name are ambiguous (`--channel` and the fit file name a channel
/// by its name): refused, naming both entries.
#[test]
fn npz_repeated_channel_name() {
    let mut e = axes();
    e.push(("value.npy", value(&[2, 3, 4, 2])));
    let meta = br#"{"channels": ["r", "r"]}"#.to_vec();
    e.push(("meta_json.npy", npy_bytes(&Array1::from(meta))));
    let msg = npz_err(&e);
    assert!(
        msg.contains("bad.npz: array 'meta_json'")
            && msg.contains("channels[1] 'r' repeats channels[0]"),
        "{msg}"
    );
}

/// A `synthetic` label with a value furfit does not read is an error in every format and
/// in a folder's metadata.json: read as "no label" it turned synthetic data into measured.
/// A comment that mentions synthetic without being an entry gets a loader note.
#[test]
fn unreadable_synthetic_label_is_an_error() {
    let e = csv_err(&format!("# synthetic: true # simulated\n{HEAD}0,0,0,1\n"));
    assert_at(&e, "bad.csv", 1, "metadata");
    assert!(
        e.contains("'true # simulated' is not a value of 'synthetic'"),
        "{e}"
    );
    let e = err_of(
        "bad.txt",
        b"# theta_i: 30\n# Synthetic: maybe\n0 10 1\n",
        &LoadOptions::default(),
    );
    assert_at(&e, "bad.txt", 2, "metadata");
    let mut entries = axes();
    entries.push(("value.npy", value(&[2, 3, 4])));
    let meta = br#"{"metadata": [["species", "x"], ["synthetic", "simulated"]]}"#;
    entries.push(("meta_json.npy", npy_bytes(&Array1::from(meta.to_vec()))));
    let e = npz_err(&entries);
    assert!(e.contains("meta_json") && e.contains("metadata[1]"), "{e}");
    // A folder's metadata.json, also for a file named inside the folder.
    let t = Tmp::new();
    let dir = t.dir.path().join("fox");
    std::fs::create_dir(&dir).unwrap();
    std::fs::write(dir.join("p.csv"), format!("{HEAD}0,0,0,1\n")).unwrap();
    std::fs::write(dir.join("metadata.json"), r#"{"synthetic": "synthetic"}"#).unwrap();
    let opts = LoadOptions::default();
    for e in [
        profile::load_dir(&dir, &opts).map(|_| ()),
        profile::load_full(&dir.join("p.csv"), &opts).map(|_| ()),
    ] {
        let e = e.unwrap_err().to_string();
        assert!(
            e.contains("metadata.json: key \"synthetic\": 'synthetic' is not a value"),
            "{e}"
        );
    }
    // Understood values still load, and a comment that only mentions it is noted.
    std::fs::write(dir.join("metadata.json"), r#"{"synthetic": true}"#).unwrap();
    assert!(profile::load_dir(&dir, &opts)
        .unwrap()
        .profile
        .is_synthetic());
    let p = t.write(
        "c.csv",
        format!("# synthetic=true\n{HEAD}0,0,0,1\n").as_bytes(),
    );
    let l = profile::load_full(&p, &LoadOptions::default()).unwrap();
    assert!(!l.profile.is_synthetic());
    assert!(
        l.notes
            .iter()
            .any(|n| n.contains("line 1: the comment '# synthetic=true'")),
        "{:?}",
        l.notes
    );
}
