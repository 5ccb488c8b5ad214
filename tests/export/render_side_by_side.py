#!/usr/bin/env python3
"""The picture of reports/export/: Mitsuba 3's render of `furfit export --scene` of a
species' chiang2016 fit beside `furfit render` of the same fit (furfit renders it through
the model interface, near field, as Mitsuba does), same lock, camera, key light and
constant environment (the scene's), both halves from linear radiance through the same
sRGB transfer, and the two compared over the lock's pixels.

Usage: render_side_by_side.py --furfit BIN --species red-fox --out reports/export/red-fox.png
(from the project folder; DRJIT_LIBLLVM_PATH set for the llvm variant).
"""

import argparse
import re
import subprocess
import tempfile
from pathlib import Path

import numpy as np


def srgb(x):
    """Linear radiance to 8-bit sRGB, clipped to [0, 1] (Mitsuba's Bitmap conversion)."""
    x = np.clip(x, 0.0, 1.0)
    y = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    return np.round(255 * y).astype(np.uint8)


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
    fit = f"fits/chiang2016/{a.species}.json"
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        xml = tmp / f"{a.species}.xml"
        subprocess.run([a.furfit, "export", "--params", fit, "--to", "mitsuba", "--scene",
                        "--out", str(xml)], check=True)
        text = xml.read_text()
        env = float(re.search(r'<emitter type="constant">\s*<rgb name="radiance" value="([^,"]+)',
                              text).group(1))
        left = np.array(mi.render(mi.load_file(str(xml), spp=a.spp)), dtype=np.float64)[:, :, :3]
        ours = tmp / "furfit.png"
        subprocess.run([a.furfit, "render", "--fit", fit, "--mode", "near", "--env", repr(env),
                        "--spp", str(a.spp), "--no-aovs", "--out", str(ours)], check=True)
        right = np.array(mi.Bitmap(str(ours.with_suffix(".exr"))), dtype=np.float64)[:, :, :3]
    # The lock's pixels: those where either image departs from the bare environment.
    lock = (np.abs(left - env).max(axis=2) > 1e-4 * env) | (np.abs(right - env).max(axis=2) > 1e-4 * env)
    l, r = left[lock].mean(axis=1), right[lock].mean(axis=1)
    ml, mr = l.mean(), r.mean()
    rmse = np.sqrt(np.mean((l - r) ** 2))
    # Mean over 8x8 blocks of pixels, lock or not: most of the per-pixel noise averages out.
    def blocks(x):
        h, w = x.shape[0] // 8 * 8, x.shape[1] // 8 * 8
        return x[:h, :w].mean(axis=2).reshape(h // 8, 8, w // 8, 8).mean(axis=(1, 3))
    bl, br = blocks(left), blocks(right)
    bmask = blocks(lock[:, :, None].astype(np.float64)) > 0.5
    brmse = np.sqrt(np.mean((bl[bmask] - br[bmask]) ** 2))
    print(f"lock pixels {lock.sum()} of {lock.size}; environment {env}")
    print(f"mean over the lock: Mitsuba {ml:.5f}, furfit {mr:.5f}, furfit/Mitsuba - 1 = {mr / ml - 1:+.4f}")
    print(f"RMSE per pixel / Mitsuba's mean: {rmse / ml:.4f}; RMSE of 8x8-pixel block means "
          f"(blocks mostly on the lock, {bmask.sum()}) / mean: {brmse / ml:.4f}")
    gap = np.full((left.shape[0], 8, 3), 255, dtype=np.uint8)
    both = np.concatenate([srgb(left), gap, srgb(right)], axis=1)
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    mi.Bitmap(both).write(a.out)
    print(f"wrote {a.out}: left Mitsuba {mi.__version__}, right furfit render, both of {fit}")


if __name__ == "__main__":
    main()
