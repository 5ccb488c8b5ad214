//! Medulla scattering tables `C^N` and `C^M` (seed paper Sec. 3 Eqs. 8-10, Sec. 4.3
//! Eqs. 17-19, Table 3), stored as rank-k CP factors and queried without decompression.
//!
//! # Conventions (the near-field model relies on these)
//! * Azimuthal plane frame as in MODEL.md: exit azimuth `phi = 0` points back toward the
//!   light, `|phi| = pi` straight through. The `p`-th internal segment has direction
//!   `Phi^s_p` (seed Eq. 21), in the convention that a ray leaving along the segment without
//!   deflection exits at `phi = Phi^s_p + pi`. The model queries
//!   `D^s_p(h, phi) = C^N(x, psi = wrap(phi - Phi^s_p))`: `psi` is the exit azimuth
//!   relative to the segment, `psi = 0` back along it, `|psi| = pi` straight on.
//! * `x = sin(gamma_t) / kappa` in `[-1, 1]` is the signed entry offset into the medulla in
//!   medulla radii (the chord's signed impact parameter; internal reflection preserves it).
//!   Monte Carlo geometry ([`crate::model::medulla_mc`]): unit medulla disk, the ray enters
//!   travelling toward `-x̂` at plane position `y = -x`, and `psi = atan2(d_y, d_x)` of the
//!   exit direction.
//! * `C^N(tau, g, x, psi)` is the density per radian of `psi` of the energy entering at
//!   offset `x` that scatters at least once and leaves the medulla (index-matched, no
//!   absorption). The unscattered part is NOT included (the model carries it through
//!   `exp(-2 s_m sigma_m_s)`), so `integral C^N dpsi = 1 - exp(-2 tau sqrt(1 - x^2))`.
//!   The ray enters perpendicular to the axis (`theta = 0`): like the paper's `C^N` the
//!   table has no inclination dimension.
//!   Stored: the normalised shape `C^N / P_s` (a density integrating to 1) on `x in [0, 1]`;
//!   the query multiplies by the analytic `P_s(tau, x) = 1 - exp(-2 tau sqrt(1 - x^2))`
//!   with the *query* `tau` (so the scattered fraction is exact even off the grid), and
//!   negative `x` uses the mirror symmetry `C^N(x, psi) = C^N(-x, -psi)`.
//! * `C^M(tau, g, theta_i, theta_r, side)`: a collimated beam (entry offset uniform over
//!   the chord) entering with inclination `theta_i` (refraction ignored, seed Eq. 19);
//!   density per radian of the exit inclination `theta_r` of the photons that scattered at
//!   least once, split into `Front` (exit `|psi| < pi/2`, toward the light, the paper's
//!   `C^M_{phi=0}`) and `Back` (`|psi| >= pi/2`, `C^M_{phi=pi}`). Each
//!   `(tau, g, theta_i, side)` slice integrates to 1 over `theta_r in [-pi/2, pi/2]`.
//!   Unscattered light would leave at `theta_r = -theta_i`. Stored on `theta_i in [0, pi/2]`;
//!   negative `theta_i` uses `C^M(theta_i, theta_r) = C^M(-theta_i, -theta_r)`. At `tau = 0`
//!   no photon scatters; the stored slice is the limit `tau -> 0` (one scattering event
//!   uniformly placed on the chord), so `C^M` is continuous in `tau`. A slice that receives
//!   no weight at all (not reachable on the shipped grid) falls back to `cos(theta_r) / 2`.
//! * Not reciprocal: as the seed's `M_s = C^M` (Eq. 19), a density per radian of exit
//!   inclination normalised for each `theta_i`, the scattered lobes do not satisfy
//!   `f(theta_i, theta_r) = f(theta_r, theta_i)`: a diffuse exit density carries a
//!   `cos theta_r` that the swap moves to `cos theta_i` (at `phi = 0` the swapped values
//!   differ by about `cos theta_r / cos theta_i`). R, TT and TRT are reciprocal exactly.
//!   We keep the paper's definition (its fits and ours are made with it).
//!
//! # Grids, interpolation and clamping
//! Shipped grid ([`crate::model::medulla_mc::McGrid::standard`]): 35 `tau` in `[0, 20]`,
//! 31 `g` in `[-0.9, 0.95]`, 16 `x` in `[0, 1]`, 180 `psi` bin centres (2 deg), 16
//! `theta_i` in `[0, 90]` deg, 90 `theta_r` bin centres (2 deg). Values are bin averages
//! placed at bin centres. The parameter modes `tau` and `g` are interpolated by cubic
//! Hermite (C^1, so a fit can differentiate through them), the angle modes linearly (the
//! far field integrates their piecewise-linear structure exactly); `tau`, `g`, `x`, `theta_i`
//! are clamped to their axis ends (the presets of seed Table 4 have `tau` below about 3,
//! so clamping at `tau = 20` only concerns optically thick fits), `psi` is periodic, and
//! `theta_r` is constant beyond the outermost bin centres (so the piecewise-linear density
//! integrates to exactly the bin sum). Negative or near-zero values produced by the
//! compression are raised to [`NODE_FLOOR`] of their row's peak when a slice contracts the
//! ranks into its node grid, so every query is non-negative.
//!
//! # Compression and file format
//! Each of the three 4-D tensors (`C^N`: `tau x g x x x psi`; `C^M` front and back:
//! `tau x g x theta_i x theta_r`) is factored by CP-ALS ([`crate::model::cp`]) with the
//! weights `lambda_r` folded into the `tau` factor. File (all little-endian):
//! ```text
//! magic  b"FURMEDUL"          8 bytes
//! version u32 = 1
//! seed u64, nominal paths per cell u64
//! n_tensors u32 = 3           (kind 0 = C^N, 1 = C^M front, 2 = C^M back, in that order)
//! per tensor: kind u32, rank u32, n_modes u32 = 4,
//!             per mode: len u32, axis f64 x len (strictly increasing),
//!             per mode: factor f32 x (len * rank), row-major [node][rank]
//! sha256 of all preceding bytes (32 bytes)
//! ```
//! # The shipped file
//! `assets/medulla_tables.bin` (121 348 bytes, sha256 `05808985...9747ef00`) is produced by
//! ```text
//! furfit tables build --seed 2017 --paths 16000
//! ```
//! (the defaults: ranks 16, 32, 48 tried per tensor, stop at relative L2 error 0.03; that
//! target lies below the Monte Carlo noise floor of the raw tensors, so rank 48 is kept for
//! all three). Measured on the 2-core build machine: 6 min 42 s of wall time (Monte Carlo
//! 5.1e8 paths / 2.8e9 scattering events in 261 s, CP-ALS 141 s) with other work on the
//! second core; a second build from a later commit on the idle machine took 5 min 14 s and
//! wrote identical bytes. Per-rank errors of that build (relative L2 against the raw,
//! noisy tensors; the raw-tensor MC noise from an even/odd half split is C^N 0.064,
//! C^M front 0.133, C^M back 0.104):
//! ```text
//! rank        16      32      48
//! C^N       0.095   0.072   0.067
//! C^M front 0.158   0.138   0.134
//! C^M back  0.162   0.119   0.111
//! ```
//! `furfit tables info --holdout 24` (200 000 fresh paths per point, seed 777) measures the
//! error against fresh MC at random off-grid points, relative L2 rms, with the fresh
//! estimates' own MC noise in brackets: C^N 0.037 (0.024), C^M front 0.033 (0.026), C^M back
//! 0.051 (0.039) — net of that noise 0.028 / 0.020 / 0.033 with the cubic Hermite `tau`, `g`
//! interpolation, against 0.029 / 0.023 / 0.034 with the linear one it replaced (same
//! points and paths). At the table nodes
//! (`--on-grid`) the same figures are 0.036 / 0.031 / 0.048, so interpolation between nodes
//! now adds little. The first shipped file (18 `tau` x 16 `g` nodes, rank 32, 12 000 paths,
//! 69 508 bytes) had off-grid C^N 0.071, C^M 0.072 / 0.062 against on-grid 0.052 /
//! 0.044 / 0.061: interpolation in `tau` and `g` was then as large as the compression
//! error, hence the midpoints of the current grid.

use crate::error::{Error, Num, Result};
use std::f64::consts::{FRAC_PI_2, PI};
use std::path::Path;
use std::sync::{Arc, OnceLock};

/// File magic of the tables file.
pub const MAGIC: &[u8; 8] = b"FURMEDUL";
/// File format version.
pub const VERSION: u32 = 1;

