//! Python values to the library's inputs: parameters (a preset name, a file, a dict or a
//! fit result), angle arrays, far-field and lobe options; and the model registry's
//! presets and bounds as dicts.

use crate::{py_err, py_err_any, warn};
use furfit::model::far::FarOptions;
use furfit::models::{FiberModel, ModelParams};
use numpy::{AllowTypeChange, PyArrayLikeDyn, PyUntypedArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};
use serde_json::Value;

/// Parameters as the caller gave them.
pub(crate) enum ParamsIn {
    /// A preset name or a parameter / fit JSON path (as `--params` takes it).
    Spec(String),
    /// A parameter or fit object (a dict, or a fit result's fit file), and what to call
    /// it in messages.
    Json(Value, String),
}

impl ParamsIn {
    /// `params` of `synth` and `render`: a `str` or path-like (preset or file), a dict
    /// (parameter object or fit file contents) or a `FitResult`.
    pub(crate) fn from_py(obj: &Bound<'_, PyAny>) -> PyResult<ParamsIn> {
        if let Ok(fit) = obj.cast::<crate::fit::FitResult>() {
            return Ok(ParamsIn::Json(fit.borrow().json(), "the fit result".into()));
        }
        if obj.is_instance_of::<PyDict>() {
            return Ok(ParamsIn::Json(
                to_json(obj, "params")?,
                "the params dict".into(),
            ));
        }
        Ok(ParamsIn::Spec(path_text(obj, "params")?))
    }

    /// How messages name the parameters (the CLI's `--params` value).
    pub(crate) fn label(&self) -> &str {
        match self {
            ParamsIn::Spec(s) => s,
            ParamsIn::Json(_, l) => l,
        }
    }

    /// [`ModelParams::load`] (a spec) or [`ModelParams::from_json_value`] (an object) of
    /// the model `want` (default: the file's own): the parameters, the exposure and the
    /// JSON (none for a preset). A file read in place of the preset of its name is said
    /// as the CLI says it.
    pub(crate) fn load(
        &self,
        py: Python<'_>,
        want: Option<&'static dyn FiberModel>,
    ) -> PyResult<(ModelParams, f64, Option<Value>)> {
        match self {
            ParamsIn::Spec(spec) => {
                if let Some(n) = furfit::params::preset_shadow_note(spec) {
                    warn(py, &n)?;
                }
                ModelParams::load(spec, want).map_err(py_err)
            }
            ParamsIn::Json(v, _) => {
                let (p, k) = ModelParams::from_json_value(v, want).map_err(py_err)?;
                Ok((p, k, Some(v.clone())))
            }
        }
    }

    /// [`furfit::FurParams::load_json`] (the fur model's renderer): parameters and JSON.
    pub(crate) fn load_fur(&self, py: Python<'_>) -> PyResult<(furfit::FurParams, Option<Value>)> {
        match self {
            ParamsIn::Spec(spec) => {
                if let Some(n) = furfit::params::preset_shadow_note(spec) {
                    warn(py, &n)?;
                }
                let (p, _, v) = furfit::FurParams::load_json(spec).map_err(py_err)?;
                Ok((p, v))
            }
            ParamsIn::Json(v, _) => {
                let (p, _) = furfit::FurParams::from_json_value(v).map_err(py_err)?;
                Ok((p, Some(v.clone())))
            }
        }
    }
}

