//! Physics and bookkeeping checks of the virtual goniometer.

use super::optics::{dot, fresnel_dielectric};
use super::trace::{hg_scatter, trace_path, Fiber, Outcome};
use super::*;
use rand::SeedableRng;
use rand_xoshiro::Xoshiro256PlusPlus;

/// Parameters in file units (degrees), in MODEL.md order
/// (eta, kappa, alpha, beta_m, beta_n, sigma_c_a, sigma_m_s, sigma_m_a, g, l).
fn params(v: [f64; 10]) -> FurParams {
    FurParams::from_file_units(v).unwrap()
}

fn settings(p: FurParams, theta_i: f64, paths: u64, smooth: bool) -> SimSettings {
    SimSettings {
        params: p,
        theta_i: vec![theta_i],
        // Whole sphere without duplicated bins: theta_r bins cover [-90, 90], phi [-180, 180].
        theta_r: crate::grid::parse_grid("t", "-89:89:2").unwrap(),
        phi: crate::grid::parse_grid("p", "-179:179:2").unwrap(),
        paths,
        seed: 11,
        ellipse: None,
        medulla_eta: None,
        smooth,
    }
}

/// Integral of the binned density over the grid (value * bin area).
fn integral(r: &SimResult, det: &Detector) -> f64 {
    let mut s = 0.0;
    for j in 0..det.n_theta() {
        for k in 0..det.n_phi() {
            s += r.value[r.index(0, j, k)] * det.area(j, k);
        }
    }
    s
}

/// Without absorption no energy can vanish: every path exits (weights stay 1, Russian
/// roulette never fires), so the detector integral over the whole sphere must be 1 up to
/// lost paths. A lost path is a bug (or a ray counted as guided: beyond MAX_EVENTS
/// events, MAX_CUTICLE_HITS cuticle interactions or GUIDED_LENGTH along the axis), so the
/// tolerance 1e-3 (=> fewer than 1 in 1000 paths lost) is far above rounding and far below
/// any real leak; the binomial std of an *unbiased* estimate is 0 here because every path
/// carries exactly weight 1.
#[test]
fn energy_conserved_without_absorption() {
    let cases = [
        // smooth, kappa = 0
        (
            params([1.55, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0]),
            true,
            None,
            None,
        ),
        // smooth, scattering medulla, no absorption
        (
            params([1.55, 0.7, 0.0, 1.0, 1.0, 0.0, 3.0, 0.0, 0.5, 1.0]),
            true,
            None,
            None,
        ),
        // rough, tilted, layered cuticle, scattering medulla with its own IOR, ellipse
        (
            params([1.4, 0.6, 3.0, 8.0, 12.0, 0.0, 2.0, 0.0, 0.3, 2.5]),
            false,
            Some(0.8),
            Some(1.6),
        ),
    ];
    for (p, smooth, ell, etam) in cases {
        let mut s = settings(p, 30.0, 60_000, smooth);
        s.ellipse = ell;
        s.medulla_eta = etam;
        let r = simulate(&s, |_| {}).unwrap();
        let det = Detector::new(&s.theta_r, &s.phi);
        let t = r.tally[0];
        assert!(
            (t.exited - 1.0).abs() < 1e-3,
            "exited {} guided {}",
            t.exited,
            t.guided
        );
        // The detector covers the sphere: everything that exits is binned ...
        assert!((t.binned - t.exited).abs() < 1e-12, "{t:?}");
        // ... and the density normalisation integrates back to the binned energy
        // (rounding only: 1e-9).
        let integ = integral(&r, &det);
        assert!((integ - t.binned).abs() < 1e-9, "{integ} vs {t:?}");
    }
}

