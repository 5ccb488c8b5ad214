"""numpy edge cases and errors: the CLI's checks and messages, as Python exceptions."""

import json
import time

import numpy as np
import pytest

import furfit
from conftest import cli_error

TR = np.linspace(-60, 60, 25)
PHI = np.linspace(-180, 180, 37)


def test_non_contiguous_and_other_dtypes_give_the_same_values():
    base = furfit.synth("red-fox", [0.0, 30.0], TR, PHI)
    big = np.zeros((2, 50))
    big[0, ::2] = TR
    strided = big[0, ::2]
    assert not strided.flags.c_contiguous
    reversed_ = PHI[::-1][::-1]
    assert np.array_equal(furfit.synth("red-fox", [0.0, 30.0], strided, reversed_), base)
    # float32 and int hold these whole and half degrees exactly: the same angles.
    f32 = furfit.synth("red-fox", np.array([0, 30], np.float32), TR.astype(np.float32),
                       PHI.astype(np.float32))
    assert np.array_equal(f32, base)
    ints = furfit.synth("red-fox", np.array([0, 30], np.int64), [-60, 0, 60], range(0, 181, 90))
    assert np.array_equal(ints, furfit.synth("red-fox", [0.0, 30.0], [-60.0, 0.0, 60.0],
                                             [0.0, 90.0, 180.0]))
    # A column of a Fortran-ordered 2-D array.
    fort = np.asfortranarray(np.stack([TR, TR]))
    assert np.array_equal(furfit.synth("red-fox", [0.0, 30.0], fort[1], PHI), base)


def test_output_is_a_fresh_c_contiguous_float64_array():
    a = furfit.synth("cat", [0], [0, 10], [0, 90, 180])
    assert a.dtype == np.float64 and a.flags.c_contiguous and a.flags.writeable
    assert a.shape == (1, 2, 3)
    assert np.all(np.isfinite(a)) and np.all(a > 0)


@pytest.mark.parametrize("bad,match", [
    ([], "theta_r: no angles"),
    (np.array([]), "theta_r: no angles"),
    ([0.0, np.nan], "theta_r: angle NaN is not a finite number"),
    ([np.inf], "theta_r: angle inf is not a finite number"),
    ([95.0], r"theta_r: angle 95 is outside \[-90, 90\] degrees"),
    (np.zeros((2, 2)), "expected a 1-D sequence"),
    (["a", "b"], "expected a 1-D sequence"),
    ("0:10", "expected start:stop:step"),
])
def test_bad_angles_are_value_errors(bad, match):
    with pytest.raises(ValueError, match=match):
        furfit.synth("red-fox", [0], bad, [0])


def test_angle_messages_are_the_clis(cli, tmp_path):
    res = cli("synth", "--params", "red-fox", "--theta-i", "0", "--theta-r", "95",
              "--phi", "0", "--out", tmp_path / "x.csv", check=False)
    assert res.returncode != 0
    with pytest.raises(ValueError) as e:
        furfit.synth("red-fox", [0], [95], [0])
    # The same message, the option named as the argument.
    assert str(e.value) == cli_error(res).replace("--theta-r", "theta_r")


def test_huge_grid_refused_with_the_cli_limit_at_once(cli, tmp_path):
    n = int(round((furfit.MAX_GRID_SAMPLES + 1) ** (1 / 3))) + 1
    assert n ** 3 > furfit.MAX_GRID_SAMPLES
    axis = np.linspace(-80, 80, n)
    t = time.perf_counter()
    with pytest.raises(ValueError, match=f"more than the limit of {furfit.MAX_GRID_SAMPLES}"):
        furfit.synth("red-fox", axis, axis, axis)
    # Refused before any work (a synthesis of 1e7 samples takes seconds).
    assert time.perf_counter() - t < 1.0
    res = cli("synth", "--params", "red-fox", "--theta-i", f"-80:80:{160 / (n - 1)}",
              "--theta-r", f"-80:80:{160 / (n - 1)}", "--phi", f"-80:80:{160 / (n - 1)}",
              "--out", tmp_path / "x.csv", check=False)
    assert "more than the limit of" in cli_error(res)
    # Exactly at the limit is allowed by the same rule: checked on a cheap shape.
    furfit.synth("red-fox", [0], [0], np.zeros(1))


def test_parameter_errors_are_the_clis(cli, tmp_path):
    bad = dict(furfit.presets()["cat"], eta=5.0)
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(bad))
    res = cli("synth", "--params", path, "--theta-i", "0", "--theta-r", "0", "--phi", "0",
              "--out", tmp_path / "x.csv", check=False)
    msg = cli_error(res)
    assert "parameter 'eta'" in msg
    with pytest.raises(ValueError) as e:
        furfit.synth(str(path), [0], [0], [0])
    assert str(e.value) == msg
    # The dict form: the same check, without the file's name.
    with pytest.raises(ValueError, match="parameter 'eta'"):
        furfit.synth(bad, [0], [0], [0])
    with pytest.raises(ValueError, match="neither a preset"):
        furfit.synth("no-such-preset", [0], [0], [0])
    with pytest.raises(ValueError, match="unknown model"):
        furfit.synth("cat", [0], [0], [0], model="nope")
    with pytest.raises(ValueError, match="unknown lobe|lobe"):
        furfit.synth("cat", [0], [0], [0], lobes="R,XX")
    with pytest.raises(ValueError, match="--tol must be in"):
        furfit.synth("cat", [0], [0], [0], tol=2.0)
    with pytest.raises(ValueError, match="exposure must be a finite number > 0"):
        furfit.synth("cat", [0], [0], [0], exposure=-1.0)
    with pytest.raises(ValueError, match="not a finite number"):
        furfit.synth(dict(bad, eta=float("nan")), [0], [0], [0])


def test_file_errors_are_os_errors(tmp_path):
    with pytest.raises(OSError, match="no such parameter or fit file"):
        furfit.synth(str(tmp_path / "missing.json"), [0], [0], [0])
    with pytest.raises(FileNotFoundError):
        furfit.load_profile(tmp_path / "missing.csv")
    broken = tmp_path / "broken.csv"
    broken.write_text("theta_i,theta_r,phi,value\n0,0,0,1\n0,zero,0,1\n")
    with pytest.raises(OSError, match="broken.csv:3"):
        furfit.load_profile(broken)
    with pytest.raises(TypeError):
        furfit.synth(3.5, [0], [0], [0])
