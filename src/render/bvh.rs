//! Bounding volume hierarchy over fiber segments and the ray-fiber intersection.
//!
//! Fibers are intersected as **camera-facing ribbons**: a ray hits a segment when its
//! closest approach to the segment's axis (parameter clamped to the segment) is closer than
//! the local radius. The hit reports the ray distance at closest approach, the unit
//! tangent `u` (root to tip) and the signed offset `h in [-1, 1]` across the fiber,
//! `h = (p . (u x d) / |u x d|) / r` with `p` the offset from the axis to the ray, which is
//! MODEL.md's offset for light entering along `-d` (see [`super::bsdf`] for the frame).

use super::math::V3;
use super::scene::Segment;

#[derive(Clone, Copy, Debug)]
struct Aabb {
    lo: V3,
    hi: V3,
}

impl Aabb {
    fn empty() -> Aabb {
        Aabb {
            lo: V3::new(f64::INFINITY, f64::INFINITY, f64::INFINITY),
            hi: V3::new(f64::NEG_INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY),
        }
    }
    fn union(self, o: Aabb) -> Aabb {
        Aabb {
            lo: self.lo.min(o.lo),
            hi: self.hi.max(o.hi),
        }
    }
    /// Slab test; returns the entry distance if the box is hit within (tmin, tmax).
    /// `inv` = 1 / direction from [`safe_inv`], so every product is finite and the plain
    /// comparisons below (which compile to single min/max instructions, unlike the
    /// NaN-aware `f64::min`) see no NaN.
    #[inline(always)]
    fn hit(&self, o: V3, inv: V3, tmin: f64, tmax: f64) -> Option<f64> {
        let (x0, x1) = ((self.lo.x - o.x) * inv.x, (self.hi.x - o.x) * inv.x);
        let (y0, y1) = ((self.lo.y - o.y) * inv.y, (self.hi.y - o.y) * inv.y);
        let (z0, z1) = ((self.lo.z - o.z) * inv.z, (self.hi.z - o.z) * inv.z);
        let t0 = fmax(fmax(tmin, fmin(x0, x1)), fmax(fmin(y0, y1), fmin(z0, z1)));
        let t1 = fmin(fmin(tmax, fmax(x0, x1)), fmin(fmax(y0, y1), fmax(z0, z1)));
        (t0 <= t1).then_some(t0)
    }
}

#[inline(always)]
fn fmin(a: f64, b: f64) -> f64 {
    if a < b {
        a
    } else {
        b
    }
}

#[inline(always)]
fn fmax(a: f64, b: f64) -> f64 {
    if a > b {
        a
    } else {
        b
    }
}

/// `1 / x`, with a zero component replaced by `+-1e-300` so the reciprocal is finite
/// (`0 * inv` is then 0, never NaN, in the slab test).
#[inline(always)]
fn safe_inv(x: f64) -> f64 {
    1.0 / if x.abs() < 1e-300 {
        1e-300f64.copysign(x)
    } else {
        x
    }
}

#[derive(Clone, Copy, Debug)]
struct Node {
    bounds: Aabb,
    /// Leaf: first primitive index; interior: index of the right child (left = self + 1).
    index: u32,
    /// Number of primitives in a leaf, 0 for interior nodes.
    count: u32,
}

/// A ray-fiber hit.
#[derive(Clone, Copy, Debug)]
pub struct Hit {
    pub t: f64,
    /// Point on the ray at closest approach.
    pub p: V3,
    /// Unit fiber tangent, root to tip.
    pub u: V3,
    /// Signed offset across the fiber in [-1, 1] (see module doc).
    pub h: f64,
    /// Fiber radius at the hit (world units).
    pub radius: f64,
    pub fiber: u32,
    pub segment: u32,
}

/// BVH over segments (median split on the longest axis, leaves of <= 4).
pub struct Bvh {
    nodes: Vec<Node>,
    segs: Vec<Segment>,
    /// Leaf primitives in node order: index of the segment whose piece it bounds.
    prims: Vec<u32>,
}

