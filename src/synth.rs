//! `furfit synth`'s library half: a profile synthesized from any model's prediction
//! ([`synthesize`], [`synthesize_channels`]), the channels a parameter source gives
//! ([`output_channels`]) and the checks of exposures and values before a profile is written.
//!
//! The fur model's grid-structured prediction ([`GridPlan`] and its helpers) lives in
//! [`crate::model::grid_plan`], below the model interface that this module uses; it is
//! re-exported here under its older paths (`synth::GridPlan`, `synth::predict`, ...).

pub use crate::model::grid_plan::{
    capped_slices, far_many, grid_points, predict, predict_with, GridPlan, ModelKind, PairTerms,
    THETA_D_MERGE,
};

use crate::model::far::FarOptions;
use crate::model::LobeSet;
use crate::models::{Integral, ModelParams, Points};
use crate::profile::{Profile, Sample};
use std::path::Path;

/// The `source` metadata of every synthesized profile: `synth --force` replaces only a
/// file that carries it.
pub const SOURCE: &str = "synthetic: furfit synth (model prediction, no noise)";

/// Synthesize a profile on the grid `theta_i x theta_r x phi` (degrees), value
/// `exposure * sum_{p in lobes} f_p` of any model ([`crate::models`]). The metadata says it
/// is synthetic and records the model, parameters, integral, lobes and options. `params`
/// must be validated.
#[allow(clippy::too_many_arguments)]
pub fn synthesize(
    params: &ModelParams,
    theta_i: &[f64],
    theta_r: &[f64],
    phi: &[f64],
    integral: Integral,
    lobes: LobeSet,
    exposure: f64,
    opts: &FarOptions,
) -> Profile {
    let deg = grid_points(theta_i, theta_r, phi);
    let points = Points::new(
        deg.iter()
            .map(|&(a, b, c)| (a.to_radians(), b.to_radians(), c.to_radians()))
            .collect(),
    );
    let model = params.model;
    let pred = model.predict(&params.values, &points, opts, lobes, integral);
    let samples = deg
        .iter()
        .zip(&pred.lobes)
        .map(|(&(ti, tr, p), v)| Sample::new(ti, tr, p, exposure * v.sum()))
        .collect();
    let names = model.lobe_names();
    let lobe_names: Vec<&str> = (0..names.len())
        .filter(|&i| lobes.0 & (1 << i) != 0)
        .map(|i| names[i])
        .collect();
    let mut prof = Profile {
        samples,
        ..Default::default()
    };
    prof.set_meta("synthetic", "true");
    prof.set_meta("source", SOURCE);
    prof.set_meta("model", model.name());
    prof.set_meta("params", params.to_json_value().to_string());
    prof.set_meta("exposure", crate::error::Num(exposure).to_string());
    prof.set_meta("integral", integral.name());
    prof.set_meta("lobes", lobe_names.join(","));
    if integral == Integral::Far {
        prof.set_meta(
            "segments",
            format!("{},{}", opts.n_unscattered, opts.n_scattered),
        );
        prof.set_meta(
            "tol",
            opts.tol.map_or("none".to_string(), |t| format!("{t}")),
        );
        prof.set_meta("cull", format!("{}", opts.cull));
        // Slices whose tolerance-mode refinement hit its split or depth limit: their
        // values are not guaranteed to `tol` (the CLI says so on stderr).
        prof.set_meta(
            "capped_slices",
            format!("{} of {}", pred.capped.0, pred.capped.1),
        );
    }
    prof.set_meta("furfit_version", crate::TOOL_VERSION);
    prof
}

