"""Settings that may make the SAC updates faster on a CPU, for ``rodlab bench train`` to try one at a time.

Training chooses its own from ``Args.precision`` (policies/learning/precision.py); here each setting is timed alone, and must
be measured on a quiet machine (iteration time) and checked to keep the learning curve (docs/training.md) before a
run uses it. A sweep compares the precisions on the same seeds:
``rodlab sweep follow_target --seeds 0,1,2 --set precision=float32,bfloat16``. Settings:

* ``compile``: ``RodSAC.compile_updates`` (also ``rodlab train --compile``): each SAC update (losses, their
  gradients, the Adam steps) runs as one ``torch.compile``d function; the target update stays eager. Needs a C++
  compiler for the CPU inductor back-end. It is compiled with the graph pass ``UnitProductLoops``
  (policies/learning/compile_passes.py).
* ``bf16``: ``RodSAC.bf16_updates``: each forward pass of the updates runs under
  ``torch.autocast("cpu", dtype=torch.bfloat16)``, with the hidden 256x256 products in bfloat16 and the input
  and output layers, LayerNorms and losses in float32 (policies/learning/sac.py).
* torch threads: ``torch.set_num_threads`` (``rodlab bench train --threads``).
"""
from __future__ import annotations

from dataclasses import dataclass

__all__ = ["SpeedSettings", "apply_speed_settings"]


@dataclass(frozen=True)
class SpeedSettings:
    compile: bool = False
    bf16: bool = False
    bf16_layout: str = "float32_io"

    def __post_init__(self):
        from policies.learning.sac import BF16_LAYOUTS

        if self.bf16_layout not in BF16_LAYOUTS:
            raise ValueError(f"bf16_layout must be one of {BF16_LAYOUTS}, got {self.bf16_layout!r}")

    def label(self) -> str:
        """The settings as the benchmark's JSON names them ("float32" when none is on)."""
        return ",".join((["compile"] if self.compile else []) + ([f"bf16={self.bf16_layout}"] if self.bf16 else [])) \
            or "float32"


def apply_speed_settings(model, settings: SpeedSettings) -> None:
    """Apply ``settings`` to a fresh ``RodSAC`` in place; ``TrainError`` for ``compile`` without a C++ compiler."""
    if settings.compile:
        from policies.learning.training import check_compiler

        check_compiler()
    model.set_update_settings(bf16=settings.bf16, bf16_layout=settings.bf16_layout, compile_updates=settings.compile)