/// A `str` or path-like (`os.fspath`) as text; `what` names the argument in the error.
pub(crate) fn path_text(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<String> {
    if let Ok(s) = obj.cast::<PyString>() {
        return Ok(s.to_cow()?.into_owned());
    }
    let os = obj.py().import("os")?;
    match os.call_method1("fspath", (obj,)) {
        Ok(p) => match p.cast::<PyString>() {
            Ok(s) => Ok(s.to_cow()?.into_owned()),
            Err(_) => Err(PyTypeError::new_err(format!(
                "{what}: a bytes path is not supported; give a str"
            ))),
        },
        Err(_) => Err(PyTypeError::new_err(format!(
            "{what}: expected a preset name, a path, a dict or a FitResult, got {}",
            obj.get_type().name()?
        ))),
    }
}

/// A Python object (dict, list, str, number, bool, None; numpy scalars through
/// `float()`/`int()`) as JSON. A non-finite float is refused: no parameter file holds one.
pub(crate) fn to_json(obj: &Bound<'_, PyAny>, at: &str) -> PyResult<Value> {
    if obj.is_none() {
        return Ok(Value::Null);
    }
    if let Ok(b) = obj.cast::<PyBool>() {
        return Ok(Value::Bool(b.is_true()));
    }
    if let Ok(s) = obj.cast::<PyString>() {
        return Ok(Value::String(s.to_cow()?.into_owned()));
    }
    if let Ok(d) = obj.cast::<PyDict>() {
        let mut m = serde_json::Map::new();
        for (k, v) in d.iter() {
            let key = k
                .cast::<PyString>()
                .map_err(|_| PyTypeError::new_err(format!("{at}: keys must be str")))?
                .to_cow()?
                .into_owned();
            let val = to_json(&v, &format!("{at}['{key}']"))?;
            m.insert(key, val);
        }
        return Ok(Value::Object(m));
    }
    if obj.is_instance_of::<PyList>() || obj.is_instance_of::<PyTuple>() {
        let items: Vec<Value> = obj
            .try_iter()?
            .enumerate()
            .map(|(i, v)| to_json(&v?, &format!("{at}[{i}]")))
            .collect::<PyResult<_>>()?;
        return Ok(Value::Array(items));
    }
    if obj.is_instance_of::<PyInt>() {
        if let Ok(i) = obj.extract::<i64>() {
            return Ok(Value::from(i));
        }
    }
    if obj.is_instance_of::<PyFloat>() || obj.hasattr("__float__")? {
        let x: f64 = obj.call_method0("__float__")?.extract()?;
        return serde_json::Number::from_f64(x)
            .map(Value::Number)
            .ok_or_else(|| PyValueError::new_err(format!("{at}: {x} is not a finite number")));
    }
    Err(PyTypeError::new_err(format!(
        "{at}: {} cannot be given in a parameter object",
        obj.get_type().name()?
    )))
}

/// Angles (degrees) of the argument `what`: a 1-D sequence or array of numbers (any
/// float or int dtype, any strides; converted to float64), or a grid text as the CLI
/// takes it (`"-60:60:2"`, `"0,15,30"`; expanded with its rules, kept in order and with
/// repeats). Emptiness and non-finite values are left to [`furfit::grid::check_angles`].
pub(crate) fn angles(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<f64>> {
    if let Ok(s) = obj.cast::<PyString>() {
        return furfit::grid::parse_grid(what, &s.to_cow()?).map_err(py_err);
    }
    let arr: PyArrayLikeDyn<'_, f64, AllowTypeChange> = obj.extract().map_err(|e| {
        PyValueError::new_err(format!(
            "{what}: expected a 1-D sequence of angles in degrees ({e})"
        ))
    })?;
    if arr.ndim() != 1 {
        return Err(PyValueError::new_err(format!(
            "{what}: expected a 1-D sequence of angles in degrees, got an array of shape {:?}",
            arr.shape()
        )));
    }
    // An iterator over the view: any strides, one pass.
    Ok(arr.as_array().iter().copied().collect())
}

/// The far-field options of `tol` (`None`: the fixed segmentation), checked as `--tol`
/// is (the CLI's parser, so both refuse alike).
pub(crate) fn far_options(tol: Option<f64>) -> PyResult<FarOptions> {
    let far = furfit::cli::FarArgs {
        // `{}` of an f64 is its shortest exact decimal: parsed back to the same value.
        tol: Some(tol.map_or("none".to_string(), |t| format!("{t}"))),
        ..Default::default()
    };
    far.options().map_err(py_err_any)
}

/// A lobe list: `None` (all), a comma list `"R,TT"` or a sequence of names.
pub(crate) fn lobes_text(obj: Option<&Bound<'_, PyAny>>) -> PyResult<String> {
    let Some(obj) = obj else {
        return Ok("all".into());
    };
    if let Ok(s) = obj.cast::<PyString>() {
        return Ok(s.to_cow()?.into_owned());
    }
    let names: Vec<String> = obj
        .extract()
        .map_err(|_| PyTypeError::new_err("lobes: expected a str or a sequence of lobe names"))?;
    Ok(names.join(","))
}

/// A registered model by name (`None`: the default, `yan2017`).
pub(crate) fn model_of(name: Option<&str>) -> PyResult<&'static dyn FiberModel> {
    match name {
        Some(n) => furfit::models::by_name(n).map_err(py_err),
        None => Ok(furfit::models::default_model()),
    }
}

/// The named parameter sets of `model` (default `yan2017`): `{name: {param: value}}` in
/// file units (degrees for angles), as parameter files write them.
#[pyfunction]
#[pyo3(signature = (model=None))]
pub(crate) fn presets<'py>(py: Python<'py>, model: Option<&str>) -> PyResult<Bound<'py, PyDict>> {
    let m = model_of(model)?;
    let out = PyDict::new(py);
    for p in m.presets() {
        let mp = ModelParams::preset(m, p.name).expect("a registered preset");
        let d = PyDict::new(py);
        for (s, v) in m.specs().iter().zip(mp.typed_file_units()) {
            d.set_item(s.name, v)?;
        }
        out.set_item(p.name, d)?;
    }
    Ok(out)
}

/// The hard bounds of `model`'s parameters (default `yan2017`): `{param: (lower, upper)}`
/// in file units. Whether each end is included is the library's `ParamSpec`; the fitter
/// and `synth` refuse values outside with the bound in the message.
#[pyfunction]
#[pyo3(signature = (model=None))]
pub(crate) fn bounds<'py>(py: Python<'py>, model: Option<&str>) -> PyResult<Bound<'py, PyDict>> {
    let m = model_of(model)?;
    let out = PyDict::new(py);
    for s in m.specs() {
        out.set_item(s.name, (s.lower, s.upper))?;
    }
    Ok(out)
}

/// The registered models' names, default first.
#[pyfunction]
pub(crate) fn models() -> Vec<&'static str> {
    furfit::models::names()
}
