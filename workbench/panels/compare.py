"""GUI: Compare (Recordings tab): a second recorded episode drawn as a translucent ghost over the open recording
or over the live session (a running policy), stepping on the same timeline (``workbench.session.compare``); or a second
policy on the running task's scene: its episode is computed headless with the live session's seed and the live
episode restarts, so both start from the same target and obstacles."""
from __future__ import annotations

import threading

from workbench.panels.host import PanelHost
from workbench.panels.policy import NO_POLICY
from workbench.session import (
    PRETRAINED,
    FileAccessError,
    Ghost,
    GhostView,
    page_error,
    policy_episode,
    read_episodes,
    shipped_policies,
)


class ComparePanel:
    def __init__(self, app: PanelHost):
        self.app = app
        gui = app.server.gui
        files = app.replay._files()
        with app.tabs["Recordings"], gui.add_folder("Compare (ghost)"):
            self.file = gui.add_dropdown("Ghost recording", files, initial_value=files[0],
                                         hint="a second recording, drawn translucent over the shown episode or the "
                                              "live session at the same simulated time")
            self.episode = gui.add_dropdown("Ghost episode", ["0"], initial_value="0",
                                            hint="episode of the ghost recording")
            self.show_btn = gui.add_button("Show ghost", hint="overlay the chosen episode (blue, translucent)")
            pols = self._policies()
            self.policy = gui.add_dropdown("Ghost policy", pols, initial_value=pols[0],
                                           hint="a second policy for the running task (Policy tab)")
            self.policy_btn = gui.add_button("Ghost of a policy", hint="run the chosen policy on the running task's "
                                                                       "first episode and overlay it; the live "
                                                                       "episode restarts on the same scene")
            self.hide_btn = gui.add_button("Remove ghost", hint="remove the overlay")
            self.msg = gui.add_markdown("")
        self._episodes: list = []
        self._path = None
        self.view: GhostView | None = None
        # the ghost's buttons come on different callback threads: one ghost drawn or removed at a time
        self._lock = threading.RLock()
        for h in (self.file, self.episode, self.policy):
            app.checks.track(h)
        self._wire()

    def _say(self, text: str) -> None:
        self.msg.content = text

    def refresh_list(self) -> None:
        files = self.app.replay._files()
        self.file.options = files
        if self.file.value not in files:
            self.file.value = files[0]
        self.app.checks.accept(self.file)

    def _wire(self) -> None:
        ok = self.app.checks

        @self.file.on_update
        def _(_e) -> None:
            if ok.option(self.file, self._say):
                self._episodes, self._path = [], None

        @self.show_btn.on_click
        def _(_e) -> None:
            if ok.option(self.file, self._say) and ok.option(self.episode, self._say):
                self.show_listed()

        @self.policy_btn.on_click
        def _(_e) -> None:
            if ok.option(self.policy, self._say):
                self.show_policy(self.policy.value)

        @self.hide_btn.on_click
        def _(_e) -> None:
            self.hide()

    def show_listed(self) -> Ghost | None:
        """Overlay the chosen episode of the chosen recording (a listed name inside the recordings folder)."""
        path = None
        try:
            path = self.app.files.recording(self.file.value)
            if path != self._path:
                self._episodes, self._path = read_episodes(path), path
                self.episode.options = [str(i) for i in range(len(self._episodes))] or ["0"]
                if self.episode.value not in self.episode.options:
                    self.episode.value = "0"
                self.app.checks.accept(self.episode)
            if not self._episodes:
                raise ValueError(f"{path.name}: no episodes in this recording")
            return self.show(self._episodes[int(self.episode.value)], label=f"{path.name} ep {self.episode.value}")
        except (FileAccessError, OSError, ValueError, IndexError) as exc:
            self._say(f"⚠ {page_error(exc, path)}")
            return None

    @staticmethod
    def _policies() -> list[str]:
        try:
            files = [p.name for p in shipped_policies()]
        except Exception:  # noqa: BLE001 - policies not importable: zero/random only
            files = []
        return files + list(NO_POLICY)

    def show_policy(self, name: str) -> Ghost | None:
        """Overlay policy ``name`` (a listed file of policies/pretrained, or zero/random) on the running task: its
        first episode with the live session's seed; the live session restarts that episode with its own policy."""
        live = self.app.wb.policy
        if live is None:
            self._say("run a policy first (Policy tab): the ghost runs on its task")
            return None
        if name not in self._policies():
            self._say("choose a policy from the list")
            return None
        path = name if name in NO_POLICY else str(PRETRAINED / name)
        self._say(f"running {name} on {live.task} …")
        try:
            ep = policy_episode(live.task, path, seed=live.seed)
        except Exception as exc:  # noqa: BLE001 - a policy that does not fit the task
            self._say(f"⚠ {page_error(exc)}")
            return None
        self.app.policy.start_task(live.task, live.source)  # the live episode again from its start
        return self.show(ep, label=f"{name} on {live.task}")

    def show(self, ep, *, label: str = "") -> Ghost:
        """Overlay ``ep`` (an ``EpisodeData``; trusted callers and :meth:`show_listed`)."""
        ghost = Ghost(ep, label=label)
        with self._lock:
            self.hide()
            self.view = GhostView(self.app.server, ghost)
            self.app.render_hooks.append(self._draw)
            fr = self.app.view.last_frame
            self.view.draw(fr.time if fr is not None else 0.0)
        self._say(f"ghost: `{label}` · {len(ghost.t)} frames · blue, translucent")
        self.app.request_render()
        return ghost

    def _draw(self, fr) -> None:
        with self._lock:  # not removed while drawn
            if self.view is not None:
                self.view.draw(fr.time)

    def hide(self) -> None:
        with self._lock:
            if self._draw in self.app.render_hooks:
                self.app.render_hooks.remove(self._draw)
            if self.view is not None:
                self.view.remove()
                self.view = None
                self._say("")
