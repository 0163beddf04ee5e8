"""Type stubs of reflectance.mitsuba."""

def bsdf_class() -> type:
    """The BSDF class for the active Mitsuba variant."""

def register(name: str = "reflectance") -> None:
    """Registers the BSDF type ``name`` (default "reflectance", parameter ``spec``) with Mitsuba
    for the active variant."""

SPHERE_LIGHT: tuple[float, float, float]

def sphere_scene(bsdf: dict, size: int = 256, spp: int = 16, integrator: dict | None = None) -> dict:
    """The figure of ``gantry render sphere`` as a Mitsuba scene dict."""
