//! Query cost of the compressed medulla tables. Criterion prints wall time per query; on a
//! shared machine that includes time the thread waited for a core, so each group also
//! prints the thread's CPU time per query from `/proc/thread-self/schedstat` (Linux).
use criterion::{black_box, criterion_group, criterion_main, Criterion};
use furfit::model::medulla::{MedullaTables, Side};

/// Nanoseconds this thread has run on a CPU (None off Linux).
fn thread_cpu_ns() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    s.split_whitespace().next()?.parse().ok()
}

/// Print the CPU time per call of `f` over `n` calls.
fn cpu_per_call(name: &str, n: usize, mut f: impl FnMut(usize) -> f64) {
    let mut acc = 0.0;
    let t0 = thread_cpu_ns();
    let w0 = std::time::Instant::now();
    for i in 0..n {
        acc += f(i);
    }
    let wall = w0.elapsed().as_nanos() as f64 / n as f64;
    if let (Some(a), Some(b)) = (t0, thread_cpu_ns()) {
        println!(
            "{name}: {:.1} ns CPU/call, {:.1} ns wall/call over {n} calls (checksum {acc:.3e})",
            (b - a) as f64 / n as f64,
            wall
        );
    }
}

fn bench(c: &mut Criterion) {
    let t = MedullaTables::builtin();
    let s = t.slice(1.7, 0.45);
    let sm = s.sampler();
    cpu_per_call("slice(tau, g)", 200_000, |i| {
        t.slice(1.7 + 1e-6 * i as f64, 0.45).tau
    });
    cpu_per_call("slice + node grids (first query)", 2_000, |i| {
        t.slice(1.7 + 1e-6 * i as f64, 0.45).cn(0.3, 0.2)
    });
    let _ = s.cn(0.3, 0.2); // build the node grids before timing queries
    cpu_per_call("cn", 2_000_000, |i| {
        s.cn(0.31 + 1e-7 * i as f64, (i as f64 * 0.37) % 6.2 - 3.1)
    });
    cpu_per_call(
        "cn_compressed (rank sum of the CP factors)",
        2_000_000,
        |i| s.cn_compressed(0.31 + 1e-7 * i as f64, (i as f64 * 0.37) % 6.2 - 3.1),
    );
    cpu_per_call("cm", 2_000_000, |i| {
        s.cm(0.4, (i as f64 * 0.13) % 3.0 - 1.5, Side::Back)
    });
    cpu_per_call("cm_lerp", 2_000_000, |i| {
        s.cm_lerp(0.4, (i as f64 * 0.13) % 3.0 - 1.5, 2.0)
    });
    cpu_per_call("sampler build", 200, |i| {
        t.slice(1.7 + 1e-6 * i as f64, 0.45)
            .sampler()
            .pdf_cn(0.1, 0.2)
    });
    cpu_per_call("sample_cn", 1_000_000, |i| {
        sm.sample_cn(0.31, (i as f64 * 0.618_034) % 1.0).0
    });

    c.bench_function("medulla slice(tau, g)", |b| {
        b.iter(|| t.slice(black_box(1.7), black_box(0.45)))
    });
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
        b.iter(|| {
            t.slice(black_box(1.7), black_box(0.45))
                .sampler()
                .pdf_cn(0.1, 0.2)
        })
    });
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
