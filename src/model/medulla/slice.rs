//! Queries of the tables at one `(tau, g)`: `MedullaSlice`, its node grid, the `C^N`
//! profile at one offset and the importance sampler.

use super::grid::{locate, locate_periodic, locate_periodic_u, locate_uniform, wrap_pi};
use super::rows::CnRows;
use super::tables::{CpTable, MedullaTables, Side};
use std::f64::consts::{FRAC_PI_2, PI};
use std::sync::{Arc, OnceLock};

/// The tables at one `(tau, g)`: per-rank weights plus shared factors.
#[derive(Clone, Debug)]
pub struct MedullaSlice {
    /// The medulla's scattering optical thickness `tau` at which the tables were sliced.
    pub tau: f64,
    /// The Henyey-Greenstein anisotropy `g` at which the tables were sliced.
    pub g: f64,
    pub(super) wn: Vec<f64>,
    pub(super) wm: [Vec<f64>; 2],
    pub(super) cn: Arc<CpTable>,
    pub(super) cm: [Arc<CpTable>; 2],
    /// Node values of the slice (built on first query, see [`SliceNodes`]).
    nodes: OnceLock<Arc<SliceNodes>>,
    pub(super) sampler: OnceLock<Arc<MedullaSampler>>,
}

/// The slice's values at the table nodes of its two remaining modes: `C^N` shape at every
/// (`x` node, `psi` bin) and `C^M` at every (`theta_i` node, `theta_r` bin) per side.
/// Contracting the ranks once per `(tau, g)` (2 x 16 x 180 x rank multiply-adds, 0.24 ms
/// measured at rank 48) makes every later query a bilinear lerp whose cost does not
/// depend on the rank; the values are the same bilinear interpolation as the rank sum of
/// lerped factors ([`MedullaSlice::cn_compressed`]), up to rounding (tested), except that
/// every node is floored at [`NODE_FLOOR`] of its row's peak. The 4-D tables themselves are
/// never expanded.
#[derive(Debug)]
struct SliceNodes {
    cn: Vec<f64>,
    n_psi: usize,
    /// Per `x` node: `psi` integral of its (floored, periodic piecewise-linear) row.
    cn_mass: Vec<f64>,
    /// Largest `C^N` node value, and per `x` node `i` the largest `|R_{i+1} - R_i|`.
    cn_peak: f64,
    cn_gap: Vec<f64>,
    /// Per `x` node: the largest slope `|dR_i / dpsi|` of its row (periodic).
    cn_slope: Vec<f64>,
    cm: [Vec<f64>; 2],
    n_tr: usize,
}

/// Floor of the slice nodes relative to the peak of their row (one `x` of `C^N`, one
/// `theta_i` and side of `C^M`). The compression leaves small negative or near-zero values
/// where the true density is small but positive (grazing `theta_r`, the `C^N` tails);
/// clamping those to 0 made the model exactly 0 there (e.g. at `phi = pi` only the back
/// side of `C^M` counts), and one such sample dominates a log-space NRMSE (the deer
/// profile: 5.8 % at its true parameters, 3.1 % with a table whose zeros fell elsewhere).
/// `1e-3` of the peak is below the tables' own error (~3 % of the peak) and adds at most
/// `1e-3` of the peak times the row's width to the row's mass.
pub const NODE_FLOOR: f64 = 1e-3;

