//! Far field and multi-scale against the reference integrator of the same model (seed
//! Sec. 5). Scattered lobes are compared with the reference integral of whatever `C^N`
//! the build has, never with fixed numbers.
#![allow(clippy::needless_range_loop)] // fixed-size per-lobe arrays read clearer indexed

use super::*;
use crate::model::{AzimuthalSlice, FurModel, Lobe, LobeSet};
use crate::params::FurParams;
use rand::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use std::f64::consts::PI;

fn params(values: [f64; 10]) -> FurParams {
    FurParams::from_file_units(values).unwrap()
}

/// Per lobe: max over phi of |far - ref| divided by the max over phi of ref (the error
/// metric of the stability report), at one theta_d.
pub(crate) fn max_rel_err(m: &FurModel, td: f64, opts: &FarOptions, nphi: usize) -> [f64; 5] {
    let az = m.azimuthal(td);
    let fs = az.far_slice(LobeSet::ALL, opts);
    let mut peak = [0.0f64; 5];
    let mut err = [0.0f64; 5];
    for k in 0..nphi {
        let phi = -PI + 2.0 * PI * (k as f64 + 0.37) / nphi as f64;
        let f = fs.eval(phi);
        let r = az.far_reference(phi, LobeSet::ALL);
        for i in 0..5 {
            assert!(f.0[i].is_finite(), "non-finite far value {f:?}");
            peak[i] = peak[i].max(r.0[i]);
            err[i] = err[i].max((f.0[i] - r.0[i]).abs());
        }
    }
    let mut out = [0.0; 5];
    for i in 0..5 {
        out[i] = if peak[i] > 0.0 {
            err[i] / peak[i]
        } else {
            err[i]
        };
    }
    out
}

/// Default (tolerance 1e-4) far field within 1e-4 of the peak for every lobe, at the
/// given parameters and theta_d values (degrees).
fn assert_tol_mode(p: &FurParams, tds: &[f64], what: &str) {
    assert_tol_mode_with(p, tds, what, &FarOptions::default());
}

/// [`assert_tol_mode`] with the strict scattered step: every lobe within 1e-4 of its peak.
fn assert_strict_mode(p: &FurParams, tds: &[f64], what: &str) {
    assert_tol_mode_with(p, tds, what, &FarOptions::strict());
}

fn assert_tol_mode_with(p: &FurParams, tds: &[f64], what: &str, opts: &FarOptions) {
    let m = FurModel::new(p);
    for &td in tds {
        let e = max_rel_err(&m, td.to_radians(), opts, 41);
        for l in Lobe::ALL {
            // The mode's contract: <= 1e-4 of the lobe peak (the reference is ~1e-10), for
            // the scattered lobes too since they integrate the table's kinks exactly (the
            // node quadrature they replaced reached 3.7e-3 here).
            assert!(
                e[l.index()] <= 1e-4,
                "{what}, theta_d {td}: {l:?} error {:.2e} of peak (all {e:?})",
                e[l.index()]
            );
        }
    }
}

fn base() -> [f64; 10] {
    // eta, kappa, alpha, beta_m, beta_n, sigma_c_a, sigma_m_s, sigma_m_a, g, l
    [1.55, 0.6, 2.0, 8.0, 10.0, 0.3, 1.5, 0.1, 0.3, 1.0]
}

#[test]
fn stiff_tiny_beta_n() {
    let mut v = base();
    v[4] = 0.1;
    assert_tol_mode(&params(v), &[0.0, 40.0], "beta_n 0.1 deg");
}

#[test]
fn stiff_huge_beta_n() {
    let mut v = base();
    v[4] = 90.0;
    assert_tol_mode(&params(v), &[0.0, 60.0], "beta_n 90 deg");
}

#[test]
fn stiff_trt_caustic() {
    // eta' < 2 puts a TRT caustic (dPhi/dh = 0) inside (0, 1); narrow lobes make it sharp.
    let mut v = base();
    v[0] = 1.3;
    v[4] = 1.0;
    let p = params(v);
    let az_eta = FurModel::new(&p).azimuthal(0.0).eta_prime;
    assert!(az_eta < 2.0);
    assert!(FurModel::new(&p).azimuthal(0.0).trt_caustic_u().is_some());
    assert_tol_mode(&p, &[0.0, 25.0], "TRT caustic");
}

#[test]
fn stiff_huge_absorption() {
    // sigma = 1e3 per radius: exponents of -1e3 and more; exp(b^2/4a + c) would overflow.
    let mut v = base();
    v[5] = 1e3;
    v[7] = 1e3;
    assert_tol_mode(&params(v), &[0.0, 50.0], "absorption 1e3");
}

#[test]
fn stiff_grazing_theta_d() {
    assert_tol_mode(&params(base()), &[89.0, -89.0], "grazing theta_d");
}

#[test]
fn stiff_kappa_limits() {
    let mut v = base();
    v[1] = 1e-6;
    assert_tol_mode(&params(v), &[0.0, 45.0], "kappa 1e-6");
    v[1] = 0.999;
    assert_tol_mode(&params(v), &[0.0, 45.0], "kappa 0.999");
}

#[test]
fn stiff_h_to_one_multiscale_edge() {
    // The last sliver of offsets [0.999, 1] (sqrt endpoint of gamma_i = asin h), against
    // the reference of the same range.
    let m = FurModel::new(&params(base()));
    let az = m.azimuthal(0.2);
    let opts = FarOptions::default();
    let (mut peak, mut err) = ([0.0f64; 5], [0.0f64; 5]);
    for k in 0..41 {
        let phi = -PI + 2.0 * PI * (k as f64 + 0.37) / 41.0;
        let f = az.multiscale(phi, 0.999, 1.0, LobeSet::ALL, &opts);
        let r = az.multiscale_reference(phi, 0.999, 1.0, LobeSet::ALL);
        for i in 0..5 {
            peak[i] = peak[i].max(r.0[i]);
            err[i] = err[i].max((f.0[i] - r.0[i]).abs());
        }
    }
    for i in 0..5 {
        // Same 1e-4-of-peak contract as the far field.
        assert!(
            err[i] <= 1e-4 * peak[i] + 1e-300,
            "lobe {i}: {} of {}",
            err[i],
            peak[i]
        );
    }
}

