//! Dense-grid profiles: `.npz` archives and lone `.npy` arrays (NumPy formats, read and
//! written with `ndarray-npy`).
//!
//! # Arrays in a furfit `.npz`
//! | name | dtype | shape | meaning |
//! |---|---|---|---|
//! | `theta_i` | float64 or integer | `[I]` | incident inclinations, degrees, in [-90, 90] (required) |
//! | `theta_r` | float64 or integer | `[R]` | outgoing inclinations, degrees, in [-90, 90] (required) |
//! | `phi` | float64 or integer | `[P]` | relative azimuths, degrees, in [-360, 360] (required) |
//! | `value` | float64 | `[I, R, P]` or `[I, R, P, C]` | intensity; NaN = missing (required) |
//! | `present` | uint8 (or bool) | same as `value` | 1 = a sample exists at this cell, 0 = none (optional) |
//! | `sigma` | float64 | same as `value` | standard error; NaN = none (optional) |
//! | `phi_i` | float64 | same as `value` | absolute incident azimuth, degrees in [-360, 360]; NaN = none (optional) |
//! | `meta_json` | uint8 | `[n]` | UTF-8 JSON `{"metadata": [[key, value], ...], "channels": [name, ...]}` (optional; the text's bytes, `np.frombuffer(s.encode(), np.uint8)`) |
//!
//! float32 arrays are accepted too and widened to float64; a float32 axis is read as the
//! shortest decimal that names each element (`np.float32(0.1)` as 0.1, not
//! 0.10000000149011612), the grid the file was written for, so it matches a CSV of the same
//! angles instead of doubling every direction. The three axes may also be any integer dtype
//! (NumPy's `np.array([0, 15, 30])` is int64), converted to float64.
//!
//! A cell is a sample when `present` is 1 (any value but 0 and 1 is an error naming the
//! first such cell's index); without `present`, when `value` is not NaN. A sample's value, sigma and phi_i (NaN decoded as "none" for the latter two) obey
//! the CSV reader's rules ([`super::check_measured`]): an infinite `value`, a negative or
//! infinite `sigma` or a `phi_i` outside [-360, 360] is an error naming the array and the cell's
//! index; only cells that are samples are checked. The `present` mask is what lets a sparse CSV profile, including its invalid NaN
//! samples, round trip exactly: the writer always writes it, and stores invalid values as
//! they are (a negative value stays negative, NaN stays NaN). Channel names come from
//! `meta_json` (`channels` must then have `C` entries for a 4-D `value`, at most one for a
//! 3-D one; none may be empty, as in CSV); a 4-D `value` without names gets the names `"0"`,
//! `"1"`, ..., except a single channel (`[I, R, P, 1]`, NumPy's trailing singleton axis),
//! which stays unnamed like the same data shaped `[I, R, P]`, so the two merge. The writer
//! writes a 3-D `value` for a profile without channel names, 4-D otherwise.
//!
//! Axis values are normalised as in the CSV reader (`-0` -> `0`; phi, any finite value in
//! [-360, 360], converted by the [`LoadOptions`] conventions and wrapped to (-180, 180] by
//! [`super::read_phi`], so `np.arange(0, 360, 5.)` reads). Two cells that land on the same
//! direction (a phi axis holding both 0 and 360 or -180 and 180, or a repeated axis value)
//! are duplicates: identical ones are collapsed (with a note), different ones are an error
//! naming both cells (with as many indices as `value` has axes; a wrap's pair on the `phi`
//! array, saying so). Samples come out in grid order (`theta_i`, `theta_r`, `phi`, channel,
//! in array order); the writer sorts each axis ascending, so a written-and-reloaded profile
//! is in [`Profile::sort_grid_order`] order.
//!
//! Before an array is decoded its header is checked against the bytes actually present, so
//! a truncated or corrupt array is an error naming it (never a huge allocation or a panic);
//! an array larger than 512 MiB uncompressed, or of more than 20 M cells (a profile's
//! memory: ~190 bytes a sample), is refused from its header. Archives from `numpy.savez` and
//! `numpy.savez_compressed` (deflate) are both read; the writer stores arrays uncompressed
//! (NumPy reads them with `numpy.load`). Checked by hand with NumPy 2.4:
//! `np.savez(f, theta_i=ti, theta_r=tr, phi=ph, value=v)` loads, and `np.load` reads what
//! [`to_bytes`] writes, `meta_json` decoding with `json.loads(bytes(z["meta_json"]))`.
//!
//! # A lone `.npy`
//! A `.npy` file holds only `value` (3-D or 4-D, float64/float32, NaN = missing); its three
//! axes must be given as grids in [`LoadOptions`] (`--theta-i`, `--theta-r`, `--phi` on
//! the command line) and their lengths must match the array's shape.

use super::{
    check_angle, check_channel_name, check_measured, convert_theta_r, dedupe_notes, quoted,
    read_phi, wrap_conflict, Layout, LoadOptions, Origin, Profile, Sample, MAX_READ_CELLS,
};
use crate::error::{Error, Result};
use ndarray::{ArrayD, Dimension, IxDyn};
use ndarray_npy::{NpzWriter, ReadNpyExt};
use std::io::{Cursor, Read};
use std::path::Path;

/// Largest array (decompressed bytes) the reader accepts.
const MAX_ARRAY_BYTES: u64 = 1 << 29;
/// Largest `meta_json` (bytes of JSON text) the reader accepts.
const MAX_META_BYTES: u64 = 1 << 24;
/// Longest `.npy` header the reader accepts (numpy writes under 1 KB; version 1 allows
/// 64 KiB).
const MAX_HEADER_BYTES: u64 = 1 << 20;
/// Largest grid (cells) the writer produces; a sparser profile should be saved as CSV.
const MAX_WRITE_CELLS: usize = 50_000_000;

/// What the `.npy` header of an array says.
#[derive(Debug)]
struct NpyHeader {
    descr: String,
    shape: Vec<usize>,
}

impl NpyHeader {
    /// `(kind, item size)` of the dtype, e.g. `('f', 8)` for `<f8`.
    fn kind(&self) -> (char, usize) {
        let d = self.descr.trim_start_matches(['<', '>', '|', '=']);
        let mut chars = d.chars();
        let k = chars.next().unwrap_or('?');
        (k, chars.as_str().parse().unwrap_or(0))
    }
}

/// Parse and sanity-check an `.npy` header against the data that follows it; a dtype
/// that is not float, integer or bool is an error.
fn npy_header(bytes: &[u8]) -> std::result::Result<NpyHeader, String> {
    npy_header_with(bytes, |h| {
        if matches!(h.kind().0, 'f' | 'i' | 'u' | 'b') {
            Ok(())
        } else {
            Err(format!(
                "unsupported dtype '{}' (profile arrays are float, integer or bool)",
                h.descr
            ))
        }
    })
}

/// [`npy_header`] with the dtype checked by `dtype` (before the sizes, which a string or
/// object dtype would fail with a less telling message).
fn npy_header_with(
    bytes: &[u8],
    dtype: impl Fn(&NpyHeader) -> std::result::Result<(), String>,
) -> std::result::Result<NpyHeader, String> {
    let (h, end, need) = npy_layout(bytes, dtype, Some(MAX_READ_CELLS))?;
    let have = bytes.len() - end;
    if h.kind().1 > 0 && need != have {
        return Err(format!(
            "truncated or corrupt: header declares shape {:?} of '{}' ({need} bytes) but {have} bytes follow",
            h.shape, h.descr
        ));
    }
    Ok(h)
}

/// Where an `.npy` header's text starts and how long it is, by the format version (1:
/// a 16-bit length, 2 and 3: 32-bit), if `bytes` hold that much of the preamble.
fn header_span(bytes: &[u8]) -> Option<(usize, usize)> {
    match bytes.get(6)? {
        1 if bytes.len() >= 10 => Some((10, u16::from_le_bytes([bytes[8], bytes[9]]) as usize)),
        2 | 3 if bytes.len() >= 12 => Some((
            12,
            u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize,
        )),
        _ => None,
    }
}

