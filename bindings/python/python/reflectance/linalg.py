"""Linear algebra kernels of the toolkit.

``gram(a, b=None)`` is ``a @ b.T`` (``a @ a.T`` when ``b`` is None) for row-major float arrays,
computed by ``reduce::gram``'s SIMD kernel with the GIL released.
"""

from ._native import gram

__all__ = ["gram"]
