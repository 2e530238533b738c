"""Sparse maps of a step's linearisation (sim.analysis.gradients), stored by what they touch, not as dense arrays.

A column of ∂f/∂p for a natural curvature, a frame angle or a twist touches the few rows of one element, and a
frame turn depends on the two nodes of one edge: stored densely they cost B·n·K numbers, most of them zeros that
are written, kept and multiplied on every pass.
"""
from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["LocalColumns", "EdgeTurns", "band_columns"]


class LocalColumns:
    """K·C columns of an (n × K·C) matrix per env, the C columns of site k nonzero only on the L rows
    ``first + stride·k … first + stride·k + L − 1`` (rows outside 0 … n − 1 hold 0). ``values`` (B, K, L, C): entry
    (b, k, l, c) is row first + stride·k + l of column k·C + c of env b."""

    def __init__(self, values: np.ndarray, first: int, stride: int, n: int):
        B, K, L, C = values.shape
        self.values = values
        self.n = n
        self.first = first
        self.stride = stride
        self._rows = first + stride * np.arange(K)[:, None] + np.arange(L)[None, :]  # (K, L)

    @property
    def nbytes(self) -> int:
        return self.values.nbytes

    def zero_rows(self, rows: np.ndarray) -> None:
        """Set the entries of the rows flagged in ``rows`` (n,) bool to 0 (constrained DOFs: no equation)."""
        r = self._rows
        hit = np.zeros(r.shape, bool)
        inside = (r >= 0) & (r < self.n)
        hit[inside] = rows[r[inside]]
        self.values[:, hit, :] = 0.0

    def apply(self, v: np.ndarray) -> np.ndarray:
        """M v for every env: v (B, K·C) or (B, K·C, Q) → (B, n) or (B, n, Q)."""
        B, K, L, C = self.values.shape
        vk = np.ascontiguousarray(v, dtype=np.float64).reshape(B, K, C, -1)
        out = np.zeros((B, self.n, vk.shape[3]))
        _apply(self.values, self.first, self.stride, vk, out)
        return out.reshape((B, self.n) + v.shape[2:])

    def adjoint(self, lam: np.ndarray) -> np.ndarray:
        """Mᵀ λ for every env: lam (B, n) → (B, K·C)."""
        B, K, L, C = self.values.shape
        out = np.empty((B, K, C))
        _adjoint(self.values, self.first, self.stride, np.ascontiguousarray(lam, dtype=np.float64), out)
        return out.reshape(B, K * C)


@njit(cache=True)
def _apply(values, first, stride, v, out):
    """out[b, r, q] += Σ_c values[b, k, l, c] v[b, k, c, q] over the sites k and rows l with r = first + stride k + l
    inside 0 … n − 1."""
    B, K, L, C = values.shape
    n = out.shape[1]
    for b in range(B):
        for k in range(K):
            for l in range(L):
                r = first + stride * k + l
                if r < 0 or r >= n:
                    continue
                for q in range(v.shape[3]):
                    acc = 0.0
                    for c in range(C):
                        acc += values[b, k, l, c] * v[b, k, c, q]
                    out[b, r, q] += acc


@njit(cache=True)
def _adjoint(values, first, stride, lam, out):
    """out[b, k, c] = Σ_l values[b, k, l, c] lam[b, first + stride k + l] (rows inside 0 … n − 1)."""
    B, K, L, C = values.shape
    n = lam.shape[1]
    for b in range(B):
        for k in range(K):
            for c in range(C):
                acc = 0.0
                for l in range(L):
                    r = first + stride * k + l
                    if 0 <= r < n:
                        acc += values[b, k, l, c] * lam[b, r]
                out[b, k, c] = acc


def band_columns(ab: np.ndarray, kl: int, cols: np.ndarray) -> np.ndarray:
    """(B, len(cols), 2 kl + 1): entry (b, j, l) is J[c − kl + l, c] of each env's padded band ``ab`` (B, n + kl,
    2 kl + 1) (:mod:`sim.kernels.banded`'s storage) at column c = cols[j]; rows outside 0 … n − 1 give 0."""
    out = np.empty((ab.shape[0], len(cols), 2 * kl + 1))
    _band_columns(ab, kl, np.asarray(cols, dtype=np.int64), out)
    return out