#[test]
fn kappa_zero_gives_exactly_zero_scattered_and_presets_nonzero() {
    let mut v = base();
    v[1] = 0.0;
    let m = FurModel::new(&params(v));
    let fox = FurModel::new(&FurParams::preset("red-fox").unwrap());
    for phi in [-3.0, -1.0, 0.0, 0.5, 2.9] {
        let n = m
            .azimuthal(0.3)
            .far(phi, LobeSet::ALL, &FarOptions::default());
        assert_eq!(n.get(Lobe::TTs), 0.0);
        assert_eq!(n.get(Lobe::TRTs), 0.0);
        assert!(n.get(Lobe::R) > 0.0);
        let f = fox
            .azimuthal(0.3)
            .far(phi, LobeSet::ALL, &FarOptions::default());
        assert!(f.get(Lobe::TTs) > 0.0 && f.get(Lobe::TRTs) > 0.0, "{f:?}");
    }
}

#[test]
fn culling_changes_nothing_beyond_1e_12_of_peak() {
    for (name, opts) in [
        ("red-fox", FarOptions::default()),
        ("human", FarOptions::paper()),
        ("cat", FarOptions::default()),
    ] {
        let m = FurModel::new(&FurParams::preset(name).unwrap());
        for td in [0.0f64, 0.5, 1.2] {
            let az = m.azimuthal(td);
            let on = az.far_slice(LobeSet::ALL, &opts);
            let off = az.far_slice(
                LobeSet::ALL,
                &FarOptions {
                    cull: false,
                    ..opts
                },
            );
            let mut vals = Vec::new();
            for k in 0..360 {
                let phi = -PI + 2.0 * PI * (k as f64 + 0.5) / 360.0;
                vals.push((on.eval(phi), off.eval(phi)));
            }
            for i in 0..5 {
                let peak = vals.iter().map(|v| v.1 .0[i]).fold(0.0, f64::max);
                let worst = vals
                    .iter()
                    .map(|v| (v.0 .0[i] - v.1 .0[i]).abs())
                    .fold(0.0, f64::max);
                assert!(
                    worst <= 1e-12 * peak,
                    "{name} td {td} lobe {i}: {worst} vs {peak}"
                );
            }
        }
    }
}

#[test]
fn multiscale_limits_far_and_near() {
    let m = FurModel::new(&FurParams::preset("dog").unwrap());
    let opts = FarOptions::default();
    let az = m.azimuthal(0.25);
    for phi in [-2.5, -0.4, 0.0, 1.3, 3.1] {
        // [-1, 1] is the far field (Eq. 26 -> Eq. 22): same segments, same result.
        let a = az.multiscale(phi, -1.0, 1.0, LobeSet::ALL, &opts);
        let b = az.far(phi, LobeSet::ALL, &opts);
        for i in 0..5 {
            assert!(
                (a.0[i] - b.0[i]).abs() <= 1e-14 * b.0[i].abs() + 1e-300,
                "lobe {i}: {} vs {}",
                a.0[i],
                b.0[i]
            );
        }
        // A vanishing range tends to the near field: width 2e-4 around h; the near field
        // changes on a scale of ~0.05 in h here, so the mean differs by ~1e-5 relative.
        for h in [-0.7, 0.1, 0.55] {
            let ms = az.multiscale(phi, h - 1e-4, h + 1e-4, LobeSet::ALL, &opts);
            let nf = az.near(h, phi, LobeSet::ALL);
            for i in 0..5 {
                assert!(
                    (ms.0[i] - nf.0[i]).abs() <= 1e-4 * nf.0[i].abs() + 1e-12,
                    "h {h} phi {phi} lobe {i}: {} vs {}",
                    ms.0[i],
                    nf.0[i]
                );
            }
        }
        // A partial range straddling 0 against the reference of the same range.
        let ms = az.multiscale(phi, -0.5, 0.3, LobeSet::ALL, &opts);
        let r = az.multiscale_reference(phi, -0.5, 0.3, LobeSet::ALL);
        for i in 0..5 {
            // 2e-4 of the value (the mode's 1e-4 is of the peak); scattered lobes measured
            // 4.6e-6 here (0.85 % before they integrated the table's kinks exactly).
            let tol = 2e-4;
            assert!(
                (ms.0[i] - r.0[i]).abs() <= tol * r.0[i].abs() + 1e-9,
                "lobe {i}: {} vs {}",
                ms.0[i],
                r.0[i]
            );
        }
    }
}

#[test]
fn far_integrates_over_phi_to_mean_attenuation() {
    // integral N_p dphi = 1/2 integral A_p dh (D_p and C^N's angular part integrate to 1
    // and the scattered fraction respectively); checked for the unscattered lobes, whose D
    // is normalised exactly.
    for name in ["red-fox", "mouse", "human"] {
        let m = FurModel::new(&FurParams::preset(name).unwrap());
        for td in [0.0f64, 0.6] {
            let az = m.azimuthal(td);
            let fs = az.far_slice(LobeSet::UNSCATTERED, &FarOptions::default());
            let n = 1440;
            let mut e = [0.0f64; 3];
            for k in 0..n {
                let phi = -PI + 2.0 * PI * (k as f64 + 0.5) / n as f64;
                let v = fs.eval(phi);
                for i in 0..3 {
                    e[i] += v.0[i] * 2.0 * PI / n as f64;
                }
            }
            // integral A dh by adaptive GK with the medulla edge (a kink of A) as breakpoint.
            let ue = (m.params.kappa * az.eta_prime).min(1.0).asin();
            let pts = [-PI / 2.0, -ue, 0.0, ue, PI / 2.0];
            for (i, l) in [Lobe::R, Lobe::TT, Lobe::TRT].into_iter().enumerate() {
                let a = crate::model::quadrature::adaptive_gk(
                    |u| {
                        let geo = az.geometry_at_gamma_i(u);
                        0.5 * az.attenuation(&geo, LobeSet::only(l)).get(l) * geo.cos_gamma_i
                    },
                    &pts,
                    1e-12,
                    0.0,
                    10_000,
                )
                .value;
                // tol 1e-4 of the peak per phi bounds the integral's error by ~1e-4 of
                // 2 pi * peak; relative to the mean this is a few 1e-4.
                assert!(
                    (e[i] - a).abs() <= 5e-4 * a,
                    "{name} {l:?}: {} vs {a}",
                    e[i]
                );
            }
        }
    }
}

