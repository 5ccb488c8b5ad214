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

mod grid;
mod rows;
mod slice;
mod tables;
#[cfg(test)]
mod tests;

pub use grid::wrap_pi;
pub use rows::{CnRows, PsiWeights, RowWeights};
pub use slice::{
    front_back_lerp, scatter_probability, CnProfile, MedullaSampler, MedullaSlice, NODE_FLOOR,
};
pub use tables::{CpTable, MedullaTables, Side, TableKind, MAGIC, VERSION};
