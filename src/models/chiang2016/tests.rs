use super::far::{near_quadrature, Chiang, SliceNodes};
use super::lobes::*;
use super::*;
use crate::model::quadrature::adaptive_gk;
use crate::models::{Factored, SlicePlan as Plan};
use std::f64::consts::{FRAC_PI_2, PI};

/// I0 by its power series summed in f64, for moderate x (exact to rounding there).
fn i0_series(x: f64) -> f64 {
    let (mut t, mut s) = (1.0f64, 1.0f64);
    for k in 1..400 {
        t *= 0.25 * x * x / (k * k) as f64;
        s += t;
    }
    s
}

#[test]
fn scaled_log_i0_matches_the_series_and_is_continuous_at_the_switch() {
    for x in [0.0, 1e-3, 0.5, 3.0, 12.0, 29.9] {
        let want = i0_series(x).ln() - x;
        // Both sides are the same series: rounding only.
        assert!((ln_i0_scaled(x) - want).abs() < 1e-13, "x={x}");
    }
    // Both branches at the switch: the asymptotic series at 30 against the power series
    // (1e-13: each is accurate to ~1e-15 there).
    let series = i0_series(30.0).ln() - 30.0;
    assert!((ln_i0_scaled(30.0) - series).abs() < 1e-13);
    assert!((ln_i0_scaled(1e6) - (-0.5 * (2.0 * PI * 1e6).ln())).abs() < 1e-6);
}

/// d'Eon's M_p as pbrt-v4 writes it for v > 0.1 (direct, no logs).
fn m_direct(ti: f64, to: f64, v: f64) -> f64 {
    let a = ti.cos() * to.cos() / v;
    let b = ti.sin() * to.sin() / v;
    (-b).exp() * i0_series(a) / (2.0 * v * (1.0 / v).sinh())
}

#[test]
fn longitudinal_equals_the_direct_formula_and_integrates_to_one() {
    for v in [0.15, 0.5, 2.0, 27.0] {
        for (ti, to) in [(0.3f64, -0.2f64), (-1.2, 0.7), (0.0, 1.5)] {
            let got = longitudinal(ti.sin(), ti.cos(), to.sin(), to.cos(), v);
            let want = m_direct(ti, to, v);
            // Same quantity through logs: 1e-12 relative covers the exp/ln round trip.
            assert!((got - want).abs() <= 1e-12 * want, "v={v} {ti} {to}");
        }
    }
    // Normalisation over theta_i with the cosine (d'Eon 2011), narrow lobes included.
    for v in [1e-6, 1e-3, 0.05, 0.3, 5.0] {
        for to in [-1.2f64, 0.0, 0.4, 1.5] {
            // Breakpoints around the peak (at -to), so Kronrod's nodes see a narrow lobe.
            let mut pts = vec![-FRAC_PI_2, FRAC_PI_2];
            for d in [-0.01, 0.0, 0.01] {
                pts.push((d - to).clamp(-FRAC_PI_2, FRAC_PI_2));
            }
            pts.sort_by(f64::total_cmp);
            let r = adaptive_gk(
                |ti: f64| longitudinal(ti.sin(), ti.cos(), to.sin(), to.cos(), v) * ti.cos(),
                &pts,
                1e-12,
                0.0,
                10_000,
            );
            // The quadrature's own tolerance (1e-12) and rounding: 1e-9.
            assert!((r.value - 1.0).abs() < 1e-9, "v={v} to={to}: {}", r.value);
        }
    }
}

#[test]
fn attenuations_sum_to_one_without_absorption() {
    for eta in [1.01, 1.55, 3.0] {
        for to in [0.0, 0.7, 1.5] {
            let sl = Slice::new(eta, 0.0, to);
            for g in [-1.5, -0.3, 0.0, 0.9, 1.57] {
                let a = sl.attenuation(g);
                // The residual is the closed geometric series: rounding only.
                assert!(
                    (a.iter().sum::<f64>() - 1.0).abs() < 1e-14,
                    "{eta} {to} {g}"
                );
            }
        }
    }
}

