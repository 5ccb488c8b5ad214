//! The built-in test scene: a lock of curved fibers (seeded curl and clumping), a pinhole
//! camera, a directional key light and a constant or vertical-gradient environment.
//!
//! Geometry convention: every fiber is a polyline root -> tip of short straight segments;
//! the renderer intersects them as *camera-facing ribbons* of half-width `r` centred on
//! the axis (see [`super::bvh`]). At the default 512x512 framing a fiber is about 0.9 px
//! wide, so a pixel covers the whole azimuthal section and multi-scale matters.

use super::math::V3;
use rand::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use std::f64::consts::{PI, TAU};

/// One straight piece of a fiber.
#[derive(Clone, Copy, Debug)]
pub struct Segment {
    /// Start point (root side).
    pub a: V3,
    /// End point (tip side).
    pub b: V3,
    /// Fiber radius at `a` and `b` (world units).
    pub ra: f64,
    /// Fiber radius at `b` (see `ra`).
    pub rb: f64,
    /// Index of the fiber this segment belongs to.
    pub fiber: u32,
}

/// Largest number of fibers in the lock (`render --fibers`). Building the scene (segments,
/// BVH build, shadow-ray tree) peaks at about 45 KB per fiber at 24 segments each
/// (measured: 0.55 GB at 10 000 fibers, 4.4 GB and 2.5 min at 100 000), so the cap keeps
/// the peak near 4.5 GB; `--fibers 20000000` used to abort on a failed allocation.
pub const MAX_FIBERS: usize = 100_000;

/// Parameters of the procedural lock.
#[derive(Clone, Debug)]
pub struct StrandSpec {
    /// Number of fibers in the lock.
    pub fibers: usize,
    /// Straight segments per fiber.
    pub segments_per_fiber: usize,
    /// Fiber radius at the root (world units; the lock is about 1.1 units long).
    pub radius: f64,
    /// Number of clumps the fibers gather into.
    pub clumps: usize,
    /// Seed of the lock's random layout.
    pub seed: u64,
}

impl Default for StrandSpec {
    fn default() -> Self {
        StrandSpec {
            fibers: 1500,
            segments_per_fiber: 24,
            radius: 0.0011,
            clumps: 24,
            seed: 7,
        }
    }
}

/// Build the lock: roots on an ellipse at the bottom, fibers rise along +y bending toward
/// +x, grouped into clumps whose members converge toward the clump's tip (clumping), each
/// with its own helical curl of random phase, and taper to 40 % radius at the tip.
pub fn build_lock(spec: &StrandSpec) -> Vec<Segment> {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(spec.seed);
    let n_seg = spec.segments_per_fiber.max(1);
    // Clump centres (root offsets) and clump tip shifts.
    let clumps: Vec<(f64, f64, f64, f64)> = (0..spec.clumps.max(1))
        .map(|_| {
            let a = rng.random::<f64>() * TAU;
            let rr = rng.random::<f64>().sqrt();
            (
                0.28 * rr * a.cos(),
                0.10 * rr * a.sin(),
                (rng.random::<f64>() - 0.5) * 0.08,
                (rng.random::<f64>() - 0.5) * 0.05,
            )
        })
        .collect();
    let mut segs = Vec::with_capacity(spec.fibers * n_seg);
    for f in 0..spec.fibers {
        let c = clumps[rng.random_range(0..clumps.len())];
        let a = rng.random::<f64>() * TAU;
        let rr = rng.random::<f64>().sqrt() * 0.07;
        let (ox, oz) = (rr * a.cos(), rr * a.sin() * 0.6);
        let length = 0.95 + 0.2 * rng.random::<f64>();
        let curl_amp = 0.008 + 0.012 * rng.random::<f64>();
        let curl_freq = 5.0 + 4.0 * rng.random::<f64>();
        let curl_phase = rng.random::<f64>() * TAU;
        let bend = 0.30 + 0.08 * (rng.random::<f64>() - 0.5);
        let point = |s: f64| -> V3 {
            // Clumping: the offset from the clump centre shrinks toward the tip.
            let clump_pull = 1.0 - 0.75 * s * s;
            let x0 = c.0 + ox * clump_pull + c.2 * s;
            let z0 = c.1 + oz * clump_pull + c.3 * s;
            // Overall bend toward +x and a gentle S in z.
            let y = -0.55 + length * s;
            let x = x0 + bend * s * s - 0.12;
            let z = z0 + 0.05 * (PI * s).sin();
            let ph = curl_phase + TAU * curl_freq * s;
            V3::new(x + curl_amp * s * ph.cos(), y, z + curl_amp * s * ph.sin())
        };
        let radius = |s: f64| spec.radius * (1.0 - 0.6 * s);
        for k in 0..n_seg {
            let s0 = k as f64 / n_seg as f64;
            let s1 = (k + 1) as f64 / n_seg as f64;
            segs.push(Segment {
                a: point(s0),
                b: point(s1),
                ra: radius(s0),
                rb: radius(s1),
                fiber: f as u32,
            });
        }
    }
    segs
}

