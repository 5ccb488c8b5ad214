//! Criterion bench of the near-field model: `eval_near` per lobe and all five lobes.
//! Run: `cargo bench --bench model`. Figures are printed by criterion (time per call).

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use furfit::model::{FurModel, Lobe, LobeSet};
use furfit::params::FurParams;

fn bench_eval_near(c: &mut Criterion) {
    let model = FurModel::new(&FurParams::preset("red-fox").unwrap());
    let mut group = c.benchmark_group("eval_near");
    // A spread of queries so branch prediction does not see one constant input.
    let queries: Vec<(f64, f64, f64, f64)> = (0..64)
        .map(|k| {
            let t = k as f64 / 64.0;
            (
                (t * 1.1 - 0.5) * 0.9,
                (0.6 - t) * 1.2,
                -3.1 + 6.2 * t,
                -0.98 + 1.96 * ((k * 37) % 64) as f64 / 64.0,
            )
        })
        .collect();
    let sets: Vec<(&str, LobeSet)> = Lobe::ALL
        .iter()
        .map(|l| (l.name(), LobeSet::only(*l)))
        .chain(std::iter::once(("all5", LobeSet::ALL)))
        .collect();
    for (name, set) in sets {
        group.bench_function(name, |b| {
            let mut i = 0usize;
            b.iter(|| {
                let (ti, tr, phi, h) = queries[i & 63];
                i += 1;
                black_box(model.eval_near(black_box(ti), tr, phi, h, set))
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench_eval_near);
criterion_main!(benches);
