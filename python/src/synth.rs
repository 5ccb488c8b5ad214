//! `furfit.synth`: the model on an angle grid, as `furfit synth` computes it
//! (`src/cli/synth.rs`: the same loading, channel choice, checks and
//! `furfit::synth::synthesize`), returned as a float64 array instead of a file.

use crate::convert::{angles, far_options, lobes_text, model_of, ParamsIn};
use crate::{py_err, warn};
use furfit::models::Integral;
use numpy::ndarray::{ArrayD, IxDyn};
use numpy::{IntoPyArray, PyArrayDyn};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

/// Synthesize the model on the grid ``theta_i x theta_r x phi`` (degrees).
///
/// ``params``: a preset name (e.g. ``"red-fox"``), a path to a parameter or fit JSON, a
/// dict (a parameter object, or a fit file's contents) or a ``FitResult``. ``model``: the
/// model of a preset, or the model the file must be of (default: the file's own;
/// ``yan2017`` for presets). The angles are 1-D sequences or arrays (any numeric dtype,
/// any strides), or CLI grid text such as ``"-60:60:2"``; ``phi`` may lie in
/// [-360, 360] and is wrapped to (-180, 180] as ``furfit synth`` wraps it.
///
/// Returns float64 values of shape ``(len(theta_i), len(theta_r), len(phi))``: the
/// values ``furfit synth`` writes for that grid (its exposure: the file's, else 1, or
/// ``exposure``). ``tol``: far-field tolerance (``None``: the fixed 8,5 segmentation);
/// ``lobes``: names such as ``"R,TT"`` or ``["R", "TT"]``; ``integral``: ``"far"`` or
/// ``"near-quadrature"``. A fit of several channels needs ``channel=NAME``, or
/// ``channel="all"`` for shape ``(channels, theta_i, theta_r, phi)``.
///
/// Raises ValueError for bad parameters, angles (empty, NaN, out of range) or a grid over
/// ``MAX_GRID_SAMPLES``; OSError for unreadable files. Runs without the GIL; Ctrl-C
/// raises KeyboardInterrupt once the synthesis ends (it has no cancellation point; the
/// largest grid takes seconds).
#[pyfunction]
#[pyo3(signature = (params, theta_i, theta_r, phi, *, model=None, tol=Some(1e-4), lobes=None, channel=None, exposure=None, integral="far"))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn synth<'py>(
    py: Python<'py>,
    params: &Bound<'py, PyAny>,
    theta_i: &Bound<'py, PyAny>,
    theta_r: &Bound<'py, PyAny>,
    phi: &Bound<'py, PyAny>,
    model: Option<&str>,
    tol: Option<f64>,
    lobes: Option<&Bound<'py, PyAny>>,
    channel: Option<&str>,
    exposure: Option<f64>,
    integral: &str,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let want = model.map(|m| model_of(Some(m))).transpose()?;
    let input = ParamsIn::from_py(params)?;
    let spec = input.label().to_string();
    let (params, file_k, json) = input.load(py, want)?;
    let model = params.model;
    let fitted = match &json {
        Some(v) => furfit::models::fit_channels(v, &spec).map_err(py_err)?,
        None => Vec::new(),
    };
    let channels =
        furfit::synth::output_channels(params, file_k, &fitted, channel, &spec).map_err(py_err)?;
    if channels.len() > 1 && channel.is_none() {
        let names: Vec<&str> = fitted.iter().map(|c| c.name.as_str()).collect();
        return Err(PyValueError::new_err(format!(
            "{spec} has channels {}: give channel=NAME for one, or channel='all' for an \
             array of shape (channels, theta_i, theta_r, phi)",
            names.join(", ")
        )));
    }
    for (_, p, _) in &channels {
        for n in model.notes(&p.values) {
            warn(py, &format!("note: {n}"))?;
        }
    }
    let ti = angles(theta_i, "theta_i")?;
    let tr = angles(theta_r, "theta_r")?;
    let mut ph = angles(phi, "phi")?;
    // The CLI's limits: inclinations within 90 degrees; azimuths within one turn either
    // way (`grid::parse_phi_grid`), wrapped to (-180, 180] as it wraps them.
    furfit::grid::check_angles("theta_i", &ti, 90.0).map_err(py_err)?;
    furfit::grid::check_angles("theta_r", &tr, 90.0).map_err(py_err)?;
    furfit::grid::check_angles("phi", &ph, 360.0).map_err(py_err)?;
    for v in ph.iter_mut() {
        *v = furfit::grid::wrap_deg(*v);
    }
    furfit::grid::check_grid_size(ti.len(), tr.len(), ph.len(), channels.len()).map_err(py_err)?;
    for (what, g) in [("theta_i", &ti), ("theta_r", &tr), ("phi", &ph)] {
        if let Some(n) = furfit::grid::radians_note(what, g) {
            warn(py, &n)?;
        }
    }
    let kind = Integral::parse(integral).map_err(py_err)?;
    let lobes = model.parse_lobes(&lobes_text(lobes)?).map_err(py_err)?;
    if let Some(k) = exposure {
        furfit::synth::check_exposure("exposure", k).map_err(py_err)?;
    }
    let opts = far_options(tol)?;
    let (ni, nr, np) = (ti.len(), tr.len(), ph.len());
    let several = channels.len() > 1;
    // The synthesis and its checks off the GIL (the checks read every value too), on
    // this thread: a synthesis has no cancellation point, so a worker thread polling for
    // Ctrl-C could not end it sooner (Python raises KeyboardInterrupt when it returns),
    // and its two thread wake-ups cost milliseconds on a busy machine.
    let out = py.detach(|| {
        let mut prof = match channels.as_slice() {
            [(_, p, k)] => furfit::synth::synthesize(
                p,
                &ti,
                &tr,
                &ph,
                kind,
                lobes,
                exposure.unwrap_or(*k),
                &opts,
            ),
            many => furfit::synth::synthesize_channels(
                many, &ti, &tr, &ph, kind, lobes, exposure, &opts,
            ),
        };
        let source = if exposure.is_some() {
            "exposure".to_string()
        } else {
            format!("the exposure of {spec}")
        };
        let k = |c: usize| exposure.unwrap_or(channels[c.min(channels.len() - 1)].2);
        let tails = furfit::synth::check_values(&prof, &k, &source)?;
        // The one copy of the output: values in grid order (phi fastest, then theta_r,
        // theta_i, channel), which is the array's C order.
        let values: Vec<f64> = prof.samples.iter().map(|s| s.value).collect();
        let metadata = std::mem::take(&mut prof.metadata);
        // The samples (~100 bytes each) are freed on a pool thread: returning their pages
        // to the system took up to a millisecond, 5 % of this call on the 4 x 61 x 181
        // grid, which the caller need not wait for.
        rayon::spawn(move || drop(prof));
        Ok::<_, furfit::Error>((values, tails, metadata))
    });
    let (values, tails, metadata) = out.map_err(py_err)?;
    if tails > 0 {
        warn(
            py,
            &format!(
                "note: at this exposure {tails} value(s) below {:e} of their channel's peak fall below the normal f64 range ({:e}) and keep fewer significant bits",
                furfit::synth::UNDERFLOW_TAIL,
                f64::MIN_POSITIVE
            ),
        )?;
    }
    for (key, c) in &metadata {
        if key.starts_with("capped_slices") && !c.starts_with("0 ") {
            warn(
                py,
                &format!("note: {c} far-field slices hit the refinement limit; their values are not guaranteed to tol"),
            )?;
        }
    }
    let shape: Vec<usize> = if several {
        vec![channels.len(), ni, nr, np]
    } else {
        vec![ni, nr, np]
    };
    let arr = ArrayD::from_shape_vec(IxDyn(&shape), values)
        .map_err(|e| PyValueError::new_err(format!("internal shape mismatch: {e}")))?;
    // Hands the buffer to numpy: no second copy.
    Ok(arr.into_pyarray(py))
}

/// Seconds of the bare library call `furfit::synth::synthesize` of the preset `params`
/// (the default model's) on this grid, exposure 1, default options: what
/// `python/bench/bench_synth.py` compares `synth` with in the same process. Not API.
#[pyfunction]
#[pyo3(name = "_library_synth_seconds")]
pub(crate) fn library_synth_seconds(
    py: Python<'_>,
    params: &str,
    theta_i: Vec<f64>,
    theta_r: Vec<f64>,
    phi: Vec<f64>,
) -> PyResult<f64> {
    let model = furfit::models::default_model();
    let p = furfit::models::ModelParams::preset(model, params)
        .ok_or_else(|| PyValueError::new_err(format!("no preset {params}")))?;
    let opts = far_options(Some(1e-4))?;
    Ok(py.detach(|| {
        let t = std::time::Instant::now();
        let prof = furfit::synth::synthesize(
            &p,
            &theta_i,
            &theta_r,
            &phi,
            Integral::Far,
            furfit::model::LobeSet::ALL,
            1.0,
            &opts,
        );
        let dt = t.elapsed().as_secs_f64();
        drop(prof);
        dt
    }))
}