#[test]
fn caustic_derivatives_match_finite_differences() {
    let sl = Slice::new(1.55, 0.2, 0.3);
    for p in 0..3 {
        for g in [-1.2, -0.2, 0.5, 1.3] {
            let e = 1e-6;
            let fd = (sl.phi(p, g + e) - sl.phi(p, g - e)) / (2.0 * e);
            let fd2 = (sl.dphi(p, g + e) - sl.dphi(p, g - e)) / (2.0 * e);
            // Central differences at e = 1e-6: O(e^2) truncation plus 1e-10 rounding.
            assert!((fd - sl.dphi(p, g)).abs() < 1e-8);
            assert!((fd2 - sl.ddphi(p, g)).abs() < 1e-6);
        }
    }
}

/// The far field's node sums against adaptive Gauss-Kronrod over the offset: the
/// tolerance contract (1e-4 of the lobe's peak), on sleek, rough and floor roughness,
/// grazing views, index extremes and heavy absorption.
#[test]
fn far_field_meets_the_tolerance_contract() {
    let cases = [
        (1.55, 0.3, 0.0, 0.2),
        (1.55, 0.3, 1.2, 0.2),
        (1.55, BETA_N_FLOOR, 0.5, 0.1),
        (1.55, 0.05, -0.4, 0.0),
        (1.55, 1.0, 0.3, 0.5),
        (1.01, 0.2, 0.2, 0.0),
        (3.0, 0.1, 0.8, 1.0),
        (1.9, 0.15, 1.5, 20.0),
    ];
    let mut worst = 0.0f64;
    for (eta, beta_n, to, sigma) in cases {
        let sl = Slice::new(eta, sigma, to);
        let s = logistic_scale(beta_n);
        let nodes = SliceNodes::new(&sl, s);
        let phis: Vec<f64> = (0..=90).map(|k| PI * k as f64 / 90.0).collect();
        for p in 0..=P_MAX {
            let reference: Vec<f64> = phis
                .iter()
                .map(|&ph| near_quadrature(&sl, p, ph, s, 1e-11))
                .collect();
            let peak = reference.iter().cloned().fold(0.0, f64::max);
            for (ph, r) in phis.iter().zip(&reference) {
                let got = nodes.eval(*ph)[p];
                let err = (got - r).abs() / peak.max(1e-300);
                worst = worst.max(err);
                assert!(
                    err < 1e-4,
                    "eta {eta} beta_n {beta_n} theta_o {to} p {p} phi {ph}: {got} vs {r}"
                );
            }
        }
    }
    // What the panels give in fact: ~1e-13 where the logistic is narrow; 1.1e-5 at
    // beta_n = 1 (s = 4.3 rad), where the trimmed logistic's kink at |x| = pi (pbrt's
    // wrap) falls inside a panel: second order in the panel width there.
    assert!(worst < 2e-5, "worst {worst}");
}

/// White furnace: without absorption the far field scatters all light, for any view,
/// roughness and tilt (the residual lobe carries the rest of the geometric series).
#[test]
fn white_furnace_holds_without_absorption() {
    for (beta_m, beta_n, alpha) in [(0.1, 0.1, 0.0), (0.3, 0.3, 0.035), (0.9, 0.7, -0.1)] {
        let m = Chiang {
            eta: 1.55,
            beta_m,
            beta_n,
            alpha,
            sigma_a: 0.0,
        };
        for to in [-0.9, 0.0, 0.6] {
            // Integral over phi of each N̄_p (trapezoid on a periodic smooth function).
            let n_phi = 720;
            let pts: Vec<(f64, f64, f64)> = (0..n_phi)
                .map(|k| (0.0, to, -PI + 2.0 * PI * k as f64 / n_phi as f64))
                .collect();
            let plan = Plan::new(&pts, |_, tr| tr);
            let n = m.azimuthal_terms(&plan);
            let mut n_int = [0.0; P_MAX + 1];
            for &(_, f, _) in &plan.index {
                for p in 0..=P_MAX {
                    n_int[p] += n[0][f as usize][p] * 2.0 * PI / n_phi as f64;
                }
            }
            let v = variances(beta_m);
            let total = adaptive_gk(
                |ti: f64| {
                    let mm = longitudinal_lobes(ti, to, alpha, &v);
                    (0..=P_MAX).map(|p| mm[p] * n_int[p]).sum::<f64>() * ti.cos()
                },
                &[-FRAC_PI_2, 0.0, FRAC_PI_2],
                1e-12,
                0.0,
                10_000,
            )
            .value;
            // The furnace bound is 1 %; quadrature gives ~1e-8.
            assert!(
                (total - 1.0).abs() < 1e-4,
                "{beta_m} {beta_n} {alpha} {to}: {total}"
            );
        }
    }
}

