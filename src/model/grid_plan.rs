//! Grid-structured prediction of goniometric profiles from the fur model ([`GridPlan`]):
//! what `yan2017`'s adapter, the fitter, `furfit synth` and the reports evaluate.
//!
//! A profile value is `k * sum_p M_p(theta_i, theta_r) N_p(theta_d, phi)` (MODEL.md). The
//! far-field `N_p` depends on the sample only through `(theta_d, phi)` and the unscattered
//! `M_p` only through `(theta_i, theta_r)`, so [`predict`] evaluates each distinct
//! `(theta_d, phi)` pair once (in parallel over `theta_d`) and each distinct
//! `(theta_i, theta_r)` pair once, then combines: a `theta_i x theta_r x phi` grid costs far
//! less than one full evaluation per sample. Results do not depend on the thread count.

use super::azimuthal::wrap_angle;
use super::far::{BitsMap, Decisions, FarOptions, FarSlice};
use super::geometry::theta_d;
use super::medulla::front_back_lerp;
use super::{AzimuthalSlice, FurModel, Lobe, LobeSet, LobeValues};
use rayon::prelude::*;

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
