"""The BRDF measurement job (thesis chapter 3) on the simulated rig: ``run`` visits every lamp
position; ``fast`` visits the positions a reflectance model needs most within a clock budget and
completes the table from the model (``gantry capture --fast``)."""

from ._native import capture as run
from ._native import fast_capture as fast

__all__ = ["run", "fast"]