/// The broad random set of the tolerance-mode tests: eight parameter vectors across the
/// bounds that matter (eta, kappa, roughness, absorption, g, l) with a theta_d each.
fn random_cases() -> Vec<([f64; 10], f64)> {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(20170701);
    (0..8)
        .map(|_| {
            let v = [
                rng.random_range(1.1..2.5),
                rng.random_range(0.0..0.95),
                rng.random_range(-10.0..10.0),
                rng.random_range(2.0..20.0),
                rng.random_range(0.5..40.0),
                rng.random_range(0.0..3.0),
                rng.random_range(0.0..5.0),
                rng.random_range(0.0..2.0),
                rng.random_range(-0.8..0.8),
                rng.random_range(0.3..5.0),
            ];
            (v, rng.random_range(-80.0..80.0))
        })
        .collect()
}

#[test]
fn tol_mode_meets_1e_4_on_random_parameters() {
    for (case, (v, td)) in random_cases().into_iter().enumerate() {
        assert_tol_mode(&params(v), &[td], &format!("random case {case} {v:?}"));
    }
}

/// Tabulating `C^N` per node is an evaluation shortcut only: the far field must agree with
/// the rank-sum path to rounding (1e-12 of the lobe's peak; the two differ only in the
/// order of a 32-term sum), for the far field and a multi-scale range.
#[test]
fn tabulated_scattered_matches_rank_sum() {
    let p = FurParams::preset("red-fox").unwrap();
    let m = FurModel::new(&p);
    for td in [-0.6, 0.05, 0.9] {
        let az = m.azimuthal(td);
        for opts in [FarOptions::paper(), FarOptions::default()] {
            for (h1, h2) in [(-1.0, 1.0), (-0.3, 0.7)] {
                let plain = FarSlice::range(&az, h1, h2, LobeSet::ALL, &opts);
                let mut tab = plain.clone();
                tab.tabulate_scattered();
                let phis: Vec<f64> = (0..97).map(|k| -PI + 2.0 * PI * k as f64 / 97.0).collect();
                let peak = phis.iter().fold([0.0f64; 2], |acc, &phi| {
                    let v = plain.eval(phi);
                    [acc[0].max(v.get(Lobe::TTs)), acc[1].max(v.get(Lobe::TRTs))]
                });
                assert!(
                    peak[0] > 0.0 && peak[1] > 0.0,
                    "red-fox has scattered lobes"
                );
                for &phi in &phis {
                    let (a, b) = (plain.eval(phi), tab.eval(phi));
                    for (i, l) in [Lobe::TTs, Lobe::TRTs].into_iter().enumerate() {
                        assert!((a.get(l) - b.get(l)).abs() <= 1e-12 * peak[i]);
                    }
                    for l in [Lobe::R, Lobe::TT, Lobe::TRT] {
                        assert_eq!(a.get(l), b.get(l));
                    }
                }
            }
        }
    }
}

#[test]
fn stiff_eta_to_one_grazing_fresnel_layer() {
    // eta = 1 + 1e-9: the cuticle reflectance is ~1e-19 except in a layer of width
    // ~sqrt(2e-9) in cos u at h -> 1, which holds all of R's mass (peak ~3e-10). The paper's
    // segments miss it entirely; the tolerance mode must resolve it to 1e-4 of R's peak.
    let mut v = base();
    v[0] = 1.0 + 1e-9;
    let m = FurModel::new(&params(v));
    for td in [0.0f64, 70.0] {
        let az = m.azimuthal(td.to_radians());
        let (err, peak) = lobe_err_and_peak(&az, Lobe::R, &[]);
        assert!(peak > 0.0);
        // The tolerance mode's contract for unscattered lobes: 1e-4 of the peak.
        assert!(
            err <= 1e-4 * peak,
            "theta_d {td}: {err:.3e} of peak {peak:.3e}"
        );
    }
}

#[test]
fn stiff_eta_to_one_kappa_to_one_grazing_tt() {
    // eta = 1 + 1e-9, kappa = 0.999, theta_d = 89 deg: TT's medulla attenuation
    // exp(-c sqrt(u_edge - u)), c in the hundreds, puts nearly all of its mass within 1e-5
    // of the medulla edge, and its prefactor (1 - F)^2 cos u falls to 0 inside the grazing
    // Fresnel layer. The refinement's quarter-point checks once saw ~e^-100 in both fit
    // and integrand and accepted one 16-node piece up to the edge: 3.4e-3 of the peak at
    // phi = pi (the log-attenuation guard `LAM_DEV_MAX` now splits it; 7.5e-10). Without
    // the probes of `FarSlice::gl_piece`, an 8-node rule was 1.3e-2 here. Held to the
    // mode's 1e-4.
    let mut v = base();
    v[0] = 1.0 + 1e-9;
    v[1] = 0.999;
    let m = FurModel::new(&params(v));
    let az = m.azimuthal(89f64.to_radians());
    let (err, peak) = lobe_err_and_peak(&az, Lobe::TT, &[PI]);
    assert!(peak > 0.0);
    assert!(err <= 1e-4 * peak, "{:.3e} of peak {peak:.3e}", err / peak);
}

