# written by furfit export (furfit 0.1.0 (git c55d513acf09+dirty)) for Blender Cycles
# from the chiang2016 fit fits/chiang2016/cat.json (NRMSE 3.639% against its data), parameters mapped exactly
# chiang2016: eta=1.0000366344400822 beta_m=0.9778999394335682 beta_n=0.9536349756337885 alpha=-19.99999971129937 deg sigma_a=1.655418193842354, 1.655418193842354, 1.655418193842354 per unit fiber radius (r, g, b)
# the fit's exposure 9.122598827367097 is the goniometer's scale, not part of the material
#
# Run inside Blender (Text Editor, or `blender --python THIS_FILE`), or with the `bpy`
# module: it creates the material "furfit_cat" and returns it from build_material().
import math

import bpy

PARAMS = {
    "beta_m": 0.9778999394335682,
    "beta_n": 0.9536349756337885,
    "eta": 1.0000366344400822,
    "alpha_deg": -19.99999971129937,
    "sigma_a": (1.655418193842354, 1.655418193842354, 1.655418193842354),
}


def build_material(name="furfit_cat"):
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
