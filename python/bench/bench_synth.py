"""Binding overhead of ``furfit.synth`` (issue 63): the Python call on the 4 x 61 x 181
grid against the library call it wraps, ``furfit::synth::synthesize`` on the same grid
and preset, timed alone (a) in this process (``furfit._furfit._library_synth_seconds``,
the bare call without the GIL) and (b) in the Rust example ``bench_synth`` of the binding
crate (its ``--serve`` process, idle while Python runs).

Run from the repository root, in an environment with ``furfit`` installed::

    python python/bench/bench_synth.py [--calls 200]

The calls alternate in blocks of ``--block`` (Python, in-process library, Rust process),
so a busy machine's drift slows all alike (one by one, each call inherited the previous
one's freed memory or still-running frees, which favoured neither consistently). The Python time is the whole call as a user sees it (argument
conversion, the checks, the synthesis without the GIL, the one copy into the result
array). Prints one JSON line: medians, minima and the ratios to each library timing.
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


def python_call():
    t = time.perf_counter()
    a = furfit.synth("red-fox", THETA_I, THETA_R, PHI)
    dt = time.perf_counter() - t
    assert a.shape == (4, 61, 181)
    return dt


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--calls", type=int, default=300, help="calls of each (after warm-up)")
    ap.add_argument("--block", type=int, default=10, help="calls of one kind in a row")
    a = ap.parse_args()
    subprocess.run(["cargo", "build", "--quiet", "--release", "-p", "furfit-python",
                    "--example", "bench_synth"], check=True)
    lib = subprocess.Popen(["target/release/examples/bench_synth", "--serve"],
                           stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    assert lib.stdout.readline().strip() == "ready"

    def library_call():
        lib.stdin.write("\n")
        lib.stdin.flush()
        return float(lib.stdout.readline())

    def inproc_call():
        return furfit._furfit._library_synth_seconds(
            "red-fox", THETA_I, list(THETA_R), list(PHI))

    for _ in range(5):  # warm-up: thread pools, tables, allocator
        python_call()
        inproc_call()
        library_call()
    py, ip, rs = [], [], []
    for _ in range(a.calls // a.block):
        py += [python_call() for _ in range(a.block)]
        ip += [inproc_call() for _ in range(a.block)]
        rs += [library_call() for _ in range(a.block)]
    lib.stdin.close()
    lib.wait()
    med = statistics.median
    print(json.dumps({
        "grid": "4 x 61 x 181",
        "samples": 4 * 61 * 181,
        "calls": a.calls,
        "python_median_s": med(py),
        "library_in_process_median_s": med(ip),
        "library_rust_process_median_s": med(rs),
        "ratio_median_in_process": med(py) / med(ip),
        "ratio_median_rust_process": med(py) / med(rs),
        "python_min_s": min(py),
        "library_in_process_min_s": min(ip),
        "library_rust_process_min_s": min(rs),
        "ratio_min_in_process": min(py) / min(ip),
        "python_samples_per_s": 4 * 61 * 181 / med(py),
    }))
    return 0


if __name__ == "__main__":
    sys.exit(main())