/// Leaves hold at most this many pieces.
const LEAF: usize = 4;
/// Binned SAH: bins per axis.
const BINS: usize = 12;
/// A segment is bounded by pieces at most this many radii long (see [`Bvh::build`]).
const PIECE_RADII: f64 = 10.0;
const MAX_PIECES: usize = 32;

impl Aabb {
    fn area(&self) -> f64 {
        let e = self.hi - self.lo;
        if e.x < 0.0 {
            return 0.0;
        }
        2.0 * (e.x * e.y + e.y * e.z + e.z * e.x)
    }
}

impl Bvh {
    /// Build over `segs`. A fiber segment is long and thin (~40 radii) and diagonal, so its
    /// box is mostly empty; each segment is therefore bounded by several boxes, one per
    /// piece of at most [`PIECE_RADII`] radii, all pointing at the same segment. A ray
    /// entering any of them tests the WHOLE segment, so hits are exactly those of a brute
    /// force loop (every hit lies within `r` of the axis point at its parameter, inside
    /// that piece's box). The tree is split by the binned surface-area heuristic.
    pub fn build(segs: Vec<Segment>) -> Bvh {
        let mut boxes = Vec::new();
        let mut owner = Vec::new();
        for (i, s) in segs.iter().enumerate() {
            let r = s.ra.max(s.rb);
            let len = (s.b - s.a).length();
            let n = ((len / (PIECE_RADII * r.max(1e-12))).ceil() as usize).clamp(1, MAX_PIECES);
            let e = V3::new(r, r, r);
            for k in 0..n {
                let p0 = s.a + (s.b - s.a) * (k as f64 / n as f64);
                let p1 = s.a + (s.b - s.a) * ((k + 1) as f64 / n as f64);
                boxes.push(Aabb {
                    lo: p0.min(p1) - e,
                    hi: p0.max(p1) + e,
                });
                owner.push(i as u32);
            }
        }
        let mut order: Vec<usize> = (0..boxes.len()).collect();
        let centers: Vec<V3> = boxes.iter().map(|b| (b.lo + b.hi) * 0.5).collect();
        let mut nodes = Vec::with_capacity(2 * boxes.len() / LEAF + 1);
        if !boxes.is_empty() {
            build_rec(&mut nodes, &mut order, 0, &boxes, &centers);
        }
        let prims = order.iter().map(|&i| owner[i]).collect();
        Bvh { nodes, segs, prims }
    }

    pub fn segments(&self) -> &[Segment] {
        &self.segs
    }

    /// Closest hit in `(tmin, tmax)`, ignoring fiber `skip` (the fiber a path leaves).
    pub fn intersect(&self, o: V3, d: V3, tmin: f64, tmax: f64, skip: Option<u32>) -> Option<Hit> {
        self.traverse(o, d, tmin, tmax, skip, false)
    }

    /// Any hit in `(tmin, tmax)` (shadow rays).
    pub fn occluded(&self, o: V3, d: V3, tmin: f64, tmax: f64, skip: Option<u32>) -> bool {
        self.traverse(o, d, tmin, tmax, skip, true).is_some()
    }