/// Which half of the exit directions a `C^M` slice describes (seed Eq. 19).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    /// Exit `|psi| < pi/2`: back toward the light (`C^M_{phi=0}`).
    Front,
    /// Exit `|psi| >= pi/2`: onward (`C^M_{phi=pi}`).
    Back,
}

/// Kind of a stored tensor.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TableKind {
    Cn = 0,
    CmFront = 1,
    CmBack = 2,
}

/// One CP-compressed 4-D table: `value = sum_r prod_m f[m](axis_m; r)` with linear
/// interpolation of each factor along its axis.
#[derive(Clone, Debug, PartialEq)]
pub struct CpTable {
    pub rank: usize,
    pub axes: [Vec<f64>; 4],
    /// `factors[m][i * rank + r]`, lambda folded into mode 0.
    pub factors: [Vec<f64>; 4],
}

/// Index and fraction of `v` on an increasing axis, clamped to the ends.
#[inline]
fn locate(axis: &[f64], v: f64) -> (usize, f64) {
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
fn hermite_stencil(axis: &[f64], v: f64) -> ([usize; 4], [f64; 4]) {
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
fn locate_periodic(c0: f64, d: f64, n: usize, psi: f64) -> (usize, usize, f64) {
    locate_periodic_u((psi - c0) / d, n)
}

/// [`locate_periodic`] from the position `u` in bins.
#[inline]
fn locate_periodic_u(u: f64, n: usize) -> (usize, usize, f64) {
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
fn floor_i64(u: f64) -> i64 {
    let k = u as i64;
    if k as f64 > u {
        k - 1
    } else {
        k
    }
}

/// Location of `t` among `n` uniform bin centres, constant beyond the end centres.
#[inline]
fn locate_uniform(c0: f64, d: f64, n: usize, t: f64) -> (usize, f64) {
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

impl CpTable {
    /// Per-rank weights after collapsing modes 0 and 1 (`tau`, `g`) at `(a, b)`, each
    /// factor interpolated by [`hermite_stencil`]: the scattered lobes are then
    /// continuously differentiable in `kappa`, `sigma_m_s` and `g`, which the fitter
    /// differentiates (with linear interpolation the cost had a kink at every node, and
    /// LM stopped on it with one-sided derivatives).
    fn collapse01(&self, a: f64, b: f64) -> Vec<f64> {
        let r = self.rank;
        let (ia, wa) = hermite_stencil(&self.axes[0], a);
        let (ib, wb) = hermite_stencil(&self.axes[1], b);
        let f0 = &self.factors[0];
        let f1 = &self.factors[1];
        (0..r)
            .map(|k| {
                let a0: f64 = (0..4).map(|q| wa[q] * f0[ia[q] * r + k]).sum();
                let b0: f64 = (0..4).map(|q| wb[q] * f1[ib[q] * r + k]).sum();
                a0 * b0
            })
            .collect()
    }

    /// Step and first centre of the uniform last axis.
    fn last_axis(&self) -> (f64, f64, usize) {
        let a = &self.axes[3];
        (a[0], a[1] - a[0], a.len())
    }

    /// Evaluate `sum_r w_r f2(i2, f2) f3(k0, k1, f3)` (unclamped).
    #[inline]
    #[allow(clippy::needless_range_loop)]
    fn eval23(&self, w: &[f64], i: usize, fi: f64, k0: usize, k1: usize, fk: f64) -> f64 {
        let r = self.rank;
        let x0 = &self.factors[2][i * r..(i + 1) * r];
        let x1 = &self.factors[2][(i + 1) * r..(i + 2) * r];
        let p0 = &self.factors[3][k0 * r..(k0 + 1) * r];
        let p1 = &self.factors[3][k1 * r..(k1 + 1) * r];
        // Four independent accumulators (fixed order) let the compiler vectorise.
        let mut acc = [0.0f64; 4];
        let chunks = w
            .chunks_exact(4)
            .zip(x0.chunks_exact(4))
            .zip(x1.chunks_exact(4))
            .zip(p0.chunks_exact(4))
            .zip(p1.chunks_exact(4));
        for ((((w4, a0), a1), b0), b1) in chunks {
            for j in 0..4 {
                let a = a0[j] + fi * (a1[j] - a0[j]);
                let b = b0[j] + fk * (b1[j] - b0[j]);
                acc[j] += w4[j] * a * b;
            }
        }
        let mut s = (acc[0] + acc[1]) + (acc[2] + acc[3]);
        for k in r / 4 * 4..r {
            let a = x0[k] + fi * (x1[k] - x0[k]);
            let b = p0[k] + fk * (p1[k] - p0[k]);
            s += w[k] * a * b;
        }
        s
    }

    /// Value at mode-2 node `i` and mode-3 node `k` (unclamped).
    fn node23(&self, w: &[f64], i: usize, k: usize) -> f64 {
        let r = self.rank;
        (0..r)
            .map(|q| w[q] * self.factors[2][i * r + q] * self.factors[3][k * r + q])
            .sum()
    }
}

/// The medulla tables: three CP-compressed tensors and their build metadata.
#[derive(Clone, Debug, PartialEq)]
pub struct MedullaTables {
    pub cn: Arc<CpTable>,
    pub cm: [Arc<CpTable>; 2],
    /// Seed and nominal paths per cell of the build.
    pub seed: u64,
    pub paths: u64,
}

struct Reader<'a> {
    b: &'a [u8],
    pos: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8]> {
        let end = self
            .pos
            .checked_add(n)
            .filter(|&e| e <= self.b.len())
            .ok_or_else(|| bad("truncated file"))?;
        let s = &self.b[self.pos..end];
        self.pos = end;
        Ok(s)
    }
    fn u32(&mut self) -> Result<u32> {
        Ok(u32::from_le_bytes(self.take(4)?.try_into().unwrap()))
    }
    fn u64(&mut self) -> Result<u64> {
        Ok(u64::from_le_bytes(self.take(8)?.try_into().unwrap()))
    }
    fn f64(&mut self) -> Result<f64> {
        Ok(f64::from_le_bytes(self.take(8)?.try_into().unwrap()))
    }
    fn f32(&mut self) -> Result<f32> {
        Ok(f32::from_le_bytes(self.take(4)?.try_into().unwrap()))
    }
}

fn bad(msg: &str) -> Error {
    Error::Invalid(format!("medulla tables: {msg}"))
}

impl MedullaTables {
    /// The tables shipped in `assets/medulla_tables.bin`, parsed once.
    pub fn builtin() -> &'static MedullaTables {
        static T: OnceLock<MedullaTables> = OnceLock::new();
        T.get_or_init(|| {
            MedullaTables::from_bytes(include_bytes!("../../assets/medulla_tables.bin"))
                .expect("the shipped medulla tables are valid (checked by tests)")
        })
    }

    /// Load a tables file.
    pub fn load(path: &Path) -> Result<MedullaTables> {
        let b = std::fs::read(path).map_err(|e| Error::io(path, e))?;
        MedullaTables::from_bytes(&b).map_err(|e| Error::file(path, e.to_string()))
    }

    /// Parse the binary format (see the module doc). Errors, never panics.
    pub fn from_bytes(b: &[u8]) -> Result<MedullaTables> {
        use sha2::{Digest, Sha256};
        if b.len() < 8 + 4 + 32 || &b[..8] != MAGIC {
            return Err(bad("not a furfit medulla tables file (bad magic)"));
        }
        let (body, sum) = b.split_at(b.len() - 32);
        if Sha256::digest(body).as_slice() != sum {
            return Err(bad("checksum mismatch (corrupt or truncated file)"));
        }
        let mut r = Reader { b: body, pos: 8 };
        let version = r.u32()?;
        if version != VERSION {
            return Err(bad(&format!("unsupported version {version}")));
        }
        let seed = r.u64()?;
        let paths = r.u64()?;
        let n = r.u32()?;
        if n != 3 {
            return Err(bad(&format!("expected 3 tensors, found {n}")));
        }
        let mut tabs = Vec::new();
        for want in 0..3u32 {
            let kind = r.u32()?;
            if kind != want {
                return Err(bad(&format!("tensor {want} has kind {kind}")));
            }
            let rank = r.u32()? as usize;
            if rank == 0 || rank > 1024 {
                return Err(bad(&format!("tensor {want}: bad rank {rank}")));
            }
            let modes = r.u32()?;
            if modes != 4 {
                return Err(bad(&format!("tensor {want}: {modes} modes, expected 4")));
            }
            let mut axes: [Vec<f64>; 4] = Default::default();
            for (m, ax) in axes.iter_mut().enumerate() {
                let len = r.u32()? as usize;
                if !(2..=100_000).contains(&len) {
                    return Err(bad(&format!("tensor {want} mode {m}: bad length {len}")));
                }
                for _ in 0..len {
                    ax.push(r.f64()?);
                }
                if ax.iter().any(|v| !v.is_finite()) || ax.windows(2).any(|w| w[1] <= w[0]) {
                    return Err(bad(&format!(
                        "tensor {want} mode {m}: axis not finite and increasing"
                    )));
                }
            }
            let mut factors: [Vec<f64>; 4] = Default::default();
            for (m, f) in factors.iter_mut().enumerate() {
                let len = axes[m].len() * rank;
                f.reserve(len);
                for _ in 0..len {
                    let v = r.f32()?;
                    if !v.is_finite() {
                        return Err(bad(&format!("tensor {want} mode {m}: non-finite factor")));
                    }
                    f.push(v as f64);
                }
            }
            tabs.push(CpTable {
                rank,
                axes,
                factors,
            });
        }
        if r.pos != body.len() {
            return Err(bad("trailing bytes after the last tensor"));
        }
        let mut it = tabs.into_iter().map(Arc::new);
        let cn = it.next().unwrap();
        let front = it.next().unwrap();
        let back = it.next().unwrap();
        Ok(MedullaTables {
            cn,
            cm: [front, back],
            seed,
            paths,
        })
    }

    /// Serialise to the binary format (factors rounded to f32).
    pub fn to_bytes(&self) -> Vec<u8> {
        use sha2::{Digest, Sha256};
        let mut b = Vec::new();
        b.extend_from_slice(MAGIC);
        b.extend_from_slice(&VERSION.to_le_bytes());
        b.extend_from_slice(&self.seed.to_le_bytes());
        b.extend_from_slice(&self.paths.to_le_bytes());
        b.extend_from_slice(&3u32.to_le_bytes());
        for (kind, t) in [&self.cn, &self.cm[0], &self.cm[1]].iter().enumerate() {
            b.extend_from_slice(&(kind as u32).to_le_bytes());
            b.extend_from_slice(&(t.rank as u32).to_le_bytes());
            b.extend_from_slice(&4u32.to_le_bytes());
            for ax in &t.axes {
                b.extend_from_slice(&(ax.len() as u32).to_le_bytes());
                for v in ax {
                    b.extend_from_slice(&v.to_le_bytes());
                }
            }
            for f in &t.factors {
                for v in f {
                    b.extend_from_slice(&(*v as f32).to_le_bytes());
                }
            }
        }
        let sum = Sha256::digest(&b);
        b.extend_from_slice(&sum);
        b
    }

    /// Round the factors to f32 exactly as a write/read round trip does.
    pub fn rounded(mut self) -> Self {
        let round = |t: &Arc<CpTable>| {
            let mut c = (**t).clone();
            for f in c.factors.iter_mut() {
                for v in f.iter_mut() {
                    *v = *v as f32 as f64;
                }
            }
            Arc::new(c)
        };
        self.cn = round(&self.cn);
        self.cm = [round(&self.cm[0]), round(&self.cm[1])];
        self
    }

    /// The `(tau, g)` range the tables cover: `[tau_min, tau_max]`, `[g_min, g_max]`.
    pub fn domain(&self) -> ([f64; 2], [f64; 2]) {
        let ends = |a: &[f64]| [a[0], a[a.len() - 1]];
        (ends(&self.cn.axes[0]), ends(&self.cn.axes[1]))
    }

    /// Messages for a `(tau, g)` outside [`Self::domain`], where [`Self::slice`] uses the
    /// nearest table edge for the shape of the scattered lobes: the value is inside the
    /// parameter's hard bounds, so it is no error, but the user must not take the
    /// scattered lobes there for the model's (MODEL.md: never a silent clamp).
    pub fn domain_notes(&self, tau: f64, g: f64) -> Vec<String> {
        let ([t0, t1], [g0, g1]) = self.domain();
        let mut notes = Vec::new();
        if g < g0 || g > g1 {
            notes.push(format!(
                "g = {} is outside the medulla tables' g range [{g0}, {g1}]: the scattered \
                 lobes (TTs, TRTs) use the shape at g = {}",
                Num(g),
                g.clamp(g0, g1)
            ));
        }
        if tau > t1 {
            notes.push(format!(
                "tau = sigma_m_s * kappa = {} is above the medulla tables' range [{t0}, {t1}]: \
                 the scattered lobes' shape is the one at tau = {t1} (their strength still \
                 follows tau)",
                Num(tau)
            ));
        }
        notes
    }

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

/// The tables at one `(tau, g)`: per-rank weights plus shared factors.
#[derive(Clone, Debug)]
pub struct MedullaSlice {
    pub tau: f64,
    pub g: f64,
    wn: Vec<f64>,
    wm: [Vec<f64>; 2],
    cn: Arc<CpTable>,
    cm: [Arc<CpTable>; 2],
    /// Node values of the slice (built on first query, see [`SliceNodes`]).
    nodes: OnceLock<Arc<SliceNodes>>,
    sampler: OnceLock<Arc<MedullaSampler>>,
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

/// The slice's `C^N` shape at its nodes, row by row: one row per table offset `x_i`, each
/// periodic and piecewise linear in `psi` between the bin centres `c0 + k d`. Between two
/// offset nodes `C^N_shape(x, psi) = (1 - t) R_i(psi) + t R_{i+1}(psi)` with `t` linear in
/// `x` (the bilinear lerp of [`MedullaSlice::cn`]; the floored nodes are positive, so its
/// clamp at 0 never acts), which lets the far field integrate a smooth density against the
/// rows exactly, kinks included ([`CnRows::integrate`]).
#[derive(Clone, Copy, Debug)]
pub struct CnRows<'a> {
    v: &'a [f64],
    n: usize,
    c0: f64,
    d: f64,
    x: &'a [f64],
    /// Largest node value: a bound on every row.
    pub peak: f64,
    gap: &'a [f64],
    slope: &'a [f64],
}

impl CnRows<'_> {
    /// Width of a `psi` bin (radians).
    pub fn bin_width(&self) -> f64 {
        self.d
    }

    /// The table's offset nodes `x_i >= 0`.
    pub fn x_nodes(&self) -> &[f64] {
        self.x
    }

    /// The lower row `i` of the pair interpolated at offset `|x|` (as [`MedullaSlice::cn`]
    /// locates it; at most the second-to-last row).
    pub fn row_at(&self, x: f64) -> usize {
        locate(self.x, x.abs()).0
    }

    /// Rows `R_i` and `R_{i+1}`.
    fn pair(&self, i: usize) -> (&[f64], &[f64]) {
        let n = self.n;
        (
            &self.v[i * n..(i + 1) * n],
            &self.v[(i + 1) * n..(i + 2) * n],
        )
    }

    /// Largest `|R_{i+1} - R_i|` over `psi`.
    pub fn gap(&self, i: usize) -> f64 {
        self.gap[i]
    }

    /// Largest slope `|dR_i / dpsi|` of row `i` (its steepest bin).
    pub fn slope(&self, i: usize) -> f64 {
        self.slope[i]
    }

    /// The weight `t` of row `i + 1` at offset `|x|` between rows `i` and `i + 1`
    /// (clamped to [0, 1], as the table is constant beyond its end nodes).
    pub fn weight(&self, i: usize, x: f64) -> f64 {
        ((x.abs() - self.x[i]) / (self.x[i + 1] - self.x[i])).clamp(0.0, 1.0)
    }

    /// `integral_0^len [g0(s) R_i(psi0 + s) + g1(s) (R_{i+1} - R_i)(psi0 + s)] ds` for
    /// quadratics `g_j(s) = c0 + c1 s + c2 s^2` (`psi0` any real; the rows are periodic):
    /// with `g0 = w` and `g1 = w t` this is `integral w C^N_shape ds`. Exact up to
    /// rounding: the integrand is a cubic on each stretch between bin centres, where the
    /// two-point Gauss-Legendre rule is exact.
    pub fn integrate(&self, i: usize, psi0: f64, len: f64, g: &[[f64; 3]; 2]) -> f64 {
        let n = self.n;
        let (r0, r1) = self.pair(i);
        let mut acc = 0.0;
        self.gl_nodes(psi0, len, g, |_, k, fr, w0, w1| {
            let k1 = if k + 1 == n { 0 } else { k + 1 };
            acc += w0 * (r0[k] + fr * (r0[k1] - r0[k])) + w1 * (r1[k] + fr * (r1[k1] - r1[k]));
        });
        acc
    }

    /// [`Self::integrate`] as weights on the row nodes, for a `psi0` that moves by whole
    /// bins (an evenly spaced `phi` grid whose step is a multiple of the bin width): the
    /// integral at a start `k` bins further is [`CnRows::dot`] at `shift = k`.
    pub fn weights(&self, psi0: f64, len: f64, g: &[[f64; 3]; 2]) -> PsiWeights {
        let mut w = PsiWeights {
            first: 0,
            w0: Vec::new(),
            w1: Vec::new(),
        };
        self.gl_nodes(psi0, len, g, |j, k, fr, a, b| {
            if j == 0 {
                w.first = k;
            }
            if w.w0.len() < j + 2 {
                w.w0.resize(j + 2, 0.0);
                w.w1.resize(j + 2, 0.0);
            }
            w.w0[j] += a * (1.0 - fr);
            w.w0[j + 1] += a * fr;
            w.w1[j] += b * (1.0 - fr);
            w.w1[j + 1] += b * fr;
        });
        w
    }

    /// The Gauss-Legendre nodes of [`Self::integrate`]: per stretch `j` (in bin `k`, from
    /// centre `k` towards `k + 1`) and node, `f(j, k, fr, w0, w1)` with `fr` the node's
    /// fraction of the bin and `w0`, `w1` the weights of `R_i` and `R_{i+1}` there.
    fn gl_nodes(
        &self,
        psi0: f64,
        len: f64,
        g: &[[f64; 3]; 2],
        mut f: impl FnMut(usize, usize, f64, f64, f64),
    ) {
        let n = self.n;
        // Positions in bins from the first centre; the stretches between centres that
        // [u0, u1] meets are kb..=ke (this runs per piece and phi; a libm floor call was a
        // tenth of its time).
        let u0 = (psi0 - self.c0) / self.d;
        let u1 = u0 + len / self.d;
        let (kb, ke) = (floor_i64(u0), floor_i64(u1));
        let mut k = kb.rem_euclid(n as i64) as usize;
        let poly = |c: &[f64; 3], s: f64| c[0] + s * (c[1] + s * c[2]);
        // Two-point Gauss-Legendre nodes on [0, 1].
        const GL2: [f64; 2] = [0.211_324_865_405_187_1, 0.788_675_134_594_812_9];
        for (j, lo) in (kb..=ke).enumerate() {
            let lo = lo as f64;
            let (a, b) = (u0.max(lo), u1.min(lo + 1.0));
            if b > a {
                let half = 0.5 * (b - a) * self.d;
                for t in GL2 {
                    let pos = a + t * (b - a);
                    let (fr, s) = (pos - lo, (pos - u0) * self.d);
                    let p1 = poly(&g[1], s);
                    f(j, k, fr, half * (poly(&g[0], s) - p1), half * p1);
                }
            }
            k = if k + 1 == n { 0 } else { k + 1 };
        }
    }

    /// `sum_m w0[m] R_i[first + shift + m] + w1[m] R_{i+1}[...]` (indices modulo the bins).
    pub fn dot(&self, i: usize, w: &PsiWeights, shift: i64) -> f64 {
        let n = self.n;
        let (r0, r1) = self.pair(i);
        let mut k = (w.first as i64 + shift).rem_euclid(n as i64) as usize;
        let mut acc = 0.0;
        for (a, b) in w.w0.iter().zip(&w.w1) {
            acc += a * r0[k] + b * r1[k];
            k = if k + 1 == n { 0 } else { k + 1 };
        }
        acc
    }
}

impl CnRows<'_> {
    /// An empty [`RowWeights`] for these rows.
    pub fn row_weights(&self) -> RowWeights {
        RowWeights {
            w: vec![0.0; self.v.len()],
            touched: vec![false; self.v.len() / self.n],
        }
    }

    /// Add the weights of [`Self::weights`]`(psi0, len, g)` on the row pair `(i, i + 1)`
    /// to `acc`, straight from the quadrature nodes, without the piece's own weight
    /// vectors (grid synthesis accumulates a few hundred pieces per slice).
    pub fn accumulate_piece(
        &self,
        acc: &mut RowWeights,
        i: usize,
        psi0: f64,
        len: f64,
        g: &[[f64; 3]; 2],
    ) {
        let n = self.n;
        let (low, high) = acc.w.split_at_mut((i + 1) * n);
        let (r0, r1) = (&mut low[i * n..], &mut high[..n]);
        self.gl_nodes(psi0, len, g, |_, k, fr, a, b| {
            let k1 = if k + 1 == n { 0 } else { k + 1 };
            r0[k] += a * (1.0 - fr);
            r0[k1] += a * fr;
            r1[k] += b * (1.0 - fr);
            r1[k1] += b * fr;
        });
        acc.touched[i] = true;
        acc.touched[i + 1] = true;
    }

    /// Add `w C^N_shape(|x|, psi0 + shift d)` to `acc` as weights on the four row nodes
    /// around `(|x|, psi0)`: the bilinear lerp of [`MedullaSlice::cn`] written as node
    /// weights, so [`Self::correlate`] reads a point query along a grid with the pieces.
    pub fn accumulate_point(&self, acc: &mut RowWeights, x: f64, psi0: f64, w: f64) {
        let n = self.n;
        let (i, t) = locate(self.x, x.abs());
        let (k0, k1, f) = locate_periodic(self.c0, self.d, n, psi0);
        for (r, wr) in [(i, w * (1.0 - t)), (i + 1, w * t)] {
            acc.w[r * n + k0] += wr * (1.0 - f);
            acc.w[r * n + k1] += wr * f;
            acc.touched[r] = true;
        }
    }

    /// `out[q] += sum_rows sum_k acc[row][k] R_row[k + step q]` (indices modulo the bins):
    /// every accumulated piece at once, [`Self::dot`] summed over the pieces with `shift =
    /// step q`, in one pass per touched row instead of one per piece: each nonzero weight
    /// adds a strided run of its row ([`Self::add_term`]).
    pub fn correlate(&self, acc: &RowWeights, step: i64, out: &mut [f64]) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2 (checked just above).
            return unsafe { self.correlate_avx2(acc, step, out) };
        }
        self.correlate_body(acc, step, out)
    }

    /// [`Self::correlate`] compiled for AVX2 (the same multiplies and adds in the same
    /// order, four lanes wide: the same values bit for bit).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn correlate_avx2(&self, acc: &RowWeights, step: i64, out: &mut [f64]) {
        self.correlate_body(acc, step, out)
    }

    #[inline(always)]
    fn correlate_body(&self, acc: &RowWeights, step: i64, out: &mut [f64]) {
        let n = self.n;
        let m = step.unsigned_abs() as usize % n;
        // A weight at bin k reads R[k + step q] (mod n) for point q: with a one-bin step a
        // few contiguous runs of the row (ascending, or descending for a negative step),
        // which vectorise; otherwise an index stepped modulo n. Each point adds its terms
        // in the order (row, bin). Laying each row out unrolled past its period first (as
        // this did before) cost more than the sums: a synthesis slice touches ~10 rows but
        // has only ~70 nonzero weights.
        for (r, _) in acc.touched.iter().enumerate().filter(|(_, t)| **t) {
            let row = &self.v[r * n..(r + 1) * n];
            // Over nine in ten weights of a synthesis slice are 0 (~70 of ~2000): skip them
            // eight at a time (a compare per weight was a third of the time here).
            let ws = &acc.w[r * n..(r + 1) * n];
            for (j, chunk) in ws.chunks(8).enumerate() {
                // No short circuit, so the test compiles to a few vector compares.
                if !chunk.iter().fold(false, |a, &w| a | (w != 0.0)) {
                    continue;
                }
                for (i, &w) in chunk.iter().enumerate() {
                    if w != 0.0 {
                        Self::add_term(out, row, m, step >= 0, 8 * j + i, w);
                    }
                }
            }
        }
    }

    /// `out[q] += w R[k + s m q]` (modulo the row's length, `s` the sign of `up`), the
    /// term of one weight in [`Self::correlate`].
    #[inline(always)]
    fn add_term(out: &mut [f64], row: &[f64], m: usize, up: bool, k: usize, w: f64) {
        let n = row.len();
        match (m, up) {
            // A whole number of periods per step: every point reads R[k].
            (0, _) => out.iter_mut().for_each(|o| *o += w * row[k]),
            (1, true) => {
                let (mut q, mut i) = (0, k);
                while q < out.len() {
                    let run = (out.len() - q).min(n - i);
                    for (o, e) in out[q..q + run].iter_mut().zip(&row[i..i + run]) {
                        *o += w * e;
                    }
                    (q, i) = (q + run, 0);
                }
            }
            (1, false) => {
                let (mut q, mut i) = (0, k);
                while q < out.len() {
                    let run = (out.len() - q).min(i + 1);
                    let src = row[i + 1 - run..=i].iter().rev();
                    for (o, e) in out[q..q + run].iter_mut().zip(src) {
                        *o += w * e;
                    }
                    (q, i) = (q + run, n - 1);
                }
            }
            (_, up) => {
                let di = if up { m } else { n - m };
                let mut i = k;
                for o in out.iter_mut() {
                    *o += w * row[i];
                    i += di;
                    if i >= n {
                        i -= n;
                    }
                }
            }
        }
    }
}

