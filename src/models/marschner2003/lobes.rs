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

use std::f64::consts::{PI, TAU};

/// R, TT, TRT (the seed ignores `p > 2`).
pub const LOBES: usize = 3;

/// The normalised Gaussian `g(w; x)` of standard deviation `w` (Sec. 5.1).
pub fn gaussian(x: f64, w: f64) -> f64 {
    (-0.5 * (x / w) * (x / w)).exp() / (w * (TAU).sqrt())
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

/// The longitudinal shifts and widths of R, TT, TRT from `alpha_R`, `beta_R` by the
/// seed's Table 1 relations: shifts `alpha_R, -alpha_R / 2, -3 alpha_R / 2`, widths
/// `beta_R, beta_R / 2, 2 beta_R`.
pub fn shifts_widths(alpha_r: f64, beta_r: f64) -> [(f64, f64); LOBES] {
    [
        (alpha_r, beta_r),
        (-0.5 * alpha_r, 0.5 * beta_r),
        (-1.5 * alpha_r, 2.0 * beta_r),
    ]
}

/// `M_p(theta_h) = g(beta_p; theta_h - alpha_p)` of each lobe (Sec. 5.1).
pub fn longitudinal(theta_h: f64, lobes: &[(f64, f64); LOBES]) -> [f64; LOBES] {
    lobes.map(|(a, b)| gaussian(theta_h - a, b))
}

/// Bravais's indices at inclination `theta` (Appendix B): `eta'` for the perpendicular
/// polarisation, `eta''` for the parallel one.
pub fn bravais(eta: f64, theta: f64) -> (f64, f64) {
    let (s, c) = theta.sin_cos();
    let root = (eta * eta - s * s).sqrt();
    (root / c, eta * eta * c / root)
}

/// The generalised Fresnel reflectance `F(eta', eta'', gamma)` (Appendix B): the mean of
/// the perpendicular reflectance with index `eta'` and the parallel one with `eta''` at
/// incidence `gamma` in the projection plane. Indices below 1 (inside the fiber) can reach
/// total internal reflection, which gives 1.
pub fn fresnel(eta_p: f64, eta_pp: f64, gamma: f64) -> f64 {
    let (s, ci) = gamma.sin_cos();
    let ci = ci.abs();
    let perp = {
        let st2 = s * s / (eta_p * eta_p);
        if st2 >= 1.0 {
            1.0
        } else {
            let ct = (1.0 - st2).sqrt();
            let r = (ci - eta_p * ct) / (ci + eta_p * ct);
            r * r
        }
    };
    let par = {
        let st2 = s * s / (eta_pp * eta_pp);
        if st2 >= 1.0 {
            1.0
        } else {
            let ct = (1.0 - st2).sqrt();
            let r = (eta_pp * ci - ct) / (eta_pp * ci + ct);
            r * r
        }
    };
    0.5 * (perp + par)
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
pub struct Section {
    /// `eta'` at `theta_d`: Bravais's index for the perpendicular polarisation
    /// (Appendix B, [`bravais`]).
    pub eta_p: f64,
    /// `eta''` at `theta_d`: the index for the parallel polarisation.
    pub eta_pp: f64,
    /// `sigma_a / cos theta_t` (Sec. 4.3).
    pub sigma: f64,
}

impl Section {
    /// The section of a fiber of index `eta` and absorption `sigma_a` at `theta_d`.
    pub fn new(eta: f64, sigma_a: f64, theta_d: f64) -> Section {
        let (eta_p, eta_pp) = bravais(eta, theta_d);
        let st = theta_d.sin() / eta;
        Section {
            eta_p,
            eta_pp,
            sigma: sigma_a / (1.0 - st * st).sqrt(),
        }
    }

    /// `gamma_t = asin(h / eta')` (Snell in the projection plane).
    pub fn gamma_t(&self, h: f64) -> f64 {
        (h / self.eta_p).asin()
    }

    /// `Phi(p, h) = 2 p gamma_t - 2 gamma_i + p pi` (Eq. 3), not wrapped.
    pub fn phi(&self, p: usize, h: f64) -> f64 {
        let p = p as f64;
        2.0 * p * self.gamma_t(h) - 2.0 * h.asin() + p * PI
    }

    /// `dPhi / dh = 2 p / sqrt(eta'^2 - h^2) - 2 / sqrt(1 - h^2)`.
    pub fn dphi(&self, p: usize, h: f64) -> f64 {
        2.0 * p as f64 / (self.eta_p * self.eta_p - h * h).sqrt() - 2.0 / (1.0 - h * h).sqrt()
    }

    /// `d^2 Phi / dh^2`.
    pub fn ddphi(&self, p: usize, h: f64) -> f64 {
        let e = self.eta_p * self.eta_p - h * h;
        let o = 1.0 - h * h;
        2.0 * p as f64 * h / (e * e.sqrt()) - 2.0 * h / (o * o.sqrt())
    }

    /// The attenuation `A(p, h)` (Sec. 4.3, generalised to 3-D): `F(eta', eta'', gamma_i)`
    /// for R, else `(1 - F)^2 F(1/eta', 1/eta'', gamma_t)^(p-1) T^p` with
    /// `T = exp(-2 sigma_a' (1 + cos 2 gamma_t))`.
    pub fn attenuation(&self, p: usize, h: f64) -> f64 {
        let gi = h.asin();
        let f = fresnel(self.eta_p, self.eta_pp, gi);
        if p == 0 {
            return f;
        }
        let gt = self.gamma_t(h);
        let inner = fresnel(1.0 / self.eta_p, 1.0 / self.eta_pp, gt);
        let t = (-2.0 * self.sigma * (1.0 + (2.0 * gt).cos())).exp();
        (1.0 - f) * (1.0 - f) * inner.powi(p as i32 - 1) * t.powi(p as i32)
    }

    /// The offsets where `Phi(p, .)` turns (Descartes, Eq. 4): `h_c` with
    /// `h_c^2 = (4 - eta'^2) / 3` for TRT below the merge (`eta' < 2`), else none.
    pub fn caustic(&self, p: usize) -> Option<f64> {
        let h2 = (4.0 - self.eta_p * self.eta_p) / 3.0;
        (p == 2 && h2 > 0.0).then(|| h2.sqrt())
    }

    /// `Phi` in the variable `gamma_i` (`h = sin gamma_i`), smooth up to the rim where
    /// `dPhi/dh` is infinite: `2 p asin(sin(gamma) / eta') - 2 gamma + p pi`.
    pub fn phi_of_gamma(&self, p: usize, gamma: f64) -> f64 {
        let p = p as f64;
        2.0 * p * (gamma.sin() / self.eta_p).asin() - 2.0 * gamma + p * PI
    }

    /// `dPhi / dgamma_i = 2 p cos(gamma) / sqrt(eta'^2 - sin^2 gamma) - 2`.
    pub fn dphi_of_gamma(&self, p: usize, gamma: f64) -> f64 {
        let (s, c) = gamma.sin_cos();
        2.0 * p as f64 * c / (self.eta_p * self.eta_p - s * s).sqrt() - 2.0
    }

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

    /// `weight * N_p(p, phi)` with `N_p = sum_r A(p, h_r) |2 dPhi/dh(h_r)|^-1` (Eq. 8);
    /// `weight` is the caustic's damping at `phi` (1 for the plain sum). With weight 0 a
    /// root at a fold (`dPhi/dh = 0`) adds 0, its limit.
    pub fn azimuthal(
        &self,
        p: usize,
        phi: f64,
        roots: &mut Vec<f64>,
        finder: RootFinder,
        weight: f64,
    ) -> f64 {
        self.roots(p, phi, finder, roots);
        if weight == 0.0 {
            return 0.0;
        }
        roots
            .iter()
            .map(|&h| {
                let d = self.dphi(p, h).abs();
                if d == 0.0 {
                    return f64::INFINITY;
                }
                weight * self.attenuation(p, h) / (2.0 * d)
            })
            .sum()
    }
}

/// The caustic model's parameters (Table 1 "Glints"; widths in radians).
#[derive(Clone, Copy, Debug)]
pub struct Glints {
    /// Glint scale factor `k_G`.
    pub k_g: f64,
    /// Azimuthal width of the caustic, `w_c` (radians).
    pub w_c: f64,
    /// Fade range of the caustic merge, `Delta eta'`.
    pub delta_eta: f64,
    /// Caustic intensity limit, `Delta h_M`.
    pub delta_h_m: f64,
}

/// `1` below `a`, `0` above `b`, the cubic smoothstep between (Sec. 5.2.2's
/// `smoothstep(a, b, x)`, which the seed defines as 1 for `x < a`).
pub fn fade(a: f64, b: f64, x: f64) -> f64 {
    let u = ((x - a) / (b - a)).clamp(0.0, 1.0);
    1.0 - u * u * (3.0 - 2.0 * u)
}

/// `N_TRT` with the caustic replaced by smooth lobes (the procedure of Sec. 5.2.2):
/// the root sum damped by `1 - t g(phi -+ phi_c, w_c) / g(0, w_c)` around both caustics,
/// plus `t k_G A(2, h_c) Delta_h (g(phi - phi_c) + g(phi + phi_c))`, with
/// `Delta_h = min(Delta_h_M, 2 sqrt(2 w_c / |Phi''(h_c)|))` below the merge and `Delta_h_M`
/// past it, where the caustic sits at `phi_c = 0` and fades over `Delta eta'`.
pub fn trt(sec: &Section, phi: f64, gl: &Glints, roots: &mut Vec<f64>, finder: RootFinder) -> f64 {
    let (phi_c, dh, t, h_c) = match sec.caustic(2) {
        Some(hc) => {
            let dh = (2.0 * (2.0 * gl.w_c / sec.ddphi(2, hc).abs()).sqrt()).min(gl.delta_h_m);
            (wrap(sec.phi(2, hc)), dh, 1.0, hc)
        }
        None => (
            0.0,
            gl.delta_h_m,
            fade(2.0, 2.0 + gl.delta_eta, sec.eta_p),
            0.0,
        ),
    };
    let g0 = gaussian(0.0, gl.w_c);
    let damp = |x: f64| 1.0 - t * gaussian(wrap(x), gl.w_c) / g0;
    // The damping, a function of phi alone, goes in as the weight so that a root at the
    // fold, where the plain term is infinite, adds 0.
    let d = damp(phi - phi_c) * damp(phi + phi_c);
    let plain = sec.azimuthal(2, phi, roots, finder, d);
    let glint = gaussian(wrap(phi - phi_c), gl.w_c) + gaussian(wrap(phi + phi_c), gl.w_c);
    plain + t * gl.k_g * sec.attenuation(2, h_c) * dh * glint
}

/// The eccentric fiber's TRT index (Sec. 5.2.3): `eta*_1 = 2 (eta - 1) a^2 - eta + 2`,
/// `eta*_2 = 2 (eta - 1) a^-2 - eta + 2`, interpolated as
/// `((eta*_1 + eta*_2) + cos(2 phi_h) (eta*_1 - eta*_2)) / 2`.
pub fn eta_star(eta: f64, a: f64, phi_h: f64) -> f64 {
    let e1 = 2.0 * (eta - 1.0) * a * a - eta + 2.0;
    let e2 = 2.0 * (eta - 1.0) / (a * a) - eta + 2.0;
    0.5 * ((e1 + e2) + (2.0 * phi_h).cos() * (e1 - e2))
}
