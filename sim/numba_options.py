"""The numba options of every kernel module (a bottom module: it imports nothing, so the geometry, frame and
energy modules can use it without loading solver code).

The step's kernels allocate nothing (all scratch is in the thread's :class:`sim.kernels.workspace.Workspace`), so
they are compiled without the runtime's reference counting (``_nrt=False``): its atomic increments and decrements
on every array passed down the call chain, on arrays that both threads share, cost about a fifth of a step. A
kernel that tried to allocate would not compile. ``OPT_ALLOC``: the few functions that allocate (the workspace,
the parallel driver, the static Hessian). ``OPT_CONTACT``: the contact kernels, the same as ``OPT`` without
fastmath (their results are compared bit for bit with references). None of them names a CPU-only feature.
"""
from __future__ import annotations

__all__ = ["OPT", "OPT_ALLOC", "OPT_CONTACT"]

OPT_ALLOC = dict(cache=True, error_model="numpy", fastmath={"contract", "arcp", "nsz"})
OPT = dict(OPT_ALLOC, _nrt=False)
OPT_CONTACT = dict(cache=True, _nrt=False)
