//! Criterion benches of the fitter's inner loop on a 15,066-sample profile
//! (6 theta_i x 81 theta_r x 31 phi): one residual evaluation and one finite-difference
//! Jacobian. The whole-fit timing (multi-start included) is printed by
//! `furfit fit --bench <profile>` (see the fit module docs / report).

use criterion::{criterion_group, criterion_main, Criterion};
use furfit::fit::forward::{predict_points, Points};
use furfit::fit::problem::{FitData, LogResidualProblem, ParamLayout};
use furfit::model::far::FarOptions;
use furfit::model::LobeSet;
use furfit::FurParams;
use nalgebra::DVector;

fn profile() -> FitData {
    let mut pts = Points::default();
    for ti in [-45.0f64, -25.0, -5.0, 15.0, 35.0, 55.0] {
        for k in 0..81 {
            for j in 0..31 {
                let (tr, ph) = (-80.0 + 2.0 * k as f64, -180.0 + 12.0 * j as f64);
                pts.push(ti.to_radians(), tr.to_radians(), ph.to_radians());
            }
        }
    }
    let truth = FurParams::preset("red-fox").unwrap();
    let mut y = vec![0.0; pts.len()];
    predict_points(&truth, &pts, &FarOptions::paper(), LobeSet::ALL, &mut y);
    FitData::new(pts, &y, None)
}

fn bench(c: &mut Criterion) {
    let data = profile();
    let prob = LogResidualProblem::new(
        &data,
        ParamLayout::all_free(furfit::models::default_model()),
        FarOptions::paper(),
    );
    let start = FurParams::preset("cat").unwrap().to_file_units();
    let u = DVector::from_vec(prob.layout.to_u(&start));
    let mut g = c.benchmark_group("fit_15066_samples");
    g.sample_size(10);
    g.bench_function("residuals", |b| b.iter(|| prob.residuals(u.as_slice())));
    g.bench_function("jacobian_fd", |b| b.iter(|| prob.jacobian_at(&u)));
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
