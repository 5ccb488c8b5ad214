//! Azimuthal scattering in the near field: attenuation `A_p` (seed Eqs. 13-14, 20),
//! exit azimuths `Phi_p` / `Phi^s_p` (Eqs. 15, 21), distributions `D_p` (Eq. 7, a wrapped
//! Gaussian of variance `(p + 1) beta_n^2`, Eq. 16) and `D^s_p` (Eq. 10, the medulla table
//! `C^N`). Their products, the near field `N_p(h, phi)` (Eqs. 6, 9), are
//! [`AzimuthalSlice::near`](crate::model::AzimuthalSlice::near). Table 3 of the seed lists
//! them all.
//!
//! Frame (MODEL.md): `phi = 0` is backward scattering, `|phi| = pi` forward. The p-th
//! internal segment of a path has direction `Phi^s_p` measured as a deviation from the
//! incident propagation direction, so a ray leaving along it undeflected exits at
//! `phi = Phi^s_p + pi`; the table is queried with `psi = wrap(phi - Phi^s_p)`, which is
//! the exit azimuth relative to the segment with `psi = 0` back along the segment and
//! `|psi| = pi` straight on (the same convention as `phi` itself).

use super::geometry::PathGeometry;
use std::f64::consts::{PI, TAU};

/// Wrap an angle to (-pi, pi].
pub fn wrap_angle(x: f64) -> f64 {
    if x > -PI && x <= PI {
        return x;
    }
    let y = x - TAU * ((x + PI) / TAU).floor();
    // y in [-pi, pi); map -pi to pi.
    if y <= -PI {
        y + TAU
    } else {
        y
    }
}

/// Number of standard deviations beyond which a normal's two tails hold < 1e-12 of its
/// mass (erfc(7.13/sqrt 2) ~ 1e-12).
const TAIL_SIGMAS: f64 = 7.2;

/// Wrapped normal density on the circle with standard deviation `sigma` at angle `x`
/// (MODEL.md: summed over enough `2 pi` shifts that the truncated mass is below 1e-12).
/// For `sigma` above ~1.5 rad the Fourier (Jacobi theta) series converges faster and is
/// used instead; both are exact to well below 1e-12.
pub fn wrapped_gaussian(x: f64, sigma: f64) -> f64 {
    let x = wrap_angle(x);
    if sigma > 1.5 {
        // (1/2pi) (1 + 2 sum_n exp(-n^2 sigma^2/2) cos(n x)); terms < 1e-17 after
        // n^2 sigma^2 / 2 > 39, i.e. n > 8.9/sigma: at most 6 terms here.
        let mut s = 0.5;
        let mut n = 1.0f64;
        loop {
            let w = (-0.5 * n * n * sigma * sigma).exp();
            if w < 1e-17 {
                break;
            }
            s += w * (n * x).cos();
            n += 1.0;
        }
        return s / PI;
    }
    let norm = 1.0 / (sigma * TAU.sqrt());
    let inv2s2 = 0.5 / (sigma * sigma);
    let kmax = ((PI + TAIL_SIGMAS * sigma) / TAU).ceil() as i32;
    let mut s = 0.0;
    for k in -kmax..=kmax {
        let y = x + TAU * k as f64;
        s += (-y * y * inv2s2).exp();
    }
    s * norm
}

/// Exit azimuth of unscattered lobe p: `Phi_p(h) = 2 p gamma_t - 2 gamma_i + p pi`
/// (seed Eq. 15).
pub fn phi_p(p: usize, geo: &PathGeometry) -> f64 {
    let p = p as f64;
    2.0 * p * geo.gamma_t - 2.0 * geo.gamma_i + p * PI
}

/// Direction of the p-th internal segment for scattered lobe p (1 = TTs, 2 = TRTs):
/// `Phi^s_p(h) = (gamma_t - gamma_i) + (p - 1)(pi + 2 gamma_t)` (seed Eq. 21).
pub fn phi_s_p(p: usize, geo: &PathGeometry) -> f64 {
    (geo.gamma_t - geo.gamma_i) + (p as f64 - 1.0) * (PI + 2.0 * geo.gamma_t)
}

