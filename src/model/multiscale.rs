//! Multi-scale BCSDF helpers (seed Sec. 5.2), used by the renderer: the pixel coverage of a
//! fiber (Eq. 27) and the offset range `[h1, h2]` it integrates over. The integral itself is
//! [`AzimuthalSlice::multiscale`](crate::model::AzimuthalSlice::multiscale) (Eq. 26).

/// Pixel coverage of a fiber in units of `h` (seed Eq. 27):
/// `C_fiber ~ (omega_fiber . omega_lookat) C_hit / r_fiber`.
pub fn pixel_coverage(cos_fiber_lookat: f64, c_hit: f64, r_fiber: f64) -> f64 {
    (cos_fiber_lookat.abs() * c_hit / r_fiber).max(0.0)
}

/// The offset range `[h - C/2, h + C/2]` clamped to [-1, 1] (seed Sec. 5.2).
pub fn offset_range(h: f64, coverage: f64) -> (f64, f64) {
    let c = 0.5 * coverage.max(0.0);
    ((h - c).clamp(-1.0, 1.0), (h + c).clamp(-1.0, 1.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn coverage_clamps_to_the_fiber() {
        assert_eq!(offset_range(0.9, 0.4), (0.7, 1.0));
        assert_eq!(offset_range(0.0, 10.0), (-1.0, 1.0));
        // A pixel of 0.1 world units on a fiber of radius 0.5 seen head on covers 0.2 in h.
        assert!((pixel_coverage(1.0, 0.1, 0.5) - 0.2).abs() < 1e-15);
    }
}
