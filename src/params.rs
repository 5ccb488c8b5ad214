//! The ten fur fiber parameters (seed Table 1), their hard bounds (MODEL.md), the seed
//! Table 4 presets, and the JSON parameter-file format of DATA.md.
//!
//! Inside the library every angle is in radians; files and the command line use degrees.
//! Lengths (absorption and scattering coefficients) are per unit fiber radius.

use crate::error::{Error, Num, Result};
use serde_json::{Map, Value};
use std::path::Path;

/// Number of model parameters.
pub const N_PARAMS: usize = 10;

/// One of the ten parameters, in the fixed order used by vectors and tables.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum ParamId {
    /// `eta`: index of refraction of cortex and medulla, in (1, 3].
    Eta,
    /// `kappa`: medulla radius over fiber radius, in [0, 1).
    Kappa,
    /// `alpha`: cuticle scale tilt, which shifts the R/TT/TRT longitudinal peaks (seed
    /// Table 2); degrees in [-20, 20] in files.
    Alpha,
    /// `beta_m`: longitudinal roughness (the lobes' width in theta), degrees in (0, 60] in
    /// files.
    BetaM,
    /// `beta_n`: azimuthal roughness (the lobes' width in phi), degrees in (0, 90] in
    /// files.
    BetaN,
    /// `sigma_c_a`: cortex absorption coefficient, per unit fiber radius, >= 0.
    SigmaCA,
    /// `sigma_m_s`: medulla scattering coefficient, per unit fiber radius, >= 0.
    SigmaMS,
    /// `sigma_m_a`: medulla absorption coefficient, per unit fiber radius, >= 0.
    SigmaMA,
    /// `g`: Henyey-Greenstein anisotropy of the medulla's scattering, in (-1, 1).
    G,
    /// `l`: number of cuticle layers in the layered cuticle reflectance (seed Eq. 13-14),
    /// in (0, 10].
    L,
}

impl ParamId {
    /// All parameters in file/table order (MODEL.md's table).
    pub const ALL: [ParamId; N_PARAMS] = [
        ParamId::Eta,
        ParamId::Kappa,
        ParamId::Alpha,
        ParamId::BetaM,
        ParamId::BetaN,
        ParamId::SigmaCA,
        ParamId::SigmaMS,
        ParamId::SigmaMA,
        ParamId::G,
        ParamId::L,
    ];

    /// Position in [`ParamId::ALL`].
    pub const fn index(self) -> usize {
        self as usize
    }

    /// The specification (name, unit, bounds) of this parameter.
    pub fn spec(self) -> &'static ParamSpec {
        &SPECS[self.index()]
    }

    /// Look a parameter up by its file key (`eta`, `beta_m`, ...).
    pub fn from_name(name: &str) -> Option<ParamId> {
        ParamId::ALL.into_iter().find(|p| p.spec().name == name)
    }
}

/// Name, unit and hard bounds of one parameter. Bounds are in file units (degrees for
/// angles); `lower_open`/`upper_open` say whether the bound itself is excluded.
#[derive(Clone, Copy, Debug)]
pub struct ParamSpec {
    /// File key (`eta`, `beta_m`, ...), as parameter and fit files spell it.
    pub name: &'static str,
    /// What the parameter means, in a few words (for tables and messages).
    pub meaning: &'static str,
    /// Unit in files: `deg`, `1/radius` or `-` (dimensionless).
    pub unit: &'static str,
    /// Lower hard bound, file units.
    pub lower: f64,
    /// Whether `lower` itself is excluded.
    pub lower_open: bool,
    /// Upper hard bound, file units (may be infinite).
    pub upper: f64,
    /// Whether `upper` itself is excluded.
    pub upper_open: bool,
    /// Angle in degrees in files, radians inside.
    pub is_angle: bool,
}

impl ParamSpec {
    /// `v` (file units) for a one-line summary: five significant digits (an exponent
    /// beyond 1e6 or below 1e-3), or every digit where five would print a bound the
    /// value is not on (`kappa` 0.9999966 is not `1.0000`, outside `[0, 1)`).
    pub fn value_text(&self, v: f64) -> String {
        let a = v.abs();
        let short = if a == 0.0 || !a.is_finite() {
            format!("{v}")
        } else if !(1e-3..1e6).contains(&a) {
            format!("{v:.4e}")
        } else {
            let decimals = (4 - a.log10().floor() as i32).max(0) as usize;
            format!("{v:.decimals$}")
        };
        self.off_bound(v, short)
    }

