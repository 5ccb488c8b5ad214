"""Side-by-side fit speed: `furfit fit` (blind, default options) against scipy_fit.py (a
numpy far field + least_squares from a manual start) on the same kappa = 0 profiles, in one
run, interleaved, several repeats. Writes reports/fit_speed.md and .csv.

Run through bench/fit_speed/run.sh, which sets up the virtual environment.
"""

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
HERE = Path(__file__).resolve().parent
FURFIT = ROOT / "target" / "release" / "furfit"

# kappa = 0 hair (the medulla's parameters are then inert), in MODEL.md's keys.
HAIR = {"kappa": 0.0, "sigma_m_s": 1.0, "sigma_m_a": 0.1, "g": 0.3}
PROFILES = {
    # name: (parameters, theta_i, theta_r, phi): 9-10k grid points, 3-7k above furfit's floor.
    "hair-a": ({"eta": 1.55, "alpha": 2.5, "beta_m": 6.0, "beta_n": 8.0, "sigma_c_a": 0.4, "l": 1.5},
               "0:60:15", "-75:75:3", "-175:175:10"),
    "hair-b": ({"eta": 1.55, "alpha": 3.0, "beta_m": 4.0, "beta_n": 5.0, "sigma_c_a": 0.1, "l": 1.2},
               "0:45:15", "-75:75:2", "-175:175:10"),
    "hair-c": ({"eta": 1.5, "alpha": 2.0, "beta_m": 8.0, "beta_n": 12.0, "sigma_c_a": 2.0, "l": 2.0},
               "0:75:15", "-80:80:4", "-171:180:9"),
}
NOISE = 0.02


def make_profiles(work):
    """Each profile: furfit synth of the parameters, times 2 % log-normal noise (seed 1)."""
    rng = np.random.default_rng(1)
    out = {}
    for name, (p, ti, tr, ph) in PROFILES.items():
        params = work / f"{name}.params.json"
        params.write_text(json.dumps({**HAIR, **p}))
        clean = work / f"{name}.clean.csv"
        subprocess.run([FURFIT, "synth", "--params", params, "--theta-i", ti, "--theta-r", tr,
                        "--phi", ph, "--out", clean, "--force"], check=True, capture_output=True)
        lines = clean.read_text().splitlines()
        head = [l for l in lines if l.startswith("#")]
        rows = [l for l in lines if not l.startswith("#")]
        cols = rows[0].split(",")
        vi = cols.index("value")
        body = []
        for r in rows[1:]:
            c = r.split(",")
            v = float(c[vi])
            c[vi] = repr(v * float(np.exp(NOISE * rng.standard_normal()))) if v > 0 else c[vi]
            body.append(",".join(c))
        noisy = work / name / "profile.csv"
        noisy.parent.mkdir(exist_ok=True)
        noisy.write_text("\n".join(["# synthetic: true", f"# source: bench/fit_speed/run.py, 2% log-normal noise on furfit synth of {params.name}"]
                                   + [rows[0]] + body) + "\n")
        out[name] = noisy
    return out


def run_furfit(profile, work):
    out = work / f"{profile.parent.name}.fit.json"
    t0 = time.perf_counter()
    subprocess.run([FURFIT, "fit", profile, "--out", out, "--force"], check=True, capture_output=True)
    wall = time.perf_counter() - t0
    d = json.loads(out.read_text())
    return wall, d["nrmse"], d["solver"]["evaluations"]


def run_scipy(profile, nodes):
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, HERE / "scipy_fit.py", profile, "--nodes", str(nodes)],
                       check=True, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    d = json.loads(r.stdout)
    return wall, d["nrmse"], d["evaluations"]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--nodes", type=int, default=96)
    args = ap.parse_args()
    work = ROOT / "target" / "fit_speed"
    work.mkdir(parents=True, exist_ok=True)
    profiles = make_profiles(work)
    args.load_start = os.getloadavg()
    rows = []
    for rep in range(args.repeats):
        for name, prof in profiles.items():
            # Interleaved: each pair runs back to back, the order alternating by repeat.
            order = ["furfit", "scipy"] if rep % 2 == 0 else ["scipy", "furfit"]
            for tool in order:
                if tool == "furfit":
                    wall, nrmse, ev = run_furfit(prof, work)
                else:
                    wall, nrmse, ev = run_scipy(prof, args.nodes)
                rows.append((name, rep, tool, wall, nrmse, ev))
                print(f"{name} rep {rep} {tool}: {wall:.2f} s, NRMSE {100 * nrmse:.3f}%, {ev} evaluations",
                      flush=True)
    args.load_end = os.getloadavg()
    write_report(rows, profiles, args)


