//! Smooth, bound-respecting reparameterisation of the ten parameters.
//!
//! The solver works on unbounded coordinates `u`; each parameter (in FILE units: degrees
//! for angles) is a smooth monotone function of its `u` that can only produce values inside
//! MODEL.md's hard bounds:
//!
//! | parameter | map | range |
//! |---|---|---|
//! | `eta` | `1 + 2 sigmoid(u)` | (1, 3) |
//! | `kappa` | `sigmoid(u)` | (0, 1) (exactly 0 only through `--fix kappa=0`) |
//! | `alpha` | `20 tanh(u)` deg | (-20, 20) |
//! | `beta_m` | `60 sigmoid(u)` deg | (0, 60) |
//! | `beta_n` | `1e-4 + (90 - 1e-4) sigmoid(u)` deg | (1e-4, 90): [`BETA_N_FLOOR`] |
//! | `sigma_c_a`, `sigma_m_s`, `sigma_m_a` | `exp(u)` | (0, inf) |
//! | `g` | `g0 + (g1 - g0) sigmoid(u)` | (-0.9, 0.95): the medulla tables' g range `[g0, g1]`, inside MODEL.md's (-1, 1); beyond it the model is flat in `g` |
//! | `l` | `10 sigmoid(u)` | (0, 10) |
//!
//! `u` is clamped to [-`U_MAX`, `U_MAX`] before mapping so that floating-point rounding can
//! never land exactly on an open bound (e.g. `sigmoid(40) == 1.0` in f64 would give
//! `kappa = 1`). Bound-pushing data drives `u` to the clamp; the reported value then sits
//! within ~1e-13 (relative) of the bound but inside it.

use crate::params::ParamId;

/// The fitter's smallest `beta_n` (degrees), inside MODEL.md's (0, 90]. A narrower
/// azimuthal roughness cannot be told apart by any goniometer (a 1e-4 deg lobe is 5e-4
/// of a 0.2 deg detector), while the tolerance-mode far field's refinement around the
/// TRT caustic grows without bound as `beta_n -> 0`: data that pushes `beta_n` to 0 (the
/// shipped cat) made each evaluation ~4x dearer at the old floor of ~1e-11 deg than at
/// 1e-4 deg. A `--fix` below it is kept as given.
pub const BETA_N_FLOOR: f64 = 1e-4;

/// Clamp of the unbounded coordinate for sigmoid and exp maps (sigmoid(30) = 1 - 9.4e-14:
/// representable below 1).
pub const U_MAX: f64 = 30.0;
/// Clamp for tanh maps: tanh(30) rounds to exactly 1.0 in f64, tanh(17) = 1 - 3.4e-15 does not.
pub const U_MAX_TANH: f64 = 17.0;

fn clamp_u(id: ParamId, u: f64) -> f64 {
    let m = match map_of(id) {
        Map::Tanh { .. } => U_MAX_TANH,
        _ => U_MAX,
    };
    u.clamp(-m, m)
}

fn sigmoid(u: f64) -> f64 {
    1.0 / (1.0 + (-u).exp())
}

fn logit(y: f64) -> f64 {
    (y / (1.0 - y)).ln()
}

/// The shape of one parameter's map.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Map {
    /// `lo + span * sigmoid(u)`.
    Sigmoid { lo: f64, span: f64 },
    /// `scale * tanh(u)`.
    Tanh { scale: f64 },
    /// `exp(u)`.
    Exp,
}

fn map_of(id: ParamId) -> Map {
    match id {
        ParamId::Eta => Map::Sigmoid { lo: 1.0, span: 2.0 },
        ParamId::Kappa => Map::Sigmoid { lo: 0.0, span: 1.0 },
        ParamId::Alpha => Map::Tanh { scale: 20.0 },
        ParamId::BetaM => Map::Sigmoid {
            lo: 0.0,
            span: 60.0,
        },
        // Above BETA_N_FLOOR (see there).
        ParamId::BetaN => Map::Sigmoid {
            lo: BETA_N_FLOOR,
            span: 90.0 - BETA_N_FLOOR,
        },
        ParamId::SigmaCA | ParamId::SigmaMS | ParamId::SigmaMA => Map::Exp,
        ParamId::G => {
            // The medulla tables' g range, not MODEL.md's (-1, 1): beyond it the model
            // uses the table edge, so the fit would wander on a flat direction there.
            let (_, [g0, g1]) = crate::model::medulla::MedullaTables::builtin().domain();
            Map::Sigmoid {
                lo: g0,
                span: g1 - g0,
            }
        }
        ParamId::L => Map::Sigmoid {
            lo: 0.0,
            span: 10.0,
        },
    }
}

/// File-unit value of parameter `id` at unbounded coordinate `u`.
pub fn to_value(id: ParamId, u: f64) -> f64 {
    let u = clamp_u(id, u);
    match map_of(id) {
        Map::Sigmoid { lo, span } => lo + span * sigmoid(u),
        Map::Tanh { scale } => scale * u.tanh(),
        Map::Exp => u.exp(),
    }
}

/// Does `u ± se_u` span most of the parameter's range? Bounded maps: the values at the two
/// ends are more than half the range apart; `exp` maps (no upper end): a factor above
/// `e^4` between them (`se_u > 2`). Judged on the values, not on `se_u` alone: near a
/// bound a sigmoid's `u` is stretched, and `l = 9.97` with `SE(u) = 2.3` spans 8 % of
/// (0, 10], not most of it.
pub fn spans_most(id: ParamId, u: f64, se_u: f64) -> bool {
    if !se_u.is_finite() {
        return true;
    }
    match map_of(id) {
        Map::Exp => se_u > 2.0,
        _ => {
            let (lo, hi) = (to_value(id, -U_MAX), to_value(id, U_MAX));
            to_value(id, u + se_u) - to_value(id, u - se_u) > 0.5 * (hi - lo)
        }
    }
}

