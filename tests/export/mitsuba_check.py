#!/usr/bin/env python3
"""Mitsuba 3 evaluates furfit's exported hair materials; they must reproduce furfit's
own chiang2016 prediction (`furfit synth`) at every angle of the fit's data.

For every fit in --fits (chiang2016 fit files), this script
1. exports it with `furfit export --to mitsuba` (into a temporary folder),
2. loads the `<bsdf type="hair">` with Mitsuba 3 and evaluates it at each data sample
   (theta_i, theta_r, phi) averaged over the fiber offset h: Gauss-Legendre nodes in
   gamma = asin(h) on [-pi/2, pi/2] (dh = cos(gamma) dgamma, the average is half the
   integral), each node a turn of both directions about the fiber axis,
3. compares with `furfit synth --model chiang2016 --params FIT` on the same angles after
   the optimal exposure: the largest |ln(mitsuba) - ln(furfit) - ln k| must be at most
   --tol (default 0.5 %) of the range of ln(furfit) over the samples,
4. states the NRMSE of Mitsuba's values against the data next to the fit's own.

Mitsuba's hair frame (src/bsdfs/hair.cpp): the tangent is local y (toward the tip, so
sin(theta) = w.y), the azimuth is atan2(z, x), and h = sin(gamma(si.wi)) with
gamma(w) = +-acos(z / |(x, z)|) (sign of -x): a direction in the normal plane at
azimuth gamma + pi/2 has offset h = sin(gamma). si.wi is the camera side (the path
tracer's incoming direction, the one whose offset h is), wo the light; eval returns
sum_p M_p A_p N_p (its longitudinal pdf times 2 pi is d'Eon's M_p), the integrand in
solid angle. furfit's goniometer sample is cos(theta_i) times that sum (MODEL.md), so
Mitsuba's value is multiplied by cos(theta_i) here. furfit's phi = phi_r - phi_i is
Mitsuba's phi_i - phi_o: the light sits at azimuth (camera - phi).

Exit status 0 when every species is within --tol, 1 otherwise; --json writes the figures.
"""

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np


def read_profile(path):
    """(theta_i, theta_r, phi, value) of a furfit profile CSV (degrees); rows whose value
    is missing or not a number are dropped."""
    rows = []
    header = None
    with open(path) as f:
        for line in f:
            if line.startswith("#") or not line.strip():
                continue
            cells = line.strip().split(",")
            if header is None:
                header = cells
                continue
            rec = dict(zip(header, cells))
            try:
                v = float(rec["value"])
            except (KeyError, ValueError):
                continue
            rows.append((float(rec["theta_i"]), float(rec["theta_r"]), float(rec["phi"]), v))
    return np.array(rows, dtype=np.float64)


def grid_list(values):
    return ",".join(repr(float(v)) for v in sorted(set(values)))


def fit_samples(fit, root):
    """The samples the fit used: its data file (as recorded), valid and at least the fit's
    floor times the largest value."""
    data_path = root / fit["data"]["files"][0]["path"]
    prof = read_profile(data_path)
    v = prof[:, 3]
    ok = np.isfinite(v) & (v > 0)
    prof = prof[ok]
    floor = fit["data"].get("floor") or 0.0
    return prof[prof[:, 3] >= floor * prof[:, 3].max()], data_path


def furfit_prediction(furfit, fit_path, samples, work):
    """furfit synth of the fit on the grid spanned by the samples, read back at them."""
    out = work / (fit_path.stem + "-synth.csv")
    cmd = [
        furfit, "synth", "--model", "chiang2016", "--params", str(fit_path),
        "--theta-i", grid_list(samples[:, 0]), "--theta-r", grid_list(samples[:, 1]),
        "--phi", grid_list(samples[:, 2]), "--out", str(out), "--force",
    ]
    subprocess.run(cmd, check=True, capture_output=True)
    syn = read_profile(out)
    table = {(round(a, 9), round(b, 9), round(c, 9)): v for a, b, c, v in syn}
    return np.array([table[(round(a, 9), round(b, 9), round(c, 9))] for a, b, c, _ in samples])


