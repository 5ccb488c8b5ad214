//! `furfit.load_profile` and `Profile`: the library's loaders (every format `furfit
//! inspect` and `furfit fit` read, folders merged) with the loader options of the CLI,
//! the samples as numpy arrays.

use crate::convert::path_text;
use crate::{py_err, py_err_any, run_interruptible, warn};
use furfit::cancel::Cancel;
use furfit::fit::job::LoadedInputs;
use furfit::profile::LoadOptions;
use numpy::{IntoPyArray, PyArray1};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyString};
use std::path::PathBuf;

/// A loaded goniometric profile: per-sample arrays and the files' metadata.
///
/// ``theta_i``, ``theta_r``, ``phi`` (degrees; phi wrapped to (-180, 180]), ``value``
/// (float64 arrays, one entry per sample, invalid samples included: ``value <= 0`` or
/// NaN); ``sigma`` (NaN where a sample has none; ``None`` when no sample has one);
/// ``channel`` (int64 index into ``channels``; ``None`` for a single unnamed channel);
/// ``metadata`` (the files' ``# key: value`` lines); ``files`` read; ``notes`` of the
/// loaders (what ``furfit inspect`` prints). Pass it to ``furfit.fit``.
#[pyclass(frozen, module = "furfit")]
pub struct Profile {
    pub(crate) inputs: LoadedInputs,
    pub(crate) load: LoadOptions,
    pub(crate) paths: Vec<PathBuf>,
    arrays: [Py<PyArray1<f64>>; 4],
    sigma: Option<Py<PyArray1<f64>>>,
    channel: Option<Py<PyArray1<i64>>>,
}

impl Profile {
    /// The species a fit of this profile is named after (as `furfit fit` names it).
    pub(crate) fn species(&self) -> String {
        furfit::fit::job::species_name(&self.paths[0])
    }
}

/// A read-only float64 array of `v` (no copy of `v`).
fn frozen<'py, T: numpy::Element>(py: Python<'py>, v: Vec<T>) -> PyResult<Py<PyArray1<T>>> {
    let a = v.into_pyarray(py);
    a.getattr("flags")?.setattr("writeable", false)?;
    Ok(a.unbind())
}

/// Paths of `path`: one path-like, or a list / tuple of them (merged as `furfit fit`
/// merges several inputs).
pub(crate) fn paths_of_any(path: &Bound<'_, PyAny>) -> PyResult<Vec<PathBuf>> {
    if path.is_instance_of::<PyList>() || path.is_instance_of::<pyo3::types::PyTuple>() {
        let v: Vec<PathBuf> = path
            .try_iter()?
            .map(|p| Ok(PathBuf::from(path_text(&p?, "path")?)))
            .collect::<PyResult<_>>()?;
        if v.is_empty() {
            return Err(pyo3::exceptions::PyValueError::new_err(
                "path: give at least one profile file or species folder",
            ));
        }
        return Ok(v);
    }
    Ok(vec![PathBuf::from(path_text(path, "path")?)])
}

/// A loader grid option: CLI grid text, or a sequence of degrees (written as the exact
/// shortest decimals, which the grid parser reads back to the same values).
fn grid_text(obj: Option<&Bound<'_, PyAny>>) -> PyResult<Option<String>> {
    let Some(obj) = obj else { return Ok(None) };
    if let Ok(s) = obj.cast::<PyString>() {
        return Ok(Some(s.to_cow()?.into_owned()));
    }
    let v: Vec<f64> = crate::convert::angles(obj, "grid")?;
    Ok(Some(
        v.iter()
            .map(|x| format!("{x}"))
            .collect::<Vec<_>>()
            .join(","),
    ))
}

/// Load a profile file (``.csv``, ``.npz``, ``.npy``, Yan-2015 ``.txt``) or a species
/// folder, or a list of them (merged), as ``furfit fit`` and ``furfit inspect`` read them.
///
/// Loader options (the CLI's): ``theta_i``, ``theta_r``, ``phi`` (axis grids for a lone
/// ``.npy``; ``theta_i`` also for a Yan-2015 file without its ``# theta_i:`` line), as
/// grid text (``"-60:60:2"``) or a sequence of degrees; ``phi_offset`` (degrees added to
/// every phi, within [-360, 360]); ``flip_phi``; ``flip_theta_r``. Raises OSError for an
/// unreadable or malformed file (the message names file, line and column), ValueError
/// for bad options. The loaders' notes are issued as warnings too.
#[pyfunction]
#[pyo3(signature = (path, *, theta_i=None, theta_r=None, phi=None, phi_offset=0.0, flip_phi=false, flip_theta_r=false))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn load_profile(
    py: Python<'_>,
    path: &Bound<'_, PyAny>,
    theta_i: Option<&Bound<'_, PyAny>>,
    theta_r: Option<&Bound<'_, PyAny>>,
    phi: Option<&Bound<'_, PyAny>>,
    phi_offset: f64,
    flip_phi: bool,
    flip_theta_r: bool,
) -> PyResult<Profile> {
    let paths = paths_of_any(path)?;
    let args = furfit::cli::LoadArgs {
        theta_i: grid_text(theta_i)?,
        theta_r: grid_text(theta_r)?,
        phi: grid_text(phi)?,
        phi_offset,
        flip_phi,
        flip_theta_r,
    };
    let load = args.to_options().map_err(py_err_any)?;
    let p = load_paths(py, paths, load)?;
    for n in &p.inputs.notes {
        warn(py, &format!("note: {n}"))?;
    }
    Ok(p)
}

