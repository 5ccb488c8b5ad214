use super::sweep::{FourierGrid, FourierTable, SweepWindow, UniformGrid};
use super::*;
use crate::model::quadrature::adaptive_gk;
use crate::model::FurModel;
use crate::params::FurParams;

/// `lam_fit`: paper mode keeps the Appendix's chord; tolerance mode's quadratic passes
/// through all three nodes, and where its curvature is capped, still through the end
/// nodes. Interpolation is exact up to rounding of the node values' size (1e-12
/// absolute on exponents of order 1-10).
#[test]
fn lam_fit_is_the_chord_or_the_capped_quadratic() {
    let m = FurModel::new(&FurParams::preset("cat").expect("preset"));
    let az = m.azimuthal(0.2);
    let tol = FarSlice::far(&az, LobeSet::ALL, &FarOptions::default());
    let paper = FarSlice::far(&az, LobeSet::ALL, &FarOptions::paper());
    let p = 1;
    let nodes = [0.1, 0.3, 0.5].map(|u| tol.node_with(u, false));
    let mut ns = [&nodes[0], &nodes[1], &nodes[2]];
    if nodes[0].dphi[p] < 0.0 {
        ns.reverse();
    }
    let lo = ns[0].phi[p];
    let xs = ns.map(|n| n.phi[p] - lo);
    let at = |lam: &[f64; 3], k: usize| poly(lam, xs[k]) - ns[k].lam[p];
    let chord = paper.lam_fit(p, xs, ns);
    assert_eq!(chord[2], 0.0);
    let quad = tol.lam_fit(p, xs, ns);
    // The medulla's chord bends cat's TT attenuation: the line misses the middle node.
    assert!(at(&chord, 1).abs() > 1e-4, "{}", at(&chord, 1));
    for k in 0..3 {
        assert!(at(&chord, k).abs() <= 1e-12 || k == 1);
        assert!(at(&quad, k).abs() <= 1e-12, "node {k}: {}", at(&quad, k));
    }
    // A Gaussian so wide that the cap binds: the end nodes still fit exactly.
    // (Here the attenuation is convex, curvature 3.8 per rad^2.)
    assert!(quad[2] > 1.0, "{quad:?}");
    let mut wide = FarSlice::far(&az, LobeSet::ALL, &FarOptions::default());
    let cap = 0.5 * quad[2];
    wide.betas[p] = (super::super::closed_form::LAM_CURVE_MAX * 0.5 / cap).sqrt();
    let capped = wide.lam_fit(p, xs, ns);
    assert!((capped[2] - cap).abs() <= 1e-12 * cap, "{capped:?}");
    for k in [0, 2] {
        assert!(
            at(&capped, k).abs() <= 1e-12,
            "node {k}: {}",
            at(&capped, k)
        );
    }
}

/// [`FarSlice::gl_piece_with`]'s estimate (the 16- and 8-point rules' difference at the
/// probes) must bound the 16-point rule's actual error at the probes, measured against
/// adaptive Gauss-Kronrod to 1e-12, on pieces up to the [`GL_SPAN_SIGMAS`] span that
/// narrow pieces have (2.5 beta, a margin for the end nodes), and must not claim 1e-4
/// on a piece far too wide for the rules. Human TT and TRT at theta_d = 0.3 from u = 0.3:
/// pieces up to du = 0.1 are smooth (errors at rounding level); wider ones straddle
/// the medulla edge (u = 0.453), whose kink in the attenuation the rules cannot
/// integrate exactly, and there the estimate must still hold.
#[test]
fn gl_estimate_bounds_the_rule_error() {
    let m = FurModel::new(&FurParams::preset("human").expect("preset"));
    let az = m.azimuthal(0.3);
    let fs = FarSlice::far(&az, LobeSet::ALL, &FarOptions::default());
    let mut kinked = 0;
    for p in [1, 2] {
        let beta = fs.betas[p];
        let gauss = |x: f64| (-0.5 * (x / beta).powi(2)).exp() / (beta * TAU.sqrt());
        for du in [0.005, 0.02, 0.05, 0.1, 0.2, 0.4, 0.8, 1.2] {
            let (u0, u1) = (0.3, 0.3 + du);
            let (n0, n1) = (fs.node_with(u0, true), fs.node_with(u1, true));
            let (lo, hi) = (n0.phi[p].min(n1.phi[p]), n0.phi[p].max(n1.phi[p]));
            let (piece, err) = fs.gl_piece_with(p, &n0, &n1, lo, hi, false, true, &mut Tape::Off);
            let Piece::Gl { nodes, .. } = &piece else {
                panic!("not a GL piece")
            };
            let (plo, phi) = piece.range();
            let mid = 0.5 * (plo + phi);
            let (mut actual, mut peak) = (0.0f64, 0.0f64);
            for k in GL_FEW_PROBES {
                let at = mid + k * beta;
                let rule: f64 = nodes.iter().map(|&(ph, w)| w * gauss(ph - at)).sum();
                let exact = adaptive_gk(
                    |u| {
                        let n = fs.node_with(u, false);
                        n.pre[p] * n.lam[p].exp() * gauss(n.phi[p] - at)
                    },
                    &[u0, u1],
                    1e-12,
                    0.0,
                    100_000,
                )
                .value;
                actual = actual.max((rule - exact).abs());
                peak = peak.max(exact.abs());
            }
            let span = (phi - plo) / beta;
            if span <= 1.25 * GL_SPAN_SIGMAS {
                if actual > 1e-6 * peak {
                    kinked += 1;
                }
                assert!(
                    actual <= err + 1e-12 * peak,
                    "p {p} span {span:.2} beta: error {actual:.2e} above estimate {err:.2e}"
                );
            }
            if span > 4.0 {
                assert!(
                    err > 1e-4 * peak,
                    "p {p} span {span:.2} beta: estimate {err:.2e}"
                );
            }
        }
    }
    // The kink makes errors the estimate has to catch (TT at du 0.2, 0.4; TRT at 0.2).
    assert!(
        kinked >= 3,
        "only {kinked} pieces with errors above rounding"
    );
}