/// [`synthesize`] once per channel of a multi-channel fit (`(name, parameters, exposure)`;
/// an `exposure` given overrides every channel's): one profile with those named channels.
/// Its metadata are the first channel's, with `params`, `exposure` and `capped_slices`
/// per channel (`params_<name>`, ...) instead of one value.
#[allow(clippy::too_many_arguments)]
pub fn synthesize_channels(
    channels: &[(String, ModelParams, f64)],
    theta_i: &[f64],
    theta_r: &[f64],
    phi: &[f64],
    integral: Integral,
    lobes: LobeSet,
    exposure: Option<f64>,
    opts: &FarOptions,
) -> Profile {
    let mut out = Profile::default();
    for (c, (name, params, k)) in channels.iter().enumerate() {
        let k = exposure.unwrap_or(*k);
        let p = synthesize(params, theta_i, theta_r, phi, integral, lobes, k, opts);
        if c == 0 {
            out.metadata = p.metadata.clone();
            out.metadata.retain(|(key, _)| {
                !matches!(key.as_str(), "params" | "exposure" | "capped_slices")
            });
        }
        for key in ["params", "exposure", "capped_slices"] {
            if let Some(v) = p.meta(key) {
                out.set_meta(&format!("{key}_{name}"), v.to_string());
            }
        }
        out.channels.push(name.clone());
        out.samples.extend(p.samples.into_iter().map(|mut s| {
            s.channel = c;
            s
        }));
    }
    out
}

/// The output channels of a synthesis from parameters `params` with the exposure
/// `file_k` of their file, whose fit channels are `fitted` ([`crate::models::fit_channels`]
/// of the file `spec`): `(name, parameters, exposure)` each. `channel` `None` or `all`
/// gives every fitted channel (one unnamed set for a preset, a parameter file or a fit of
/// unnamed data; the one channel, named, of a single-channel fit); a name gives that
/// channel, or an error listing those there are.
pub fn output_channels(
    params: ModelParams,
    file_k: f64,
    fitted: &[crate::models::Channel],
    channel: Option<&str>,
    spec: &str,
) -> crate::Result<Vec<(String, ModelParams, f64)>> {
    let of = |f: &crate::models::Channel| (f.name.clone(), f.params.clone(), f.exposure);
    Ok(match channel {
        None | Some("all") if fitted.len() > 1 => fitted.iter().map(of).collect(),
        // `all` of a single set of parameters is that set (named if its fit's channel was).
        None | Some("all") => match fitted {
            [f] => vec![of(f)],
            _ => vec![(String::new(), params, file_k)],
        },
        Some(c) => vec![of(crate::models::select_channel(fitted, c, spec)?)],
    })
}

/// Check an exposure scale given to option `what` (e.g. `--exposure`): finite, > 0 and
/// normal (a subnormal exposure scales every value to 0 or to a few bits of precision).
pub fn check_exposure(what: &str, k: f64) -> crate::Result<()> {
    if !(k.is_finite() && k > 0.0) {
        return Err(crate::Error::Invalid(format!(
            "{what} must be a finite number > 0, got {}",
            crate::error::Num(k)
        )));
    }
    if k < f64::MIN_POSITIVE {
        return Err(crate::Error::Invalid(format!(
            "{what} {} is below {:e}: the values would underflow to 0",
            crate::error::Num(k),
            f64::MIN_POSITIVE
        )));
    }
    Ok(())
}

/// Share of a channel's peak below which a value the exposure pushes under the normal
/// f64 range is a deep tail: kept (with a note), not refused ([`check_values`]).
pub const UNDERFLOW_TAIL: f64 = 1e-12;

