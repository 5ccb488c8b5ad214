//! Sweeps along an even `phi` grid: the Fourier-space sum and the uniform grid.

use super::*;

/// [`FarSlice::eval_many`] sweeps a quadrature-node piece along an even `phi` grid only
/// when the step is at most this many `beta`: the recurrence's ratio then stays below
/// `e^(SWEEP_MAX_STEP * CULL_SIGMAS + SWEEP_MAX_STEP^2 / 2)` = `e^42` (no overflow), and a
/// coarser grid puts at most a couple of `phi` in a node's window anyway.
pub(super) const SWEEP_MAX_STEP: f64 = 4.0;

/// [`FourierGrid`] sums the series to the first `n` with `n beta >= FOURIER_REACH`: the
/// terms left out are below `exp(-FOURIER_REACH^2 / 2)` = 1e-17 of the mean.
pub(super) const FOURIER_REACH: f64 = 8.85;
/// Most terms of a [`FourierGrid`] (beyond, the node sweep is cheaper for any grid).
pub(super) const FOURIER_MAX_TERMS: usize = 256;
/// Nodes per block of [`FourierGrid::add`] (independent rotations, one vector lane each).
pub(super) const FOURIER_LANES: usize = 4;

/// The wrapped-Gaussian sum of a lobe's nodes on an evenly spaced grid, in Fourier space:
/// `sum_k W_k sum_j G(Phi_k - phi + 2 pi j; beta)` is
/// `1/(2 pi) sum_k W_k (1 + 2 sum_{n>=1} rho_n cos n(Phi_k - phi))` with
/// `rho_n = exp(-n^2 beta^2 / 2)` (the Fourier series of the wrapped normal, Poisson
/// summation; [`wrapped_gaussian`] sums the same series at one point for `beta > 1.5`,
/// to the same 1e-17 term), so the nodes enter only through `A_n = sum_k W_k cos n Phi_k` and
/// `B_n = sum_k W_k sin n Phi_k`. For a wide lobe (fur: `beta_n` ~ 10-20 deg) the series
/// needs a few dozen terms while a node's Gaussian window covers the whole grid: per node
/// that is `n` complex rotations instead of two sides times the grid. It sums every image
/// (the culled sweep leaves out those beyond `CULL_SIGMAS`, below `e^-36` of a node's
/// peak), so the two agree far within 1e-12 of the lobe's peak.
pub(super) struct FourierGrid {
    /// `rho_n`, `n = 0..terms`.
    pub(super) rho: Vec<f64>,
}

/// `cos n phi_q` and `sin n phi_q` on a grid (`[n][q]`), shared by the lobes of a slice.
#[derive(Default)]
pub(super) struct FourierTable {
    pub(super) terms: usize,
    pub(super) cos: Vec<f64>,
    pub(super) sin: Vec<f64>,
}

impl FourierTable {
    /// Make the table hold at least `terms` rows for the `points` of `g`.
    pub(super) fn reserve(&mut self, g: &UniformGrid, points: usize, terms: usize) {
        if self.terms >= terms {
            return;
        }
        self.cos = vec![0.0; terms * points];
        self.sin = vec![0.0; terms * points];
        for q in 0..points {
            let (si, co) = (g.first + q as f64 * g.step).sin_cos();
            let (mut re, mut im) = (1.0, 0.0);
            for n in 0..terms {
                self.cos[n * points + q] = re;
                self.sin[n * points + q] = im;
                (re, im) = (re * co - im * si, re * si + im * co);
            }
        }
        self.terms = terms;
    }
}

impl FourierGrid {
    /// `Some` when the series costs less than sweeping each node over its window on
    /// `points` grid points (`sides` 1 or 2; a complex rotation counted as two sweep steps).
    pub(super) fn new(
        g: &UniformGrid,
        points: usize,
        beta: f64,
        w: f64,
        sides: usize,
    ) -> Option<Self> {
        let terms = (FOURIER_REACH / beta).ceil();
        let window = ((2.0 * w / g.step).floor() + 1.0).min(points as f64);
        if !(terms <= FOURIER_MAX_TERMS as f64 && 2.0 * terms < sides as f64 * window) {
            return None;
        }
        let rho = (0..=terms as usize)
            .map(|n| (-0.5 * (n as f64 * beta).powi(2)).exp())
            .collect();
        Some(FourierGrid { rho })
    }

