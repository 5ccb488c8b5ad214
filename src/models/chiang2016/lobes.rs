//! The near field of Chiang et al. 2016, one function per concept, as pbrt-v4's
//! `HairBxDF` (`src/pbrt/bxdfs.h`, `bxdfs.cpp`) and Mitsuba 3's `src/bsdfs/hair.cpp` write
//! it: roughness maps, `M_p` (d'Eon et al. 2011), `A_p`, `Phi`, the trimmed logistic `N_p`.
//!
//! Conventions pinned here (the papers leave them to the renderer):
//! - `theta_o` is the camera's inclination (the goniometer's `theta_r`), `theta_i` the
//!   light's, both toward the tip positive (MODEL.md); pbrt's `wo` / `wi`.
//! - `h` in [-1, 1] is the offset of the *camera* ray (pbrt samples `h` for `wo`), so
//!   `A_p`, `eta'` and the absorption path depend on `theta_o` only.
//! - `phi` is the relative azimuth of MODEL.md (0 = backward); pbrt's `phi_i - phi_o` is
//!   its negative, which the far field cannot tell apart (it is even in `phi`).
//! - `sigma_a` is per unit fiber radius: the path inside is `2 cos gamma_t / cos theta_t`
//!   radii (pbrt-v4 `HairBxDF::f`), as MODEL.md's `sigma_c_a`.

use crate::models::dual::Real;
use std::f64::consts::PI;

/// pbrt-v4 / Mitsuba 3 use `p_max = 3`: R, TT, TRT and the residual TRRT+.
pub const P_MAX: usize = 3;

/// Longitudinal variance `v_p` per lobe from `beta_m` in (0, 1] (Chiang 2016 Eq. 7,
/// pbrt-v4 `HairBxDF::HairBxDF`): `v_0 = (0.726 b + 0.812 b^2 + 3.7 b^20)^2`,
/// `v_1 = v_0 / 4`, `v_2 = v_3 = 4 v_0`.
///
/// Generic over [`Real`] (values or forward-mode derivatives); every constant is on the
/// right of its operation, which is commutative, so the `f64` path is the same
/// arithmetic as the expression above (likewise below).
pub fn variances<T: Real>(beta_m: T) -> [T; P_MAX + 1] {
    let v0 = (beta_m * 0.726 + beta_m * 0.812 * beta_m + beta_m.powi(20) * 3.7).powi(2);
    [v0, v0 * 0.25, v0 * 4.0, v0 * 4.0]
}

/// Logistic scale `s` from `beta_n` in (0, 1] (Chiang 2016 Eq. 8):
/// `s = sqrt(pi/8) (0.265 b + 1.194 b^2 + 5.372 b^22)`.
pub fn logistic_scale<T: Real>(beta_n: T) -> T {
    (beta_n * 0.265 + beta_n * 1.194 * beta_n + beta_n.powi(22) * 5.372) * (PI / 8.0).sqrt()
}

/// The cuticle tilt applied to `theta_o` per lobe (Chiang 2016 Sec. 4.1): R by `-2 alpha`,
/// TT by `+alpha`, TRT by `+4 alpha`, the residual not at all. Returns the shifted
/// `(sin, |cos|)` of pbrt-v4's `sinThetap_o`, `cosThetap_o`.
pub fn tilted<T: Real>(theta_o: f64, alpha: T, p: usize) -> (T, T) {
    let shift = match p {
        0 => alpha * -2.0,
        1 => alpha,
        2 => alpha * 4.0,
        _ => T::cst(0.0),
    };
    let t = shift + theta_o;
    (t.sin(), t.cos().abs())
}

/// `ln(I_0(x) e^-x)`, the exponentially scaled modified Bessel function of order 0, to
/// ~1e-15 relative for `x >= 0`: its power series below 30, the asymptotic series
/// (`sum ((2k-1)!!)^2 / (k! (8x)^k)`, whose smallest term near `k = 2x` is far below
/// rounding at `x >= 30`) above.
/// (Its derivatives are the series' term by term, cut where the values' are.)
pub fn ln_i0_scaled<T: Real>(x: T) -> T {
    if x.value() < 30.0 {
        let q = x * 0.25 * x;
        let (mut term, mut sum) = (T::cst(1.0), T::cst(1.0));
        for k in 1..200 {
            term *= q / (k * k) as f64;
            sum += term;
            if term.value() < 1e-17 * sum.value() {
                break;
            }
        }
        sum.ln() - x
    } else {
        let (mut term, mut sum) = (T::cst(1.0), T::cst(1.0));
        for k in 1..30 {
            let odd = (2 * k - 1) as f64;
            term *= T::cst(odd * odd) / (x * (k as f64 * 8.0));
            sum += term;
            if term.value() < 1e-17 {
                break;
            }
        }
        sum.ln() - (x * (2.0 * PI)).ln() * 0.5
    }
}