#[test]
fn terms_reuse_what_a_step_cannot_change() {
    let model: &'static dyn FiberModel = &Chiang2016;
    let pts = Points::grid_degrees(
        &[0.0, 30.0],
        &[-60.0, 0.0, 45.0],
        &[-180.0, -30.0, 0.0, 90.0],
    );
    let far = FarOptions::default();
    let p0 = [1.55, 0.3, 0.3, 0.035, 0.4];
    let base = model.terms(&p0, &pts, &far);
    for k in 0..5 {
        let mut p = p0;
        p[k] *= 1.01;
        let stepped = base.with_change(&p, k, &pts, &far);
        let fresh = model.terms(&p, &pts, &far);
        let (mut a, mut b) = (vec![0.0; pts.len()], vec![0.0; pts.len()]);
        stepped.values(&pts, &mut a);
        fresh.values(&pts, &mut b);
        // The reused factor does not depend on parameter k: identical bits.
        assert_eq!(a, b, "parameter {k}");
    }
    let pred = model.predict(&p0, &pts, &far, LobeSet(0b1111), Integral::Far);
    let mut v = vec![0.0; pts.len()];
    base.values(&pts, &mut v);
    for (l, x) in pred.lobes.iter().zip(&v) {
        assert!((l.sum() - x).abs() <= 1e-15 * x.abs());
        assert!(*x > 0.0 && x.is_finite());
    }
}

#[test]
fn melanin_gives_the_deon_coefficients() {
    let s = sigma_a_from_melanin(1.0, 0.0);
    assert_eq!(s, EUMELANIN_SIGMA_A);
    let s = sigma_a_from_melanin(0.5, 2.0);
    for c in 0..3 {
        let want = 0.5 * EUMELANIN_SIGMA_A[c] + 2.0 * PHEOMELANIN_SIGMA_A[c];
        assert!((s[c] - want).abs() < 1e-15);
    }
}

/// The division-free [`wrap`] is the `rem_euclid` formula bit for bit, on its branch
/// edges and on random angles of every range it meets (and beyond, where it falls back).
#[test]
fn wrap_is_the_rem_euclid_formula_bit_for_bit() {
    use rand::{Rng, SeedableRng};
    let old = |x: f64| {
        let y = (x + PI).rem_euclid(2.0 * PI) - PI;
        if y < -PI {
            y + 2.0 * PI
        } else {
            y
        }
    };
    let tau = 2.0 * PI;
    let mut xs = vec![
        0.0,
        -0.0,
        PI,
        -PI,
        3.0 * PI,
        -3.0 * PI,
        5.0 * PI,
        1e300,
        -1e-300,
    ];
    for edge in [-tau, 0.0, tau, 2.0 * tau] {
        let a = edge - PI;
        let mut x = a;
        for _ in 0..4 {
            x = x.next_down();
        }
        for _ in 0..9 {
            xs.push(x);
            x = x.next_up();
        }
    }
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(7);
    for _ in 0..200_000 {
        let r: f64 = rng.random();
        xs.push((r - 0.5) * 16.0 * PI);
    }
    for x in xs {
        assert_eq!(wrap(x).to_bits(), old(x).to_bits(), "x = {x:e}");
    }
    assert!(wrap(f64::NAN).is_nan());
}
