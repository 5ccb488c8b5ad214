//! Closed-form segment integrals of the seed Appendix, made robust where they are stiff.
//!
//! * [`poly_gauss`]: `integral_0^X (c0 + c1 x + c2 x^2) exp(l0 + l1 x + l2 x^2) G(x - m; beta)
//!   dx`, a quadratic times the exponential of a quadratic (Appendix "Integrating Q1
//!   exp(Q2)"; the Appendix's log-attenuation is linear, `l2 = 0`, and a curved one folds
//!   into the Gaussian's quadratic exponent while it stays concave),
//!   in erf form after completing the square. `exp(b^2/4a + c)` is never formed on its own:
//!   the erf difference is written with `erfcx` and the exponent's actual endpoint values
//!   (one-sided: a difference of two such terms; peak inside: the peak's mass less two
//!   tails), so nothing overflows; the interval is first cut to where the integrand is
//!   within `e^-40` of its maximum. When the erf form is ill-conditioned (peak far outside
//!   the interval, or the quadratic coefficient vanishing relative to the interval) a
//!   composite Gauss-Legendre rule of the *same* integrand is used, so the result is the
//!   exact integral of the fitted model either way.
//! * [`poly_exp`]: `integral_0^X (c0 + c1 x + c2 x^2) exp(l0 + l x) dx` (Appendix
//!   "Integrating C exp(L)"), closed form for `|l| X >= 1`, Gauss-Legendre below (where the
//!   closed form divides by small powers of `l`).

use crate::model::quadrature::GaussLegendre;
use puruspe::erfcx;
use std::f64::consts::PI;

/// The integrand is dropped where it is below `e^-TRUNC` of its maximum on the interval.
const TRUNC: f64 = 40.0;

/// `e^-TRUNC`.
const E_NEG_TRUNC: f64 = 4.248354255291589e-18;

/// `c0 + c1 x + c2 x^2`.
#[inline]
pub(super) fn poly(c: &[f64; 3], x: f64) -> f64 {
    c[0] + x * (c[1] + x * c[2])
}

