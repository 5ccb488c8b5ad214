//! Training of the Strand energy network ([`super::strand`]) from fresh Monte Carlo: the
//! physical directional albedo of a clear-cortex fiber by the virtual goniometer's tracer
//! ([`crate::simulate::trace::trace_path`]), then full-batch Adam (Kingma & Ba 2015,
//! Algorithm 1, default moments 0.9 / 0.999) on the squared error of the albedo. Everything
//! is seeded: the same seed gives the same file.
//!
//! The training fiber: the six network inputs, a clear cortex (`sigma_c_a = 0`), no
//! cuticle tilt (`alpha = 0`, so the albedo is even in `theta`), `l = 1` and 5 degree
//! micro-roughness (roughness moves a path's entry into the medulla only slightly). Its
//! albedo counts every path's exit weight and the weight of light guided along the fiber
//! ([`crate::simulate::trace::Outcome::Guided`]): in a furnace that light leaves elsewhere
//! along the (infinite, uniformly lit) fiber, which by translation returns the same amount
//! here.

use super::strand::{
    softplus, StrandMlp, DIMS, ETA, G_MAX, N_WEIGHTS, SIGMA_M_A_MAX, SIGMA_M_S_MAX,
};
use crate::params::FurParams;
use crate::simulate::trace::{trace_path, Fiber, Outcome};
use rand::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use rayon::prelude::*;

/// One Monte Carlo point: the network's raw inputs, its target and the target's standard
/// error.
#[derive(Clone, Copy, Debug)]
pub struct Sample {
    /// `eta, kappa, sigma_m_s, sigma_m_a, g, theta` (radians).
    pub raw: [f64; 6],
    /// The Monte Carlo's physical albedo `E_phys` at these inputs.
    pub albedo: f64,
    /// Standard error of `albedo`.
    pub se: f64,
}

/// Physical directional albedo of the training fiber (module doc) by `paths` traced
/// photons: mean and standard error.
pub fn mc_albedo(raw: [f64; 6], paths: usize, seed: u64) -> crate::Result<(f64, f64)> {
    let [eta, kappa, sms, sma, g, theta] = raw;
    let p = FurParams::from_file_units([eta, kappa, 0.0, 5.0, 5.0, 0.0, sms, sma, g, 1.0])?;
    let fiber = Fiber::new(&p, None, None, false);
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    let (mut s, mut s2) = (0.0, 0.0);
    for _ in 0..paths {
        let w = match trace_path(&fiber, theta, &mut rng) {
            Outcome::Exit(e) => e.weight,
            Outcome::Guided(w) => w,
            Outcome::Absorbed => 0.0,
        };
        s += w;
        s2 += w * w;
    }
    let n = paths.max(1) as f64;
    let m = s / n;
    Ok((m, ((s2 / n - m * m).max(0.0) / n).sqrt()))
}

/// Random raw inputs over the training domain: `eta`, `kappa`, `g`, `theta` uniform (theta
/// in [0, 89] degrees; the albedo is even in it), `sigma_m_s` and `sigma_m_a` uniform in
/// `ln(1 + sigma)` (as the network reads them).
pub fn draw(rng: &mut Xoshiro256PlusPlus) -> [f64; 6] {
    let mut u = || rng.random::<f64>();
    let lg = |u: f64, max: f64| (u * f64::ln_1p(max)).exp_m1();
    [
        ETA.0 + (ETA.1 - ETA.0) * u(),
        0.05 + 0.94 * u(),
        lg(u(), SIGMA_M_S_MAX),
        lg(u(), SIGMA_M_A_MAX).max(1e-3),
        G_MAX * (2.0 * u() - 1.0),
        89f64.to_radians() * u(),
    ]
}

/// `n` Monte Carlo points with `paths` photons each (point `k` seeded from `(seed, k)`).
pub fn dataset(n: usize, paths: usize, seed: u64) -> crate::Result<Vec<Sample>> {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    let raws: Vec<[f64; 6]> = (0..n).map(|_| draw(&mut rng)).collect();
    raws.par_iter()
        .enumerate()
        .map(|(k, &raw)| {
            let s = crate::simulate::chunk_seed(seed, 1, k as u64);
            let (albedo, se) = mc_albedo(raw, paths, s)?;
            Ok(Sample { raw, albedo, se })
        })
        .collect()
}

/// The network's albedo at a sample.
pub fn predict(m: &StrandMlp, s: &Sample) -> f64 {
    let [eta, kappa, sms, sma, g, theta] = s.raw;
    m.albedo(eta, kappa, sms, sma, g, theta)
}

/// Gradient of the mean squared albedo error over `data` (and the loss), over fixed
/// chunks in parallel, summed in chunk order (deterministic for any thread count).
fn gradient(m: &StrandMlp, data: &[Sample]) -> (Vec<f64>, f64) {
    let parts: Vec<(Vec<f64>, f64)> = data.par_chunks(256).map(|c| gradient_sum(m, c)).collect();
    let mut grad = vec![0.0; N_WEIGHTS];
    let mut loss = 0.0;
    for (g, l) in parts {
        grad.iter_mut().zip(&g).for_each(|(a, b)| *a += b);
        loss += l;
    }
    let k = 1.0 / data.len().max(1) as f64;
    grad.iter_mut().for_each(|g| *g *= k);
    (grad, loss * k)
}