/// Mean over the entry offset `h` (uniform on [-1, 1], theta_i = 0) of `f(F, b)`: `F` the
/// Fresnel reflectance at entry, `b = |h| / eta` the impact parameter that every internal
/// pass of a smooth centred circular fiber keeps (reflection at a centred circle preserves
/// it), which fixes the chord lengths of every pass. Midpoint rule with 4000 points: its
/// error is far below the Monte Carlo noise of the tests that use it.
fn mean_over_h(eta: f64, f: impl Fn(f64, f64) -> f64) -> f64 {
    let m = 4000;
    let mut e = 0.0;
    for i in 0..m {
        let h = -1.0 + (i as f64 + 0.5) * 2.0 / m as f64;
        e += f(fresnel_dielectric((1.0 - h * h).sqrt(), eta), h.abs() / eta);
    }
    e / m as f64
}

/// Medulla chord length at impact parameter `b` (0 when the pass misses the medulla).
fn medulla_chord(kappa: f64, b: f64) -> f64 {
    2.0 * (kappa * kappa - b * b).max(0.0).sqrt()
}

/// Trace `n` paths at theta_i = 0; returns the exited weight and scattering count of each
/// path (every path must exit or be absorbed: none of these fibers guides light).
fn trace_exits(fiber: &Fiber, n: usize, seed: u64) -> Vec<(f64, u32)> {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    (0..n)
        .map(|_| match trace_path(fiber, 0.0, &mut rng) {
            Outcome::Exit(e) => (e.weight, e.scatters),
            Outcome::Absorbed => (0.0, 0),
            Outcome::Guided(w) => panic!("guided path of weight {w}"),
        })
        .collect()
}

/// Weighted absorption with Russian roulette is unbiased: for kappa = 0, smooth, theta_i = 0
/// the analytic exit energy is sum over paths of R + (1-F)^2 T (1 + F T + (F T)^2 ...)
/// averaged over h, with T = exp(-2 sigma cos(gamma_t)) (3-D length = 2D / cos theta_t = 2D
/// at theta_i = 0). Tolerance: 5 standard errors of the MC mean (std of a weight <= 1).
#[test]
fn absorption_matches_beer_lambert() {
    let sigma = 0.8;
    let eta = 1.55;
    let p = params([eta, 0.0, 0.0, 1.0, 1.0, sigma, 0.0, 0.0, 0.0, 1.0]);
    let n = 200_000u64;
    let r = simulate(&settings(p, 0.0, n, true), |_| {}).unwrap();
    let e = mean_over_h(eta, |f, b| {
        let t = (-2.0 * sigma * (1.0 - b * b).sqrt()).exp();
        f + (1.0 - f) * (1.0 - f) * t / (1.0 - f * t)
    });
    let tol = 5.0 * 0.5 / (n as f64).sqrt();
    assert!(
        (r.tally[0].exited - e).abs() < tol,
        "{} vs {e}",
        r.tally[0].exited
    );
}