/// Pinhole camera looking at `target` from spherical position (`dist`, `elev`, `azim`).
#[derive(Clone, Copy, Debug)]
pub struct Camera {
    /// Camera position.
    pub eye: V3,
    /// Unit look-at direction `omega_lookat` of seed Eq. 27.
    pub forward: V3,
    /// Unit image-plane right.
    pub right: V3,
    /// Unit image-plane up.
    pub up: V3,
    /// `tan(fov_y / 2)`.
    pub tan_half: f64,
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
}

impl Camera {
    /// `fov_y_deg` vertical field of view; `elev_deg` above the horizontal; `azim_deg` about
    /// the vertical, 0 = on +z looking toward -z.
    pub fn look_at(
        target: V3,
        dist: f64,
        elev_deg: f64,
        azim_deg: f64,
        fov_y_deg: f64,
        width: usize,
        height: usize,
    ) -> Camera {
        let (e, a) = (elev_deg.to_radians(), azim_deg.to_radians());
        let eye = target + V3::new(a.sin() * e.cos(), e.sin(), a.cos() * e.cos()) * dist;
        let forward = (target - eye).normalized();
        let right = forward.cross(V3::new(0.0, 1.0, 0.0)).normalized();
        let up = right.cross(forward);
        Camera {
            eye,
            forward,
            right,
            up,
            tan_half: (0.5 * fov_y_deg.to_radians()).tan(),
            width,
            height,
        }
    }

    /// Angle subtended by one pixel at the image centre (radians): the spread of the
    /// primary ray cone used for the pixel footprint `C_hit` (seed Eq. 27).
    pub fn pixel_angle(&self) -> f64 {
        2.0 * self.tan_half / self.height as f64
    }

    /// Unit ray direction through image position (`px`, `py`) in pixels (0,0 = top left).
    pub fn ray_dir(&self, px: f64, py: f64) -> V3 {
        let aspect = self.width as f64 / self.height as f64;
        let sx = (2.0 * px / self.width as f64 - 1.0) * self.tan_half * aspect;
        let sy = (1.0 - 2.0 * py / self.height as f64) * self.tan_half;
        (self.forward + self.right * sx + self.up * sy).normalized()
    }
}

/// Environment light: radiance `bottom` straight down blending linearly (in `y`) to
/// `top` straight up; equal values give a constant environment.
#[derive(Clone, Copy, Debug)]
pub struct Environment {
    /// Radiance straight up, r, g, b.
    pub top: [f64; 3],
    /// Radiance straight down, r, g, b.
    pub bottom: [f64; 3],
}

impl Environment {
    /// A uniform environment of radiance `v` in every channel.
    pub fn constant(v: f64) -> Environment {
        Environment {
            top: [v; 3],
            bottom: [v; 3],
        }
    }

    /// Radiance arriving from direction `d` (unit; linear in `d.y` between bottom and top).
    pub fn radiance(&self, d: V3) -> [f64; 3] {
        let t = 0.5 * (d.y + 1.0);
        [0, 1, 2].map(|c| self.bottom[c] + (self.top[c] - self.bottom[c]) * t)
    }

    /// Whether the environment adds no light (its sampling is skipped).
    pub fn is_black(&self) -> bool {
        self.top.iter().chain(self.bottom.iter()).all(|v| *v <= 0.0)
    }
}

/// Directional (delta) key light: unit direction *toward* the light and irradiance on a
/// surface facing it.
#[derive(Clone, Copy, Debug)]
pub struct DirectionalLight {
    /// Unit direction toward the light.
    pub dir: V3,
    /// Irradiance on a surface facing the light, r, g, b.
    pub irradiance: [f64; 3],
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lock_is_deterministic_and_fibers_are_thin_and_connected() {
        let spec = StrandSpec {
            fibers: 20,
            ..Default::default()
        };
        let a = build_lock(&spec);
        let b = build_lock(&spec);
        assert_eq!(a.len(), 20 * spec.segments_per_fiber);
        for (x, y) in a.iter().zip(&b) {
            assert_eq!(x.a, y.a);
        }
        // Consecutive segments of one fiber share their joint exactly (a polyline).
        for w in a.windows(2) {
            if w[0].fiber == w[1].fiber {
                assert_eq!(w[0].b, w[1].a);
                // Segments are short compared with the lock (< 0.1 units).
                assert!((w[0].b - w[0].a).length() < 0.1);
            }
        }
    }

    #[test]
    fn default_fiber_is_at_most_one_pixel_wide() {
        let cam = Camera::look_at(V3::new(0.0, 0.0, 0.0), 3.0, 10.0, 0.0, 26.0, 512, 512);
        let dist = 3.0 - 0.3; // nearest fibers
        let px = cam.pixel_angle() * dist;
        assert!(2.0 * StrandSpec::default().radius <= px, "{px}");
    }
}
