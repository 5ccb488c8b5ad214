use super::grid::*;
use super::rows::*;
use super::slice::*;
use super::tables::*;
use crate::model::medulla_mc::{build_tables, BuildOptions, McBudget, McGrid};
use rand::{Rng, SeedableRng};
use std::f64::consts::{FRAC_PI_2, PI};

/// The fast floor-and-wrap of `locate_periodic` equals floor + Euclidean remainder
/// exactly, in and far outside one period, at bin edges and for negative zero.
#[test]
fn locate_periodic_matches_floor_and_rem_euclid() {
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(4);
    let (n, d) = (90usize, 2.0 * PI / 90.0);
    let c0 = -PI + 0.5 * d;
    let mut psis: Vec<f64> = (0..5000).map(|_| rng.random_range(-40.0..40.0)).collect();
    psis.extend((-200..200).map(|k| c0 + k as f64 * d));
    psis.extend([0.0, -0.0, PI, -PI, c0, c0 - 1e-17]);
    for psi in psis {
        let u = (psi - c0) / d;
        let fl = u.floor();
        let k0 = (fl as i64).rem_euclid(n as i64) as usize;
        let want = (k0, (k0 + 1) % n, u - fl);
        let got = locate_periodic(c0, d, n, psi);
        assert_eq!(got.0, want.0, "psi {psi}");
        assert_eq!(got.1, want.1, "psi {psi}");
        assert_eq!(got.2.to_bits(), want.2.to_bits(), "psi {psi}");
    }
}

fn tiny_options(seed: u64) -> BuildOptions {
    BuildOptions {
        grid: McGrid::tiny(),
        seed,
        budget: McBudget::from_paths(400),
        ranks: vec![4],
        target_error: 0.0,
        max_iter: 30,
    }
}

fn tiny_bytes(seed: u64) -> Vec<u8> {
    build_tables(&tiny_options(seed), &|| {}, &mut |_| {})
        .0
        .to_bytes()
}

/// The per-slice node grid is a rounding-level reorganisation of the rank sum: queries
/// agree with the compressed factors to 1e-12 of the peak (the two sum the same
/// products in another order) wherever no floored node is involved, which is most
/// queries, and otherwise only lie above them, at random `(tau, g)`, `x` and `psi`.
#[test]
fn node_grid_matches_compressed_factors() {
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(11);
    for _ in 0..8 {
        let s = MedullaTables::builtin()
            .slice(rng.random_range(0.0..22.0), rng.random_range(-0.95..0.97));
        let mut exact = 0;
        for _ in 0..200 {
            let (x, psi) = (rng.random_range(-1.2..1.2), rng.random_range(-4.0..4.0));
            let peak = (0..720)
                .map(|k| s.cn_compressed(x, -PI + k as f64 * PI / 360.0))
                .fold(1e-300f64, f64::max);
            let (a, b) = (s.cn(x, psi), s.cn_compressed(x, psi));
            let tol = 1e-12 * peak;
            // Flooring a node only raises it (from a compression negative, which is at
            // most a few % of the peak, to NODE_FLOOR of the row's peak), so a query
            // near such a node rises by less than 5 % of the peak and never falls.
            assert!(
                a >= b - tol && a <= b + 0.05 * peak + tol,
                "x {x} psi {psi}: {a} vs {b} (peak {peak})"
            );
            exact += ((a - b).abs() <= tol) as usize;
        }
        assert!(
            exact >= 150,
            "only {exact} of 200 queries away from the floor"
        );
    }
}