/// Piece weights summed per table row ([`CnRows::accumulate_piece`]), for
/// [`CnRows::correlate`].
#[derive(Clone, Debug)]
pub struct RowWeights {
    /// Dense per row, `rows x n`.
    w: Vec<f64>,
    touched: Vec<bool>,
}

impl RowWeights {
    /// Back to no weight (keeps the allocation).
    pub fn clear(&mut self) {
        self.w.iter_mut().for_each(|x| *x = 0.0);
        self.touched.iter_mut().for_each(|t| *t = false);
    }
}

/// [`CnRows::integrate`] as weights on row nodes ([`CnRows::weights`]).
#[derive(Clone, Debug)]
pub struct PsiWeights {
    first: usize,
    w0: Vec<f64>,
    w1: Vec<f64>,
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::medulla_mc::{build_tables, BuildOptions, McBudget, McGrid};
    use rand::{Rng, SeedableRng};

    /// The fast floor-and-wrap of `locate_periodic` equals floor + Euclidean remainder
    /// exactly, in and far outside one period, at bin edges and for negative zero.
    #[test]
    fn locate_periodic_matches_floor_and_rem_euclid() {
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(4);
        let (n, d) = (90usize, 2.0 * PI / 90.0);
        let c0 = -PI + 0.5 * d;
        let mut psis: Vec<f64> = (0..5000).map(|_| rng.random_range(-40.0..40.0)).collect();
        psis.extend((-200..200).map(|k| c0 + k as f64 * d));
        psis.extend([0.0, -0.0, PI, -PI, c0, c0 - 1e-17]);
        for psi in psis {
            let u = (psi - c0) / d;
            let fl = u.floor();
            let k0 = (fl as i64).rem_euclid(n as i64) as usize;
            let want = (k0, (k0 + 1) % n, u - fl);
            let got = locate_periodic(c0, d, n, psi);
            assert_eq!(got.0, want.0, "psi {psi}");
            assert_eq!(got.1, want.1, "psi {psi}");
            assert_eq!(got.2.to_bits(), want.2.to_bits(), "psi {psi}");
        }
    }

