"""Shared fixtures: the gantry CLI the round trips compare against, and the shared data."""

import os
import pathlib
import shutil

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[3]


@pytest.fixture(scope="session")
def gantry():
    """Path of the gantry binary: $GANTRY_BIN, else target/debug or target/release."""
    cands = [os.environ.get("GANTRY_BIN")] + [
        str(ROOT / "target" / p / "gantry") for p in ("debug", "release")
    ]
    for c in cands:
        if c and os.access(c, os.X_OK):
            return c
    c = shutil.which("gantry")
    if c:
        return c
    pytest.fail("no gantry binary: run `cargo build -p gantry` or set GANTRY_BIN")


@pytest.fixture(scope="session")
def shared_data():
    """The shared reference data (MERL materials as NBRDF weights); fails when missing."""
    d = os.environ.get("BRDF_DATA_DIR")
    d = pathlib.Path(d) if d else ROOT.parent / "shared" / "data"
    if not (d / "nbrdf" / "merl").is_dir():
        pytest.fail(f"the shared data is missing at {d} (set BRDF_DATA_DIR)")
    os.environ.setdefault("BRDF_DATA_DIR", str(d))
    return d