impl SliceNodes {
    fn new(s: &MedullaSlice) -> SliceNodes {
        let grid = |t: &CpTable, w: &[f64]| -> (Vec<f64>, usize) {
            let n = t.axes[3].len();
            let mut v = Vec::with_capacity(t.axes[2].len() * n);
            for i in 0..t.axes[2].len() {
                let row: Vec<f64> = (0..n).map(|k| t.node23(w, i, k)).collect();
                let floor = NODE_FLOOR * row.iter().fold(0.0f64, |a, &b| a.max(b));
                v.extend(row.into_iter().map(|x| x.max(floor)));
            }
            (v, n)
        };
        let (cn, n_psi) = grid(&s.cn, &s.wn);
        let (_, d, _) = s.cn.last_axis();
        let cn_mass = cn
            .chunks_exact(n_psi)
            .map(|r| d * r.iter().sum::<f64>())
            .collect();
        let cn_peak = cn.iter().fold(0.0f64, |a, &b| a.max(b));
        let rows: Vec<&[f64]> = cn.chunks_exact(n_psi).collect();
        let cn_gap = rows
            .windows(2)
            .map(|w| {
                w[0].iter()
                    .zip(w[1])
                    .fold(0.0f64, |a, (x, y)| a.max((y - x).abs()))
            })
            .collect();
        let cn_slope = rows
            .iter()
            .map(|r| {
                (0..r.len()).fold(0.0f64, |a, k| a.max((r[(k + 1) % r.len()] - r[k]).abs())) / d
            })
            .collect();
        let (cm0, n_tr) = grid(&s.cm[0], &s.wm[0]);
        let (cm1, _) = grid(&s.cm[1], &s.wm[1]);
        SliceNodes {
            cn,
            n_psi,
            cn_mass,
            cn_peak,
            cn_gap,
            cn_slope,
            cm: [cm0, cm1],
            n_tr,
        }
    }

    /// Bilinear interpolation of a `[node][bin]` grid with `n` bins per node.
    #[inline]
    fn lerp2(v: &[f64], n: usize, i: usize, fi: f64, k0: usize, k1: usize, fk: f64) -> f64 {
        let (r0, r1) = (&v[i * n..(i + 1) * n], &v[(i + 1) * n..(i + 2) * n]);
        let a = r0[k0] + fk * (r0[k1] - r0[k0]);
        let b = r1[k0] + fk * (r1[k1] - r1[k0]);
        a + fi * (b - a)
    }
}

/// Seed Eq. 19's blend of the front and back `C^M` values: `lerp(front, back, |phi| / pi)`.
#[inline]
pub fn front_back_lerp(front: f64, back: f64, phi: f64) -> f64 {
    let t = wrap_pi(phi).abs() / PI;
    front + t * (back - front)
}

/// Analytic probability that a chord at offset `x` scatters at least once.
///
/// The chord is the cross-section's (`theta = 0`), as the seed's `C^N` tables are built:
/// MODEL.md parameterises `C^N` by `tau` alone. The unscattered medulla transmittance
/// `T_m` uses the tilted path (`/ cos theta_d`, MODEL.md), so at `theta_d != 0`
/// `T_m + P_s < 1` and TTs/TRTs are weaker than an energy balance would make them (for a
/// thin medulla up to 20-30 % at `theta_d` 45-60 degrees; under 2 % when the medulla is
/// optically thick, as for the red fox). Kept as the spec and the seed have it; using
/// `tau sqrt(1 - x^2) / cos theta_d` here would be the consistent alternative.
#[inline]
pub fn scatter_probability(tau: f64, x: f64) -> f64 {
    let half = (1.0 - x * x).max(0.0).sqrt();
    -(-2.0 * tau * half).exp_m1()
}

impl MedullaSlice {
    fn nodes(&self) -> &SliceNodes {
        self.nodes.get_or_init(|| Arc::new(SliceNodes::new(self)))
    }

    /// Normalised `C^N` shape (integrates to ~1 over psi), unclamped. Negative `x` reads
    /// the table at `|x|` with `psi` flipped (mirror symmetry of the cross-section). The
    /// sign test includes `-0.0`: the Monte-Carlo row at `x = 0` is even in `psi` only up
    /// to noise, and the far field's node at `h = 0` must take its `h -> 0+` value in the
    /// direct part and its `h -> 0-` value (flipped) in the mirrored part, or the far field
    /// stops being even in `phi` (it was off by up to 1e-2 of the lobe peak).
    #[inline]
    fn cn_shape(&self, x: f64, psi: f64) -> f64 {
        let (x, psi) = if x.is_sign_negative() {
            (-x, -psi)
        } else {
            (x, psi)
        };
        let t = &*self.cn;
        let (i, fi) = locate(&t.axes[2], x);
        let (c0, d, n) = t.last_axis();
        let (k0, k1, fk) = locate_periodic(c0, d, n, psi);
        let nodes = self.nodes();
        SliceNodes::lerp2(&nodes.cn, nodes.n_psi, i, fi, k0, k1, fk)
    }