/// The tabulated profile is the same function as the point query: both lerp the same
/// node grid, in `x` then `psi` or the other way round, so agreement to 1e-12 of the
/// profile's peak is a real check, including the `x < 0` flip and mirror.
#[test]
fn cn_profile_matches_cn() {
    let s = MedullaTables::builtin().slice(3.0, 0.4);
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(5);
    // +0 and -0 first: the h -> 0+ and h -> 0- limits read the x = 0 row unflipped
    // and flipped, in the profile as in the point query.
    let xs: Vec<f64> = [0.0, -0.0]
        .into_iter()
        .chain((0..40).map(|_| rng.random_range(-1.0..1.0)))
        .collect();
    for x in xs {
        let prof = s.cn_profile(x);
        let peak = (0..720)
            .map(|k| s.cn(x, -PI + k as f64 * PI / 360.0))
            .fold(0.0f64, f64::max)
            .max(1e-300);
        for _ in 0..50 {
            let psi: f64 = rng.random_range(-4.0..4.0);
            assert!((prof.cn(psi) - s.cn(x, psi)).abs() <= 1e-12 * peak);
            assert!((prof.cn_mirror(psi) - s.cn(-x, psi)).abs() <= 1e-12 * peak);
        }
    }
}

/// `CnRows::integrate` is the exact integral of a quadratic density against the rows'
/// periodic piecewise-linear interpolant: against an adaptive Gauss-Kronrod reference
/// (1e-13, split at every bin centre so each piece is a polynomial) for spans from a
/// sliver of a bin to more than a period, starts far outside (-pi, pi], the first and
/// last row pairs. 1e-12 of the integral of |density| times the row peak: the two-point
/// rule is exact for each cubic piece, so only rounding remains.
#[test]
fn cn_rows_integrate_is_exact() {
    use crate::model::quadrature::adaptive_gk;
    let s = MedullaTables::builtin().slice(3.0, 0.4);
    let rows = s.cn_rows();
    let xs = rows.x_nodes().to_vec();
    let d = rows.bin_width();
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(41);
    for case in 0..200 {
        let i = [0, xs.len() - 2, case % (xs.len() - 1)][case % 3];
        let psi0: f64 = rng.random_range(-9.0..9.0);
        let len: f64 = 10f64.powf(rng.random_range(-4.0..0.9));
        let g = [0, 1].map(|_| {
            [
                rng.random_range(-2.0..2.0),
                rng.random_range(-2.0..2.0),
                rng.random_range(-2.0..2.0),
            ]
        });
        let poly = |c: &[f64; 3], t: f64| c[0] + t * (c[1] + t * c[2]);
        // Row values through the point query at the row's own node (clamping never
        // acts: floored nodes are positive).
        let f = |t: f64| {
            let (r0, r1) = (
                s.cn_shape_clamped(xs[i], psi0 + t),
                s.cn_shape_clamped(xs[i + 1], psi0 + t),
            );
            poly(&g[0], t) * r0 + poly(&g[1], t) * (r1 - r0)
        };
        let (c0, _, _) = s.cn.last_axis();
        let first = ((psi0 - c0) / d).ceil() as i64;
        let mut pts = vec![0.0, len];
        let mut k = first;
        while c0 + k as f64 * d - psi0 < len {
            pts.push(c0 + k as f64 * d - psi0);
            k += 1;
        }
        pts.sort_by(f64::total_cmp);
        let reference = adaptive_gk(f, &pts, 1e-13, 1e-300, 1_000_000).value;
        let scale = adaptive_gk(
            |t| (poly(&g[0], t).abs() + poly(&g[1], t).abs()) * rows.peak,
            &pts,
            1e-10,
            1e-300,
            1_000_000,
        )
        .value;
        let v = rows.integrate(i, psi0, len, &g);
        assert!(
            (v - reference).abs() <= 1e-12 * scale,
            "row {i} psi0 {psi0} len {len}: {v} vs {reference}"
        );
    }
}