    fn traverse(
        &self,
        o: V3,
        d: V3,
        tmin: f64,
        mut tmax: f64,
        skip: Option<u32>,
        any: bool,
    ) -> Option<Hit> {
        if self.nodes.is_empty() {
            return None;
        }
        let inv = V3::new(safe_inv(d.x), safe_inv(d.y), safe_inv(d.z));
        let mut stack = [0u32; 128];
        let mut sp = 1;
        let mut best: Option<Hit> = None;
        // The last segment tested (neighbouring pieces of one segment share leaves).
        let mut last = u32::MAX;
        while sp > 0 {
            sp -= 1;
            let node = &self.nodes[stack[sp] as usize];
            if node.bounds.hit(o, inv, tmin, tmax).is_none() {
                continue;
            }
            if node.count > 0 {
                let first = node.index as usize;
                for &si in &self.prims[first..first + node.count as usize] {
                    if si == last {
                        continue;
                    }
                    last = si;
                    let s = &self.segs[si as usize];
                    if Some(s.fiber) == skip {
                        continue;
                    }
                    if let Some(mut hit) = intersect_segment(s, o, d, tmin, tmax) {
                        hit.segment = si;
                        tmax = hit.t;
                        best = Some(hit);
                        if any {
                            return best;
                        }
                    }
                }
            } else {
                let me = stack[sp] as usize;
                let (l, r) = (me as u32 + 1, node.index);
                let tl = self.nodes[l as usize].bounds.hit(o, inv, tmin, tmax);
                let tr = self.nodes[r as usize].bounds.hit(o, inv, tmin, tmax);
                match (tl, tr) {
                    (Some(a), Some(b)) => {
                        let (near, far) = if a <= b { (l, r) } else { (r, l) };
                        stack[sp] = far;
                        stack[sp + 1] = near;
                        sp += 2;
                    }
                    (Some(_), None) => {
                        stack[sp] = l;
                        sp += 1;
                    }
                    (None, Some(_)) => {
                        stack[sp] = r;
                        sp += 1;
                    }
                    (None, None) => {}
                }
            }
        }
        best
    }
}

fn build_rec(
    nodes: &mut Vec<Node>,
    order: &mut [usize],
    first: usize,
    boxes: &[Aabb],
    centers: &[V3],
) -> usize {
    let me = nodes.len();
    let bounds = order.iter().fold(Aabb::empty(), |b, &i| b.union(boxes[i]));
    nodes.push(Node {
        bounds,
        index: first as u32,
        count: order.len() as u32,
    });
    if order.len() <= LEAF {
        return me;
    }
    let cb = order.iter().fold(Aabb::empty(), |b, &i| Aabb {
        lo: b.lo.min(centers[i]),
        hi: b.hi.max(centers[i]),
    });
    // Binned SAH over the three axes: cost of a split = sum over sides of count * area.
    let mut best: Option<(f64, usize, f64)> = None; // (cost, axis, split coordinate)
    for axis in 0..3 {
        let (lo, hi) = (cb.lo.axis(axis), cb.hi.axis(axis));
        if hi - lo <= 0.0 {
            continue;
        }
        let scale = BINS as f64 / (hi - lo);
        let bin = |i: usize| (((centers[i].axis(axis) - lo) * scale) as usize).min(BINS - 1);
        let mut cnt = [0usize; BINS];
        let mut bb = [Aabb::empty(); BINS];
        for &i in order.iter() {
            let b = bin(i);
            cnt[b] += 1;
            bb[b] = bb[b].union(boxes[i]);
        }
        // Sweep from the right, then from the left.
        let mut right_area = [0.0; BINS];
        let mut right_cnt = [0usize; BINS];
        let (mut acc, mut n) = (Aabb::empty(), 0);
        for k in (1..BINS).rev() {
            acc = acc.union(bb[k]);
            n += cnt[k];
            right_area[k] = acc.area();
            right_cnt[k] = n;
        }
        let (mut acc, mut n) = (Aabb::empty(), 0);
        for k in 1..BINS {
            acc = acc.union(bb[k - 1]);
            n += cnt[k - 1];
            if n == 0 || right_cnt[k] == 0 {
                continue;
            }
            let cost = n as f64 * acc.area() + right_cnt[k] as f64 * right_area[k];
            if best.map_or(true, |b| cost < b.0) {
                best = Some((cost, axis, lo + k as f64 / scale));
            }
        }
    }
    let mid = match best {
        Some((_, axis, split)) => {
            let mut m = 0;
            for k in 0..order.len() {
                if centers[order[k]].axis(axis) < split {
                    order.swap(k, m);
                    m += 1;
                }
            }
            m
        }
        None => 0,
    };
    // Degenerate split (all centres in one bin or coincident): median on the widest axis.
    let mid = if mid == 0 || mid == order.len() {
        let ext = cb.hi - cb.lo;
        let axis = if ext.x >= ext.y && ext.x >= ext.z {
            0
        } else if ext.y >= ext.z {
            1
        } else {
            2
        };
        let mid = order.len() / 2;
        order.select_nth_unstable_by(mid, |&a, &b| {
            centers[a].axis(axis).total_cmp(&centers[b].axis(axis))
        });
        mid
    } else {
        mid
    };
    let (left, right) = order.split_at_mut(mid);
    build_rec(nodes, left, first, boxes, centers);
    let r = build_rec(nodes, right, first + mid, boxes, centers);
    nodes[me].index = r as u32;
    nodes[me].count = 0;
    me
}

