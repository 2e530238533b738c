"""GUI: the Fit tab — calibrate the live scene to measured motion (``rodlab fit`` in the page, ``workbench.session.fitting``).

Choose a measurement file (and optionally commanded curvature) from the data folder, tick the parameters, run the fit
with its loss curve and progress; the result shows each value ± its standard error, draws the fitted rod with the
measured points and a residual line from each to the rod (scrub the time), and applies as a new scene of the scenes
folder (never over a file)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
from viser import uplot

from sim.analysis import FitError
from sim.scene import SceneError
from workbench.panels.host import PanelHost
from workbench.session import (
    DEFAULT_PARAMS,
    FIT_CHOICES,
    FileAccessError,
    FitJob,
    overlay_at,
    page_error,
    spec_with,
    write_scene,
)

NONE = "(no data files)"
REST = "(rest controls)"
FIT_COLOR = (240, 120, 40)       # the fitted rod
MEASURED_COLOR = (40, 200, 90)   # measured points
RESIDUAL_COLOR = (230, 40, 40)   # measured point -> fitted rod


class FitPanel:
    def __init__(self, app: PanelHost):
        self.app = app
        gui = app.server.gui
        files = self._files()
        with app.tabs["Fit"]:
            self.data = gui.add_dropdown("Measured motion", files, initial_value=files[0],
                                         hint=f"CSV t,s,x,y,z[,rod] or .npz (t, s, pos) in the data folder "
                                              f"({app.files.data}; --data-dir)")
            self.controls = gui.add_dropdown("Commanded curvature", [REST] + self._files(controls=True),
                                             initial_value=REST,
                                             hint="CSV t,node,kappa1,kappa2,twist of the data folder, or the scene's "
                                                  "rest controls")
            self.refresh_btn = gui.add_button("Refresh lists", hint="list the data folder again")
            self.ticks = {}
            with gui.add_folder("Parameters"):
                for name in FIT_CHOICES:
                    self.ticks[name] = gui.add_checkbox(name, initial_value=name in DEFAULT_PARAMS)
            self.evals = gui.add_number("Max evaluations", initial_value=30, min=1, max=1000, step=1,
                                        hint="most residual evaluations (each one simulation of the whole motion)")
            self.run_btn = gui.add_button("Run fit", hint="fit the live scene's parameters to the measured motion")
            self.stop_btn = gui.add_button("Stop fit", hint="end after the current evaluation, keeping the best so far")
            self.msg = gui.add_markdown("")      # what the last action did, or why it was refused
            self.status = gui.add_markdown("")   # the running fit's progress
            self.loss_folder = gui.add_folder("Loss")  # the loss curve, made when a fit starts
            self.result = gui.add_markdown("")
            self.show = gui.add_checkbox("Show fitted motion", initial_value=True,
                                         hint="draw the fitted rod (orange), the measured points (green) and each "
                                              "point's residual (red)")
            self.time = gui.add_slider("Fit time [s]", min=0.0, max=1.0, step=0.01, initial_value=0.0,
                                       hint="the time of the fitted motion drawn")
            self.apply_btn = gui.add_button("Apply as new scene", hint="write the fitted scene as a new file of the "
                                                                        "scenes folder and open it")
        for h in (self.data, self.controls, self.evals, self.time):
            app.checks.track(h)
        self.loss = None
        self.job: FitJob | None = None
        self._drawn = None        # the job whose result the loss curve and table show
        self._nodes = None
        self._wire()

    # ------------------------------------------------------------------ lists
    def _files(self, controls: bool = False) -> list[str]:
        files = self.app.files.data_files()
        if controls:
            return [f for f in files if f.lower().endswith(".csv")]
        return files or [NONE]

    def refresh_list(self) -> None:
        files = self._files()
        self.data.options = files
        if self.data.value not in files:
            self.data.value = files[0]
        ctl = [REST] + self._files(controls=True)
        self.controls.options = ctl
        if self.controls.value not in ctl:
            self.controls.value = REST
        self.app.checks.accept(self.data)
        self.app.checks.accept(self.controls)

    def _say(self, text: str) -> None:
        self.msg.content = text

    # ------------------------------------------------------------------ actions
    def _wire(self) -> None:
        ok = self.app.checks

        @self.refresh_btn.on_click
        def _(_e) -> None:
            self.refresh_list()

        @self.run_btn.on_click
        def _(_e) -> None:
            if ok.option(self.data, self._say) and ok.option(self.controls, self._say) and \
                    ok.number(self.evals, self._say):
                self.start(self.data.value, [k for k, h in self.ticks.items() if h.value is True],
                           controls=None if self.controls.value == REST else self.controls.value,
                           max_evaluations=int(self.evals.value))

        @self.stop_btn.on_click
        def _(_e) -> None:
            if self.job is not None:
                self.job.stop()

        @self.time.on_update
        def _(_e) -> None:
            if ok.number(self.time, self._say):
                self.draw()

        @self.show.on_update
        def _(_e) -> None:
            self.draw()

        @self.apply_btn.on_click
        def _(_e) -> None:
            self.apply()

    def start(self, data: str, params: list[str], *, controls: str | None = None,
              max_evaluations: int = 30) -> FitJob | None:
        """Start a fit of the live scene to the listed file ``data`` (and ``controls``) over ``params``."""
        if self.job is not None and self.job.running:
            self._say("⚠ a fit is running: stop it first")
            return None
        if self.app.wb.policy is not None:
            self._say("⚠ stop the policy first (Policy tab): the fit calibrates the teleop scene")
            return None
        path = None
        try:
            path = self.app.files.data_file(data)
            ctl = self.app.files.data_file(controls) if controls is not None else None
            with self.app.wb.lock:
                spec = spec_with(self.app.wb.live.base_spec, self.app.wb.obstacles)
            job = FitJob(spec, path, params, controls=ctl, max_evaluations=max_evaluations,
                         notify=self.app.request_render)
        except (FileAccessError, FitError, SceneError, OSError, ValueError) as exc:
            self._say(f"⚠ {page_error(exc, path)}")
            return None
        self.close()
        with self.loss_folder:
            self.loss = self.app.server.gui.add_uplot(
                data=(np.zeros(1), np.zeros(1)),
                series=(uplot.Series(label="evaluation"), uplot.Series(label="rms [mm]", stroke="#f07828", width=2)),
                title="fit: RMS residual [mm] per evaluation", aspect=2.2)
        self.job = job.start()
        self._drawn = None
        self.result.content = ""
        self._say("")
        self.status.content = job.progress()
        return job

    def apply(self):
        """Write the fitted scene as a new file of the scenes folder and open it; returns its path (None if none)."""
        job = self.job
        if job is None or job.result is None:
            self._say("⚠ no fitted scene yet: run a fit first")
            return None
        try:
            current = self.app.wb.scene_path
            stem = (Path(current).stem if current is not None else "scene") + "_fitted"
            path = self.app.files.scene_for_save(self.app.files.new_scene_name(stem[:80]), None)
            write_scene(job.result.spec, path)
            self.app.wb.load_scene(path)
        except (FileAccessError, OSError, SceneError, ValueError) as exc:
            self._say(f"⚠ {page_error(exc)}")
            return None
        self.app.refresh_rod_scene()
        self._say(f"applied: opened the fitted scene `{path.name}` (scenes folder)")
        return path

    # ------------------------------------------------------------------ drawing
    def update_status(self) -> None:
        """Progress, loss curve and, once finished, the result (called with the readouts)."""
        job = self.job
        if job is None:
            return
        self.status.content = job.progress()
        hist = list(job.history)
        if len(hist) >= 1 and self.loss is not None:
            k = np.array([h[0] for h in hist], dtype=np.float64)
            r = np.array([h[1] for h in hist], dtype=np.float64) * 1e3
            self.loss.data = (k, r)
        if job.result is not None and self._drawn is not job:
            self._drawn = job
            tr = job.result.track
            if tr is not None and tr.t.size > 1:
                self.time.max = float(tr.t[-1])
                self.time.step = float(tr.t[1] - tr.t[0])
                self.time.value = 0.0
                self.app.checks.accept(self.time)
            self.draw()
            self.result.content = job.table()  # last: a result shown is a result drawn

    def draw(self) -> None:
        """The fitted rod, the measured points and their residuals at the Fit time (removed when not shown)."""
        job = self.job
        tr = job.result.track if job is not None and job.result is not None else None
        if tr is None or not self.show.value:
            self._remove()
            return
        nodes, meas, pred, _ = overlay_at(tr, float(self.time.value))
        sc = self.app.server.scene
        segs = np.stack([nodes[:-1], nodes[1:]], axis=1)[job.material_edges]  # not across the joints of rods
        self._nodes = [
            sc.add_line_segments("/fit/rod", segs, FIT_COLOR, thickness=5.0),
            sc.add_point_cloud("/fit/measured", meas if len(meas) else np.zeros((1, 3)), MEASURED_COLOR,
                               point_size=0.02, point_shape="circle", visible=bool(len(meas))),
            sc.add_line_segments("/fit/residual", np.stack([meas, pred], axis=1) if len(meas) else np.zeros((1, 2, 3)),
                                 RESIDUAL_COLOR, thickness=3.0, visible=bool(len(meas))),
        ]

    def _remove(self) -> None:
        for h in self._nodes or ():
            h.remove()
        self._nodes = None

    def close(self) -> None:
        """End a running fit (the session is closing or a new fit starts) and remove its drawing."""
        job = self.job
        if job is not None and job.running:
            job.stop()
            job.join()
        self._remove()
        if self.loss is not None:
            self.loss.remove()
            self.loss = None
