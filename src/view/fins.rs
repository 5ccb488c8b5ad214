//! Fins at the swatch's silhouettes (seed 003 Sec. 5: "we plan to add fins"; after
//! Lengyel et al. 2001). The swatch is flat, so the surface turns edge-on at its four
//! borders: there the shell stack, seen from the side, shows as a pile of flat layers.
//! Each border carries a fin, a vertical quad from the base to the top of the stack,
//! textured with the coverage of the fibers in a thin slab just inside that border,
//! projected along the border's normal.
//!
//! * Coverage: [`coverage`], `res` texels along the border (the tile repeats along it) by
//!   `4 x shells` rows up the stack, combined as the shells' are (`1 - prod (1 - c)`).
//! * Radiance: not a texture of its own. A fin fragment at height `y` takes the radiance
//!   of shell `floor(y / dy)` at its position (the shells' PRT, self-shadowing included),
//!   so fins and shells are lit by the same transfer.
//! * Opacity: `w(|d . n|) (1 - (1 - c)^(1 / |d . n|))`, `d` the view ray and `n` the
//!   fin's normal: the shells' slant rule, faded out by [`weight`] as the fin itself turns
//!   edge-on (a fin seen along its plane would draw a hard line).
//! * Order: back walls (camera on the swatch's side of the plane) before the shells,
//!   front walls after them, each in index order ([`order`]); the page does the same.

use super::shells::FurSpec;
use super::shells::{capsule_share, EXTENT};
use crate::render::math::V3;

/// Depth of the slab of fibers a fin shows (tile units, ~4 texels at 128^2).
pub const DEPTH: f64 = 0.03;
/// Rows of the fin texture per shell.
pub const ROWS_PER_SHELL: usize = 4;

/// One border of the swatch.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Wall {
    /// 0: the plane `x = c`, along `z`; 2: the plane `z = c`, along `x`.
    pub axis: usize,
    /// The plane's coordinate.
    pub c: f64,
    /// Outward normal's sign along the axis.
    pub sign: f64,
}

impl Wall {
    /// The wall's outward unit normal.
    pub fn normal(&self) -> V3 {
        if self.axis == 0 {
            V3::new(self.sign, 0.0, 0.0)
        } else {
            V3::new(0.0, 0.0, self.sign)
        }
    }

    /// The coordinate across the wall and the one along it.
    fn coords(&self, p: V3) -> (f64, f64) {
        if self.axis == 0 {
            (p.x, p.z)
        } else {
            (p.z, p.x)
        }
    }

    /// The camera is inside the half-space the swatch is in: the wall is seen from behind.
    pub fn is_back(&self, eye: V3) -> bool {
        (self.coords(eye).0 - self.c) * self.sign < 0.0
    }
}

/// The four walls, the page's order: x min, x max, z min, z max.
pub const WALLS: [Wall; 4] = [
    Wall {
        axis: 0,
        c: -EXTENT,
        sign: -1.0,
    },
    Wall {
        axis: 0,
        c: 1.0 + EXTENT,
        sign: 1.0,
    },
    Wall {
        axis: 2,
        c: -EXTENT,
        sign: -1.0,
    },
    Wall {
        axis: 2,
        c: 1.0 + EXTENT,
        sign: 1.0,
    },
];

/// The walls seen from behind and those facing a camera at `eye`, each in index order.
/// Back walls are drawn before the shells (the fur in front of them covers their lower
/// part, their tips stand out against what is behind), front walls after.
pub fn order(eye: V3) -> (Vec<usize>, Vec<usize>) {
    let back = (0..4).filter(|&w| WALLS[w].is_back(eye)).collect();
    let front = (0..4).filter(|&w| !WALLS[w].is_back(eye)).collect();
    (back, front)
}

