//! Per-render table of the sampler's lobe-selection state.
//!
//! [`super::bsdf`]'s sampler picks a lobe with probability ∝ its energy on the camera side
//! (`A_p(h)` times the in-domain mass of `M_p`, or `A^s_p(h)` times the scattered fraction of
//! `C^N`) and frames the scattered lobes at the medulla offset `x` and the segment directions
//! `Phi^s_p(h)`. These are *choices* of the sampler, not physics: any probabilities and any
//! frame keep the estimator unbiased as long as the sampler and its pdf use the same ones
//! and the mixture covers every lobe that carries energy. Computing them exactly costs three
//! attenuations (one Fresnel and the absorption exponentials per channel) per query, and a
//! path vertex queries them five times (one sample, four MIS midpoints), so the renderer
//! reads them from this table, bilinear in `(theta_o, h)`, built once per render from the
//! exact formula. Sample and pdf read the same table, so the mixture pdf stays exact (the
//! chi-square tests in `bsdf_tests` run with and without it).
//!
//! Grid: [`N_THETA`] nodes of `theta_o` over `[-pi/2, pi/2]` (3 degrees) and [`N_H`] nodes of
//! `h` over `[-1, 1]`, stored as `f32` (32 bytes a node, 80 KB in all, so it stays in cache).
//! Interpolated probabilities are renormalised to sum to one.

use std::f64::consts::{FRAC_PI_2, PI};

/// `theta_o` nodes over `[-pi/2, pi/2]`.
pub const N_THETA: usize = 61;
/// `h` nodes over `[-1, 1]`.
pub const N_H: usize = 41;

/// The sampler's state at one `(theta_o, h)`: lobe probabilities (by
/// [`crate::model::Lobe::index`]) and the scattered lobes' frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Selection {
    /// Probability of each lobe, indexed by [`crate::model::Lobe::index`].
    pub probs: [f64; 5],
    /// Medulla entry offset `x` of the `C^N` query.
    pub x_med: f64,
    /// `Phi^s_p` of TTs and TRTs.
    pub phi_s: [f64; 2],
}

/// [`Selection`] on a `(theta_o, h)` grid (see module doc).
#[derive(Clone, Debug)]
pub struct SelectTable {
    /// `[theta node][h node]`: five probabilities, `x`, `Phi^s_1`, `Phi^s_2`.
    nodes: Vec<[f32; 8]>,
}

const D_THETA: f64 = PI / (N_THETA - 1) as f64;
const D_H: f64 = 2.0 / (N_H - 1) as f64;

impl SelectTable {
    /// Tabulate `exact(theta_o, h)` at the grid nodes.
    pub fn build(exact: impl Fn(f64, f64) -> Selection) -> SelectTable {
        let mut nodes = Vec::with_capacity(N_THETA * N_H);
        for i in 0..N_THETA {
            let theta_o = -FRAC_PI_2 + i as f64 * D_THETA;
            for j in 0..N_H {
                let s = exact(theta_o, -1.0 + j as f64 * D_H);
                let p = s.probs;
                nodes.push(
                    [
                        p[0], p[1], p[2], p[3], p[4], s.x_med, s.phi_s[0], s.phi_s[1],
                    ]
                    .map(|v| v as f32),
                );
            }
        }
        SelectTable { nodes }
    }

    /// Bilinear lookup; arguments outside the grid are clamped to it.
    pub fn lookup(&self, theta_o: f64, h: f64) -> Selection {
        let (i, ft) = cell((theta_o + FRAC_PI_2) / D_THETA, N_THETA);
        let (j, fh) = cell((h + 1.0) / D_H, N_H);
        let at = |a: usize, b: usize| &self.nodes[a * N_H + b];
        let (n00, n01, n10, n11) = (at(i, j), at(i, j + 1), at(i + 1, j), at(i + 1, j + 1));
        let v: [f64; 8] = std::array::from_fn(|k| {
            let c = [n00[k], n01[k], n10[k], n11[k]].map(f64::from);
            // The azimuths `Phi^s_p` are angles: the corners are read on the branch of
            // the first, else a cell straddling +-pi interpolates to the opposite side.
            let c = if k >= 6 {
                c.map(|a| c[0] + crate::model::azimuthal::wrap_angle(a - c[0]))
            } else {
                c
            };
            let lo = c[0] + fh * (c[1] - c[0]);
            let hi = c[2] + fh * (c[3] - c[2]);
            lo + ft * (hi - lo)
        });
        let mut probs = [v[0], v[1], v[2], v[3], v[4]];
        let sum: f64 = probs.iter().sum();
        if sum > 0.0 {
            probs = probs.map(|p| p / sum);
        }
        Selection {
            probs,
            x_med: v[5],
            phi_s: [v[6], v[7]].map(crate::model::azimuthal::wrap_angle),
        }
    }
}

