//! The model interface: every fiber model the fitter, `synth`, the reports and `stability`
//! evaluate implements [`FiberModel`] once, in a room of its own:
//!
//! | name | model | room |
//! |---|---|---|
//! | `yan2017` (default) | the 5-lobe fur BCSDF of seed `000` (MODEL.md) | [`crate::model`], adapted in [`yan2017`] |
//! | `marschner2003` | Marschner et al. 2003 (seed `002`), R, TT, TRT | [`marschner2003`] |
//! | `chiang2016` | Chiang et al. 2016 as pbrt-v4 / Mitsuba 3 implement it | [`chiang2016`] |
//!
//! A trait object, not a closed enum: each model keeps its own precomputed state (the fur
//! model's medulla table slice, Marschner's root tables, Chiang's quadrature rules) behind
//! [`FiberModel::predict`] and [`ModelTerms`], and the generic code holds only
//! `&'static dyn FiberModel` with a plain parameter vector ([`ModelParams`]). Adding a model
//! is one file set and one line in [`MODELS`]; nothing generic names a parameter.
//!
//! # What every model predicts
//! A goniometer sample (collimated light from `theta_i`, detector at `(theta_r, phi)`)
//! predicts `k * sum_p f_p(theta_i, theta_r, phi)` with the exposure `k` solved by the
//! fitter. `f_p` is the model's rendering-equation integrand for a collimated source in
//! the `(theta_i, phi_i)` measure MODEL.md uses for the fur model (seed 000 Eq. 2:
//! `L_r = integral L_i S cos^2 theta_i dtheta_i dphi_i`), averaged over the fiber offset
//! `h` (the far field). Each model's doc comment states its factor (fur: `M_p N_p`).
//!
//! Parameters are vectors in the model's [`FiberModel::specs`] order: *file units*
//! (degrees for angles) at the boundary, *internal units* (radians) inside, as
//! [`ParamSpec::to_internal`] converts.

mod bsdf;
pub mod chiang2016;
pub mod dual;
mod factored;
mod interface;
pub mod marschner2003;
mod params;
mod points;
mod registry;
pub mod yan2017;

pub use bsdf::{LobeRgb, NearBsdf};
pub use factored::{Factored, FactoredTerms, Factors};
pub use interface::{
    parse_lobes, FiberModel, Integral, Map, ModelTerms, Param, PlainTerms, Prediction, Preset,
    Reduction, ValueJacobian, U_MAX, U_MAX_TANH,
};
pub use params::{fit_channels, select_channel, Channel, ModelParams};
pub use points::{Points, SlicePlan};
pub use registry::{by_name, default_model, names, MODELS};

pub use crate::params::ParamSpec;

#[cfg(test)]
mod tests {
    use super::*;

    /// Every registered model's maps stay inside its hard bounds at any coordinate, its
    /// plausible box lies inside them, and its presets are valid parameter sets.
    #[test]
    fn registered_models_are_consistent() {
        for m in MODELS {
            let n = m.specs().len();
            assert!(m.lobe_names().len() <= 5, "{}", m.name());
            for i in 0..n {
                let s = &m.specs()[i];
                for u in [-1e9, -U_MAX, -40.0, 0.0, 40.0, U_MAX, 1e9] {
                    let v = m.map(i).to_value(u);
                    assert!(s.contains(v), "{} {} u={u} -> {v}", m.name(), s.name);
                }
                let (lo, hi, _) = m.plausible_box(i);
                assert!(
                    s.contains(lo) && s.contains(hi) && lo < hi,
                    "{} {}",
                    m.name(),
                    s.name
                );
            }
            for p in m.presets() {
                assert_eq!(p.values.len(), n, "{} {}", m.name(), p.name);
                ModelParams::from_file_units(m, p.values).unwrap();
            }
            assert_eq!(by_name(m.name()).unwrap().name(), m.name());
        }
        let e = match by_name("blinn") {
            Err(e) => e.to_string(),
            Ok(_) => panic!("no model blinn"),
        };
        assert!(e.contains("blinn") && e.contains("yan2017"), "{e}");
    }

    #[test]
    fn maps_round_trip() {
        for map in [
            Map::Sigmoid { lo: 1.0, span: 2.0 },
            Map::Tanh { scale: 20.0 },
            Map::Exp,
        ] {
            for v in [1.3f64, 2.9, 0.5] {
                let v = if matches!(map, Map::Sigmoid { .. }) {
                    v.max(1.01)
                } else {
                    v
                };
                // Closed-form inverses: float rounding only (1e-12 relative).
                assert!((map.to_value(map.to_u(v)) - v).abs() < 1e-12 * v.abs());
            }
        }
    }
}