/// The node weights of `CnRows::weights`, moved by whole bins, give `integrate` at the
/// start moved by as many bin widths (1e-12 of the scale: the same nodes, summed in
/// another order), across the period and both ways.
#[test]
fn cn_rows_weights_match_integrate_shifted() {
    let s = MedullaTables::builtin().slice(1.5, -0.3);
    let rows = s.cn_rows();
    let d = rows.bin_width();
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(43);
    for _ in 0..100 {
        let i = rng.random_range(0..rows.x_nodes().len() - 1);
        let psi0: f64 = rng.random_range(-4.0..4.0);
        let len: f64 = 10f64.powf(rng.random_range(-4.0..0.9));
        let g = [0, 1].map(|_| std::array::from_fn(|_| rng.random_range(-2.0..2.0)));
        let w = rows.weights(psi0, len, &g);
        let scale = len * rows.peak * 10.0;
        for shift in [-400i64, -181, -7, -1, 0, 1, 3, 179, 180, 361] {
            let a = rows.dot(i, &w, shift);
            let b = rows.integrate(i, psi0 + shift as f64 * d, len, &g);
            assert!((a - b).abs() <= 1e-12 * scale, "shift {shift}: {a} vs {b}");
        }
    }
}

/// A random `psi` piece for the correlation tests: lower row `i`, start `psi0`, length
/// (1e-3 to 3 rad) and the quadratics `g`.
fn random_piece(
    rng: &mut rand_xoshiro::Xoshiro256PlusPlus,
    rows: &CnRows,
) -> (usize, f64, f64, [[f64; 3]; 2]) {
    let i = rng.random_range(0..rows.x_nodes().len() - 1);
    let psi0: f64 = rng.random_range(-4.0..4.0);
    let len: f64 = 10f64.powf(rng.random_range(-3.0..0.5));
    let g = [0, 1].map(|_| std::array::from_fn(|_| rng.random_range(0.0..2.0)));
    (i, psi0, len, g)
}

/// Pieces accumulated per table row ([`CnRows::accumulate_piece`]) and correlated
/// along a grid equal the sum of their own dots at every grid point (1e-12 of the
/// scale: the same products, summed in another order), for steps of either sign and
/// overlapping pieces on neighbouring row pairs, and grids longer than a period.
#[test]
fn row_weights_correlate_equals_summed_dots() {
    let s = MedullaTables::builtin().slice(0.9, 0.4);
    let rows = s.cn_rows();
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(47);
    let mut acc = rows.row_weights();
    for step in [1i64, -1, 2, -3, 0, 180, -90, 7] {
        acc.clear();
        let mut pieces = Vec::new();
        for _ in 0..30 {
            let (i, psi0, len, g) = random_piece(&mut rng, &rows);
            let w = rows.weights(psi0, len, &g);
            rows.accumulate_piece(&mut acc, i, psi0, len, &g);
            pieces.push((i, w, len));
        }
        // 400 points: the runs of a one-bin step wrap more than once (180 bins).
        for points in [91, 400] {
            let mut out = vec![0.0; points];
            rows.correlate(&acc, step, &mut out);
            let scale: f64 = pieces.iter().map(|p| p.2).sum::<f64>() * rows.peak * 10.0;
            for (q, &o) in out.iter().enumerate() {
                let sum: f64 = pieces
                    .iter()
                    .map(|(i, w, _)| rows.dot(*i, w, step * q as i64))
                    .sum();
                assert!(
                    (o - sum).abs() <= 1e-12 * scale,
                    "step {step} q {q}: {o} vs {sum}"
                );
            }
        }
    }
}

/// The AVX2 build of [`CnRows::correlate`] gives the portable build's values bit for
/// bit (the dispatch picks one by CPU; results may not depend on the machine), for
/// steps of either sign, one bin and several.
#[test]
fn correlate_avx2_equals_portable_build() {
    let s = MedullaTables::builtin().slice(0.9, 0.4);
    let rows = s.cn_rows();
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(59);
    let mut acc = rows.row_weights();
    for _ in 0..20 {
        let (i, psi0, len, g) = random_piece(&mut rng, &rows);
        rows.accumulate_piece(&mut acc, i, psi0, len, &g);
    }
    for step in [1i64, -1, 3, -7, 0] {
        let mut portable = vec![0.5; 200];
        rows.correlate_body(&acc, step, &mut portable);
        let mut chosen = vec![0.5; 200];
        rows.correlate(&acc, step, &mut chosen);
        assert!(portable.iter().any(|&v| v > 0.5));
        for (a, b) in portable.iter().zip(&chosen) {
            assert_eq!(a.to_bits(), b.to_bits(), "step {step}");
        }
    }
}

