//! The library call `furfit.synth` wraps, timed alone: `furfit::synth::synthesize` of the
//! red-fox preset on the 4 x 61 x 181 grid (theta_i 0,15,30,45; theta_r -60:60:2; phi
//! -180:180:2), as `python/bench/bench_synth.py` times the Python call on the same grid.
//!
//! `cargo run --release -p furfit-python --example bench_synth [REPEATS]` prints one line
//! of JSON: the seconds of every call after a warm-up, their median and minimum. With
//! `--serve` it makes one call per line read from stdin and prints its seconds, so the
//! Python script can alternate call by call (both see the same machine load).

use furfit::model::far::FarOptions;
use furfit::model::LobeSet;
use furfit::models::{Integral, ModelParams};

fn main() {
    let arg = std::env::args().nth(1);
    let serve = arg.as_deref() == Some("--serve");
    let repeats: usize = arg.and_then(|a| a.parse().ok()).unwrap_or(50);
    let model = furfit::models::default_model();
    let p = ModelParams::preset(model, "red-fox").expect("a preset");
    let ti = [0.0, 15.0, 30.0, 45.0];
    let tr: Vec<f64> = (0..61).map(|i| -60.0 + 2.0 * i as f64).collect();
    let phi: Vec<f64> = (0..181).map(|i| -180.0 + 2.0 * i as f64).collect();
    let opts = FarOptions::default();
    let run = || {
        let t = std::time::Instant::now();
        let prof =
            furfit::synth::synthesize(&p, &ti, &tr, &phi, Integral::Far, LobeSet::ALL, 1.0, &opts);
        let dt = t.elapsed().as_secs_f64();
        assert_eq!(prof.samples.len(), 4 * 61 * 181);
        dt
    };
    // Warm-up: the thread pool and the medulla tables.
    for _ in 0..3 {
        run();
    }
    if serve {
        use std::io::{BufRead, Write};
        println!("ready");
        for line in std::io::stdin().lock().lines() {
            if line.is_err() {
                break;
            }
            let mut out = std::io::stdout().lock();
            if writeln!(out, "{:e}", run())
                .and_then(|()| out.flush())
                .is_err()
            {
                break;
            }
        }
        return;
    }
    let mut times: Vec<f64> = (0..repeats).map(|_| run()).collect();
    let raw = times.clone();
    times.sort_by(f64::total_cmp);
    let median = times[times.len() / 2];
    println!(
        "{{\"what\": \"furfit::synth::synthesize\", \"samples\": {}, \"repeats\": {repeats}, \"median_s\": {median:e}, \"min_s\": {:e}, \"times_s\": {:?}}}",
        4 * 61 * 181,
        times[0],
        raw
    );
}
