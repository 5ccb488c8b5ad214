//! The fur volume: a periodic tile of fibers (density, length, curl and comb from
//! options, deterministic in the seed), cut into concentric shells whose texels hold the
//! fibers' coverage (seed 003 Sec. 2.1: "the shells are transparent everywhere except at
//! the intersection of the shell and the microgeometry").
//!
//! The swatch is flat: shells are the planes `y = (s + 1/2) dy` over a tile of side 1
//! that repeats in `x` and `z`, so a fiber crossing the tile's edge continues on the far
//! side (the textures tile seamlessly and the page can lay out several tiles). The same
//! fibers, as polylines, are what the path-traced reference ([`super::reference`])
//! intersects.

use crate::render::math::V3;
use crate::render::scene::Segment;
use rand::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use rayon::prelude::*;
use std::f64::consts::TAU;

/// The swatch the page draws: tiles over `[-EXTENT, 1 + EXTENT]^2` (fins stand on its
/// borders).
pub const EXTENT: f64 = 1.0;

/// How the fur is grown.
#[derive(Clone, Debug, PartialEq)]
pub struct FurSpec {
    /// Texels per tile side.
    pub res: usize,
    /// Number of shells stacked over the skin.
    pub shells: usize,
    /// Fibers per tile.
    pub fibers: usize,
    /// Fiber length (tile = 1); each fiber draws its own in [0.6, 1] times this.
    pub length: f64,
    /// Fiber radius at the root (tile units); tapers to half at the tip.
    pub radius: f64,
    /// Helical curl radius (tile units; 0 = straight).
    pub curl: f64,
    /// Turns of the curl along a fiber.
    pub curl_turns: f64,
    /// Comb: tilt of the fibers from the vertical toward +x (degrees).
    pub tilt_deg: f64,
    /// Per-fiber random spread of the tilt (degrees).
    pub spread_deg: f64,
    /// Straight segments per fiber.
    pub segments: usize,
    /// Seed of the fibers' random layout.
    pub seed: u64,
}

impl Default for FurSpec {
    fn default() -> Self {
        FurSpec {
            res: 128,
            shells: 32,
            fibers: 4000,
            length: 0.26,
            radius: 0.0045,
            curl: 0.006,
            curl_turns: 1.0,
            tilt_deg: 30.0,
            spread_deg: 6.0,
            segments: 8,
            seed: 3,
        }
    }
}

impl FurSpec {
    /// Refuse values that would make no fur or run for ever.
    pub fn validate(&self) -> crate::Result<()> {
        let bad = |m: String| Err(crate::Error::Invalid(m));
        if !(8..=1024).contains(&self.res) {
            return bad(format!("--res {}: expected 8 to 1024 texels", self.res));
        }
        if !(2..=128).contains(&self.shells) {
            return bad(format!("--shells {}: expected 2 to 128", self.shells));
        }
        if !(1..=200_000).contains(&self.fibers) {
            return bad(format!("--fibers {}: expected 1 to 200000", self.fibers));
        }
        if !(self.length > 0.0 && self.length <= 2.0) {
            return bad(format!(
                "--length {}: expected (0, 2] tile sides",
                self.length
            ));
        }
        if !(self.radius > 0.0 && self.radius <= 0.05) {
            return bad(format!("--radius {}: expected (0, 0.05]", self.radius));
        }
        if !(self.curl >= 0.0 && self.curl <= 0.1) {
            return bad(format!("--curl {}: expected [0, 0.1]", self.curl));
        }
        if !(self.tilt_deg.abs() <= 75.0 && (0.0..=30.0).contains(&self.spread_deg)) {
            return bad(format!(
                "--tilt {} / spread {}: expected |tilt| <= 75 and spread in [0, 30] degrees",
                self.tilt_deg, self.spread_deg
            ));
        }
        Ok(())
    }

    /// The comb direction: the mean fiber tangent, root to tip.
    pub fn comb(&self) -> V3 {
        let t = self.tilt_deg.to_radians();
        V3::new(t.sin(), t.cos(), 0.0)
    }