/// `integral_0^X (c0 + c1 x + c2 x^2) exp(l0 + l1 x + l2 x^2) G(x - m; beta) dx` with `G`
/// the normalised Gaussian of standard deviation `beta` and `lam = [l0, l1, l2]`. The
/// exponent must stay concave: `l2 <=` [`lam_curve_cap`]`(beta)` (the caller's
/// choice; see there).
pub fn poly_gauss(c: &[f64; 3], lam: &[f64; 3], m: f64, beta: f64, x_len: f64) -> f64 {
    if x_len <= 0.0 {
        return 0.0;
    }
    let [l0, l, l2] = *lam;
    let g = 0.5 / (beta * beta);
    let norm = 1.0 / (beta * (2.0 * PI).sqrt());
    // Exponent Q(x) = l0 + l x + l2 x^2 - g (x - m)^2 = C - a (x - m')^2, a = g - l2.
    let a = g - l2;
    let q = |x: f64| l0 + x * (l + l2 * x) - g * (x - m) * (x - m);
    // Peak m' = (l + 2 g m) / 2a. Linear (l2 = 0): m + l / 2g as the Appendix's form had
    // it. Curved: not as m + (l + 2 l2 m) / 2a, which cancels when l2 << -g (m' -> 0
    // from |m| ~ 9, 1e-15 off against a width 1/sqrt(a) of 4e-4: 3e-12 of the integral).
    let mp = if l2 == 0.0 {
        m + l / (2.0 * a)
    } else {
        (l + 2.0 * g * m) / (2.0 * a)
    };
    let xc = mp.clamp(0.0, x_len);
    let qmax = q(xc);
    // Cut to |x - m'| <= R where Q >= Qmax - TRUNC.
    let r = ((xc - mp) * (xc - mp) + TRUNC / a).sqrt();
    let (x_lo, x_hi) = ((mp - r).max(0.0), (mp + r).min(x_len));
    if x_hi <= x_lo {
        return 0.0;
    }
    let len = x_hi - x_lo;
    let dist = if mp < x_lo {
        x_lo - mp
    } else if mp > x_hi {
        mp - x_hi
    } else {
        0.0
    };
    let sa = a.sqrt();
    if sa * len >= 0.5 && dist <= 3.0 * len {
        // Erf form about the completed square.
        let (s0, s1) = (x_lo - mp, x_hi - mp);
        // The exponential at an end: exp(Qmax) where the end is the clamped peak, and
        // exp(Qmax - TRUNC) where the cut made it (Q = Qmax - TRUNC there, up to rounding
        // of r, which moves a term of e^-40 of the result): one exp, not two or three.
        let ex = qmax.exp();
        let end = |x: f64, cut: bool| {
            if x == xc {
                ex
            } else if cut {
                ex * E_NEG_TRUNC
            } else {
                q(x).exp()
            }
        };
        let (e0, e1) = (end(x_lo, mp - r >= 0.0), end(x_hi, mp + r <= x_len));
        let (y0, y1) = (sa * s0, sa * s1);
        let k = PI.sqrt() / (2.0 * sa);
        let m0 = if y0 >= 0.0 {
            k * (e0 * erfcx(y0) - e1 * erfcx(y1))
        } else if y1 <= 0.0 {
            k * (e1 * erfcx(-y1) - e0 * erfcx(-y0))
        } else {
            // Peak inside: C = Qmax, so exp(C) = ex, and e^C (erf(y1) - erf(y0)) is
            // 2 e^C less the two tails e^C erfc(|y|) = e_end erfcx(|y|) (exp(C - y^2) is
            // the exponential at that end). Two erfcx at ~11 ns, not two erf at ~45 ns
            // (puruspe); no cancellation, as y1 - y0 >= 0.5 keeps erf(y1) - erf(y0) at or
            // above erf(0.5) = 0.52. A tail from |y| >= 6 is below e^C erfc(6) = 2e-17 e^C,
            // under half an ulp of the result: a piece longer than its cut has
            // y = +-sqrt(TRUNC) = +-6.3 at both ends.
            let tail = |y: f64, e: f64| if y >= 6.0 { 0.0 } else { e * erfcx(y) };
            k * (2.0 * ex - tail(y1, e1) - tail(-y0, e0))
        };
        let m1 = (e0 - e1) / (2.0 * a);
        let m2 = (m0 + s0 * e0 - s1 * e1) / (2.0 * a);
        // Polynomial in s = x - m'.
        let d0 = c[0] + mp * (c[1] + mp * c[2]);
        let d1 = c[1] + 2.0 * c[2] * mp;
        let d2 = c[2];
        return norm * (d0 * m0 + d1 * m1 + d2 * m2);
    }
    // Composite Gauss-Legendre on the cut interval: each piece spans at most 3 units of
    // the exponent, where a 10-point rule is exact to ~1e-13 for this integrand. Most calls
    // here are short segments under a wide Gaussian whose exponent varies by well under a
    // unit; a quadratic times exp of that is resolved by far fewer nodes (the rule's error
    // term scales as spread^(2n) / (2n)!; the random test below checks 1e-12).
    let qmin = q(x_lo).min(q(x_hi));
    let spread = qmax - qmin;
    let pieces = (spread / 3.0).ceil().clamp(1.0, 64.0) as usize;
    let nodes = if spread <= 0.05 {
        6
    } else if spread <= 0.3 {
        8
    } else {
        10
    };
    let gl = GaussLegendre::cached(nodes);
    let h = len / pieces as f64;
    let mut s = 0.0;
    for i in 0..pieces {
        let a0 = x_lo + i as f64 * h;
        s += gl.integrate(a0, a0 + h, |x| poly(c, x) * q(x).exp());
    }
    norm * s
}

/// Largest curvature `l2` of the log-attenuation that [`poly_gauss`] and
/// [`poly_gauss_nodes`] take, as a fraction of the Gaussian's `1 / (2 beta^2)`: the combined
/// exponent then keeps at least half the Gaussian's curvature, so its completed square,
/// cut and Gauss-Legendre spread stay those of a Gaussian at most `sqrt 2` wider.
pub const LAM_CURVE_MAX: f64 = 0.5;

/// The largest `l2` [`poly_gauss`] takes under a Gaussian of width `beta`:
/// [`LAM_CURVE_MAX`] of its curvature `1 / (2 beta^2)`.
pub fn lam_curve_cap(beta: f64) -> f64 {
    LAM_CURVE_MAX * 0.5 / (beta * beta)
}