    /// [`Self::cn`] evaluated straight from the compressed factors (a rank sum of lerped
    /// factors, no node grid): the reference the node grid is tested against, and the
    /// cost of a query without the per-slice contraction.
    pub fn cn_compressed(&self, x: f64, psi: f64) -> f64 {
        let x = if x.is_nan() { 0.0 } else { x.clamp(-1.0, 1.0) };
        if psi.is_nan() {
            return 0.0;
        }
        let (xa, psi_a) = if x.is_sign_negative() {
            (-x, -psi)
        } else {
            (x, psi)
        };
        let t = &*self.cn;
        let (i, fi) = locate(&t.axes[2], xa);
        let (c0, d, n) = t.last_axis();
        let (k0, k1, fk) = locate_periodic(c0, d, n, psi_a);
        t.eval23(&self.wn, i, fi, k0, k1, fk).max(0.0) * scatter_probability(self.tau, x)
    }

    /// `C^N(x, psi)`: per radian of `psi`, from the slice's floored node grid.
    #[inline]
    pub fn cn(&self, x: f64, psi: f64) -> f64 {
        let s = self.cn_shape_clamped(x, psi);
        if s > 0.0 {
            s * scatter_probability(self.tau, x)
        } else {
            0.0
        }
    }

    /// `C^N(x, psi) / P_s(tau, x)`: [`Self::cn`] without the analytic scattered fraction
    /// (for callers that evaluate many `psi` at one `x` and hoist the fraction).
    #[inline]
    pub fn cn_shape_clamped(&self, x: f64, psi: f64) -> f64 {
        let x = if x.is_nan() { 0.0 } else { x.clamp(-1.0, 1.0) };
        if psi.is_nan() {
            return 0.0;
        }
        self.cn_shape(x, psi).max(0.0)
    }

