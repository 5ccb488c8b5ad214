//! The environment lights of the viewer, each exactly of SH order <= 4 (so PRT lights
//! them without truncation and the path-traced reference sees the very same function):
//!
//! * `lobe`: `L(w) = k ((1 + w . d) / 2)^4`, a smooth directional-like lobe (half maximum
//!   65 degrees from `d`), of total irradiance `E = 4 pi k / 5` (`∫ L dw`);
//! * `sky`: `render`'s vertical gradient (`bottom` straight down to `top` straight up,
//!   linear in `y`: SH order 1).
//!
//! A light is defined about `+y` and turned so `+y` goes to (elevation, azimuth), the
//! camera's convention (`azimuth 0` = toward `+z`).

use super::prt::Rgb25;
use super::sh::{self, Mat3, Rule};
use std::f64::consts::PI;

/// What a light is: both kinds are exactly of SH order <= 4 (module doc).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Kind {
    /// RGB total irradiance of the lobe.
    Lobe([f64; 3]),
    /// `render`'s vertical gradient, linear in `y` (SH order 1).
    Sky {
        /// Radiance straight up, r, g, b.
        top: [f64; 3],
        /// Radiance straight down, r, g, b.
        bottom: [f64; 3],
    },
}

/// One environment light of the viewer, with the direction it starts at.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Light {
    /// The `--light` name.
    pub name: &'static str,
    /// The page's label for it.
    pub label: &'static str,
    /// Its radiance (defined about `+y`).
    pub kind: Kind,
    /// Elevation (degrees) the light starts at: the sky stays upright by default.
    pub default_elev: f64,
    /// Azimuth (degrees) the light starts at.
    pub default_azim: f64,
}

/// The lights, the page's order.
pub const LIGHTS: [Light; 2] = [
    Light {
        name: "lobe",
        label: "key lobe (order-4, 65 deg half max)",
        kind: Kind::Lobe([6.0, 5.6, 5.1]),
        default_elev: 55.0,
        default_azim: -40.0,
    },
    Light {
        name: "sky",
        label: "sky gradient",
        kind: Kind::Sky {
            top: [0.55, 0.62, 0.75],
            bottom: [0.12, 0.10, 0.08],
        },
        default_elev: 90.0,
        default_azim: 0.0,
    },
];

/// A light by name.
pub fn by_name(name: &str) -> crate::Result<Light> {
    LIGHTS
        .iter()
        .copied()
        .find(|l| l.name.eq_ignore_ascii_case(name.trim()))
        .ok_or_else(|| {
            let names: Vec<&str> = LIGHTS.iter().map(|l| l.name).collect();
            crate::Error::Invalid(format!(
                "unknown light '{name}' (expected one of: {})",
                names.join(", ")
            ))
        })
}

impl Light {
    /// Radiance toward direction `w` (light about `+y`).
    pub fn radiance_canonical(&self, w: [f64; 3]) -> [f64; 3] {
        match self.kind {
            Kind::Lobe(e) => {
                let f = ((1.0 + w[1]) / 2.0).powi(4) * 5.0 / (4.0 * PI);
                e.map(|v| v * f)
            }
            Kind::Sky { top, bottom } => {
                let t = 0.5 * (w[1] + 1.0);
                [0, 1, 2].map(|c| bottom[c] + (top[c] - bottom[c]) * t)
            }
        }
    }

    /// SH coefficients about `+y` (exact: the rule integrates degree 8 exactly).
    pub fn canonical(&self) -> Rgb25 {
        let rule = Rule::product(8, 17);
        std::array::from_fn(|c| sh::project(&rule, |w| self.radiance_canonical(w)[c]))
    }

    /// SH coefficients turned to (elevation, azimuth) in degrees.
    pub fn coeffs(&self, elev_deg: f64, azim_deg: f64) -> Rgb25 {
        let r = orientation(elev_deg, azim_deg);
        self.canonical().map(|c| sh::rotate(&c, &r))
    }
}

/// The rotation taking `+y` to the direction at (elevation, azimuth):
/// `R_y(azim) R_x(90 - elev)`.
pub fn orientation(elev_deg: f64, azim_deg: f64) -> Mat3 {
    let (se, ce) = (90.0 - elev_deg).to_radians().sin_cos();
    let (sa, ca) = azim_deg.to_radians().sin_cos();
    let rx = [[1.0, 0.0, 0.0], [0.0, ce, -se], [0.0, se, ce]];
    let ry = [[ca, 0.0, sa], [0.0, 1.0, 0.0], [-sa, 0.0, ca]];
    let mut m = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            m[i][j] = (0..3).map(|k| ry[i][k] * rx[k][j]).sum();
        }
    }
    m
}

/// Unit direction at (elevation, azimuth), degrees.
pub fn direction(elev_deg: f64, azim_deg: f64) -> [f64; 3] {
    let (e, a) = (elev_deg.to_radians(), azim_deg.to_radians());
    [a.sin() * e.cos(), e.sin(), a.cos() * e.cos()]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The lobe's total irradiance is E (exact rule: rounding, 1e-9), its SH expansion
    /// reproduces it exactly (order 4), and turning it puts the peak at the direction.
    #[test]
    fn lights_are_exact_in_sh_and_turn_as_told() {
        let l = LIGHTS[0];
        let c = l.coeffs(30.0, 70.0);
        let Kind::Lobe(e) = l.kind else {
            unreachable!()
        };
        assert!((c[0][0] * (4.0 * PI).sqrt() - e[0]).abs() < 1e-9);
        let d = direction(30.0, 70.0);
        let peak = sh::reconstruct(&c[0], d);
        let want = e[0] * 5.0 / (4.0 * PI);
        assert!((peak - want).abs() < 1e-9, "{peak} vs {want}");
        let r = orientation(30.0, 70.0);
        for w in Rule::product(4, 7).dirs {
            let got = sh::reconstruct(&c[1], sh::mat_vec(&r, w));
            assert!((got - l.radiance_canonical(w)[1]).abs() < 1e-9);
        }
        let sky = LIGHTS[1].canonical();
        assert!((sh::reconstruct(&sky[2], [0.0, 1.0, 0.0]) - 0.75).abs() < 1e-9);
    }
}
