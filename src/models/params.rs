//! A parameter set of any registered model, and the parameter/fit JSON of DATA.md made
//! generic: a `params` object keyed by the model's parameter names, and a `model` key
//! naming the model (absent: `yan2017`, the files this project wrote before the zoo).

use super::interface::FiberModel;
use super::registry::{by_name, default_model};
use crate::error::{Error, Num, Result};
use serde_json::{Map as JsonMap, Value};
use std::path::Path;

/// Parameters of one model, internal units (radians), in its [`FiberModel::specs`] order.
/// Built through [`ModelParams::from_file_units`] or [`ModelParams::new_checked`], so the
/// hard bounds are checked once, at the boundary.
#[derive(Clone)]
pub struct ModelParams {
    /// The model the parameters belong to.
    pub model: &'static dyn FiberModel,
    /// The values, internal units, in the model's [`FiberModel::specs`] order.
    pub values: Vec<f64>,
}

impl std::fmt::Debug for ModelParams {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}{:?}", self.model.name(), self.values)
    }
}

impl PartialEq for ModelParams {
    fn eq(&self, o: &Self) -> bool {
        self.model.name() == o.model.name() && self.values == o.values
    }
}

/// The error of parameter `key` of `model`, naming both.
fn param_error(model: &dyn FiberModel, key: &str, msg: String) -> Error {
    Error::Param {
        key: key.to_string(),
        msg: format!("{msg} (model {})", model.name()),
    }
}

impl From<crate::params::FurParams> for ModelParams {
    fn from(p: crate::params::FurParams) -> Self {
        ModelParams {
            model: &super::yan2017::Yan2017,
            values: p.to_array().to_vec(),
        }
    }
}

impl ModelParams {
    /// From file units (degrees), validated against the hard bounds and the model's own
    /// checks.
    pub fn from_file_units(model: &'static dyn FiberModel, file: &[f64]) -> Result<Self> {
        let specs = model.specs();
        if file.len() != specs.len() {
            return Err(Error::Invalid(format!(
                "model {} has {} parameters, {} given",
                model.name(),
                specs.len(),
                file.len()
            )));
        }
        for (s, &v) in specs.iter().zip(file) {
            check_bound(model, s, v)?;
        }
        let values = specs
            .iter()
            .zip(file)
            .map(|(s, &v)| s.to_internal(v))
            .collect();
        let p = ModelParams { model, values };
        model.check(&p.values)?;
        Ok(p)
    }

    /// Internal units, validated.
    pub fn new_checked(model: &'static dyn FiberModel, values: Vec<f64>) -> Result<Self> {
        let p = ModelParams { model, values };
        p.validate()?;
        Ok(p)
    }

    /// Check every value against its hard bound, then the model's own checks.
    pub fn validate(&self) -> Result<()> {
        let specs = self.model.specs();
        if self.values.len() != specs.len() {
            return Err(Error::Invalid(format!(
                "model {} has {} parameters, {} given",
                self.model.name(),
                specs.len(),
                self.values.len()
            )));
        }
        for (s, v) in specs.iter().zip(self.to_file_units()) {
            check_bound(self.model, s, v)?;
        }
        self.model.check(&self.values)
    }

    /// File-unit values (degrees for angles).
    pub fn to_file_units(&self) -> Vec<f64> {
        self.model
            .specs()
            .iter()
            .zip(&self.values)
            .map(|(s, &v)| s.to_file(v))
            .collect()
    }

    /// [`Self::to_file_units`] as they were typed: each value the shortest 12-digit form
    /// when that reads back to the same internal value (3.75 deg, not 3.7499999999999996).
    pub fn typed_file_units(&self) -> Vec<f64> {
        let specs = self.model.specs();
        let mut out = self.to_file_units();
        for ((s, v), &internal) in specs.iter().zip(out.iter_mut()).zip(&self.values) {
            let short: f64 = format!("{v:.12e}").parse().unwrap_or(*v);
            if s.to_internal(short) == internal {
                *v = short;
            }
        }
        out
    }

    /// The fur model's typed parameters, when these are of `yan2017` (the renderer and
    /// the virtual goniometer are the fur model's own).
    pub fn fur(&self) -> Option<crate::params::FurParams> {
        (self.model.name() == "yan2017").then(|| {
            let mut a = [0.0; crate::params::N_PARAMS];
            a.copy_from_slice(&self.values);
            crate::params::FurParams::from_array(a)
        })
    }

    /// These of the fur model, with the error a command of the fur model alone gives for
    /// another model's parameters.
    pub fn require_fur(&self, what: &str) -> Result<crate::params::FurParams> {
        self.fur().ok_or_else(|| {
            Error::Invalid(format!(
                "{what} supports the yan2017 fur model only; these parameters are of {}",
                self.model.name()
            ))
        })
    }

