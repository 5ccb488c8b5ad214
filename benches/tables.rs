//! Query cost of the compressed medulla tables (criterion prints the time per query).
use criterion::{black_box, criterion_group, criterion_main, Criterion};
use furfit::model::medulla::{MedullaTables, Side};

fn bench(c: &mut Criterion) {
    let t = MedullaTables::builtin();
    c.bench_function("medulla slice(tau, g)", |b| {
        b.iter(|| t.slice(black_box(1.7), black_box(0.45)))
    });
    let s = t.slice(1.7, 0.45);
    let mut psi = 0.0f64;
    c.bench_function("medulla cn query", |b| {
        b.iter(|| {
            psi = (psi + 0.37) % 3.1;
            s.cn(black_box(0.31), black_box(psi))
        })
    });
    let mut tr = 0.0f64;
    c.bench_function("medulla cm query", |b| {
        b.iter(|| {
            tr = (tr + 0.13) % 1.5;
            s.cm(black_box(0.4), black_box(tr), Side::Back)
        })
    });
    c.bench_function("medulla cm_lerp query", |b| {
        b.iter(|| {
            tr = (tr + 0.13) % 1.5;
            s.cm_lerp(black_box(0.4), black_box(tr), black_box(2.0))
        })
    });
    c.bench_function("medulla sampler build", |b| {
        b.iter(|| t.slice(black_box(1.7), black_box(0.45)).sampler())
    });
    let sm = s.sampler();
    let mut u = 0.0f64;
    c.bench_function("medulla sample_cn", |b| {
        b.iter(|| {
            u = (u + 0.618_034) % 1.0;
            sm.sample_cn(black_box(0.31), u)
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
