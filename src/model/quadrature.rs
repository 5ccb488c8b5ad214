//! Numerical quadrature used around the model: fixed Gauss-Legendre rules (cached) and an
//! adaptive Gauss-Kronrod (G7-K15) integrator used as the *reference* for the far field
//! (tests and reports only; it is slow on purpose, ~1e-10 relative).

use std::sync::{Mutex, OnceLock};

/// Gauss-Legendre nodes and weights on [-1, 1] for `n` points (Newton on the Legendre
/// recurrence; nodes accurate to ~1e-15). Sorted by increasing node.
pub fn gauss_legendre_rule(n: usize) -> (Vec<f64>, Vec<f64>) {
    assert!(n >= 1, "Gauss-Legendre needs at least one point");
    let mut xs = vec![0.0; n];
    let mut ws = vec![0.0; n];
    let m = n.div_ceil(2);
    for i in 0..m {
        let mut x = (std::f64::consts::PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
        let mut dp = 1.0;
        for _ in 0..100 {
            let (mut p0, mut p1) = (1.0, x);
            for k in 2..=n {
                let p2 = ((2 * k - 1) as f64 * x * p1 - (k - 1) as f64 * p0) / k as f64;
                p0 = p1;
                p1 = p2;
            }
            if n == 1 {
                p0 = 1.0;
                p1 = x;
            }
            dp = n as f64 * (x * p1 - p0) / (x * x - 1.0);
            let dx = p1 / dp;
            x -= dx;
            if dx.abs() < 1e-16 {
                break;
            }
        }
        if n == 1 {
            x = 0.0;
            dp = 1.0;
        }
        let w = 2.0 / ((1.0 - x * x) * dp * dp);
        xs[i] = -x;
        ws[i] = w;
        xs[n - 1 - i] = x;
        ws[n - 1 - i] = w;
    }
    (xs, ws)
}

/// A Gauss-Legendre rule with nodes and weights in one vector.
pub struct GaussLegendre {
    /// Nodes on [-1, 1], increasing.
    pub nodes: Vec<f64>,
    /// Weights, summing to 2.
    pub weights: Vec<f64>,
}

impl GaussLegendre {
    /// The `n`-point rule ([`gauss_legendre_rule`]).
    pub fn new(n: usize) -> Self {
        let (nodes, weights) = gauss_legendre_rule(n);
        GaussLegendre { nodes, weights }
    }

    /// Cached `n`-point rule (`n >= 1`), built on its first use (building all of 1..=256
    /// up front cost ~30 ms of Newton iterations, a tenth of a one-shot `synth`). Rules
    /// above 256 points (benchmarks only) live in a map for the rest of the run.
    pub fn cached(n: usize) -> &'static GaussLegendre {
        static CACHE: [OnceLock<GaussLegendre>; 257] = [const { OnceLock::new() }; 257];
        static LARGE: Mutex<Vec<(usize, &'static GaussLegendre)>> = Mutex::new(Vec::new());
        let n = n.max(1);
        if n <= 256 {
            return CACHE[n].get_or_init(|| GaussLegendre::new(n));
        }
        let mut large = LARGE.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(&(_, g)) = large.iter().find(|(m, _)| *m == n) {
            return g;
        }
        // Leaked on purpose: a handful of sizes, each kept for the process's lifetime.
        let g: &'static GaussLegendre = Box::leak(Box::new(GaussLegendre::new(n)));
        large.push((n, g));
        g
    }

    /// `integral_a^b f(x) dx`.
    pub fn integrate(&self, a: f64, b: f64, mut f: impl FnMut(f64) -> f64) -> f64 {
        let (c, r) = (0.5 * (a + b), 0.5 * (b - a));
        let mut s = 0.0;
        for (x, w) in self.nodes.iter().zip(&self.weights) {
            s += w * f(c + r * x);
        }
        s * r
    }
}

// Gauss-Kronrod 7-15 nodes (abscissae on [0, 1], symmetric) and weights (QUADPACK qk15).
const XGK: [f64; 8] = [
    0.991_455_371_120_812_6,
    0.949_107_912_342_758_5,
    0.864_864_423_359_769_1,
    0.741_531_185_599_394_4,
    0.586_087_235_467_691_1,
    0.405_845_151_377_397_2,
    0.207_784_955_007_898_5,
    0.0,
];
const WGK: [f64; 8] = [
    0.022_935_322_010_529_22,
    0.063_092_092_629_978_55,
    0.104_790_010_322_250_2,
    0.140_653_259_715_525_9,
    0.169_004_726_639_267_9,
    0.190_350_578_064_785_4,
    0.204_432_940_075_298_9,
    0.209_482_141_084_728,
];
const WG: [f64; 4] = [
    0.129_484_966_168_869_7,
    0.279_705_391_489_276_7,
    0.381_830_050_505_118_9,
    0.417_959_183_673_469_4,
];

/// One G7-K15 step on [a, b]: (Kronrod estimate, |Kronrod - Gauss|).
fn gk15(a: f64, b: f64, f: &mut impl FnMut(f64) -> f64) -> (f64, f64) {
    let c = 0.5 * (a + b);
    let r = 0.5 * (b - a);
    let fc = f(c);
    let mut rk = fc * WGK[7];
    let mut rg = fc * WG[3];
    for j in 0..7 {
        let dx = r * XGK[j];
        let s = f(c - dx) + f(c + dx);
        rk += WGK[j] * s;
        if j % 2 == 1 {
            rg += WG[j / 2] * s;
        }
    }
    (rk * r, ((rk - rg) * r).abs())
}

/// Result of [`adaptive_gk`].
#[derive(Clone, Copy, Debug)]
pub struct GkResult {
    /// The integral estimate (the K15 sums).
    pub value: f64,
    /// Sum of the local |K15 - G7| estimates (a pessimistic error bound).
    pub error: f64,
    /// Number of integrand evaluations.
    pub evaluations: usize,
}

/// Adaptive Gauss-Kronrod (G7-K15) of `f` over the ordered breakpoints `points` (each
/// consecutive pair is one initial interval): bisects the interval with the largest error
/// estimate until the total estimate is below `max(abs_tol, rel_tol * |value|)` or
/// `max_intervals` intervals exist. Used as the reference integrator.
pub fn adaptive_gk(
    mut f: impl FnMut(f64) -> f64,
    points: &[f64],
    rel_tol: f64,
    abs_tol: f64,
    max_intervals: usize,
) -> GkResult {
    use std::collections::BinaryHeap;
    /// Interval ordered by its error estimate (max-heap).
    struct Iv(f64, f64, f64, f64);
    impl PartialEq for Iv {
        fn eq(&self, o: &Self) -> bool {
            self.3 == o.3
        }
    }
    impl Eq for Iv {}
    impl PartialOrd for Iv {
        fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
            Some(self.cmp(o))
        }
    }
    impl Ord for Iv {
        fn cmp(&self, o: &Self) -> std::cmp::Ordering {
            self.3.total_cmp(&o.3)
        }
    }
    let mut heap = BinaryHeap::new();
    let mut evals = 0usize;
    let (mut value, mut error) = (0.0, 0.0);
    for w in points.windows(2) {
        if w[1] > w[0] {
            let (v, e) = gk15(w[0], w[1], &mut f);
            evals += 15;
            value += v;
            error += e;
            heap.push(Iv(w[0], w[1], v, e));
        }
    }
    let mut n = heap.len();
    while error > abs_tol.max(rel_tol * value.abs()) && n < max_intervals {
        let Some(Iv(a, b, v, e)) = heap.pop() else {
            break;
        };
        let m = 0.5 * (a + b);
        if !(m > a && m < b) || e == 0.0 {
            // Cannot improve this interval in floating point: freeze it.
            error -= e;
            heap.push(Iv(a, b, v, 0.0));
            if e == 0.0 {
                break;
            }
            continue;
        }
        let (v1, e1) = gk15(a, m, &mut f);
        let (v2, e2) = gk15(m, b, &mut f);
        evals += 30;
        value += v1 + v2 - v;
        error += e1 + e2 - e;
        heap.push(Iv(a, m, v1, e1));
        heap.push(Iv(m, b, v2, e2));
        n += 1;
    }
    // Re-sum to remove drift from the running updates.
    let value = heap.iter().map(|iv| iv.2).sum();
    let error = heap.iter().map(|iv| iv.3).sum();
    GkResult {
        value,
        error,
        evaluations: evals,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gauss_legendre_is_exact_for_polynomials() {
        // 300 and 1024 take the cache of rules above 256 points (which once clamped to
        // 256 silently).
        for n in [1usize, 2, 5, 8, 16, 64, 128, 300, 1024] {
            let gl = GaussLegendre::cached(n);
            assert_eq!(gl.nodes.len(), n);
            assert!(
                std::ptr::eq(gl, GaussLegendre::cached(n)),
                "n={n}: not cached"
            );
            // Rounding of n-term sums grows with n: 1e-13 up to 128 points, in proportion
            // above.
            let tol = 1e-13 * (n as f64 / 128.0).max(1.0);
            let sw: f64 = gl.weights.iter().sum();
            // Weights sum to the interval length 2 (rounding only).
            assert!((sw - 2.0).abs() < tol, "n={n}: {sw}");
            // Exact for degree 2n-1: integral_0^1 x^(2n-1) = 1/(2n).
            let d = (2 * n - 1) as i32;
            let v = gl.integrate(0.0, 1.0, |x| x.powi(d));
            assert!((v - 1.0 / (2 * n) as f64).abs() < tol, "n={n}: {v}");
        }
    }

    #[test]
    fn adaptive_gk_handles_sqrt_endpoint_and_peaks() {
        // integral_0^1 sqrt(x) = 2/3 (endpoint singularity of the derivative).
        let r = adaptive_gk(|x| x.sqrt(), &[0.0, 1.0], 1e-12, 0.0, 2000);
        assert!((r.value - 2.0 / 3.0).abs() < 1e-11, "{r:?}");
        // Narrow Gaussian of width 1e-3 at 0.3: integral = 1 (tails beyond [0,1] negligible).
        let s = 1e-3;
        let g = |x: f64| {
            (-0.5 * ((x - 0.3) / s).powi(2)).exp() / (s * (2.0 * std::f64::consts::PI).sqrt())
        };
        let r = adaptive_gk(g, &[0.0, 0.3, 1.0], 1e-12, 0.0, 2000);
        assert!((r.value - 1.0).abs() < 1e-10, "{r:?}");
    }
}
