//! Marschner et al. 2003 (seed `002`), one function per concept: the longitudinal
//! Gaussians `M_p` (Sec. 5.1), the Bravais indices and generalised Fresnel (Appendix B),
//! the exact cross-section geometry `Phi(p, h)` (Eq. 3) and its roots, the attenuation
//! `A(p, h)` (Sec. 4.3), the azimuthal `N_p` (Eq. 8), the TRT caustic procedure
//! (Sec. 5.2.2) and the eccentricity index `eta*` (Sec. 5.2.3).
//!
//! Conventions the seed leaves open, pinned here:
//! - Angles are MODEL.md's: `theta` toward the tip positive, `theta_h`, `theta_d` its
//!   half sum and difference, `phi = phi_r - phi_i` with 0 backward. The seed's own
//!   frame is the same (`theta` = 90 deg along `u`, root to tip; `Phi(0, 0) = 0` is the
//!   mirror back toward the light).
//! - Roots are solved on the *exact* geometry (`gamma_t = asin(h / eta')`), not the cubic
//!   of Eq. 10, which the seed offers only as a speed-up (error up to 0.75 deg).
//! - `sigma_a` is per unit fiber radius (Sec. 4.3), lengthened by `1 / cos theta_t` with
//!   `sin theta_t = sin theta_d / eta` (the internal inclination).
//! - The Bravais indices are taken at `theta_d` (Eq. 9).
//! - The eccentricity's `phi_h` is `phi / 2`: a goniometer's fiber does not turn about
//!   its axis, and its major axis is taken along the light's azimuth (`phi_i = 0`).
//!   Everything in `N_TRT` (roots, Fresnel, absorption, caustic) uses `eta*`.
//! - The caustic's `A(2, theta, phi)` is the attenuation at the caustic's own offset
//!   `h_c` (at `h = 0`, the central path, past the merge: the limit of `h_c`).
//! - `g(x, w)` is the normalised Gaussian of standard deviation `w`, of `x` wrapped to
//!   `(-pi, pi]` (its mass beyond `pi` is below 1e-10 for `w <= 45 deg`).

//!
//! The functions are generic over [`Real`]: `f64` gives the values (the same operations in
//! the same order as the plain formulas, bit for bit: every constant sits on the right of
//! a commutative operation), [`crate::models::dual::Dual`] their derivatives for the
//! fitter's analytic Jacobian. Roots are found on the values and lifted
//! ([`Section::lift_root`]).

use crate::models::dual::Real;
use std::f64::consts::{PI, TAU};

/// R, TT, TRT (the seed ignores `p > 2`).
pub const LOBES: usize = 3;

/// The normalised Gaussian `g(w; x)` of standard deviation `w` (Sec. 5.1).
pub fn gaussian<T: Real>(x: T, w: T) -> T {
    let q = x / w;
    (q * -0.5 * q).exp() / (w * TAU.sqrt())
}

/// `x` wrapped to `(-pi, pi]`.
pub fn wrap(x: f64) -> f64 {
    let y = x.rem_euclid(TAU);
    if y > PI {
        y - TAU
    } else {
        y
    }
}

/// [`wrap`] of a value, its derivatives kept (a shift by a multiple of `2 pi`).
fn wrapped<T: Real>(x: T) -> T {
    x.with_value(wrap(x.value()))
}

/// The longitudinal shifts and widths of R, TT, TRT from `alpha_R`, `beta_R` by the
/// seed's Table 1 relations: shifts `alpha_R, -alpha_R / 2, -3 alpha_R / 2`, widths
/// `beta_R, beta_R / 2, 2 beta_R`.
pub fn shifts_widths<T: Real>(alpha_r: T, beta_r: T) -> [(T, T); LOBES] {
    [
        (alpha_r, beta_r),
        (alpha_r * -0.5, beta_r * 0.5),
        (alpha_r * -1.5, beta_r * 2.0),
    ]
}

/// `M_p(theta_h) = g(beta_p; theta_h - alpha_p)` of each lobe (Sec. 5.1).
pub fn longitudinal<T: Real>(theta_h: f64, lobes: &[(T, T); LOBES]) -> [T; LOBES] {
    lobes.map(|(a, b)| gaussian(T::cst(theta_h) - a, b))
}

