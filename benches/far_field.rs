//! Criterion benches: far field of all five lobes per (theta pair, phi) in the default
//! (tol 1e-4) and paper (8/5) modes vs Gauss-Legendre quadrature of the near field, and
//! grid synthesis throughput on a 4 x 61 x 181 grid.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use furfit::model::far::FarOptions;
use furfit::model::{FurModel, LobeSet};
use furfit::synth::predict;
use furfit::FurParams;
use std::hint::black_box;

fn far_field(c: &mut Criterion) {
    let m = FurModel::new(&FurParams::preset("red-fox").unwrap());
    let (ti, tr) = (0.3, -0.1);
    let mut g = c.benchmark_group("five_lobes_one_sample");
    g.bench_function("far_default_tol1e-4", |b| {
        let o = FarOptions::default();
        b.iter(|| m.eval_far(black_box(ti), tr, black_box(1.0), LobeSet::ALL, &o))
    });
    g.bench_function("far_paper_8_5", |b| {
        let o = FarOptions::paper();
        b.iter(|| m.eval_far(black_box(ti), tr, black_box(1.0), LobeSet::ALL, &o))
    });
    for n in [32usize, 64, 128] {
        g.bench_function(format!("gauss_legendre_{n}"), |b| {
            let az = m.azimuthal(0.5 * (tr - ti));
            b.iter(|| az.far_gl(black_box(1.0), n, LobeSet::ALL))
        });
    }
    g.finish();
}

fn synth_grid(c: &mut Criterion) {
    let m = FurModel::new(&FurParams::preset("red-fox").unwrap());
    let pts = furfit::report::far_error::throughput_grid();
    let mut g = c.benchmark_group("synth_grid_4x61x181");
    g.sample_size(10);
    g.throughput(Throughput::Elements(pts.len() as u64));
    for (name, o) in [
        ("default", FarOptions::default()),
        ("paper", FarOptions::paper()),
    ] {
        g.bench_function(name, |b| {
            b.iter(|| predict(&m, black_box(&pts), LobeSet::ALL, &o))
        });
    }
    g.finish();
}

criterion_group!(benches, far_field, synth_grid);
criterion_main!(benches);