/// A point query as row weights ([`CnRows::accumulate_point`]) read along a grid by
/// [`CnRows::correlate`] equals the query itself at every grid point: the bilinear
/// lerp rewritten, so to rounding (1e-12 of the table's peak times the weight).
#[test]
fn accumulate_point_correlates_to_point_queries() {
    let s = MedullaTables::builtin().slice(2.0, 0.6);
    let rows = s.cn_rows();
    let d = rows.bin_width();
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(53);
    let mut acc = rows.row_weights();
    for step in [1i64, -1, 2, -3, 0] {
        for _ in 0..40 {
            acc.clear();
            // Offsets include the end nodes and beyond (constant there).
            let x: f64 = [0.0, 1.0, rng.random_range(0.0..1.0)][rng.random_range(0..3)];
            let psi0: f64 = rng.random_range(-9.0..9.0);
            let w: f64 = rng.random_range(0.1..3.0);
            rows.accumulate_point(&mut acc, x, psi0, w);
            let mut out = vec![0.0; 91];
            rows.correlate(&acc, step, &mut out);
            for (q, &o) in out.iter().enumerate() {
                let want = w * s.cn_shape_clamped(x, psi0 + (step * q as i64) as f64 * d);
                assert!(
                    (o - want).abs() <= 1e-12 * w * rows.peak,
                    "step {step} x {x} psi0 {psi0} q {q}: {o} vs {want}"
                );
            }
        }
    }
}

/// Trapezoid over 8 points per psi bin: exact for the piecewise-linear `cn` at fixed
/// `x` (every bin centre is a sample point) up to the clamping of negatives.
fn integrate_cn(s: &MedullaSlice, x: f64) -> f64 {
    let n = 180 * 8;
    let h = 2.0 * PI / n as f64;
    // Periodic: the plain sum is the trapezoid rule.
    (0..n)
        .map(|k| s.cn(x, -PI + (k as f64 + 0.5) * h))
        .sum::<f64>()
        * h
}

fn integrate_cm(s: &MedullaSlice, ti: f64, side: Side) -> f64 {
    let n = 90 * 8;
    let h = PI / n as f64;
    (0..n)
        .map(|k| s.cm(ti, -FRAC_PI_2 + (k as f64 + 0.5) * h, side))
        .sum::<f64>()
        * h
}

#[test]
fn deterministic_build_same_seed_same_bytes() {
    let a = tiny_bytes(11);
    let b = tiny_bytes(11);
    assert_eq!(a, b);
    assert_ne!(a, tiny_bytes(12));
    let t = MedullaTables::from_bytes(&a).unwrap();
    assert_eq!(t.to_bytes(), a, "parse/serialise round trip");
}

#[test]
fn corrupt_bytes_are_errors_not_panics() {
    let b = tiny_bytes(5);
    for len in (0..b.len()).step_by(7) {
        assert!(MedullaTables::from_bytes(&b[..len]).is_err(), "len {len}");
    }
    for pos in (0..b.len()).step_by(13) {
        let mut c = b.clone();
        c[pos] ^= 0x5a;
        assert!(MedullaTables::from_bytes(&c).is_err(), "flip at {pos}");
    }
    // A body with a valid checksum but an absurd rank / axis must still be rejected.
    use sha2::{Digest, Sha256};
    let reseal = |mut body: Vec<u8>| {
        let s = Sha256::digest(&body);
        body.extend_from_slice(&s);
        body
    };
    let body = b[..b.len() - 32].to_vec();
    let rank_pos = 8 + 4 + 8 + 8 + 4 + 4;
    let mut bad_rank = body.clone();
    bad_rank[rank_pos..rank_pos + 4].copy_from_slice(&u32::MAX.to_le_bytes());
    assert!(MedullaTables::from_bytes(&reseal(bad_rank)).is_err());
    let mut nan_axis = body.clone();
    let axis_pos = rank_pos + 8 + 4; // first value of the tau axis
    nan_axis[axis_pos..axis_pos + 8].copy_from_slice(&f64::NAN.to_le_bytes());
    assert!(MedullaTables::from_bytes(&reseal(nan_axis)).is_err());
    let mut short = body.clone();
    short.truncate(body.len() - 4);
    assert!(MedullaTables::from_bytes(&reseal(short)).is_err());
    assert!(MedullaTables::from_bytes(&reseal(body)).is_ok());
}

