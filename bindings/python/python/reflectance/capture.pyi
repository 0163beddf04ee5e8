"""Type stubs of reflectance.capture."""

from os import PathLike
from typing import Any, Callable, Optional, Union

def run(
    material: str,
    directory: Union[str, PathLike],
    positions: int = 3,
    scale: float = 0.1,
    seed: int = 1,
    calibrate: bool = False,
    resume: bool = False,
    progress: Optional[Callable[[str, int, int], Any]] = None,
) -> dict[str, Any]:
    """The capture job (``acquire::run``) on the simulated rig; returns ``report.json`` as a
    dict. ``progress(stage, done, total)`` is called as the job advances (stages 'positions',
    'binning', 'validation', 'inverse'); an exception it raises is re-raised at the end."""