    /// The value of the parameter named `name`, internal units.
    pub fn get(&self, name: &str) -> Option<f64> {
        let i = self.model.specs().iter().position(|s| s.name == name)?;
        Some(self.values[i])
    }

    /// The `params` JSON object (file units), keys in the model's order.
    pub fn to_json_value(&self) -> Value {
        let mut m = JsonMap::new();
        for (s, v) in self.model.specs().iter().zip(self.typed_file_units()) {
            m.insert(s.name.into(), Value::from(v));
        }
        Value::Object(m)
    }

    /// A preset of `model` by name (case-insensitive; `_` and spaces read as `-`).
    pub fn preset(model: &'static dyn FiberModel, name: &str) -> Option<ModelParams> {
        let key = name.to_ascii_lowercase().replace(['_', ' '], "-");
        let key = if key == "redfox" {
            "red-fox".to_string()
        } else {
            key
        };
        model.presets().iter().find(|p| p.name == key).map(|p| {
            ModelParams::from_file_units(model, p.values).expect("presets are within bounds")
        })
    }

    /// Parse a parameter object, or a fit file (its `params` and `exposure`), of the model
    /// the JSON names (`model` key; `yan2017` when absent). With `want`, a file of another
    /// model is an error naming both. Returns the parameters and the exposure (default 1).
    pub fn from_json_value(
        v: &Value,
        want: Option<&'static dyn FiberModel>,
    ) -> Result<(ModelParams, f64)> {
        let obj = v.as_object().ok_or_else(|| Error::Param {
            key: "<file>".into(),
            msg: "a parameter file must be a JSON object".into(),
        })?;
        let model = match obj.get("model") {
            None => default_model(),
            Some(Value::String(name)) => by_name(name)?,
            Some(other) => {
                return Err(Error::Param {
                    key: "model".into(),
                    msg: format!("expected a model name, found {other}"),
                })
            }
        };
        if let Some(w) = want {
            if w.name() != model.name() {
                return Err(Error::Invalid(format!(
                    "the parameters are of model {}, not of the model asked for ({}): \
                     refit with --model {}, or drop --model to use the file's own",
                    model.name(),
                    w.name(),
                    w.name()
                )));
            }
        }
        let exposure = match obj.get("exposure") {
            Some(e) => parse_exposure(e)?,
            None => 1.0,
        };
        if let Some(inner) = obj.get("params") {
            let p = parse_params_object(model, inner)?;
            return Ok((p, exposure));
        }
        // A fit file that lost its `params` would otherwise be read as a parameter file
        // and blamed on its first other key.
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
        let mut inner = obj.clone();
        inner.remove("exposure");
        inner.remove("model");
        let p = parse_params_object(model, &Value::Object(inner))?;
        Ok((p, exposure))
    }

    /// Load parameters from a preset name of `want` (default `yan2017`), a parameter JSON
    /// file or a fit JSON file. Returns the parameters, the exposure and the file's JSON
    /// (`None` for a preset).
    pub fn load(
        spec: &str,
        want: Option<&'static dyn FiberModel>,
    ) -> Result<(ModelParams, f64, Option<Value>)> {
        let path = Path::new(spec);
        if let Some(p) = ModelParams::preset(want.unwrap_or(default_model()), spec) {
            if !path.exists() {
                return Ok((p, 1.0, None));
            }
        }
        let text = std::fs::read_to_string(path).map_err(|e| {
            let looks_like_path = spec.contains(['/', '\\']) || path.extension().is_some();
            if e.kind() == std::io::ErrorKind::NotFound && looks_like_path {
                Error::file(path, "no such parameter or fit file")
            } else if e.kind() == std::io::ErrorKind::NotFound {
                let m = want.unwrap_or(default_model());
                let presets: Vec<&str> = m.presets().iter().map(|p| p.name).collect();
                Error::Invalid(format!(
                    "'{spec}' is neither a preset of {} nor an existing parameter/fit file (presets: {})",
                    m.name(),
                    presets.join(", ")
                ))
            } else {
                Error::io(path, e)
            }
        })?;
        let v = crate::io::parse_json(&text, path)?;
        let (p, k) = ModelParams::from_json_value(&v, want).map_err(|e| match e {
            Error::Param { key, msg } => Error::Param {
                key,
                msg: format!("{msg} (in {})", path.display()),
            },
            Error::Invalid(msg) => Error::Invalid(format!("{}: {msg}", path.display())),
            other => other,
        })?;
        Ok((p, k, Some(v)))
    }
}

