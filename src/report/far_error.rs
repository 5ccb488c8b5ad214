//! `furfit bench-model`: far-field error versus evaluation time, beside Gauss-Legendre
//! quadrature of the near field. Writes `far_field_error_vs_time.{csv,png,svg,md}`.
//!
//! Test set: presets red-fox, human, dog, mouse x theta_d {0, 30, 60} deg x 48 phi. Error
//! of a method = max over the set of `|N - N_ref| / (peak over phi of N_ref)` (per preset,
//! theta_d and lobe), also the median. Time = one evaluation of all five lobes at one
//! `(theta pair, phi)`: "single" builds the far-field slice for that call (what
//! `eval_far` costs), "amortised" shares the slice across the 48 phi of a theta_d (what
//! grid prediction costs). Gauss-Legendre has no per-theta_d precomputation.
#![allow(clippy::needless_range_loop)] // fixed-size per-lobe arrays read clearer indexed

use crate::model::far::FarOptions;
use crate::model::{AzimuthalSlice, FurModel, LobeSet, LobeValues};
use crate::params::FurParams;
use crate::report::plot::{loglog_chart, ChartSpec, Series};
use std::f64::consts::PI;
use std::fmt::Write as _;
use std::hint::black_box;
use std::path::Path;
use std::time::Instant;

const PRESETS: [&str; 4] = ["red-fox", "human", "dog", "mouse"];
const THETA_D: [f64; 3] = [0.0, 30.0, 60.0];
const N_PHI: usize = 48;
const GL_POINTS: [usize; 10] = [8, 12, 16, 24, 32, 48, 64, 80, 96, 128];
const TOLS: [f64; 5] = [1e-2, 1e-3, 1e-4, 1e-5, 1e-6];

/// One row of the report.
#[derive(Clone, Debug)]
pub struct Row {
    /// `Gauss-Legendre` or the far-field mode measured.
    pub method: String,
    /// The method's setting: node count or tolerance.
    pub setting: String,
    /// Largest error over the test set, relative to the peak over phi of `N_ref`.
    pub max_err: f64,
    /// Median of that error over the test set.
    pub median_err: f64,
    /// The max error per lobe (R, TT, TRT, TTs, TRTs): how far each lobe stays inside a
    /// tolerance.
    pub max_err_lobe: [f64; 5],
    /// Microseconds per evaluation of all five lobes, slice built per call.
    pub us_single: f64,
    /// Microseconds per evaluation with the slice shared over a theta_d's 48 phi.
    pub us_amortised: f64,
    /// The far-field options measured (`None` for Gauss-Legendre).
    pub opts: Option<FarOptions>,
}

struct Set {
    models: Vec<FurModel>,
    phis: Vec<f64>,
    /// `reference[model][theta_d][phi]`
    reference: Vec<Vec<Vec<LobeValues>>>,
}

/// Max and median error over the set, and the max per lobe.
fn errors(set: &Set, vals: &[Vec<Vec<LobeValues>>]) -> (f64, f64, [f64; 5]) {
    let mut all = Vec::new();
    let mut lobe = [0.0f64; 5];
    for (m, per_td) in vals.iter().enumerate() {
        for (t, row) in per_td.iter().enumerate() {
            let rf = &set.reference[m][t];
            for i in 0..5 {
                let peak = rf.iter().map(|v| v.0[i]).fold(0.0, f64::max);
                if peak <= 0.0 {
                    continue;
                }
                for (v, r) in row.iter().zip(rf) {
                    let e = (v.0[i] - r.0[i]).abs() / peak;
                    lobe[i] = lobe[i].max(e);
                    all.push(e);
                }
            }
        }
    }
    all.sort_by(|a, b| a.total_cmp(b));
    let max = all.last().copied().unwrap_or(0.0);
    let med = all.get(all.len() / 2).copied().unwrap_or(0.0);
    (max, med, lobe)
}

/// The far field with `opts`, one call per `phi` (what `eval_far` costs).
fn far_single(opts: &FarOptions) -> impl Fn(&AzimuthalSlice, f64) -> LobeValues + '_ {
    move |az: &AzimuthalSlice, phi: f64| az.far(phi, LobeSet::ALL, opts)
}