/// Bravais's indices at inclination `theta` (Appendix B): `eta'` for the perpendicular
/// polarisation, `eta''` for the parallel one.
pub fn bravais<T: Real>(eta: T, theta: f64) -> (T, T) {
    let (s, c) = theta.sin_cos();
    let root = (eta * eta - s * s).sqrt();
    (root / c, eta * eta * c / root)
}

/// The generalised Fresnel reflectance `F(eta', eta'', gamma)` (Appendix B): the mean of
/// the perpendicular reflectance with index `eta'` and the parallel one with `eta''` at
/// incidence `gamma` in the projection plane. Indices below 1 (inside the fiber) can reach
/// total internal reflection, which gives 1.
pub fn fresnel<T: Real>(eta_p: T, eta_pp: T, gamma: T) -> T {
    let one = T::cst(1.0);
    let (s, ci) = gamma.sin_cos();
    let ci = ci.abs();
    let perp = {
        let st2 = s * s / (eta_p * eta_p);
        if st2.value() >= 1.0 {
            one
        } else {
            let ct = (one - st2).sqrt();
            let r = (ci - eta_p * ct) / (ci + eta_p * ct);
            r * r
        }
    };
    let par = {
        let st2 = s * s / (eta_pp * eta_pp);
        if st2.value() >= 1.0 {
            one
        } else {
            let ct = (one - st2).sqrt();
            let r = (eta_pp * ci - ct) / (eta_pp * ci + ct);
            r * r
        }
    };
    (perp + par) * 0.5
}

/// How [`Section::roots`] finds the roots of `Phi(p, h) = phi`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RootFinder {
    /// Split `[-1, 1]` where `Phi` turns (Descartes's `h_c`), one safeguarded Newton
    /// solve per target `phi + 2 pi k` each monotone piece covers (the model's own).
    Segments,
    /// Sign changes of `Phi - phi` (wrapped) on a uniform grid of [`SCAN_CELLS`] cells,
    /// each bisected to rounding: knows nothing of the caustic (the reference).
    Scan,
}

/// Cells of [`RootFinder::Scan`].
pub const SCAN_CELLS: usize = 20_000;

/// One `theta_d` of one lobe family: the Bravais indices and the lengthened absorption.
#[derive(Clone, Copy, Debug)]
pub struct Section<T = f64> {
    /// `eta'` at `theta_d`: Bravais's index for the perpendicular polarisation
    /// (Appendix B, [`bravais`]).
    pub eta_p: T,
    /// `eta''` at `theta_d`: the index for the parallel polarisation.
    pub eta_pp: T,
    /// `sigma_a / cos theta_t` (Sec. 4.3).
    pub sigma: T,
}

impl<T: Real> Section<T> {
    /// The section of a fiber of index `eta` and absorption `sigma_a` at `theta_d`.
    pub fn new(eta: T, sigma_a: T, theta_d: f64) -> Section<T> {
        let (eta_p, eta_pp) = bravais(eta, theta_d);
        let st = T::cst(theta_d.sin()) / eta;
        Section {
            eta_p,
            eta_pp,
            sigma: sigma_a / (T::cst(1.0) - st * st).sqrt(),
        }
    }

    /// The section's values (its derivatives dropped), where roots are found.
    pub fn values(&self) -> Section<f64> {
        Section {
            eta_p: self.eta_p.value(),
            eta_pp: self.eta_pp.value(),
            sigma: self.sigma.value(),
        }
    }

    /// `gamma_t = asin(h / eta')` (Snell in the projection plane).
    pub fn gamma_t(&self, h: T) -> T {
        (h / self.eta_p).asin()
    }

    /// `Phi(p, h) = 2 p gamma_t - 2 gamma_i + p pi` (Eq. 3), not wrapped.
    pub fn phi(&self, p: usize, h: T) -> T {
        let p = p as f64;
        self.gamma_t(h) * (2.0 * p) - h.asin() * 2.0 + p * PI
    }

