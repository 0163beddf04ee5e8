#!/usr/bin/env python3
"""Path-tracing efficiency of `gantry render` against Mitsuba 3 on the same scene.

Scene: a unit sphere of GGX (alpha 0.2, dielectric Fresnel with ior 1.5, no diffuse term) on a
Lambert ground (albedo 0.5) under a constant white sky; camera at (0, 1, 5) looking at (0, 1, 0),
vertical field of view 30 degrees, 160 x 120 pixels, 256 samples per pixel, path tracing with at
most 8 bounces. Each renderer renders the scene with two seeds, each render in its own process
so that start-up (process, scene loading, importance tables, JIT) is part of the time.

    efficiency = variance x wall time (lower is better),
    variance   = mean over pixels and channels of (I_seed1 - I_seed2)^2 / 2

and the ratio printed is gantry's efficiency over Mitsuba's (goal <= 1). The mean images of the
two renderers are compared as well (relative difference of the image means).

The GGX lobes differ in one detail: the toolkit's `ggx` model uses the height-correlated Smith
masking-shadowing term, Mitsuba's `roughconductor` (with eta = 1.5, k = 0, i.e. the dielectric
Fresnel term) the separable one; the difference of the image means is printed.

With `--material SPEC` (e.g. `merl:blue-acrylic`) the sphere is a tabulated material instead:
`gantry render` tabulates it on the MERL grid and builds its importance tables (thesis A.2.4),
and Mitsuba renders the same spec through the toolkit's BSDF plugin (`reflectance.mitsuba`, the
Python package of bindings/python, installed in the same environment), which uploads the same
table and importance tables and evaluates them with Dr.Jit (`scalar_rgb` runs the plugin's Python
code once per lane, which is what that variant offers for a plugin written in Python).

    python3 -m venv .venv && .venv/bin/pip install mitsuba==3.9.1 numpy
    cargo build --release -p gantry
    .venv/bin/python tools/render/mitsuba_compare.py [--gantry target/release/gantry]
        [--variants scalar_rgb,llvm_ad_rgb] [--spp 256] [--repeats 1] [--material SPEC | --lambert]

With `--lambert` the sphere is an analytic Lambert surface of albedo 0.8 (Mitsuba: `diffuse`).
"""
import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

W, H, FOV = 160, 120, 30.0
ALPHA, IOR = 0.2, 1.5
GROUND_ALBEDO = 0.5
LAMBERT_ALBEDO = 0.8
MAX_DEPTH = 8

SCENE_TOML = """
[camera]
position = [0.0, 1.0, 5.0]
look_at = [0.0, 1.0, 0.0]
fov = {fov}
width = {w}
height = {h}

[render]
spp = {spp}
max_depth = {depth}
integrator = "path"
seed = {seed}

[materials.ggx]
spec = "{spec}"
tabulate = {tabulate}

[materials.ground]
spec = "lambert:kd={g}"

[[objects]]
kind = "sphere"
center = [0.0, 1.0, 0.0]
radius = 1.0
material = "ggx"

[[objects]]
kind = "ground"
y = 0.0
size = 40.0
material = "ground"

[environment]
constant = [1.0, 1.0, 1.0]
"""

MITSUBA_CHILD = r"""
import sys, time
import mitsuba as mi
variant, spp, seed, out = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
spec = sys.argv[5] if len(sys.argv) > 5 else None
mi.set_variant(variant)
if spec and spec.startswith("lambert:"):
    sphere_bsdf = {"type": "diffuse",
                   "reflectance": {"type": "rgb", "value": float(spec.split("=")[1])}}
elif spec:
    import reflectance.mitsuba
    reflectance.mitsuba.register()
    sphere_bsdf = {"type": "reflectance", "spec": spec}
else:
    sphere_bsdf = {"type": "roughconductor", "distribution": "ggx", "alpha": %(alpha)f,
                   "eta": %(ior)f, "k": 0.0}
T = mi.ScalarTransform4f
scene = mi.load_dict({
    "type": "scene",
    "integrator": {"type": "path", "max_depth": %(depth)d + 1},
    "sensor": {
        "type": "perspective", "fov": %(fov)f, "fov_axis": "y",
        "to_world": T().look_at(origin=[0, 1, 5], target=[0, 1, 0], up=[0, 1, 0]),
        "film": {"type": "hdrfilm", "width": %(w)d, "height": %(h)d,
                 "rfilter": {"type": "box"}, "pixel_format": "rgb"},
        "sampler": {"type": "independent", "sample_count": spp},
    },
    "sphere": {"type": "sphere", "center": [0, 1, 0], "radius": 1.0,
               "bsdf": sphere_bsdf},
    "ground": {"type": "rectangle",
               "to_world": T().rotate([1, 0, 0], -90).scale(20.0),
               "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": %(g)f}}},
    "sky": {"type": "constant", "radiance": {"type": "rgb", "value": 1.0}},
})
img = mi.render(scene, spp=spp, seed=seed)
mi.util.write_bitmap(out, img)
"""


