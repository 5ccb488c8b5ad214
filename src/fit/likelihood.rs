//! Profile-likelihood intervals: for one parameter, the values at which the best fit with
//! that parameter held fixed (every other free parameter and the exposure re-solved)
//! costs `s^2` more than the optimum, `(RSS(x) - RSS*) / s^2 = 1` (one parameter, 68 %
//! for Gaussian errors). Unlike the linearised standard error ([`super::uncertainty`]) it
//! follows a curved or bounded valley: a parameter pinned near a bound gets a one-sided
//! interval that ends at the bound, not a symmetric `±SE` that crosses it.
//!
//! Each side steps the parameter's unbounded coordinate `u` by `c * SE(u)`,
//! `c = 1, 2, 4, 8` ([`STEPS`]; `SE(u) = 1` when the linearised one is undefined),
//! re-solving the others from the previous point (warm start), until `Delta >= 1`; the
//! crossing is interpolated in `sqrt(Delta)`, which is linear in the step for a quadratic
//! valley. A side whose `u` reaches the map's clamp (`reparam::U_MAX`: the value sits at
//! its bound) without crossing ends at the bound; one still below 1 after the last step
//! reports how far it got. A re-solve cheaper than the optimum (`Delta < -0.1`) means the
//! fit stopped short of the valley's floor; the interval says so.

use super::problem::LogResidualProblem;
use super::reparam;
use super::uncertainty::{residual_variance, Uncertainty};
use crate::params::ParamId;
use nalgebra::DVector;

/// Multiples of `SE(u)` tried on each side.
pub const STEPS: [f64; 4] = [1.0, 2.0, 4.0, 8.0];

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
    pub fn value(self) -> f64 {
        match self {
            End::Crossing(v) | End::Bound(v) | End::Beyond(v) => v,
        }
    }

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
    pub id: ParamId,
    /// The fitted value (file units).
    pub at: f64,
    /// Lower and upper end (file units).
    pub lo: End,
    pub hi: End,
    /// The lowest `Delta` met (negative: a better fit exists with `id` moved) and where.
    pub lowest: Option<(f64, f64)>,
    /// Re-solves spent.
    pub refits: usize,
}

/// A re-solve with the parameter's coordinate fixed at a `u`, from a start for the other
/// free coordinates: `(RSS, their solution)`.
pub type Resolve<'r> = dyn FnMut(f64, &DVector<f64>) -> (f64, DVector<f64>) + 'r;

/// What the profile of one parameter needs to know about the fit.
pub struct ProfileProblem {
    pub id: ParamId,
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
    let step = pp.se_u.filter(|s| s.is_finite() && *s > 0.0).unwrap_or(1.0);
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
    let mut lowest: Option<(f64, f64)> = None;
    let mut side = |dir: f64| -> End {
        let mut start = others(&pp.u);
        let (mut c_prev, mut d_prev) = (0.0f64, 0.0f64);
        let mut last_u = u0;
        for &c in &STEPS {
            let uj = (u0 + dir * c * step).clamp(-clamp, clamp);
            // At the clamp the value sits on its bound (within ~1e-13): a step that cannot
            // move further ends the side there.
            let at_clamp = uj.abs() >= clamp;
            if uj == last_u {
                return End::Bound(reparam::to_value(pp.id, uj));
            }
            let (rss, sol) = resolve(uj, &start);
            refits += 1;
            let d = (rss - rss0) / s2;
            let x = reparam::to_value(pp.id, uj);
            if !lowest.is_some_and(|(dl, _)| d >= dl) {
                lowest = Some((d, x));
            }
            let c_eff = (uj - u0).abs() / step;
            if d >= 1.0 {
                let (a, b) = (d_prev.max(0.0).sqrt(), d.sqrt());
                let t = if b > a { (1.0 - a) / (b - a) } else { 1.0 };
                let c_x = c_prev + t.clamp(0.0, 1.0) * (c_eff - c_prev);
                return End::Crossing(reparam::to_value(pp.id, u0 + dir * c_x * step));
            }
            if at_clamp {
                return End::Bound(x);
            }
            start = sol;
            (c_prev, d_prev, last_u) = (c_eff, d, uj);
        }
        End::Beyond(reparam::to_value(pp.id, last_u))
    };
    let lo_dir = side(-1.0);
    let hi_dir = side(1.0);
    // `u` increases with the value on every map, so the -u side is the lower end.
    Interval {
        id: pp.id,
        at: reparam::to_value(pp.id, u0),
        lo: lo_dir,
        hi: hi_dir,
        // Only a drop above the RSS's rounding counts (noise-free data have s^2 ~ 0, where
        // any rounding is many s^2).
        lowest: lowest.filter(|&(d, _)| d < LOWER_COST && -d * s2 > RSS_ROUNDING * rss0),
        refits,
    }
}