    /// The `C^N` node grid row by row (see [`CnRows`]).
    pub fn cn_rows(&self) -> CnRows<'_> {
        let nodes = self.nodes();
        let (c0, d, n) = self.cn.last_axis();
        CnRows {
            v: &nodes.cn,
            n,
            c0,
            d,
            x: &self.cn.axes[2],
            peak: nodes.cn_peak,
            gap: &nodes.cn_gap,
            slope: &nodes.cn_slope,
        }
    }

    /// The analytic probability `P_s(tau, x)` that a chord at offset `x` scatters.
    #[inline]
    pub fn scattered_probability(&self, x: f64) -> f64 {
        let x = if x.is_nan() { 0.0 } else { x.clamp(-1.0, 1.0) };
        scatter_probability(self.tau, x)
    }

    /// `C^N` at a fixed entry offset `x`, tabulated over the table's `psi` bins, for
    /// evaluating many `psi` at one `x` (the far field at many `phi`): the two node-grid
    /// rows around `x` lerped once here, then a lerp in `psi` per query.
    /// [`CnProfile::cn`] equals [`Self::cn`] up to rounding (the two lerps in the other
    /// order).
    pub fn cn_profile(&self, x: f64) -> CnProfile {
        let x = if x.is_nan() { 0.0 } else { x.clamp(-1.0, 1.0) };
        let t = &*self.cn;
        let (i, fi) = locate(&t.axes[2], x.abs());
        let (c0, d, n) = t.last_axis();
        let nodes = self.nodes();
        let (r0, r1) = (
            &nodes.cn[i * n..(i + 1) * n],
            &nodes.cn[(i + 1) * n..(i + 2) * n],
        );
        let shape = r0.iter().zip(r1).map(|(a, b)| a + fi * (b - a)).collect();
        CnProfile {
            c0,
            d,
            shape,
            prob: scatter_probability(self.tau, x),
            x,
        }
    }

    /// `C^M(theta_i, theta_r, side)` per radian of `theta_r` (radians).
    #[inline]
    pub fn cm(&self, theta_i: f64, theta_r: f64, side: Side) -> f64 {
        if theta_i.is_nan() || theta_r.is_nan() {
            return 0.0;
        }
        let (ti, tr) = if theta_i < 0.0 {
            (-theta_i, -theta_r)
        } else {
            (theta_i, theta_r)
        };
        let s = match side {
            Side::Front => 0,
            Side::Back => 1,
        };
        let t = &*self.cm[s];
        let (i, fi) = locate(&t.axes[2], ti);
        let (c0, d, n) = t.last_axis();
        let (k, fk) = locate_uniform(c0, d, n, tr);
        let nodes = self.nodes();
        SliceNodes::lerp2(&nodes.cm[s], nodes.n_tr, i, fi, k, k + 1, fk).max(0.0)
    }

    /// Seed Eq. 19: `M_s = lerp(C^M_front, C^M_back, |phi| / pi)`.
    #[inline]
    pub fn cm_lerp(&self, theta_i: f64, theta_r: f64, phi: f64) -> f64 {
        let f = self.cm(theta_i, theta_r, Side::Front);
        let b = self.cm(theta_i, theta_r, Side::Back);
        front_back_lerp(f, b, phi)
    }

    /// Integral of [`Self::cn`] over `psi`: `P_s(tau, x) * integral shape`, exact for the
    /// floored piecewise-linear periodic rows (bin width times the node sum, lerped in `x`).
    pub fn scattered_fraction(&self, x: f64) -> f64 {
        self.cn_mass(x) * self.scattered_probability(x)
    }

    /// The mass of `C^N` over `psi` at entry offset `x` (interpolated between the table's
    /// rows): [`Self::scattered_fraction`] without the scattering probability.
    pub fn cn_mass(&self, x: f64) -> f64 {
        let x = if x.is_nan() { 0.0 } else { x.clamp(-1.0, 1.0) };
        let (i, fi) = locate(&self.cn.axes[2], x.abs());
        let m = &self.nodes().cn_mass;
        m[i] + fi * (m[i + 1] - m[i])
    }

    /// The importance sampler of this slice (built on first use, then cached).
    pub fn sampler(&self) -> &MedullaSampler {
        self.sampler
            .get_or_init(|| Arc::new(MedullaSampler::new(self)))
    }

    /// Sample `psi` for entry offset `x` from `u in [0,1)`: see [`MedullaSampler::sample_cn`].
    pub fn sample_cn(&self, x: f64, u: f64) -> (f64, f64) {
        self.sampler().sample_cn(x, u)
    }
}

impl MedullaTables {
    /// Collapse the `tau` and `g` modes once per parameter set. `tau` and `g` are clamped
    /// to the table axes for the shape; `tau` itself (clamped to `>= 0`) sets the analytic
    /// scattered fraction of `C^N`.
    pub fn slice(&self, tau: f64, g: f64) -> MedullaSlice {
        let tau = if tau.is_finite() { tau.max(0.0) } else { 0.0 };
        let g = if g.is_nan() { 0.0 } else { g };
        let wn = self.cn.collapse01(tau, g);
        let wm = [self.cm[0].collapse01(tau, g), self.cm[1].collapse01(tau, g)];
        MedullaSlice {
            tau,
            g,
            wn,
            wm,
            cn: self.cn.clone(),
            cm: self.cm.clone(),
            nodes: OnceLock::new(),
            sampler: OnceLock::new(),
        }
    }
}

/// `C^N(x, .)` at one offset `x`: the unclamped shape at the `psi` bin centres and the
/// analytic scattered fraction (see [`MedullaSlice::cn_profile`]).
#[derive(Clone, Debug)]
pub struct CnProfile {
    c0: f64,
    d: f64,
    shape: Vec<f64>,
    prob: f64,
    /// The (clamped) offset: queries at `x < 0` use `-psi` (the table stores `x >= 0`).
    x: f64,
}

impl CnProfile {
    /// `C^N(x, psi)`, as [`MedullaSlice::cn`].
    #[inline]
    pub fn cn(&self, psi: f64) -> f64 {
        self.shape_clamped(psi) * self.prob
    }

