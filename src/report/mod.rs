//! Reports: tables and plots written under `reports/`.

pub mod far_error;
pub mod plot;
pub mod stability;
