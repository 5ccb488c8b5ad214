#!/usr/bin/env python3
"""The picture of reports/export/: Mitsuba 3's render of `furfit export --scene` of a
species' chiang2016 fit beside `furfit render` of the same species' fur (yan2017) fit
(`furfit render` renders the fur model only), same lock, camera and key light.

Usage: render_side_by_side.py --furfit BIN --species red-fox --out reports/export/red-fox.png
(from the project folder; DRJIT_LIBLLVM_PATH set for the llvm variant).
"""

import argparse
import subprocess
import tempfile
from pathlib import Path

import numpy as np


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--furfit", required=True)
    ap.add_argument("--species", default="red-fox")
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--variant", default="llvm_ad_rgb")
    ap.add_argument("--out", required=True)
    a = ap.parse_args()
    import mitsuba as mi

    mi.set_variant(a.variant)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        xml = tmp / f"{a.species}.xml"
        subprocess.run([a.furfit, "export", "--params", f"fits/chiang2016/{a.species}.json", "--to",
                        "mitsuba", "--scene", "--out", str(xml)], check=True)
        img = mi.render(mi.load_file(str(xml), spp=a.spp))
        left = np.array(mi.Bitmap(img).convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.UInt8, True))
        ours = tmp / "furfit.png"
        subprocess.run([a.furfit, "render", "--fit", f"fits/{a.species}.json", "--spp", str(a.spp),
                        "--no-aovs", "--out", str(ours)], check=True)
        right = np.array(mi.Bitmap(str(ours)).convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.UInt8, True))
    gap = np.full((left.shape[0], 8, 3), 255, dtype=np.uint8)
    both = np.concatenate([left, gap, right[:, :, :3]], axis=1)
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    mi.Bitmap(both).write(a.out)
    print(f"wrote {a.out}: left Mitsuba {mi.__version__} (chiang2016 export), right furfit render (yan2017 fit)")


if __name__ == "__main__":
    main()