    fn tiny_options(seed: u64) -> BuildOptions {
        BuildOptions {
            grid: McGrid::tiny(),
            seed,
            budget: McBudget::from_paths(400),
            ranks: vec![4],
            target_error: 0.0,
            max_iter: 30,
        }
    }

    fn tiny_bytes(seed: u64) -> Vec<u8> {
        build_tables(&tiny_options(seed), &|| {}, &mut |_| {})
            .0
            .to_bytes()
    }

    /// The per-slice node grid is a rounding-level reorganisation of the rank sum: queries
    /// agree with the compressed factors to 1e-12 of the peak (the two sum the same
    /// products in another order) wherever no floored node is involved, which is most
    /// queries, and otherwise only lie above them, at random `(tau, g)`, `x` and `psi`.
    #[test]
    fn node_grid_matches_compressed_factors() {
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(11);
        for _ in 0..8 {
            let s = MedullaTables::builtin()
                .slice(rng.random_range(0.0..22.0), rng.random_range(-0.95..0.97));
            let mut exact = 0;
            for _ in 0..200 {
                let (x, psi) = (rng.random_range(-1.2..1.2), rng.random_range(-4.0..4.0));
                let peak = (0..720)
                    .map(|k| s.cn_compressed(x, -PI + k as f64 * PI / 360.0))
                    .fold(1e-300f64, f64::max);
                let (a, b) = (s.cn(x, psi), s.cn_compressed(x, psi));
                let tol = 1e-12 * peak;
                // Flooring a node only raises it (from a compression negative, which is at
                // most a few % of the peak, to NODE_FLOOR of the row's peak), so a query
                // near such a node rises by less than 5 % of the peak and never falls.
                assert!(
                    a >= b - tol && a <= b + 0.05 * peak + tol,
                    "x {x} psi {psi}: {a} vs {b} (peak {peak})"
                );
                exact += ((a - b).abs() <= tol) as usize;
            }
            assert!(
                exact >= 150,
                "only {exact} of 200 queries away from the floor"
            );
        }
    }

