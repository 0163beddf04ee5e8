"""Materials: loading, evaluation against `gantry eval`, tabulation, MERL files, summaries."""

import csv
import io
import math
import subprocess

import numpy as np
import pytest

import reflectance


def gantry_eval(gantry, spec, angles, tmp_path, interp="nearest"):
    path = tmp_path / "angles.csv"
    with open(path, "w") as f:
        f.write("theta_h,theta_d,phi_d\n")
        for th, td, pd in angles:
            f.write(f"{float(th)!r},{float(td)!r},{float(pd)!r}\n")
    out = subprocess.run(
        [gantry, "eval", spec, "--angles", str(path), "--interp", interp],
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    rows = list(csv.DictReader(io.StringIO(out)))
    return np.array([[float(r["r"]), float(r["g"]), float(r["b"])] for r in rows])


def random_angles(n, seed):
    rng = np.random.default_rng(seed)
    return np.stack(
        [
            rng.uniform(0, math.pi / 2, n),
            rng.uniform(0, math.pi / 2, n),
            rng.uniform(0, 2 * math.pi, n),
        ],
        axis=1,
    )


def assert_relative(a, b, tol):
    scale = np.maximum(np.abs(b), 1e-300)
    both_zero = (a == 0) & (b == 0)
    rel = np.where(both_zero, 0.0, np.abs(a - b) / scale)
    assert rel.max() <= tol, f"max relative difference {rel.max():.3g}"


@pytest.mark.parametrize(
    "spec",
    ["merl:blue-acrylic", "merl:chrome", "ggx:alpha=0.2,kd=0.1", "lafortune:kd=0.2,cx1=-0.8,cz1=0.9,n1=20,rho1=0.5"],
)
def test_eval_agrees_with_gantry_eval(gantry, shared_data, tmp_path, spec):
    angles = random_angles(200, seed=3)
    want = gantry_eval(gantry, spec, angles, tmp_path)
    m = reflectance.load(spec)
    got = m.eval(angles[:, 0], angles[:, 1], angles[:, 2])
    assert got.shape == (200, 3)
    assert (want > 0).any()
    assert_relative(got, want, 1e-6)


@pytest.mark.parametrize("interp", ["nearest", "trilinear"])
def test_table_file_eval_agrees_with_gantry_eval(gantry, shared_data, tmp_path, interp):
    table = tmp_path / "acrylic.binary"
    reflectance.load("merl:blue-acrylic").write_merl(table)
    angles = random_angles(200, seed=4)
    want = gantry_eval(gantry, str(table), angles, tmp_path, interp)
    got = reflectance.load(str(table), interpolation=interp).eval(*angles.T)
    assert_relative(got, want, 1e-6)


def test_tabulate_holds_the_values_at_the_grid_nodes(shared_data):
    m = reflectance.load("merl:blue-acrylic")
    t = m.tabulate()
    assert t.shape == (90, 90, 180, 3) and t.dtype == np.float64
    rng = np.random.default_rng(5)
    i, j, k = rng.integers(0, 90, 50), rng.integers(0, 90, 50), rng.integers(0, 180, 50)
    th = (i / 90.0) ** 2 * (math.pi / 2)
    td = j / 90.0 * (math.pi / 2)
    pd = k / 180.0 * math.pi
    direct = m.eval(th, td, pd)
    # the NBRDF fast path decodes in float32
    assert_relative(t[i, j, k], direct, 1e-4)


def test_merl_files_round_trip(tmp_path):
    m = reflectance.load("ggx:alpha=0.3,kd=0.2/0.1/0.05")
    t = m.tabulate()
    path = tmp_path / "ggx.binary"
    reflectance.write_merl(path, t)
    back = reflectance.read_merl(path)
    assert_relative(back, t, 1e-12)
    m.write_merl(tmp_path / "ggx2.binary")
    assert (tmp_path / "ggx2.binary").read_bytes() == path.read_bytes()
    # a material from the array evaluates like the file
    fm = reflectance.from_table(t)
    assert_relative(fm.eval(0.2, 0.3, 1.0), reflectance.load(str(path)).eval(0.2, 0.3, 1.0), 1e-12)


def test_eval_broadcasts_and_eval_directions_is_reciprocal():
    m = reflectance.load("ggx:alpha=0.2,kd=0.1")
    v = m.eval(np.array([0.1, 0.2]), 0.3, 0.0)
    assert v.shape == (2, 3)
    rng = np.random.default_rng(2)
    wi = rng.normal(size=(100, 3))
    wo = rng.normal(size=(100, 3))
    wi[:, 2] = np.abs(wi[:, 2])
    wo[:, 2] = np.abs(wo[:, 2])
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    f = m.eval_directions(wi, wo)
    assert_relative(m.eval_directions(wo, wi), f, 1e-10)
    lam = reflectance.load("lambert:kd=0.6")
    assert np.allclose(lam.eval_directions(wi, wo), 0.6 / math.pi)


def test_albedo_and_reciprocity_summaries():
    lam = reflectance.load("lambert:kd=0.8/0.5/0.2")
    assert np.allclose(lam.albedo(0.4), [0.8, 0.5, 0.2], rtol=1e-3)
    assert reflectance.load("ggx:alpha=0.2").reciprocity_residual(2000) < 1e-9
    s = lam.summary()
    assert s["reciprocity_residual"] < 1e-9
    assert len(s["albedo"]) >= 5
    assert abs(s["albedo"][0]["albedo"][0] - 0.8) < 1e-3


@pytest.mark.parametrize(
    "spec",
    ["merl:no-such-material", "ggx:alpha=abc", "nosuchmodel:x=1", "", "lambert:kd=0.5,bogus=1", "/nonexistent/file.binary"],
)
def test_bad_specs_raise_value_error(spec):
    with pytest.raises(ValueError):
        reflectance.load(spec)


def test_bad_arguments_raise_value_error():
    with pytest.raises(ValueError):
        reflectance.from_table(np.zeros((3, 3)))
    with pytest.raises(ValueError):
        reflectance.load("ggx:alpha=0.2", interpolation="trilinear")
    with pytest.raises(ValueError):
        reflectance.load("ggx:alpha=0.2").eval_directions(np.zeros((4, 2)), np.zeros((4, 2)))
