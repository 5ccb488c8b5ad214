//! `--medulla-energy strand`: energy compensation of the scattered lobes in the style of the
//! Strand model (Hostettler 2025, seed `004_99cbcc14715af6b4.txt`: the medulla's
//! single-scattering lobes are scaled by an energy ratio that a tiny perceptron learns from
//! a precomputation, so parameters change with no new precomputation).
//!
//! # What is scaled, and to what
//! The fitted lobe shapes stay. At camera side `theta_o` the renderer's BCSDF returns the
//! directional albedo `E_u(theta_o) + E_s(theta_o)` (unscattered R, TT, TRT plus scattered
//! TTs, TRTs; [`super::furnace`] measures it). The scattered lobes are multiplied by
//!
//! `s(theta_o) = max(E_phys(theta_o) - E_u^clear(theta_o), 0) / E_s^clear(theta_o)`
//!
//! per colour channel, where `E_phys` is the physical albedo of the fiber (exitant over
//! intercepted power) of the project's own Monte Carlo, the virtual goniometer's double
//! cylinder ([`crate::simulate::trace::trace_path`]), and `^clear` means the same fiber with
//! a clear cortex (`sigma_c_a = 0`). Why the clear cortex: `E_phys` is learnt over the six
//! inputs the Strand ratio takes, `(eta, kappa, sigma_m_s, sigma_m_a, g, theta)`, which
//! leave out the cortex. With a clear cortex the compensated albedo equals `E_phys`
//! exactly; with cortex absorption every lobe carries its own `T_c < 1`, so the albedo is
//! `E_u + s E_s <= E_u^clear + s E_s^clear = E_phys <= 1`. A lossless fiber has `E_phys = 1`
//! by energy conservation, which the network's output form keeps exactly
//! ([`StrandMlp::albedo`]), so it renders at 1 in a white furnace: the light the fitted
//! lobes lose (TRRT+ is not a lobe; `M_p` mass beyond the poles; the non-reciprocal `C^M`
//! columns) or gain is given back to, or taken from, the scattered lobes.
//!
//! `E_u^clear`, `E_s^clear` depend on the fitted `alpha`, `beta_m`, `beta_n`, `l` as well
//! (not network inputs): they are integrals of the BCSDF itself, computed by deterministic
//! quadrature once per render on [`N_NODES`] nodes of `theta_o` ([`EnergyScale::build`],
//! in [`super::strand_albedo`]).
//! Only the Monte Carlo, which costs minutes, is replaced by the network.
//!
//! # The network
//! A 6-16-16-1 perceptron (tanh hidden units, 401 weights, 1.6 KB as f32). Its forward
//! pass is written out here ([`StrandMlp::forward`]): two small matrix-vector products and
//! a tanh do not justify a crate (the maintained ones, e.g. `candle`, `burn`, `tract`, pull
//! in tensor runtimes of megabytes for a 401-weight function evaluated 37 times a render).
//! Weights: `assets/strand_mlp.bin`, built into the binary, rebuilt by
//! `furfit tables strand` ([`super::strand_train`]); `--energy-weights FILE` reads another.

use crate::error::{Error, Result};
use std::f64::consts::FRAC_PI_2;
use std::path::Path;

/// Magic of a weights file (8 bytes).
pub const MAGIC: &[u8; 8] = b"FFMLP01\n";
/// Layer widths: inputs, hidden, hidden, output.
pub const DIMS: [usize; 4] = [6, 16, 16, 1];
/// Number of weights and biases.
pub const N_WEIGHTS: usize = DIMS[1] * (DIMS[0] + 1) + DIMS[2] * (DIMS[1] + 1) + DIMS[2] + 1;
/// Where the shipped weights live in the source tree.
pub const BUILTIN_PATH: &str = "assets/strand_mlp.bin";
/// How to rebuild them (for error messages).
pub const REBUILD: &str = "rebuild them with `furfit tables strand --out assets/strand_mlp.bin` \
(fresh Monte Carlo, a few minutes)";

/// The training domain of the network's inputs; inputs outside are clamped to it
/// ([`StrandMlp::inputs`]).
pub const ETA: (f64, f64) = (1.1, 2.0);
/// Upper end of the training domain of `sigma_m_s` (per unit radius; the lower is 0).
pub const SIGMA_M_S_MAX: f64 = 10.0;
/// Upper end of the training domain of `sigma_m_a` (per unit radius; the lower is 0).
pub const SIGMA_M_A_MAX: f64 = 5.0;
/// Bound of the training domain of `|g|`.
pub const G_MAX: f64 = 0.9;

