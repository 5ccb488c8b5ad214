//! `chiang2016`'s near field as the renderer's BCSDF ([`NearBsdf`]), evaluated and
//! sampled as pbrt-v4's `HairBxDF::f` / `Sample_f` / `PDF` do (`src/pbrt/bxdfs.cpp`):
//!
//! - value: `cos(theta) sum_p M_p(theta, theta_o') A_p(theta_o, h) N_p(phi; h)` per
//!   channel ([`lobes`]; pbrt's `f |cos theta_i|` in the `(theta, phi)` measure, the
//!   goniometer value of [`super`]);
//! - sampling: the lobe `p` with probability `A_p / sum A` (A averaged over r, g, b, as
//!   pbrt's `ApPDF` averages its spectrum), `theta` from `M_p` by d'Eon et al. 2011's
//!   sampling of the von Mises-Fisher lobe about the mirrored tilted camera direction
//!   (whose marginal over its own azimuth is `M_p cos(theta)`, exactly), `phi` from the
//!   trimmed logistic about `Phi(p, h)` (uniform for the residual);
//! - pdf: `cos(theta) sum_p P_p M_p N_p` with the same terms, exact for those draws.
//!
//! pbrt floors the `M_p` uniform at 1e-5 against `ln(0)`; here the argument of the
//! logarithm is floored at the smallest positive double instead, which changes no draw.
//! Sampling reads the green channel's shape (`eta`, `beta_m`, `beta_n`, `alpha`): for a
//! fit whose channels differ in more than `sigma_a` that only costs efficiency, the pdf
//! being that of what is drawn.

use super::lobes::{self, Slice, P_MAX};
use super::specs::{ALPHA, BETA_M, BETA_N, ETA, SIGMA_A};
use crate::models::bsdf::{LobeRgb, NearBsdf};
use std::f64::consts::PI;

/// One channel's parameters and what they fix: the variances `v_p`, the logistic scale.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Channel {
    eta: f64,
    alpha: f64,
    sigma_a: f64,
    v: [f64; P_MAX + 1],
    s: f64,
    norm: f64,
}

impl Channel {
    fn new(p: &[f64]) -> Channel {
        let s = lobes::logistic_scale(p[BETA_N]);
        Channel {
            eta: p[ETA],
            alpha: p[ALPHA],
            sigma_a: p[SIGMA_A],
            v: lobes::variances(p[BETA_M]),
            s,
            norm: lobes::trimmed_norm(s),
        }
    }

    /// `N_p(phi; h)` of every lobe on this channel's slice at `gamma = asin h`.
    fn azimuthal(&self, slice: &Slice, gamma: f64, phi: f64) -> [f64; P_MAX + 1] {
        std::array::from_fn(|p| {
            if p < P_MAX {
                lobes::trimmed_logistic(lobes::wrap(phi - slice.phi(p, gamma)), self.s, self.norm)
            } else {
                1.0 / (2.0 * PI)
            }
        })
    }

    /// `M_p A_p N_p` per lobe (no `cos theta`).
    fn lobes(&self, theta_o: f64, gamma: f64, theta: f64, phi: f64) -> [f64; P_MAX + 1] {
        let slice = Slice::new(self.eta, self.sigma_a, theta_o);
        let a = slice.attenuation(gamma);
        let n = self.azimuthal(&slice, gamma, phi);
        let m = lobes::longitudinal_lobes(theta, theta_o, self.alpha, &self.v);
        std::array::from_fn(|p| m[p] * a[p] * n[p])
    }
}

/// The near field of `chiang2016` per channel r, g, b.
pub struct ChiangBsdf {
    ch: [Channel; 3],
    /// All channels equal (a fit of one channel): evaluated once.
    grey: bool,
}

/// The channel whose shape the sampler reads.
const SAMPLER: usize = 1;

impl ChiangBsdf {
    /// From each channel's parameters (internal units).
    pub fn new(rgb: [&[f64]; 3]) -> ChiangBsdf {
        let ch = rgb.map(Channel::new);
        ChiangBsdf {
            grey: ch[0] == ch[1] && ch[1] == ch[2],
            ch,
        }
    }

    /// The lobe probabilities at `(theta_o, h)`: `A_p` averaged over the channels, over
    /// its sum.
    fn lobe_probs(&self, theta_o: f64, gamma: f64) -> Option<[f64; P_MAX + 1]> {
        let mut a = [0.0; P_MAX + 1];
        let chans: &[Channel] = if self.grey { &self.ch[..1] } else { &self.ch };
        for c in chans {
            let ac = Slice::new(c.eta, c.sigma_a, theta_o).attenuation(gamma);
            for p in 0..=P_MAX {
                a[p] += ac[p];
            }
        }
        let total: f64 = a.iter().sum();
        if !(total > 0.0 && total.is_finite()) {
            return None;
        }
        Some(a.map(|x| x / total))
    }
}

