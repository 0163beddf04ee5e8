"""Render a measured MERL material in Mitsuba 3 through the reflectance plugin, and the same
sphere with the toolkit's own renderer, from Python.

    python bindings/python/examples/render_merl_in_mitsuba.py merl:blue-acrylic out.png

The Mitsuba scene is the figure of `gantry render sphere` (reflectance.mitsuba.sphere_scene);
it can be any Mitsuba scene whose BSDF is {"type": "reflectance", "spec": "<any spec>"}.
"""

import sys

import mitsuba as mi

mi.set_variant("llvm_ad_rgb")  # "scalar_rgb" works too, slowly

import numpy as np

import reflectance
import reflectance.mitsuba

spec = sys.argv[1] if len(sys.argv) > 1 else "merl:blue-acrylic"
out = sys.argv[2] if len(sys.argv) > 2 else "sphere.png"

reflectance.mitsuba.register()  # the BSDF type "reflectance"
scene = mi.load_dict(
    reflectance.mitsuba.sphere_scene({"type": "reflectance", "spec": spec}, size=256, spp=64)
)
image = mi.render(scene)
mi.util.write_bitmap(out, image)

# the toolkit's own path tracer on the same figure, as a numpy array
ours = reflectance.render.sphere(spec, size=256, spp=64)
print(f"{spec}: Mitsuba mean {np.array(image).mean():.5f}, toolkit mean {ours.mean():.5f}; wrote {out}")
