#!/usr/bin/env python3
"""Renders the validation photos of `recover` with Mitsuba 3, a renderer that is not ours.

A unit sphere at the origin seen from (0, 0, 4) with a 32° field of view (the scenes of
crates/recover/examples/nielsen_study.rs and docs/recover.md), lit by one point light of
25 W/sr or by an HDR light probe (Mitsuba's `envmap`, whose latitude-longitude convention is the
toolkit's), with either

    --kd R G B        Mitsuba's own `diffuse` BSDF (our `lambert:kd=R/G/B`), or
    --spec SPEC       any material of the toolkit through its Mitsuba plugin (`nielsen:<name>`,
                      `merl:<name>`, a `.binary` file ...; reflectance.mitsuba).

One photo (venv with `pip install mitsuba numpy` and the toolkit's Python package):

    python tools/recover/mitsuba_render.py OUT.exr --size 128 --light 2 2 4 --kd 0.5 0.3 0.2
    python tools/recover/mitsuba_render.py OUT.exr --size 256 --envmap probe.exr --spec nielsen:cardboard

and recover it with the matching scene TOML written beside it (OUT.toml):

    gantry recover --scene OUT.toml --image OUT.exr --model model.bin --out rec.binary

All the photos of the Nielsen study (each material under the probe at 256² and under the
study's three point lights at 128²), into STUDY_DIR/mitsuba/, where `nielsen_study MODEL
STUDY_DIR` reads them:

    BRDF_DATA_DIR=../shared/data python tools/recover/mitsuba_render.py --study STUDY_DIR
"""
import argparse
import pathlib
import sys

import mitsuba as mi

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "python"))
from mitsuba_timing import probe_path  # noqa: E402  (the shared probe, one place)

NIELSEN = ["bindercover", "bluebook", "cardboard", "glossyredpaper", "greencloth", "notebook",
           "paintedmetal", "yellowpaper"]
# The point lights of nielsen_study.rs (25 W/sr each).
STUDY_LIGHTS = [[2.0, 2.0, 4.0], [-3.0, 0.5, 2.5], [0.5, -2.5, 3.0]]


def scene_dict(size, spp, bsdf, light=None, intensity=25.0, envmap=None):
    """The study's sphere scene: a point light at `light`, or the probe `envmap`."""
    if envmap is not None:
        emitter = {"type": "envmap", "filename": str(envmap)}
    else:
        emitter = {"type": "point", "position": light,
                   "intensity": {"type": "rgb", "value": [intensity] * 3}}
    return {
        "type": "scene",
        "integrator": {"type": "direct"},
        "sensor": {
            "type": "perspective",
            "fov": 32.0,
            "fov_axis": "y",
            "to_world": mi.ScalarTransform4f().look_at(
                origin=[0, 0, 4], target=[0, 0, 0], up=[0, 1, 0]),
            "film": {"type": "hdrfilm", "width": size, "height": size,
                     "rfilter": {"type": "box"}, "pixel_format": "rgb"},
            "sampler": {"type": "independent", "sample_count": spp},
        },
        "sphere": {"type": "sphere", "center": [0, 0, 0], "radius": 1.0, "bsdf": bsdf},
        "light": emitter,
    }


def scene_toml(size, light=None, intensity=25.0, envmap=None):
    """The same scene for `gantry recover --scene`."""
    if envmap is not None:
        lights = f'[environment]\npath = "{pathlib.Path(envmap).resolve()}"\n'
    else:
        lx, ly, lz = light
        lights = (f'[[lights]]\nkind = "point"\nposition = [{lx}, {ly}, {lz}]\n'
                  f"intensity = [{intensity}, {intensity}, {intensity}]\n")
    return f"""[camera]
position = [0.0, 0.0, 4.0]
look_at = [0.0, 0.0, 0.0]
fov = 32.0
width = {size}
height = {size}

[[objects]]
kind = "sphere"
center = [0.0, 0.0, 0.0]
radius = 1.0
material = "object"

{lights}"""


def render(out, size, spp, bsdf, **light):
    img = mi.render(mi.load_dict(scene_dict(size, spp, bsdf, **light)))
    mi.util.write_bitmap(str(out), img)
    pathlib.Path(out).with_suffix(".toml").write_text(scene_toml(size, **light))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("out", nargs="?")
    ap.add_argument("--study", help="render every photo of the Nielsen study into STUDY/mitsuba/")
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--light", type=float, nargs=3, default=[2.0, 2.0, 4.0])
    ap.add_argument("--intensity", type=float, default=25.0)
    ap.add_argument("--envmap", help="an HDR probe instead of the point light")
    ap.add_argument("--kd", type=float, nargs=3, default=[0.5, 0.3, 0.2])
    ap.add_argument("--spec", help="a toolkit material through the Mitsuba plugin")
    ap.add_argument("--variant", default="llvm_ad_rgb")
    ap.add_argument("--materials", default=",".join(NIELSEN))
    a = ap.parse_args()
    mi.set_variant(a.variant)
    if a.spec or a.study:
        import reflectance.mitsuba
        reflectance.mitsuba.register()

    def bsdf(spec):
        if spec:
            return {"type": "reflectance", "spec": spec}
        return {"type": "diffuse", "reflectance": {"type": "rgb", "value": a.kd}}

    if a.study:
        out = pathlib.Path(a.study) / "mitsuba"
        out.mkdir(parents=True, exist_ok=True)
        probe = probe_path()
        for name in a.materials.split(","):
            b = bsdf(f"nielsen:{name}")
            render(out / f"{name}-probe.exr", 256, 32, b, envmap=probe)
            for i, light in enumerate(STUDY_LIGHTS):
                render(out / f"{name}-point{i}.exr", 128, 16, b, light=light)
            print(f"{name}: 4 photos in {out}", flush=True)
        return
    if not a.out:
        ap.error("OUT (or --study DIR) is required")
    light = {"envmap": a.envmap} if a.envmap else {"light": a.light, "intensity": a.intensity}
    render(a.out, a.size, a.spp, bsdf(a.spec), **light)


if __name__ == "__main__":
    main()