    /// `dPhi / dh = 2 p / sqrt(eta'^2 - h^2) - 2 / sqrt(1 - h^2)`.
    pub fn dphi(&self, p: usize, h: T) -> T {
        T::cst(2.0 * p as f64) / (self.eta_p * self.eta_p - h * h).sqrt()
            - T::cst(2.0) / (T::cst(1.0) - h * h).sqrt()
    }

    /// `d^2 Phi / dh^2`.
    pub fn ddphi(&self, p: usize, h: T) -> T {
        let e = self.eta_p * self.eta_p - h * h;
        let o = T::cst(1.0) - h * h;
        h * (2.0 * p as f64) / (e * e.sqrt()) - h * 2.0 / (o * o.sqrt())
    }

    /// The attenuation `A(p, h)` (Sec. 4.3, generalised to 3-D): `F(eta', eta'', gamma_i)`
    /// for R, else `(1 - F)^2 F(1/eta', 1/eta'', gamma_t)^(p-1) T^p` with
    /// `T = exp(-2 sigma_a' (1 + cos 2 gamma_t))`.
    pub fn attenuation(&self, p: usize, h: T) -> T {
        let one = T::cst(1.0);
        let gi = h.asin();
        let f = fresnel(self.eta_p, self.eta_pp, gi);
        if p == 0 {
            return f;
        }
        let gt = self.gamma_t(h);
        let inner = fresnel(one / self.eta_p, one / self.eta_pp, gt);
        let t = (self.sigma * -2.0 * ((gt * 2.0).cos() + 1.0)).exp();
        (one - f) * (one - f) * inner.powi(p as i32 - 1) * t.powi(p as i32)
    }

    /// The offsets where `Phi(p, .)` turns (Descartes, Eq. 4): `h_c` with
    /// `h_c^2 = (4 - eta'^2) / 3` for TRT below the merge (`eta' < 2`), else none.
    pub fn caustic(&self, p: usize) -> Option<T> {
        let h2 = (T::cst(4.0) - self.eta_p * self.eta_p) / 3.0;
        (p == 2 && h2.value() > 0.0).then(|| h2.sqrt())
    }

    /// `Phi` in the variable `gamma_i` (`h = sin gamma_i`), smooth up to the rim where
    /// `dPhi/dh` is infinite: `2 p asin(sin(gamma) / eta') - 2 gamma + p pi`.
    pub fn phi_of_gamma(&self, p: usize, gamma: T) -> T {
        let p = p as f64;
        (gamma.sin() / self.eta_p).asin() * (2.0 * p) - gamma * 2.0 + p * PI
    }

    /// `dPhi / dgamma_i = 2 p cos(gamma) / sqrt(eta'^2 - sin^2 gamma) - 2`.
    pub fn dphi_of_gamma(&self, p: usize, gamma: T) -> T {
        let (s, c) = gamma.sin_cos();
        c * (2.0 * p as f64) / (self.eta_p * self.eta_p - s * s).sqrt() - 2.0
    }

    /// A root `h` of `Phi(p, h) = phi` found on [`Self::values`], with its derivatives:
    /// by the implicit function theorem in `gamma_i = asin h`,
    /// `d gamma / d x = -(dPhi/dx) / (dPhi/dgamma)` (`phi` does not move), and
    /// `dh = cos(gamma) d gamma`. The value stays `h` exactly; with `f64` nothing is done.
    /// At a fold (`dPhi/dgamma = 0`) the root's derivative is unbounded and is left out.
    pub fn lift_root(&self, p: usize, h: f64) -> T {
        if !T::DIFFERENTIATES {
            return T::cst(h);
        }
        let g = h.asin();
        let slope = self.dphi_of_gamma(p, T::cst(g)).value();
        if slope == 0.0 || !slope.is_finite() {
            return T::cst(h);
        }
        let f = self.phi_of_gamma(p, T::cst(g));
        // `f - f.value()` is 0 with the derivatives of Phi at fixed gamma.
        T::cst(h) + (f - f.value()) * (-g.cos() / slope)
    }
}

