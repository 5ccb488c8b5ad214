//! `furfit.fit` and `FitResult`: the fitter as `furfit fit` runs one species
//! (`src/cli/fit.rs`: the options, the data notes, `fit::job::fit_species`), its result
//! kept in memory until `to_json` writes the fit file the CLI would write.

use crate::convert::{far_options, model_of};
use crate::profile::{load_paths, Profile};
use crate::{py_err, run_interruptible, warn};
use furfit::cancel::Cancel;
use furfit::fit::job::{fit_species, Job, SpeciesFit};
use furfit::fit::FitOptions;
use furfit::models::Param;
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyFloat, PyInt};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Fit a model to a profile, as ``furfit fit PATH --seed SEED`` does.
///
/// ``profile_or_path``: a ``Profile`` (``load_profile``), or a path (file or species
/// folder) or list of paths, loaded with the default loader options. ``model``: the model
/// fitted (``yan2017``, ``marschner2003``, ``chiang2016``). ``seed``: the seed of the
/// subsample and the Halton starts (``None``: 0, the CLI's default). ``fix``: parameters
/// held, ``{name: value}`` in file units (``--fix name=value``). ``weighted``: weight
/// residuals by sigma/value. ``tol``: far-field tolerance (``None``: fixed segmentation).
///
/// Returns a ``FitResult``. Runs without the GIL; Ctrl-C stops the fit within a model
/// evaluation and raises KeyboardInterrupt. Raises ValueError for data or options the
/// fitter refuses (no valid sample, an unknown or out-of-bound ``fix``), OSError for
/// unreadable files. The data's notes (samples left out) are issued as warnings.
#[pyfunction]
#[pyo3(signature = (profile_or_path, *, model="yan2017", seed=None, fix=None, weighted=false, tol=Some(1e-4)))]
pub(crate) fn fit(
    py: Python<'_>,
    profile_or_path: &Bound<'_, PyAny>,
    model: &str,
    seed: Option<u64>,
    fix: Option<&Bound<'_, PyDict>>,
    weighted: bool,
    tol: Option<f64>,
) -> PyResult<FitResult> {
    let bound: Bound<'_, Profile> = match profile_or_path.cast::<Profile>() {
        Ok(p) => p.clone(),
        Err(_) => {
            let paths = crate::profile::paths_of_any(profile_or_path)?;
            let p = load_paths(py, paths, Default::default())?;
            for n in &p.inputs.notes {
                warn(py, &format!("note: {n}"))?;
            }
            Bound::new(py, p)?
        }
    };
    let prof = bound.get();
    let model = model_of(Some(model))?;
    let mut opts = FitOptions {
        seed: seed.unwrap_or(0),
        weighted,
        ..FitOptions::for_model(model)
    };
    opts.far = far_options(tol)?;
    if let Some(fix) = fix {
        for (k, v) in fix.iter() {
            let key: String = k
                .extract()
                .map_err(|_| PyTypeError::new_err("fix: keys must be parameter names (str)"))?;
            if !(v.is_instance_of::<PyFloat>()
                || v.is_instance_of::<PyInt>()
                || v.hasattr("__float__")?)
            {
                return Err(PyTypeError::new_err(format!(
                    "fix['{key}']: expected a number"
                )));
            }
            let x: f64 = v.call_method0("__float__")?.extract()?;
            opts.fix(key.trim(), x).map_err(py_err)?;
        }
    }
    let species = prof.species();
    // What `Batch::prepare` checks of a species before its fit, and the notes it prints.
    let job = Job {
        species: species.clone(),
        inputs: prof.paths.clone(),
        out: PathBuf::new(),
        force: false,
    };
    let (notes, unfit) =
        furfit::fit::batch::data_notes(&job, &prof.inputs, &opts).map_err(py_err)?;
    if let Some(e) = unfit {
        return Err(py_err(e));
    }
    for n in notes {
        warn(py, &format!("{species}: note: {n}"))?;
    }
    let cancel = Cancel::new();
    opts.cancel = cancel.clone();
    let (inputs, load) = (&prof.inputs, &prof.load);
    let res = run_interruptible(py, &cancel, || {
        fit_species(&species, inputs, &opts, load, None)
    })?
    .map_err(py_err)?;
    let mut res = res;
    // The token is this call's; a kept result carries none.
    res.opts.cancel = Cancel::default();
    let fit = Arc::new(res);
    Ok(FitResult {
        channel: fit.primary,
        fit,
    })
}

/// The result of ``furfit.fit``: one channel's fit (the primary one: ``y`` if the data
/// have it, else the first), every channel under ``channels``.
///
/// ``params`` (file units, as the fit file's ``params``), ``exposure``, ``nrmse`` (a
/// fraction, MODEL.md's), ``stderr`` (linearised standard errors, None where undefined),
/// ``evaluations``, ``wall_time_s``; ``to_json(path)`` writes the fit file ``furfit fit``
/// writes, ``to_dict()`` gives its contents.
#[pyclass(frozen, module = "furfit")]
pub struct FitResult {
    fit: Arc<SpeciesFit>,
    channel: usize,
}

