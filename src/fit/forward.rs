//! The forward model the fitter evaluates: the far-field value `sum_p M_p N_p` (MODEL.md
//! "What a goniometer sample predicts", before the exposure `k`) at a list of goniometer
//! points.
//!
//! All model evaluations of the fitter go through [`predict_points`]; it is the single
//! place that calls into the model, so the fitter never re-implements any physics.

use crate::model::{FurModel, LobeSet};
use crate::params::FurParams;

/// Far-field segment counts: `h_i = sqrt(i/n)` segments for the unscattered lobes and for
/// the scattered lobes (seed Sec. 5.1 "Validation" uses 8 and 5, the default here).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Segments {
    pub unscattered: usize,
    pub scattered: usize,
}

impl Default for Segments {
    fn default() -> Self {
        Segments {
            unscattered: 8,
            scattered: 5,
        }
    }
}

impl Segments {
    /// Parse `N,M` (unscattered, scattered) or a single `N` for both.
    pub fn parse(s: &str) -> crate::Result<Segments> {
        let parts: Vec<&str> = s.split(',').map(str::trim).collect();
        let num = |t: &str| -> crate::Result<usize> {
            match t.parse::<usize>() {
                Ok(n) if (1..=4096).contains(&n) => Ok(n),
                _ => Err(crate::Error::Invalid(format!(
                    "--segments: '{t}' is not a segment count in 1..=4096"
                ))),
            }
        };
        match parts.as_slice() {
            [a] => {
                let n = num(a)?;
                Ok(Segments {
                    unscattered: n,
                    scattered: n,
                })
            }
            [a, b] => Ok(Segments {
                unscattered: num(a)?,
                scattered: num(b)?,
            }),
            _ => Err(crate::Error::Invalid(format!(
                "--segments: expected N or N,M, found '{s}'"
            ))),
        }
    }
}

/// Goniometer points in radians, structure of arrays.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Points {
    pub theta_i: Vec<f64>,
    pub theta_r: Vec<f64>,
    pub phi: Vec<f64>,
}

impl Points {
    pub fn len(&self) -> usize {
        self.phi.len()
    }

    pub fn is_empty(&self) -> bool {
        self.phi.is_empty()
    }

    pub fn push(&mut self, theta_i: f64, theta_r: f64, phi: f64) {
        self.theta_i.push(theta_i);
        self.theta_r.push(theta_r);
        self.phi.push(phi);
    }

    /// Consecutive pieces of at most `size` points (for parallel evaluation).
    pub fn chunks(&self, size: usize) -> Vec<Points> {
        let size = size.max(1);
        (0..self.len())
            .step_by(size)
            .map(|lo| {
                let hi = (lo + size).min(self.len());
                Points {
                    theta_i: self.theta_i[lo..hi].to_vec(),
                    theta_r: self.theta_r[lo..hi].to_vec(),
                    phi: self.phi[lo..hi].to_vec(),
                }
            })
            .collect()
    }

    /// The points at the given indices.
    pub fn subset(&self, idx: &[usize]) -> Points {
        Points {
            theta_i: idx.iter().map(|&i| self.theta_i[i]).collect(),
            theta_r: idx.iter().map(|&i| self.theta_r[i]).collect(),
            phi: idx.iter().map(|&i| self.phi[i]).collect(),
        }
    }
}

/// Model value (no exposure) of the lobes in `lobes` at every point, written into `out`
/// (`out.len() == points.len()`). `params` must be within the hard bounds.
pub fn predict_points(
    params: &FurParams,
    points: &Points,
    segments: Segments,
    lobes: LobeSet,
    out: &mut [f64],
) {
    debug_assert_eq!(out.len(), points.len());
    let model = FurModel::new(params);
    // Temporary far field until the `far` branch lands: Gauss-Legendre over h of the
    // near field, N_p = 1/2 int A_p D_p dh (seed Eq. 22).
    let (nodes, weights) = gauss_legendre(4 * segments.unscattered.max(segments.scattered));
    for (k, o) in out.iter_mut().enumerate() {
        let (ti, tr, ph) = (points.theta_i[k], points.theta_r[k], points.phi[k]);
        let lob = lobes.intersect(model.active_lobes());
        let m = model.longitudinal(ti, tr, ph, lob);
        let az = model.azimuthal(crate::model::geometry::theta_d(ti, tr));
        let mut n = [0.0; 5];
        for (h, w) in nodes.iter().zip(&weights) {
            let v = az.near(*h, ph, lob);
            for (a, b) in n.iter_mut().zip(v.0) {
                *a += 0.5 * w * b;
            }
        }
        *o = (0..5).map(|i| m.0[i] * n[i]).sum();
    }
}

/// Gauss-Legendre nodes and weights on [-1, 1] (Newton on the Legendre recurrence).
fn gauss_legendre(n: usize) -> (Vec<f64>, Vec<f64>) {
    let mut x = vec![0.0; n];
    let mut w = vec![0.0; n];
    for i in 0..n {
        let mut z = (std::f64::consts::PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
        let mut dp = 1.0;
        for _ in 0..100 {
            let (mut p0, mut p1) = (1.0, z);
            for k in 2..=n {
                let p2 = ((2 * k - 1) as f64 * z * p1 - (k - 1) as f64 * p0) / k as f64;
                p0 = p1;
                p1 = p2;
            }
            dp = n as f64 * (z * p1 - p0) / (z * z - 1.0);
            let dz = p1 / dp;
            z -= dz;
            if dz.abs() < 1e-15 {
                break;
            }
        }
        x[i] = z;
        w[i] = 2.0 / ((1.0 - z * z) * dp * dp);
    }
    (x, w)
}