    /// The tabulated profile is the same function as the point query: both lerp the same
    /// node grid, in `x` then `psi` or the other way round, so agreement to 1e-12 of the
    /// profile's peak is a real check, including the `x < 0` flip and mirror.
    #[test]
    fn cn_profile_matches_cn() {
        let s = MedullaTables::builtin().slice(3.0, 0.4);
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(5);
        // +0 and -0 first: the h -> 0+ and h -> 0- limits read the x = 0 row unflipped
        // and flipped, in the profile as in the point query.
        let xs: Vec<f64> = [0.0, -0.0]
            .into_iter()
            .chain((0..40).map(|_| rng.random_range(-1.0..1.0)))
            .collect();
        for x in xs {
            let prof = s.cn_profile(x);
            let peak = (0..720)
                .map(|k| s.cn(x, -PI + k as f64 * PI / 360.0))
                .fold(0.0f64, f64::max)
                .max(1e-300);
            for _ in 0..50 {
                let psi: f64 = rng.random_range(-4.0..4.0);
                assert!((prof.cn(psi) - s.cn(x, psi)).abs() <= 1e-12 * peak);
                assert!((prof.cn_mirror(psi) - s.cn(-x, psi)).abs() <= 1e-12 * peak);
            }
        }
    }

    /// `CnRows::integrate` is the exact integral of a quadratic density against the rows'
    /// periodic piecewise-linear interpolant: against an adaptive Gauss-Kronrod reference
    /// (1e-13, split at every bin centre so each piece is a polynomial) for spans from a
    /// sliver of a bin to more than a period, starts far outside (-pi, pi], the first and
    /// last row pairs. 1e-12 of the integral of |density| times the row peak: the two-point
    /// rule is exact for each cubic piece, so only rounding remains.
    #[test]
    fn cn_rows_integrate_is_exact() {
        use crate::model::quadrature::adaptive_gk;
        let s = MedullaTables::builtin().slice(3.0, 0.4);
        let rows = s.cn_rows();
        let xs = rows.x_nodes().to_vec();
        let d = rows.bin_width();
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(41);
        for case in 0..200 {
            let i = [0, xs.len() - 2, case % (xs.len() - 1)][case % 3];
            let psi0: f64 = rng.random_range(-9.0..9.0);
            let len: f64 = 10f64.powf(rng.random_range(-4.0..0.9));
            let g = [0, 1].map(|_| {
                [
                    rng.random_range(-2.0..2.0),
                    rng.random_range(-2.0..2.0),
                    rng.random_range(-2.0..2.0),
                ]
            });
            let poly = |c: &[f64; 3], t: f64| c[0] + t * (c[1] + t * c[2]);
            // Row values through the point query at the row's own node (clamping never
            // acts: floored nodes are positive).
            let f = |t: f64| {
                let (r0, r1) = (
                    s.cn_shape_clamped(xs[i], psi0 + t),
                    s.cn_shape_clamped(xs[i + 1], psi0 + t),
                );
                poly(&g[0], t) * r0 + poly(&g[1], t) * (r1 - r0)
            };
            let (c0, _, _) = s.cn.last_axis();
            let first = ((psi0 - c0) / d).ceil() as i64;
            let mut pts = vec![0.0, len];
            let mut k = first;
            while c0 + k as f64 * d - psi0 < len {
                pts.push(c0 + k as f64 * d - psi0);
                k += 1;
            }
            pts.sort_by(f64::total_cmp);
            let reference = adaptive_gk(f, &pts, 1e-13, 1e-300, 1_000_000).value;
            let scale = adaptive_gk(
                |t| (poly(&g[0], t).abs() + poly(&g[1], t).abs()) * rows.peak,
                &pts,
                1e-10,
                1e-300,
                1_000_000,
            )
            .value;
            let v = rows.integrate(i, psi0, len, &g);
            assert!(
                (v - reference).abs() <= 1e-12 * scale,
                "row {i} psi0 {psi0} len {len}: {v} vs {reference}"
            );
        }
    }

