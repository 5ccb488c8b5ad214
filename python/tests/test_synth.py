"""furfit.synth gives the values ``furfit synth`` writes on the same grid."""

import numpy as np
import pytest

import furfit
from conftest import read_csv_profile

# The throughput grid of the issue: 4 x 61 x 181 (the CLI writes 180 phi: it keeps one of
# -180 and 180, the same direction; Python keeps every value given).
TI = "0,15,30,45"
TR = "-60:60:2"
PHI = "-180:180:2"

# Both sides run the same library code on the same angles: any difference would be a
# different computation, not rounding, so the bound is the 1e-12 relative.
REL = 1e-12


def assert_close(py, cli):
    assert py.shape == cli.shape
    scale = np.maximum(np.abs(cli), 1e-300)
    worst = np.max(np.abs(py - cli) / scale)
    assert worst <= REL, f"largest relative difference {worst:e}"


def cli_npz(cli, tmp_path, *args):
    out = tmp_path / "cli.npz"
    cli("synth", *args, "--out", out, "--force")
    z = np.load(out)
    return z["theta_i"], z["theta_r"], z["phi"], z["value"]


def test_throughput_grid_equals_cli_npz(cli, tmp_path):
    ti, tr, phi, value = cli_npz(cli, tmp_path, "--params", "red-fox", "--theta-i", TI,
                                 "--theta-r", TR, "--phi", PHI)
    assert value.shape == (4, 61, 180)
    got = furfit.synth("red-fox", ti, tr, phi)
    assert got.dtype == np.float64 and got.shape == (4, 61, 180)
    assert_close(got, value)
    # The full 181-value phi axis: -180 gives the values of 180.
    full = furfit.synth("red-fox", ti, tr, -180.0 + 2.0 * np.arange(181))
    assert full.shape == (4, 61, 181)
    assert_close(full[..., 1:], value)
    assert_close(full[..., :1], value[..., -1:])


def test_grid_text_equals_cli_csv(cli, tmp_path):
    out = tmp_path / "cli.csv"
    cli("synth", "--params", "cat", "--theta-i", "0,30", "--theta-r", "-40:40:10",
        "--phi", "-170:180:30", "--out", out)
    c = read_csv_profile(out)
    got = furfit.synth("cat", "0,30", "-40:40:10", "-170:180:30")
    assert_close(got.reshape(-1), c["value"])


@pytest.mark.parametrize("model", furfit.models())
def test_every_model_and_options_equal_cli(cli, tmp_path, model):
    preset = sorted(furfit.presets(model))[0]
    args = ["--params", preset, "--model", model, "--theta-i", "0,40",
            "--theta-r", "-50:50:25", "--phi", "-150:180:30"]
    _, _, _, value = cli_npz(cli, tmp_path, *args)
    got = furfit.synth(preset, [0, 40], "-50:50:25", "-150:180:30", model=model)
    assert_close(got, value)
    # Fixed segmentation, an exposure and a lobe subset (the model's first two lobes).
    lobes = {"yan2017": ["R", "TRT"]}.get(model, ["R", "TT"])
    _, _, _, value = cli_npz(cli, tmp_path, *args, "--tol", "none", "--exposure", "2.5",
                             "--lobes", ",".join(lobes))
    got = furfit.synth(preset, [0, 40], "-50:50:25", "-150:180:30", model=model,
                       tol=None, exposure=2.5, lobes=lobes)
    assert_close(got, value)


def test_fit_file_uses_its_exposure_and_dicts_equal_files(cli, tmp_path, root):
    path = root / "fits" / "red-fox.json"
    _, _, _, value = cli_npz(cli, tmp_path, "--params", path, "--theta-i", "15",
                             "--theta-r", "-30:30:15", "--phi", "0,60,120,180")
    got = furfit.synth(str(path), [15], "-30:30:15", [0, 60, 120, 180])
    assert_close(got, value)
    import json
    fitd = json.loads(path.read_text())
    assert fitd["exposure"] != 1.0
    assert_close(furfit.synth(fitd, [15], "-30:30:15", [0, 60, 120, 180]), value)
    # A bare parameter dict has exposure 1: the fit's values over its exposure.
    bare = furfit.synth(fitd["params"], [15], "-30:30:15", [0, 60, 120, 180])
    assert_close(bare * fitd["exposure"], value)


def test_phi_is_wrapped_as_the_cli_wraps_it():
    a = furfit.synth("deer", [30], [10], [270.0, -270.0, 360.0])
    b = furfit.synth("deer", [30], [10], [-90.0, 90.0, 0.0])
    assert_close(a, b)


def test_rgb_fit_channels(cli, tmp_path):
    import json
    chans = []
    for name, sigma, k in [("r", 0.1, 2.0), ("g", 0.4, 3.0), ("b", 1.6, 5.0)]:
        p = dict(furfit.presets()["cat"], sigma_c_a=sigma)
        chans.append({"params": p, "exposure": k, "data": {"channel": name}})
    top = dict(chans[0], channels=chans)
    path = tmp_path / "rgb.json"
    path.write_text(json.dumps(top))
    out = tmp_path / "rgb.csv"
    cli("synth", "--params", path, "--theta-i", "0,30", "--theta-r", "-20:20:20",
        "--phi", "0,90,180", "--out", out)
    c = read_csv_profile(out)
    with pytest.raises(ValueError, match="has channels r, g, b"):
        furfit.synth(str(path), [0, 30], "-20:20:20", [0, 90, 180])
    allc = furfit.synth(str(path), [0, 30], "-20:20:20", [0, 90, 180], channel="all")
    assert allc.shape == (3, 2, 3, 3)
    for i, name in enumerate("rgb"):
        rows = c["channel"] == name
        assert_close(allc[i].reshape(-1), c["value"][rows])
        one = furfit.synth(str(path), [0, 30], "-20:20:20", [0, 90, 180], channel=name)
        assert_close(one, allc[i])
    with pytest.raises(ValueError, match="has channels r, g, b"):
        furfit.synth(str(path), [0], [0], [0], channel="y")
