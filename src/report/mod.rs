//! Reports: tables and plots written under `reports/`.

pub mod compare;
pub mod far_error;
pub mod fig11;
pub mod fit_scaling;
pub mod fit_time;
pub mod model_vs_sim;
pub mod nrmse;
pub mod plot;
pub mod se_calibration;
pub mod stability;
pub mod stability_models;
pub mod zoo_bench;

pub use crate::error::sig;
