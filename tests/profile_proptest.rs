//! Fuzz-style properties: no loader panics on arbitrary input, and whatever the CSV loader
//! accepts survives a write/read round trip unchanged.

use furfit::profile::{csv, npz, same_sample, yan, LoadOptions};
use proptest::prelude::*;
use std::path::Path;

fn cfg() -> ProptestConfig {
    // 256 cases each keeps the whole file well under a second.
    ProptestConfig::with_cases(256)
}

/// CSV-ish text: a few header variants, then rows of tokens that are often numbers.
fn csvish() -> impl Strategy<Value = String> {
    let token = prop_oneof![
        (-200.0f64..200.0).prop_map(|v| format!("{v}")),
        (-3i32..200).prop_map(|v| v.to_string()),
        Just(String::new()),
        Just("nan".to_string()),
        Just("-inf".to_string()),
        Just("# x: y".to_string()),
        Just("\"q,uote\"".to_string()),
        "[a-z0-9 .#:\"-]{0,6}",
    ];
    let header = prop_oneof![
        Just("theta_i,theta_r,phi,value".to_string()),
        Just("value,phi,channel,theta_r,sigma,theta_i,extra".to_string()),
        Just("theta_i,theta_r,phi_i,phi,value,sigma".to_string()),
        "[a-z_,]{0,30}",
    ];
    let row = proptest::collection::vec(token, 0..8).prop_map(|t| t.join(","));
    (
        proptest::collection::vec("# [a-z]{0,5}: [a-z ]{0,8}", 0..3),
        header,
        proptest::collection::vec(row, 0..12),
    )
        .prop_map(|(meta, h, rows)| {
            let mut s = meta.join("\n");
            s.push('\n');
            s.push_str(&h);
            for r in rows {
                s.push('\n');
                s.push_str(&r);
            }
            s
        })
}

fn yanish() -> impl Strategy<Value = String> {
    let token = prop_oneof![
        (-400.0f64..400.0).prop_map(|v| format!("{v}")),
        (-100i32..400).prop_map(|v| v.to_string()),
        Just("?".to_string()),
        Just("nan".to_string()),
        "[a-z0-9.?#:-]{0,4}",
    ];
    let line = prop_oneof![
        proptest::collection::vec(token, 0..5).prop_map(|t| t.join(" ")),
        (-100.0f64..100.0).prop_map(|v| format!("# theta_i: {v}")),
        "# [a-z]{0,5}: [a-z0-9]{0,5}",
    ];
    proptest::collection::vec(line, 0..15).prop_map(|l| l.join("\n"))
}

/// Well-formed CSV: columns in a random order, valid angles, values that are often
/// invalid (empty, nan, <= 0), random sigma and channel.
fn valid_csv() -> impl Strategy<Value = String> {
    let value = prop_oneof![
        (1e-6f64..1e6).prop_map(|v| v.to_string()),
        (-10.0f64..0.0).prop_map(|v| v.to_string()),
        Just(String::new()),
        Just("NaN".to_string()),
        any::<f64>()
            .prop_filter("finite", |v| v.is_finite())
            .prop_map(|v| format!("{v:e}")),
    ];
    let sigma = prop_oneof![
        Just(String::new()),
        (0.0f64..1.0).prop_map(|v| v.to_string())
    ];
    let row = (
        -90.0f64..=90.0,
        -90.0f64..=90.0,
        -180.0f64..=180.0,
        value,
        sigma,
        prop_oneof![Just("r"), Just("g"), Just("650nm")],
    );
    (proptest::collection::vec(row, 1..20), any::<bool>()).prop_map(|(rows, flip)| {
        let mut s = String::from("# species: prop\n");
        s.push_str(if flip {
            "channel,sigma,value,phi,theta_r,theta_i\n"
        } else {
            "theta_i,theta_r,phi,value,sigma,channel\n"
        });
        // Index the angles by row number so rows never repeat a direction.
        for (k, (ti, tr, ph, v, sg, ch)) in rows.into_iter().enumerate() {
            let ti = if k % 2 == 0 { ti } else { (k as f64) - 10.0 };
            let line = if flip {
                format!("{ch},{sg},{v},{ph},{tr},{ti}\n")
            } else {
                format!("{ti},{tr},{ph},{v},{sg},{ch}\n")
            };
            s.push_str(&line);
        }
        s
    })
}

fn yan_opts() -> LoadOptions {
    LoadOptions {
        theta_i: Some(vec![10.0]),
        ..Default::default()
    }
}

