"""Linear models of the space of measured BRDFs (thesis chapter 4): PCA in log space."""

from ._native import PcaModel

__all__ = ["PcaModel"]