/// `f(v)` from [`hermite_stencil`] on samples of `f` at `axis`.
fn hermite(axis: &[f64], f: impl Fn(f64) -> f64, v: f64) -> f64 {
    let (nodes, w) = hermite_stencil(axis, v);
    (0..4).map(|q| w[q] * f(axis[nodes[q]])).sum()
}

/// The stencil passes through the nodes, reproduces straight lines on an uneven axis
/// and quadratics between interior nodes of an even one (centred slopes are then
/// exact), and is constant beyond the ends. Tolerances: 1e-12, rounding of a few
/// operations on O(1) values.
#[test]
fn hermite_stencil_interpolates_exactly_where_it_should() {
    let uneven = [0.0, 0.1, 0.35, 0.4, 1.0, 2.5];
    let line = |x: f64| 3.0 - 2.0 * x;
    for k in 0..=250 {
        let v = 2.5 * k as f64 / 250.0;
        assert!((hermite(&uneven, line, v) - line(v)).abs() < 1e-12, "{v}");
    }
    for (i, &x) in uneven.iter().enumerate() {
        let f = |y: f64| (5.0 * y).sin() + i as f64;
        assert!((hermite(&uneven, f, x) - f(x)).abs() < 1e-12);
    }
    let even: Vec<f64> = (0..8).map(|k| k as f64 * 0.5).collect();
    let quad = |x: f64| 1.0 + x - 0.7 * x * x;
    for k in 0..=100 {
        let v = 0.5 + 2.5 * k as f64 / 100.0; // between nodes 1 and 6
        assert!((hermite(&even, quad, v) - quad(v)).abs() < 1e-12, "{v}");
    }
    assert_eq!(hermite(&even, quad, -3.0), quad(0.0));
    assert_eq!(hermite(&even, quad, 9.0), quad(3.5));
}

/// C^1: on both sides of every interior node of an uneven axis the one-sided slopes
/// agree (a linear interpolant's jump there is O(1) for this curve). Steps of 1e-6 give
/// one-sided slopes within ~1e-5 of the node's derivative; 1e-4 leaves room.
#[test]
fn hermite_stencil_is_continuously_differentiable() {
    let axis = [0.0, 0.2, 0.5, 0.55, 1.0, 1.7, 3.0];
    let f = |x: f64| (2.0 * x).sin() + 0.3 * x * x;
    let h = 1e-6;
    for &x in &axis[1..axis.len() - 1] {
        let left = (hermite(&axis, f, x) - hermite(&axis, f, x - h)) / h;
        let right = (hermite(&axis, f, x + h) - hermite(&axis, f, x)) / h;
        assert!((left - right).abs() < 1e-4, "node {x}: {left} vs {right}");
    }
}

/// The shipped tables' scattered lobes are differentiable in `tau` and `g` across
/// their nodes (the fitter stopped on kinks there when `tau` and `g` were interpolated
/// linearly): one-sided slopes of `C^N` and `C^M` at a node agree to 1e-3 of their
/// size, where the linear interpolation's slopes differed by tens of percent.
#[test]
fn shipped_tables_have_no_kink_at_tau_and_g_nodes() {
    let t = MedullaTables::builtin();
    let (taus, gs) = (&t.cn.axes[0], &t.cn.axes[1]);
    let (tau0, g0) = (taus[taus.len() / 6], gs[gs.len() / 2]);
    let h = 1e-6;
    let probe = |tau: f64, g: f64| {
        let s = t.slice(tau, g);
        [
            s.cn(0.3, 2.0),
            s.cn(-0.6, 0.4),
            s.cm(0.3, -0.2, Side::Front),
            s.cm(0.7, 0.5, Side::Back),
        ]
    };
    for (dt, dg) in [(h, 0.0), (0.0, h)] {
        let (lo, mid, hi) = (
            probe(tau0 - dt, g0 - dg),
            probe(tau0, g0),
            probe(tau0 + dt, g0 + dg),
        );
        for q in 0..4 {
            let (left, right) = ((mid[q] - lo[q]) / h, (hi[q] - mid[q]) / h);
            let scale = left.abs().max(right.abs()).max(1e-3 * mid[q]);
            assert!(
                (left - right).abs() <= 1e-3 * scale + 1e-9,
                "tau {tau0} g {g0} probe {q} d({dt},{dg}): {left} vs {right}"
            );
        }
    }
}

