"""A hand on the rod: grab it at a node and pull it toward the pointer with a spring.

The hand holds the grabbed node and up to :data:`PATCH` neighbours on each side (on the same rod), as a hand holds a
short stretch of a soft arm. Held node ``j`` is pulled toward the pointer ``p`` plus its offset ``o_j`` from the
point where the rod was pressed (on its surface), at the moment of the grab: the held stretch moves with the hand as
it was held, not squeezed onto the pointer, by

    F_j = m_j (α (p + o_j − x_j) / h² − β v_j / h)

with ``m_j`` the node's mass, ``h`` the step and ``x_j``, ``v_j`` its position and velocity at the start of the step.
The forces enter the step as ``Control.force`` (docs/physics.md §3.1): held over the step, no new physics path. The
spring is explicit, so its constants scale with the node masses and the step: for a node that moved alone (no
elastic neighbours, the least stable case) the error ``e = x − p − o`` follows ``e' = (1 − α) e + (1 − β) h v`` and
``h v' = (1 − β) h v − α e``, whose eigenvalues have modulus √(1 − β) ≈ 0.45 with α = 1, β = 0.8: it settles
within a few steps whatever the scene, and the rod's elasticity only stiffens the node further.
"""
from __future__ import annotations

import dataclasses

import numpy as np

PATCH = 2  # nodes on each side of the grabbed one that the hand holds (on the same rod)
STIFFNESS = 1.0  # α: spring k_j = α m_j / h² [N/m] per held node
DAMPING = 0.8  # β: damper c_j = β m_j / h [N s/m] per held node
MAX_REACH_M = 100.0  # a pointer farther than this from the origin is refused (not a place on the page)
HAND_EVENTS = 256  # the page's drag phases queued for the stepping thread at most (a flood drops the oldest)


@dataclasses.dataclass
class Pull:
    """A grab in progress.

    node: the grabbed node (global index); nodes: the held nodes (K,); offsets: (K, 3) [m] their positions relative to
    the pressed point at the grab; pointer: (3,) [m] where the hand is (the pressed point at the grab); force: (3,)
    [N] the total force of the last step (0 before the first)."""

    node: int
    nodes: np.ndarray
    offsets: np.ndarray
    pointer: np.ndarray
    force: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(3))


def point(value, what: str = "pointer") -> np.ndarray:
    """``value`` as a (3,) float array of finite numbers within :data:`MAX_REACH_M`; ValueError naming ``what``."""
    try:
        p = np.asarray(value, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise ValueError(f"{what} must be 3 finite numbers [m], got {value!r}") from None
    if p.shape != (3,) or not np.all(np.isfinite(p)):
        raise ValueError(f"{what} must be 3 finite numbers [m], got {value!r}")
    if np.abs(p).max() > MAX_REACH_M:
        raise ValueError(f"{what} is more than {MAX_REACH_M:g} m from the origin")
    return p


def held_nodes(node: int, n_nodes: int, rod_offsets: np.ndarray | None = None) -> np.ndarray:
    """The nodes a hand holds when it grabs ``node``: ±:data:`PATCH` around it, within its rod (``rod_offsets``: where
    each rod's nodes start, then N; None for one rod)."""
    lo, hi = 0, n_nodes
    if rod_offsets is not None:
        r = int(np.searchsorted(rod_offsets, node, side="right")) - 1
        lo, hi = int(rod_offsets[r]), int(rod_offsets[r + 1])
    return np.arange(max(node - PATCH, lo), min(node + PATCH + 1, hi))


def grab(x: np.ndarray, at, rod_offsets: np.ndarray | None = None) -> Pull:
    """The pull of a hand that grabs the rod of node positions ``x`` (N, 3) at the node nearest the point ``at``."""
    p = point(at, "grab point")
    node = int(np.argmin(np.linalg.norm(x - p, axis=1)))
    nodes = held_nodes(node, len(x), rod_offsets)
    return Pull(node=node, nodes=nodes, offsets=x[nodes] - p, pointer=p)


def held_point(pull: Pull, x: np.ndarray) -> np.ndarray:
    """(3,) [m] where the hand holds the rod of node positions ``x`` (N, 3) now: the pressed point, moved with the
    grabbed node."""
    return x[pull.node] - pull.offsets[int(np.flatnonzero(pull.nodes == pull.node)[0])]


def spring_forces(pull: Pull, x: np.ndarray, v: np.ndarray, mass: np.ndarray, h: float) -> np.ndarray:
    """(K, 3) [N] the forces on the held nodes for the next step of length ``h`` from node positions ``x`` (N, 3),
    velocities ``v`` (N, 3) and masses ``mass`` (N,) at its start."""
    j = pull.nodes
    m = mass[j][:, None]
    return m * (STIFFNESS * (pull.pointer + pull.offsets - x[j]) / h ** 2 - DAMPING * v[j] / h)


def control_force(pull: Pull, state, env: int, mass: np.ndarray, h: float) -> np.ndarray:
    """(B, N, 3) [N] the ``Control.force`` of the next step of length ``h`` for a hand on env ``env`` of ``state``
    (a sim ``State``; ``mass`` (N,) the node masses): the springs on that env's held nodes, zero elsewhere. Keeps
    the total in ``pull.force``."""
    F = spring_forces(pull, np.asarray(state.node_pos[env]), np.asarray(state.node_vel[env]), np.asarray(mass), h)
    force = np.zeros((state.dof.shape[0], len(mass), 3))
    force[env, pull.nodes] = F
    pull.force = F.sum(axis=0)
    return force


def apply_gestures(queue, grab_at, move_to, release, say, errors=(ValueError,)) -> bool:
    """Apply the queued drag phases ``(phase, start, end)`` in order: start grabs at ``start`` and moves the hand to
    ``end``, update moves it, end lets go; a refused one (one of ``errors``) is passed to ``say``. Returns whether
    there were any."""
    any_ = False
    while queue:
        phase, start, end = queue.popleft()
        any_ = True
        try:
            if phase == "start":
                grab_at(start)
                move_to(end)
            elif phase == "update":
                move_to(end)
            else:
                release()
        except errors as exc:
            say(exc)
    return any_