    /// Height of the shell stack: the tallest a fiber can reach.
    pub fn height(&self) -> f64 {
        let t = (self.tilt_deg.abs() - self.spread_deg)
            .max(0.0)
            .to_radians();
        self.length * t.cos() + 2.0 * self.curl
    }

    /// Spacing of the shells.
    pub fn dy(&self) -> f64 {
        self.height() / self.shells as f64
    }

    /// Height of shell `s`'s plane.
    pub fn shell_y(&self, s: usize) -> f64 {
        (s as f64 + 0.5) * self.dy()
    }
}

/// The fibers of one tile as polylines (root first), roots in `[0, 1)^2` at `y = 0`.
pub fn grow(spec: &FurSpec) -> Vec<Vec<V3>> {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(spec.seed);
    let base_tilt = spec.tilt_deg.to_radians();
    (0..spec.fibers)
        .map(|_| {
            let root = V3::new(rng.random(), 0.0, rng.random());
            let tilt = base_tilt + spec.spread_deg.to_radians() * (rng.random::<f64>() * 2.0 - 1.0);
            let yaw = spec.spread_deg.to_radians() * (rng.random::<f64>() * 2.0 - 1.0);
            let t = V3::new(tilt.sin() * yaw.cos(), tilt.cos(), tilt.sin() * yaw.sin());
            let e1 = t.cross(V3::new(0.0, 0.0, 1.0)).normalized();
            let e2 = t.cross(e1);
            let len = spec.length * (0.6 + 0.4 * rng.random::<f64>());
            let phase = TAU * rng.random::<f64>();
            let n = spec.segments.max(1);
            (0..=n)
                .map(|i| {
                    let s = i as f64 / n as f64;
                    let a = phase + TAU * spec.curl_turns * s;
                    // The helix starts at the root: subtract its offset there.
                    let off =
                        (e1 * (a.cos() - phase.cos()) + e2 * (a.sin() - phase.sin())) * spec.curl;
                    let p = root + t * (len * s) + off;
                    V3::new(p.x, p.y.max(0.0), p.z)
                })
                .collect()
        })
        .collect()
}

/// The fibers as the renderer's segments, with copies shifted by whole tiles so the
/// geometry covers `[-margin, 1 + margin]^2` (fibers rooted there).
pub fn segments(spec: &FurSpec, fibers: &[Vec<V3>], margin: f64) -> Vec<Segment> {
    let mut out = Vec::new();
    let reach = margin.ceil() as i64 + 1;
    let mut id = 0u32;
    for dx in -reach..=reach {
        for dz in -reach..=reach {
            let shift = V3::new(dx as f64, 0.0, dz as f64);
            for f in fibers {
                let r0 = f[0] + shift;
                let inside = |v: f64| v >= -margin && v <= 1.0 + margin;
                if !(inside(r0.x) && inside(r0.z)) {
                    continue;
                }
                let n = (f.len() - 1) as f64;
                for (i, w) in f.windows(2).enumerate() {
                    let ra = spec.radius * (1.0 - 0.5 * i as f64 / n);
                    let rb = spec.radius * (1.0 - 0.5 * (i + 1) as f64 / n);
                    out.push(Segment {
                        a: w[0] + shift,
                        b: w[1] + shift,
                        ra,
                        rb,
                        fiber: id,
                    });
                }
                id += 1;
            }
        }
    }
    out
}

/// Coverage of each shell texel, `[shell][texel]` (texel `(i, j)` at `j * res + i`, the
/// texel centred on `x = (i + 1/2) / res`, `z = (j + 1/2) / res`): the fraction of the
/// texel that the fibers' pieces inside the shell's slab cover seen from above, fibers
/// combined as independent occluders (`1 - prod (1 - c)`), 4x4 samples per texel.
pub fn coverage(spec: &FurSpec, fibers: &[Vec<V3>]) -> Vec<Vec<f32>> {
    pieces(spec, fibers).coverage()
}

