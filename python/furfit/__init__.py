"""furfit: fit fiber reflectance models to goniometric profiles (Python bindings).

The functions are the Rust library's (the same code the ``furfit`` CLI runs): the same
numbers, numpy arrays in and out. See ``help(furfit.synth)`` and the stub
``furfit/__init__.pyi``.
"""

from ._furfit import *  # noqa: F401,F403
from ._furfit import __doc__ as _native_doc  # noqa: F401

__all__ = [name for name in dir() if not name.startswith("_")]
