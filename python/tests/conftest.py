"""Shared fixtures: the repository, the CLI binary built from it, and helpers that run the
CLI and read what it writes, so the tests compare furfit (Python) with ``furfit`` (CLI)."""

import csv
import json
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def root():
    return ROOT


@pytest.fixture(scope="session")
def cli():
    """The release binary (``FURFIT_BIN``, else ``target/release/furfit``, built if
    missing), as a function running it and returning the completed process."""
    exe = os.environ.get("FURFIT_BIN") or str(ROOT / "target" / "release" / "furfit")
    if not Path(exe).exists():
        subprocess.run(["cargo", "build", "--release", "--bin", "furfit"], cwd=ROOT, check=True)

    def run(*args, check=True):
        res = subprocess.run([exe, *map(str, args)], cwd=ROOT, capture_output=True, text=True)
        if check and res.returncode != 0:
            raise AssertionError(f"furfit {' '.join(map(str, args))} failed:\n{res.stderr}")
        return res

    return run


def read_csv_profile(path):
    """A CSV profile as {column: array} (comment lines dropped)."""
    with open(path) as f:
        rows = list(csv.reader(line for line in f if not line.startswith("#")))
    head, body = rows[0], rows[1:]
    return {h: np.array([r[i] for r in body], dtype=float if h != "channel" else object)
            for i, h in enumerate(head)}


def cli_error(res):
    """The message of the CLI's ``error: ...`` line."""
    lines = [line for line in res.stderr.splitlines() if line.startswith("error: ")]
    assert lines, res.stderr
    return lines[-1][len("error: "):]


# Fields of a fit file that are wall-clock measurements, different on every run.
CLOCK_FIELDS = ("wall_time_s", "model_time_s", "model_time_share")


def without_clock(fit):
    """A fit file's JSON without its wall-clock fields (and without the build's
    ``tool_version``: the binary and the module may be built at different revisions)."""
    fit = json.loads(json.dumps(fit))
    for k in CLOCK_FIELDS:
        fit["solver"].pop(k)
    for t in fit["trace"]:
        t.pop("time_s")
    fit.pop("tool_version")
    for ch in fit.get("channels", []):
        for k in CLOCK_FIELDS:
            ch["solver"].pop(k)
        for t in ch["trace"]:
            t.pop("time_s")
        ch.pop("tool_version")
    return fit
