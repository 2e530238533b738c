"""The contact protocol the Newton stages call, once per stage (docs/physics.md §4, stages in
:mod:`sim.kernels.newton`).

A scene's contact is a :class:`ContactSets`: obstacle contact (:mod:`sim.contact.obstacles`, an
``ObstacleContact``) and edge-pair contact between rod edges (:mod:`sim.contact.edge_pairs`, an
``EdgePairContact``). Both implementations provide the same functions with the same arguments —
``present(prm)``, ``candidates(e, c)``, ``friction_acts(prm)``, ``broadphase``, ``refresh``, ``penetration``,
``step_limit``, ``accumulate``, ``energy``, ``report`` — and each stage below runs them for the implementations the
scene has (``present``), skipping one with no candidates where that decides the result. Every stage takes the env
index ``e``, the parameters ``prm`` (a :class:`sim.kernels.data.Params` record), the rod ``rod``
(:class:`sim.kernels.data.RodData`), the contact sets ``cs`` and the stage's own arrays: node positions ``pos``
(N, 3) (the (sub)step's start ``pos0``), the node update ``dpos`` (N, 3), the thread's Workspace ``w`` (residual,
band, coupling list) or the contact rows ``rows`` (:class:`sim.kernels.data.ContactReport`).
"""
from __future__ import annotations

from collections import namedtuple

from numba import njit

from sim.contact import edge_pairs, obstacles
from sim.numba_options import OPT_ALLOC, OPT_CONTACT

__all__ = ["ContactSets", "alloc", "present", "has_candidates", "friction_acts", "symmetric", "broadphase",
           "refresh", "penetration", "step_limit", "accumulate", "energy", "report"]

ContactSets = namedtuple("ContactSets", ["obstacles", "pairs"])
ContactSets.__doc__ = """A scene's contact for one thread of the step: ``obstacles`` (an ObstacleContact) and ``pairs``
(an EdgePairContact)."""


@njit(**OPT_ALLOC)
def alloc(cd, N, P):
    """One thread's :class:`ContactSets` for a rod of N nodes: the obstacles' ContactData ``cd`` and P allowed edge
    pairs."""
    return ContactSets(obstacles.alloc(cd, N), edge_pairs.alloc(N, P))


@njit(inline="always", **OPT_CONTACT)
def present(prm):
    """Whether the scene has any contact."""
    return obstacles.present(prm) or edge_pairs.present(prm)


@njit(inline="always", **OPT_CONTACT)
def has_candidates(e, prm, cs):
    """Whether env ``e`` has contact candidates now."""
    return ((obstacles.present(prm) and obstacles.candidates(e, cs.obstacles) > 0)
            or (edge_pairs.present(prm) and edge_pairs.candidates(e, cs.pairs) > 0))


@njit(inline="always", **OPT_CONTACT)
def friction_acts(e, prm, cs):
    """Whether friction can act in env ``e`` now: a contact with μ > 0 has candidates."""
    return ((obstacles.friction_acts(prm) and obstacles.present(prm) and obstacles.candidates(e, cs.obstacles) > 0)
            or (edge_pairs.friction_acts(prm) and edge_pairs.present(prm) and edge_pairs.candidates(e, cs.pairs) > 0))


@njit(inline="always", **OPT_CONTACT)
def symmetric(prm):
    """Whether the contact leaves the Newton Jacobian symmetric: yes unless friction can act."""
    return not ((obstacles.present(prm) and obstacles.friction_acts(prm))
                or (edge_pairs.present(prm) and edge_pairs.friction_acts(prm)))


@njit(inline="always", **OPT_CONTACT)
def broadphase(e, prm, rod, cs, pos0, pos):
    """Candidate lists over the motion pos0 → pos."""
    if obstacles.present(prm):
        obstacles.broadphase(e, prm, rod, cs.obstacles, pos0, pos)
    if edge_pairs.present(prm):
        edge_pairs.broadphase(e, prm, rod, cs.pairs, pos0, pos)


