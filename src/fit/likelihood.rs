//! Profile-likelihood intervals: for one parameter, the values at which the best fit with
//! that parameter held fixed (every other free parameter and the exposure re-solved)
//! costs `s^2` more than the optimum, `(RSS(x) - RSS*) / s^2 = 1` (one parameter, 68 %
//! for Gaussian errors). Unlike the linearised standard error ([`super::uncertainty`]) it
//! follows a curved or bounded valley: a parameter pinned near a bound gets a one-sided
//! interval that ends at the bound, not a symmetric `±SE` that crosses it.
//!
//! Each side steps the parameter's unbounded coordinate `u` by `c * step`,
//! `c = 1, 2, 4, 8, 16` ([`STEPS`]; `step = SE(u)` at most [`MAX_STEP_U`], which is also
//! taken when the linearised one is undefined; a smaller step goes on doubling up to the
//! same reach, `16 MAX_STEP_U`), re-solving the others from the previous
//! point (warm start), until `Delta >= 1`; the bracketed crossing is then narrowed by up
//! to [`REFINE`] more re-solves (regula falsi in `sqrt(Delta)`, which is linear in the
//! step for a quadratic valley, with a bisection when it stalls) until `Delta` is within
//! [`CROSS_TOL`] of 1. A parameter on its bound (`reparam::at_bound`: the map's
//! derivative has vanished, so steps of its `u` would not move it) ends at the bound on
//! that side, and the other side starts from the map's interior edge
//! (`reparam::interior_edge`) with the map's own step. A side whose `u` reaches the map's
//! clamp without crossing ends at the bound; one still below 1 after the last step
//! reports how far it got. Each re-solve with another parameter on its bound is also run
//! from that parameter's interior edge, and the better kept. A re-solve cheaper than the optimum (`Delta < -0.1`) means the
//! fit stopped short of the valley's floor; the interval says so.

use super::problem::LogResidualProblem;
use super::reparam;
use super::uncertainty::{residual_variance, Uncertainty};
use crate::models::Param;
use nalgebra::DVector;

/// Multiples of the step tried on each side.
pub const STEPS: [f64; 5] = [1.0, 2.0, 4.0, 8.0, 16.0];
/// The multiples of `step` tried on a side: [`STEPS`], then further doublings while the
/// offset stays within `16 * MAX_STEP_U`, the reach of a profile whose step is
/// [`MAX_STEP_U`]. A linearised SE that holds a partner on its bound can be far too small
/// (a valley two absorptions trade along): its profile must still be able to walk as far
/// as one with an undefined SE.
fn steps(step: f64) -> Vec<f64> {
    let mut out = STEPS.to_vec();
    let reach = STEPS[STEPS.len() - 1] * MAX_STEP_U;
    let mut c = 2.0 * STEPS[STEPS.len() - 1];
    while c * step <= reach * (1.0 + 1e-12) && out.len() < 64 {
        out.push(c);
        c *= 2.0;
    }
    out
}

/// Largest step in `u` (a factor e for `exp` maps): a huge linearised `SE(u)` (24 for an
/// absorption the data barely sees) would jump past the crossing by orders of magnitude.
pub const MAX_STEP_U: f64 = 1.0;
/// Re-solves spent narrowing a bracketed crossing.
pub const REFINE: usize = 6;
/// `|Delta - 1|` that ends the narrowing.
pub const CROSS_TOL: f64 = 0.1;

/// `Delta` below this at a profile point means the re-solve beat the reported optimum.
pub const LOWER_COST: f64 = -0.1;

/// Relative size of an RSS difference that is rounding, not a better fit.
pub const RSS_ROUNDING: f64 = 1e-9;

/// How one side of an interval ended.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum End {
    /// `Delta` crossed 1 at this value (file units).
    Crossing(f64),
    /// The value reached its bound (file units) with `Delta` still below 1.
    Bound(f64),
    /// `Delta` was still below 1 at this value, the last step tried.
    Beyond(f64),
}

impl End {
    /// The value the side ended at, file units.
    pub fn value(self) -> f64 {
        match self {
            End::Crossing(v) | End::Bound(v) | End::Beyond(v) => v,
        }
    }

    /// `crossing`, `bound` or `beyond`, as reports and fit files name it.
    pub fn kind(self) -> &'static str {
        match self {
            End::Crossing(_) => "crossing",
            End::Bound(_) => "bound",
            End::Beyond(_) => "beyond",
        }
    }
}