/// Load and merge `paths` with `load`, off the GIL (`fit::job::load_inputs_full`, then the
/// check that every axis option given was read, as `furfit fit` does).
pub(crate) fn load_paths(
    py: Python<'_>,
    paths: Vec<PathBuf>,
    load: LoadOptions,
) -> PyResult<Profile> {
    let cancel = Cancel::new();
    let inputs = run_interruptible(py, &cancel, || {
        let l = furfit::fit::job::load_inputs_full(&paths, &load)?;
        load.check_used(&l.formats())?;
        Ok::<_, furfit::Error>(l)
    })?
    .map_err(py_err)?;
    let s = &inputs.profile.samples;
    let col = |f: fn(&furfit::Sample) -> f64| s.iter().map(f).collect::<Vec<f64>>();
    let arrays = [
        frozen(py, col(|x| x.theta_i))?,
        frozen(py, col(|x| x.theta_r))?,
        frozen(py, col(|x| x.phi))?,
        frozen(py, col(|x| x.value))?,
    ];
    let sigma = if s.iter().any(|x| x.sigma.is_some()) {
        Some(frozen(py, col(|x| x.sigma.unwrap_or(f64::NAN)))?)
    } else {
        None
    };
    let channel = if inputs.profile.channels.is_empty() {
        None
    } else {
        Some(frozen(py, s.iter().map(|x| x.channel as i64).collect())?)
    };
    Ok(Profile {
        inputs,
        load,
        paths,
        arrays,
        sigma,
        channel,
    })
}

#[pymethods]
impl Profile {
    /// Incident inclinations, degrees.
    #[getter]
    fn theta_i(&self, py: Python<'_>) -> Py<PyArray1<f64>> {
        self.arrays[0].clone_ref(py)
    }

    /// Outgoing inclinations, degrees.
    #[getter]
    fn theta_r(&self, py: Python<'_>) -> Py<PyArray1<f64>> {
        self.arrays[1].clone_ref(py)
    }

    /// Relative azimuths phi_r - phi_i, degrees in (-180, 180] (0: backward scattering).
    #[getter]
    fn phi(&self, py: Python<'_>) -> Py<PyArray1<f64>> {
        self.arrays[2].clone_ref(py)
    }

    /// Measured values (<= 0 or NaN: invalid, left out of fits).
    #[getter]
    fn value(&self, py: Python<'_>) -> Py<PyArray1<f64>> {
        self.arrays[3].clone_ref(py)
    }

    /// Standard errors of the values (NaN where missing), or None if no sample has one.
    #[getter]
    fn sigma(&self, py: Python<'_>) -> Option<Py<PyArray1<f64>>> {
        self.sigma.as_ref().map(|a| a.clone_ref(py))
    }

    /// Channel index of each sample into ``channels``, or None for one unnamed channel.
    #[getter]
    fn channel(&self, py: Python<'_>) -> Option<Py<PyArray1<i64>>> {
        self.channel.as_ref().map(|a| a.clone_ref(py))
    }

    /// Channel names (empty for one unnamed channel).
    #[getter]
    fn channels(&self) -> Vec<String> {
        self.inputs.profile.channels.clone()
    }

    /// The files' ``# key: value`` metadata (a later key of the same name wins).
    #[getter]
    fn metadata<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for (k, v) in &self.inputs.profile.metadata {
            d.set_item(k, v)?;
        }
        Ok(d)
    }

    /// The files read (folders expanded).
    #[getter]
    fn files(&self) -> Vec<String> {
        let f = &self.inputs.files;
        f.iter().map(|r| r.path.display().to_string()).collect()
    }

    /// The loaders' notes (collapsed duplicates, a radians warning ...).
    #[getter]
    fn notes(&self) -> Vec<String> {
        self.inputs.notes.clone()
    }

    /// The species name a fit gives it (the folder's, or the file's stem).
    #[getter(species)]
    fn species_py(&self) -> String {
        self.species()
    }

    /// Whether the files say the data are synthetic (simulated or synthesized).
    #[getter]
    fn synthetic(&self) -> bool {
        self.inputs.profile.is_synthetic()
    }

    fn __len__(&self) -> usize {
        self.inputs.profile.samples.len()
    }

    fn __repr__(&self) -> String {
        let p = &self.inputs.profile;
        format!(
            "<furfit.Profile {}: {} samples ({} valid){}, {} file(s)>",
            self.species(),
            p.samples.len(),
            p.n_valid(),
            if p.channels.is_empty() {
                String::new()
            } else {
                format!(", channels {}", p.channels.join(","))
            },
            self.inputs.files.len()
        )
    }
}
