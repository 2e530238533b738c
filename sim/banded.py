"""Banded LU without pivoting (numba), for the per-env Newton systems.

Storage ("padded band"): ``ab`` has shape (n + kl, 2kl + 1) with ``ab[i, kl + j - i] = A[i, j]`` for
|i − j| ≤ kl; the kl padding rows at the bottom are identity rows (``ab[i, kl] = 1``, rest 0) and entries
that would reference columns outside [0, n) are 0. ``b`` has length n + kl (padding entries 0). The padding
makes every inner loop have the constant trip count kl, which lets LLVM unroll/vectorise them (≈4× faster).
The factorisation is general (non-symmetric allowed, e.g. friction Jacobians); pivots are checked: a zero,
tiny (|p| ≤ 1e-14·max|diag|) or non-finite pivot is reported as a failure.
"""
from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["band_lu_solve", "dense_to_band", "solve_dense_banded"]


@njit(cache=True, error_model="numpy", fastmath={"contract", "arcp", "nsz"}, inline="always")
def band_lu_solve(ab, n, kl, b):
    """Factor the padded band ``ab`` in place and overwrite ``b`` with the solution of A x = b.

    Returns 0 on success, else 1 + the index of the first bad pivot (b is then undefined).
    """
    dmax = 0.0
    for i in range(n):
        v = abs(ab[i, kl])
        if v > dmax:
            dmax = v
    if not (dmax > 0.0 and dmax < np.inf):
        return 1
    tiny = 1e-14 * dmax
    for k in range(n):
        p = ab[k, kl]
        if not (abs(p) > tiny and abs(p) < np.inf):
            return k + 1
        ip = 1.0 / p
        for i in range(1, kl + 1):
            lik = ab[k + i, kl - i] * ip
            ab[k + i, kl - i] = lik
            for j in range(1, kl + 1):
                ab[k + i, kl + j - i] -= lik * ab[k, kl + j]
    for i in range(n):
        s = b[i]
        for k in range(1, kl + 1):
            if i - k >= 0:
                s -= ab[i, kl - k] * b[i - k]
        b[i] = s
    for i in range(n - 1, -1, -1):
        s = b[i]
        for j in range(1, kl + 1):
            s -= ab[i, kl + j] * b[i + j]
        b[i] = s / ab[i, kl]
    return 0


def dense_to_band(A: np.ndarray, kl: int) -> np.ndarray:
    """Padded band storage (n + kl, 2kl + 1) of a dense (n, n) matrix (entries outside the band are dropped)."""
    n = A.shape[0]
    ab = np.zeros((n + kl, 2 * kl + 1))
    for i in range(n):
        for j in range(max(0, i - kl), min(n, i + kl + 1)):
            ab[i, kl + j - i] = A[i, j]
    ab[n:, kl] = 1.0
    return ab


@njit(cache=True, error_model="numpy")
def _solve_band(ab, n, kl, b):
    return band_lu_solve(ab, n, kl, b)


def solve_dense_banded(A: np.ndarray, kl: int, b: np.ndarray) -> tuple[np.ndarray, int]:
    """Solve A x = b (A dense (n, n), only its band of half-width kl is used). Returns (x, status)."""
    n = A.shape[0]
    ab = dense_to_band(np.asarray(A, dtype=np.float64), kl)
    bb = np.zeros(n + kl)
    bb[:n] = b
    st = _solve_band(ab, n, kl, bb)
    return bb[:n].copy(), int(st)