fn gamma_of(h: f64) -> f64 {
    h.clamp(-1.0, 1.0).asin()
}

/// pbrt-v4's `SampleTrimmedLogistic(u, s, -pi, pi)`: the inverse CDF of the logistic of
/// scale `s` restricted to [-pi, pi].
fn sample_trimmed_logistic(u: f64, s: f64) -> f64 {
    let cdf = |x: f64| 1.0 / (1.0 + (-x / s).exp());
    let (lo, k) = (cdf(-PI), cdf(PI) - cdf(-PI));
    let x = -s * (1.0 / (u * k + lo) - 1.0).ln();
    if x.is_nan() {
        0.0
    } else {
        x.clamp(-PI, PI)
    }
}

impl NearBsdf for ChiangBsdf {
    fn eval(&self, theta_o: f64, h: f64, theta: f64, phi: f64) -> LobeRgb {
        let gamma = gamma_of(h);
        let cos = theta.cos().max(0.0);
        let mut out = [[0.0; 3]; 5];
        for c in 0..3 {
            let v = if self.grey && c > 0 {
                std::array::from_fn(|p| out[p][0])
            } else {
                self.ch[c]
                    .lobes(theta_o, gamma, theta, phi)
                    .map(|x| x * cos)
            };
            for p in 0..=P_MAX {
                out[p][c] = v[p];
            }
        }
        out
    }

    fn pdf(&self, theta_o: f64, h: f64, theta: f64, phi: f64) -> f64 {
        let gamma = gamma_of(h);
        let Some(probs) = self.lobe_probs(theta_o, gamma) else {
            return 0.0;
        };
        let c = &self.ch[SAMPLER];
        let slice = Slice::new(c.eta, c.sigma_a, theta_o);
        let n = c.azimuthal(&slice, gamma, phi);
        let m = lobes::longitudinal_lobes(theta, theta_o, c.alpha, &c.v);
        let sum: f64 = (0..=P_MAX).map(|p| probs[p] * m[p] * n[p]).sum();
        sum * theta.cos().max(0.0)
    }