    /// `v` (file units) with `decimals` decimals (report tables), or every digit where
    /// that would print a bound the value is not on (as [`Self::value_text`]).
    pub fn fixed_text(&self, v: f64, decimals: usize) -> String {
        self.off_bound(v, format!("{v:.decimals$}"))
    }

    /// `short`, the text of `v`, unless it reads as an excluded (open) bound: then the
    /// fewest more digits that tell `v` from it (an exponent below 1e-3). A closed bound
    /// may be printed: `v` could be on it.
    fn off_bound(&self, v: f64, short: String) -> String {
        let excluded = |text: &str| {
            text.parse::<f64>().is_ok_and(|r| {
                (self.lower_open && r == self.lower) || (self.upper_open && r == self.upper)
            })
        };
        if !excluded(&short) {
            return short;
        }
        if v != 0.0 && v.abs() < 1e-3 {
            return format!("{v:.3e}");
        }
        (0..=17)
            .map(|d| format!("{v:.d$}"))
            .find(|t| !excluded(t))
            .unwrap_or_else(|| crate::error::Num(v).to_string())
    }

    /// Is `v` (file units) inside the hard bounds?
    pub fn contains(&self, v: f64) -> bool {
        if !v.is_finite() {
            return false;
        }
        let lo = if self.lower_open {
            v > self.lower
        } else {
            v >= self.lower
        };
        let hi = if self.upper_open {
            v < self.upper
        } else {
            v <= self.upper
        };
        lo && hi
    }

    /// [`Self::bound_text`] followed by the unit, if the parameter has one.
    pub fn bound_with_unit(&self) -> String {
        if self.unit == "-" {
            self.bound_text()
        } else {
            format!("{} {}", self.bound_text(), self.unit)
        }
    }

    /// The bound as interval notation, e.g. `(1, 3]`.
    pub fn bound_text(&self) -> String {
        let up = if self.upper.is_infinite() {
            "inf".to_string()
        } else {
            Num(self.upper).to_string()
        };
        format!(
            "{}{}, {}{}",
            if self.lower_open { '(' } else { '[' },
            Num(self.lower),
            up,
            if self.upper_open || self.upper.is_infinite() {
                ')'
            } else {
                ']'
            }
        )
    }

    /// File units -> internal units.
    pub fn to_internal(&self, v: f64) -> f64 {
        if self.is_angle {
            v.to_radians()
        } else {
            v
        }
    }

    /// Internal units -> file units.
    pub fn to_file(&self, v: f64) -> f64 {
        if self.is_angle {
            v.to_degrees()
        } else {
            v
        }
    }
}

const INF: f64 = f64::INFINITY;

/// Hard bounds exactly as MODEL.md's table.
pub const SPECS: [ParamSpec; N_PARAMS] = [
    spec(
        "eta",
        "IOR of cortex and medulla",
        "-",
        (1.0, true, 3.0, false),
        false,
    ),
    spec(
        "kappa",
        "medulla radius / fiber radius",
        "-",
        (0.0, false, 1.0, true),
        false,
    ),
    spec(
        "alpha",
        "cuticle scale tilt",
        "deg",
        (-20.0, false, 20.0, false),
        true,
    ),
    spec(
        "beta_m",
        "longitudinal roughness",
        "deg",
        (0.0, true, 60.0, false),
        true,
    ),
    spec(
        "beta_n",
        "azimuthal roughness",
        "deg",
        (0.0, true, 90.0, false),
        true,
    ),
    spec(
        "sigma_c_a",
        "cortex absorption",
        "1/radius",
        (0.0, false, INF, true),
        false,
    ),
    spec(
        "sigma_m_s",
        "medulla scattering",
        "1/radius",
        (0.0, false, INF, true),
        false,
    ),
    spec(
        "sigma_m_a",
        "medulla absorption",
        "1/radius",
        (0.0, false, INF, true),
        false,
    ),
    spec(
        "g",
        "HG anisotropy in the medulla",
        "-",
        (-1.0, true, 1.0, true),
        false,
    ),
    spec("l", "cuticle layers", "-", (0.0, true, 10.0, false), false),
];

