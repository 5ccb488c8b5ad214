//! Evidence for the renderer's BCSDF: sampling matches its own pdf (chi-square), sample
//! weights match evaluation, white furnace energy bounds.

use super::bsdf::*;
use crate::model::{Lobe, LobeSet};
use crate::params::FurParams;
use rand::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use std::f64::consts::{FRAC_PI_2, PI};

/// 4-point Gauss-Legendre on [-1, 1].
const GL4: [(f64, f64); 4] = [
    (-0.861_136_311_594_052_6, 0.347_854_845_137_453_9),
    (-0.339_981_043_584_856_3, 0.652_145_154_862_546_1),
    (0.339_981_043_584_856_3, 0.652_145_154_862_546_1),
    (0.861_136_311_594_052_6, 0.347_854_845_137_453_9),
];

/// ∫_a^b f with `panels` composite 4-point Gauss-Legendre panels.
fn integrate(a: f64, b: f64, panels: usize, f: &mut impl FnMut(f64) -> f64) -> f64 {
    let w = (b - a) / panels as f64;
    let mut s = 0.0;
    for k in 0..panels {
        let c = a + (k as f64 + 0.5) * w;
        for (x, wt) in GL4 {
            s += wt * 0.5 * w * f(c + 0.5 * w * x);
        }
    }
    s
}

fn params(v: [f64; 10]) -> FurParams {
    FurParams::from_file_units(v).unwrap()
}

/// Hair-like (kappa = 0), moderately rough.
fn hair() -> FurParams {
    params([1.55, 0.0, 3.0, 10.0, 25.0, 0.3, 0.0, 0.0, 0.0, 1.0])
}

/// Fur with a medulla (kappa > 0): all five lobes.
fn fur() -> FurParams {
    params([1.5, 0.5, 2.0, 12.0, 30.0, 0.2, 1.5, 0.1, 0.3, 1.3])
}

/// Sharper lobes, strong cuticle tilt: tests truncation near the poles.
fn sharp() -> FurParams {
    params([1.6, 0.3, 8.0, 4.0, 10.0, 0.5, 0.8, 0.2, 0.0, 1.0])
}

const NT: usize = 18;
const NP: usize = 36;

fn bin_of(theta: f64, phi: f64) -> usize {
    let i = (((theta + FRAC_PI_2) / PI) * NT as f64)
        .floor()
        .clamp(0.0, NT as f64 - 1.0) as usize;
    let j = (((phi + PI) / (2.0 * PI)) * NP as f64)
        .floor()
        .clamp(0.0, NP as f64 - 1.0) as usize;
    i * NP + j
}

/// Probability of each (theta, phi) bin under `pdf` (sub-panels per bin side: `sub`).
fn bin_probs(pdf: &mut impl FnMut(f64, f64) -> f64, sub: usize) -> Vec<f64> {
    let (dt, dp) = (PI / NT as f64, 2.0 * PI / NP as f64);
    let mut out = vec![0.0; NT * NP];
    for i in 0..NT {
        for j in 0..NP {
            let t0 = -FRAC_PI_2 + i as f64 * dt;
            let p0 = -PI + j as f64 * dp;
            out[i * NP + j] = integrate(t0, t0 + dt, sub, &mut |t| {
                integrate(p0, p0 + dp, sub, &mut |p| pdf(t, p))
            });
        }
    }
    out
}

/// Pearson chi-square of `counts` against `probs` (bins with expected < 5 pooled); returns
/// the Wilson-Hilferty z-score (standard normal under the null).
fn chi_square_z(counts: &[u64], probs: &[f64], n: u64) -> f64 {
    let (mut chi, mut k) = (0.0, 0usize);
    let (mut pool_o, mut pool_e) = (0.0, 0.0);
    for (c, p) in counts.iter().zip(probs) {
        let e = p * n as f64;
        if e < 5.0 {
            pool_o += *c as f64;
            pool_e += e;
        } else {
            chi += (*c as f64 - e).powi(2) / e;
            k += 1;
        }
    }
    if pool_e >= 5.0 {
        chi += (pool_o - pool_e).powi(2) / pool_e;
        k += 1;
    } else {
        // A pooled remainder that is too small must also be (nearly) empty.
        assert!(
            pool_o <= 5.0 + 5.0 * pool_e,
            "{pool_o} samples where {pool_e} expected"
        );
    }
    let dof = (k - 1) as f64;
    ((chi / dof).cbrt() - (1.0 - 2.0 / (9.0 * dof))) / (2.0 / (9.0 * dof)).sqrt()
}

