//! Criterion benchmarks of the renderer: one small frame per BCSDF scale (the full
//! 512x512 / 64 spp preview timing is printed by `furfit render`), and the BCSDF sampling
//! + evaluation kernels.

use criterion::{criterion_group, criterion_main, Criterion};
use furfit::model::LobeSet;
use furfit::params::FurParams;
use furfit::render::bsdf::{FiberBsdf, HRange, Mode, Tint};
use furfit::render::{render_scene, RenderSettings, Scene};

fn frames(c: &mut Criterion) {
    let p = FurParams::preset("red-fox").unwrap();
    let base = RenderSettings {
        width: 512,
        height: 512,
        spp: 2,
        region: Some((224, 224, 64, 64)),
        ..RenderSettings::default()
    };
    let scene = Scene::build(&base.strand);
    let mut g = c.benchmark_group("render_64x64_patch_2spp");
    g.sample_size(10);
    for mode in [Mode::Near, Mode::Far, Mode::Multiscale] {
        let s = RenderSettings {
            mode,
            ..base.clone()
        };
        let r = render_scene(&scene, &p, &s).unwrap();
        println!(
            "{}: {:.3} Mrays/s ({} rays in {:.3} s)",
            mode.name(),
            r.rays_per_second() / 1e6,
            r.rays,
            r.seconds
        );
        g.bench_function(mode.name(), |b| {
            b.iter(|| render_scene(&scene, &p, &s).unwrap())
        });
    }
    g.finish();
}

fn kernels(c: &mut Criterion) {
    let p = FurParams::preset("red-fox").unwrap();
    let b = FiberBsdf::new(&p, Tint::default(), LobeSet::ALL);
    c.bench_function("bsdf_sample_near", |bn| {
        let side = b.camera_side(0.3);
        let mut k = 0u64;
        bn.iter(|| {
            k += 1;
            let u = (k as f64 * 0.618_033_988_75).fract();
            b.sample(&side, HRange::At(0.2), [u, 0.5, 1.0 - u, 0.3])
        })
    });
    c.bench_function("bsdf_eval_near", |bn| {
        bn.iter(|| b.eval(0.3, -0.2, 1.0, HRange::At(0.2)))
    });
    c.bench_function("bsdf_eval_far", |bn| {
        bn.iter(|| b.eval(0.3, -0.2, 1.0, HRange::Span(-1.0, 1.0)))
    });
    c.bench_function("bsdf_eval_multiscale", |bn| {
        bn.iter(|| b.eval(0.3, -0.2, 1.0, HRange::Span(0.1, 0.5)))
    });
}

criterion_group!(benches, frames, kernels);
criterion_main!(benches);