/// The far field with `opts`, one slice per theta_d evaluated at all its `phi`, exactly
/// as grid prediction (`synth`, the fitter) does it ([`crate::synth::far_many`]).
fn far_amortised(opts: &FarOptions) -> impl Fn(&AzimuthalSlice, &[f64]) -> Vec<LobeValues> + '_ {
    move |az: &AzimuthalSlice, phis: &[f64]| crate::synth::far_many(az, LobeSet::ALL, opts, phis)
}

/// [`measure`] for the far field with `opts`.
fn measure_far(set: &Set, reps: usize, opts: &FarOptions) -> (Vec<Vec<Vec<LobeValues>>>, f64, f64) {
    measure(set, reps, far_single(opts), far_amortised(opts))
}

/// Evaluate a method over the set; returns values and (single, amortised) microseconds
/// per five-lobe evaluation (best of `reps` timing passes).
fn measure<F, G>(
    set: &Set,
    reps: usize,
    single: F,
    amortised: G,
) -> (Vec<Vec<Vec<LobeValues>>>, f64, f64)
where
    F: Fn(&AzimuthalSlice, f64) -> LobeValues,
    G: Fn(&AzimuthalSlice, &[f64]) -> Vec<LobeValues>,
{
    let mut vals = Vec::new();
    for m in &set.models {
        let mut per_td = Vec::new();
        for td in THETA_D {
            let az = m.azimuthal(td.to_radians());
            per_td.push(amortised(&az, &set.phis));
        }
        vals.push(per_td);
    }
    let mut best_s = f64::INFINITY;
    let mut best_a = f64::INFINITY;
    for _ in 0..reps {
        best_s = best_s.min(time_single(set, &single));
        best_a = best_a.min(time_amortised(set, &amortised));
    }
    (vals, best_s, best_a)
}

/// Evaluations in one pass over the set.
fn evals(set: &Set) -> f64 {
    (set.models.len() * THETA_D.len() * set.phis.len()) as f64
}

/// One pass of per-`phi` calls over the set: microseconds per evaluation.
fn time_single<F: Fn(&AzimuthalSlice, f64) -> LobeValues>(set: &Set, single: &F) -> f64 {
    let t = Instant::now();
    for m in &set.models {
        for td in THETA_D {
            let az = m.azimuthal(td.to_radians());
            for &phi in &set.phis {
                black_box(single(&az, phi));
            }
        }
    }
    t.elapsed().as_secs_f64() * 1e6 / evals(set)
}

/// One pass of per-`theta_d` batch calls over the set: microseconds per evaluation.
fn time_amortised<G: Fn(&AzimuthalSlice, &[f64]) -> Vec<LobeValues>>(
    set: &Set,
    amortised: &G,
) -> f64 {
    let t = Instant::now();
    for m in &set.models {
        for td in THETA_D {
            let az = m.azimuthal(td.to_radians());
            black_box(amortised(&az, &set.phis));
        }
    }
    t.elapsed().as_secs_f64() * 1e6 / evals(set)
}

/// Larger Gauss-Legendre rules tried (errors only, not plotted) when none of
/// [`GL_POINTS`] reaches a far-field setting's error.
const GL_POINTS_SEARCH: [usize; 16] = [
    192, 256, 384, 512, 768, 1024, 1536, 2048, 3072, 4096, 6144, 8192, 12288, 16384, 24576, 32768,
];

