"""``rodlab workbench`` command line: serves the default scene, rejects bad input clearly."""
from __future__ import annotations

import signal
import socket
import subprocess
import sys
import threading
import urllib.request
from pathlib import Path

from workbench.serve.cli import default_scene, workbench_main

REPO = Path(__file__).resolve().parents[3]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_default_scene_is_the_obstacle_scene():
    p = default_scene()
    assert p is not None and p.name in ("default.toml", "arm.toml")


def test_serves_the_page_on_localhost():
    """As a user runs it: the page is served once the start-up line is printed, and Ctrl-C quits cleanly."""
    port = free_port()
    # SIGINT as a terminal gives it: a shell without job control starts background commands with SIGINT ignored,
    # which the child would inherit (and Python then installs no KeyboardInterrupt handler).
    proc = subprocess.Popen([sys.executable, "-m", "rodlab_cli", "workbench", "--port", str(port), "--no-env-map", "--no-shadows"],
                            cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        seen = []
        for line in proc.stdout:  # ends on the start-up line, or when the process dies
            seen.append(line)
            if f"http://127.0.0.1:{port}/" in line:
                break
        assert proc.poll() is None, "".join(seen)
        threading.Thread(target=proc.stdout.read, daemon=True).start()  # keep its output flowing
        html = urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=600).read()
        assert b"<html" in html.lower()
    finally:
        proc.send_signal(signal.SIGINT)
        rc = proc.wait(timeout=600)
    assert rc == 0


def test_missing_scene_file_is_a_clear_error(capsys, tmp_path):
    assert workbench_main([str(tmp_path / "nope.toml")]) == 2
    assert "nope.toml" in capsys.readouterr().err


def test_invalid_scene_names_the_problem(capsys, tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[sim]\ndt = -1\n")
    assert workbench_main([str(bad)]) == 2
    err = capsys.readouterr().err
    assert "bad.toml" in err and "cannot load" in err


def test_scene_and_task_together_are_rejected(capsys):
    assert workbench_main(["x.toml", "--task", "follow_target"]) == 2
    assert "not both" in capsys.readouterr().err


def test_task_option_starts_a_policy_session():
    from workbench.serve.app import WorkbenchApp
    from workbench.session.core import Workbench

    app = WorkbenchApp(Workbench.builtin(), port=0, env_map=False)
    try:
        app.policy.start_task("follow_target")
        assert app.wb.mode == "policy" and app.wb.policy.task == "follow_target"
        for _ in range(4):
            app.wb.step()
        assert app.wb.policy.scalars["episode_step"] == 2
    finally:
        app.stop()


def test_task_option_prints_the_tasks_scene(capsys):
    """``--task T`` names T's scene at start-up, not the teleop scene opened underneath it (default.toml)."""
    assert workbench_main(["--task", "follow_target_2d", "--port", "0", "--no-env-map", "--no-shadows", "--seconds", "0"]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if "http://" in x)
    assert "task follow_target_2d, scene arm_2d.toml" in line and "default.toml" not in line, line