#[inline]
pub fn intersect_segment(s: &Segment, o: V3, d: V3, tmin: f64, tmax: f64) -> Option<Hit> {
    let e = s.b - s.a;
    let w0 = o - s.a;
    let b = d.dot(e);
    let c = e.dot(e);
    let dd = d.dot(w0);
    let ee = e.dot(w0);
    let denom = c - b * b; // |d| = 1
    if denom <= 1e-14 * c {
        return None; // ray parallel to the fiber: it sees no width
    }
    let sp = ((ee - b * dd) / denom).clamp(0.0, 1.0);
    let pa = s.a + e * sp;
    let t = (pa - o).dot(d);
    if t <= tmin || t >= tmax {
        return None;
    }
    let pr = o + d * t;
    let off = pr - pa;
    let r = s.ra + (s.rb - s.ra) * sp;
    let dist2 = off.dot(off);
    if dist2 >= r * r {
        return None;
    }
    let u = e * (1.0 / c.sqrt());
    let ud = u.cross(d);
    let h = (off.dot(ud) / (ud.length() * r)).clamp(-1.0, 1.0);
    Some(Hit {
        t,
        p: pr,
        u,
        h,
        radius: r,
        fiber: s.fiber,
        segment: 0,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::scene::{build_lock, StrandSpec};
    use rand::{Rng, SeedableRng};

    #[test]
    fn ribbon_offset_is_signed_distance_over_radius() {
        // Fiber along +y through the origin, ray along -z at x = 0.5 r.
        let s = Segment {
            a: V3::new(0.0, -1.0, 0.0),
            b: V3::new(0.0, 1.0, 0.0),
            ra: 0.01,
            rb: 0.01,
            fiber: 3,
        };
        let d = V3::new(0.0, 0.0, -1.0);
        let hit = intersect_segment(&s, V3::new(0.005, 0.2, 5.0), d, 0.0, 1e9).unwrap();
        assert!((hit.t - 5.0).abs() < 1e-12);
        // u x d = (0,1,0) x (0,0,-1) = (-1, 0, 0): offset +x gives h = -0.5.
        assert!((hit.h + 0.5).abs() < 1e-12, "{}", hit.h);
        assert!(intersect_segment(&s, V3::new(0.011, 0.2, 5.0), d, 0.0, 1e9).is_none());
        assert!(intersect_segment(&s, V3::new(0.0, 1.5, 5.0), d, 0.0, 1e9).is_none());
    }

    #[test]
    fn bvh_matches_brute_force() {
        let segs = build_lock(&StrandSpec {
            fibers: 60,
            ..Default::default()
        });
        let bvh = Bvh::build(segs.clone());
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(1);
        let mut hits = 0;
        for _ in 0..3000 {
            let o = V3::new(
                rng.random::<f64>() * 0.6 - 0.3,
                rng.random::<f64>() * 1.2 - 0.6,
                2.0,
            );
            let d = V3::new(
                rng.random::<f64>() * 0.1 - 0.05,
                rng.random::<f64>() * 0.1 - 0.05,
                -1.0,
            )
            .normalized();
            let brute = segs
                .iter()
                .filter_map(|s| intersect_segment(s, o, d, 0.0, 1e9))
                .map(|h| h.t)
                .fold(f64::INFINITY, f64::min);
            let got = bvh
                .intersect(o, d, 0.0, 1e9, None)
                .map_or(f64::INFINITY, |h| h.t);
            assert_eq!(brute, got);
            if got.is_finite() {
                hits += 1;
                assert!(bvh.occluded(o, d, 0.0, 1e9, None));
            }
        }
        // The test must exercise hits, not only misses.
        assert!(hits > 20, "{hits}");
    }
}
