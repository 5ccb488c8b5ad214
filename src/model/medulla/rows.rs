//! The `C^N` rows of a slice (`CnRows`): exact integrals of a density against them and
//! their correlation along a `psi` grid.

use super::grid::{floor_i64, locate, locate_periodic};

/// The slice's `C^N` shape at its nodes, row by row: one row per table offset `x_i`, each
/// periodic and piecewise linear in `psi` between the bin centres `c0 + k d`. Between two
/// offset nodes `C^N_shape(x, psi) = (1 - t) R_i(psi) + t R_{i+1}(psi)` with `t` linear in
/// `x` (the bilinear lerp of [`MedullaSlice::cn`](super::MedullaSlice::cn); the floored nodes are positive, so its
/// clamp at 0 never acts), which lets the far field integrate a smooth density against the
/// rows exactly, kinks included ([`CnRows::integrate`]).
#[derive(Clone, Copy, Debug)]
pub struct CnRows<'a> {
    pub(super) v: &'a [f64],
    pub(super) n: usize,
    pub(super) c0: f64,
    pub(super) d: f64,
    pub(super) x: &'a [f64],
    /// Largest node value: a bound on every row.
    pub peak: f64,
    pub(super) gap: &'a [f64],
    pub(super) slope: &'a [f64],
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

    /// The lower row `i` of the pair interpolated at offset `|x|` (as [`MedullaSlice::cn`](super::MedullaSlice::cn)
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
    /// around `(|x|, psi0)`: the bilinear lerp of [`MedullaSlice::cn`](super::MedullaSlice::cn) written as node
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
    pub(super) fn correlate_body(&self, acc: &RowWeights, step: i64, out: &mut [f64]) {
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
    pub(super) w: Vec<f64>,
    pub(super) touched: Vec<bool>,
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
    pub(super) first: usize,
    pub(super) w0: Vec<f64>,
    pub(super) w1: Vec<f64>,
}
