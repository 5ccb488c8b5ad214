//! `furfit export`: a fit turned into a material of the renderers that speak the Chiang
//! 2016 hair model — Mitsuba 3 (`hair`), pbrt-v4 (`Material "hair"`), Blender Cycles
//! (Principled Hair BSDF, Chiang model) and MaterialX 1.39 (`chiang_hair_bsdf`).
//!
//! The material is always a `chiang2016` parameter set ([`Material`]):
//! - from a `chiang2016` fit its parameters exactly ([`Material::from_fit`]): one
//!   `sigma_a` for a fit of one channel, one per channel for a fit of channels named
//!   r, g, b (the renderers take one `eta`, `beta_m`, `beta_n`, `alpha`: the green
//!   channel's, with a note when the others differ);
//! - from a fit of any other model (`yan2017`, `marschner2003`, ...) the closest Chiang
//!   material: `chiang2016` fitted by the library's own fitter ([`crate::fit::fit_data`])
//!   to that model's far-field prediction at the fit's data angles (its samples above the
//!   fit's floor), whose NRMSE (MODEL.md, optimal exposure) is what the export costs
//!   ([`Origin::Approximated`]).
//!
//! Conventions shared by every target (checked against the sources named in each
//! writer): `theta` is measured from the normal plane of the fiber, positive toward the
//! tip; the offset `h` belongs to the camera ray; `alpha > 0` tilts the R lobe by
//! `-2 alpha` on the camera's inclination (pbrt-v4 `HairBxDF::f`, Mitsuba 3
//! `reframe_with_scales`), `sigma_a` is per unit fiber *radius* (the path inside is
//! `2 cos(gamma_t) / cos(theta_t)` radii in all four implementations), and every
//! renderer's BSDF value is `sum_p M_p A_p N_p` without the extra `cos(theta_i)` a
//! goniometer sample carries (MODEL.md; [`crate::models::chiang2016`]). A target that
//! cannot hold a value clamps it to its range and says so ([`Written::notes`]), in the
//! file and on stdout.

pub mod cycles;
mod material;
pub mod materialx;
pub mod mitsuba;
pub mod pbrt;
pub mod scene;

pub use material::{Material, Origin, Written, MARKER};

use crate::error::{Error, Result};
use std::path::Path;

/// The renderer formats of `--to`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// Mitsuba 3 scene XML (`hair` BSDF, `.xml`).
    Mitsuba,
    /// pbrt-v4 scene (`hair` material, `.pbrt`).
    Pbrt,
    /// A Blender Python script setting up a Cycles Principled Hair BSDF (`.py`).
    Cycles,
    /// A MaterialX document (`chiang_bsdf`, `.mtlx`).
    MaterialX,
}

impl Format {
    /// Every format, in `--to` listing order.
    pub const ALL: [Format; 4] = [
        Format::Mitsuba,
        Format::Pbrt,
        Format::Cycles,
        Format::MaterialX,
    ];

    /// The `--to` name.
    pub fn name(self) -> &'static str {
        match self {
            Format::Mitsuba => "mitsuba",
            Format::Pbrt => "pbrt",
            Format::Cycles => "cycles",
            Format::MaterialX => "materialx",
        }
    }

    /// The file extension the format is usually read under.
    pub fn extension(self) -> &'static str {
        match self {
            Format::Mitsuba => "xml",
            Format::Pbrt => "pbrt",
            Format::Cycles => "py",
            Format::MaterialX => "mtlx",
        }
    }

    /// Parse a `--to` value (case-insensitive; `mitsuba3`, `pbrt-v4`, `pbrt4`, `blender`,
    /// `mtlx` as aliases).
    pub fn parse(s: &str) -> Result<Format> {
        match s.trim().to_ascii_lowercase().as_str() {
            "mitsuba" | "mitsuba3" => Ok(Format::Mitsuba),
            "pbrt" | "pbrt-v4" | "pbrt4" | "pbrtv4" => Ok(Format::Pbrt),
            "cycles" | "blender" => Ok(Format::Cycles),
            "materialx" | "mtlx" => Ok(Format::MaterialX),
            _ => Err(Error::Invalid(format!(
                "unknown export format '{}' (expected one of: {})",
                s.trim(),
                Format::ALL.map(Format::name).join(", ")
            ))),
        }
    }
}

/// The file of `format` for `m`.
pub fn write(m: &Material, format: Format) -> Result<Written> {
    match format {
        Format::Mitsuba => mitsuba::write(m),
        Format::Pbrt => pbrt::write(m),
        Format::Cycles => cycles::write(m),
        Format::MaterialX => materialx::write(m),
    }
}

/// Check before any work that `out` may be written: a file path whose folder can take it;
/// an existing file only with `force`, and only an earlier export ([`MARKER`] on its first
/// line), never another file.
pub fn check_out(out: &Path, force: bool) -> Result<()> {
    crate::io::check_out_file(out)?;
    if out.symlink_metadata().is_err() {
        return Ok(());
    }
    if !force {
        return Err(Error::file(
            out,
            "exists; export would replace it (give --force to replace an earlier export, or choose another --out)",
        ));
    }
    let head = std::fs::read(out).map_err(|e| Error::io(out, e))?;
    let first = head
        .split(|&b| b == b'\n')
        .take(3)
        .any(|l| String::from_utf8_lossy(l).contains(MARKER));
    if !first {
        return Err(Error::file(
            out,
            "exists and is not a file written by furfit export: not replaced, even with --force (move it away first)",
        ));
    }
    Ok(())
}

/// [`check_out`] for the control-point file beside a Mitsuba scene: `--force` replaces
/// it only when it reads as one (lines of four numbers, blank lines between fibers), the
/// format allowing no marker.
pub fn check_out_curves(out: &Path, force: bool) -> Result<()> {
    crate::io::check_out_file(out)?;
    if out.symlink_metadata().is_err() {
        return Ok(());
    }
    if !force {
        return Err(Error::file(
            out,
            "exists; export --scene would replace it (give --force to replace an earlier export)",
        ));
    }
    let text = std::fs::read_to_string(out).unwrap_or_default();
    let curves = !text.trim().is_empty()
        && text.lines().all(|l| {
            l.trim().is_empty()
                || (l.split_whitespace().count() == 4
                    && l.split_whitespace().all(|x| x.parse::<f64>().is_ok()))
        });
    if !curves {
        return Err(Error::file(
            out,
            "exists and is not a curve file written by furfit export: not replaced, even with --force (move it away first)",
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests;