/// Smooth cylinder, kappa = 0: the R paths (one cuticle interaction) leave at
/// phi = 2 asin(h) (impact at y = h; MODEL.md's -2 gamma_i is the mirrored h convention) and
/// theta_r = -theta_i. With h uniform on [-1, 1] (density 1/2) and dh/dphi = cos(phi/2)/2,
/// the reflected energy per radian of phi is (1/4) cos(phi/2) F, F the Fresnel reflectance
/// at the 3-D incidence cosine cos(theta_i) cos(phi/2). Each 10-degree bin is compared with
/// its expected count: tolerance 5 sqrt(expected) (Poisson) + 0.5 % of the bin for the
/// Simpson rule.
#[test]
fn r_lobe_matches_specular_cylinder() {
    let eta = 1.55;
    let p = params([eta, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0]);
    let fiber = Fiber::new(&p, None, None, true);
    for theta_i in [0.0f64, 30.0] {
        let ti = theta_i.to_radians();
        let n = 400_000usize;
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(3);
        let nb = 36;
        let mut hist = vec![0.0; nb];
        for _ in 0..n {
            if let Outcome::Exit(e) = trace_path(&fiber, ti, &mut rng) {
                if e.cuticle == 1 {
                    let (th, ph) = exit_angles(&e);
                    assert!((th + ti).abs() < 1e-9, "R leaves on the specular cone");
                    let k = (((ph + PI) / (2.0 * PI)) * nb as f64).floor() as usize;
                    hist[k.min(nb - 1)] += 1.0;
                }
            }
        }
        let dens = |phi: f64| {
            0.25 * (phi / 2.0).cos() * fresnel_dielectric(ti.cos() * (phi / 2.0).cos(), eta)
        };
        for (k, &obs) in hist.iter().enumerate() {
            let a = -PI + k as f64 * 2.0 * PI / nb as f64;
            let b = a + 2.0 * PI / nb as f64;
            let m = 200;
            let hh = (b - a) / m as f64;
            let mut integ = dens(a) + dens(b);
            for i in 1..m {
                integ += dens(a + i as f64 * hh) * if i % 2 == 1 { 4.0 } else { 2.0 };
            }
            let expected = integ * hh / 3.0 * n as f64;
            let tol = 5.0 * expected.sqrt() + 0.005 * expected + 1.0;
            assert!(
                (obs - expected).abs() < tol,
                "theta_i {theta_i}: bin {k}: observed {obs}, expected {expected:.1}"
            );
        }
    }
}

/// Rough cuticle: near the backscatter centre (|phi| < 20 deg, so cos(gamma) > 0.97) the R
/// lobe is centred at -theta_i + alpha with a longitudinal std close to beta_m (normal tilts
/// alpha/2 and beta_m/2, doubled by the reflection). Tolerance 0.3 degree on the mean (MC
/// std of the mean ~ 0.1 degree; cos(gamma) bias <= 3 % of 4 degrees) and 10 % on the std
/// (cos(gamma) and sin/asin mapping bias a few percent, MC error ~ 2 %).
#[test]
fn r_lobe_longitudinal_shift_and_width() {
    let (alpha, beta_m) = (4.0, 8.0);
    // Cortex absorption only shortens the (irrelevant) internal paths: a tilted cuticle
    // steers internally reflected light into guided modes that would otherwise run to
    // MAX_EVENTS. R events (one cuticle interaction) are unaffected.
    let p = params([1.55, 0.0, alpha, beta_m, 5.0, 0.5, 0.0, 0.0, 0.0, 1.0]);
    let fiber = Fiber::new(&p, None, None, false);
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(5);
    let mut v = Vec::new();
    for _ in 0..600_000 {
        if let Outcome::Exit(e) = trace_path(&fiber, 0.0, &mut rng) {
            let (th, ph) = exit_angles(&e);
            if e.cuticle == 1 && ph.abs() < 20f64.to_radians() {
                v.push(th.to_degrees());
            }
        }
    }
    let n = v.len() as f64;
    assert!(n > 2000.0);
    let mean = v.iter().sum::<f64>() / n;
    let std = (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n).sqrt();
    assert!((mean - alpha).abs() < 0.3, "mean {mean}");
    assert!((std / beta_m - 1.0).abs() < 0.10, "std {std}");
}

