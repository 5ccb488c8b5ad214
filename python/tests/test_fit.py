"""furfit.fit gives the fit ``furfit fit`` gives, and writes the same fit file."""

import json

import numpy as np
import pytest

import furfit
from conftest import read_csv_profile, without_clock

SPECIES = "measurements/red-fox"


@pytest.fixture(scope="session")
def cli_fit(cli, root, tmp_path_factory):
    """``furfit fit measurements/red-fox --seed 1`` (one run for the session)."""
    out = tmp_path_factory.mktemp("cli") / "red-fox.json"
    cli("fit", SPECIES, "--seed", 1, "--out", out)
    return json.loads(out.read_text())


@pytest.fixture(scope="session")
def py_fit(root):
    import os
    here = os.getcwd()
    os.chdir(root)  # the CLI's paths are given from the repository root
    try:
        with pytest.warns(UserWarning, match="without a positive value left out"):
            return furfit.fit(SPECIES, seed=1)
    finally:
        os.chdir(here)


def test_fit_equals_cli(cli_fit, py_fit):
    # Deterministic for a seed whatever the thread count: the same solve, so the bound
    # is the 1e-9 (relative) on every parameter and the NRMSE.
    assert py_fit.model == "yan2017" and py_fit.species == "red-fox"
    assert set(py_fit.params) == set(cli_fit["params"])
    for k, v in cli_fit["params"].items():
        assert py_fit.params[k] == pytest.approx(v, rel=1e-9, abs=1e-300), k
    assert py_fit.nrmse == pytest.approx(cli_fit["nrmse"], rel=1e-9)
    assert py_fit.exposure == pytest.approx(cli_fit["exposure"], rel=1e-9)
    assert py_fit.evaluations == cli_fit["solver"]["evaluations"]
    for k, v in cli_fit["uncertainty"]["standard_error"].items():
        if v is None:
            assert py_fit.stderr[k] is None
        else:
            assert py_fit.stderr[k] == pytest.approx(v, rel=1e-9), k
    assert 0 < py_fit.wall_time_s < 3600
    assert 0 < py_fit.nrmse < 1


def test_to_json_writes_the_clis_fit_file(cli_fit, py_fit, root, tmp_path):
    import os
    out = tmp_path / "red-fox.json"
    here = os.getcwd()
    os.chdir(root)
    try:
        py_fit.to_json(out)
    finally:
        os.chdir(here)
    mine = json.loads(out.read_text())
    # Everything but the clock: the files recorded (relative to the fit file) included.
    assert without_clock(mine) == without_clock(cli_fit)
    assert out.read_text().endswith("}\n")
    # A refit of the same data replaces it; a file that is no fit is never replaced.
    py_fit.to_json(out)
    other = tmp_path / "notes.json"
    other.write_text('{"mine": true}')
    with pytest.raises(OSError, match="not a furfit fit file"):
        py_fit.to_json(other)
    assert json.loads(other.read_text()) == {"mine": True}
    with pytest.raises(OSError, match="must end in .json"):
        py_fit.to_json(tmp_path / "fit.txt")
    d = py_fit.to_dict()
    assert d["params"] == mine["params"] and d["species"] == "red-fox"


@pytest.fixture(scope="session")
def small_profile(cli, tmp_path_factory):
    """A small noise-free synthetic profile (red fox), fast to fit."""
    out = tmp_path_factory.mktemp("small") / "fox.csv"
    cli("synth", "--params", "red-fox", "--theta-i", "0,30", "--theta-r", "-60:60:10",
        "--phi", "-180:180:20", "--out", out)
    return out


def test_profile_arrays_are_the_files(small_profile):
    p = furfit.load_profile(small_profile)
    c = read_csv_profile(small_profile)
    assert len(p) == len(c["value"]) == 2 * 13 * 18
    for k in ("theta_i", "theta_r", "phi", "value"):
        a = getattr(p, k)
        assert a.dtype == np.float64 and np.array_equal(a, c[k]), k
        assert not a.flags.writeable
    assert p.sigma is None and p.channel is None and p.channels == []
    assert p.metadata["model"] == "yan2017" and p.synthetic
    assert p.species == "fox" and p.files == [str(small_profile)]


def test_fit_of_a_profile_with_fixed_parameters(cli, small_profile, tmp_path):
    truth = furfit.presets()["red-fox"]
    fix = {k: v for k, v in truth.items() if k not in ("eta", "beta_m")}
    p = furfit.load_profile(small_profile)
    r = furfit.fit(p, seed=3, fix=fix)
    out = tmp_path / "fox.json"
    cli("fit", small_profile, "--seed", 3, "--out", out,
        *[a for k, v in fix.items() for a in ("--fix", f"{k}={v!r}")])
    c = json.loads(out.read_text())
    for k, v in c["params"].items():
        assert r.params[k] == pytest.approx(v, rel=1e-9), k
    assert r.nrmse == pytest.approx(c["nrmse"], rel=1e-9, abs=1e-15)
    # Noise-free data of the truth: recovered (to the far field's tolerance).
    assert r.params["eta"] == pytest.approx(truth["eta"], rel=1e-3)
    assert set(r.channels) == {""} and r.channel == ""
    # The fit result is a parameter source too.
    grid = furfit.synth(r, [0, 30], "-60:60:10", "-180:180:20")
    assert grid.shape == (2, 13, 19)


def test_fit_option_errors(small_profile):
    with pytest.raises(ValueError, match="unknown parameter"):
        furfit.fit(small_profile, fix={"nope": 1.0})
    with pytest.raises(ValueError, match="hard bound"):
        furfit.fit(small_profile, fix={"eta": 9.0})
    with pytest.raises(ValueError, match="sigma"):
        furfit.fit(small_profile, weighted=True)
    with pytest.raises(ValueError, match="unknown model"):
        furfit.fit(small_profile, model="nope")