def write_report(rows, profiles, args):
    samples = {}
    for n, p in profiles.items():
        body = [l for l in p.read_text().splitlines() if not l.startswith("#")]
        vi = body[0].split(",").index("value")
        vals = [float(l.split(",")[vi]) for l in body[1:]]
        # The samples both fits use: positive and within furfit's default floor.
        samples[n] = sum(1 for v in vals if v > 0 and v >= 1e-8 * max(vals))
    lines = ["# Fit speed: furfit against a scipy script", "",
             "Written by `bench/fit_speed/run.sh` (" + time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()) + ").", "",
             "Data: SYNTHETIC kappa = 0 hair profiles: `furfit synth` of three parameter sets (R, TT, TRT;"
             " `bench/fit_speed/run.py` lists them) with 2 % log-normal noise, seed 1.",
             f"Machine: {platform.machine()}, {os.cpu_count()} logical CPUs, {platform.platform()};"
             f" load average (1, 5, 15 min) {args.load_start} at the start, {args.load_end} at the end"
             " (above the CPU count, other work shared the cores: furfit, on both cores, loses more"
             " to it than the one-threaded numpy).", "",
             "- furfit: `furfit fit PROFILE --out F --force`, blind (no start values), default options.",
             f"- scipy: `python bench/fit_speed/scipy_fit.py PROFILE --nodes {args.nodes}`: numpy far field"
             " of MODEL.md's unscattered lobes with Gauss-Legendre over h, `least_squares(method='trf')`"
             " from a manual start, six hair parameters and the exposure.",
             f"- Wall time of each whole process, {args.repeats} repeats, interleaved (order alternating).", "",
             "| profile | samples | furfit median s | scipy median s | ratio scipy/furfit | furfit NRMSE | scipy NRMSE |",
             "|---|---:|---:|---:|---:|---:|---:|"]
    ratios = []
    for name in profiles:
        f = [r for r in rows if r[0] == name and r[2] == "furfit"]
        s = [r for r in rows if r[0] == name and r[2] == "scipy"]
        fm, sm = statistics.median(r[3] for r in f), statistics.median(r[3] for r in s)
        ratios.append(sm / fm)
        lines.append(f"| {name} | {samples[name]} | {fm:.2f} | {sm:.2f} | {sm / fm:.2f}x | "
                     f"{100 * f[0][4]:.3f}% | {100 * s[0][4]:.3f}% |")
    lines += ["", f"Median ratio over the profiles: **{statistics.median(ratios):.2f}x** (goal: 10x at an NRMSE no worse than scipy's + 2 %).", "",
              "## Every run", "", "| profile | repeat | tool | wall s | NRMSE | evaluations |", "|---|---:|---|---:|---:|---:|"]
    lines += [f"| {n} | {rep} | {t} | {w:.2f} | {100 * e:.3f}% | {ev} |" for n, rep, t, w, e, ev in rows]
    # The ledger of what each direction gave, measured by hand and kept beside this script.
    lines += ["", (ROOT / "bench" / "fit_speed" / "directions.md").read_text().rstrip()]
    (ROOT / "reports" / "fit_speed.md").write_text("\n".join(lines) + "\n")
    with open(ROOT / "reports" / "fit_speed.csv", "w") as f:
        f.write("profile,repeat,tool,wall_s,nrmse,evaluations\n")
        for r in rows:
            f.write(",".join(map(str, r)) + "\n")
    print("wrote reports/fit_speed.md")


if __name__ == "__main__":
    main()
