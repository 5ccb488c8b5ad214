//! Measurement effects of the virtual goniometer, each switchable and recorded in the
//! metadata. Applied in this order to the Monte Carlo profile ([`super::SimResult`]):
//!
//! 1. **Noise.** The Monte Carlo noise of finite paths is real noise already (its standard
//!    error is the `sigma` column). Optionally, on top:
//!    - *shot noise*: the sensor counts `P` photons at the profile's peak; a sample's count
//!      is Poisson with mean `P * value / peak`, the value becomes `count * peak / P`;
//!    - *multiplicative noise*: `value *= exp(s N(0,1) - s^2/2)` (log-normal, mean kept).
//!
//!    Both come from one seeded Xoshiro256++ stream walked in sample order, so they are
//!    deterministic for a seed. `sigma` grows by the added variance.
//! 2. **Detector floor.** Values below `floor * peak` (the peak of the noisy profile, over
//!    all incidence angles: one exposure for the whole session) are written as invalid
//!    (value 0, DATA.md).
//! 3. **Occluded wedge.** Samples whose view direction lies within `wedge` degrees of the
//!    light direction are invalid: there the camera would stand in the beam. The light
//!    direction is `(theta_r, phi) = (theta_i, 0)` (both angles point away from the fiber,
//!    MODEL.md), so the gap sits at `theta_r = +theta_i`, `phi = 0`; the specular cone
//!    `theta_r = -theta_i` is only occluded at `theta_i = 0`.
//! 4. **Dropped samples.** A random fraction `drop` of the samples is invalid (a missed
//!    frame, a saturated pixel).
//!
//! A sample with no detected energy at all (value exactly 0) is invalid as well.

use super::SimResult;
use rand::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;

/// The switches. Zero / `None` disables an effect.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct Effects {
    /// Relative detector floor (fraction of the peak); 0 = off.
    pub floor: f64,
    /// Half-angle (degrees) of the occluded cone around the light direction; 0 = off.
    pub wedge_deg: f64,
    /// Fraction of samples dropped at random; 0 = off.
    pub drop: f64,
    /// Photons counted at the peak (shot noise); None = off.
    pub shot_photons: Option<f64>,
    /// Log-normal multiplicative noise std; 0 = off.
    pub mult_noise: f64,
    /// Seed of the measurement-effects stream.
    pub seed: u64,
}

/// Why a sample is invalid.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Invalid {
    /// No energy reached the bin (value not finite or `<= 0`).
    NoSignal,
    /// Below the detector floor (`floor * peak`).
    Floor,
    /// In the occluded wedge around the light (within `wedge_deg` of it).
    Wedge,
    /// Dropped at random (a fraction `drop`).
    Dropped,
}

/// The measured profile: `value[b] > 0` and `sigma[b]` for valid samples, `value = 0` for
/// invalid ones with the reason.
#[derive(Clone, Debug)]
pub struct Measured {
    /// Measured value per bin, flattened as [`super::SimResult::value`]; 0 where invalid.
    pub value: Vec<f64>,
    /// Its standard error (Monte Carlo and measurement noise).
    pub sigma: Vec<f64>,
    /// Per bin: `None` if valid, else why not.
    pub invalid: Vec<Option<Invalid>>,
    /// Peak of the noisy profile, the floor's reference.
    pub peak: f64,
}

impl Measured {
    /// Number of samples with validity `why` (`None`: the valid ones).
    pub fn count(&self, why: Option<Invalid>) -> usize {
        self.invalid.iter().filter(|r| **r == why).count()
    }
}

fn gauss(rng: &mut Xoshiro256PlusPlus) -> f64 {
    let u1: f64 = 1.0 - rng.random::<f64>();
    let u2: f64 = rng.random::<f64>();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// Poisson variate: Knuth's product method for small means, a rounded normal above 50
/// (relative error of that approximation is far below the noise it models).
fn poisson(lambda: f64, rng: &mut Xoshiro256PlusPlus) -> f64 {
    if lambda <= 0.0 {
        return 0.0;
    }
    if lambda > 50.0 {
        return (lambda + lambda.sqrt() * gauss(rng)).round().max(0.0);
    }
    let l = (-lambda).exp();
    let mut k = 0.0;
    let mut p = 1.0;
    loop {
        p *= rng.random::<f64>();
        if p <= l {
            return k;
        }
        k += 1.0;
    }
}

/// Apply the effects to a simulated profile.
pub fn apply(sim: &SimResult, fx: &Effects) -> Measured {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(fx.seed ^ 0x5EED_0FEF_FEC7);
    let mut value = sim.value.clone();
    let mut sigma = sim.sigma.clone();
    let peak0 = value.iter().cloned().fold(0.0, f64::max);
    for (v, s) in value.iter_mut().zip(sigma.iter_mut()) {
        if let Some(p) = fx.shot_photons {
            if peak0 > 0.0 {
                let lam = p * *v / peak0;
                *s = (*s * *s + *v * peak0 / p).sqrt();
                *v = poisson(lam, &mut rng) * peak0 / p;
            }
        }
        if fx.mult_noise > 0.0 {
            let m = fx.mult_noise;
            *s = (*s * *s + (m * *v).powi(2)).sqrt();
            *v *= (m * gauss(&mut rng) - 0.5 * m * m).exp();
        }
    }
    let peak = value.iter().cloned().fold(0.0, f64::max);
    let mut invalid = vec![None; value.len()];
    let cos_wedge = fx.wedge_deg.to_radians().cos();
    for (i, ti) in sim.theta_i.iter().enumerate() {
        let ti = ti.to_radians();
        let light = [ti.cos(), 0.0, ti.sin()];
        for (j, tr) in sim.theta_r.iter().enumerate() {
            let tr = tr.to_radians();
            for (k, ph) in sim.phi.iter().enumerate() {
                let b = sim.index(i, j, k);
                let ph = ph.to_radians();
                let view = [tr.cos() * ph.cos(), tr.cos() * ph.sin(), tr.sin()];
                let cosang = light[0] * view[0] + light[1] * view[1] + light[2] * view[2];
                let dropped = fx.drop > 0.0 && rng.random::<f64>() < fx.drop;
                invalid[b] = if !value[b].is_finite() || value[b] <= 0.0 {
                    Some(Invalid::NoSignal)
                } else if fx.floor > 0.0 && value[b] < fx.floor * peak {
                    Some(Invalid::Floor)
                } else if fx.wedge_deg > 0.0 && cosang > cos_wedge {
                    Some(Invalid::Wedge)
                } else if dropped {
                    Some(Invalid::Dropped)
                } else {
                    None
                };
            }
        }
    }
    for (b, r) in invalid.iter().enumerate() {
        if r.is_some() {
            value[b] = 0.0;
        }
    }
    Measured {
        value,
        sigma,
        invalid,
        peak,
    }
}
