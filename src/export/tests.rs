use super::material::exact;
use super::*;
use crate::models::chiang2016::Chiang2016;
use crate::models::ModelParams;

fn material(beta_m: f64, beta_n: f64, alpha: f64, sigma: [f64; 3]) -> Material {
    Material {
        name: "red-fox".into(),
        eta: 1.55,
        beta_m,
        beta_n,
        alpha_deg: alpha,
        sigma_a: sigma,
        exposure: 2.0,
        origin: Origin::Exact {
            fit: "fits/chiang2016/red-fox.json".into(),
            nrmse: 0.05,
        },
        notes: Vec::new(),
    }
}

/// The value of `attr="..."` on the line of `text` that holds `key`.
fn attr(text: &str, key: &str, attr: &str) -> String {
    let line = text
        .lines()
        .find(|l| l.contains(key))
        .unwrap_or_else(|| panic!("{key}"));
    let start = line.find(&format!("{attr}=\"")).unwrap() + attr.len() + 2;
    line[start..start + line[start..].find('"').unwrap()].to_string()
}

#[test]
fn formats_parse_and_unknown_names_the_choices() {
    assert_eq!(Format::parse("Mitsuba").unwrap(), Format::Mitsuba);
    assert_eq!(Format::parse("pbrt-v4").unwrap(), Format::Pbrt);
    assert_eq!(Format::parse("blender").unwrap(), Format::Cycles);
    assert_eq!(Format::parse("mtlx").unwrap(), Format::MaterialX);
    let e = Format::parse("arnold").unwrap_err().to_string();
    assert!(e.contains("arnold") && e.contains("materialx"), "{e}");
}

/// Every Mitsuba value reads back to the material's bits (shortest round-trip digits).
#[test]
fn mitsuba_values_round_trip_exactly() {
    let m = material(
        0.3141592653589793,
        0.9,
        -19.99999971484908,
        [0.1, 0.2, 9e-14],
    );
    let w = mitsuba::write(&m).unwrap();
    let f = |k: &str| {
        attr(&w.text, &format!("\"{k}\""), "value")
            .parse::<f64>()
            .unwrap()
    };
    assert_eq!(f("longitudinal_roughness"), m.beta_m);
    assert_eq!(f("azimuthal_roughness"), m.beta_n);
    assert_eq!(f("scale_tilt"), m.alpha_deg);
    assert_eq!(f("int_ior"), m.eta);
    assert_eq!(f("ext_ior"), 1.0);
    let s: Vec<f64> = attr(&w.text, "name=\"sigma_a\"", "value")
        .split(',')
        .map(|x| x.trim().parse().unwrap())
        .collect();
    assert_eq!(s, m.sigma_a.to_vec());
    assert!(w.text.lines().nth(1).unwrap().contains(MARKER));
    // No `--` inside a comment (invalid XML).
    for l in w.text.lines().filter(|l| l.starts_with("<!--")) {
        assert!(!l[4..l.len() - 3].contains("--"), "{l}");
    }
    let mut near_one = m.clone();
    near_one.eta = 1.0 + 1e-9;
    let e = mitsuba::write(&near_one).unwrap_err().to_string();
    assert!(e.contains("eta") && e.contains("single precision"), "{e}");
}

/// pbrt-v4: the block parses back (pbrt's tokens) and every value is the material's.
#[test]
fn pbrt_block_parses_back_to_every_value() {
    let m = material(0.25, 0.75, 2.5, [0.419, 0.697, 1.37]);
    let w = pbrt::write(&m).unwrap();
    let p = pbrt::parse_params(&w.text, "Material").unwrap();
    let get = |name: &str| {
        let (ty, _, v) = p.iter().find(|(_, n, _)| n == name).unwrap();
        (
            ty.clone(),
            v.iter()
                .map(|x| x.parse::<f64>().unwrap())
                .collect::<Vec<_>>(),
        )
    };
    assert_eq!(get("sigma_a"), ("rgb".into(), m.sigma_a.to_vec()));
    assert_eq!(get("eta"), ("float".into(), vec![m.eta]));
    assert_eq!(get("beta_m"), ("float".into(), vec![m.beta_m]));
    assert_eq!(get("beta_n"), ("float".into(), vec![m.beta_n]));
    assert_eq!(get("alpha"), ("float".into(), vec![m.alpha_deg]));
    assert_eq!(p.len(), 5);
    assert!(w.text.contains("Material \"hair\""));
}

