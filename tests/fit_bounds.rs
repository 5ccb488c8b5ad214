//! Bounds: whatever the data, a fit reports parameters inside MODEL.md's hard bounds.

use furfit::fit::forward::{predict_points, Points};
use furfit::fit::problem::FitData;
use furfit::fit::{fit_data, FitOptions};
use furfit::model::far::FarOptions;
use furfit::model::LobeSet;
use furfit::params::{FurParams, ParamId};

fn grid() -> Points {
    let mut p = Points::default();
    for ti in [-20.0f64, 20.0] {
        for k in 0..13 {
            for j in 0..25 {
                let (tr, ph) = (-60.0 + 10.0 * k as f64, -180.0 + 15.0 * j as f64);
                p.push(ti.to_radians(), tr.to_radians(), ph.to_radians());
            }
        }
    }
    p
}

fn quick() -> FitOptions {
    FitOptions {
        n_global: 16,
        n_best: 2,
        max_iters: 40,
        ..FitOptions::default()
    }
}

fn assert_inside(p: &FurParams) {
    p.validate().unwrap();
    for (id, v) in ParamId::ALL.into_iter().zip(p.to_file_units()) {
        assert!(
            id.spec().contains(v),
            "{} = {v} outside {}",
            id.spec().name,
            id.spec().bound_text()
        );
    }
}

#[test]
fn data_at_the_bounds_gives_in_bound_fits() {
    // eta = 3 (closed upper bound), beta_n = 90 (closed upper bound), l = 10: the optimum
    // sits on the bounds, so the solver is pushed against them.
    let mut v = FurParams::preset("dog").unwrap().to_file_units();
    v[ParamId::Eta.index()] = 3.0;
    v[ParamId::BetaN.index()] = 90.0;
    v[ParamId::L.index()] = 10.0;
    let truth = FurParams::from_file_units(v).unwrap();
    let pts = grid();
    let mut m = vec![0.0; pts.len()];
    predict_points(&truth, &pts, &FarOptions::paper(), LobeSet::ALL, &mut m);
    let fit = fit_data(&FitData::new(pts, &m, None), &quick(), None).unwrap();
    assert_inside(&fit.params.fur().unwrap());
}

#[test]
fn featureless_data_gives_in_bound_fits() {
    // A nearly flat profile (a 1 % sawtooth over the samples; an exactly flat one has no
    // log range and is refused) that no parameter set reproduces: roughness is pushed to
    // its maximum, absorption toward 0 or infinity.
    let pts = grid();
    let y: Vec<f64> = (0..pts.len())
        .map(|i| 1.0 + 0.01 * (i % 7) as f64)
        .collect();
    let fit = fit_data(&FitData::new(pts, &y, None), &quick(), None).unwrap();
    assert_inside(&fit.params.fur().unwrap());
    assert!(fit.nrmse.is_finite());
}

#[test]
fn empty_data_is_an_error() {
    let e = fit_data(&FitData::new(Points::default(), &[], None), &quick(), None).unwrap_err();
    assert!(e.to_string().contains("no valid sample"), "{e}");
}
