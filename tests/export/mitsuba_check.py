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


def furfit_prediction(furfit, fit_path, samples, work, channel=None):
    """furfit synth of the fit (its channel `channel`) on the grid spanned by the
    samples, read back at them."""
    out = work / (fit_path.stem + f"-{channel or 'all'}-synth.csv")
    cmd = [
        furfit, "synth", "--model", "chiang2016", "--params", str(fit_path),
        "--theta-i", grid_list(samples[:, 0]), "--theta-r", grid_list(samples[:, 1]),
        "--phi", grid_list(samples[:, 2]), "--out", str(out), "--force",
    ] + (["--channel", channel] if channel else [])
    subprocess.run(cmd, check=True, capture_output=True)
    syn = read_profile(out)
    table = {(round(a, 9), round(b, 9), round(c, 9)): v for a, b, c, v in syn}
    return np.array([table[(round(s[0], 9), round(s[1], 9), round(s[2], 9))] for s in samples])


def mitsuba_far_field(mi, dr, bsdf, samples, nodes, chunk=2_000_000):
    """The h-averaged, cos(theta_i)-weighted value of the BSDF at every sample, r, g, b:
    shape (3, samples)."""
    x, w = np.polynomial.legendre.leggauss(nodes)
    gamma = 0.5 * math.pi * x
    # (1/2) int_{-1}^{1} f dh = (1/2) int f cos(gamma) dgamma, dgamma = (pi/2) dx.
    weight = 0.5 * (0.5 * math.pi) * w * np.cos(gamma)
    ti = np.radians(samples[:, 0])
    tr = np.radians(samples[:, 1])
    ph = np.radians(samples[:, 2])
    n, g = len(samples), len(gamma)
    total = np.zeros((3, n))
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
        # Color3f of width m * g: shape (3, m * g).
        f = np.array(bsdf.eval(ctx, si, wo))
        total[:, sl] = (f.reshape(3, m, g) * weight[None, None, :]).sum(axis=2)
    return total * np.cos(ti)[None, :]


# The goniometer grid of the shipped profiles (degrees).
GRID = np.array(
    [(ti, tr, ph) for ti in (0, 15, 30, 45) for tr in range(-80, 81, 2) for ph in range(-176, 181, 4)],
    dtype=np.float64,
)

# Hand-made materials: sleek brown hair (pbrt-v4's defaults with eumelanin 1.3), a glossy
# tilted-the-other-way fiber, a rough pale one.
CASES = {
    "sleek-brown": dict(eta=1.55, beta_m=0.3, beta_n=0.3, alpha=2.0, sigma_a=[1.3 * 0.419, 1.3 * 0.697, 1.3 * 1.37]),
    "glossy-tilted": dict(eta=1.6, beta_m=0.15, beta_n=0.25, alpha=-3.0, sigma_a=[0.2, 0.5, 2.0]),
    "rough-pale": dict(eta=1.4, beta_m=0.6, beta_n=0.7, alpha=5.0, sigma_a=[0.05, 0.08, 0.15]),
}


def synthetic_cases(work):
    """(name, fit file) of each of CASES: a chiang2016 fit of channels r, g, b."""
    for name, p in CASES.items():
        chans = []
        for c, sig in zip("rgb", p["sigma_a"]):
            params = dict(eta=p["eta"], beta_m=p["beta_m"], beta_n=p["beta_n"], alpha=p["alpha"], sigma_a=sig)
            chans.append({"model": "chiang2016", "params": params, "exposure": 1.0, "nrmse": 0.0,
                          "data": {"channel": c}})
        top = dict(chans[1], species=name, channels=chans)
        path = work / f"{name}.json"
        path.write_text(json.dumps(top))
        yield name, path


def check_case(mi, dr, a, work, fit_path, name, samples, channels):
    """Export `fit_path`, evaluate it with Mitsuba at `samples`, compare each channel of
    `channels` (None: a grey fit, compared on green) with furfit synth. None on failure."""
    xml = work / f"{fit_path.stem}.xml"
    subprocess.run([a.furfit, "export", "--params", str(fit_path), "--to", "mitsuba",
                    "--out", str(xml), "--force"], check=True, capture_output=True)
    bsdf = mi.load_file(str(xml))
    theirs = mitsuba_far_field(mi, dr, bsdf, samples, a.nodes)
    if not (np.all(np.isfinite(theirs)) and np.all(theirs > 0)):
        print(f"{name}: Mitsuba gave non-positive or non-finite values", file=sys.stderr)
        return None
    worst, rms = 0.0, 0.0
    for c in channels:
        ours = furfit_prediction(a.furfit, fit_path, samples, work, c)
        k = {"r": 0, "g": 1, "b": 2, None: 1}[c]
        w, r = compare(theirs[k], ours)
        worst, rms = max(worst, w), max(rms, r)
    fit = json.loads(fit_path.read_text())
    params = dict(fit["params"])
    if "channels" in fit:
        params["sigma_a"] = [ch["params"]["sigma_a"] for ch in fit["channels"]]
    return {"species": name, "fit": str(fit_path), "samples": int(len(samples)), "params": params,
            "max_log_error": worst, "rms_log_error": rms, "ok": worst <= a.tol,
            "theirs": theirs[[1]]}


