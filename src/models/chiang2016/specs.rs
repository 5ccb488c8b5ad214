//! `chiang2016`'s parameter vector: the positions and the table of names, meanings, units
//! and hard bounds. A leaf of the room, so that `far` and `bsdf` read the positions without
//! importing the model's `mod.rs`, which imports them.

use crate::params::spec;
use crate::params::ParamSpec;

/// Parameter vector positions.
pub const ETA: usize = 0;
/// Position of `beta_m`, the longitudinal roughness.
pub const BETA_M: usize = 1;
/// Position of `beta_n`, the azimuthal roughness.
pub const BETA_N: usize = 2;
/// Position of `alpha`, the cuticle tilt (radians inside).
pub const ALPHA: usize = 3;
/// Position of `sigma_a`, the absorption per unit fiber radius.
pub const SIGMA_A: usize = 4;

/// pbrt-v4's and Mitsuba 3's parameters and their ranges (`alpha` bounded as the fur
/// model's: TRT's tilt `4 alpha` is then at most 80 deg).
pub(super) static SPECS: [ParamSpec; 5] = [
    spec(
        "eta",
        "index of refraction",
        "-",
        (1.0, true, 3.0, false),
        false,
    ),
    spec(
        "beta_m",
        "longitudinal roughness",
        "-",
        (0.0, true, 1.0, false),
        false,
    ),
    spec(
        "beta_n",
        "azimuthal roughness",
        "-",
        (0.0, true, 1.0, false),
        false,
    ),
    spec(
        "alpha",
        "cuticle scale tilt",
        "deg",
        (-20.0, false, 20.0, false),
        true,
    ),
    spec(
        "sigma_a",
        "absorption",
        "1/radius",
        (0.0, false, f64::INFINITY, true),
        false,
    ),
];
