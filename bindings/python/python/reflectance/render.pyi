"""Type stubs of reflectance.render (linear RGB float32 images, (height, width, 3))."""

from os import PathLike
from typing import Optional, Union

import numpy as np
import numpy.typing as npt

from . import Material

_M = Union[Material, str]

def sphere(material: _M, size: int = 256, spp: int = 16, seed: int = 1) -> npt.NDArray[np.float32]:
    """``gantry render sphere``: unit sphere under a point light (irradiance π), direct lighting."""

def teapot(
    material: _M,
    width: int = 320,
    spp: int = 64,
    seed: int = 1,
    env: Optional[Union[str, PathLike]] = None,
) -> npt.NDArray[np.float32]:
    """``gantry render teapot``: the Utah teapot under a light probe, path traced."""

def scene(
    path: Union[str, PathLike], spp: Optional[int] = None, seed: int = 1
) -> npt.NDArray[np.float32]:
    """``gantry render SCENE.toml``: a TOML scene file (docs/render.md)."""