/// The profile interval of one parameter.
#[derive(Clone, Debug, PartialEq)]
pub struct Interval {
    /// The parameter.
    pub id: Param,
    /// The fitted value (file units).
    pub at: f64,
    /// Lower end (file units).
    pub lo: End,
    /// Upper end (file units).
    pub hi: End,
    /// The lowest `Delta` met (negative: a better fit exists with `id` moved) and where.
    pub lowest: Option<(f64, f64)>,
    /// The free coordinates of that better fit (the re-solve with `id` at its value),
    /// when `lowest` is reported.
    pub better: Option<DVector<f64>>,
    /// Re-solves spent.
    pub refits: usize,
}

/// A re-solve of a problem with one more parameter fixed, from a start for its free
/// coordinates: their solution and its RSS.
pub type Refit<'r> = dyn FnMut(&LogResidualProblem, DVector<f64>) -> (DVector<f64>, f64) + 'r;

/// A profile re-solve better than the optimum by more than this (in `s^2`: a change of
/// the fit the data can tell) makes the fitter polish again from it
/// ([`super::fit_data`]); smaller improvements are only reported.
pub const REPOLISH: f64 = -1.0;

/// A re-solve with the parameter's coordinate fixed at a `u`, from a start for the other
/// free coordinates: `(RSS, their solution)`.
pub type Resolve<'r> = dyn FnMut(f64, &DVector<f64>) -> (f64, DVector<f64>) + 'r;

/// What the profile of one parameter needs to know about the fit.
pub struct ProfileProblem {
    /// The parameter profiled.
    pub id: Param,
    /// The parameter's position among the free coordinates.
    pub j: usize,
    /// The fitted free coordinates.
    pub u: DVector<f64>,
    /// `SE(u)` of the parameter (`None`: undefined).
    pub se_u: Option<f64>,
}

/// Profile interval of `pp.id`; `rss0` and `s2` are the optimum's residual sum of squares
/// and variance.
pub fn interval(pp: &ProfileProblem, rss0: f64, s2: f64, resolve: &mut Resolve) -> Interval {
    let u0 = pp.u[pp.j];
    let id = pp.id;
    let se_step = pp
        .se_u
        .filter(|s| s.is_finite() && *s > 0.0)
        .map_or(MAX_STEP_U, |s| s.min(MAX_STEP_U));
    let clamp = reparam::U_MAX;
    let others = |u: &DVector<f64>| {
        DVector::from_iterator(
            u.len() - 1,
            u.iter()
                .enumerate()
                .filter(|&(k, _)| k != pp.j)
                .map(|(_, &v)| v),
        )
    };
    let mut refits = 0;
    let mut lowest: Option<(f64, f64, DVector<f64>)> = None;
    let mut probe = |uj: f64, start: &DVector<f64>, refits: &mut usize| {
        let (rss, sol) = resolve(uj, start);
        *refits += 1;
        let d = (rss - rss0) / s2;
        if !lowest.as_ref().is_some_and(|(dl, _, _)| d >= *dl) {
            // The full free coordinates of this re-solve: `uj` back at position `j`.
            let mut full = Vec::with_capacity(sol.len() + 1);
            full.extend(sol.iter().take(pp.j));
            full.push(uj);
            full.extend(sol.iter().skip(pp.j));
            lowest = Some((d, reparam::to_value(id, uj), DVector::from_vec(full)));
        }
        (d, sol)
    };
    let mut side = |dir: f64| -> End {
        let on_bound = reparam::at_bound(id, u0);
        if on_bound && dir * u0 > 0.0 {
            // Toward the bound it already sits on.
            return End::Bound(reparam::to_value(id, u0));
        }
        let (base, step) = if on_bound {
            reparam::interior_edge(id, u0)
        } else {
            (u0, se_step)
        };
        // The bracket's inner end: `(u, Delta, solution)`, from the fit itself.
        let mut inner = (u0, 0.0f64, others(&pp.u));
        let offsets = if on_bound { &[0.0][..] } else { &[][..] };
        for &c in offsets.iter().chain(&steps(step)) {
            let uj = (base + dir * c * step).clamp(-clamp, clamp);
            if uj == inner.0 {
                return End::Bound(reparam::to_value(id, uj));
            }
            let (d, sol) = probe(uj, &inner.2, &mut refits);
            if d >= 1.0 {
                return End::Crossing(narrow(
                    inner,
                    (uj, d, sol),
                    &mut |u, s| probe(u, s, &mut refits),
                    id,
                ));
            }
            // Into the region where the value sits on its bound (the map's clamp, an
            // exp-map coefficient below 1e-4) without crossing: the side ends there.
            if uj.abs() >= clamp || (reparam::at_bound(id, uj) && dir * uj > 0.0) {
                return End::Bound(reparam::to_value(id, dir * clamp));
            }
            inner = (uj, d, sol);
        }
        End::Beyond(reparam::to_value(id, inner.0))
    };
    let lo_dir = side(-1.0);
    let hi_dir = side(1.0);
    // Only a drop above the RSS's rounding counts (noise-free data have s^2 ~ 0, where any
    // rounding is many s^2).
    let better = lowest.filter(|(d, _, _)| *d < LOWER_COST && -d * s2 > RSS_ROUNDING * rss0);
    // `u` increases with the value on every map, so the -u side is the lower end.
    Interval {
        id,
        at: reparam::to_value(id, u0),
        lo: lo_dir,
        hi: hi_dir,
        lowest: better.as_ref().map(|(d, x, _)| (*d, *x)),
        better: better.map(|(_, _, u)| u),
        refits,
    }
}