/// The header of an `.npy` (its dtype checked by `dtype`, its cells by `max_cells`, a
/// profile grid's limit), where it ends, and the data bytes it declares. `bytes` need hold
/// only the header: [`entry`] reads an archive member's header first.
fn npy_layout(
    bytes: &[u8],
    dtype: impl Fn(&NpyHeader) -> std::result::Result<(), String>,
    max_cells: Option<usize>,
) -> std::result::Result<(NpyHeader, usize, usize), String> {
    const MAGIC: &[u8] = b"\x93NUMPY";
    let n = bytes.len().min(MAGIC.len());
    if bytes[..n] != MAGIC[..n] {
        return Err("not an .npy array (bad magic bytes)".into());
    }
    if bytes.len() < 10 {
        return Err("truncated .npy header".into());
    }
    let (start, hlen) = header_span(bytes)
        .ok_or_else(|| format!("unsupported .npy version {} or truncated header", bytes[6]))?;
    let end = start
        .checked_add(hlen)
        .filter(|e| *e <= bytes.len())
        .ok_or("truncated .npy header")?;
    let text = String::from_utf8_lossy(&bytes[start..end]);
    let after = |key: &str| -> std::result::Result<&str, String> {
        let k = text
            .find(&format!("'{key}'"))
            .or_else(|| text.find(&format!("\"{key}\"")))
            .ok_or(format!("corrupt .npy header: no '{key}'"))?;
        let rest = &text[k + key.len() + 2..];
        let colon = rest.find(':').ok_or("corrupt .npy header")?;
        Ok(rest[colon + 1..].trim_start())
    };
    let d = after("descr")?;
    let q = d.chars().next().ok_or("corrupt .npy header")?;
    if q != '\'' && q != '"' {
        return Err("unsupported dtype (structured arrays are not profiles)".into());
    }
    let descr = d[1..]
        .split(q)
        .next()
        .ok_or("corrupt .npy header")?
        .to_string();
    let s = after("shape")?;
    let s = s
        .strip_prefix('(')
        .and_then(|s| s.split(')').next())
        .ok_or("corrupt .npy header: bad shape")?;
    let mut shape = Vec::new();
    for part in s.split(',').map(str::trim).filter(|p| !p.is_empty()) {
        shape.push(
            part.trim_end_matches('L')
                .parse::<usize>()
                .map_err(|_| format!("corrupt .npy header: bad shape entry '{part}'"))?,
        );
    }
    let h = NpyHeader { descr, shape };
    dtype(&h)?;
    let size = h.kind().1;
    // Checked on the header, before anything is decoded or allocated.
    let cells = h.shape.iter().try_fold(1usize, |n, &d| n.checked_mul(d));
    if max_cells.is_some_and(|max| cells.is_none_or(|n| n > max)) {
        return Err(format!(
            "shape {:?} holds more than the {MAX_READ_CELLS} cells a profile may hold (each \
             sample takes ~190 bytes once loaded); split the grid into several files",
            h.shape
        ));
    }
    let need = h
        .shape
        .iter()
        .try_fold(size.max(1), |a, &n| a.checked_mul(n))
        .ok_or("corrupt .npy header: shape overflows")?;
    Ok((h, end, need))
}

/// A reader error of ndarray-npy on one line (its header parser's messages span several).
fn npy_err(path: &Path, array: &str, e: ndarray_npy::ReadNpyError) -> Error {
    let text = e.to_string();
    arr_err(
        path,
        array,
        text.split_whitespace().collect::<Vec<_>>().join(" "),
    )
}

fn arr_err(path: &Path, array: &str, msg: impl Into<String>) -> Error {
    Error::Array {
        file: path.to_path_buf(),
        array: array.to_string(),
        msg: msg.into(),
    }
}

/// Decode a float array (float64, or float32 widened).
fn read_float(bytes: &[u8], path: &Path, name: &str) -> Result<ArrayD<f64>> {
    let h = npy_header(bytes).map_err(|m| arr_err(path, name, m))?;

    let npy = |e: ndarray_npy::ReadNpyError| npy_err(path, name, e);
    match h.kind() {
        ('f', 8) => ArrayD::<f64>::read_npy(bytes).map_err(npy),
        ('f', 4) => Ok(ArrayD::<f32>::read_npy(bytes).map_err(npy)?.mapv(f64::from)),
        _ => Err(arr_err(
            path,
            name,
            format!("wrong dtype '{}': expected float64 (or float32)", h.descr),
        )),
    }
}

/// A float32 angle as the decimal it was written for: the shortest decimal that reads back
/// as `v` (Rust's `Display`), read as f64. `0.1f32` is 0.10000000149011612 widened, a
/// direction no CSV of the same grid names; this gives 0.1.
fn f32_angle(v: f32) -> f64 {
    // Display of a finite f32 always reads back; NaN and inf are refused by the range check.
    format!("{v}").parse().unwrap_or(f64::from(v))
}

/// Decode an axis array: float (as [`read_float`], a float32 axis by [`f32_angle`]) or any
/// integer type, since `np.array([0, 15, 30])` is int64 and whole-degree grids are common.
fn read_axis(bytes: &[u8], path: &Path, name: &str) -> Result<ArrayD<f64>> {
    let h = npy_header(bytes).map_err(|m| arr_err(path, name, m))?;
    let npy = |e: ndarray_npy::ReadNpyError| npy_err(path, name, e);
    // Integers beyond 2^53 round, but such an angle fails the range check anyway.
    match h.kind() {
        ('i', 1) => Ok(ArrayD::<i8>::read_npy(bytes).map_err(npy)?.mapv(f64::from)),
        ('i', 2) => Ok(ArrayD::<i16>::read_npy(bytes).map_err(npy)?.mapv(f64::from)),
        ('i', 4) => Ok(ArrayD::<i32>::read_npy(bytes).map_err(npy)?.mapv(f64::from)),
        ('i', 8) => Ok(ArrayD::<i64>::read_npy(bytes)
            .map_err(npy)?
            .mapv(|v| v as f64)),
        ('u', 1) => Ok(ArrayD::<u8>::read_npy(bytes).map_err(npy)?.mapv(f64::from)),
        ('u', 2) => Ok(ArrayD::<u16>::read_npy(bytes).map_err(npy)?.mapv(f64::from)),
        ('u', 4) => Ok(ArrayD::<u32>::read_npy(bytes).map_err(npy)?.mapv(f64::from)),
        ('u', 8) => Ok(ArrayD::<u64>::read_npy(bytes)
            .map_err(npy)?
            .mapv(|v| v as f64)),
        ('f', 4) => Ok(ArrayD::<f32>::read_npy(bytes).map_err(npy)?.mapv(f32_angle)),
        ('f', 8) => read_float(bytes, path, name),
        _ => Err(arr_err(
            path,
            name,
            format!(
                "wrong dtype '{}': expected float64, float32 or an integer type",
                h.descr
            ),
        )),
    }
}

/// The bytes of a bool `.npy` with its dtype rewritten to `u1` (same length, so the data
/// stay where they are): `b1` is the only `b1` in a header (its keys and shape hold none).
fn bool_header_as_u8(bytes: &[u8]) -> Vec<u8> {
    let mut v = bytes.to_vec();
    let end = v.iter().position(|&c| c == b'\n').unwrap_or(0);
    if let Some(k) = v[..end].windows(2).position(|w| w == b"b1") {
        v[k] = b'u';
    }
    v
}