def read_exr(path):
    import mitsuba as mi
    mi.set_variant("scalar_rgb")
    a = np.array(mi.Bitmap(path), dtype=np.float64)
    return a[..., :3]


def timed(cmd, env=None):
    t = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env)
    return time.perf_counter() - t


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--gantry", default="target/release/gantry")
    ap.add_argument("--variants", default="scalar_rgb,llvm_ad_rgb")
    ap.add_argument("--spp", type=int, default=256)
    ap.add_argument("--repeats", type=int, default=1, help="timed renders per seed (median)")
    ap.add_argument("--material", default=None,
                    help="a tabulated material spec for the sphere (default: the analytic GGX)")
    ap.add_argument("--lambert", action="store_true",
                    help=f"an analytic Lambert sphere (albedo {LAMBERT_ALBEDO}) instead of the GGX; "
                         "Mitsuba renders its `diffuse` BSDF")
    args = ap.parse_args()
    if not os.path.exists(args.gantry):
        sys.exit(f"{args.gantry} not found: run `cargo build --release -p gantry` first")
    tmp = tempfile.mkdtemp(prefix="mitsuba_compare_")
    params = dict(fov=FOV, w=W, h=H, spp=args.spp, depth=MAX_DEPTH, alpha=ALPHA, ior=IOR,
                  g=GROUND_ALBEDO)
    child = os.path.join(tmp, "mitsuba_child.py")
    with open(child, "w") as f:
        f.write(MITSUBA_CHILD % params)

    results = {}

    def run_gantry(seed):
        scene = os.path.join(tmp, f"scene{seed}.toml")
        with open(scene, "w") as f:
            if args.material:
                sphere = dict(spec=args.material, tabulate="true")
            elif args.lambert:
                sphere = dict(spec=f"lambert:kd={LAMBERT_ALBEDO}", tabulate="false")
            else:
                sphere = dict(spec=f"ggx:alpha={ALPHA},kd=0,ks=1,ior={IOR}", tabulate="false")
            f.write(SCENE_TOML.format(seed=seed, **params, **sphere))
        out = os.path.join(tmp, f"gantry{seed}.exr")
        t = statistics.median(
            timed([args.gantry, "render", scene, "--spp", str(args.spp), "--out", out])
            for _ in range(args.repeats))
        return t, read_exr(out)

    def run_mitsuba(variant, seed):
        out = os.path.join(tmp, f"{variant}{seed}.exr")
        t = statistics.median(
            timed([sys.executable, child, variant, str(args.spp), str(seed), out]
                  + ([args.material] if args.material else [])
                  + ([f"lambert:kd={LAMBERT_ALBEDO}"] if args.lambert else []))
            for _ in range(args.repeats))
        return t, read_exr(out)

    renderers = [("gantry render", run_gantry)]
    for v in args.variants.split(","):
        renderers.append((f"mitsuba {v}", lambda s, v=v: run_mitsuba(v, s)))
    # Interleaved: seed 1 of every renderer, then seed 2.
    runs = {name: [] for name, _ in renderers}
    for seed in (1, 2):
        for name, f in renderers:
            if runs[name] is None:  # failed with the first seed
                continue
            try:
                runs[name].append(f(seed))
            except subprocess.CalledProcessError as e:
                print(f"{name}: failed ({e.stderr.decode(errors='replace').strip()[-300:]})")
                runs[name] = None
    for name, r in runs.items():
        if not r or len(r) < 2:
            continue
        (t1, a), (t2, b) = r
        var = float(np.mean((a - b) ** 2) / 2.0)
        t = (t1 + t2) / 2.0
        results[name] = (t, var, var * t, float(np.mean((a + b) / 2.0)))
    ref = results.get("gantry render")
    sphere = args.material or (f"Lambert (albedo {LAMBERT_ALBEDO})" if args.lambert
                               else f"GGX (alpha {ALPHA})")
    print(f"scene: {sphere} sphere on Lambert ground under a constant sky, "
          f"{W}x{H}, {args.spp} spp, path tracing, max depth {MAX_DEPTH}")
    for name, (t, var, eff, mean) in results.items():
        line = f"{name:24s} wall {t:7.2f} s  variance {var:.4e}  efficiency {eff:.4e}  mean {mean:.5f}"
        if ref and name != "gantry render":
            line += (f"  | gantry/this: efficiency ratio {ref[2] / eff:.2f}, time ratio "
                     f"{ref[0] / t:.2f}, variance ratio {ref[1] / var:.2f}, mean diff "
                     f"{(ref[3] - mean) / mean * 100:+.2f} %")
        print(line)


if __name__ == "__main__":
    main()