/// Summed (not averaged) gradient and loss of one chunk.
fn gradient_sum(m: &StrandMlp, data: &[Sample]) -> (Vec<f64>, f64) {
    let [n0, n1, n2, _] = DIMS;
    let (o_b1, o_w2) = (n1 * n0, n1 * n0 + n1);
    let o_b2 = o_w2 + n2 * n1;
    let o_w3 = o_b2 + n2;
    let o_b3 = o_w3 + n2;
    let w = &m.w;
    let mut grad = vec![0.0; N_WEIGHTS];
    let mut loss = 0.0;
    for s in data {
        let [eta, kappa, sms, sma, g, theta] = s.raw;
        let x = StrandMlp::inputs(eta, kappa, sms, sma, g, theta);
        let mut a1 = [0.0; 16];
        for i in 0..n1 {
            let z: f64 = (0..n0).map(|j| w[i * n0 + j] * x[j]).sum::<f64>() + w[o_b1 + i];
            a1[i] = z.tanh();
        }
        let mut a2 = [0.0; 16];
        let mut z = w[o_b3];
        for i in 0..n2 {
            let t: f64 = (0..n1).map(|j| w[o_w2 + i * n1 + j] * a1[j]).sum::<f64>() + w[o_b2 + i];
            a2[i] = t.tanh();
            z += w[o_w3 + i] * a2[i];
        }
        let e = (-sma * softplus(z)).exp();
        let r = e - s.albedo;
        loss += r * r;
        // d(r^2)/dz = 2 r dE/dz, dE/dz = -sma sigmoid(z) E.
        let dz = 2.0 * r * (-sma * e / (1.0 + (-z).exp()));
        grad[o_b3] += dz;
        let mut d1 = [0.0; 16];
        for i in 0..n2 {
            grad[o_w3 + i] += dz * a2[i];
            let d2 = dz * w[o_w3 + i] * (1.0 - a2[i] * a2[i]);
            grad[o_b2 + i] += d2;
            for j in 0..n1 {
                grad[o_w2 + i * n1 + j] += d2 * a1[j];
                d1[j] += d2 * w[o_w2 + i * n1 + j];
            }
        }
        for i in 0..n1 {
            let d = d1[i] * (1.0 - a1[i] * a1[i]);
            grad[o_b1 + i] += d;
            for j in 0..n0 {
                grad[i * n0 + j] += d * x[j];
            }
        }
    }
    (grad, loss)
}

/// Train from `data` with `epochs` full-batch Adam steps (learning rate 1e-2 decaying
/// geometrically to 1e-4), weights initialised Xavier-uniform from `seed`.
pub fn train(data: &[Sample], epochs: usize, seed: u64) -> StrandMlp {
    let [n0, n1, n2, _] = DIMS;
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed ^ 0x5EED_57AA_D000_0001);
    let mut w = Vec::with_capacity(N_WEIGHTS);
    for (fan_in, fan_out, count) in [
        (n0, n1, n1 * n0),
        (0, 0, n1),
        (n1, n2, n2 * n1),
        (0, 0, n2),
        (n2, 1, n2),
        (0, 0, 1),
    ] {
        for _ in 0..count {
            let a = if fan_in == 0 {
                0.0
            } else {
                (6.0 / (fan_in + fan_out) as f64).sqrt()
            };
            w.push(a * (2.0 * rng.random::<f64>() - 1.0));
        }
    }
    let mut m = StrandMlp { w };
    let (b1, b2, eps) = (0.9, 0.999, 1e-8);
    let mut mom = vec![0.0; N_WEIGHTS];
    let mut vel = vec![0.0; N_WEIGHTS];
    for t in 1..=epochs {
        let lr = 1e-2 * (1e-2f64).powf(t as f64 / epochs.max(1) as f64);
        let (g, _) = gradient(&m, data);
        for k in 0..N_WEIGHTS {
            mom[k] = b1 * mom[k] + (1.0 - b1) * g[k];
            vel[k] = b2 * vel[k] + (1.0 - b2) * g[k] * g[k];
            let mh = mom[k] / (1.0 - b1.powi(t as i32));
            let vh = vel[k] / (1.0 - b2.powi(t as i32));
            m.w[k] -= lr * mh / (vh.sqrt() + eps);
        }
    }
    m
}

/// `(max, median)` absolute albedo error of `m` over `data`.
pub fn errors(m: &StrandMlp, data: &[Sample]) -> (f64, f64) {
    let mut e: Vec<f64> = data
        .iter()
        .map(|s| (predict(m, s) - s.albedo).abs())
        .collect();
    e.sort_by(f64::total_cmp);
    let med = if e.is_empty() {
        f64::NAN
    } else {
        e[e.len() / 2]
    };
    (e.last().copied().unwrap_or(f64::NAN), med)
}