/// Draw `n` samples; histogram them and accumulate the summed weight (green channel).
fn sample_hist(b: &FiberBsdf, theta_o: f64, hr: HRange, n: u64, seed: u64) -> (Vec<u64>, f64, f64) {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    let mut counts = vec![0u64; NT * NP];
    let (mut sw, mut sw2) = (0.0, 0.0);
    let side = b.camera_side(theta_o);
    for _ in 0..n {
        let u = [rng.random(), rng.random(), rng.random(), rng.random()];
        if let Some(s) = b.sample(&side, hr, u) {
            counts[bin_of(s.theta, s.phi)] += 1;
            // The reported pdf is the mixture pdf at the sampled h, and the weight is the
            // near-field value at that h over it.
            let pdf = b.pdf_at(theta_o, s.theta, s.phi, s.h);
            assert!((pdf - s.pdf).abs() <= 1e-12 * pdf.max(1.0));
            let w = lobe_sum(&s.weight)[1];
            let direct = lobe_sum(&b.eval_near(theta_o, s.theta, s.phi, s.h))[1] / pdf;
            assert!(
                (w - direct).abs() <= 1e-12 * direct.max(1.0),
                "{w} vs {direct}"
            );
            sw += w;
            sw2 += w * w;
        }
    }
    (
        counts,
        sw / n as f64,
        (sw2 / n as f64 - (sw / n as f64).powi(2)).max(0.0),
    )
}

/// ∫∫ sum M N over (theta, phi), green channel, of the near field at `h`.
fn albedo_near(b: &FiberBsdf, theta_o: f64, h: f64) -> f64 {
    integrate(-FRAC_PI_2, FRAC_PI_2, 24, &mut |t| {
        integrate(-PI, PI, 48, &mut |p| {
            lobe_sum(&b.eval_near(theta_o, t, p, h))[1]
        })
    })
}

/// The albedo of a query: for a span, the `h`-average of the near-field albedo, which is
/// what far field / multi-scale integrate (seed Eq. 26; the analytic far field's agreement
/// with that average is the model's own test). The albedo rises steeply near the rim
/// (grazing Fresnel), so `h` takes 12 panels: 3 were 1 % low on `[-1, 1]` (0.7195 against
/// 0.7267 for `fur()` at `theta_o = 0.4`).
fn albedo(b: &FiberBsdf, theta_o: f64, hr: HRange) -> f64 {
    match hr {
        HRange::At(h) => albedo_near(b, theta_o, h),
        HRange::Span(h1, h2) => {
            integrate(h1, h2, 12, &mut |h| albedo_near(b, theta_o, h)) / (h2 - h1)
        }
    }
}

fn check_sampling(p: &FurParams, lobes: LobeSet, theta_o: f64, hr: HRange, seed: u64) {
    check_sampling_of(
        &FiberBsdf::new(p, Tint::default(), lobes),
        theta_o,
        hr,
        seed,
    );
}

