"""rodlab learning: SAC (and CrossQ) on the batched tasks — training runs, checkpoints, evaluation, policy files,
Ray sweeps and their reports (docs/training.md).

Public surface (what the rest of rodlab and a user's script use; the modules behind it are this package's own)::

    from policies.learning import Args, train, evaluate, load_policy
    train(Args(task="follow_target", total_steps=200_000, run_dir="runs/ft"))   # `rodlab train`
    policy, meta = load_policy("runs/ft/policy.zip")                           # rodlab's pickle-free format
    evaluate("runs/ft/policy.zip", "follow_target", episodes=20)               # `rodlab eval`

Names load on first use (PEP 562): most modules here load torch and stable-baselines3; the light names
(``PRESETS``, ``PRECISIONS``) load only what they need. ``python -m policies.learning.sweep`` / ``.report`` /
``.training_report`` are the command lines of the modules of those names.
"""
from __future__ import annotations

from sim.support.lazy import lazy_face

# public name -> the module of this package that defines it (read by tests/test_import_graph.py as imports)
_LAZY = {
    # training runs (rodlab train)
    "Args": "policies.learning.training",
    "train": "policies.learning.training",
    "TrainError": "policies.learning.sb3_env",
    "ALGORITHMS": "policies.learning.training",
    "build_sac": "policies.learning.training",
    "check_compiler": "policies.learning.training",
    "check_device": "policies.learning.training",
    "make_sb3_env": "policies.learning.sb3_env",
    "task_short_name": "policies.learning.sb3_env",
    # settings: presets, precision, speed
    "PRESETS": "policies.learning.presets",
    "DEFAULT_PRESET": "policies.learning.presets",
    "preset_settings": "policies.learning.presets",
    "PRECISIONS": "policies.learning.precision",
    "configure_compile_cache": "policies.learning.precision",
    "SpeedSettings": "policies.learning.train_speed",
    "apply_speed_settings": "policies.learning.train_speed",
    "BF16_LAYOUTS": "policies.learning.sac",
    # models and policy files
    "RodSAC": "policies.learning.sac",
    "RodCrossQ": "policies.learning.crossq",
    "load_policy": "policies.learning.sac",
    "save_policy": "policies.learning.sac",
    "read_policy_meta": "policies.learning.sac",
    "PolicyLoadError": "policies.learning.sac",
    # checkpoints
    "CheckpointError": "policies.learning.checkpoint",
    "find_checkpoint": "policies.learning.checkpoint",
    "read_state": "policies.learning.checkpoint",
    # evaluation
    "evaluate": "policies.learning.evaluation",
    "check_compatible": "policies.learning.evaluation",
    # shipped policies and reports
    "PRETRAINED": "policies.learning.training_report",
    "PAPER_TABLE_II": "policies.learning.training_report",
}

__all__ = sorted(_LAZY)


__getattr__, __dir__ = lazy_face(__name__, _LAZY)
