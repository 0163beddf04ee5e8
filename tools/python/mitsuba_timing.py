"""Render time of the Mitsuba plugin against Mitsuba's own BSDFs on the same scene.

The scene is the figure of `gantry render sphere` (reflectance.mitsuba.sphere_scene): a 256 × 256
sphere at 64 spp with Mitsuba's path integrator (so every BSDF is sampled and evaluated), lit either
by its point light or by the shared HDR light probe (`real/envmap/venice_sunset_1k.exr` of the
shared data, `BRDF_DATA_DIR`). Each render is timed cold (first call: Dr.Jit traces and compiles
the kernel) and warm (median of the next `--repeats`); plugin construction (tabulation and
importance tables) is timed apart. The ratio column divides each warm time by that of Mitsuba's
`roughplastic` under the same light.

    python tools/python/mitsuba_timing.py [--variant llvm_ad_rgb] [--size 256] [--spp 64]
        [--light point|probe|both] [--repeats 3] [--only NAME ...]
"""

import argparse
import os
import pathlib
import statistics
import time

import drjit as dr
import mitsuba as mi


def timed_renders(scene, repeats=3):
    """Cold time, median warm time and the last image of `repeats` + 1 renders of `scene`."""
    t0 = time.perf_counter()
    img = mi.render(scene, seed=0)
    dr.eval(img)
    dr.sync_thread()
    cold = time.perf_counter() - t0
    warm = []
    for s in range(1, repeats + 1):
        t0 = time.perf_counter()
        img = mi.render(scene, seed=s)
        dr.eval(img)
        dr.sync_thread()
        warm.append(time.perf_counter() - t0)
    return cold, statistics.median(warm), img


def probe_path():
    """The shared HDR light probe (an error naming BRDF_DATA_DIR when it is missing)."""
    default = pathlib.Path(__file__).resolve().parents[3] / "shared" / "data"
    data = pathlib.Path(os.environ.get("BRDF_DATA_DIR", default))
    path = data / "real" / "envmap" / "venice_sunset_1k.exr"
    if not path.is_file():
        raise SystemExit(f"the light probe is missing at {path} (set BRDF_DATA_DIR)")
    return path


def scene_dict(rm, bsdf, light, size, spp):
    """The sphere figure with `bsdf`, lit by its point light or by the probe."""
    d = rm.sphere_scene(bsdf, size=size, spp=spp, integrator={"type": "path", "max_depth": 8})
    if light == "probe":
        del d["light"]
        d["light"] = {"type": "envmap", "filename": str(probe_path())}
    return d


BSDFS = {
    "reflectance merl:blue-acrylic": {"type": "reflectance", "spec": "merl:blue-acrylic"},
    "reflectance merl:chrome": {"type": "reflectance", "spec": "merl:chrome"},
    "roughplastic (GGX, alpha 0.1)": {
        "type": "roughplastic",
        "distribution": "ggx",
        "alpha": 0.1,
        "diffuse_reflectance": {"type": "rgb", "value": [0.05, 0.1, 0.4]},
    },
    "roughconductor (GGX, alpha 0.1, Al)": {
        "type": "roughconductor",
        "distribution": "ggx",
        "alpha": 0.1,
        "material": "Al",
    },
}
REFERENCE = "roughplastic (GGX, alpha 0.1)"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--variant", default="llvm_ad_rgb")
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--light", choices=["point", "probe", "both"], default="both")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--only", nargs="*", help="substrings of the BSDF names to time (and the reference)")
    args = ap.parse_args()
    mi.set_variant(args.variant)
    import reflectance.mitsuba as rm

    rm.register()
    names = [
        n for n in BSDFS if not args.only or n == REFERENCE or any(s in n for s in args.only)
    ]
    # the reference first, so that every other line can show its ratio
    names.sort(key=lambda n: n != REFERENCE)
    lights = ["point", "probe"] if args.light == "both" else [args.light]
    print(f"variant {args.variant}, {args.size}x{args.size}, {args.spp} spp, path integrator")
    print(f"{'light':6s} {'BSDF':38s} {'load s':>7s} {'cold s':>7s} {'warm s':>7s} {'ratio':>6s}")
    for light in lights:
        reference = None
        for name in names:
            t0 = time.perf_counter()
            scene = mi.load_dict(scene_dict(rm, BSDFS[name], light, args.size, args.spp))
            load = time.perf_counter() - t0
            cold, warm, _ = timed_renders(scene, args.repeats)
            if reference is None:
                reference = warm
            print(
                f"{light:6s} {name:38s} {load:7.2f} {cold:7.2f} {warm:7.3f} {warm / reference:6.2f}",
                flush=True,
            )


if __name__ == "__main__":
    main()
