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
/// `furfit<Keyword>` text attributes). The text is stored as UTF-8 bytes, as the PNG's
/// iTXt is: OpenEXR strings are length-prefixed bytes of no fixed encoding, and Latin-1
/// would turn a CJK path in the recorded command into `?`. The header's attributes are
/// sorted by name ([`sort_header_attributes`]), so the same image gives the same bytes.
/// `path` names the target in errors.
pub fn exr_bytes(img: &Image, text: &PngText, path: &Path) -> crate::Result<Vec<u8>> {
    use exr::meta::attribute::{AttributeValue, Text};
    use exr::prelude::*;
    if img.data.len() != img.width * img.height {
        return Err(crate::Error::file(path, "image buffer has the wrong size"));
    }
    let utf8 = |s: &str| Text::from_slice_unchecked(s.as_bytes());
    let mut attrs = LayerAttributes::default();
    for (key, value) in text {
        match *key {
            "Software" => attrs.software_name = Some(utf8(value)),
            "Description" => attrs.comments = Some(utf8(value)),
            _ => {
                attrs.other.insert(
                    utf8(&format!("furfit{key}")),
                    AttributeValue::Text(utf8(value)),
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
    let mut bytes = out.into_inner();
    sort_header_attributes(&mut bytes)
        .ok_or_else(|| crate::Error::file(path, "EXR encoding failed: unreadable header"))?;
    Ok(bytes)
}

/// Sort the attributes of a single-part EXR's header by name, in place. The exr crate
/// writes non-standard attributes from a `HashMap`, whose order changes from run to run
/// (so did the file's bytes, and its ledger digest). Reordering keeps the header's length,
/// so the offset table after it stays valid; readers take attributes in any order.
/// `None` if the bytes are not a single-part EXR header.
fn sort_header_attributes(bytes: &mut [u8]) -> Option<()> {
    const MAGIC: [u8; 4] = [0x76, 0x2f, 0x31, 0x01];
    const MULTIPART: u8 = 0x10; // bit 12 of the version field
    if bytes.get(..4)? != MAGIC || bytes.get(5)? & MULTIPART != 0 {
        return None;
    }
    let start = 8;
    let nul = |from: usize| Some(from + bytes.get(from..)?.iter().position(|&b| b == 0)?);
    // Each attribute: name NUL, type NUL, i32 size (little-endian), value; a lone NUL ends
    // the header.
    let mut attrs: Vec<(usize, usize, usize)> = Vec::new(); // (start, name end, end)
    let mut pos = start;
    while *bytes.get(pos)? != 0 {
        let name_end = nul(pos)?;
        let type_end = nul(name_end + 1)?;
        let size = i32::from_le_bytes(bytes.get(type_end + 1..type_end + 5)?.try_into().ok()?);
        let end = type_end + 5 + usize::try_from(size).ok()?;
        bytes.get(..end)?;
        attrs.push((pos, name_end, end));
        pos = end;
    }
    attrs.sort_by(|a, b| bytes[a.0..a.1].cmp(&bytes[b.0..b.1]));
    let sorted: Vec<u8> = attrs
        .iter()
        .flat_map(|&(s, _, e)| bytes[s..e].iter().copied())
        .collect();
    bytes[start..pos].copy_from_slice(&sorted);
    Some(())
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

/// Largest and smallest label size on a contact sheet, in pixels: below the smallest a
/// label is unreadable, so a longer one is ellipsised instead.
const LABEL_PX: (f64, f64) = (18.0, 9.0);

/// The size and texts of the contact-sheet labels: one size for all, the largest up to
/// [`LABEL_PX`] at which every label fits its room (`rooms[i]` pixels wide, as measured by
/// `width(text, px)`); a label that does not fit even at the smallest size keeps as many
/// leading characters as fit before a `…` (none if not even that fits).
fn fit_labels(
    labels: &[&str],
    rooms: &[f64],
    width: impl Fn(&str, f64) -> f64,
) -> (f64, Vec<String>) {
    let (max_px, min_px) = LABEL_PX;
    let fits_all = |px: f64| labels.iter().zip(rooms).all(|(l, r)| width(l, px) <= *r);
    let mut px = max_px;
    while px > min_px && !fits_all(px) {
        px -= 1.0;
    }
    let texts = labels
        .iter()
        .zip(rooms)
        .map(|(l, &room)| {
            if width(l, px) <= room {
                return l.to_string();
            }
            let chars: Vec<char> = l.chars().collect();
            (0..chars.len())
                .rev()
                .map(|n| chars[..n].iter().collect::<String>() + "\u{2026}")
                .find(|t| width(t, px) <= room)
                .unwrap_or_default()
        })
        .collect();
    (px, texts)
}

/// Tiles side by side (one row), each with its label drawn in the shipped font under it,
/// sized or ellipsised to the tile's width ([`fit_labels`]) and drawn clipped to it, so a
/// long name never runs into its neighbour's label.
pub fn write_contact_sheet(
    tiles: &[(String, Image)],
    exposure_ev: f64,
    text: &PngText,
    path: &Path,
) -> crate::Result<()> {
    use plotters::prelude::*;
    register_font();
    let draw_err = |e: String| crate::Error::file(path, format!("drawing label failed: {e}"));
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
    // Indent 6 px (less on narrow tiles) on the left, and keep as much free on the right.
    let pad = |tw: usize| 6.min(tw / 8);
    let labels: Vec<&str> = tiles.iter().map(|t| t.0.as_str()).collect();
    let rooms: Vec<f64> = tiles
        .iter()
        .map(|t| t.1.width.saturating_sub(2 * pad(t.1.width)) as f64)
        .collect();
    let (px, texts) = {
        let mut scratch = vec![0u8; 3];
        let area = BitMapBackend::with_buffer(&mut scratch, (1, 1)).into_drawing_area();
        let width = |t: &str, px: f64| {
            let style = TextStyle::from((FONT, px).into_font());
            // A text the font cannot measure counts as too wide: it is dropped, not drawn
            // over the neighbour.
            area.estimate_text_size(t, &style)
                .map_or(f64::INFINITY, |(tw, _)| tw as f64)
        };
        fit_labels(&labels, &rooms, width)
    };
    // Each label is drawn into its own strip the width of its tile, then copied in: the
    // font's own overhang past the measured width cannot reach the next tile either.
    let mut x0 = 0;
    for ((_, img), label) in tiles.iter().zip(&texts) {
        let tw = img.width;
        let mut strip = vec![40u8; tw * label_h * 3];
        if !label.is_empty() && tw > 0 {
            let root = BitMapBackend::with_buffer(&mut strip, (tw as u32, label_h as u32))
                .into_drawing_area();
            let style = TextStyle::from((FONT, px).into_font()).color(&WHITE);
            root.draw(&Text::new(label.clone(), (pad(tw) as i32, 5), style))
                .map_err(|e| draw_err(e.to_string()))?;
            root.present().map_err(|e| draw_err(e.to_string()))?;
        }
        for j in 0..label_h {
            let d = ((th + j) * w + x0) * 3;
            buf[d..d + tw * 3].copy_from_slice(&strip[j * tw * 3..(j + 1) * tw * 3]);
        }
        x0 += tw;
    }
    // Listed in the folder's ledger as it lands (`furfit render --all` keeps one).
    crate::io::write_output(path, &encode(buf, w, h, text, path)?)
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
    /// the rest as `furfit*` attributes) as UTF-8, characters beyond Latin-1 included
    /// (they used to become `?`), and the pixels still read back.
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
            (
                "Source",
                "furfit render --out '\u{65e5}\u{672c} dir/fox \u{fc}.png'".to_string(),
            ),
        ];
        let bytes = exr_bytes(&img, &text, Path::new("x.exr")).unwrap();
        let meta = exr::meta::MetaData::read_from_buffered(Cursor::new(&bytes), true).unwrap();
        let layer = &meta.headers[0].own_attributes;
        assert_eq!(layer.software_name, Some(Text::from("furfit test")));
        let utf8 = |t: &Text| String::from_utf8(t.as_slice().to_vec()).unwrap();
        assert_eq!(utf8(layer.comments.as_ref().unwrap()), text[1].1);
        let Some(AttributeValue::Text(source)) = layer.other.get(&Text::from("furfitSource"))
        else {
            panic!("no furfitSource in {:?}", layer.other)
        };
        assert_eq!(utf8(source), text[2].1);
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("t.exr");
        std::fs::write(&p, &bytes).unwrap();
        assert!(read_exr(&p).unwrap().rmse(&img) < 1e-6);
    }

    /// The same image and text give the same EXR bytes every time: the exr crate writes
    /// the `furfit*` attributes from a `HashMap`, whose order changed from map to map.
    #[test]
    fn exr_bytes_are_deterministic() {
        let img = Image::new(3, 2);
        let text = [
            ("Software", "furfit test".to_string()),
            ("Source", "furfit render".to_string()),
            ("Comment", "parameters {}".to_string()),
            ("Extra", "x".to_string()),
            ("More", "y".to_string()),
        ];
        let first = exr_bytes(&img, &text, Path::new("x.exr")).unwrap();
        for _ in 0..16 {
            assert!(exr_bytes(&img, &text, Path::new("x.exr")).unwrap() == first);
        }
        // Still a valid EXR holding every attribute.
        let meta = exr::meta::MetaData::read_from_buffered(Cursor::new(&first), true).unwrap();
        assert_eq!(meta.headers[0].own_attributes.other.len(), 4);
    }

    /// A label longer than its tile is shrunk down to the smallest size, then ellipsised
    /// to fit; short labels are kept whole (a fake measure: 0.6 em per character).
    #[test]
    fn labels_are_fitted_to_their_tiles() {
        let width = |t: &str, px: f64| 0.6 * px * t.chars().count() as f64;
        let (px, t) = fit_labels(&["fox", "human"], &[100.0, 100.0], width);
        assert_eq!(
            (px, t),
            (18.0, vec!["fox".to_string(), "human".to_string()])
        );
        let long = "a-very-long-species-name-for-label-test";
        let (px, t) = fit_labels(&[long, "fox"], &[52.0, 52.0], width);
        assert_eq!(px, LABEL_PX.1);
        assert_eq!(t[1], "fox");
        assert!(t[0].ends_with('\u{2026}') && long.starts_with(t[0].trim_end_matches('\u{2026}')));
        assert!(width(&t[0], px) <= 52.0, "{}", t[0]);
        // No room at all: nothing is drawn.
        assert_eq!(fit_labels(&[long], &[0.0], width).1, [""]);
    }

    /// On a real sheet a long name stays in its own tile: the label strip under the next
    /// tile, whose label is empty, is untouched background (it used to carry the tail of
    /// the long name), and the long label did draw something in its own strip.
    #[test]
    fn contact_sheet_labels_stay_in_their_tile() {
        let dir = tempfile::tempdir().unwrap();
        for side in [24, 64] {
            let p = dir.path().join(format!("s{side}.png"));
            let tiles = vec![
                (
                    "a-very-long-species-name-for-label-test".to_string(),
                    Image::new(side, side),
                ),
                (String::new(), Image::new(side, side)),
            ];
            write_contact_sheet(&tiles, 0.0, &[], &p).unwrap();
            let img = image::open(&p).unwrap().to_rgb8();
            let strip = |x: std::ops::Range<u32>| {
                (side as u32..img.height())
                    .flat_map(|y| x.clone().map(move |x| (x, y)))
                    .filter(|&(x, y)| img.get_pixel(x, y).0 != [40, 40, 40])
                    .count()
            };
            let s = side as u32;
            assert!(strip(0..s) > 0, "{side}: no label drawn");
            assert_eq!(strip(s..2 * s), 0, "{side}: label ran into the next tile");
        }
    }
}