    /// Add the sum over `nodes` `(Phi_k, W_k)` for the direct side (`G(Phi_k - phi)`) and
    /// the mirrored one (`G(Phi_k + phi)`) at every grid point of `table` to `s` (sorted
    /// order; `table` holds at least `self.rho.len()` rows).
    pub(super) fn add(
        &self,
        nodes: &[(f64, f64)],
        (direct, mirror): (bool, bool),
        table: &FourierTable,
        s: &mut [f64],
    ) {
        if nodes.is_empty() || !(direct || mirror) {
            return;
        }
        let terms = self.rho.len();
        // A_n, B_n by rotation, z^n with z = exp(i Phi_k) (error ~n eps), in blocks of
        // FOURIER_LANES nodes with one partial sum per lane.
        const L: usize = FOURIER_LANES;
        let (mut a, mut b) = (vec![[0.0; L]; terms], vec![[0.0; L]; terms]);
        for block in nodes.chunks(L) {
            let (mut re, mut im, mut co, mut si) = ([0.0; L], [0.0; L], [1.0; L], [0.0; L]);
            for (j, &(ph, wt)) in block.iter().enumerate() {
                (si[j], co[j]) = ph.sin_cos();
                re[j] = wt;
            }
            for n in 0..terms {
                for j in 0..L {
                    a[n][j] += re[j];
                    b[n][j] += im[j];
                    (re[j], im[j]) = (re[j] * co[j] - im[j] * si[j], re[j] * si[j] + im[j] * co[j]);
                }
            }
        }
        // Direct + mirror: cos n(Phi - phi) + cos n(Phi + phi) = 2 cos n Phi cos n phi;
        // the sine parts carry the difference of the sides.
        let ca = (direct as u8 + mirror as u8) as f64;
        let cb = direct as u8 as f64 - mirror as u8 as f64;
        let points = s.len();
        for n in 0..terms {
            let f = if n == 0 { 1.0 } else { 2.0 * self.rho[n] } / TAU;
            let an = ca * f * a[n].iter().sum::<f64>();
            let bn = cb * f * b[n].iter().sum::<f64>();
            let row = n * points..(n + 1) * points;
            for (x, c) in s.iter_mut().zip(&table.cos[row.clone()]) {
                *x += an * c;
            }
            if bn != 0.0 {
                for (x, c) in s.iter_mut().zip(&table.sin[row]) {
                    *x += bn * c;
                }
            }
        }
    }
}

/// Points per run of the Gaussian recurrence before it restarts from exponentials: each
/// of its [`SWEEP_CHAINS`] chains takes `SWEEP_RUN / SWEEP_CHAINS` = 32 steps, whose drift
/// is ~`32^2 eps / 2` = 6e-14 relative, and the restart costs two exponentials per 128
/// points instead of 128.
pub(super) const SWEEP_RUN: usize = 128;
/// Interleaved recurrence chains of a sweep run (see [`UniformGrid::gaussian_sweep`]).
pub(super) const SWEEP_CHAINS: usize = 4;
/// Sweep runs whose starting exponentials [`UniformGrid::gaussian_sweep`] takes together
/// (a multiple of the 4 lanes of `f64x4`).
pub(super) const SWEEP_BATCH: usize = 32;

/// Sorted `phi` that are evenly spaced: `first + q * step` within [`UNIFORM_SLACK`].
pub(super) struct UniformGrid {
    pub(super) first: f64,
    pub(super) step: f64,
}

/// Largest deviation (radians) of a sorted grid from its arithmetic progression that still
/// counts as even: a grid of `to_radians` of even degree steps deviates by a few ulp
/// (~1e-15). A node's Gaussian then moves by `|y| dev / beta^2 <= 8.5 dev / beta` of itself
/// (1e-11 at `beta` = 0.1 deg), below the engine's 1e-4 tolerance by far.
pub(super) const UNIFORM_SLACK: f64 = 1e-13;

/// Where a piece's node Gaussians are swept: images `mu = sign * phi + shift` for the
/// sorted `phi` in `qa..qb`, lobe width `beta`, window half-width `w`.
pub(super) struct SweepWindow {
    pub(super) sign: f64,
    pub(super) shift: f64,
    pub(super) qa: usize,
    pub(super) qb: usize,
    pub(super) beta: f64,
    pub(super) w: f64,
}