/// The value where `Delta = 1` between `inner` (`Delta < 1`) and `outer` (`>= 1`), each
/// `(u, Delta, solution)`: regula falsi in `sqrt(Delta)` (exact for a quadratic valley),
/// a bisection when a step would land within a tenth of the bracket of one end, at most
/// [`REFINE`] probes, ending once `|Delta - 1| <= CROSS_TOL`.
fn narrow(
    mut inner: (f64, f64, DVector<f64>),
    mut outer: (f64, f64, DVector<f64>),
    probe: &mut Resolve,
    id: Param,
) -> f64 {
    let guess = |a: &(f64, f64, DVector<f64>), b: &(f64, f64, DVector<f64>)| {
        let t = fraction(a.1, b.1);
        let t = if (0.1..=0.9).contains(&t) { t } else { 0.5 };
        a.0 + t * (b.0 - a.0)
    };
    for _ in 0..REFINE {
        if (inner.1 - 1.0).abs() <= CROSS_TOL {
            return reparam::to_value(id, inner.0);
        }
        if (outer.1 - 1.0).abs() <= CROSS_TOL {
            return reparam::to_value(id, outer.0);
        }
        let um = guess(&inner, &outer);
        let (d, sol) = probe(um, &inner.2);
        if (d - 1.0).abs() <= CROSS_TOL {
            return reparam::to_value(id, um);
        }
        if d < 1.0 {
            inner = (um, d, sol);
        } else {
            outer = (um, d, sol);
        }
    }
    // Out of probes: the interpolation between the last bracket (no bisection fallback).
    let t = fraction(inner.1, outer.1);
    reparam::to_value(id, inner.0 + t * (outer.0 - inner.0))
}

/// Where between two probes with `Delta` `a < 1 <= b` the crossing lies (0 at `a`, 1 at
/// `b`): linear in `sqrt(Delta)` near a quadratic valley's floor (`a >= 0.1`), linear in
/// `ln Delta` when `a` is orders of magnitude below 1 (a wall: `Delta` growing
/// exponentially across the bracket), else linear in `sqrt(Delta)` from 0.
fn fraction(a: f64, b: f64) -> f64 {
    let t = if (1e-12..0.1).contains(&a) {
        -a.ln() / (b / a).ln()
    } else {
        let (sa, sb) = (a.max(0.0).sqrt(), b.sqrt());
        if sb > sa {
            (1.0 - sa) / (sb - sa)
        } else {
            0.5
        }
    };
    if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.5
    }
}

