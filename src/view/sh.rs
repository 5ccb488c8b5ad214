//! Real spherical harmonics of orders 0-4 (25 functions), projection and rotation.
//!
//! The basis is the orthonormal real SH of Sloan, "Stupid Spherical Harmonics (SH)
//! Tricks" (GDC 2008), Appendix A2, written as polynomials in the unit vector `(x, y, z)`
//! (seed 003 Eq. 6 gives the same functions through associated Legendre polynomials;
//! the polynomial form needs no trigonometry). Index `k = l (l + 1) + m`. No
//! Condon-Shortley phase: any consistent sign is a valid orthonormal basis, and the page
//! (`web/viewer.js`) evaluates the very same polynomials.
//!
//! Rotation is done by re-projection with a quadrature that is exact for this band
//! limit: a rotated order-4 function times an order-4 basis function is a polynomial of
//! degree <= 8, which a 5-point Gauss-Legendre rule in `z` times 10 equally spaced
//! azimuths integrates exactly. So `rotate` is exact (to rounding), needs no Wigner-D
//! recurrences, and the page does the same 50-point sum per frame on the CPU.

use std::f64::consts::PI;

/// Number of SH coefficients of orders 0-4.
pub const N_COEFFS: usize = 25;
/// Highest order.
pub const MAX_ORDER: usize = 4;

/// The 25 basis functions at unit vector `d`.
pub fn eval(d: [f64; 3]) -> [f64; N_COEFFS] {
    let [x, y, z] = d;
    let (x2, y2, z2) = (x * x, y * y, z * z);
    [
        0.282_094_791_773_878_1,
        0.488_602_511_902_919_9 * y,
        0.488_602_511_902_919_9 * z,
        0.488_602_511_902_919_9 * x,
        1.092_548_430_592_079_2 * x * y,
        1.092_548_430_592_079_2 * y * z,
        0.315_391_565_252_52 * (3.0 * z2 - 1.0),
        1.092_548_430_592_079_2 * x * z,
        0.546_274_215_296_039_6 * (x2 - y2),
        0.590_043_589_926_643_5 * y * (3.0 * x2 - y2),
        2.890_611_442_640_554 * x * y * z,
        0.457_045_799_464_465_8 * y * (5.0 * z2 - 1.0),
        0.373_176_332_590_115_4 * z * (5.0 * z2 - 3.0),
        0.457_045_799_464_465_8 * x * (5.0 * z2 - 1.0),
        1.445_305_721_320_277 * z * (x2 - y2),
        0.590_043_589_926_643_5 * x * (x2 - 3.0 * y2),
        2.503_342_941_796_704_5 * x * y * (x2 - y2),
        1.770_130_769_779_930_5 * y * z * (3.0 * x2 - y2),
        0.946_174_695_757_56 * x * y * (7.0 * z2 - 1.0),
        0.669_046_543_557_289_1 * y * z * (7.0 * z2 - 3.0),
        0.105_785_546_915_204_2 * (35.0 * z2 * z2 - 30.0 * z2 + 3.0),
        0.669_046_543_557_289_1 * x * z * (7.0 * z2 - 3.0),
        0.473_087_347_878_78 * (x2 - y2) * (7.0 * z2 - 1.0),
        1.770_130_769_779_930_5 * x * z * (x2 - 3.0 * y2),
        0.625_835_735_449_176_1 * (x2 * (x2 - 3.0 * y2) - y2 * (3.0 * x2 - y2)),
    ]
}

/// Value of the function with coefficients `c` at `d`.
pub fn reconstruct(c: &[f64; N_COEFFS], d: [f64; 3]) -> f64 {
    eval(d).iter().zip(c).map(|(y, c)| y * c).sum()
}

/// A quadrature rule on the sphere: unit directions and weights summing to `4 pi`.
#[derive(Clone, Debug)]
pub struct Rule {
    /// Unit directions of the nodes.
    pub dirs: Vec<[f64; 3]>,
    /// Weights, summing to `4 pi`.
    pub weights: Vec<f64>,
}