/// Lobe `l` alone in default tolerance mode against the reference at 12 even phi and
/// `extra` ones: (max |far - ref|, max ref).
fn lobe_err_and_peak(az: &AzimuthalSlice, l: Lobe, extra: &[f64]) -> (f64, f64) {
    let set = LobeSet::only(l);
    let fs = az.far_slice(set, &FarOptions::default());
    let (mut peak, mut err) = (0.0f64, 0.0f64);
    let even = (0..12).map(|k| -PI + 2.0 * PI * (k as f64 + 0.37) / 12.0);
    for phi in even.chain(extra.iter().copied()) {
        let rv = az.far_reference(phi, set).get(l);
        peak = peak.max(rv);
        err = err.max((fs.eval(phi).get(l) - rv).abs());
    }
    (err, peak)
}

#[test]
fn tol_mode_refinement_stays_bounded_at_eta_one_tiny_beta() {
    // eta -> 1 with beta_n = 0.1 deg: TT's Phi is constant to ~1e-9 (every segment is a
    // caustic) and R's mass sits in the grazing Fresnel layer. The refinement once ran to
    // millions of segments here (`furfit stability` never finished); it must end well
    // inside the split cap without hitting it.
    let mut v = base();
    v[0] = 1.0 + 1e-9;
    v[4] = 0.1;
    let m = FurModel::new(&params(v));
    for td in [0.0f64, 20.0, -89.0] {
        let fs = m
            .azimuthal(td.to_radians())
            .far_slice(LobeSet::ALL, &FarOptions::default());
        let s = fs.stats();
        let total = s.unscattered_segments + s.gl_segments + s.scattered_segments;
        assert!(s.capped.is_empty(), "theta_d {td}: capped {:?}", s.capped);
        // 5 lobes x 4096 splits would be ~20k; a few thousand is what resolving needs.
        assert!(total < 5000, "theta_d {td}: {s:?}");
        assert!(fs.eval(PI).0.iter().all(|x| x.is_finite()));
    }
}

/// Every lobe of `got[k]` within `rel` of the peak over `want` of that lobe of `want[k]`;
/// `what(k)` names sample `k` in a failure.
fn assert_within_of_peak(
    want: &[LobeValues],
    got: &[LobeValues],
    rel: f64,
    what: impl Fn(usize) -> String,
) {
    assert_eq!(want.len(), got.len());
    for l in Lobe::ALL {
        let peak = want.iter().map(|v| v.get(l)).fold(0.0, f64::max);
        for (k, (a, b)) in want.iter().zip(got).enumerate() {
            assert!(
                (a.get(l) - b.get(l)).abs() <= rel * peak,
                "{} {l:?}: {} vs {}",
                what(k),
                a.get(l),
                b.get(l)
            );
        }
    }
}

/// Far-field slices for the batch-evaluation tests: 24 random parameter sets (`kappa`
/// cycling through 0, 0.5, 0.9 and `beta_n` through 0.1..90 deg, so windows range from a
/// sliver to all images) at a random `theta_d`, both segmentations, the far field and a
/// multi-scale range; `f` gets a description and the slice.
fn for_random_slices(seed: u64, mut f: impl FnMut(&str, &FarSlice)) {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    for case in 0..24 {
        let v = random_params(&mut rng, case);
        let m = FurModel::new(&params(v));
        let az = m.azimuthal(rng.random_range(-1.5..1.5));
        for opts in [FarOptions::paper(), FarOptions::default()] {
            for (h1, h2) in [(-1.0, 1.0), (-0.2, 0.9)] {
                let slice = FarSlice::range(&az, h1, h2, LobeSet::ALL, &opts);
                f(&format!("case {case} {v:?} h {h1}..{h2}"), &slice);
            }
        }
    }
}

fn random_params(rng: &mut Xoshiro256PlusPlus, case: usize) -> [f64; 10] {
    [
        rng.random_range(1.05..2.5),
        [0.0, 0.5, 0.9][case % 3],
        rng.random_range(-10.0..10.0),
        rng.random_range(2.0..20.0),
        [0.1, 2.0, 15.0, 60.0, 90.0][case % 5],
        rng.random_range(0.0..3.0),
        rng.random_range(0.0..5.0),
        rng.random_range(0.0..2.0),
        rng.random_range(-0.8..0.8),
        rng.random_range(0.3..5.0),
    ]
}

/// The batch evaluation over a grid of `phi` is a reordering of the loops only: it must
/// equal per-`phi` evaluation exactly, for random parameters (narrow to very wide
/// `beta_n`, so windows from a sliver to all images), both segmentations, far field and a
/// multi-scale range, unsorted and repeated `phi` and angles outside `(-pi, pi]`.
#[test]
fn eval_many_equals_eval_exactly() {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(7);
    let mut phis: Vec<f64> = (0..181)
        .map(|k| (-180.0 + 2.0 * k as f64).to_radians())
        .collect();
    phis.extend([PI, -PI, 3.5 * PI, -7.0, 0.0, 0.0, 1e-300]);
    phis.extend((0..40).map(|_| rng.random_range(-4.0..4.0)));
    for_random_slices(7, |what, slice| {
        let many = slice.eval_many(&phis);
        for (&phi, b) in phis.iter().zip(&many) {
            assert_eq!(slice.eval(phi), *b, "{what} phi {phi}");
        }
    });
}

