"""The BRDF measurement job (thesis chapter 3) on the simulated rig."""

from ._native import capture as run

__all__ = ["run"]
