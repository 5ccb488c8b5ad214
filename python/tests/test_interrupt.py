"""Ctrl-C during a long call raises KeyboardInterrupt and leaves Python usable."""

import os
import signal
import threading
import time

import pytest

import furfit


def interrupt_after(seconds):
    """SIGINT to this process after ``seconds`` (as Ctrl-C sends it)."""
    t = threading.Timer(seconds, lambda: os.kill(os.getpid(), signal.SIGINT))
    t.start()
    return t


# The data's note on zero samples is said by every fit of this species.
@pytest.mark.filterwarnings("ignore:red-fox. note")
def test_ctrl_c_stops_a_fit_and_python_goes_on(root):
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    start = time.perf_counter()
    timer = interrupt_after(1.0)
    try:
        # A full species fit takes 10 s or more on two cores: the signal lands inside it.
        with pytest.raises(KeyboardInterrupt):
            furfit.fit(root / "measurements" / "red-fox", seed=1)
    finally:
        timer.join()
    took = time.perf_counter() - start
    # Answered within about one model evaluation, not at the end of the fit.
    assert took < 6.0, f"KeyboardInterrupt after {took:.1f} s"
    # The interpreter and the module work on.
    assert furfit.synth("red-fox", [0], [0], [0]).shape == (1, 1, 1)
    r = furfit.fit(root / "measurements" / "red-fox", seed=1,
                   fix={k: v for k, v in furfit.presets()["red-fox"].items() if k != "eta"})
    assert 1.0 <= r.params["eta"] <= 3.0


def test_ctrl_c_stops_a_render():
    start = time.perf_counter()
    timer = interrupt_after(0.5)
    try:
        with pytest.raises(KeyboardInterrupt):
            furfit.render("red-fox", size=(512, 512), spp=256)
    finally:
        timer.join()
    assert time.perf_counter() - start < 10.0
    assert furfit.render("red-fox", size=(8, 6), spp=1).shape == (6, 8, 3)