/// Decode a byte array (uint8 or bool).
fn read_bytes_array(bytes: &[u8], path: &Path, name: &str) -> Result<ArrayD<u8>> {
    let h = npy_header(bytes).map_err(|m| arr_err(path, name, m))?;
    let npy = |e: ndarray_npy::ReadNpyError| npy_err(path, name, e);
    match h.kind() {
        ('u', 1) => ArrayD::<u8>::read_npy(bytes).map_err(npy),
        // Read as the bytes they are, so a byte other than 0 or 1 reaches the caller's
        // check, which names its cell (the bool reader only says it failed).
        ('b', 1) => ArrayD::<u8>::read_npy(&bool_header_as_u8(bytes)[..]).map_err(npy),
        _ => Err(arr_err(
            path,
            name,
            format!("wrong dtype '{}': expected uint8 (or bool)", h.descr),
        )),
    }
}

/// Decode `meta_json`: the UTF-8 bytes of a JSON text, as uint8 (or bool, as
/// [`read_bytes_array`]). A NumPy string (`np.array(s)`, the natural thing to write) or
/// another integer type is refused with the one spelling that works.
fn read_meta_json(bytes: &[u8], path: &Path) -> Result<ArrayD<u8>> {
    const HOW: &str = "meta_json must be the UTF-8 bytes of a JSON text as a uint8 array, \
                       e.g. np.frombuffer(s.encode(), np.uint8)";
    npy_header_with(bytes, |h| match h.kind() {
        ('u', 1) | ('b', 1) => Ok(()),
        _ => Err(format!("dtype '{}': {HOW}", h.descr)),
    })
    .map_err(|m| arr_err(path, "meta_json", m))?;
    read_bytes_array(bytes, path, "meta_json")
}

/// The raw bytes of array `name` (`name.npy` or `name`) in the archive, if present.
fn entry<R: Read + std::io::Seek>(
    zip: &mut zip::ZipArchive<R>,
    path: &Path,
    name: &str,
) -> Result<Option<Vec<u8>>> {
    let want = format!("{name}.npy");
    let idx = zip
        .index_for_name(&want)
        .or_else(|| zip.index_for_name(name));
    let Some(idx) = idx else { return Ok(None) };
    let mut f = zip
        .by_index(idx)
        .map_err(|e| arr_err(path, name, format!("unreadable archive entry: {e}")))?;
    let corrupt = |e: std::io::Error| {
        arr_err(
            path,
            name,
            format!("truncated or corrupt archive entry: {e}"),
        )
    };
    // The header first: the shape it declares bounds what is decompressed after it, so a
    // small archive whose member inflates far past its header's size stops there.
    let mut out = Vec::new();
    (&mut f).take(12).read_to_end(&mut out).map_err(corrupt)?;
    let Some((start, hlen)) = header_span(&out) else {
        // Not an .npy: the array's reader names what is wrong.
        return Ok(Some(out));
    };
    let header_len = (start + hlen) as u64;
    if header_len > MAX_HEADER_BYTES {
        return Err(arr_err(
            path,
            name,
            format!("corrupt .npy header: {header_len} bytes long (at most {MAX_HEADER_BYTES})"),
        ));
    }
    (&mut f)
        .take(header_len.saturating_sub(out.len() as u64))
        .read_to_end(&mut out)
        .map_err(corrupt)?;
    // The metadata text is no grid: bounded by its bytes, not a grid's cells.
    let (max_cells, max_bytes) = if name == "meta_json" {
        (None, MAX_META_BYTES)
    } else {
        (Some(MAX_READ_CELLS), MAX_ARRAY_BYTES)
    };
    let (h, end, need) =
        npy_layout(&out, |_| Ok(()), max_cells).map_err(|m| arr_err(path, name, m))?;
    if !(matches!(h.kind().0, 'f' | 'i' | 'u' | 'b') && h.kind().1 > 0) {
        // No profile array has such a dtype (strings, objects, dates: the header gives no
        // plain item size), and every reader refuses it from the header before the data:
        // the header alone lets it name the dtype, and nothing more is decompressed.
        return Ok(Some(out));
    }
    let total = (end as u64).saturating_add(need as u64);
    if need as u64 > max_bytes {
        return Err(arr_err(
            path,
            name,
            format!(
                "array too large: shape {:?} of '{}' is {need} bytes (at most {max_bytes})",
                h.shape, h.descr
            ),
        ));
    }
    // One byte past the declared size tells a member longer than its header says.
    (&mut f)
        .take(total + 1 - out.len() as u64)
        .read_to_end(&mut out)
        .map_err(corrupt)?;
    if out.len() as u64 > total {
        return Err(arr_err(
            path,
            name,
            format!(
                "truncated or corrupt: header declares shape {:?} of '{}' ({need} bytes) but more follow",
                h.shape, h.descr
            ),
        ));
    }
    Ok(Some(out))
}

#[derive(serde::Deserialize, Default)]
struct MetaJson {
    #[serde(default)]
    metadata: Vec<(String, String)>,
    #[serde(default)]
    channels: Vec<String>,
}

/// Read a furfit `.npz` (see the module doc) without convention options. Returns the
/// profile and loader notes.
pub fn parse_npz(bytes: &[u8], path: &Path) -> Result<(Profile, Vec<String>)> {
    parse_npz_with(bytes, path, &LoadOptions::default())
}

/// [`parse_npz`] with the convention options of `opts` (`flip_phi`, `phi_offset`,
/// `flip_theta_r`) applied to the axes as they are read.
pub fn parse_npz_with(
    bytes: &[u8],
    path: &Path,
    opts: &LoadOptions,
) -> Result<(Profile, Vec<String>)> {
    let mut zip = zip::ZipArchive::new(Cursor::new(bytes)).map_err(|e| {
        Error::file(
            path,
            format!("not a readable .npz (zip) archive (truncated or corrupt?): {e}"),
        )
    })?;
    // Two members of one array (`value.npy` twice, or `value.npy` and `value`): which one
    // a reader takes would be the zip library's choice.
    let mut seen = std::collections::HashSet::new();
    for i in 0..zip.len() {
        let name = zip.name_for_index(i).unwrap_or_default();
        let array = name.strip_suffix(".npy").unwrap_or(name).to_string();
        if !seen.insert(array.clone()) {
            return Err(Error::file(
                path,
                format!("the archive holds array {} twice", quoted(&array)),
            ));
        }
    }
    let mut required = |name: &str| -> Result<Vec<u8>> {
        entry(&mut zip, path, name)?
            .ok_or_else(|| arr_err(path, name, "missing from the archive (required)"))
    };
    let ti = required("theta_i")?;
    let tr = required("theta_r")?;
    let ph = required("phi")?;
    let va = required("value")?;
    let theta_axis = |bytes: &[u8], name: &str| -> Result<Vec<f64>> {
        axis(&read_axis(bytes, path, name)?, path, name, |v| {
            check_angle(name, v, 90.0)
        })
    };
    let phi_written = axis(&read_axis(&ph, path, "phi")?, path, "phi", Ok)?;
    let axes = Axes::new(
        theta_axis(&ti, "theta_i")?,
        theta_axis(&tr, "theta_r")?,
        phi_written,
        "phi",
        opts,
        |k, m| arr_err(path, "phi", format!("element {k}: {m}")),
    )?;
    let value = read_float(&va, path, "value")?;
    let present = match entry(&mut zip, path, "present")? {
        Some(b) => {
            let m = read_bytes_array(&b, path, "present")?;
            // A mask holds 1 (a sample) or 0 (none); another value (255, a count) means the
            // array is not one, and reading it as "a sample" would hide that.
            if let Some((ix, v)) = m.indexed_iter().find(|(_, &v)| v > 1) {
                return Err(arr_err(
                    path,
                    "present",
                    format!(
                        "index {:?}: {v} is neither 1 (a sample) nor 0 (none)",
                        ix.slice()
                    ),
                ));
            }
            Some(m)
        }
        None => None,
    };
    let sigma = match entry(&mut zip, path, "sigma")? {
        Some(b) => Some(read_float(&b, path, "sigma")?),
        None => None,
    };
    let phi_i = match entry(&mut zip, path, "phi_i")? {
        Some(b) => Some(read_float(&b, path, "phi_i")?),
        None => None,
    };
    let meta = match entry(&mut zip, path, "meta_json")? {
        Some(b) => {
            let raw = read_meta_json(&b, path)?;
            if raw.ndim() != 1 {
                return Err(arr_err(path, "meta_json", "must be 1-D"));
            }
            let text: Vec<u8> = raw.iter().copied().collect();
            serde_json::from_slice::<MetaJson>(&text).map_err(|e| {
                arr_err(
                    path,
                    "meta_json",
                    format!("not the expected JSON {{\"metadata\": [[k, v], ...], \"channels\": [...]}}: {e}"),
                )
            })?
        }
        None => MetaJson::default(),
    };
    for (k, (key, value)) in meta.metadata.iter().enumerate() {
        super::check_synthetic_label(key, value)
            .map_err(|m| arr_err(path, "meta_json", format!("metadata[{k}]: {m}")))?;
    }
    grid_to_profile(
        path,
        axes,
        opts,
        value,
        Extras {
            present,
            sigma,
            phi_i,
        },
        meta,
    )
}

