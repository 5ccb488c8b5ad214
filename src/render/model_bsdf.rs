//! The renderer's BCSDF for a model other than the fur model: its near field through
//! the model interface ([`crate::models::FiberModel::render_bsdf`], a [`NearBsdf`]),
//! at the camera ray's own offset `h` (as pbrt-v4 and Mitsuba 3 render hair). Renders
//! of such a model are near field ([`super::render_model_scene`] refuses another mode):
//! the far field and multi-scale of [`super::bsdf`] are the fur model's.
//!
//! Sampling is the model's, exact pdf and all, so a sample's weight is `value / pdf`
//! and the MIS pdf is that pdf: the estimator stays unbiased.

use super::bsdf::{BsdfSample, HRange, LobeRgb};
use super::integrator::Bcsdf;
use crate::model::Lobe;
use crate::models::NearBsdf;

/// A model's near field as the integrator's [`Bcsdf`].
pub struct ModelBsdf {
    /// The model's near field ([`crate::models::FiberModel::render_bsdf`]).
    pub inner: Box<dyn NearBsdf>,
}

/// The offset of a query: the hit's own in near-field renders; a span (never built for
/// a model render, whose mode is near) is read at its middle.
fn offset(hr: HRange) -> f64 {
    match hr {
        HRange::At(h) => h,
        HRange::Span(h1, h2) => 0.5 * (h1 + h2),
    }
}

impl Bcsdf for ModelBsdf {
    type Side = f64;
    type Mis = (f64, f64);

    fn camera_side(&self, theta_o: f64) -> f64 {
        theta_o
    }

    fn eval(&self, theta_o: f64, theta: f64, phi: f64, hr: HRange) -> LobeRgb {
        self.inner.eval(theta_o, offset(hr), theta, phi)
    }

    fn mis_prepare(&self, side: &f64, hr: HRange) -> (f64, f64) {
        (*side, offset(hr))
    }

    fn pdf_mis_prepared(&self, &(theta_o, h): &(f64, f64), theta: f64, phi: f64) -> f64 {
        self.inner.pdf(theta_o, h, theta, phi)
    }

    fn sample(&self, &theta_o: &f64, hr: HRange, u: [f64; 4]) -> Option<BsdfSample> {
        let h = offset(hr);
        let (theta, phi) = self.inner.sample(theta_o, h, [u[0], u[1], u[2]])?;
        let pdf = self.inner.pdf(theta_o, h, theta, phi);
        if !(pdf > 0.0 && pdf.is_finite()) {
            return None;
        }
        let mut weight = self.inner.eval(theta_o, h, theta, phi);
        weight.iter_mut().flatten().for_each(|c| *c /= pdf);
        // The lobe of largest weight (reported only; the AOV split reads the weights).
        let lum = |l: &[f64; 3]| l.iter().sum::<f64>();
        let best = (0..5).max_by(|&a, &b| lum(&weight[a]).total_cmp(&lum(&weight[b])))?;
        Some(BsdfSample {
            theta,
            phi,
            h,
            lobe: Lobe::ALL[best],
            weight,
            pdf,
        })
    }
}