@njit(cache=True)
def _band_columns(ab, kl, cols, out):
    n = ab.shape[1] - kl
    for b in range(ab.shape[0]):
        for j in range(cols.shape[0]):
            c = cols[j]
            for l in range(2 * kl + 1):
                r = c - kl + l
                out[b, j, l] = ab[b, r, 2 * kl - l] if 0 <= r < n else 0.0  # band entry (r, kl + c − r)


@njit(cache=True)
def _transport_turns(t_from, t_to, x, t, link, w):
    B, E = t.shape[0], t.shape[1]
    for b in range(B):
        for j in range(E):
            if not link[j]:
                w[b, j, 0] = w[b, j, 1] = w[b, j, 2] = 0.0
                continue
            a0, a1, a2 = t_from[b, j, 0], t_from[b, j, 1], t_from[b, j, 2]
            c0, c1, c2 = t_to[b, j, 0], t_to[b, j, 1], t_to[b, j, 2]
            s = 1.0 / (1.0 + a0 * c0 + a1 * c1 + a2 * c2)
            k0, k1, k2 = (c1 * a2 - c2 * a1) * s, (c2 * a0 - c0 * a2) * s, (c0 * a1 - c1 * a0) * s
            e0 = x[b, 4 * j + 4] - x[b, 4 * j]
            e1 = x[b, 4 * j + 5] - x[b, 4 * j + 1]
            e2 = x[b, 4 * j + 6] - x[b, 4 * j + 2]
            il = 1.0 / np.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
            u0, u1, u2 = t[b, j, 0], t[b, j, 1], t[b, j, 2]
            tk = u0 * k0 + u1 * k1 + u2 * k2
            w[b, j, 0] = (k0 - tk * u0) * il
            w[b, j, 1] = (k1 - tk * u1) * il
            w[b, j, 2] = (k2 - tk * u2) * il


class EdgeTurns:
    """The map of a change of the 3-D DOFs (B, n) to one angle per edge, w_j · (δx_{j+1} − δx_j) with
    ``w`` (B, E, 3) (a frame's turn as its edge's end nodes move; n = 4 (E + 1): 4 DOFs per node)."""

    def __init__(self, w: np.ndarray):
        self.w = w

    @classmethod
    def of_transport(cls, t_from: np.ndarray, t_to: np.ndarray, x: np.ndarray, t: np.ndarray,
                     link: np.ndarray) -> "EdgeTurns":
        """The turn of each edge's transported director from a change of the DOFs x (B, n) whose edge tangents are
        t: w_j = (I − t tᵀ) k_j / |e_j|, k = (t_to × t_from) / (1 + t_from·t_to) for the transport from tangents
        ``t_from`` to ``t_to`` (B, E, 3) (docs/physics.md §3.9, "Frames"); an edge with ``link`` 0 (a joint edge:
        it keeps its frame) turns by 0."""
        w = np.empty(t.shape)
        _transport_turns(t_from, t_to, x, t, link.astype(np.bool_), w)
        return cls(w)

    @property
    def nbytes(self) -> int:
        return self.w.nbytes

    def apply(self, dx: np.ndarray) -> np.ndarray:
        """(B, E, Q) for dx (B, n, Q)."""
        B, E = self.w.shape[:2]
        pos = dx.reshape((B, E + 1, 4) + dx.shape[2:])
        d = pos[:, 1:, :3] - pos[:, :-1, :3]  # (B, E, 3, Q)
        return np.einsum("bec,becq->beq", self.w, d)

    def adjoint(self, g: np.ndarray) -> np.ndarray:
        """(B, n) for g (B, E): the transpose."""
        B, E = self.w.shape[:2]
        wg = self.w * g[:, :, None]  # (B, E, 3)
        out = np.zeros((B, E + 1, 4))
        out[:, 1:, :3] += wg
        out[:, :-1, :3] -= wg
        return out.reshape(B, 4 * (E + 1))
