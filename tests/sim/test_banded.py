"""Banded LU (no pivoting) against numpy.linalg.solve, and its pivot checks."""
from __future__ import annotations

import numpy as np
import pytest

from sim.kernels.banded import dense_to_band, solve_dense_banded


def _random_banded(rng, n, kl, symmetric):
    A = rng.standard_normal((n, n))
    if symmetric:
        A = A + A.T
    A += (4 * kl + 2) * np.eye(n)   # diagonally dominant: no pivoting needed
    i, j = np.indices((n, n))
    A[np.abs(i - j) > kl] = 0.0
    return A


@pytest.mark.parametrize("n, kl, sym", [(84, 10, True), (84, 10, False), (42, 5, False), (12, 10, False),
                                        (7, 5, True)])
def test_banded_lu_matches_dense_solve(n, kl, sym):
    rng = np.random.default_rng(n + kl)
    for _ in range(5):
        A = _random_banded(rng, n, kl, sym)
        b = rng.standard_normal(n)
        x, st = solve_dense_banded(A, kl, b)
        assert st == 0
        ref = np.linalg.solve(A, b)
        assert np.abs(x - ref).max() <= 1e-12 * max(1.0, np.abs(ref).max())


def test_banded_lu_identity_rows_for_constraints():
    rng = np.random.default_rng(0)
    A = _random_banded(rng, 40, 10, False)
    for k in (0, 1, 2, 39):
        A[k, :] = 0
        A[:, k] = 0
        A[k, k] = 1
    b = rng.standard_normal(40)
    b[[0, 1, 2, 39]] = 0
    x, st = solve_dense_banded(A, 10, b)
    assert st == 0 and np.all(x[[0, 1, 2, 39]] == 0)
    assert np.allclose(A @ x, b, atol=1e-12)


def test_banded_lu_reports_bad_pivots():
    rng = np.random.default_rng(1)
    A = _random_banded(rng, 30, 5, False)
    A0 = A.copy()
    A0[7, :] = 0.0          # singular: zero row -> zero pivot at row 7 at the latest
    _, st = solve_dense_banded(A0, 5, np.ones(30))
    assert st != 0
    A1 = A.copy()
    A1[3, 3] = np.nan
    _, st = solve_dense_banded(A1, 5, np.ones(30))
    assert st != 0
    A2 = A.copy()
    A2[0, 0] = np.inf
    _, st = solve_dense_banded(A2, 5, np.ones(30))
    assert st != 0


# ------------------------------------------------------------------ symmetric twin (LDLᵀ, upper half only)
@pytest.mark.parametrize("n, kl", [(84, 10), (42, 5), (12, 10), (7, 5), (1, 10)])
def test_banded_ldl_matches_dense_solve_and_lu(n, kl):
    rng = np.random.default_rng(100 + n + kl)
    for _ in range(5):
        A = _random_banded(rng, n, kl, True)
        b = rng.standard_normal(n)
        x, st = solve_dense_banded(A, kl, b, symmetric=True)  # lower half is NaN there: never read
        assert st == 0
        ref = np.linalg.solve(A, b)
        assert np.abs(x - ref).max() <= 1e-12 * max(1.0, np.abs(ref).max())
        x_lu, _ = solve_dense_banded(A, kl, b)
        assert np.abs(x - x_lu).max() <= 1e-12 * max(1.0, np.abs(ref).max())


def test_banded_ldl_indefinite_and_constraint_rows():
    """An indefinite symmetric matrix (negative pivots, as a Newton Jacobian with compressive bending can be)
    is solved; identity rows/columns of fixed DOFs give exact zeros."""
    rng = np.random.default_rng(5)
    n, kl = 40, 10
    A = _random_banded(rng, n, kl, True)
    A[np.arange(0, n, 3), np.arange(0, n, 3)] *= -1.0
    for k in (0, 1, 2, 39):
        A[k, :] = 0
        A[:, k] = 0
        A[k, k] = 1
    b = rng.standard_normal(n)
    b[[0, 1, 2, 39]] = 0
    x, st = solve_dense_banded(A, kl, b, symmetric=True)
    assert st == 0 and np.all(x[[0, 1, 2, 39]] == 0)
    assert np.allclose(A @ x, b, atol=1e-11)


def test_banded_ldl_reports_bad_pivots():
    rng = np.random.default_rng(2)
    A = _random_banded(rng, 30, 5, True)
    for bad in ("zero", "nan", "inf"):
        Ab = A.copy()
        if bad == "zero":
            Ab[7, :] = 0.0
            Ab[:, 7] = 0.0
        else:
            Ab[3, 3] = np.nan if bad == "nan" else np.inf
        _, st = solve_dense_banded(Ab, 5, np.ones(30), symmetric=True)
        assert st != 0, bad


@pytest.mark.parametrize("n, kl", [(84, 11), (42, 5), (12, 10)])
def test_one_factorisation_solves_with_the_matrix_and_its_transpose(n, kl):
    from sim.kernels.linearise import factor_bands, solve_bands

    rng = np.random.default_rng(n * kl)
    B = 3
    A = np.stack([_random_banded(rng, n, kl, False) for _ in range(B)])
    ab = np.stack([dense_to_band(a, kl) for a in A])
    status = np.zeros(B, np.int64)
    factor_bands(ab, kl, status)
    assert np.all(status == 0)
    rhs = rng.standard_normal((B, n, 2))
    for transpose in (False, True):
        out = np.empty_like(rhs)
        solve_bands(ab, kl, transpose, rhs, out)
        ref = np.linalg.solve(A.transpose(0, 2, 1) if transpose else A, rhs)
        assert np.abs(out - ref).max() <= 1e-12 * np.abs(ref).max()
