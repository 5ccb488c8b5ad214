"""furfit: fit fiber reflectance models to goniometric profiles, from Python.

The functions are the Rust library's, the same calls the ``furfit`` command line makes:
``synth`` returns the values ``furfit synth`` writes, ``fit`` the fit ``furfit fit``
writes, with numpy arrays in and out. Long calls release the GIL and stop on Ctrl-C.

    >>> import furfit
    >>> grid = furfit.synth("red-fox", [0, 30], range(-60, 61, 2), range(-180, 181, 4))
    >>> grid.shape
    (2, 61, 91)
"""

from ._furfit import (
    MAX_GRID_SAMPLES,
    TOOL_VERSION,
    FitResult,
    Profile,
    __version__,
    bounds,
    fit,
    load_profile,
    models,
    presets,
    render,
    synth,
)

__all__ = [
    "MAX_GRID_SAMPLES",
    "TOOL_VERSION",
    "FitResult",
    "Profile",
    "__version__",
    "bounds",
    "fit",
    "load_profile",
    "models",
    "presets",
    "render",
    "synth",
]
