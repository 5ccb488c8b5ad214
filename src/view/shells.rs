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
    let dy = spec.dy();
    let res = spec.res;
    (0..spec.shells)
        .into_par_iter()
        .map(|s| {
            let (lo, hi) = (s as f64 * dy, (s + 1) as f64 * dy);
            // log(1 - alpha) accumulated per texel.
            let mut log_t = vec![0.0f64; res * res];
            for f in fibers {
                let n = (f.len() - 1) as f64;
                for (i, w) in f.windows(2).enumerate() {
                    let (a, b) = (w[0], w[1]);
                    let (ya, yb) = (a.y.min(b.y), a.y.max(b.y));
                    if yb < lo || ya >= hi {
                        continue;
                    }
                    // The part of the segment inside the slab.
                    let clip = |y: f64| {
                        if (b.y - a.y).abs() < 1e-12 {
                            0.5
                        } else {
                            ((y - a.y) / (b.y - a.y)).clamp(0.0, 1.0)
                        }
                    };
                    let (t0, t1) = (clip(lo), clip(hi));
                    let (p, q) = (a + (b - a) * t0.min(t1), a + (b - a) * t0.max(t1));
                    let r = spec.radius * (1.0 - 0.5 * (i as f64 + 0.5) / n);
                    splat_capsule(&mut log_t, res, p, q, r);
                }
            }
            log_t.iter().map(|l| (1.0 - l.exp()) as f32).collect()
        })
        .collect()
}

/// Add the capsule `p`-`q` of radius `r` (projected on `xz`) to `log_t`, wrapping around
/// the tile.
fn splat_capsule(log_t: &mut [f64], res: usize, p: V3, q: V3, r: f64) {
    let texel = 1.0 / res as f64;
    let (x0, x1) = (p.x.min(q.x) - r, p.x.max(q.x) + r);
    let (z0, z1) = (p.z.min(q.z) - r, p.z.max(q.z) + r);
    let (i0, i1) = ((x0 / texel).floor() as i64, (x1 / texel).floor() as i64);
    let (j0, j1) = ((z0 / texel).floor() as i64, (z1 / texel).floor() as i64);
    for j in j0..=j1 {
        for i in i0..=i1 {
            let c = capsule_share((p.x, p.z), (q.x, q.z), r, (texel, texel), (i, j));
            if c > 0.0 {
                let (wi, wj) = (
                    i.rem_euclid(res as i64) as usize,
                    j.rem_euclid(res as i64) as usize,
                );
                // A fully covered texel stays finite: 1 - 1e-4 at most per piece.
                log_t[wj * res + wi] += (1.0 - c.min(0.9999)).ln();
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
