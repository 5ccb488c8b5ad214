//! Reports: tables and plots written under `reports/`.

pub mod compare;
pub mod far_error;
pub mod fig11;
pub mod fit_time;
pub mod model_vs_sim;
pub mod nrmse;
pub mod plot;
pub mod se_calibration;
pub mod stability;
pub mod stability_models;

/// `x` to `digits` significant digits (at least 1): plain decimals for magnitudes in
/// [1e-4, 1e6), else exponent form as [`crate::error::Num`] writes them. Standard errors
/// and fitted - true differences span decades across parameters; a fixed count of
/// decimals printed an SE of 0.00034 as 0.000.
pub fn sig(x: f64, digits: usize) -> String {
    if !x.is_finite() {
        return "-".into();
    }
    if x == 0.0 {
        return "0".into();
    }
    let d = digits.max(1);
    // Round first: 0.0995 to two digits is 0.10, whose decimals follow from 0.1.
    let r: f64 = format!("{:.*e}", d - 1, x).parse().unwrap_or(x);
    let a = r.abs();
    if !(1e-4..1e6).contains(&a) {
        return format!("{:.*e}", d - 1, r);
    }
    let decimals = d as i32 - 1 - a.log10().floor() as i32;
    format!("{:.*}", decimals.max(0) as usize, r)
}
