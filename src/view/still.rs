//! `furfit view --still`: the page's picture on the CPU, through the same packed
//! textures and the same per-frame lighting, so the page can be checked against it
//! pixel by pixel. GL conventions are followed where they matter: pixel centres at
//! `+0.5`, bilinear `LINEAR` filtering with `REPEAT` wrap (texel centres at `(i + 0.5) /
//! res`), premultiplied "over" compositing back to front (back fins, shells, front fins), tone map after compositing.

use super::fins;
use super::lights::Light;
use super::pack::{Packed, ALPHA};
use super::prt::{frame_lighting, Rgb25};
use super::sh::{self, N_COEFFS};
use super::{target, View, ViewData};
use crate::render::math::V3;
use crate::render::scene::Camera;
use crate::render::Image;
use rayon::prelude::*;

pub use super::shells::EXTENT;

/// What one picture shows.
#[derive(Clone, Debug)]
pub struct Still {
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
    /// Camera and light placement.
    pub view: View,
    /// Which species of the view data, by index.
    pub species: usize,
    /// The environment light.
    pub light: Light,
    /// Show the environment behind the fur (the page does); off for the comparison with
    /// a reference that has none behind it.
    pub background: bool,
    /// Draw the fins at the swatch's borders ([`super::fins`]).
    pub fins: bool,
}

/// The camera of a view.
pub fn camera(data: &ViewData, v: &View, width: usize, height: usize) -> Camera {
    Camera::look_at(
        target(&data.fur),
        v.dist,
        v.elev_deg,
        v.azim_deg,
        v.fov_deg,
        width,
        height,
    )
}

/// World SH of the light and the per-frame lighting coefficients of a view.
pub fn lighting(
    data: &ViewData,
    species: usize,
    light: &Light,
    v: &View,
    width: usize,
    height: usize,
) -> (Rgb25, Rgb25) {
    let l = light.coeffs(v.light_elev_deg, v.light_azim_deg);
    let cam = camera(data, v, width, height);
    let wo = (cam.eye - target(&data.fur)).normalized();
    let c = frame_lighting(&data.species[species].table, &l, wo, data.fur.comb());
    (l, c)
}

/// Radiance and coverage of every texel of every shell: `[s][texel]` as `(r, g, b,
/// alpha)`, from the packed (dequantised) channels, f32 as the shader does.
pub fn texel_radiance(p: &Packed, c: &Rgb25) -> Vec<Vec<[f32; 4]>> {
    let n = p.res * p.res;
    (0..p.shells)
        .into_par_iter()
        .map(|s| {
            (0..n)
                .map(|texel| {
                    let mut out = [0.0f32; 4];
                    for k in 0..N_COEFFS {
                        let v = p.value(s, k, texel);
                        for ch in 0..3 {
                            out[ch] += c[ch][k] as f32 * v;
                        }
                    }
                    out[3] = p.value(s, ALPHA, texel);
                    out
                })
                .collect()
        })
        .collect()
}

/// Shells are seen through at a slant: the camera ray crosses a slab `1 / |d_y|` times as
/// thick as the vertical one whose coverage the texel holds, so its opacity is
/// `1 - (1 - alpha)^(1 / |d_y|)`, the transfer's own rule for light ([`super::prt::transfer`],
/// seed 003 Eq. 4). `|d_y|` is held at or above this (a slant of 10 at most).
pub const SLANT_MIN_COS: f64 = 0.1;

/// The opacity of coverage `alpha` seen at slant `slant = 1 / |d_y|`.
#[inline]
pub fn slant_alpha(alpha: f32, slant: f32) -> f32 {
    1.0 - (1.0 - alpha.clamp(0.0, 1.0)).powf(slant)
}