    /// The node weights of `CnRows::weights`, moved by whole bins, give `integrate` at the
    /// start moved by as many bin widths (1e-12 of the scale: the same nodes, summed in
    /// another order), across the period and both ways.
    #[test]
    fn cn_rows_weights_match_integrate_shifted() {
        let s = MedullaTables::builtin().slice(1.5, -0.3);
        let rows = s.cn_rows();
        let d = rows.bin_width();
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(43);
        for _ in 0..100 {
            let i = rng.random_range(0..rows.x_nodes().len() - 1);
            let psi0: f64 = rng.random_range(-4.0..4.0);
            let len: f64 = 10f64.powf(rng.random_range(-4.0..0.9));
            let g = [0, 1].map(|_| std::array::from_fn(|_| rng.random_range(-2.0..2.0)));
            let w = rows.weights(psi0, len, &g);
            let scale = len * rows.peak * 10.0;
            for shift in [-400i64, -181, -7, -1, 0, 1, 3, 179, 180, 361] {
                let a = rows.dot(i, &w, shift);
                let b = rows.integrate(i, psi0 + shift as f64 * d, len, &g);
                assert!((a - b).abs() <= 1e-12 * scale, "shift {shift}: {a} vs {b}");
            }
        }
    }

    /// A random `psi` piece for the correlation tests: lower row `i`, start `psi0`, length
    /// (1e-3 to 3 rad) and the quadratics `g`.
    fn random_piece(
        rng: &mut rand_xoshiro::Xoshiro256PlusPlus,
        rows: &CnRows,
    ) -> (usize, f64, f64, [[f64; 3]; 2]) {
        let i = rng.random_range(0..rows.x_nodes().len() - 1);
        let psi0: f64 = rng.random_range(-4.0..4.0);
        let len: f64 = 10f64.powf(rng.random_range(-3.0..0.5));
        let g = [0, 1].map(|_| std::array::from_fn(|_| rng.random_range(0.0..2.0)));
        (i, psi0, len, g)
    }

    /// Pieces accumulated per table row ([`CnRows::accumulate_piece`]) and correlated
    /// along a grid equal the sum of their own dots at every grid point (1e-12 of the
    /// scale: the same products, summed in another order), for steps of either sign and
    /// overlapping pieces on neighbouring row pairs, and grids longer than a period.
    #[test]
    fn row_weights_correlate_equals_summed_dots() {
        let s = MedullaTables::builtin().slice(0.9, 0.4);
        let rows = s.cn_rows();
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(47);
        let mut acc = rows.row_weights();
        for step in [1i64, -1, 2, -3, 0, 180, -90, 7] {
            acc.clear();
            let mut pieces = Vec::new();
            for _ in 0..30 {
                let (i, psi0, len, g) = random_piece(&mut rng, &rows);
                let w = rows.weights(psi0, len, &g);
                rows.accumulate_piece(&mut acc, i, psi0, len, &g);
                pieces.push((i, w, len));
            }
            // 400 points: the runs of a one-bin step wrap more than once (180 bins).
            for points in [91, 400] {
                let mut out = vec![0.0; points];
                rows.correlate(&acc, step, &mut out);
                let scale: f64 = pieces.iter().map(|p| p.2).sum::<f64>() * rows.peak * 10.0;
                for (q, &o) in out.iter().enumerate() {
                    let sum: f64 = pieces
                        .iter()
                        .map(|(i, w, _)| rows.dot(*i, w, step * q as i64))
                        .sum();
                    assert!(
                        (o - sum).abs() <= 1e-12 * scale,
                        "step {step} q {q}: {o} vs {sum}"
                    );
                }
            }
        }
    }

    /// The AVX2 build of [`CnRows::correlate`] gives the portable build's values bit for
    /// bit (the dispatch picks one by CPU; results may not depend on the machine), for
    /// steps of either sign, one bin and several.
    #[test]
    fn correlate_avx2_equals_portable_build() {
        let s = MedullaTables::builtin().slice(0.9, 0.4);
        let rows = s.cn_rows();
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(59);
        let mut acc = rows.row_weights();
        for _ in 0..20 {
            let (i, psi0, len, g) = random_piece(&mut rng, &rows);
            rows.accumulate_piece(&mut acc, i, psi0, len, &g);
        }
        for step in [1i64, -1, 3, -7, 0] {
            let mut portable = vec![0.5; 200];
            rows.correlate_body(&acc, step, &mut portable);
            let mut chosen = vec![0.5; 200];
            rows.correlate(&acc, step, &mut chosen);
            assert!(portable.iter().any(|&v| v > 0.5));
            for (a, b) in portable.iter().zip(&chosen) {
                assert_eq!(a.to_bits(), b.to_bits(), "step {step}");
            }
        }
    }

    /// A point query as row weights ([`CnRows::accumulate_point`]) read along a grid by
    /// [`CnRows::correlate`] equals the query itself at every grid point: the bilinear
    /// lerp rewritten, so to rounding (1e-12 of the table's peak times the weight).
    #[test]
    fn accumulate_point_correlates_to_point_queries() {
        let s = MedullaTables::builtin().slice(2.0, 0.6);
        let rows = s.cn_rows();
        let d = rows.bin_width();
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(53);
        let mut acc = rows.row_weights();
        for step in [1i64, -1, 2, -3, 0] {
            for _ in 0..40 {
                acc.clear();
                // Offsets include the end nodes and beyond (constant there).
                let x: f64 = [0.0, 1.0, rng.random_range(0.0..1.0)][rng.random_range(0..3)];
                let psi0: f64 = rng.random_range(-9.0..9.0);
                let w: f64 = rng.random_range(0.1..3.0);
                rows.accumulate_point(&mut acc, x, psi0, w);
                let mut out = vec![0.0; 91];
                rows.correlate(&acc, step, &mut out);
                for (q, &o) in out.iter().enumerate() {
                    let want = w * s.cn_shape_clamped(x, psi0 + (step * q as i64) as f64 * d);
                    assert!(
                        (o - want).abs() <= 1e-12 * w * rows.peak,
                        "step {step} x {x} psi0 {psi0} q {q}: {o} vs {want}"
                    );
                }
            }
        }
    }

    /// Trapezoid over 8 points per psi bin: exact for the piecewise-linear `cn` at fixed
    /// `x` (every bin centre is a sample point) up to the clamping of negatives.
    fn integrate_cn(s: &MedullaSlice, x: f64) -> f64 {
        let n = 180 * 8;
        let h = 2.0 * PI / n as f64;
        // Periodic: the plain sum is the trapezoid rule.
        (0..n)
            .map(|k| s.cn(x, -PI + (k as f64 + 0.5) * h))
            .sum::<f64>()
            * h
    }

    fn integrate_cm(s: &MedullaSlice, ti: f64, side: Side) -> f64 {
        let n = 90 * 8;
        let h = PI / n as f64;
        (0..n)
            .map(|k| s.cm(ti, -FRAC_PI_2 + (k as f64 + 0.5) * h, side))
            .sum::<f64>()
            * h
    }

    #[test]
    fn deterministic_build_same_seed_same_bytes() {
        let a = tiny_bytes(11);
        let b = tiny_bytes(11);
        assert_eq!(a, b);
        assert_ne!(a, tiny_bytes(12));
        let t = MedullaTables::from_bytes(&a).unwrap();
        assert_eq!(t.to_bytes(), a, "parse/serialise round trip");
    }

