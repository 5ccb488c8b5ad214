//! CANDECOMP/PARAFAC (CP) decomposition by alternating least squares (seed Eqs. 17-18):
//! `A ~ sum_r lambda_r a^(r,1) (x) a^(r,2) (x) ... (x) a^(r,d)`.
//!
//! Each ALS step solves the normal equations of one mode,
//! `A_n = X_(n) (KhatriRao_{m != n} A_m) (Hadamard_{m != n} A_m^T A_m)^-1`,
//! with the Gram Hadamard product factored by Cholesky (a tiny ridge keeps it positive
//! definite; nalgebra's pseudo-inverse is the fallback). The matricised-tensor times
//! Khatri-Rao product is computed in one sequential pass over the tensor, so every
//! reduction runs in a fixed order and the result is bit-reproducible. Initialisation is
//! pseudo-random from a fixed seed.

use nalgebra::DMatrix;
use rand::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;

/// A dense tensor: `data` in row-major order (last mode fastest).
#[derive(Clone, Debug)]
pub struct Tensor {
    /// Size of each mode.
    pub dims: Vec<usize>,
    /// The entries, row-major (last mode fastest); `dims.iter().product()` of them.
    pub data: Vec<f64>,
}

impl Tensor {
    /// A tensor of shape `dims` holding `data` (row-major); panics if the sizes differ.
    pub fn new(dims: Vec<usize>, data: Vec<f64>) -> Self {
        assert_eq!(dims.iter().product::<usize>(), data.len());
        Tensor { dims, data }
    }
    /// Frobenius norm.
    pub fn norm(&self) -> f64 {
        self.data.iter().map(|v| v * v).sum::<f64>().sqrt()
    }
}

/// CP factors: `factors[n]` is `dims[n] x rank`, row-major (`factors[n][i * rank + r]`);
/// `lambda` the column weights (columns of every factor have unit norm).
#[derive(Clone, Debug)]
pub struct CpModel {
    /// Number of rank-one components.
    pub rank: usize,
    /// Size of each mode.
    pub dims: Vec<usize>,
    /// Weight of each component, `rank` of them.
    pub lambda: Vec<f64>,
    /// One factor matrix per mode, `dims[n] x rank`, row-major.
    pub factors: Vec<Vec<f64>>,
}

impl CpModel {
    /// Full reconstruction (for error measurement and tests).
    pub fn reconstruct(&self) -> Tensor {
        let n: usize = self.dims.iter().product();
        let d = self.dims.len();
        let mut out = vec![0.0; n];
        let mut idx = vec![0usize; d];
        for v in out.iter_mut() {
            let mut s = 0.0;
            for r in 0..self.rank {
                let mut p = self.lambda[r];
                for (m, &i) in idx.iter().enumerate() {
                    p *= self.factors[m][i * self.rank + r];
                }
                s += p;
            }
            *v = s;
            // increment multi-index (last fastest)
            for m in (0..d).rev() {
                idx[m] += 1;
                if idx[m] < self.dims[m] {
                    break;
                }
                idx[m] = 0;
            }
        }
        Tensor::new(self.dims.clone(), out)
    }

    /// Relative Frobenius error `||X - X_hat|| / ||X||` by full reconstruction.
    pub fn rel_error(&self, x: &Tensor) -> f64 {
        let rec = self.reconstruct();
        let e: f64 = rec
            .data
            .iter()
            .zip(&x.data)
            .map(|(a, b)| (a - b) * (a - b))
            .sum::<f64>()
            .sqrt();
        e / x.norm().max(1e-300)
    }

    /// Fold `lambda` into the factor of `mode` (so evaluation is a plain product).
    pub fn folded_factors(&self, mode: usize) -> Vec<Vec<f64>> {
        let mut f = self.factors.clone();
        for (i, v) in f[mode].iter_mut().enumerate() {
            *v *= self.lambda[i % self.rank];
        }
        f
    }
}

