//! `furfit view`: a real-time preview of fitted fur in the browser, after seed 003
//! (Lengyel-style shell textures with precomputed radiance transfer onto 25 SH functions),
//! driven by the fitted far-field BCSDF of any registered model.
//!
//! * [`sh`]: the real SH basis of orders 0-4, exact projection and rotation;
//! * [`shells`]: the fur tile (fibers from density, length, curl, comb; seeded) and its
//!   shells' coverage;
//! * [`prt`]: the per-texel transfer (self-shadowing through the shells) and the BCSDF's
//!   SH matrices, combined per frame into 25 lighting coefficients;
//! * [`fins`]: fin textures at the swatch's borders, where the surface turns edge-on;
//! * [`own`]: the fiber-aware self-shadowing (a fiber does not shadow itself);
//! * [`direct`]: the transfer integrated against the light directly (no SH), to measure
//!   the SH truncation;
//! * [`pack`]: the transfer packed into 8-bit textures with per-shell scale and offset;
//! * [`still`]: the page's reconstruction on the CPU (`--still`);
//! * [`page`]: the static WebGL2 page; [`serve`]: a local HTTP server for it;
//! * [`reference`](mod@reference): the path-traced reference of the same fibers through `render`.
//!
//! Nothing here names a model's parameters: the BCSDF is reached through
//! [`crate::models::FiberModel::predict`], the colour through the fit's r, g, b channels
//! or, for the fur model, the renderer's tint ([`crate::render::bsdf::Tint`]).

// Per-channel / per-coefficient loops index several arrays at once, as the formulas do
// (as in src/render/).
#![allow(clippy::needless_range_loop)]

pub mod direct;
pub mod fins;
pub mod lights;
pub mod own;
pub mod pack;
pub mod page;
pub mod prt;
pub mod reference;
pub mod serve;
pub mod sh;
pub mod shells;
pub mod still;

use crate::models::{fit_channels, ModelParams};
use crate::render::bsdf::Tint;
use crate::render::math::V3;
use std::path::Path;
use std::time::Instant;

/// One fit to show: its name, model, parameter lines and RGB BCSDF table.
#[derive(Clone, Debug)]
pub struct Species {
    /// The species' name (the fit's file stem).
    pub name: String,
    /// The model's registry name (`yan2017`, ...).
    pub model: String,
    /// The model's one-line title.
    pub title: String,
    /// `name = value unit` per parameter, in the model's order.
    pub params: Vec<String>,
    /// How the colour was made.
    pub colour: String,
    /// The fitted BCSDF as SH matrices per camera inclination.
    pub table: prt::BcsdfTable,
    /// The r, g, b parameter sets the table was made of.
    pub channels: [ModelParams; 3],
    /// Seconds to tabulate the BCSDF.
    pub seconds: f64,
}

/// The r, g, b parameter sets of a fit: its own r, g, b channels, else (fur model) the
/// renderer's default tint, else grey.
pub fn rgb_channels(
    p: &ModelParams,
    json: Option<&serde_json::Value>,
    spec: &str,
) -> crate::Result<([ModelParams; 3], String)> {
    if let Some(v) = json {
        let chans = fit_channels(v, spec)?;
        let find = |names: [&str; 2]| {
            chans
                .iter()
                .find(|c| names.iter().any(|n| c.name.eq_ignore_ascii_case(n)))
                .map(|c| c.params.clone())
        };
        if let (Some(r), Some(g), Some(b)) = (
            find(["r", "red"]),
            find(["g", "green"]),
            find(["b", "blue"]),
        ) {
            return Ok(([r, g, b], "the fit's r, g, b channels".into()));
        }
    }
    if let Some(fur) = p.fur() {
        let tint = Tint::default();
        let ch = [0, 1, 2].map(|c| ModelParams::from(tint.apply(&fur, c)));
        return Ok((ch, format!("render's default tint ({tint})")));
    }
    Ok((
        [p.clone(), p.clone(), p.clone()],
        "grey (one channel, no tint for this model)".into(),
    ))
}

/// Load a fit (or parameter file, or preset) and tabulate its BCSDF.
pub fn load_species(spec: &str, size: prt::TableSize) -> crate::Result<Species> {
    let (p, _exposure, json) = ModelParams::load(spec, None)?;
    let (channels, colour) = rgb_channels(&p, json.as_ref(), spec)?;
    let name = json
        .as_ref()
        .and_then(|v| v["species"].as_str().map(str::to_string))
        .filter(|s| !s.is_empty())
        .unwrap_or_else(|| {
            Path::new(spec)
                .file_stem()
                .map_or_else(|| spec.to_string(), |s| s.to_string_lossy().into_owned())
        });
    let params = p
        .model
        .specs()
        .iter()
        .zip(p.typed_file_units())
        .map(|(s, v)| {
            format!("{} = {} {}", s.name, crate::error::Num(sig(v, 4)), s.unit)
                .trim_end()
                .to_string()
        })
        .collect();
    let t0 = Instant::now();
    let table = prt::bcsdf_table(&channels, size);
    Ok(Species {
        name,
        model: p.model.name().to_string(),
        title: p.model.title().to_string(),
        params,
        colour,
        table,
        channels,
        seconds: t0.elapsed().as_secs_f64(),
    })
}

