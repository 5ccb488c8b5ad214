//! Grid-structured prediction of goniometric profiles from the model: what the fitter,
//! `furfit synth` and the reports evaluate.
//!
//! A profile value is `k * sum_p M_p(theta_i, theta_r) N_p(theta_d, phi)` (MODEL.md). The
//! far-field `N_p` depends on the sample only through `(theta_d, phi)` and the unscattered
//! `M_p` only through `(theta_i, theta_r)`, so [`predict`] evaluates each distinct
//! `(theta_d, phi)` pair once (in parallel over `theta_d`) and each distinct
//! `(theta_i, theta_r)` pair once, then combines: a `theta_i x theta_r x phi` grid costs far
//! less than one full evaluation per sample. Results do not depend on the thread count.

use crate::model::azimuthal::wrap_angle;
use crate::model::far::{BitsMap, Decisions, FarOptions, FarSlice};
use crate::model::geometry::theta_d;
use crate::model::medulla::front_back_lerp;
use crate::model::{AzimuthalSlice, FurModel, Lobe, LobeSet, LobeValues};
use crate::models::{Integral, ModelParams, Points};
use crate::profile::{Profile, Sample};
use rayon::prelude::*;
use std::path::Path;

/// The far field of one `theta_d` at many `phi`, as grid prediction computes it: one
/// slice (segmentation and fits), evaluated at all of them
/// ([`FarSlice::eval_grid`](crate::model::far::FarSlice::eval_grid)).
pub fn far_many(
    az: &AzimuthalSlice,
    lobes: LobeSet,
    opts: &FarOptions,
    phis: &[f64],
) -> Vec<LobeValues> {
    az.far_slice(lobes, opts).eval_grid(phis)
}

/// Which azimuthal integral a synthesized profile uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ModelKind {
    /// The piecewise-analytic far field (seed Sec. 5.1).
    Far,
    /// The far-field integral by adaptive quadrature of the near field (the reference
    /// integrator, ~1e-10 relative; slow).
    NearQuadrature,
}

impl ModelKind {
    /// The kind's name, as [`ModelKind::parse`] reads it (`far`, `near-quadrature`).
    pub fn name(self) -> &'static str {
        match self {
            ModelKind::Far => "far",
            ModelKind::NearQuadrature => "near-quadrature",
        }
    }

    /// Parse `far` or `near-quadrature`.
    pub fn parse(s: &str) -> crate::Result<ModelKind> {
        match s.trim().to_ascii_lowercase().as_str() {
            "far" => Ok(ModelKind::Far),
            "near-quadrature" | "near_quadrature" | "quadrature" => Ok(ModelKind::NearQuadrature),
            other => Err(crate::Error::Invalid(format!(
                "unknown model '{other}' (expected far or near-quadrature)"
            ))),
        }
    }
}

/// Per-lobe `M_p N_p` (no exposure) at each `(theta_i, theta_r, phi)` point (radians), with
/// the piecewise-analytic far field.
pub fn predict(
    model: &FurModel,
    points: &[(f64, f64, f64)],
    lobes: LobeSet,
    opts: &FarOptions,
) -> Vec<LobeValues> {
    predict_with(model, points, lobes, ModelKind::Far, opts)
}

/// [`predict`] with a choice of azimuthal integral.
pub fn predict_with(
    model: &FurModel,
    points: &[(f64, f64, f64)],
    lobes: LobeSet,
    kind: ModelKind,
    opts: &FarOptions,
) -> Vec<LobeValues> {
    GridPlan::new(points).predict(model, lobes, kind, opts)
}

/// The grid structure of a list of goniometer points, found once and reused for every
/// parameter set (the fitter evaluates the same points hundreds of times): the distinct
/// `|theta_d|` values with their distinct `|phi|` (wrapped to `[0, pi]`), and the distinct
/// `(theta_i, theta_r)` pairs.
#[derive(Clone, Debug, Default)]
pub struct GridPlan {
    points: Vec<(f64, f64, f64)>,
    /// Per distinct `|theta_d|`: the value and its distinct `|phi|` values.
    groups: Vec<(f64, Vec<f64>)>,
    /// Per point: (group, index of its `phi` in the group).
    where_n: Vec<(usize, usize)>,
    /// Distinct `(theta_i, theta_r)` pairs, and per point the index of its pair.
    pairs: Vec<(f64, f64)>,
    where_m: Vec<usize>,
}

