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

    /// Slab test in f64: the entry distance if the ray meets the box within (tmin, tmax).
    fn enter(&self, o: V3, inv: V3, tmin: f64, tmax: f64) -> Option<f64> {
        let (mut t0, mut t1) = (tmin, tmax);
        for a in 0..3 {
            let x0 = (self.lo.axis(a) - o.axis(a)) * inv.axis(a);
            let x1 = (self.hi.axis(a) - o.axis(a)) * inv.axis(a);
            t0 = t0.max(x0.min(x1));
            t1 = t1.min(x0.max(x1));
        }
        (t0 <= t1).then_some(t0)
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

/// Four-wide node of the traversal tree, collapsed from the binary SAH tree: the boxes of
/// up to four children in single precision, laid out axis-major so the slab test of all
/// four is a handful of 4-lane operations, and a node is exactly two cache lines (unused
/// lanes hold a box at +infinity, which no ray enters, so no lane count is stored). Boxes are
/// rounded outward (see [`PAD`]), so they stay conservative: the final segment test is in
/// f64 and hits are exactly those of a brute-force loop.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
struct Node4 {
    /// `lo[axis][lane]`, `hi[axis][lane]`.
    lo: [[f32; 4]; 3],
    hi: [[f32; 4]; 3],
    /// Interior child: its node index; leaf child: first primitive index.
    child: [u32; 4],
    /// Primitives of a leaf child; 0 for an interior child and for an unused lane.
    count: [u32; 4],
}

const _: () = assert!(std::mem::size_of::<Node4>() == 128);

/// Outward padding of the single-precision boxes (world units). The lock spans a couple of
/// units around the origin and traversal starts rays at the root box (see
/// [`Bvh::traverse`]), so coordinates and ray distances stay below ~10 and the rounding
/// of boxes, origin and slab products is a few ulp of that, ~1e-6; 1e-5 covers it ten
/// times over and loosens a box by ~2 % of a fiber tip's radius.
const PAD: f32 = 1e-5;

/// Traversal stack entries: a visit pushes at most three more than it pops, so a tree of
/// depth `D` needs `3 D + 1`; [`Bvh::build`] checks the collapsed depth against this.
const STACK: usize = 192;

/// A ray-fiber hit.
#[derive(Clone, Copy, Debug)]
pub struct Hit {
    /// Ray parameter at the closest approach (the ray's direction is unit).
    pub t: f64,
    /// Point on the ray at closest approach.
    pub p: V3,
    /// Unit fiber tangent, root to tip.
    pub u: V3,
    /// Signed offset across the fiber in [-1, 1] (see module doc).
    pub h: f64,
    /// Fiber radius at the hit (world units).
    pub radius: f64,
    /// Index of the fiber hit.
    pub fiber: u32,
    /// Index of the segment hit, into [`Bvh::segments`].
    pub segment: u32,
}

/// BVH over segments: binned-SAH binary tree collapsed to four-wide nodes, leaves of <= 4.
pub struct Bvh {
    tree: Tree,
    segs: Vec<Segment>,
}

/// A four-wide tree over the segments' pieces (see [`Bvh::build`]), in some frame.
struct Tree {
    nodes: Vec<Node4>,
    /// Bounds of everything (f64), where traversal starts its rays.
    root: Aabb,
    /// Leaf primitives in node order: index of the segment whose piece it bounds.
    prims: Vec<u32>,
}

/// A piece of a segment (see [`Bvh::build`]): axis from `p0` to `p1`, largest radius `r`.
struct Piece {
    p0: V3,
    p1: V3,
    r: f64,
    owner: u32,
}

/// The pieces of `segs`, each at most [`PIECE_RADII`] radii long.
fn pieces(segs: &[Segment]) -> Vec<Piece> {
    let mut out = Vec::new();
    for (i, s) in segs.iter().enumerate() {
        let r = s.ra.max(s.rb);
        let len = (s.b - s.a).length();
        let n = ((len / (PIECE_RADII * r.max(1e-12))).ceil() as usize).clamp(1, MAX_PIECES);
        for k in 0..n {
            out.push(Piece {
                p0: s.a + (s.b - s.a) * (k as f64 / n as f64),
                p1: s.a + (s.b - s.a) * ((k + 1) as f64 / n as f64),
                r,
                owner: i as u32,
            });
        }
    }
    out
}

impl Tree {
    /// The tree over the pieces of `segs` with their boxes in the orthonormal frame `to`
    /// maps points into (the identity for world axes).
    fn over_pieces(segs: &[Segment], to: impl Fn(V3) -> V3, area: fn(&Aabb) -> f64) -> Tree {
        let ps = pieces(segs);
        // A capsule of radius r about p0-p1 lies, in any orthonormal frame, in the box of
        // its two ends grown by r.
        let boxes: Vec<Aabb> = ps
            .iter()
            .map(|p| {
                let (q0, q1) = (to(p.p0), to(p.p1));
                let e = V3::new(p.r, p.r, p.r);
                Aabb {
                    lo: q0.min(q1) - e,
                    hi: q0.max(q1) + e,
                }
            })
            .collect();
        let owner: Vec<u32> = ps.iter().map(|p| p.owner).collect();
        Tree::build(&boxes, &owner, area)
    }

    /// Binned-SAH binary tree over `boxes` (`area` weighs a box by how likely the rays
    /// of interest meet it), collapsed to four-wide nodes.
    fn build(boxes: &[Aabb], owner: &[u32], area: fn(&Aabb) -> f64) -> Tree {
        let mut order: Vec<usize> = (0..boxes.len()).collect();
        let centers: Vec<V3> = boxes.iter().map(|b| (b.lo + b.hi) * 0.5).collect();
        let ctx = BuildCtx {
            boxes,
            centers: &centers,
            area,
        };
        let nodes = if boxes.is_empty() {
            Vec::new()
        } else {
            build_rec(&mut order, 0, &ctx)
        };
        let prims = order.iter().map(|&i| owner[i]).collect();
        let mut wide = Vec::with_capacity(nodes.len() / 2 + 1);
        if !nodes.is_empty() {
            if nodes[0].count > 0 {
                // The whole tree is one leaf: a root with one leaf lane.
                let mut root = Node4::empty();
                root.set_lane(0, &nodes[0].bounds, nodes[0].index, nodes[0].count);
                wide.push(root);
            } else {
                let (_, depth) = collapse(&nodes, 0, &mut wide, 1, area);
                // The binned SAH halves the work per level in practice (depth ~12 for the
                // default lock); 63 levels would need ~4^63 primitives.
                assert!(3 * depth < STACK, "BVH depth {depth} exceeds the stack");
            }
        }
        Tree {
            nodes: wide,
            // The binary root's bounds are the union of every piece box.
            root: nodes.first().map_or(Aabb::empty(), |n| n.bounds),
            prims,
        }
    }
}

/// Shadow rays toward a directional light all travel along one direction `d`. In a frame
/// whose z axis is `d` each is a point `(x, y)` moving towards +z, so a tree built in that
/// frame tests a box with comparisons only (no slab products), and its SAH weighs boxes by
/// their area projected along `d` (the chance such a ray meets them) instead of their
/// surface area. Leaves hold the same pieces and the segment test is the same f64 test
/// as [`Bvh::occluded`], so [`Bvh::occluded_along`] gives exactly its answer.
pub struct DirTree {
    dir: V3,
    /// Rows of the rotation into the frame (`axes[2] = dir`).
    axes: [V3; 3],
    tree: Tree,
}

impl DirTree {
    /// The direction the tree was built along (toward the light).
    pub fn dir(&self) -> V3 {
        self.dir
    }
}

/// Leaves hold at most this many pieces.
const LEAF: usize = 4;
/// Binned SAH: bins per axis.
const BINS: usize = 12;
/// A segment is bounded by pieces at most this many radii long (see [`Bvh::build`]).
const PIECE_RADII: f64 = 10.0;
const MAX_PIECES: usize = 32;

impl Aabb {
    /// Surface area: the SAH weight of a box for rays in all directions.
    fn area(&self) -> f64 {
        let e = self.hi - self.lo;
        if e.x < 0.0 {
            return 0.0;
        }
        2.0 * (e.x * e.y + e.y * e.z + e.z * e.x)
    }

    /// Area projected along z: the SAH weight for rays along z ([`DirTree`]).
    fn projected_area(&self) -> f64 {
        let e = self.hi - self.lo;
        if e.x < 0.0 {
            return 0.0;
        }
        e.x * e.y
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
        Bvh {
            tree: Tree::over_pieces(&segs, |p| p, Aabb::area),
            segs,
        }
    }

    /// The tree for rays along `dir` ([`DirTree`]).
    pub fn dir_tree(&self, dir: V3) -> DirTree {
        let z = dir.normalized();
        // Any unit vector perpendicular to z completes the frame.
        let helper = if z.x.abs() < 0.9 {
            V3::new(1.0, 0.0, 0.0)
        } else {
            V3::new(0.0, 1.0, 0.0)
        };
        let x = helper.cross(z).normalized();
        let axes = [x, z.cross(x), z];
        let to = |p: V3| V3::new(p.dot(axes[0]), p.dot(axes[1]), p.dot(axes[2]));
        DirTree {
            dir,
            axes,
            tree: Tree::over_pieces(&self.segs, to, Aabb::projected_area),
        }
    }

    /// [`Self::occluded`] for a ray along `t.dir()` from `o`, traversing `t`.
    pub fn occluded_along(
        &self,
        t: &DirTree,
        o: V3,
        tmin: f64,
        tmax: f64,
        skip: Option<u32>,
    ) -> bool {
        let tree = &t.tree;
        if tree.nodes.is_empty() {
            return false;
        }
        let q = [0, 1, 2].map(|a| o.dot(t.axes[a]));
        let (x, y) = (q[0] as f32, q[1] as f32);
        // The ray covers z in [q + tmin, q + tmax]; boxes are padded, so comparing against
        // the rounded ends stays conservative.
        let zlo = (q[2] + tmin) as f32 - PAD;
        let zhi = ((q[2] + tmax) as f32 + PAD).min(f32::MAX);
        let mut stack = [0u32; STACK];
        let mut sp = 1;
        let mut last = u32::MAX;
        while sp > 0 {
            sp -= 1;
            let node = &tree.nodes[stack[sp] as usize];
            let hit = node.contains_column(x, y, zlo, zhi);
            for lane in 0..4 {
                if !hit[lane] {
                    continue;
                }
                let count = node.count[lane];
                if count == 0 {
                    stack[sp] = node.child[lane];
                    sp += 1;
                    continue;
                }
                let first = node.child[lane] as usize;
                let leaf = &tree.prims[first..first + count as usize];
                for (_, s) in self.leaf_segments(leaf, &mut last, skip) {
                    if intersect_segment(s, o, t.dir, tmin, tmax).is_some() {
                        return true;
                    }
                }
            }
        }
        false
    }

    /// The segments a leaf's pieces name, each with its index, to be tested against a
    /// ray: neighbouring pieces of one segment share leaves, so a segment just tested
    /// (`last`, carried across leaves) is skipped, and so is the fiber `skip` a path
    /// leaves.
    #[inline(always)]
    fn leaf_segments<'a>(
        &'a self,
        leaf: &'a [u32],
        last: &'a mut u32,
        skip: Option<u32>,
    ) -> impl Iterator<Item = (u32, &'a Segment)> + 'a {
        leaf.iter().filter_map(move |&si| {
            if si == *last {
                return None;
            }
            *last = si;
            let s = &self.segs[si as usize];
            (Some(s.fiber) != skip).then_some((si, s))
        })
    }

    /// The segments, in the order [`Hit::segment`] indexes them.
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
        let Tree { nodes, root, prims } = &self.tree;
        if nodes.is_empty() {
            return None;
        }
        // The f32 slab tests run from the ray's entry into the root box (`shift` along the
        // ray), so a far camera does not cost them precision; distances below are relative
        // to it. Segment tests and hits stay in f64 from the true origin.
        let inv64 = V3::new(safe_inv(d.x), safe_inv(d.y), safe_inv(d.z));
        let shift = match root.enter(o, inv64, tmin, tmax) {
            Some(t) => t.max(tmin),
            None => return None,
        };
        let os = o + d * shift;
        let of = [os.x as f32, os.y as f32, os.z as f32];
        let inv = [inv64.x as f32, inv64.y as f32, inv64.z as f32];
        let tmin32 = (tmin - shift) as f32 - PAD;
        // Entry distance stored with each pushed node: popped nodes farther than the
        // closest hit so far are skipped without touching their memory.
        let mut stack = [(0u32, 0f32); STACK];
        stack[0] = (0, tmin32);
        let mut sp = 1;
        let mut best: Option<Hit> = None;
        // The last segment tested (neighbouring pieces of one segment share leaves).
        let mut last = u32::MAX;
        while sp > 0 {
            sp -= 1;
            let (ni, tentry) = stack[sp];
            if f64::from(tentry) > tmax - shift {
                continue;
            }
            let node = &nodes[ni as usize];
            // Finite, so an unused lane's box at +infinity is never entered.
            let tmax32 = (((tmax - shift) as f32) * (1.0 + 1e-6) + PAD).min(f32::MAX);
            let (t0, hit) = node.slab(&of, &inv, tmin32, tmax32);
            // Hit lanes sorted by entry distance (at most four: insertion sort).
            let mut lanes = [0usize; 4];
            let mut k = 0;
            for lane in 0..4 {
                if !hit[lane] {
                    continue;
                }
                let mut j = k;
                while j > 0 && t0[lanes[j - 1]] > t0[lane] {
                    lanes[j] = lanes[j - 1];
                    j -= 1;
                }
                lanes[j] = lane;
                k += 1;
            }
            // Leaves first, nearest first (a hit shrinks tmax for the rest); interior
            // children pushed farthest first so the nearest is popped next.
            for &lane in &lanes[..k] {
                let count = node.count[lane];
                if count == 0 {
                    continue;
                }
                let first = node.child[lane] as usize;
                let leaf = &prims[first..first + count as usize];
                for (si, s) in self.leaf_segments(leaf, &mut last, skip) {
                    if let Some(mut hit) = intersect_segment(s, o, d, tmin, tmax) {
                        hit.segment = si;
                        tmax = hit.t;
                        best = Some(hit);
                        if any {
                            return best;
                        }
                    }
                }
            }
            for &lane in lanes[..k].iter().rev() {
                if node.count[lane] == 0 {
                    stack[sp] = (node.child[lane], t0[lane]);
                    sp += 1;
                }
            }
        }
        best
    }
}

