//! Every registered model recovers itself: a profile synthesised by the model from one of
//! its presets, with 2 % log-normal noise, fitted blind (default options, automatic starts)
//! reaches the noise floor and gives back the parameters within their standard errors.

use furfit::fit::forward::{predict_model, Points};
use furfit::fit::problem::{nrmse, FitData};
use furfit::fit::{fit_data, FitOptions};
use furfit::model::far::FarOptions;
use furfit::models::{FiberModel, ModelParams, MODELS};
use rand::{Rng, SeedableRng};

/// Log-normal noise: 2 % standard deviation of ln(value).
const NOISE: f64 = 0.02;
/// Detector floor relative to the peak (the shipped data's is 1e-3): the models' far tails
/// run to e^-100, which no goniometer records and which would outweigh the lobes.
const FLOOR: f64 = 1e-4;

/// Standard normal by Box-Muller (rand 0.9 has no normal without rand_distr).
fn normal(rng: &mut impl Rng) -> f64 {
    let u1: f64 = rng.random::<f64>().max(1e-300);
    let u2: f64 = rng.random();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// 4 theta_i x 31 theta_r x 45 phi (5 580 samples before the floor).
fn grid() -> Points {
    let tr: Vec<f64> = (0..31).map(|k| -75.0 + 5.0 * k as f64).collect();
    let phi: Vec<f64> = (0..45).map(|j| -180.0 + 8.0 * j as f64).collect();
    Points::grid_degrees(&[-30.0, 0.0, 20.0, 45.0], &tr, &phi)
}

/// The noisy profile of `truth` and its noise-floor NRMSE (the truth's own on the data).
fn noisy(truth: &ModelParams, seed: u64) -> (FitData, f64) {
    let all = grid();
    let mut m = vec![0.0; all.len()];
    predict_model(truth, &all, &FarOptions::default(), &mut m);
    let peak = m.iter().cloned().fold(0.0f64, f64::max);
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(seed);
    let (mut pts, mut y, mut clean) = (Points::default(), Vec::new(), Vec::new());
    for (&(ti, tr, ph), &v) in all.pts.iter().zip(&m) {
        let e = (NOISE * normal(&mut rng)).exp();
        if v >= FLOOR * peak {
            pts.push(ti, tr, ph);
            y.push(3.0 * v * e);
            clean.push(v);
        }
    }
    let data = FitData::new(pts, &y, None);
    let floor = nrmse(&clean, &data.ln_y, data.range).0;
    (data, floor)
}

fn recovers(model: &'static dyn FiberModel, preset: usize, seed: u64) {
    let p = &model.presets()[preset];
    let truth = ModelParams::from_file_units(model, p.values).unwrap();
    let (data, floor) = noisy(&truth, seed);
    let fit = fit_data(&data, &FitOptions::for_model(model), None).unwrap();
    let who = format!("{} preset {}", model.name(), p.name);
    // The optimum fits the noise at least as well as the truth does, up to the solver's
    // stopping tolerance; 5 % above the floor is the bound.
    assert!(
        fit.nrmse <= 1.05 * floor,
        "{who}: NRMSE {} vs noise floor {floor}",
        fit.nrmse
    );
    let got = fit.params.to_file_units();
    for (i, s) in model.specs().iter().enumerate() {
        let flagged = fit
            .uncertainty
            .unconstrained
            .iter()
            .any(|(q, _)| q.index == i);
        let Some(se) = fit.uncertainty.se[i].filter(|_| !flagged) else {
            continue;
        };
        // Three standard errors: ten or so parameters each within 3 SE fail together by
        // chance about 3 % of the time for exact Gaussian errors (fixed seed: this is a
        // check of the pipeline, not a random test), while a wrong map, unit or
        // derivative puts a parameter tens of SEs off.
        let z = (got[i] - p.values[i]).abs() / se.max(1e-12 * p.values[i].abs().max(1.0));
        assert!(
            z <= 3.0,
            "{who}: {} = {} vs truth {} (SE {se}, {z:.1} SE off)",
            s.name,
            got[i],
            p.values[i]
        );
    }
}

#[test]
fn every_model_recovers_its_own_noisy_profile() {
    for m in MODELS {
        recovers(m, 0, 7);
    }
}
