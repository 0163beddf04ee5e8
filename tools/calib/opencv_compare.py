#!/usr/bin/env python3
"""Side by side: OpenCV and `gantry calibrate intrinsics` on the same checkerboard photographs
with the same distortion model.

OpenCV: findChessboardCorners + cornerSubPix (11x11 window) + calibrateCamera with the flags of
the model. Ours: the gantry binary's camera.json. Both RMS figures are per point (OpenCV's).

    python3 -m venv /work/wt/venv-calib && /work/wt/venv-calib/bin/pip install opencv-python-headless numpy
    cargo build --release -p gantry
    /work/wt/venv-calib/bin/python tools/calib/opencv_compare.py \
        --images '/work/shared/data/real/chessboard/left*.jpg' --board 9x6 --square 0.025 \
        --model k1k2 [--gantry target/release/gantry]
"""
import argparse, glob, json, os, subprocess, sys, tempfile

import cv2
import numpy as np

FLAGS = {
    "k1": cv2.CALIB_FIX_K2 | cv2.CALIB_FIX_K3 | cv2.CALIB_ZERO_TANGENT_DIST,
    "k1k2": cv2.CALIB_FIX_K3 | cv2.CALIB_ZERO_TANGENT_DIST,
    "k1k2k3": cv2.CALIB_ZERO_TANGENT_DIST,
    "k1k2p1p2k3": 0,
}


def opencv(files, cols, rows, square, model, fix_aspect):
    obj = np.zeros((cols * rows, 3), np.float32)
    obj[:, :2] = np.mgrid[0:cols, 0:rows].T.reshape(-1, 2) * square
    objs, imgs, size, found = [], [], None, 0
    for f in files:
        g = cv2.imread(f, cv2.IMREAD_GRAYSCALE)
        size = (g.shape[1], g.shape[0])
        ok, c = cv2.findChessboardCorners(g, (cols, rows))
        if not ok:
            continue
        found += 1
        crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 30, 0.001)
        c = cv2.cornerSubPix(g, c, (11, 11), (-1, -1), crit)
        objs.append(obj)
        imgs.append(c)
    flags = FLAGS[model] | (cv2.CALIB_FIX_ASPECT_RATIO if fix_aspect else 0)
    k0 = np.eye(3)
    rms, k, d, _, _ = cv2.calibrateCamera(objs, imgs, size, k0, None, flags=flags)
    d = d.ravel().tolist() + [0.0] * 5
    return {
        "found": found,
        "fx": k[0, 0], "fy": k[1, 1], "cx": k[0, 2], "cy": k[1, 2],
        "dist": d[:5], "rms": rms,
    }


def ours(args, files):
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "camera.json")
        cmd = [args.gantry, "calibrate", "intrinsics", "--images", args.images,
               "--board", args.board, "--square", str(args.square), "--model", args.model,
               "--out", out, "--corners-dir", os.path.join(tmp, "corners")]
        if args.fix_aspect:
            cmd.append("--fix-aspect")
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
        j = json.load(open(out))
    c = j["camera"]
    return {
        "found": j["views_used"],
        "fx": c["fx"], "fy": c["fy"], "cx": c["cx"], "cy": c["cy"],
        "dist": [c.get(k, 0.0) for k in ("k1", "k2", "p1", "p2", "k3")],
        "rms": j["rms_point_px"],
    }


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--images", default="/work/shared/data/real/chessboard/left*.jpg")
    p.add_argument("--board", default="9x6", help="inner corners COLSxROWS")
    p.add_argument("--square", type=float, default=0.025)
    p.add_argument("--model", default="k1k2", choices=sorted(FLAGS))
    p.add_argument("--fix-aspect", action="store_true")
    p.add_argument("--gantry", default="target/release/gantry")
    p.add_argument("--opencv-only", action="store_true", help="print OpenCV's figures only")
    args = p.parse_args()
    files = sorted(glob.glob(args.images))
    if not files:
        sys.exit(f"no file matches {args.images}")
    cols, rows = (int(v) for v in args.board.lower().split("x"))
    cv = opencv(files, cols, rows, args.square, args.model, args.fix_aspect)
    rows_out = [("OpenCV " + cv2.__version__, cv)]
    if not args.opencv_only:
        rows_out.append(("gantry", ours(args, files)))
    print(f"{len(files)} images, board {args.board} inner corners, model {args.model}")
    print(f"{'':16} {'found':>5} {'fx':>10} {'fy':>10} {'cx':>9} {'cy':>9} {'RMS px':>8}  k1 k2 p1 p2 k3")
    for name, r in rows_out:
        d = " ".join(f"{v:+.5f}" for v in r["dist"])
        print(f"{name:16} {r['found']:>5} {r['fx']:10.4f} {r['fy']:10.4f} {r['cx']:9.4f} {r['cy']:9.4f} {r['rms']:8.4f}  {d}")
    if len(rows_out) == 2:
        a, b = rows_out[0][1], rows_out[1][1]
        print(f"gantry vs OpenCV: fx {100 * (b['fx'] / a['fx'] - 1):+.3f}%, fy {100 * (b['fy'] / a['fy'] - 1):+.3f}%, "
              f"cx {b['cx'] - a['cx']:+.2f} px, cy {b['cy'] - a['cy']:+.2f} px, RMS x{b['rms'] / a['rms']:.3f}")


if __name__ == "__main__":
    main()