/// One fiber's optical depth `-ln(1 - c)` in one shell, on the smallest texel rectangle
/// holding it: texel `(i0 + a, j0 + b)` (unwrapped: the fiber's own continuous
/// coordinates, which may leave `[0, res)`) at `vals[at + b * w + a]`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Patch {
    /// First texel column (unwrapped).
    pub i0: i64,
    /// First texel row (unwrapped).
    pub j0: i64,
    /// Width in texels (0: the fiber does not reach the shell).
    pub w: usize,
    /// Height in texels.
    pub h: usize,
    /// Offset of its first value in [`Pieces::vals`].
    pub at: usize,
    /// The piece's mean unit tangent (its parts' chords summed).
    pub tangent: [f32; 3],
    /// The piece's cross-section per unit `|t x d|` (`2 r L`) over its vertical
    /// footprint's area: [`Pieces::factor`].
    pub cross: f32,
}

/// Every fiber's pieces, shell by shell: what [`coverage`] combines, kept apart so the
/// transfer can tell a texel's own fibers from the others ([`super::prt::Shadowing`]).
/// The shells' optical depth is exactly the sum of the pieces' (coverage combines
/// pieces as independent occluders: `ln(1 - alpha) = sum ln(1 - c)`).
#[derive(Clone, Debug)]
pub struct Pieces {
    /// Texels per tile side.
    pub res: usize,
    /// Number of shells.
    pub shells: usize,
    /// `[fiber * shells + shell]`; `w == 0`: the fiber does not reach that shell.
    pub patches: Vec<Patch>,
    /// The patches' optical depths, each patch row-major at its `at`.
    pub vals: Vec<f32>,
}

/// Largest coverage of a texel by one piece (keeps its depth finite, [`MAX_OD`]).
const MAX_COVER: f32 = 0.9999;

/// A fully covered texel stays finite: 1 - 1e-4 at most per piece (and per texel).
pub const MAX_OD: f64 = 9.210_340_371_976_182; // -ln(1e-4)

impl Pieces {
    /// The patch of `fiber` in shell `s`.
    pub fn patch(&self, fiber: usize, s: usize) -> &Patch {
        &self.patches[fiber * self.shells + s]
    }

    /// Number of fibers.
    pub fn fibers(&self) -> usize {
        self.patches.len() / self.shells.max(1)
    }

    /// What turns the vertical optical depth of patch `i`'s piece into its depth along
    /// `d` per slab crossed. A tube of radius `r` and length `L` with tangent `t` blocks
    /// `2 r L |t x d|` of a beam along `d`, and a beam of unit cross-section crosses
    /// `1 / |d_y|` of horizontal area; seen from above the piece covers its vertical
    /// footprint instead, which counts its end caps (`pi r^2`) again in every shell. For
    /// the comb's 30 degrees the plain `od / |d_y|` of seed 003 Eq. 4 over-shadows steep
    /// light about twofold (a ray along a steep fiber meets its caps once, not per
    /// shell). So each texel's coverage `c` is scaled by the ratio of the two areas,
    /// `g = cross |t x d| / |d_y|`, and turned back into depth, `-ln(1 - g c)`: summed
    /// over the patch, over its vertical depth. Measured against shadow rays through the
    /// same fibers (`reports/viewer/prt_error.md`, "Tube depth").
    pub fn factor(&self, i: usize, d: [f32; 3]) -> f32 {
        let p = &self.patches[i];
        let vals = &self.vals[p.at..p.at + p.w * p.h];
        let t = p.tangent;
        let c = t[0] * d[0] + t[1] * d[1] + t[2] * d[2];
        let g = p.cross * (1.0 - c * c).max(0.0).sqrt() / d[1].abs();
        let (mut num, mut den) = (0.0f32, 0.0f32);
        for &v in vals {
            let cv = 1.0 - (-v).exp();
            num -= (1.0 - (cv * g).min(MAX_COVER)).ln();
            den += v;
        }
        if den > 0.0 {
            num / den
        } else {
            0.0
        }
    }