/// The first rule of [`GL_POINTS_SEARCH`] whose max error over the set is at most
/// `target`, then the first passing one on a finer ladder (steps of 1/32 of it) up from
/// the previous rule, so the rule found, and so the speedup, is within ~3 % of the
/// smallest (GL's cost is linear in `N`). With its error.
fn gl_reaching(set: &Set, target: f64) -> Option<(usize, f64)> {
    let passes = |n: usize| {
        let e = gl_error(set, n);
        (e <= target).then_some((n, e))
    };
    let (k, found) = GL_POINTS_SEARCH
        .iter()
        .enumerate()
        .find_map(|(k, &n)| Some((k, passes(n)?)))?;
    let hi = GL_POINTS_SEARCH[k];
    let lo = if k == 0 {
        *GL_POINTS.last().expect("non-empty")
    } else {
        GL_POINTS_SEARCH[k - 1]
    };
    let step = (hi / 32).max(1);
    // Rungs below `hi` only: `hi`'s error is already known.
    (lo + step..hi)
        .step_by(step)
        .find_map(passes)
        .or(Some(found))
}

/// Max error over the set of `n`-point Gauss-Legendre.
fn gl_error(set: &Set, n: usize) -> f64 {
    let vals = per_sample(&set.models, &set.phis, |az, p| {
        az.far_gl(p, n, LobeSet::ALL)
    });
    errors(set, &vals).0
}

/// `R 1.0e-5  TT ...` for a per-lobe array.
fn lobe_list(v: &[f64; 5]) -> String {
    crate::model::Lobe::ALL
        .iter()
        .map(|l| format!("{} {:.1e}", l.name(), v[l.index()]))
        .collect::<Vec<_>>()
        .join("  ")
}

/// `f` at every (model, theta_d, phi) of the set, models in parallel.
fn per_sample<F>(models: &[FurModel], phis: &[f64], f: F) -> Vec<Vec<Vec<LobeValues>>>
where
    F: Fn(&AzimuthalSlice, f64) -> LobeValues + Sync,
{
    use rayon::prelude::*;
    models
        .par_iter()
        .map(|m| {
            THETA_D
                .iter()
                .map(|td| {
                    let az = m.azimuthal(td.to_radians());
                    phis.iter().map(|&p| f(&az, p)).collect()
                })
                .collect()
        })
        .collect()
}

/// Rounds of [`head_to_head`]: an odd count, so the median is one round's ratio.
const H2H_ROUNDS: usize = 9;