impl Node4 {
    fn empty() -> Node4 {
        Node4 {
            // A point at +infinity: every slab gives +inf or -inf for both planes, so
            // the lane misses any ray whose tmax is finite (traverse clamps it).
            lo: [[f32::INFINITY; 4]; 3],
            hi: [[f32::INFINITY; 4]; 3],
            child: [0; 4],
            count: [0; 4],
        }
    }

    /// Store `b` in `lane` in f32, padded outward by [`PAD`].
    fn set_lane(&mut self, lane: usize, b: &Aabb, child: u32, count: u32) {
        for a in 0..3 {
            self.lo[a][lane] = b.lo.axis(a) as f32 - PAD;
            self.hi[a][lane] = b.hi.axis(a) as f32 + PAD;
        }
        self.child[lane] = child;
        self.count[lane] = count;
    }

    /// Which lanes' boxes meet the column `(x, y) x [zlo, zhi]` (a ray along +z of the
    /// box frame; an unused lane's box at +infinity never does).
    #[inline(always)]
    fn contains_column(&self, x: f32, y: f32, zlo: f32, zhi: f32) -> [bool; 4] {
        std::array::from_fn(|l| {
            (self.lo[0][l] <= x)
                & (x <= self.hi[0][l])
                & (self.lo[1][l] <= y)
                & (y <= self.hi[1][l])
                & (self.hi[2][l] >= zlo)
                & (self.lo[2][l] <= zhi)
        })
    }

