//! A model's near field as a path tracer's BCSDF ([`FiberModel::render_bsdf`]): what
//! `furfit render` needs of a model other than the fur model (whose renderer is
//! [`crate::render::bsdf`]), in the model's own room.
//!
//! # Arguments and units (the renderer's, [`crate::render::bsdf`]'s module doc)
//! At a hit, `theta_o` is the camera side's inclination, `h` in [-1, 1] the camera ray's
//! offset across the fiber, `(theta, phi)` the light side: its inclination and its
//! azimuth relative to the camera side's (`phi_o = 0`). Values are the model's goniometer
//! value of [`super`]'s module doc at offset `h` (no average over `h`): the integrand of
//! the rendering equation in the `(theta, phi)` measure, so a directional light of
//! irradiance `E` adds `E * value / cos(theta)` and a sampled direction weighs
//! `value / pdf`. Pdfs are in the same `(theta, phi)` measure.
//!
//! [`FiberModel::render_bsdf`]: super::FiberModel::render_bsdf

/// Per-lobe (slots of [`super::FiberModel::lobe_names`]), per-channel (r, g, b) values.
pub type LobeRgb = [[f64; 3]; 5];

/// The near field of one parameter set per channel, with importance sampling whose pdf
/// is exact for what it draws (see the module doc for the arguments).
pub trait NearBsdf: Send + Sync {
    /// The goniometer value of each lobe and channel.
    fn eval(&self, theta_o: f64, h: f64, theta: f64, phi: f64) -> LobeRgb;

    /// The density of [`Self::sample`]'s draws at `(theta, phi)`.
    fn pdf(&self, theta_o: f64, h: f64, theta: f64, phi: f64) -> f64;

    /// A light-side `(theta, phi)` from three uniforms in [0, 1); `None` when no lobe
    /// carries energy.
    fn sample(&self, theta_o: f64, h: f64, u: [f64; 3]) -> Option<(f64, f64)>;
}
