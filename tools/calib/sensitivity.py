#!/usr/bin/env python3
"""Sensitivity of the measured BRDF to calibration errors (docs/calib.md).

Runs `gantry capture --sim` once with the simulator's true geometry (baseline) and then once per
perturbed calibration file, each perturbation changing ONE parameter of the true geometry, and
tabulates `truth_table_error` (median and 90th percentile of |ln(measured / true)| over the
MERL bins) from DIR/report.json.

The true geometry is the baseline's DIR/calibration.json (written from the simulator's truth by
`--true-geometry`; the same schema and values as `gantry calibrate --sim`'s truth.json at the
same scale). Pixel perturbations are given in full-resolution pixels (1300 x 1030) and scaled to
the capture's sensor scale, so that they describe the same angular error.

Usage:
  python3 tools/calib/sensitivity.py --out /tmp/calib_sensitivity [--scale 0.25]
      [--positions 110] [--material merl:blue-acrylic] [--tenfold]
Environment: GANTRY = command of the gantry binary (default: cargo run --release -p gantry --),
BRDF_DATA_DIR as for every gantry run.
"""

import argparse
import copy
import json
import math
import os
import shlex
import subprocess
import sys
import tempfile
import time

import numpy as np


def rotation_about(axis, angle_rad):
    """Rotation matrix about a unit axis (Rodrigues)."""
    a = np.asarray(axis, float)
    a = a / np.linalg.norm(a)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(angle_rad) * k + (1 - math.cos(angle_rad)) * (k @ k)


def perturbations(scale, factor):
    """(name, function editing a calibration dict) for every parameter, `factor` x the issue's
    tolerance."""

    def cam(key, fn):
        def edit(c):
            c["camera"][key] = fn(c["camera"][key])

        return edit

    def rotate_camera(angle_deg):
        # Camera turned about its own x axis (up/down), about its centre: the centre
        # C = -R^T t stays, the pointing changes.
        def edit(c):
            r = np.array(c["pose"]["rotation"])
            t = np.array(c["pose"]["translation"])
            centre = -r.T @ t
            r2 = rotation_about([1, 0, 0], math.radians(angle_deg)) @ r
            c["pose"]["rotation"] = r2.tolist()
            c["pose"]["translation"] = (-r2 @ centre).tolist()

        return edit

    def translate_camera(mm):
        # t moved along the camera's x axis (sideways in the image).
        def edit(c):
            c["pose"]["translation"][0] += mm * 1e-3

        return edit

    def move_lamp_centre(mm):
        # Lamp-circle centre moved along the circle's reference direction (in its plane).
        def edit(c):
            ref = np.array(c["lamp"]["reference"])
            c["lamp"]["centre"] = (np.array(c["lamp"]["centre"]) + mm * 1e-3 * ref).tolist()

        return edit

    def lamp_radius(mm):
        def edit(c):
            c["lamp"]["radius"] += mm * 1e-3

        return edit

    def move_sphere(mm):
        # Sphere centre moved sideways as seen by the camera (camera x axis in the world).
        def edit(c):
            r = np.array(c["pose"]["rotation"])
            side = r[0]  # camera x axis in world coordinates
            c["sphere"]["centre"] = (np.array(c["sphere"]["centre"]) + mm * 1e-3 * side).tolist()

        return edit

    def shift_cx_compensated(px):
        # What the calibration actually produces at a narrow field of view: cx off by `px`
        # and the extrinsic rotation absorbing it (camera turned about its y axis, about its
        # centre, so that the sphere centre projects where it did).
        def project(c, p):
            r = np.array(c["pose"]["rotation"])
            q = r @ p + np.array(c["pose"]["translation"])
            x, y = q[0] / q[2], q[1] / q[2]
            k = c["camera"]
            r2 = x * x + y * y
            d = 1 + r2 * (k["k1"] + k["k2"] * r2)
            return np.array([k["fx"] * x * d + k["cx"], k["fy"] * y * d + k["cy"]])

        def edit(c):
            target = np.array(c["sphere"]["centre"])
            before = project(c, target)
            c["camera"]["cx"] += px
            r = np.array(c["pose"]["rotation"])
            t = np.array(c["pose"]["translation"])
            centre = -r.T @ t
            best = None
            for sign in (1.0, -1.0):
                r2 = rotation_about([0, 1, 0], sign * px / c["camera"]["fx"]) @ r
                trial = copy.deepcopy(c)
                trial["pose"]["rotation"] = r2.tolist()
                trial["pose"]["translation"] = (-r2 @ centre).tolist()
                miss = np.linalg.norm(project(trial, target) - before)
                if best is None or miss < best[0]:
                    best = (miss, trial)
            c["pose"] = best[1]["pose"]

        return edit

    f = factor
    extra = []
    if factor == 1:
        extra = [(
            "cx +10 px, rotation absorbing it",
            shift_cx_compensated(10 * scale),
        )]
    return [
        (f"fx +{0.2 * f:g} %", cam("fx", lambda v: v * (1 + 0.002 * f))),
        (f"cx +{1 * f:g} px", cam("cx", lambda v: v + 1 * f * scale)),
        (f"cx +{10 * f:g} px", cam("cx", lambda v: v + 10 * f * scale)),
        (f"k1 +{5 * f:g} %", cam("k1", lambda v: v * (1 + 0.05 * f))),
        (f"rotation {0.05 * f:g} deg", rotate_camera(0.05 * f)),
        (f"translation {0.5 * f:g} mm", translate_camera(0.5 * f)),
        (f"lamp centre {0.5 * f:g} mm", move_lamp_centre(0.5 * f)),
        (f"lamp radius +{0.3 * f:g} mm", lamp_radius(0.3 * f)),
        (f"sphere centre {0.1 * f:g} mm", move_sphere(0.1 * f)),
    ] + extra


