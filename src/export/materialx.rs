//! MaterialX 1.39's `chiang_hair_bsdf` (`libraries/pbrlib/pbrlib_defs.mtlx`
//! `ND_chiang_hair_bsdf`; reference implementation `pbrlib/genglsl/mx_chiang_hair_bsdf.glsl`),
//! written as a `.mtlx` document: the BSDF, a `surface` shader and a `surfacematerial`.
//!
//! MaterialX takes each lobe's roughness already mapped, as `(v, s)`: the longitudinal
//! variance and the azimuthal logistic scale before pbrt's `sqrt(pi/8)` (genglsl's
//! `mx_chiang_hair_roughness` computes them from `beta`, and its trimmed logistic
//! multiplies `s` by `0.626657`):
//!
//! | chiang2016 | MaterialX | why |
//! |---|---|---|
//! | `beta_m` | `roughness_R.x = v`, `roughness_TT.x = v/4`, `roughness_TRT.x = 4v` (also TRRT+), `v = (0.726 b + 0.812 b^2 + 3.7 b^20)^2` | pbrt-v4's `v[p]`; `mx_chiang_hair_roughness` with its default `scale_TT` 0.5, `scale_TRT` 2 gives the same |
//! | `beta_n` | `roughness_*.y = 0.265 b + 1.194 b^2 + 5.372 b^22` | one scale for all lobes, as pbrt |
//! | `eta` | `ior` | |
//! | `alpha` (deg) | `cuticle_angle = 0.5 - alpha / 180` (`alpha_mx = cuticle_angle * pi - pi/2`) | `mx_hair_alpha_angles` tilts the light's inclination by `(2 - 3p) alpha_mx`, R by `+2 alpha_mx`, which puts the lobes where pbrt's tilt of the camera by `-2 alpha` does for `alpha_mx = -alpha` |
//! | `sigma_a` | `absorption_coefficient` | `T = exp(-absorption * 2 cos(gamma_t) / cos(theta_t))`: per unit radius |
//!
//! genglsl clamps every `(v, s)` to [0.001, 1], so rougher fibers than `v = 1` (a
//! `beta_m` above about 0.62 for R, 0.42 for TRT) or `s = 1` (`beta_n` above about 0.62)
//! cannot be represented: they are written clamped, and the file says so. (The
//! specification's text calls `cuticle_angle` above 0.5 a tilt toward the root; the
//! reference implementation's formula, which renders, decides the sign here.)

use super::material::{clamp_named, comment_safe, identifier, Material, Written, MARKER};
use crate::error::{Num, Result};
use crate::models::chiang2016::lobes;

/// genglsl's clamp of every roughness component.
pub const ROUGHNESS_RANGE: (f64, f64) = (0.001, 1.0);

/// `(v, s)` per lobe R, TT, TRT of `m`, unclamped (MaterialX's units).
pub fn lobe_roughness(m: &Material) -> [(f64, f64); 3] {
    let v = lobes::variances(m.beta_m);
    let s = lobes::logistic_scale(m.beta_n) / (std::f64::consts::PI / 8.0).sqrt();
    [(v[0], s), (v[1], s), (v[2], s)]
}

/// `cuticle_angle` of `alpha` degrees (see the module doc).
pub fn cuticle_angle(alpha_deg: f64) -> f64 {
    0.5 - alpha_deg / 180.0
}

/// The `.mtlx` document of `m`.
pub fn write(m: &Material) -> Result<Written> {
    let mut notes = Vec::new();
    let t = "MaterialX's chiang_hair_bsdf (genglsl clamp)";
    let (lo, hi) = ROUGHNESS_RANGE;
    let rough: Vec<(f64, f64)> = lobe_roughness(m)
        .iter()
        .zip(["R", "TT", "TRT"])
        .map(|(&(v, s), lobe)| {
            (
                clamp_named(
                    v,
                    lo,
                    hi,
                    &format!("roughness_{lobe} variance v"),
                    t,
                    &mut notes,
                ),
                clamp_named(
                    s,
                    lo,
                    hi,
                    &format!("roughness_{lobe} scale s"),
                    t,
                    &mut notes,
                ),
            )
        })
        .collect();
    let id = identifier(&format!("furfit_{}", m.name));
    let mut s = String::from("<?xml version=\"1.0\"?>\n");
    s.push_str(&format!(
        "<!-- {MARKER} ({}) for MaterialX 1.39 -->\n",
        crate::TOOL_VERSION
    ));
    for line in m.header(&notes) {
        s.push_str(&format!("<!-- {} -->\n", comment_safe(&line)));
    }
    s.push_str("<materialx version=\"1.39\">\n");
    s.push_str(&format!(
        "  <chiang_hair_bsdf name=\"{id}_bsdf\" type=\"BSDF\">\n"
    ));
    let input = |name: &str, ty: &str, value: String| {
        format!("    <input name=\"{name}\" type=\"{ty}\" value=\"{value}\" />\n")
    };
    s.push_str(&input("ior", "float", Num(m.eta).to_string()));
    for ((v, sc), lobe) in rough.iter().zip(["R", "TT", "TRT"]) {
        s.push_str(&input(
            &format!("roughness_{lobe}"),
            "vector2",
            format!("{}, {}", Num(*v), Num(*sc)),
        ));
    }
    s.push_str(&input(
        "cuticle_angle",
        "float",
        Num(cuticle_angle(m.alpha_deg)).to_string(),
    ));
    s.push_str(&input(
        "absorption_coefficient",
        "vector3",
        m.sigma_a.map(|v| Num(v).to_string()).join(", "),
    ));
    s.push_str("  </chiang_hair_bsdf>\n");
    s.push_str(&format!(
        "  <surface name=\"{id}_surface\" type=\"surfaceshader\">\n    <input name=\"bsdf\" type=\"BSDF\" nodename=\"{id}_bsdf\" />\n  </surface>\n"
    ));
    s.push_str(&format!(
        "  <surfacematerial name=\"{id}\" type=\"material\">\n    <input name=\"surfaceshader\" type=\"surfaceshader\" nodename=\"{id}_surface\" />\n  </surfacematerial>\n"
    ));
    s.push_str("</materialx>\n");
    Ok(Written { text: s, notes })
}
