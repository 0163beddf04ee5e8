"""Data-driven reflectance: measured BRDFs after Matusik's thesis, from Python.

A thin layer over the toolkit's Rust crates. Materials are named by the same spec strings as
every ``gantry`` command (``merl:blue-acrylic``, ``nielsen:<name>``, ``path/to/file.binary``,
``ggx:alpha=0.2,kd=0.1``, ...)::

    import reflectance
    m = reflectance.load("merl:blue-acrylic")
    table = m.tabulate()              # numpy (90, 90, 180, 3), 1/sr
    rgb = m.eval(0.1, 0.5, 1.0)       # at (theta_h, theta_d, phi_d), radians

Submodules: :mod:`reflectance.linalg` (the Gram kernel), :mod:`reflectance.models` (PCA
models), :mod:`reflectance.render` (the thesis's figures and scene files),
:mod:`reflectance.capture` (the measurement job on the simulated rig) and
:mod:`reflectance.mitsuba` (a Mitsuba 3 BSDF plugin).
"""

from ._native import Material, __version__, from_table, load, read_merl, spec_forms, write_merl
from . import capture, linalg, models, render

__all__ = [
    "Material",
    "__version__",
    "capture",
    "from_table",
    "linalg",
    "load",
    "spec_forms",
    "models",
    "read_merl",
    "render",
    "write_merl",
]
