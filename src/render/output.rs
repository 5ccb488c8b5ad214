//! Tone mapping and image files: sRGB PNG (tone-mapped), linear OpenEXR, per-lobe AOV
//! PNGs and labelled contact sheets.
//!
//! Tone map (documented choice): linear radiance `x` times `2^exposure_ev`, then the
//! ACES filmic curve fit of Narkowicz 2015, `(x (2.51 x + 0.03)) / (x (2.43 x + 0.59) + 0.14)`
//! clamped to [0, 1], then the sRGB transfer function, 8 bits. The EXR keeps linear values.

use super::Image;
use crate::io::write_atomic;
use std::io::Cursor;
use std::path::Path;

/// Largest exposure magnitude in stops (`--exposure`): `2^64` times
/// [`super::MAX_RADIANCE`] is still far from overflowing `x (2.51 x + 0.03)` in [`aces`],
/// and any image is all black or all white well inside it.
pub const MAX_EXPOSURE_EV: f64 = 64.0;

/// The shipped font, registered with plotters under [`FONT`].
pub const FONT: &str = "furfit-dejavu";
static FONT_BYTES: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");

/// Register the shipped font (no system fonts are used); idempotent.
pub fn register_font() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let _ =
            plotters::style::register_font(FONT, plotters::style::FontStyle::Normal, FONT_BYTES);
    });
}

/// ACES filmic fit (Narkowicz 2015).
pub fn aces(x: f64) -> f64 {
    let x = x.max(0.0);
    ((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14)).clamp(0.0, 1.0)
}

