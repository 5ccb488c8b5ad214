//! Forward-mode derivatives: a dual number [`Dual<N>`] (a value and its gradient with
//! respect to `N` parameters) and the [`Real`] trait that `f64` and `Dual<N>` implement,
//! so that one generic function gives both the value (`f64`, the same operations in the
//! same order as before it was generic: bit for bit) and its derivatives (`Dual<N>`).
//!
//! Written here rather than taken from the maintained `num-dual` crate: the models need a
//! dozen elementary functions, a fixed small `N` (2 or 3) known at compile time, and a
//! value path that stays the plain `f64` code; `num-dual`'s `DualNum` trait would bring
//! its own float abstraction (and its own operation order) into the value path of every
//! function made generic, for no function the models need that is not here. The hot
//! inner sums (Chiang's logistic over the far-field nodes) are differentiated by hand
//! next to their value code instead; the dual numbers carry the set-up (node positions,
//! weights, attenuations), where clarity matters more than the last flop.
//!
//! Comparisons (`min`, `max`, `clamp`, branches) are made on the value: the derivative is
//! that of the branch taken, as a finite difference small enough not to cross a branch
//! point sees it.

use std::ops::{Add, AddAssign, Div, Mul, MulAssign, Neg, Sub, SubAssign};

/// A number the model code can be generic over: `f64` (values) or [`Dual`] (values and
/// derivatives). Operations with plain `f64` constants take the constant on the right
/// (`x * 2.0`); write `T::cst(1.0) - x` for a constant on the left.
pub trait Real:
    Copy
    + Send
    + Sync
    + std::fmt::Debug
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + Add<f64, Output = Self>
    + Sub<f64, Output = Self>
    + Mul<f64, Output = Self>
    + Div<f64, Output = Self>
    + AddAssign
    + MulAssign
    + SubAssign
    + 'static
{
    /// Whether this type carries derivatives (`false` for `f64`): lets generic code skip
    /// work that only the derivatives need, such as lifting a root found on the values.
    const DIFFERENTIATES: bool;
    /// A constant (zero derivative).
    fn cst(v: f64) -> Self;
    /// The value.
    fn value(self) -> f64;
    /// This number with its value replaced by `v` (the derivatives kept): a shift by a
    /// constant, as wrapping an angle into [-pi, pi] is.
    fn with_value(self, v: f64) -> Self;
    /// `sin x`, derivative `cos x`.
    fn sin(self) -> Self;
    /// `cos x`, derivative `-sin x`.
    fn cos(self) -> Self;
    /// `(sin x, cos x)` in one call.
    fn sin_cos(self) -> (Self, Self) {
        (self.sin(), self.cos())
    }
    /// `tan x`, derivative `1 + tan^2 x`.
    fn tan(self) -> Self;
    /// `asin x`, derivative `1 / sqrt(1 - x^2)`.
    fn asin(self) -> Self;
    /// `atan2(y = self, x)`, the angle of the point `(x, y)`; derivative
    /// `(x dy - y dx) / (x^2 + y^2)`.
    fn atan2(self, x: Self) -> Self;
    /// `sqrt x`, derivative `1 / (2 sqrt x)`.
    fn sqrt(self) -> Self;
    /// `e^x`, derivative `e^x`.
    fn exp(self) -> Self;
    /// `ln x`, derivative `1 / x`.
    fn ln(self) -> Self;
    /// `ln(1 + x)`, accurate near 0, derivative `1 / (1 + x)`.
    fn ln_1p(self) -> Self;
    /// `tanh x`, derivative `1 - tanh^2 x`.
    fn tanh(self) -> Self;
    /// `x^n` for an integer `n`, derivative `n x^(n - 1)`.
    fn powi(self, n: i32) -> Self;
    /// `|x|`, derivative `sign(x) dx`.
    fn abs(self) -> Self;
    /// `1 / self`.
    fn recip(self) -> Self;
    /// The larger by value (NaN as `f64::max`: the other).
    fn max(self, o: Self) -> Self;
    /// The smaller by value.
    fn min(self, o: Self) -> Self;
    /// `self` clamped to `[lo, hi]` by value.
    fn clamp(self, lo: f64, hi: f64) -> Self;
}