impl GridPlan {
    /// The plan of `points` `(theta_i, theta_r, phi)`, radians.
    pub fn new(points: &[(f64, f64, f64)]) -> GridPlan {
        // The azimuthal model depends on theta_d only through cos theta_d
        // (`FurModel::azimuthal`), so theta_d and -theta_d share one slice: a grid
        // symmetric about theta_i = theta_r costs up to half.
        let tds: Vec<f64> = points
            .iter()
            .map(|&(ti, tr, _)| theta_d(ti, tr).abs())
            .collect();
        let (reps, td_group) = merge_rounding_twins(&tds);
        let mut phi_index: Vec<BitsMap<u64, usize>> = vec![BitsMap::default(); reps.len()];
        let mut pair_index: BitsMap<(u64, u64), usize> = BitsMap::default();
        let mut plan = GridPlan {
            points: points.to_vec(),
            groups: reps.into_iter().map(|td| (td, Vec::new())).collect(),
            ..GridPlan::default()
        };
        for (&(ti, tr, phi), &td) in points.iter().zip(&tds) {
            let g = td_group[&td.to_bits()];
            // N_p is even and 2 pi-periodic in phi (far_field_is_even_in_phi), so phi and
            // -phi share one evaluation: a symmetric grid costs half.
            let phi_n = wrap_angle(phi).abs();
            let k = *phi_index[g].entry(phi_n.to_bits()).or_insert_with(|| {
                plan.groups[g].1.push(phi_n);
                plan.groups[g].1.len() - 1
            });
            plan.where_n.push((g, k));
            let m = *pair_index
                .entry((ti.to_bits(), tr.to_bits()))
                .or_insert_with(|| {
                    plan.pairs.push((ti, tr));
                    plan.pairs.len() - 1
                });
            plan.where_m.push(m);
        }
        plan
    }

    /// The number of distinct `|theta_d|` slices the plan evaluates.
    pub fn slices(&self) -> usize {
        self.groups.len()
    }

    /// The slices: each distinct `|theta_d|` with its distinct `|phi|`.
    pub fn groups(&self) -> &[(f64, Vec<f64>)] {
        &self.groups
    }

    /// Number of points planned.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether there are no points.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Per-lobe `M_p N_p` (no exposure) at every point of the plan.
    pub fn predict(
        &self,
        model: &FurModel,
        lobes: LobeSet,
        kind: ModelKind,
        opts: &FarOptions,
    ) -> Vec<LobeValues> {
        let lobes = lobes.intersect(model.active_lobes());
        if self.points.is_empty() || lobes.is_empty() {
            return vec![LobeValues::default(); self.points.len()];
        }
        let n = self.azimuthal_terms(model, lobes, kind, opts);
        let m = self.longitudinal_terms(model, lobes);
        self.combine(&n, &m).collect()
    }

    /// [`Self::predict`] with the far field, and the number of `theta_d` slices whose
    /// tolerance-mode refinement hit a limit ([`capped_slices`]).
    pub fn predict_far_checked(
        &self,
        model: &FurModel,
        lobes: LobeSet,
        opts: &FarOptions,
    ) -> (Vec<LobeValues>, usize) {
        let lobes = lobes.intersect(model.active_lobes());
        if self.points.is_empty() || lobes.is_empty() {
            return (vec![LobeValues::default(); self.points.len()], 0);
        }
        let (n, decisions) = self.far_terms_taped(model, lobes, opts, None);
        let m = self.longitudinal_terms(model, lobes);
        (self.combine(&n, &m).collect(), capped_slices(&decisions))
    }

    /// The far-field [`Self::azimuthal_terms`] recording each slice's refinement
    /// decisions, or with `replay` (one [`Decisions`] per slice, as recorded) taking them
    /// instead: the fitter's finite differences replay the decisions of the point they
    /// differentiate at, so a tolerance-mode split tipped by the step cannot swamp the
    /// derivative. Without `replay` the decisions are the slices' own.
    pub fn far_terms_taped(
        &self,
        model: &FurModel,
        lobes: LobeSet,
        opts: &FarOptions,
        replay: Option<&[Decisions]>,
    ) -> (Vec<Vec<LobeValues>>, Vec<Decisions>) {
        let lobes = lobes.intersect(model.active_lobes());
        self.groups
            .par_iter()
            .enumerate()
            .map(|(g, (td, phis))| {
                if lobes.is_empty() {
                    return (
                        vec![LobeValues::default(); phis.len()],
                        Decisions::default(),
                    );
                }
                let az = model.azimuthal(*td);
                let (slice, rec) =
                    FarSlice::far_taped(&az, lobes, opts, replay.and_then(|r| r.get(g)));
                (slice.eval_grid(phis), rec)
            })
            .unzip()
    }

