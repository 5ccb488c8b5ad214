//! The PRT without its SH projection, to measure what the projection costs
//! (`furfit view --reference --decompose`, `reports/viewer/prt_error.md`).
//!
//! The PRT computes `L_o(x) = ∫ g(w) T(x, w) dw` with `g = L P / cos theta` (see
//! [`super::prt`]) as `sum_k c_k v_k(x)`, `c` and `v` the order-4 SH projections of `g`
//! and `T`. For an order-4 light `c` is the exact projection of `g`, so the sum is
//! `∫ g proj4(T) dw`: the one truncation is of `T`. Here the same visibility (the same
//! sweep, the same transmittances at the same directions) is integrated against `g`
//! itself: `T` is taken constant over each sweep direction's cell of the product rule
//! (a Gauss-Legendre band in `y` times an azimuth sector), and `g` is integrated over that
//! cell exactly on a fine grid in the fiber frame. The difference between the two
//! reconstructions is the SH truncation of `T` (plus the cell quadrature of `T`, which
//! shrinks with `--dirs`).

use super::prt::{fiber_frame, Rgb25};
use super::sh::{self, N_COEFFS};
use crate::model::far::FarOptions;
use crate::model::LobeSet;
use crate::models::{Integral, ModelParams, Points};
use crate::render::math::V3;
use std::f64::consts::PI;

/// Index of the sweep direction whose cell holds the world direction `d`, for the
/// product rule of `n_z` Gauss-Legendre nodes (in `y`, cumulative weights `bounds`) by
/// `n_phi` azimuths ([`super::prt::sweep_dirs`]: azimuth about `y` from `+x` toward `+z`).
fn cell_of(d: [f64; 3], bounds: &[f64], n_phi: usize) -> usize {
    let i = bounds[1..]
        .iter()
        .position(|&b| d[1] < b)
        .unwrap_or(bounds.len() - 2);
    let a = d[2].atan2(d[0]).rem_euclid(2.0 * PI);
    let j = ((a / (2.0 * PI / n_phi as f64)) as usize).min(n_phi - 1);
    i * n_phi + j
}

/// What [`lighting`] returns.
pub struct Direct {
    /// Per sweep direction (rule order), RGB: `∫ g dw` over its cell.
    pub cells: Vec<Vec<f32>>,
    /// The SH projection of `g` at the camera's exact inclination (no table, no
    /// interpolation between inclinations).
    pub c: Rgb25,
}

/// `g = L P / cos theta` for the camera `wo` (unit, toward the camera), comb tangent `u`
/// and world-SH light `light`, integrated over the cells of the `dirs = (n_z, n_phi)`
/// product rule and projected on the SH basis, on a `grid = (n_theta, n_phi)` midpoint
/// grid in the fiber frame (`dtheta dphi`, P's own measure: no pole singularity).
pub fn lighting(
    channels: &[ModelParams; 3],
    light: &Rgb25,
    wo: V3,
    u: V3,
    dirs: (usize, usize),
    grid: (usize, usize),
) -> Direct {
    let (gz, gw) = sh::gauss_legendre(dirs.0);
    let mut bounds = vec![-1.0];
    for w in &gw {
        bounds.push(bounds.last().copied().unwrap_or(-1.0) + w);
    }
    debug_assert!(gz
        .iter()
        .enumerate()
        .all(|(i, z)| *z > bounds[i] && *z < bounds[i + 1]));
    let r = fiber_frame(wo, u);
    let rt = sh::transpose(&r);
    let theta_o = wo.dot(u).clamp(-1.0, 1.0).asin();
    let (nt, np) = grid;
    let cell = (PI / nt as f64) * (2.0 * PI / np as f64);
    let mut pts = Vec::with_capacity(nt * np);
    let mut world = Vec::with_capacity(nt * np);
    for t in 0..nt {
        let ti = -0.5 * PI + (t as f64 + 0.5) * PI / nt as f64;
        for p in 0..np {
            let ph = -PI + (p as f64 + 0.5) * 2.0 * PI / np as f64;
            pts.push((ti, theta_o, ph));
            let l = [ti.cos() * ph.cos(), ti.cos() * ph.sin(), ti.sin()];
            world.push(sh::mat_vec(&rt, l));
        }
    }
    let points = Points::new(pts);
    let mut out = Direct {
        cells: vec![vec![0.0f32; 3]; dirs.0 * dirs.1],
        c: [[0.0; N_COEFFS]; 3],
    };
    let mut cells = vec![[0.0f64; 3]; dirs.0 * dirs.1];
    let mut ps: Vec<Vec<f64>> = Vec::new();
    for ch in 0..3 {
        let p = match (0..ch).find(|&b| channels[b] == channels[ch]) {
            Some(b) => ps[b].clone(),
            None => {
                let m = &channels[ch];
                let pred = m.model.predict(
                    &m.values,
                    &points,
                    &FarOptions::default(),
                    LobeSet::ALL,
                    Integral::Far,
                );
                pred.lobes.iter().map(|l| l.sum()).collect()
            }
        };
        for (i, d) in world.iter().enumerate() {
            let g = sh::reconstruct(&light[ch], *d) * p[i] * cell;
            cells[cell_of(*d, &bounds, dirs.1)][ch] += g;
            for (ck, y) in out.c[ch].iter_mut().zip(sh::eval(*d)) {
                *ck += g * y;
            }
        }
        ps.push(p);
    }
    for (o, c) in out.cells.iter_mut().zip(&cells) {
        *o = c.iter().map(|&v| v as f32).collect();
    }
    out
}