#[test]
fn shipped_cn_integrates_to_analytic_scattered_fraction() {
    let t = MedullaTables::builtin();
    for &(tau, g) in &[
        (0.3, 0.0),
        (1.2, 0.6),
        (2.7, 0.79),
        (6.0, -0.4),
        (15.0, 0.9),
    ] {
        let s = t.slice(tau, g);
        for &x in &[-0.95, -0.5, 0.0, 0.33, 0.8, 0.999] {
            let num = integrate_cn(&s, x);
            let sf = s.scattered_fraction(x);
            let exact = scatter_probability(tau, x);
            // Clamping compressed negatives only adds their (tiny) mass: 1% of the
            // fraction bounds it for the shipped ranks.
            assert!(
                (num - sf).abs() <= 0.01 * sf + 1e-12,
                "{tau} {g} {x}: {num} {sf}"
            );
            // Every raw slice integrates to exactly 1; the CP shape keeps that to
            // within its compression error (a few %), so 5% of the fraction.
            assert!(
                (num - exact).abs() <= 0.05 * exact + 1e-12,
                "{tau} {g} {x}: {num} vs {exact}"
            );
        }
    }
}

#[test]
fn shipped_cm_integrates_to_one() {
    let t = MedullaTables::builtin();
    for &(tau, g) in &[
        (0.0, 0.0),
        (0.3, 0.2),
        (1.2, 0.6),
        (2.7, 0.79),
        (12.0, -0.6),
    ] {
        let s = t.slice(tau, g);
        for &ti in &[-1.2, -0.3, 0.0, 0.5, 1.0, 1.5] {
            for side in [Side::Front, Side::Back] {
                let i = integrate_cm(&s, ti, side);
                // Raw slices integrate to 1; CP compression error of a few % (5%).
                assert!((i - 1.0).abs() < 0.05, "{tau} {g} {ti} {side:?}: {i}");
            }
        }
    }
}

#[test]
fn thick_medulla_reflects_around_the_entry_normal() {
    // Optically thick, isotropic: light diffuses out near the entry point, whose
    // outward normal for offset x lies at psi = -asin(x) (same side as the paper's
    // R lobe at phi = -2 asin(h) for positive h). So the density at psi = -asin(x) is
    // well above its mirror image +asin(x) and far above straight-through.
    let s = MedullaTables::builtin().slice(10.0, 0.0);
    let x: f64 = 0.7;
    let n = s.cn(x, -x.asin());
    let m = s.cn(x, x.asin());
    let fwd = s.cn(x, PI);
    assert!(n > 1.5 * m, "{n} vs mirror {m}");
    assert!(n > 3.0 * fwd, "{n} vs forward {fwd}");
    // Thin medulla, strong forward scattering: almost everything goes straight on.
    let s = MedullaTables::builtin().slice(0.2, 0.9);
    assert!(s.cn(0.3, PI) > 20.0 * s.cn(0.3, 0.0));
}