/// Gauss-Legendre nodes and weights on [-1, 1] (Newton on the Legendre recurrence;
/// Numerical Recipes `gauleg`).
pub fn gauss_legendre(n: usize) -> (Vec<f64>, Vec<f64>) {
    let (mut x, mut w) = (vec![0.0; n], vec![0.0; n]);
    for i in 0..n.div_ceil(2) {
        let mut z = (PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
        let mut dp = 1.0;
        for _ in 0..100 {
            let (mut p1, mut p2) = (1.0, 0.0);
            for j in 0..n {
                let p3 = p2;
                p2 = p1;
                p1 = ((2 * j + 1) as f64 * z * p2 - j as f64 * p3) / (j + 1) as f64;
            }
            dp = n as f64 * (z * p1 - p2) / (z * z - 1.0);
            let dz = p1 / dp;
            z -= dz;
            if dz.abs() < 1e-15 {
                break;
            }
        }
        x[i] = -z;
        x[n - 1 - i] = z;
        w[i] = 2.0 / ((1.0 - z * z) * dp * dp);
        w[n - 1 - i] = w[i];
    }
    (x, w)
}

impl Rule {
    /// Product rule: `n_z` Gauss-Legendre nodes in `z` times `n_phi` equally spaced
    /// azimuths (offset by half a step). Exact for polynomials of degree `< 2 n_z` in `z`
    /// times trigonometric polynomials of degree `< n_phi` in the azimuth.
    pub fn product(n_z: usize, n_phi: usize) -> Rule {
        let (zs, wz) = gauss_legendre(n_z);
        let mut r = Rule {
            dirs: Vec::with_capacity(n_z * n_phi),
            weights: Vec::with_capacity(n_z * n_phi),
        };
        for (z, w) in zs.iter().zip(&wz) {
            let s = (1.0 - z * z).max(0.0).sqrt();
            for j in 0..n_phi {
                let a = 2.0 * PI * (j as f64 + 0.5) / n_phi as f64;
                r.dirs.push([s * a.cos(), s * a.sin(), *z]);
                r.weights.push(w * 2.0 * PI / n_phi as f64);
            }
        }
        r
    }

    /// The rule [`rotate`] uses: exact for products of two order-4 functions.
    pub fn rotation() -> Rule {
        Rule::product(5, 10)
    }
}

/// Project `f` onto the basis with the rule `rule`.
pub fn project(rule: &Rule, f: impl Fn([f64; 3]) -> f64) -> [f64; N_COEFFS] {
    let mut c = [0.0; N_COEFFS];
    for (d, w) in rule.dirs.iter().zip(&rule.weights) {
        let v = f(*d) * w;
        for (ck, y) in c.iter_mut().zip(eval(*d)) {
            *ck += v * y;
        }
    }
    c
}

/// A 3x3 rotation, rows `r[i]`: `d' = r d`.
pub type Mat3 = [[f64; 3]; 3];

/// `r d`: the rotation applied to `d`.
pub fn mat_vec(r: &Mat3, d: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|i| r[i][0] * d[0] + r[i][1] * d[1] + r[i][2] * d[2])
}

/// The inverse rotation.
pub fn transpose(r: &Mat3) -> Mat3 {
    [0, 1, 2].map(|i| [r[0][i], r[1][i], r[2][i]])
}

/// Coefficients of `g(d) = f(r^T d)`, the function `f` turned by `r` (what `f` had at `d`
/// is now at `r d`). Exact re-projection (module doc).
pub fn rotate(c: &[f64; N_COEFFS], r: &Mat3) -> [f64; N_COEFFS] {
    thread_local! {
        static RULE: Rule = Rule::rotation();
    }
    let rt = transpose(r);
    RULE.with(|rule| project(rule, |d| reconstruct(c, mat_vec(&rt, d))))
}