    /// [`Self::factor`] of every patch (`[fiber * shells + shell]`) for direction `d`.
    pub fn factors(&self, d: [f32; 3]) -> Vec<f32> {
        (0..self.patches.len()).map(|i| self.factor(i, d)).collect()
    }

    /// The optical depth of shell `s` along the direction of `factors` ([`Self::factors`])
    /// per texel, wrapped, into `out`.
    pub fn along(&self, s: usize, factors: &[f32], out: &mut [f32]) {
        let res = self.res;
        out.fill(0.0);
        for f in 0..self.fibers() {
            let p = self.patch(f, s);
            if p.w == 0 {
                continue;
            }
            let k = factors[f * self.shells + s];
            for b in 0..p.h {
                let j = (p.j0 + b as i64).rem_euclid(res as i64) as usize;
                let row = &self.vals[p.at + b * p.w..p.at + (b + 1) * p.w];
                for (a, v) in row.iter().enumerate() {
                    let i = (p.i0 + a as i64).rem_euclid(res as i64) as usize;
                    out[j * res + i] += v * k;
                }
            }
        }
    }

    /// The shells' optical depth `[shell][texel]`: the pieces summed (wrapped), at most
    /// [`MAX_OD`].
    pub fn optical_depth(&self) -> Vec<Vec<f64>> {
        let (res, shells) = (self.res, self.shells);
        let mut od = vec![vec![0.0f64; res * res]; shells];
        for f in 0..self.fibers() {
            for (s, plane) in od.iter_mut().enumerate() {
                let p = self.patch(f, s);
                for b in 0..p.h {
                    let j = (p.j0 + b as i64).rem_euclid(res as i64) as usize;
                    for a in 0..p.w {
                        let i = (p.i0 + a as i64).rem_euclid(res as i64) as usize;
                        plane[j * res + i] += self.vals[p.at + b * p.w + a] as f64;
                    }
                }
            }
        }
        for v in od.iter_mut().flatten() {
            *v = v.min(MAX_OD);
        }
        od
    }

    /// Coverage `1 - exp(-od)` of every shell texel (what [`coverage`] returns).
    pub fn coverage(&self) -> Vec<Vec<f32>> {
        self.optical_depth()
            .iter()
            .map(|p| p.iter().map(|o| (1.0 - (-o).exp()) as f32).collect())
            .collect()
    }

    /// Per shell, the fibers covering each texel with their optical depth there, as
    /// `(start, entries)`: texel `t`'s are `entries[start[t]..start[t + 1]]`.
    pub fn by_texel(&self) -> Vec<TexelFibers> {
        let (res, shells) = (self.res, self.shells);
        (0..shells)
            .into_par_iter()
            .map(|s| {
                let mut lists: Vec<Vec<(u32, f32)>> = vec![Vec::new(); res * res];
                for f in 0..self.fibers() {
                    let p = self.patch(f, s);
                    for b in 0..p.h {
                        let j = (p.j0 + b as i64).rem_euclid(res as i64) as usize;
                        for a in 0..p.w {
                            let i = (p.i0 + a as i64).rem_euclid(res as i64) as usize;
                            let v = self.vals[p.at + b * p.w + a];
                            if v > 0.0 {
                                lists[j * res + i].push((f as u32, v));
                            }
                        }
                    }
                }
                let mut start = Vec::with_capacity(res * res + 1);
                let mut entries = Vec::new();
                for l in lists {
                    start.push(entries.len() as u32);
                    entries.extend(l);
                }
                start.push(entries.len() as u32);
                (start, entries)
            })
            .collect()
    }
}

/// One shell's fibers per texel, `(start, entries)`: texel `t`'s `(fiber, optical depth)`
/// pairs are `entries[start[t]..start[t + 1]]` ([`Pieces::by_texel`]).
pub type TexelFibers = (Vec<u32>, Vec<(u32, f32)>);

