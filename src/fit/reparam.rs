//! Smooth, bound-respecting reparameterisation of a model's parameters.
//!
//! The solver works on unbounded coordinates `u`; each parameter (in FILE units: degrees
//! for angles) is a smooth monotone function of its `u` ([`Map`], chosen by the model,
//! [`crate::models::FiberModel::map`]; the fur model's table is at
//! [`crate::models::yan2017::Yan2017`]) that can only produce values inside its hard bounds.
//!
//! `u` is clamped to [-`U_MAX`, `U_MAX`] before mapping so that floating-point rounding can
//! never land exactly on an open bound (e.g. `sigmoid(40) == 1.0` in f64 would give
//! `kappa = 1`). Bound-pushing data drives `u` to the clamp; the reported value then sits
//! within ~1e-13 (relative) of the bound but inside it.

pub use crate::models::yan2017::BETA_N_FLOOR;
use crate::models::{Map, Param};
pub use crate::models::{U_MAX, U_MAX_TANH};

/// Value (file units) of parameter `id` at unbounded coordinate `u`.
pub fn to_value(id: Param, u: f64) -> f64 {
    id.map().to_value(u)
}

/// Does `u ± se_u` span most of the parameter's range? Bounded maps: the values at the two
/// ends are more than half the range apart; `exp` maps (no upper end): a factor above
/// `e^4` between them (`se_u > 2`). Judged on the values, not on `se_u` alone: near a
/// bound a sigmoid's `u` is stretched, and `l = 9.97` with `SE(u) = 2.3` spans 8 % of
/// (0, 10], not most of it.
pub fn spans_most(id: Param, u: f64, se_u: f64) -> bool {
    if !se_u.is_finite() {
        return true;
    }
    match id.map() {
        Map::Exp => se_u > 2.0,
        _ => {
            let (lo, hi) = (to_value(id, -U_MAX), to_value(id, U_MAX));
            to_value(id, u + se_u) - to_value(id, u - se_u) > 0.5 * (hi - lo)
        }
    }
}

/// `d value / d u` at `u` (file units per unit of `u`); 0 beyond the clamp.
pub fn derivative(id: Param, u: f64) -> f64 {
    id.map().derivative(u)
}

/// Unbounded coordinate of a file-unit value. Values on or beyond a bound (possible for a
/// user's `--init`, e.g. `sigma_m_a = 0`) map to the clamp `±U_MAX`.
pub fn to_u(id: Param, v: f64) -> f64 {
    id.map().to_u(v)
}

/// `|u|` of a start point on a bounded (sigmoid, tanh) map: `sigmoid(7)` = 1 - 9e-4, where
/// `d value / d u` is still 9e-4 of the span. A start at the clamp `U_MAX` (a preset's 0,
/// a `--init` beyond the fitter's g range, a value pinned at a bound by an earlier fit)
/// has a derivative of ~1e-13 there and the solver could never move it.
pub const U_START_MAX: f64 = 7.0;

/// `exp` maps: values below this (per radius: an absorption or scattering coefficient
/// no fiber shows) count as on the bound 0 ([`at_bound`]).
pub const EXP_AT_BOUND: f64 = 1e-4;

/// Is coordinate `u` of `id` on its bound, where the map's derivative has all but vanished
/// and the solver cannot move it back? Bounded maps: `|u| > U_START_MAX` (the derivative
/// below ~1e-3 of the span); `exp` maps: a value below [`EXP_AT_BOUND`].
pub fn at_bound(id: Param, u: f64) -> bool {
    match id.map() {
        Map::Exp => u < EXP_AT_BOUND.ln(),
        _ => u.abs() > U_START_MAX,
    }
}

/// Where a profile leaves a bound that `u` sits on ([`at_bound`]), and its step: bounded
/// maps from `U_START_MAX` (on `u`'s side) by 1; `exp` maps from [`EXP_AT_BOUND`] by a
/// decade (a coefficient the data cannot see, up through the values they can).
pub fn interior_edge(id: Param, u: f64) -> (f64, f64) {
    match id.map() {
        Map::Exp => (EXP_AT_BOUND.ln(), std::f64::consts::LN_10),
        _ => (U_START_MAX.copysign(u), 1.0),
    }
}