/// Check the values of a synthesized profile whose channel `c` was scaled by
/// `exposure(c)` (named `source` in errors: `--exposure`, or the parameter file's),
/// before it is handed out. Returns how many values in a deep tail (below
/// [`UNDERFLOW_TAIL`] of their channel's peak) the exposure pushed below the normal f64
/// range, for a note.
///
/// The model is finite (the stability report checks it): only the exposure can push a
/// value past the f64 range, to inf (which would not load back), or from the normal range
/// below it (a few bits at most). A value the model itself gives below the normal range
/// (a far tail under heavy absorption, 1e-310) is kept as it is. An exposure that pushes
/// values into that range costs them bits: refused where the value is at least
/// [`UNDERFLOW_TAIL`] of its channel's peak (the data), counted for a deep tail (a whole
/// grid refused over one grazing sample at 1e-300 of the peak was the black-box audit's
/// finding). NaN is the model's failure, refused naming where.
pub fn check_values(
    prof: &Profile,
    exposure: &dyn Fn(usize) -> f64,
    source: &str,
) -> crate::Result<usize> {
    // Only a non-finite value or one below the normal range can fail or count: one pass
    // finds there is none, the common case (the peaks are needed only otherwise).
    let suspect = |v: f64| !v.is_finite() || (v > 0.0 && v < f64::MIN_POSITIVE);
    if !prof.samples.iter().any(|s| suspect(s.value)) {
        return Ok(0);
    }
    let mut peak = vec![0.0f64; prof.channels.len().max(1)];
    for s in &prof.samples {
        if let Some(p) = peak.get_mut(s.channel) {
            *p = p.max(s.value);
        }
    }
    let exposure_underflow = |s: &Sample| {
        s.value > 0.0
            && s.value < f64::MIN_POSITIVE
            && s.value / exposure(s.channel) >= f64::MIN_POSITIVE
    };
    let in_tail =
        |s: &Sample| s.value < UNDERFLOW_TAIL * peak.get(s.channel).copied().unwrap_or(0.0);
    let tail_underflows = prof
        .samples
        .iter()
        .filter(|s| exposure_underflow(s) && in_tail(s))
        .count();
    if let Some(s) = prof
        .samples
        .iter()
        .find(|s| !s.value.is_finite() || (exposure_underflow(s) && !in_tail(s)))
    {
        // NaN is no exposure's doing: the model failed there (the stability report
        // checks for this; say where, so it can be reported).
        if s.value.is_nan() {
            return Err(crate::Error::Invalid(format!(
                "the model gave NaN at theta_i {}, theta_r {}, phi {}: a furfit bug for these \
                 parameters; nothing was written",
                s.theta_i, s.theta_r, s.phi
            )));
        }
        let (what, fix) = if s.value.is_finite() {
            ("underflows", "larger")
        } else {
            ("overflows", "smaller")
        };
        return Err(crate::Error::Invalid(format!(
            "{source}: the value at theta_i {}, theta_r {}, phi {} {what} ({:e}); use a {fix} exposure",
            s.theta_i, s.theta_r, s.phi, s.value
        )));
    }
    Ok(tail_underflows)
}