/// A parameter's spec in a model's static table: `bounds` is `(lower, lower_open, upper,
/// upper_open)` in file units.
pub(crate) const fn spec(
    name: &'static str,
    meaning: &'static str,
    unit: &'static str,
    bounds: (f64, bool, f64, bool),
    is_angle: bool,
) -> ParamSpec {
    ParamSpec {
        name,
        meaning,
        unit,
        lower: bounds.0,
        lower_open: bounds.1,
        upper: bounds.2,
        upper_open: bounds.3,
        is_angle,
    }
}
/// The ten parameters of the 5-lobe fur BCSDF, in internal units (radians, 1/radius).
/// Construct through [`FurParams::from_file_units`] or [`FurParams::new_checked`] so the
/// hard bounds are enforced once, at the boundary.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FurParams {
    /// Index of refraction of cortex and medulla (seed Table 1 `eta`).
    pub eta: f64,
    /// Medulla radius / fiber radius (seed Table 1 `kappa`).
    pub kappa: f64,
    /// Cuticle scale tilt, radians (lobe `p` peaks shifted by a multiple of it, seed
    /// Table 2).
    pub alpha: f64,
    /// Longitudinal roughness, radians: the width of R's `M_p` (TT and TRT take
    /// `beta_m / 2` and `3 beta_m / 2`, seed Table 2).
    pub beta_m: f64,
    /// Azimuthal roughness, radians (the width of `N_p`).
    pub beta_n: f64,
    /// Cortex absorption coefficient, per unit fiber radius.
    pub sigma_c_a: f64,
    /// Medulla scattering coefficient, per unit fiber radius.
    pub sigma_m_s: f64,
    /// Medulla absorption coefficient, per unit fiber radius.
    pub sigma_m_a: f64,
    /// Henyey-Greenstein anisotropy of medulla scattering.
    pub g: f64,
    /// Cuticle layers of the layered cuticle reflectance (seed Eq. 13-14).
    pub l: f64,
}

impl FurParams {
    /// Internal-unit vector in [`ParamId::ALL`] order.
    pub fn to_array(&self) -> [f64; N_PARAMS] {
        [
            self.eta,
            self.kappa,
            self.alpha,
            self.beta_m,
            self.beta_n,
            self.sigma_c_a,
            self.sigma_m_s,
            self.sigma_m_a,
            self.g,
            self.l,
        ]
    }

    /// From an internal-unit vector; no validation (use [`FurParams::validate`]).
    pub fn from_array(a: [f64; N_PARAMS]) -> Self {
        FurParams {
            eta: a[0],
            kappa: a[1],
            alpha: a[2],
            beta_m: a[3],
            beta_n: a[4],
            sigma_c_a: a[5],
            sigma_m_s: a[6],
            sigma_m_a: a[7],
            g: a[8],
            l: a[9],
        }
    }

    /// Value of one parameter, internal units.
    pub fn get(&self, id: ParamId) -> f64 {
        self.to_array()[id.index()]
    }

    /// Set one parameter, internal units; no validation.
    pub fn set(&mut self, id: ParamId, v: f64) {
        let mut a = self.to_array();
        a[id.index()] = v;
        *self = FurParams::from_array(a);
    }

    /// File-unit vector (degrees for angles).
    pub fn to_file_units(&self) -> [f64; N_PARAMS] {
        let mut a = self.to_array();
        for id in ParamId::ALL {
            a[id.index()] = id.spec().to_file(a[id.index()]);
        }
        a
    }

    /// From file units (degrees), validated against the hard bounds.
    pub fn from_file_units(a: [f64; N_PARAMS]) -> Result<Self> {
        for id in ParamId::ALL {
            check_bound(id, a[id.index()])?;
        }
        let mut b = a;
        for id in ParamId::ALL {
            b[id.index()] = id.spec().to_internal(a[id.index()]);
        }
        Ok(FurParams::from_array(b))
    }

    /// Internal units, validated.
    pub fn new_checked(a: [f64; N_PARAMS]) -> Result<Self> {
        let p = FurParams::from_array(a);
        p.validate()?;
        Ok(p)
    }