#[test]
fn symmetries_hold_exactly() {
    let s = MedullaTables::builtin().slice(1.7, 0.45);
    for &x in &[0.1, 0.5, 0.93] {
        for &psi in &[-3.0, -1.0, 0.2, 2.5, PI] {
            let a = s.cn(x, psi);
            let b = s.cn(-x, -psi);
            // Same factor rows by construction; wrap of -pi vs pi may differ by 1 ulp.
            assert!(
                (a - b).abs() <= 1e-12 * (a.abs() + 1e-300),
                "{x} {psi}: {a} {b}"
            );
        }
    }
    for &ti in &[0.2, 0.9] {
        for &tr in &[-1.0, 0.0, 0.7] {
            for side in [Side::Front, Side::Back] {
                assert_eq!(s.cm(ti, tr, side), s.cm(-ti, -tr, side));
            }
        }
    }
}

#[test]
fn domain_notes_name_what_leaves_the_tables() {
    let t = MedullaTables::builtin();
    let ([_, t1], [g0, g1]) = t.domain();
    assert!(t.domain_notes(1.0, 0.3).is_empty());
    assert!(
        t.domain_notes(t1, g1).is_empty(),
        "the edges themselves are covered"
    );
    let n = t.domain_notes(1.0, 0.97);
    assert!(n.len() == 1 && n[0].contains("g = 0.97"), "{n:?}");
    assert_eq!(t.domain_notes(1.0, g0 - 0.05).len(), 1);
    let n = t.domain_notes(t1 * 2.0, -0.99);
    assert_eq!(n.len(), 2, "{n:?}");
    // A huge tau (sigma_m_s = 1e12) in scientific notation, not 12 digits and more.
    let n = t.domain_notes(1e12 * 0.86, 0.3);
    assert!(
        n[0].contains("tau = sigma_m_s * kappa = 8.6e11 is above"),
        "{n:?}"
    );
    let n = t.domain_notes(1.0, -1e300);
    assert!(n[0].contains("g = -1e300 is outside"), "{n:?}");
}

#[test]
fn extreme_queries_are_finite_and_non_negative() {
    let t = MedullaTables::builtin();
    let big = 1e6;
    for &tau in &[0.0, 1e-9, 20.0, 1e3, big, f64::INFINITY, -1.0] {
        for &g in &[-0.999, -0.9, 0.0, 0.95, 0.999] {
            let s = t.slice(tau, g);
            for &x in &[-1.0, -0.999_999, 0.0, 1.0, 1.5, -7.0] {
                for &psi in &[-PI, -1e-9, 0.0, PI, 10.0, -100.0] {
                    let v = s.cn(x, psi);
                    assert!(v.is_finite() && v >= 0.0, "cn {tau} {g} {x} {psi}: {v}");
                }
                let f = s.scattered_fraction(x);
                assert!(f.is_finite() && f >= 0.0);
            }
            for &ti in &[-FRAC_PI_2, -1.0, 0.0, FRAC_PI_2, 2.0] {
                for &tr in &[-FRAC_PI_2, 0.0, FRAC_PI_2, 3.0] {
                    for &phi in &[0.0, 1.0, PI, -PI] {
                        let v = s.cm_lerp(ti, tr, phi);
                        assert!(v.is_finite() && v >= 0.0, "cm {tau} {g} {ti} {tr}");
                    }
                }
            }
        }
    }
    // tau = 0: no scattering at all.
    assert_eq!(t.slice(0.0, 0.3).cn(0.2, 1.0), 0.0);
}

