//! One photon path through a 3-D double-cylinder fiber (the physics of the virtual
//! goniometer; see the module docs of [`crate::simulate`] for every modelling choice).

use super::optics::{
    add, dot, fresnel_dielectric, hg_cos, normalize, pile_of_plates, reflect, refract, scale, V3,
};
use rand::Rng;
use rand_xoshiro::Xoshiro256PlusPlus;

/// Maximum number of segments (straight pieces inside the fiber plus interface events) of
/// one path. Paths still inside after this are light guided along the fiber, which leaves
/// far from the lit spot; their energy is tallied as `guided`, never binned. A medulla that
/// scatters strongly and absorbs little needs thousands of scatterings near the lit spot
/// (at 2000, `tau` 40 lost 1.6 % of the energy; review, 2026-11-28), so this stays large
/// and trapped cortex paths are cut by [`MAX_CUTICLE_HITS`] instead.
pub const MAX_EVENTS: u32 = 20_000;

/// Most cuticle interactions of one path before it counts as `guided`: a path reflected
/// this often inside the cortex is trapped by total internal reflection. In a lossless
/// cortex with a cuticle tilt (`sigma_c_a = 0`, `alpha = 8`, theta_i 30) 14 % of the paths
/// are trapped at weight 1, where Russian roulette never starts, and each ran the full
/// [`MAX_EVENTS`]: that run took 48 s for 20 000 paths (audit, 2026-11-28).
pub const MAX_CUTICLE_HITS: u32 = 2_000;

/// Axial distance (fiber radii) from the entry point beyond which a path still inside is
/// tallied as `guided` at once: 500 diameters, tens of millimetres for fur, far outside
/// any goniometer's lit spot (paths guided along the axis end here, those circling the
/// fiber at [`MAX_CUTICLE_HITS`]).
pub const GUIDED_LENGTH: f64 = 1000.0;

/// Russian roulette starts after this many interface/scattering events ...
const RR_AFTER: u32 = 6;
/// ... for paths whose weight fell below this; survivors get weight `RR_WEIGHT`.
const RR_WEIGHT: f64 = 0.1;

/// Tries to draw a cuticle micro-normal whose outcome is geometrically consistent before
/// falling back to the smooth normal.
const NORMAL_TRIES: usize = 16;

/// The fiber as the tracer sees it: the ten parameters (internal units) plus the optional
/// geometry extras.
#[derive(Clone, Copy, Debug)]
pub struct Fiber {
    /// Cortex (cuticle) IOR.
    pub eta: f64,
    /// Medulla IOR (equal to `eta` by default: index matched, no interface).
    pub eta_m: f64,
    /// Medulla radius / fiber radius.
    pub kappa: f64,
    /// Normal tilt toward the tip: `alpha / 2` (so the R lobe sits at `-theta_i + alpha`).
    pub tilt: f64,
    /// Std of the longitudinal micro-tilt of the normal: `beta_m / 2`.
    pub s_m: f64,
    /// Std of the azimuthal micro-tilt of the normal: `beta_n / 2`.
    pub s_n: f64,
    /// Cortex absorption, per unit radius.
    pub sigma_c_a: f64,
    /// Medulla scattering, per unit radius.
    pub sigma_m_s: f64,
    /// Medulla absorption, per unit radius.
    pub sigma_m_a: f64,
    /// Henyey-Greenstein anisotropy of medulla scattering.
    pub g: f64,
    /// Cuticle layers (the layered cuticle reflectance).
    pub l: f64,
    /// Semi-axes of the outer cross-section (x, y); (1, 1) for the circular fiber.
    pub ax: f64,
    /// Semi-axis of the outer cross-section along y (1 for the circular fiber).
    pub ay: f64,
    /// Random rotation of the cross-section about the axis (only for an ellipse).
    pub rotate: bool,
}