    /// Check every parameter against its hard bound; the error names the key and bound.
    pub fn validate(&self) -> Result<()> {
        for (id, v) in ParamId::ALL.into_iter().zip(self.to_file_units()) {
            check_bound(id, v)?;
        }
        Ok(())
    }

    /// A seed Table 4 preset by name (`bobcat`, `cat`, `deer`, `dog`, `mouse`, `rabbit`,
    /// `raccoon`, `red-fox`, `springbok`, `human`). Also accepts `red_fox`/`redfox`.
    pub fn preset(name: &str) -> Option<FurParams> {
        let key = name.to_ascii_lowercase().replace(['_', ' '], "-");
        let key = if key == "redfox" {
            "red-fox".to_string()
        } else {
            key
        };
        PRESETS
            .iter()
            .find(|p| p.name == key)
            .map(|p| FurParams::from_file_units(p.values).expect("presets are within bounds"))
    }

    /// Parse a parameter JSON object (DATA.md "Parameter files"). Returns the parameters
    /// and the optional exposure (default 1). `origin` names the source in errors.
    pub fn from_json_value(v: &Value) -> Result<(FurParams, f64)> {
        let obj = v.as_object().ok_or_else(|| Error::Param {
            key: "<file>".into(),
            msg: "a parameter file must be a JSON object".into(),
        })?;
        // A parameter or fit file of another model (`crate::models`): the fur model's own
        // commands (render, simulate) cannot read it.
        if let Some(m) = obj.get("model").filter(|m| m.as_str() != Some("yan2017")) {
            return Err(Error::Param {
                key: "model".into(),
                msg: format!(
                    "these parameters are of model {m}; this command reads the yan2017 fur \
                     model's only"
                ),
            });
        }
        // A fit file: take its `params` object (and its exposure).
        if let Some(inner) = obj.get("params") {
            let (p, _) = FurParams::from_json_value(inner)?;
            let k = match obj.get("exposure") {
                Some(e) => parse_exposure(e)?,
                None => 1.0,
            };
            return Ok((p, k));
        }
        // A fit file that lost its `params` (hand-edited, truncated by a tool) would
        // otherwise be read as a parameter file and blamed on its first other key.
        if ["uncertainty", "solver", "nrmse", "trace"]
            .iter()
            .any(|k| obj.contains_key(*k))
        {
            return Err(Error::Param {
                key: "params".into(),
                msg: "missing: this looks like a fit file (it has fit keys such as \
                      uncertainty or solver) but has no `params` object"
                    .into(),
            });
        }
        let mut vals = [f64::NAN; N_PARAMS];
        let mut seen = [false; N_PARAMS];
        let mut exposure = 1.0;
        for (key, val) in obj {
            if key == "exposure" || key == "model" {
                exposure = parse_exposure(val)?;
                continue;
            }
            let id = ParamId::from_name(key).ok_or_else(|| Error::Param {
                key: key.clone(),
                msg: format!(
                    "unknown key (expected one of: {}, and optionally exposure)",
                    ParamId::ALL.map(|p| p.spec().name).join(", ")
                ),
            })?;
            let x = json_number(val).ok_or_else(|| Error::Param {
                key: key.clone(),
                msg: format!("expected a number, found {val}"),
            })?;
            vals[id.index()] = x;
            seen[id.index()] = true;
        }
        if let Some(missing) = ParamId::ALL.into_iter().find(|p| !seen[p.index()]) {
            return Err(Error::Param {
                key: missing.spec().name.into(),
                msg: "missing key".into(),
            });
        }
        Ok((FurParams::from_file_units(vals)?, exposure))
    }

    /// The parameter JSON object (file units), keys in table order.
    pub fn to_json_value(&self) -> Value {
        let mut m = Map::new();
        for (id, v) in ParamId::ALL.into_iter().zip(self.typed_file_units()) {
            m.insert(id.spec().name.into(), Value::from(v));
        }
        Value::Object(m)
    }