/// Read a lone `.npy` holding `value`; the axes come from `opts`.
pub fn parse_npy(bytes: &[u8], path: &Path, opts: &LoadOptions) -> Result<(Profile, Vec<String>)> {
    let value = read_float(bytes, path, "value")?;
    let need = |g: &Option<Vec<f64>>, opt: &str| -> Result<Vec<f64>> {
        g.clone().ok_or_else(|| {
            Error::file(
                path,
                format!(
                    "a lone .npy holds only the value array: give its axes as grids ({opt} missing; \
                     --theta-i, --theta-r and --phi are all needed), or use an .npz with axis arrays"
                ),
            )
        })
    };
    let theta = |g: Vec<f64>, opt: &str| -> Result<Vec<f64>> {
        g.into_iter()
            .map(|v| {
                check_angle(opt, v, 90.0)
                    .map_err(|m| Error::Invalid(format!("{}: {m}", path.display())))
            })
            .collect()
    };
    let axes = Axes::new(
        theta(need(&opts.theta_i, "--theta-i")?, "--theta-i")?,
        theta(need(&opts.theta_r, "--theta-r")?, "--theta-r")?,
        need(&opts.phi, "--phi")?,
        "--phi",
        opts,
        |_, m| Error::Invalid(format!("{}: {m}", path.display())),
    )?;
    grid_to_profile(
        path,
        axes,
        opts,
        value,
        Extras {
            present: None,
            sigma: None,
            phi_i: None,
        },
        MetaJson::default(),
    )
}

/// Validate a 1-D axis array, each element with `check` (a message names the element).
fn axis(
    a: &ArrayD<f64>,
    path: &Path,
    name: &str,
    check: impl Fn(f64) -> std::result::Result<f64, String>,
) -> Result<Vec<f64>> {
    if a.ndim() != 1 {
        return Err(arr_err(
            path,
            name,
            format!("wrong shape {:?}: an axis must be 1-D", a.shape()),
        ));
    }
    if a.is_empty() {
        return Err(arr_err(path, name, "empty axis"));
    }
    a.iter()
        .enumerate()
        .map(|(k, &v)| check(v).map_err(|m| arr_err(path, name, format!("element {k}: {m}"))))
        .collect()
}

/// The three axes of a grid as the samples take them (the convention options applied, phi
/// wrapped), and phi as written (for a wrap's duplicate message).
struct Axes {
    theta_i: Vec<f64>,
    theta_r: Vec<f64>,
    phi: Vec<f64>,
    phi_written: Vec<f64>,
    /// Where phi came from: the archive's `phi` array, or `--phi` (a lone .npy).
    phi_name: String,
}

impl Axes {
    /// The error of element `k` of the phi axis, placed where that axis came from.
    fn phi_err(&self, path: &Path, k: usize, msg: String) -> Error {
        if self.phi_name == "phi" {
            arr_err(path, "phi", format!("element {k}: {msg}"))
        } else {
            Error::Invalid(format!(
                "{}: {} element {k}: {msg}",
                path.display(),
                self.phi_name
            ))
        }
    }

    /// Axes from checked inclinations and phi as written (checked here by
    /// [`read_phi`] under the name `phi_name`; `err(element, message)` places its error).
    fn new(
        theta_i: Vec<f64>,
        theta_r: Vec<f64>,
        phi_written: Vec<f64>,
        phi_name: &str,
        opts: &LoadOptions,
        err: impl Fn(usize, String) -> Error,
    ) -> Result<Axes> {
        let phi = phi_written
            .iter()
            .enumerate()
            .map(|(k, &v)| read_phi(phi_name, v, opts).map_err(|m| err(k, m)))
            .collect::<Result<Vec<f64>>>()?;
        Ok(Axes {
            theta_i,
            theta_r: theta_r
                .into_iter()
                .map(|t| convert_theta_r(opts, t))
                .collect(),
            phi,
            phi_written,
            phi_name: phi_name.to_string(),
        })
    }

    fn lens(&self) -> [usize; 3] {
        [self.theta_i.len(), self.theta_r.len(), self.phi.len()]
    }
}

struct Extras {
    present: Option<ArrayD<u8>>,
    sigma: Option<ArrayD<f64>>,
    phi_i: Option<ArrayD<f64>>,
}