/// The longitudinal lobe `M_p` of d'Eon et al. 2011 (Chiang 2016 Eq. 6):
/// `M = exp(-sin(theta_i) sin(theta_o') / v) I_0(cos(theta_i) cos(theta_o') / v) /
/// (2 v sinh(1 / v))`, normalised so that `integral M cos(theta_i) dtheta_i = 1`.
///
/// Evaluated in logs with the exponent `(a - b - 1/v)` written as
/// `(cos(theta_i + theta_o'') - 1) / v` (`theta_o''` the tilted direction reflected into
/// [-90, 90] deg when its cosine was folded), so that `v -> 0` neither overflows nor
/// cancels (pbrt switches to a log form below `v = 0.1` for the same reason).
pub fn longitudinal<T: Real>(sin_i: f64, cos_i: f64, sin_o: T, cos_o: T, v: T) -> T {
    let a = cos_o * cos_i / v;
    // cos(theta_i + theta_o'') - 1 = -2 sin^2((theta_i + theta_o'') / 2), stable.
    let half = (sin_o.atan2(cos_o) + sin_i.atan2(cos_i)) * 0.5;
    let exponent = half.sin().powi(2) * -2.0 / v;
    // 2 v sinh(1/v) = v e^{1/v} (1 - e^{-2/v}); the e^{1/v} is inside `exponent`.
    let log_norm = v.ln() + (-(T::cst(-2.0) / v).exp()).ln_1p();
    (exponent + ln_i0_scaled(a) - log_norm).exp()
}

/// The longitudinal lobes of all `p` for light at `theta_i`, camera at `theta_o`.
pub fn longitudinal_lobes<T: Real>(
    theta_i: f64,
    theta_o: f64,
    alpha: T,
    v: &[T; P_MAX + 1],
) -> [T; P_MAX + 1] {
    let (sin_i, cos_i) = theta_i.sin_cos();
    std::array::from_fn(|p| {
        let (so, co) = tilted(theta_o, alpha, p);
        longitudinal(sin_i, cos_i, so, co, v[p])
    })
}

/// What the azimuthal terms of one `theta_o` share: the Bravais index, the refracted
/// inclination and the absorption coefficient along the path. Generic over [`Real`]:
/// `Slice<Dual<N>>` carries the derivatives with respect to `eta` and `sigma_a`.
#[derive(Clone, Copy, Debug)]
pub struct Slice<T = f64> {
    /// Index of refraction of the fiber.
    pub eta: T,
    /// `cos theta_o` of the slice's outgoing inclination.
    pub cos_theta_o: f64,
    /// `eta' = sqrt(eta^2 - sin^2 theta_o) / cos theta_o` (pbrt's `etap`).
    pub eta_prime: T,
    /// `sigma_a / cos theta_t`, so that `T = exp(-2 cos(gamma_t) * sigma_path)`.
    pub sigma_path: T,
}

impl<T: Real> Slice<T> {
    /// The slice of `theta_o` (radians) for index `eta` and absorption `sigma_a` per unit
    /// radius.
    pub fn new(eta: T, sigma_a: T, theta_o: f64) -> Slice<T> {
        let (sin_o, cos_o) = theta_o.sin_cos();
        // At exactly grazing theta_o, cos -> 0: a floor keeps eta' finite (it only enters
        // through asin(h / eta') and the A_p, both bounded).
        let cos_o = cos_o.max(1e-12);
        let sin_t = T::cst(sin_o) / eta;
        let cos_t = (T::cst(1.0) - sin_t * sin_t).max(T::cst(0.0)).sqrt();
        Slice {
            eta,
            cos_theta_o: cos_o,
            eta_prime: (eta * eta - sin_o * sin_o).sqrt() / cos_o,
            sigma_path: sigma_a / cos_t,
        }
    }

    /// `gamma_t = asin(sin(gamma) / eta')` (Snell in the normal plane, Bravais index).
    pub fn gamma_t(&self, gamma: T) -> T {
        (gamma.sin() / self.eta_prime).clamp(-1.0, 1.0).asin()
    }

    /// `Phi(p, h) = 2 p gamma_t - 2 gamma_o + p pi` (Chiang 2016 Eq. 9, Marschner 2003
    /// Eq. 3), with `gamma_o = asin(h)` written `gamma`.
    pub fn phi(&self, p: usize, gamma: T) -> T {
        self.gamma_t(gamma) * (2.0 * p as f64) - gamma * 2.0 + p as f64 * PI
    }

    /// `dPhi/dgamma = 2 p cos(gamma) / sqrt(eta'^2 - sin^2 gamma) - 2`.
    pub fn dphi(&self, p: usize, gamma: T) -> T {
        let (s, c) = gamma.sin_cos();
        c * (2.0 * p as f64) / (self.eta_prime * self.eta_prime - s * s).sqrt() - 2.0
    }

    /// `d^2 Phi / dgamma^2 = -2 p sin(gamma) (eta'^2 - 1) / (eta'^2 - sin^2 gamma)^(3/2)`.
    pub fn ddphi(&self, p: usize, gamma: T) -> T {
        let s = gamma.sin();
        let e = self.eta_prime * self.eta_prime - s * s;
        s * (-2.0 * p as f64) * (self.eta_prime * self.eta_prime - 1.0) / (e * e.sqrt())
    }