/// Exact geometry of the tilted cuticle over the whole width: a smooth cone-shaped scale
/// (normal tilted by t = alpha/2 toward the tip) reflects the ray from theta_i = 0 hitting
/// at azimuthal incidence gamma to theta_r = asin(cos(gamma) sin(2t)), so the h-averaged
/// R lobe is shifted by less than alpha. Compare the Fresnel-weighted mean over h
/// (quadrature) with the traced mean; tolerance 0.02 degree (the smooth trace is exact,
/// MC error of the mean over ~15k events of a ~1 degree spread is ~0.01 degree).
#[test]
fn tilted_cuticle_exact_cone_reflection() {
    let alpha = 6f64.to_radians();
    let eta = 1.55;
    let p = params([
        eta,
        0.0,
        alpha.to_degrees(),
        1.0,
        1.0,
        0.5, // absorption: see r_lobe_longitudinal_shift_and_width
        0.0,
        0.0,
        0.0,
        1.0,
    ]);
    let fiber = Fiber::new(&p, None, None, true);
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(6);
    let (mut s, mut n) = (0.0, 0.0);
    for _ in 0..300_000 {
        if let Outcome::Exit(e) = trace_path(&fiber, 0.0, &mut rng) {
            if e.cuticle == 1 {
                s += exit_angles(&e).0;
                n += 1.0;
            }
        }
    }
    let t = alpha / 2.0;
    let m = 20_000;
    let (mut num, mut den) = (0.0, 0.0);
    for i in 0..m {
        let h = -1.0 + (i as f64 + 0.5) * 2.0 / m as f64;
        let cg = (1.0 - h * h).sqrt();
        let f = fresnel_dielectric(cg * t.cos(), eta);
        num += f * (cg * (2.0 * t).sin()).asin();
        den += f;
    }
    let expected = num / den;
    assert!(expected < 0.8 * alpha, "the cos(gamma) reduction is real");
    assert!(
        ((s / n) - expected).abs().to_degrees() < 0.02,
        "{} vs {}",
        (s / n).to_degrees(),
        expected.to_degrees()
    );
}

/// tau -> 0 (sigma_m_s = 0): no medulla scattering event can happen.
#[test]
fn no_scattering_without_sigma_m_s() {
    let p = params([1.5, 0.9, 2.0, 6.0, 6.0, 0.2, 0.0, 0.3, 0.5, 1.0]);
    let r = simulate(&settings(p, 20.0, 50_000, false), |_| {}).unwrap();
    assert_eq!(r.tally[0].scatter_events, 0);
    // And with scattering on, events do happen (the test above could otherwise pass
    // vacuously).
    let p = params([1.5, 0.9, 2.0, 6.0, 6.0, 0.2, 2.0, 0.3, 0.5, 1.0]);
    let r = simulate(&settings(p, 20.0, 5_000, false), |_| {}).unwrap();
    assert!(r.tally[0].scatter_events > 1000);
}

/// g = 0: scattered directions are isotropic. Chi-square of the cosine with the incoming
/// direction (20 equal bins, uniform on [-1, 1] for isotropy) and of the azimuth around the
/// z axis: 19 degrees of freedom, threshold 50 (p ~ 1e-4).
#[test]
fn hg_isotropic_for_g0() {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(9);
    let d = super::optics::normalize([0.3, -0.5, 0.8]);
    let n = 200_000;
    let mut hc = [0.0f64; 20];
    let mut hz = [0.0f64; 20];
    for _ in 0..n {
        let w = hg_scatter(d, 0.0, &mut rng);
        let c = dot(w, d);
        hc[(((c + 1.0) / 2.0 * 20.0) as usize).min(19)] += 1.0;
        // z component of an isotropic direction is uniform on [-1, 1] too.
        hz[(((w[2] + 1.0) / 2.0 * 20.0) as usize).min(19)] += 1.0;
    }
    let e = n as f64 / 20.0;
    let chi = |h: &[f64; 20]| h.iter().map(|o| (o - e).powi(2) / e).sum::<f64>();
    assert!(chi(&hc) < 50.0, "chi2 cos {}", chi(&hc));
    assert!(chi(&hz) < 50.0, "chi2 z {}", chi(&hz));
}

/// g > 0: the mean cosine of the HG phase function is g. Tolerance: 5 standard errors
/// (std of the cosine <= 1).
#[test]
fn hg_mean_cosine_is_g() {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(10);
    let d = [0.0, 0.0, 1.0];
    let n = 200_000;
    for g in [0.3, 0.79, -0.5] {
        let m: f64 = (0..n).map(|_| hg_scatter(d, g, &mut rng)[2]).sum::<f64>() / n as f64;
        assert!((m - g).abs() < 5.0 / (n as f64).sqrt(), "g {g}: {m}");
    }
}