/// Cut every fiber into its shells' pieces ([`Pieces`]): per slab, the part of each
/// segment inside it, splatted as a capsule seen from above (4x4 samples per texel).
pub fn pieces(spec: &FurSpec, fibers: &[Vec<V3>]) -> Pieces {
    let dy = spec.dy();
    let (res, shells) = (spec.res, spec.shells);
    let per_fiber: Vec<Vec<(Patch, Vec<f32>)>> = fibers
        .par_iter()
        .map(|f| {
            let n = (f.len() - 1) as f64;
            (0..shells)
                .map(|s| {
                    let (lo, hi) = (s as f64 * dy, (s + 1) as f64 * dy);
                    // (i, j) unwrapped -> log(1 - c), summed over the fiber's pieces.
                    let mut cells: Vec<((i64, i64), f64)> = Vec::new();
                    // The parts' chords summed, and their cross-section 2 r L.
                    let (mut chord, mut xs) = (V3::new(0.0, 0.0, 0.0), 0.0);
                    for (i, w) in f.windows(2).enumerate() {
                        let (a, b) = (w[0], w[1]);
                        let (ya, yb) = (a.y.min(b.y), a.y.max(b.y));
                        if yb < lo || ya >= hi {
                            continue;
                        }
                        // The part of the segment inside the slab.
                        let clip = |y: f64| ((y - a.y) / (b.y - a.y)).clamp(0.0, 1.0);
                        // A level segment lies wholly in its slab.
                        let (t0, t1) = if (b.y - a.y).abs() < 1e-12 {
                            (0.0, 1.0)
                        } else {
                            (clip(lo), clip(hi))
                        };
                        let (p, q) = (a + (b - a) * t0.min(t1), a + (b - a) * t0.max(t1));
                        let r = spec.radius * (1.0 - 0.5 * (i as f64 + 0.5) / n);
                        splat_capsule(&mut cells, res, p, q, r);
                        chord = chord + (q - p);
                        xs += 2.0 * r * (q - p).length();
                    }
                    let (mut patch, vals) = to_patch(&cells);
                    // The vertical footprint's area, in texels.
                    let area: f64 = vals.iter().map(|&v| 1.0 - (-(v as f64)).exp()).sum();
                    if area > 0.0 && chord.length() > 0.0 {
                        let t = chord.normalized();
                        patch.tangent = [t.x as f32, t.y as f32, t.z as f32];
                        patch.cross = (xs * (res * res) as f64 / area) as f32;
                    }
                    (patch, vals)
                })
                .collect()
        })
        .collect();
    let mut patches = Vec::with_capacity(fibers.len() * shells);
    let mut vals = Vec::new();
    for (mut p, v) in per_fiber.into_iter().flatten() {
        p.at = vals.len();
        vals.extend(v);
        patches.push(p);
    }
    Pieces {
        res,
        shells,
        patches,
        vals,
    }
}

/// The smallest rectangle holding `cells`, dense, as optical depth.
fn to_patch(cells: &[((i64, i64), f64)]) -> (Patch, Vec<f32>) {
    if cells.is_empty() {
        return (Patch::default(), Vec::new());
    }
    let i0 = cells.iter().map(|c| c.0 .0).min().unwrap_or(0);
    let i1 = cells.iter().map(|c| c.0 .0).max().unwrap_or(0);
    let j0 = cells.iter().map(|c| c.0 .1).min().unwrap_or(0);
    let j1 = cells.iter().map(|c| c.0 .1).max().unwrap_or(0);
    let (w, h) = ((i1 - i0 + 1) as usize, (j1 - j0 + 1) as usize);
    let mut v = vec![0.0f64; w * h];
    for ((i, j), l) in cells {
        v[(j - j0) as usize * w + (i - i0) as usize] -= l;
    }
    let p = Patch {
        i0,
        j0,
        w,
        h,
        ..Patch::default()
    };
    (p, v.iter().map(|x| x.min(MAX_OD) as f32).collect())
}

