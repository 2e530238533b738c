"""Drive a workbench session the way a hostile client would, for a while, and sample the memory it holds.

A raw WebSocket client (``tools.hostile_client``) sends, in a loop, a value for a random GUI element of the
page: a plausible one (an option of a dropdown, a number in a slider's range, a button press: loading scenes,
opening recordings, running policies and grids, recording, exporting) or a hostile one (huge, non-finite, of the
wrong type, a file name outside the folders). Every ``sample_s`` the process's resident memory is sampled.

    python -m tools.soak --seconds 600 --json /tmp/soak.json
"""
from __future__ import annotations

import argparse
import json
import math
import os
import random
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import NamedTuple

HOSTILE = (1e308, -1e308, math.inf, -math.inf, math.nan, 2 ** 63, -1, 0, True, None, "", "x" * 5000,
           "../../etc/passwd", "/etc/shadow", "a/b.toml", "..", "C:\\\\x", [1, 2, 3], {"a": 1}, 123456789)


class Sample(NamedTuple):
    """One look at the server process during a soak."""

    t: float  # seconds since the soak started
    rss_mb: float  # resident memory [MB]
    backlog: int  # messages held for pages plus callbacks waiting to run
    threads: int  # OS threads of the process
    pool_threads: int  # of which the page callbacks' thread pool (viser's, up to its max_workers)

    @property
    def outside_pool(self) -> int:
        """Threads outside the callback pool: those of actions that run on, rerun's streams, the server's own."""
        return self.threads - self.pool_threads


def threads() -> int:
    """OS threads of this process (Linux /proc; Python's count misses native ones, e.g. rerun's)."""
    try:
        return len(os.listdir("/proc/self/task"))
    except OSError:
        return threading.active_count()


def sample(app, t: float) -> Sample:
    return Sample(t, rss_mb(), backlog(app), threads(), pool_threads(app))


def callback_pools(app) -> list:
    """The thread pools that run the page's GUI and scene callbacks (viser shares one between them). A pool starts
    a thread whenever a callback is submitted while all its threads are busy, up to its ``max_workers``, and keeps
    it: on a busy machine the count climbs towards that bound as actions overlap more, which is growth by design,
    not a leak."""
    pools = {id(p): p for p in (api._thread_executor._inner for api in (app.server.gui, app.server.scene))}
    return list(pools.values())


def pool_threads(app) -> int:
    """Threads of the callback pools (:func:`callback_pools`)."""
    return sum(len(p._threads) for p in callback_pools(app))


def rss_mb() -> float:
    """Resident memory of this process [MB] (Linux /proc)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024.0
    return math.nan


def plausible(handle, rng: random.Random):
    """A value the page itself could send for ``handle``."""
    opts = getattr(handle, "options", None)
    if opts:
        return rng.choice(tuple(opts))
    lo, hi = getattr(handle, "min", None), getattr(handle, "max", None)
    v = handle.value
    if isinstance(v, bool):
        return not v
    if isinstance(v, (int, float)) and lo is not None and hi is not None:
        return rng.uniform(float(lo), float(hi))
    if isinstance(v, tuple) and v and all(isinstance(x, (int, float)) for x in v):
        return tuple(x + rng.uniform(-0.5, 0.5) for x in v)
    if isinstance(v, str):
        return rng.choice(("scene.toml", "ep", "x", v))
    return v


def backlog(app) -> int:
    """Work the server holds for its clients: messages in viser's broadcast buffer and callbacks waiting to run."""
    return len(app.server._websock_server._broadcast_buffer.message_from_id) + pending_callbacks(app)


def pending_callbacks(app) -> int:
    """Callbacks of the page's actions submitted and not started (the thread pool's queue)."""
    return sum(api._thread_executor._inner._work_queue.qsize() for api in (app.server.gui, app.server.scene))


# actions that wait (up to their timeout) for the page to render a frame, which a raw client never does
WAITS_FOR_PAGE = ("Screenshot", "Record video")


