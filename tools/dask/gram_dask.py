"""Out-of-core PCA of a corpus store on a Dask cluster (docs/corpus-store.md).

Every task reads one panel of bins (all materials × one range of bin chunks) from the Zarr
store with zarr-python, centres it on its own column means (a panel holds every material of
its bins, so the centring is exact) and forms its part of the centred Gram matrix
``B = Yc Ycᵀ`` with the Rust kernel ``reflectance.linalg.gram``. The client sums the parts,
decomposes ``B`` (thesis eqs. 4.1–4.3) and, in a second distributed pass, forms the components
``U = Ycᵀ V Λ^{-1/2}`` panel by panel, again with ``reflectance.linalg.gram``.

Usage (a scheduler address, or none for a local cluster of 2 worker processes)::

    python tools/dask/gram_dask.py corpus.zarr --components 10 [--scheduler tcp://host:8786]
        [--panel-chunks 1] [--out-npz result.npz]
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np


def open_values(path: str):
    """The corpus array of a store, opened read-only with zarr-python."""
    import zarr

    group = zarr.open_group(path, mode="r")
    if group.attrs.get("format") != "reflectance-corpus":
        raise ValueError(f"{path}: not a reflectance corpus store")
    return group["values"]


def panels(path: str, panel_chunks: int) -> list[tuple[int, int]]:
    """Bin ranges of the panels: ``panel_chunks`` chunk columns each."""
    values = open_values(path)
    dim = values.shape[1]
    width = values.chunks[1] * panel_chunks
    return [(c, min(c + width, dim)) for c in range(0, dim, width)]


def read_centred(path: str, cols: tuple[int, int]):
    """Panel ``cols`` of every material as float32, centred; and its column means."""
    values = open_values(path)
    panel = np.asarray(values[:, cols[0] : cols[1]], dtype=np.float32)
    mean = panel.mean(axis=0, dtype=np.float64).astype(np.float32)
    panel -= mean
    return np.ascontiguousarray(panel), mean


def gram_task(path: str, cols: tuple[int, int]):
    """The panel's contribution to the centred Gram matrix, with timing and bytes read."""
    import reflectance

    t0 = time.perf_counter()
    panel, mean = read_centred(path, cols)
    t1 = time.perf_counter()
    g = reflectance.linalg.gram(panel)
    t2 = time.perf_counter()
    nbytes = panel.shape[0] * panel.shape[1] * open_values(path).dtype.itemsize
    return g, mean, {"read": t1 - t0, "gram": t2 - t1, "bytes": nbytes}


def basis_task(path: str, cols: tuple[int, int], coef_t):
    """Rows ``cols`` of the components: ``(Ycᵀ C)ᵀ = Cᵀ Yc`` as ``gram(Cᵀ, Ycᵀ)``."""
    import reflectance

    panel, _ = read_centred(path, cols)
    return reflectance.linalg.gram(coef_t, np.ascontiguousarray(panel.T))


def tree_sum(client, futures):
    """Sums Gram parts pairwise on the workers; only the total travels to the client."""

    def add(a, b):
        return (a[0] + b[0], None, None)

    level = [client.submit(lambda r: (r[0], None, None), f) for f in futures]
    while len(level) > 1:
        nxt = [client.submit(add, level[i], level[i + 1]) for i in range(0, len(level) - 1, 2)]
        if len(level) % 2:
            nxt.append(level[-1])
        level = nxt
    return level[0].result()[0]


def pca(client, path: str, components: int, panel_chunks: int = 1):
    """PCA of the store at ``path`` on ``client``: (eigenvalues, basis D × k, mean, stats)."""
    ranges = panels(path, panel_chunks)
    t0 = time.perf_counter()
    parts = [client.submit(gram_task, path, r, pure=False) for r in ranges]
    info = client.gather([client.submit(lambda p: (p[1], p[2]), f) for f in parts])
    gram = tree_sum(client, parts)
    del parts
    t1 = time.perf_counter()
    lam, v = np.linalg.eigh(gram)
    order = np.argsort(lam)[::-1]
    lam, v = np.maximum(lam[order], 0.0), v[:, order]
    rank = int(np.sum(lam > 1e-6 * lam[0]))
    k = min(components, rank)
    coef_t = np.ascontiguousarray((v[:, :k] / np.sqrt(lam[:k])).T.astype(np.float32))
    coef_f = client.scatter(coef_t, broadcast=True)
    blocks = client.gather([client.submit(basis_task, path, r, coef_f, pure=False) for r in ranges])
    t2 = time.perf_counter()
    basis = np.concatenate(blocks, axis=1).T  # D × k
    mean = np.concatenate([m for m, _ in info])
    stats = {
        "tasks": len(ranges),
        "gram_pass_seconds": t1 - t0,
        "basis_pass_seconds": t2 - t1,
        "task_read_seconds": [s["read"] for _, s in info],
        "task_gram_seconds": [s["gram"] for _, s in info],
        "bytes_read_per_pass": int(sum(s["bytes"] for _, s in info)),
    }
    return lam, basis, mean, stats


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("store")
    ap.add_argument("--components", type=int, default=10)
    ap.add_argument("--scheduler", help="address of a running scheduler (default: local cluster)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--panel-chunks", type=int, default=1)
    ap.add_argument("--out-npz")
    a = ap.parse_args()
    from dask.distributed import Client, LocalCluster

    if a.scheduler:
        client = Client(a.scheduler)
    else:
        cluster = LocalCluster(
            n_workers=a.workers, threads_per_worker=1, processes=True,
            host="127.0.0.1", dashboard_address=None,
        )
        client = Client(cluster)
    with client:
        lam, basis, mean, stats = pca(client, a.store, a.components, a.panel_chunks)
    print(json.dumps({**stats, "eigenvalues": lam[: a.components].tolist()}, indent=1))
    if a.out_npz:
        np.savez(a.out_npz, eigenvalues=lam, basis=basis, mean=mean)


if __name__ == "__main__":
    main()
