"""Out-of-core PCA of a corpus store on a Dask cluster (docs/corpus-store.md).

Every task reads one panel of bins (all materials × one range of bin chunks) from the Zarr
store with zarr-python and centres it on its own column means (a panel holds every material of
its bins, so the centring is exact); every product is formed by the Rust kernel
``reflectance.linalg.gram`` (rows against rows, f64 sums). Two methods, as in
``gantry corpus pca``:

* ``gram`` (N up to about 20,000): each task forms its part of the centred Gram matrix
  ``B = Yc Ycᵀ``; the client sums the parts, decomposes ``B`` (thesis eqs. 4.1–4.3) and, in a
  second distributed pass, the components ``U = Ycᵀ V Λ^{-1/2}`` are formed panel by panel.
* ``randomized`` (any N): the randomized range finder of ``reduce::ooc`` with the same Gaussian
  test matrix (regenerated per panel from the seed and the bin index), so the result is the
  single-process run's: a sketch pass ``Z = Σ Yc_p Ω_p``, ``q`` power passes
  ``Z = Σ Yc_p (Yc_pᵀ Q)``, and a Rayleigh–Ritz pass whose ``T_p = Yc_pᵀ Q`` stay on the
  workers; only ``N × l`` and ``l × l`` parts travel to the client.

Usage (a scheduler address, or none for a local cluster of 2 worker processes)::

    python tools/dask/gram_dask.py corpus.zarr --components 10 [--method gram|randomized]
        [--scheduler tcp://host:8786] [--panel-chunks 1] [--out-npz result.npz]
"""

from __future__ import annotations

import argparse
import json
import os
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


def _mix(z):
    """SplitMix64's finaliser on uint64 arrays (wrapping arithmetic)."""
    with np.errstate(over="ignore"):
        z = z + np.uint64(0x9E37_79B9_7F4A_7C15)
        z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58_476D_1CE4_E5B9)
        z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D0_49BB_1331_11EB)
    return z ^ (z >> np.uint64(31))


def gaussian_block(seed: int, rows: tuple[int, int], l: int):
    """Rows ``rows`` (bins) of the test matrix Ω, ``w × l`` float32: the same counter-based
    standard normal values as ``reduce::ooc`` (value at bin d, column j from the seed)."""
    d = np.arange(rows[0], rows[1], dtype=np.uint64)[:, None]
    j = np.arange(l, dtype=np.uint64)[None, :]
    h = _mix(np.uint64(seed) ^ _mix((d << np.uint64(20)) ^ j))
    u1 = ((h >> np.uint64(11)).astype(np.float64) + 0.5) / float(1 << 53)
    u2 = (_mix(h) >> np.uint64(11)).astype(np.float64) / float(1 << 53)
    return (np.sqrt(-2.0 * np.log(u1)) * np.cos(2.0 * np.pi * u2)).astype(np.float32)


def _c(a):
    return np.ascontiguousarray(a, dtype=np.float32)


def sketch_task(path: str, cols: tuple[int, int], seed: int, l: int):
    """The panel's part of the sketch ``Z = Yc Ω`` (N × l), its column means and timings."""
    import reflectance

    t0 = time.perf_counter()
    panel, mean = read_centred(path, cols)
    t1 = time.perf_counter()
    z = reflectance.linalg.gram(panel, _c(gaussian_block(seed, cols, l).T))
    t2 = time.perf_counter()
    nbytes = panel.shape[0] * panel.shape[1] * open_values(path).dtype.itemsize
    return z, mean, {"read": t1 - t0, "compute": t2 - t1, "bytes": nbytes}


def power_task(path: str, cols: tuple[int, int], q_t):
    """The panel's part of ``Yc Ycᵀ Q`` (N × l), given ``Qᵀ`` (l × N); and timings."""
    import reflectance

    t0 = time.perf_counter()
    panel, _ = read_centred(path, cols)
    t1 = time.perf_counter()
    t = reflectance.linalg.gram(_c(panel.T), q_t)  # w × l = Yc_pᵀ Q
    z = reflectance.linalg.gram(panel, _c(t.T))  # N × l = Yc_p T_p
    t2 = time.perf_counter()
    return z, None, {"read": t1 - t0, "compute": t2 - t1}


def ritz_task(path: str, cols: tuple[int, int], q_t):
    """``T_p = Yc_pᵀ Q`` (w × l, kept on the worker) and its part ``T_pᵀ T_p`` of ``M``."""
    import reflectance

    t0 = time.perf_counter()
    panel, _ = read_centred(path, cols)
    t1 = time.perf_counter()
    t = _c(reflectance.linalg.gram(_c(panel.T), q_t))
    m = reflectance.linalg.gram(_c(t.T))
    t2 = time.perf_counter()
    return t, m, {"read": t1 - t0, "compute": t2 - t1}