/// Save a synthesized profile (`.csv` or `.npz`, atomically) with the shared profile
/// writers.
pub fn save(path: &Path, prof: &Profile) -> crate::Result<()> {
    crate::profile::save(path, prof)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::FurParams;

    /// The profile says how many slices' refinement hit its limit: none for a preset at
    /// the default tolerance, all at the smallest `--tol` (1e-8) with a `beta_n` of 1e-4
    /// deg, where the TRT caustic needs more splits than the limit allows. (1e-3 deg did
    /// it until the tolerance mode fitted the log-attenuation by a quadratic; a `beta_n`
    /// of 1e-11 deg did it at the default tolerance until the model floored widths at
    /// `MIN_WIDTH`.)
    #[test]
    fn synthesize_records_capped_slices() {
        let capped = |beta_n_deg: f64, tol: f64| {
            let mut p = FurParams::preset("red-fox").unwrap();
            p.beta_n = beta_n_deg.to_radians();
            let prof = synthesize(
                &p.into(),
                &[0.0, 30.0],
                &[-40.0, 0.0, 40.0],
                &[-90.0, 0.0, 90.0, 180.0],
                Integral::Far,
                LobeSet::ALL,
                1.0,
                &FarOptions {
                    tol: Some(tol),
                    ..FarOptions::default()
                },
            );
            let m = prof.meta("capped_slices").unwrap().to_string();
            let (n, of) = m.split_once(" of ").unwrap();
            (n.parse::<usize>().unwrap(), of.parse::<usize>().unwrap())
        };
        let fox = FurParams::preset("red-fox").unwrap().beta_n.to_degrees();
        // |theta_d| in {0, 5, 15, 20, 35} degrees: five slices.
        assert_eq!(capped(fox, 1e-4), (0, 5));
        let (n, of) = capped(1e-4, 1e-8);
        assert!(n > 0 && of == 5, "{n} of {of}");
    }

    /// The output channels of each kind of parameter source: one unnamed set (a preset),
    /// every channel of a multi-channel fit or the one asked for, and an error naming
    /// the channels there are for another name.
    #[test]
    fn output_channels_follow_the_fit_channels() {
        let p: ModelParams = FurParams::preset("cat").unwrap().into();
        let one = output_channels(p.clone(), 2.0, &[], None, "cat").unwrap();
        assert_eq!(one, vec![(String::new(), p.clone(), 2.0)]);
        let ch = |name: &str, k: f64| crate::models::Channel {
            name: name.into(),
            params: p.clone(),
            exposure: k,
        };
        let rgb = [ch("r", 1.0), ch("g", 2.0), ch("b", 3.0)];
        for all in [None, Some("all")] {
            let v = output_channels(p.clone(), 9.0, &rgb, all, "f.json").unwrap();
            let names: Vec<&str> = v.iter().map(|c| c.0.as_str()).collect();
            assert_eq!(names, ["r", "g", "b"]);
            assert_eq!(v[2].2, 3.0);
        }
        let g = output_channels(p.clone(), 9.0, &rgb, Some("g"), "f.json").unwrap();
        assert_eq!(g, vec![("g".to_string(), p.clone(), 2.0)]);
        // A fit of one named channel keeps its name and its exposure.
        let y = output_channels(p.clone(), 9.0, &rgb[..1], None, "f.json").unwrap();
        assert_eq!(y, vec![("r".to_string(), p.clone(), 1.0)]);
        let e = output_channels(p, 9.0, &rgb, Some("y"), "f.json").unwrap_err();
        assert!(e.to_string().contains("has channels r, g, b"), "{e}");
    }

    #[test]
    fn exposure_checks_name_the_option() {
        assert!(check_exposure("--exposure", 2.5).is_ok());
        for (k, want) in [
            (0.0, "--exposure must be a finite number > 0, got 0"),
            (f64::NAN, "--exposure must be a finite number > 0, got NaN"),
            (1e-310, "--exposure 1e-310 is below"),
        ] {
            let e = check_exposure("--exposure", k).unwrap_err().to_string();
            assert!(e.starts_with(want), "{e}");
        }
    }

    /// Values the exposure pushed past the f64 range are refused (naming the sample and
    /// the exposure's source), a deep tail below the normal range is only counted, and
    /// NaN is the model's failure.
    #[test]
    fn check_values_refuses_overflow_counts_deep_tails() {
        let prof = |values: &[f64]| Profile {
            samples: values
                .iter()
                .enumerate()
                .map(|(i, &v)| Sample::new(0.0, i as f64, 0.0, v))
                .collect(),
            ..Default::default()
        };
        let one = |_: usize| 1.0;
        assert_eq!(check_values(&prof(&[1.0, 0.5]), &one, "x").unwrap(), 0);
        let e = check_values(&prof(&[1.0, f64::INFINITY]), &one, "--exposure")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("--exposure: the value at theta_i 0, theta_r 1, phi 0 overflows"),
            "{e}"
        );
        let e = check_values(&prof(&[f64::NAN]), &one, "x")
            .unwrap_err()
            .to_string();
        assert!(e.contains("the model gave NaN"), "{e}");
        // 1e-310 scaled from 1e-10 by an exposure of 1e-300: far below the peak (1), a
        // tail; the same underflow at the peak's own scale is refused.
        let tiny = |_: usize| 1e-300;
        assert_eq!(check_values(&prof(&[1.0, 1e-310]), &tiny, "x").unwrap(), 1);
        let e = check_values(&prof(&[2e-310, 1e-310]), &tiny, "k")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("underflows") && e.contains("use a larger exposure"),
            "{e}"
        );
    }
}
