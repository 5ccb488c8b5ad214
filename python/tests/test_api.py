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