/// One channel of a multi-channel fit file (its `channels` array, `fit::job`).
#[derive(Clone, Debug, PartialEq)]
pub struct Channel {
    /// The channel's name (`data.channel`).
    pub name: String,
    /// The channel's fitted parameters.
    pub params: ModelParams,
    /// The channel's exposure `k`.
    pub exposure: f64,
}

/// The channels of a fit file's JSON (`v` as [`ModelParams::load`] returns it): each of a
/// multi-channel fit's `channels`, the one channel of a fit of one named channel (its top
/// level, `data.channel`), and none for a parameter file or a fit of unnamed data. `spec`
/// names the file in errors.
pub fn fit_channels(v: &Value, spec: &str) -> Result<Vec<Channel>> {
    let Some(chs) = v.get("channels").and_then(|c| c.as_array()) else {
        // A fit of one named channel keeps its name on the way out (`synth` labels the
        // profile, `--channel` accepts it).
        return match v["data"]["channel"].as_str().filter(|n| !n.is_empty()) {
            Some(name) => {
                let (params, exposure) = ModelParams::from_json_value(v, None)
                    .map_err(|e| Error::Invalid(format!("{spec}: {e}")))?;
                Ok(vec![Channel {
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
            let (params, exposure) = ModelParams::from_json_value(ch, None).map_err(|e| {
                Error::Invalid(format!("{spec}: channel '{name}' (channels[{i}]): {e}"))
            })?;
            Ok(Channel {
                name,
                params,
                exposure,
            })
        })
        .collect()
}

/// The channel `name` of a fit's channels ([`fit_channels`]; `spec` names the file), or an
/// error listing the channels there are.
pub fn select_channel<'a>(channels: &'a [Channel], name: &str, spec: &str) -> Result<&'a Channel> {
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

/// The `params` object of `model`: exactly its keys, each a number within its bound.
fn parse_params_object(model: &'static dyn FiberModel, v: &Value) -> Result<ModelParams> {
    let obj = v.as_object().ok_or_else(|| Error::Param {
        key: "params".into(),
        msg: "must be a JSON object".into(),
    })?;
    let specs = model.specs();
    let mut vals = vec![f64::NAN; specs.len()];
    let mut seen = vec![false; specs.len()];
    for (key, val) in obj {
        let i = specs.iter().position(|s| s.name == key).ok_or_else(|| {
            let names: Vec<&str> = specs.iter().map(|s| s.name).collect();
            param_error(
                model,
                key,
                format!(
                    "unknown key (expected one of: {}, and optionally exposure)",
                    names.join(", ")
                ),
            )
        })?;
        vals[i] = val
            .as_f64()
            .ok_or_else(|| param_error(model, key, format!("expected a number, found {val}")))?;
        seen[i] = true;
    }
    if let Some(i) = seen.iter().position(|s| !s) {
        return Err(param_error(model, specs[i].name, "missing key".into()));
    }
    ModelParams::from_file_units(model, &vals)
}

fn parse_exposure(v: &Value) -> Result<f64> {
    match v.as_f64() {
        Some(k) if k.is_finite() && k > 0.0 => Ok(k),
        _ => Err(Error::Param {
            key: "exposure".into(),
            msg: format!("must be a finite number > 0, found {v}"),
        }),
    }
}

fn check_bound(model: &dyn FiberModel, s: &crate::params::ParamSpec, v: f64) -> Result<()> {
    if s.contains(v) {
        Ok(())
    } else {
        Err(param_error(
            model,
            s.name,
            format!(
                "value {} is outside its hard bound {}",
                Num(v),
                s.bound_with_unit()
            ),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::FurParams;

    #[test]
    fn fur_files_read_the_same_as_before() {
        let fox = FurParams::preset("red-fox").unwrap();
        let v = serde_json::json!({"params": fox.to_json_value(), "exposure": 2.5});
        let (p, k) = ModelParams::from_json_value(&v, None).unwrap();
        assert_eq!(p.model.name(), "yan2017");
        assert_eq!(p.values, fox.to_array());
        assert_eq!(k, 2.5);
        assert_eq!(p.to_json_value(), fox.to_json_value());
    }

    #[test]
    fn errors_name_model_and_parameter() {
        let fox = FurParams::preset("red-fox").unwrap();
        let mut bad = fox.to_json_value();
        bad["kappa"] = 1.0.into();
        let e = ModelParams::from_json_value(&bad, None)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("kappa") && e.contains("[0, 1)") && e.contains("yan2017"),
            "{e}"
        );
        let mut unknown = fox.to_json_value();
        unknown["sigma_a"] = 1.0.into();
        let e = ModelParams::from_json_value(&unknown, None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("sigma_a") && e.contains("yan2017"), "{e}");
        let wrong = serde_json::json!({"model": "nope", "params": {}});
        let e = ModelParams::from_json_value(&wrong, None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("nope"), "{e}");
    }
}