proptest! {
    #![proptest_config(cfg())]

    #[test]
    fn csv_arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..400)) {
        let _ = csv::parse(&bytes, Path::new("f.csv"));
    }

    #[test]
    fn csv_ish_text_never_panics_and_round_trips(text in csvish()) {
        if let Ok((p, _)) = csv::parse(text.as_bytes(), Path::new("f.csv")) {
            // Whatever loads must write and read back identically.
            let out = csv::to_string(&p).unwrap();
            let (q, notes) = csv::parse(out.as_bytes(), Path::new("g.csv")).unwrap();
            prop_assert!(notes.is_empty());
            prop_assert_eq!(p.samples.len(), q.samples.len());
            for (a, b) in p.samples.iter().zip(&q.samples) {
                prop_assert!(same_sample(a, b), "{:?} vs {:?}", a, b);
            }
            prop_assert_eq!(&p.channels, &q.channels);
            prop_assert_eq!(&p.metadata, &q.metadata);
            // And through npz (grid order, so compare after sorting).
            let bytes = npz::to_bytes(&p).unwrap();
            let (mut r, _) = npz::parse_npz(&bytes, Path::new("h.npz")).unwrap();
            let mut p2 = p.clone();
            p2.sort_grid_order();
            r.sort_grid_order();
            prop_assert_eq!(p2.samples.len(), r.samples.len());
            for (a, b) in p2.samples.iter().zip(&r.samples) {
                prop_assert!(same_sample(a, b), "{:?} vs {:?}", a, b);
            }
        }
    }

    #[test]
    fn valid_csv_loads_and_round_trips_through_csv_and_npz(text in valid_csv()) {
        let (p, _) = csv::parse(text.as_bytes(), Path::new("f.csv"))
            .map_err(|e| TestCaseError::fail(format!("{e}\n{text}")))?;
        prop_assert_eq!(p.samples.len(), text.lines().count() - 2);
        let (q, _) = csv::parse(csv::to_string(&p).unwrap().as_bytes(), Path::new("g.csv")).unwrap();
        prop_assert_eq!(p.samples.len(), q.samples.len());
        for (a, b) in p.samples.iter().zip(&q.samples) {
            prop_assert!(same_sample(a, b), "{:?} vs {:?}", a, b);
        }
        let (mut r, _) = npz::parse_npz(&npz::to_bytes(&p).unwrap(), Path::new("h.npz")).unwrap();
        let mut p2 = p.clone();
        p2.sort_grid_order();
        r.sort_grid_order();
        prop_assert_eq!(&r.channels, &p.channels);
        prop_assert_eq!(&r.metadata, &p.metadata);
        for (a, b) in p2.samples.iter().zip(&r.samples) {
            prop_assert!(same_sample(a, b), "{:?} vs {:?}", a, b);
        }
    }

    #[test]
    fn yan_arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..400)) {
        let _ = yan::parse(&bytes, Path::new("f.txt"), &yan_opts());
        let _ = yan::parse(&bytes, Path::new("f.txt"), &LoadOptions::default());
    }

    #[test]
    fn yan_ish_text_never_panics(text in yanish()) {
        if let Ok((p, _)) = yan::parse(text.as_bytes(), Path::new("f.txt"), &yan_opts()) {
            prop_assert!(p.samples.iter().all(|s| s.phi > -180.0 && s.phi <= 180.0));
            prop_assert!(!p.samples.is_empty());
        }
    }

    #[test]
    fn npz_arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..600)) {
        let _ = npz::parse_npz(&bytes, Path::new("f.npz"));
        let o = LoadOptions {
            theta_i: Some(vec![0.0]),
            theta_r: Some(vec![0.0]),
            phi: Some(vec![0.0]),
            ..Default::default()
        };
        let _ = npz::parse_npy(&bytes, Path::new("f.npy"), &o);
    }

    #[test]
    fn npz_corrupted_valid_archive_never_panics(
        flips in proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..6),
        cut in any::<prop::sample::Index>(),
    ) {
        let p = furfit::profile::load(
            &Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/example.csv"),
            &LoadOptions::default(),
        ).unwrap();
        let mut bytes = npz::to_bytes(&p).unwrap();
        for (i, b) in flips {
            let k = i.index(bytes.len());
            bytes[k] = b;
        }
        let _ = npz::parse_npz(&bytes, Path::new("f.npz"));
        let n = cut.index(bytes.len());
        let _ = npz::parse_npz(&bytes[..n], Path::new("f.npz"));
    }
}
