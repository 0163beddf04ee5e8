"""The Mitsuba comparison images of docs/python.md: spheres of MERL materials rendered by Mitsuba
through the reflectance plugin and by `gantry render sphere`, side by side with their difference.

    python tools/python/sphere_comparison.py --gantry target/release/gantry --out docs/images/python

For each material writes `<name>.png`: Mitsuba (plugin, trilinear table), gantry (the material as
loaded), and |difference| × 4, all in sRGB clipped at 1; prints the image means.
"""

import argparse
import pathlib
import subprocess
import tempfile

import numpy as np
import mitsuba as mi


def srgb8(img):
    x = np.clip(img, 0.0, 1.0)
    x = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    return (x * 255 + 0.5).astype(np.uint8)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--gantry", default="target/release/gantry")
    ap.add_argument("--out", default="docs/images/python")
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("materials", nargs="*", default=["blue-acrylic", "chrome"])
    args = ap.parse_args()
    mi.set_variant("llvm_ad_rgb")
    import reflectance.mitsuba as rm

    rm.register()
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for name in args.materials:
        spec = f"merl:{name}"
        scene = mi.load_dict(rm.sphere_scene({"type": "reflectance", "spec": spec}, args.size, args.spp))
        m = np.array(mi.render(scene, seed=1))
        with tempfile.TemporaryDirectory() as tmp:
            exr = pathlib.Path(tmp) / "g.exr"
            subprocess.run(
                [args.gantry, "render", "sphere", spec, "--size", str(args.size), "--spp",
                 str(args.spp), "--out", str(exr)],
                check=True, capture_output=True,
            )
            g = np.array(mi.Bitmap(str(exr)), dtype=np.float32)[..., :3]
        diff = np.abs(m - g) * 4
        gap = np.ones((args.size, 4, 3), np.float32)
        row = np.concatenate([m, gap, g, gap, diff], axis=1)
        mi.Bitmap(srgb8(row)).write(str(out / f"{name}.png"))
        lit = g.sum(-1) > 0
        print(
            f"{name}: mean Mitsuba {m.mean():.5f}, gantry {g.mean():.5f}, ratio {m.mean() / g.mean():.4f}, "
            f"median |rel diff| over lit pixels {np.median(np.abs(m - g)[lit] / np.maximum(g[lit], 1e-6)):.4f}"
        )


if __name__ == "__main__":
    main()
