"""Type stubs of the furfit Python module (the Rust extension ``furfit._furfit``)."""

import os
from typing import Dict, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

__version__: str
TOOL_VERSION: str
MAX_GRID_SAMPLES: int

PathLike = Union[str, "os.PathLike[str]"]
#: A preset name, a parameter / fit JSON path, a parameter or fit object, or a fit result.
Params = Union[str, "os.PathLike[str]", Mapping[str, object], "FitResult"]
#: Degrees: a 1-D sequence or array of numbers, or CLI grid text such as "-60:60:2".
Angles = Union[str, Sequence[float], npt.ArrayLike]
Lobes = Union[str, Sequence[str], None]

class Profile:
    """A loaded goniometric profile (``load_profile``)."""

    @property
    def theta_i(self) -> npt.NDArray[np.float64]: ...
    @property
    def theta_r(self) -> npt.NDArray[np.float64]: ...
    @property
    def phi(self) -> npt.NDArray[np.float64]: ...
    @property
    def value(self) -> npt.NDArray[np.float64]: ...
    @property
    def sigma(self) -> Optional[npt.NDArray[np.float64]]: ...
    @property
    def channel(self) -> Optional[npt.NDArray[np.int64]]: ...
    @property
    def channels(self) -> List[str]: ...
    @property
    def metadata(self) -> Dict[str, str]: ...
    @property
    def files(self) -> List[str]: ...
    @property
    def notes(self) -> List[str]: ...
    @property
    def species(self) -> str: ...
    @property
    def synthetic(self) -> bool: ...
    def __len__(self) -> int: ...

class FitResult:
    """The result of ``fit`` (its primary channel; every channel in ``channels``)."""

    @property
    def params(self) -> Dict[str, float]: ...
    @property
    def model(self) -> str: ...
    @property
    def exposure(self) -> float: ...
    @property
    def nrmse(self) -> float: ...
    @property
    def stderr(self) -> Dict[str, Optional[float]]: ...
    @property
    def evaluations(self) -> int: ...
    @property
    def iterations(self) -> int: ...
    @property
    def wall_time_s(self) -> float: ...
    @property
    def termination(self) -> str: ...
    @property
    def n_used(self) -> int: ...
    @property
    def species(self) -> str: ...
    @property
    def channel(self) -> str: ...
    @property
    def channels(self) -> Dict[str, "FitResult"]: ...
    def to_json(self, path: PathLike, *, force: bool = False) -> None: ...
    def to_dict(self) -> Dict[str, object]: ...

def synth(
    params: Params,
    theta_i: Angles,
    theta_r: Angles,
    phi: Angles,
    *,
    model: Optional[str] = None,
    tol: Optional[float] = 1e-4,
    lobes: Lobes = None,
    channel: Optional[str] = None,
    exposure: Optional[float] = None,
    integral: str = "far",
) -> npt.NDArray[np.float64]:
    """The model on the grid theta_i x theta_r x phi (degrees): shape
    (len(theta_i), len(theta_r), len(phi)), the values ``furfit synth`` writes."""

def load_profile(
    path: Union[PathLike, Sequence[PathLike]],
    *,
    theta_i: Optional[Angles] = None,
    theta_r: Optional[Angles] = None,
    phi: Optional[Angles] = None,
    phi_offset: float = 0.0,
    flip_phi: bool = False,
    flip_theta_r: bool = False,
) -> Profile:
    """Load a profile file or species folder (or several, merged) as ``furfit fit`` does."""

def fit(
    profile_or_path: Union[Profile, PathLike, Sequence[PathLike]],
    *,
    model: str = "yan2017",
    seed: Optional[int] = None,
    fix: Optional[Mapping[str, float]] = None,
    weighted: bool = False,
    tol: Optional[float] = 1e-4,
) -> FitResult:
    """Fit ``model`` to the profile as ``furfit fit PATH --seed SEED`` does."""

def render(
    params: Params,
    *,
    size: Tuple[int, int] = (256, 256),
    spp: int = 16,
    mode: str = "multiscale",
    seed: int = 0,
    lobes: Lobes = None,
    tint: Union[str, Sequence[float], None] = None,
) -> npt.NDArray[np.float64]:
    """Path-trace the built-in test lock as ``furfit render``: linear radiance, (H, W, 3)."""

def presets(model: Optional[str] = None) -> Dict[str, Dict[str, float]]:
    """The model's presets, {name: {param: value}} in file units."""

def bounds(model: Optional[str] = None) -> Dict[str, Tuple[float, float]]:
    """The model's hard parameter bounds, {param: (lower, upper)} in file units."""

def models() -> List[str]:
    """The registered models, default first."""
