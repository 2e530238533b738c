"""Banded LU and LDLᵀ without pivoting (numba), for the per-env Newton systems.

Storage ("padded band"): ``ab`` has shape (n + kl, 2kl + 1) with ``ab[i, kl + j - i] = A[i, j]`` for
|i − j| ≤ kl; the kl padding rows at the bottom are identity rows (``ab[i, kl] = 1``, rest 0) and entries
that would reference columns outside [0, n) are 0. ``b`` has length n + kl (padding entries 0). The padding
makes every inner loop have the constant trip count kl, which lets LLVM unroll them fully (≈4× faster).
:func:`band_lu_solve` is general (non-symmetric allowed, e.g. friction Jacobians); :func:`band_ldl_solve` is
its symmetric twin (LDLᵀ, reads and writes only the upper half of the band, about half the work). Neither
pivots, and for a symmetric matrix both take the same pivots (elimination without pivoting keeps the trailing
block symmetric, U = D Lᵀ), so they agree to rounding; indefinite matrices are fine as long as no pivot
vanishes. Pivots are checked: a zero, tiny (|p| ≤ 1e-14·max|diag|) or non-finite pivot is reported as a
failure.

Measured on the 84-unknown arm system (kl = 10, znver4): LU + solve 5.4 µs, LDLᵀ + solve 2.9 µs. The inner
loops have constant trip counts and are fully unrolled, not vectorised (numba ships LLVM's SLP vectoriser off);
the back substitution keeps two partial sums, which halves its dependency chain.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from sim.numba_options import OPT_CONTACT

__all__ = ["band_ldl_solve", "band_lu_solve", "band_ldl_factor", "band_ldl_apply", "band_lu_factor", "band_lu_apply",
           "band_lu_apply_transposed",
           "dense_to_band", "solve_dense_banded", "dense_lu_solve"]


@njit(cache=True, error_model="numpy", fastmath={"contract", "arcp", "nsz"}, inline="always")
def _pivot_floor(ab, n, kl):
    """1e-14·max|diag| (a pivot must exceed it in magnitude), or −1 if the diagonal is all zero or not finite."""
    dmax = 0.0
    for i in range(n):
        v = abs(ab[i, kl])
        if v > dmax:
            dmax = v
    if not (dmax > 0.0 and dmax < np.inf):
        return -1.0
    return 1e-14 * dmax


@njit(cache=True, error_model="numpy", fastmath={"contract", "arcp", "nsz"}, inline="always")
def band_lu_solve(ab, n, kl, b):
    """Factor the padded band ``ab`` in place and overwrite ``b`` with the solution of A x = b.

    Returns 0 on success, else 1 + the index of the first bad pivot (b is then undefined).
    """
    st = band_lu_factor(ab, n, kl)
    if st == 0:
        band_lu_apply(ab, n, kl, b)
    return st


@njit(cache=True, error_model="numpy", fastmath={"contract", "arcp", "nsz"}, inline="always")
def band_lu_factor(ab, n, kl):
    """LU of the padded band ``ab`` in place (no pivoting). Returns 0, or 1 + the index of the first bad pivot."""
    tiny = _pivot_floor(ab, n, kl)
    if tiny < 0.0:
        return 1
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
    return 0


@njit(cache=True, error_model="numpy", fastmath={"contract", "arcp", "nsz"}, inline="always")
def band_lu_apply(ab, n, kl, b):
    """Overwrite ``b`` (length n + kl) with A⁻¹ b from the factors :func:`band_lu_factor` left in ``ab``."""
    for k in range(n):  # forward, column (axpy) form: L[k+i, k] = ab[k+i, kl-i]; b's padding absorbs k+i >= n
        bk = b[k]
        for i in range(1, kl + 1):
            b[k + i] -= ab[k + i, kl - i] * bk
    for k in range(n, n + kl):
        b[k] = 0.0
    for i in range(n - 1, -1, -1):
        b[i] = _upper_dot_residual(ab, kl, b, i) / ab[i, kl]


@njit(cache=True, error_model="numpy", fastmath={"contract", "arcp", "nsz"}, inline="always")
def band_lu_apply_transposed(ab, n, kl, b):
    """Overwrite ``b`` (length n + kl) with A⁻ᵀ b from the factors :func:`band_lu_factor` left in ``ab``:
    Aᵀ = Uᵀ Lᵀ, so Uᵀ z = b forward (column form: U[k, k + j] = ab[k, kl + j]), then Lᵀ x = z backward
    (Lᵀ[k, k + i] = L[k + i, k] = ab[k + i, kl − i]; the padding rows' multipliers are 0)."""
    for k in range(n):
        zk = b[k] / ab[k, kl]
        b[k] = zk
        for j in range(1, kl + 1):
            b[k + j] -= ab[k, kl + j] * zk
    for k in range(n, n + kl):
        b[k] = 0.0
    for k in range(n - 1, -1, -1):
        s = b[k]
        for i in range(1, kl + 1):
            s -= ab[k + i, kl - i] * b[k + i]
        b[k] = s


@njit(cache=True, error_model="numpy", fastmath={"contract", "arcp", "nsz"}, inline="always")
def _upper_dot_residual(ab, kl, b, i):
    """b[i] − Σ_{j=1..kl} ab[i, kl+j]·b[i+j], with two partial sums (shorter dependency chain)."""
    s0 = b[i]
    s1 = 0.0
    for j in range(1, kl + 1, 2):
        s0 -= ab[i, kl + j] * b[i + j]
        if j + 1 <= kl:
            s1 += ab[i, kl + j + 1] * b[i + j + 1]
    return s0 - s1


@njit(cache=True, error_model="numpy", fastmath={"contract", "arcp", "nsz"}, inline="always")
def band_ldl_solve(ab, n, kl, b):
    """Symmetric twin of :func:`band_lu_solve`: LDLᵀ of the padded band ``ab`` in place, using only its upper
    half (``ab[i, kl + j]``, j ≥ 0; the lower half is neither read nor written), and ``b`` overwritten with the
    solution. The caller must know A is symmetric. Returns 0 on success, else 1 + the first bad pivot's index.
    """
    st = band_ldl_factor(ab, n, kl)
    if st == 0:
        band_ldl_apply(ab, n, kl, b)
    return st


@njit(cache=True, error_model="numpy", fastmath={"contract", "arcp", "nsz"}, inline="always")
def band_ldl_factor(ab, n, kl):
    """LDLᵀ of the upper half of the padded band ``ab`` in place. Returns 0, or 1 + the first bad pivot's index."""
    tiny = _pivot_floor(ab, n, kl)
    if tiny < 0.0:
        return 1
    for k in range(n):
        p = ab[k, kl]
        if not (abs(p) > tiny and abs(p) < np.inf):
            return k + 1
        ip = 1.0 / p
        for i in range(1, kl + 1):
            lk = ab[k, kl + i] * ip  # L[k+i, k] = A[k, k+i] / d_k
            for j in range(i, kl + 1):
                ab[k + i, kl + j - i] -= lk * ab[k, kl + j]
        for i in range(1, kl + 1):
            ab[k, kl + i] *= ip  # row k of the upper half now holds Lᵀ
    return 0


@njit(cache=True, error_model="numpy", fastmath={"contract", "arcp", "nsz"}, inline="always")
def band_ldl_apply(ab, n, kl, b):
    """Overwrite ``b`` (length n + kl) with A⁻¹ b from the factors :func:`band_ldl_factor` left in ``ab``."""
    for k in range(n):  # L y = b (unit lower, column form); the padding rows of ab are identity rows
        bk = b[k]
        for i in range(1, kl + 1):
            b[k + i] -= ab[k, kl + i] * bk
    for k in range(n, n + kl):  # keep the padding 0 (it meets zero band entries in the back substitution)
        b[k] = 0.0
    for k in range(n):
        b[k] /= ab[k, kl]
    for i in range(n - 1, -1, -1):  # Lᵀ x = y (unit upper)
        b[i] = _upper_dot_residual(ab, kl, b, i)


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


@njit(cache=True, error_model="numpy")
def _solve_band_sym(ab, n, kl, b):
    return band_ldl_solve(ab, n, kl, b)


def solve_dense_banded(A: np.ndarray, kl: int, b: np.ndarray, *, symmetric: bool = False) -> tuple[np.ndarray, int]:
    """Solve A x = b (A dense (n, n), only its band of half-width kl is used; with ``symmetric`` only the upper
    half of the band, by LDLᵀ). Returns (x, status)."""
    n = A.shape[0]
    ab = dense_to_band(np.asarray(A, dtype=np.float64), kl)
    if symmetric:
        ab[:, :kl] = np.nan  # the LDLᵀ path must never read the lower half
    bb = np.zeros(n + kl)
    bb[:n] = b
    st = (_solve_band_sym if symmetric else _solve_band)(ab, n, kl, bb)
    assert not symmetric or np.isnan(ab[:, :kl]).all()
    return bb[:n].copy(), int(st)


@njit(**OPT_CONTACT)  # as in the contact kernels: no fastmath (bitwise references)
def dense_lu_solve(A, k, b, piv):
    """Solve A[:k, :k] y = b[:k] in place (LU with partial pivoting; A overwritten, y into b). False if singular."""
    for c in range(k):
        p = c
        big = abs(A[c, c])
        for r in range(c + 1, k):
            if abs(A[r, c]) > big:
                big = abs(A[r, c])
                p = r
        if not (big > 0.0 and big < np.inf):
            return False
        piv[c] = p
        if p != c:
            for m in range(k):
                tmp = A[c, m]
                A[c, m] = A[p, m]
                A[p, m] = tmp
            tmp = b[c]
            b[c] = b[p]
            b[p] = tmp
        ip = 1.0 / A[c, c]
        for r in range(c + 1, k):
            l = A[r, c] * ip
            if l != 0.0:
                A[r, c] = l
                for m in range(c + 1, k):
                    A[r, m] -= l * A[c, m]
                b[r] -= l * b[c]
    for r in range(k - 1, -1, -1):
        v = b[r]
        for m in range(r + 1, k):
            v -= A[r, m] * b[m]
        b[r] = v / A[r, r]
    return True