def idle(app) -> bool:
    """No page callback waiting or running."""
    return all(api._thread_executor.busy() == 0 for api in (app.server.gui, app.server.scene))


def warm_up(app, *, seed: int = 0) -> int:
    """Every element of the page once, one at a time, with a value the page could send, each waited for: what a
    session loads once (each scene's kernels, the policies, meshes, a recording, a grid) is loaded before memory is
    watched. Returns how many elements were set."""
    from viser import _messages as vm

    from tools.browser import wait_for
    from tools.hostile_client import HostileClient

    rng = random.Random(seed)
    client = HostileClient(app)
    n = 0
    try:
        for uuid, impl in list(app.server.gui._gui_input_handle_from_uuid.items()):
            if uuid not in app.server.gui._gui_input_handle_from_uuid:  # removed by an earlier action
                continue
            if getattr(impl, "label", "") in WAITS_FOR_PAGE:
                continue
            client.send(vm.GuiUpdateMessage(uuid, {"value": plausible(impl, rng)}))
            n += 1
            # one connection's messages are handled in order: once a marker value sent after it is applied, the
            # element's callbacks have been submitted, and idle means they have run
            speed = app.controls.speed
            marker = 0.55 if speed.value != 0.55 else 0.65
            client.set(speed, marker)
            what = f"the action of {getattr(impl, 'label', uuid)!r}"
            wait_for(lambda: speed.value == marker and idle(app), what=what)
    finally:
        client.close()
    return n


def drive(app, seconds: float, *, seed: int = 0, rate_hz: float = 200.0, sample_s: float = 5.0,
          read: bool = True, progress=None) -> list[Sample]:
    """Send hostile and plausible GUI values to ``app`` for ``seconds``, reading what the server sends (as a
    page does) unless ``read`` is False; returns a :class:`Sample` every ``sample_s`` (and at both ends)."""
    from viser import _messages as vm

    from tools.hostile_client import HostileClient

    rng = random.Random(seed)
    client = HostileClient(app, read=read)
    samples = [sample(app, 0.0)]
    t0 = time.monotonic()
    next_sample = t0 + sample_s
    try:
        while (now := time.monotonic()) - t0 < seconds:
            handles = list(app.server.gui._gui_input_handle_from_uuid.items())
            uuid, impl = rng.choice(handles)
            value = plausible(impl, rng) if rng.random() < 0.6 else rng.choice(HOSTILE)
            client.send(vm.GuiUpdateMessage(uuid, {"value": value}))
            time.sleep(1.0 / rate_hz)
            if now >= next_sample:
                samples.append(sample(app, now - t0))
                next_sample += sample_s
                if progress is not None:
                    progress(samples[-1])
    finally:
        client.close()
    samples.append(sample(app, time.monotonic() - t0))
    return samples


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tools.soak", description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=300.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--rate", type=float, default=200.0, help="GUI messages per second")
    ap.add_argument("--no-read", action="store_true", help="never read what the server sends (a stalled client)")
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args(argv)
    from workbench.serve import WorkbenchApp
    from workbench.session import Workbench

    with tempfile.TemporaryDirectory() as tmp:
        app = WorkbenchApp(Workbench.builtin(), port=0, env_map=False, wait_for_browser=False,
                           scenes_dir=Path(tmp) / "scenes", recordings_dir=Path(tmp) / "recordings").start()
        try:
            samples = drive(app, args.seconds, seed=args.seed, rate_hz=args.rate, read=not args.no_read,
                            progress=lambda s: print(f"{s.t:7.1f} s  RSS {s.rss_mb:8.1f} MB  backlog {s.backlog}"
                                                     f"  threads {s.threads} ({s.pool_threads} in the callback"
                                                     " pool)", flush=True))
        finally:
            app.stop()
    if args.json:
        args.json.write_text(json.dumps({"seconds": args.seconds, "seed": args.seed, "rate_hz": args.rate,
                                         "samples": [s._asdict() for s in samples]}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
