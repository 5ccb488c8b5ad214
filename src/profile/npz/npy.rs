//! Reading NumPy arrays from an archive's bytes: each header checked against the bytes
//! present and the size limits before anything is decoded, then the typed readers (float,
//! axis, mask, `meta_json`) and the archive entries.

use crate::error::{Error, Result};
use crate::profile::checks::MAX_READ_CELLS;
use ndarray::ArrayD;
use ndarray_npy::ReadNpyExt;
use std::io::Read;
use std::path::Path;

/// Largest array (decompressed bytes) the reader accepts.
const MAX_ARRAY_BYTES: u64 = 1 << 29;
/// Largest `meta_json` (bytes of JSON text) the reader accepts.
const MAX_META_BYTES: u64 = 1 << 24;
/// Longest `.npy` header the reader accepts (numpy writes under 1 KB; version 1 allows
/// 64 KiB).
const MAX_HEADER_BYTES: u64 = 1 << 20;

/// What the `.npy` header of an array says.
#[derive(Debug)]
pub(super) struct NpyHeader {
    pub(super) descr: String,
    pub(super) shape: Vec<usize>,
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
pub(super) fn npy_header(bytes: &[u8]) -> std::result::Result<NpyHeader, String> {
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

pub(super) fn arr_err(path: &Path, array: &str, msg: impl Into<String>) -> Error {
    Error::Array {
        file: path.to_path_buf(),
        array: array.to_string(),
        msg: msg.into(),
    }
}

/// Decode a float array (float64, or float32 widened).
pub(super) fn read_float(bytes: &[u8], path: &Path, name: &str) -> Result<ArrayD<f64>> {
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
pub(super) fn read_axis(bytes: &[u8], path: &Path, name: &str) -> Result<ArrayD<f64>> {
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
pub(super) fn read_bytes_array(bytes: &[u8], path: &Path, name: &str) -> Result<ArrayD<u8>> {
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
pub(super) fn read_meta_json(bytes: &[u8], path: &Path) -> Result<ArrayD<u8>> {
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
pub(super) fn entry<R: Read + std::io::Seek>(
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