/// Bilinear `REPEAT` sample of a `res x res` texel grid at tile coordinates `(x, z)`.
fn sample(tex: &[[f32; 4]], res: usize, x: f64, z: f64) -> [f32; 4] {
    let (fx, fz) = (x * res as f64 - 0.5, z * res as f64 - 0.5);
    let (i0, j0) = (fx.floor(), fz.floor());
    let (ax, az) = ((fx - i0) as f32, (fz - j0) as f32);
    let r = res as i64;
    let w = |a: f64, d: i64| ((a as i64 + d).rem_euclid(r)) as usize;
    let t = |i: usize, j: usize| tex[j * res + i];
    let (i0u, i1u, j0u, j1u) = (w(i0, 0), w(i0, 1), w(j0, 0), w(j0, 1));
    let (a, b, c, d) = (t(i0u, j0u), t(i1u, j0u), t(i0u, j1u), t(i1u, j1u));
    std::array::from_fn(|k| {
        let top = a[k] + ax * (b[k] - a[k]);
        let bot = c[k] + ax * (d[k] - c[k]);
        top + az * (bot - top)
    })
}

/// The shells in drawing order (back to front) for a camera at height `eye_y`.
pub fn shell_order(data: &ViewData, eye_y: f64) -> Vec<usize> {
    let shells = data.fur.shells;
    let mut below: Vec<usize> = (0..shells)
        .filter(|&s| data.fur.shell_y(s) < eye_y)
        .collect();
    let above: Vec<usize> = (0..shells)
        .rev()
        .filter(|&s| data.fur.shell_y(s) >= eye_y)
        .collect();
    below.extend(above);
    below
}

/// The lighting coefficients at the four corners of the picture (top-left, top-right,
/// bottom-left, bottom-right), each for its own view direction (the corner pixel's ray,
/// reversed): the BCSDF depends on the view direction, which turns by the field of view
/// across the picture (24 degrees by default), so one camera-to-target direction for
/// the whole frame leaves a large-scale error (`reports/viewer/prt_error.md`). Between
/// the corners the coefficients are interpolated bilinearly in the picture, as the page
/// does per fragment.
pub fn corner_lighting(
    data: &ViewData,
    species: usize,
    light: &Light,
    v: &View,
    width: usize,
    height: usize,
) -> [Rgb25; 4] {
    let l = light.coeffs(v.light_elev_deg, v.light_azim_deg);
    let cam = camera(data, v, width, height);
    let (w, h) = (width as f64, height as f64);
    [(0.0, 0.0), (w, 0.0), (0.0, h), (w, h)].map(|(px, py)| {
        let wo = -cam.ray_dir(px, py);
        frame_lighting(&data.species[species].table, &l, wo, data.fur.comb())
    })
}

/// Render the still (linear radiance): the page's picture.
pub fn render(data: &ViewData, s: &Still) -> Image {
    let c = corner_lighting(data, s.species, &s.light, &s.view, s.width, s.height);
    let tex = c.map(|c| texel_radiance(&data.packed, &c));
    render_tex(data, s, &tex)
}

/// Bilinear weights of the four corners' lighting at pixel `(px, py)` (centres).
fn corner_weights(px: usize, py: usize, width: usize, height: usize) -> [f32; 4] {
    let sx = (px as f32 + 0.5) / width as f32;
    let sy = (py as f32 + 0.5) / height as f32;
    [
        (1.0 - sx) * (1.0 - sy),
        sx * (1.0 - sy),
        (1.0 - sx) * sy,
        sx * sy,
    ]
}

/// Radiance and coverage at tile point `(x, z)` of shell `s`: the blend of `tex`'s
/// radiance (one, or the four corners' with `wts`), the first's coverage.
fn shade(
    tex: &[Vec<Vec<[f32; 4]>>],
    wts: &[f32; 4],
    s: usize,
    res: usize,
    x: f64,
    z: f64,
) -> [f32; 4] {
    let mut t = sample(&tex[0][s], res, x, z);
    if tex.len() == 4 {
        let a = t[3];
        let ts: Vec<[f32; 4]> = (1..4).map(|q| sample(&tex[q][s], res, x, z)).collect();
        for ch in 0..3 {
            t[ch] = wts[0] * t[ch] + (0..3).map(|q| wts[q + 1] * ts[q][ch]).sum::<f32>();
        }
        t[3] = a;
    }
    t
}