/// `v` to `n` significant digits (for display).
fn sig(v: f64, n: i32) -> f64 {
    if v == 0.0 || !v.is_finite() {
        return v;
    }
    let e = v.abs().log10().floor() as i32;
    let k = 10f64.powi(n - 1 - e);
    (v * k).round() / k
}

/// Camera placement, as `render`'s (degrees), looking at the middle of the fur.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct View {
    /// Distance from the middle of the fur (tile units).
    pub dist: f64,
    /// Camera elevation above the swatch's plane, degrees.
    pub elev_deg: f64,
    /// Camera azimuth, degrees (0 toward `+z`).
    pub azim_deg: f64,
    /// Vertical field of view, degrees.
    pub fov_deg: f64,
    /// Light elevation, degrees (the light's `+y` turned there).
    pub light_elev_deg: f64,
    /// Light azimuth, degrees.
    pub light_azim_deg: f64,
    /// Exposure in EV (ACES + sRGB as `render`).
    pub exposure_ev: f64,
}

impl Default for View {
    fn default() -> Self {
        View {
            dist: 2.2,
            elev_deg: 40.0,
            azim_deg: 20.0,
            fov_deg: 24.0,
            light_elev_deg: 55.0,
            light_azim_deg: -40.0,
            exposure_ev: 0.0,
        }
    }
}

/// Everything the page and `--still` share.
pub struct ViewData {
    /// How the fur was grown.
    pub fur: shells::FurSpec,
    /// The shells' quantised transfer and coverage textures.
    pub packed: pack::Packed,
    /// Fin coverage, 8-bit (`[wall][row][texel]`, [`fins::pack`]), `fin_rows` rows.
    pub fin_bytes: Vec<u8>,
    /// Fin texture rows per wall.
    pub fin_rows: usize,
    /// The fits shown, one each.
    pub species: Vec<Species>,
    /// Seconds: growing + coverage, transfer, packing.
    pub seconds: [f64; 3],
    /// Sweep directions of the transfer.
    pub n_dirs: usize,
    /// Which fibers shadow in the transfer.
    pub shadowing: prt::Shadowing,
}

/// The target the camera looks at: the middle of the fur over the tile's centre.
pub fn target(fur: &shells::FurSpec) -> V3 {
    V3::new(0.5, 0.5 * fur.height(), 0.5)
}

/// Build the shells, their transfer and every species' table.
pub fn build(
    fur: &shells::FurSpec,
    fits: &[String],
    size: prt::TableSize,
    dirs: (usize, usize),
    shadowing: prt::Shadowing,
) -> crate::Result<ViewData> {
    fur.validate()?;
    if !dirs.0.is_multiple_of(2) || dirs.0 < 2 || dirs.1 < 3 {
        return Err(crate::Error::Invalid(format!(
            "--dirs {}x{}: expected an even number of inclinations >= 2 and >= 3 azimuths",
            dirs.0, dirs.1
        )));
    }
    let species = fits
        .iter()
        .map(|f| load_species(f, size))
        .collect::<crate::Result<Vec<_>>>()?;
    let t0 = Instant::now();
    let fibers = shells::grow(fur);
    let pieces = shells::pieces(fur, &fibers);
    let cov = pieces.coverage();
    let fin = fins::coverage(fur, &fibers);
    let t1 = Instant::now();
    let rule = sh::Rule::product(dirs.0, dirs.1);
    let weights = prt::sh_weights(&rule);
    let transfer = prt::transfer_pieces(fur, &pieces, &rule, shadowing, &weights, sh::N_COEFFS);
    let t2 = Instant::now();
    let packed = pack::pack_u8(&transfer, &cov);
    let t3 = Instant::now();
    Ok(ViewData {
        fur: fur.clone(),
        packed,
        fin_bytes: fins::pack(&fin),
        fin_rows: fin.rows,
        species,
        seconds: [
            (t1 - t0).as_secs_f64(),
            (t2 - t1).as_secs_f64(),
            (t3 - t2).as_secs_f64(),
        ],
        n_dirs: rule.dirs.len(),
        shadowing,
    })
}