/// Profile intervals of `ids` (free parameters of `full`) at the fitted coordinates `u`
/// with residuals `r` and linearised uncertainty `unc`; `refit` re-solves a problem with
/// one more parameter fixed from a start, returning the solution and its RSS; `say`
/// hears which parameter is being profiled (each costs several re-solves).
pub fn intervals(
    full: &LogResidualProblem,
    u: &DVector<f64>,
    r: &DVector<f64>,
    unc: &Uncertainty,
    ids: &[Param],
    refit: &mut Refit,
    say: &dyn Fn(&str),
) -> Vec<Interval> {
    let free = full.layout.free();
    let rss0 = r.norm_squared();
    let s2 = residual_variance(r, free.len());
    let mut out = Vec::new();
    let todo: Vec<Param> = ids.iter().copied().filter(|id| free.contains(id)).collect();
    for (k, &id) in todo.iter().enumerate() {
        let Some(j) = free.iter().position(|&f| f == id) else {
            continue;
        };
        say(&format!(
            "profile likelihood: {} ({} of {})",
            id.spec().name,
            k + 1,
            todo.len()
        ));
        let se_u = unc.se[id.index()]
            .map(|se| se / reparam::derivative(id, u[j]).abs())
            .filter(|s| s.is_finite());
        let pp = ProfileProblem {
            id,
            j,
            u: u.clone(),
            se_u,
        };
        let mut resolve = |uj: f64, start: &DVector<f64>| {
            let mut layout = full.layout.clone();
            layout.fixed[id.index()] = Some(reparam::to_value(id, uj));
            let sub = LogResidualProblem::new(full.data, layout, full.far)
                .with_cancel(full.cancel.clone());
            if start.is_empty() {
                // Nothing left to re-solve.
                return (sub.residuals(&[]).norm_squared(), start.clone());
            }
            let (sol, rss) = refit(&sub, start.clone());
            // A partner on its bound cannot leave it in the re-solve (its map's derivative
            // has all but vanished there), yet with this parameter moved the data may
            // favour an interior value (two absorptions trading off against each other):
            // re-solve also from the partners' interior edge and keep the better.
            let lifted = lift_off_bounds(&sub.layout.free(), start);
            if lifted == *start {
                return (rss, sol);
            }
            let (sol2, rss2) = refit(&sub, lifted);
            if rss2 < rss {
                (rss2, sol2)
            } else {
                (rss, sol)
            }
        };
        out.push(interval(&pp, rss0, s2, &mut resolve));
    }
    out
}

/// `u` with every coordinate on its bound ([`reparam::at_bound`]) moved to the map's
/// interior edge on that side ([`reparam::interior_edge`]), where a solver can move it.
fn lift_off_bounds(free: &[Param], u: &DVector<f64>) -> DVector<f64> {
    DVector::from_iterator(
        u.len(),
        free.iter().zip(u.iter()).map(|(&id, &v)| {
            if reparam::at_bound(id, v) {
                reparam::interior_edge(id, v).0
            } else {
                v
            }
        }),
    )
}

/// One line for the terminal: `eta 1.6012 in [1.5870, 1.6130] (profile, 68 %; 6 re-solves)`,
/// an end at a bound or short of a crossing marked as such.
pub fn describe(iv: &Interval) -> String {
    // Four decimals hid small ends ("beyond 0.0000"): small and huge values in
    // scientific notation.
    let num = |v: f64| {
        if v == 0.0 || (1e-2..1e4).contains(&v.abs()) {
            format!("{v:.4}")
        } else {
            format!("{v:.3e}")
        }
    };
    let end = |e: End| match e {
        End::Crossing(v) => num(v),
        End::Bound(v) => format!("{} (bound)", num(v)),
        End::Beyond(v) => format!("beyond {}", num(v)),
    };
    let mut s = format!(
        "profile {}: {} in [{}, {}] (68 %, {} re-solves)",
        iv.id.spec().name,
        num(iv.at),
        end(iv.lo),
        end(iv.hi),
        iv.refits
    );
    if let Some((d, x)) = iv.lowest {
        s.push_str(&format!(
            "; a re-solve at {} fits better (Delta RSS = {d:.2} s^2): the optimum is not settled along it (refit with --init from there)",
            num(x)
        ));
    }
    s
}