impl Fiber {
    /// Build from the ten parameters. `ellipse` is the axis ratio (minor/major, Marschner
    /// 2003's `a`); the cross-section keeps the unit circle's area: semi-axes
    /// `1/sqrt(e)` and `sqrt(e)`. `smooth` zeroes the micro-roughness (tests only).
    pub fn new(
        p: &crate::FurParams,
        ellipse: Option<f64>,
        eta_m: Option<f64>,
        smooth: bool,
    ) -> Self {
        let (ax, ay, rotate) = match ellipse {
            Some(e) if (e - 1.0).abs() > 1e-12 => (1.0 / e.sqrt(), e.sqrt(), true),
            _ => (1.0, 1.0, false),
        };
        Fiber {
            eta: p.eta,
            eta_m: eta_m.unwrap_or(p.eta),
            kappa: p.kappa,
            tilt: 0.5 * p.alpha,
            s_m: if smooth { 0.0 } else { 0.5 * p.beta_m },
            s_n: if smooth { 0.0 } else { 0.5 * p.beta_n },
            sigma_c_a: p.sigma_c_a,
            sigma_m_s: p.sigma_m_s,
            sigma_m_a: p.sigma_m_a,
            g: p.g,
            l: p.l,
            ax,
            ay,
            rotate,
        }
    }
}

/// Where and how a path ended.
#[derive(Clone, Copy, Debug, Default)]
pub struct Exit {
    /// Outgoing direction (unit), fiber frame.
    pub dir: V3,
    /// Azimuth of the incident light in the fiber frame (0 for the circular fiber).
    pub phi_i: f64,
    /// Energy weight carried out (launched weight 1).
    pub weight: f64,
    /// Number of cuticle interactions (1 = the R path: one external reflection).
    pub cuticle: u32,
    /// Number of volume scattering events in the medulla.
    pub scatters: u32,
}

/// Outcome of one traced path.
#[derive(Clone, Copy, Debug)]
pub enum Outcome {
    /// Left the fiber; binned by the detector.
    Exit(Exit),
    /// Absorbed or killed by Russian roulette (weight 0 by construction).
    Absorbed,
    /// Still inside after [`MAX_EVENTS`] or [`MAX_CUTICLE_HITS`], or beyond
    /// [`GUIDED_LENGTH`]: guided along the fiber; carries `weight`.
    Guided(f64),
}

/// Roots of `|P + t D|^2 = 1` for the ellipse with semi-axes `(ax, ay)` scaled by `s`:
/// returns `(t0, t1)`, `t0 <= t1`, or `None` when the line misses.
#[inline]
fn ellipse_roots(p: V3, d: V3, ax: f64, ay: f64) -> Option<(f64, f64)> {
    let (px, py) = (p[0] / ax, p[1] / ay);
    let (dx, dy) = (d[0] / ax, d[1] / ay);
    let a = dx * dx + dy * dy;
    if a < 1e-300 {
        return None;
    }
    let b = px * dx + py * dy;
    let c = px * px + py * py - 1.0;
    let disc = b * b - a * c;
    if disc <= 0.0 {
        return None;
    }
    let sq = disc.sqrt();
    // Numerically stable pair of roots.
    let q = -(b + sq.copysign(b));
    let (r0, r1) = if q == 0.0 { (0.0, 0.0) } else { (q / a, c / q) };
    Some(if r0 <= r1 { (r0, r1) } else { (r1, r0) })
}

/// Outward unit normal of the ellipse (semi-axes ax, ay) at the boundary point `p`.
#[inline]
fn ellipse_normal(p: V3, ax: f64, ay: f64) -> V3 {
    let n = [p[0] / (ax * ax), p[1] / (ay * ay), 0.0];
    let k = 1.0 / (n[0] * n[0] + n[1] * n[1]).sqrt();
    [n[0] * k, n[1] * k, 0.0]
}