/// On an evenly spaced `phi` grid `eval_many` sweeps the quadrature-node pieces with a
/// Gaussian recurrence instead of one exponential per `phi`, and short `Phi` pieces through
/// their node form: it must still match per-`phi` evaluation, to 1e-11 of each lobe's peak
/// (measured worst 1-2e-12: the node form's 8-point rule on 2-beta sub-intervals; the
/// recurrence drifts by ~n eps and drops node terms below e^-36 of their peak), and with
/// tabulated `C^N` profiles it reads them
/// along the grid; on the random slices of `eval_many_equals_eval_exactly` and grids fine
/// and coarse, full and half circle.
#[test]
fn eval_many_on_even_grids_matches_eval() {
    let grids: Vec<Vec<f64>> = [(0.0, 180.0, 2.0), (-180.0, 179.5, 0.5), (1.0, 179.0, 4.0)]
        .iter()
        .map(|&(a, b, d): &(f64, f64, f64)| {
            let n = ((b - a) / d).round() as usize + 1;
            (0..n).map(|k| (a + d * k as f64).to_radians()).collect()
        })
        .collect();
    for_random_slices(8, |what, slice| {
        // Also with the scattered nodes' C^N tabulated (what grid synthesis does), which
        // the even-grid path reads along the grid.
        let mut tabulated = slice.clone();
        tabulated.tabulate_scattered();
        for (slice, phis) in [slice, &tabulated]
            .into_iter()
            .flat_map(|sl| grids.iter().map(move |g| (sl, g)))
        {
            let many = slice.eval_many(phis);
            let one: Vec<LobeValues> = phis.iter().map(|&p| slice.eval(p)).collect();
            assert_within_of_peak(&one, &many, 1e-11, |k| format!("{what} phi {}", phis[k]));
        }
    });
}

/// The tolerance mode meets its 1e-4 of the peak for every lobe, scattered ones included,
/// with the default and the strict scattered step: on the random set of
/// `tol_mode_meets_1e_4_on_random_parameters`, stiff cases and the bench-model presets.
/// The scattered lobes' node quadrature alone (before they integrated the table's kinks
/// exactly) gave 3.7e-3 at kappa 0.999, so the test can fail.
#[test]
fn tol_mode_meets_1e_4_on_stiff_cases_and_presets() {
    for check in [assert_tol_mode, assert_strict_mode] {
        for (case, (v, td)) in random_cases().into_iter().enumerate() {
            check(&params(v), &[td], &format!("random case {case} {v:?}"));
        }
        let mut v = base();
        v[1] = 0.999;
        check(&params(v), &[0.0, 45.0], "kappa 0.999");
        let mut v = base();
        v[4] = 0.1;
        check(&params(v), &[0.0, 40.0], "beta_n 0.1 deg");
        let mut v = base();
        v[4] = 90.0;
        check(&params(v), &[0.0, 60.0], "beta_n 90 deg");
        check(&params(base()), &[89.0, -89.0], "grazing theta_d");
        for name in ["red-fox", "human", "dog", "mouse"] {
            let p = FurParams::preset(name).unwrap();
            check(&p, &[0.0, 30.0, 60.0], name);
        }
    }
}

/// Tighter tolerances hold too, on the bench-model presets and angles: every lobe within
/// `tol` of its peak at 1e-5 and 1e-6 (worst measured 1.8e-7 at 1e-6). A scattered-segment
/// change that met 1e-4 with room but missed 1e-6 by 1.5x (TRTs, dog at theta_d 60) was
/// caught only by `bench-model`, not by the 1e-4 tests.
#[test]
fn tol_mode_meets_tighter_tolerances_on_presets() {
    for tol in [1e-5, 1e-6] {
        let opts = FarOptions {
            tol: Some(tol),
            ..FarOptions::default()
        };
        for name in ["red-fox", "human", "dog", "mouse"] {
            let m = FurModel::new(&FurParams::preset(name).unwrap());
            for td in [0.0f64, 30.0, 60.0] {
                let e = max_rel_err(&m, td.to_radians(), &opts, 48);
                for l in Lobe::ALL {
                    assert!(
                        e[l.index()] <= tol,
                        "{name} tol {tol:e} theta_d {td}: {l:?} error {:.2e} of peak",
                        e[l.index()]
                    );
                }
            }
        }
    }
}

/// [`SliceStats::per_lobe`] books each piece under the lobe that built it: a one-lobe
/// slice has work under that lobe only (cat: it has a medulla, so every lobe builds
/// pieces).
#[test]
fn slice_stats_book_pieces_per_lobe() {
    let m = FurModel::new(&FurParams::preset("cat").unwrap());
    let opts = FarOptions::default();
    for td in [0.1, 0.6] {
        for l in Lobe::ALL {
            let st = m.azimuthal(td).far_slice(LobeSet::only(l), &opts).stats();
            for (k, w) in st.per_lobe.iter().enumerate() {
                let any = w.closed_form + w.gl_segments > 0;
                assert_eq!(any, k == l.index(), "{l:?} at {td}: {st:?}");
            }
        }
    }
}

/// Wide unscattered lobes (red fox, beta_n 17.6 deg) are resolved by the 4-point rule of
/// the Gauss-Legendre cascade ([`FarSlice::gl_piece_with`]): most pieces of TT and TRT
/// keep 4 nodes (8 or 16 before the cascade; 44 nodes over 8 pieces measured for TT at
/// theta_d 0), and the lobes stay within 1e-7 of their peak
/// (measured ~5e-9: the 4-point rule is accepted only where it agrees with the 8-point
/// one to 1e-3 of the tolerance).
#[test]
fn gl_cascade_keeps_four_nodes_on_wide_lobes() {
    let m = FurModel::new(&FurParams::preset("red-fox").unwrap());
    for td in [0.0, 0.5] {
        for l in [Lobe::TT, Lobe::TRT] {
            let st = m
                .azimuthal(td)
                .far_slice(LobeSet::only(l), &FarOptions::default())
                .stats();
            assert!(st.gl_segments > 0, "{l:?}: {st:?}");
            assert!(st.gl_nodes <= 6 * st.gl_segments, "{l:?} at {td}: {st:?}");
        }
        let e = max_rel_err(&m, td, &FarOptions::default(), 61);
        for l in [Lobe::TT, Lobe::TRT] {
            assert!(e[l.index()] <= 1e-7, "{l:?} at {td}: {e:?}");
        }
    }
}