@njit(inline="always", **OPT_CONTACT)
def refresh(e, prm, rod, cs, pos0, pos):
    """Candidates over the motion actually taken pos0 → pos merged into the lists: (whether any was added, whether
    the (sub)step must be solved again)."""
    added = False
    resolve = False
    if obstacles.present(prm):
        a, r = obstacles.refresh(e, prm, rod, cs.obstacles, pos0, pos)
        added = added or a
        resolve = resolve or r
    if edge_pairs.present(prm):
        a, r = edge_pairs.refresh(e, prm, rod, cs.pairs, pos0, pos)
        added = added or a
        resolve = resolve or r
    return added, resolve


@njit(inline="always", **OPT_CONTACT)
def penetration(e, prm, rod, cs, pos):
    """Deepest penetration [m] (≥ 0) over the candidates at ``pos``."""
    pen = 0.0
    if obstacles.present(prm) and obstacles.candidates(e, cs.obstacles) > 0:
        pen = obstacles.penetration(e, prm, rod, cs.obstacles, pos)
    if edge_pairs.present(prm) and edge_pairs.candidates(e, cs.pairs) > 0:
        pen = max(pen, edge_pairs.penetration(e, prm, rod, cs.pairs, pos))
    return pen


@njit(inline="always", **OPT_CONTACT)
def step_limit(e, prm, rod, cs, pos, dpos):
    """Largest fraction t ∈ (0, 1] of the node update ``dpos`` from ``pos`` that carries no rod edge through an
    obstacle or another edge."""
    t = 1.0
    if obstacles.present(prm) and obstacles.candidates(e, cs.obstacles) > 0:
        t = obstacles.step_limit(e, prm, rod, cs.obstacles, pos, dpos)
    if edge_pairs.present(prm) and edge_pairs.candidates(e, cs.pairs) > 0:
        t = min(t, edge_pairs.step_limit(e, prm, rod, cs.pairs, pos, dpos))
    return t


@njit(inline="always", **OPT_CONTACT)
def accumulate(e, prm, rod, cs, w, h, with_jac, sym):
    """Add the contact residual into ``w.f`` and (``with_jac``) its Jacobian into ``w.ab`` / ``w.coupling`` at the
    nodes w.pos (velocities from w.pos0 over h); returns the contact energy [J]."""
    ec = 0.0
    if obstacles.present(prm):
        ec += obstacles.accumulate(e, prm, rod, cs.obstacles, w, h, with_jac, sym)
    if edge_pairs.present(prm):
        ec += edge_pairs.accumulate(e, prm, rod, cs.pairs, w, h, with_jac, sym)
    return ec


@njit(inline="always", **OPT_CONTACT)
def energy(e, prm, rod, cs, pos, pos0, h):
    """Contact energy [J] over the current candidates at ``pos`` (friction off)."""
    ec = 0.0
    if obstacles.present(prm) and obstacles.candidates(e, cs.obstacles) > 0:
        ec += obstacles.energy(e, prm, rod, cs.obstacles, pos, pos0, h)
    if edge_pairs.present(prm) and edge_pairs.candidates(e, cs.pairs) > 0:
        ec += edge_pairs.energy(e, prm, rod, cs.pairs, pos, pos0, h)
    return ec


@njit(inline="always", **OPT_CONTACT)
def report(e, prm, rod, cs, pos, pos0, rows):
    """Env ``e``'s contact rows, max penetration, dropped rows and total force at the state kept (``pos``; ``pos0`` the step's start by its
    velocity), over fresh candidate lists (a guard fallback or a restored state is not the configuration the last
    sub-step's lists were built for); returns the contact energy [J]."""
    rows.count[e] = 0
    rows.max_penetration[e] = 0.0
    rows.dropped[e] = 0
    for a in range(3):
        rows.force[e, a] = 0.0
    ec = 0.0
    if obstacles.present(prm):
        ec += obstacles.report(e, prm, rod, cs.obstacles, pos, pos0, rows)
    if edge_pairs.present(prm):
        ec += edge_pairs.report(e, prm, rod, cs.pairs, pos, pos0, rows)
    return ec