/// The weights of the 6-16-16-1 perceptron (module doc).
#[derive(Clone, Debug, PartialEq)]
pub struct StrandMlp {
    /// Flat, in the order W1 (16x6, row-major), b1, W2 (16x16), b2, W3 (1x16), b3.
    pub w: Vec<f64>,
}

/// FNV-1a over bytes (the file's checksum: detects truncation and corruption).
fn fnv1a(b: &[u8]) -> u64 {
    b.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &x| {
        (h ^ x as u64).wrapping_mul(0x0100_0000_01b3)
    })
}

impl StrandMlp {
    /// The weights built into the binary (`assets/strand_mlp.bin`).
    pub fn builtin() -> Result<StrandMlp> {
        Self::from_bytes(
            include_bytes!("../../assets/strand_mlp.bin"),
            Path::new(BUILTIN_PATH),
        )
        .map_err(|e| Error::Invalid(format!("{e} (the weights built into this binary)")))
    }

    /// Read a weights file; a missing or corrupt file is an error naming it and how to
    /// rebuild it (never a silent fallback).
    pub fn load(path: &Path) -> Result<StrandMlp> {
        let bytes = std::fs::read(path).map_err(|e| {
            Error::file(
                path,
                format!("cannot read the Strand energy weights ({e}); {REBUILD}"),
            )
        })?;
        Self::from_bytes(&bytes, path)
    }

    /// `path` names the source in errors.
    pub fn from_bytes(b: &[u8], path: &Path) -> Result<StrandMlp> {
        let bad = |m: String| Err(Error::file(path, format!("{m}; {REBUILD}")));
        let want = 8 + 12 + 4 * N_WEIGHTS + 8;
        if b.len() != want {
            return bad(format!(
                "not a Strand energy weights file ({} bytes, expected {want})",
                b.len()
            ));
        }
        if &b[..8] != MAGIC {
            return bad("not a Strand energy weights file (bad magic)".into());
        }
        let u32_at = |i: usize| u32::from_le_bytes(b[i..i + 4].try_into().unwrap()) as usize;
        let dims = [u32_at(8), u32_at(12), u32_at(16)];
        if dims != [DIMS[0], DIMS[1], DIMS[2]] {
            return bad(format!("layer widths {dims:?}, expected {:?}", &DIMS[..3]));
        }
        let body = want - 8;
        let sum = u64::from_le_bytes(b[body..].try_into().unwrap());
        if sum != fnv1a(&b[..body]) {
            return bad("checksum mismatch (corrupt or truncated)".into());
        }
        let w: Vec<f64> = (0..N_WEIGHTS)
            .map(|k| f32::from_le_bytes(b[20 + 4 * k..24 + 4 * k].try_into().unwrap()) as f64)
            .collect();
        if w.iter().any(|v| !v.is_finite()) {
            return bad("non-finite weight".into());
        }
        Ok(StrandMlp { w })
    }