    /// Slab test of the four lanes: entry distances and hit flags (an unused lane's box at
    /// +infinity never hits while `tmax` is finite). Written lane-wise over fixed
    /// arrays so it compiles to 4-wide SSE.
    #[inline(always)]
    fn slab(&self, o: &[f32; 3], inv: &[f32; 3], tmin: f32, tmax: f32) -> ([f32; 4], [bool; 4]) {
        let mut t0 = [tmin; 4];
        let mut t1 = [tmax; 4];
        for a in 0..3 {
            for l in 0..4 {
                let x0 = (self.lo[a][l] - o[a]) * inv[a];
                let x1 = (self.hi[a][l] - o[a]) * inv[a];
                t0[l] = fmax32(t0[l], fmin32(x0, x1));
                t1[l] = fmin32(t1[l], fmax32(x0, x1));
            }
        }
        let mut hit = [false; 4];
        for l in 0..4 {
            hit[l] = t0[l] <= t1[l];
        }
        (t0, hit)
    }
}

#[inline(always)]
fn fmin32(a: f32, b: f32) -> f32 {
    if a < b {
        a
    } else {
        b
    }
}

#[inline(always)]
fn fmax32(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

/// `1 / x` with |x| clamped to >= 1e-30, so the reciprocal stays finite (<= 1e30) also
/// in f32 and `0 * inv` is never NaN in a slab test.
#[inline(always)]
fn safe_inv(x: f64) -> f64 {
    1.0 / if x.abs() < 1e-30 {
        1e-30f64.copysign(x)
    } else {
        x
    }
}

/// Collapse the binary subtree at interior node `i` into four-wide nodes appended to
/// `out`; returns the index of the new node. Each wide node takes the binary node's two
/// children and repeatedly opens the interior child of largest surface area until it has
/// four lanes or only leaves. Returns the new node's index and the depth of its subtree
/// counted from `depth` (the new node's own level).
fn collapse(
    nodes: &[Node],
    i: usize,
    out: &mut Vec<Node4>,
    depth: usize,
    area: fn(&Aabb) -> f64,
) -> (u32, usize) {
    let mut kids: Vec<usize> = vec![i + 1, nodes[i].index as usize];
    while kids.len() < 4 {
        let open = kids
            .iter()
            .enumerate()
            .filter(|(_, &c)| nodes[c].count == 0)
            .max_by(|a, b| area(&nodes[*a.1].bounds).total_cmp(&area(&nodes[*b.1].bounds)))
            .map(|(k, _)| k);
        let Some(k) = open else { break };
        let c = kids.swap_remove(k);
        kids.push(c + 1);
        kids.push(nodes[c].index as usize);
    }
    let me = out.len();
    out.push(Node4::empty());
    let mut node = Node4::empty();
    let mut deepest = depth;
    for (lane, &c) in kids.iter().enumerate() {
        if nodes[c].count > 0 {
            node.set_lane(lane, &nodes[c].bounds, nodes[c].index, nodes[c].count);
        } else {
            let (child, d) = collapse(nodes, c, out, depth + 1, area);
            deepest = deepest.max(d);
            node.set_lane(lane, &nodes[c].bounds, child, 0);
        }
    }
    out[me] = node;
    (me as u32, deepest)
}

/// What [`build_rec`] reads: the piece boxes, their centres and the SAH area weight.
struct BuildCtx<'a> {
    boxes: &'a [Aabb],
    centers: &'a [V3],
    area: fn(&Aabb) -> f64,
}