/// [`check_sampling`] of a prepared BCSDF (e.g. one reading the selection table).
fn check_sampling_of(b: &FiberBsdf, theta_o: f64, hr: HRange, seed: u64) {
    let lobes = b.lobes();
    let n = 40_000;
    let (counts, mean_w, var_w) = sample_hist(b, theta_o, hr, n, seed);
    let probs = match hr {
        HRange::At(h) => bin_probs(&mut |t, ph| b.pdf_at(theta_o, t, ph, h), 3),
        HRange::Span(h1, h2) => bin_probs(
            &mut |t, ph| integrate(h1, h2, 6, &mut |h| b.pdf_at(theta_o, t, ph, h)) / (h2 - h1),
            2,
        ),
    };
    let total: f64 = probs.iter().sum();
    // The pdf integrates to one: quadrature error of the binned integral is < 1e-3 here.
    assert!((total - 1.0).abs() < 2e-3, "pdf mass {total}");
    let z = chi_square_z(&counts, &probs, n);
    // z ~ N(0,1) when sampling matches the pdf; 4.5 sigma keeps false alarms < 1e-5.
    assert!(
        z < 4.5,
        "chi-square z = {z:.2} (lobes {lobes:?}, theta_o {theta_o}, {hr:?})"
    );
    // E[weight] equals the integral of the BCSDF (f cos / pdf consistency); 5 standard
    // errors plus 0.5 % for the quadrature of sharp lobes.
    let a = albedo(b, theta_o, hr);
    let se = (var_w / n as f64).sqrt();
    assert!(
        (mean_w - a).abs() < 5.0 * se + 5e-3 * a,
        "E[w] {mean_w} vs albedo {a} (se {se}) lobes {lobes:?} {hr:?}"
    );
}

#[test]
fn chi_square_near_field_each_lobe_and_mixture() {
    for (k, p) in [hair(), fur(), sharp()].iter().enumerate() {
        let b = FiberBsdf::new(p, Tint::default(), LobeSet::ALL);
        let mut sets: Vec<LobeSet> = b.lobes().iter().map(LobeSet::only).collect();
        sets.push(LobeSet::ALL);
        for (j, set) in sets.into_iter().enumerate() {
            let theta_o = [0.3, -0.9, 1.2][j % 3];
            let h = [0.35, -0.7, 0.05][(j + k) % 3];
            check_sampling(p, set, theta_o, HRange::At(h), 100 + (k * 10 + j) as u64);
        }
    }
}

#[test]
fn chi_square_far_and_multiscale_marginal() {
    check_sampling(&fur(), LobeSet::ALL, 0.4, HRange::Span(-1.0, 1.0), 7);
    check_sampling(&hair(), LobeSet::ALL, -0.2, HRange::Span(0.1, 0.6), 8);
}

/// The renderer samples with the tabulated lobe selection ([`crate::render::select`]):
/// sampling and pdf read the same table, so the chi-square and weight checks still hold,
/// between table nodes as well.
#[test]
fn chi_square_with_the_selection_table() {
    for (k, (p, theta_o, hr)) in [
        (fur(), 0.31, HRange::At(0.337)),
        (sharp(), -0.95, HRange::At(-0.71)),
        (fur(), 0.4, HRange::Span(-1.0, 1.0)),
        (hair(), -0.2, HRange::Span(0.1, 0.6)),
    ]
    .into_iter()
    .enumerate()
    {
        let mut b = FiberBsdf::new(&p, Tint::default(), LobeSet::ALL);
        b.build_select_table();
        check_sampling_of(&b, theta_o, hr, 300 + k as u64);
    }
}