    /// `N_p` of the lobes in `lobes` (others 0) per distinct `(theta_d, phi)`, indexed
    /// `[group][phi]`; parallel over `theta_d`. Each lobe's value does not depend on which
    /// other lobes are asked for, so terms of different lobe sets can be merged.
    pub fn azimuthal_terms(
        &self,
        model: &FurModel,
        lobes: LobeSet,
        kind: ModelKind,
        opts: &FarOptions,
    ) -> Vec<Vec<LobeValues>> {
        if kind == ModelKind::Far {
            // One slice per theta_d (segmentation and fits), evaluated at all its phi; the
            // decisions it records cost a push each and are dropped.
            return self.far_terms_taped(model, lobes, opts, None).0;
        }
        let lobes = lobes.intersect(model.active_lobes());
        self.groups
            .par_iter()
            .map(|(td, phis)| {
                if lobes.is_empty() {
                    return vec![LobeValues::default(); phis.len()];
                }
                let az = model.azimuthal(*td);
                phis.par_iter()
                    .with_min_len(4)
                    .map(|&phi| az.far_reference(phi, lobes))
                    .collect()
            })
            .collect()
    }

    /// Longitudinal terms per distinct `(theta_i, theta_r)`: `M_p` of the unscattered lobes
    /// in `lobes`, and the front/back `C^M` of the scattered ones (`None` when no scattered
    /// lobe is asked for or exists); `M_s` depends on `phi` through the lerp of Eq. 19.
    pub fn longitudinal_terms(&self, model: &FurModel, lobes: LobeSet) -> Vec<PairTerms> {
        let lobes = lobes.intersect(model.active_lobes());
        let unsc = lobes.intersect(LobeSet::UNSCATTERED);
        let scat = lobes.intersect(LobeSet::SCATTERED);
        self.pairs
            .iter()
            .map(|&(ti, tr)| {
                let sides = if scat.is_empty() {
                    None
                } else {
                    model.scattered_longitudinal_sides(ti, tr)
                };
                (model.longitudinal(ti, tr, 0.0, unsc), sides)
            })
            .collect()
    }

    /// Per-lobe `M_p N_p` at every point from the two kinds of terms (in point order).
    pub fn combine<'s>(
        &'s self,
        n: &'s [Vec<LobeValues>],
        m: &'s [PairTerms],
    ) -> impl IndexedParallelIterator<Item = LobeValues> + 's {
        self.points
            .par_iter()
            .zip(self.where_n.par_iter().zip(self.where_m.par_iter()))
            .with_min_len(1024)
            .map(move |(&(_, _, phi), (&(g, k), &mi))| {
                let (mut mv, sides) = m[mi];
                if let Some((front, back)) = sides {
                    let ms = front_back_lerp(front, back, phi);
                    mv.set(Lobe::TTs, ms);
                    mv.set(Lobe::TRTs, ms);
                }
                mv.mul(&n[g][k])
            })
    }
}

/// How many slices' builds (one [`Decisions`] each) had a lobe whose tolerance-mode
/// refinement hit its split or depth limit ([`Decisions::capped`]): their values are not
/// guaranteed to `tol` (extreme parameters, e.g. `beta_n` far below a degree at a caustic).
pub fn capped_slices(decisions: &[Decisions]) -> usize {
    decisions.iter().filter(|d| !d.capped().is_empty()).count()
}

/// `|theta_d|` values closer than this (radians) are one goniometer configuration.
///
/// `theta_d = (theta_r - theta_i) / 2` of angles converted from degrees carries a rounding
/// error of a few `1e-16` rad that depends on the pair: on the 4 x 61 x 181 throughput grid
/// the 99 distinct `theta_d` came out as 159 bit patterns, each costing its own slice. A
/// shift of `1e-14` rad changes `N_p` by ~1e-14 of itself for ordinary parameters (its
/// `theta_d` scale is a degree or more), far below the far field's `tol`.
pub const THETA_D_MERGE: f64 = 1e-14;