/// A standard normal variate (Box-Muller; one of the pair is discarded for simplicity).
#[inline]
pub fn gauss(rng: &mut Xoshiro256PlusPlus) -> f64 {
    let u1: f64 = 1.0 - rng.random::<f64>();
    let u2: f64 = rng.random::<f64>();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// Sample a cuticle micro-normal at a boundary point with geometric outward normal `n0`:
/// tilt toward the tip by `tilt + s_m N(0,1)` and in azimuth by `s_n N(0,1)`.
#[inline]
fn micro_normal(f: &Fiber, n0: V3, rng: &mut Xoshiro256PlusPlus) -> V3 {
    let b = f.tilt + if f.s_m > 0.0 { f.s_m * gauss(rng) } else { 0.0 };
    let a = if f.s_n > 0.0 { f.s_n * gauss(rng) } else { 0.0 };
    if a == 0.0 && b == 0.0 {
        return n0;
    }
    let (sa, ca) = a.sin_cos();
    let (sb, cb) = b.sin_cos();
    // Tangent around the axis: z x n0.
    let t = [-n0[1], n0[0], 0.0];
    [
        cb * (ca * n0[0] + sa * t[0]),
        cb * (ca * n0[1] + sa * t[1]),
        sb,
    ]
}

/// A cuticle interaction at a boundary point with outward geometric normal `n0`.
/// `from_outside` says on which side the ray arrives. Returns the new direction and whether
/// it crossed the interface. The micro-normal is redrawn (up to [`NORMAL_TRIES`]) until the
/// ray faces it and the outcome leaves on the geometrically right side (no self-shadowing
/// model); after that the smooth normal is used.
#[inline]
fn cuticle(
    f: &Fiber,
    d: V3,
    n0: V3,
    from_outside: bool,
    rng: &mut Xoshiro256PlusPlus,
) -> (V3, bool) {
    // Relative index seen by the ray.
    let eta_rel = if from_outside { f.eta } else { 1.0 / f.eta };
    // Sign so that `s * n` faces the incoming ray.
    let s = if from_outside { 1.0 } else { -1.0 };
    for attempt in 0..=NORMAL_TRIES {
        let n = if attempt == NORMAL_TRIES {
            n0
        } else {
            micro_normal(f, n0, rng)
        };
        let nf = scale(n, s);
        let cos_i = -dot(d, nf);
        if cos_i <= 0.0 {
            continue;
        }
        let big_f = pile_of_plates(fresnel_dielectric(cos_i, eta_rel), f.l);
        let u: f64 = rng.random();
        if u < big_f {
            let r = reflect(d, nf);
            // Reflected ray must stay on the incoming side of the real surface.
            if dot(r, n0) * s > 0.0 || attempt == NORMAL_TRIES {
                return (r, false);
            }
        } else if let Some(t) = refract(d, nf, eta_rel) {
            if dot(t, n0) * s < 0.0 || attempt == NORMAL_TRIES {
                return (t, true);
            }
        } else if attempt == NORMAL_TRIES {
            return (reflect(d, nf), false);
        }
    }
    // Unreachable in practice: the smooth attempt always returns above (for the smooth
    // normal, cos_i > 0 holds for a ray that reached the boundary from its side).
    (reflect(d, scale(n0, s)), false)
}

/// Henyey-Greenstein scattering of `d` with anisotropy `g`.
#[inline]
pub fn hg_scatter(d: V3, g: f64, rng: &mut Xoshiro256PlusPlus) -> V3 {
    let u: f64 = rng.random();
    let v: f64 = rng.random();
    super::optics::around(d, hg_cos(g, u), std::f64::consts::TAU * v)
}

/// Smooth dielectric interface at the medulla boundary (only when `eta_m != eta`).
/// `n0` is the outward medulla normal; `into_medulla` gives the side.
#[inline]
fn medulla_interface(
    f: &Fiber,
    d: V3,
    n0: V3,
    into_medulla: bool,
    rng: &mut Xoshiro256PlusPlus,
) -> (V3, bool) {
    let (eta_rel, s) = if into_medulla {
        (f.eta_m / f.eta, 1.0)
    } else {
        (f.eta / f.eta_m, -1.0)
    };
    let nf = scale(n0, s);
    let cos_i = -dot(d, nf);
    let fr = fresnel_dielectric(cos_i.abs(), eta_rel);
    let u: f64 = rng.random();
    if u < fr {
        return (reflect(d, nf), false);
    }
    match refract(d, nf, eta_rel) {
        Some(t) => (t, true),
        None => (reflect(d, nf), false),
    }
}

#[derive(Clone, Copy, PartialEq)]
enum Region {
    Cortex,
    Medulla,
}

/// A path inside the fiber between events: position (`z` dropped: the fiber is
/// translation-invariant along it), direction, weight, region, and the tallies an
/// [`Exit`] reports.
struct Walk {
    p: V3,
    d: V3,
    w: f64,
    /// Axial travel since entry.
    z: f64,
    region: Region,
    cuticle_n: u32,
    scatters: u32,
    phi_i: f64,
}

/// The medulla's semi-axes and how its boundary acts (fixed per fiber).
struct MedullaShape {
    mx: f64,
    my: f64,
    present: bool,
    /// `eta_m == eta`: the boundary is no interface.
    index_matched: bool,
}

impl Walk {
    /// The path leaving through the cuticle now.
    fn exit(&self) -> Outcome {
        Outcome::Exit(Exit {
            dir: self.d,
            phi_i: self.phi_i,
            weight: self.w,
            cuticle: self.cuticle_n,
            scatters: self.scatters,
        })
    }

    /// Move `t` along the direction through a medium absorbing `sigma_a` per unit radius.
    #[inline]
    fn advance(&mut self, t: f64, sigma_a: f64) {
        self.w *= (-sigma_a * t).exp();
        self.p = add(self.p, scale(self.d, t));
        self.z += self.d[2] * t;
    }

    /// Cross the medulla boundary where the path stands (`into` the medulla or out of
    /// it), refracting or reflecting at an interface.
    fn medulla_boundary(
        &mut self,
        f: &Fiber,
        m: &MedullaShape,
        into: bool,
        rng: &mut Xoshiro256PlusPlus,
    ) {
        let other = if into {
            Region::Medulla
        } else {
            Region::Cortex
        };
        if m.index_matched {
            self.region = other;
        } else {
            let nm = ellipse_normal(self.p, m.mx, m.my);
            let (nd, crossed) = medulla_interface(f, self.d, nm, into, rng);
            self.d = nd;
            if crossed {
                self.region = other;
            }
        }
    }

    /// One segment in the cortex: to the medulla or to the cuticle, where the path may
    /// leave (`Some`).
    fn cortex_step(
        &mut self,
        f: &Fiber,
        m: &MedullaShape,
        rng: &mut Xoshiro256PlusPlus,
    ) -> Option<Outcome> {
        let t_out = match ellipse_roots(self.p, self.d, f.ax, f.ay) {
            Some((_, t1)) => t1.max(0.0),
            None => return Some(Outcome::Guided(self.w)),
        };
        let t_med = if m.present {
            match ellipse_roots(self.p, self.d, m.mx, m.my) {
                Some((t0, _)) if t0 > 1e-12 => t0,
                _ => f64::INFINITY,
            }
        } else {
            f64::INFINITY
        };
        if t_med < t_out {
            self.advance(t_med, f.sigma_c_a);
            self.medulla_boundary(f, m, true, rng);
            return None;
        }
        self.advance(t_out, f.sigma_c_a);
        // Re-project onto the boundary to stop rounding drift over many bounces.
        let p = self.p;
        let k = 1.0 / ((p[0] / f.ax).powi(2) + (p[1] / f.ay).powi(2)).sqrt();
        self.p = [p[0] * k, p[1] * k, 0.0];
        self.cuticle_n += 1;
        let n0 = ellipse_normal(self.p, f.ax, f.ay);
        let (nd, crossed) = cuticle(f, self.d, n0, false, rng);
        self.d = nd;
        crossed.then(|| self.exit())
    }

    /// One segment in the medulla: a scattering or the boundary. `false` when the path
    /// is tangential to the boundary (treated as leaving it, with no segment).
    fn medulla_step(&mut self, f: &Fiber, m: &MedullaShape, rng: &mut Xoshiro256PlusPlus) -> bool {
        let t_b = match ellipse_roots(self.p, self.d, m.mx, m.my) {
            Some((_, t1)) => t1.max(0.0),
            None => {
                self.region = Region::Cortex;
                return false;
            }
        };
        let s = if f.sigma_m_s > 0.0 {
            -(1.0 - rng.random::<f64>()).ln() / f.sigma_m_s
        } else {
            f64::INFINITY
        };
        if s < t_b {
            self.advance(s, f.sigma_m_a);
            self.d = hg_scatter(self.d, f.g, rng);
            self.scatters += 1;
        } else {
            self.advance(t_b, f.sigma_m_a);
            self.medulla_boundary(f, m, false, rng);
        }
        true
    }
}

/// Where a path from `theta_i` first meets the fiber: the light's azimuth `phi_i` (random
/// when the fiber rotates), the propagation direction and the hit point at a uniformly
/// random offset over the projected width; `None` for a grazing miss.
fn launch(f: &Fiber, theta_i: f64, rng: &mut Xoshiro256PlusPlus) -> Option<(f64, V3, V3)> {
    let phi_i = if f.rotate {
        std::f64::consts::TAU * rng.random::<f64>()
    } else {
        0.0
    };
    let (si, ci) = theta_i.sin_cos();
    let (sp, cp) = phi_i.sin_cos();
    // Propagation direction: away from the light.
    let d: V3 = [-ci * cp, -ci * sp, -si];
    // Offset across the projected width along e = (-sin phi_i, cos phi_i).
    let e = [-sp, cp, 0.0];
    let half_w = (f.ax * f.ax * e[0] * e[0] + f.ay * f.ay * e[1] * e[1]).sqrt();
    let h: f64 = 2.0 * rng.random::<f64>() - 1.0;
    let far = 4.0 * f.ax.max(f.ay);
    let start = [
        far * cp + h * half_w * e[0],
        far * sp + h * half_w * e[1],
        0.0,
    ];
    let (t0, _) = ellipse_roots(start, d, f.ax, f.ay)?;
    Some((phi_i, d, add(start, scale(d, t0))))
}

/// Trace one path: collimated light from `theta_i` (inclination of the direction toward the
/// light), hitting the fiber at a uniformly random offset over its projected width.
pub fn trace_path(f: &Fiber, theta_i: f64, rng: &mut Xoshiro256PlusPlus) -> Outcome {
    // |h| -> 1 rounding: a grazing miss counts as a grazing R event of weight 0.
    let Some((phi_i, d, p)) = launch(f, theta_i, rng) else {
        return Outcome::Absorbed;
    };
    let n0 = ellipse_normal(p, f.ax, f.ay);
    let (d, crossed) = cuticle(f, d, n0, true, rng);
    let mut walk = Walk {
        p,
        d,
        w: 1.0,
        z: 0.0,
        region: Region::Cortex,
        cuticle_n: 1,
        scatters: 0,
        phi_i,
    };
    if !crossed {
        return walk.exit();
    }
    let m = MedullaShape {
        mx: f.kappa * f.ax,
        my: f.kappa * f.ay,
        present: f.kappa > 0.0,
        index_matched: (f.eta_m - f.eta).abs() < 1e-12,
    };
    let mut events = 1u32;
    loop {
        events += 1;
        if events > MAX_EVENTS || walk.cuticle_n > MAX_CUTICLE_HITS || walk.z.abs() > GUIDED_LENGTH
        {
            return Outcome::Guided(walk.w);
        }
        if events > RR_AFTER && walk.w < RR_WEIGHT {
            let q = walk.w / RR_WEIGHT;
            if rng.random::<f64>() >= q {
                return Outcome::Absorbed;
            }
            walk.w = RR_WEIGHT;
        }
        match walk.region {
            Region::Cortex => {
                if let Some(out) = walk.cortex_step(f, &m, rng) {
                    return out;
                }
            }
            Region::Medulla => {
                if !walk.medulla_step(f, &m, rng) {
                    continue;
                }
            }
        }
        // Keep the direction unit length against rounding drift.
        if events.is_multiple_of(64) {
            walk.d = normalize(walk.d);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    /// A circular fiber with the given cuticle roughness (radians: `tilt`, `s_m`, `s_n`)
    /// and medulla IOR; the volume terms are irrelevant to these helpers.
    fn fiber(tilt: f64, s_m: f64, s_n: f64, eta_m: f64, l: f64) -> Fiber {
        Fiber {
            eta: 1.55,
            eta_m,
            kappa: 0.5,
            tilt,
            s_m,
            s_n,
            sigma_c_a: 0.0,
            sigma_m_s: 0.0,
            sigma_m_a: 0.0,
            g: 0.0,
            l,
            ax: 1.0,
            ay: 1.0,
            rotate: false,
        }
    }

    fn mean_std(v: &[f64]) -> (f64, f64) {
        let n = v.len() as f64;
        let m = v.iter().sum::<f64>() / n;
        (
            m,
            (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / n).sqrt(),
        )
    }

    /// The roots land on the ellipse and the normal there is perpendicular to it: checked
    /// against the chord between the boundary points at parameter `t -+ 0.1`, which for an
    /// ellipse `(ax cos t, ay sin t)` is exactly parallel to the tangent at `t` (so the
    /// check does not reuse the gradient formula). 1e-12 is rounding of O(1) quantities;
    /// a wrong normal of this ellipse is off by O(0.1).
    #[test]
    fn ellipse_roots_lie_on_the_boundary_and_normals_are_perpendicular_to_it() {
        let (ax, ay) = (1.3, 0.6);
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(1);
        for _ in 0..1000 {
            let t = std::f64::consts::TAU * rng.random::<f64>();
            let on = |t: f64| [ax * t.cos(), ay * t.sin(), 0.0];
            let n = ellipse_normal(on(t), ax, ay);
            assert!((dot(n, n) - 1.0).abs() < 1e-12);
            let (a, b) = (on(t - 0.1), on(t + 0.1));
            let chord = normalize([b[0] - a[0], b[1] - a[1], 0.0]);
            assert!(dot(n, chord).abs() < 1e-12, "t {t}: {n:?}");
            assert!(dot(n, on(t)) > 0.0, "outward");
            // A line from inside through the boundary at that point: one root is it.
            let d = normalize([rng.random::<f64>() - 0.5, rng.random::<f64>() - 0.5, 0.3]);
            let p = add(on(t), scale(d, -0.2));
            let (t0, t1) = ellipse_roots(p, d, ax, ay).expect("a line from inside meets it");
            assert!(t0 <= t1);
            for r in [t0, t1] {
                let q = add(p, scale(d, r));
                assert!(((q[0] / ax).powi(2) + (q[1] / ay).powi(2) - 1.0).abs() < 1e-12);
            }
            assert!((t0 - 0.2).abs() < 1e-12 || (t1 - 0.2).abs() < 1e-12);
        }
    }

    /// The micro-normal is the geometric one turned toward the tip by `tilt + s_m N(0,1)`
    /// and about the axis by `s_n N(0,1)`, with both widths distinct here so a swap shows:
    /// the angles read back from 100 000 normals have those means (5 standard errors) and
    /// standard deviations (1.5 %, the std's relative standard error being 0.22 %); every
    /// normal is unit (rounding, 1e-12).
    #[test]
    fn micro_normals_carry_the_documented_tilts() {
        let (tilt, s_m, s_n) = (0.05, 0.07, 0.2);
        let f = fiber(tilt, s_m, s_n, 1.55, 1.0);
        let n0 = [0.7f64.cos(), 0.7f64.sin(), 0.0];
        let t = [-n0[1], n0[0], 0.0];
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(2);
        let (mut lon, mut azi) = (Vec::new(), Vec::new());
        for _ in 0..100_000 {
            let n = micro_normal(&f, n0, &mut rng);
            assert!((dot(n, n) - 1.0).abs() < 1e-12, "{n:?}");
            lon.push(n[2].asin());
            azi.push(dot(n, t).atan2(dot(n, n0)));
        }
        let se = 5.0 / (lon.len() as f64).sqrt();
        let (m, s) = mean_std(&lon);
        assert!((m - tilt).abs() < se * s_m, "longitudinal mean {m}");
        assert!((s / s_m - 1.0).abs() < 0.015, "longitudinal std {s}");
        let (m, s) = mean_std(&azi);
        assert!(m.abs() < se * s_n, "azimuthal mean {m}");
        assert!((s / s_n - 1.0).abs() < 0.015, "azimuthal std {s}");
    }

    /// A rough cuticle at grazing incidence draws many micro-normals whose mirror or
    /// refraction would cross the real surface; those are redrawn, so every reflection
    /// stays on the side the ray came from and every transmission crosses, from outside
    /// and from inside. With the smooth normal the reflected fraction is the pile of
    /// `l` plates over the exact Fresnel factor (5 binomial standard errors).
    #[test]
    fn cuticle_events_leave_on_the_geometric_side_with_the_layered_fresnel_weight() {
        let n0 = [1.0, 0.0, 0.0];
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(3);
        let rough = fiber(0.05, 0.3, 0.5, 1.55, 1.0);
        for (from_outside, d) in [
            (true, normalize([-0.1, 0.6, -0.4])),
            (false, normalize([0.1, -0.6, 0.4])),
        ] {
            let s = if from_outside { 1.0 } else { -1.0 };
            let mut crossed_n = 0;
            for _ in 0..50_000 {
                let (nd, crossed) = cuticle(&rough, d, n0, from_outside, &mut rng);
                assert!((dot(nd, nd) - 1.0).abs() < 1e-12);
                if crossed {
                    crossed_n += 1;
                    assert!(
                        dot(nd, n0) * s < 0.0,
                        "transmitted to the wrong side: {nd:?}"
                    );
                } else {
                    assert!(dot(nd, n0) * s > 0.0, "reflected to the wrong side: {nd:?}");
                }
            }
            // Both outcomes occur (from inside 432 of 50 000 cross), so neither side
            // check above is vacuous.
            assert!(crossed_n > 100 && crossed_n < 49_900, "{crossed_n} crossed");
        }
        let (l, n) = (2.5, 200_000);
        let smooth = fiber(0.0, 0.0, 0.0, 1.55, l);
        let d = normalize([-0.6, 0.3, -0.2]);
        let reflected = (0..n)
            .filter(|_| !cuticle(&smooth, d, n0, true, &mut rng).1)
            .count() as f64
            / n as f64;
        let p = pile_of_plates(fresnel_dielectric(-dot(d, n0), 1.55), l);
        let tol = 5.0 * (p * (1.0 - p) / n as f64).sqrt();
        assert!((reflected - p).abs() < tol, "{reflected} vs {p}");
    }

    /// The medulla boundary is a smooth interface between the cortex (`eta`) and the
    /// medulla (`eta_m`): the reflected fraction is the Fresnel factor of the ratio seen
    /// from the ray's side (5 binomial standard errors), transmission obeys Snell's law
    /// with those indices (rounding, 1e-12), and from the denser medulla beyond the
    /// critical angle every ray is reflected.
    #[test]
    fn medulla_interface_uses_the_medulla_index_on_both_sides() {
        let (eta, eta_m) = (1.55, 2.2);
        let f = fiber(0.0, 0.0, 0.0, eta_m, 1.0);
        let n0 = [0.0, 1.0, 0.0];
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(4);
        let n = 200_000;
        for (into, cos_i, ratio) in [(true, 0.3f64, eta_m / eta), (false, 0.95, eta / eta_m)] {
            let s = if into { 1.0 } else { -1.0 };
            let sin_i = (1.0 - cos_i * cos_i).sqrt();
            let d = [sin_i, -s * cos_i, 0.0];
            let mut refl = 0;
            for _ in 0..n {
                let (t, crossed) = medulla_interface(&f, d, n0, into, &mut rng);
                if crossed {
                    assert!(dot(t, n0) * s < 0.0);
                    let (n_i, n_t) = if into { (eta, eta_m) } else { (eta_m, eta) };
                    assert!((n_i * sin_i - n_t * t[0]).abs() < 1e-12, "Snell: {t:?}");
                } else {
                    refl += 1;
                    assert!((t[0] - d[0]).abs() < 1e-12 && (t[1] + d[1]).abs() < 1e-12);
                }
            }
            let (got, p) = (refl as f64 / n as f64, fresnel_dielectric(cos_i, ratio));
            let tol = 5.0 * (p * (1.0 - p) / n as f64).sqrt();
            assert!((got - p).abs() < tol, "into {into}: {got} vs {p}");
        }
        // sin 0.8 * 2.2 / 1.55 > 1: total internal reflection inside the medulla.
        let d = [0.8, 0.6, 0.0];
        for _ in 0..1000 {
            assert!(!medulla_interface(&f, d, n0, false, &mut rng).1);
        }
    }

    /// An elliptical fiber is seen at a uniformly random rotation about its axis (the
    /// tally averages over the orientations of a pelt's hairs); a circular one at 0.
    /// Chi-square of 20 equal bins of `phi_i` over 20 000 paths: 19 degrees of freedom,
    /// threshold 50 (p ~ 1e-4).
    #[test]
    fn an_ellipse_is_seen_at_uniformly_random_rotations() {
        let p =
            crate::FurParams::from_file_units([1.55, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0])
                .unwrap();
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(5);
        let circle = Fiber::new(&p, None, None, true);
        for _ in 0..1000 {
            if let Outcome::Exit(e) = trace_path(&circle, 0.3, &mut rng) {
                assert_eq!(e.phi_i, 0.0);
            }
        }
        let ellipse = Fiber::new(&p, Some(0.7), None, true);
        let mut hist = [0.0f64; 20];
        let mut n = 0.0;
        while n < 20_000.0 {
            if let Outcome::Exit(e) = trace_path(&ellipse, 0.3, &mut rng) {
                let k = (e.phi_i / std::f64::consts::TAU * 20.0) as usize;
                hist[k.min(19)] += 1.0;
                n += 1.0;
            }
        }
        let e = n / 20.0;
        let chi = hist.iter().map(|o| (o - e).powi(2) / e).sum::<f64>();
        assert!(chi < 50.0, "chi2 {chi}");
    }
}