/// [`to_u`] for a start point: on bounded maps limited to `|u| <= U_START_MAX`.
pub fn to_u_start(id: Param, v: f64) -> f64 {
    let u = to_u(id, v);
    match id.map() {
        Map::Exp => u,
        _ => u.clamp(-U_START_MAX, U_START_MAX),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::ParamId as Fur;

    /// The fur model's parameter `id`.
    #[allow(non_snake_case)]
    fn P(id: Fur) -> Param {
        id.into()
    }

    /// "Spans most of its range" is judged on values: `l = 9.97` with a wide `SE(u)` (its
    /// sigmoid stretched near the bound 10) spans a few per cent, while the same `SE(u)`
    /// at mid-range spans most of it; exp maps keep the factor rule.
    #[test]
    fn spans_most_is_judged_on_values() {
        let u_edge = to_u(P(Fur::L), 9.97);
        assert!(!spans_most(P(Fur::L), u_edge, 2.3));
        assert!(spans_most(P(Fur::L), to_u(P(Fur::L), 5.0), 2.3));
        assert!(!spans_most(P(Fur::L), to_u(P(Fur::L), 5.0), 0.3));
        assert!(spans_most(P(Fur::SigmaMA), 0.0, 2.1));
        assert!(!spans_most(P(Fur::SigmaMA), 0.0, 1.9));
        assert!(spans_most(P(Fur::Eta), 0.0, f64::INFINITY));
    }

    #[test]
    fn round_trip_and_derivative() {
        let vals = [1.55, 0.4, -3.0, 9.0, 12.0, 0.3, 2.0, 0.05, 0.2, 1.5];
        for (id, v) in Fur::ALL.into_iter().map(P).zip(vals) {
            let u = to_u(id, v);
            // Smooth maps inverted in closed form: agreement to float rounding (1e-12 rel).
            assert!(
                (to_value(id, u) - v).abs() < 1e-12 * v.abs().max(1.0),
                "{id:?}"
            );
            let e = 1e-6;
            let fd = (to_value(id, u + e) - to_value(id, u - e)) / (2.0 * e);
            // Central difference with step 1e-6: truncation ~1e-12, rounding ~1e-10 rel.
            assert!(
                (fd - derivative(id, u)).abs() < 1e-7 * derivative(id, u).abs().max(1.0),
                "{id:?}"
            );
        }
    }

    #[test]
    fn values_beyond_a_range_map_to_its_clamp() {
        // A user's --init may lie outside the fitter's range (g = 0.97 beyond the tables,
        // eta = 3 on its bound): the start is the nearest end, not the middle.
        assert_eq!(to_u(P(Fur::G), 0.97), U_MAX);
        assert_eq!(to_u(P(Fur::G), -0.99), -U_MAX);
        assert_eq!(to_u(P(Fur::Eta), 3.0), U_MAX);
        assert!(to_value(P(Fur::G), U_MAX) > 0.949);
        // As a start, the same values sit where the solver can still move them.
        let u = to_u_start(P(Fur::G), 0.97);
        assert_eq!(u, U_START_MAX);
        assert!(derivative(P(Fur::G), u) > 1e-3);
        assert_eq!(to_u_start(P(Fur::SigmaCA), 2000.0), 2000f64.ln());
    }

    #[test]
    fn beta_n_stays_above_its_floor() {
        assert!(to_value(P(Fur::BetaN), -U_MAX) >= BETA_N_FLOOR);
        assert!(to_value(P(Fur::BetaN), -U_MAX) < 1.0001 * BETA_N_FLOOR);
        // A start or --init below the floor maps to the clamp, not to NaN.
        assert_eq!(to_u(P(Fur::BetaN), 0.0), -U_MAX);
        assert_eq!(to_u(P(Fur::BetaN), 1e-6), -U_MAX);
    }

    #[test]
    fn extreme_u_stays_inside_hard_bounds() {
        for id in Fur::ALL.map(P) {
            for u in [-1e9, -U_MAX, -40.0, 0.0, 40.0, U_MAX, 1e9] {
                let v = to_value(id, u);
                assert!(id.spec().contains(v), "{id:?} u={u} -> {v}");
            }
        }
    }
}