impl Real for f64 {
    const DIFFERENTIATES: bool = false;
    #[inline]
    fn cst(v: f64) -> f64 {
        v
    }
    #[inline]
    fn value(self) -> f64 {
        self
    }
    #[inline]
    fn with_value(self, v: f64) -> f64 {
        v
    }
    #[inline]
    fn sin(self) -> f64 {
        f64::sin(self)
    }
    #[inline]
    fn cos(self) -> f64 {
        f64::cos(self)
    }
    #[inline]
    fn sin_cos(self) -> (f64, f64) {
        f64::sin_cos(self)
    }
    #[inline]
    fn tan(self) -> f64 {
        f64::tan(self)
    }
    #[inline]
    fn asin(self) -> f64 {
        f64::asin(self)
    }
    #[inline]
    fn atan2(self, x: f64) -> f64 {
        f64::atan2(self, x)
    }
    #[inline]
    fn sqrt(self) -> f64 {
        f64::sqrt(self)
    }
    #[inline]
    fn exp(self) -> f64 {
        f64::exp(self)
    }
    #[inline]
    fn ln(self) -> f64 {
        f64::ln(self)
    }
    #[inline]
    fn ln_1p(self) -> f64 {
        f64::ln_1p(self)
    }
    #[inline]
    fn tanh(self) -> f64 {
        f64::tanh(self)
    }
    #[inline]
    fn powi(self, n: i32) -> f64 {
        f64::powi(self, n)
    }
    #[inline]
    fn abs(self) -> f64 {
        f64::abs(self)
    }
    #[inline]
    fn recip(self) -> f64 {
        f64::recip(self)
    }
    #[inline]
    fn max(self, o: f64) -> f64 {
        f64::max(self, o)
    }
    #[inline]
    fn min(self, o: f64) -> f64 {
        f64::min(self, o)
    }
    #[inline]
    fn clamp(self, lo: f64, hi: f64) -> f64 {
        f64::clamp(self, lo, hi)
    }
}

/// A value `v` and its gradient `g` with respect to `N` parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Dual<const N: usize> {
    /// Value of the function at the point.
    pub v: f64,
    /// Gradient: `d v / d p_k` for each of the `N` parameters.
    pub g: [f64; N],
}

impl<const N: usize> Dual<N> {
    /// Parameter `k` of the gradient, at value `v` (`d v / d p_k = 1`).
    pub fn variable(v: f64, k: usize) -> Self {
        let mut g = [0.0; N];
        g[k] = 1.0;
        Dual { v, g }
    }

    /// `f(v)` with `f'(v) = d`: the chain rule.
    #[inline]
    fn chain(self, f: f64, d: f64) -> Self {
        Dual {
            v: f,
            g: self.g.map(|x| x * d),
        }
    }
}

impl<const N: usize> Add for Dual<N> {
    type Output = Self;
    #[inline]
    fn add(self, o: Self) -> Self {
        Dual {
            v: self.v + o.v,
            g: std::array::from_fn(|k| self.g[k] + o.g[k]),
        }
    }
}

impl<const N: usize> Sub for Dual<N> {
    type Output = Self;
    #[inline]
    fn sub(self, o: Self) -> Self {
        Dual {
            v: self.v - o.v,
            g: std::array::from_fn(|k| self.g[k] - o.g[k]),
        }
    }
}

impl<const N: usize> Mul for Dual<N> {
    type Output = Self;
    /// The product rule (the `+` is its sum of two terms).
    #[inline]
    #[allow(clippy::suspicious_arithmetic_impl)]
    fn mul(self, o: Self) -> Self {
        Dual {
            v: self.v * o.v,
            g: std::array::from_fn(|k| self.g[k] * o.v + self.v * o.g[k]),
        }
    }
}

impl<const N: usize> Div for Dual<N> {
    type Output = Self;
    #[inline]
    fn div(self, o: Self) -> Self {
        let inv = 1.0 / o.v;
        let q = self.v / o.v;
        Dual {
            v: q,
            g: std::array::from_fn(|k| (self.g[k] - q * o.g[k]) * inv),
        }
    }
}

impl<const N: usize> Neg for Dual<N> {
    type Output = Self;
    #[inline]
    fn neg(self) -> Self {
        Dual {
            v: -self.v,
            g: self.g.map(|x| -x),
        }
    }
}

impl<const N: usize> Add<f64> for Dual<N> {
    type Output = Self;
    #[inline]
    fn add(self, c: f64) -> Self {
        Dual {
            v: self.v + c,
            g: self.g,
        }
    }
}

impl<const N: usize> Sub<f64> for Dual<N> {
    type Output = Self;
    #[inline]
    fn sub(self, c: f64) -> Self {
        Dual {
            v: self.v - c,
            g: self.g,
        }
    }
}

impl<const N: usize> Mul<f64> for Dual<N> {
    type Output = Self;
    #[inline]
    fn mul(self, c: f64) -> Self {
        Dual {
            v: self.v * c,
            g: self.g.map(|x| x * c),
        }
    }
}

impl<const N: usize> Div<f64> for Dual<N> {
    type Output = Self;
    #[inline]
    fn div(self, c: f64) -> Self {
        Dual {
            v: self.v / c,
            g: self.g.map(|x| x / c),
        }
    }
}

impl<const N: usize> AddAssign for Dual<N> {
    #[inline]
    fn add_assign(&mut self, o: Self) {
        *self = *self + o;
    }
}

impl<const N: usize> SubAssign for Dual<N> {
    #[inline]
    fn sub_assign(&mut self, o: Self) {
        *self = *self - o;
    }
}

impl<const N: usize> MulAssign for Dual<N> {
    #[inline]
    fn mul_assign(&mut self, o: Self) {
        *self = *self * o;
    }
}