/// Same seed -> bit-identical output with 1 and 2 threads (chunked RNG streams summed in
/// chunk order). The path count is not a multiple of the chunk size on purpose.
#[test]
fn deterministic_across_thread_counts() {
    let p = FurParams::preset("red-fox").unwrap();
    let mut s = settings(p, 15.0, 2 * CHUNK + 777, false);
    s.theta_i = vec![0.0, 40.0];
    let run = |t: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(t)
            .build()
            .unwrap();
        pool.install(|| simulate(&s, |_| {}).unwrap())
    };
    let a = run(1);
    let b = run(2);
    assert_eq!(a.value, b.value);
    assert_eq!(a.sigma, b.sigma);
    // A different seed gives different noise (so the equality above is not vacuous).
    s.seed += 1;
    let c = simulate(&s, |_| {}).unwrap();
    assert_ne!(a.value, c.value);
}

/// Bins are centred on grid values with the grid step as width; phi wraps so -180 and 180
/// both receive light leaving near the forward direction.
#[test]
fn detector_bins_and_wrap() {
    let det = Detector::new(&[-10.0, 0.0, 10.0], &[-180.0, -90.0, 0.0, 90.0, 180.0]);
    assert!((det.theta_bins[0].0 - (-15f64).to_radians()).abs() < 1e-12);
    assert!((det.area(1, 2) - (10f64.to_radians() * 90f64.to_radians())).abs() < 1e-12);
    let mut hits = Vec::new();
    det.deposit(0.0, 179f64.to_radians(), |b| hits.push(b));
    hits.sort();
    assert_eq!(hits, vec![5, 9]);
    hits.clear();
    det.deposit(0.2, 1f64.to_radians(), |b| hits.push(b));
    assert_eq!(hits, vec![2 * 5 + 2]);
    hits.clear();
    det.deposit(0.5, 0.0, |b| hits.push(b)); // theta_r = 28.6 deg: outside
    assert!(hits.is_empty());
}

/// Measurement effects: the occluded cone sits at (theta_r, phi) = (theta_i, 0), the floor
/// removes small values, dropping removes about the requested fraction.
#[test]
fn measurement_effects() {
    let p = FurParams::preset("deer").unwrap();
    let mut s = settings(p, 30.0, 100_000, false);
    s.theta_r = crate::grid::parse_grid("t", "-60:60:2").unwrap();
    s.phi = crate::grid::parse_grid("p", "-180:180:4").unwrap();
    let r = simulate(&s, |_| {}).unwrap();
    let fx = measure::Effects {
        floor: 1e-3,
        wedge_deg: 5.0,
        drop: 0.05,
        shot_photons: Some(1e5),
        mult_noise: 0.02,
        seed: 1,
    };
    let m = measure::apply(&r, &fx);
    let jt = s.theta_r.iter().position(|&t| t == 30.0).unwrap();
    let kp = s.phi.iter().position(|&t| t == 0.0).unwrap();
    assert_eq!(m.invalid[r.index(0, jt, kp)], Some(measure::Invalid::Wedge));
    let jm = s.theta_r.iter().position(|&t| t == -30.0).unwrap();
    assert_ne!(m.invalid[r.index(0, jm, kp)], Some(measure::Invalid::Wedge));
    for (v, why) in m.value.iter().zip(&m.invalid) {
        match why {
            None => assert!(*v >= 1e-3 * m.peak),
            Some(_) => assert_eq!(*v, 0.0),
        }
    }
    // Drops are drawn for every sample but only counted when nothing else invalidated
    // it, so the dropped share among the rest is ~5 % (binomial 5 sigma).
    let rest = m.value.len()
        - m.count(Some(measure::Invalid::Floor))
        - m.count(Some(measure::Invalid::Wedge))
        - m.count(Some(measure::Invalid::NoSignal));
    let frac = m.count(Some(measure::Invalid::Dropped)) as f64 / rest as f64;
    let sd = (0.05 * 0.95 / rest as f64).sqrt();
    assert!((frac - 0.05).abs() < 5.0 * sd, "{frac}");
}

