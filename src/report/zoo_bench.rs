//! `furfit bench-model --models`: every registered model side by side in one run. The
//! far-field prediction on the 4 x 61 x 181 grid
//! ([`super::far_error::throughput_grid`]) per model and preset, in the tolerance mode
//! (1e-4) and the fixed rule, as time per sample; then a blind fit of each model (default
//! options) on one species' profile. Prints; writes nothing.

use crate::fit::{channel_data, fit_data, FitOptions, DEFAULT_FLOOR};
use crate::model::far::FarOptions;
use crate::model::LobeSet;
use crate::models::{Integral, Points, MODELS};
use std::path::Path;
use std::time::Instant;

/// Timed runs per model and mode (the best is reported, then the median).
const RUNS: usize = 7;

/// Best and median seconds of [`RUNS`] runs of `f` after one warm-up.
fn time(mut f: impl FnMut()) -> (f64, f64) {
    f();
    let mut t: Vec<f64> = (0..RUNS)
        .map(|_| {
            let s = Instant::now();
            f();
            s.elapsed().as_secs_f64()
        })
        .collect();
    t.sort_by(f64::total_cmp);
    (t[0], t[RUNS / 2])
}

/// Print the throughput of every model and preset on the grid.
pub fn throughput(log: &mut dyn FnMut(&str)) {
    let pts = Points::new(super::far_error::throughput_grid());
    let n = pts.len() as f64;
    log(&format!(
        "far-field prediction, {} samples (4 theta_i x 61 theta_r x 181 phi), {} threads; best (median) of {RUNS}:",
        pts.len(),
        rayon::current_num_threads()
    ));
    for m in MODELS {
        for (mode, far) in [
            ("tol 1e-4", FarOptions::default()),
            ("fixed", FarOptions::paper()),
        ] {
            let mut per = Vec::new();
            for p in m.presets() {
                let v = crate::models::ModelParams::from_file_units(m, p.values)
                    .expect("presets are valid");
                let (best, med) = time(|| {
                    std::hint::black_box(m.predict(
                        &v.values,
                        &pts,
                        &far,
                        LobeSet::ALL,
                        Integral::Far,
                    ));
                });
                per.push((best, med, p.name));
            }
            per.sort_by(|a, b| a.0.total_cmp(&b.0));
            let (fast, slow) = (per[0], per[per.len() - 1]);
            let median = per[per.len() / 2];
            log(&format!(
                "  {:<14} {mode:<8}: {:.3e} samples/s median preset ({}; {:.1} ns/sample, median run {:.1} ns), slowest {:.3e} ({}), fastest {:.3e} ({})",
                m.name(),
                n / median.0,
                median.2,
                1e9 * median.0 / n,
                1e9 * median.1 / n,
                n / slow.0,
                slow.2,
                n / fast.0,
                fast.2
            ));
        }
    }
}

/// Fit every model blind to the profile(s) at `species` (a species folder), one after
/// another in this run, and print wall time, evaluations and NRMSE of each.
pub fn fits(species: &Path, log: &mut dyn FnMut(&str)) -> crate::Result<()> {
    let inputs = crate::fit::job::load_inputs_full(&[species.to_path_buf()], &Default::default())?;
    let data = channel_data(&inputs.profile, 0, false, DEFAULT_FLOOR)?;
    log(&format!(
        "blind fits of {} ({} samples, default options, {} threads):",
        species.display(),
        data.len(),
        rayon::current_num_threads()
    ));
    for m in MODELS {
        let t = Instant::now();
        let o = fit_data(&data, &FitOptions::for_model(m), None)?;
        log(&format!(
            "  {:<14}: {:.2} s wall, {} evaluations ({:.1} ms each on average), NRMSE {:.3}%, {} free parameters",
            m.name(),
            t.elapsed().as_secs_f64(),
            o.evaluations,
            1e3 * o.wall_time_s / o.evaluations.max(1) as f64,
            100.0 * o.nrmse,
            o.uncertainty.free.len()
        ));
    }
    Ok(())
}