impl<const N: usize> Real for Dual<N> {
    const DIFFERENTIATES: bool = true;
    #[inline]
    fn cst(v: f64) -> Self {
        Dual { v, g: [0.0; N] }
    }
    #[inline]
    fn value(self) -> f64 {
        self.v
    }
    #[inline]
    fn with_value(self, v: f64) -> Self {
        Dual { v, g: self.g }
    }
    #[inline]
    fn sin(self) -> Self {
        let (s, c) = self.v.sin_cos();
        self.chain(s, c)
    }
    #[inline]
    fn cos(self) -> Self {
        let (s, c) = self.v.sin_cos();
        self.chain(c, -s)
    }
    #[inline]
    fn sin_cos(self) -> (Self, Self) {
        let (s, c) = self.v.sin_cos();
        (self.chain(s, c), self.chain(c, -s))
    }
    #[inline]
    fn tan(self) -> Self {
        let t = self.v.tan();
        self.chain(t, 1.0 + t * t)
    }
    #[inline]
    fn asin(self) -> Self {
        self.chain(self.v.asin(), 1.0 / (1.0 - self.v * self.v).sqrt())
    }
    #[inline]
    fn atan2(self, x: Self) -> Self {
        // d atan2(y, x) = (x dy - y dx) / (x^2 + y^2).
        let (y, r2) = (self.v, self.v * self.v + x.v * x.v);
        Dual {
            v: y.atan2(x.v),
            g: std::array::from_fn(|k| (x.v * self.g[k] - y * x.g[k]) / r2),
        }
    }
    #[inline]
    fn sqrt(self) -> Self {
        let r = self.v.sqrt();
        self.chain(r, 0.5 / r)
    }
    #[inline]
    fn exp(self) -> Self {
        let e = self.v.exp();
        self.chain(e, e)
    }
    #[inline]
    fn ln(self) -> Self {
        self.chain(self.v.ln(), 1.0 / self.v)
    }
    #[inline]
    fn ln_1p(self) -> Self {
        self.chain(self.v.ln_1p(), 1.0 / (1.0 + self.v))
    }
    #[inline]
    fn tanh(self) -> Self {
        let t = self.v.tanh();
        self.chain(t, 1.0 - t * t)
    }
    #[inline]
    fn powi(self, n: i32) -> Self {
        if n == 0 {
            return Real::cst(1.0);
        }
        self.chain(self.v.powi(n), n as f64 * self.v.powi(n - 1))
    }
    #[inline]
    fn abs(self) -> Self {
        if self.v < 0.0 {
            -self
        } else {
            self
        }
    }
    #[inline]
    fn recip(self) -> Self {
        let r = 1.0 / self.v;
        self.chain(r, -r * r)
    }
    #[inline]
    fn max(self, o: Self) -> Self {
        // As f64::max: a NaN loses.
        if self.v.is_nan() || o.v > self.v {
            o
        } else {
            self
        }
    }
    #[inline]
    fn min(self, o: Self) -> Self {
        if self.v.is_nan() || o.v < self.v {
            o
        } else {
            self
        }
    }
    #[inline]
    fn clamp(self, lo: f64, hi: f64) -> Self {
        if self.v < lo {
            Real::cst(lo)
        } else if self.v > hi {
            Real::cst(hi)
        } else {
            self
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every elementary function's derivative against a central difference (step 1e-6:
    /// truncation ~1e-12 times the third derivative, rounding ~1e-10; 1e-7 relative).
    #[test]
    fn elementary_derivatives_match_central_differences() {
        type D = Dual<2>;
        type Case = (&'static str, fn(D) -> D);
        let fs: [Case; 14] = [
            ("sin", |x| x.sin()),
            ("cos", |x| x.cos()),
            ("tan", |x| x.tan()),
            ("asin", |x| (x * 0.5).asin()),
            ("atan2", |x| (x * 0.3).atan2(x.cos())),
            ("sqrt", |x| x.sqrt()),
            ("exp", |x| x.exp()),
            ("ln", |x| x.ln()),
            ("ln_1p", |x| x.ln_1p()),
            ("tanh", |x| x.tanh()),
            ("powi", |x| x.powi(5)),
            ("recip", |x| x.recip()),
            ("div", |x| (x * x + 1.0) / (x.sin() + 2.0)),
            ("abs", |x| (x - 1.0).abs() * x),
        ];
        for (name, f) in fs {
            for x0 in [0.3, 0.77, 1.4] {
                let d = f(D::variable(x0, 1)).g;
                let h = 1e-6;
                let fd = (f(Real::cst(x0 + h)).v - f(Real::cst(x0 - h)).v) / (2.0 * h);
                assert_eq!(d[0], 0.0, "{name}");
                assert!(
                    (d[1] - fd).abs() <= 1e-7 * fd.abs().max(1.0),
                    "{name} at {x0}: {} vs {fd}",
                    d[1]
                );
            }
        }
    }
}