    /// `C^N(-x, psi)` (the mirrored offset), as [`MedullaSlice::cn`] at `-x`.
    #[inline]
    pub fn cn_mirror(&self, psi: f64) -> f64 {
        self.shape_clamped_mirror(psi) * self.prob
    }

    /// [`Self::cn`] without the scattered fraction, as [`MedullaSlice::cn_shape_clamped`].
    #[inline]
    pub fn shape_clamped(&self, psi: f64) -> f64 {
        self.at(if self.flips(false) { -psi } else { psi })
    }

    /// [`Self::cn_mirror`] without the scattered fraction.
    #[inline]
    pub fn shape_clamped_mirror(&self, psi: f64) -> f64 {
        self.at(if self.flips(true) { -psi } else { psi })
    }

    /// Whether a query at `x` (or, `mirror`, at `-x`) reads the table with `psi` flipped:
    /// the sign test of [`MedullaSlice::cn_shape`], so at `x = +0` the mirror is `-0`, the
    /// `h -> 0-` limit, and flips.
    #[inline]
    fn flips(&self, mirror: bool) -> bool {
        (if mirror { -self.x } else { self.x }).is_sign_negative()
    }

    /// The clamped linear interpolation at a located bin position.
    #[inline]
    fn lerp(&self, (k0, k1, f): (usize, usize, f64)) -> f64 {
        (self.shape[k0] + f * (self.shape[k1] - self.shape[k0])).max(0.0)
    }

    /// [`Self::shape_clamped`] (or [`Self::shape_clamped_mirror`]) at `psi0 + q dpsi` for
    /// `q` in `0..n`, passed to `f(q, value)`. The table is `2 pi`-periodic, so no point is
    /// wrapped, and each bin position is one multiply-add from the first instead of a
    /// wrap and a division: the positions agree with per-point queries to ~1e-14 of a bin.
    pub fn shape_on_grid(
        &self,
        mirror: bool,
        psi0: f64,
        dpsi: f64,
        n: usize,
        mut f: impl FnMut(usize, f64),
    ) {
        let (p0, dp) = if self.flips(mirror) {
            (-psi0, -dpsi)
        } else {
            (psi0, dpsi)
        };
        let (u0, du) = ((p0 - self.c0) / self.d, dp / self.d);
        let m = self.shape.len();
        for q in 0..n {
            f(q, self.lerp(locate_periodic_u(u0 + q as f64 * du, m)));
        }
    }

    #[inline]
    fn at(&self, psi: f64) -> f64 {
        if psi.is_nan() {
            return 0.0;
        }
        self.lerp(locate_periodic(self.c0, self.d, self.shape.len(), psi))
    }
}

/// A piecewise-linear density on knots: values clamped to `>= 0` at every table node.
#[derive(Clone, Debug)]
struct PlDensity {
    vals: Vec<f64>,
    /// Cumulative mass at each knot (len = knots), `cdf[0] = 0`.
    cdf: Vec<f64>,
}

impl PlDensity {
    fn new(knots: &[f64], vals: Vec<f64>) -> Self {
        let mut cdf = Vec::with_capacity(knots.len());
        cdf.push(0.0);
        for j in 1..knots.len() {
            let m = 0.5 * (vals[j - 1] + vals[j]) * (knots[j] - knots[j - 1]);
            cdf.push(cdf[j - 1] + m);
        }
        PlDensity { vals, cdf }
    }
    fn mass(&self) -> f64 {
        *self.cdf.last().unwrap()
    }
    /// Value at the knot location `(j, f)` = `locate(knots, t)` (mixtures on one knot
    /// set locate `t` once for all their components).
    fn eval_at(&self, (j, f): (usize, f64)) -> f64 {
        self.vals[j] + f * (self.vals[j + 1] - self.vals[j])
    }
    /// Invert the CDF at mass `m in [0, mass]`.
    fn invert(&self, knots: &[f64], m: f64) -> f64 {
        let n = knots.len();
        let j = self.cdf.partition_point(|&c| c <= m).clamp(1, n - 1) - 1;
        let t = (m - self.cdf[j]).max(0.0);
        let w = knots[j + 1] - knots[j];
        let (va, vb) = (self.vals[j], self.vals[j + 1]);
        let k = (vb - va) / w;
        let root = (va * va + 2.0 * k * t).max(0.0).sqrt();
        let s = if va + root > 0.0 {
            2.0 * t / (va + root)
        } else {
            0.0
        };
        knots[j] + s.clamp(0.0, w)
    }
}