    /// [`Self::to_file_units`] as they were typed: an angle given as 3.75 deg comes back
    /// from radians as 3.7499999999999996, so each value is the shortest 12-digit form
    /// when that reads back to the same internal value (what files and printouts show).
    pub fn typed_file_units(&self) -> [f64; N_PARAMS] {
        let internal = self.to_array();
        let mut out = self.to_file_units();
        for (id, v) in ParamId::ALL.into_iter().zip(out.iter_mut()) {
            let short: f64 = format!("{v:.12e}").parse().unwrap_or(*v);
            if id.spec().to_internal(short) == internal[id.index()] {
                *v = short;
            }
        }
        out
    }

    /// Load parameters from a preset name, a parameter JSON file or a fit JSON file.
    /// Returns parameters and exposure.
    pub fn load(spec: &str) -> Result<(FurParams, f64)> {
        FurParams::load_json(spec).map(|(p, k, _)| (p, k))
    }

    /// [`FurParams::load`], with the file's JSON (`None` for a preset) for what else it
    /// holds, e.g. a fit's channels.
    pub fn load_json(spec: &str) -> Result<(FurParams, f64, Option<Value>)> {
        if let Some(p) = FurParams::preset(spec) {
            if !Path::new(spec).exists() {
                return Ok((p, 1.0, None));
            }
        }
        let path = Path::new(spec);
        let text = std::fs::read_to_string(path).map_err(|e| {
            let looks_like_path = spec.contains(['/', '\\']) || path.extension().is_some();
            if e.kind() == std::io::ErrorKind::NotFound && looks_like_path {
                Error::file(path, "no such parameter or fit file")
            } else if e.kind() == std::io::ErrorKind::NotFound {
                Error::Invalid(format!(
                    "'{spec}' is neither a preset nor an existing parameter/fit file (presets: {})",
                    preset_names().join(", ")
                ))
            } else {
                Error::io(path, e)
            }
        })?;
        let v = crate::io::parse_json(&text, path)?;
        let (p, k) = FurParams::from_json_value(&v).map_err(|e| match e {
            Error::Param { key, msg } => Error::Param {
                key,
                msg: format!("{msg} (in {})", path.display()),
            },
            other => other,
        })?;
        Ok((p, k, Some(v)))
    }
}

/// A note for the commands to print when `spec` names both a preset and an existing file:
/// [`FurParams::load_json`] reads the file (what the user put there), which would
/// otherwise pass for the preset unsaid.
pub fn preset_shadow_note(spec: &str) -> Option<String> {
    (FurParams::preset(spec).is_some() && Path::new(spec).exists()).then(|| {
        format!(
            "note: '{spec}' is read from the file of that name here, not the preset '{spec}' \
             (move or rename the file to use the preset)"
        )
    })
}

/// One channel of a multi-channel fit file (its `channels` array, `fit::job`).
#[derive(Clone, Debug, PartialEq)]
pub struct FitChannel {
    /// The channel's name (`data.channel`).
    pub name: String,
    /// The channel's fitted parameters.
    pub params: FurParams,
    /// The channel's exposure `k` (the closed-form scale between model and data).
    pub exposure: f64,
}

/// The channels of a fit file's JSON (`v` as [`FurParams::load_json`] returns it): each
/// of a multi-channel fit's `channels`, the one channel of a fit of one named channel (its
/// top level, `data.channel`), and none for a parameter file or a fit of unnamed data.
/// `spec` names the file in errors.
pub fn fit_channels(v: &Value, spec: &str) -> Result<Vec<FitChannel>> {
    let Some(chs) = v.get("channels").and_then(|c| c.as_array()) else {
        // A fit of one named channel keeps its name on the way out (`synth` labels the
        // profile, `--channel` accepts it; audit, 2026-12-02).
        return match v["data"]["channel"].as_str().filter(|n| !n.is_empty()) {
            Some(name) => {
                let (params, exposure) = FurParams::from_json_value(v)
                    .map_err(|e| Error::Invalid(format!("{spec}: {e}")))?;
                Ok(vec![FitChannel {
                    name: name.to_string(),
                    params,
                    exposure,
                }])
            }
            None => Ok(Vec::new()),
        };
    };
    chs.iter()
        .enumerate()
        .map(|(i, ch)| {
            let name = ch["data"]["channel"]
                .as_str()
                .map_or_else(|| format!("{i}"), str::to_string);
            let (params, exposure) = FurParams::from_json_value(ch).map_err(|e| {
                Error::Invalid(format!("{spec}: channel '{name}' (channels[{i}]): {e}"))
            })?;
            Ok(FitChannel {
                name,
                params,
                exposure,
            })
        })
        .collect()
}