/// sRGB opto-electronic transfer function.
pub fn srgb_encode(x: f64) -> f64 {
    let x = x.clamp(0.0, 1.0);
    if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

/// 8-bit sRGB bytes of a linear image under the documented tone map.
pub fn tonemap(img: &Image, exposure_ev: f64) -> Vec<u8> {
    let k = 2f64.powf(exposure_ev);
    img.data
        .iter()
        .flat_map(|p| p.map(|v| (srgb_encode(aces(v * k)) * 255.0 + 0.5) as u8))
        .collect()
}

/// Text stored in a PNG beside the pixels (iTXt: UTF-8), as `(keyword, text)` with the
/// PNG spec's keywords (`Software`, `Source`, `Description`, `Comment`): a shared image
/// keeps what made it.
pub type PngText = [(&'static str, String)];

/// PNG bytes of an 8-bit RGB buffer with `text` chunks (`path` only names the target in
/// errors).
fn encode(
    bytes: Vec<u8>,
    w: usize,
    h: usize,
    text: &PngText,
    path: &Path,
) -> crate::Result<Vec<u8>> {
    let fail =
        |e: png::EncodingError| crate::Error::file(path, format!("PNG encoding failed: {e}"));
    if bytes.len() != w * h * 3 {
        return Err(crate::Error::file(path, "image buffer has the wrong size"));
    }
    let mut out = Vec::new();
    let mut enc = png::Encoder::new(&mut out, w as u32, h as u32);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    for (key, value) in text {
        enc.add_itxt_chunk(key.to_string(), value.clone())
            .map_err(fail)?;
    }
    let mut writer = enc.write_header().map_err(fail)?;
    writer.write_image_data(&bytes).map_err(fail)?;
    writer.finish().map_err(fail)?;
    Ok(out)
}

/// The tone-mapped sRGB PNG's bytes with `text` chunks, for
/// [`crate::io::write_atomic_all`] (`path` names the target in errors).
pub fn png_bytes(
    img: &Image,
    exposure_ev: f64,
    text: &PngText,
    path: &Path,
) -> crate::Result<Vec<u8>> {
    encode(tonemap(img, exposure_ev), img.width, img.height, text, path)
}

/// The linear image as 32-bit float OpenEXR bytes, `text` in its header (`Software` and
/// `Description` as the standard `software` and `comments` attributes, others as
/// `furfit<Keyword>` text attributes; EXR text is Latin-1, other characters become `?`).
/// `path` names the target in errors.
pub fn exr_bytes(img: &Image, text: &PngText, path: &Path) -> crate::Result<Vec<u8>> {
    use exr::meta::attribute::{AttributeValue, Text};
    use exr::prelude::*;
    if img.data.len() != img.width * img.height {
        return Err(crate::Error::file(path, "image buffer has the wrong size"));
    }
    let latin1 = |s: &str| {
        let s: String = s
            .chars()
            .map(|c| if (c as u32) < 256 { c } else { '?' })
            .collect();
        Text::new_or_none(s).unwrap_or_default()
    };
    let mut attrs = LayerAttributes::default();
    for (key, value) in text {
        match *key {
            "Software" => attrs.software_name = Some(latin1(value)),
            "Description" => attrs.comments = Some(latin1(value)),
            _ => {
                attrs.other.insert(
                    latin1(&format!("furfit{key}")),
                    AttributeValue::Text(latin1(value)),
                );
            }
        }
    }
    let w = img.width;
    let pixels = SpecificChannels::rgb(|p: Vec2<usize>| {
        let v = img.data[p.y() * w + p.x()];
        (v[0] as f32, v[1] as f32, v[2] as f32)
    });
    let layer = Layer::new(
        (img.width, img.height),
        attrs,
        Encoding::FAST_LOSSLESS,
        pixels,
    );
    let mut out = Cursor::new(Vec::new());
    exr::prelude::Image::from_layer(layer)
        .write()
        .to_buffered(&mut out)
        .map_err(|e| crate::Error::file(path, format!("EXR encoding failed: {e}")))?;
    Ok(out.into_inner())
}

/// Write the linear image as 32-bit float OpenEXR.
pub fn write_exr(img: &Image, path: &Path) -> crate::Result<()> {
    write_atomic(path, &exr_bytes(img, &[], path)?)
}

/// Read a linear EXR back (tests and comparisons).
pub fn read_exr(path: &Path) -> crate::Result<Image> {
    let img = image::open(path)
        .map_err(|e| crate::Error::file(path, format!("cannot read image: {e}")))?
        .to_rgb32f();
    let (w, h) = (img.width() as usize, img.height() as usize);
    let data = img
        .pixels()
        .map(|p| [p.0[0] as f64, p.0[1] as f64, p.0[2] as f64])
        .collect();
    Ok(Image {
        width: w,
        height: h,
        data,
    })
}

/// Tiles side by side (one row), each with its label drawn in the shipped font under it.
pub fn write_contact_sheet(
    tiles: &[(String, Image)],
    exposure_ev: f64,
    text: &PngText,
    path: &Path,
) -> crate::Result<()> {
    use plotters::prelude::*;
    register_font();
    let th = tiles.iter().map(|t| t.1.height).max().unwrap_or(0);
    let label_h = 28;
    let total_w: usize = tiles.iter().map(|t| t.1.width).sum();
    let (w, h) = (total_w.max(1), th + label_h);
    let mut buf = vec![40u8; w * h * 3];
    let mut x0 = 0;
    for (_, img) in tiles {
        let tm = tonemap(img, exposure_ev);
        for j in 0..img.height {
            for i in 0..img.width {
                let s = (j * img.width + i) * 3;
                let d = (j * w + x0 + i) * 3;
                buf[d..d + 3].copy_from_slice(&tm[s..s + 3]);
            }
        }
        x0 += img.width;
    }
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w as u32, h as u32)).into_drawing_area();
        let mut x0 = 0;
        // One size for every label: 18 px, smaller where the longest would run into the
        // next tile (up to about 0.75 em per character after the 6 px indent; at least 6).
        let px = tiles
            .iter()
            .map(|(label, img)| {
                let room = (img.width as f64 - 10.0).max(1.0);
                room / (0.75 * label.chars().count().max(1) as f64)
            })
            .fold(18.0f64, f64::min)
            .max(6.0);
        for (label, img) in tiles {
            let style = TextStyle::from((FONT, px).into_font()).color(&WHITE);
            root.draw(&Text::new(
                label.clone(),
                (x0 as i32 + 6, th as i32 + 5),
                style,
            ))
            .map_err(|e| crate::Error::file(path, format!("drawing label failed: {e}")))?;
            x0 += img.width;
        }
        root.present()
            .map_err(|e| crate::Error::file(path, format!("drawing failed: {e}")))?;
    }
    write_atomic(path, &encode(buf, w, h, text, path)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tone_map_is_monotone_and_bounded() {
        let mut last = -1.0;
        for k in 0..200 {
            let v = srgb_encode(aces(k as f64 * 0.05));
            assert!(v >= last && (0.0..=1.0).contains(&v));
            last = v;
        }
        assert_eq!(srgb_encode(aces(0.0)), 0.0);
    }

    #[test]
    fn exr_round_trips_linear_values() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.exr");
        let mut img = Image::new(3, 2);
        img.data[4] = [0.25, 2.5, 17.0];
        write_exr(&img, &p).unwrap();
        let back = read_exr(&p).unwrap();
        // f32 storage: relative error ~6e-8.
        assert!(back.rmse(&img) < 1e-6);
    }

    /// The provenance text lands in the EXR header (standard `software` and `comments`,
    /// the rest as `furfit*` attributes), Latin-1 only, and the pixels still read back.
    #[test]
    fn exr_header_carries_the_text() {
        use exr::meta::attribute::{AttributeValue, Text};
        let mut img = Image::new(2, 2);
        img.data[3] = [1.0, 0.5, 0.25];
        let text = [
            ("Software", "furfit test".to_string()),
            (
                "Description",
                "fit file \u{b5}.json (\u{3b2} \u{2192})".to_string(),
            ),
            ("Source", "furfit render --params red-fox".to_string()),
        ];
        let bytes = exr_bytes(&img, &text, Path::new("x.exr")).unwrap();
        let meta = exr::meta::MetaData::read_from_buffered(Cursor::new(&bytes), true).unwrap();
        let layer = &meta.headers[0].own_attributes;
        assert_eq!(layer.software_name, Some(Text::from("furfit test")));
        // The micro sign is Latin-1; beta and the arrow are not.
        assert_eq!(
            layer.comments,
            Some(Text::from("fit file \u{b5}.json (? ?)"))
        );
        assert_eq!(
            layer.other.get(&Text::from("furfitSource")),
            Some(&AttributeValue::Text(Text::from(
                "furfit render --params red-fox"
            )))
        );
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("t.exr");
        std::fs::write(&p, &bytes).unwrap();
        assert!(read_exr(&p).unwrap().rmse(&img) < 1e-6);
    }
}
