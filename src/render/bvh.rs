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
    fn of(s: &Segment) -> Aabb {
        let r = s.ra.max(s.rb);
        let e = V3::new(r, r, r);
        Aabb {
            lo: s.a.min(s.b) - e,
            hi: s.a.max(s.b) + e,
        }
    }
    fn union(self, o: Aabb) -> Aabb {
        Aabb {
            lo: self.lo.min(o.lo),
            hi: self.hi.max(o.hi),
        }
    }
    /// Slab test; returns the entry distance if the box is hit within (tmin, tmax).
    #[inline]
    fn hit(&self, o: V3, inv: V3, tmin: f64, tmax: f64) -> Option<f64> {
        let mut t0 = tmin;
        let mut t1 = tmax;
        for a in 0..3 {
            let (oa, ia) = (o.axis(a), inv.axis(a));
            let mut ta = (self.lo.axis(a) - oa) * ia;
            let mut tb = (self.hi.axis(a) - oa) * ia;
            if ta > tb {
                std::mem::swap(&mut ta, &mut tb);
            }
            // NaN (0 * inf) compares false and leaves the bound unchanged.
            if ta > t0 {
                t0 = ta;
            }
            if tb < t1 {
                t1 = tb;
            }
            if t0 > t1 {
                return None;
            }
        }
        Some(t0)
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
}

const LEAF: usize = 4;

impl Bvh {
    pub fn build(segs: Vec<Segment>) -> Bvh {
        let mut order: Vec<usize> = (0..segs.len()).collect();
        let boxes: Vec<Aabb> = segs.iter().map(Aabb::of).collect();
        let centers: Vec<V3> = boxes.iter().map(|b| (b.lo + b.hi) * 0.5).collect();
        let mut nodes = Vec::with_capacity(2 * segs.len() / LEAF + 1);
        if !segs.is_empty() {
            build_rec(&mut nodes, &mut order, 0, &boxes, &centers);
        }
        let segs = order.iter().map(|&i| segs[i]).collect();
        Bvh { nodes, segs }
    }

    pub fn segments(&self) -> &[Segment] {
        &self.segs
    }

    /// Closest hit in (tmin, tmax), ignoring fiber `skip` (the fiber the ray leaves: a
    /// fiber's BCSDF already contains its internal paths, so it cannot shadow itself).
    pub fn intersect(&self, o: V3, d: V3, tmin: f64, tmax: f64, skip: Option<u32>) -> Option<Hit> {
        self.traverse(o, d, tmin, tmax, skip, false)
    }

    /// Is anything hit in (tmin, tmax)? (Shadow rays.)
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
        let inv = V3::new(1.0 / d.x, 1.0 / d.y, 1.0 / d.z);
        let mut stack = [0u32; 64];
        let mut sp = 1;
        let mut best: Option<Hit> = None;
        while sp > 0 {
            sp -= 1;
            let node = &self.nodes[stack[sp] as usize];
            if node.bounds.hit(o, inv, tmin, tmax).is_none() {
                continue;
            }
            if node.count > 0 {
                let first = node.index as usize;
                for (k, s) in self.segs[first..first + node.count as usize]
                    .iter()
                    .enumerate()
                {
                    if Some(s.fiber) == skip {
                        continue;
                    }
                    if let Some(mut hit) = intersect_segment(s, o, d, tmin, tmax) {
                        hit.segment = (first + k) as u32;
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
                // Visit the nearer child first.
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
    let (left, right) = order.split_at_mut(mid);
    build_rec(nodes, left, first, boxes, centers);
    let r = build_rec(nodes, right, first + mid, boxes, centers);
    nodes[me].index = r as u32;
    nodes[me].count = 0;
    me
}

/// Ray vs camera-facing ribbon around segment `s` (see module doc).
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
