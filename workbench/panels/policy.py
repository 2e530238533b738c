"""GUI: policies (pick task + policy, play, take over / hand back), rewind, recording."""
from __future__ import annotations

import time
from pathlib import Path

from workbench.panels.guard import resend_value
from workbench.panels.host import PanelHost
from workbench.session import PRETRAINED, PolicySession, page_error, shipped_policies, task_names

NO_POLICY = ("zero", "random")
RESEND_AFTER_S = 0.5  # [s] after the page last moved the Rewind slider, its chosen frame is sent to the pages again
REWIND_HELP = ("Rewind goes back to the chosen frame and pauses there; the frames after it are dropped. While the "
               "session plays the slider follows the newest frame until you move it.")


class PolicyPanel:
    def __init__(self, app: PanelHost):
        self.app = app
        gui = app.server.gui
        try:

            tasks = task_names()
        except Exception as exc:  # noqa: BLE001 - policies not importable: the panel says why
            tasks, self._why = [], str(exc)
        with app.tabs["Policy"]:
            self.task = gui.add_dropdown("Task", tasks or ["(unavailable)"],
                                         initial_value=(tasks or ["(unavailable)"])[0],
                                         hint="task (docs/tasks.md): its scene, targets, reward and episode length")
            self.policy = gui.add_dropdown("Policy file", self._policies(), initial_value=self._policies()[0],
                                           hint="a shipped policy of this task (policies/pretrained), or zero/random "
                                                "actions")
            self.load_btn = gui.add_button("Run policy", hint="start the chosen task with the chosen policy")
            self.take_btn = gui.add_button("Take over", hint="drive the task by hand with the Teleop sliders; "
                                                             "press again to hand back to the policy")
            self.stop_btn = gui.add_button("Stop policy", hint="back to teleop on the scene opened before")
            self.reward = gui.add_markdown("")
        with app.tabs["Run"], gui.add_folder("Rewind"):
            self.rewind = gui.add_slider("Rewind to frame", min=0, max=1, step=1, initial_value=0,
                                         hint="an earlier frame of this session (the frames after it are dropped); "
                                              "it follows the newest frame while playing, until you move it")
            self.rewind_btn = gui.add_button("Rewind", hint="go back to that frame and pause (also while playing)")
            self.rewind_help = gui.add_markdown(REWIND_HELP)
            self.rewind_note = gui.add_markdown("")
        with app.tabs["Run"], gui.add_folder("Record"):
            self.rec_btn = gui.add_button("Start recording", hint="write the following frames to an .rrd file in "
                                                                  "the recordings folder")
            self.rec_msg = gui.add_markdown("")
        self._rewind_chosen = False  # the page moved the rewind slider: it stops following the newest frame
        self._rewind_set = 0  # the value the server gave it last
        self._rewind_touched = 0.0  # when the page last moved it (monotonic s)
        for h in (self.task, self.policy, self.rewind):
            app.checks.track(h)
        self._wire()

    def _policies(self) -> list[str]:
        try:

            task = self.task.value if hasattr(self, "task") else None
            files = [p.name for p in shipped_policies(task if task and not task.startswith("(") else None)]
        except Exception:  # noqa: BLE001
            files = []
        return files + list(NO_POLICY)

    def start_listed(self) -> None:
        """Start the task and policy chosen in the page: both must be listed options; the policy is a file
        name in policies/pretrained (never a path from the page) or zero/random."""
        task, policy = self.task.value, self.policy.value
        if task not in tuple(self.task.options) or policy not in self._policies():
            raise ValueError("choose a task and a policy from the lists")

        self.start_task(task, policy if policy in NO_POLICY else str(PRETRAINED / Path(policy).name))

    def start_task(self, task: str, policy: str | None = None) -> None:
        """Start ``task`` with ``policy`` (file name in policies/pretrained, a path, or zero/random).
        Trusted callers only (``--task``, tests): the page goes through :meth:`start_listed`."""
        if policy is None:
            files = shipped_policies(task)
            policy = str(files[0]) if files else "zero"
        elif policy not in NO_POLICY and not Path(policy).is_file():
            policy = str(PRETRAINED / policy)
        session = PolicySession(task, policy)
        self.app.wb.start_policy(session)
        self.show_choice(session.task, policy if policy in NO_POLICY else Path(policy).name)
        self.take_btn.label = "Take over"
        self.app.controls.sync_sliders()
        self.app.request_render()

    def show_choice(self, task: str, policy: str) -> None:
        """The Task and Policy file dropdowns show the running task and policy (a policy file outside the
        shipped list is shown as its name but cannot be started from the page)."""
        ok = self.app.checks
        if task in tuple(self.task.options) and self.task.value != task:
            self.task.value = task  # its callback lists that task's policies
        opts = self._policies()
        if policy not in opts:
            opts = [*opts, policy]
        self.policy.options = opts
        self.policy.value = policy
        ok.accept(self.task)
        ok.accept(self.policy)

    def _say(self, text: str) -> None:
        self.reward.content = text

    def _wire(self) -> None:
        app, wb, ok = self.app, self.app.wb, self.app.checks

        @self.task.on_update
        def _(_e) -> None:
            if not ok.option(self.task, self._say):
                return
            opts = self._policies()
            self.policy.options = opts
            self.policy.value = opts[0]
            ok.accept(self.policy)

        @self.policy.on_update
        def _(_e) -> None:
            ok.option(self.policy, self._say)

        @self.load_btn.on_click
        def _(_e) -> None:
            if not (ok.option(self.task, self._say) and ok.option(self.policy, self._say)):
                return
            self.reward.content = f"loading {self.policy.value} on {self.task.value} …"
            try:
                self.start_listed()
            except Exception as exc:  # noqa: BLE001 - show it in the page
                self.reward.content = f"⚠ {page_error(exc)}"
                return
            self.reward.content = f"running **{self.policy.value}** on **{self.task.value}**"

        @self.take_btn.on_click
        def _(_e) -> None:
            if wb.policy is None:
                return
            if not wb.hand_control:
                wb.take_over()
                self.take_btn.label = "Hand back"
            else:
                wb.hand_back()
                self.take_btn.label = "Take over"
            app.controls.sync_sliders()

        @self.stop_btn.on_click
        def _(_e) -> None:
            wb.stop_policy()
            self.take_btn.label = "Take over"
            self.reward.content = ""
            app.controls.sync_sliders()
            app.request_render()

        @self.rewind.on_update
        def _(e) -> None:
            if e.client is None:  # set by the server (following the newest frame)
                return
            if ok.number(self.rewind, self._say):
                self._rewind_chosen = True
                self._rewind_touched = time.monotonic()

        @self.rewind_btn.on_click
        def _(_e) -> None:
            if not ok.number(self.rewind, self._say):
                return
            try:
                wb.rewind(int(self.rewind.value))
            except KeyError as exc:
                self.reward.content = f"⚠ {exc}"
                return
            self._rewind_chosen = False
            self._rewind_set = int(self.rewind.value)
            app.controls.sync_sliders()
            app.request_render()

        @self.rec_btn.on_click
        def _(_e) -> None:
            if wb.recorder is None:
                from workbench.session import SessionRecorder

                try:
                    path = wb.start_recording(SessionRecorder.default_path(app.recordings_dir))
                except Exception as exc:  # noqa: BLE001
                    self.rec_msg.content = f"⚠ {exc}"
                    return
                self.rec_btn.label = "Stop recording"
                self.rec_msg.content = f"recording to `{path.name}` …"
            else:
                self.rec_btn.label = "Start recording"
                self.rec_msg.content = "writing …"
                try:
                    out = wb.stop_recording()
                except Exception as exc:  # noqa: BLE001
                    self.rec_msg.content = f"⚠ {exc}"
                    return
                self.rec_msg.content = f"saved `{out}`" if out else "nothing recorded"
                app.replay.refresh_list()

    def choose_rewind_frame(self, frame: int) -> None:
        """Put the Rewind slider on ``frame`` as if the page had chosen it (it stops following the newest frame)."""
        h = self.app.wb.history
        frame = min(max(int(frame), h.first_index), max(h.last_index, h.first_index + 1))
        self._rewind_chosen = True
        self._rewind_touched = time.monotonic()
        self.rewind.value = frame
        self._rewind_set = frame
        self.app.checks.accept(self.rewind)

    def update_status(self) -> None:
        """Rewind range + reward line (called a few times per second)."""
        wb = self.app.wb
        h = wb.history
        lo, hi = h.first_index, max(h.last_index, h.first_index + 1)
        note = (f"history trimmed: the oldest {h.dropped} frames were dropped (rewind keeps the last {h.limit})"
                if h.dropped else "")
        if self.rewind_note.content != note:
            self.rewind_note.content = note
        if (self.rewind.min, self.rewind.max) != (lo, hi):
            # while playing the slider follows the newest frame, unless the page chose a frame (still in the history)
            v = int(self.rewind.value)
            chosen = (self._rewind_chosen or v != self._rewind_set) and lo <= v <= hi
            self._rewind_chosen = chosen
            self.rewind.min, self.rewind.max = lo, hi
            if wb.playing and not chosen:
                self.rewind.value = hi
            elif chosen and time.monotonic() - self._rewind_touched > RESEND_AFTER_S:
                resend_value(self.rewind)  # a newest-frame value sent just before the page's choice may show there
            self._rewind_set = int(self.rewind.value)
            self.app.checks.accept(self.rewind)
        if wb.policy is not None and wb.mode == "policy":
            sc = wb.policy.scalars
            terms = " · ".join(f"{k[2:]} {v:+.3f}" for k, v in sc.items() if k.startswith("r_"))
            self.reward.content = (f"**{wb.policy.task}** · {wb.policy.name}{' · HAND' if wb.hand_control else ''}  \n"
                                   f"step {int(sc.get('episode_step', 0))} · reward {sc.get('reward', 0.0):+.3f}"
                                   f" · return {sc.get('return', 0.0):+.2f}  \n{terms}")
        if wb.recorder is not None:
            self.rec_msg.content = f"recording `{wb.recorder.path.name}` · {wb.recorder.frames} frames"
