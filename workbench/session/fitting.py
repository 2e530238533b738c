"""The Fit tab's work, without the page: one ``rodlab fit`` (``sim.analysis.calibration``) of the live scene to a measurement file,
run in its own thread, with its progress (loss per evaluation, an ETA), a stop, and its result; and the picture of
the result at a time: the fitted rod, the measured points and the residual between them (``FitTrack``).

The measurement and controls files are chosen from the data folder (``workbench.session.files.Folders.data``); the fitted
scene is written as a new file of the scenes folder, never over one.
"""
from __future__ import annotations

import math
import threading
import time
import traceback
from pathlib import Path
from typing import Any

import numpy as np

from sim.analysis import FIT_PARAMETERS, FitError, FitResult, FitTrack, fit, load_controls, load_measurements
from sim.scene import build_model

__all__ = ["FitJob", "overlay_at", "FIT_CHOICES"]

# the parameters the Fit tab offers (sim.analysis.calibration.FIT_PARAMETERS, in that order) and the ones ticked at first
FIT_CHOICES = FIT_PARAMETERS
DEFAULT_PARAMS = ("youngs_modulus", "damping")


class FitJob:
    """A fit of ``spec`` to the measurements in ``data`` (a CSV or .npz, ``sim.analysis.calibration.load_measurements``), with the
    commanded curvature of ``controls`` (a CSV; None: the scene's rest controls), over ``params``, at most
    ``max_evaluations`` residual evaluations. Reading the files happens here (a bad file raises at once, naming the
    row); the fit itself runs in a thread after :meth:`start`, calling ``notify()`` (if given) after each evaluation
    and at its end.

    ``state``: "ready", "running", "done", "stopped" (by :meth:`stop`: the best parameters so far) or "failed"
    (``error`` says why). ``history``: (evaluation, RMS residual [m]) of each evaluation; ``result``: the :class:`sim.analysis.calibration.FitResult` once finished."""

    def __init__(self, spec: Any, data: Path, params: list[str], *, controls: Path | None = None,
                 max_evaluations: int = 30, notify=None):

        if not params:
            raise FitError("tick at least one parameter to fit")
        unknown = [p for p in params if p not in FIT_CHOICES]
        if unknown:
            raise FitError(f"unknown parameter {unknown[0]!r}; known: {', '.join(FIT_CHOICES)}")
        if not 1 <= int(max_evaluations) <= 1000:
            raise FitError(f"the number of evaluations must be within [1, 1000], got {max_evaluations}")
        self.spec = spec
        self.data = Path(data)
        self.params = list(params)
        self.max_evaluations = int(max_evaluations)
        self.meas = load_measurements(self.data, spec)
        model = build_model(spec)
        self.cmds = load_controls(controls, model) if controls is not None else None
        self.material_edges = np.asarray(model.edge_link, dtype=bool)  # False: a joint between two rods
        self._notify = notify
        self.state = "ready"
        self.error = ""
        self.history: list[tuple[int, float]] = []
        self.result: FitResult | None = None
        self._stop = threading.Event()
        self._t0 = 0.0
        self._thread: threading.Thread | None = None

    def start(self) -> "FitJob":
        self.state = "running"
        self._t0 = time.perf_counter()
        self._thread = threading.Thread(target=self._run, name="rodlab-fit", daemon=True)
        self._thread.start()
        return self

    def _on_eval(self, k: int, rms: float, values: dict) -> bool:
        self.history.append((k, rms))
        self._tell()
        return self._stop.is_set()

    def _tell(self) -> None:
        if self._notify is not None:
            self._notify()

    def _run(self) -> None:
        try:
            res = fit(self.spec, self.meas, self.params, cmds=self.cmds, max_iterations=self.max_evaluations,
                        on_eval=self._on_eval)
        except (FitError, ValueError, ArithmeticError) as exc:
            self._failed(str(exc).splitlines()[0] if str(exc) else type(exc).__name__)
            return
        except Exception as exc:  # noqa: BLE001 - a defect: the panel says so (never "running" for ever), stderr has it
            traceback.print_exc()
            self._failed(f"{type(exc).__name__}: {exc}".splitlines()[0])
            return
        self.result = res
        self.state = "stopped" if res.interrupted else "done"
        self._tell()

    def _failed(self, message: str) -> None:
        self.error = message
        self.state = "failed"
        self._tell()

    def stop(self) -> None:
        """Ask the fit to end after its current evaluation (it keeps the best parameters so far)."""
        self._stop.set()

    def join(self, timeout: float | None = None) -> bool:
        """Wait for the thread; whether it has ended."""
        if self._thread is not None:
            self._thread.join(timeout)
            return not self._thread.is_alive()
        return True

    @property
    def running(self) -> bool:
        return self.state == "running"

    def progress(self) -> str:
        """One line: evaluations done of at most how many, the RMS residual, the time spent and an ETA (the time
        left if every remaining evaluation were needed: trust-region fits usually stop sooner)."""
        k = len(self.history)
        spent = time.perf_counter() - self._t0 if self._t0 else 0.0
        if self.state == "failed":
            return f"⚠ fit failed: {self.error}"
        if not k:
            return "fit: simulating the first evaluation …" if self.running else "fit: not started"
        rms = self.history[-1][1]
        best = min(r for _, r in self.history)
        head = {"running": "fitting", "done": "done", "stopped": "stopped: best so far kept", "ready": "ready"}
        line = (f"{head[self.state]} · evaluation {k} of at most {self.max_evaluations} · rms {rms * 1e3:.3g} mm "
                f"(best {best * 1e3:.3g} mm) · {spent:.1f} s")
        if self.running:
            left = (self.max_evaluations - k) * spent / k
            line += f" · at most ≈ {left:.0f} s left"
        return line

    def table(self) -> str:
        """The result in markdown: each parameter's value ± standard error, the RMS residual."""
        res = self.result
        if res is None:
            return ""
        rows = []
        for k, v in res.params.items():
            e = res.stderr.get(k, math.nan)
            rows.append(f"- {k} = {v:.6g} ± {'(not separable)' if math.isinf(e) else f'{e:.2g}'}")
        n = res.track.measured_t.size if res.track is not None else 0
        rows.append(f"\nRMS residual **{res.rms_m * 1e3:.3g} mm** over {n} measured points, {res.iterations} "
                    f"evaluations, {res.seconds:.1f} s")
        for g in res.confounded:
            rows.append(f"\nthe data cannot separate {', '.join(g)}: fix all but one")
        if res.unconverged_steps:
            rows.append(f"\n{res.unconverged_steps} steps ended unconverged (differentiated as if converged)")
        return "\n".join(rows)


def overlay_at(track: FitTrack, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """What to draw at time ``t`` [s]: the fitted rod's node positions (N, 3) at the step nearest ``t``, the measured
    points (K, 3) of the measurement time nearest ``t`` and the fitted rod's points there (K, 3), and that time."""
    k = int(np.clip(round(t / track.t[1]) if track.t.size > 1 else 0, 0, track.t.size - 1))
    times = np.unique(track.measured_t)
    tm = float(times[np.argmin(np.abs(times - t))]) if times.size else 0.0
    sel = track.measured_t == tm
    return track.node_pos[k], track.measured[sel], track.predicted[sel], tm
