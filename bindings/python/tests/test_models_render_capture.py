"""PCA models, the toolkit's renderer, and the capture job, through the package."""

import math

import numpy as np
import pytest

import reflectance
from reflectance import capture, models, render

CORPUS = [
    "ggx:alpha=0.1,kd=0.2/0.1/0.05",
    "ggx:alpha=0.3,kd=0.05/0.1/0.2",
    "lambert:kd=0.4",
    "ward:alpha=0.2,kd=0.1,ks=0.1",
]


def test_pca_model_reconstructs_its_corpus_and_round_trips(tmp_path):
    model = models.PcaModel.build(CORPUS, components=3)
    assert model.names == CORPUS and model.components == 3
    ev = model.eigenvalues
    assert np.all(np.diff(ev) <= 0) and ev[0] > 0
    # four materials span a 3-dimensional affine space: all components reconstruct each exactly
    target = reflectance.load(CORPUS[1]).tabulate()
    x = model.project(CORPUS[1])
    assert x.shape == (3,)
    back = model.reconstruct(x)
    mask = target > 1e-3
    assert np.max(np.abs(back[mask] / target[mask] - 1)) < 1e-3
    # fewer components reconstruct worse
    x1 = model.project(reflectance.load(CORPUS[1]), k=1)
    err1 = np.abs(np.log(model.reconstruct(x1)[mask] / target[mask])).mean()
    err3 = np.abs(np.log(back[mask] / target[mask])).mean()
    assert err1 > 10 * err3
    # the half-precision decoder gives the same table to its rounding
    fast = model.reconstruct(x, fast=True)
    assert fast.shape == back.shape
    assert np.max(np.abs(fast[mask] / back[mask] - 1)) < 2e-3
    with pytest.raises(ValueError):
        model.reconstruct([float("nan")], fast=True)
    path = tmp_path / "model.bin"
    model.save(path)
    again = models.PcaModel.load(path)
    assert np.allclose(again.project(target), x, rtol=1e-6, atol=1e-9)
    with pytest.raises(ValueError):
        models.PcaModel.build(["merl:no-such-material"], components=1)


def test_sphere_of_a_white_lambertian_reaches_radiance_one():
    img = render.sphere("lambert:kd=1", size=48, spp=4, seed=3)
    assert img.shape == (48, 48, 3) and img.dtype == np.float32
    # irradiance π at normal incidence: radiance kd/π · π · cos θ peaks at 1
    peak = img[..., 1].max()
    assert 0.97 < peak <= 1.0 + 1e-3
    assert img[0, 0].max() == 0.0  # black background
    # the same figure from a Material object and with another seed: same scene
    other = render.sphere(reflectance.load("lambert:kd=1"), size=48, spp=4, seed=4)
    assert abs(float(other.mean()) - float(img.mean())) < 0.01 * float(img.mean())


def test_teapot_and_scene_file(tmp_path):
    img = render.teapot("ggx:alpha=0.3,kd=0.2", width=32, spp=2)
    assert img.shape == (24, 32, 3) and np.isfinite(img).all() and img.max() > 0
    with pytest.raises(ValueError):
        render.scene(tmp_path / "missing.toml")
    with pytest.raises(ValueError):
        render.sphere("merl:no-such-material", size=8, spp=1)


def test_capture_job_with_progress_callback(tmp_path):
    seen = []
    report = capture.run(
        "ggx:alpha=0.3,kd=0.2/0.1/0.05,ks=0.04",
        tmp_path / "job",
        positions=2,
        scale=0.1,
        progress=lambda stage, done, total: seen.append((stage, done, total)),
    )
    assert (tmp_path / "job" / "brdf.binary").exists()
    assert report["coverage"] > 0
    stages = {s for s, _, _ in seen}
    assert "positions" in stages and "binning" in stages
    assert ("positions", 2, 2) in seen
    # the measured table evaluates where it has data
    measured = reflectance.load(str(tmp_path / "job" / "brdf.binary"))
    assert (measured.tabulate() > 0).any()

    def fail(stage, done, total):
        raise KeyError("stop")

    with pytest.raises(KeyError):
        capture.run("lambert:kd=0.5", tmp_path / "job2", positions=1, scale=0.1, progress=fail)


def test_fast_capture_plans_then_completes_the_table_from_a_model(tmp_path):
    model = models.PcaModel.build(CORPUS, components=3)
    model.save(tmp_path / "model.bin")
    material = "ggx:alpha=0.2,kd=0.1/0.1/0.1"
    plan = capture.fast(material, tmp_path / "dry", tmp_path / "model.bin", positions=3, components=3, dry_run=True)
    assert len(plan["angles_deg"]) == 3 and plan["predicted_clock_s"] <= 600
    assert not (tmp_path / "dry").exists()
    report = capture.fast(material, tmp_path / "job", tmp_path / "model.bin", positions=3, components=3)
    assert report["positions"] == 3 and report["angles_deg"] == plan["angles_deg"]
    # the rig's clock is the planned one
    assert abs(report["simulated_capture_s"] - plan["predicted_clock_s"]) < 1e-6 * plan["predicted_clock_s"]
    measured = np.load(tmp_path / "job" / "measured.npy")
    sd = np.load(tmp_path / "job" / "completion_sd.npy")
    assert measured.shape == (3, 1458000) and int(measured.sum()) == report["measured_entries"]
    assert np.all(sd[measured == 1] == 0) and np.all(sd[measured == 0] > 0)
    table = reflectance.load(str(tmp_path / "job" / "brdf.binary")).tabulate()
    assert np.isfinite(table).all() and (table >= 0).all()
    with pytest.raises(ValueError):
        capture.fast(material, tmp_path / "bad", tmp_path / "no-model.bin")