/// A strict step at a tighter tolerance asks for thousands of scattered pieces: they are cut
/// up front, not by bisection, which exhausted the split budget depth-first and left the
/// end of the range coarse (TRTs was 5e-2 of its peak for red-fox at theta_d 0).
#[test]
fn strict_step_at_tight_tolerance_is_not_capped() {
    let m = FurModel::new(&FurParams::preset("red-fox").unwrap());
    let opts = FarOptions {
        tol: Some(1e-6),
        ..FarOptions::strict()
    };
    let stats = m.azimuthal(0.0).far_slice(LobeSet::ALL, &opts).stats();
    assert!(stats.capped.is_empty(), "{stats:?}");
    let e = max_rel_err(&m, 0.0, &opts, 48);
    assert!(e.iter().all(|&x| x <= 1e-4), "{e:?}");
}

/// The far field is even in `phi` (the `h -> -h` mirror): `A_p(-h) = A_p(h)`,
/// `Phi_p(-h) = -Phi_p(h)` and `C^N(-x, psi) = C^N(x, -psi)`. The engine adds each segment
/// at `phi` and `-phi`, so it must be even to rounding in every mode, scattered lobes
/// included: the `h = 0` node once read the table's `x = 0` row unflipped on both sides,
/// and that row is even only up to Monte-Carlo noise (up to 1e-2 of the peak, paper mode).
/// Tolerance 1e-12 of the peak: the two sides add the same terms in another order.
#[test]
fn far_field_is_even_in_phi() {
    for name in ["red-fox", "human", "dog", "mouse"] {
        let m = FurModel::new(&FurParams::preset(name).unwrap());
        for opts in [FarOptions::default(), FarOptions::paper()] {
            for td in [0.0f64, 0.3, 0.9, 1.4] {
                let fs = m.azimuthal(td).far_slice(LobeSet::ALL, &opts);
                let phis: Vec<f64> = (0..=45).map(|k| k as f64 * 4f64.to_radians()).collect();
                let pos: Vec<LobeValues> = phis.iter().map(|&p| fs.eval(p)).collect();
                let neg: Vec<LobeValues> = phis.iter().map(|&p| fs.eval(-p)).collect();
                assert_within_of_peak(&pos, &neg, 1e-12, |k| {
                    format!("{name} td {td} phi {:.1} deg", phis[k].to_degrees())
                });
            }
        }
    }
}

/// The far field depends on `theta_d` only through `cos theta_d`, so it is even in
/// `theta_d`: grid prediction (`synth::GridPlan`) builds one slice per `|theta_d|` and
/// relies on this. Exact equality: `cos` is even in IEEE arithmetic, and everything after
/// it is the same computation.
#[test]
fn far_field_is_even_in_theta_d() {
    for name in ["red-fox", "human", "mouse"] {
        let m = FurModel::new(&FurParams::preset(name).unwrap());
        let opts = FarOptions::default();
        for td_deg in [0.5f64, 17.0, 44.5, 60.0, 89.0] {
            let td = td_deg.to_radians();
            let phis: Vec<f64> = (0..=36).map(|k| (k as f64 * 5.0).to_radians()).collect();
            let pos = m
                .azimuthal(td)
                .far_slice(LobeSet::ALL, &opts)
                .eval_many(&phis);
            let neg = m
                .azimuthal(-td)
                .far_slice(LobeSet::ALL, &opts)
                .eval_many(&phis);
            for (k, (a, b)) in pos.iter().zip(&neg).enumerate() {
                for l in Lobe::ALL {
                    assert_eq!(
                        a.get(l).to_bits(),
                        b.get(l).to_bits(),
                        "{name} theta_d +-{td_deg} deg, phi {} deg, {l:?}",
                        5 * k
                    );
                }
            }
        }
    }
}

/// A single call builds only the unscattered segments whose `Phi_p` can reach the culling
/// window of its `phi` ([`FarSlice::far_at`], [`FarSlice::range_at`]); what it leaves out
/// would have been culled at that `phi`, so the value must equal the full slice's bit for
/// bit. Random parameters (`beta_n` 0.1..90 deg), both segmentations, far field and
/// two-sided and one-sided multi-scale ranges, `phi` on and off `(-pi, pi]`, plus the
/// `eta -> 1` corner (`eta' = 1` to rounding) where the bound on `dPhi/du` meets the 0/0 at `h = 1`. Slices whose
/// full build hit the split cap are skipped (there the saved splits may legitimately
/// refine further).
#[test]
fn single_phi_build_equals_full_slice_exactly() {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(11);
    let mut cases: Vec<([f64; 10], f64)> = (0..24)
        .map(|case| (random_params(&mut rng, case), rng.random_range(-1.5..1.5)))
        .collect();
    for (eta, td) in [
        (1.0 + 1e-15, 0.0),
        (1.0 + 1e-9, 89f64.to_radians()),
        (1.0 + 1e-15, 1.2),
    ] {
        let mut v = base();
        v[0] = eta;
        v[4] = 0.5;
        cases.push((v, td));
    }
    let mut phis: Vec<f64> = (0..37)
        .map(|k| (-180.0 + 10.0 * k as f64).to_radians())
        .collect();
    phis.extend([1e-300, -7.0, 3.5 * PI]);
    phis.extend((0..8).map(|_| rng.random_range(-PI..PI)));
    let mut compared = 0;
    for (v, td) in cases {
        let m = FurModel::new(&params(v));
        let az = m.azimuthal(td);
        for opts in [FarOptions::paper(), FarOptions::default()] {
            for (h1, h2) in [(-1.0, 1.0), (-0.2, 0.9), (0.3, 0.7)] {
                let full = FarSlice::range(&az, h1, h2, LobeSet::ALL, &opts);
                if full.stats().capped != LobeSet::NONE {
                    continue;
                }
                for &phi in &phis {
                    let one = FarSlice::range_at(&az, (h1, h2), LobeSet::ALL, &opts, phi);
                    assert_eq!(one, full.eval(phi), "{v:?} td {td} h {h1}..{h2} phi {phi}");
                    compared += 1;
                }
            }
            let full = FarSlice::far(&az, LobeSet::ALL, &opts);
            if full.stats().capped == LobeSet::NONE {
                for &phi in &phis {
                    let one = FarSlice::far_at(&az, LobeSet::ALL, &opts, phi);
                    assert_eq!(one, full.eval(phi), "{v:?} td {td} far phi {phi}");
                }
            }
        }
    }
    // Nearly all slices take part (a few random stiff ones may be capped).
    assert!(
        compared > 27 * 2 * 3 * phis.len() * 9 / 10,
        "only {compared} compared"
    );
    // At beta_n = 0.1 deg the culling window is 0.85 deg wide: a dense phi grid probes the
    // reach test at the windows' edges (a window of 3 beta instead of 8.5 fails here).
    let mut v = base();
    v[4] = 0.1;
    let m = FurModel::new(&params(v));
    for td in [0.0, 0.7] {
        let az = m.azimuthal(td);
        let dense: Vec<f64> = (0..1800)
            .map(|k| (-180.0 + 0.2 * k as f64).to_radians())
            .collect();
        for opts in [FarOptions::paper(), FarOptions::default()] {
            let full = FarSlice::far(&az, LobeSet::only(Lobe::TRT), &opts);
            assert_eq!(full.stats().capped, LobeSet::NONE);
            for &phi in &dense {
                let one = FarSlice::far_at(&az, LobeSet::only(Lobe::TRT), &opts, phi);
                assert_eq!(one, full.eval(phi), "tiny beta td {td} phi {phi}");
            }
        }
    }
}