/// Time ratio of `n`-point Gauss-Legendre over the far field with `opts` (single call,
/// amortised), as the median over [`H2H_ROUNDS`] rounds that time both back to back: a
/// slowdown of the shared machine then hits both sides of a ratio, where the table's
/// separate best-of-3 timings, minutes apart, moved these ratios by +-50% between runs.
fn head_to_head(set: &Set, opts: &FarOptions, n: usize) -> (f64, f64) {
    let (far_s, far_a) = (far_single(opts), far_amortised(opts));
    let gl_s = |az: &AzimuthalSlice, phi: f64| az.far_gl(phi, n, LobeSet::ALL);
    let mut rs = Vec::new();
    let mut ra = Vec::new();
    for _ in 0..H2H_ROUNDS {
        rs.push(time_single(set, &gl_s) / time_single(set, &far_s));
        // Gauss-Legendre has no per-theta_d precomputation: its amortised pass is its
        // per-phi pass.
        ra.push(time_single(set, &gl_s) / time_amortised(set, &far_a));
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    (median(&mut rs), median(&mut ra))
}

/// Run the benchmark and write `far_field_error_vs_time.{csv,png,svg,md}` into `out`.
/// Returns the rows.
pub fn run(out: &Path, outer_log: &mut dyn FnMut(&str)) -> crate::Result<Vec<Row>> {
    // Every printed line is also kept for far_field_error_vs_time.md (what the files ran on).
    let mut lines: Vec<String> = Vec::new();
    let t_run = Instant::now();
    let rows = {
        let mut tee = |l: &str| {
            lines.push(l.to_string());
            outer_log(l);
        };
        let log: &mut dyn FnMut(&str) = &mut tee;
        let set = test_set(log);
        let rows = measure_rows(&set, log);
        log_speedups(&set, &rows, log);
        synth_throughput(log);
        rows
    };
    let log = outer_log;
    write_files(out, &rows, &lines, t_run, log)?;
    Ok(rows)
}

/// The test set: the presets' models, the `phi` grid and the reference values (adaptive
/// Gauss-Kronrod), timed in the log.
fn test_set(log: &mut dyn FnMut(&str)) -> Set {
    let models: Vec<FurModel> = PRESETS
        .iter()
        .map(|n| FurModel::new(&FurParams::preset(n).expect("shipped preset")))
        .collect();
    let phis: Vec<f64> = (0..N_PHI)
        .map(|k| -PI + 2.0 * PI * (k as f64 + 0.37) / N_PHI as f64)
        .collect();
    log(&format!(
        "reference (adaptive Gauss-Kronrod, ~1e-10) on {} presets x {} theta_d x {} phi ...",
        PRESETS.len(),
        THETA_D.len(),
        N_PHI
    ));
    let t0 = Instant::now();
    let reference = per_sample(&models, &phis, |az, p| az.far_reference(p, LobeSet::ALL));
    log(&format!("  done in {:.1} s", t0.elapsed().as_secs_f64()));
    Set {
        models,
        phis,
        reference,
    }
}

/// Score one measured method against `set`: its errors, logged (per lobe too for the
/// tolerance modes), as a new row; `r` is its values and timings from [`measure`].
fn push_row(
    set: &Set,
    rows: &mut Vec<Row>,
    method: &str,
    setting: String,
    r: (Vec<Vec<Vec<LobeValues>>>, f64, f64),
    opts: Option<FarOptions>,
    log: &mut dyn FnMut(&str),
) {
    let (max_err, median_err, max_err_lobe) = errors(set, &r.0);
    log(&format!(
            "{method:<12} {setting:<10} max err {max_err:.2e}  median {median_err:.2e}  {:.2} us/eval single, {:.2} us amortised",
            r.1, r.2
        ));
    if method.starts_with("far-tol") {
        log(&format!("  max err per lobe: {}", lobe_list(&max_err_lobe)));
    }
    rows.push(Row {
        method: method.into(),
        setting,
        max_err,
        median_err,
        max_err_lobe,
        us_single: r.1,
        us_amortised: r.2,
        opts,
    });
}

/// The table's rows: the far field with fixed segments and in its tolerance modes, then
/// Gauss-Legendre of the near field, each scored by [`push_row`].
fn measure_rows(set: &Set, log: &mut dyn FnMut(&str)) -> Vec<Row> {
    let mut rows = Vec::new();
    let reps = 3;
    for n in 1..=16usize {
        let opts = FarOptions {
            n_unscattered: n,
            n_scattered: n,
            tol: None,
            ..FarOptions::paper()
        };
        let r = measure_far(set, reps, &opts);
        push_row(
            set,
            &mut rows,
            "far-fixed",
            format!("n={n}"),
            r,
            Some(opts),
            log,
        );
    }
    for (method, base) in [
        ("far-tol", FarOptions::default()),
        ("far-tol-strict", FarOptions::strict()),
    ] {
        for tol in TOLS {
            let opts = FarOptions {
                tol: Some(tol),
                ..base
            };
            let r = measure_far(set, reps, &opts);
            push_row(
                set,
                &mut rows,
                method,
                format!("tol={tol:.0e}"),
                r,
                Some(opts),
                log,
            );
        }
    }
    for n in GL_POINTS {
        let r = measure(
            set,
            reps,
            |az, phi| az.far_gl(phi, n, LobeSet::ALL),
            |az, phis| {
                phis.iter()
                    .map(|&p| az.far_gl(p, n, LobeSet::ALL))
                    .collect()
            },
        );
        push_row(
            set,
            &mut rows,
            "gauss-legendre",
            format!("N={n}"),
            r,
            None,
            log,
        );
    }
    rows
}

/// Log the speedup at equal error of the rows the goal is stated for: the cheapest
/// Gauss-Legendre rule at least as accurate, timed [`head_to_head`].
fn log_speedups(set: &Set, rows: &[Row], log: &mut dyn FnMut(&str)) {
    let gl: Vec<&Row> = rows
        .iter()
        .filter(|r| r.method == "gauss-legendre")
        .collect();
    // The rows the goal is stated for.
    let compared = [
        ("far-fixed", "n=8"),
        ("far-tol", "tol=1e-4"),
        ("far-tol-strict", "tol=1e-4"),
    ];
    for (method, setting) in compared {
        let Some((r, opts)) = rows
            .iter()
            .find(|r| r.method == method && r.setting == setting)
            .and_then(|r| Some((r, r.opts?)))
        else {
            continue;
        };
        // The cheapest rule at least as accurate: among the plotted ones, else among
        // larger rules searched for the comparison only, else the largest (a bound).
        let found = match gl.iter().position(|g| g.max_err <= r.max_err) {
            Some(k) => Some((GL_POINTS[k], gl[k].max_err)),
            None => gl_reaching(set, r.max_err),
        };
        let (n, what) = match found {
            Some((n, err)) => (
                n,
                format!("Gauss-Legendre needs N={n} for max err <= that ({err:.2e})"),
            ),
            None => {
                let n = *GL_POINTS_SEARCH.last().expect("non-empty");
                (
                    n,
                    format!(
                        "no Gauss-Legendre rule up to N={n} reaches it; vs that rule, a lower bound"
                    ),
                )
            }
        };
        let (xs, xa) = head_to_head(set, &opts, n);
        log(&format!(
            "speedup {method} {setting} (max err {:.2e}): {what}: {xs:.1}x single, {xa:.1}x amortised (median of {H2H_ROUNDS} interleaved rounds)",
            r.max_err
        ));
    }
}

/// Write the CSV, the chart (PNG, SVG) and the markdown with the run's printed `lines`
/// (`t_run`: when the run started), and log where.
fn write_files(
    out: &Path,
    rows: &[Row],
    lines: &[String],
    t_run: Instant,
    log: &mut dyn FnMut(&str),
) -> crate::Result<()> {
    let mut csv = String::from(
        "method,setting,max_rel_err,median_rel_err,us_per_eval_single,us_per_eval_amortised,max_rel_err_R,max_rel_err_TT,max_rel_err_TRT,max_rel_err_TTs,max_rel_err_TRTs\n",
    );
    for r in rows {
        let _ = writeln!(
            csv,
            "{},{},{:.4e},{:.4e},{:.4},{:.4},{}",
            r.method,
            r.setting,
            r.max_err,
            r.median_err,
            r.us_single,
            r.us_amortised,
            r.max_err_lobe.map(|e| format!("{e:.4e}")).join(",")
        );
    }
    // The report's four files land together, each listed in the ledger as it lands.
    let mut files = vec![(out.join("far_field_error_vs_time.csv"), csv.into_bytes())];
    let series_of = |method: &str, amortised: bool, name: &str| Series {
        name: name.into(),
        points: rows
            .iter()
            .filter(|r| r.method == method)
            .map(|r| {
                (
                    if amortised {
                        r.us_amortised
                    } else {
                        r.us_single
                    },
                    r.max_err,
                )
            })
            .collect(),
        markers: true,
    };
    let series = vec![
        series_of(
            "far-fixed",
            true,
            "far field, n = 1..16 segments (amortised)",
        ),
        series_of("far-fixed", false, "far field, n = 1..16 (single call)"),
        series_of("far-tol", true, "far field, tol 1e-2..1e-6 (amortised)"),
        series_of("far-tol", false, "far field, tol (single call)"),
        series_of(
            "far-tol-strict",
            true,
            "far field, tol, strict scattered step (amortised)",
        ),
        series_of(
            "gauss-legendre",
            false,
            "Gauss-Legendre of near field, N = 8..128",
        ),
    ];
    files.extend(loglog_chart(
        Some(&out.join("far_field_error_vs_time.png")),
        Some(&out.join("far_field_error_vs_time.svg")),
        &ChartSpec {
            title: "Far field: max error (rel. to lobe peak) vs time per 5-lobe evaluation",
            x_label: "microseconds per evaluation (all five lobes)",
            y_label: "max |N - N_ref| / peak",
            width: 960,
            height: 640,
        },
        &series,
    )?);
    let md = format!(
        "# Far-field error vs evaluation time\n\n\
         Written by `furfit bench-model` ({}) in {:.0} s on {} thread(s); the timings depend on \
         the machine and its load. Test set: the far field of the presets {} at theta_d {} \
         deg, {N_PHI} phi each, against adaptive Gauss-Kronrod quadrature of the near field \
         (~1e-10); error = |N - N_ref| / (the reference's peak over phi for that theta_d and \
         lobe), all five lobes. Figures: `far_field_error_vs_time.{{csv,png,svg}}`.\n\n\
         What the run printed:\n\n```text\n{}\n```\n",
        crate::TOOL_VERSION,
        t_run.elapsed().as_secs_f64(),
        rayon::current_num_threads(),
        PRESETS.join(", "),
        THETA_D
            .iter()
            .map(|t| format!("{t:.0}"))
            .collect::<Vec<_>>()
            .join(", "),
        lines.join("\n")
    );
    files.push((out.join("far_field_error_vs_time.md"), md.into_bytes()));
    crate::io::write_outputs(&files)?;
    log(&format!(
        "wrote {}/far_field_error_vs_time.{{csv,png,svg,md}}",
        out.display()
    ));
    Ok(())
}

/// The issue's synthesis benchmark grid (radians): theta_i 0, 15, 30, 45 deg, theta_r
/// -60..60 deg step 2 (61), phi -180..180 deg step 2 (181). Shared with `benches/far_field.rs`.
pub fn throughput_grid() -> Vec<(f64, f64, f64)> {
    let tr: Vec<f64> = (0..61).map(|k| -60.0 + 2.0 * k as f64).collect();
    let phi: Vec<f64> = (0..181).map(|j| -180.0 + 2.0 * j as f64).collect();
    crate::synth::grid_points(&[0.0, 15.0, 30.0, 45.0], &tr, &phi)
        .into_iter()
        .map(|(a, b, c)| (a.to_radians(), b.to_radians(), c.to_radians()))
        .collect()
}

/// Timed runs per mode of [`synth_throughput`] (each takes milliseconds).
pub const SYNTH_RUNS: usize = 21;

/// The tolerances [`synth_throughput`] times: the default first, then looser ones, which
/// show how much of the default's cost the tolerance sets (the rest is the segmentation,
/// the error checks' fixed part and the evaluation, which no tolerance removes).
const SYNTH_TOLS: [f64; 3] = [1e-4, 1e-3, 1e-2];

/// Print the throughput of grid synthesis (what `furfit synth` and the fitter do) on the
/// issue's 4 x 61 x 181 grid for every preset of seed Table 4, in the paper's fixed
/// segments and the tolerance mode (and, for red fox and human, the strict scattered
/// step), on the current rayon pool: the best and the median of [`SYNTH_RUNS`] runs after
/// one warm-up (machines are noisy: on a shared 2-core machine the median ran 1.2-1.4x
/// the best), then the spread of the tolerance mode's best over the presets, at the
/// default tolerance and the looser ones of [`SYNTH_TOLS`]. The cost grows as `beta_n`
/// shrinks (more pieces resolve a narrower lobe), so the presets span a range rather
/// than one figure.
pub fn synth_throughput(log: &mut dyn FnMut(&str)) {
    let pts = throughput_grid();
    // The plan (the grid's distinct theta_d, phi and theta pairs) is built once per grid:
    // `synth` pays it once, the fitter once per fit. Timed apart from the evaluation.
    let mut plan_t: Vec<f64> = (0..SYNTH_RUNS)
        .map(|_| {
            let t = Instant::now();
            black_box(crate::synth::GridPlan::new(black_box(&pts)));
            t.elapsed().as_secs_f64()
        })
        .collect();
    plan_t.sort_by(f64::total_cmp);
    let plan = crate::synth::GridPlan::new(&pts);
    log(&format!(
        "synth plan of the 4 x 61 x 181 grid ({} slices): {:.4} s once per grid on one thread (best of {SYNTH_RUNS}; median {:.4}), not in the rates below",
        plan.slices(),
        plan_t[0],
        plan_t[SYNTH_RUNS / 2]
    ));
    // Per tolerance of SYNTH_TOLS: (samples/s, preset) over the presets.
    let mut tol_rates: Vec<Vec<(f64, &str)>> = vec![Vec::new(); SYNTH_TOLS.len()];
    for name in crate::params::preset_names() {
        let model = FurModel::new(&FurParams::preset(name).expect("shipped preset"));
        // (label, options, index into SYNTH_TOLS for the tolerance ladder).
        let mut modes = vec![
            ("paper 8/5".to_string(), FarOptions::paper(), None),
            (
                format!("tol {:.0e}", SYNTH_TOLS[0]),
                FarOptions::default(),
                Some(0),
            ),
        ];
        if matches!(name, "red-fox" | "human") {
            modes.push(("tol 1e-4 strict".to_string(), FarOptions::strict(), None));
        }
        // Looser tolerances: how much of the cost the tolerance itself sets.
        for (k, &t) in SYNTH_TOLS.iter().enumerate().skip(1) {
            let opts = FarOptions {
                tol: Some(t),
                ..FarOptions::default()
            };
            modes.push((format!("tol {t:.0e}"), opts, Some(k)));
        }
        for (mode, opts, ladder) in modes {
            let run = || {
                let t = Instant::now();
                let v = plan.predict(&model, LobeSet::ALL, crate::synth::ModelKind::Far, &opts);
                black_box(v);
                t.elapsed().as_secs_f64()
            };
            run();
            let mut t: Vec<f64> = (0..SYNTH_RUNS).map(|_| run()).collect();
            t.sort_by(f64::total_cmp);
            let (best, median) = (t[0], t[SYNTH_RUNS / 2]);
            if let Some(k) = ladder {
                tol_rates[k].push((pts.len() as f64 / best, name));
            }
            log(&format!(
                "synth {name} {mode}: 4 x 61 x 181 = {} samples in {:.4} s on {} threads = {:.3e} samples/s (best of {SYNTH_RUNS}; median {:.3e})",
                pts.len(),
                best,
                rayon::current_num_threads(),
                pts.len() as f64 / best,
                pts.len() as f64 / median
            ));
            // The breakdown for the modes the goal and the paper are stated for.
            if ladder.is_none_or(|k| k == 0) {
                log(&slice_breakdown(&model, &plan, &opts));
            }
        }
    }
    for (rates, tol) in tol_rates.iter_mut().zip(SYNTH_TOLS) {
        rates.sort_by(|a, b| a.0.total_cmp(&b.0));
        if let (Some(lo), Some(hi)) = (rates.first(), rates.last()) {
            let mid = rates[rates.len() / 2];
            log(&format!(
                "synth tol {tol:.0e} over the {} presets (best of {SYNTH_RUNS} each): slowest {:.3e} samples/s ({}), median {:.3e} ({}), fastest {:.3e} ({}); {} of {} at 1e7 or more",
                rates.len(),
                lo.0,
                lo.1,
                mid.0,
                mid.1,
                hi.0,
                hi.1,
                rates.iter().filter(|r| r.0 >= 1e7).count(),
                rates.len()
            ));
        }
    }
}

/// Where a grid synthesis spends its time, on one thread: per `|theta_d|` slice of
/// `plan`, the mean slice build (segmentation and fits) and evaluation at its `|phi|`
/// (best of three passes over all slices), and the mean quadrature pieces and nodes per
/// slice, in all and per lobe (with the closed-form pieces). At 1e7 samples/s on two
/// cores the 4 x 61 x 181 grid allows about 85 us per slice on each (a budget, not a
/// measurement).
fn slice_breakdown(model: &FurModel, plan: &crate::synth::GridPlan, opts: &FarOptions) -> String {
    use crate::model::far::FarSlice;
    let groups = plan.groups();
    let (mut build, mut eval) = (f64::INFINITY, f64::INFINITY);
    for _ in 0..3 {
        let (mut b, mut e) = (0.0, 0.0);
        for (td, phis) in groups {
            let az = model.azimuthal(*td);
            let t = Instant::now();
            let slice = FarSlice::far(&az, LobeSet::ALL, opts);
            b += t.elapsed().as_secs_f64();
            let t = Instant::now();
            black_box(slice.eval_grid(phis));
            e += t.elapsed().as_secs_f64();
        }
        build = build.min(b);
        eval = eval.min(e);
    }
    let mut per_lobe = [crate::model::far::LobeWork::default(); 5];
    for (td, _) in groups {
        let s = FarSlice::far(&model.azimuthal(*td), LobeSet::ALL, opts).stats();
        for (sum, w) in per_lobe.iter_mut().zip(&s.per_lobe) {
            sum.closed_form += w.closed_form;
            sum.gl_segments += w.gl_segments;
            sum.gl_nodes += w.gl_nodes;
        }
    }
    let n = groups.len().max(1) as f64;
    let phis = groups.iter().map(|g| g.1.len()).max().unwrap_or(0);
    let gl: usize = per_lobe.iter().map(|w| w.gl_segments).sum();
    let nodes: usize = per_lobe.iter().map(|w| w.gl_nodes).sum();
    // Where the evaluation's work sits: every phi pays for each closed-form piece in reach
    // and for each quadrature node's Gaussian.
    let lobes: Vec<String> = crate::model::Lobe::ALL
        .iter()
        .zip(&per_lobe)
        .map(|(l, w)| {
            if l.is_scattered() {
                format!("{} {:.1}", l.name(), w.closed_form as f64 / n)
            } else {
                format!(
                    "{} {:.1} + {:.1} ({:.1} nodes)",
                    l.name(),
                    w.closed_form as f64 / n,
                    w.gl_segments as f64 / n,
                    w.gl_nodes as f64 / n
                )
            }
        })
        .collect();
    format!(
        "  one thread, per slice ({} slices of up to {phis} phi): build {:.1} us, evaluation {:.1} us; quadrature pieces {:.1}, nodes {:.1}\n  per lobe and slice, closed-form pieces + quadrature pieces (their nodes): {}",
        groups.len(),
        1e6 * build / n,
        1e6 * eval / n,
        gl as f64 / n,
        nodes as f64 / n,
        lobes.join(", ")
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The ladder's first tolerance is the default mode the goal is stated for.
    #[test]
    fn synth_ladder_starts_at_the_default_tolerance() {
        assert_eq!(FarOptions::default().tol, Some(SYNTH_TOLS[0]));
    }

    /// Errors are relative to each lobe's own peak over phi; the per-lobe maxima are the
    /// lobes' largest such errors and the overall max is the largest of them. Values are
    /// exact binary fractions, so the comparisons are exact.
    #[test]
    fn errors_are_relative_to_each_lobes_peak() {
        let lv = |v: [f64; 5]| LobeValues(v);
        let set = Set {
            models: Vec::new(),
            phis: vec![0.0, 1.0],
            reference: vec![vec![vec![
                lv([1.0, 8.0, 0.0, 2.0, 4.0]),
                lv([2.0, 4.0, 0.0, 1.0, 4.0]),
            ]]],
        };
        let vals = vec![vec![vec![
            lv([1.5, 8.0, 0.25, 2.0, 4.0]),
            lv([2.0, 5.0, 0.0, 1.0, 3.0]),
        ]]];
        let (max, median, lobe) = errors(&set, &vals);
        // R: 0.5 / 2; TT: 1 / 8; TRT has no peak (skipped); TTs: 0; TRTs: 1 / 4.
        assert_eq!(lobe, [0.25, 0.125, 0.0, 0.0, 0.25]);
        assert_eq!(max, 0.25);
        // Sorted: five zeros, 0.125, 0.25, 0.25; the median is element 4.
        assert_eq!(median, 0.0);
        assert_eq!(
            lobe_list(&lobe),
            "R 2.5e-1  TT 1.2e-1  TRT 0.0e0  TTs 0.0e0  TRTs 2.5e-1"
        );
    }
}