    /// The file's bytes (weights rounded to f32).
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut b = MAGIC.to_vec();
        for d in &DIMS[..3] {
            b.extend((*d as u32).to_le_bytes());
        }
        for v in &self.w {
            b.extend((*v as f32).to_le_bytes());
        }
        let sum = fnv1a(&b);
        b.extend(sum.to_le_bytes());
        b
    }

    /// The weights as the file stores them (f32), so training reports the error of what
    /// ships.
    pub fn rounded(&self) -> StrandMlp {
        StrandMlp {
            w: self.w.iter().map(|v| *v as f32 as f64).collect(),
        }
    }

    /// Normalised network inputs, each about [-1, 1] over the training domain (clamped to
    /// it): `eta`, `kappa`, `ln(1 + sigma_m_s)`, `ln(1 + sigma_m_a)`, `g`, `cos theta`. The
    /// training fiber has no cuticle tilt, so its albedo is even in `theta`.
    pub fn inputs(eta: f64, kappa: f64, sms: f64, sma: f64, g: f64, theta: f64) -> [f64; 6] {
        let lg = |x: f64, max: f64| 2.0 * (x.clamp(0.0, max).ln_1p() / max.ln_1p()) - 1.0;
        [
            2.0 * (eta.clamp(ETA.0, ETA.1) - ETA.0) / (ETA.1 - ETA.0) - 1.0,
            2.0 * kappa.clamp(0.0, 1.0) - 1.0,
            lg(sms, SIGMA_M_S_MAX),
            lg(sma, SIGMA_M_A_MAX),
            g.clamp(-G_MAX, G_MAX) / G_MAX,
            2.0 * theta.clamp(-FRAC_PI_2, FRAC_PI_2).cos() - 1.0,
        ]
    }

    /// The raw network output `z` for normalised inputs `x`.
    pub fn forward(&self, x: &[f64; 6]) -> f64 {
        let [n0, n1, n2, _] = DIMS;
        let w = &self.w;
        let (w1, rest) = w.split_at(n1 * n0);
        let (b1, rest) = rest.split_at(n1);
        let (w2, rest) = rest.split_at(n2 * n1);
        let (b2, rest) = rest.split_at(n2);
        let (w3, b3) = rest.split_at(n2);
        let mut a1 = [0.0; 16];
        for i in 0..n1 {
            let s: f64 = (0..n0).map(|j| w1[i * n0 + j] * x[j]).sum();
            a1[i] = (s + b1[i]).tanh();
        }
        let mut z = b3[0];
        for i in 0..n2 {
            let s: f64 = (0..n1).map(|j| w2[i * n1 + j] * a1[j]).sum();
            z += w3[i] * (s + b2[i]).tanh();
        }
        z
    }

    /// The physical directional albedo of a clear-cortex fiber, `exp(-sigma_m_a *
    /// softplus(z))`: exactly 1 without medulla absorption (energy conservation, not
    /// learnt), in (0, 1] always; `softplus(z)` is the albedo's log-derivative in
    /// `sigma_m_a`, of the order of the mean path length in the medulla.
    pub fn albedo(&self, eta: f64, kappa: f64, sms: f64, sma: f64, g: f64, theta: f64) -> f64 {
        if sma <= 0.0 {
            return 1.0;
        }
        let z = self.forward(&Self::inputs(eta, kappa, sms, sma, g, theta));
        (-sma * softplus(z)).exp()
    }
}

/// `ln(1 + e^z)`, without overflow.
pub fn softplus(z: f64) -> f64 {
    if z > 30.0 {
        z
    } else {
        z.exp().ln_1p()
    }
}

/// Nodes of `theta_o` of the scale table, over [-90, 90] degrees, uniform in `u` with
/// `theta = 90 deg sign(u) (1 - (1 - |u|)^2)`: 7.5 degrees apart at the equator, 0.16 at the
/// poles. The fitted scattered lobes fade toward the poles (bobcat: `E_s` 0.019 at 85
/// degrees, 0.003 at 89.94), so the scale grows ~10x in the last 5 degrees, and a uniform 5
/// degree grid interpolated it 2 % low at 89.9 degrees (shipped fits, lossless: 0.978).
pub const N_NODES: usize = 49;
/// The end nodes sit this far inside the poles (the path geometry degenerates at them).
const POLE_INSET: f64 = 1e-3;

/// Per-channel scale of the scattered lobes on the `theta_o` nodes (module doc),
/// interpolated linearly.
#[derive(Clone, Debug, PartialEq)]
pub struct EnergyScale {
    /// `[node][channel]`.
    pub scale: Vec<[f64; 3]>,
    /// Per node and channel: `E_phys`, `E_u^clear`, `E_s^clear` (for reports and tests).
    pub parts: Vec<[[f64; 3]; 3]>,
}

/// `theta_o` of node `i` ([`N_NODES`]).
pub fn node_theta(i: usize) -> f64 {
    let u = -1.0 + 2.0 * i as f64 / (N_NODES - 1) as f64;
    let t = FRAC_PI_2 * u.signum() * (1.0 - (1.0 - u.abs()).powi(2));
    t.clamp(-FRAC_PI_2 + POLE_INSET, FRAC_PI_2 - POLE_INSET)
}

/// The grid coordinate of `theta_o` (inverse of [`node_theta`] without the inset), in
/// `[0, N_NODES - 1]`.
fn node_coord(theta_o: f64) -> f64 {
    let a = (theta_o.abs() / FRAC_PI_2).min(1.0);
    let u = theta_o.signum() * (1.0 - (1.0 - a).sqrt());
    ((u + 1.0) * 0.5 * (N_NODES - 1) as f64).clamp(0.0, (N_NODES - 1) as f64)
}

