//! Azimuthal geometry of a ray in the fiber cross-section (MODEL.md "Azimuthal geometry"):
//! Bravais index, refraction angle and the chord lengths in cortex and medulla.

/// `cos theta_d` below this is clamped: at exactly grazing `theta_d = ±90°` the azimuthal
/// projection degenerates. With this floor absorption terms underflow to 0 smoothly and
/// the Bravais index stays finite (MODEL.md: grazing `theta_d` must not produce NaN).
pub const MIN_COS_THETA_D: f64 = 1e-9;

/// `theta_d = (theta_r - theta_i) / 2`.
pub fn theta_d(theta_i: f64, theta_r: f64) -> f64 {
    0.5 * (theta_r - theta_i)
}

/// Bravais virtual index `eta' = sqrt(eta^2 - sin^2 theta_d) / cos theta_d` (seed Eq. 3).
pub fn eta_prime(eta: f64, cos_theta_d: f64) -> f64 {
    let c = cos_theta_d.max(MIN_COS_THETA_D);
    let s2 = 1.0 - c * c;
    (eta * eta - s2).max(0.0).sqrt() / c
}

/// Everything along a path that depends only on the offset `h` (and `eta'`, `kappa`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PathGeometry {
    /// `h` clamped to [-1, 1].
    pub h: f64,
    /// `gamma_i = asin h`.
    pub gamma_i: f64,
    /// `cos gamma_i = sqrt(1 - h^2)`.
    pub cos_gamma_i: f64,
    /// `gamma_t = asin(h / eta')`.
    pub gamma_t: f64,
    /// `sin gamma_t = h / eta'`: the signed impact parameter of every internal chord.
    pub sin_gamma_t: f64,
    /// Internal half-chord `cos gamma_t`.
    pub cos_gamma_t: f64,
    /// Medulla half-chord `s_m = sqrt(max(kappa^2 - sin^2 gamma_t, 0))`.
    pub s_m: f64,
    /// Cortex part of the half-chord `s_c = cos gamma_t - s_m`.
    pub s_c: f64,
}

impl PathGeometry {
    /// Geometry of the path entering at offset `h` (MODEL.md "Azimuthal geometry").
    pub fn new(h: f64, eta_prime: f64, kappa: f64) -> Self {
        let h = h.clamp(-1.0, 1.0);
        Self::from_incidence(h, h.asin(), (1.0 - h * h).max(0.0).sqrt(), eta_prime, kappa)
    }

    /// [`PathGeometry::new`] at `gamma_i = u` in `[-pi/2, pi/2]` (the far field's variable
    /// of integration): no `asin`, and `cos gamma_i = cos u` keeps its full relative
    /// precision as `h -> 1`, where `sqrt(1 - h^2)` cancels.
    pub fn at_gamma_i(u: f64, eta_prime: f64, kappa: f64) -> Self {
        let (h, c) = u.sin_cos();
        Self::from_incidence(h.clamp(-1.0, 1.0), u, c.max(0.0), eta_prime, kappa)
    }

    fn from_incidence(h: f64, gamma_i: f64, cos_gamma_i: f64, eta_prime: f64, kappa: f64) -> Self {
        let sin_gamma_t = h / eta_prime;
        let gamma_t = sin_gamma_t.asin();
        let cos_gamma_t = (1.0 - sin_gamma_t * sin_gamma_t).max(0.0).sqrt();
        let s_m = (kappa * kappa - sin_gamma_t * sin_gamma_t).max(0.0).sqrt();
        let s_c = (cos_gamma_t - s_m).max(0.0);
        PathGeometry {
            h,
            gamma_i,
            cos_gamma_i,
            gamma_t,
            sin_gamma_t,
            cos_gamma_t,
            s_m,
            s_c,
        }
    }

    /// Does the internal chord meet the medulla (`|sin gamma_t| < kappa`)?
    pub fn meets_medulla(&self) -> bool {
        self.s_m > 0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bravais_index_reduces_to_eta_at_normal_incidence() {
        assert_eq!(eta_prime(1.55, 1.0), 1.55);
        // Grows with theta_d (Bravais): eta' > eta for theta_d != 0.
        assert!(eta_prime(1.55, 30f64.to_radians().cos()) > 1.55);
        assert!(eta_prime(1.55, 0.0).is_finite());
    }

    #[test]
    fn at_gamma_i_matches_new() {
        // Same path to rounding (1e-14: a few ulps of asin and of sqrt(1 - h^2)), and
        // cos gamma_i exact where sqrt(1 - h^2) has lost digits.
        for u in [-1.2, -0.3, 0.0, 0.4, 1.0, 1.5] {
            let (a, b) = (
                PathGeometry::at_gamma_i(u, 1.6, 0.4),
                PathGeometry::new(u.sin(), 1.6, 0.4),
            );
            for (x, y) in [
                (a.h, b.h),
                (a.gamma_i, b.gamma_i),
                (a.cos_gamma_i, b.cos_gamma_i),
                (a.gamma_t, b.gamma_t),
                (a.s_m, b.s_m),
                (a.s_c, b.s_c),
            ] {
                assert!((x - y).abs() < 1e-14, "u {u}: {x} vs {y}");
            }
        }
        let u = std::f64::consts::FRAC_PI_2 - 1e-7;
        let g = PathGeometry::at_gamma_i(u, 1.6, 0.4);
        // u carries ~1e-16 of absolute rounding, 1e-9 of cos u here; sqrt(1 - h^2) is off
        // by ~1e-2 (h = 1 - 5e-15 holds 1e-16 of absolute rounding).
        assert!(
            (g.cos_gamma_i / 1e-7 - 1.0).abs() < 1e-8,
            "{}",
            g.cos_gamma_i
        );
    }

    #[test]
    fn chords_add_up() {
        let g = PathGeometry::new(0.3, 1.5, 0.5);
        assert!((g.s_c + g.s_m - g.cos_gamma_t).abs() < 1e-15);
        assert!((g.gamma_t.sin() - 0.2).abs() < 1e-15);
        let edge = PathGeometry::new(1.0, 1.5, 0.5);
        assert_eq!(edge.cos_gamma_i, 0.0);
        assert!(!PathGeometry::new(0.9, 1.2, 0.5).meets_medulla());
        assert!(PathGeometry::new(0.1, 1.2, 0.5).meets_medulla());
    }
}
