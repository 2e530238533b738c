"""Hardening, recordings: `rodlab record` refuses bad --max-steps, unwritable --out (before any episode) and a
policy of another task with a clear error; SIGTERM/SIGKILL leave no hidden part folder behind (a real
subprocess is killed); `rodlab inspect` on a truncated .rrd gives a clear error; progress bar on request."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from policies.recording.cli import inspect_main, record_main
from tests.helpers.paths import REPO

EXAMPLE = REPO / "recordings" / "examples" / "follow_target.rrd"


@pytest.mark.parametrize("cut", [0.5, 0.02])
def test_inspect_truncated_rrd_is_a_clear_error(tmp_path, capsys, cut):
    data = EXAMPLE.read_bytes()
    bad = tmp_path / "truncated.rrd"
    bad.write_bytes(data[: int(len(data) * cut)])
    assert inspect_main([str(bad)]) == 2
    err = capsys.readouterr().err
    assert "truncated.rrd: not a readable .rrd file" in err and "Traceback" not in err, err


@pytest.mark.parametrize("steps", ["0", "-3"])
def test_record_max_steps_must_be_positive(tmp_path, capsys, steps):
    out = tmp_path / "x.rrd"
    assert record_main(["--task", "follow_target", "--max-steps", steps, "--out", str(out)]) == 2
    assert "--max-steps must be >= 1" in capsys.readouterr().err and not out.exists()


@pytest.mark.parametrize("kind", ["read-only", "file-as-parent", "directory"])
def test_record_unwritable_out_refused_before_any_episode(tmp_path, capsys, monkeypatch, kind):
    (tmp_path / "f").write_text("x")
    (tmp_path / "d.rrd").mkdir()
    out = {"read-only": "/proc/rodlab_hardening/x.rrd", "file-as-parent": str(tmp_path / "f" / "x.rrd"),
           "directory": str(tmp_path / "d.rrd")}[kind]

    def no_env(*a, **k):
        raise AssertionError("episodes started before the output was checked")

    monkeypatch.setattr("policies.make_vec_env", no_env)
    assert record_main(["--task", "follow_target", "--out", out]) == 2
    err = capsys.readouterr().err
    assert err.startswith("rodlab record: ") and "Traceback" not in err, err


def test_record_into_a_missing_folder_is_a_clear_error(tmp_path, capsys, monkeypatch):
    out = tmp_path / "missing" / "x.rrd"

    def no_env(*a, **k):
        raise AssertionError("episodes started before the output was checked")

    monkeypatch.setattr("policies.make_vec_env", no_env)
    assert record_main(["--task", "follow_target", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"folder {tmp_path / 'missing'} does not exist" in err and "Traceback" not in err, err
    assert not (tmp_path / "missing").exists()  # not created


def test_record_with_another_tasks_policy_is_a_clear_error(tmp_path, capsys):
    out = tmp_path / "x.rrd"
    rc = record_main(["--task", "follow_target", "--policy", str(REPO / "policies/pretrained/ik4d.zip"),
                      "--max-steps", "2", "--out", str(out)])
    err = capsys.readouterr().err
    assert rc == 2 and "does not fit task" in err and not out.exists(), err
    assert not any(p.name.startswith(".") for p in tmp_path.iterdir())


def test_record_progress_bar_on_request(tmp_path, capsys):
    out = tmp_path / "p.rrd"
    assert record_main(["--task", "follow_target", "--episodes", "2", "--max-steps", "3", "--out", str(out),
                        "--progress"]) == 0
    err = capsys.readouterr().err
    assert "rodlab record" in err and "6/6" in err and out.exists()


def _start_recording(out: Path) -> subprocess.Popen:
    cmd = [sys.executable, str(REPO / "rodlab_cli.py"), "record", "--task", "follow_target", "--episodes", "400",
           "--max-steps", "400", "--out", str(out)]
    p = subprocess.Popen(cmd, cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         env={**os.environ, "PYTHONPATH": str(REPO)})
    deadline = time.monotonic() + 600
    while not list(out.parent.glob(f".{out.name}.parts-*")):  # the first episode has begun
        if p.poll() is not None or time.monotonic() > deadline:
            p.kill()
            raise AssertionError(f"recording did not start: {p.communicate()}")
        time.sleep(0.2)
    return p


def test_sigterm_leaves_no_part_folder_and_sigkill_leftovers_are_cleaned_next_start(tmp_path):
    out = tmp_path / "term.rrd"
    p = _start_recording(out)
    p.send_signal(signal.SIGTERM)
    _, err = p.communicate(timeout=600)
    assert p.returncode == 143 and "terminated; nothing written" in err, err
    assert list(tmp_path.iterdir()) == []

    killed = tmp_path / "killed.rrd"
    p = _start_recording(killed)
    p.send_signal(signal.SIGKILL)
    p.wait(timeout=600)
    left = list(tmp_path.iterdir())
    assert len(left) == 1 and left[0].name.startswith(".killed.rrd.parts-")
    # the next recording in this folder (any name) removes the dead process's part folder
    other = tmp_path / "other.rrd"
    assert record_main(["--task", "follow_target", "--max-steps", "2", "--out", str(other)]) == 0
    assert sorted(x.name for x in tmp_path.iterdir()) == ["other.rrd"]