impl UniformGrid {
    /// `Some` when `sorted` has at least three distinct, evenly spaced values.
    pub(super) fn detect(sorted: &[f64]) -> Option<UniformGrid> {
        let n = sorted.len();
        if n < 3 {
            return None;
        }
        let (first, last) = (sorted[0], sorted[n - 1]);
        let step = (last - first) / (n - 1) as f64;
        if step <= 0.0 {
            return None;
        }
        sorted
            .iter()
            .enumerate()
            .all(|(q, &x)| (x - (first + q as f64 * step)).abs() <= UNIFORM_SLACK)
            .then_some(UniformGrid { first, step })
    }

    /// Add `sum_nodes wt G(ph - mu_q; beta)` to `s[q]` (sorted order) for every `q` of the window
    /// whose image `mu_q` lies within `w` of the node (beyond, a node's Gaussian is below
    /// `e^-36` of its peak, as [`FarSlice::add_piece`] would add). Along the grid
    /// `y_q = ph - mu_q` moves by `-sign * step`, so `G_{q+1} = G_q r_q` with
    /// `r_{q+1} = r_q exp(-step^2 / beta^2)`: two exponentials per run of [`SWEEP_RUN`]
    /// points instead of one per `phi`.
    pub(super) fn gaussian_sweep(&self, nodes: &[(f64, f64)], at: &SweepWindow, s: &mut [f64]) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2 (checked just above).
            return unsafe { self.gaussian_sweep_avx2(nodes, at, s) };
        }
        self.gaussian_sweep_body(nodes, at, s)
    }

    /// [`Self::gaussian_sweep`] compiled for AVX2 (wider vectors for the chains; the same
    /// operations in the same order, so the same values bit for bit).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    pub(super) fn gaussian_sweep_avx2(
        &self,
        nodes: &[(f64, f64)],
        at: &SweepWindow,
        s: &mut [f64],
    ) {
        self.gaussian_sweep_body(nodes, at, s)
    }

    #[inline(always)]
    pub(super) fn gaussian_sweep_body(
        &self,
        nodes: &[(f64, f64)],
        at: &SweepWindow,
        s: &mut [f64],
    ) {
        let c = 0.5 / (at.beta * at.beta);
        let norm = 1.0 / (at.beta * TAU.sqrt());
        let d = at.sign * self.step;
        let damp = (-2.0 * self.step * self.step * c).exp();
        let damp_s2 = damp.powi((SWEEP_CHAINS * SWEEP_CHAINS) as i32);
        let inv_step = 1.0 / self.step;
        // The runs (start, end, weight) and the exponents of their first value and ratio,
        // batched so that the exponentials are taken four at a time: a narrow lobe's
        // window holds ~10 points, so these two per run were most of a sweep.
        let mut runs = [(0usize, 0usize, 0.0f64); SWEEP_BATCH];
        let mut args = [[0.0f64; SWEEP_BATCH]; 2];
        let mut n = 0;
        for &(ph, wt) in nodes {
            // mu_q within w of ph: sign * x_q in [ph - shift - w, ph - shift + w].
            let (lo, hi) = (ph - at.shift - at.w, ph - at.shift + at.w);
            let (xlo, xhi) = if at.sign > 0.0 { (lo, hi) } else { (-hi, -lo) };
            let q0 = (((xlo - self.first) * inv_step).ceil().max(at.qa as f64)) as usize;
            let q1 = (((xhi - self.first) * inv_step).floor() + 1.0).min(at.qb as f64);
            if q1 <= q0 as f64 {
                continue;
            }
            let q1 = q1 as usize;
            // Restarted from the exact grid position every SWEEP_RUN points: `damp`'s
            // rounding compounds quadratically along a chain (n^2 eps / 2).
            for start in (q0..q1).step_by(SWEEP_RUN) {
                let mu = at.sign * (self.first + start as f64 * self.step) + at.shift;
                let y = ph - mu;
                // A ratio's exponent is at most c w^2 = 36 in magnitude where a run has
                // a second point (both within w = 8.5 beta of the node: sweeps run with
                // culling on); f64x4::exp's 0 above 708 (not inf) can only reach a ratio
                // that is never used.
                runs[n] = (start, (start + SWEEP_RUN).min(q1), wt);
                args[0][n] = -y * y * c;
                args[1][n] = (2.0 * y * d - self.step * self.step) * c;
                n += 1;
                if n == SWEEP_BATCH {
                    sweep_runs(&runs, &args, norm, [damp, damp_s2], s);
                    n = 0;
                }
            }
        }
        sweep_runs(&runs[..n], &args, norm, [damp, damp_s2], s);
    }
}

