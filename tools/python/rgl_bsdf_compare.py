"""Mitsuba 3's own `measured` BSDF on files written by the toolkit, against the toolkit's plugin
on the same material: image means, per-pixel relative RMS and render times, under the point
light of `reflectance.mitsuba.sphere_scene` and under the shared light probe.

Both BSDFs get the same data: each material is tabulated once (MERL `.binary`), the plugin reads
that table (trilinear) and the `.bsdf` file is written from it.

    BRDF_DATA_DIR=/work/shared/data python tools/python/rgl_bsdf_compare.py \
        [--variant llvm_ad_rgb] [--size 128] [--spp 64] [--resolution 32] [MATERIAL ...]
"""

import argparse
import os
import pathlib
import tempfile

import mitsuba as mi
import numpy as np
from mitsuba_timing import timed_renders

DEFAULT = ["lambert:kd=0.6", "merl:blue-acrylic", "merl:pink-felt", "merl:chrome", "merl:yellow-paint"]


def render(scene_dict, repeats=2):
    """The image and the median warm render time."""
    _, warm, img = timed_renders(mi.load_dict(scene_dict), repeats)
    return np.array(img), warm


def with_probe(scene, probe):
    scene = dict(scene)
    del scene["light"]
    scene["light"] = {"type": "envmap", "filename": str(probe)}
    scene["integrator"] = {"type": "path", "max_depth": 3}
    return scene


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("materials", nargs="*", default=DEFAULT)
    ap.add_argument("--variant", default="llvm_ad_rgb")
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--resolution", type=int, default=32)
    args = ap.parse_args()
    mi.set_variant(args.variant)
    import reflectance
    import reflectance.mitsuba as rm

    rm.register()
    data = pathlib.Path(os.environ.get("BRDF_DATA_DIR", pathlib.Path(__file__).resolve().parents[3] / "shared" / "data"))
    probe = data / "real" / "envmap" / "venice_sunset_1k.exr"
    print(f"variant {args.variant}, {args.size}x{args.size}, {args.spp} spp, .bsdf grid {args.resolution}")
    print("| material | light | mean difference R / G / B (%) | per-pixel relative RMS | plugin s | measured s |")
    print("|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as d:
        for spec in args.materials:
            table = pathlib.Path(d) / "m.binary"
            reflectance.load(spec).write_merl(table)
            bsdf_file = pathlib.Path(d) / "m.bsdf"
            reflectance.load(str(table), interpolation="trilinear").save_bsdf(bsdf_file, resolution=args.resolution)
            plugin = {"type": "reflectance", "spec": str(table)}
            measured = {"type": "measured", "filename": str(bsdf_file)}
            for light in ("point", "probe"):
                scenes = [rm.sphere_scene(b, size=args.size, spp=args.spp) for b in (plugin, measured)]
                if light == "probe":
                    scenes = [with_probe(s, probe) for s in scenes]
                (a, ta), (b, tb) = (render(s) for s in scenes)
                ma, mb = a.reshape(-1, 3).mean(0), b.reshape(-1, 3).mean(0)
                lit = a.sum(-1) > 1e-4 * a.sum(-1).max()
                rms = np.sqrt(np.mean(((b - a)[lit]) ** 2) / np.mean(a[lit] ** 2))
                diff = " / ".join(f"{x:+.2f}" for x in (mb - ma) / ma * 100)
                print(f"| {spec} | {light} | {diff} | {rms:.3f} | {ta:.2f} | {tb:.2f} |", flush=True)


if __name__ == "__main__":
    main()
