"""CrossQ (sb3-contrib) as a second training algorithm of ``rodlab train --algorithm crossq`` (docs/training.md).

CrossQ drops the target networks of SAC and puts batch renormalisation into actor and critics; the critic sees the
current and next transitions in one forward pass, so that its normalisation statistics cover both. The actor (and
the entropy coefficient) is updated every ``policy_delay`` critic updates. Everything a run directory holds stays as
for SAC: the same monitor, checkpoints (``RodCrossQ.load``), policy files (``save_policy`` writes
``"algorithm": "crossq"`` and the batch-renormalisation settings into ``meta.json``; ``load_policy`` builds the
network from them and loads weights only, never unpickling) and evaluation.

What differs from sb3-contrib's class (``RodCrossQ``): the duration of the latest ``train()`` call is kept in
``last_update_time`` for the training log; nothing else. The updates run eagerly in float32.
"""
from __future__ import annotations

import time

from sb3_contrib import CrossQ
from sb3_contrib.crossq.policies import CrossQPolicy

__all__ = ["RodCrossQ", "CrossQPolicy", "crossq_policy"]


class RodCrossQ(CrossQ):
    """sb3-contrib's ``CrossQ`` with the update time kept for the training log."""

    last_update_time = 0.0
    compile_updates = False

    def set_update_settings(self, *, bf16: bool, bf16_layout: str, compile_updates: bool) -> None:
        """As ``RodSAC.set_update_settings``; CrossQ's updates are eager float32 only."""
        if bf16 or compile_updates:
            raise ValueError("CrossQ runs its updates eagerly in float32")

    def train(self, gradient_steps: int, batch_size: int = 64) -> None:
        t0 = time.perf_counter()
        super().train(gradient_steps, batch_size)
        self.last_update_time = time.perf_counter() - t0


def crossq_policy(observation_space, action_space, meta: dict) -> CrossQPolicy:
    """A fresh ``CrossQPolicy`` with the layout a policy file's ``meta`` names (``save_policy`` writes the critics'
    layers and the batch-renormalisation settings; its weights are loaded after)."""
    return CrossQPolicy(observation_space, action_space, lambda _: 1e-3,
                        net_arch={"pi": [int(n) for n in meta["net_arch"]],
                                  "qf": [int(n) for n in meta["critic_net_arch"]]},
                        n_critics=int(meta["n_critics"]), batch_norm=bool(meta["batch_norm"]),
                        batch_norm_momentum=float(meta["batch_norm_momentum"]),
                        batch_norm_eps=float(meta["batch_norm_eps"]),
                        renorm_warmup_steps=int(meta["renorm_warmup_steps"]))
