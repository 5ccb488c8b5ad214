use super::lobes::{self, fresnel, Glints, RootFinder, Section};
use super::*;
use crate::model::quadrature::GaussLegendre;
use crate::models::ModelParams;
use rand::{Rng, SeedableRng};
use std::f64::consts::PI;

const GLINTS: Glints = Glints {
    k_g: 2.0,
    w_c: 0.26,
    delta_eta: 0.3,
    delta_h_m: 0.5,
};

/// Bravais's `eta'` is exact for the perpendicular polarisation: the projected Fresnel
/// term equals the 3-D one at the true incidence angle `acos(cos theta cos gamma)`.
#[test]
fn bravais_perpendicular_fresnel_is_the_3d_one() {
    let rs = |n: f64, g: f64| {
        let (s, c) = g.sin_cos();
        let ct = (1.0 - s * s / (n * n)).sqrt();
        ((c - n * ct) / (c + n * ct)).powi(2)
    };
    for eta in [1.2, 1.55, 2.4] {
        for th in [0.0, 0.3, 0.8, 1.3] {
            let (ep, epp) = lobes::bravais(eta, th);
            for g in [0.0f64, 0.4, 1.0, 1.5] {
                let i3 = (th.cos() * g.cos()).acos();
                // Closed forms evaluated two ways: rounding only.
                assert!((rs(ep, g) - rs(eta, i3)).abs() < 1e-12, "{eta} {th} {g}");
            }
            if th == 0.0 {
                assert!((ep - eta).abs() < 1e-15 && (epp - eta).abs() < 1e-15);
                let f0 = ((eta - 1.0) / (eta + 1.0)).powi(2);
                assert!((fresnel(ep, epp, 0.0) - f0).abs() < 1e-15);
            }
        }
    }
}

/// The analytic root finder against the independent scan, pointwise over a broad random
/// set of `theta_d`, `phi`, `eta` (away from the fold, where both roots of a pair fall in
/// one scan cell).
#[test]
fn segment_roots_equal_the_scan() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(3);
    let (mut r1, mut r2) = (Vec::new(), Vec::new());
    let mut worst: f64 = 0.0;
    for _ in 0..400 {
        let eta = rng.random_range(1.05..2.8);
        let td = rng.random_range(-1.3..1.3);
        let phi = rng.random_range(-PI..PI);
        let sec = Section::new(eta, rng.random_range(0.0..3.0), td);
        for p in 0..3 {
            if let Some(hc) = sec.caustic(p) {
                if (lobes::wrap(sec.phi(p, hc)).abs() - phi.abs()).abs() < 1e-3 {
                    continue;
                }
            }
            let a = sec.azimuthal(p, phi, &mut r1, RootFinder::Segments, 1.0);
            let b = sec.azimuthal(p, phi, &mut r2, RootFinder::Scan, 1.0);
            assert_eq!(r1.len(), r2.len(), "{eta} {td} {phi} p={p}: {r1:?} {r2:?}");
            let rel = (a - b).abs() / a.abs().max(1e-300);
            worst = worst.max(rel);
            // Both bisect/Newton to rounding of h; N's relative error follows h's near
            // a fold, where 1/|Phi'| amplifies it.
            assert!(rel < 1e-7, "{eta} {td} {phi} p={p}: {a} vs {b}");
        }
    }
    assert!(worst < 1e-7);
}