/// Azimuthal standard deviation of unscattered lobe p: `sqrt(p + 1) beta_n` (seed Eq. 16).
pub fn beta_p(p: usize, beta_n: f64) -> f64 {
    ((p + 1) as f64).sqrt() * beta_n
}

/// Absorption coefficients and `1 / cos theta_d`, the parameters of the attenuation terms.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Absorption {
    /// Cortex absorption coefficient `sigma_c_a`, per unit radius.
    pub sigma_c_a: f64,
    /// Medulla extinction for unscattered light, `sigma_m_a + sigma_m_s`.
    pub sigma_m_t: f64,
    /// Medulla absorption coefficient `sigma_m_a`, per unit radius (for the scattered
    /// lobes' paths).
    pub sigma_m_a: f64,
    /// Medulla radius / fiber radius.
    pub kappa: f64,
    /// `1 / cos theta_d` (the elongation of azimuthal paths, seed Sec. 4.2).
    pub inv_cos_d: f64,
}

/// Attenuation of unscattered lobe p at cuticle reflectance `f_cut` (seed Eqs. 13-14):
/// `A_0 = F`, `A_p = (1 - F)^2 F^(p-1) T_c T_m` with
/// `T_c = exp(-2 p s_c sigma_c_a / cos theta_d)` and
/// `T_m = exp(-2 p s_m (sigma_m_a + sigma_m_s) / cos theta_d)`: [`a_p_cuticle`] times the
/// exponential of [`a_p_exponent`].
pub fn a_p(p: usize, f_cut: f64, geo: &PathGeometry, ab: &Absorption) -> f64 {
    if p == 0 {
        return f_cut;
    }
    a_p_cuticle(p, f_cut) * a_p_exponent(p, geo, ab).exp()
}

/// The cuticle part of [`a_p`]: `F`, `(1 - F)^2`, `(1 - F)^2 F` for p = 0, 1, 2. The far
/// field fits it and the exponent separately (seed Appendix).
pub fn a_p_cuticle(p: usize, f_cut: f64) -> f64 {
    match p {
        0 => f_cut,
        _ => (1.0 - f_cut).powi(2) * f_cut.powi(p as i32 - 1),
    }
}

/// The absorption exponent of [`a_p`], `ln(T_c T_m) = -2 p (s_c sigma_c_a + s_m (sigma_m_a
/// + sigma_m_s)) / cos theta_d` (0 for R).
pub fn a_p_exponent(p: usize, geo: &PathGeometry, ab: &Absorption) -> f64 {
    if p == 0 {
        return 0.0;
    }
    let pf = p as f64;
    -(2.0 * pf * (geo.s_c * ab.sigma_c_a + geo.s_m * ab.sigma_m_t) * ab.inv_cos_d)
}

/// Attenuation of scattered lobe p (1 = TTs, 2 = TRTs), seed Eq. 20:
/// `A^s_p = (1 - F) F^(p-1) T_a T_b` with
/// `T_a = exp(-[(2p - 1) s_c sigma_c_a + 2 (p - 1) s_m (sigma_m_a + sigma_m_s)] / cos theta_d)`
/// (up to where the p-th segment enters the medulla) and
/// `T_b = exp(-[kappa sigma_m_a + (1 - kappa) sigma_c_a] / cos theta_d)` (from the medulla
/// centre out, no cuticle event on exit). Zero where the p-th segment misses the medulla.
/// (Table 3 of the seed prints `F` for TTs; Eq. 20 and MODEL.md give `1 - F`, used here.)
/// [`a_s_p_cuticle`] times the exponential of [`a_s_p_exponent`].
pub fn a_s_p(p: usize, f_cut: f64, geo: &PathGeometry, ab: &Absorption) -> f64 {
    if !geo.meets_medulla() {
        return 0.0;
    }
    a_s_p_cuticle(p, f_cut) * a_s_p_exponent(p, geo, ab).exp()
}

/// The cuticle part of [`a_s_p`]: `(1 - F) F^(p-1)`.
pub fn a_s_p_cuticle(p: usize, f_cut: f64) -> f64 {
    (1.0 - f_cut) * f_cut.powi(p as i32 - 1)
}