/// Domains of the sampled `psi` (of `C^N`) and `theta_r` (of `C^M`): where an empty
/// mixture falls back to uniform sampling.
const PSI_RANGE: (f64, f64) = (-PI, PI);
const INCLINATION_RANGE: (f64, f64) = (-FRAC_PI_2, FRAC_PI_2);

/// Per-slice tabulated CDFs for importance sampling.
///
/// The sampled density at an arbitrary `x` (or `theta_i`, `phi`) is the mixture of the
/// node densities of the two neighbouring `x` nodes (four components for `C^M`: two
/// `theta_i` nodes times front/back with the Eq. 19 weights), each component the
/// piecewise-linear interpolation of the compressed values at the table nodes clamped to
/// `>= 0`. This equals the normalised `cn`/`cm_lerp` wherever the compression left no
/// negative node values; the returned pdf is always exactly the density sampled.
#[derive(Clone, Debug)]
pub struct MedullaSampler {
    x_axis: Vec<f64>,
    psi_knots: Vec<f64>,
    cn: Vec<PlDensity>,
    /// The `C^M` columns: `cm_cols[side][theta_r node]`, a density in `theta_i >= 0` over
    /// `ti_knots` (the table's `theta_i` nodes, extended flat to 0 and 90 degrees as
    /// [`MedullaSlice::cm`] reads beyond them).
    ti_knots: Vec<f64>,
    cm_cols: [Vec<PlDensity>; 2],
    /// The `theta_r` node centres `(c0, step, count)`.
    tr_nodes: (f64, f64, usize),
}

impl MedullaSampler {
    fn new(s: &MedullaSlice) -> Self {
        let nodes = s.nodes();
        let t = &*s.cn;
        let (c0, d, n) = t.last_axis();
        // Periodic: knots -pi, centres, pi; the value at +-pi is the wrap midpoint.
        let mut psi_knots = vec![c0 - 0.5 * d];
        psi_knots.extend((0..n).map(|k| c0 + k as f64 * d));
        psi_knots.push(c0 + (n as f64 - 0.5) * d);
        let cn = (0..t.axes[2].len())
            .map(|i| {
                // Node rows are floored, hence non-negative densities already.
                let v = &nodes.cn[i * n..(i + 1) * n];
                let mut vals = vec![0.5 * (v[0] + v[n - 1])];
                vals.extend_from_slice(v);
                vals.push(vals[0]);
                PlDensity::new(&psi_knots, vals)
            })
            .collect();
        let tm = &*s.cm[0];
        let (c0, d, n) = tm.last_axis();
        let ti_axis = &tm.axes[2];
        let lead = usize::from(ti_axis[0] > 0.0);
        let mut ti_knots = Vec::with_capacity(ti_axis.len() + 2);
        if lead == 1 {
            ti_knots.push(0.0);
        }
        ti_knots.extend_from_slice(ti_axis);
        let tail = ti_axis[ti_axis.len() - 1] < FRAC_PI_2;
        if tail {
            ti_knots.push(FRAC_PI_2);
        }
        let cm_cols = [0usize, 1].map(|side| {
            let v = &nodes.cm[side];
            (0..n)
                .map(|k| {
                    let col = |i: usize| v[i * n + k];
                    let mut vals: Vec<f64> = (0..lead).map(|_| col(0)).collect();
                    vals.extend((0..ti_axis.len()).map(col));
                    if tail {
                        vals.push(col(ti_axis.len() - 1));
                    }
                    PlDensity::new(&ti_knots, vals)
                })
                .collect()
        });
        MedullaSampler {
            x_axis: t.axes[2].clone(),
            psi_knots,
            cn,
            ti_knots,
            cm_cols,
            tr_nodes: (c0, d, n),
        }
    }