/// Eq. 8 is a change of variables: brute-force sampling of `Phi(p, h)` with weights
/// `A(p, h) / 2` gives each 2-degree bin of `phi` the mass of `N_p` integrated over the
/// bin, including the TRT caustic's integrable singularity.
#[test]
fn root_sum_matches_brute_force_histogram_of_phi() {
    let bins = 180;
    let width = 2.0 * PI / bins as f64;
    let n = 2_000_000;
    for (eta, td) in [(1.55, 0.2), (1.55, 0.9), (1.9, 0.5)] {
        let sec = Section::new(eta, 0.4, td);
        for p in 0..3 {
            let mut hist = vec![0.0; bins];
            let dg = PI / n as f64;
            for i in 0..n {
                // Midpoints in gamma_i (h = sin gamma_i, dh = cos gamma_i dgamma_i): a
                // deterministic sample as dense in phi at the rim as inside.
                let g = -0.5 * PI + (i as f64 + 0.5) * dg;
                let h = g.sin();
                let x = lobes::wrap(sec.phi(p, h));
                let b = (((x + PI) / width) as usize).min(bins - 1);
                hist[b] += 0.5 * sec.attenuation(p, h) * g.cos() * dg;
            }
            let caustic = sec.caustic(p).map(|hc| lobes::wrap(sec.phi(p, hc)));
            let mut roots = Vec::new();
            let (mut total, mut worst) = (0.0, 0.0f64);
            for (b, &mass) in hist.iter().enumerate() {
                let lo = -PI + b as f64 * width;
                let near = caustic.is_some_and(|c| {
                    [c, -c]
                        .iter()
                        .any(|&c| c > lo - width && c < lo + 2.0 * width)
                });
                // Midpoints in phi; a bin at a caustic is split there and each piece
                // graded toward it (x = c + u^2), which takes out the 1/sqrt singularity.
                let mut f = |x: f64| sec.azimuthal(p, x, &mut roots, RootFinder::Segments, 1.0);
                let exact: f64 = if near {
                    let mut cuts = vec![lo, lo + width];
                    for c in caustic.iter().flat_map(|&c| [c, -c]) {
                        if c > lo && c < lo + width {
                            cuts.push(c);
                        }
                    }
                    cuts.sort_by(f64::total_cmp);
                    cuts.windows(2)
                        .map(|w| graded(&mut f, w[0], w[1], caustic.unwrap()))
                        .sum()
                } else {
                    let dx = width / 200.0;
                    (0..200).map(|k| f(lo + (k as f64 + 0.5) * dx) * dx).sum()
                };
                assert!(exact.is_finite());
                total += exact;
                let err = (exact - mass).abs() / mass.max(1e-4);
                worst = worst.max(err);
                // 2e6 samples of gamma: a bin's share is off by the cells at its edges
                // (~1e-5 of a bin each where Phi is steepest; 8e-5 measured).
                assert!(
                    err < 1e-3,
                    "eta {eta} td {td} p={p} bin {b}: {exact} vs {mass}"
                );
            }
            let gl = GaussLegendre::new(64);
            // In gamma_i, where A is smooth up to the rim.
            let whole = gl.integrate(-0.5 * PI, 0.5 * PI, |g| {
                0.5 * sec.attenuation(p, g.sin()) * g.cos()
            });
            // The root sum's total is (1/2) integral A dh (energy, Eq. 5); the bins'
            // midpoint rules leave ~1e-8 (measured 4e-9).
            assert!(
                (total - whole).abs() < 1e-6 * whole,
                "{eta} {td} p={p}: {total} vs {whole}"
            );
        }
    }
}

/// `integral_a^b f` by 20,000 midpoints in `u` with `x` graded quadratically toward
/// whichever end lies at `+-c` (where `f` may have a 1/sqrt singularity).
fn graded(f: &mut impl FnMut(f64) -> f64, a: f64, b: f64, c: f64) -> f64 {
    let n = 20_000;
    let at = |x: f64| (x.abs() - c.abs()).abs() < 1e-12;
    let (anchor, sign) = if at(a) {
        (a, 1.0)
    } else if at(b) {
        (b, -1.0)
    } else {
        (a, 1.0)
    };
    let len = (b - a).sqrt();
    let du = len / n as f64;
    (0..n)
        .map(|k| {
            let u = (k as f64 + 0.5) * du;
            f(anchor + sign * u * u) * 2.0 * u * du
        })
        .sum()
}

/// The caustic's glint stays finite at the caustic, on it and a hair's breadth off, and
/// `N_TRT` is continuous across the caustic merge (`eta' = 2`).
#[test]
fn trt_glint_is_finite_and_continuous_across_the_merge() {
    let mut roots = Vec::new();
    let sec = Section::new(1.55, 0.3, 0.2);
    let hc = sec.caustic(2).unwrap();
    let phic = lobes::wrap(sec.phi(2, hc));
    for phi in [phic, -phic, phic + 1e-12, phic - 1e-9, phic + 1e-6] {
        let v = lobes::trt(&sec, phi, &GLINTS, &mut roots, RootFinder::Segments);
        assert!(v.is_finite() && v > 0.0, "{phi}: {v}");
    }
    // Without the glint the plain root sum is unbounded there.
    // Three paths on the side of phi_c toward 0.
    let plain = |d: f64| {
        let x = phic - phic.signum() * d;
        sec.azimuthal(2, x, &mut Vec::new(), RootFinder::Segments, 1.0)
    };
    // ~1/sqrt(distance): 1e4 times closer is ~100 times brighter.
    assert!(
        plain(1e-10) > 50.0 * plain(1e-6),
        "{} {}",
        plain(1e-10),
        plain(1e-6)
    );

    // theta_d where eta' = 2: cos^2 = (eta^2 - 1) / 3.
    let eta: f64 = 1.55;
    let td = ((eta * eta - 1.0) / 3.0).sqrt().acos();
    for phi in [0.0, 0.1, 0.5, 2.0] {
        let below = Section::new(eta, 0.3, td - 1e-7);
        let above = Section::new(eta, 0.3, td + 1e-7);
        let a = lobes::trt(&below, phi, &GLINTS, &mut roots, RootFinder::Segments);
        let b = lobes::trt(&above, phi, &GLINTS, &mut roots, RootFinder::Segments);
        // h_c ~ sqrt(eta' - 2) ~ 3e-4 at 1e-7 rad: differences of that order.
        assert!(
            (a - b).abs() < 2e-3 * a.abs().max(1e-3),
            "{phi}: {a} vs {b}"
        );
    }
}