/// The absorption exponent of [`a_s_p`], `ln(T_a T_b)`.
pub fn a_s_p_exponent(p: usize, geo: &PathGeometry, ab: &Absorption) -> f64 {
    let pf = p as f64;
    let ta = (2.0 * pf - 1.0) * geo.s_c * ab.sigma_c_a + 2.0 * (pf - 1.0) * geo.s_m * ab.sigma_m_t;
    let tb = ab.kappa * ab.sigma_m_a + (1.0 - ab.kappa) * ab.sigma_c_a;
    -(ta + tb) * ab.inv_cos_d
}

/// Unscattered azimuthal distribution `D_p(h, phi) = G(Phi_p(h) - phi; beta_p)` (Eq. 7),
/// a wrapped normal.
pub fn d_p(p: usize, geo: &PathGeometry, phi: f64, beta_n: f64) -> f64 {
    wrapped_gaussian(phi_p(p, geo) - phi, beta_p(p, beta_n))
}

/// Relative exit azimuth `psi` at which scattered lobe p queries `C^N` (see module doc).
pub fn psi_s_p(p: usize, geo: &PathGeometry, phi: f64) -> f64 {
    wrap_angle(phi - phi_s_p(p, geo))
}

/// Entry offset into the medulla in medulla radii, `x = sin gamma_t / kappa` (the table's
/// offset axis), clamped to [-1, 1].
pub fn medulla_offset(geo: &PathGeometry, kappa: f64) -> f64 {
    if kappa <= 0.0 {
        0.0
    } else {
        (geo.sin_gamma_t / kappa).clamp(-1.0, 1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn simpson_circle(f: impl Fn(f64) -> f64, n: usize) -> f64 {
        let h = TAU / n as f64;
        let mut s = f(-PI) + f(PI);
        for k in 1..n {
            s += f(-PI + k as f64 * h) * if k % 2 == 1 { 4.0 } else { 2.0 };
        }
        s * h / 3.0
    }

    #[test]
    fn wrap_is_in_range() {
        for x in [-10.0, -PI, -3.0, 0.0, PI, 3.5, 100.0] {
            let w = wrap_angle(x);
            assert!(w > -PI && w <= PI, "{x} -> {w}");
            assert!(((x - w) / TAU - ((x - w) / TAU).round()).abs() < 1e-12);
        }
    }

    #[test]
    fn wrapped_gaussian_integrates_to_one_tiny_to_huge() {
        // 0.1 deg to 90*sqrt(3) deg (TRT at the beta_n bound).
        for sdeg in [0.1f64, 1.0, 10.0, 60.0, 85.9, 86.0, 155.9] {
            let s = sdeg.to_radians();
            // Enough points to resolve a 0.1 deg lobe: step << sigma.
            let n = ((TAU / s) * 40.0).max(2000.0) as usize / 2 * 2;
            let v = simpson_circle(|x| wrapped_gaussian(x, s), n);
            // Simpson on a smooth periodic integrand: error far below 1e-10.
            assert!((v - 1.0).abs() < 1e-10, "sigma={sdeg} deg: {v}");
        }
    }

    #[test]
    fn wrapped_gaussian_branches_agree_at_switch() {
        // Direct image sum and the Fourier series must agree where they hand over.
        let s = 1.5;
        for x in [-3.0, -1.0, 0.0, 0.7, 3.1] {
            let direct: f64 = (-6..=6)
                .map(|k| {
                    let y = wrap_angle(x) + TAU * k as f64;
                    (-0.5 * y * y / (s * s)).exp()
                })
                .sum::<f64>()
                / (s * TAU.sqrt());
            let (a, b) = (wrapped_gaussian(x, s + 1e-12), wrapped_gaussian(x, s));
            // Both series are converged far below 1e-13; sigma differs by 1e-12, which moves
            // the density by ~1e-12 at most.
            assert!(
                (a - direct).abs() < 2e-12,
                "x={x}: fourier {a} direct {direct}"
            );
            assert!((b - direct).abs() < 1e-14, "x={x}: {b} vs {direct}");
        }
    }

    /// The attenuations, widths and the scattered fraction written out from the seed's
    /// equations with literal numbers. The far field, its reference integrator and the
    /// renderer all call these functions, so their agreement with each other cannot catch
    /// a wrong exponent or factor here; a mutation audit (2026-12-03) found that a chord
    /// count of `p` instead of `2p` (Eq. 14), `2p` instead of `2p - 1` (Eq. 20), Table 3's
    /// misprinted `F` for TTs, `(p + 1) beta_n` for `sqrt(p + 1) beta_n` (Eq. 16) and a
    /// scattered probability over one half-chord all passed every library test. Tolerance
    /// 1e-14 relative: each side is a few roundings of the same quantities.
    #[test]
    fn attenuations_and_widths_follow_the_seed_equations() {
        let close = |a: f64, b: f64, what: &str| {
            assert!((a - b).abs() <= 1e-14 * b.abs(), "{what}: {a} vs {b}");
        };
        let (h, eta_prime, kappa) = (0.3, 1.6, 0.5);
        let g = PathGeometry::new(h, eta_prime, kappa);
        // sin gamma_t = h / eta' = 0.1875; medulla half-chord sqrt(kappa^2 - 0.1875^2).
        let (st, sm) = (0.1875f64, (0.25f64 - 0.1875 * 0.1875).sqrt());
        let sc = (1.0 - st * st).sqrt() - sm;
        let cos_d = 20f64.to_radians().cos();
        let ab = Absorption {
            sigma_c_a: 0.7,
            sigma_m_t: 1.3,
            sigma_m_a: 0.4,
            kappa,
            inv_cos_d: 1.0 / cos_d,
        };
        let f = 0.08;
        // Eq. 13-14: A_p = (1 - F)^2 F^(p - 1) exp(-2 p (s_c sigma_c_a + s_m sigma_m_t) / cos).
        let path = sc * 0.7 + sm * 1.3;
        close(a_p(0, f, &g, &ab), f, "A_R");
        close(
            a_p(1, f, &g, &ab),
            0.92 * 0.92 * (-2.0 * path / cos_d).exp(),
            "A_TT",
        );
        close(
            a_p(2, f, &g, &ab),
            0.92 * 0.92 * 0.08 * (-4.0 * path / cos_d).exp(),
            "A_TRT",
        );
        // Eq. 20: A^s_p = (1 - F) F^(p - 1) T_a T_b; T_a over 2p - 1 cortex half-chords and
        // 2 (p - 1) medulla ones, T_b = exp(-(kappa sigma_m_a + (1 - kappa) sigma_c_a) / cos).
        let tb = (-(0.5 * 0.4 + 0.5 * 0.7) / cos_d).exp();
        close(
            a_s_p(1, f, &g, &ab),
            0.92 * (-(sc * 0.7) / cos_d).exp() * tb,
            "A_TTs",
        );
        close(
            a_s_p(2, f, &g, &ab),
            0.92 * 0.08 * (-(3.0 * sc * 0.7 + 2.0 * sm * 1.3) / cos_d).exp() * tb,
            "A_TRTs",
        );
        // Eq. 16: beta_p = sqrt(p + 1) beta_n.
        for (p, k) in [(0, 1.0f64), (1, 2.0), (2, 3.0)] {
            close(beta_p(p, 0.1), k.sqrt() * 0.1, "beta_p");
        }
        // The medulla entry offset is sin gamma_t / kappa, and a ray entering there crosses
        // a chord of 2 sqrt(1 - x^2) medulla radii: P_s = 1 - exp(-2 tau sqrt(1 - x^2)).
        let x = medulla_offset(&g, kappa);
        close(x, 0.375, "x");
        let tau = 1.7;
        close(
            crate::model::medulla::scatter_probability(tau, x),
            1.0 - (-2.0 * tau * (1.0 - 0.375f64 * 0.375).sqrt()).exp(),
            "P_s",
        );
    }

    #[test]
    fn reflection_lobe_center_is_mirror_direction() {
        // h = 0: R goes straight back (0), TT straight through (pi).
        let g = PathGeometry::new(0.0, 1.55, 0.0);
        assert_eq!(phi_p(0, &g), 0.0);
        assert!((phi_p(1, &g) - PI).abs() < 1e-15);
        // h > 0: R exits at -2 asin h (MODEL.md's Phi_0 = -2 gamma_i).
        let g = PathGeometry::new(0.5, 1.55, 0.0);
        assert!((phi_p(0, &g) + 2.0 * 0.5f64.asin()).abs() < 1e-15);
    }
}
