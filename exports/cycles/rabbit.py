# written by furfit export (furfit 0.1.0 (git c55d513acf09+dirty)) for Blender Cycles
# from the chiang2016 fit fits/chiang2016/rabbit.json (NRMSE 7.207% against its data), parameters mapped exactly
# chiang2016: eta=1.0011680900759157 beta_m=0.933476192538014 beta_n=0.9606621980837299 alpha=-19.999999999999932 deg sigma_a=1.2375368634007669, 1.2375368634007669, 1.2375368634007669 per unit fiber radius (r, g, b)
# the fit's exposure 3.6258829329375697 is the goniometer's scale, not part of the material
#
# Run inside Blender (Text Editor, or `blender --python THIS_FILE`), or with the `bpy`
# module: it creates the material "furfit_rabbit" and returns it from build_material().
import math

import bpy

PARAMS = {
    "beta_m": 0.933476192538014,
    "beta_n": 0.9606621980837299,
    "eta": 1.0011680900759157,
    "alpha_deg": -19.999999999999932,
    "sigma_a": (1.2375368634007669, 1.2375368634007669, 1.2375368634007669),
}


def build_material(name="furfit_rabbit"):
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
