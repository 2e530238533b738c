"""Shared helpers for tests/training (SAC training, evaluation, shipped policies)."""
from __future__ import annotations

import os

import pytest

os.environ.setdefault("OMP_NUM_THREADS", "1")


@pytest.fixture(autouse=True)
def _one_torch_thread():
    import torch

    n = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(n)


_READY: dict[str, bool] = {}


def rodlab_task_ready(name: str) -> bool:
    """True when the rodlab task `name` is registered AND one batched env can be built, reset and stepped.

    (Tasks are built by another module; before they work, the end-to-end test runs on Pendulum-v1.)
    """
    if name not in _READY:
        try:
            import numpy as np

            import policies

            venv = policies.make_vec_env(name, 2, seed=0)
            venv.reset(seed=0)
            venv.step(np.zeros((2, *venv.single_action_space.shape), np.float32))
            venv.close()
            _READY[name] = True
        except Exception as exc:  # noqa: BLE001 - any failure means "not ready"
            import warnings

            warnings.warn(f"rodlab task {name!r} not usable yet ({type(exc).__name__}: {exc}); using Pendulum-v1")
            _READY[name] = False
    return _READY[name]
