#!/usr/bin/env python3
"""MaterialX (the `materialx` package) reads furfit's exported .mtlx documents: each
loads, validates against the standard libraries, binds its `chiang_hair_bsdf` to the
nodedef ND_chiang_hair_bsdf, holds the values the fit maps to (recomputed here from the
fit's parameters by the formulas of MaterialX's genglsl mx_chiang_hair_roughness and
mx_chiang_hair_bsdf, clamped to their [0.001, 1]) and generates GLSL for its material.

Exit status 0 when every fit in --fits passes, 1 otherwise.
"""

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path


def expected(params):
    """The inputs furfit's mapping gives (see src/export/materialx.rs)."""
    bm, bn = params["beta_m"], params["beta_n"]
    v = (0.726 * bm + 0.812 * bm**2 + 3.7 * bm**20) ** 2
    s = 0.265 * bn + 1.194 * bn**2 + 5.372 * bn**22
    clamp = lambda x: min(max(x, 0.001), 1.0)
    sig = params["sigma_a"]
    return {
        "ior": [params["eta"]],
        "roughness_R": [clamp(v), clamp(s)],
        "roughness_TT": [clamp(v / 4), clamp(s)],
        "roughness_TRT": [clamp(4 * v), clamp(s)],
        "cuticle_angle": [0.5 - params["alpha"] / 180.0],
        "absorption_coefficient": [sig, sig, sig],
    }


def values(inp):
    v = inp.getValue()
    if isinstance(v, float):
        return [v]
    return [float(x) for x in v]


def check(mx, gen_glsl, gen_shader, lib, path, params):
    """A list of what is wrong with the document at `path` (empty: it passes)."""
    problems = []
    doc = mx.createDocument()
    mx.readFromXmlFile(doc, str(path))
    doc.importLibrary(lib)
    ok, msg = doc.validate()
    if not ok:
        problems.append(f"does not validate: {msg}")
    nodes = [n for n in doc.getNodes() if n.getCategory() == "chiang_hair_bsdf"]
    if len(nodes) != 1:
        return problems + [f"{len(nodes)} chiang_hair_bsdf nodes"]
    node = nodes[0]
    nd = node.getNodeDef()
    if nd is None or nd.getName() != "ND_chiang_hair_bsdf":
        problems.append(f"binds to {nd.getName() if nd else None}, not ND_chiang_hair_bsdf")
    for name, want in expected(params).items():
        inp = node.getInput(name)
        if inp is None:
            problems.append(f"no input {name}")
            continue
        have = values(inp)
        # MaterialX holds floats in single precision: 1e-6 relative.
        if len(have) != len(want) or any(abs(h - w) > 1e-6 * max(1.0, abs(w)) for h, w in zip(have, want)):
            problems.append(f"{name} = {have}, expected {want}")
    mats = [n for n in doc.getNodes() if n.getType() == "material"]
    if len(mats) != 1:
        return problems + [f"{len(mats)} materials"]
    gen = gen_glsl.GlslShaderGenerator.create()
    ctx = gen_shader.GenContext(gen)
    ctx.registerSourceCodeSearchPath(mx.getDefaultDataSearchPath())
    shader = gen.generate(mats[0].getName(), mats[0], ctx)
    if "mx_chiang_hair_bsdf(" not in shader.getSourceCode(gen_shader.PIXEL_STAGE):
        problems.append("the generated GLSL does not call mx_chiang_hair_bsdf")
    return problems


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--furfit", required=True)
    ap.add_argument("--fits", required=True, help="folder of chiang2016 fit files")
    a = ap.parse_args()
    import MaterialX as mx
    import MaterialX.PyMaterialXGenGlsl as gen_glsl
    import MaterialX.PyMaterialXGenShader as gen_shader

    lib = mx.createDocument()
    mx.loadLibraries(mx.getDefaultDataLibraryFolders(), mx.getDefaultDataSearchPath(), lib)
    failed, n = False, 0
    with tempfile.TemporaryDirectory() as tmp:
        for fit_path in sorted(Path(a.fits).glob("*.json")):
            fit = json.loads(fit_path.read_text())
            out = Path(tmp) / f"{fit_path.stem}.mtlx"
            subprocess.run([a.furfit, "export", "--params", str(fit_path), "--to", "materialx",
                            "--out", str(out)], check=True, capture_output=True)
            problems = check(mx, gen_glsl, gen_shader, lib, out, fit["params"])
            n += 1
            failed |= bool(problems)
            print(f"{fit_path.stem}: MaterialX {mx.getVersionString()}: "
                  + ("loads, validates, values match, GLSL generated" if not problems else "; ".join(problems)))
    if n == 0:
        print("no fit checked", file=sys.stderr)
        return 1
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
