"""PyElastica back-end of the tasks (``rodlab eval POLICY --backend elastica``), needs the ``peers`` extra.

``policies.elastica.rods``: the paper's Elastica arm (docs/tasks.md §1.6), also used by the benchmarks;
``policies.elastica.backend``: the four tasks with that arm in place of the implicit simulator.
"""
from __future__ import annotations

__all__ = ["make_elastica_core", "make_elastica_vec_env"]


def make_elastica_core(task: str, envs: int, **kwargs):
    from policies.elastica.backend import make_elastica_core as _make

    return _make(task, envs, **kwargs)


def make_elastica_vec_env(task: str, envs: int, **kwargs):
    """``BatchedVecEnv`` (gymnasium VectorEnv) of the task on PyElastica."""
    from policies.vec_env import BatchedVecEnv

    core = make_elastica_core(task, envs, **kwargs)
    return BatchedVecEnv(core, task_id=f"{type(core).__name__}[elastica]")
