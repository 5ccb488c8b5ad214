use super::npy::*;
use super::read::*;
use super::*;

use crate::profile::{LoadOptions, Profile, Sample};
use ndarray::{ArrayD, IxDyn};
use ndarray_npy::NpzWriter;
use std::io::Cursor;
use std::path::Path;

fn sample(ti: f64, tr: f64, phi: f64, value: f64) -> Sample {
    Sample::new(ti, tr, phi, value)
}

/// A version-1.0 `.npy` header holding the dict `text`, padded as NumPy pads it (no
/// data after it).
fn npy_header_bytes(text: &str) -> Vec<u8> {
    let mut hdr = b"\x93NUMPY\x01\x00".to_vec();
    let pad = 64 - (hdr.len() + 2 + text.len() + 1) % 64;
    let text = format!("{text}{}\n", " ".repeat(pad));
    hdr.extend((text.len() as u16).to_le_bytes());
    hdr.extend(text.as_bytes());
    hdr
}

/// Two samples in one cell name the channel as the profile does (`g`, not index 1).
#[test]
fn writing_a_shared_cell_names_the_channel() {
    let mut g = [sample(0.0, 10.0, 5.0, 1.0), sample(0.0, 10.0, 5.0, 2.0)];
    for s in &mut g {
        s.channel = 1;
    }
    let p = Profile {
        samples: [vec![sample(0.0, 10.0, 5.0, 1.0)], g.to_vec()].concat(),
        channels: vec!["r".into(), "g".into()],
        ..Default::default()
    };
    let e = to_bytes(&p).unwrap_err().to_string();
    assert!(
        e.ends_with("share the grid cell theta_i 0, theta_r 10, phi 5, channel g"),
        "{e}"
    );
}

#[test]
fn round_trip_keeps_invalid_values_and_sparsity() {
    let mut p = Profile {
        samples: vec![
            sample(0.0, -10.0, 0.0, 1.5),
            sample(0.0, 10.0, 90.0, -2.0),
            sample(30.0, 10.0, 180.0, f64::NAN),
        ],
        ..Default::default()
    };
    p.samples[1].sigma = Some(0.25);
    p.metadata.push(("species".into(), "test".into()));
    let bytes = to_bytes(&p).unwrap();
    let (back, notes) = parse_npz(&bytes, Path::new("x.npz")).unwrap();
    assert!(notes.is_empty());
    assert_eq!(back.samples.len(), 3);
    assert_eq!(back.samples[1].value, -2.0);
    assert_eq!(back.samples[1].sigma, Some(0.25));
    assert!(back.samples[2].value.is_nan());
    assert_eq!(back.metadata, p.metadata);
    // Deterministic bytes.
    assert_eq!(to_bytes(&back).unwrap(), bytes);
}

/// A complex array and a truncated header are named as such (they were reported as
/// "truncated or corrupt" and "bad magic bytes").
#[test]
fn complex_dtype_and_truncated_header_are_named() {
    let mut hdr = npy_header_bytes("{'descr': '<c16', 'fortran_order': False, 'shape': (2,), }");
    hdr.extend([0u8; 32]);
    let e = npy_header(&hdr).unwrap_err();
    assert!(e.contains("unsupported dtype '<c16'"), "{e}");
    let e = npy_header(b"\x93NUMPY\x01").unwrap_err();
    assert!(e.contains("truncated"), "{e}");
    assert!(npy_header(b"PK\x03\x04 not npy")
        .unwrap_err()
        .contains("magic"));
}

/// A grid past the cell limit is refused from its header alone (the shape is
/// claimed, no data follow: nothing is decoded or allocated).
#[test]
fn huge_value_array_is_refused_from_its_header() {
    let hdr =
        npy_header_bytes("{'descr': '<f8', 'fortran_order': False, 'shape': (10, 2000, 1001), }");
    let e = read_float(&hdr, Path::new("big.npy"), "value")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("value") && e.contains("[10, 2000, 1001]") && e.contains("20000000"),
        "{e}"
    );
}

