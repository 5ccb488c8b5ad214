#!/usr/bin/env python3
"""Opt-in check of `furfit export --to cycles` with Blender itself (the `bpy` module,
a 374 MB wheel: `python3.11 -m venv target/bpy-venv && target/bpy-venv/bin/pip install
bpy==5.0.1 numpy`).

For one species it runs the exported script in Blender, checks that the material holds a
Principled Hair BSDF in the Chiang model with the absorption parametrization and the
fit's values (Offset in radians), then renders one small Cycles frame of the preview's
lock (the curves of `furfit export --to mitsuba --scene`, as a Blender hair Curves
object) under the scene's sun and environment, and writes it (--out).

Exit status 0 when the material is right and the frame has the lock in it.
"""

import argparse
import json
import math
import runpy
import subprocess
import sys
import tempfile
from pathlib import Path


def read_curves(path):
    fibers, cur = [], []
    for line in Path(path).read_text().splitlines():
        if not line.strip():
            if cur:
                fibers.append(cur)
            cur = []
            continue
        cur.append([float(x) for x in line.split()])
    if cur:
        fibers.append(cur)
    return fibers


def check_material(mat, params):
    """What is wrong with the built material (empty: nothing)."""
    problems = []
    hair = [n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfHairPrincipled"]
    if len(hair) != 1:
        return [f"{len(hair)} Principled Hair BSDF nodes"]
    h = hair[0]
    if getattr(h, "model", "CHIANG") != "CHIANG":
        problems.append(f"model {h.model}")
    if h.parametrization != "ABSORPTION":
        problems.append(f"parametrization {h.parametrization}")
    want = {
        "Roughness": params["beta_m"],
        "Radial Roughness": params["beta_n"],
        "IOR": params["eta"],
        "Offset": math.radians(params["alpha"]),
        "Coat": 0.0,
    }
    for name, w in want.items():
        v = h.inputs[name].default_value
        # Blender stores sockets in single precision.
        if abs(v - w) > 1e-6 * max(1.0, abs(w)):
            problems.append(f"{name} = {v}, expected {w}")
    absorb = list(h.inputs["Absorption Coefficient"].default_value)
    if any(abs(a - params["sigma_a"]) > 1e-6 * max(1.0, params["sigma_a"]) for a in absorb):
        problems.append(f"Absorption Coefficient = {absorb}, expected {params['sigma_a']}")
    out = [n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial"]
    if not out or not out[0].inputs["Surface"].is_linked:
        problems.append("the hair BSDF does not reach the material output")
    return problems


def render(bpy, mat, fibers, out, size, samples):
    scene = bpy.context.scene
    hc = bpy.data.hair_curves.new("lock")
    hc.add_curves([len(f) for f in fibers])
    flat = [c for f in fibers for p in f for c in p[:3]]
    hc.position_data.foreach_set("vector", flat)
    radius = hc.attributes.get("radius") or hc.attributes.new("radius", "FLOAT", "POINT")
    radius.data.foreach_set("value", [p[3] for f in fibers for p in f])
    hc.materials.append(mat)
    obj = bpy.data.objects.new("lock", hc)
    # Blender is z-up; the lock (and the scene files) are y-up.
    obj.rotation_euler = (math.pi / 2, 0.0, 0.0)
    scene.collection.objects.link(obj)
    cam_data = bpy.data.cameras.new("cam")
    cam_data.sensor_fit = "VERTICAL"
    cam_data.angle = math.radians(26.0)
    cam = bpy.data.objects.new("cam", cam_data)
    e = math.radians(10.0)
    cam.location = (0.0, -3.0 * math.cos(e), 3.0 * math.sin(e))
    cam.rotation_euler = (math.pi / 2 - e, 0.0, 0.0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    sun_data = bpy.data.lights.new("sun", "SUN")
    sun_data.energy = 2.5
    sun = bpy.data.objects.new("sun", sun_data)
    # The key light's direction (-0.5, 0.6, 0.62) (toward the light, y-up) in z-up.
    d = (-0.5, -0.62, 0.6)
    sun.rotation_euler = (math.acos(d[2] / math.sqrt(sum(x * x for x in d))), 0.0, math.atan2(d[1], d[0]) + math.pi / 2)
    scene.collection.objects.link(sun)
    world = bpy.data.worlds.new("env")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.2233, 0.2233, 0.2233, 1.0)
    scene.world = world
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = samples
    scene.render.resolution_x = size
    scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    # Plain sRGB, as Mitsuba's PNG (Blender's default view transform compresses highlights).
    scene.view_settings.view_transform = "Standard"
    scene.render.filepath = str(out)
    scene.render.image_settings.file_format = "PNG"
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(str(out))
    px = list(img.pixels)
    lum = [px[i] for i in range(0, len(px), 4)]
    w = size
    corner = sum(lum[r * w + c] for r in range(4) for c in range(4)) / 16
    mid = sum(lum[r * w + c] for r in range(w // 2 - 8, w // 2 + 8) for c in range(w // 2 - 8, w // 2 + 8)) / 256
    return corner, mid


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--furfit", required=True)
    ap.add_argument("--species", default="red-fox")
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--samples", type=int, default=16)
    ap.add_argument("--out", help="the rendered PNG (default: a temporary file)")
    a = ap.parse_args()
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    fit = Path(f"fits/chiang2016/{a.species}.json")
    params = json.loads(fit.read_text())["params"]
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        script = tmp / f"{a.species}.py"
        subprocess.run([a.furfit, "export", "--params", str(fit), "--to", "cycles", "--out", str(script)],
                       check=True, capture_output=True)
        mat = runpy.run_path(str(script))["build_material"]()
        problems = check_material(mat, params)
        print(f"{a.species}: Blender {bpy.app.version_string}: the exported script builds "
              + ("the Principled Hair BSDF (Chiang, absorption) with the fit's values" if not problems
                 else "a wrong material: " + "; ".join(problems)))
        xml = tmp / "scene.xml"
        subprocess.run([a.furfit, "export", "--params", str(fit), "--to", "mitsuba", "--scene", "--out", str(xml)],
                       check=True, capture_output=True)
        out = Path(a.out) if a.out else tmp / "frame.png"
        out.parent.mkdir(parents=True, exist_ok=True)
        corner, mid = render(bpy, mat, read_curves(tmp / "scene.curves.txt"), out.resolve(), a.size, a.samples)
    ok_frame = abs(mid - corner) > 0.05 * max(corner, 1e-6)
    print(f"{a.species}: Cycles rendered {a.size}x{a.size} at {a.samples} spp: background {corner:.4f}, "
          f"lock {mid:.4f} {'ok' if ok_frame else 'FAIL (no lock in the frame)'}"
          + (f"; wrote {a.out}" if a.out else ""))
    return 0 if not problems and ok_frame else 1


if __name__ == "__main__":
    sys.exit(main())