def write_json_atomic(path, value):
    d = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(dir=d, prefix=".tmp-")
    with os.fdopen(fd, "w") as fh:
        json.dump(value, fh, indent=2)
    os.replace(tmp, path)


def capture(gantry, args, out, extra):
    cmd = gantry + [
        "capture", "--sim", "--material", args.material, "--positions", str(args.positions),
        "--scale", str(args.scale), "--seed", str(args.seed), "--out", out,
    ] + extra
    t0 = time.time()
    res = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    if res.returncode != 0:
        sys.stderr.write(res.stderr[-4000:])
        raise SystemExit(f"failed: {' '.join(cmd)}")
    with open(os.path.join(out, "report.json")) as fh:
        err = json.load(fh)["truth_table_error"]
    return err, time.time() - t0


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, help="work directory (one capture per subdirectory)")
    p.add_argument("--scale", type=float, default=0.25)
    p.add_argument("--positions", type=int, default=110)
    p.add_argument("--material", default="merl:blue-acrylic")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--tenfold", action="store_true", help="also run 10x every perturbation")
    args = p.parse_args()
    gantry = shlex.split(os.environ.get("GANTRY", "cargo run --release -q -p gantry --"))
    os.makedirs(args.out, exist_ok=True)
    results = []
    base_dir = os.path.join(args.out, "baseline")
    if not os.path.exists(os.path.join(base_dir, "report.json")):
        err, secs = capture(gantry, args, base_dir, ["--true-geometry"])
    else:
        with open(os.path.join(base_dir, "report.json")) as fh:
            err, secs = json.load(fh)["truth_table_error"], 0.0
    results.append(("true geometry", err))
    print(f"true geometry: {err} ({secs:.0f} s)", flush=True)
    with open(os.path.join(base_dir, "calibration.json")) as fh:
        truth = json.load(fh)
    factors = [1, 10] if args.tenfold else [1]
    for factor in factors:
        for i, (name, edit) in enumerate(perturbations(args.scale, factor)):
            if factor == 10 and i == 1:
                continue  # 10 x (cx +1 px) is the 1 x (cx +10 px) run
            run = os.path.join(args.out, f"x{factor}_{i}")
            if os.path.exists(os.path.join(run, "report.json")):
                with open(os.path.join(run, "report.json")) as fh:
                    err, secs = json.load(fh)["truth_table_error"], 0.0
            else:
                cal = copy.deepcopy(truth)
                edit(cal)
                os.makedirs(run, exist_ok=True)
                path = os.path.join(args.out, f"calibration_x{factor}_{i}.json")
                write_json_atomic(path, cal)
                err, secs = capture(gantry, args, run, ["--calibration", path])
            results.append((name, err))
            print(f"{name}: {err} ({secs:.0f} s)", flush=True)
    base = results[0][1]
    print()
    print("| calibration error | median abs ln | p90 abs ln | median change | p90 change |")
    print("| --- | --- | --- | --- | --- |")
    for name, e in results:
        print(
            f"| {name} | {e['median_abs_log']:.4f} | {e['p90_abs_log']:.4f} | "
            f"{e['median_abs_log'] - base['median_abs_log']:+.4f} | "
            f"{e['p90_abs_log'] - base['p90_abs_log']:+.4f} |"
        )
    write_json_atomic(
        os.path.join(args.out, "sensitivity.json"),
        [{"perturbation": n, "truth_table_error": e} for n, e in results],
    )


if __name__ == "__main__":
    main()