    fn sample(&self, theta_o: f64, h: f64, u: [f64; 3]) -> Option<(f64, f64)> {
        let gamma = gamma_of(h);
        let probs = self.lobe_probs(theta_o, gamma)?;
        // The lobe from u[0], which is then rescaled to a fresh uniform for the
        // longitudinal azimuth (pbrt's remapping of `uc`).
        let mut acc = 0.0;
        let mut pick = None;
        for (p, &q) in probs.iter().enumerate() {
            if q > 0.0 && u[0] < acc + q {
                pick = Some((p, ((u[0] - acc) / q).clamp(0.0, 1.0)));
                break;
            }
            acc += q;
        }
        let (p, u0) = match pick {
            Some(x) => x,
            None => (probs.iter().rposition(|&q| q > 0.0)?, 0.5),
        };
        let c = &self.ch[SAMPLER];
        // M_p: cos of the angle to the lobe's axis from the vMF of concentration 1/v,
        // then the direction at azimuth 2 pi u0 about that axis (d'Eon et al. 2011).
        let (sin_o, cos_o) = lobes::tilted(theta_o, c.alpha, p);
        let v = c.v[p];
        let arg = (u[1] + (1.0 - u[1]) * (-2.0 / v).exp()).max(f64::MIN_POSITIVE);
        let cos_t = (1.0 + v * arg.ln()).clamp(-1.0, 1.0);
        let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
        let sin_i = (-cos_t * sin_o + sin_t * (2.0 * PI * u0).cos() * cos_o).clamp(-1.0, 1.0);
        let theta = sin_i.asin();
        let phi = if p < P_MAX {
            let slice = Slice::new(c.eta, c.sigma_a, theta_o);
            lobes::wrap(slice.phi(p, gamma) + sample_trimmed_logistic(u[2], c.s))
        } else {
            2.0 * PI * u[2] - PI
        };
        Some((theta, phi))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::far::FarOptions;
    use crate::model::LobeSet;
    use crate::models::{FiberModel, Integral, Points};
    use rand::{Rng, SeedableRng};
    use rand_xoshiro::Xoshiro256PlusPlus;
    use std::f64::consts::FRAC_PI_2;

    /// Internal units: `eta`, `beta_m`, `beta_n`, `alpha` (rad), `sigma_a`.
    fn params(sigma_a: f64) -> [f64; 5] {
        [1.55, 0.3, 0.3, 2f64.to_radians(), sigma_a]
    }

    fn grey(p: &[f64; 5]) -> ChiangBsdf {
        ChiangBsdf::new([p, p, p])
    }

    /// `(integral of eval per channel, integral of the pdf)` over the sphere in the
    /// `(theta, phi)` measure, by the midpoint rule on `nt x np` cells.
    fn quadrature(b: &ChiangBsdf, theta_o: f64, h: f64, nt: usize, np: usize) -> ([f64; 3], f64) {
        let (dt, dp) = (PI / nt as f64, 2.0 * PI / np as f64);
        let (mut e, mut q) = ([0.0; 3], 0.0);
        for i in 0..nt {
            let theta = -FRAC_PI_2 + (i as f64 + 0.5) * dt;
            for j in 0..np {
                let phi = -PI + (j as f64 + 0.5) * dp;
                let v = b.eval(theta_o, h, theta, phi);
                for c in 0..3 {
                    e[c] += v.iter().map(|l| l[c]).sum::<f64>() * dt * dp;
                }
                q += b.pdf(theta_o, h, theta, phi) * dt * dp;
            }
        }
        (e, q)
    }

    /// White furnace of one fiber: with `sigma_a = 0` the lobes' energies `A_p` sum to
    /// exactly 1 (the residual is the geometric series of the rest) and each `M_p`,
    /// `N_p` is normalised, so the directional albedo is 1 at every `(theta_o, h)`.
    /// Measured by quadrature (600 x 720 cells; its error here is < 1e-4, so the band
    /// [0.998, 1.0005] fails for a lobe that lost or gained 0.2 %), and every sample's
    /// weight is `sum_p A_p = 1` exactly (to rounding, 1e-9), which fails unless the pdf
    /// is the value's own shape.
    #[test]
    fn lossless_fiber_returns_what_it_receives() {
        let b = grey(&params(0.0));
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(7);
        for theta_o in [-60f64, 0.0, 35.0, 75.0].map(f64::to_radians) {
            for h in [-0.9, 0.0, 0.6] {
                let (e, q) = quadrature(&b, theta_o, h, 600, 720);
                for c in 0..3 {
                    assert!(
                        (0.998..=1.0005).contains(&e[c]),
                        "theta_o {theta_o} h {h}: {e:?}"
                    );
                }
                assert!((q - 1.0).abs() < 2e-3, "pdf integrates to {q}");
                for _ in 0..2000 {
                    let u = [rng.random(), rng.random(), rng.random()];
                    let (theta, phi) = b.sample(theta_o, h, u).unwrap();
                    let w: f64 = b
                        .eval(theta_o, h, theta, phi)
                        .iter()
                        .map(|l| l[1])
                        .sum::<f64>()
                        / b.pdf(theta_o, h, theta, phi);
                    assert!((w - 1.0).abs() < 1e-9, "weight {w} at {theta}, {phi}");
                }
            }
        }
    }

    /// The sampler draws from its pdf: a chi-square test of 200 000 draws in 18 x 36
    /// cells (expected counts by an 8 x 8 midpoint rule per cell) against the pdf, for
    /// an absorbing fiber at oblique camera sides and offsets; cells expecting fewer than
    /// 5 draws are pooled. The bound is dof + 6 sqrt(2 dof) (6 standard deviations of
    /// the chi-square: a wrong sign of the tilt or of `Phi`, or a sampler drawing the
    /// residual's lobe as TRT's, exceeds it by orders of magnitude).
    #[test]
    fn sampling_follows_the_pdf() {
        let b = grey(&params(0.8));
        let (nt, np, sub, n) = (18usize, 36usize, 8usize, 200_000usize);
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(11);
        for (theta_o, h) in [(20f64, 0.3), (-55.0, -0.7), (70.0, 0.9)] {
            let theta_o = theta_o.to_radians();
            let mut counts = vec![0f64; nt * np];
            for _ in 0..n {
                let u = [rng.random(), rng.random(), rng.random()];
                let (theta, phi) = b.sample(theta_o, h, u).unwrap();
                let i = (((theta + FRAC_PI_2) / PI * nt as f64) as usize).min(nt - 1);
                let j = (((phi + PI) / (2.0 * PI) * np as f64) as usize).min(np - 1);
                counts[i * np + j] += 1.0;
            }
            let (dt, dp) = (PI / nt as f64, 2.0 * PI / np as f64);
            let (mut chi2, mut dof, mut pooled_o, mut pooled_e) = (0.0, 0usize, 0.0, 0.0);
            for i in 0..nt {
                for j in 0..np {
                    let mut e = 0.0;
                    for a in 0..sub {
                        for c in 0..sub {
                            let t = -FRAC_PI_2 + (i as f64 + (a as f64 + 0.5) / sub as f64) * dt;
                            let p = -PI + (j as f64 + (c as f64 + 0.5) / sub as f64) * dp;
                            e += b.pdf(theta_o, h, t, p);
                        }
                    }
                    let e = e * dt * dp / (sub * sub) as f64 * n as f64;
                    let o = counts[i * np + j];
                    if e < 5.0 {
                        pooled_o += o;
                        pooled_e += e;
                    } else {
                        chi2 += (o - e).powi(2) / e;
                        dof += 1;
                    }
                }
            }
            if pooled_e >= 5.0 {
                chi2 += (pooled_o - pooled_e).powi(2) / pooled_e;
                dof += 1;
            }
            let bound = dof as f64 + 6.0 * (2.0 * dof as f64).sqrt();
            assert!(dof > 50, "{dof} cells");
            assert!(
                chi2 < bound,
                "theta_o {theta_o} h {h}: chi2 {chi2} over {dof} dof"
            );
        }
    }

    /// The estimator a render uses, `value / pdf` at sampled directions, is unbiased for a
    /// coloured fiber (three absorptions, the green channel's shape sampled): its mean
    /// over 100 000 draws per channel lies within 5 standard errors (+ the quadrature's
    /// 1e-4) of the albedo by quadrature.
    #[test]
    fn sampled_albedo_matches_quadrature_per_channel() {
        let [r, g, bl] = [0.2, 0.8, 2.5].map(params);
        let b = ChiangBsdf::new([&r, &g, &bl]);
        assert!(!b.grey);
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(3);
        for (theta_o, h) in [(10f64, -0.2), (-40.0, 0.8)] {
            let theta_o = theta_o.to_radians();
            let (want, _) = quadrature(&b, theta_o, h, 600, 720);
            let n = 100_000;
            let (mut s, mut s2) = ([0.0; 3], [0.0; 3]);
            for _ in 0..n {
                let u = [rng.random(), rng.random(), rng.random()];
                let (theta, phi) = b.sample(theta_o, h, u).unwrap();
                let v = b.eval(theta_o, h, theta, phi);
                let pdf = b.pdf(theta_o, h, theta, phi);
                for c in 0..3 {
                    let w = v.iter().map(|l| l[c]).sum::<f64>() / pdf;
                    s[c] += w;
                    s2[c] += w * w;
                }
            }
            for c in 0..3 {
                let mean = s[c] / n as f64;
                let se = ((s2[c] / n as f64 - mean * mean) / n as f64).sqrt();
                assert!(
                    (mean - want[c]).abs() < 5.0 * se + 1e-4,
                    "channel {c}: {mean} +- {se} vs {}",
                    want[c]
                );
            }
        }
    }

    /// The renderer's near field is the model's: averaged over the offset `h` (2000-point
    /// midpoint rule in `gamma = asin h`), it matches the model interface's far-field
    /// prediction (`FiberModel::predict`, what the fitter fits) lobe by lobe to 1e-4 of
    /// the lobes' sum.
    #[test]
    fn offset_average_is_the_fitted_far_field() {
        let model: &'static dyn FiberModel = &super::super::Chiang2016;
        let p = params(0.6);
        let b = grey(&p);
        let cases: [(f64, f64, f64); 3] = [
            (30.0, -20.0, 40.0),
            (-10.0, 50.0, 170.0),
            (60.0, 10.0, -5.0),
        ];
        let pts: Vec<(f64, f64, f64)> = cases
            .iter()
            .map(|&(a, c, d)| (a.to_radians(), c.to_radians(), d.to_radians()))
            .collect();
        let pred = model.predict(
            &p,
            &Points::new(pts.clone()),
            &FarOptions::default(),
            LobeSet::ALL,
            Integral::Far,
        );
        let n = 2000;
        for (k, &(ti, tr, ph)) in pts.iter().enumerate() {
            let mut avg = [0.0; 5];
            // dh = cos(gamma) dgamma: smooth in gamma, where it is not in h at |h| = 1.
            for j in 0..n {
                let gamma = -FRAC_PI_2 + (j as f64 + 0.5) * PI / n as f64;
                let v = b.eval(tr, gamma.sin(), ti, ph);
                for l in 0..5 {
                    avg[l] += v[l][0] * gamma.cos() * PI / n as f64 / 2.0;
                }
            }
            let want = &pred.lobes[k];
            let total = want.sum();
            assert!(total > 0.0);
            for (l, lobe) in crate::model::Lobe::ALL.into_iter().enumerate().take(4) {
                assert!(
                    (avg[l] - want.get(lobe)).abs() < 1e-4 * total,
                    "point {k} lobe {l}: {} vs {}",
                    avg[l],
                    want.get(lobe)
                );
            }
        }
    }
}
