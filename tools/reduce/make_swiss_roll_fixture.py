#!/usr/bin/env python3
"""Generate the Swiss-roll fixture for the `reduce` scikit-learn cross-checks.

Writes crates/reduce/tests/fixtures/swiss_roll_sklearn.csv: the 3-D points of a seeded Swiss
roll and the 2-D embeddings scikit-learn computes for them with classical MDS, Isomap and
standard LLE (dense eigensolvers). The Rust tests recompute the embeddings and compare them
to these columns with the Procrustes disparity. Parameters are recorded in `#` header lines.

    pip install numpy scikit-learn
    python3 tools/reduce/make_swiss_roll_fixture.py
"""
import pathlib

import numpy as np
import sklearn
from sklearn.datasets import make_swiss_roll
from sklearn.manifold import ClassicalMDS, Isomap, LocallyLinearEmbedding

N = 300
SEED = 7
ISOMAP_K = 10
LLE_K = 12
LLE_REG = 1e-3


def main():
    x, t = make_swiss_roll(n_samples=N, noise=0.0, random_state=SEED)
    mds = ClassicalMDS(n_components=2).fit_transform(x)
    iso = Isomap(n_neighbors=ISOMAP_K, n_components=2, eigen_solver="dense", path_method="D").fit_transform(x)
    lle = LocallyLinearEmbedding(
        n_neighbors=LLE_K, n_components=2, reg=LLE_REG, eigen_solver="dense", method="standard"
    ).fit_transform(x)
    out = pathlib.Path(__file__).resolve().parents[2] / "crates/reduce/tests/fixtures/swiss_roll_sklearn.csv"
    out.parent.mkdir(parents=True, exist_ok=True)
    cols = np.column_stack([x, t, mds, iso, lle])
    with open(out, "w") as f:
        f.write(f"# make_swiss_roll(n_samples={N}, noise=0.0, random_state={SEED}); scikit-learn {sklearn.__version__}\n")
        f.write(f"# isomap_k={ISOMAP_K}\n# lle_k={LLE_K}\n# lle_reg={LLE_REG}\n")
        f.write("x,y,z,t,mds1,mds2,iso1,iso2,lle1,lle2\n")
        for row in cols:
            f.write(",".join(repr(float(v)) for v in row) + "\n")
    print(f"wrote {out} ({out.stat().st_size} bytes)")


if __name__ == "__main__":
    main()
