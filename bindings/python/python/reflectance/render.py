"""The thesis's figures and scene files rendered by the toolkit's path tracer, as numpy images.

Each function returns linear RGB float32 of shape (height, width, 3); a material is a
:class:`reflectance.Material` or a spec string.
"""

from ._native import render_scene_file as scene
from ._native import render_sphere as sphere
from ._native import render_teapot as teapot

__all__ = ["scene", "sphere", "teapot"]