/// Subtrees with more primitives than this build their two halves in parallel.
const PARALLEL_BUILD: usize = 4096;

/// Binary SAH subtree over `order` (primitives `first..` in leaf order), in depth-first
/// order with interior `index` fields relative to the returned vector's start.
fn build_rec(order: &mut [usize], first: usize, ctx: &BuildCtx) -> Vec<Node> {
    let BuildCtx {
        boxes,
        centers,
        area,
    } = *ctx;
    let bounds = order.iter().fold(Aabb::empty(), |b, &i| b.union(boxes[i]));
    let mut nodes = vec![Node {
        bounds,
        index: first as u32,
        count: order.len() as u32,
    }];
    if order.len() <= LEAF {
        return nodes;
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
            right_area[k] = area(&acc);
            right_cnt[k] = n;
        }
        let (mut acc, mut n) = (Aabb::empty(), 0);
        for k in 1..BINS {
            acc = acc.union(bb[k - 1]);
            n += cnt[k - 1];
            if n == 0 || right_cnt[k] == 0 {
                continue;
            }
            let cost = n as f64 * area(&acc) + right_cnt[k] as f64 * right_area[k];
            if best.is_none_or(|b| cost < b.0) {
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
    let big = order.len() > PARALLEL_BUILD;
    let (left, right) = order.split_at_mut(mid);
    let (l, r) = if big {
        rayon::join(
            || build_rec(left, first, ctx),
            || build_rec(right, first + mid, ctx),
        )
    } else {
        (
            build_rec(left, first, ctx),
            build_rec(right, first + mid, ctx),
        )
    };
    // Left child at 1, right child after the left subtree; shift the children's relative
    // interior links by where they land.
    nodes[0].index = (1 + l.len()) as u32;
    nodes[0].count = 0;
    for (base, sub) in [(1, l), (nodes[0].index as usize, r)] {
        nodes.extend(sub.into_iter().map(|mut n| {
            if n.count == 0 {
                n.index += base as u32;
            }
            n
        }));
    }
    nodes
}

/// The hit of the unit ray `o + t d`, `t` in `(tmin, tmax)`, with segment `s`: at the ray's
/// closest approach to the segment's axis, inside the radius interpolated from `ra` to `rb`
/// (`segment` left 0 for the caller).
#[inline(always)]
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

    /// A 60-fiber lock and its BVH.
    fn small_lock() -> (Vec<Segment>, Bvh) {
        let segs = build_lock(&StrandSpec {
            fibers: 60,
            ..Default::default()
        });
        let bvh = Bvh::build(segs.clone());
        (segs, bvh)
    }

    /// A direction uniform on the unit sphere.
    fn random_dir(rng: &mut impl Rng) -> V3 {
        let z: f64 = rng.random::<f64>() * 2.0 - 1.0;
        let a = rng.random::<f64>() * std::f64::consts::TAU;
        let r = (1.0 - z * z).sqrt();
        V3::new(r * a.cos(), r * a.sin(), z)
    }

    /// Closest hit distance by testing every segment (infinite on a miss).
    fn brute_t(segs: &[Segment], o: V3, d: V3, tmin: f64, tmax: f64, skip: Option<u32>) -> f64 {
        segs.iter()
            .filter(|q| Some(q.fiber) != skip)
            .filter_map(|q| intersect_segment(q, o, d, tmin, tmax))
            .map(|h| h.t)
            .fold(f64::INFINITY, f64::min)
    }

    /// The BVH's closest hit equals the brute-force one and `occluded` agrees with it;
    /// returns the hit distance (infinite on a miss).
    fn check_ray(
        segs: &[Segment],
        bvh: &Bvh,
        o: V3,
        d: V3,
        (tmin, tmax): (f64, f64),
        skip: Option<u32>,
    ) -> f64 {
        let brute = brute_t(segs, o, d, tmin, tmax, skip);
        let got = bvh
            .intersect(o, d, tmin, tmax, skip)
            .map_or(f64::INFINITY, |h| h.t);
        assert_eq!(brute, got, "ray {o:?} {d:?}");
        assert_eq!(bvh.occluded(o, d, tmin, tmax, skip), got.is_finite());
        got
    }

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
        let (segs, bvh) = small_lock();
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
            let got = check_ray(&segs, &bvh, o, d, (0.0, 1e9), None);
            hits += usize::from(got.is_finite());
        }
        // The test must exercise hits, not only misses.
        assert!(hits > 20, "{hits}");
    }

    /// Rays built to pass a segment's axis at `(1 - 1e-6)` of its radius (along the common
    /// perpendicular, so that is exactly the closest approach `intersect_segment` tests),
    /// from near and far and at every angle to the segment, including near-parallel ones:
    /// the f32 boxes must keep every such grazing hit.
    #[test]
    fn bvh_keeps_grazing_hits() {
        // Untapered copies of the lock's segments: the radius is the same all along, so
        // the grazing distance is also within 1e-6 of the largest radius, which the piece
        // boxes are built from.
        let segs: Vec<Segment> = small_lock()
            .0
            .into_iter()
            .map(|s| Segment { rb: s.ra, ..s })
            .collect();
        let bvh = Bvh::build(segs.clone());
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(5);
        let mut checked = 0;
        while checked < 4000 {
            let s = &segs[rng.random_range(0..segs.len())];
            let e = s.b - s.a;
            let sp: f64 = rng.random_range(0.05..0.95);
            let d = random_dir(&mut rng);
            let n = e.cross(d);
            if n.length() < 1e-3 * e.length() {
                continue; // parallel: the ribbon has no width
            }
            let side = if rng.random::<bool>() { 1.0 } else { -1.0 };
            let r = s.ra + (s.rb - s.ra) * sp;
            let x = s.a + e * sp + n.normalized() * (side * r * (1.0 - 1e-6));
            let o = x - d * 10f64.powf(rng.random_range(-2.0..3.0));
            let got = check_ray(&segs, &bvh, o, d, (0.0, f64::INFINITY), None);
            assert!(got.is_finite(), "the constructed ray must hit");
            checked += 1;
        }
    }

    /// A camera thousands of units away: the f32 traversal starts at the root box, so
    /// distant origins lose no hits.
    #[test]
    fn bvh_matches_brute_force_from_far_away() {
        let (segs, bvh) = small_lock();
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(3);
        let mut hits = 0;
        for _ in 0..3000 {
            let target = V3::new(
                rng.random::<f64>() * 0.6 - 0.3,
                rng.random::<f64>() * 1.2 - 0.6,
                rng.random::<f64>() * 0.2 - 0.1,
            );
            let d =
                V3::new(rng.random::<f64>() - 0.5, rng.random::<f64>() - 0.5, -1.0).normalized();
            let o = target - d * 1e4;
            let got = check_ray(&segs, &bvh, o, d, (0.0, f64::INFINITY), None);
            hits += usize::from(got.is_finite());
        }
        assert!(hits > 20, "{hits}");
    }

    /// Secondary and shadow rays start inside the lock and go anywhere: the f32 boxes must
    /// stay conservative for every direction, including axis-aligned ones.
    #[test]
    fn bvh_matches_brute_force_from_inside_in_all_directions() {
        let (segs, bvh) = small_lock();
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(2);
        let mut hits = 0;
        for k in 0..4000 {
            // Start on a segment's axis (where scattering vertices are), skipping its fiber.
            let s = &segs[rng.random_range(0..segs.len())];
            let o = s.a + (s.b - s.a) * rng.random::<f64>();
            let d = if k % 8 == 0 {
                // Axis-aligned: zero direction components exercise the reciprocal clamp.
                let mut v = [0.0; 3];
                v[k / 8 % 3] = if k % 16 == 0 { 1.0 } else { -1.0 };
                V3::new(v[0], v[1], v[2])
            } else {
                random_dir(&mut rng)
            };
            let got = check_ray(&segs, &bvh, o, d, (1e-9, 1e9), Some(s.fiber));
            hits += usize::from(got.is_finite());
        }
        assert!(hits > 200, "{hits}");
    }

    /// Shadow rays along one direction through the direction's own tree: the same answer
    /// as a brute-force loop for origins on fibers (skipping their fiber), off the lock and
    /// far away, for directions along the axes and in general position.
    #[test]
    fn dir_tree_matches_brute_force() {
        let (segs, bvh) = small_lock();
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(9);
        let mut dirs = vec![
            V3::new(-0.5, 0.6, 0.62).normalized(),
            V3::new(1.0, 0.0, 0.0),
            V3::new(0.0, -1.0, 0.0),
            V3::new(0.0, 0.0, 1.0),
        ];
        for _ in 0..4 {
            dirs.push(random_dir(&mut rng));
        }
        let (mut blocked, mut total) = (0, 0);
        for d in dirs {
            let tree = bvh.dir_tree(d);
            for k in 0..1500 {
                let s = &segs[rng.random_range(0..segs.len())];
                let (o, skip, tmax) = match k % 3 {
                    0 | 1 => (s.a + (s.b - s.a) * rng.random::<f64>(), Some(s.fiber), 1e9),
                    // Off the lock, towards it from up to 1e3 units away, bounded tmax.
                    _ => {
                        let dist = 10f64.powf(rng.random_range(-1.0..3.0));
                        (s.a - d * dist, None, dist * rng.random_range(0.5..1.5))
                    }
                };
                let brute = brute_t(&segs, o, d, 1e-9, tmax, skip).is_finite();
                assert_eq!(
                    bvh.occluded_along(&tree, o, 1e-9, tmax, skip),
                    brute,
                    "ray {o:?} {d:?}"
                );
                assert_eq!(bvh.occluded(o, d, 1e-9, tmax, skip), brute);
                blocked += usize::from(brute);
                total += 1;
            }
        }
        // Both answers must be exercised.
        assert!(
            blocked > total / 10 && blocked < total * 9 / 10,
            "{blocked}/{total}"
        );
    }
}