fn grid_to_profile(
    path: &Path,
    axes: Axes,
    opts: &LoadOptions,
    value: ArrayD<f64>,
    extras: Extras,
    meta: MetaJson,
) -> Result<(Profile, Vec<String>)> {
    let shape = value.shape().to_vec();
    let (has_sigma, has_phi_i) = (extras.sigma.is_some(), extras.phi_i.is_some());
    let lens = axes.lens();
    if !(shape.len() == 3 || shape.len() == 4) || shape[..3] != lens {
        return Err(arr_err(
            path,
            "value",
            format!(
                "wrong shape {shape:?}: expected [theta_i, theta_r, phi] = {lens:?} (optionally with a trailing channel axis)"
            ),
        ));
    }
    let nc = if shape.len() == 4 { shape[3] } else { 1 };
    if nc == 0 {
        return Err(arr_err(path, "value", "channel axis has length 0"));
    }
    for (name, s) in [
        ("present", extras.present.as_ref().map(|a| a.shape())),
        ("sigma", extras.sigma.as_ref().map(|a| a.shape())),
        ("phi_i", extras.phi_i.as_ref().map(|a| a.shape())),
    ] {
        if let Some(s) = s {
            if s != shape.as_slice() {
                return Err(arr_err(
                    path,
                    name,
                    format!("wrong shape {s:?}: must match value's shape {shape:?}"),
                ));
            }
        }
    }
    for (k, name) in meta.channels.iter().enumerate() {
        check_channel_name(name)
            .map_err(|m| arr_err(path, "meta_json", format!("channels[{k}]: {m}")))?;
        if let Some(j) = meta.channels[..k].iter().position(|c| c == name) {
            return Err(arr_err(
                path,
                "meta_json",
                format!("channels[{k}] {} repeats channels[{j}]", quoted(name)),
            ));
        }
    }
    let channels = if shape.len() == 4 {
        if meta.channels.is_empty() && nc == 1 {
            // A trailing singleton axis is one unnamed channel, as for a 3-D `value`.
            Vec::new()
        } else if meta.channels.is_empty() {
            (0..nc).map(|c| c.to_string()).collect()
        } else if meta.channels.len() == nc {
            meta.channels
        } else {
            return Err(arr_err(
                path,
                "meta_json",
                format!(
                    "{} channel names for a channel axis of length {nc}",
                    meta.channels.len()
                ),
            ));
        }
    } else if meta.channels.len() <= 1 {
        meta.channels
    } else {
        return Err(arr_err(
            path,
            "meta_json",
            format!(
                "{} channel names but value is 3-D (one channel)",
                meta.channels.len()
            ),
        ));
    };
    let mut samples = Vec::new();
    let mut cells: Vec<[usize; 4]> = Vec::new();
    let opt = |a: &Option<ArrayD<f64>>, ix: &IxDyn| -> Option<f64> {
        a.as_ref().map(|a| a[ix]).filter(|v| !v.is_nan())
    };
    for (i, &theta_i) in axes.theta_i.iter().enumerate() {
        for (r, &theta_r) in axes.theta_r.iter().enumerate() {
            for (p, &phi) in axes.phi.iter().enumerate() {
                for c in 0..nc {
                    let ix = if shape.len() == 4 {
                        IxDyn(&[i, r, p, c])
                    } else {
                        IxDyn(&[i, r, p])
                    };
                    let v = value[&ix];
                    let here = match &extras.present {
                        Some(m) => m[&ix] != 0,
                        None => !v.is_nan(),
                    };
                    if !here {
                        continue;
                    }
                    let sigma = opt(&extras.sigma, &ix);
                    let phi_i = opt(&extras.phi_i, &ix);
                    check_measured(v, sigma, phi_i).map_err(|(field, msg)| {
                        arr_err(
                            path,
                            field.name(),
                            format!(
                                "index {:?} (theta_i {theta_i}, theta_r {theta_r}, phi {phi}): {msg}",
                                ix.slice()
                            ),
                        )
                    })?;
                    samples.push(Sample {
                        theta_i,
                        theta_r,
                        phi,
                        value: v,
                        sigma,
                        channel: c,
                        phi_i,
                        // Row-major over `value` (a 3-D one has nc = 1, c = 0).
                        origin: Origin::at_cell(((i * lens[1] + r) * lens[2] + p) * nc + c),
                    });
                    cells.push([i, r, p, c]);
                }
            }
        }
    }
    if samples.is_empty() {
        return Err(arr_err(
            path,
            "value",
            "no samples (every cell is NaN or marked absent)",
        ));
    }
    // As many indices as `value` has axes.
    let cell = |k: usize| format!("{:?}", &cells[k][..shape.len()]);
    let raw_phi: Vec<f64> = cells.iter().map(|c| axes.phi_written[c[2]]).collect();
    let what = "grid cell(s) repeating a direction with identical data";
    let notes = dedupe_notes(&mut samples, &channels, &raw_phi, what, |c| {
        let (pa, pb) = (cells[c.first][2], cells[c.repeat][2]);
        let pair = format!(" in cells {} and {}", cell(c.first), cell(c.repeat));
        let first_at = format!("element {pa}");
        let (wa, wb) = (axes.phi_written[pa], axes.phi_written[pb]);
        match wrap_conflict(wa, wb, &first_at, &c, &pair, opts) {
            Some(m) => axes.phi_err(path, pb, m),
            None => arr_err(
                path,
                c.field.name(),
                format!(
                    "{}: cells {} and {}",
                    c.what(),
                    cell(c.first),
                    cell(c.repeat)
                ),
            ),
        }
    })?;
    Ok((
        Profile {
            samples,
            channels,
            metadata: meta.metadata,
            source: Some(path.to_path_buf()),
            files: vec![path.to_path_buf()],
            layouts: vec![Layout::Grid {
                shape,
                sigma: has_sigma,
                phi_i: has_phi_i,
            }],
        },
        notes,
    ))
}

/// Sorted distinct values of one angle over the samples.
fn axis_of(profile: &Profile, get: impl Fn(&Sample) -> f64) -> Result<Vec<f64>> {
    let mut v: Vec<f64> = Vec::with_capacity(profile.samples.len());
    for s in &profile.samples {
        let a = get(s);
        if !a.is_finite() {
            return Err(Error::Invalid(format!(
                "cannot write npz: a sample has a non-finite angle ({a})"
            )));
        }
        v.push(a + 0.0);
    }
    v.sort_by(f64::total_cmp);
    v.dedup_by(|a, b| a.to_bits() == b.to_bits());
    Ok(v)
}