/// A single theta_r or phi value has no bin width (it would be a made-up 1 degree);
/// validate refuses it, naming the axis. A single theta_i is fine (it is not binned).
#[test]
fn single_value_detector_axis_is_refused() {
    let p = FurParams::preset("red-fox").unwrap();
    let mut s = settings(p, 0.0, 1000, false);
    assert!(s.validate().is_ok());
    s.phi = vec![0.0];
    let e = s.validate().unwrap_err().to_string();
    assert!(
        e.contains("--phi has a single value") && e.contains("at least two"),
        "{e}"
    );
    s.phi = vec![0.0, 90.0];
    s.theta_r = vec![0.0];
    let e = s.validate().unwrap_err().to_string();
    assert!(e.contains("--theta-r has a single value"), "{e}");
}

/// The grid-size limit (crate::grid::MAX_GRID_SAMPLES) applies to theta_i x theta_r x phi.
#[test]
fn grid_size_is_limited() {
    let p = FurParams::preset("red-fox").unwrap();
    let mut s = settings(p, 0.0, 1000, false);
    s.theta_r = crate::grid::parse_grid("t", "-90:90:0.01").unwrap();
    s.phi = crate::grid::parse_grid("p", "-179.99:180:0.01").unwrap();
    let e = s.validate().unwrap_err().to_string();
    assert!(e.contains("1 x 18001 x 36000 = 648036000 samples"), "{e}");
}

/// Few enough chunks in flight that their accumulators fit the budget, however fine the
/// detector; 4 per thread on an ordinary grid.
#[test]
fn chunks_in_flight_bounded_by_memory() {
    assert_eq!(chunks_in_flight(2, 81 * 90), 8);
    assert_eq!(chunks_in_flight(0, 10), 4);
    for (threads, bins) in [(64, 10_000_000), (2, 5_000_000), (8, 1_000_000)] {
        let n = chunks_in_flight(threads, bins) as usize;
        assert!(
            n >= 1 && n * 16 * bins <= ACCUM_BUDGET.max(16 * bins),
            "{n}"
        );
    }
    assert_eq!(chunks_in_flight(64, 10_000_000), 3);
}

/// An end bin centred at theta_r = +-90 covers only the side below the pole: its area is
/// half an inner bin's (it was a full bin, half of it past the pole, so its density read
/// about half), and an exit just below the pole still lands in it.
#[test]
fn theta_r_end_bins_at_the_pole_stop_there() {
    let theta: Vec<f64> = (-45..=45).map(|k| 2.0 * k as f64).collect();
    let d = Detector::new(&theta, &[-90.0, 0.0, 90.0]);
    let inner = d.area(1, 1);
    let last = d.n_theta() - 1;
    // Exact halves up to the rounding of degree-to-radian conversion (~1e-16 relative).
    assert!((d.area(0, 1) / inner - 0.5).abs() < 1e-12);
    assert!((d.area(last, 1) / inner - 0.5).abs() < 1e-12);
    assert_eq!(d.theta_bins[last].1, std::f64::consts::FRAC_PI_2);
    let mut hit = None;
    d.deposit(89.9f64.to_radians(), 0.0, |b| hit = Some(b));
    assert_eq!(hit.map(|b| b / d.n_phi()), Some(last));
    // Centres short of the pole keep their symmetric end bins.
    let d = Detector::new(&[-80.0, -78.0, 78.0, 80.0], &[0.0, 10.0]);
    assert!((d.theta_bins[3].1 - 81f64.to_radians()).abs() < 1e-15);
}