/// The far field equals the reference (roots by scan) at a grid's points, lobe by lobe.
#[test]
fn far_field_equals_the_scan_reference() {
    let model: &'static dyn FiberModel = &Marschner2003;
    let pts = Points::grid_degrees(
        &[0.0, 25.0, 50.0],
        &[-70.0, -20.0, 10.0, 60.0],
        &[-171.0, -93.0, -31.0, 0.0, 47.0, 129.0],
    );
    let far = FarOptions::default();
    for preset in model.presets() {
        let p = ModelParams::from_file_units(model, preset.values).unwrap();
        let a = model.predict(&p.values, &pts, &far, LobeSet::ALL, Integral::Far);
        let b = model.predict(
            &p.values,
            &pts,
            &far,
            LobeSet::ALL,
            Integral::NearQuadrature,
        );
        for (x, y) in a.lobes.iter().zip(&b.lobes) {
            for l in 0..LOBES {
                let (u, v) = (x.0[l], y.0[l]);
                // Same formula, roots to rounding by two finders (see above).
                assert!(
                    (u - v).abs() <= 1e-7 * u.abs().max(1e-12),
                    "{}: {u} {v}",
                    preset.name
                );
            }
        }
    }
}

/// The Table 1 relations and unit-integral Gaussians: each `M_p` integrates to 1 over
/// `theta_h`.
#[test]
fn longitudinal_lobes_follow_table1() {
    let sw = lobes::shifts_widths(-0.13, 0.12);
    assert_eq!(sw[1], (0.065, 0.06));
    assert!((sw[2].0 - 0.195).abs() < 1e-15 && (sw[2].1 - 0.24).abs() < 1e-15);
    let gl = GaussLegendre::new(64);
    for p in 0..LOBES {
        let total: f64 = (0..40)
            .map(|k| {
                let a = -PI / 2.0 + k as f64 * PI / 40.0;
                gl.integrate(a, a + PI / 40.0, |th| lobes::longitudinal(th, &sw)[p])
            })
            .sum();
        // TRT (shift 11 deg, width 14 deg) leaves 5e-9 of its mass beyond 90 deg.
        assert!((total - 1.0).abs() < 1e-8, "{p}: {total}");
    }
}

/// A round fiber has `eta* = eta` for every `phi_h`; an eccentric one spans `eta*_1`
/// (major axis, `phi_h = 0`) to `eta*_2`.
#[test]
fn eta_star_interpolates_between_the_axes() {
    assert!((lobes::eta_star(1.55, 1.0, 0.7) - 1.55).abs() < 1e-15);
    let e1 = 2.0 * 0.55 * 0.81 - 1.55 + 2.0;
    let e2 = 2.0 * 0.55 / 0.81 - 1.55 + 2.0;
    assert!((lobes::eta_star(1.55, 0.9, 0.0) - e1).abs() < 1e-14);
    assert!((lobes::eta_star(1.55, 0.9, PI / 2.0) - e2).abs() < 1e-14);
    assert!(lobes::eta_star(1.001, 0.8, 0.0) >= 1.0);
}

/// A terms change reuses what a parameter cannot reach, bit for bit with a fresh build.
#[test]
fn terms_reuse_what_a_step_cannot_change() {
    let model: &'static dyn FiberModel = &Marschner2003;
    let pts = Points::grid_degrees(&[0.0, 30.0], &[-60.0, 0.0, 45.0], &[-180.0, -30.0, 0.0]);
    let far = FarOptions::default();
    let p0 = ModelParams::from_file_units(model, PRESETS[1].values).unwrap();
    let base = model.terms(&p0.values, &pts, &far);
    for i in 0..SPECS.len() {
        let mut p = p0.values.clone();
        p[i] *= 1.01;
        let mut a = vec![0.0; pts.len()];
        let mut b = vec![0.0; pts.len()];
        base.with_change(&p, i, &pts, &far).values(&pts, &mut a);
        model.terms(&p, &pts, &far).values(&pts, &mut b);
        assert_eq!(a, b, "{}", SPECS[i].name);
    }
}