    #[test]
    fn corrupt_bytes_are_errors_not_panics() {
        let b = tiny_bytes(5);
        for len in (0..b.len()).step_by(7) {
            assert!(MedullaTables::from_bytes(&b[..len]).is_err(), "len {len}");
        }
        for pos in (0..b.len()).step_by(13) {
            let mut c = b.clone();
            c[pos] ^= 0x5a;
            assert!(MedullaTables::from_bytes(&c).is_err(), "flip at {pos}");
        }
        // A body with a valid checksum but an absurd rank / axis must still be rejected.
        use sha2::{Digest, Sha256};
        let reseal = |mut body: Vec<u8>| {
            let s = Sha256::digest(&body);
            body.extend_from_slice(&s);
            body
        };
        let body = b[..b.len() - 32].to_vec();
        let rank_pos = 8 + 4 + 8 + 8 + 4 + 4;
        let mut bad_rank = body.clone();
        bad_rank[rank_pos..rank_pos + 4].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(MedullaTables::from_bytes(&reseal(bad_rank)).is_err());
        let mut nan_axis = body.clone();
        let axis_pos = rank_pos + 8 + 4; // first value of the tau axis
        nan_axis[axis_pos..axis_pos + 8].copy_from_slice(&f64::NAN.to_le_bytes());
        assert!(MedullaTables::from_bytes(&reseal(nan_axis)).is_err());
        let mut short = body.clone();
        short.truncate(body.len() - 4);
        assert!(MedullaTables::from_bytes(&reseal(short)).is_err());
        assert!(MedullaTables::from_bytes(&reseal(body)).is_ok());
    }

    /// `f(v)` from [`hermite_stencil`] on samples of `f` at `axis`.
    fn hermite(axis: &[f64], f: impl Fn(f64) -> f64, v: f64) -> f64 {
        let (nodes, w) = hermite_stencil(axis, v);
        (0..4).map(|q| w[q] * f(axis[nodes[q]])).sum()
    }

    /// The stencil passes through the nodes, reproduces straight lines on an uneven axis
    /// and quadratics between interior nodes of an even one (centred slopes are then
    /// exact), and is constant beyond the ends. Tolerances: 1e-12, rounding of a few
    /// operations on O(1) values.
    #[test]
    fn hermite_stencil_interpolates_exactly_where_it_should() {
        let uneven = [0.0, 0.1, 0.35, 0.4, 1.0, 2.5];
        let line = |x: f64| 3.0 - 2.0 * x;
        for k in 0..=250 {
            let v = 2.5 * k as f64 / 250.0;
            assert!((hermite(&uneven, line, v) - line(v)).abs() < 1e-12, "{v}");
        }
        for (i, &x) in uneven.iter().enumerate() {
            let f = |y: f64| (5.0 * y).sin() + i as f64;
            assert!((hermite(&uneven, f, x) - f(x)).abs() < 1e-12);
        }
        let even: Vec<f64> = (0..8).map(|k| k as f64 * 0.5).collect();
        let quad = |x: f64| 1.0 + x - 0.7 * x * x;
        for k in 0..=100 {
            let v = 0.5 + 2.5 * k as f64 / 100.0; // between nodes 1 and 6
            assert!((hermite(&even, quad, v) - quad(v)).abs() < 1e-12, "{v}");
        }
        assert_eq!(hermite(&even, quad, -3.0), quad(0.0));
        assert_eq!(hermite(&even, quad, 9.0), quad(3.5));
    }

    /// C^1: on both sides of every interior node of an uneven axis the one-sided slopes
    /// agree (a linear interpolant's jump there is O(1) for this curve). Steps of 1e-6 give
    /// one-sided slopes within ~1e-5 of the node's derivative; 1e-4 leaves room.
    #[test]
    fn hermite_stencil_is_continuously_differentiable() {
        let axis = [0.0, 0.2, 0.5, 0.55, 1.0, 1.7, 3.0];
        let f = |x: f64| (2.0 * x).sin() + 0.3 * x * x;
        let h = 1e-6;
        for &x in &axis[1..axis.len() - 1] {
            let left = (hermite(&axis, f, x) - hermite(&axis, f, x - h)) / h;
            let right = (hermite(&axis, f, x + h) - hermite(&axis, f, x)) / h;
            assert!((left - right).abs() < 1e-4, "node {x}: {left} vs {right}");
        }
    }

    /// The shipped tables' scattered lobes are differentiable in `tau` and `g` across
    /// their nodes (the fitter stopped on kinks there when `tau` and `g` were interpolated
    /// linearly): one-sided slopes of `C^N` and `C^M` at a node agree to 1e-3 of their
    /// size, where the linear interpolation's slopes differed by tens of percent.
    #[test]
    fn shipped_tables_have_no_kink_at_tau_and_g_nodes() {
        let t = MedullaTables::builtin();
        let (taus, gs) = (&t.cn.axes[0], &t.cn.axes[1]);
        let (tau0, g0) = (taus[taus.len() / 6], gs[gs.len() / 2]);
        let h = 1e-6;
        let probe = |tau: f64, g: f64| {
            let s = t.slice(tau, g);
            [
                s.cn(0.3, 2.0),
                s.cn(-0.6, 0.4),
                s.cm(0.3, -0.2, Side::Front),
                s.cm(0.7, 0.5, Side::Back),
            ]
        };
        for (dt, dg) in [(h, 0.0), (0.0, h)] {
            let (lo, mid, hi) = (
                probe(tau0 - dt, g0 - dg),
                probe(tau0, g0),
                probe(tau0 + dt, g0 + dg),
            );
            for q in 0..4 {
                let (left, right) = ((mid[q] - lo[q]) / h, (hi[q] - mid[q]) / h);
                let scale = left.abs().max(right.abs()).max(1e-3 * mid[q]);
                assert!(
                    (left - right).abs() <= 1e-3 * scale + 1e-9,
                    "tau {tau0} g {g0} probe {q} d({dt},{dg}): {left} vs {right}"
                );
            }
        }
    }

    #[test]
    fn shipped_cn_integrates_to_analytic_scattered_fraction() {
        let t = MedullaTables::builtin();
        for &(tau, g) in &[
            (0.3, 0.0),
            (1.2, 0.6),
            (2.7, 0.79),
            (6.0, -0.4),
            (15.0, 0.9),
        ] {
            let s = t.slice(tau, g);
            for &x in &[-0.95, -0.5, 0.0, 0.33, 0.8, 0.999] {
                let num = integrate_cn(&s, x);
                let sf = s.scattered_fraction(x);
                let exact = scatter_probability(tau, x);
                // Clamping compressed negatives only adds their (tiny) mass: 1% of the
                // fraction bounds it for the shipped ranks.
                assert!(
                    (num - sf).abs() <= 0.01 * sf + 1e-12,
                    "{tau} {g} {x}: {num} {sf}"
                );
                // Every raw slice integrates to exactly 1; the CP shape keeps that to
                // within its compression error (a few %), so 5% of the fraction.
                assert!(
                    (num - exact).abs() <= 0.05 * exact + 1e-12,
                    "{tau} {g} {x}: {num} vs {exact}"
                );
            }
        }
    }

    #[test]
    fn shipped_cm_integrates_to_one() {
        let t = MedullaTables::builtin();
        for &(tau, g) in &[
            (0.0, 0.0),
            (0.3, 0.2),
            (1.2, 0.6),
            (2.7, 0.79),
            (12.0, -0.6),
        ] {
            let s = t.slice(tau, g);
            for &ti in &[-1.2, -0.3, 0.0, 0.5, 1.0, 1.5] {
                for side in [Side::Front, Side::Back] {
                    let i = integrate_cm(&s, ti, side);
                    // Raw slices integrate to 1; CP compression error of a few % (5%).
                    assert!((i - 1.0).abs() < 0.05, "{tau} {g} {ti} {side:?}: {i}");
                }
            }
        }
    }

    #[test]
    fn thick_medulla_reflects_around_the_entry_normal() {
        // Optically thick, isotropic: light diffuses out near the entry point, whose
        // outward normal for offset x lies at psi = -asin(x) (same side as the paper's
        // R lobe at phi = -2 asin(h) for positive h). So the density at psi = -asin(x) is
        // well above its mirror image +asin(x) and far above straight-through.
        let s = MedullaTables::builtin().slice(10.0, 0.0);
        let x: f64 = 0.7;
        let n = s.cn(x, -x.asin());
        let m = s.cn(x, x.asin());
        let fwd = s.cn(x, PI);
        assert!(n > 1.5 * m, "{n} vs mirror {m}");
        assert!(n > 3.0 * fwd, "{n} vs forward {fwd}");
        // Thin medulla, strong forward scattering: almost everything goes straight on.
        let s = MedullaTables::builtin().slice(0.2, 0.9);
        assert!(s.cn(0.3, PI) > 20.0 * s.cn(0.3, 0.0));
    }

