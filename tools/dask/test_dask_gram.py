"""The corpus store read by zarr-python, and the Dask run against the single-process Rust run.

Needs GANTRY_BIN (the `gantry` binary; tools/tests.d/50-dask.sh builds it) and the venv of
.ci/setup (dask[distributed], zarr, numpy, pytest, reflectance).
"""

import json
import math
import os
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))
import gram_dask  # noqa: E402

# analytic base materials: no shared data needed
BASE = [
    "lambert:kd=0.5/0.4/0.3",
    "lambert:kd=0.05",
    "ggx:alpha=0.08",
    "ggx:alpha=0.3",
    "ggx:alpha=0.6",
    "ward:alpha=0.2",
]
GRID = "6"  # strides 6:6:6 -> 15 x 15 x 30 x 3 = 20,250 values per material
K = 8


def gantry(*args):
    exe = os.environ.get("GANTRY_BIN")
    if not exe or not Path(exe).is_file():
        pytest.fail("GANTRY_BIN is not set to the gantry binary: run tools/tests.d/50-dask.sh")
    out = subprocess.run([exe, *args], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    return out.stdout


def read_npy(path):
    return np.load(path)


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    d = tmp_path_factory.mktemp("store")
    path = d / "synth.zarr"
    gantry(
        "corpus", "synth", "--from", *BASE, "--n", "70", "--seed", "3", "--grid", GRID,
        "--materials-per-chunk", "16", "--bins-per-chunk", "2048", "--out", str(path),
    )
    return path


def test_zarr_python_opens_the_store(store, tmp_path):
    import zarr

    g = zarr.open_group(str(store), mode="r")
    assert g.attrs["format"] == "reflectance-corpus"
    v = g["values"]
    assert v.shape == (70, 3 * 15 * 15 * 30)
    assert v.dtype == np.float16
    assert v.chunks == (16, 2048)
    assert list(v.metadata.dimension_names) == ["material", "bin"]
    names = v.attrs["names"]
    assert len(names) == 70 and names[0] == "synth-3-000000"
    assert v.attrs["grid"]["shape"] == [15, 15, 30]
    # every synthetic material is non-negative: log values at or above ln(floor)
    floor = v.attrs["transform"]["floor"]
    data = np.asarray(v[:], dtype=np.float32)
    assert np.isfinite(data).all()
    assert data.min() >= math.log(floor) - 1e-2

    # a Lambertian material packed by gantry holds ln(kd/pi + floor) in every bin
    lam = tmp_path / "lambert.zarr"
    gantry("corpus", "pack", "lambert:kd=0.5", "ggx:alpha=0.2", "--grid", GRID, "--out", str(lam))
    w = zarr.open_group(str(lam), mode="r")["values"]
    row = np.asarray(w[0], dtype=np.float64)
    expected = math.log(0.5 / math.pi + floor)
    # every bin holds ln(kd/pi + floor) (float16 rounding of a value near -1.8), except bins
    # with a direction below the horizon, which hold ln(floor)
    lit = np.abs(row - expected) < 2e-3
    dark = np.abs(row - math.log(floor)) < 1e-2
    assert (lit | dark).all() and lit.mean() > 0.5
    assert w.attrs["names"] == ["lambert:kd=0.5", "ggx:alpha=0.2"]


def test_dask_gram_matches_the_rust_out_of_core_pca(store, tmp_path):
    from dask.distributed import Client, LocalCluster

    basis_npy, stats_json = tmp_path / "basis.npy", tmp_path / "stats.json"
    gantry(
        "corpus", "pca", "--corpus", str(store), "--components", str(K), "--method", "gram",
        "--memory-budget", "256M", "--out", str(tmp_path / "model.bin"),
        "--basis-npy", str(basis_npy), "--stats", str(stats_json),
    )
    rust_basis = read_npy(basis_npy).astype(np.float64)
    rust_ev = np.array(json.loads(stats_json.read_text())["eigenvalues"])

    with LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
        dashboard_address=None,
    ) as cluster, Client(cluster) as client:
        assert len(client.scheduler_info()["workers"]) == 2
        lam, basis, mean, stats = gram_dask.pca(client, str(store), K, panel_chunks=2)
    assert stats["tasks"] == math.ceil(20250 / 4096)
    # same eigenvalues (1e-6 relative) and same subspace (principal angles)
    np.testing.assert_allclose(lam[:K], rust_ev, rtol=1e-6)
    # Both bases are stored in f32 (cosines a few 1e-7 above 1), and the Rust Gram sums f32
    # partial products while this one is f64: the last component, nearest its neighbour's
    # eigenvalue, turns by about 1e-3 rad (cosine 1 - 1.2e-6 measured).
    cos = np.linalg.svd(basis.astype(np.float64).T @ rust_basis, compute_uv=False)
    assert cos.min() > 1 - 1e-5, cos
    # orthonormal components
    np.testing.assert_allclose(basis.T.astype(np.float64) @ basis, np.eye(K), atol=1e-4)


