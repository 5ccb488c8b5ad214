//! Blender Cycles' Principled Hair BSDF, Chiang model (node
//! `source/blender/nodes/shader/nodes/node_shader_bsdf_hair_principled.cc`, closure
//! `intern/cycles/kernel/closure/bsdf_principled_hair_chiang.h`), written as a Python
//! script that builds the material with `bpy`.
//!
//! | chiang2016 | Principled Hair (Chiang, "Absorption Coefficient" parametrization) | why |
//! |---|---|---|
//! | `beta_m` | Roughness | `bsdf_hair_chiang_setup`: `v = (0.726 b + 0.812 b^2 + 3.7 b^20)^2` after clamping `b` to [0.001, 1]; TT `v/4`, TRT and TRRT+ `4v` |
//! | — | Coat = 0 | the R lobe's roughness is `(1 - Coat) * Roughness`: 0 keeps pbrt's |
//! | `beta_n` | Radial Roughness | `s = sqrt(pi/8) (0.265 b + 1.194 b^2 + 5.372 b^22)`, `b` clamped to [0.001, 1] |
//! | `eta` | IOR | the socket's range is [0, 1000] |
//! | `alpha` (deg) | Offset (radians in Python; the UI shows degrees) | the setup negates it (`bsdf->alpha = -bsdf->alpha`, Blender 4.x and later), so a positive Offset tilts as pbrt's positive `alpha`; the socket's range is [-90, 90] deg |
//! | `sigma_a` | Absorption Coefficient (r, g, b) | `T = exp(-sigma * 2 cos(gamma_t) / cos(theta_t))`: per unit radius; the socket's range is [0, 1000] |
//! | — | Random Color = Random Roughness = 0 | no per-strand variation |
//!
//! One difference no parameter can remove: Cycles tilts the *light's* inclination
//! (`hair_alpha_angles` on `local_I`) where pbrt tilts the camera's, so with a tilt the
//! lobes peak where pbrt's do but their longitudinal shape differs slightly.

use super::material::{clamp_named, identifier, Material, Written, MARKER};
use crate::error::{Num, Result};

/// The Python script of `m`.
pub fn write(m: &Material) -> Result<Written> {
    let mut notes = Vec::new();
    let t = "Blender's Principled Hair BSDF";
    let beta_m = clamp_named(m.beta_m, 0.001, 1.0, "beta_m (Roughness)", t, &mut notes);
    let beta_n = clamp_named(
        m.beta_n,
        0.001,
        1.0,
        "beta_n (Radial Roughness)",
        t,
        &mut notes,
    );
    let eta = clamp_named(m.eta, 0.0, 1000.0, "eta (IOR)", t, &mut notes);
    let alpha = clamp_named(
        m.alpha_deg,
        -90.0,
        90.0,
        "alpha (Offset, deg)",
        t,
        &mut notes,
    );
    let sigma = m.sigma_a.map(|s| {
        clamp_named(
            s,
            0.0,
            1000.0,
            "sigma_a (Absorption Coefficient)",
            t,
            &mut notes,
        )
    });
    let name = identifier(&format!("furfit_{}", m.name));
    let mut s = format!("# {MARKER} ({}) for Blender Cycles\n", crate::TOOL_VERSION);
    for line in m.header(&notes) {
        s.push_str(&format!("# {line}\n"));
    }
    s.push_str(&format!(
        r#"#
# Run inside Blender (Text Editor, or `blender --python THIS_FILE`), or with the `bpy`
# module: it creates the material "{name}" and returns it from build_material().
import math

import bpy

PARAMS = {{
    "beta_m": {beta_m},
    "beta_n": {beta_n},
    "eta": {eta},
    "alpha_deg": {alpha},
    "sigma_a": ({s0}, {s1}, {s2}),
}}


def build_material(name="{name}"):
    """The Principled Hair BSDF (Chiang model, absorption coefficient) of the fit."""
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nodes = mat.node_tree.nodes
    for node in list(nodes):
        nodes.remove(node)
    out = nodes.new("ShaderNodeOutputMaterial")
    hair = nodes.new("ShaderNodeBsdfHairPrincipled")
    if hasattr(hair, "model"):
        hair.model = "CHIANG"
    hair.parametrization = "ABSORPTION"
    inputs = hair.inputs
    inputs["Absorption Coefficient"].default_value = PARAMS["sigma_a"]
    inputs["Roughness"].default_value = PARAMS["beta_m"]
    inputs["Radial Roughness"].default_value = PARAMS["beta_n"]
    inputs["Coat"].default_value = 0.0
    inputs["IOR"].default_value = PARAMS["eta"]
    inputs["Offset"].default_value = math.radians(PARAMS["alpha_deg"])
    # No per-strand variation (Random Color only exists for the melanin parametrization).
    for socket in ("Random Color", "Random Roughness"):
        if inputs.get(socket) is not None:
            inputs[socket].default_value = 0.0
    mat.node_tree.links.new(hair.outputs["BSDF"], out.inputs["Surface"])
    return mat


if __name__ == "__main__":
    build_material()
"#,
        beta_m = Num(beta_m),
        beta_n = Num(beta_n),
        eta = Num(eta),
        alpha = Num(alpha),
        s0 = Num(sigma[0]),
        s1 = Num(sigma[1]),
        s2 = Num(sigma[2]),
    ));
    Ok(Written { text: s, notes })
}