    #[test]
    fn symmetries_hold_exactly() {
        let s = MedullaTables::builtin().slice(1.7, 0.45);
        for &x in &[0.1, 0.5, 0.93] {
            for &psi in &[-3.0, -1.0, 0.2, 2.5, PI] {
                let a = s.cn(x, psi);
                let b = s.cn(-x, -psi);
                // Same factor rows by construction; wrap of -pi vs pi may differ by 1 ulp.
                assert!(
                    (a - b).abs() <= 1e-12 * (a.abs() + 1e-300),
                    "{x} {psi}: {a} {b}"
                );
            }
        }
        for &ti in &[0.2, 0.9] {
            for &tr in &[-1.0, 0.0, 0.7] {
                for side in [Side::Front, Side::Back] {
                    assert_eq!(s.cm(ti, tr, side), s.cm(-ti, -tr, side));
                }
            }
        }
    }

    #[test]
    fn domain_notes_name_what_leaves_the_tables() {
        let t = MedullaTables::builtin();
        let ([_, t1], [g0, g1]) = t.domain();
        assert!(t.domain_notes(1.0, 0.3).is_empty());
        assert!(
            t.domain_notes(t1, g1).is_empty(),
            "the edges themselves are covered"
        );
        let n = t.domain_notes(1.0, 0.97);
        assert!(n.len() == 1 && n[0].contains("g = 0.97"), "{n:?}");
        assert_eq!(t.domain_notes(1.0, g0 - 0.05).len(), 1);
        let n = t.domain_notes(t1 * 2.0, -0.99);
        assert_eq!(n.len(), 2, "{n:?}");
        // A huge tau (sigma_m_s = 1e12) in scientific notation, not 12 digits and more.
        let n = t.domain_notes(1e12 * 0.86, 0.3);
        assert!(
            n[0].contains("tau = sigma_m_s * kappa = 8.6e11 is above"),
            "{n:?}"
        );
        let n = t.domain_notes(1.0, -1e300);
        assert!(n[0].contains("g = -1e300 is outside"), "{n:?}");
    }

    #[test]
    fn extreme_queries_are_finite_and_non_negative() {
        let t = MedullaTables::builtin();
        let big = 1e6;
        for &tau in &[0.0, 1e-9, 20.0, 1e3, big, f64::INFINITY, -1.0] {
            for &g in &[-0.999, -0.9, 0.0, 0.95, 0.999] {
                let s = t.slice(tau, g);
                for &x in &[-1.0, -0.999_999, 0.0, 1.0, 1.5, -7.0] {
                    for &psi in &[-PI, -1e-9, 0.0, PI, 10.0, -100.0] {
                        let v = s.cn(x, psi);
                        assert!(v.is_finite() && v >= 0.0, "cn {tau} {g} {x} {psi}: {v}");
                    }
                    let f = s.scattered_fraction(x);
                    assert!(f.is_finite() && f >= 0.0);
                }
                for &ti in &[-FRAC_PI_2, -1.0, 0.0, FRAC_PI_2, 2.0] {
                    for &tr in &[-FRAC_PI_2, 0.0, FRAC_PI_2, 3.0] {
                        for &phi in &[0.0, 1.0, PI, -PI] {
                            let v = s.cm_lerp(ti, tr, phi);
                            assert!(v.is_finite() && v >= 0.0, "cm {tau} {g} {ti} {tr}");
                        }
                    }
                }
            }
        }
        // tau = 0: no scattering at all.
        assert_eq!(t.slice(0.0, 0.3).cn(0.2, 1.0), 0.0);
    }

    #[test]
    fn sampled_psi_follows_returned_pdf_and_cn() {
        let s = MedullaTables::builtin().slice(1.3, 0.5);
        let sm = s.sampler();
        let x = -0.37;
        let total = integrate_cn(&s, x);
        // pdf is the density actually sampled; equals cn / integral where nothing clamps.
        for &psi in &[-2.9, -1.0, 0.0, 1.5, 3.0] {
            let p = sm.pdf_cn(x, psi);
            let c = s.cn(x, psi) / total;
            assert!((p - c).abs() < 0.02 * c.max(0.05), "{psi}: {p} vs {c}");
        }
        // Histogram of 40k samples in 24 bins against the pdf integrated per bin
        // (chi-square with 23 dof: mean 23, sd 6.8; 70 is ~7 sd).
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(9);
        let n = 40_000;
        let bins = 24;
        let mut hist = vec![0.0; bins];
        for _ in 0..n {
            let (psi, pdf) = sm.sample_cn(x, rng.random());
            assert!((pdf - sm.pdf_cn(x, psi)).abs() <= 1e-9 * pdf.max(1.0));
            let k = (((psi + PI) / (2.0 * PI) * bins as f64) as usize).min(bins - 1);
            hist[k] += 1.0;
        }
        let mut chi2 = 0.0;
        for (k, &h) in hist.iter().enumerate() {
            let m = 64;
            let w = 2.0 * PI / bins as f64;
            let e: f64 = (0..m)
                .map(|j| sm.pdf_cn(x, -PI + k as f64 * w + (j as f64 + 0.5) * w / m as f64))
                .sum::<f64>()
                * w
                / m as f64
                * n as f64;
            if e > 5.0 {
                chi2 += (h - e) * (h - e) / e;
            }
        }
        assert!(chi2 < 70.0, "chi2 {chi2}");
    }

    /// The column sampler (incident `theta_i` for a given exit `theta_r`, the renderer's
    /// light side) draws what its pdf says (chi-square over 18 bins), and its pdf is the
    /// normalised column of `cm_lerp`, both signs of `theta_i` (the mirrored half reads the
    /// table at `(-theta_i, -theta_r)`) and at the ends beyond the table's nodes.
    #[test]
    fn sampled_theta_i_follows_returned_pdf_and_the_column() {
        let s = MedullaTables::builtin().slice(0.8, 0.3);
        let sm = s.sampler();
        for (case, &(tr, phi)) in [(-0.6, 2.0), (0.9, 0.3), (0.0, PI)].iter().enumerate() {
            let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(20 + case as u64);
            let n = 40_000;
            let bins = 18;
            let mut hist = vec![0.0; bins];
            for _ in 0..n {
                let (ti, pdf) = sm.sample_cm_incident(tr, phi, rng.random());
                assert!((-FRAC_PI_2..=FRAC_PI_2).contains(&ti));
                let again = sm.pdf_cm_incident(tr, ti, phi);
                assert!(
                    (pdf - again).abs() <= 1e-9 * pdf.max(1.0),
                    "{pdf} vs {again}"
                );
                let k = (((ti + FRAC_PI_2) / PI * bins as f64) as usize).min(bins - 1);
                hist[k] += 1.0;
            }
            let w = PI / bins as f64;
            let mut chi2 = 0.0;
            for (k, &h) in hist.iter().enumerate() {
                let m = 64;
                let e: f64 = (0..m)
                    .map(|j| {
                        let ti = -FRAC_PI_2 + k as f64 * w + (j as f64 + 0.5) * w / m as f64;
                        sm.pdf_cm_incident(tr, ti, phi)
                    })
                    .sum::<f64>()
                    * w
                    / m as f64
                    * n as f64;
                if e > 5.0 {
                    chi2 += (h - e) * (h - e) / e;
                }
            }
            // 17 dof: mean 17, sd 5.8; 60 is ~7 sd.
            assert!(chi2 < 60.0, "case {case}: chi2 {chi2}");
            // The pdf is the column of cm_lerp, normalised: the same piecewise-linear
            // function, so equal up to the midpoint rule's error on 2880 cells (< 1e-3).
            let cells = 2880;
            let norm: f64 = (0..cells)
                .map(|k| s.cm_lerp(-FRAC_PI_2 + (k as f64 + 0.5) * PI / cells as f64, tr, phi))
                .sum::<f64>()
                * PI
                / cells as f64;
            for &ti in &[-1.5, -0.7, -0.01, 0.01, 0.5, 1.2, 1.56] {
                let p = sm.pdf_cm_incident(tr, ti, phi);
                let c = s.cm_lerp(ti, tr, phi) / norm;
                assert!(
                    (p - c).abs() < 1e-3 * c,
                    "case {case}, theta_i {ti}: {p} vs {c}"
                );
            }
        }
    }
}