/// Rotation by `angle` (radians) about unit `axis` (Rodrigues).
pub fn axis_angle(axis: [f64; 3], angle: f64) -> Mat3 {
    let (s, c) = angle.sin_cos();
    let [x, y, z] = axis;
    let t = 1.0 - c;
    [
        [t * x * x + c, t * x * y - s * z, t * x * z + s * y],
        [t * x * y + s * z, t * y * y + c, t * y * z - s * x],
        [t * x * z - s * y, t * y * z + s * x, t * z * z + c],
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Orthonormality on an exact rule (products have degree <= 8): rounding only, so
    /// 1e-12.
    #[test]
    fn basis_is_orthonormal() {
        let rule = Rule::product(8, 17);
        let mut gram = [[0.0; N_COEFFS]; N_COEFFS];
        for (d, w) in rule.dirs.iter().zip(&rule.weights) {
            let y = eval(*d);
            for i in 0..N_COEFFS {
                for j in 0..N_COEFFS {
                    gram[i][j] += w * y[i] * y[j];
                }
            }
        }
        for i in 0..N_COEFFS {
            for j in 0..N_COEFFS {
                let want = if i == j { 1.0 } else { 0.0 };
                assert!(
                    (gram[i][j] - want).abs() < 1e-12,
                    "<Y{i}, Y{j}> = {}",
                    gram[i][j]
                );
            }
        }
        let wsum: f64 = rule.weights.iter().sum();
        assert!((wsum - 4.0 * PI).abs() < 1e-12);
    }

    /// A polynomial of degree 4 lies in the span: projection then reconstruction gives it
    /// back everywhere (1e-12: rounding). A degree-6 one does not: the order-4 truncation
    /// must leave an error.
    #[test]
    fn project_reconstruct_known_function() {
        let f =
            |d: [f64; 3]| 1.0 + 0.5 * d[0] - d[1] * d[2] + 2.0 * d[2].powi(4) - d[0] * d[1].powi(3);
        let c = project(&Rule::product(8, 17), f);
        let probe = Rule::product(7, 13);
        for d in &probe.dirs {
            assert!((reconstruct(&c, *d) - f(*d)).abs() < 1e-12, "{d:?}");
        }
        // Constant: only the first coefficient, sqrt(4 pi).
        let c1 = project(&Rule::product(8, 17), |_| 1.0);
        assert!((c1[0] - (4.0 * PI).sqrt()).abs() < 1e-12);
        assert!(c1[1..].iter().all(|v| v.abs() < 1e-12));
        let g = |d: [f64; 3]| d[2].powi(6);
        let cg = project(&Rule::product(8, 17), g);
        let worst = probe
            .dirs
            .iter()
            .map(|d| (reconstruct(&cg, *d) - g(*d)).abs())
            .fold(0.0, f64::max);
        assert!(worst > 1e-3, "degree 6 reconstructed exactly? {worst}");
    }

    /// Rotating the coefficients equals projecting the rotated function (1e-11: rounding
    /// over two 25-term sums); rotations compose and the inverse undoes one.
    #[test]
    fn rotation_matches_reprojection() {
        let f = |d: [f64; 3]| ((1.0 + 0.3 * d[0] + 0.6 * d[1] + 0.74 * d[2]) / 2.0).powi(4);
        let rule = Rule::product(8, 17);
        let c = project(&rule, f);
        let axis = {
            let a = [0.3f64, -0.5, 0.8];
            let n = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
            a.map(|v| v / n)
        };
        let r = axis_angle(axis, 1.1);
        let rt = transpose(&r);
        let want = project(&rule, |d| f(mat_vec(&rt, d)));
        let got = rotate(&c, &r);
        for k in 0..N_COEFFS {
            assert!(
                (got[k] - want[k]).abs() < 1e-11,
                "coefficient {k}: {} vs {}",
                got[k],
                want[k]
            );
        }
        let back = rotate(&got, &rt);
        for k in 0..N_COEFFS {
            assert!((back[k] - c[k]).abs() < 1e-11);
        }
        // The rotated function's value at r d is the original's at d.
        let d = [0.6, 0.0, 0.8];
        assert!((reconstruct(&got, mat_vec(&r, d)) - f(d)).abs() < 1e-11);
    }
}