/// Encode a profile as a furfit `.npz` (see the module doc); uncompressed, with fixed zip
/// timestamps, so the same profile always gives the same bytes.
pub fn to_bytes(profile: &Profile) -> Result<Vec<u8>> {
    let ax = [
        axis_of(profile, |s| s.theta_i)?,
        axis_of(profile, |s| s.theta_r)?,
        axis_of(profile, |s| s.phi)?,
    ];
    let nc = profile.n_channels();
    let four = !profile.channels.is_empty();
    let mut shape = vec![ax[0].len(), ax[1].len(), ax[2].len()];
    if four {
        shape.push(nc);
    }
    let cells = shape
        .iter()
        .try_fold(1usize, |a, &n| a.checked_mul(n))
        .filter(|n| *n <= MAX_WRITE_CELLS)
        .ok_or_else(|| {
            Error::Invalid(format!(
                "grid {shape:?} too large for npz (limit {MAX_WRITE_CELLS} cells); save as .csv"
            ))
        })?;
    let _ = cells;
    let mut value = ArrayD::<f64>::from_elem(IxDyn(&shape), f64::NAN);
    let mut present = ArrayD::<u8>::zeros(IxDyn(&shape));
    let mut sigma = ArrayD::<f64>::from_elem(IxDyn(&shape), f64::NAN);
    let mut phi_i = ArrayD::<f64>::from_elem(IxDyn(&shape), f64::NAN);
    let find = |a: &[f64], v: f64| a.binary_search_by(|x| x.total_cmp(&(v + 0.0))).unwrap_or(0);
    for s in &profile.samples {
        if s.channel >= nc {
            return Err(Error::Invalid(format!(
                "cannot write npz: sample channel {} out of range ({nc} channels)",
                s.channel
            )));
        }
        let mut ix = vec![
            find(&ax[0], s.theta_i),
            find(&ax[1], s.theta_r),
            find(&ax[2], s.phi),
        ];
        if four {
            ix.push(s.channel);
        }
        let ix = IxDyn(&ix);
        if present[&ix] != 0 {
            return Err(Error::Invalid(format!(
                "cannot write npz: two samples share the grid cell theta_i {}, theta_r {}, phi {}{}",
                s.theta_i,
                s.theta_r,
                s.phi,
                // By name, as a loader's duplicate error names it.
                profile
                    .channels
                    .get(s.channel)
                    .map(|n| format!(", channel {n}"))
                    .unwrap_or_default()
            )));
        }
        present[&ix] = 1;
        value[&ix] = s.value;
        if let Some(x) = s.sigma {
            sigma[&ix] = x;
        }
        if let Some(x) = s.phi_i {
            phi_i[&ix] = x;
        }
    }
    let meta = serde_json::json!({
        "metadata": profile.metadata,
        "channels": profile.channels,
    });
    let meta = serde_json::to_vec(&meta)
        .map_err(|e| Error::Invalid(format!("cannot encode npz metadata: {e}")))?;
    let werr = |e: ndarray_npy::WriteNpzError| Error::Invalid(format!("writing npz: {e}"));
    let mut w = NpzWriter::new(Cursor::new(Vec::new()));
    for (name, a) in [("theta_i", &ax[0]), ("theta_r", &ax[1]), ("phi", &ax[2])] {
        w.add_array(name, &ndarray::Array1::from(a.clone()))
            .map_err(werr)?;
    }
    w.add_array("value", &value).map_err(werr)?;
    w.add_array("present", &present).map_err(werr)?;
    if profile.samples.iter().any(|s| s.sigma.is_some()) {
        w.add_array("sigma", &sigma).map_err(werr)?;
    }
    if profile.samples.iter().any(|s| s.phi_i.is_some()) {
        w.add_array("phi_i", &phi_i).map_err(werr)?;
    }
    w.add_array("meta_json", &ndarray::Array1::from(meta))
        .map_err(werr)?;
    Ok(w.finish().map_err(werr)?.into_inner())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(ti: f64, tr: f64, phi: f64, value: f64) -> Sample {
        Sample::new(ti, tr, phi, value)
    }

    /// A version-1.0 `.npy` header holding the dict `text`, padded as NumPy pads it (no
    /// data after it).
    fn npy_header_bytes(text: &str) -> Vec<u8> {
        let mut hdr = b"\x93NUMPY\x01\x00".to_vec();
        let pad = 64 - (hdr.len() + 2 + text.len() + 1) % 64;
        let text = format!("{text}{}\n", " ".repeat(pad));
        hdr.extend((text.len() as u16).to_le_bytes());
        hdr.extend(text.as_bytes());
        hdr
    }

    /// Two samples in one cell name the channel as the profile does (`g`, not index 1).
    #[test]
    fn writing_a_shared_cell_names_the_channel() {
        let mut g = [sample(0.0, 10.0, 5.0, 1.0), sample(0.0, 10.0, 5.0, 2.0)];
        for s in &mut g {
            s.channel = 1;
        }
        let p = Profile {
            samples: [vec![sample(0.0, 10.0, 5.0, 1.0)], g.to_vec()].concat(),
            channels: vec!["r".into(), "g".into()],
            ..Default::default()
        };
        let e = to_bytes(&p).unwrap_err().to_string();
        assert!(
            e.ends_with("share the grid cell theta_i 0, theta_r 10, phi 5, channel g"),
            "{e}"
        );
    }

    #[test]
    fn round_trip_keeps_invalid_values_and_sparsity() {
        let mut p = Profile {
            samples: vec![
                sample(0.0, -10.0, 0.0, 1.5),
                sample(0.0, 10.0, 90.0, -2.0),
                sample(30.0, 10.0, 180.0, f64::NAN),
            ],
            ..Default::default()
        };
        p.samples[1].sigma = Some(0.25);
        p.metadata.push(("species".into(), "test".into()));
        let bytes = to_bytes(&p).unwrap();
        let (back, notes) = parse_npz(&bytes, Path::new("x.npz")).unwrap();
        assert!(notes.is_empty());
        assert_eq!(back.samples.len(), 3);
        assert_eq!(back.samples[1].value, -2.0);
        assert_eq!(back.samples[1].sigma, Some(0.25));
        assert!(back.samples[2].value.is_nan());
        assert_eq!(back.metadata, p.metadata);
        // Deterministic bytes.
        assert_eq!(to_bytes(&back).unwrap(), bytes);
    }

    /// A complex array and a truncated header are named as such (they were reported as
    /// "truncated or corrupt" and "bad magic bytes").
    #[test]
    fn complex_dtype_and_truncated_header_are_named() {
        let mut hdr =
            npy_header_bytes("{'descr': '<c16', 'fortran_order': False, 'shape': (2,), }");
        hdr.extend([0u8; 32]);
        let e = npy_header(&hdr).unwrap_err();
        assert!(e.contains("unsupported dtype '<c16'"), "{e}");
        let e = npy_header(b"\x93NUMPY\x01").unwrap_err();
        assert!(e.contains("truncated"), "{e}");
        assert!(npy_header(b"PK\x03\x04 not npy")
            .unwrap_err()
            .contains("magic"));
    }

    /// A grid past the cell limit is refused from its header alone (the shape is
    /// claimed, no data follow: nothing is decoded or allocated).
    #[test]
    fn huge_value_array_is_refused_from_its_header() {
        let hdr = npy_header_bytes(
            "{'descr': '<f8', 'fortran_order': False, 'shape': (10, 2000, 1001), }",
        );
        let e = read_float(&hdr, Path::new("big.npy"), "value")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("value") && e.contains("[10, 2000, 1001]") && e.contains("20000000"),
            "{e}"
        );
    }

    #[test]
    fn integer_axes_are_read_as_degrees() {
        let mut w = NpzWriter::new(Cursor::new(Vec::new()));
        w.add_array("theta_i", &ndarray::arr1(&[0i64, 30])).unwrap();
        w.add_array("theta_r", &ndarray::arr1(&[-10i32])).unwrap();
        w.add_array("phi", &ndarray::arr1(&[0u16, 90, 180]))
            .unwrap();
        w.add_array("value", &ArrayD::<f64>::from_elem(IxDyn(&[2, 1, 3]), 1.0))
            .unwrap();
        let bytes = w.finish().unwrap().into_inner();
        let (p, _) = parse_npz(&bytes, Path::new("i.npz")).unwrap();
        assert_eq!(p.samples.len(), 6);
        assert_eq!(
            (p.samples[5].theta_i, p.samples[5].theta_r, p.samples[5].phi),
            (30.0, -10.0, 180.0)
        );
        // Other dtypes keep their clear error.
        let mut w = NpzWriter::new(Cursor::new(Vec::new()));
        w.add_array("theta_i", &ndarray::arr1(&[true])).unwrap();
        w.add_array("theta_r", &ndarray::arr1(&[0.0])).unwrap();
        w.add_array("phi", &ndarray::arr1(&[0.0])).unwrap();
        w.add_array("value", &ArrayD::<f64>::from_elem(IxDyn(&[1, 1, 1]), 1.0))
            .unwrap();
        let bytes = w.finish().unwrap().into_inner();
        let e = parse_npz(&bytes, Path::new("b.npz"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("'theta_i'") && e.contains("wrong dtype"), "{e}");
    }

    /// An archive of `value` (shape `shape`, filled by `f(flat index)`) over the axes given.
    fn archive(
        ti: &[f64],
        tr: &[f64],
        phi: &[f64],
        shape: &[usize],
        f: impl Fn(usize) -> f64,
    ) -> Vec<u8> {
        let mut w = NpzWriter::new(Cursor::new(Vec::new()));
        w.add_array("theta_i", &ndarray::arr1(ti)).unwrap();
        w.add_array("theta_r", &ndarray::arr1(tr)).unwrap();
        w.add_array("phi", &ndarray::arr1(phi)).unwrap();
        let n: usize = shape.iter().product();
        let v = ArrayD::from_shape_vec(IxDyn(shape), (0..n).map(f).collect()).unwrap();
        w.add_array("value", &v).unwrap();
        w.finish().unwrap().into_inner()
    }

    /// Every sample of a multi-channel grid is named by its own cell, channel included
    /// (messages about a sample, such as a merge's duplicate or a weighted fit's worst
    /// residual, send the user to that cell): the cell a sample's origin names holds that
    /// sample's value.
    #[test]
    fn each_sample_is_named_by_its_own_cell() {
        let shape = [2, 2, 3, 2];
        let bytes = archive(
            &[0.0, 30.0],
            &[-10.0, 10.0],
            &[0.0, 5.0, 10.0],
            &shape,
            |k| 1.0 + k as f64,
        );
        let (p, _) = parse_npz(&bytes, Path::new("a.npz")).unwrap();
        assert_eq!(p.samples.len(), 24);
        for s in &p.samples {
            // Value 1 + k sits at row-major index k.
            let k = s.value as usize - 1;
            let ix = [k / 12, k / 6 % 2, k / 2 % 3, k % 2];
            assert_eq!(p.origin_of(s).unwrap(), format!("a.npz index {ix:?}"));
        }
    }

    /// `present` holds only 1 (a sample) and 0 (none): a 2 is an error naming the array,
    /// the first such cell (in index order) and the value, not a silent "present".
    #[test]
    fn present_other_than_0_or_1_is_an_error() {
        let with_present = |mask: &[u8]| {
            let mut w = NpzWriter::new(Cursor::new(Vec::new()));
            w.add_array("theta_i", &ndarray::arr1(&[0.0])).unwrap();
            w.add_array("theta_r", &ndarray::arr1(&[10.0, 20.0]))
                .unwrap();
            w.add_array("phi", &ndarray::arr1(&[0.0, 5.0])).unwrap();
            let shape = IxDyn(&[1, 2, 2]);
            let v = ArrayD::from_shape_vec(shape.clone(), vec![1.0; 4]).unwrap();
            w.add_array("value", &v).unwrap();
            let m = ArrayD::from_shape_vec(shape, mask.to_vec()).unwrap();
            w.add_array("present", &m).unwrap();
            parse_npz(&w.finish().unwrap().into_inner(), Path::new("m.npz"))
        };
        let e = with_present(&[1, 0, 2, 255]).unwrap_err().to_string();
        assert_eq!(
            e,
            "m.npz: array 'present': index [0, 1, 0]: 2 is neither 1 (a sample) nor 0 (none)"
        );
        let (p, _) = with_present(&[1, 0, 0, 1]).unwrap();
        assert_eq!(p.samples.len(), 2);
    }

    /// `np.arange(0, 360, 5.)` as the phi axis reads (element 37, 185, was "out of
    /// range"), wrapped to (-180, 180]; the offset applies before the wrap.
    #[test]
    fn phi_axis_in_0_360_reads_wrapped() {
        let phi: Vec<f64> = (0..72).map(|k| 5.0 * k as f64).collect();
        let bytes = archive(&[0.0], &[10.0], &phi, &[1, 1, 72], |_| 1.0);
        let (p, notes) = parse_npz(&bytes, Path::new("a.npz")).unwrap();
        assert!(notes.is_empty(), "{notes:?}");
        assert_eq!(p.samples.len(), 72);
        assert_eq!(p.samples[37].phi, -175.0);
        assert_eq!(p.samples[36].phi, 180.0);
        let opts = LoadOptions {
            phi_offset: -180.0,
            ..Default::default()
        };
        let (p, _) = parse_npz_with(&bytes, Path::new("a.npz"), &opts).unwrap();
        assert_eq!((p.samples[0].phi, p.samples[37].phi), (180.0, 5.0));
        let bytes = archive(&[0.0], &[10.0], &[0.0, 400.0], &[1, 1, 2], |_| 1.0);
        let e = parse_npz(&bytes, Path::new("a.npz"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("array 'phi': element 1: phi = 400 deg is out of range [-360, 360]"),
            "{e}"
        );
    }

    /// A phi axis holding 0 and 360 with different data: named on the `phi` array as a
    /// wrap, with as many cell indices as `value` has axes (a 3-D array got 4).
    #[test]
    fn wrap_and_duplicate_cells_are_named_with_value_s_rank() {
        let bytes = archive(&[0.0], &[10.0], &[0.0, 180.0, 360.0], &[1, 1, 3], |k| {
            1.0 + k as f64
        });
        let e = parse_npz(&bytes, Path::new("w.npz"))
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "w.npz: array 'phi': element 2: phi 360 wraps to 0, which element 0 already holds \
             with a different value (1 vs 3) in cells [0, 0, 0] and [0, 0, 2]; drop one of \
             the two endpoint measurements"
        );
        // A repeated theta_r (not a wrap) keeps the value array's message, 3 indices.
        let bytes = archive(&[0.0], &[10.0, 10.0], &[0.0], &[1, 2, 1], |k| {
            1.0 + k as f64
        });
        let e = parse_npz(&bytes, Path::new("w.npz"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("array 'value': duplicate sample")
                && e.ends_with("cells [0, 0, 0] and [0, 1, 0]"),
            "{e}"
        );
        // 4-D: four indices.
        let bytes = archive(&[0.0], &[10.0, 10.0], &[0.0], &[1, 2, 1, 2], |k| {
            1.0 + k as f64
        });
        let e = parse_npz(&bytes, Path::new("w.npz"))
            .unwrap_err()
            .to_string();
        assert!(e.ends_with("cells [0, 0, 0, 0] and [0, 1, 0, 0]"), "{e}");
        // Identical cells collapse; the note gives the axis's own wrapped pair as example.
        let bytes = archive(&[0.0], &[10.0], &[0.0, 180.0, 360.0], &[1, 1, 3], |k| {
            [1.0, 2.0, 1.0][k]
        });
        let (p, notes) = parse_npz(&bytes, Path::new("w.npz")).unwrap();
        assert_eq!(p.samples.len(), 2);
        assert!(notes[0].contains("e.g. 0 and 360"), "{notes:?}");
    }

    /// NumPy's trailing singleton channel axis (`[I, R, P, 1]`) without names is one
    /// unnamed channel, as the same data shaped `[I, R, P]` (it was named "0", and merging
    /// the two forms was refused).
    #[test]
    fn singleton_channel_axis_is_unnamed() {
        let four = archive(&[0.0], &[10.0], &[0.0, 5.0], &[1, 1, 2, 1], |_| 1.0);
        let three = archive(&[0.0], &[10.0], &[10.0, 15.0], &[1, 1, 2], |_| 1.0);
        let (a, _) = parse_npz(&four, Path::new("a.npz")).unwrap();
        let (b, _) = parse_npz(&three, Path::new("b.npz")).unwrap();
        assert!(a.channels.is_empty(), "{:?}", a.channels);
        let (m, _) = super::super::merge(vec![a, b]).unwrap();
        assert_eq!((m.samples.len(), m.channels.len()), (4, 0));
        // Two unnamed channels are still numbered.
        let two = archive(&[0.0], &[10.0], &[0.0], &[1, 1, 1, 2], |_| 1.0);
        let (c, _) = parse_npz(&two, Path::new("c.npz")).unwrap();
        assert_eq!(c.channels, vec!["0".to_string(), "1".to_string()]);
    }

    #[test]
    fn header_check_catches_truncation() {
        let mut w = Vec::new();
        ndarray_npy::WriteNpyExt::write_npy(&ndarray::Array1::<f64>::zeros(4), &mut w).unwrap();
        assert!(npy_header(&w).is_ok());
        let e = npy_header(&w[..w.len() - 3]).unwrap_err();
        assert!(e.contains("truncated"), "{e}");
    }

    /// An archive member that inflates past the size its header declares (a small zip
    /// bomb) is refused once that size is passed, not decompressed whole.
    #[test]
    fn member_longer_than_its_header_is_refused_at_the_declared_size() {
        let npy = |a: ArrayD<f64>| {
            let mut w = Vec::new();
            ndarray_npy::WriteNpyExt::write_npy(&a, &mut w).unwrap();
            w
        };
        let axis = |n: usize| npy(ArrayD::from_shape_fn(IxDyn(&[n]), |i| i[0] as f64));
        let mut value = npy(ArrayD::from_elem(IxDyn(&[2, 3, 4]), 1.0));
        value.extend(std::iter::repeat_n(0u8, 8 << 20));
        let members = [
            ("theta_i.npy", axis(2)),
            ("theta_r.npy", axis(3)),
            ("phi.npy", axis(4)),
            ("value.npy", value),
        ];
        let bytes = zip_of(&members);
        assert!(bytes.len() < 100_000, "{} bytes", bytes.len());
        let e = parse_npz(&bytes, Path::new("bomb.npz"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("'value'") && e.contains("(192 bytes) but more follow"),
            "{e}"
        );
        // A dtype whose size the header does not state plainly is read whole (within the
        // limit) for its reader to name: np.array(s) as meta_json gets the how-to, not
        // "corrupt".
        let mut members = members.to_vec();
        members[3].1 = npy(ArrayD::from_elem(IxDyn(&[2, 3, 4]), 1.0));
        let mut text = npy_header_bytes("{'descr': '<U2', 'fortran_order': False, 'shape': (), }");
        text.extend([b'{', 0, 0, 0, b'}', 0, 0, 0]);
        members.push(("meta_json.npy", text));
        let e = parse_npz(&zip_of(&members), Path::new("m.npz"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("array 'meta_json': dtype '<U2': meta_json must be"),
            "{e}"
        );
        // Nor is a string member decompressed past its header: its dtype is refused there.
        let mut strings =
            npy_header_bytes("{'descr': '<U1', 'fortran_order': False, 'shape': (2, 3, 4), }");
        strings.extend(std::iter::repeat_n(0u8, 8 << 20));
        members[3].1 = strings;
        let e = parse_npz(&zip_of(&members[..4]), Path::new("s.npz"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("array 'value': unsupported dtype '<U1'"), "{e}");
        // Two members of one array are refused, not one of them taken.
        let twice = [members[3].clone(), ("value", members[3].1.clone())];
        let e = parse_npz(&zip_of(&twice), Path::new("two.npz"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("holds array 'value' twice"), "{e}");
    }

    /// A deflated zip of the named members.
    fn zip_of(members: &[(&str, Vec<u8>)]) -> Vec<u8> {
        use std::io::Write;
        let mut z = zip::ZipWriter::new(Cursor::new(Vec::new()));
        let opt = zip::write::SimpleFileOptions::default()
            .compression_method(zip::CompressionMethod::Deflated);
        for (name, bytes) in members {
            z.start_file(*name, opt).unwrap();
            z.write_all(bytes).unwrap();
        }
        z.finish().unwrap().into_inner()
    }

    /// A bool mask holding a byte other than 0 or 1 reads as that byte, so the caller names
    /// its cell (the bool reader failed without an index).
    #[test]
    fn bool_mask_keeps_a_stray_byte_for_the_cell_check() {
        let a = ArrayD::<bool>::from_elem(IxDyn(&[1, 2, 2]), true);
        let mut w = Vec::new();
        ndarray_npy::WriteNpyExt::write_npy(&a, &mut w).unwrap();
        let last = w.len() - 1;
        w[last] = 2;
        let m = read_bytes_array(&w, Path::new("x.npz"), "present").unwrap();
        assert_eq!(m.as_slice().unwrap(), &[1, 1, 1, 2]);
    }

    #[test]
    fn lone_npy_needs_axes() {
        let mut w = Vec::new();
        let a = ArrayD::<f64>::from_elem(IxDyn(&[1, 2, 3]), 1.0);
        ndarray_npy::WriteNpyExt::write_npy(&a, &mut w).unwrap();
        let path = Path::new("v.npy");
        let e = parse_npy(&w, path, &LoadOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("v.npy") && e.contains("--theta-i"), "{e}");
        let opts = LoadOptions {
            theta_i: Some(vec![0.0]),
            theta_r: Some(vec![0.0, 10.0]),
            phi: Some(vec![0.0, 90.0, -180.0]),
            ..Default::default()
        };
        let (p, _) = parse_npy(&w, path, &opts).unwrap();
        assert_eq!(p.samples.len(), 6);
        assert_eq!(p.samples[2].phi, 180.0);
        let bad = LoadOptions {
            phi: Some(vec![0.0, 90.0]),
            ..opts.clone()
        };
        let e = parse_npy(&w, path, &bad).unwrap_err().to_string();
        assert!(e.contains("'value'") && e.contains("wrong shape"), "{e}");
        // A wrap clash among --phi values is placed on --phi (the file has no phi array).
        let mut w4 = Vec::new();
        let a = ArrayD::<f64>::from_shape_vec(IxDyn(&[1, 1, 4]), vec![1.0, 2.0, 3.0, 4.0]).unwrap();
        ndarray_npy::WriteNpyExt::write_npy(&a, &mut w4).unwrap();
        let wraps = LoadOptions {
            theta_r: Some(vec![0.0]),
            phi: Some(vec![0.0, 90.0, 180.0, 360.0]),
            ..opts
        };
        let e = parse_npy(&w4, path, &wraps).unwrap_err().to_string();
        assert!(
            e.starts_with("v.npy: --phi element 3: phi 360 wraps to 0"),
            "{e}"
        );
    }

    /// A float32 axis reads as the decimals it was written for (0.1f32 widened is
    /// 0.10000000149011612): the same grid in a CSV is then the same directions, so the two
    /// merge into one sample per direction, not two, and a different value is a conflict.
    #[test]
    fn float32_axes_read_as_their_shortest_decimal() {
        let mut w = NpzWriter::new(Cursor::new(Vec::new()));
        w.add_array("theta_i", &ndarray::arr1(&[0.1f32, 30.0]))
            .unwrap();
        w.add_array("theta_r", &ndarray::arr1(&[-59.9f32, 60.1]))
            .unwrap();
        w.add_array("phi", &ndarray::arr1(&[-0.3f32, 179.9]))
            .unwrap();
        let v = ArrayD::from_shape_vec(IxDyn(&[2, 2, 2]), (1..=8).map(f64::from).collect());
        w.add_array("value", &v.unwrap()).unwrap();
        let bytes = w.finish().unwrap().into_inner();
        let (p, _) = parse_npz(&bytes, Path::new("f.npz")).unwrap();
        let s = &p.samples[7];
        assert_eq!((s.theta_i, s.theta_r, s.phi), (30.0, 60.1, 179.9));
        let s = &p.samples[0];
        assert_eq!((s.theta_i, s.theta_r, s.phi), (0.1, -59.9, -0.3));
        // The same grid as a lab writes it, in decimals.
        let mut csv = String::from("theta_i,theta_r,phi,value\n");
        let mut v = 0;
        for ti in ["0.1", "30"] {
            for tr in ["-59.9", "60.1"] {
                for ph in ["-0.3", "179.9"] {
                    v += 1;
                    csv.push_str(&format!("{ti},{tr},{ph},{v}\n"));
                }
            }
        }
        let (c, _) = super::super::csv::parse(csv.as_bytes(), Path::new("f.csv")).unwrap();
        let (m, collapsed) = super::super::merge(vec![p, c]).unwrap();
        assert_eq!((m.samples.len(), collapsed), (8, 8));
        // Values are data, not a grid: widened exactly.
        let mut w = NpzWriter::new(Cursor::new(Vec::new()));
        w.add_array("theta_i", &ndarray::arr1(&[0.0])).unwrap();
        w.add_array("theta_r", &ndarray::arr1(&[0.0])).unwrap();
        w.add_array("phi", &ndarray::arr1(&[0.0])).unwrap();
        w.add_array("value", &ArrayD::from_elem(IxDyn(&[1, 1, 1]), 0.1f32))
            .unwrap();
        let (p, _) = parse_npz(&w.finish().unwrap().into_inner(), Path::new("v.npz")).unwrap();
        assert_eq!(p.samples[0].value, f64::from(0.1f32));
    }

    /// meta_json written as a NumPy string (`np.array(s)`) or another integer type says
    /// how to write it (it said "profile arrays are float, integer or bool" / "expected
    /// uint8 (or bool)").
    #[test]
    fn meta_json_of_the_wrong_dtype_says_how_to_write_it() {
        let how = "meta_json must be the UTF-8 bytes of a JSON text as a uint8 array, e.g. \
                   np.frombuffer(s.encode(), np.uint8)";
        // A 0-d '<U2' array: 2 UCS-4 characters, 8 bytes.
        let mut text = npy_header_bytes("{'descr': '<U2', 'fortran_order': False, 'shape': (), }");
        text.extend([b'{', 0, 0, 0, b'}', 0, 0, 0]);
        let e = read_meta_json(&text, Path::new("m.npz"))
            .unwrap_err()
            .to_string();
        assert_eq!(e, format!("m.npz: array 'meta_json': dtype '<U2': {how}"));
        let mut int8 =
            npy_header_bytes("{'descr': '|i1', 'fortran_order': False, 'shape': (2,), }");
        int8.extend(b"{}");
        let e = read_meta_json(&int8, Path::new("m.npz"))
            .unwrap_err()
            .to_string();
        assert!(e.ends_with(&format!("dtype '|i1': {how}")), "{e}");
        let mut ok = npy_header_bytes("{'descr': '|u1', 'fortran_order': False, 'shape': (2,), }");
        ok.extend(b"{}");
        assert_eq!(read_meta_json(&ok, Path::new("m.npz")).unwrap().len(), 2);
    }
}