/// Options of [`cp_als`].
#[derive(Clone, Copy, Debug)]
pub struct CpOptions {
    /// Number of rank-one components to fit.
    pub rank: usize,
    /// Most ALS sweeps.
    pub max_iter: usize,
    /// Stop when the relative fit changes by less than this between sweeps.
    pub tol: f64,
    /// Seed of the random initial factors.
    pub seed: u64,
}

/// Matricised tensor times Khatri-Rao product for mode `n`:
/// `M[i_n][r] = sum_{other indices} X[...] prod_{m != n} A_m[i_m][r]`.
fn mttkrp(x: &Tensor, factors: &[Vec<f64>], rank: usize, n: usize) -> Vec<f64> {
    let d = x.dims.len();
    let last = d - 1;
    let nl = x.dims[last];
    let outer: usize = x.dims[..last].iter().product();
    let mut out = vec![0.0; x.dims[n] * rank];
    let mut idx = vec![0usize; last];
    let mut pre = vec![0.0; rank];
    for o in 0..outer {
        // prefix product over modes 0..last except n
        pre.iter_mut().for_each(|p| *p = 1.0);
        for (m, &i) in idx.iter().enumerate() {
            if m != n {
                let row = &factors[m][i * rank..(i + 1) * rank];
                for (p, a) in pre.iter_mut().zip(row) {
                    *p *= a;
                }
            }
        }
        let slab = &x.data[o * nl..(o + 1) * nl];
        if n == last {
            for (l, &v) in slab.iter().enumerate() {
                if v != 0.0 {
                    let row = &mut out[l * rank..(l + 1) * rank];
                    for (acc, p) in row.iter_mut().zip(&pre) {
                        *acc += v * p;
                    }
                }
            }
        } else {
            let target = idx[n];
            let row_out = &mut out[target * rank..(target + 1) * rank];
            let fl = &factors[last];
            for (l, &v) in slab.iter().enumerate() {
                if v != 0.0 {
                    let fr = &fl[l * rank..(l + 1) * rank];
                    for ((acc, p), a) in row_out.iter_mut().zip(&pre).zip(fr) {
                        *acc += v * p * a;
                    }
                }
            }
        }
        for m in (0..last).rev() {
            idx[m] += 1;
            if idx[m] < x.dims[m] {
                break;
            }
            idx[m] = 0;
        }
    }
    out
}

/// Gram matrix `A^T A` of a row-major `rows x rank` factor.
fn gram(a: &[f64], rank: usize) -> DMatrix<f64> {
    let rows = a.len() / rank;
    let mut g = DMatrix::zeros(rank, rank);
    for i in 0..rows {
        let row = &a[i * rank..(i + 1) * rank];
        for p in 0..rank {
            for q in p..rank {
                g[(p, q)] += row[p] * row[q];
            }
        }
    }
    for p in 0..rank {
        for q in 0..p {
            g[(p, q)] = g[(q, p)];
        }
    }
    g
}

/// Solve `A V = M` for `A` (rows of `M`), `V` symmetric positive semi-definite.
fn solve_rows(m: &[f64], v: &DMatrix<f64>, rank: usize) -> Vec<f64> {
    let rows = m.len() / rank;
    let scale = (0..rank)
        .map(|i| v[(i, i)])
        .fold(0.0f64, f64::max)
        .max(1e-300);
    let mut vr = v.clone();
    for i in 0..rank {
        vr[(i, i)] += 1e-13 * scale;
    }
    // M is rows x rank; A = M V^-1 -> A^T = V^-1 M^T.
    let mt = DMatrix::from_fn(rank, rows, |r, i| m[i * rank + r]);
    let at = match vr.clone().cholesky() {
        Some(ch) => ch.solve(&mt),
        None => {
            let pinv = vr
                .pseudo_inverse(1e-12 * scale)
                .unwrap_or_else(|_| DMatrix::identity(rank, rank));
            pinv * mt
        }
    };
    let mut a = vec![0.0; rows * rank];
    for i in 0..rows {
        for r in 0..rank {
            a[i * rank + r] = at[(r, i)];
        }
    }
    a
}