/// Count of each piece kind of a slice, the structure a replay must keep.
fn structure(fs: &FarSlice) -> (usize, usize, usize) {
    let s = fs.stats();
    (s.unscattered_segments, s.gl_segments, s.scattered_segments)
}

/// Replayed decisions ([`Decisions`]) keep a slice's segments across a parameter step that
/// changes a fresh tolerance-mode build's segments, and the value then moves smoothly.
/// Scans eta in steps of 1e-6 until a fresh build's segment counts change between two
/// neighbours (a tipped decision), then replays the decisions of the lower one at the
/// upper one: same counts as the lower, and a value change in line with the step before
/// (a fresh build's change across a tipped decision is up to `tol` of the peak instead).
#[test]
fn replayed_decisions_keep_the_segments_across_a_tipped_split() {
    let v = FurParams::preset("red-fox").unwrap().to_file_units();
    let opts = FarOptions::default();
    let td = 0.3;
    let phis: Vec<f64> = (0..46).map(|k| (4.0 * k as f64).to_radians()).collect();
    let build = |eta: f64, replay: Option<&Decisions>| {
        let mut v = v;
        v[0] = eta;
        let m = FurModel::new(&params(v));
        let az = m.azimuthal(td);
        let (fs, rec) = FarSlice::far_taped(&az, LobeSet::ALL, &opts, replay);
        (structure(&fs), fs.eval_grid(&phis), rec)
    };
    let sum = |vals: &[LobeValues]| vals.iter().map(|x| x.sum()).sum::<f64>();
    let eta0 = v[0];
    let h = 1e-6;
    let mut prev = build(eta0, None);
    let mut prev_step = f64::NAN;
    let mut found = false;
    for k in 1..20_000 {
        let eta = eta0 + k as f64 * h;
        let cur = build(eta, None);
        if cur.0 != prev.0 && prev_step.is_finite() {
            let (rs, rv, _) = build(eta, Some(&prev.2));
            assert_eq!(rs, prev.0, "eta {eta}: replay changed the segments");
            let smooth = (sum(&rv) - sum(&prev.1)).abs();
            let peak = prev.1.iter().map(|x| x.sum()).fold(0.0, f64::max);
            // The step before was smooth: the replayed change must be of its size (a
            // factor 3 for the curvature over two steps, plus rounding of the sums).
            assert!(
                smooth <= 3.0 * prev_step + 1e-12 * peak,
                "eta {eta}: replayed change {smooth:.3e}, previous step {prev_step:.3e}"
            );
            found = true;
            break;
        }
        prev_step = (sum(&cur.1) - sum(&prev.1)).abs();
        prev = cur;
    }
    assert!(
        found,
        "no tipped decision within 0.02 of eta: the test checks nothing"
    );
}

#[test]
fn stiff_optically_thick_medulla() {
    // tau = sigma_m_s kappa of 200 and 300: TRTs lives within ~1e-6 of the medulla edge in
    // h (its extinction exp(-2 s_m sigma_m_t) against the scattering 1 - exp(-2 s_m
    // sigma_m_s)), where no initial node fell; it came out 10 orders low.
    for (kappa, sigma_m_s) in [(0.5, 400.0), (0.3, 1000.0)] {
        let mut v = base();
        v[1] = kappa;
        v[6] = sigma_m_s;
        let p = params(v);
        assert_tol_mode(&p, &[0.0, 60.0], &format!("tau {}", kappa * sigma_m_s));
    }
}

#[test]
fn reference_resolves_the_medulla_layer() {
    // The reference against an integral in t, h = edge cos t (inside the medulla, where
    // TRTs lives): the layer's exp(-c kappa sin t) is smooth in t, so adaptive
    // Gauss-Kronrod from a few decades of breakpoints resolves it without the mesh the
    // reference and the far field share. Before that mesh the reference was 8 % off here.
    let mut v = base();
    v[1] = 0.3;
    v[6] = 1000.0;
    let m = FurModel::new(&params(v));
    let az = m.azimuthal(60f64.to_radians());
    let edge = 0.3 * az.eta_prime;
    for phi in [0.0, 2.0] {
        let reference = az.reference_integral(phi, -1.0, 1.0, Lobe::TRTs);
        let mut brute = 0.0;
        for sign in [-1.0, 1.0] {
            let f = |t: f64| {
                let h = sign * edge * t.cos();
                az.near(h, phi, LobeSet::only(Lobe::TRTs)).get(Lobe::TRTs) * edge * t.sin()
            };
            let pts = [0.0, 1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 0.1, 0.5, PI / 2.0];
            brute += crate::model::quadrature::adaptive_gk(f, &pts, 1e-11, 0.0, 200_000).value;
        }
        // 1e-7: both aim at ~1e-10; the table's kinks in x cost the t-integral a little.
        assert!(
            (reference - brute).abs() <= 1e-7 * brute,
            "phi {phi}: reference {reference:e}, integral in t {brute:e}"
        );
    }
}

