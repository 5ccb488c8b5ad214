//! Locating a value on a table axis: clamped, uniform, periodic and cubic Hermite.

use std::f64::consts::PI;

/// Index and fraction of `v` on an increasing axis, clamped to the ends.
#[inline]
pub(super) fn locate(axis: &[f64], v: f64) -> (usize, f64) {
    let n = axis.len();
    if v.is_nan() || v <= axis[0] {
        return (0, 0.0);
    }
    if v >= axis[n - 1] {
        return (n - 2, 1.0);
    }
    let i = axis.partition_point(|&a| a <= v).clamp(1, n - 1) - 1;
    (i, (v - axis[i]) / (axis[i + 1] - axis[i]))
}

/// Nodes and weights of the cubic Hermite interpolant of a function sampled on `axis`
/// (at least two nodes), at `v`: `f(v) = sum_q w[q] f[nodes[q]]`. The slopes at the nodes
/// are centred differences (one-sided at the ends), so the interpolant passes through
/// every node and is continuously differentiable (Catmull-Rom for uniform nodes); it is
/// constant beyond the ends, like [`locate`]. Unused entries have weight 0.
#[inline]
pub(super) fn hermite_stencil(axis: &[f64], v: f64) -> ([usize; 4], [f64; 4]) {
    let n = axis.len();
    let (i, t) = locate(axis, v);
    let (h00, h10, h01, h11) = (
        (1.0 + 2.0 * t) * (1.0 - t) * (1.0 - t),
        t * (1.0 - t) * (1.0 - t),
        t * t * (3.0 - 2.0 * t),
        t * t * (t - 1.0),
    );
    let dx = axis[i + 1] - axis[i];
    let (lo, hi) = (i.saturating_sub(1), (i + 2).min(n - 1));
    let mut nodes = [lo, i, i + 1, hi];
    let mut w = [0.0, h00, h01, 0.0];
    // Slope at node i: (f[i+1] - f[lo]) / (x[i+1] - x[lo]), scaled by dx h10.
    let c = dx * h10 / (axis[i + 1] - axis[lo]);
    w[2] += c;
    if lo == i {
        w[1] -= c;
    } else {
        w[0] -= c;
    }
    // Slope at node i+1: (f[hi] - f[i]) / (x[hi] - x[i]), scaled by dx h11.
    let c = dx * h11 / (axis[hi] - axis[i]);
    w[1] -= c;
    if hi == i + 1 {
        w[2] += c;
        nodes[3] = i + 1;
    } else {
        w[3] += c;
    }
    (nodes, w)
}

/// Periodic location of `psi` among `n` uniform bin centres starting at `c0` (step `d`).
#[inline]
pub(super) fn locate_periodic(c0: f64, d: f64, n: usize, psi: f64) -> (usize, usize, f64) {
    locate_periodic_u((psi - c0) / d, n)
}

/// [`locate_periodic`] from the position `u` in bins.
#[inline]
pub(super) fn locate_periodic_u(u: f64, n: usize) -> (usize, usize, f64) {
    // floor by truncation and a correction, and the wrap by one period when `u` is within
    // a period of the table (wrapped angles, or grid positions a little beyond), else by
    // a remainder: this runs per (node, phi) in the far field's scattered sum, where a
    // libm floor call and two integer divisions were a tenth of the synthesis time.
    let k = floor_i64(u);
    let f = u - k as f64;
    let n = n as i64;
    let k0 = if (0..n).contains(&k) {
        k
    } else if (-n..0).contains(&k) {
        k + n
    } else if (n..2 * n).contains(&k) {
        k - n
    } else {
        k.rem_euclid(n)
    };
    let k1 = if k0 + 1 == n { 0 } else { k0 + 1 };
    (k0 as usize, k1 as usize, f)
}

/// `floor(u)` by truncation and a correction: cheaper than a libm `floor` call on the
/// baseline target, and the table lookups run it per (node, phi).
#[inline]
pub(super) fn floor_i64(u: f64) -> i64 {
    let k = u as i64;
    if k as f64 > u {
        k - 1
    } else {
        k
    }
}

/// Location of `t` among `n` uniform bin centres, constant beyond the end centres.
#[inline]
pub(super) fn locate_uniform(c0: f64, d: f64, n: usize, t: f64) -> (usize, f64) {
    let u = ((t - c0) / d).clamp(0.0, (n - 1) as f64);
    let k = (u.floor() as usize).min(n - 2);
    (k, u - k as f64)
}

/// Wrap an angle to `(-pi, pi]`.
#[inline]
pub fn wrap_pi(a: f64) -> f64 {
    let mut w = a.rem_euclid(2.0 * PI);
    if w > PI {
        w -= 2.0 * PI;
    }
    w
}