/// The distinct values of `v` with those within [`THETA_D_MERGE`] of a smaller one merged
/// (in ascending order; each cluster is represented by its smallest value and spans at
/// most `THETA_D_MERGE`), and the cluster index of each value's bit pattern.
fn merge_rounding_twins(v: &[f64]) -> (Vec<f64>, BitsMap<u64, usize>) {
    let mut sorted = v.to_vec();
    // Equal under total_cmp means equal bits, so an unstable sort gives the same order.
    sorted.sort_unstable_by(f64::total_cmp);
    sorted.dedup_by(|a, b| a.to_bits() == b.to_bits());
    let mut reps: Vec<f64> = Vec::new();
    let mut index = BitsMap::with_capacity_and_hasher(sorted.len(), Default::default());
    for x in sorted {
        match reps.last() {
            Some(&r) if x - r <= THETA_D_MERGE => {}
            _ => reps.push(x),
        }
        index.insert(x.to_bits(), reps.len() - 1);
    }
    (reps, index)
}

/// Longitudinal terms of one `(theta_i, theta_r)` pair ([`GridPlan::longitudinal_terms`]):
/// unscattered `M_p`, and the front/back `C^M` of the scattered lobes if any.
pub type PairTerms = (LobeValues, Option<(f64, f64)>);

/// The points of the grid `theta_i x theta_r x phi`, in that nesting order (`phi` fastest),
/// in the units given.
pub fn grid_points(theta_i: &[f64], theta_r: &[f64], phi: &[f64]) -> Vec<(f64, f64, f64)> {
    let mut pts = Vec::with_capacity(theta_i.len() * theta_r.len() * phi.len());
    for &ti in theta_i {
        for &tr in theta_r {
            for &p in phi {
                pts.push((ti, tr, p));
            }
        }
    }
    pts
}

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

    #[test]
    fn predict_matches_pointwise_evaluation() {
        let p = FurParams::preset("red-fox").unwrap();
        let model = FurModel::new(&p);
        let opts = FarOptions::default();
        let mut pts = Vec::new();
        for ti in [0.0f64, 30.0] {
            for tr in [-20.0f64, 10.0, 40.0] {
                // Negative and out-of-range phi exercise the plan's fold to |wrapped phi|.
                for phi in [-180.0f64, -170.0, -30.0, 0.0, 30.0, 90.0, 180.0, 200.0] {
                    pts.push((ti.to_radians(), tr.to_radians(), phi.to_radians()));
                }
            }
        }
        let v = predict(&model, &pts, LobeSet::ALL, &opts);
        for (i, &(ti, tr, phi)) in pts.iter().enumerate() {
            let w = model.eval_far(ti, tr, phi, LobeSet::ALL, &opts);
            for l in Lobe::ALL {
                // Same code path per (theta_d, phi): identical up to the order of two
                // multiplications (1e-14 relative).
                assert!(
                    (v[i].get(l) - w.get(l)).abs() <= 1e-14 * w.get(l).abs().max(1e-300),
                    "{l:?}: {} vs {}",
                    v[i].get(l),
                    w.get(l)
                );
            }
        }
    }

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

    #[test]
    fn plan_merges_rounding_twins_of_theta_d() {
        // The throughput grid's 99 distinct theta_d (whole and half degrees, 0..52.5)
        // arrive as more bit patterns; the plan gives each configuration one slice.
        let pts = crate::report::far_error::throughput_grid();
        let raw: std::collections::HashSet<u64> = pts
            .iter()
            .map(|&(ti, tr, _)| theta_d(ti, tr).abs().to_bits())
            .collect();
        assert!(raw.len() > 99, "the grid no longer shows rounding twins");
        let plan = GridPlan::new(&pts);
        assert_eq!(plan.slices(), 99);
        // Every point's slice sits within THETA_D_MERGE of its own theta_d, and the
        // slices are genuinely distinct configurations (a quarter degree apart at least).
        for (&(ti, tr, _), &(g, _)) in pts.iter().zip(&plan.where_n) {
            assert!((plan.groups[g].0 - theta_d(ti, tr).abs()).abs() <= THETA_D_MERGE);
        }
        for w in plan.groups.windows(2) {
            assert!(w[1].0 - w[0].0 > 0.25f64.to_radians());
        }
    }

    #[test]
    fn merge_keeps_values_apart_beyond_the_threshold() {
        let a = 0.3;
        let v = [a, a + 0.5 * THETA_D_MERGE, a + 3.0 * THETA_D_MERGE, 0.1];
        let (reps, index) = merge_rounding_twins(&v);
        // 0.1 alone; a and its twin; a + 3 THETA_D_MERGE is its own configuration.
        assert_eq!(reps, vec![0.1, a, a + 3.0 * THETA_D_MERGE]);
        assert_eq!(index[&v[0].to_bits()], index[&v[1].to_bits()]);
        assert_ne!(index[&v[0].to_bits()], index[&v[2].to_bits()]);
    }
}