#[test]
fn eta_a_few_ulps_above_one_is_not_nan() {
    // eta = 1 + 1e-15: TT's Phi spans a few ulps over a segment, and its quadratic fit in
    // Phi had NaN coefficients; TT was NaN at phi = pi (its peak), in every mode, and in
    // the multi-scale model (black-box accuracy search).
    let p = params([
        1.000000000000001,
        0.0,
        0.0,
        10.0,
        10.0,
        0.0,
        0.0,
        0.0,
        0.0,
        1.0,
    ]);
    let m = FurModel::new(&p);
    let az = m.azimuthal(0.0);
    for opts in [FarOptions::default(), FarOptions::paper()] {
        let fs = az.far_slice(LobeSet::ALL, &opts);
        for phi in [PI, 2.5, 0.0] {
            let f = fs.eval(phi);
            let r = az.far_reference(phi, LobeSet::ALL);
            assert!(f.0.iter().all(|v| v.is_finite()), "phi {phi}: {f:?}");
            // TT holds all the light here (peak 1.62 at pi): 1e-4 of that peak.
            let tt = Lobe::TT.index();
            assert!(
                (f.0[tt] - r.0[tt]).abs() <= 1e-4 * 1.62,
                "phi {phi}: {f:?} vs {r:?}"
            );
        }
    }
    let p = params([
        1.000000000000001,
        0.98,
        0.0,
        10.0,
        10.0,
        0.0,
        0.0,
        0.0,
        -0.4,
        2.0,
    ]);
    let m = FurModel::new(&p);
    let az = m.azimuthal(-60f64.to_radians());
    let v = az.multiscale(PI, -0.05, 1e-4, LobeSet::ALL, &FarOptions::default());
    assert!(v.0.iter().all(|x| x.is_finite()), "{v:?}");
}

#[test]
fn few_cuticle_layers_resolve_the_grazing_layer() {
    // l = 5e-6: the pile-of-plates F climbs from ~l f / (1 - f) to 1 within ~1e-6 rad of
    // grazing, where R's peak at phi = pi comes from. The initial nodes missed that layer
    // and R was 1.4e-4 of its peak off there (accuracy search); the layer mesh brings it
    // to ~2e-7. 1e-4 of the peak is the tolerance mode's claim.
    let p = params([1.7, 0.0, 0.0, 10.0, 2.0, 0.0, 0.0, 0.0, -0.1, 5e-6]);
    let m = FurModel::new(&p);
    let az = m.azimuthal((-40.0f64).to_radians());
    let fs = az.far_slice(LobeSet::ALL, &FarOptions::default());
    let r = Lobe::R.index();
    let peak = az.far_reference(PI, LobeSet::ALL).0[r];
    for phi in [PI, PI - 0.01, PI - 0.05, 2.0, 0.0] {
        let f = fs.eval(phi).0[r];
        let want = az.far_reference(phi, LobeSet::ALL).0[r];
        assert!(
            (f - want).abs() <= 1e-4 * peak,
            "phi {phi}: {f} vs {want} (peak {peak})"
        );
    }
}

/// Multi-scale ranges within ~1e-3 of h = 1 hold two or three scattered pieces whose error
/// bounds add up at the lobe's peak: 1.3-1.7e-4 of it at tol 1e-4 before
/// `FarSlice::peak_rescale` (accuracy search, 2026-11-28; the reference agreed with 64 x
/// 256-node Gauss-Legendre to 1e-10 there). Held to the mode's 1e-4 of the peak.
#[test]
fn multiscale_scattered_near_grazing_meets_tol() {
    let cases: [([f64; 10], f64, f64, f64); 3] = [
        (
            [
                1.192, 0.744, -4.22, 10.38, 28.09, 0.891, 0.213, 0.461, 0.437, 0.00529,
            ],
            61.12,
            0.999_977_996,
            0.999_997_178,
        ),
        (
            [
                1.388, 0.999, -2.78, 2.311, 6.234, 1.466, 0.0804, 0.633, 0.0237, 0.959,
            ],
            -20.77,
            0.999_616_742,
            0.999_999_838,
        ),
        (
            [
                1.785, 0.999, 3.33, 7.746, 28.81, 0.810, 0.328, 0.689, -0.129, 2.868,
            ],
            -41.17,
            0.999_142_527,
            1.0,
        ),
    ];
    for (v, td, h1, h2) in cases {
        let m = FurModel::new(&params(v));
        let az = m.azimuthal(td.to_radians());
        let fs = FarSlice::range(&az, h1, h2, LobeSet::SCATTERED, &FarOptions::default());
        let (mut peak, mut err) = ([0.0f64; 2], [0.0f64; 2]);
        for k in 0..24 {
            let phi = -PI + 2.0 * PI * (k as f64 + 0.37) / 24.0;
            let (f, r) = (
                fs.eval(phi),
                az.multiscale_reference(phi, h1, h2, LobeSet::SCATTERED),
            );
            for (i, l) in [Lobe::TTs, Lobe::TRTs].into_iter().enumerate() {
                peak[i] = peak[i].max(r.get(l));
                err[i] = err[i].max((f.get(l) - r.get(l)).abs());
            }
        }
        for i in 0..2 {
            assert!(peak[i] > 0.0, "{v:?}");
            assert!(
                err[i] <= 1e-4 * peak[i],
                "theta_d {td}, [{h1}, {h2}], lobe {}: {:.3e} of peak",
                3 + i,
                err[i] / peak[i]
            );
        }
    }
}
