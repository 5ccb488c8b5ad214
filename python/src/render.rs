//! `furfit.render`: the path-traced preview of `furfit render` (the built-in test lock,
//! the CLI's defaults and checks: its settings come from the CLI's own parser), as the
//! linear beauty image instead of PNG/EXR files.

use crate::convert::{lobes_text, ParamsIn};
use crate::{py_err, py_err_any, run_interruptible, warn};
use clap::Parser;
use furfit::cancel::Cancel;
use furfit::cli::{Cli, Command};
use furfit::render::bsdf::Tint;
use numpy::ndarray::Array3;
use numpy::{IntoPyArray, PyArray3};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

/// Render fur with these parameters on the built-in test lock, as ``furfit render``.
///
/// ``params``: a preset name, a parameter or fit JSON path, a dict or a ``FitResult``
/// (the fur model, ``yan2017``). ``size``: ``(width, height)``; ``spp``: samples per
/// pixel; ``mode``: ``"near"``, ``"far"`` or ``"multiscale"``; ``seed``: the path
/// tracer's seed (same seed, same image); ``lobes``: e.g. ``"R,TT"`` (default all);
/// ``tint``: ``"melanin"``, ``"grey"`` or ``(r, g, b)`` absorption ratios (default: a fit
/// with r, g, b channels gives each colour its own absorption, else melanin). Every other
/// setting is the CLI's default (camera, key light, environment, 1500 fibers).
///
/// Returns the linear radiance (the EXR's values, before the PNG's tone map), float64 of
/// shape ``(height, width, 3)``, top row first. Runs without the GIL; Ctrl-C stops it
/// after the image rows in progress and raises KeyboardInterrupt.
#[pyfunction]
#[pyo3(signature = (params, *, size=(256, 256), spp=16, mode="multiscale", seed=0, lobes=None, tint=None))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn render<'py>(
    py: Python<'py>,
    params: &Bound<'py, PyAny>,
    size: (usize, usize),
    spp: u64,
    mode: &str,
    seed: u64,
    lobes: Option<&Bound<'py, PyAny>>,
    tint: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyArray3<f64>>> {
    let input = ParamsIn::from_py(params)?;
    let spec = input.label().to_string();
    let (p, json) = input.load_fur(py)?;
    let tint_text = match tint {
        None => None,
        Some(t) => Some(match t.extract::<String>() {
            Ok(s) => s,
            Err(_) => {
                let v: Vec<f64> = t.extract().map_err(|_| {
                    PyValueError::new_err("tint: expected melanin, grey or three ratios (r, g, b)")
                })?;
                v.iter()
                    .map(|x| format!("{x}"))
                    .collect::<Vec<_>>()
                    .join(",")
            }
        }),
    };
    // The CLI's parser and checks, so every default and limit is `furfit render`'s; the
    // output path is never written (only its extension is checked).
    let mut argv: Vec<String> = [
        "furfit",
        "render",
        "--params",
        "python",
        "--out",
        "python.png",
        "--no-aovs",
    ]
    .map(String::from)
    .to_vec();
    for (flag, v) in [
        ("--size", format!("{}x{}", size.0, size.1)),
        ("--spp", spp.to_string()),
        ("--mode", mode.to_string()),
        ("--seed", seed.to_string()),
        ("--lobes", lobes_text(lobes)?),
    ] {
        argv.push(flag.into());
        argv.push(v);
    }
    if let Some(t) = &tint_text {
        argv.push("--tint".into());
        argv.push(t.clone());
    }
    let args = match Cli::try_parse_from(&argv) {
        Ok(Cli {
            command: Command::Render(a),
        }) => a,
        Ok(_) => unreachable!("the render subcommand was given"),
        // clap's message without its `error: ` prefix and usage lines.
        Err(e) => {
            let text = e.to_string();
            let first = text
                .lines()
                .next()
                .unwrap_or("")
                .trim_start_matches("error: ");
            return Err(PyValueError::new_err(first.to_string()));
        }
    };
    let mut s = furfit::cli::render::settings_from(&args).map_err(py_err_any)?;
    // A fit's own r, g, b absorption unless a tint is given (as the CLI colours a fit).
    if tint_text.is_none() {
        if let Some(v) = &json {
            let fitted = furfit::params::fit_channels(v, &spec).map_err(py_err)?;
            if let Some(t) = Tint::from_fit_channels(&fitted) {
                s.tint = t;
            }
        }
    }
    for n in furfit::model::FurModel::model_notes(&p) {
        warn(py, &format!("note: {n}"))?;
    }
    let cancel = Cancel::new();
    s.cancel = cancel.clone();
    let out = run_interruptible(py, &cancel, || furfit::render::render(&p, &s))?.map_err(py_err)?;
    let img = out.beauty;
    let flat: Vec<f64> = img.data.iter().flat_map(|px| px.iter().copied()).collect();
    let arr = Array3::from_shape_vec((img.height, img.width, 3), flat)
        .map_err(|e| PyValueError::new_err(format!("internal shape mismatch: {e}")))?;
    Ok(arr.into_pyarray(py))
}
