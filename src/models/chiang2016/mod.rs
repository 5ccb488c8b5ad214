//! `chiang2016`: the production hair model of Chiang, Bitterli, Tappan and Burley 2016
//! (*A Practical and Controllable Hair and Fur Model for Production Path Tracing*), with
//! the longitudinal lobes of d'Eon et al. 2011, exactly as pbrt-v4's `HairBxDF` and
//! Mitsuba 3's `hair` BSDF evaluate it: R, TT, TRT and the residual TRRT+ (`p_max = 3`),
//! roughness maps from `beta_m`, `beta_n` in (0, 1], cuticle tilt `alpha`, a trimmed
//! logistic in azimuth and one absorption coefficient `sigma_a` per channel (per unit
//! fiber radius; [`lobes::sigma_a_from_melanin`] gives it from melanin concentrations).
//!
//! The near field is [`lobes`], its average over the fiber offset [`far`]. A goniometer
//! sample predicts `cos(theta_i) sum_p M_p A_p N_p` (models/mod.rs): pbrt's `f` divides its
//! sum by `|cos theta_i|` so that `f |cos theta_i|` is the sum, the integrand in solid
//! angle, and solid angle is `cos(theta_i) dtheta_i dphi_i`.

pub mod bsdf;
pub mod far;
pub mod lobes;
mod specs;
#[cfg(test)]
mod tests;

use crate::model::far::FarOptions;
use crate::model::LobeSet;
use crate::models::bsdf::NearBsdf;
use crate::models::factored::{Factored, FactoredTerms, Factors};
use crate::models::interface::{FiberModel, Integral, Map, ModelTerms, Prediction, Preset};
use crate::models::points::{Points, SlicePlan as Plan};
use crate::params::ParamSpec;
use far::Chiang;
use specs::SPECS;
use std::sync::Arc;

pub use specs::{ALPHA, BETA_M, BETA_N, ETA, SIGMA_A};

/// The model (its state lives in [`far::Chiang`], built per parameter set).
pub struct Chiang2016;

/// pbrt-v4's defaults (`eta` 1.55, `beta_m` = `beta_n` = 0.3, `alpha` 2 deg) with the
/// green channel of d'Eon's eumelanin at 0.3, 1.3 and 8 (blond, brown, black), and a
/// rough variant.
static PRESETS: [Preset; 4] = [
    Preset {
        name: "blond",
        values: &[1.55, 0.3, 0.3, 2.0, 0.3 * 0.697],
    },
    Preset {
        name: "brown",
        values: &[1.55, 0.3, 0.3, 2.0, 1.3 * 0.697],
    },
    Preset {
        name: "black",
        values: &[1.55, 0.3, 0.3, 2.0, 8.0 * 0.697],
    },
    Preset {
        name: "rough",
        values: &[1.55, 0.6, 0.6, 2.0, 0.5],
    },
];

/// The fitter's smallest `beta_m`: a longitudinal width of 0.04 deg, far below any
/// goniometer's resolution.
pub const BETA_M_FLOOR: f64 = 1e-3;

/// The fitter's smallest `beta_n`: a logistic scale of 0.2 deg (a standard deviation of
/// 0.37 deg), below a goniometer's degree-wide steps. The far field's node count grows as
/// `1 / s`, so a floor much lower would make every evaluation of data that pushes `beta_n`
/// down dearer for no difference any sample can show.
pub const BETA_N_FLOOR: f64 = 0.02;

fn plan(points: &Points) -> Arc<Plan> {
    points.cached("chiang2016", |pts| Plan::new(pts, |_, tr| tr))
}

impl FiberModel for Chiang2016 {
    fn name(&self) -> &'static str {
        "chiang2016"
    }

    fn title(&self) -> &'static str {
        "Chiang et al. 2016 hair BSDF as pbrt-v4 and Mitsuba 3 implement it: R, TT, TRT, residual"
    }

    fn specs(&self) -> &'static [ParamSpec] {
        &SPECS
    }

    fn lobe_names(&self) -> &'static [&'static str] {
        &["R", "TT", "TRT", "TRRT+"]
    }

    /// | parameter | map | range |
    /// |---|---|---|
    /// | `eta` | `1 + 2 sigmoid(u)` | (1, 3) |
    /// | `beta_m` | `1e-3 + (1 - 1e-3) sigmoid(u)` | [`BETA_M_FLOOR`] |
    /// | `beta_n` | `0.02 + (1 - 0.02) sigmoid(u)` | [`BETA_N_FLOOR`] |
    /// | `alpha` | `20 tanh(u)` deg | (-20, 20) |
    /// | `sigma_a` | `exp(u)` | (0, inf) |
    fn map(&self, i: usize) -> Map {
        match i {
            ETA => Map::Sigmoid { lo: 1.0, span: 2.0 },
            BETA_M => Map::Sigmoid {
                lo: BETA_M_FLOOR,
                span: 1.0 - BETA_M_FLOOR,
            },
            BETA_N => Map::Sigmoid {
                lo: BETA_N_FLOOR,
                span: 1.0 - BETA_N_FLOOR,
            },
            ALPHA => Map::Tanh { scale: 20.0 },
            _ => Map::Exp,
        }
    }

    /// Human hair and fur both: `beta` from sleek to rough, `sigma_a` from blond to black.
    fn plausible_box(&self, i: usize) -> (f64, f64, bool) {
        match i {
            ETA => (1.2, 1.9, false),
            BETA_M => (0.05, 0.8, true),
            BETA_N => (0.05, 0.9, true),
            ALPHA => (-4.0, 6.0, false),
            _ => (0.01, 6.0, true),
        }
    }

    fn presets(&self) -> &'static [Preset] {
        &PRESETS
    }

    fn predict(
        &self,
        p: &[f64],
        points: &Points,
        _far: &FarOptions,
        lobes: LobeSet,
        integral: Integral,
    ) -> Prediction {
        let plan = plan(points);
        let model = Chiang::from_params(p);
        let factors = match integral {
            Integral::Far => model.factors(&plan),
            Integral::NearQuadrature => Factors {
                n: near_terms(&model, &plan),
                m: model.longitudinal_terms(&plan),
            },
        };
        Prediction {
            lobes: factors.lobe_values(&plan, lobes).collect(),
            capped: (0, plan.slices.len()),
        }
    }

    fn terms(&self, p: &[f64], points: &Points, _far: &FarOptions) -> Box<dyn ModelTerms> {
        let plan = plan(points);
        Box::new(FactoredTerms::<Chiang, { lobes::P_MAX + 1 }>::new(p, plan))
    }

    /// pbrt-v4's `HairBxDF` at the camera ray's offset ([`bsdf::ChiangBsdf`]).
    fn render_bsdf(&self, rgb: [&[f64]; 3]) -> Option<Box<dyn NearBsdf>> {
        Some(Box::new(bsdf::ChiangBsdf::new(rgb)))
    }
}

/// `N̄_p` of every slice by adaptive quadrature ([`far::near_quadrature`], 1e-10).
fn near_terms(model: &Chiang, plan: &Plan) -> Vec<Vec<[f64; lobes::P_MAX + 1]>> {
    use rayon::prelude::*;
    let s = lobes::logistic_scale(model.beta_n);
    plan.slices
        .par_iter()
        .zip(&plan.phis)
        .map(|(&tr, phis)| {
            let slice = lobes::Slice::new(model.eta, model.sigma_a, tr);
            phis.iter()
                .map(|&ph| std::array::from_fn(|p| far::near_quadrature(&slice, p, ph, s, 1e-10)))
                .collect()
        })
        .collect()
}