impl Section<f64> {
    /// Every root `h` of `Phi(p, h) = phi (mod 2 pi)` in `[-1, 1]`, into `out`: on each
    /// interval of `gamma_i` where `Phi` is monotone (split at the caustic's
    /// `asin h_c`) the targets `phi + 2 pi k` its range covers, each by safeguarded
    /// Newton in `gamma_i` to rounding.
    pub fn roots(&self, p: usize, phi: f64, finder: RootFinder, out: &mut Vec<f64>) {
        out.clear();
        if finder == RootFinder::Scan {
            return self.roots_by_scan(p, phi, out);
        }
        if p == 0 {
            // -2 asin h = phi: the one mirror path.
            out.push(-(0.5 * wrap(phi)).sin());
            return;
        }
        let half = 0.5 * PI;
        let mut edges = vec![-half];
        if let Some(hc) = self.caustic(p) {
            let gc = hc.asin();
            edges.extend([-gc, gc]);
        }
        edges.push(half);
        for w in edges.windows(2) {
            let (a, b) = (w[0], w[1]);
            let (fa, fb) = (self.phi_of_gamma(p, a), self.phi_of_gamma(p, b));
            let (lo, hi) = (fa.min(fb), fa.max(fb));
            let k0 = ((lo - phi) / TAU).ceil() as i64;
            let k1 = ((hi - phi) / TAU).floor() as i64;
            for k in k0..=k1 {
                let target = phi + TAU * k as f64;
                out.push(self.solve(p, target, a, b, fa).sin());
            }
        }
    }

