#!/usr/bin/env python3
"""Renders the validation photos of `recover` with Mitsuba 3, a renderer that is not ours.

A unit sphere at the origin seen from (0, 0, 4) with a 32° field of view (the scenes of
crates/recover/examples/nielsen_study.rs and docs/recover.md), lit by one point light of
25 W/sr, with an analytic material Mitsuba renders natively:

    diffuse       Lambertian, reflectance R G B   (our `lambert:kd=R/G/B`)

Usage (venv with `pip install mitsuba numpy`):

    python tools/recover/mitsuba_render.py OUT.exr --size 128 --light 2 2 4 --kd 0.5 0.3 0.2

and recover it with the matching scene TOML written beside it (OUT.toml):

    gantry recover --scene OUT.toml --image OUT.exr --model model.bin --out rec.binary
"""
import argparse
import pathlib

import mitsuba as mi


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--light", type=float, nargs=3, default=[2.0, 2.0, 4.0])
    ap.add_argument("--intensity", type=float, default=25.0)
    ap.add_argument("--kd", type=float, nargs=3, default=[0.5, 0.3, 0.2])
    a = ap.parse_args()
    mi.set_variant("scalar_rgb")
    scene = mi.load_dict({
        "type": "scene",
        "integrator": {"type": "direct"},
        "sensor": {
            "type": "perspective",
            "fov": 32.0,
            "fov_axis": "y",
            "to_world": mi.ScalarTransform4f().look_at(
                origin=[0, 0, 4], target=[0, 0, 0], up=[0, 1, 0]),
            "film": {"type": "hdrfilm", "width": a.size, "height": a.size,
                     "rfilter": {"type": "box"}, "pixel_format": "rgb"},
            "sampler": {"type": "independent", "sample_count": a.spp},
        },
        "sphere": {
            "type": "sphere", "center": [0, 0, 0], "radius": 1.0,
            "bsdf": {"type": "diffuse",
                     "reflectance": {"type": "rgb", "value": a.kd}},
        },
        "light": {"type": "point", "position": a.light,
                  "intensity": {"type": "rgb", "value": [a.intensity] * 3}},
    })
    img = mi.render(scene)
    mi.util.write_bitmap(a.out, img)
    toml = pathlib.Path(a.out).with_suffix(".toml")
    lx, ly, lz = a.light
    toml.write_text(f"""[camera]
position = [0.0, 0.0, 4.0]
look_at = [0.0, 0.0, 0.0]
fov = 32.0
width = {a.size}
height = {a.size}

[[objects]]
kind = "sphere"
center = [0.0, 0.0, 0.0]
radius = 1.0
material = "object"

[[lights]]
kind = "point"
position = [{lx}, {ly}, {lz}]
intensity = [{a.intensity}, {a.intensity}, {a.intensity}]
""")


if __name__ == "__main__":
    main()