/// The table reproduces the exact selection at its nodes (f32 storage), and between them
/// gives a blend of the four surrounding nodes (each probability within their range), so
/// a swapped or shifted axis fails. How far the blend is from the exact selection costs
/// only efficiency (sampler and pdf read the same table); it is largest where the exact
/// one jumps, e.g. where the path starts to miss the medulla (TTs 0.25 -> 0 across a
/// 0.05 cell of `h`) and at the rim (grazing Fresnel).
#[test]
fn selection_table_matches_the_exact_selection() {
    use crate::render::select::{N_H, N_THETA};
    let (dt, dh) = (PI / (N_THETA - 1) as f64, 2.0 / (N_H - 1) as f64);
    for p in [fur(), sharp()] {
        let exact = FiberBsdf::new(&p, Tint::default(), LobeSet::ALL);
        let mut tab = exact.clone();
        tab.build_select_table();
        let node = |i: usize, j: usize| (-FRAC_PI_2 + i as f64 * dt, -1.0 + j as f64 * dh);
        for i in (0..N_THETA - 1).step_by(7) {
            for j in (0..N_H - 1).step_by(3) {
                let (to, h) = node(i, j);
                let corners = [(0, 0), (0, 1), (1, 0), (1, 1)].map(|(a, b)| {
                    let (t, hh) = node(i + a, j + b);
                    exact.lobe_probs(t, hh)
                });
                let (a, b) = (corners[0], tab.lobe_probs(to, h));
                for l in 0..5 {
                    assert!((a[l] - b[l]).abs() < 1e-6, "node {to} {h}: {a:?} vs {b:?}");
                }
                let mid = tab.lobe_probs(to + 0.37 * dt, h + 0.61 * dh);
                for l in 0..5 {
                    let lo = corners.iter().map(|c| c[l]).fold(f64::INFINITY, f64::min);
                    let hi = corners.iter().map(|c| c[l]).fold(0.0, f64::max);
                    assert!(
                        mid[l] >= lo - 1e-6 && mid[l] <= hi + 1e-6,
                        "cell {to} {h} lobe {l}: {} outside [{lo}, {hi}]",
                        mid[l]
                    );
                }
            }
        }
    }
}

#[test]
fn chi_square_detects_a_wrong_pdf() {
    // The test must be able to fail: compare samples of the fur BCSDF with the pdf of a
    // different h; the z-score must be huge.
    let b = FiberBsdf::new(&fur(), Tint::default(), LobeSet::ALL);
    let (counts, _, _) = sample_hist(&b, 0.3, HRange::At(0.3), 60_000, 3);
    let probs = bin_probs(&mut |t, p| b.pdf_at(0.3, t, p, 0.1), 3);
    assert!(chi_square_z(&counts, &probs, 60_000) > 20.0);
}

#[test]
fn white_furnace_energy_bounds() {
    // kappa = 0, no absorption, l = 1: energy sum_p A_p <= 1 (the higher orders are left
    // out), and the BCSDF integrates to about A_0 + A_1 + A_2.
    let p = params([1.55, 0.0, 2.0, 6.0, 15.0, 0.0, 0.0, 0.0, 0.0, 1.0]);
    let b = FiberBsdf::new(&p, Tint::GREY, LobeSet::ALL);
    for theta_o in [0.0, 0.5, -1.0] {
        for h in [0.0, 0.5, -0.9] {
            let a = albedo(&b, theta_o, HRange::At(h));
            let slice = b.model(0).azimuthal(-theta_o);
            let geo = slice.geometry(h);
            let at = slice.attenuation(&geo, LobeSet::UNSCATTERED);
            let expect = at.get(Lobe::R) + at.get(Lobe::TT) + at.get(Lobe::TRT);
            // <= 1 up to quadrature error (1e-4).
            assert!(a <= 1.0 + 1e-4, "albedo {a} at theta_o {theta_o} h {h}");
            // A_p varies with theta_d across the 6-18 deg wide M lobes and M loses its mass
            // beyond 90 deg: allow 3 %.
            assert!((a - expect).abs() < 0.03 * expect, "{a} vs {expect}");
        }
    }
}

#[test]
fn frame_round_trips_directions() {
    use crate::render::math::V3;
    let u = V3::new(0.3, 0.9, -0.2).normalized();
    let wo = V3::new(0.1, 0.2, 1.0).normalized();
    let f = Frame::new(u, wo);
    let (to, po) = f.to_local(wo);
    assert!(po.abs() < 1e-12, "camera side has phi = 0");
    assert!((to - wo.dot(u).asin()).abs() < 1e-12);
    for (t, p) in [(0.3, 2.0), (-1.2, -0.4), (0.0, 3.1)] {
        let d = f.to_world(t, p);
        let (t2, p2) = f.to_local(d);
        assert!((t - t2).abs() < 1e-12 && (p - p2).abs() < 1e-12);
    }
    // Right-handed (v, w, u): azimuth increases counter-clockwise about u.
    assert!((f.v.cross(f.w).dot(u) - 1.0).abs() < 1e-12);
}

