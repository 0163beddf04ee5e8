"""Render time of the Mitsuba plugin against Mitsuba's own roughconductor on the same scene.

The scene is the figure of `gantry render sphere` (reflectance.mitsuba.sphere_scene): a 256 × 256
sphere under one point light, 64 spp, Mitsuba's path integrator (so both BSDFs are sampled and
evaluated). Each render is timed cold (first call: Dr.Jit traces and compiles the kernel) and warm
(median of the next three); plugin construction (tabulation + importance tables) is timed apart.

    python tools/python/mitsuba_timing.py [--variant llvm_ad_rgb] [--size 256] [--spp 64]
"""

import argparse
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


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--variant", default="llvm_ad_rgb")
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--spp", type=int, default=64)
    args = ap.parse_args()
    mi.set_variant(args.variant)
    import reflectance.mitsuba as rm

    rm.register()
    bsdfs = {
        "reflectance merl:chrome": {"type": "reflectance", "spec": "merl:chrome"},
        "reflectance merl:blue-acrylic": {"type": "reflectance", "spec": "merl:blue-acrylic"},
        "roughconductor (GGX, alpha 0.1, Al)": {
            "type": "roughconductor",
            "distribution": "ggx",
            "alpha": 0.1,
            "material": "Al",
        },
    }
    integrator = {"type": "path", "max_depth": 8}
    print(f"variant {args.variant}, {args.size}x{args.size}, {args.spp} spp, path integrator")
    print(f"{'BSDF':40s} {'load s':>8s} {'cold s':>8s} {'warm s':>8s}")
    for name, b in bsdfs.items():
        t0 = time.perf_counter()
        scene = mi.load_dict(rm.sphere_scene(b, size=args.size, spp=args.spp, integrator=integrator))
        load = time.perf_counter() - t0
        cold, warm, _ = timed_renders(scene)
        print(f"{name:40s} {load:8.2f} {cold:8.2f} {warm:8.2f}")


if __name__ == "__main__":
    main()
