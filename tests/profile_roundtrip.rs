//! Round trips between the profile formats, and the committed example data.
//!
//! `tests/data/example.npz` is the npz writer's output for `tests/data/example.csv`;
//! regenerate it with `FURFIT_REGEN_DATA=1 cargo test --test profile_roundtrip`.

use furfit::profile::{self, csv, npz, same_sample, LoadOptions, Profile};
use std::path::{Path, PathBuf};

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name)
}

/// Every sample of `a` has an identical partner in `b` and the counts agree (NaN == NaN,
/// bit-exact floats otherwise: the formats promise lossless round trips, so no tolerance).
fn same_sample_set(a: &Profile, b: &Profile) -> bool {
    let mut a = a.clone();
    let mut b = b.clone();
    a.sort_grid_order();
    b.sort_grid_order();
    a.samples.len() == b.samples.len()
        && a.samples
            .iter()
            .zip(&b.samples)
            .all(|(x, y)| same_sample(x, y) && x.theta_i.to_bits() == y.theta_i.to_bits())
}

#[test]
fn example_csv_reads_as_hand_counted() {
    let p = profile::load(&data("example.csv"), &LoadOptions::default()).unwrap();
    // 2 theta_i x 3 theta_r x 4 phi, two of them invalid (an empty value and a 0).
    assert_eq!(p.samples.len(), 24);
    assert_eq!(p.n_invalid(), 2);
    assert_eq!(p.n_valid(), 22);
    assert_eq!(p.metadata.len(), 3);
    assert_eq!(p.meta("fiber"), Some("1"));
    assert!(p.is_synthetic());
    assert_eq!(p.samples.iter().filter(|s| s.sigma.is_some()).count(), 8);
    // Row 1 of the file (line 5): phi 0, value 1.0, theta_r -30, theta_i 0, sigma 0.01.
    let s0 = &p.samples[0];
    assert_eq!(
        (s0.theta_i, s0.theta_r, s0.phi, s0.value, s0.sigma),
        (0.0, -30.0, 0.0, 1.0, Some(0.01))
    );
}

#[test]
fn csv_npz_csv_is_lossless() {
    let dir = tempfile::tempdir().unwrap();
    let mut p1 = profile::load(&data("example.csv"), &LoadOptions::default()).unwrap();
    p1.sort_grid_order();
    let csv1 = csv::to_string(&p1).unwrap();

    let npz_path = dir.path().join("x.npz");
    profile::save(&npz_path, &p1).unwrap();
    let p2 = profile::load(&npz_path, &LoadOptions::default()).unwrap();
    assert!(same_sample_set(&p1, &p2));
    assert_eq!(p2.metadata, p1.metadata);
    assert_eq!(p2.channels, p1.channels);
    // npz loads come out in grid order, which is the order we sorted p1 into.
    assert_eq!(csv::to_string(&p2).unwrap(), csv1);

    // And back through a CSV file on disk.
    let csv_path = dir.path().join("y.csv");
    profile::save(&csv_path, &p2).unwrap();
    assert_eq!(std::fs::read_to_string(&csv_path).unwrap(), csv1);
    let p3 = profile::load(&csv_path, &LoadOptions::default()).unwrap();
    assert!(same_sample_set(&p1, &p3));
    assert_eq!(p3.metadata, p1.metadata);
}