/// Render the still from given texel radiance and coverage (`tex[q][shell][texel]`, as
/// [`texel_radiance`]): one set for the whole picture, or four, the corners' lighting
/// ([`corner_lighting`]) blended per pixel. The page's drawing of any transfer
/// ([`super::direct`]).
pub fn render_tex(data: &ViewData, s: &Still, tex: &[Vec<Vec<[f32; 4]>>]) -> Image {
    assert!(
        tex.len() == 1 || tex.len() == 4,
        "one texture set or four corners'"
    );
    let l = s.light.coeffs(s.view.light_elev_deg, s.view.light_azim_deg);
    let cam = camera(data, &s.view, s.width, s.height);
    let order = shell_order(data, cam.eye.y);
    let (back, front) = fins::order(cam.eye);
    let res = data.packed.res;
    let rows: Vec<Vec<[f64; 3]>> = (0..s.height)
        .into_par_iter()
        .map(|py| {
            (0..s.width)
                .map(|px| {
                    let wts = corner_weights(px, py, s.width, s.height);
                    let d = cam.ray_dir(px as f64 + 0.5, py as f64 + 0.5);
                    let slant = (1.0 / d.y.abs().max(SLANT_MIN_COS)) as f32;
                    let mut col = if s.background {
                        let y = sh::eval([d.x, d.y, d.z]);
                        [0, 1, 2]
                            .map(|ch| (0..N_COEFFS).map(|k| l[ch][k] * y[k]).sum::<f64>() as f32)
                    } else {
                        [0.0f32; 3]
                    };
                    if s.fins {
                        for &w in &back {
                            fin(data, tex, &wts, cam.eye, d, w, &mut col);
                        }
                    }
                    for &sh_i in &order {
                        if let Some(p) = hit_shell(data, cam.eye, d, sh_i) {
                            // Radiance and coverage filtered apart, then
                            // premultiplied: what the shader does with its samples.
                            let t = shade(tex, &wts, sh_i, res, p.x, p.z);
                            let a = slant_alpha(t[3], slant);
                            for ch in 0..3 {
                                col[ch] = t[ch] * a + (1.0 - a) * col[ch];
                            }
                        }
                    }
                    if s.fins {
                        for &w in &front {
                            fin(data, tex, &wts, cam.eye, d, w, &mut col);
                        }
                    }
                    col.map(|v| v as f64)
                })
                .collect()
        })
        .collect();
    Image {
        width: s.width,
        height: s.height,
        data: rows.into_iter().flatten().collect(),
    }
}

/// Where the ray from `eye` along `d` meets shell `s` inside the swatch, if it does.
fn hit_shell(data: &ViewData, eye: V3, d: V3, s: usize) -> Option<V3> {
    if d.y.abs() < 1e-12 {
        return None;
    }
    let t = (data.fur.shell_y(s) - eye.y) / d.y;
    if t <= 0.0 {
        return None;
    }
    let p = eye + d * t;
    let inside = |v: f64| (-EXTENT..=1.0 + EXTENT).contains(&v);
    (inside(p.x) && inside(p.z)).then_some(p)
}

/// Composite wall `w`'s fin over `col`, if the ray meets it ([`super::fins`]): coverage
/// from the fin texture, radiance of the shell at that height and place, as the page's
/// fin shader.
fn fin(
    data: &ViewData,
    tex: &[Vec<Vec<[f32; 4]>>],
    wts: &[f32; 4],
    eye: V3,
    d: V3,
    w: usize,
    col: &mut [f32; 3],
) {
    let Some((p, fv)) = fins::hit(&data.fur, eye, d, w) else {
        return;
    };
    let wall = fins::WALLS[w];
    let along = if wall.axis == 0 { p.z } else { p.x };
    let h = data.fur.height();
    let cov = fins::sample(
        &data.fin_bytes,
        data.fur.res,
        data.fin_rows,
        w,
        along,
        p.y / h,
    );
    if cov <= 0.0 {
        return;
    }
    let fv = fv as f32;
    let a = fins::weight(fv) * slant_alpha(cov, 1.0 / fv.max(SLANT_MIN_COS as f32));
    if a <= 0.0 {
        return;
    }
    let s = ((p.y / data.fur.dy()).floor().max(0.0) as usize).min(data.fur.shells - 1);
    let t = shade(tex, wts, s, data.packed.res, p.x, p.z);
    for ch in 0..3 {
        col[ch] = t[ch] * a + (1.0 - a) * col[ch];
    }
}
