"""The sparse maps of a step's linearisation equal the dense matrices they stand for, and their adjoints are the
transposes."""
import numpy as np

from sim.analysis.local_maps import EdgeTurns, LocalColumns, band_columns


def _dense_columns(m: LocalColumns) -> np.ndarray:
    B, K, L, C = m.values.shape
    out = np.zeros((B, m.n, K * C))
    for k in range(K):
        off = m.first + m.stride * k
        for l in range(L):
            if 0 <= off + l < m.n:
                out[:, off + l, k * C:(k + 1) * C] = m.values[:, k, l, :]
    return out


def test_local_columns_apply_and_adjoint_are_the_dense_products():
    rng = np.random.default_rng(0)
    B, N, L, C, n = 3, 6, 11, 2, 24
    m = LocalColumns(rng.normal(size=(B, N, L, C)), -4, 4, n)  # first and last run off the ends
    D = _dense_columns(m)
    v = rng.normal(size=(B, N * C))
    np.testing.assert_allclose(m.apply(v), np.einsum("bnk,bk->bn", D, v), rtol=1e-13, atol=1e-13)
    V = rng.normal(size=(B, N * C, 4))
    np.testing.assert_allclose(m.apply(V), D @ V, rtol=1e-13, atol=1e-13)
    lam = rng.normal(size=(B, n))
    np.testing.assert_allclose(m.adjoint(lam), np.einsum("bnk,bn->bk", D, lam), rtol=1e-13, atol=1e-13)


def test_zeroed_rows_are_gone_from_both_products():
    rng = np.random.default_rng(1)
    B, K, L, n = 2, 5, 7, 20
    m = LocalColumns(rng.normal(size=(B, K, L, 1)), -3, 4, n)
    rows = np.zeros(n, bool)
    rows[[0, 5, 19]] = True
    m.zero_rows(rows)
    assert np.all(m.apply(rng.normal(size=(B, K)))[:, rows] == 0.0)
    lam = np.zeros((B, n))
    lam[:, rows] = 1.0
    assert np.all(m.adjoint(lam) == 0.0)
    assert np.any(_dense_columns(m) != 0.0)


def test_edge_turns_are_the_difference_of_the_end_nodes_and_the_adjoint_its_transpose():
    rng = np.random.default_rng(2)
    B, E = 3, 5
    n = 4 * (E + 1)
    w = rng.normal(size=(B, E, 3))
    t = EdgeTurns(w)
    D = np.zeros((B, E, n))
    for j in range(E):
        D[:, j, 4 * (j + 1):4 * (j + 1) + 3] = w[:, j]
        D[:, j, 4 * j:4 * j + 3] = -w[:, j]
    dx = rng.normal(size=(B, n, 2))
    np.testing.assert_allclose(t.apply(dx), D @ dx, rtol=1e-13, atol=1e-13)
    g = rng.normal(size=(B, E))
    np.testing.assert_allclose(t.adjoint(g), np.einsum("ben,be->bn", D, g), rtol=1e-13, atol=1e-13)


def test_band_columns_are_the_columns_of_the_dense_matrix():
    rng = np.random.default_rng(3)
    B, n, kl = 2, 30, 5
    A = rng.normal(size=(B, n, n)) * (np.abs(np.subtract.outer(np.arange(n), np.arange(n))) <= kl)
    ab = np.zeros((B, n + kl, 2 * kl + 1))
    for r in range(n):
        for c in range(max(0, r - kl), min(n, r + kl + 1)):
            ab[:, r, kl + c - r] = A[:, r, c]
    cols = np.array([0, 3, 17, 29])
    got = band_columns(ab, kl, cols)
    for j, c in enumerate(cols):
        for l in range(2 * kl + 1):
            r = c - kl + l
            np.testing.assert_array_equal(got[:, j, l], A[:, r, c] if 0 <= r < n else 0.0)


def test_transport_turns_follow_the_formula_and_joint_edges_keep_their_frame():
    rng = np.random.default_rng(4)
    B, E = 3, 4
    x = rng.normal(size=(B, 4 * (E + 1)))
    pos = x.reshape(B, E + 1, 4)[:, :, :3]
    e = pos[:, 1:] - pos[:, :-1]
    t = e / np.linalg.norm(e, axis=2, keepdims=True)
    t_from = rng.normal(size=(B, E, 3))
    t_from /= np.linalg.norm(t_from, axis=2, keepdims=True)
    link = np.array([1, 1, 0, 1], bool)
    got = EdgeTurns.of_transport(t_from, t, x, t, link).w
    k = np.cross(t, t_from) / (1.0 + np.einsum("bij,bij->bi", t_from, t))[..., None]
    want = (k - np.einsum("bij,bij->bi", t, k)[..., None] * t) / np.linalg.norm(e, axis=2)[..., None]
    want[:, ~link] = 0.0
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-15)