    /// [`RootFinder::Scan`]: a wrapped difference that changes sign by less than pi
    /// between two grid offsets brackets a root (a jump across the wrap is not one).
    fn roots_by_scan(&self, p: usize, phi: f64, out: &mut Vec<f64>) {
        let f = |h: f64| wrap(self.phi(p, h) - phi);
        let step = 2.0 / SCAN_CELLS as f64;
        let mut a = -1.0;
        let mut fa = f(a);
        for i in 1..=SCAN_CELLS {
            let b = if i == SCAN_CELLS {
                1.0
            } else {
                -1.0 + i as f64 * step
            };
            let fb = f(b);
            if fa == 0.0 {
                out.push(a);
            } else if fa * fb < 0.0 && (fa - fb).abs() < PI {
                let (mut lo, mut hi, flo) = (a, b, fa);
                for _ in 0..80 {
                    let mid = 0.5 * (lo + hi);
                    let fm = f(mid);
                    if fm.signum() == flo.signum() {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                out.push(0.5 * (lo + hi));
            }
            (a, fa) = (b, fb);
        }
        if fa == 0.0 {
            out.push(a);
        }
    }

    /// `gamma_i` in `[a, b]` with `Phi = target`, `Phi` monotone there, `fa = Phi(a)`.
    fn solve(&self, p: usize, target: f64, mut a: f64, mut b: f64, fa: f64) -> f64 {
        let sa = (fa - target).signum();
        let mut g = 0.5 * (a + b);
        for _ in 0..100 {
            let f = self.phi_of_gamma(p, g) - target;
            if f.abs() < 1e-15 {
                break;
            }
            if f.signum() == sa {
                a = g;
            } else {
                b = g;
            }
            let newton = g - f / self.dphi_of_gamma(p, g);
            g = if newton > a && newton < b {
                newton
            } else {
                0.5 * (a + b)
            };
            if b - a < 1e-15 {
                break;
            }
        }
        g
    }
}

impl<T: Real> Section<T> {
    /// `weight * N_p(p, phi)` with `N_p = sum_r A(p, h_r) |2 dPhi/dh(h_r)|^-1` (Eq. 8);
    /// `weight` is the caustic's damping at `phi` (1 for the plain sum). With weight 0 a
    /// root at a fold (`dPhi/dh = 0`) adds 0, its limit.
    pub fn azimuthal(
        &self,
        p: usize,
        phi: f64,
        roots: &mut Vec<f64>,
        finder: RootFinder,
        weight: T,
    ) -> T {
        self.values().roots(p, phi, finder, roots);
        if weight.value() == 0.0 {
            return T::cst(0.0);
        }
        // From -0.0, as `f64`'s `Sum` (an empty sum is -0.0, bit for bit as before).
        roots.iter().fold(T::cst(-0.0), |sum, &h| {
            let h = self.lift_root(p, h);
            let d = self.dphi(p, h).abs();
            if d.value() == 0.0 {
                return sum + f64::INFINITY;
            }
            if d.value().is_infinite() {
                // A path at the rim (h = +-1): its term is 0 and stays 0 nearby; its
                // derivatives would be 0 * inf.
                return sum + 0.0;
            }
            sum + weight * self.attenuation(p, h) / (d * 2.0)
        })
    }
}

/// The caustic model's parameters (Table 1 "Glints"; widths in radians).
#[derive(Clone, Copy, Debug)]
pub struct Glints<T = f64> {
    /// Glint scale factor `k_G`.
    pub k_g: T,
    /// Azimuthal width of the caustic, `w_c` (radians).
    pub w_c: T,
    /// Fade range of the caustic merge, `Delta eta'`.
    pub delta_eta: T,
    /// Caustic intensity limit, `Delta h_M`.
    pub delta_h_m: T,
}

/// `1` below `a`, `0` above `b`, the cubic smoothstep between (Sec. 5.2.2's
/// `smoothstep(a, b, x)`, which the seed defines as 1 for `x < a`).
pub fn fade<T: Real>(a: T, b: T, x: T) -> T {
    let u = ((x - a) / (b - a)).clamp(0.0, 1.0);
    T::cst(1.0) - u * u * (T::cst(3.0) - u * 2.0)
}

/// `N_TRT` with the caustic replaced by smooth lobes (the procedure of Sec. 5.2.2):
/// the root sum damped by `1 - t g(phi -+ phi_c, w_c) / g(0, w_c)` around both caustics,
/// plus `t k_G A(2, h_c) Delta_h (g(phi - phi_c) + g(phi + phi_c))`, with
/// `Delta_h = min(Delta_h_M, 2 sqrt(2 w_c / |Phi''(h_c)|))` below the merge and `Delta_h_M`
/// past it, where the caustic sits at `phi_c = 0` and fades over `Delta eta'`.
pub fn trt<T: Real>(
    sec: &Section<T>,
    phi: f64,
    gl: &Glints<T>,
    roots: &mut Vec<f64>,
    finder: RootFinder,
) -> T {
    let zero = T::cst(0.0);
    let (phi_c, dh, t, h_c) = match sec.caustic(2) {
        Some(hc) => {
            let dh = ((gl.w_c * 2.0 / sec.ddphi(2, hc).abs()).sqrt() * 2.0).min(gl.delta_h_m);
            (wrapped(sec.phi(2, hc)), dh, T::cst(1.0), hc)
        }
        None => (
            zero,
            gl.delta_h_m,
            fade(T::cst(2.0), gl.delta_eta + 2.0, sec.eta_p),
            zero,
        ),
    };
    let g0 = gaussian(zero, gl.w_c);
    let damp = |x: T| T::cst(1.0) - t * gaussian(wrapped(x), gl.w_c) / g0;
    // The damping, a function of phi alone, goes in as the weight so that a root at the
    // fold, where the plain term is infinite, adds 0.
    let d = damp(T::cst(phi) - phi_c) * damp(phi_c + phi);
    let plain = sec.azimuthal(2, phi, roots, finder, d);
    let glint =
        gaussian(wrapped(T::cst(phi) - phi_c), gl.w_c) + gaussian(wrapped(phi_c + phi), gl.w_c);
    plain + t * gl.k_g * sec.attenuation(2, h_c) * dh * glint
}

/// The eccentric fiber's TRT index (Sec. 5.2.3): `eta*_1 = 2 (eta - 1) a^2 - eta + 2`,
/// `eta*_2 = 2 (eta - 1) a^-2 - eta + 2`, interpolated as
/// `((eta*_1 + eta*_2) + cos(2 phi_h) (eta*_1 - eta*_2)) / 2`.
pub fn eta_star<T: Real>(eta: T, a: T, phi_h: f64) -> T {
    let e1 = (eta - 1.0) * 2.0 * a * a - eta + 2.0;
    let e2 = (eta - 1.0) * 2.0 / (a * a) - eta + 2.0;
    ((e1 + e2) + (e1 - e2) * (2.0 * phi_h).cos()) * 0.5
}