def mitsuba_far_field(mi, dr, bsdf, samples, nodes, chunk=2_000_000):
    """The h-averaged, cos(theta_i)-weighted value of the BSDF at every sample."""
    x, w = np.polynomial.legendre.leggauss(nodes)
    gamma = 0.5 * math.pi * x
    # (1/2) int_{-1}^{1} f dh = (1/2) int f cos(gamma) dgamma, dgamma = (pi/2) dx.
    weight = 0.5 * (0.5 * math.pi) * w * np.cos(gamma)
    ti = np.radians(samples[:, 0])
    tr = np.radians(samples[:, 1])
    ph = np.radians(samples[:, 2])
    n, g = len(samples), len(gamma)
    total = np.zeros(n)
    per = max(1, chunk // g)
    ctx = mi.BSDFContext()
    for start in range(0, n, per):
        sl = slice(start, min(n, start + per))
        m = sl.stop - sl.start
        T_i = np.repeat(ti[sl], g)
        T_r = np.repeat(tr[sl], g)
        P = np.repeat(ph[sl], g)
        G = np.tile(gamma, m)
        phi_cam = G + 0.5 * math.pi
        phi_light = phi_cam - P
        si = dr.zeros(mi.SurfaceInteraction3f, m * g)
        si.wi = mi.Vector3f(np.cos(T_r) * np.cos(phi_cam), np.sin(T_r), np.cos(T_r) * np.sin(phi_cam))
        wo = mi.Vector3f(np.cos(T_i) * np.cos(phi_light), np.sin(T_i), np.cos(T_i) * np.sin(phi_light))
        # Color3f of width m * g: shape (3, m * g); a grey material, so the green channel.
        f = np.array(bsdf.eval(ctx, si, wo))[1]
        total[sl] = (f.reshape(m, g) * weight[None, :]).sum(axis=1)
    return total * np.cos(ti)


def compare(a, b):
    """(max, rms) of |ln a - ln b - ln k| with the optimal k, over the range of ln b."""
    la, lb = np.log(a), np.log(b)
    d = la - lb
    d -= d.mean()
    rng = lb.max() - lb.min()
    return float(np.abs(d).max() / rng), float(np.sqrt(np.mean(d * d)) / rng)


def nrmse(model, data):
    """MODEL.md's NRMSE: RMS of ln residuals at the optimal exposure over ln range of data."""
    lm, ly = np.log(model), np.log(data)
    d = lm - ly
    d -= d.mean()
    return float(np.sqrt(np.mean(d * d)) / (ly.max() - ly.min()))


def report(results, a, version):
    """reports/export.md: per species the fit's NRMSE, Mitsuba's, their difference, and
    Mitsuba against furfit."""
    worst = max(results, key=lambda r: r["max_log_error"])
    lines = [
        "# Export to the renderers: Mitsuba 3 against furfit and the data",
        "",
        "Written by `tests/export/mitsuba_check.py --report reports/export.md` (the check",
        "`cargo test --release --test export_renderers` runs). Every shipped chiang2016 fit",
        "(`fits/chiang2016/`) exported by `furfit export --to mitsuba` (as in `exports/mitsuba/`),",
        f"loaded and evaluated by Mitsuba {version} (`{a.variant}`) at every sample the fit used,",
        f"averaged over the fiber offset h ({a.nodes} Gauss-Legendre nodes in asin h), times",
        "cos(theta_i) (a goniometer sample, MODEL.md).",
        "",
        "- **Mitsuba vs furfit**: |ln(Mitsuba) - ln(furfit synth) - ln k| at the optimal exposure",
        "  k, largest and RMS over the samples, as a share of the range of ln(furfit); the",
        f"  limit is {100 * a.tol:.1f} %. Worst: {worst['species']}, {100 * worst['max_log_error']:.4f} %.",
        "- **NRMSE** (MODEL.md, optimal exposure) against the data: the fit's own (its file),",
        "  Mitsuba's evaluation of the export, and Mitsuba minus the fit.",
        "",
        "| species | samples | Mitsuba vs furfit, max | RMS | NRMSE fit | NRMSE Mitsuba | difference |",
        "|---|---:|---:|---:|---:|---:|---:|",
    ]
    for r in results:
        lines.append(
            f"| {r['species']} | {r['samples']} | {100 * r['max_log_error']:.4f} % | "
            f"{100 * r['rms_log_error']:.4f} % | {100 * r['fit_nrmse']:.4f} % | "
            f"{100 * r['mitsuba_nrmse']:.4f} % | {100 * (r['mitsuba_nrmse'] - r['fit_nrmse']):+.1e} % |"
        )
    lines += [
        "",
        "The other formats: the MaterialX documents load, validate and generate GLSL",
        "(`tests/export/materialx_check.py`; their roughness is clamped to genglsl's [0.001, 1],",
        "which every shipped fit exceeds: the documents name each clamp); the pbrt-v4 blocks",
        "parse back to the fits' values bit for bit (`tests/export_cli.rs`); the Blender",
        "scripts are not run here (the `bpy` wheel is 374 MB).",
        "",
        "Regenerate `exports/` with, for each fit and format,",
        "`furfit export --params fits/chiang2016/<species>.json --to <format> --out",
        "exports/<format>/<species>.<xml|pbrt|py|mtlx> --force`.",
        "",
    ]
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--furfit", required=True)
    ap.add_argument("--fits", required=True, help="folder of chiang2016 fit files")
    ap.add_argument("--root", default=".", help="project folder the fits' data paths start from")
    ap.add_argument("--variant", default=os.environ.get("FURFIT_MITSUBA_VARIANT", "llvm_ad_rgb"))
    ap.add_argument("--nodes", type=int, default=128, help="Gauss-Legendre nodes in gamma")
    ap.add_argument("--tol", type=float, default=0.005)
    ap.add_argument("--json", help="write the figures here")
    ap.add_argument("--report", help="write reports/export.md here")
    a = ap.parse_args()

    import drjit as dr
    import mitsuba as mi

    mi.set_variant(a.variant)
    root = Path(a.root)
    results = []
    failed = False
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        for fit_path in sorted(Path(a.fits).glob("*.json")):
            fit = json.loads(fit_path.read_text())
            species = fit.get("species", fit_path.stem)
            xml = work / f"{fit_path.stem}.xml"
            subprocess.run([a.furfit, "export", "--params", str(fit_path), "--to", "mitsuba",
                            "--out", str(xml)], check=True, capture_output=True)
            bsdf = mi.load_file(str(xml))
            samples, data_path = fit_samples(fit, root)
            ours = furfit_prediction(a.furfit, fit_path, samples, work)
            theirs = mitsuba_far_field(mi, dr, bsdf, samples, a.nodes)
            if not (np.all(np.isfinite(theirs)) and np.all(theirs > 0)):
                print(f"{species}: Mitsuba gave non-positive or non-finite values", file=sys.stderr)
                failed = True
                continue
            worst, rms = compare(theirs, ours)
            r = {
                "species": species,
                "fit": str(fit_path),
                "samples": int(len(samples)),
                "max_log_error": worst,
                "rms_log_error": rms,
                "fit_nrmse": float(fit["nrmse"]),
                "furfit_nrmse": nrmse(ours, samples[:, 3]),
                "mitsuba_nrmse": nrmse(theirs, samples[:, 3]),
            }
            ok = worst <= a.tol
            failed |= not ok
            results.append(r)
            print(
                f"{species}: Mitsuba vs furfit max {100 * worst:.4f}% rms {100 * rms:.4f}% of the log range "
                f"({len(samples)} samples, {a.variant}, {a.nodes} nodes in h); NRMSE vs data: "
                f"fit {100 * r['fit_nrmse']:.4f}%, Mitsuba {100 * r['mitsuba_nrmse']:.4f}% "
                f"{'ok' if ok else 'FAIL'}"
            )
    if a.json:
        Path(a.json).write_text(json.dumps(results, indent=2) + "\n")
    if a.report:
        Path(a.report).write_text(report(results, a, mi.__version__))
    if not results:
        print("no fit checked", file=sys.stderr)
        return 1
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