/// Add the capsule `p`-`q` of radius `r` (projected on `xz`) to `cells` as `log(1 - c)`
/// per covered texel (unwrapped texel coordinates).
fn splat_capsule(cells: &mut Vec<((i64, i64), f64)>, res: usize, p: V3, q: V3, r: f64) {
    let texel = 1.0 / res as f64;
    let (x0, x1) = (p.x.min(q.x) - r, p.x.max(q.x) + r);
    let (z0, z1) = (p.z.min(q.z) - r, p.z.max(q.z) + r);
    let (i0, i1) = ((x0 / texel).floor() as i64, (x1 / texel).floor() as i64);
    let (j0, j1) = ((z0 / texel).floor() as i64, (z1 / texel).floor() as i64);
    for j in j0..=j1 {
        for i in i0..=i1 {
            let c = capsule_share((p.x, p.z), (q.x, q.z), r, (texel, texel), (i, j));
            if c > 0.0 {
                cells.push(((i, j), (1.0 - c.min(0.9999)).ln()));
            }
        }
    }
}

/// The share of cell `(i, j)` (sides `cell`) inside the 2-D capsule `p`-`q` of radius
/// `r`, on a 4 x 4 grid of points in the cell (the shells' and the fins' coverage).
pub(super) fn capsule_share(
    p: (f64, f64),
    q: (f64, f64),
    r: f64,
    cell: (f64, f64),
    (i, j): (i64, i64),
) -> f64 {
    const SUB: usize = 4;
    let (du, dv) = (q.0 - p.0, q.1 - p.1);
    let len2 = du * du + dv * dv;
    let mut hits = 0;
    for sj in 0..SUB {
        for si in 0..SUB {
            let u = (i as f64 + (si as f64 + 0.5) / SUB as f64) * cell.0;
            let v = (j as f64 + (sj as f64 + 0.5) / SUB as f64) * cell.1;
            let t = if len2 > 0.0 {
                (((u - p.0) * du + (v - p.1) * dv) / len2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let (eu, ev) = (u - p.0 - t * du, v - p.1 - t * dv);
            if eu * eu + ev * ev <= r * r {
                hits += 1;
            }
        }
    }
    hits as f64 / (SUB * SUB) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fur_is_deterministic_and_inside_the_stack() {
        let spec = FurSpec {
            res: 32,
            fibers: 200,
            ..FurSpec::default()
        };
        let a = grow(&spec);
        assert_eq!(a, grow(&spec));
        let h = spec.height();
        for f in &a {
            assert!(f.iter().all(|p| p.y >= 0.0 && p.y <= h + 1e-12));
        }
        let other = grow(&FurSpec {
            seed: 4,
            ..spec.clone()
        });
        assert_ne!(a, other);
    }

    /// One vertical fiber through every shell covers pi r^2 of the tile in each, r its
    /// mean radius (a one-segment fiber: 0.75 of the root's), wherever it sits (also
    /// across the edge); 4x4 supersampling of a disc ~8 texels across: within 5 %.
    #[test]
    fn coverage_of_a_vertical_fiber_is_its_cross_section() {
        let spec = FurSpec {
            res: 256,
            shells: 8,
            radius: 0.02,
            ..FurSpec::default()
        };
        for root in [V3::new(0.5, 0.0, 0.5), V3::new(0.001, 0.0, 0.999)] {
            let fiber = vec![root, root + V3::new(0.0, spec.height(), 0.0)];
            let cov = coverage(&spec, &[fiber]);
            for shell in &cov {
                let area: f64 = shell.iter().map(|&c| c as f64).sum::<f64>() / (256.0 * 256.0);
                let want = std::f64::consts::PI * 0.015 * 0.015;
                assert!((area / want - 1.0).abs() < 0.05, "{area} vs {want}");
            }
        }
    }
}
