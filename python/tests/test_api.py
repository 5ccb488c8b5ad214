"""presets, bounds, models, render, and the stub shipped with the package."""

from pathlib import Path

import numpy as np
import pytest

import furfit


def test_presets_and_bounds():
    assert furfit.models()[0] == "yan2017"
    fur = furfit.presets()
    assert "red-fox" in fur and fur["red-fox"]["eta"] == 1.49
    for model in furfit.models():
        b = furfit.bounds(model)
        for name, p in furfit.presets(model).items():
            assert set(p) == set(b), name
            for k, v in p.items():
                lo, hi = b[k]
                assert lo <= v <= hi, (model, name, k)
    with pytest.raises(ValueError, match="unknown model"):
        furfit.bounds("nope")


def test_render_is_linear_radiance_and_seeded():
    a = furfit.render("red-fox", size=(24, 16), spp=2, seed=3)
    assert a.shape == (16, 24, 3) and a.dtype == np.float64
    assert np.all(np.isfinite(a)) and np.all(a >= 0) and a.max() > 0
    assert np.array_equal(a, furfit.render("red-fox", size=(24, 16), spp=2, seed=3))
    assert not np.array_equal(a, furfit.render("red-fox", size=(24, 16), spp=2, seed=4))
    grey = furfit.render("red-fox", size=(24, 16), spp=2, seed=3, tint="grey")
    assert not np.array_equal(a, grey)
    with pytest.raises(ValueError, match="spp"):
        furfit.render("red-fox", spp=0)
    with pytest.raises(ValueError, match="mode"):
        furfit.render("red-fox", mode="bogus")
    with pytest.raises(ValueError, match="yan2017"):
        furfit.render({"model": "chiang2016", **furfit.presets("chiang2016")[
            sorted(furfit.presets("chiang2016"))[0]]})


def test_package_ships_stub_and_marker():
    pkg = Path(furfit.__file__).parent
    assert (pkg / "py.typed").exists()
    stub = (pkg / "__init__.pyi").read_text()
    for name in furfit.__all__:
        if not name.startswith("__"):
            assert name in stub, name


# The README's example, verbatim: it must run as written from the repository root.
README_EXAMPLE = '''\
import furfit
fit = furfit.fit("measurements/red-fox", seed=1)
print(fit.params, f"NRMSE {fit.nrmse:.2%}")
grid = furfit.synth(fit, [0, 30], range(-60, 61, 2), range(-180, 181, 4))
print(grid.shape)  # (2, 61, 91): theta_i x theta_r x phi
'''


def test_readme_example_runs_as_written(root):
    import subprocess
    import sys
    res = subprocess.run([sys.executable, "-c", README_EXAMPLE], cwd=root,
                         capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr
    out = res.stdout.splitlines()
    assert out[-1] == "(2, 61, 91)"
    assert "NRMSE 2.2" in out[0] and "'eta'" in out[0]