    /// A uniform variate as the samplers use it: clamped to `[0, 1]`, 0.5 if not finite.
    fn unit(u: f64) -> f64 {
        if u.is_finite() {
            u.clamp(0.0, 1.0)
        } else {
            0.5
        }
    }

    /// The uniform draw over `range` an empty density falls back to, with its pdf.
    fn uniform((lo, hi): (f64, f64), u: f64) -> (f64, f64) {
        (lo + u * (hi - lo), 1.0 / (hi - lo))
    }

    /// Sample a mixture `sum_c w_c p_c` from `u`; returns `(value, pdf)`.
    fn sample_mixture(
        comps: &[(f64, &PlDensity)],
        knots: &[f64],
        u: f64,
        fallback: (f64, f64),
    ) -> (f64, f64) {
        let total: f64 = comps.iter().map(|(w, p)| w * p.mass()).sum();
        let u = Self::unit(u);
        if total.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            return Self::uniform(fallback, u);
        }
        let target = u * total;
        let mut acc = 0.0;
        let mut chosen = comps.len() - 1;
        for (c, (w, p)) in comps.iter().enumerate() {
            let m = w * p.mass();
            if m > 0.0 && target < acc + m {
                chosen = c;
                break;
            }
            acc += m;
        }
        // Skip trailing empty components.
        while comps[chosen].0 * comps[chosen].1.mass() <= 0.0 && chosen > 0 {
            chosen -= 1;
        }
        let (w, p) = comps[chosen];
        let local = ((target - acc) / w).clamp(0.0, p.mass());
        let v = p.invert(knots, local);
        (v, Self::mixture_density(comps, knots, v, total))
    }

    /// Density of the mixture `comps` (total mass `total > 0`) at `v`: every component
    /// shares the knots, so `v` is located once.
    fn mixture_density(comps: &[(f64, &PlDensity)], knots: &[f64], v: f64, total: f64) -> f64 {
        let at = locate(knots, v);
        comps.iter().map(|(w, p)| w * p.eval_at(at)).sum::<f64>() / total
    }

    /// The pdf [`Self::sample_mixture`] samples, at `v`: the normalised mixture, or the
    /// uniform density of its fallback range when the mixture is empty.
    fn mixture_pdf(comps: &[(f64, &PlDensity)], knots: &[f64], v: f64, range: (f64, f64)) -> f64 {
        let total: f64 = comps.iter().map(|(w, p)| w * p.mass()).sum();
        if total > 0.0 {
            Self::mixture_density(comps, knots, v, total)
        } else {
            1.0 / (range.1 - range.0)
        }
    }

    /// Sample the exit azimuth `psi` of `C^N` at offset `x` from `u in [0, 1)`; returns
    /// `(psi, pdf)` with the pdf per radian of the density actually sampled.
    pub fn sample_cn(&self, x: f64, u: f64) -> (f64, f64) {
        let x = if x.is_nan() { 0.0 } else { x.clamp(-1.0, 1.0) };
        let (i, f) = locate(&self.x_axis, x.abs());
        let comps = [(1.0 - f, &self.cn[i]), (f, &self.cn[i + 1])];
        let (psi, pdf) = Self::sample_mixture(&comps, &self.psi_knots, u, PSI_RANGE);
        (if x.is_sign_negative() { -psi } else { psi }, pdf)
    }

    /// The pdf [`Self::sample_cn`] samples, at `psi`.
    pub fn pdf_cn(&self, x: f64, psi: f64) -> f64 {
        let x = if x.is_nan() { 0.0 } else { x.clamp(-1.0, 1.0) };
        let psi = wrap_pi(if x.is_sign_negative() { -psi } else { psi });
        let (i, f) = locate(&self.x_axis, x.abs());
        let comps = [(1.0 - f, &self.cn[i]), (f, &self.cn[i + 1])];
        Self::mixture_pdf(&comps, &self.psi_knots, psi, PSI_RANGE)
    }

    /// The column components of `M_s(., theta_r, phi)` as a density in `|theta_i|`: for
    /// `theta_i >= 0` ([`MedullaSlice::cm`] at `(theta_i, theta_r)`) and for `theta_i < 0`
    /// (the table read at `(-theta_i, -theta_r)`), each the bilinear table's lerp of two
    /// `theta_r` columns per side.
    fn cm_col_comps(&self, theta_r: f64, phi: f64) -> [[(f64, &PlDensity); 4]; 2] {
        let (c0, d, n) = self.tr_nodes;
        let t = if phi.is_nan() {
            0.5
        } else {
            wrap_pi(phi).abs() / PI
        };
        [theta_r, -theta_r].map(|tr| {
            let (k, f) = locate_uniform(c0, d, n, tr);
            [
                ((1.0 - f) * (1.0 - t), &self.cm_cols[0][k]),
                (f * (1.0 - t), &self.cm_cols[0][k + 1]),
                ((1.0 - f) * t, &self.cm_cols[1][k]),
                (f * t, &self.cm_cols[1][k + 1]),
            ]
        })
    }

    /// Sample the incident inclination `theta_i` of `M_s(theta_i, theta_r, phi)` (seed
    /// Eq. 19) for a given exit `theta_r`: the table's column, for a renderer that knows
    /// the camera side and draws the light side. Returns `(theta_i, pdf)` per radian.
    pub fn sample_cm_incident(&self, theta_r: f64, phi: f64, u: f64) -> (f64, f64) {
        let tr = if theta_r.is_nan() { 0.0 } else { theta_r };
        let halves = self.cm_col_comps(tr, phi);
        let mass = halves.map(|c| c.iter().map(|(w, p)| w * p.mass()).sum::<f64>());
        let total = mass[0] + mass[1];
        let u = Self::unit(u);
        if total.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            return Self::uniform(INCLINATION_RANGE, u);
        }
        // The sign first (by the halves' masses), then |theta_i| within its half.
        let target = u * total;
        let (half, local) = if (target < mass[0] && mass[0] > 0.0) || mass[1] <= 0.0 {
            (0, (target / mass[0]).min(1.0))
        } else {
            (1, ((target - mass[0]) / mass[1]).clamp(0.0, 1.0))
        };
        let range = (0.0, FRAC_PI_2);
        let (v, _) = Self::sample_mixture(&halves[half], &self.ti_knots, local, range);
        let pdf = Self::mixture_density(&halves[half], &self.ti_knots, v, total);
        (if half == 1 { -v } else { v }, pdf)
    }

    /// The mass of the column [`Self::sample_cm_incident`] samples,
    /// `∫ M_s(theta_i, theta_r, phi) dtheta_i` over both signs of `theta_i` (1 would make
    /// `C^M` conserve energy read this way; it is normalised over `theta_r` instead).
    pub fn column_mass(&self, theta_r: f64, phi: f64) -> f64 {
        let tr = if theta_r.is_nan() { 0.0 } else { theta_r };
        Self::comps_mass(&self.cm_col_comps(tr, phi))
    }

    /// The mass of a column's components ([`Self::cm_col_comps`]), both halves.
    fn comps_mass(halves: &[[(f64, &PlDensity); 4]; 2]) -> f64 {
        halves
            .iter()
            .flat_map(|c| c.iter())
            .map(|(w, p)| w * p.mass())
            .sum()
    }

    /// The pdf [`Self::sample_cm_incident`] samples, at `theta_i`.
    pub fn pdf_cm_incident(&self, theta_r: f64, theta_i: f64, phi: f64) -> f64 {
        let tr = if theta_r.is_nan() { 0.0 } else { theta_r };
        let halves = self.cm_col_comps(tr, phi);
        let total = Self::comps_mass(&halves);
        if total.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            return 1.0 / (INCLINATION_RANGE.1 - INCLINATION_RANGE.0);
        }
        // As MedullaSlice::cm reads it: theta_i < 0 (not -0.0) is the mirrored half.
        let (half, v) = if theta_i < 0.0 {
            (1, -theta_i)
        } else {
            (0, theta_i)
        };
        if v.is_nan() || v > FRAC_PI_2 {
            return 0.0;
        }
        Self::mixture_density(&halves[half], &self.ti_knots, v, total)
    }
}