/// Fade of a fin seen at `|d . n| = fv`: 0 below 0.15 (nearly along its plane), 1 above
/// 0.5, smoothstep between (GLSL's).
#[inline]
pub fn weight(fv: f32) -> f32 {
    let t = ((fv - 0.15) / (0.5 - 0.15)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// Fin coverage of every wall: `[wall][row * res + i]`, row `j` centred on
/// `y = (j + 1/2) H / rows` (`H` the stack's height), texel `i` on `along = (i + 1/2) / res`
/// (the tile repeats along the wall).
#[derive(Clone, Debug)]
pub struct FinCoverage {
    /// Texels per row, along the wall (the tile's resolution).
    pub res: usize,
    /// Rows over the stack's height ([`ROWS_PER_SHELL`] per shell).
    pub rows: usize,
    /// Coverage per wall, `[wall][row * res + i]`, in [0, 1].
    pub cov: Vec<Vec<f32>>,
}

/// Coverage of the fibers in the slab of depth [`DEPTH`] inside each wall, projected on it
/// (4x4 samples per texel).
pub fn coverage(spec: &FurSpec, fibers: &[Vec<V3>]) -> FinCoverage {
    let (res, rows) = (spec.res, ROWS_PER_SHELL * spec.shells);
    let h = spec.height();
    let cov = WALLS
        .iter()
        .map(|wall| {
            let (lo, hi) = if wall.sign < 0.0 {
                (wall.c, wall.c + DEPTH)
            } else {
                (wall.c - DEPTH, wall.c)
            };
            let mut log_t = vec![0.0f64; res * rows];
            for k in (lo.floor() as i64 - 1)..=(hi.floor() as i64 + 1) {
                let shift = if wall.axis == 0 {
                    V3::new(k as f64, 0.0, 0.0)
                } else {
                    V3::new(0.0, 0.0, k as f64)
                };
                for f in fibers {
                    let n = (f.len() - 1) as f64;
                    for (i, w) in f.windows(2).enumerate() {
                        let (a, b) = (w[0] + shift, w[1] + shift);
                        let (ca, cb) = (wall.coords(a).0, wall.coords(b).0);
                        if ca.max(cb) < lo || ca.min(cb) >= hi {
                            continue;
                        }
                        // A segment parallel to the wall lies wholly inside the slab.
                        let (t0, t1) = if (cb - ca).abs() < 1e-12 {
                            (0.0, 1.0)
                        } else {
                            let clip = |c: f64| ((c - ca) / (cb - ca)).clamp(0.0, 1.0);
                            (clip(lo), clip(hi))
                        };
                        let (p, q) = (a + (b - a) * t0.min(t1), a + (b - a) * t0.max(t1));
                        let r = spec.radius * (1.0 - 0.5 * (i as f64 + 0.5) / n);
                        let (pu, qu) = (wall.coords(p).1, wall.coords(q).1);
                        splat(&mut log_t, res, rows, h, (pu, p.y), (qu, q.y), r);
                    }
                }
            }
            log_t.iter().map(|l| (1.0 - l.exp()) as f32).collect()
        })
        .collect();
    FinCoverage { res, rows, cov }
}

/// Add the capsule `p`-`q` (along, y) of radius `r` to `log_t` (`rows` rows over `[0, h]`,
/// `res` texels over the repeating unit along).
fn splat(log_t: &mut [f64], res: usize, rows: usize, h: f64, p: (f64, f64), q: (f64, f64), r: f64) {
    let (tu, ty) = (1.0 / res as f64, h / rows as f64);
    let (i0, i1) = (
        ((p.0.min(q.0) - r) / tu).floor() as i64,
        ((p.0.max(q.0) + r) / tu).floor() as i64,
    );
    let (j0, j1) = (
        (((p.1.min(q.1) - r) / ty).floor() as i64).max(0),
        (((p.1.max(q.1) + r) / ty).floor() as i64).min(rows as i64 - 1),
    );
    for j in j0..=j1 {
        for i in i0..=i1 {
            let c = capsule_share(p, q, r, (tu, ty), (i, j));
            if c > 0.0 {
                let wi = i.rem_euclid(res as i64) as usize;
                log_t[j as usize * res + wi] += (1.0 - c.min(0.9999)).ln();
            }
        }
    }
}

/// The coverage quantised to 8 bits, the page's R8 texture array (`[wall][row][texel]`).
pub fn pack(f: &FinCoverage) -> Vec<u8> {
    f.cov
        .iter()
        .flatten()
        .map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8)
        .collect()
}

/// Bilinear sample of wall `w`'s packed coverage at `(along, v)` (`v = y / H`): `REPEAT`
/// along, `CLAMP_TO_EDGE` up, as the page's sampler.
pub fn sample(bytes: &[u8], res: usize, rows: usize, w: usize, along: f64, v: f64) -> f32 {
    let (fu, fv) = (along * res as f64 - 0.5, v * rows as f64 - 0.5);
    let (i0, j0) = (fu.floor(), fv.floor());
    let (au, av) = ((fu - i0) as f32, (fv - j0) as f32);
    let wrap = |i: i64| i.rem_euclid(res as i64) as usize;
    let clamp = |j: i64| j.clamp(0, rows as i64 - 1) as usize;
    let (i0, j0) = (i0 as i64, j0 as i64);
    let t = |i: usize, j: usize| bytes[(w * rows + j) * res + i] as f32 / 255.0;
    let (ia, ib, ja, jb) = (wrap(i0), wrap(i0 + 1), clamp(j0), clamp(j0 + 1));
    let top = t(ia, ja) + au * (t(ib, ja) - t(ia, ja));
    let bot = t(ia, jb) + au * (t(ib, jb) - t(ia, jb));
    top + av * (bot - top)
}

/// Where the ray from `eye` along `d` meets wall `w` inside the swatch's side:
/// `(point, |d . n|)`.
pub fn hit(spec: &FurSpec, eye: V3, d: V3, w: usize) -> Option<(V3, f64)> {
    let wall = WALLS[w];
    let (ea, _) = wall.coords(eye);
    let (da, _) = wall.coords(d);
    if da.abs() < 1e-12 {
        return None;
    }
    let t = (wall.c - ea) / da;
    if t <= 0.0 {
        return None;
    }
    let p = eye + d * t;
    let along = wall.coords(p).1;
    let inside = (-EXTENT..=1.0 + EXTENT).contains(&along) && (0.0..=spec.height()).contains(&p.y);
    inside.then_some((p, da.abs()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fiber standing just inside the x-min wall covers a band `2 r` wide and as tall as
    /// the fiber on that wall's fin, and nothing on the opposite wall; its coverage sums
    /// to its projected area (4x4 supersampling: within 5 %).
    #[test]
    fn a_fiber_by_the_wall_shows_on_its_fin_only() {
        let spec = FurSpec {
            res: 128,
            shells: 16,
            radius: 0.01,
            ..FurSpec::default()
        };
        let h = spec.height();
        let root = V3::new(0.01, 0.0, 0.5);
        let fiber = vec![root, root + V3::new(0.0, 0.5 * h, 0.0)];
        let f = coverage(&spec, &[fiber]);
        let area = |w: usize| {
            f.cov[w].iter().map(|&c| c as f64).sum::<f64>()
                * (1.0 / f.res as f64)
                * (h / f.rows as f64)
        };
        // Mean radius of a one-segment fiber: 0.75 of the root's; pieces are capsules, so
        // the tip adds a half disc (the root's half disc falls below the base).
        let r = 0.0075;
        let want = 2.0 * r * 0.5 * h + 0.5 * std::f64::consts::PI * r * r;
        assert!((area(0) / want - 1.0).abs() < 0.05, "{} vs {want}", area(0));
        assert_eq!(area(1), 0.0);
        // Along z at 0.5, the fin's texels there are covered up to half the height.
        let bytes = pack(&f);
        assert!(sample(&bytes, f.res, f.rows, 0, 0.5, 0.25) > 0.9);
        assert!(sample(&bytes, f.res, f.rows, 0, 0.5, 0.75) < 0.01);
        // ... and, the tile repeating along the wall, one tile over too.
        assert!(sample(&bytes, f.res, f.rows, 0, 1.5, 0.25) > 0.9);
    }

    #[test]
    fn walls_are_ordered_back_to_front() {
        // A camera above the swatch's middle, toward +z: the z-max wall faces it, the
        // others are seen from the swatch's side.
        let eye = V3::new(0.5, 1.0, 4.0);
        assert_eq!(order(eye), (vec![0, 1, 2], vec![3]));
        let eye = V3::new(-3.0, 1.0, 0.5);
        assert_eq!(order(eye), (vec![1, 2, 3], vec![0]));
        assert_eq!(weight(0.1), 0.0);
        assert_eq!(weight(0.6), 1.0);
    }
}