/// Per-texel radiance and coverage (`[shell][texel]` as `(r, g, b, alpha)`, what
/// [`super::still::render_tex`] draws) of a 3-plane RGB transfer.
pub fn texels(t: &super::prt::Transfer, cov: &[Vec<f32>]) -> Vec<Vec<[f32; 4]>> {
    (0..t.shells)
        .map(|s| {
            let (r, g, b) = (t.at(s, 0), t.at(s, 1), t.at(s, 2));
            (0..t.res * t.res)
                .map(|i| [r[i], g[i], b[i], cov[s][i]])
                .collect()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every direction falls in the cell of the rule node nearest to it in `y` band and
    /// azimuth sector: the nodes themselves map to their own index.
    #[test]
    fn rule_nodes_are_in_their_own_cells() {
        let (nz, np) = (8, 16);
        let rule = sh::Rule::product(nz, np);
        let dirs = super::super::prt::sweep_dirs(&rule);
        let (_, gw) = sh::gauss_legendre(nz);
        let mut bounds = vec![-1.0];
        for w in &gw {
            bounds.push(bounds.last().unwrap() + w);
        }
        for (i, (d, _)) in dirs.iter().enumerate() {
            assert_eq!(cell_of(*d, &bounds, np), i, "{d:?}");
        }
    }
}

#[cfg(test)]
mod lighting_tests {
    use super::*;
    use crate::view::prt::{bcsdf_table, frame_lighting, TableSize};

    /// With nothing in the way (`T = 1`), the SH reconstruction is `c_0 sqrt(4 pi)` and
    /// the direct integration the sum of the cells' `∫ g`: both `∫ g dw`. The cells
    /// partition the sphere, so their sum equals this module's own SH `c_0 sqrt(4 pi)` to
    /// rounding (1e-9 relative); the page's tabulated BCSDF (2-degree grid, linear in the
    /// camera inclination) agrees within 2 % (the tolerance of
    /// `prt::tests::unshadowed_radiance_matches_direct_integral`).
    #[test]
    fn unshadowed_direct_equals_sh() {
        let fur = crate::FurParams::preset("cat").unwrap();
        let mp = ModelParams::from(fur);
        let ch = [mp.clone(), mp.clone(), mp.clone()];
        let light = crate::view::lights::LIGHTS[0].coeffs(55.0, -40.0);
        let wo = V3::new(0.26, 0.64, 0.72).normalized();
        let u = V3::new(0.5, 0.866, 0.0).normalized();
        let d = lighting(&ch, &light, wo, u, (8, 16), (180, 360));
        let k0 = (4.0 * PI).sqrt();
        let cells: f64 = d.cells.iter().map(|c| c[0] as f64).sum();
        let sh_exact = d.c[0][0] * k0;
        assert!(
            (cells / sh_exact - 1.0).abs() < 1e-6,
            "{cells} vs {sh_exact}"
        );
        let table = bcsdf_table(&ch, TableSize::default());
        let page = frame_lighting(&table, &light, wo, u)[0][0] * k0;
        assert!((page / cells - 1.0).abs() < 0.02, "{page} vs {cells}");
    }
}