def scene_check(mi, a, work, fit_path):
    """`furfit export --scene` renders as it is: Mitsuba loads it and a small frame has
    finite values, the lock (darker or brighter than the background) in it."""
    xml = work / "scene" / f"{fit_path.stem}.xml"
    xml.parent.mkdir(exist_ok=True)
    subprocess.run([a.furfit, "export", "--params", str(fit_path), "--to", "mitsuba", "--scene",
                    "--out", str(xml)], check=True, capture_output=True)
    scene = mi.load_file(str(xml), spp=4, width=64, height=64)
    img = np.array(mi.render(scene))
    corner = img[:4, :4].mean()
    centre = img[24:40, 24:40].mean()
    ok = bool(np.isfinite(img).all() and img.mean() > 0 and abs(centre - corner) > 0.05 * corner)
    print(f"scene ({fit_path.stem}): Mitsuba renders the exported scene (64x64, 4 spp): background "
          f"{corner:.4f}, lock {centre:.4f} {'ok' if ok else 'FAIL'}")
    return ok


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


def report(results, extra, a, version):
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
        "Beyond the shipped fits (all very rough, `alpha` at -20 deg, `eta` near 1 or no",
        "absorption), hand-made r, g, b materials are checked the same way on the goniometer's",
        "grid (each channel against `furfit synth --channel`):",
        "",
        "| material | eta | beta_m | beta_n | alpha | sigma_a (r, g, b) | max | RMS |",
        "|---|---:|---:|---:|---:|---|---:|---:|",
    ]
    for r in extra:
        p = r["params"]
        lines.append(
            f"| {r['species']} | {p['eta']} | {p['beta_m']} | {p['beta_n']} | {p['alpha']} | "
            f"{', '.join(f'{x:.4g}' for x in p['sigma_a'])} | {100 * r['max_log_error']:.4f} % | "
            f"{100 * r['rms_log_error']:.4f} % |"
        )
    lines += [
        "",
        "The other formats: the MaterialX documents load, validate and generate GLSL",
        "(`tests/export/materialx_check.py`; their roughness is clamped to genglsl's [0.001, 1],",
        "which every shipped fit exceeds: the documents name each clamp); the pbrt-v4 blocks",
        "parse back to the fits' values bit for bit (`tests/export_cli.rs`); the Blender",
        "scripts are checked by Blender itself in an opt-in test (`bpy` 5.0.1 is a 374 MB wheel,",
        "not installed by `.ci/run`; `tests/export/blender_check.py`), run once: the script",
        "builds the Principled Hair BSDF (Chiang model, absorption coefficient) with the fit's",
        "values and Cycles renders the lock (below).",
        "",
        "## The exported scene rendered",
        "",
        "![Mitsuba 3 render of the exported red-fox scene beside furfit render](export/red-fox.png)",
        "",
        "`reports/export/red-fox.png` (`tests/export/render_side_by_side.py`): left, Mitsuba 3's",
        "render of `furfit export --params fits/chiang2016/red-fox.json --to mitsuba --scene`",
        "as written; right, `furfit render --fit fits/red-fox.json` (furfit renders the fur",
        "model only, so this is the species' yan2017 fit): the same lock, camera and key light",
        "(Mitsuba's environment is the constant mean of furfit's gradient). The Chiang material",
        "is grey, its fit being of one channel (furfit render tints a single channel",
        "eumelanin-like), and darker: fitted to the fur profile it has `eta` near 1 (no",
        "cuticle reflection) and absorbs more than the fur model's medulla scatters back.",
        "",
        "![Blender 5.0.1 Cycles render of the exported red-fox script on the same lock](export/red-fox-cycles.png)",
        "",
        "`reports/export/red-fox-cycles.png` (`tests/export/blender_check.py --size 512 --samples 64",
        "--out ...`): Cycles (Blender 5.0.1) renders `exports/cycles/red-fox.py`'s material on the",
        "same lock as a hair Curves object, same camera, a sun of the key light's direction and",
        "strength and the constant environment, Standard view transform: it matches Mitsuba's",
        "render of the same fit (left above).",
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
    results, extra = [], []
    failed = False
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        for fit_path in sorted(Path(a.fits).glob("*.json")):
            fit = json.loads(fit_path.read_text())
            samples, _ = fit_samples(fit, root)
            r = check_case(mi, dr, a, work, fit_path, fit.get("species", fit_path.stem), samples, [None])
            if r is None:
                failed = True
                continue
            r["fit_nrmse"] = float(fit["nrmse"])
            r["mitsuba_nrmse"] = nrmse(r.pop("theirs")[0], samples[:, 3])
            results.append(r)
            failed |= not r["ok"]
            print(
                f"{r['species']}: Mitsuba vs furfit max {100 * r['max_log_error']:.4f}% rms "
                f"{100 * r['rms_log_error']:.4f}% of the log range ({len(samples)} samples, {a.variant}, "
                f"{a.nodes} nodes in h); NRMSE vs data: fit {100 * r['fit_nrmse']:.4f}%, "
                f"Mitsuba {100 * r['mitsuba_nrmse']:.4f}% {'ok' if r['ok'] else 'FAIL'}"
            )
        for name, fit_path in synthetic_cases(work):
            r = check_case(mi, dr, a, work, fit_path, name, GRID, ["r", "g", "b"])
            if r is None:
                failed = True
                continue
            r.pop("theirs")
            failed |= not r["ok"]
            extra.append(r)
            print(
                f"{name} (synthetic, r g b): Mitsuba vs furfit max {100 * r['max_log_error']:.4f}% rms "
                f"{100 * r['rms_log_error']:.4f}% of the log range ({len(GRID)} angles, {a.nodes} nodes in h) "
                f"{'ok' if r['ok'] else 'FAIL'}"
            )
        if results:
            ok = scene_check(mi, a, work, Path(results[0]["fit"]))
            failed |= not ok
    if a.json:
        Path(a.json).write_text(json.dumps(results, indent=2) + "\n")
    if a.report:
        Path(a.report).write_text(report(results, extra, a, mi.__version__))
    if not results:
        print("no fit checked", file=sys.stderr)
        return 1
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