/// Gauss-Legendre nodes of one sub-interval of [`poly_gauss_nodes`].
const NODE_RULE: usize = 8;
/// Longest sub-interval of [`poly_gauss_nodes`], in `beta`. The rule's error grows as
/// span^17: measured worst 4e-14 at 1 `beta`, 1.5e-12 at 2, 1e-9 at 3 (test
/// `nodes_match_the_reference`). Two halve the nodes of 1 for an error still at the 1e-12
/// the closed forms promise; grid synthesis 1.1x faster in tolerance mode, 1.2x in paper
/// mode (cat, mouse, human).
const NODE_SPAN_SIGMAS: f64 = 2.0;
/// Largest change of the log-attenuation over one sub-interval.
const NODE_MAX_SLOPE: f64 = 3.0;
/// Most sub-intervals [`poly_gauss_nodes`] uses; a longer piece keeps the erf form.
pub const NODE_MAX_SUBS: usize = 6;

/// [`poly_gauss`] as fixed nodes, for many `m` at once: appends `(lo + x_k, W_k)` with
/// `integral ~= sum_k W_k G(x_k - m; beta)` for every `m`, where `W_k` folds the
/// quadratic, the exponential and the rule's weight (not the Gaussian's normalisation).
/// An 8-point Gauss-Legendre rule per sub-interval of at most 2 `beta` and at most 3 units
/// of the log-attenuation `lam` integrates the Gaussian times the smooth factor to ~1e-12 of
/// `len * max(density) * G(0)` for any `m` (test `nodes_match_the_reference`), so an evenly
/// spaced grid of `m` can then sweep each node's Gaussian by recurrence instead of calling
/// [`poly_gauss`] per `m`. Returns `false` (nothing appended) when the piece would need
/// more than [`NODE_MAX_SUBS`] sub-intervals.
pub fn poly_gauss_nodes(
    c: &[f64; 3],
    lam: &[f64; 3],
    lo: f64,
    x_len: f64,
    beta: f64,
    out: &mut Vec<(f64, f64)>,
) -> bool {
    if x_len <= 0.0 {
        return true;
    }
    // The exponent's steepest slope on [0, X] (at an end: its derivative is linear).
    let slope = lam[1].abs().max((lam[1] + 2.0 * lam[2] * x_len).abs());
    let subs = (x_len / (NODE_SPAN_SIGMAS * beta))
        .max(slope * x_len / NODE_MAX_SLOPE)
        .ceil()
        .max(1.0);
    if subs.is_nan() || subs > NODE_MAX_SUBS as f64 {
        return false;
    }
    let subs = subs as usize;
    let gl = GaussLegendre::cached(NODE_RULE);
    let h = x_len / subs as f64;
    for i in 0..subs {
        let c0 = (i as f64 + 0.5) * h;
        for (t, w) in gl.nodes.iter().zip(&gl.weights) {
            let x = c0 + 0.5 * h * t;
            out.push((lo + x, 0.5 * h * w * poly(c, x) * poly(lam, x).exp()));
        }
    }
    true
}

/// `integral_0^X (c0 + c1 x + c2 x^2) exp(l0 + l x) dx`.
pub fn poly_exp(c: &[f64; 3], l0: f64, l: f64, x_len: f64) -> f64 {
    if x_len <= 0.0 {
        return 0.0;
    }
    // Cut to where the exponential is within e^-TRUNC of its maximum.
    let (mut x_lo, mut x_hi) = (0.0, x_len);
    if l * x_len > TRUNC {
        x_lo = x_len - TRUNC / l;
    } else if -l * x_len > TRUNC {
        x_hi = TRUNC / -l;
    }
    let len = x_hi - x_lo;
    if (l * len).abs() < 1.0 {
        let gl = GaussLegendre::cached(8);
        return gl.integrate(x_lo, x_hi, |x| poly(c, x) * (l0 + l * x).exp());
    }
    // Antiderivative e^(l0 + l x) [p/l - p'/l^2 + p''/l^3] (Appendix, quadratic C).
    let anti = |x: f64| {
        let p0 = poly(c, x);
        let p1 = c[1] + 2.0 * c[2] * x;
        let p2 = 2.0 * c[2];
        (l0 + l * x).exp() * (p0 / l - p1 / (l * l) + p2 / (l * l * l))
    };
    anti(x_hi) - anti(x_lo)
}