#[test]
fn sampled_psi_follows_returned_pdf_and_cn() {
    let s = MedullaTables::builtin().slice(1.3, 0.5);
    let sm = s.sampler();
    let x = -0.37;
    let total = integrate_cn(&s, x);
    // pdf is the density actually sampled; equals cn / integral where nothing clamps.
    for &psi in &[-2.9, -1.0, 0.0, 1.5, 3.0] {
        let p = sm.pdf_cn(x, psi);
        let c = s.cn(x, psi) / total;
        assert!((p - c).abs() < 0.02 * c.max(0.05), "{psi}: {p} vs {c}");
    }
    // Histogram of 40k samples in 24 bins against the pdf integrated per bin
    // (chi-square with 23 dof: mean 23, sd 6.8; 70 is ~7 sd).
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(9);
    let n = 40_000;
    let bins = 24;
    let mut hist = vec![0.0; bins];
    for _ in 0..n {
        let (psi, pdf) = sm.sample_cn(x, rng.random());
        assert!((pdf - sm.pdf_cn(x, psi)).abs() <= 1e-9 * pdf.max(1.0));
        let k = (((psi + PI) / (2.0 * PI) * bins as f64) as usize).min(bins - 1);
        hist[k] += 1.0;
    }
    let mut chi2 = 0.0;
    for (k, &h) in hist.iter().enumerate() {
        let m = 64;
        let w = 2.0 * PI / bins as f64;
        let e: f64 = (0..m)
            .map(|j| sm.pdf_cn(x, -PI + k as f64 * w + (j as f64 + 0.5) * w / m as f64))
            .sum::<f64>()
            * w
            / m as f64
            * n as f64;
        if e > 5.0 {
            chi2 += (h - e) * (h - e) / e;
        }
    }
    assert!(chi2 < 70.0, "chi2 {chi2}");
}

/// The column sampler (incident `theta_i` for a given exit `theta_r`, the renderer's
/// light side) draws what its pdf says (chi-square over 18 bins), and its pdf is the
/// normalised column of `cm_lerp`, both signs of `theta_i` (the mirrored half reads the
/// table at `(-theta_i, -theta_r)`) and at the ends beyond the table's nodes.
#[test]
fn sampled_theta_i_follows_returned_pdf_and_the_column() {
    let s = MedullaTables::builtin().slice(0.8, 0.3);
    let sm = s.sampler();
    for (case, &(tr, phi)) in [(-0.6, 2.0), (0.9, 0.3), (0.0, PI)].iter().enumerate() {
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(20 + case as u64);
        let n = 40_000;
        let bins = 18;
        let mut hist = vec![0.0; bins];
        for _ in 0..n {
            let (ti, pdf) = sm.sample_cm_incident(tr, phi, rng.random());
            assert!((-FRAC_PI_2..=FRAC_PI_2).contains(&ti));
            let again = sm.pdf_cm_incident(tr, ti, phi);
            assert!(
                (pdf - again).abs() <= 1e-9 * pdf.max(1.0),
                "{pdf} vs {again}"
            );
            let k = (((ti + FRAC_PI_2) / PI * bins as f64) as usize).min(bins - 1);
            hist[k] += 1.0;
        }
        let w = PI / bins as f64;
        let mut chi2 = 0.0;
        for (k, &h) in hist.iter().enumerate() {
            let m = 64;
            let e: f64 = (0..m)
                .map(|j| {
                    let ti = -FRAC_PI_2 + k as f64 * w + (j as f64 + 0.5) * w / m as f64;
                    sm.pdf_cm_incident(tr, ti, phi)
                })
                .sum::<f64>()
                * w
                / m as f64
                * n as f64;
            if e > 5.0 {
                chi2 += (h - e) * (h - e) / e;
            }
        }
        // 17 dof: mean 17, sd 5.8; 60 is ~7 sd.
        assert!(chi2 < 60.0, "case {case}: chi2 {chi2}");
        // The pdf is the column of cm_lerp, normalised: the same piecewise-linear
        // function, so equal up to the midpoint rule's error on 2880 cells (< 1e-3).
        let cells = 2880;
        let norm: f64 = (0..cells)
            .map(|k| s.cm_lerp(-FRAC_PI_2 + (k as f64 + 0.5) * PI / cells as f64, tr, phi))
            .sum::<f64>()
            * PI
            / cells as f64;
        for &ti in &[-1.5, -0.7, -0.01, 0.01, 0.5, 1.2, 1.56] {
            let p = sm.pdf_cm_incident(tr, ti, phi);
            let c = s.cm_lerp(ti, tr, phi) / norm;
            assert!(
                (p - c).abs() < 1e-3 * c,
                "case {case}, theta_i {ti}: {p} vs {c}"
            );
        }
    }
}