#[test]
fn integer_axes_are_read_as_degrees() {
    let mut w = NpzWriter::new(Cursor::new(Vec::new()));
    w.add_array("theta_i", &ndarray::arr1(&[0i64, 30])).unwrap();
    w.add_array("theta_r", &ndarray::arr1(&[-10i32])).unwrap();
    w.add_array("phi", &ndarray::arr1(&[0u16, 90, 180]))
        .unwrap();
    w.add_array("value", &ArrayD::<f64>::from_elem(IxDyn(&[2, 1, 3]), 1.0))
        .unwrap();
    let bytes = w.finish().unwrap().into_inner();
    let (p, _) = parse_npz(&bytes, Path::new("i.npz")).unwrap();
    assert_eq!(p.samples.len(), 6);
    assert_eq!(
        (p.samples[5].theta_i, p.samples[5].theta_r, p.samples[5].phi),
        (30.0, -10.0, 180.0)
    );
    // Other dtypes keep their clear error.
    let mut w = NpzWriter::new(Cursor::new(Vec::new()));
    w.add_array("theta_i", &ndarray::arr1(&[true])).unwrap();
    w.add_array("theta_r", &ndarray::arr1(&[0.0])).unwrap();
    w.add_array("phi", &ndarray::arr1(&[0.0])).unwrap();
    w.add_array("value", &ArrayD::<f64>::from_elem(IxDyn(&[1, 1, 1]), 1.0))
        .unwrap();
    let bytes = w.finish().unwrap().into_inner();
    let e = parse_npz(&bytes, Path::new("b.npz"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("'theta_i'") && e.contains("wrong dtype"), "{e}");
}

/// An archive of `value` (shape `shape`, filled by `f(flat index)`) over the axes given.
fn archive(
    ti: &[f64],
    tr: &[f64],
    phi: &[f64],
    shape: &[usize],
    f: impl Fn(usize) -> f64,
) -> Vec<u8> {
    let mut w = NpzWriter::new(Cursor::new(Vec::new()));
    w.add_array("theta_i", &ndarray::arr1(ti)).unwrap();
    w.add_array("theta_r", &ndarray::arr1(tr)).unwrap();
    w.add_array("phi", &ndarray::arr1(phi)).unwrap();
    let n: usize = shape.iter().product();
    let v = ArrayD::from_shape_vec(IxDyn(shape), (0..n).map(f).collect()).unwrap();
    w.add_array("value", &v).unwrap();
    w.finish().unwrap().into_inner()
}

/// Every sample of a multi-channel grid is named by its own cell, channel included
/// (messages about a sample, such as a merge's duplicate or a weighted fit's worst
/// residual, send the user to that cell): the cell a sample's origin names holds that
/// sample's value.
#[test]
fn each_sample_is_named_by_its_own_cell() {
    let shape = [2, 2, 3, 2];
    let bytes = archive(
        &[0.0, 30.0],
        &[-10.0, 10.0],
        &[0.0, 5.0, 10.0],
        &shape,
        |k| 1.0 + k as f64,
    );
    let (p, _) = parse_npz(&bytes, Path::new("a.npz")).unwrap();
    assert_eq!(p.samples.len(), 24);
    for s in &p.samples {
        // Value 1 + k sits at row-major index k.
        let k = s.value as usize - 1;
        let ix = [k / 12, k / 6 % 2, k / 2 % 3, k % 2];
        assert_eq!(p.origin_of(s).unwrap(), format!("a.npz index {ix:?}"));
    }
}

/// `present` holds only 1 (a sample) and 0 (none): a 2 is an error naming the array,
/// the first such cell (in index order) and the value, not a silent "present".
#[test]
fn present_other_than_0_or_1_is_an_error() {
    let with_present = |mask: &[u8]| {
        let mut w = NpzWriter::new(Cursor::new(Vec::new()));
        w.add_array("theta_i", &ndarray::arr1(&[0.0])).unwrap();
        w.add_array("theta_r", &ndarray::arr1(&[10.0, 20.0]))
            .unwrap();
        w.add_array("phi", &ndarray::arr1(&[0.0, 5.0])).unwrap();
        let shape = IxDyn(&[1, 2, 2]);
        let v = ArrayD::from_shape_vec(shape.clone(), vec![1.0; 4]).unwrap();
        w.add_array("value", &v).unwrap();
        let m = ArrayD::from_shape_vec(shape, mask.to_vec()).unwrap();
        w.add_array("present", &m).unwrap();
        parse_npz(&w.finish().unwrap().into_inner(), Path::new("m.npz"))
    };
    let e = with_present(&[1, 0, 2, 255]).unwrap_err().to_string();
    assert_eq!(
        e,
        "m.npz: array 'present': index [0, 1, 0]: 2 is neither 1 (a sample) nor 0 (none)"
    );
    let (p, _) = with_present(&[1, 0, 0, 1]).unwrap();
    assert_eq!(p.samples.len(), 2);
}

/// `np.arange(0, 360, 5.)` as the phi axis reads (element 37, 185, was "out of
/// range"), wrapped to (-180, 180]; the offset applies before the wrap.
#[test]
fn phi_axis_in_0_360_reads_wrapped() {
    let phi: Vec<f64> = (0..72).map(|k| 5.0 * k as f64).collect();
    let bytes = archive(&[0.0], &[10.0], &phi, &[1, 1, 72], |_| 1.0);
    let (p, notes) = parse_npz(&bytes, Path::new("a.npz")).unwrap();
    assert!(notes.is_empty(), "{notes:?}");
    assert_eq!(p.samples.len(), 72);
    assert_eq!(p.samples[37].phi, -175.0);
    assert_eq!(p.samples[36].phi, 180.0);
    let opts = LoadOptions {
        phi_offset: -180.0,
        ..Default::default()
    };
    let (p, _) = parse_npz_with(&bytes, Path::new("a.npz"), &opts).unwrap();
    assert_eq!((p.samples[0].phi, p.samples[37].phi), (180.0, 5.0));
    let bytes = archive(&[0.0], &[10.0], &[0.0, 400.0], &[1, 1, 2], |_| 1.0);
    let e = parse_npz(&bytes, Path::new("a.npz"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("array 'phi': element 1: phi = 400 deg is out of range [-360, 360]"),
        "{e}"
    );
}

/// A phi axis holding 0 and 360 with different data: named on the `phi` array as a
/// wrap, with as many cell indices as `value` has axes (a 3-D array got 4).
#[test]
fn wrap_and_duplicate_cells_are_named_with_value_s_rank() {
    let bytes = archive(&[0.0], &[10.0], &[0.0, 180.0, 360.0], &[1, 1, 3], |k| {
        1.0 + k as f64
    });
    let e = parse_npz(&bytes, Path::new("w.npz"))
        .unwrap_err()
        .to_string();
    assert_eq!(
        e,
        "w.npz: array 'phi': element 2: phi 360 wraps to 0, which element 0 already holds \
         with a different value (1 vs 3) in cells [0, 0, 0] and [0, 0, 2]; drop one of \
         the two endpoint measurements"
    );
    // A repeated theta_r (not a wrap) keeps the value array's message, 3 indices.
    let bytes = archive(&[0.0], &[10.0, 10.0], &[0.0], &[1, 2, 1], |k| {
        1.0 + k as f64
    });
    let e = parse_npz(&bytes, Path::new("w.npz"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("array 'value': duplicate sample")
            && e.ends_with("cells [0, 0, 0] and [0, 1, 0]"),
        "{e}"
    );
    // 4-D: four indices.
    let bytes = archive(&[0.0], &[10.0, 10.0], &[0.0], &[1, 2, 1, 2], |k| {
        1.0 + k as f64
    });
    let e = parse_npz(&bytes, Path::new("w.npz"))
        .unwrap_err()
        .to_string();
    assert!(e.ends_with("cells [0, 0, 0, 0] and [0, 1, 0, 0]"), "{e}");
    // Identical cells collapse; the note gives the axis's own wrapped pair as example.
    let bytes = archive(&[0.0], &[10.0], &[0.0, 180.0, 360.0], &[1, 1, 3], |k| {
        [1.0, 2.0, 1.0][k]
    });
    let (p, notes) = parse_npz(&bytes, Path::new("w.npz")).unwrap();
    assert_eq!(p.samples.len(), 2);
    assert!(notes[0].contains("e.g. 0 and 360"), "{notes:?}");
}

/// NumPy's trailing singleton channel axis (`[I, R, P, 1]`) without names is one
/// unnamed channel, as the same data shaped `[I, R, P]` (it was named "0", and merging
/// the two forms was refused).
#[test]
fn singleton_channel_axis_is_unnamed() {
    let four = archive(&[0.0], &[10.0], &[0.0, 5.0], &[1, 1, 2, 1], |_| 1.0);
    let three = archive(&[0.0], &[10.0], &[10.0, 15.0], &[1, 1, 2], |_| 1.0);
    let (a, _) = parse_npz(&four, Path::new("a.npz")).unwrap();
    let (b, _) = parse_npz(&three, Path::new("b.npz")).unwrap();
    assert!(a.channels.is_empty(), "{:?}", a.channels);
    let (m, _) = super::super::merge(vec![a, b]).unwrap();
    assert_eq!((m.samples.len(), m.channels.len()), (4, 0));
    // Two unnamed channels are still numbered.
    let two = archive(&[0.0], &[10.0], &[0.0], &[1, 1, 1, 2], |_| 1.0);
    let (c, _) = parse_npz(&two, Path::new("c.npz")).unwrap();
    assert_eq!(c.channels, vec!["0".to_string(), "1".to_string()]);
}

#[test]
fn header_check_catches_truncation() {
    let mut w = Vec::new();
    ndarray_npy::WriteNpyExt::write_npy(&ndarray::Array1::<f64>::zeros(4), &mut w).unwrap();
    assert!(npy_header(&w).is_ok());
    let e = npy_header(&w[..w.len() - 3]).unwrap_err();
    assert!(e.contains("truncated"), "{e}");
}

/// An archive member that inflates past the size its header declares (a small zip
/// bomb) is refused once that size is passed, not decompressed whole.
#[test]
fn member_longer_than_its_header_is_refused_at_the_declared_size() {
    let npy = |a: ArrayD<f64>| {
        let mut w = Vec::new();
        ndarray_npy::WriteNpyExt::write_npy(&a, &mut w).unwrap();
        w
    };
    let axis = |n: usize| npy(ArrayD::from_shape_fn(IxDyn(&[n]), |i| i[0] as f64));
    let mut value = npy(ArrayD::from_elem(IxDyn(&[2, 3, 4]), 1.0));
    value.extend(std::iter::repeat_n(0u8, 8 << 20));
    let members = [
        ("theta_i.npy", axis(2)),
        ("theta_r.npy", axis(3)),
        ("phi.npy", axis(4)),
        ("value.npy", value),
    ];
    let bytes = zip_of(&members);
    assert!(bytes.len() < 100_000, "{} bytes", bytes.len());
    let e = parse_npz(&bytes, Path::new("bomb.npz"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("'value'") && e.contains("(192 bytes) but more follow"),
        "{e}"
    );
    // A dtype whose size the header does not state plainly is read whole (within the
    // limit) for its reader to name: np.array(s) as meta_json gets the how-to, not
    // "corrupt".
    let mut members = members.to_vec();
    members[3].1 = npy(ArrayD::from_elem(IxDyn(&[2, 3, 4]), 1.0));
    let mut text = npy_header_bytes("{'descr': '<U2', 'fortran_order': False, 'shape': (), }");
    text.extend([b'{', 0, 0, 0, b'}', 0, 0, 0]);
    members.push(("meta_json.npy", text));
    let e = parse_npz(&zip_of(&members), Path::new("m.npz"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("array 'meta_json': dtype '<U2': meta_json must be"),
        "{e}"
    );
    // Nor is a string member decompressed past its header: its dtype is refused there.
    let mut strings =
        npy_header_bytes("{'descr': '<U1', 'fortran_order': False, 'shape': (2, 3, 4), }");
    strings.extend(std::iter::repeat_n(0u8, 8 << 20));
    members[3].1 = strings;
    let e = parse_npz(&zip_of(&members[..4]), Path::new("s.npz"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("array 'value': unsupported dtype '<U1'"), "{e}");
    // Two members of one array are refused, not one of them taken.
    let twice = [members[3].clone(), ("value", members[3].1.clone())];
    let e = parse_npz(&zip_of(&twice), Path::new("two.npz"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("holds array 'value' twice"), "{e}");
}

/// A deflated zip of the named members.
fn zip_of(members: &[(&str, Vec<u8>)]) -> Vec<u8> {
    use std::io::Write;
    let mut z = zip::ZipWriter::new(Cursor::new(Vec::new()));
    let opt = zip::write::SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Deflated);
    for (name, bytes) in members {
        z.start_file(*name, opt).unwrap();
        z.write_all(bytes).unwrap();
    }
    z.finish().unwrap().into_inner()
}

/// A bool mask holding a byte other than 0 or 1 reads as that byte, so the caller names
/// its cell (the bool reader failed without an index).
#[test]
fn bool_mask_keeps_a_stray_byte_for_the_cell_check() {
    let a = ArrayD::<bool>::from_elem(IxDyn(&[1, 2, 2]), true);
    let mut w = Vec::new();
    ndarray_npy::WriteNpyExt::write_npy(&a, &mut w).unwrap();
    let last = w.len() - 1;
    w[last] = 2;
    let m = read_bytes_array(&w, Path::new("x.npz"), "present").unwrap();
    assert_eq!(m.as_slice().unwrap(), &[1, 1, 1, 2]);
}

#[test]
fn lone_npy_needs_axes() {
    let mut w = Vec::new();
    let a = ArrayD::<f64>::from_elem(IxDyn(&[1, 2, 3]), 1.0);
    ndarray_npy::WriteNpyExt::write_npy(&a, &mut w).unwrap();
    let path = Path::new("v.npy");
    let e = parse_npy(&w, path, &LoadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("v.npy") && e.contains("--theta-i"), "{e}");
    let opts = LoadOptions {
        theta_i: Some(vec![0.0]),
        theta_r: Some(vec![0.0, 10.0]),
        phi: Some(vec![0.0, 90.0, -180.0]),
        ..Default::default()
    };
    let (p, _) = parse_npy(&w, path, &opts).unwrap();
    assert_eq!(p.samples.len(), 6);
    assert_eq!(p.samples[2].phi, 180.0);
    let bad = LoadOptions {
        phi: Some(vec![0.0, 90.0]),
        ..opts.clone()
    };
    let e = parse_npy(&w, path, &bad).unwrap_err().to_string();
    assert!(e.contains("'value'") && e.contains("wrong shape"), "{e}");
    // A wrap clash among --phi values is placed on --phi (the file has no phi array).
    let mut w4 = Vec::new();
    let a = ArrayD::<f64>::from_shape_vec(IxDyn(&[1, 1, 4]), vec![1.0, 2.0, 3.0, 4.0]).unwrap();
    ndarray_npy::WriteNpyExt::write_npy(&a, &mut w4).unwrap();
    let wraps = LoadOptions {
        theta_r: Some(vec![0.0]),
        phi: Some(vec![0.0, 90.0, 180.0, 360.0]),
        ..opts
    };
    let e = parse_npy(&w4, path, &wraps).unwrap_err().to_string();
    assert!(
        e.starts_with("v.npy: --phi element 3: phi 360 wraps to 0"),
        "{e}"
    );
}

/// A float32 axis reads as the decimals it was written for (0.1f32 widened is
/// 0.10000000149011612): the same grid in a CSV is then the same directions, so the two
/// merge into one sample per direction, not two, and a different value is a conflict.
#[test]
fn float32_axes_read_as_their_shortest_decimal() {
    let mut w = NpzWriter::new(Cursor::new(Vec::new()));
    w.add_array("theta_i", &ndarray::arr1(&[0.1f32, 30.0]))
        .unwrap();
    w.add_array("theta_r", &ndarray::arr1(&[-59.9f32, 60.1]))
        .unwrap();
    w.add_array("phi", &ndarray::arr1(&[-0.3f32, 179.9]))
        .unwrap();
    let v = ArrayD::from_shape_vec(IxDyn(&[2, 2, 2]), (1..=8).map(f64::from).collect());
    w.add_array("value", &v.unwrap()).unwrap();
    let bytes = w.finish().unwrap().into_inner();
    let (p, _) = parse_npz(&bytes, Path::new("f.npz")).unwrap();
    let s = &p.samples[7];
    assert_eq!((s.theta_i, s.theta_r, s.phi), (30.0, 60.1, 179.9));
    let s = &p.samples[0];
    assert_eq!((s.theta_i, s.theta_r, s.phi), (0.1, -59.9, -0.3));
    // The same grid as a lab writes it, in decimals.
    let mut csv = String::from("theta_i,theta_r,phi,value\n");
    let mut v = 0;
    for ti in ["0.1", "30"] {
        for tr in ["-59.9", "60.1"] {
            for ph in ["-0.3", "179.9"] {
                v += 1;
                csv.push_str(&format!("{ti},{tr},{ph},{v}\n"));
            }
        }
    }
    let (c, _) = super::super::csv::parse(csv.as_bytes(), Path::new("f.csv")).unwrap();
    let (m, collapsed) = super::super::merge(vec![p, c]).unwrap();
    assert_eq!((m.samples.len(), collapsed), (8, 8));
    // Values are data, not a grid: widened exactly.
    let mut w = NpzWriter::new(Cursor::new(Vec::new()));
    w.add_array("theta_i", &ndarray::arr1(&[0.0])).unwrap();
    w.add_array("theta_r", &ndarray::arr1(&[0.0])).unwrap();
    w.add_array("phi", &ndarray::arr1(&[0.0])).unwrap();
    w.add_array("value", &ArrayD::from_elem(IxDyn(&[1, 1, 1]), 0.1f32))
        .unwrap();
    let (p, _) = parse_npz(&w.finish().unwrap().into_inner(), Path::new("v.npz")).unwrap();
    assert_eq!(p.samples[0].value, f64::from(0.1f32));
}

/// meta_json written as a NumPy string (`np.array(s)`) or another integer type says
/// how to write it (it said "profile arrays are float, integer or bool" / "expected
/// uint8 (or bool)").
#[test]
fn meta_json_of_the_wrong_dtype_says_how_to_write_it() {
    let how = "meta_json must be the UTF-8 bytes of a JSON text as a uint8 array, e.g. \
               np.frombuffer(s.encode(), np.uint8)";
    // A 0-d '<U2' array: 2 UCS-4 characters, 8 bytes.
    let mut text = npy_header_bytes("{'descr': '<U2', 'fortran_order': False, 'shape': (), }");
    text.extend([b'{', 0, 0, 0, b'}', 0, 0, 0]);
    let e = read_meta_json(&text, Path::new("m.npz"))
        .unwrap_err()
        .to_string();
    assert_eq!(e, format!("m.npz: array 'meta_json': dtype '<U2': {how}"));
    let mut int8 = npy_header_bytes("{'descr': '|i1', 'fortran_order': False, 'shape': (2,), }");
    int8.extend(b"{}");
    let e = read_meta_json(&int8, Path::new("m.npz"))
        .unwrap_err()
        .to_string();
    assert!(e.ends_with(&format!("dtype '|i1': {how}")), "{e}");
    let mut ok = npy_header_bytes("{'descr': '|u1', 'fortran_order': False, 'shape': (2,), }");
    ok.extend(b"{}");
    assert_eq!(read_meta_json(&ok, Path::new("m.npz")).unwrap().len(), 2);
}
