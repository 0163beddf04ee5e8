"""Type stubs of reflectance.models."""

from os import PathLike
from typing import Optional, Sequence, Union

import numpy as np
import numpy.typing as npt

from . import Material

class PcaModel:
    """PCA of log-space BRDFs (thesis chapter 4; ``reduce::model::Model``)."""

    @staticmethod
    def build(specs: Sequence[str], components: int = 60) -> PcaModel:
        """PCA with ``components`` components of the materials of ``specs``: material specs,
        folders of neural-BRDF weights or ``.binary`` files, or corpus stores (as
        ``gantry model build --corpus`` takes them)."""
    @staticmethod
    def load(path: Union[str, PathLike]) -> PcaModel:
        """Reads a model file (``gantry model build`` or :meth:`save`)."""
    def save(self, path: Union[str, PathLike]) -> None: ...
    @property
    def names(self) -> list[str]: ...
    @property
    def components(self) -> int: ...
    @property
    def eigenvalues(self) -> npt.NDArray[np.float64]: ...
    def project(
        self, material: Union[Material, str, npt.ArrayLike], k: Optional[int] = None
    ) -> npt.NDArray[np.float64]:
        """Coordinates of a material on the first ``k`` components (all when None)."""
    def reconstruct(
        self, x: Sequence[float], fast: bool = False
    ) -> npt.NDArray[np.float64]:
        """The (90, 90, 180, 3) table (1/sr) of the coordinates ``x``; with ``fast``,
        through the half-precision decoder (two to four times faster, within 0.3 %)."""