def test_zarr_python_verifies_the_chunk_checksums(tmp_path):
    import zarr

    path = tmp_path / "sum.zarr"
    gantry("corpus", "pack", "lambert:kd=0.5", "ggx:alpha=0.2", "--grid", GRID,
           "--bins-per-chunk", "4096", "--out", str(path))
    codecs = [c.to_dict()["name"] for c in zarr.open_array(str(path / "values"), mode="r").metadata.codecs]
    assert codecs[-1] == "crc32c", codecs
    good = np.asarray(zarr.open_group(str(path), mode="r")["values"][:], dtype=np.float32)
    chunk = path / "values" / "c" / "0" / "2"
    raw = bytearray(chunk.read_bytes())
    raw[len(raw) // 3] ^= 0x10
    chunk.write_bytes(bytes(raw))
    with pytest.raises(Exception, match="(?i)checksum"):
        zarr.open_group(str(path), mode="r")["values"][:, 8192:12288]
    # gantry finds the same chunk, fails, and a second pack repairs it
    exe = os.environ["GANTRY_BIN"]
    out = subprocess.run([exe, "corpus", "info", str(path)], capture_output=True, text=True)
    assert out.returncode != 0 and "chunk 0/2: Damaged" in out.stdout, out.stdout + out.stderr
    gantry("corpus", "pack", "lambert:kd=0.5", "ggx:alpha=0.2", "--grid", GRID,
           "--bins-per-chunk", "4096", "--out", str(path))
    assert "complete     yes" in gantry("corpus", "info", str(path))
    again = np.asarray(zarr.open_group(str(path), mode="r")["values"][:], dtype=np.float32)
    np.testing.assert_array_equal(again, good)


def _rust_randomized(store, tmp_path, seed):
    basis_npy, stats_json = tmp_path / f"basis{seed}.npy", tmp_path / f"stats{seed}.json"
    gantry(
        "corpus", "pca", "--corpus", str(store), "--components", str(K),
        "--method", "randomized", "--seed", str(seed), "--oversampling", "4",
        "--power-iterations", "1", "--memory-budget", "256M",
        "--out", str(tmp_path / f"model{seed}.bin"),
        "--basis-npy", str(basis_npy), "--stats", str(stats_json),
    )
    return (
        np.array(json.loads(stats_json.read_text())["eigenvalues"]),
        read_npy(basis_npy).astype(np.float64),
    )


def test_the_test_matrix_is_standard_normal_and_counter_based():
    a = gram_dask.gaussian_block(7, (0, 4000), 25)
    b = gram_dask.gaussian_block(7, (1000, 1010), 25)
    np.testing.assert_array_equal(a[1000:1010], b)  # any panel is regenerated alone
    assert abs(a.mean()) < 0.01 and abs(a.std() - 1) < 0.01
    assert not np.array_equal(a, gram_dask.gaussian_block(8, (0, 4000), 25))


def test_dask_randomized_matches_the_rust_randomized_run(store, tmp_path):
    from dask.distributed import Client, LocalCluster

    rust_ev, rust_basis = _rust_randomized(store, tmp_path, seed=5)
    other_ev, _ = _rust_randomized(store, tmp_path, seed=6)
    with LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
        dashboard_address=None,
    ) as cluster, Client(cluster) as client:
        lam, basis, mean, stats = gram_dask.randomized_pca(
            client, str(store), K, panel_chunks=2, oversampling=4, power_iterations=1, seed=5,
        )
    assert stats["tasks"] == math.ceil(20250 / 4096)
    assert len(stats["pass_seconds"]) == 1 + 1 + 1
    # With the same test matrix (the same seed), the same result as the single-process run;
    # another seed changes the trailing eigenvalues by far more than this tolerance, so the
    # agreement checks that the test matrix is regenerated identically.
    rel = np.abs(lam[:K] - rust_ev) / rust_ev
    assert rel.max() < 1e-6, rel
    assert (np.abs(other_ev - rust_ev) / rust_ev).max() > 100 * rel.max()
    cos = np.linalg.svd(basis.astype(np.float64).T @ rust_basis, compute_uv=False)
    assert cos.min() > 1 - 1e-5, cos
    np.testing.assert_allclose(basis.T.astype(np.float64) @ basis, np.eye(K), atol=1e-4)