/// The channel `name` of a fit's channels ([`fit_channels`]; `spec` names the file), or an
/// error listing the channels there are; `--channel` of `synth` and `simulate`.
pub fn select_channel<'a>(
    channels: &'a [FitChannel],
    name: &str,
    spec: &str,
) -> Result<&'a FitChannel> {
    if channels.is_empty() {
        return Err(Error::Invalid(format!(
            "--channel {name}: {spec} is not a fit of named channels"
        )));
    }
    channels.iter().find(|c| c.name == name).ok_or_else(|| {
        let names: Vec<&str> = channels.iter().map(|c| c.name.as_str()).collect();
        Error::Invalid(format!(
            "--channel {name}: {spec} has channels {}",
            names.join(", ")
        ))
    })
}

fn json_number(v: &Value) -> Option<f64> {
    v.as_f64()
}

fn parse_exposure(v: &Value) -> Result<f64> {
    match json_number(v) {
        Some(k) if k.is_finite() && k > 0.0 => Ok(k),
        _ => Err(Error::Param {
            key: "exposure".into(),
            msg: format!("must be a finite number > 0, found {v}"),
        }),
    }
}

fn check_bound(id: ParamId, v: f64) -> Result<()> {
    let s = id.spec();
    if s.contains(v) {
        Ok(())
    } else {
        Err(Error::Param {
            key: s.name.into(),
            msg: format!(
                "value {} is outside its hard bound {}",
                Num(v),
                s.bound_with_unit()
            ),
        })
    }
}

/// A named preset: seed Table 4, file units, in [`ParamId::ALL`] order
/// (eta, kappa, alpha, beta_m, beta_n, sigma_c_a, sigma_m_s, sigma_m_a, g, l).
///
/// The paper labels the absorption/scattering rows "diameter^-1" but states that "all
/// length-related parameters are calculated assuming the azimuthal section of every fiber is
/// a unit circle"; we take the numbers as they stand, per unit radius, as MODEL.md says.
#[derive(Clone, Copy, Debug)]
pub struct Preset {
    /// The species of the Table 4 column, lower-case and hyphenated (`red-fox`): the name
    /// [`FurParams::preset`] looks up.
    pub name: &'static str,
    /// The ten values in file units, in [`ParamId::ALL`] order.
    pub values: [f64; N_PARAMS],
    /// NRMSE the paper reports for its own fit (Table 4, "ours"), as a fraction.
    pub paper_nrmse: f64,
    /// NRMSE the paper reports for Yan et al. 2015 (Table 4), as a fraction.
    pub paper_nrmse_yan2015: f64,
}

/// Seed Table 4, column by column.
// Rabbit's alpha is 3.14 degrees, not pi.
#[allow(clippy::approx_constant)]
pub const PRESETS: [Preset; 10] = [
    preset(
        "bobcat",
        [1.69, 0.88, 5.48, 11.64, 7.49, 0.64, 1.69, 0.17, 0.44, 0.47],
        0.068,
        0.072,
    ),
    preset(
        "cat",
        [1.36, 0.87, 3.65, 5.66, 1.34, 0.06, 2.47, 0.12, 0.60, 0.44],
        0.064,
        0.053,
    ),
    preset(
        "deer",
        [1.60, 0.91, 3.52, 7.00, 4.53, 1.39, 2.51, 0.09, 0.46, 0.45],
        0.071,
        0.079,
    ),
    preset(
        "dog",
        [1.58, 0.68, 2.94, 5.77, 18.94, 0.01, 2.44, 0.00, 0.26, 0.60],
        0.073,
        0.091,
    ),
    preset(
        "mouse",
        [1.35, 0.66, 0.55, 8.39, 2.80, 0.04, 1.34, 0.06, 0.36, 2.36],
        0.047,
        0.085,
    ),
    preset(
        "rabbit",
        [1.47, 0.79, 3.14, 11.91, 10.52, 0.24, 0.78, 0.10, 0.12, 1.03],
        0.060,
        0.084,
    ),
    preset(
        "raccoon",
        [1.19, 0.65, 1.81, 7.44, 6.88, 0.25, 2.30, 0.14, 0.08, 2.00],
        0.097,
        0.101,
    ),
    preset(
        "red-fox",
        [1.49, 0.86, 2.64, 9.45, 17.63, 0.39, 3.15, 0.21, 0.79, 0.68],
        0.062,
        0.063,
    ),
    preset(
        "springbok",
        [1.48, 0.82, 4.61, 8.02, 11.46, 0.32, 2.45, 0.31, 0.19, 0.46],
        0.081,
        0.070,
    ),
    preset(
        "human",
        [1.20, 0.36, 0.70, 2.05, 3.75, 0.41, 3.49, 0.00, 0.28, 1.79],
        0.161,
        0.193,
    ),
];

