"""Binding overhead of ``furfit.synth`` (issue 63): the Python call on the 4 x 61 x 181
grid against the library call it wraps (``furfit::synth::synthesize``, timed alone by the
Rust example ``bench_synth`` of the binding crate on the same grid and preset).

Run from the repository root, in an environment with ``furfit`` installed::

    python python/bench/bench_synth.py [--repeats 50] [--rust-json FILE]

Without ``--rust-json`` it runs ``cargo run --release -p furfit-python --example
bench_synth``. The two runs alternate in rounds (Python, Rust, Python, ...) so a busy
machine slows both alike; the figure is the ratio of the medians. Prints one JSON line.
"""

import argparse
import json
import statistics
import subprocess
import sys
import time

import numpy as np

import furfit

THETA_I = [0.0, 15.0, 30.0, 45.0]
THETA_R = -60.0 + 2.0 * np.arange(61)
PHI = -180.0 + 2.0 * np.arange(181)


def python_times(repeats):
    """Seconds of each ``furfit.synth`` call (after a warm-up), values checked."""
    for _ in range(3):
        furfit.synth("red-fox", THETA_I, THETA_R, PHI)
    out = []
    for _ in range(repeats):
        t = time.perf_counter()
        a = furfit.synth("red-fox", THETA_I, THETA_R, PHI)
        out.append(time.perf_counter() - t)
        assert a.shape == (4, 61, 181)
    return out


def rust_times(repeats):
    """Seconds of each library call, from the Rust example."""
    cmd = ["cargo", "run", "--quiet", "--release", "-p", "furfit-python",
           "--example", "bench_synth", "--", str(repeats)]
    res = subprocess.run(cmd, check=True, capture_output=True, text=True)
    return json.loads(res.stdout.strip().splitlines()[-1])["times_s"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=50, help="calls per round")
    ap.add_argument("--rounds", type=int, default=3, help="alternating rounds")
    ap.add_argument("--rust-json", help="a saved output line of the Rust example")
    a = ap.parse_args()
    py, rs = [], []
    for _ in range(a.rounds):
        py += python_times(a.repeats)
        if a.rust_json:
            with open(a.rust_json) as f:
                rs = json.load(f)["times_s"]
        else:
            rs += rust_times(a.repeats)
    mp, mr = statistics.median(py), statistics.median(rs)
    print(json.dumps({
        "grid": "4 x 61 x 181",
        "samples": 4 * 61 * 181,
        "python_median_s": mp,
        "python_min_s": min(py),
        "library_median_s": mr,
        "library_min_s": min(rs),
        "ratio_median": mp / mr,
        "ratio_min": min(py) / min(rs),
        "calls": [len(py), len(rs)],
    }))
    return 0


if __name__ == "__main__":
    sys.exit(main())