/// The scattered lobes' `M_s` takes the light as the model's incident side, as the fit
/// does (`C^M` is not reciprocal): swapping camera and light (same `theta_d`, `h`, `phi`,
/// hence the same azimuthal part) scales TTs by `M_s(b, a) / M_s(a, b)`, for every mode.
/// The renderer read `M_s(theta_o, theta_light)` before, the inverse ratio.
#[test]
fn scattered_lobes_read_c_m_with_the_light_incident() {
    let p = params([1.49, 0.86, 2.64, 9.45, 17.63, 0.39, 3.15, 0.21, 0.79, 0.68]);
    let b = FiberBsdf::new(&p, Tint::default(), LobeSet::only(Lobe::TTs));
    let m = b.model(0);
    let (cam, light, phi, h) = (0.0, 60f64.to_radians(), 0.4, 0.2);
    let ms = |ti: f64, tr: f64| m.longitudinal(ti, tr, phi, LobeSet::ALL).get(Lobe::TTs);
    let want = ms(cam, light) / ms(light, cam);
    // The tables make the ratio far from 1 here (0.2 / 0.46 for the red fox).
    assert!((want - 1.0).abs() > 0.3, "{want}");
    let i = Lobe::TTs.index();
    for hr in [
        HRange::At(h),
        HRange::Span(-1.0, 1.0),
        HRange::Span(0.1, 0.3),
    ] {
        let a = b.eval(cam, light, phi, hr)[i][0];
        let s = b.eval(light, cam, phi, hr)[i][0];
        assert!(a > 0.0 && s > 0.0, "{hr:?}");
        // Same azimuthal factor both ways up to rounding: 1e-9 relative.
        assert!(
            (s / a / want - 1.0).abs() < 1e-9,
            "{hr:?}: {} vs {want}",
            s / a
        );
    }
}

/// Relative variance `var / mean^2` of the sample weight (green channel).
fn rel_var(b: &FiberBsdf, theta_o: f64, hr: HRange, seed: u64) -> f64 {
    let (_, m, v) = sample_hist(b, theta_o, hr, 20_000, seed);
    v / (m * m)
}

/// The lobe choice follows the lobes' energy closely enough that no sample weight is an
/// outlier. Reading the scattered lobes' energy at the specular `theta_d` alone gave TTs
/// probability 0 near the rim (`h` -0.79 at `theta_o` 0.4, where that path misses the
/// medulla but steeper ones meet it), so its light came as rare weights up to 248 and the
/// relative variance of the span's weight was 3.5. With the energy read over `M_s`'s
/// quantiles (and its column mass) the cases below measured 0.004-0.09 (20 000 samples,
/// seed 9). The bound 0.25 leaves ~3x for the estimate's own noise (heavy tails make it
/// noisy) and still fails the old 3.5 by far.
#[test]
fn sample_weights_have_low_relative_variance() {
    for (name, p) in [("fur", fur()), ("sharp", sharp())] {
        let b = FiberBsdf::new(&p, Tint::default(), LobeSet::ALL);
        for (to, hr) in [
            (0.3, HRange::At(0.35)),
            (1.2, HRange::At(-0.7)),
            (-1.4, HRange::At(0.05)),
            (0.4, HRange::Span(-1.0, 1.0)),
            (1.3, HRange::Span(-1.0, 1.0)),
        ] {
            let r = rel_var(&b, to, hr, 9);
            assert!(
                r < 0.25,
                "{name} theta_o {to} {hr:?}: relative variance {r}"
            );
        }
    }
    // The rim path of the finding: TTs must be selectable there.
    let b = FiberBsdf::new(&fur(), Tint::default(), LobeSet::ALL);
    let probs = b.lobe_probs(0.4, -0.79);
    assert!(probs[Lobe::TTs.index()] > 0.01, "{probs:?}");
}