/// Uneven and gapped grids get bins centred on their values, never across a gap, and phi
/// bins that never overlap around the circle (audit, 2026-11-28: `--theta-r -40,-30,10`
/// gave -30 the bin [-35, -10], a wrapped `--phi 90:270:2` gave -90 a 91-degree bin, and
/// `--phi -170,170` two 340-degree bins that counted the light twice).
#[test]
fn uneven_grids_get_centred_bins_without_overlap() {
    let deg = |b: (f64, f64)| (b.0.to_degrees(), b.1.to_degrees());
    let close = |a: (f64, f64), b: (f64, f64)| (a.0 - b.0).abs() < 1e-9 && (a.1 - b.1).abs() < 1e-9;
    let b = bins(&[-40.0, -30.0, 10.0], false);
    for (got, want) in b
        .iter()
        .zip([(-45.0, -35.0), (-35.0, -25.0), (-10.0, 30.0)])
    {
        assert!(close(deg(*got), want), "{:?} vs {want:?}", deg(*got));
    }
    let b = bins(&[-170.0, 170.0], true);
    assert!(
        close(deg(b[0]), (-180.0, -160.0)) && close(deg(b[1]), (160.0, 180.0)),
        "{b:?}"
    );
    // Half a circle wrapped into (-180, 180]: -90 and 90 are 180 degrees apart.
    let phi: Vec<f64> = (-89..=0)
        .map(|k| 2.0 * k as f64 - 2.0)
        .filter(|p| *p >= -180.0)
        .chain((45..=90).map(|k| 2.0 * k as f64))
        .collect();
    let b = bins(&phi, true);
    let total: f64 = b.iter().map(|x| x.1 - x.0).sum();
    assert!(
        b.iter()
            .all(|x| (x.1 - x.0 - 2f64.to_radians()).abs() < 1e-12),
        "{total}"
    );
    // Uniform grids, fine ones included: edges shared exactly (the midpoints), as before,
    // and the end bins as wide as the step.
    for (grid, cyclic) in [
        (vec![-10.0, 0.0, 10.0, 20.0], false),
        (
            (0..=16000).map(|k| -80.0 + 0.01 * k as f64).collect(),
            false,
        ),
        (
            (1..=36000).map(|k| -180.0 + 0.01 * k as f64).collect(),
            true,
        ),
    ] {
        let b = bins(&grid, cyclic);
        for w in b.windows(2) {
            assert_eq!(w[0].1, w[1].0);
        }
        let c0 = grid[0].to_radians();
        assert_eq!(b[0].0, c0 - 0.5 * (grid[1].to_radians() - c0));
    }
    // Distinct values closer than any grid step keep disjoint bins of their own.
    let b = bins(&[0.0, 1e-8, 10.0], false);
    assert!(
        b[0].1 <= b[1].0 && b[1].1 <= b[2].0 && b[1].1 > b[1].0,
        "{b:?}"
    );
    // Energy is counted once: every direction lands in at most one phi bin.
    let det = Detector::new(&[-10.0, 0.0, 10.0], &[-170.0, 170.0]);
    for k in 0..360 {
        let mut n = 0;
        det.deposit(0.0, (k as f64 - 179.5).to_radians(), |_| n += 1);
        assert!(n <= 1, "phi {k}: {n} bins");
    }
}

