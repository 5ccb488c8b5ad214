//! Small optics kernels for the virtual goniometer: 3-D vectors, exact dielectric Fresnel,
//! the pile-of-plates cuticle reflectance of MODEL.md, mirror reflection, Snell refraction
//! and Henyey-Greenstein sampling.
//!
//! The Fresnel functions are the model's ([`crate::model::fresnel`], re-exported here);
//! the rest is local to `simulate`. Where the analytic model evaluates them at the Bravais
//! 2-D angles, here every interface is handled with the *exact 3-D* incidence angle between
//! the ray and the (micro-)normal, which is the physics the analytic model approximates.

/// A 3-D vector (x, y in the fiber's cross-section plane, z along the fiber axis `u`).
pub type V3 = [f64; 3];

#[inline]
/// Dot product.
pub fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[inline]
/// Sum.
pub fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

#[inline]
/// `a` times `s`.
pub fn scale(a: V3, s: f64) -> V3 {
    [a[0] * s, a[1] * s, a[2] * s]
}

#[inline]
/// `a` scaled to unit length.
pub fn normalize(a: V3) -> V3 {
    scale(a, 1.0 / dot(a, a).sqrt())
}

// Fresnel and the pile-of-plates cuticle are the low-level optics the goniometer shares
// with the analytic model (one copy, in `model::fresnel`).
pub use crate::model::fresnel::{fresnel_dielectric, layered as pile_of_plates};

/// Mirror `d` about the plane with unit normal `n` (either orientation).
#[inline]
pub fn reflect(d: V3, n: V3) -> V3 {
    let k = 2.0 * dot(d, n);
    [d[0] - k * n[0], d[1] - k * n[1], d[2] - k * n[2]]
}

/// Refract unit direction `d` through an interface with unit normal `n` facing the incident
/// side (`dot(d, n) < 0`), relative index `eta = n_t / n_i`. `None` on total internal
/// reflection.
#[inline]
pub fn refract(d: V3, n: V3, eta: f64) -> Option<V3> {
    let cos_i = -dot(d, n);
    let r = 1.0 / eta;
    let sin2_t = r * r * (1.0 - cos_i * cos_i);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let k = r * cos_i - cos_t;
    Some(normalize([
        r * d[0] + k * n[0],
        r * d[1] + k * n[1],
        r * d[2] + k * n[2],
    ]))
}

/// Cosine of the Henyey-Greenstein scattering angle for a uniform `u` in [0, 1)
/// (inverse CDF); `|g| < 1e-4` is treated as isotropic to avoid the 0/0.
#[inline]
pub fn hg_cos(g: f64, u: f64) -> f64 {
    if g.abs() < 1e-4 {
        return 1.0 - 2.0 * u;
    }
    let s = (1.0 - g * g) / (1.0 - g + 2.0 * g * u);
    ((1.0 + g * g - s * s) / (2.0 * g)).clamp(-1.0, 1.0)
}

/// The direction at polar cosine `cos_t` and azimuth `phi` around the unit axis `d`.
#[inline]
pub fn around(d: V3, cos_t: f64, phi: f64) -> V3 {
    // Duff et al. 2017 branchless orthonormal basis.
    let sign = 1.0f64.copysign(d[2]);
    let a = -1.0 / (sign + d[2]);
    let b = d[0] * d[1] * a;
    let t1 = [1.0 + sign * d[0] * d[0] * a, sign * b, -sign * d[0]];
    let t2 = [b, sign + d[1] * d[1] * a, -d[1]];
    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    let (s, c) = phi.sin_cos();
    normalize([
        d[0] * cos_t + sin_t * (c * t1[0] + s * t2[0]),
        d[1] * cos_t + sin_t * (c * t1[1] + s * t2[1]),
        d[2] * cos_t + sin_t * (c * t1[2] + s * t2[2]),
    ])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fresnel_known_values() {
        // Normal incidence: ((n-1)/(n+1))^2 exactly.
        let f = fresnel_dielectric(1.0, 1.5);
        assert!((f - 0.04).abs() < 1e-12);
        // Brewster angle: p vanishes, so f = rs^2 / 2; tan(theta_B) = 1.5.
        let tb = 1.5f64.atan();
        let ci = tb.cos();
        let ct = (1.0 - (tb.sin() / 1.5).powi(2)).sqrt();
        let rs = (ci - 1.5 * ct) / (ci + 1.5 * ct);
        assert!((fresnel_dielectric(ci, 1.5) - 0.5 * rs * rs).abs() < 1e-12);
        // Grazing -> 1, TIR from inside -> 1.
        assert!(fresnel_dielectric(1e-9, 1.5) > 0.999);
        assert_eq!(fresnel_dielectric(0.5, 1.0 / 1.5), 1.0);
        // Reciprocity: f(inside at theta_t) = f(outside at theta_i).
        let ci = 0.7f64;
        let st = (1.0 - ci * ci).sqrt() / 1.5;
        let ct = (1.0 - st * st).sqrt();
        assert!((fresnel_dielectric(ci, 1.5) - fresnel_dielectric(ct, 1.0 / 1.5)).abs() < 1e-12);
    }

    #[test]
    fn pile_of_plates_limits() {
        assert!((pile_of_plates(0.04, 1.0) - 0.04).abs() < 1e-15);
        assert_eq!(pile_of_plates(1.0, 3.0), 1.0);
        // Two plates: 2f/(1+f).
        assert!((pile_of_plates(0.1, 2.0) - 0.2 / 1.1).abs() < 1e-15);
    }

    #[test]
    fn snell_holds() {
        let d = normalize([-0.6, 0.3, -0.2]);
        let n = [1.0, 0.0, 0.0];
        let t = refract(d, n, 1.55).unwrap();
        let sin_i = (1.0 - dot(d, n).powi(2)).sqrt();
        let sin_t = (1.0 - dot(t, n).powi(2)).sqrt();
        assert!((sin_i - 1.55 * sin_t).abs() < 1e-12);
        assert!(dot(t, n) < 0.0);
        // The refracted ray stays in the plane of d and n.
        let cross_y = d[2] * n[0] - d[0] * n[2];
        let cross_y_t = t[2] * n[0] - t[0] * n[2];
        assert!(cross_y * cross_y_t > 0.0);
    }

    #[test]
    fn around_is_unit_and_at_angle() {
        for d in [
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
            normalize([0.3, -0.4, 0.5]),
        ] {
            let w = around(d, 0.3, 1.1);
            assert!((dot(w, w) - 1.0).abs() < 1e-12);
            assert!((dot(w, d) - 0.3).abs() < 1e-12);
        }
    }
}