/// The fit file's `uncertainty.profile` object: per parameter its ends and how each ended.
pub fn to_json(ivs: &[Interval], time_s: f64) -> serde_json::Value {
    use serde_json::json;
    let mut per = serde_json::Map::new();
    for iv in ivs {
        per.insert(
            iv.id.spec().name.into(),
            json!({
                "at": iv.at,
                "lo": iv.lo.value(),
                "lo_end": iv.lo.kind(),
                "hi": iv.hi.value(),
                "hi_end": iv.hi.kind(),
                "refits": iv.refits,
                "better_fit": iv.lowest.map(|(d, x)| json!({"delta": d, "at": x})),
            }),
        );
    }
    json!({
        "method": "profile likelihood: the parameter held at values stepped by 1, 2, 4, 8 linearised standard errors (of its solver coordinate) on each side, the others and the exposure re-solved; an end is where (RSS - RSS_min) / s^2 crosses 1 (interpolated in its square root), `bound` where the value reached its bound first, `beyond` where it had not crossed at the last step",
        "params": per,
        "time_s": time_s,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::ParamId;

    /// The fur model's parameter `id`.
    #[allow(non_snake_case)]
    fn P(id: ParamId) -> Param {
        id.into()
    }

    /// A quadratic valley `RSS(u_j) = rss0 + s2 ((u_j - u0) / se)^2` (the others
    /// irrelevant): the profile crosses 1 at exactly `u0 ± se`, which the `sqrt(Delta)`
    /// regula falsi recovers in one probe.
    #[test]
    fn quadratic_valley_crosses_at_one_standard_error() {
        let (u0, se, rss0, s2) = (0.3, 0.25, 10.0, 0.01);
        let pp = ProfileProblem {
            id: P(ParamId::Eta),
            j: 0,
            u: DVector::from_vec(vec![u0, 1.0]),
            se_u: Some(0.6 * se),
        };
        let mut resolve =
            |uj: f64, start: &DVector<f64>| (rss0 + s2 * ((uj - u0) / se).powi(2), start.clone());
        let iv = interval(&pp, rss0, s2, &mut resolve);
        let eta = |u: f64| reparam::to_value(P(ParamId::Eta), u);
        // Exact in u up to rounding (1e-12 of the value).
        assert!((iv.lo.value() - eta(u0 - se)).abs() < 1e-12, "{iv:?}");
        assert!((iv.hi.value() - eta(u0 + se)).abs() < 1e-12, "{iv:?}");
        assert_eq!((iv.lo.kind(), iv.hi.kind()), ("crossing", "crossing"));
        // Per side: 0.6 se (Delta 0.36), 1.2 se (1.44), then the crossing itself.
        assert_eq!(iv.refits, 6);
        assert!(iv.lowest.is_none());
    }

    /// A valley far from quadratic: flat, then a wall (an absorption the data barely see
    /// until it darkens everything). The linearised SE(u) of 24 must not put the end next
    /// to the fit (the first probe lands beyond the wall; interpolating from there gave an
    /// end 4 % above the fit): narrowing finds `Delta = 1` within CROSS_TOL.
    #[test]
    fn wall_is_found_by_narrowing_not_by_one_interpolation() {
        let (u0, rss0, s2) = (-3.5, 1.0, 1.0);
        let wall = -1.0; // Delta = exp(8 (u - wall)): 1 at the wall, 0.0004 at u0 + 1.
        let pp = ProfileProblem {
            id: P(ParamId::SigmaCA),
            j: 0,
            u: DVector::from_vec(vec![u0]),
            se_u: Some(24.0),
        };
        let mut resolve =
            |uj: f64, s: &DVector<f64>| (rss0 + s2 * (8.0 * (uj - wall)).exp(), s.clone());
        let iv = interval(&pp, rss0, s2, &mut resolve);
        let End::Crossing(hi) = iv.hi else {
            panic!("{iv:?}")
        };
        // Delta within CROSS_TOL of 1: u within ln(1.1) / 8 of the wall.
        assert!(
            (hi.ln() - wall).abs() <= 1.1f64.ln() / 8.0 + 1e-12,
            "{iv:?}"
        );
        assert!(
            iv.refits <= 2 * (steps(MAX_STEP_U).len() + REFINE),
            "{iv:?}"
        );
    }

    /// A coefficient fitted onto its bound 0 (exp map, u = -30): the lower end is the
    /// bound, and the upper side starts at the map's interior edge (1e-4) and steps by
    /// decades to the crossing, instead of creeping up from 1e-13.
    #[test]
    fn parameter_on_its_bound_gets_a_one_sided_interval() {
        let (rss0, s2) = (5.0, 0.1);
        let pp = ProfileProblem {
            id: P(ParamId::SigmaMA),
            j: 0,
            u: DVector::from_vec(vec![-reparam::U_MAX]),
            se_u: None,
        };
        // Delta = (x / 0.3)^2 in the value x: the end at 0.3.
        let mut resolve = |uj: f64, s: &DVector<f64>| {
            let x = reparam::to_value(P(ParamId::SigmaMA), uj);
            (rss0 + s2 * (x / 0.3).powi(2), s.clone())
        };
        let iv = interval(&pp, rss0, s2, &mut resolve);
        assert_eq!(iv.lo.kind(), "bound", "{iv:?}");
        assert!(iv.lo.value() < 1e-12, "{iv:?}");
        let End::Crossing(hi) = iv.hi else {
            panic!("{iv:?}")
        };
        // Delta within CROSS_TOL of 1: x within 5 % of 0.3.
        assert!((hi / 0.3 - 1.0).abs() <= 0.05, "{iv:?}");
    }

    /// A valley that flattens toward the lower bound (the value near it, not on it): the
    /// lower side ends at the bound, the upper one crosses.
    #[test]
    fn flat_side_ends_at_the_bound() {
        let (u0, rss0, s2) = (-6.0, 5.0, 0.1);
        let pp = ProfileProblem {
            id: P(ParamId::SigmaMA),
            j: 0,
            u: DVector::from_vec(vec![u0]),
            se_u: Some(2.0),
        };
        let mut resolve = |uj: f64, s: &DVector<f64>| {
            // Flat below u0, steep above.
            let d = (uj - u0).max(0.0);
            (rss0 + s2 * d * d, s.clone())
        };
        let iv = interval(&pp, rss0, s2, &mut resolve);
        assert_eq!(iv.lo.kind(), "bound", "{iv:?}");
        assert!(iv.lo.value() < 1e-12, "{iv:?}");
        assert_eq!(iv.hi.kind(), "crossing");
        assert!((iv.hi.value() - (u0 + 1.0).exp()).abs() < 1e-12 * (u0 + 1.0).exp());
    }

    /// A re-solve that beats the optimum is reported, and a valley too flat to cross within
    /// the steps reports how far it went (an exp map upward), or ends at the bound
    /// (downward, into coefficients below 1e-4).
    #[test]
    fn lower_cost_and_flat_valley_are_reported() {
        let (u0, rss0, s2) = (0.0, 1.0, 1.0);
        let id = P(ParamId::SigmaMS);
        let pp = ProfileProblem {
            id,
            j: 0,
            u: DVector::from_vec(vec![u0]),
            se_u: None,
        };
        let mut resolve = |uj: f64, s: &DVector<f64>| {
            // A dip of 0.5 at u = -1, otherwise Delta = 0.001 u^2 (crosses at |u| = 31.6,
            // beyond the last step, 16).
            let dip = if (uj + 1.0).abs() < 1e-12 { -0.5 } else { 0.0 };
            (rss0 + s2 * (0.001 * uj * uj + dip), s.clone())
        };
        let iv = interval(&pp, rss0, s2, &mut resolve);
        let (d, x) = iv.lowest.expect("the dip");
        assert!((d - (-0.499)).abs() < 1e-12 && (x - reparam::to_value(id, -1.0)).abs() < 1e-12);
        assert_eq!(iv.hi, End::Beyond(reparam::to_value(id, 16.0)));
        // Steps -1, -2, -4, -8, -16: -16 is below ln(1e-4).
        assert_eq!(iv.lo, End::Bound(reparam::to_value(id, -reparam::U_MAX)));
    }

    /// A linearised SE far smaller than the valley (held by a partner on its bound): the
    /// profile keeps doubling past 16 steps and finds the crossing at u0 - 0.5, which
    /// 16 x 0.01 would never reach.
    #[test]
    fn a_tight_standard_error_still_walks_to_the_crossing() {
        let (u0, rss0, s2) = (-1.0, 1.0, 1.0);
        let id = P(ParamId::SigmaMA);
        let pp = ProfileProblem {
            id,
            j: 0,
            u: DVector::from_vec(vec![u0]),
            se_u: Some(0.01),
        };
        let mut resolve =
            |uj: f64, s: &DVector<f64>| (rss0 + s2 * ((uj - u0) / 0.5).powi(2), s.clone());
        let iv = interval(&pp, rss0, s2, &mut resolve);
        assert_eq!(
            (iv.lo.kind(), iv.hi.kind()),
            ("crossing", "crossing"),
            "{iv:?}"
        );
        // The narrowing ends within CROSS_TOL of Delta = 1, i.e. within ~5 % of 0.5 in u.
        let lo = iv.lo.value().ln();
        assert!((lo - (u0 - 0.5)).abs() < 0.03, "{lo} {iv:?}");
        assert_eq!(steps(1.0), STEPS.to_vec());
        assert_eq!(*steps(0.01).last().unwrap(), 1024.0);
    }
}