/// Cell index and fraction of grid coordinate `x` on `n` nodes, clamped to the grid.
#[inline]
fn cell(x: f64, n: usize) -> (usize, f64) {
    let x = x.clamp(0.0, (n - 1) as f64);
    let i = (x as usize).min(n - 2);
    (i, x - i as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn smooth(theta_o: f64, h: f64) -> Selection {
        let w = [1.0 + h, 2.0 - h, 1.0 + theta_o.sin(), 0.5, 0.0];
        let s: f64 = w.iter().sum();
        Selection {
            probs: w.map(|x| x / s),
            x_med: 0.3 * h,
            phi_s: [theta_o, 2.0 * h],
        }
    }

    #[test]
    fn lookup_reproduces_nodes_and_sums_to_one() {
        let t = SelectTable::build(smooth);
        for (i, j) in [(0, 0), (7, 13), (N_THETA - 1, N_H - 1), (30, 20)] {
            let (to, h) = (-FRAC_PI_2 + i as f64 * D_THETA, -1.0 + j as f64 * D_H);
            let (a, b) = (t.lookup(to, h), smooth(to, h));
            // f32 storage: 1e-6 relative of values of order one.
            for k in 0..5 {
                assert!((a.probs[k] - b.probs[k]).abs() < 1e-6, "{a:?} vs {b:?}");
            }
            assert!((a.x_med - b.x_med).abs() < 1e-6);
            assert!((a.phi_s[0] - b.phi_s[0]).abs() < 1e-6);
        }
        // Between nodes and outside the grid: a proper distribution, zero stays zero.
        for (to, h) in [(0.123, 0.456), (-3.0, 2.0), (1.5, -0.999)] {
            let s = t.lookup(to, h);
            assert!((s.probs.iter().sum::<f64>() - 1.0).abs() < 1e-12);
            assert!(s.probs.iter().all(|&p| p >= 0.0) && s.probs[4] == 0.0);
        }
        // Linear in h between nodes (the x_med column is linear in h): exact up to f32.
        let s = t.lookup(0.2, 0.5 * D_H + 0.01);
        assert!((s.x_med - 0.3 * (0.5 * D_H + 0.01)).abs() < 1e-6);
    }

    /// `Phi^s_p` is an angle: a cell whose nodes straddle +-pi interpolates on the short
    /// arc (a plain blend of 3.1 and -3.1 gave 0, the opposite side of the fiber).
    #[test]
    fn lookup_interpolates_azimuths_on_the_short_arc() {
        let t = SelectTable::build(|_, h| Selection {
            probs: [1.0, 0.0, 0.0, 0.0, 0.0],
            x_med: 0.0,
            phi_s: [if h < 0.0 { 3.1 } else { -3.1 }, 0.2],
        });
        // h = 0 is a node (N_H odd); halfway to the node below, the arc's middle is pi.
        let s = t.lookup(0.3, -0.5 * D_H);
        // f32 storage of 3.1: 1e-6.
        assert!((s.phi_s[0].abs() - PI).abs() < 1e-6, "{s:?}");
        assert!(s.phi_s[0] > -PI && s.phi_s[0] <= PI);
        // A quarter of the way from the 3.1 node: 3.1 + 0.25 * (2 pi - 6.2), wrapped.
        let s = t.lookup(0.3, -0.75 * D_H);
        assert!(
            (s.phi_s[0] - (3.1 + 0.25 * (2.0 * PI - 6.2))).abs() < 1e-6,
            "{s:?}"
        );
        assert!((s.phi_s[1] - 0.2).abs() < 1e-6);
    }
}
