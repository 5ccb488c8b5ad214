//! The static page `furfit view --out DIR` writes: `index.html`, `viewer.js` (raw
//! WebGL2, no library: the whole renderer is ~300 lines, and a page with no dependency
//! works from `file://` and offline), `data.js` (sizes, scales, lights, each species'
//! BCSDF matrices) and `textures.js` (the packed shell and fin textures, base64). Data travel as
//! scripts, not as fetched files, because Chromium refuses `fetch` from `file://`.

use super::pack::Packed;
use super::sh::Rule;
use super::still::EXTENT;
use super::{lights, target, View, ViewData};
use crate::io;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};

const INDEX: &str = include_str!("web/index.html");
const VIEWER: &str = include_str!("web/viewer.js");

/// The files a view consists of.
pub const FILES: [&str; 4] = ["index.html", "viewer.js", "data.js", "textures.js"];

/// Standard base64 (RFC 4648) of `bytes`.
pub fn base64(bytes: &[u8]) -> String {
    const T: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for c in bytes.chunks(3) {
        let n = (c[0] as u32) << 16
            | (*c.get(1).unwrap_or(&0) as u32) << 8
            | *c.get(2).unwrap_or(&0) as u32;
        for i in 0..4 {
            if i <= c.len() {
                out.push(T[(n >> (18 - 6 * i) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

fn f32_base64(v: &[f32]) -> String {
    let bytes: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
    base64(&bytes)
}

/// The page's data object.
pub fn data_json(data: &ViewData, view: &View) -> Value {
    let rot = Rule::rotation();
    let p: &Packed = &data.packed;
    let f = &data.fur;
    json!({
        "version": 1,
        "res": p.res,
        "shells": p.shells,
        "shell_y": (0..f.shells).map(|s| f.shell_y(s)).collect::<Vec<_>>(),
        "extent": EXTENT,
        "comb": [f.comb().x, f.comb().y, f.comb().z],
        "target": [target(f).x, target(f).y, target(f).z],
        "rot_rule": {"dirs": rot.dirs, "weights": rot.weights},
        "height": f.height(),
        "dy": f.dy(),
        "fins": {"rows": data.fin_rows, "depth": super::fins::DEPTH,
                 "walls": super::fins::WALLS.iter().map(|w| json!({"axis": w.axis, "c": w.c, "sign": w.sign})).collect::<Vec<_>>()},
        "slant_min_cos": super::still::SLANT_MIN_COS,
        "scale": p.scale,
        "offset": p.offset,
        "lights": lights::LIGHTS.iter().map(|l| json!({
            "name": l.name, "label": l.label, "coeffs": l.canonical(),
            "elev": l.default_elev, "azim": l.default_azim,
        })).collect::<Vec<_>>(),
        "species": data.species.iter().map(|s| json!({
            "name": s.name, "model": s.model, "title": s.title, "params": s.params,
            "colour": s.colour, "n_o": s.table.n_o, "m": f32_base64(&s.table.m),
        })).collect::<Vec<_>>(),
        "view": {"dist": view.dist, "elev": view.elev_deg, "azim": view.azim_deg,
                 "fov": view.fov_deg, "exposure": view.exposure_ev},
        "fur": {"fibers": f.fibers, "length": f.length, "radius": f.radius, "curl": f.curl,
                "tilt_deg": f.tilt_deg, "spread_deg": f.spread_deg, "seed": f.seed},
    })
}

/// Refuse an `--out` that holds anything but an earlier view's files (as furfit wrote
/// them), unless `force`.
pub fn check_out(dir: &Path, force: bool) -> crate::Result<()> {
    io::check_out_dir(dir)?;
    if force || !dir.exists() {
        return Ok(());
    }
    let rd = std::fs::read_dir(dir).map_err(|e| crate::Error::io(dir, e))?;
    let mut ours = Vec::new();
    for e in rd {
        let e = e.map_err(|e| crate::Error::io(dir, e))?;
        let name = e.file_name().to_string_lossy().into_owned();
        if name == io::LEDGER || name == io::LEDGER_LOCK {
            continue;
        }
        if !FILES.contains(&name.as_str()) {
            return Err(crate::Error::file(
                e.path(),
                format!(
                    "{} holds files other than an earlier view's; give --force to write the view there anyway, or choose another --out",
                    dir.display()
                ),
            ));
        }
        ours.push(e.path());
    }
    io::check_replaceable(&ours, false)
}

/// Write the page into `dir` (one group write: all files land or none).
pub fn write(dir: &Path, data: &ViewData, view: &View) -> crate::Result<Vec<PathBuf>> {
    let js = format!("window.FURFIT = {};\n", data_json(data, view));
    let tex = format!(
        "window.FURFIT_TEX = \"{}\";\nwindow.FURFIT_FIN = \"{}\";\n",
        base64(&data.packed.bytes),
        base64(&data.fin_bytes)
    );
    let files: Vec<(PathBuf, Vec<u8>)> = vec![
        (dir.join("index.html"), INDEX.as_bytes().to_vec()),
        (dir.join("viewer.js"), VIEWER.as_bytes().to_vec()),
        (dir.join("data.js"), js.into_bytes()),
        (dir.join("textures.js"), tex.into_bytes()),
    ];
    std::fs::create_dir_all(dir).map_err(|e| crate::Error::io(dir, e))?;
    io::write_outputs(&files)?;
    Ok(files.into_iter().map(|(p, _)| p).collect())
}

#[cfg(test)]
mod tests {
    #[test]
    fn base64_matches_rfc4648_vectors() {
        for (i, o) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(super::base64(i.as_bytes()), o);
        }
    }
}