/// At a grazing camera most of R's `M_R` falls beyond the pole (sharp lobes, strong
/// cuticle tilt), so the unscattered lobes' selection must weigh `A_p` by the truncated
/// lobe's in-domain mass. Selecting by `A_p` alone passed every other test; here it gave R
/// 99.8 % instead of 97.8 % at `theta_o` -1.53 and relative variances 0.17-0.34 (measured,
/// 20 000 samples, seed 9) against 0.008 with the mass. The bound 0.05 is 6x the correct
/// figure and a third of the lowest wrong one.
#[test]
fn grazing_selection_weighs_the_truncated_lobe_mass() {
    let b = FiberBsdf::new(&sharp(), Tint::default(), LobeSet::ALL);
    for hr in [HRange::Span(-1.0, 1.0), HRange::At(0.3), HRange::At(-0.6)] {
        let r = rel_var(&b, -1.53, hr, 9);
        assert!(r < 0.05, "theta_o -1.53 {hr:?}: relative variance {r}");
    }
}

/// ISHair's Cauchy proposals ([`crate::render::ishair`]) and the uniform baseline: the
/// samples follow the pdf the sampler reports, per lobe and mixed, in each mode (near
/// field at one `h`, far field over [-1, 1], multi-scale over a footprint), with and
/// without the selection table, as Mitsuba's chi2 test checks a BSDF's `sample` against
/// its `pdf`; the weights' mean is the BCSDF's integral.
#[test]
fn chi_square_ishair_and_uniform_per_mode() {
    use crate::render::ishair::Sampling;
    // (params, theta_o, query, sampler, with the selection table): near field, far field
    // and multi-scale footprints; span cases cost ~10x a near one (the binned pdf
    // integrates over h), so the uniform baseline takes one of each.
    let (ish, uni) = (Sampling::Ishair, Sampling::Uniform);
    for (k, (p, theta_o, hr, sampling, table)) in [
        (fur(), 0.3, HRange::At(0.35), ish, false),
        (sharp(), -0.95, HRange::At(-0.71), ish, true),
        (hair(), 1.2, HRange::At(0.05), ish, false),
        (fur(), 0.3, HRange::At(0.35), uni, false),
        (fur(), 0.4, HRange::Span(-1.0, 1.0), ish, true),
        (sharp(), 1.2, HRange::Span(-1.0, 1.0), uni, false),
        (hair(), -0.2, HRange::Span(0.1, 0.6), ish, false),
        (sharp(), -0.95, HRange::Span(-0.2, 0.45), ish, true),
    ]
    .into_iter()
    .enumerate()
    {
        let mut b = FiberBsdf::new(&p, Tint::default(), LobeSet::ALL);
        b.sampling = sampling;
        if table {
            b.build_select_table();
        }
        check_sampling_of(&b, theta_o, hr, 500 + k as u64);
    }
    // Each lobe alone under ISHair (near field).
    let b0 = FiberBsdf::new(&fur(), Tint::default(), LobeSet::ALL);
    for (j, l) in b0.lobes().iter().enumerate() {
        let mut b = FiberBsdf::new(&fur(), Tint::default(), LobeSet::only(l));
        b.sampling = Sampling::Ishair;
        check_sampling_of(
            &b,
            [0.3, -0.9, 1.2][j % 3],
            HRange::At(-0.4),
            600 + j as u64,
        );
    }
}

/// The chi-square test can fail for ISHair too: its samples against the Gaussian
/// sampler's pdf (a different proposal of the same lobes) give a huge z.
#[test]
fn chi_square_tells_ishair_from_the_gaussian_proposal() {
    use crate::render::ishair::Sampling;
    let mut b = FiberBsdf::new(&sharp(), Tint::default(), LobeSet::ALL);
    b.sampling = Sampling::Ishair;
    let (counts, _, _) = sample_hist(&b, 0.3, HRange::At(0.3), 60_000, 3);
    let mut g = b.clone();
    g.sampling = Sampling::Lobes;
    let probs = bin_probs(&mut |t, p| g.pdf_at(0.3, t, p, 0.3), 3);
    assert!(chi_square_z(&counts, &probs, 60_000) > 20.0);
}
