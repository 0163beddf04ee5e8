#!/usr/bin/env python3
"""Writes the small seed corpora of the fuzz targets into fuzz/seeds/<target>/ (committed).

Binary seeds follow the layouts the project's writers document (gantry_hal::encode_frames,
binning::PositionSamples::to_bytes); text seeds are short valid inputs of each parser. Seeds
that already exist in the repository (the rig example, a scene, an EXR fixture, NBRDF weights)
are passed to libFuzzer with -seed_inputs by run.sh instead of being copied. Re-running this
script rewrites the same bytes.
"""
import os, struct, zlib

HERE = os.path.dirname(os.path.abspath(__file__))


def put(target, name, data):
    d = os.path.join(HERE, "seeds", target)
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, name), "wb") as f:
        f.write(data if isinstance(data, bytes) else data.encode())


def frames(frames, magic=b"GBFRAME2", crc=True):
    out = bytearray(magic) + struct.pack("<I", len(frames))
    for (w, h, depth, pattern, exposure, data) in frames:
        out += struct.pack("<IIBBdddQ", w, h, depth, pattern, exposure, 1.5, 25.0, 7)
        out += b"".join(struct.pack("<H", v) for v in data)
    if crc:
        out += struct.pack("<I", zlib.crc32(out) & 0xFFFFFFFF)
    return bytes(out)


def fnv1a(data):
    h = 0xCBF29CE484222325
    for b in data:
        h ^= b
        h = (h * 0x100000001B3) & 0xFFFFFFFFFFFFFFFF
    return h


def samples(position, angle, recs):
    body = b"".join(struct.pack("<If", k, v) for k, v in recs)
    head = b"GBSAMPL1" + struct.pack("<IdQ", position, angle, len(recs))
    return head + body + struct.pack("<Q", fnv1a(body))


two = [(2, 2, 10, 0, 0.01, [1, 2, 3, 1023]), (2, 2, 10, 0, 0.04, [4, 8, 12, 1023])]
put("frames", "seed-two", frames(two))
put("frames", "seed-v1", frames(two[:1], magic=b"GBFRAME1", crc=False))
put("frames_structured", "seed-two", frames(two)[8:-4])
recs = [(0, 0.5), (1458000 + 17, 0.25), (2 * 1458000 + 99, 1.0)]
put("samples_checkpoint", "seed-three", samples(3, 12.5, recs))
s = samples(3, 12.5, recs)
put("samples_checkpoint_structured", "seed-three", s[8:12] + s[12:20] + b"\x00" + s[28:-8])
# MERL header (the parser wants 90 x 90 x 180 and the whole body; the header paths).
put("merl_binary", "seed-header", struct.pack("<iii", 90, 90, 180) + bytes(64))
put("merl_binary", "seed-small", struct.pack("<iii", 2, 2, 2) + struct.pack("<24d", *([0.1] * 24)))
npy_header = "{'descr': '<f4', 'fortran_order': False, 'shape': (2, 3), }"
npy_header += " " * (63 - len(npy_header) % 64) + "\n"
put("npy", "seed-f4", b"\x93NUMPY\x01\x00" + struct.pack("<H", len(npy_header)) + npy_header.encode()
    + struct.pack("<6f", 1, 2, 3, 4, 5, 6))
for i, spec in enumerate(["merl:blue-acrylic", "nielsen:white-paint", "ggx:alpha=0.3,kd=0.2/0.1/0.05,ks=0.04",
                          "lambert:0.5/0.5/0.5", "phong:kd=0.1,ks=0.2,n=30", "table:/tmp/x.binary"]):
    put("material_spec", f"seed-{i}", spec)
for i, line in enumerate(["ok", "error:9", "ALARM:1", "<Idle|MPos:12.500,0.000,-1.250|FS:0,0|A:SF>",
                          "<Run|WPos:1,2,3|FS:600,0>", "Grbl 1.1h ['$' for help]", "[MSG:'$H'|'$X' to unlock]",
                          "ok\r\n<Hold:0|MPos:0.000,0.000,0.000|FS:0,0>\r\nALARM:3"]):
    put("grbl_response", f"seed-{i}", line)