const fn preset(name: &'static str, values: [f64; N_PARAMS], ours: f64, yan: f64) -> Preset {
    Preset {
        name,
        values,
        paper_nrmse: ours,
        paper_nrmse_yan2015: yan,
    }
}

/// The presets' names (seed Table 4 order).
pub fn preset_names() -> Vec<&'static str> {
    PRESETS.iter().map(|p| p.name).collect()
}

/// Find a preset's record (for the paper's NRMSE) by name.
pub fn preset_record(name: &str) -> Option<&'static Preset> {
    let key = name.to_ascii_lowercase().replace(['_', ' '], "-");
    PRESETS.iter().find(|p| p.name == key)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Parameter files show the values as typed (3.75, not 3.7499999999999996 from the
    /// degree -> radian -> degree trip), and still read back to the same parameters.
    #[test]
    fn json_values_are_the_typed_decimals() {
        for p in PRESETS {
            let v = FurParams::preset(p.name).unwrap().to_json_value();
            for id in ParamId::ALL {
                assert_eq!(
                    v[id.spec().name].as_f64().unwrap(),
                    p.values[id.index()],
                    "{}",
                    p.name
                );
            }
            let (back, _) = FurParams::from_json_value(&v).unwrap();
            assert_eq!(back, FurParams::preset(p.name).unwrap());
        }
    }

    /// Parameter text is read correctly rounded (serde_json's `float_roundtrip`): the
    /// default parser was an ulp off at times, so a fit's exposure changed on the way
    /// into `synth`, and the largest double below 1 read as 1, outside kappa's `[0, 1)`.
    #[test]
    fn json_numbers_read_correctly_rounded() {
        let text = r#"{"eta":1.55,"kappa":0.9999999999999999,"alpha":2,"beta_m":5,"beta_n":10,
            "sigma_c_a":0.3,"sigma_m_s":3.2109876543210987,"sigma_m_a":0.2,"g":0.5,"l":1,
            "exposure":1.3218498822254305}"#;
        let v: Value = serde_json::from_str(text).unwrap();
        let (p, k) = FurParams::from_json_value(&v).unwrap();
        assert_eq!(p.kappa, 1.0 - f64::EPSILON / 2.0);
        // Rust's own parser rounds correctly.
        assert_eq!(p.sigma_m_s, "3.2109876543210987".parse::<f64>().unwrap());
        assert_eq!(k, 1.3218498822254305);
    }

    #[test]
    fn presets_load_and_are_in_bounds() {
        for p in PRESETS {
            let fp = FurParams::preset(p.name).unwrap();
            fp.validate().unwrap();
            // Degrees in, radians inside: alpha round trips to 1e-12 deg (float rounding).
            assert!((fp.alpha.to_degrees() - p.values[2]).abs() < 1e-12);
        }
        assert!(FurParams::preset("Red Fox").is_some());
        assert!(FurParams::preset("unicorn").is_none());
    }

    #[test]
    fn typed_file_units_give_back_a_bound_typed() {
        // beta_m = 60 deg comes back from radians as 59.99999999999999; `fit` printed
        // that, beside a fit file holding 60 (audit, 2026-11-28).
        let mut v = PRESETS[0].values;
        v[3] = 60.0;
        let p = FurParams::from_file_units(v).unwrap();
        assert_ne!(p.to_file_units()[3], 60.0);
        assert_eq!(p.typed_file_units()[3], 60.0);
        assert_eq!(SPECS[3].value_text(p.typed_file_units()[3]), "60.000");
    }

    #[test]
    fn value_text_is_short_and_never_prints_a_bound_it_is_not_on() {
        let spec = |name: &str| SPECS.iter().find(|s| s.name == name).unwrap();
        let kappa = spec("kappa");
        assert_eq!(kappa.value_text(0.86077), "0.86077");
        assert_eq!(kappa.value_text(0.123456789), "0.12346");
        assert_eq!(kappa.value_text(0.9999966), "0.999997");
        assert_eq!(kappa.value_text(0.0), "0");
        let sca = spec("sigma_c_a");
        assert_eq!(sca.value_text(1e308), "1.0000e308");
        assert_eq!(sca.value_text(2.5e-7), "2.5000e-7");
        assert_eq!(sca.value_text(17.63), "17.630");
        assert_eq!(spec("alpha").value_text(-20.0), "-20.000");
        assert_eq!(kappa.fixed_text(0.9999966, 2), "0.999997");
        assert_eq!(kappa.fixed_text(0.86077, 2), "0.86");
        // A closed bound may show (sigma_c_a >= 0), an open one may not (beta_n > 0).
        assert_eq!(sca.fixed_text(3.99e-6, 2), "0.00");
        assert_eq!(spec("beta_n").fixed_text(7.32e-4, 2), "7.320e-4");
    }

    #[test]
    fn bound_errors_name_key_and_bound() {
        let mut v = PRESETS[0].values;
        v[ParamId::Kappa.index()] = 1.0;
        let e = FurParams::from_file_units(v).unwrap_err().to_string();
        assert!(e.contains("kappa") && e.contains("[0, 1)"), "{e}");
        let mut v = PRESETS[0].values;
        v[ParamId::BetaN.index()] = 0.0;
        let e = FurParams::from_file_units(v).unwrap_err().to_string();
        assert!(e.contains("beta_n") && e.contains("(0, 90]"), "{e}");
        let mut v = PRESETS[0].values;
        v[ParamId::SigmaCA.index()] = f64::NAN;
        let e = FurParams::from_file_units(v).unwrap_err().to_string();
        assert!(e.contains("sigma_c_a") && e.contains("[0, inf)"), "{e}");
        // Values far from 1 in scientific notation ({} wrote -1e-300 as 300 zeros).
        let mut v = PRESETS[0].values;
        v[ParamId::SigmaCA.index()] = -1e-300;
        let e = FurParams::from_file_units(v).unwrap_err().to_string();
        assert!(
            e.contains("value -1e-300 is outside its hard bound [0, inf)"),
            "{e}"
        );
    }

    #[test]
    fn json_round_trip_and_errors() {
        let p = FurParams::preset("red-fox").unwrap();
        let v = p.to_json_value();
        let (q, k) = FurParams::from_json_value(&v).unwrap();
        assert_eq!(k, 1.0);
        for (a, b) in p.to_array().iter().zip(q.to_array()) {
            // deg -> rad -> deg -> rad: a few ulps at most.
            assert!((a - b).abs() <= 1e-15 * a.abs().max(1.0));
        }
        let mut bad = v.clone();
        bad.as_object_mut()
            .unwrap()
            .insert("bogus".into(), 1.0.into());
        let e = FurParams::from_json_value(&bad).unwrap_err().to_string();
        assert!(e.contains("bogus"), "{e}");
        let mut missing = v.clone();
        missing.as_object_mut().unwrap().remove("g");
        let e = FurParams::from_json_value(&missing)
            .unwrap_err()
            .to_string();
        assert!(e.contains("'g'") && e.contains("missing"), "{e}");
        let fit = serde_json::json!({"params": v, "exposure": 2.5});
        let (_, k) = FurParams::from_json_value(&fit).unwrap();
        assert_eq!(k, 2.5);
        // A fit file without its `params`: named as that, not as an unknown key.
        let gutted = serde_json::json!({"exposure": 2.5, "correlation": {}, "uncertainty": {}});
        let e = FurParams::from_json_value(&gutted).unwrap_err().to_string();
        assert!(e.contains("'params'") && e.contains("fit file"), "{e}");
    }
}
