"""Named training settings: ``rodlab train --preset NAME`` and ``rodlab sweep --preset NAME`` (docs/training.md,
"Presets"). A preset names the settings it changes from ``Args``' defaults; options given on the command line
override it. The measured figures behind each preset are in BENCHMARKS.md §6.

* ``paper``: the paper's SAC settings (docs/tasks.md §8.1, table A.1): 500 envs, 4 updates of batch 1024 per
  batched env step, learning rate 1e-3. The shipped policies were trained with these.
* ``fast``: the setting that reached the paper's plateau soonest in wall-clock on the 2-core test CPU: the same
  SAC on 100 envs instead of 500. Learning there is bound by gradient updates, not by data (the plateau came after
  about the same number of updates with 100, 250 or 500 envs), so the env steps between updates are cut: an
  iteration is 4 updates after a 100-env step (4 ms) instead of a 500-env step (14 ms). Tried and slower: batches
  of 512, target updates every 2 updates, 3-step returns, CrossQ (BENCHMARKS.md §6). Measured on Follow Target:
  on 4D IK (one seed each) the paper's 500 envs reached the plateau sooner (4.9 against 5.8 min), so there ``paper``
  is the faster preset; on 2D Tight Obstacles ``fast`` reached it in 9.2 min (one seed, about as many updates as the
  paper's settings needed).

``DEFAULT_PRESET`` is the one a run takes when none is named.
"""
from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["Preset", "PRESETS", "DEFAULT_PRESET", "preset_settings"]


@dataclass(frozen=True)
class Preset:
    name: str
    summary: str
    settings: dict = field(default_factory=dict)   # Args fields -> values (the rest: Args' defaults)


PRESETS = {p.name: p for p in (
    Preset("paper", "the paper's SAC settings (table A.1): 500 envs, 4 updates of batch 1024 per env step"),
    Preset("fast", "SAC on 100 envs (else as paper): Follow Target's plateau soonest in wall-clock on 2 cores",
           {"num_envs": 100}),
)}

DEFAULT_PRESET = "paper"


def preset_settings(name: str) -> dict:
    """The ``Args`` fields preset ``name`` sets (including ``preset`` itself); ``ValueError`` naming the known
    presets for another name."""
    if name not in PRESETS:
        raise ValueError(f"unknown preset {name!r}; known: {', '.join(PRESETS)}")
    return {"preset": name, **PRESETS[name].settings}