/// The AVX2 build of the sweep must give the portable build's values bit for bit (the
/// dispatch picks one by CPU; results may not depend on the machine), on long runs
/// (restarts), short windows, both signs and a shifted image.
#[test]
fn gaussian_sweep_avx2_equals_portable_build() {
    let sorted: Vec<f64> = (0..361).map(|q| -PI + q as f64 * TAU / 360.0).collect();
    let g = UniformGrid::detect(&sorted).expect("even grid");
    let nodes: Vec<(f64, f64)> = (0..37)
        .map(|k| (-3.0 + 0.17 * k as f64, 1.0 + 0.01 * k as f64))
        .collect();
    for (beta, sign, shift) in [(0.3, 1.0, 0.0), (0.05, -1.0, 0.0), (0.5, 1.0, TAU)] {
        let at = SweepWindow {
            sign,
            shift,
            qa: 0,
            qb: sorted.len(),
            beta,
            w: CULL_SIGMAS * beta,
        };
        let mut portable = vec![0.0; sorted.len()];
        g.gaussian_sweep_body(&nodes, &at, &mut portable);
        let mut chosen = vec![0.0; sorted.len()];
        g.gaussian_sweep(&nodes, &at, &mut chosen);
        assert!(portable.iter().any(|&v| v > 0.0));
        for (a, b) in portable.iter().zip(&chosen) {
            assert_eq!(a.to_bits(), b.to_bits(), "beta {beta} sign {sign}");
        }
    }
}

/// The Fourier sum of node Gaussians equals the wrapped Gaussians summed directly, for
/// either side alone and both, at widths where it is chosen; it is not chosen for a
/// narrow lobe, whose window covers a few grid points.
#[test]
fn fourier_grid_equals_wrapped_gaussian_sums() {
    let sorted: Vec<f64> = (0..91).map(|q| q as f64 * PI / 90.0).collect();
    let g = UniformGrid::detect(&sorted).expect("even grid");
    let nodes: Vec<(f64, f64)> = (0..23)
        .map(|k| (-2.9 + 0.41 * k as f64, 0.2 + 0.05 * (k % 7) as f64))
        .collect();
    let mut table = FourierTable::default();
    for beta in [0.2, 0.5, 1.3, 2.5] {
        let f = FourierGrid::new(&g, sorted.len(), beta, CULL_SIGMAS * beta, 2)
            .expect("a wide lobe takes the series");
        table.reserve(&g, sorted.len(), f.rho.len());
        for sides in [(true, false), (false, true), (true, true)] {
            let mut s = vec![0.0; sorted.len()];
            f.add(&nodes, sides, &table, &mut s);
            let scale: f64 = nodes.iter().map(|n| n.1).sum::<f64>() / (beta * TAU.sqrt());
            for (q, &phi) in sorted.iter().enumerate() {
                let direct: f64 = nodes
                    .iter()
                    .map(|&(ph, w)| {
                        let d = if sides.0 {
                            wrapped_gaussian(ph - phi, beta)
                        } else {
                            0.0
                        };
                        let m = if sides.1 {
                            wrapped_gaussian(ph + phi, beta)
                        } else {
                            0.0
                        };
                        w * (d + m)
                    })
                    .sum();
                // Truncation is 1e-17 of the mean; rounding grows with the terms
                // (up to 45 here) times eps of the nodes' summed peak.
                assert!(
                    (s[q] - direct).abs() <= 1e-13 * scale,
                    "beta {beta} sides {sides:?} phi {phi}: {} vs {direct}",
                    s[q]
                );
            }
        }
    }
    // Human hair's R lobe (beta_n 3.75 deg): 136 terms against a 33-point window.
    let beta = 3.75f64.to_radians();
    assert!(FourierGrid::new(&g, sorted.len(), beta, CULL_SIGMAS * beta, 2).is_none());
}

/// The misfit integral of a quartic is exact (the quartic through five points is
/// itself), whatever the nodes' order and spacing.
#[test]
fn misfit_integral_is_exact_for_quartics() {
    let f = |x: f64| 0.3 - 1.1 * x + 0.7 * x * x + 2.0 * x.powi(3) - 1.5 * x.powi(4);
    for s in [[0.0, 0.5, 1.0], [0.9, 0.35, 0.1], [2.0, 2.3, 3.1]] {
        let c = quadratic_through(s, s.map(f));
        let quarter = [0.25, 0.75].map(|t| {
            let x = s[0] + t * (s[2] - s[0]);
            (x, f(x) - poly(&c, x))
        });
        let est = FarSlice::misfit_integral(s, quarter);
        // Reference: 40-point Gauss-Legendre of f - quadratic over the nodes' range.
        let (lo, hi) = (s[0].min(s[2]), s[0].max(s[2]));
        let gl = crate::model::quadrature::GaussLegendre::cached(40);
        let exact: f64 = gl
            .nodes
            .iter()
            .zip(&gl.weights)
            .map(|(x, w)| {
                let u = 0.5 * (lo + hi) + 0.5 * (hi - lo) * x;
                0.5 * (hi - lo) * w * (f(u) - poly(&c, u))
            })
            .sum();
        // Both exact up to rounding of terms of order 1.
        assert!((est - exact).abs() < 1e-12, "{s:?}: {est} vs {exact}");
        assert!(exact.abs() > 1e-4, "the case must have a misfit to measure");
    }
}