put("obj", "seed-tetra", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nvn 0 0 1\nvt 0 0\nf 1 2 3\nf 1//1 2//1 4//1\nf 2/1/1 3/1/1 4/1/1\n")
put("plan_csv", "seed", "theta_h,theta_d,phi_d,channel\n0.1,0.2,0.3,0\n1.0,0.5,2.0,2\n")
put("values_csv", "seed", "theta_h,theta_d,phi_d,channel,value\n0.1,0.2,0.3,0,0.25\n1.0,0.5,2.0,2,1e-3\n")
put("angles_csv", "seed", "theta_h,theta_d,phi_d\n0.1,0.2,0.3\n0.5,1.0,1.5\n")
put("opencv_yaml", "seed", """%YAML:1.0
---
image_width: 640
image_height: 480
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 800., 0., 320., 0., 800., 240., 0., 0., 1. ]
distortion_coefficients: !!opencv-matrix
   rows: 1
   cols: 5
   dt: d
   data: [ -0.1, 0.01, 0., 0., 0. ]
avg_reprojection_error: 0.2
""")
put("recovery_scene_toml", "seed", """[camera]
position = [0.0, 0.0, 3.0]
look_at = [0.0, 0.0, 0.0]
fov_deg = 30.0

[[lights]]
position = [1.0, 1.0, 2.0]
intensity = [1.0, 1.0, 1.0]

[object]
sphere = { center = [0.0, 0.0, 0.0], radius = 1.0 }

[[photos]]
path = "photo.exr"
""")
put("calibration_json", "seed-version", '{"version": 2, "camera": {"width": 64, "height": 48}}')
# Model files: the magic and a short body (the writers' headers).
put("reduce_model", "seed-magic", b"BRDFMODL" + bytes(32))
put("sampling_model", "seed-magic", b"SMPLMODL" + bytes(32))
put("wavelet_basis", "seed-magic", b"CWBASIS1" + bytes(32))
put("wavelet_tree", "seed-magic", b"GWTREE01" + bytes(32))
# Radiance .hdr: a flat 4×2 image and a 16×2 image with new-style run-length scanlines.
hdr_head = lambda w, h: f"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\nEXPOSURE=1.0\n\n-Y {h} +X {w}\n".encode()
put("radiance_hdr", "seed-flat", hdr_head(4, 2) + bytes([128, 64, 32, 129] * 8))
rle_line = bytes([2, 2, 0, 16]) + b"".join(bytes([0x80 + 16, v]) for v in (200, 100, 50, 130))
put("radiance_hdr", "seed-rle", hdr_head(16, 2) + rle_line * 2)
# Upload endpoint: file name, a zero byte, then the body (a MERL header and a short body).
for target in ("upload", "upload_http"):
    put(target, "seed-header", b"felt.binary\0" + struct.pack("<iii", 90, 90, 180) + bytes(64))
    put(target, "seed-path", b"../../x y.binary\0" + struct.pack("<iii", 2, 2, 2))
# Structured MERL bodies: a first byte (interpolation), then (u32 bin index, f64 value) patches.
patch = lambda pairs: b"".join(struct.pack("<Id", i, v) for i, v in pairs)
put("merl_binary_structured", "seed-missing", b"\x00" + patch([(0, -1.0), (90 * 180 + 7, -1.0), (2 * 1458000 + 5, 1e3)]))
put("merl_binary_structured", "seed-trilinear", b"\x01" + patch([(i * 9973, -1.0 if i % 3 else 50.0) for i in range(40)]))
put("merl_binary_structured", "seed-nan", b"\x01" + patch([(12, float("nan"))]))
# zarr_store seeds (fuzz/seeds/zarr_store, committed) are not written here: each is a real
# store's compact `values/zarr.json`, a zero byte and its chunk `c/0/0`, from
# `gantry corpus pack lambert:kd=0.5 ggx:alpha=0.2 --grid 15 --bins-per-chunk 2048
# --materials-per-chunk 2 --out a.zarr` (and `--dtype f32 --bins-per-chunk 512
# --materials-per-chunk 1` for the f32 seed).