def randomized_pca(
    client, path: str, components: int, panel_chunks: int = 1,
    oversampling: int = 10, power_iterations: int = 2, seed: int = 0,
):
    """Randomized PCA of the store on ``client``, as ``gantry corpus pca --method randomized``
    with the same ``oversampling``, ``power_iterations`` and ``seed``:
    (eigenvalues, basis D × k, mean, stats)."""
    ranges = panels(path, panel_chunks)
    n, dim = open_values(path).shape
    l = min(components + oversampling, n, dim)
    passes, task_stats = [], []

    def run(fn, *args):
        t0 = time.perf_counter()
        futs = [client.submit(fn, path, r, *args, pure=False) for r in ranges]
        info = client.gather([client.submit(lambda p: (p[1], p[2]), f) for f in futs])
        total = tree_sum(client, futs) if fn is not ritz_task else None
        passes.append(time.perf_counter() - t0)
        task_stats.extend(s for _, s in info)
        return futs, info, total

    def orth_t(z):
        q, _ = np.linalg.qr(z)
        return client.scatter(_c(q.T), broadcast=True), q

    futs, info, z = run(sketch_task, seed, l)
    mean = np.concatenate([m for m, _ in info])
    bytes_read = int(sum(s["bytes"] for _, s in info))
    del futs
    for _ in range(power_iterations):
        q_t, _ = orth_t(z)
        futs, _, z = run(power_task, q_t)
        del futs
    q_t, q = orth_t(z)
    t_futs, _, _ = run(ritz_task, q_t)
    t0 = time.perf_counter()
    m = tree_sum(client, [client.submit(lambda p: (p[1], None, None), f) for f in t_futs])
    mu, u = np.linalg.eigh(m)
    order = np.argsort(mu)[::-1]
    mu, u = np.maximum(mu[order], 0.0), u[:, order]
    rank = int(np.sum(mu > 1e-6 * mu[0]))
    k = min(components, rank)
    # basis rows of a panel: T_p U_k Σ⁻¹, formed where T_p lives
    coef_t = client.scatter(_c((u[:, :k] / np.sqrt(mu[:k])).T), broadcast=True)

    def basis_rows(t, c):
        import reflectance

        return reflectance.linalg.gram(t[0], c)

    blocks = client.gather([client.submit(basis_rows, f, coef_t) for f in t_futs])
    passes[-1] += time.perf_counter() - t0
    basis = np.concatenate(blocks, axis=0)  # D × k
    stats = {
        "method": "randomized",
        "tasks": len(ranges),
        "sketch_columns": l,
        "pass_seconds": passes,
        "task_read_seconds": [s["read"] for s in task_stats],
        "task_compute_seconds": [s["compute"] for s in task_stats],
        "bytes_read_per_pass": bytes_read,
        "bytes_to_client_per_pass": n * l * 8,
    }
    return mu, basis, mean, stats


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
        "method": "gram",
        "tasks": len(ranges),
        "gram_pass_seconds": t1 - t0,
        "basis_pass_seconds": t2 - t1,
        "task_read_seconds": [s["read"] for _, s in info],
        "task_gram_seconds": [s["gram"] for _, s in info],
        "bytes_read_per_pass": int(sum(s["bytes"] for _, s in info)),
    }
    return lam, basis, mean, stats


def peak_rss() -> int | None:
    """This process's peak resident memory in bytes (VmHWM), where /proc has it."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return None


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("store")
    ap.add_argument("--components", type=int, default=10)
    ap.add_argument("--scheduler", help="address of a running scheduler (default: local cluster)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--method", choices=["gram", "randomized"], default="gram")
    ap.add_argument("--oversampling", type=int, default=10)
    ap.add_argument("--power-iterations", type=int, default=2)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--panel-chunks", type=int, default=1)
    ap.add_argument("--memory-limit", default="auto",
                    help="memory limit of each local worker, e.g. 2GiB (Dask pauses a worker "
                         "at 80 %% and restarts it at 95 %%)")
    ap.add_argument("--out-npz")
    a = ap.parse_args()
    from dask.distributed import Client, LocalCluster

    if a.scheduler:
        client = Client(a.scheduler)
    else:
        # One thread per worker process: the Rust kernels' rayon pools get one thread each too
        # (inherited by the worker processes), so that C workers use C cores.
        os.environ.setdefault("RAYON_NUM_THREADS", "1")
        cluster = LocalCluster(
            n_workers=a.workers, threads_per_worker=1, processes=True,
            host="127.0.0.1", dashboard_address=None, memory_limit=a.memory_limit,
        )
        client = Client(cluster)
    t0 = time.perf_counter()
    with client:
        if a.method == "gram":
            lam, basis, mean, stats = pca(client, a.store, a.components, a.panel_chunks)
        else:
            lam, basis, mean, stats = randomized_pca(
                client, a.store, a.components, a.panel_chunks,
                a.oversampling, a.power_iterations, a.seed,
            )
        stats["wall_seconds"] = time.perf_counter() - t0
        stats["worker_peak_rss"] = list(client.run(peak_rss).values())
        stats["client_peak_rss"] = peak_rss()
    print(json.dumps({**stats, "eigenvalues": lam[: a.components].tolist()}, indent=1))
    if a.out_npz:
        np.savez(a.out_npz, eigenvalues=lam, basis=basis, mean=mean)


if __name__ == "__main__":
    main()