/// Concentric index-matched medulla, smooth cuticle, theta_i = 0: every internal pass of a
/// path entering at `h` runs at impact parameter `b = h / eta` (see [`mean_over_h`]),
/// through `L_m` of medulla and `2 sqrt(1 - b^2) - L_m` of cortex. With `g = 1` the HG
/// phase function is a delta forward, so scattering events happen but never turn the ray.
/// Then the exit energy is the series of `absorption_matches_beer_lambert` with the per
/// pass transmission `exp(-sigma_c_a (L - L_m) - sigma_m_a L_m)`, whatever `sigma_m_s`
/// (absorption counts on the way to every event, not just to the boundary); and without
/// absorption (every path exits with weight 1) the mean number of events per path is
/// `sigma_m_s mean_h L_m`: entry `1 - F` times `1 / (1 - F)` passes. Tolerances: 5
/// standard errors (an exit weight lies in [0, 1]: std <= 0.5; the count's std measured).
#[test]
fn medulla_absorbs_and_scatters_along_straight_paths() {
    let (eta, kappa, sc, sm, ss) = (1.55, 0.6, 0.4, 1.5, 2.0);
    let mut fiber = Fiber::new(
        &params([eta, kappa, 0.0, 1.0, 1.0, sc, ss, sm, 0.0, 1.0]),
        None,
        None,
        true,
    );
    fiber.g = 1.0;
    let n = 400_000;
    let got = trace_exits(&fiber, n, 21).iter().map(|e| e.0).sum::<f64>() / n as f64;
    let e = mean_over_h(eta, |f, b| {
        let (l, lm) = (2.0 * (1.0 - b * b).sqrt(), medulla_chord(kappa, b));
        let t = (-sc * (l - lm) - sm * lm).exp();
        f + (1.0 - f) * (1.0 - f) * t / (1.0 - f * t)
    });
    let tol = 5.0 * 0.5 / (n as f64).sqrt();
    assert!((got - e).abs() < tol, "exit energy {got} vs {e}");

    fiber.sigma_c_a = 0.0;
    fiber.sigma_m_a = 0.0;
    let counts: Vec<f64> = trace_exits(&fiber, n, 22)
        .iter()
        .map(|&(w, k)| {
            assert_eq!(w, 1.0, "lossless: every path exits whole");
            k as f64
        })
        .collect();
    let mean = counts.iter().sum::<f64>() / n as f64;
    let var = counts.iter().map(|k| (k - mean).powi(2)).sum::<f64>() / n as f64;
    let expected = ss * mean_over_h(eta, |_, b| medulla_chord(kappa, b));
    assert!(
        (mean - expected).abs() < 5.0 * (var / n as f64).sqrt(),
        "events per path {mean} vs {expected}"
    );
}

/// A medulla with its own IOR reflects part of the light at its boundary. Make it opaque
/// (`sigma_m_a` 200: a pass through it keeps `exp(-200 L_m)`, which matters only within
/// ~1e-4 of its rim) and lossless elsewhere, smooth, theta_i = 0: a path whose internal
/// pass misses the medulla (`b >= kappa`) exits whole; one that meets it (at incidence
/// `asin(b / kappa)`) survives only by the medulla's Fresnel reflection `F_m` at ratio
/// `eta_m / eta`, bouncing between cuticle and medulla: `F + (1 - F)^2 F_m / (1 - F F_m)`.
/// Index matched, `F_m = 0`: only the R reflection survives. Tolerance 5 standard errors
/// (std of a weight in [0, 1] <= 0.5).
#[test]
fn a_medulla_with_its_own_index_reflects_at_its_boundary() {
    let (eta, kappa) = (1.55, 0.6);
    let p = params([eta, kappa, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0]);
    let n = 400_000;
    for eta_m in [None, Some(2.2)] {
        let mut fiber = Fiber::new(&p, None, eta_m, true);
        fiber.sigma_m_a = 200.0;
        let got = trace_exits(&fiber, n, 23).iter().map(|e| e.0).sum::<f64>() / n as f64;
        let e = mean_over_h(eta, |f, b| {
            if b >= kappa {
                return 1.0;
            }
            let fm = match eta_m {
                Some(em) => fresnel_dielectric((1.0 - (b / kappa).powi(2)).sqrt(), em / eta),
                None => 0.0,
            };
            f + (1.0 - f) * (1.0 - f) * fm / (1.0 - f * fm)
        });
        let tol = 5.0 * 0.5 / (n as f64).sqrt();
        assert!(
            (got - e).abs() < tol,
            "eta_m {eta_m:?}: exit energy {got} vs {e}"
        );
    }
}