/// Profile intervals of `ids` (free parameters of `full`) at the fitted coordinates `u`
/// with residuals `r` and linearised uncertainty `unc`; `refit` re-solves a problem with
/// one more parameter fixed.
pub fn intervals(
    full: &LogResidualProblem,
    u: &DVector<f64>,
    r: &DVector<f64>,
    unc: &Uncertainty,
    ids: &[ParamId],
    refit: &mut dyn FnMut(&LogResidualProblem, DVector<f64>) -> DVector<f64>,
) -> Vec<Interval> {
    let free = full.layout.free();
    let rss0 = r.norm_squared();
    let s2 = residual_variance(r, free.len());
    let mut out = Vec::new();
    for &id in ids {
        let Some(j) = free.iter().position(|&f| f == id) else {
            continue;
        };
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
            let sub = LogResidualProblem::new(full.data, layout, full.far);
            let sol = if start.is_empty() {
                start.clone()
            } else {
                refit(&sub, start.clone())
            };
            (sub.residuals(sol.as_slice()).norm_squared(), sol)
        };
        out.push(interval(&pp, rss0, s2, &mut resolve));
    }
    out
}

/// One line for the terminal: `eta 1.6012 in [1.5870, 1.6130] (profile, 68 %; 6 re-solves)`,
/// an end at a bound or short of a crossing marked as such.
pub fn describe(iv: &Interval) -> String {
    let end = |e: End| match e {
        End::Crossing(v) => format!("{v:.4}"),
        End::Bound(v) => format!("{v:.4} (bound)"),
        End::Beyond(v) => format!("beyond {v:.4}"),
    };
    let mut s = format!(
        "profile {}: {:.4} in [{}, {}] (68 %, {} re-solves)",
        iv.id.spec().name,
        iv.at,
        end(iv.lo),
        end(iv.hi),
        iv.refits
    );
    if let Some((d, x)) = iv.lowest {
        s.push_str(&format!(
            "; a re-solve at {x:.4} fits better (Delta RSS = {d:.2} s^2): the optimum is not settled along it"
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

    /// A quadratic valley `RSS(u_j) = rss0 + s2 ((u_j - u0) / se)^2` (the others
    /// irrelevant): the profile crosses 1 at exactly `u0 ± se`, which the `sqrt(Delta)`
    /// interpolation recovers exactly.
    #[test]
    fn quadratic_valley_crosses_at_one_standard_error() {
        let (u0, se, rss0, s2) = (0.3, 0.25, 10.0, 0.01);
        let pp = ProfileProblem {
            id: ParamId::Eta,
            j: 0,
            u: DVector::from_vec(vec![u0, 1.0]),
            se_u: Some(0.6 * se),
        };
        let mut calls = 0;
        let mut resolve = |uj: f64, start: &DVector<f64>| {
            calls += 1;
            (rss0 + s2 * ((uj - u0) / se).powi(2), start.clone())
        };
        let iv = interval(&pp, rss0, s2, &mut resolve);
        let eta = |u: f64| reparam::to_value(ParamId::Eta, u);
        // Exact in u up to rounding (1e-12 of the value).
        assert!((iv.lo.value() - eta(u0 - se)).abs() < 1e-12, "{iv:?}");
        assert!((iv.hi.value() - eta(u0 + se)).abs() < 1e-12, "{iv:?}");
        assert_eq!((iv.lo.kind(), iv.hi.kind()), ("crossing", "crossing"));
        // Steps 0.6 se (Delta 0.36) then 1.2 se (1.44) on each side.
        assert_eq!(iv.refits, 4);
        assert!(iv.lowest.is_none());
    }

    /// A valley that flattens toward the lower bound (the value pinned near it): the lower
    /// side ends at the bound, the upper one crosses.
    #[test]
    fn flat_side_ends_at_the_bound() {
        let (u0, rss0, s2) = (-25.0, 5.0, 0.1);
        let pp = ProfileProblem {
            id: ParamId::SigmaMA,
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
    /// the steps reports how far it went.
    #[test]
    fn lower_cost_and_flat_valley_are_reported() {
        let (u0, rss0, s2) = (0.0, 1.0, 1.0);
        let pp = ProfileProblem {
            id: ParamId::L,
            j: 0,
            u: DVector::from_vec(vec![u0]),
            se_u: None,
        };
        let mut resolve = |uj: f64, s: &DVector<f64>| {
            // A dip of 0.5 at u = -1, otherwise Delta = 0.01 u^2 (crosses at |u| = 10).
            let dip = if (uj + 1.0).abs() < 1e-12 { -0.5 } else { 0.0 };
            (rss0 + s2 * (0.01 * uj * uj + dip), s.clone())
        };
        let iv = interval(&pp, rss0, s2, &mut resolve);
        let (d, x) = iv.lowest.expect("the dip");
        assert!(
            (d - (-0.49)).abs() < 1e-12 && (x - reparam::to_value(ParamId::L, -1.0)).abs() < 1e-12
        );
        // Steps 1, 2, 4, 8 (SE(u) undefined: 1): Delta(8) = 0.64 < 1.
        assert_eq!(iv.hi, End::Beyond(reparam::to_value(ParamId::L, 8.0)));
        assert_eq!(iv.lo, End::Beyond(reparam::to_value(ParamId::L, -8.0)));
    }
}