/// MaterialX: `(v, s)` per lobe are pbrt's variances and the logistic scale over
/// `sqrt(pi/8)`; the tilt maps to `0.5 - alpha/180`; out-of-range roughness is clamped
/// and named.
#[test]
fn materialx_maps_roughness_and_names_its_clamps() {
    let m = material(0.3, 0.3, 2.0, [0.5; 3]);
    let w = materialx::write(&m).unwrap();
    let v = crate::models::chiang2016::lobes::variances(0.3);
    let s =
        crate::models::chiang2016::lobes::logistic_scale(0.3) / (std::f64::consts::PI / 8.0).sqrt();
    let pair = |k: &str| -> Vec<f64> {
        attr(&w.text, &format!("\"roughness_{k}\""), "value")
            .split(',')
            .map(|x| x.trim().parse().unwrap())
            .collect()
    };
    assert_eq!(pair("R"), vec![v[0], s]);
    assert_eq!(pair("TT"), vec![v[1], s]);
    assert_eq!(pair("TRT"), vec![v[2], s]);
    // v/4 and 4v as mx_chiang_hair_roughness's scale_TT 0.5, scale_TRT 2 give them.
    assert!((v[1] - v[0] * 0.25).abs() < 1e-15 && (v[2] - 4.0 * v[0]).abs() < 1e-15);
    let ca: f64 = attr(&w.text, "cuticle_angle", "value").parse().unwrap();
    // 2 deg = pi/90 rad: genglsl's alpha = ca * pi - pi/2 must be -2 deg in radians.
    assert!(
        (ca * std::f64::consts::PI - std::f64::consts::FRAC_PI_2 + 2f64.to_radians()).abs() < 1e-15
    );
    assert!(w.notes.is_empty(), "{:?}", w.notes);
    let rough = material(0.95, 0.95, 2.0, [0.5; 3]);
    let w = materialx::write(&rough).unwrap();
    assert_eq!(pair_of(&w.text, "R"), vec![1.0, 1.0]);
    assert_eq!(w.notes.len(), 6, "{:?}", w.notes);
    assert!(w.notes[0].contains("roughness_R variance v") && w.notes[0].contains("written as 1"));
    assert!(w.text.contains("note: roughness_R variance v"));
}

fn pair_of(text: &str, lobe: &str) -> Vec<f64> {
    attr(text, &format!("\"roughness_{lobe}\""), "value")
        .split(',')
        .map(|x| x.trim().parse().unwrap())
        .collect()
}

/// Cycles: values in the script as given, the Offset converted to radians by the script,
/// and what Blender's sockets cannot hold clamped with a note.
#[test]
fn cycles_script_holds_values_and_names_clamps() {
    let m = material(0.3, 0.4, -3.0, [0.1, 0.2, 0.3]);
    let w = cycles::write(&m).unwrap();
    assert!(w.text.contains("\"beta_m\": 0.3,") && w.text.contains("\"alpha_deg\": -3,"));
    assert!(w.text.contains("\"sigma_a\": (0.1, 0.2, 0.3)"));
    assert!(w.text.contains("math.radians(PARAMS[\"alpha_deg\"])"));
    assert!(w.notes.is_empty());
    let w = cycles::write(&material(0.0005, 0.4, 2.0, [2000.0, 1.0, 1.0])).unwrap();
    assert_eq!(w.notes.len(), 2, "{:?}", w.notes);
    assert!(w.notes[0].contains("Roughness") && w.notes[0].contains("written as 0.001"));
    assert!(w.notes[1].contains("Absorption") && w.notes[1].contains("written as 1000"));
    assert!(w.text.contains("# note: beta_m (Roughness)"));
}

/// An r, g, b fit gives one absorption per channel and the green channel's other
/// parameters, with a note when the channels disagree.
#[test]
fn rgb_channels_give_per_channel_absorption() {
    let ch = |name: &str, eta: f64, sigma: f64| crate::models::Channel {
        name: name.into(),
        params: ModelParams::from_file_units(&Chiang2016, &[eta, 0.3, 0.4, 2.0, sigma]).unwrap(),
        exposure: 1.0,
    };
    let chans = vec![ch("r", 1.55, 0.2), ch("g", 1.55, 0.5), ch("b", 1.55, 1.2)];
    let m = exact("x", &chans[0].params, 1.0, &chans).unwrap();
    assert_eq!(m.sigma_a, [0.2, 0.5, 1.2]);
    assert!(m.notes.is_empty(), "{:?}", m.notes);
    let chans = vec![
        ch("red", 1.5, 0.2),
        ch("green", 1.55, 0.5),
        ch("blue", 1.6, 1.2),
    ];
    let m = exact("x", &chans[0].params, 1.0, &chans).unwrap();
    assert_eq!(m.eta, 1.55);
    assert!(
        m.notes.len() == 1 && m.notes[0].contains("eta"),
        "{:?}",
        m.notes
    );
    let chans = vec![ch("r", 1.55, 0.2), ch("nir", 1.55, 0.5)];
    let e = exact("x", &chans[0].params, 1.0, &chans)
        .unwrap_err()
        .to_string();
    assert!(e.contains("nir") && e.contains("r, g, b"), "{e}");
}

#[test]
fn existing_output_needs_force_and_must_be_an_export() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("a.xml");
    check_out(&p, false).unwrap();
    std::fs::write(&p, "<scene/>\n").unwrap();
    let e = check_out(&p, false).unwrap_err().to_string();
    assert!(e.contains("--force"), "{e}");
    let e = check_out(&p, true).unwrap_err().to_string();
    assert!(e.contains("not a file written by furfit export"), "{e}");
    let m = material(0.3, 0.3, 2.0, [0.5; 3]);
    std::fs::write(&p, mitsuba::write(&m).unwrap().text).unwrap();
    assert!(check_out(&p, false).is_err());
    check_out(&p, true).unwrap();
}
