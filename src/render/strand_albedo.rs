//! The quadrature half of `--medulla-energy strand` ([`super::strand`]'s module doc):
//! [`EnergyScale::build`] integrates the BCSDF's own clear-cortex albedos `E_u^clear`,
//! `E_s^clear` on the scale's `theta_o` nodes and divides by the network's `E_phys`. Apart
//! from `strand.rs` because it evaluates [`FiberBsdf`], which holds an [`EnergyScale`]: the
//! network and the scale table stay below the BCSDF, this file above it.

use super::bsdf::{FiberBsdf, Tint};
use super::strand::{node_theta, EnergyScale, StrandMlp, N_NODES};
use crate::model::{Lobe, LobeSet};
use crate::params::FurParams;
use rayon::prelude::*;
use std::f64::consts::{FRAC_PI_2, PI};

/// 4-point Gauss-Legendre on [-1, 1].
const GL4: [(f64, f64); 4] = [
    (-0.861_136_311_594_052_6, 0.347_854_845_137_453_9),
    (-0.339_981_043_584_856_3, 0.652_145_154_862_546_1),
    (0.339_981_043_584_856_3, 0.652_145_154_862_546_1),
    (0.861_136_311_594_052_6, 0.347_854_845_137_453_9),
];

/// Composite Gauss-Legendre nodes and weights on [a, b] with `panels` panels.
fn gl_nodes(a: f64, b: f64, panels: usize) -> Vec<(f64, f64)> {
    let w = (b - a) / panels as f64;
    (0..panels)
        .flat_map(|k| {
            let c = a + (k as f64 + 0.5) * w;
            GL4.map(|(x, wt)| (c + 0.5 * w * x, 0.5 * w * wt))
        })
        .collect()
}

impl EnergyScale {
    /// Build for `params` with colour `tint` (the scale is per channel: the tint sets each
    /// channel's `sigma_m_a`).
    ///
    /// Quadrature (deterministic): `h` by 3 Gauss-Legendre panels on each side of the
    /// medulla's edge ([`h_nodes`]). The unscattered lobes integrate their wrapped Gaussian
    /// `D_p` over `phi` exactly (to 1) and `M_p A_p` over `theta` with panels of at most
    /// `beta/2` about the lobe's centre; the scattered lobes, smooth tables, take 8 panels
    /// in `theta` and 12 in `phi` (4 nodes each).
    pub fn build(params: &FurParams, tint: Tint, mlp: &StrandMlp) -> EnergyScale {
        let sma: [f64; 3] = std::array::from_fn(|c| tint.apply(params, c).sigma_m_a);
        let clear = Tint::Absorption {
            sigma_c_a: [0.0; 3],
            sigma_m_a: sma,
        };
        let un = FiberBsdf::new(params, clear, LobeSet::UNSCATTERED);
        let sc = FiberBsdf::new(params, clear, LobeSet::only(Lobe::TTs).with(Lobe::TRTs));
        let has_scattered = !sc.lobes().is_empty();
        let rows: Vec<([f64; 3], [[f64; 3]; 3])> = (0..N_NODES)
            .into_par_iter()
            .map(|i| {
                let to = node_theta(i);
                let eu = unscattered_albedo(&un, params, to);
                let es = if has_scattered {
                    scattered_albedo(&sc, params, to)
                } else {
                    [0.0; 3]
                };
                let mut scale = [1.0; 3];
                let mut phys = [1.0; 3];
                for c in 0..3 {
                    let p = tint.apply(params, c);
                    phys[c] = mlp.albedo(p.eta, p.kappa, p.sigma_m_s, sma[c], p.g, to);
                    if es[c] > 1e-9 {
                        scale[c] = (phys[c] - eu[c]).max(0.0) / es[c];
                    }
                }
                (scale, [phys, eu, es])
            })
            .collect();
        EnergyScale {
            scale: rows.iter().map(|r| r.0).collect(),
            parts: rows.iter().map(|r| r.1).collect(),
        }
    }
}

/// Gauss-Legendre nodes in `h` over [-1, 1] at slice `theta_d`, split where the path
/// starts to miss the medulla (`|h| = kappa eta'`): the attenuations have a kink there and
/// the scattered lobes end there (`panels` per piece).
fn h_nodes(params: &FurParams, theta_d: f64, panels: usize, inner_only: bool) -> Vec<(f64, f64)> {
    let cos_d = theta_d.cos().max(crate::model::geometry::MIN_COS_THETA_D);
    let edge = (params.kappa * crate::model::geometry::eta_prime(params.eta, cos_d)).min(1.0);
    let mut v = if edge > 0.0 {
        gl_nodes(-edge, edge, panels)
    } else {
        Vec::new()
    };
    if !inner_only && edge < 1.0 {
        v.extend(gl_nodes(-1.0, -edge, panels));
        v.extend(gl_nodes(edge, 1.0, panels));
    }
    v
}

/// `E_u` per channel at `theta_o`: `1/2 ∫dh ∫dtheta sum_p M_p A_p` (`∫ D_p dphi = 1`).
fn unscattered_albedo(b: &FiberBsdf, params: &FurParams, theta_o: f64) -> [f64; 3] {
    let mut out = [0.0; 3];
    for l in b.lobes().iter() {
        let (a, w) = crate::model::longitudinal::shift_width(l.p(), params.alpha, params.beta_m);
        let mu = -theta_o + a;
        // Panels of width <= w/2 over mu +- 8 w, within the domain.
        let (lo, hi) = (
            (mu - 8.0 * w).max(-FRAC_PI_2),
            (mu + 8.0 * w).min(FRAC_PI_2),
        );
        if hi <= lo {
            continue;
        }
        let panels = (((hi - lo) / (0.5 * w)).ceil() as usize).clamp(4, 400);
        for (t, wt) in gl_nodes(lo, hi, panels) {
            let m = b.longitudinal(theta_o, t, 0.0).get(l);
            if m == 0.0 {
                continue;
            }
            let td = crate::model::geometry::theta_d(theta_o, t);
            let slice = b.model(0).azimuthal(td);
            for (h, wh) in h_nodes(params, td, 3, false) {
                let a = b.attenuation_rgb(td, &slice.geometry(h));
                for c in 0..3 {
                    out[c] += 0.5 * wh * wt * m * a[c].get(l);
                }
            }
        }
    }
    out
}

/// `E_s` per channel at `theta_o`: `1/2 ∫dh ∫∫ M_s N_s dtheta dphi` of the scattered lobes
/// as fitted (no scale).
fn scattered_albedo(b: &FiberBsdf, params: &FurParams, theta_o: f64) -> [f64; 3] {
    let ts = gl_nodes(-FRAC_PI_2, FRAC_PI_2, 8);
    let ps = gl_nodes(-PI, PI, 12);
    let mut out = [0.0; 3];
    for &(t, wt) in &ts {
        let td = crate::model::geometry::theta_d(theta_o, t);
        let hs = h_nodes(params, td, 3, true);
        for &(p, wp) in &ps {
            for &(h, wh) in &hs {
                let v = b.eval_near(theta_o, t, p, h);
                for c in 0..3 {
                    out[c] +=
                        0.5 * wh * wt * wp * (v[Lobe::TTs.index()][c] + v[Lobe::TRTs.index()][c]);
                }
            }
        }
    }
    out
}
