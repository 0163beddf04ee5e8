"""reflectance.linalg.gram against numpy."""

import threading

import numpy as np
import pytest

from reflectance.linalg import gram


@pytest.mark.parametrize("m,n,d", [(1, 1, 3), (7, 5, 1300), (12, 3, 2 * 1024 + 9)])
def test_gram_matches_numpy(m, n, d):
    rng = np.random.default_rng(m * 100 + n)
    a = rng.normal(size=(m, d)).astype(np.float32)
    b = rng.normal(size=(n, d)).astype(np.float32)
    want = a.astype(np.float64) @ b.astype(np.float64).T
    g = gram(a, b)
    assert g.dtype == np.float64 and g.shape == (m, n)
    assert np.abs(g - want).max() <= 1e-5 * max(1.0, np.abs(want).max())
    s = gram(a)
    want_s = a.astype(np.float64) @ a.astype(np.float64).T
    assert s.shape == (m, m)
    assert np.abs(s - want_s).max() <= 1e-5 * max(1.0, np.abs(want_s).max())
    assert np.array_equal(s, s.T)


def test_gram_accepts_float64_and_strided_input():
    rng = np.random.default_rng(1)
    a = rng.normal(size=(6, 200))
    want = a @ a.T
    assert np.abs(gram(a) - want).max() <= 1e-4 * np.abs(want).max()
    f = np.asfortranarray(a.astype(np.float32))
    assert np.abs(gram(f, a[:2]) - want[:, :2]).max() <= 1e-4 * np.abs(want).max()


def test_gram_rejects_bad_shapes_and_dtypes():
    a = np.ones((3, 4), np.float32)
    with pytest.raises(ValueError):
        gram(a, np.ones((3, 5), np.float32))
    with pytest.raises(ValueError):
        gram(np.ones(4, np.float32))
    with pytest.raises(ValueError):
        gram(np.ones((3, 4), np.int64))
    with pytest.raises(ValueError):
        gram([[1.0, 2.0]])
    with pytest.raises(ValueError):
        gram(a, np.ones((2, 2, 4), np.float32))


def test_gram_runs_in_parallel_threads():
    # the GIL is released: threads give the same results as serial calls
    rng = np.random.default_rng(2)
    blocks = [rng.normal(size=(8, 5000)).astype(np.float32) for _ in range(4)]
    want = [gram(b) for b in blocks]
    got = [None] * 4

    def work(i):
        got[i] = gram(blocks[i])

    threads = [threading.Thread(target=work, args=(i,)) for i in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for g, w in zip(got, want):
        assert np.array_equal(g, w)