/// Normalise the columns of a factor to unit norm, returning the norms.
fn normalise_columns(a: &mut [f64], rank: usize) -> Vec<f64> {
    let rows = a.len() / rank;
    let mut norms = vec![0.0; rank];
    for i in 0..rows {
        for r in 0..rank {
            norms[r] += a[i * rank + r] * a[i * rank + r];
        }
    }
    for n in norms.iter_mut() {
        *n = n.sqrt();
    }
    for i in 0..rows {
        for r in 0..rank {
            if norms[r] > 0.0 {
                a[i * rank + r] /= norms[r];
            }
        }
    }
    norms
}

/// CP-ALS. Returns the model and the relative error history (one entry per sweep, from the
/// cheap Gram identity `||X - X_hat||^2 = ||X||^2 - 2 <X, X_hat> + ||X_hat||^2`).
pub fn cp_als(x: &Tensor, opt: &CpOptions) -> (CpModel, Vec<f64>) {
    let rank = opt.rank.max(1);
    let d = x.dims.len();
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(opt.seed);
    let mut factors: Vec<Vec<f64>> = x
        .dims
        .iter()
        .map(|&n| (0..n * rank).map(|_| rng.random::<f64>()).collect())
        .collect();
    for f in factors.iter_mut() {
        normalise_columns(f, rank);
    }
    let mut lambda = vec![1.0; rank];
    let xnorm2 = x.data.iter().map(|v| v * v).sum::<f64>();
    let mut history = Vec::new();
    let mut grams: Vec<DMatrix<f64>> = factors.iter().map(|f| gram(f, rank)).collect();
    for _ in 0..opt.max_iter {
        let mut last_m = Vec::new();
        for n in 0..d {
            let m = mttkrp(x, &factors, rank, n);
            let mut v = DMatrix::from_element(rank, rank, 1.0);
            for (k, g) in grams.iter().enumerate() {
                if k != n {
                    v.component_mul_assign(g);
                }
            }
            let mut a = solve_rows(&m, &v, rank);
            lambda = normalise_columns(&mut a, rank);
            grams[n] = gram(&a, rank);
            factors[n] = a;
            if n == d - 1 {
                last_m = m;
            }
        }
        // <X, X_hat> = sum_{i,r} M[i][r] A_last[i][r] lambda_r  (M excludes the last mode)
        let al = &factors[d - 1];
        let mut inner = 0.0;
        for (i, mv) in last_m.iter().enumerate() {
            inner += mv * al[i] * lambda[i % rank];
        }
        let mut v = DMatrix::from_element(rank, rank, 1.0);
        for g in &grams {
            v.component_mul_assign(g);
        }
        let mut xh2 = 0.0;
        for p in 0..rank {
            for q in 0..rank {
                xh2 += lambda[p] * lambda[q] * v[(p, q)];
            }
        }
        let err = ((xnorm2 - 2.0 * inner + xh2).max(0.0) / xnorm2.max(1e-300)).sqrt();
        let prev = history.last().copied();
        history.push(err);
        if let Some(p) = prev {
            if (p - err).abs() < opt.tol {
                break;
            }
        }
    }
    // Sort components by decreasing lambda (seed Eq. 18 keeps the largest).
    let mut order: Vec<usize> = (0..rank).collect();
    order.sort_by(|&a, &b| lambda[b].total_cmp(&lambda[a]).then(a.cmp(&b)));
    let lambda_sorted = order.iter().map(|&r| lambda[r]).collect();
    let factors_sorted = factors
        .iter()
        .map(|f| {
            let rows = f.len() / rank;
            let mut g = vec![0.0; f.len()];
            for i in 0..rows {
                for (k, &r) in order.iter().enumerate() {
                    g[i * rank + k] = f[i * rank + r];
                }
            }
            g
        })
        .collect();
    (
        CpModel {
            rank,
            dims: x.dims.clone(),
            lambda: lambda_sorted,
            factors: factors_sorted,
        },
        history,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recovers_synthetic_rank3() {
        let dims = vec![6, 5, 7, 8];
        let rank = 3;
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(42);
        let truth = CpModel {
            rank,
            dims: dims.clone(),
            lambda: vec![3.0, 2.0, 1.0],
            factors: dims
                .iter()
                .map(|&n| (0..n * rank).map(|_| rng.random::<f64>() - 0.3).collect())
                .collect(),
        };
        let x = truth.reconstruct();
        let (m, hist) = cp_als(
            &x,
            &CpOptions {
                rank,
                max_iter: 2000,
                tol: 0.0,
                seed: 7,
            },
        );
        let e = m.rel_error(&x);
        // An exactly rank-3 tensor: ALS converges to the exact factors; 1e-8 leaves room
        // for the ridge (1e-13 relative) and round-off accumulated over the sweeps.
        assert!(e <= 1e-8, "rel error {e}, last history {:?}", hist.last());
    }

    #[test]
    fn deterministic() {
        let dims = vec![4, 3, 5];
        let data: Vec<f64> = (0..60).map(|i| ((i * 37 % 11) as f64).sin()).collect();
        let x = Tensor::new(dims, data);
        let o = CpOptions {
            rank: 4,
            max_iter: 30,
            tol: 0.0,
            seed: 1,
        };
        let (a, _) = cp_als(&x, &o);
        let (b, _) = cp_als(&x, &o);
        assert_eq!(a.factors, b.factors);
        assert_eq!(a.lambda, b.lambda);
    }

    #[test]
    fn error_decreases_with_rank() {
        let dims = vec![5, 6, 7];
        let data: Vec<f64> = (0..210).map(|i| ((i * 13 % 17) as f64).cos()).collect();
        let x = Tensor::new(dims, data);
        let e = |rank| {
            let (m, _) = cp_als(
                &x,
                &CpOptions {
                    rank,
                    max_iter: 200,
                    tol: 1e-12,
                    seed: 3,
                },
            );
            m.rel_error(&x)
        };
        assert!(e(8) < e(2));
    }

    /// The returned history is what its doc says, the relative error of each sweep: the
    /// last entry (Gram identity) equals the error of the returned model by full
    /// reconstruction, so the components' reordering kept each weight with its columns.
    /// 1e-9: the identity's cancellation costs ~1e-16 of `||X||^2`, i.e. ~1e-15 of an
    /// error near 0.3. ALS never increases the error (1e-12 slack for the ridge and
    /// rounding). Components come sorted by decreasing weight, unit columns, and folding
    /// the weights into any one factor reproduces the tensor (rounding, 1e-12 relative).
    #[test]
    fn history_weights_and_folding_describe_the_returned_model() {
        let dims = vec![5, 6, 7];
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(11);
        let data: Vec<f64> = (0..210).map(|_| rng.random::<f64>() - 0.2).collect();
        let x = Tensor::new(dims.clone(), data);
        let rank = 4;
        let (m, hist) = cp_als(
            &x,
            &CpOptions {
                rank,
                max_iter: 60,
                tol: 0.0,
                seed: 5,
            },
        );
        assert_eq!(hist.len(), 60);
        let e = m.rel_error(&x);
        assert!(e > 0.05, "not an exact fit: {e}");
        let last = *hist.last().unwrap();
        assert!(
            (last - e).abs() < 1e-9,
            "history {last} vs reconstruction {e}"
        );
        for w in hist.windows(2) {
            assert!(w[1] <= w[0] + 1e-12, "error rose: {w:?}");
        }
        for w in m.lambda.windows(2) {
            assert!(w[0] >= w[1], "weights not sorted: {:?}", m.lambda);
        }
        for f in &m.factors {
            for r in 0..rank {
                let n2: f64 = f.chunks(rank).map(|row| row[r] * row[r]).sum();
                assert!((n2 - 1.0).abs() < 1e-12);
            }
        }
        let full = m.reconstruct();
        for mode in 0..dims.len() {
            let f = m.folded_factors(mode);
            let folded = CpModel {
                lambda: vec![1.0; rank],
                factors: f,
                ..m.clone()
            }
            .reconstruct();
            for (a, b) in folded.data.iter().zip(&full.data) {
                assert!((a - b).abs() <= 1e-12 * x.norm(), "mode {mode}: {a} vs {b}");
            }
        }
    }
}