impl FitResult {
    fn summary(&self) -> &furfit::fit::FitOutcome {
        &self.fit.channels[self.channel].0.outcome
    }

    /// The fit file's contents as `furfit fit` would write them to `fit.json` in the
    /// current folder (whose path the data files are recorded relative to).
    pub(crate) fn json(&self) -> Value {
        let top = self.fit.to_json(Path::new("fit.json"));
        if self.channel == self.fit.primary {
            return top;
        }
        // Another channel: its own complete fit object (kept under `channels`).
        top["channels"][self.channel].clone()
    }
}

#[pymethods]
impl FitResult {
    /// The fitted parameters, ``{name: value}`` in file units (degrees for angles).
    #[getter]
    fn params<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let p = &self.summary().params;
        let d = PyDict::new(py);
        for (s, v) in p.model.specs().iter().zip(p.typed_file_units()) {
            d.set_item(s.name, v)?;
        }
        Ok(d)
    }

    /// The model fitted.
    #[getter]
    fn model(&self) -> &'static str {
        self.summary().params.model.name()
    }

    /// The exposure k of the solve.
    #[getter]
    fn exposure(&self) -> f64 {
        self.summary().exposure
    }

    /// NRMSE as a fraction (MODEL.md: log residuals over the data's log range).
    #[getter]
    fn nrmse(&self) -> f64 {
        self.summary().nrmse
    }

    /// Linearised standard errors, ``{name: value or None}`` in file units.
    #[getter]
    fn stderr<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let o = self.summary();
        let d = PyDict::new(py);
        for id in Param::all(o.params.model) {
            d.set_item(
                id.name(),
                o.uncertainty.se[id.index()].filter(|v| v.is_finite()),
            )?;
        }
        Ok(d)
    }

    /// Model evaluations of the solve.
    #[getter]
    fn evaluations(&self) -> u64 {
        self.summary().evaluations
    }

    /// LM iterations over all runs.
    #[getter]
    fn iterations(&self) -> u64 {
        self.summary().iterations
    }

    /// Wall-clock seconds of the fit.
    #[getter]
    fn wall_time_s(&self) -> f64 {
        self.summary().wall_time_s
    }

    /// How the final solve ended.
    #[getter]
    fn termination(&self) -> String {
        self.summary().termination.clone()
    }

    /// Samples fitted (valid, above the floor).
    #[getter]
    fn n_used(&self) -> usize {
        self.summary().n_used
    }

    /// The species name (the fit file's ``species``).
    #[getter]
    fn species(&self) -> String {
        self.fit.species.clone()
    }

    /// This result's channel name (empty for one unnamed channel).
    #[getter(channel)]
    fn channel_name(&self) -> String {
        self.fit.channels[self.channel].0.channel.clone()
    }

    /// Every channel's result by name (one entry, this result, for one channel).
    #[getter]
    fn channels<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for (c, (s, _)) in self.fit.channels.iter().enumerate() {
            let r = FitResult {
                fit: self.fit.clone(),
                channel: c,
            };
            d.set_item(s.channel.clone(), Bound::new(py, r)?)?;
        }
        Ok(d)
    }

    /// Write the fit file ``furfit fit --out PATH`` writes (every channel), atomically.
    /// An existing file is replaced only if it is a fit of the same data, or with
    /// ``force``; anything else there is refused (OSError), as by the CLI.
    #[pyo3(signature = (path, *, force=false))]
    fn to_json(&self, py: Python<'_>, path: &Bound<'_, PyAny>, force: bool) -> PyResult<()> {
        let p = PathBuf::from(crate::convert::path_text(path, "path")?);
        let fit = self.fit.clone();
        py.detach(move || fit.save(&p, force).map(|_| ()))
            .map_err(py_err)
    }

    /// The fit file's contents (this channel's object for a non-primary channel) as a
    /// dict, data files recorded relative to the current folder.
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let text = serde_json::to_string(&self.json())
            .map_err(|e| pyo3::exceptions::PyValueError::new_err(format!("JSON: {e}")))?;
        py.import("json")?.call_method1("loads", (text,))
    }

    fn __repr__(&self) -> String {
        let o = self.summary();
        let ch = self.channel_name();
        format!(
            "<furfit.FitResult {}{} ({}): NRMSE {:.3}%, exposure {:.4e}, {} evaluations, {:.2} s>",
            self.fit.species,
            if ch.is_empty() {
                String::new()
            } else {
                format!(" [{ch}]")
            },
            o.params.model.name(),
            100.0 * o.nrmse,
            o.exposure,
            o.evaluations,
            o.wall_time_s
        )
    }
}
