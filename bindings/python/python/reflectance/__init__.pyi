"""Type stubs of the reflectance package (the native module re-exported)."""

from os import PathLike
from typing import Any, Optional, Union

import numpy as np
import numpy.typing as npt

from . import capture as capture
from . import linalg as linalg
from . import models as models
from . import render as render

__version__: str

_Path = Union[str, PathLike]
_Angles = npt.ArrayLike

class Material:
    """A loaded material (any toolkit spec); see :func:`load`."""

    @property
    def spec(self) -> str: ...
    @property
    def name(self) -> str: ...
    @property
    def is_isotropic(self) -> bool: ...
    def eval(self, theta_h: _Angles, theta_d: _Angles, phi_d: _Angles) -> npt.NDArray[np.float64]:
        """BRDF (1/sr, RGB) at Rusinkiewicz angles in radians; inputs broadcast, result has
        their shape plus a last axis of 3."""
    def eval_directions(self, wi: npt.ArrayLike, wo: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """BRDF (1/sr, RGB) for unit direction pairs (..., 3) in the local frame (normal +z);
        ``wi`` towards the light, ``wo`` towards the viewer."""
    def tabulate(self) -> npt.NDArray[np.float64]:
        """The material on the MERL grid, (90, 90, 180, 3) in 1/sr; negative = missing."""
    def write_merl(self, path: _Path) -> None:
        """Writes the tabulated material as a MERL ``.binary`` file (atomically)."""
    def save_bsdf(self, path: _Path, resolution: int = 32, theta_i: int = 16, spectral: bool = False) -> None:
        """Writes the material as an RGL tensor ``.bsdf`` file (atomically) for Mitsuba 3's
        ``measured`` BSDF (RGB variants; ``spectral=True`` for spectral variants and pbrt-v4);
        ``load`` reads such files back."""
    def albedo(self, theta_i: float, n_u: int = 256, n_phi: int = 256) -> list[float]:
        """Directional albedo (RGB) for light at polar angle ``theta_i`` (radians)."""
    def reciprocity_residual(self, n: int = 20000, seed: int = 1) -> float:
        """Relative RMS of f(wi, wo) - f(wo, wi) over ``n`` seeded random pairs."""
    def summary(self) -> dict[str, Any]:
        """The summary of ``gantry info --json``."""
    def importance_tables(
        self, theta_r: int = 90, theta_i: int = 90, phi_diff: int = 180, supersample: int = 2
    ) -> dict[str, Any]:
        """Thesis A.2.4 importance tables: ``cell``, ``conditional_cdf``, ``marginal_cdf``,
        ``row_totals``, ``defensive``, and the same density as alias tables: ``marginal_alias``,
        ``conditional_alias``, ``cell_density``."""

def spec_forms() -> list[str]:
    """The material-spec forms this package reads (the list ``gantry forms`` prints)."""

def load(spec: str, interpolation: Optional[str] = None) -> Material:
    """Loads a material spec; ``interpolation`` ('nearest'/'trilinear') applies to tables.
    Raises ValueError for a bad spec."""

def from_table(
    table: npt.ArrayLike, name: Optional[str] = None, interpolation: Optional[str] = None
) -> Material:
    """A material from a (90, 90, 180, 3) array of BRDF values (1/sr, negative = missing)."""

def read_merl(path: _Path) -> npt.NDArray[np.float64]:
    """Reads a MERL ``.binary`` file as a (90, 90, 180, 3) array in 1/sr."""

def write_merl(path: _Path, table: npt.ArrayLike) -> None:
    """Writes a (90, 90, 180, 3) array (1/sr) as a MERL ``.binary`` file (atomically)."""
