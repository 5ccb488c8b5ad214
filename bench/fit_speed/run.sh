#!/usr/bin/env bash
# Side-by-side fit speed (reports/fit_speed.md): builds furfit, sets up a virtual
# environment with numpy and scipy from PyPI, and runs run.py. Arguments go to run.py
# (e.g. --repeats 5).
set -euo pipefail
cd "$(dirname "$0")/../.."
cargo build --release --quiet
venv=target/fit_speed/venv
if [ ! -x "$venv/bin/python" ]; then
    python3 -m venv "$venv"
    "$venv/bin/pip" install --quiet numpy scipy
fi
"$venv/bin/python" bench/fit_speed/run.py "$@"
