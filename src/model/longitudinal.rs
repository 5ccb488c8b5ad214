//! Longitudinal lobes `M_p` (seed Eq. 5 and Table 2).

use std::f64::consts::PI;

/// Normalised Gaussian density `G(x; mu, sigma)` on the real line.
pub fn gaussian(x: f64, mu: f64, sigma: f64) -> f64 {
    let z = (x - mu) / sigma;
    (-0.5 * z * z).exp() / (sigma * (2.0 * PI).sqrt())
}

/// Longitudinal shift `alpha_p` and width `beta_p` of unscattered lobe `p` (seed Table 2):
/// R `(alpha, beta_m)`, TT `(-alpha/2, beta_m/2)`, TRT `(-3 alpha/2, 3 beta_m/2)`.
pub fn shift_width(p: usize, alpha: f64, beta_m: f64) -> (f64, f64) {
    match p {
        0 => (alpha, beta_m),
        1 => (-0.5 * alpha, 0.5 * beta_m),
        _ => (-1.5 * alpha, 1.5 * beta_m),
    }
}

/// `M_p(theta_i, theta_r) = G(theta_r; -theta_i + alpha_p, beta_p)` (seed Eq. 5), a density
/// per radian of `theta_r`.
///
/// As MODEL.md says, a plain normalised Gaussian on the line, not renormalised to
/// `[-pi/2, pi/2]`: when the lobe centre is near ±90° or `beta_p` is large, the mass that
/// falls outside the domain is simply lost (see [`m_p_mass_in_domain`]); the fitted
/// exposure absorbs the overall scale, and the paper does the same.
pub fn m_p(p: usize, theta_i: f64, theta_r: f64, alpha: f64, beta_m: f64) -> f64 {
    let (a, b) = shift_width(p, alpha, beta_m);
    gaussian(theta_r, -theta_i + a, b)
}

/// Fraction of `M_p`'s mass inside `theta_r in [-pi/2, pi/2]` (1 when the lobe is well
/// inside the domain); documents the truncation of [`m_p`].
pub fn m_p_mass_in_domain(p: usize, theta_i: f64, alpha: f64, beta_m: f64) -> f64 {
    let (a, b) = shift_width(p, alpha, beta_m);
    let mu = -theta_i + a;
    let s = b * std::f64::consts::SQRT_2;
    0.5 * (puruspe::erf((0.5 * PI - mu) / s) - puruspe::erf((-0.5 * PI - mu) / s))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Composite Simpson over [-pi/2, pi/2] with n (even) intervals.
    fn integrate(f: impl Fn(f64) -> f64, n: usize) -> f64 {
        let (a, b) = (-0.5 * PI, 0.5 * PI);
        let h = (b - a) / n as f64;
        let mut s = f(a) + f(b);
        for k in 1..n {
            s += f(a + k as f64 * h) * if k % 2 == 1 { 4.0 } else { 2.0 };
        }
        s * h / 3.0
    }

    #[test]
    fn m_p_integrates_to_one_inside_domain() {
        let (alpha, beta_m) = (3f64.to_radians(), 8f64.to_radians());
        for p in 0..3 {
            for ti in [-40.0f64, 0.0, 30.0] {
                let ti = ti.to_radians();
                let v = integrate(|tr| m_p(p, ti, tr, alpha, beta_m), 4000);
                // Lobe lies >4 sigma inside the domain: missing mass < 1e-4;
                // Simpson error with 4000 steps is ~1e-12 for these widths.
                assert!((v - 1.0).abs() < 1e-4, "p={p} ti={ti} v={v}");
                let mass = m_p_mass_in_domain(p, ti, alpha, beta_m);
                assert!((v - mass).abs() < 1e-9, "p={p} v={v} mass={mass}");
            }
        }
    }

    #[test]
    fn wide_lobes_lose_exactly_the_mass_outside_the_domain() {
        // beta_m = 60 deg: TRT width 90 deg; the lost mass equals the erf prediction.
        let (alpha, beta_m) = (10f64.to_radians(), 60f64.to_radians());
        for p in 0..3 {
            let ti = 70f64.to_radians();
            let v = integrate(|tr| m_p(p, ti, tr, alpha, beta_m), 4000);
            let mass = m_p_mass_in_domain(p, ti, alpha, beta_m);
            assert!(mass < 0.99);
            assert!((v - mass).abs() < 1e-9, "p={p} v={v} mass={mass}");
        }
    }
}
