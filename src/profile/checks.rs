//! The checks every reader applies to what a file writes: sample counts, angles and their
//! conventions ([`read_phi`], [`wrap_phi`]), values, sigmas and channel names.

use super::sample::{Field, LoadOptions};
use crate::error::{Error, Num, Result};
use std::path::Path;

/// Most samples (or grid cells) a loader reads from one file: a loaded sample takes ~190
/// bytes (an audit measured 185), so 20 M is ~3.8 GB; a 512 MiB float64 npz array (67 M
/// cells) would need ~13 GB. Beyond, the file is refused before the memory is spent.
pub const MAX_READ_CELLS: usize = 20_000_000;

/// Before reading sample `n + 1` on `line` of `path`: an error once `n` reaches `limit`
/// ([`MAX_READ_CELLS`] for the text loaders).
/// Largest profile file the loaders read (1 GiB): above the largest profile of
/// [`MAX_READ_CELLS`] samples in any format (a CSV row of ~40 bytes, an npz cell of value,
/// sigma, phi_i and mask in 25).
pub const MAX_FILE_BYTES: u64 = 1 << 30;

pub(crate) fn check_sample_count(n: usize, limit: usize, path: &Path, line: usize) -> Result<()> {
    if n < limit {
        return Ok(());
    }
    Err(Error::file(
        path,
        format!(
            "line {line}: more than {limit} samples, the most a profile file may hold (each \
             takes ~190 bytes once loaded); split it into several files"
        ),
    ))
}

/// Largest |phi| (degrees) a profile may hold as written, in every format: azimuths come in
/// (-180, 180] or [0, 360) (or negated), and are wrapped to (-180, 180] by [`read_phi`].
/// Beyond one turn a value is a typo, not a convention.
pub(crate) const PHI_LIMIT: f64 = 360.0;

/// A phi as a file (or a lone `.npy`'s `--phi` grid) writes it, read under `opts`: finite and
/// within [-[`PHI_LIMIT`], `PHI_LIMIT`], negated if `flip_phi`, plus `phi_offset`, then
/// wrapped to (-180, 180]. Every reader calls it, so the formats cannot drift apart and the
/// offset applies before the wrap (a file in [0, 360) may take `--phi-offset -180`). With
/// no conversion a phi in (-180, 180] comes back bit for bit ([`wrap_phi`] is the identity
/// there, `-0` and `-180` aside). `name` labels the message, which the caller places.
pub(crate) fn read_phi(name: &str, v: f64, opts: &LoadOptions) -> std::result::Result<f64, String> {
    let v = check_angle(name, v, PHI_LIMIT)?;
    let p = if opts.flip_phi { -v } else { v } + opts.phi_offset;
    if !p.is_finite() {
        return Err(format!(
            "{name} {} plus the phi offset {} is not finite",
            Num(v),
            Num(opts.phi_offset)
        ));
    }
    Ok(wrap_phi(p))
}

/// A theta_r as a file writes it (already range-checked), under `opts`: negated if
/// `flip_theta_r`; `-0` becomes `0`.
pub(crate) fn convert_theta_r(opts: &LoadOptions, theta_r: f64) -> f64 {
    let t = if opts.flip_theta_r { -theta_r } else { theta_r };
    t + 0.0
}

/// Does `opts` change phi as read (so a message about a wrap names the options too)?
pub(super) fn converts_phi(opts: &LoadOptions) -> bool {
    opts.flip_phi || opts.phi_offset != 0.0
}

/// Normalise an angle as every loader does: `-0` becomes `0` and `phi = -180` becomes
/// `180`, following MODEL.md's wrap of phi to (-180, 180]; the two spellings are the same
/// direction, and one canonical spelling keeps grids and duplicate checks exact.
pub fn canonical_phi(phi: f64) -> f64 {
    if phi == -180.0 {
        180.0
    } else {
        phi + 0.0
    }
}

/// Wrap any finite azimuth (degrees) to (-180, 180].
pub fn wrap_phi(phi: f64) -> f64 {
    let mut p = phi % 360.0;
    if p <= -180.0 {
        p += 360.0;
    } else if p > 180.0 {
        p -= 360.0;
    }
    canonical_phi(p)
}

/// Check an angle read from a file: finite and within `[-limit, limit]` degrees.
/// Returns a message for the caller to place (file, line, column or array).
pub(crate) fn check_angle(name: &str, v: f64, limit: f64) -> std::result::Result<f64, String> {
    if !v.is_finite() {
        return Err(format!("{name} must be a finite angle, found {v}"));
    }
    if v < -limit || v > limit {
        return Err(format!(
            "{name} = {} deg is out of range [-{limit}, {limit}]",
            Num(v)
        ));
    }
    Ok(v + 0.0)
}

/// The rules every loader applies to a sample's measured fields, once the format's own
/// spelling of "none" has been decoded (CSV: an empty cell, or `nan` for sigma; npz: NaN).
/// One function, so the formats cannot drift apart:
/// - `value`: NaN or `<= 0` is an *invalid* sample (DATA.md: no usable signal), kept;
///   infinite is an error — no detector reports it, so it is corruption, not a gap;
/// - `sigma`, if given: finite and `>= 0`;
/// - `phi_i`, if given: a finite angle in [-360, 360], as a phi is (DATA.md: an angle out
///   of range is an error), kept as written (only carried for round trips).
///
/// Returns the field at fault and a message for the caller to place (file, line and
/// column, or array and cell).
pub(crate) fn check_measured(
    value: f64,
    sigma: Option<f64>,
    phi_i: Option<f64>,
) -> std::result::Result<(), (Field, String)> {
    if value.is_infinite() {
        return Err((
            Field::Value,
            format!("value {value} is infinite or beyond the f64 range, 1.8e308 (mark a missing sample with NaN)"),
        ));
    }
    if let Some(s) = sigma {
        if !(s.is_finite() && s >= 0.0) {
            return Err((
                Field::Sigma,
                format!("sigma must be finite and >= 0, found {}", Num(s)),
            ));
        }
    }
    if let Some(p) = phi_i {
        check_angle("phi_i", p, PHI_LIMIT).map_err(|m| (Field::PhiI, m))?;
    }
    Ok(())
}

/// A channel name as read from a file (trimmed): it may not be empty, since an empty
/// `channel` cell is a forgotten label, not a channel (DATA.md names channels such as `r`
/// or `650nm`), and it would merge by name with every other unlabelled row.
pub(crate) fn check_channel_name(name: &str) -> std::result::Result<(), String> {
    if name.trim().is_empty() {
        return Err("empty channel name (label every sample, e.g. r, g, b or 650nm)".into());
    }
    Ok(())
}
