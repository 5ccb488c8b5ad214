//! Cuticle reflectance: unpolarised dielectric Fresnel and the layered (pile-of-plates)
//! cuticle of MODEL.md, `F = l f / (1 + (l - 1) f)`.
//!
//! Shared with the virtual goniometer as a low-level optics helper (not as "the model").

use crate::models::dual::Real;

/// Unpolarised Fresnel reflectance of a smooth dielectric interface (the mean of the s and
/// p reflectances): `cos_i = cos(angle of incidence)`, `eta = n_transmitted / n_incident`.
/// Returns 1 at grazing incidence and under total internal reflection (`eta < 1`, as for
/// the goniometer's rays leaving the fiber).
pub fn fresnel_dielectric(cos_i: f64, eta: f64) -> f64 {
    fresnel_dielectric_generic(cos_i, eta)
}

/// [`fresnel_dielectric`] generic over [`Real`] (forward-mode derivatives; the `f64`
/// instance is that function, operation for operation).
pub fn fresnel_dielectric_generic<T: Real>(cos_i: T, eta: T) -> T {
    let one = T::cst(1.0);
    let cos_i = cos_i.clamp(0.0, 1.0);
    let sin2_t = (one - cos_i * cos_i) / (eta * eta);
    if sin2_t.value() >= 1.0 {
        return one;
    }
    let cos_t = (one - sin2_t).sqrt();
    let rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    let rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    (rs * rs + rp * rp) * 0.5
}

/// Pile-of-plates reflectance of `l` cuticle interfaces, each with reflectance `f`
/// (MODEL.md; `l = 1` gives `f`). Continuous in `l` in (0, 10]; stays in [0, 1].
pub fn layered(f: f64, l: f64) -> f64 {
    let d = 1.0 + (l - 1.0) * f;
    if d <= 0.0 {
        // Only reachable for f = 1 and l -> 0; the limit of l f / (l) is 1.
        1.0
    } else {
        (l * f / d).clamp(0.0, 1.0)
    }
}

/// The cuticle reflectance `F(eta', gamma_i, l)` of seed Eq. 13-14 at azimuthal incidence
/// `gamma_i` with the Bravais index `eta_prime`.
pub fn cuticle_reflectance(eta_prime: f64, cos_gamma_i: f64, l: f64) -> f64 {
    layered(fresnel_dielectric(cos_gamma_i, eta_prime), l)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normal_incidence_matches_closed_form() {
        // ((n-1)/(n+1))^2 exactly; 1e-15 allows one rounding.
        let n: f64 = 1.55;
        let r0 = ((n - 1.0) / (n + 1.0)).powi(2);
        assert!((fresnel_dielectric(1.0, n) - r0).abs() < 1e-15);
        assert_eq!(fresnel_dielectric(0.0, n), 1.0);
        // Index-matched: no reflection (up to rounding of the two amplitudes).
        assert!(fresnel_dielectric(0.3, 1.0) < 1e-30);
    }

    #[test]
    fn layered_limits() {
        let f = 0.04;
        assert!((layered(f, 1.0) - f).abs() < 1e-16);
        // Two plates without absorption: 2f/(1+f).
        assert!((layered(f, 2.0) - 2.0 * f / (1.0 + f)).abs() < 1e-16);
        assert_eq!(layered(1.0, 0.5), 1.0);
        assert!(layered(0.5, 0.01) < 0.5 && layered(0.5, 10.0) > 0.5);
    }
}