#[test]
fn multichannel_awkward_floats_round_trip() {
    let mut p = Profile {
        channels: vec!["r".into(), "650nm".into(), "with, comma".into()],
        metadata: vec![("note".into(), "x: y".into())],
        ..Default::default()
    };
    let vals = [
        1.0 / 3.0,
        1e-300,
        -2.5,
        f64::NAN,
        0.0,
        6.02214076e23,
        f64::MIN_POSITIVE,
    ];
    for (k, v) in vals.iter().enumerate() {
        for c in 0..3 {
            p.samples.push(furfit::Sample {
                theta_i: 0.1 * k as f64,
                theta_r: -89.99999999999,
                phi: if k == 0 {
                    180.0
                } else {
                    -179.5 + k as f64 / 7.0
                },
                value: *v,
                sigma: (c == 1).then_some(0.1 + k as f64),
                channel: c,
                phi_i: (c == 2).then_some(12.5),
                origin: Default::default(),
            });
        }
    }
    let dir = tempfile::tempdir().unwrap();
    for ext in ["csv", "npz"] {
        let path = dir.path().join(format!("m.{ext}"));
        profile::save(&path, &p).unwrap();
        let q = profile::load(&path, &LoadOptions::default()).unwrap();
        assert!(same_sample_set(&p, &q), "{ext}");
        assert_eq!(q.channels, p.channels, "{ext}");
        assert_eq!(q.metadata, p.metadata, "{ext}");
    }
}

#[test]
fn committed_npz_is_the_writers_output_for_the_csv() {
    let p = profile::load(&data("example.csv"), &LoadOptions::default()).unwrap();
    let bytes = npz::to_bytes(&p).unwrap();
    let path = data("example.npz");
    if std::env::var_os("FURFIT_REGEN_DATA").is_some() {
        std::fs::write(&path, &bytes).unwrap();
    }
    let committed =
        std::fs::read(&path).expect("tests/data/example.npz (regenerate: see module doc)");
    assert_eq!(committed, bytes, "example.npz is stale; regenerate it");
    let q = profile::load(&path, &LoadOptions::default()).unwrap();
    assert!(same_sample_set(&p, &q));
}

#[test]
fn yan_example_reads_as_hand_counted() {
    let p = profile::load(&data("yan_theta30.txt"), &LoadOptions::default()).unwrap();
    assert_eq!(p.samples.len(), 12);
    assert_eq!(p.n_invalid(), 2);
    assert!(p.samples.iter().all(|s| s.theta_i == 30.0));
    // phi 270 in the file is -90 after the wrap to (-180, 180].
    assert_eq!(p.samples.iter().filter(|s| s.phi == -90.0).count(), 3);
    assert!(p.samples.iter().all(|s| s.phi > -180.0 && s.phi <= 180.0));
    // Each sample knows its file and line, for errors found after loading.
    let at = |k: usize| p.origin_of(&p.samples[k]).unwrap();
    assert!(at(0).ends_with("yan_theta30.txt line 4"), "{}", at(0));
    assert!(at(4).ends_with("yan_theta30.txt line 8"), "{}", at(4));
}

#[test]
fn load_dir_merges_and_skips_metadata() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::copy(data("example.csv"), dir.path().join("a.csv")).unwrap();
    std::fs::copy(data("yan_theta30.txt"), dir.path().join("b.txt")).unwrap();
    std::fs::write(dir.path().join("metadata.json"), "{}").unwrap();
    std::fs::write(dir.path().join("README.md"), "hi").unwrap();
    std::fs::write(dir.path().join("README.txt"), "not a profile").unwrap();
    // The CSV and the Yan file overlap at theta_i 30, theta_r -30, phi 0 with different
    // values (1.3 and 0.2), so merging them is an error naming both files.
    let e = profile::load_dir(dir.path(), &LoadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("b.txt") && e.contains("a.csv"), "{e}");
    // Without the CSV's theta_i = 30 half they merge cleanly.
    let mut a = profile::load(&data("example.csv"), &LoadOptions::default()).unwrap();
    a.samples.retain(|s| s.theta_i == 0.0);
    let dir2 = tempfile::tempdir().unwrap();
    profile::save(&dir2.path().join("a.csv"), &a).unwrap();
    std::fs::copy(data("yan_theta30.txt"), dir2.path().join("b.txt")).unwrap();
    std::fs::write(dir2.path().join("metadata.json"), "{}").unwrap();
    let m = profile::load_dir(dir2.path(), &LoadOptions::default()).unwrap();
    assert_eq!(m.profile.samples.len(), 12 + 12);
    assert_eq!(m.profile.source.as_deref(), Some(dir2.path()));
}