    /// The attenuations `A_p` of the camera ray at offset `h = sin(gamma)` (Chiang 2016
    /// Eq. 10-11, pbrt-v4 `Ap`): `A_0 = f`, `A_1 = (1 - f)^2 T`, `A_2 = A_1 T f`, and the
    /// residual `A_3 = A_2 f T / (1 - f T)`, the geometric series of every longer path.
    /// `f` is the unpolarised Fresnel of `eta` at `cos(theta_o) cos(gamma)` (the incidence
    /// angle in 3-D), `T = exp(-2 sigma_a cos(gamma_t) / cos(theta_t))`.
    pub fn attenuation(&self, gamma: T) -> [T; P_MAX + 1] {
        let f = crate::model::fresnel::fresnel_dielectric_generic(
            gamma.cos().max(T::cst(0.0)) * self.cos_theta_o,
            self.eta,
        );
        let t = (self.sigma_path * -2.0 * self.gamma_t(gamma).cos()).exp();
        let one = T::cst(1.0);
        let a1 = (one - f) * (one - f) * t;
        let a2 = a1 * t * f;
        let d = one - f * t;
        let a3 = if d.value() > 0.0 {
            a2 * f * t / d
        } else {
            T::cst(0.0)
        };
        [f, a1, a2, a3]
    }
}

/// The logistic distribution's density with scale `s` (Chiang 2016 Eq. 8).
pub fn logistic(x: f64, s: f64) -> f64 {
    let e = (-x.abs() / s).exp();
    e / (s * (1.0 + e) * (1.0 + e))
}

/// The logistic trimmed to [-pi, pi] and renormalised there (pbrt-v4 `TrimmedLogistic`):
/// a density on the circle for `x` wrapped into [-pi, pi]. `norm` is
/// [`trimmed_norm`]`(s)`.
pub fn trimmed_logistic(x: f64, s: f64, norm: f64) -> f64 {
    logistic(x, s) / norm
}

/// `CDF(pi) - CDF(-pi) = tanh(pi / (2 s))` of the logistic with scale `s`.
pub fn trimmed_norm<T: Real>(s: T) -> T {
    (T::cst(PI) / (s * 2.0)).tanh()
}

/// `x` wrapped into [-pi, pi]: `(x + pi).rem_euclid(2 pi) - pi`, bit for bit, without
/// the division for `x + pi` in (-2 pi, 4 pi), as every difference of two wrapped angles
/// is (the far field's inner loop; `fmod` was a tenth of a fit's time). There
/// `rem_euclid(a)` is `a` on [0, 2 pi), `a - 2 pi` on [2 pi, 4 pi) (exact in both: `fmod`
/// is, and so is that subtraction by Sterbenz's lemma) and `a + 2 pi` rounded once on
/// (-2 pi, 0), as `rem_euclid` adds it to `fmod(a) = a` (tested).
pub fn wrap(x: f64) -> f64 {
    const TAU: f64 = 2.0 * PI;
    let a = x + PI;
    let r = if (0.0..TAU).contains(&a) {
        a
    } else if (TAU..2.0 * TAU).contains(&a) {
        a - TAU
    } else if a < 0.0 && a > -TAU {
        a + TAU
    } else {
        a.rem_euclid(TAU)
    };
    let y = r - PI;
    if y < -PI {
        y + TAU
    } else {
        y
    }
}

/// The eumelanin and pheomelanin absorption per unit concentration (d'Eon et al. 2011,
/// as pbrt-v4's `HairBxDF::SigmaAFromConcentration` and Mitsuba 3's `hair` use them), in
/// r, g, b, per unit fiber radius.
pub const EUMELANIN_SIGMA_A: [f64; 3] = [0.419, 0.697, 1.37];
/// Pheomelanin's absorption per unit concentration, r, g, b (see [`EUMELANIN_SIGMA_A`]).
pub const PHEOMELANIN_SIGMA_A: [f64; 3] = [0.187, 0.4, 1.05];

/// `sigma_a` in r, g, b of eumelanin and pheomelanin concentrations.
pub fn sigma_a_from_melanin(eumelanin: f64, pheomelanin: f64) -> [f64; 3] {
    std::array::from_fn(|c| eumelanin * EUMELANIN_SIGMA_A[c] + pheomelanin * PHEOMELANIN_SIGMA_A[c])
}

/// The near field of lobe `p < P_MAX` at offset `gamma` (= asin h) and relative azimuth
/// `phi`, azimuthal part only: `A_p(h) N_p(phi; h)`; the residual's is `A_3 / (2 pi)`.
pub fn azimuthal_near(slice: &Slice, p: usize, gamma: f64, phi: f64, s: f64) -> f64 {
    let a = slice.attenuation(gamma);
    if p >= P_MAX {
        return a[P_MAX] / (2.0 * PI);
    }
    a[p] * trimmed_logistic(wrap(phi - slice.phi(p, gamma)), s, trimmed_norm(s))
}