/// The recurrences of [`UniformGrid::gaussian_sweep`]'s batched `runs`: run `i` adds
/// `wt G_q` to `s[q]` for `q` in `start..end`, from `G_start = wt norm exp(args[0][i])`
/// with first ratio `exp(args[1][i])`, each ratio moving by `damp[0]` (`damp[1]` =
/// `damp[0]^(S^2)` along a chain). A function, not a closure, so that it is inlined into
/// the AVX2 build (a closure was compiled for the baseline target).
#[inline(always)]
pub(super) fn sweep_runs(
    runs: &[(usize, usize, f64)],
    args: &[[f64; SWEEP_BATCH]; 2],
    norm: f64,
    [damp, damp_s2]: [f64; 2],
    s: &mut [f64],
) {
    let n = runs.len();
    let mut e = [[0.0f64; SWEEP_BATCH]; 2];
    for (ek, ak) in e.iter_mut().zip(args) {
        for (o, a) in ek[..n.next_multiple_of(4)]
            .chunks_exact_mut(4)
            .zip(ak.chunks_exact(4))
        {
            o.copy_from_slice(&f64x4::from([a[0], a[1], a[2], a[3]]).exp().to_array());
        }
    }
    for (i, &(start, end, wt)) in runs.iter().enumerate() {
        let mut g = wt * norm * e[0][i];
        let mut r = e[1][i];
        // SWEEP_CHAINS interleaved chains, chain k on points start + k + j S
        // (S = SWEEP_CHAINS): its multiplier is the product of S consecutive ratios, and
        // moves by damp^(S^2) per step. Independent chains keep the multiplier latency off
        // the critical path.
        let mut gs = [0.0; SWEEP_CHAINS];
        let mut ratios = [0.0; 2 * SWEEP_CHAINS - 1];
        for (k, rk) in ratios.iter_mut().enumerate() {
            if k < SWEEP_CHAINS {
                gs[k] = g;
                g *= r;
            }
            *rk = r;
            r *= damp;
        }
        // ratios[k] = r_{start + k}; chain k's multiplier is r_{start + k} ...
        // r_{start + k + S - 1}.
        let mut ps: [f64; SWEEP_CHAINS] =
            std::array::from_fn(|k| ratios[k..k + SWEEP_CHAINS].iter().product());
        let run = &mut s[start..end];
        let mut chunks = run.chunks_exact_mut(SWEEP_CHAINS);
        for chunk in &mut chunks {
            for k in 0..SWEEP_CHAINS {
                chunk[k] += gs[k];
                gs[k] *= ps[k];
                ps[k] *= damp_s2;
            }
        }
        for (x, gk) in chunks.into_remainder().iter_mut().zip(gs) {
            *x += gk;
        }
    }
}

/// How far (in bins) a grid step may be from a whole number of `psi` bins for
/// [`FarSlice::add_rows_sweep`]: over 360 points the positions then drift by under 4e-7 of
/// a bin, which moves a piece's integral (or a node's query) by that fraction of its value
/// at most.
pub(super) const PSI_SWEEP_SLACK: f64 = 1e-9;

/// [`FarSlice::eval_grid`] tabulates the medulla table per scattered node from this many
/// `phi` on: a node's profile (one rank dot product per psi bin) costs about as much as
/// 60 rank-sum queries, and each `phi` makes about five queries per node.
pub(super) const TABULATE_MIN_PHI: usize = 12;

/// Slack (radians) of [`FarSlice::eval_many`]'s candidate windows: far above the rounding
/// of `lo - w - mu` (~1e-15) and far below any window width, so it only adds candidates
/// whose own image test then rejects them.
pub(super) const WINDOW_SLACK: f64 = 1e-9;
