"""What is computed from the simulator rather than by stepping it: static equilibrium and its Hessian, inverse
statics (the natural curvature that reaches a target), derivatives of a rollout by the implicit function theorem,
``rodlab fit`` (calibrating a scene to measured motion), open-loop trajectory optimisation and the internal loads of a rod (docs/physics.md §2.5, §3.8-3.10).
"""
from __future__ import annotations

from sim.support.lazy import lazy_face

_LAZY = {
    "Commands": "sim.analysis.calibration",
    "FIT_PARAMETERS": "sim.analysis.calibration",
    "FitError": "sim.analysis.calibration",
    "FitResult": "sim.analysis.calibration",
    "FitTrack": "sim.analysis.calibration",
    "Measurements": "sim.analysis.calibration",
    "Problem": "sim.analysis.calibration",
    "command_schedule": "sim.analysis.calibration",
    "fit": "sim.analysis.calibration",
    "fit_command": "sim.analysis.calibration",
    "load_controls": "sim.analysis.calibration",
    "load_measurements": "sim.analysis.calibration",
    "measurements_from_arrays": "sim.analysis.calibration",
    "node_arclength": "sim.analysis.calibration",
    "GradientError": "sim.analysis.gradients",
    "Tape": "sim.analysis.gradients",
    "rollout": "sim.analysis.gradients",
    "internal_loads": "sim.analysis.internal",
    "reach": "sim.analysis.inverse",
    "negative_threshold": "sim.analysis.static",
    "solve_static": "sim.analysis.static",
    "static_hessian": "sim.analysis.static",
    "static_stability": "sim.analysis.static",
    "TrajectoryResult": "sim.analysis.trajectory",
    "optimise_controls": "sim.analysis.trajectory",
    "start_points": "sim.analysis.multistart",
}

__all__ = sorted(_LAZY)

__getattr__, __dir__ = lazy_face(__name__, _LAZY)
