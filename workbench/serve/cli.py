"""``rodlab workbench [SCENE.toml | --task T] [--host 127.0.0.1] [--port 8080] [--scenes-dir scenes]
[--recordings-dir recordings] [--data-dir data] [--max-upload-mb 50]``.

The first line with ``http://`` printed at start-up is the page's full address (with ``?token=...`` when
bound to a non-loopback address; a warning follows on stderr)."""
from __future__ import annotations

import argparse
import signal
import sys
import time
from pathlib import Path

from sim.support.assets import asset_path
from workbench.serve.handshake import BindError
from workbench.session import FileAccessError

DEFAULT_SCENES = (asset_path("scenes/default.toml"), asset_path("scenes/arm.toml"))


def default_scene() -> Path | None:
    """assets/scenes/default.toml, else arm.toml, else None (built-in rod)."""
    for p in DEFAULT_SCENES:
        if p.is_file():
            return p
    return None


def task_scene(session) -> str:
    """What a ``--task`` session shows at start-up: the task and its scene file (``config.scene``; the shipped arm
    when it names none)."""
    from policies.tasks.scenes import ARM_SCENE

    scene = getattr(session.core.config, "scene", None) or ARM_SCENE
    return f"task {session.task}, scene {Path(str(scene)).name}"


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="rodlab workbench", description="interactive web workbench (viser)")
    ap.add_argument("scene", nargs="?", help="scene TOML (default: assets/scenes/default.toml or arm.toml)")
    ap.add_argument("--task", help="start with this task's scene and its first shipped policy")
    ap.add_argument("--host", default="127.0.0.1",
                    help="bind address (default 127.0.0.1: this machine only). Any other address needs the "
                         "per-launch token printed in the URL; prefer an SSH tunnel (see README, Security)")
    ap.add_argument("--port", type=int, default=8080, help="port (busy -> next free one)")
    ap.add_argument("--speed", type=float, default=1.0, help="real-time factor (default 1)")
    ap.add_argument("--scenes-dir", default=None,
                    help="folder where the page saves and loads scenes (default: scenes/ in the working directory)")
    ap.add_argument("--recordings-dir", default=None,
                    help="folder of the recordings the page replays and writes (default: recordings/ in the working "
                         "directory)")
    ap.add_argument("--data-dir", default=None,
                    help="folder of the measured motion and controls files the Fit tab reads (default: data/ in the "
                         "working directory)")
    ap.add_argument("--max-upload-mb", type=float, default=50.0, help="largest mesh upload accepted [MB] (default 50)")
    ap.add_argument("--no-env-map", action="store_true", help="no HDRI lighting (faster in software GL)")
    ap.add_argument("--no-shadows", action="store_true",
                    help="no shadows on the floor at start (much faster in software GL; the Display tab toggles them)")
    ap.add_argument("--seconds", type=float, default=None, help="quit after this many seconds (tests)")
    return ap


def workbench_main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(sys.argv[1:] if argv is None else argv)
    from workbench.serve.app import WorkbenchApp
    from workbench.session import Workbench

    if args.scene and args.task:
        print("rodlab workbench: give a scene file or --task, not both", file=sys.stderr)
        return 2
    scene = Path(args.scene) if args.scene else default_scene()
    if scene is not None and not scene.is_file():
        print(f"rodlab workbench: scene file not found: {scene}", file=sys.stderr)
        return 2
    try:
        wb = Workbench.from_path(scene) if scene is not None else Workbench.builtin()
    except Exception as exc:  # noqa: BLE001 - SceneError etc.: one clear line
        print(f"rodlab workbench: cannot load {scene}: {exc}", file=sys.stderr)
        return 2

    try:
        app = WorkbenchApp(wb, host=args.host, port=args.port, env_map=not args.no_env_map,
                           shadows=not args.no_shadows, speed=args.speed,
                           scenes_dir=args.scenes_dir, recordings_dir=args.recordings_dir,
                           max_upload_mb=args.max_upload_mb, data_dir=args.data_dir)
    except (BindError, FileAccessError) as exc:
        print(f"rodlab workbench: {exc}", file=sys.stderr)
        return 2
    if args.task:
        try:
            app.policy.start_task(args.task)
        except Exception as exc:  # noqa: BLE001
            print(f"rodlab workbench: cannot start task {args.task!r}: {exc}", file=sys.stderr)
            app.stop()
            return 2
    app.start()
    shown = task_scene(app.wb.policy) if args.task else (scene or "built-in rod")
    print(f"rodlab workbench: open {app.url}  ({shown}; Ctrl-C to quit)", flush=True)
    if not app.guard.loopback:
        print(f"rodlab workbench: WARNING: serving on {args.host}, reachable from other machines; anyone with the "
              "token in the address above can drive this session (prefer --host 127.0.0.1 and an SSH tunnel)",
              file=sys.stderr, flush=True)
    t_end = None if args.seconds is None else time.monotonic() + args.seconds
    with QuitOnSignal() as asked:
        try:
            while not asked and (t_end is None or time.monotonic() < t_end):
                time.sleep(0.2)
        except KeyboardInterrupt:  # a second Ctrl-C while stopping
            pass
        finally:
            app.stop()
    return 0


class QuitOnSignal:
    """Ctrl-C (SIGINT) and SIGTERM set a flag the main loop polls, instead of raising KeyboardInterrupt wherever the
    main thread happens to be: while the stepping thread compiles the kernels (a first start), the main thread spends
    much of its time collecting the compiler's garbage, and an exception raised inside a finaliser there is
    swallowed, so the Ctrl-C was lost and the workbench ran on. A second signal raises as usual."""

    def __init__(self):
        self.signum: int | None = None
        self._old: dict = {}

    def __bool__(self) -> bool:
        return self.signum is not None

    def _handle(self, signum, _frame) -> None:
        first = self.signum is None
        self.signum = signum
        signal.signal(signal.SIGINT, signal.default_int_handler)  # the next Ctrl-C interrupts the stop itself
        if not first:
            raise KeyboardInterrupt

    def __enter__(self) -> "QuitOnSignal":
        for s in (signal.SIGINT, signal.SIGTERM):
            self._old[s] = signal.signal(s, self._handle)
        return self

    def __exit__(self, *exc) -> None:
        for s, h in self._old.items():
            signal.signal(s, h)
