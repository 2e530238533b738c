"""The small training runs of the learning tests: tiny nets, few steps, on the real follow_target task."""
from __future__ import annotations

from pathlib import Path

from policies.learning.training import Args

TASK = "follow_target"


def train_args(run_dir: Path, steps: int, **kw) -> Args:
    base = dict(task=TASK, num_envs=4, total_steps=steps, seed=1, run_dir=str(run_dir), batch_size=32,
                learning_starts=40, updates_per_iter=2, net_arch=[32, 32, 32], buffer_size=10_000, log_interval_s=0.0,
                checkpoint_minutes=60.0, precision="float32")
    base.update(kw)
    return Args(**base)