impl EnergyScale {
    /// The scale of channel `c` at `theta_o` (linear between nodes).
    #[inline]
    pub fn at(&self, theta_o: f64, c: usize) -> f64 {
        let x = node_coord(theta_o);
        let i = (x as usize).min(N_NODES - 2);
        let f = x - i as f64;
        self.scale[i][c] * (1.0 - f) + self.scale[i + 1][c] * f
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{Lobe, LobeSet};
    use crate::params::FurParams;
    use crate::render::bsdf::{FiberBsdf, MedullaEnergy, Tint};
    use crate::render::furnace::{default_thetas_deg, furnace, furnace_bsdf, lossless};

    fn params(v: [f64; 10]) -> FurParams {
        FurParams::from_file_units(v).unwrap()
    }

    /// The goal, as a test: a lossless fiber with a medulla renders at 1.00 +-
    /// 0.02 in a white furnace at every inclination under `strand` (eta, kappa, g, roughness
    /// and scattering spread over their ranges; the red fox fit's shapes among them), and
    /// at most 1 with absorption. 40 000 samples give standard errors of 0.001-0.004
    /// (largest at the poles), so a true 1.00 passes with >= 5 sigma to spare and a miss of
    /// 0.03 fails. The `fit` reading of the first fiber gains light (1.69 measured at 0 deg),
    /// which shows the check can fail.
    #[test]
    fn white_furnace_strand_is_one_when_lossless_and_at_most_one_with_absorption() {
        let thetas = default_thetas_deg();
        let n = 40_000;
        let fibers = [
            // red fox fit (l < 1, beta_n at its bound)
            [
                1.70, 0.857, 1.92, 7.07, 1e-4, 3.46, 1.77, 0.004, 0.605, 0.194,
            ],
            // bobcat fit (the shipped fit whose poles were furthest off before)
            [
                1.458, 0.827, 4.85, 11.23, 10.19, 0.578, 1.011, 1.189, 0.224, 0.423,
            ],
            [1.3, 0.3, 3.0, 12.0, 20.0, 0.5, 5.0, 0.3, -0.5, 1.5],
            [1.9, 0.95, 0.5, 3.0, 8.0, 0.2, 0.5, 1.0, 0.1, 3.0],
            [1.55, 0.6, -4.0, 20.0, 40.0, 1.0, 9.0, 0.05, 0.85, 1.0],
        ];
        for (k, v) in fibers.iter().enumerate() {
            let p = params(*v);
            let b = furnace_bsdf(&lossless(&p), MedullaEnergy::Strand, None).unwrap();
            for r in furnace(&b, &thetas, n, 10 + k as u64).unwrap() {
                assert!(
                    (r.albedo - 1.0).abs() <= 0.02,
                    "fiber {k} lossless theta {}: albedo {} (se {})",
                    r.theta_deg,
                    r.albedo,
                    r.se
                );
            }
            let b = furnace_bsdf(&p, MedullaEnergy::Strand, None).unwrap();
            for r in furnace(&b, &thetas, n / 4, 20 + k as u64).unwrap() {
                // <= 1 up to 4 standard errors of the estimate.
                assert!(
                    r.albedo <= 1.0 + 4.0 * r.se,
                    "fiber {k} theta {}: albedo {} (se {})",
                    r.theta_deg,
                    r.albedo,
                    r.se
                );
            }
            if k == 0 {
                let b = furnace_bsdf(&lossless(&p), MedullaEnergy::Fit, None).unwrap();
                let r = furnace(&b, &[0.0], n, 3).unwrap();
                assert!(r[0].albedo > 1.3, "fit reading: {}", r[0].albedo);
            }
        }
    }

    /// The scale table's quadrature of the fitted lobes agrees with the furnace's Monte
    /// Carlo of the same BCSDF (`fit`, no scale): E_u + E_s against E within 4 standard
    /// errors plus 1 % (quadrature).
    #[test]
    fn scale_quadrature_matches_the_monte_carlo_albedo() {
        let p = params([1.5, 0.7, 2.0, 9.0, 15.0, 0.0, 2.0, 0.2, 0.4, 1.0]);
        let mlp = StrandMlp::builtin().unwrap();
        let e = EnergyScale::build(&p, Tint::GREY, &mlp);
        let b = furnace_bsdf(&p, MedullaEnergy::Fit, None).unwrap();
        for i in [2, 12, 18, 27, 34, 46] {
            let to = node_theta(i);
            let (mc, se) = crate::render::furnace::directional_albedo(&b, to, 40_000, 5);
            let q = e.parts[i][1][0] + e.parts[i][2][0];
            assert!(
                (q - mc).abs() < 4.0 * se + 0.01 * mc,
                "node {i}: quadrature {q} vs MC {mc} +- {se}"
            );
        }
    }

    /// Diagnostic (not a check): quadrature parts against Monte Carlo near the poles.
    #[test]
    #[ignore]
    fn pole_diagnostic() {
        let p = params([
            1.458, 0.827, 4.85, 11.23, 10.19, 0.0, 1.011, 0.0, 0.224, 0.423,
        ]);
        let mlp = StrandMlp::builtin().unwrap();
        let e = EnergyScale::build(&p, Tint::GREY, &mlp);
        for set in [
            LobeSet::UNSCATTERED,
            LobeSet::only(Lobe::TTs).with(Lobe::TRTs),
        ] {
            let mut b = FiberBsdf::new(&p, Tint::GREY, set);
            b.build_select_table();
            for i in [0, 1, 2, 46, 47, 48] {
                let to = node_theta(i);
                let (mc, se) = crate::render::furnace::directional_albedo(&b, to, 200_000, 5);
                eprintln!(
                    "{set:?} node {i} theta {:.3}: quad u {:.4} s {:.4} scale {:.4} | MC {mc:.4} +- {se:.4}",
                    to.to_degrees(),
                    e.parts[i][1][0],
                    e.parts[i][2][0],
                    e.scale[i][0]
                );
            }
        }
    }

    /// A missing or corrupt weights file is an error naming the file and the command that
    /// rebuilds it; the shipped bytes round-trip.
    #[test]
    fn weights_files_fail_loudly() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("none.bin");
        let e = StrandMlp::load(&missing).unwrap_err().to_string();
        assert!(
            e.contains("none.bin") && e.contains("furfit tables strand"),
            "{e}"
        );
        let mlp = StrandMlp::builtin().unwrap();
        let mut b = mlp.to_bytes();
        assert_eq!(StrandMlp::from_bytes(&b, Path::new("x.bin")).unwrap(), mlp);
        b[100] ^= 0x40;
        let bad = dir.path().join("bad.bin");
        std::fs::write(&bad, &b).unwrap();
        let e = StrandMlp::load(&bad).unwrap_err().to_string();
        assert!(e.contains("bad.bin") && e.contains("checksum"), "{e}");
        assert!(e.contains("furfit tables strand"), "{e}");
        std::fs::write(&bad, &b[..50]).unwrap();
        let e = StrandMlp::load(&bad).unwrap_err().to_string();
        assert!(e.contains("bad.bin") && e.contains("50 bytes"), "{e}");
        let e = MedullaEnergy::parse("magic").unwrap_err().to_string();
        assert!(e.contains("magic") && e.contains("strand"), "{e}");
    }

    /// The shipped network reproduces fresh Monte Carlo of the training fiber (a few
    /// points inside the domain, 40 000 paths each, a seed the training never used):
    /// within 0.03 + 4 standard errors (reports/energy.md: median held-out error ~0.01).
    #[test]
    fn shipped_network_matches_fresh_monte_carlo() {
        let mlp = StrandMlp::builtin().unwrap();
        for (k, raw) in [
            [1.55, 0.8, 1.8, 0.5, 0.6, 0.3],
            [1.3, 0.5, 5.0, 2.0, 0.0, 1.0],
            [1.8, 0.9, 0.5, 0.1, -0.4, 0.0],
        ]
        .into_iter()
        .enumerate()
        {
            let (mc, se) =
                crate::render::strand_train::mc_albedo(raw, 40_000, 99 + k as u64).unwrap();
            let [eta, kappa, sms, sma, g, th] = raw;
            let nn = mlp.albedo(eta, kappa, sms, sma, g, th);
            assert!(
                (nn - mc).abs() < 0.03 + 4.0 * se,
                "{raw:?}: network {nn} MC {mc} +- {se}"
            );
        }
    }
}