/// Coefficients of the quadratic through `(x_j, y_j)`, j = 0..3, in powers of `x`
/// (Newton divided differences; the `x_j` must be distinct).
pub fn quadratic_through(x: [f64; 3], y: [f64; 3]) -> [f64; 3] {
    let d01 = (y[1] - y[0]) / (x[1] - x[0]);
    let d12 = (y[2] - y[1]) / (x[2] - x[1]);
    let d012 = (d12 - d01) / (x[2] - x[0]);
    // y = y0 + d01 (x - x0) + d012 (x - x0)(x - x1)
    let c2 = d012;
    let c1 = d01 - d012 * (x[0] + x[1]);
    let c0 = y[0] - d01 * x[0] + d012 * x[0] * x[1];
    [c0, c1, c2]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::quadrature::adaptive_gk;

    #[test]
    fn e_neg_trunc_is_exp_of_minus_trunc() {
        assert_eq!(E_NEG_TRUNC, (-TRUNC).exp());
    }

    fn reference_pg(c: &[f64; 3], lam: &[f64; 3], m: f64, beta: f64, x: f64) -> f64 {
        let f = |t: f64| {
            poly(c, t) * (poly(lam, t) - 0.5 * ((t - m) / beta).powi(2)).exp()
                / (beta * (2.0 * PI).sqrt())
        };
        // Breakpoints around the combined exponent's peak, in units of its width.
        let a = 0.5 / (beta * beta) - lam[2];
        let (peak, width) = ((lam[1] + m / (beta * beta)) / (2.0 * a), (0.5 / a).sqrt());
        let mut pts = vec![0.0, x];
        for k in -8..=8 {
            pts.push(peak + k as f64 * width);
        }
        pts.retain(|&t| t >= 0.0 && t <= x);
        pts.sort_by(|a, b| a.partial_cmp(b).unwrap());
        adaptive_gk(f, &pts, 1e-13, 1e-300, 100_000).value
    }

    /// A random log-attenuation `[l0, l1, l2]` on `[0, x]` with slope `l1`: half linear
    /// (the Appendix's form), half curved by up to 30 nats across the piece (a fit of
    /// `ln(T_c T_m) <= 0` through three nodes bends by no more than their spread), convex
    /// ones at most nearly [`LAM_CURVE_MAX`] of the Gaussian's curvature.
    fn random_lam(rng: &mut impl rand::Rng, l1: f64, beta: f64, x: f64) -> [f64; 3] {
        let l0 = rng.random_range(-5.0..0.0);
        let bend = 30.0 / (x * x);
        let l2 = if rng.random_bool(0.5) {
            0.0
        } else if rng.random_bool(0.5) {
            -bend * rng.random_range(0.0..1.0)
        } else {
            bend.min(0.999 * lam_curve_cap(beta)) * rng.random_range(0.0..1.0)
        };
        [l0, l1, l2]
    }

    /// A random quadratic positive on `[0, x]` (fitted densities are), or `None`.
    fn positive_quadratic(rng: &mut impl rand::Rng, x: f64) -> Option<[f64; 3]> {
        let c = [
            rng.random_range(0.1..2.0),
            rng.random_range(-2.0..2.0),
            rng.random_range(-2.0..2.0),
        ];
        (0..=8)
            .all(|k| poly(&c, x * k as f64 / 8.0) > 0.0)
            .then_some(c)
    }

    /// The low-order rules of the Gauss-Legendre branch (short segment under a wide
    /// Gaussian) against the adaptive reference, on random cases of that branch: 1e-12
    /// relative is three orders below the far field's own tolerance, so the saving costs
    /// nothing measurable.
    #[test]
    fn poly_gauss_wide_gaussian_branch_is_accurate() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(11);
        let mut checked = 0;
        while checked < 400 {
            let beta: f64 = rng.random_range(0.05..3.0);
            let x: f64 = rng.random_range(0.001..1.0) * beta;
            let Some(c) = positive_quadratic(&mut rng, x) else {
                continue;
            };
            let l: f64 = rng.random_range(-3.0..3.0) / x.max(0.05);
            let m: f64 = rng.random_range(-2.0..2.0) * beta;
            let lam = random_lam(&mut rng, l, beta, x);
            let v = poly_gauss(&c, &lam, m, beta, x);
            let r = reference_pg(&c, &lam, m, beta, x);
            assert!(
                (v - r).abs() <= 1e-12 * r.abs() + 1e-300,
                "{:?}: {v} vs {r}",
                (c, lam, m, beta, x)
            );
            checked += 1;
        }
    }

    /// Every branch on random cases drawn across the engine's range (narrow and wide
    /// Gaussians, peaks inside and far outside the segment, steep attenuation slopes):
    /// the Gauss-Legendre branch's node counts must keep 1e-12 relative (three orders
    /// below the far field's tolerance) wherever they are used.
    #[test]
    fn poly_gauss_is_accurate_on_random_cases() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(29);
        let mut checked = 0;
        let mut worst: f64 = 0.0;
        while checked < 3000 {
            let beta: f64 = 10f64.powf(rng.random_range(-2.7..0.5));
            let x: f64 = 10f64.powf(rng.random_range(-3.0..0.3));
            let Some(c) = positive_quadratic(&mut rng, x) else {
                continue;
            };
            let l: f64 = rng.random_range(-30.0..30.0);
            let m: f64 = x * rng.random_range(-0.5..1.5) + beta * rng.random_range(-6.0..6.0);
            let lam = random_lam(&mut rng, l, beta, x);
            let v = poly_gauss(&c, &lam, m, beta, x);
            let r = reference_pg(&c, &lam, m, beta, x);
            if r < 1e-290 {
                continue;
            }
            let e = (v - r).abs() / r;
            worst = worst.max(e);
            assert!(e <= 1e-12, "{:?}: {v} vs {r}", (c, lam, m, beta, x));
            checked += 1;
        }
        eprintln!("poly_gauss random cases: worst relative error {worst:.2e}");
    }

    /// The node form against the adaptive reference, on random pieces across the engine's
    /// range (lengths up to the sub-interval limit, steep attenuation slopes, centres inside
    /// and up to 9 beta outside): within 1e-11 of `len * max(density) * G(0)`, the scale
    /// of the piece's contribution to the lobe near its peak (measured worst 1.5e-12 with
    /// sub-intervals of 2 beta, 4.3e-14 with 1 beta; the reference itself is converged to
    /// 1e-13 of its value).
    #[test]
    fn nodes_match_the_reference() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(31);
        let (mut checked, mut worst) = (0, 0.0f64);
        let mut nodes = Vec::new();
        while checked < 1000 {
            let beta: f64 = 10f64.powf(rng.random_range(-2.7..0.5));
            let x: f64 = beta * rng.random_range(0.001..NODE_MAX_SUBS as f64 * NODE_SPAN_SIGMAS);
            let Some(c) = positive_quadratic(&mut rng, x) else {
                continue;
            };
            let l: f64 = rng.random_range(-3.0..3.0) * rng.random_range(0.0..6.0) / x;
            let lam = random_lam(&mut rng, l, beta, x);
            let lo = rng.random_range(-3.0..3.0);
            nodes.clear();
            if !poly_gauss_nodes(&c, &lam, lo, x, beta, &mut nodes) {
                continue;
            }
            let dmax = (0..=64)
                .map(|k| {
                    let t = x * k as f64 / 64.0;
                    poly(&c, t) * poly(&lam, t).exp()
                })
                .fold(0.0f64, f64::max);
            let norm = 1.0 / (beta * (2.0 * PI).sqrt());
            let scale = x * dmax * norm;
            for _ in 0..4 {
                let m = x * rng.random_range(0.0..1.0) + beta * rng.random_range(-9.0..9.0);
                let v: f64 = nodes
                    .iter()
                    .map(|&(p, w)| w * norm * (-0.5 * ((p - lo - m) / beta).powi(2)).exp())
                    .sum();
                let r = reference_pg(&c, &lam, m, beta, x);
                let e = (v - r).abs() / scale;
                worst = worst.max(e);
                assert!(e <= 1e-11, "{:?}: {v} vs {r}", (c, lam, m, beta, x));
            }
            checked += 1;
        }
        eprintln!("poly_gauss_nodes: worst error {worst:.2e} of len * max density * G(0)");
    }

    #[test]
    fn poly_gauss_matches_quadrature_across_regimes() {
        let c = [0.7, -0.4, 0.9];
        // (l0, l, m, beta, X): peak inside, far tail both sides, tiny and huge beta,
        // strong absorption slope, a huge exponent that would overflow exp(b^2/4a + c).
        let cases = [
            (0.0, 0.0, 0.3, 0.2, 1.0),
            (-1.0, -3.0, 0.5, 0.05, 1.0),
            (0.0, 0.0, 2.5, 0.3, 1.0),
            (0.0, 0.0, -1.5, 0.3, 1.0),
            (0.0, 0.0, 0.4, 0.001_745, 1.0),
            (0.0, 0.0, 0.4, 2.7, 1.0),
            (-300.0, -800.0, 0.2, 0.5, 1.0),
            (-5.0, 400.0, 0.5, 0.3, 1.0),
            (0.0, 0.0, 0.5, 100.0, 0.01),
            (0.0, -2.0, 30.0, 3.0, 0.5),
        ];
        for (l0, l, m, beta, x) in cases {
            let v = poly_gauss(&c, &[l0, l, 0.0], m, beta, x);
            let r = reference_pg(&c, &[l0, l, 0.0], m, beta, x);
            assert!(v.is_finite());
            // The closed form and the 1e-13 reference agree to ~1e-11 relative; absolute
            // floor for cases whose value underflows towards 0.
            assert!(
                (v - r).abs() <= 1e-10 * r.abs() + 1e-300,
                "{:?}: {v} vs {r}",
                (l0, l, m, beta, x)
            );
        }
    }

    /// Curved log-attenuations (`l2 != 0`): strongly concave, convex at the largest
    /// curvature taken ([`LAM_CURVE_MAX`] of the Gaussian's, less 0.1 %), a convex one
    /// under a Gaussian so wide that the combined exponent is nearly flat, and an
    /// exponent far beyond `exp`'s range at the peak. Same tolerance as the linear regimes.
    #[test]
    fn poly_gauss_takes_a_curved_log_attenuation() {
        let c = [0.7, -0.4, 0.9];
        let edge = |beta: f64| 0.999 * lam_curve_cap(beta);
        let cases = [
            (-1.0, -3.0, -500.0, 0.5, 0.05, 1.0),
            (-1.0, 2.0, edge(0.05), 0.5, 0.05, 1.0),
            (0.0, 0.5, edge(2.0), 0.3, 2.0, 1.0),
            (0.0, -1.0, -40.0, 2.5, 0.3, 1.0),
            (-600.0, 900.0, -300.0, 0.2, 0.5, 1.0),
            (0.0, 0.0, 3.0, 0.4, 0.001_745, 1.0),
        ];
        for (l0, l, l2, m, beta, x) in cases {
            let lam = [l0, l, l2];
            let v = poly_gauss(&c, &lam, m, beta, x);
            let r = reference_pg(&c, &lam, m, beta, x);
            assert!(v.is_finite());
            assert!(
                (v - r).abs() <= 1e-10 * r.abs() + 1e-300,
                "{:?}: {v} vs {r}",
                (lam, m, beta, x)
            );
        }
    }

    #[test]
    fn poly_exp_matches_quadrature() {
        let c = [0.2, 1.1, -0.6];
        for (l0, l, x) in [
            (0.0, 0.0, 1.0),
            (0.0, 1e-9, 1.0),
            (-2.0, 0.9, 1.0),
            (-2.0, -1.5, 1.0),
            (-100.0, -3000.0, 0.5),
            (-10.0, 50.0, 1.0),
        ] {
            let v = poly_exp(&c, l0, l, x);
            let r = adaptive_gk(
                |t| poly(&c, t) * (l0 + l * t).exp(),
                &[0.0, x],
                1e-13,
                1e-300,
                10_000,
            )
            .value;
            assert!(
                (v - r).abs() <= 1e-11 * r.abs() + 1e-300,
                "{:?}: {v} vs {r}",
                (l0, l, x)
            );
        }
    }

    #[test]
    fn quadratic_through_interpolates() {
        let x = [0.1, 0.4, 1.3];
        let y = [1.0, -2.0, 0.5];
        let c = quadratic_through(x, y);
        for j in 0..3 {
            assert!((poly(&c, x[j]) - y[j]).abs() < 1e-13);
        }
    }
}