/// `d value / d u` at `u` (file units per unit of `u`); 0 beyond the clamp.
pub fn derivative(id: ParamId, u: f64) -> f64 {
    if clamp_u(id, u) != u {
        return 0.0;
    }
    match map_of(id) {
        Map::Sigmoid { span, .. } => {
            let s = sigmoid(u);
            span * s * (1.0 - s)
        }
        Map::Tanh { scale } => {
            let t = u.tanh();
            scale * (1.0 - t * t)
        }
        Map::Exp => u.exp(),
    }
}

/// Unbounded coordinate of a file-unit value. Values on or beyond a bound (possible for a
/// user's `--init`, e.g. `sigma_m_a = 0`) map to the clamp `±U_MAX`.
pub fn to_u(id: ParamId, v: f64) -> f64 {
    let u = match map_of(id) {
        // Clamped first: a value beyond the range maps to the clamp, not to NaN (-> 0).
        Map::Sigmoid { lo, span } => logit(((v - lo) / span).clamp(0.0, 1.0)),
        Map::Tanh { scale } => (v / scale).clamp(-1.0, 1.0).atanh(),
        Map::Exp => v.ln(),
    };
    if u.is_nan() {
        0.0
    } else {
        clamp_u(id, u)
    }
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
pub fn at_bound(id: ParamId, u: f64) -> bool {
    match map_of(id) {
        Map::Exp => u < EXP_AT_BOUND.ln(),
        _ => u.abs() > U_START_MAX,
    }
}

/// Where a profile leaves a bound that `u` sits on ([`at_bound`]), and its step: bounded
/// maps from `U_START_MAX` (on `u`'s side) by 1; `exp` maps from [`EXP_AT_BOUND`] by a
/// decade (a coefficient the data cannot see, up through the values they can).
pub fn interior_edge(id: ParamId, u: f64) -> (f64, f64) {
    match map_of(id) {
        Map::Exp => (EXP_AT_BOUND.ln(), std::f64::consts::LN_10),
        _ => (U_START_MAX.copysign(u), 1.0),
    }
}

/// [`to_u`] for a start point: on bounded maps limited to `|u| <= U_START_MAX`.
pub fn to_u_start(id: ParamId, v: f64) -> f64 {
    let u = to_u(id, v);
    match map_of(id) {
        Map::Exp => u,
        _ => u.clamp(-U_START_MAX, U_START_MAX),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// "Spans most of its range" is judged on values: `l = 9.97` with a wide `SE(u)` (its
    /// sigmoid stretched near the bound 10) spans a few per cent, while the same `SE(u)`
    /// at mid-range spans most of it; exp maps keep the factor rule.
    #[test]
    fn spans_most_is_judged_on_values() {
        let u_edge = to_u(ParamId::L, 9.97);
        assert!(!spans_most(ParamId::L, u_edge, 2.3));
        assert!(spans_most(ParamId::L, to_u(ParamId::L, 5.0), 2.3));
        assert!(!spans_most(ParamId::L, to_u(ParamId::L, 5.0), 0.3));
        assert!(spans_most(ParamId::SigmaMA, 0.0, 2.1));
        assert!(!spans_most(ParamId::SigmaMA, 0.0, 1.9));
        assert!(spans_most(ParamId::Eta, 0.0, f64::INFINITY));
    }

    #[test]
    fn round_trip_and_derivative() {
        let vals = [1.55, 0.4, -3.0, 9.0, 12.0, 0.3, 2.0, 0.05, 0.2, 1.5];
        for (id, v) in ParamId::ALL.into_iter().zip(vals) {
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
        assert_eq!(to_u(ParamId::G, 0.97), U_MAX);
        assert_eq!(to_u(ParamId::G, -0.99), -U_MAX);
        assert_eq!(to_u(ParamId::Eta, 3.0), U_MAX);
        assert!(to_value(ParamId::G, U_MAX) > 0.949);
        // As a start, the same values sit where the solver can still move them.
        let u = to_u_start(ParamId::G, 0.97);
        assert_eq!(u, U_START_MAX);
        assert!(derivative(ParamId::G, u) > 1e-3);
        assert_eq!(to_u_start(ParamId::SigmaCA, 2000.0), 2000f64.ln());
    }

    #[test]
    fn beta_n_stays_above_its_floor() {
        assert!(to_value(ParamId::BetaN, -U_MAX) >= BETA_N_FLOOR);
        assert!(to_value(ParamId::BetaN, -U_MAX) < 1.0001 * BETA_N_FLOOR);
        // A start or --init below the floor maps to the clamp, not to NaN.
        assert_eq!(to_u(ParamId::BetaN, 0.0), -U_MAX);
        assert_eq!(to_u(ParamId::BetaN, 1e-6), -U_MAX);
    }

    #[test]
    fn extreme_u_stays_inside_hard_bounds() {
        for id in ParamId::ALL {
            for u in [-1e9, -U_MAX, -40.0, 0.0, 40.0, U_MAX, 1e9] {
                let v = to_value(id, u);
                assert!(id.spec().contains(v), "{id:?} u={u} -> {v}");
            }
        }
    }
}
