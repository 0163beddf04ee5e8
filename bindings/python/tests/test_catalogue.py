"""One catalogue of material forms: the package reads every spec form and corpus the CLI reads."""

import subprocess

import numpy as np
import pytest

import reflectance
from reflectance.models import PcaModel

from test_materials import gantry_eval, random_angles


def run(gantry, *args):
    return subprocess.run([gantry, *map(str, args)], check=True, capture_output=True, text=True).stdout


def test_the_package_lists_the_forms_the_cli_lists(gantry):
    lines = run(gantry, "forms").splitlines()
    cli_forms = [l for l in lines if not l.startswith("--corpus:")]
    assert reflectance.spec_forms() == cli_forms
    assert any(f.startswith("pca:") for f in cli_forms)
    assert any(f.startswith("wavelet:") for f in cli_forms)
    assert any("zarr" in l for l in lines if l.startswith("--corpus:"))


@pytest.fixture(scope="module")
def examples(gantry, shared_data, tmp_path_factory):
    """One spec of every form `gantry forms` lists, made with the CLI."""
    d = tmp_path_factory.mktemp("forms")
    run(gantry, "convert", "ggx:alpha=0.3,kd=0.2/0.1/0.05,ks=0.04", "--out", d / "t.binary")
    run(gantry, "model", "build", "--corpus", "ggx:alpha=0.2", "ggx:alpha=0.5,kd=0.3",
        "lambert:kd=0.1", "--components", "2", "--chart-dim", "0", "--out", d / "m.bin")
    run(gantry, "wavelet", "basis", "--corpus", "ggx:alpha=0.3", "lambert:kd=0.2",
        "--target", "0.05", "--out", d / "b.wtree")
    run(gantry, "wavelet", "compress", "ggx:alpha=0.25,kd=0.15", "--basis", d / "b.wtree",
        "--out", d / "c.wtree")
    run(gantry, "convert", "ggx:alpha=0.3,kd=0.2", "--out", d / "r.bsdf", "--resolution", "12",
        "--theta-i", "6")
    nielsen = sorted(p.name.rsplit("_", 1)[0] for p in (shared_data / "nbrdf" / "nielsen").glob("*_b1.npy"))[0]
    return {
        "<file>.binary": str(d / "t.binary"),
        "nbrdf:<dir>/<name>": f"nbrdf:{shared_data / 'nbrdf' / 'merl'}/blue-acrylic",
        "merl:<name>": "merl:chrome",
        "nielsen:<name>": f"nielsen:{nielsen}",
        "<model>:<params>": "cook-torrance:m=0.3,kd=0.1,ks=0.5",
        "pca:": f"pca:{d / 'm.bin'}?c=0.5/-0.25",
        "wavelet:": f"wavelet:{d / 'c.wtree'}",
        "rgl:": f"rgl:{d / 'r.bsdf'}",
    }


def test_every_form_loads_in_the_package_as_in_the_cli(gantry, examples, tmp_path):
    forms = reflectance.spec_forms()
    for form in forms:
        key = next((k for k in examples if form.startswith(k)), None)
        assert key is not None, f"no example of the form {form}"
    angles = random_angles(200, seed=11)
    for key, spec in examples.items():
        want = gantry_eval(gantry, spec, angles, tmp_path)
        got = reflectance.load(spec).eval(*angles.T)
        assert (want > 0).any(), spec
        np.testing.assert_allclose(got, want, rtol=1e-6, atol=1e-9, err_msg=spec)


def test_a_corpus_store_is_a_corpus_in_the_package_and_the_cli(gantry, tmp_path):
    specs = ["ggx:alpha=0.2", "ggx:alpha=0.5,kd=0.3", "lambert:kd=0.1", "ggx:alpha=0.1,kd=0.05"]
    store = tmp_path / "s.zarr"
    run(gantry, "corpus", "pack", *specs, "--out", store, "--dtype", "f32")
    from_store = PcaModel.build([str(store)], components=2)
    from_specs = PcaModel.build(specs, components=2)
    assert from_store.names == specs
    np.testing.assert_allclose(from_store.eigenvalues, from_specs.eigenvalues, rtol=1e-4)
    run(gantry, "model", "build", "--corpus", store, "--components", "2", "--chart-dim", "0",
        "--out", tmp_path / "m.bin")
    cli = PcaModel.load(tmp_path / "m.bin")
    np.testing.assert_allclose(cli.eigenvalues, from_store.eigenvalues, rtol=1e-5)
    with pytest.raises(ValueError):
        PcaModel.build([str(tmp_path / "no-such-store.zarr")])
