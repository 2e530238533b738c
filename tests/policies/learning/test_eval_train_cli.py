"""Hardening, outputs of `rodlab eval --record` and `rodlab train --run-dir`: a read-only, file-as-parent or
folder path is refused with a clear error before any work; eval shows a progress bar with ETA on request."""
from __future__ import annotations

import pytest

from policies.cli import eval_main, train_main


def _bad(tmp_path, kind, name):
    (tmp_path / "f").write_text("x")
    (tmp_path / "d.rrd").mkdir()
    return {"read-only": f"/proc/rodlab_hardening/{name}", "file-as-parent": str(tmp_path / "f" / name),
            "directory": str(tmp_path / "d.rrd")}[kind]


def _no_work(*a, **k):
    raise AssertionError("the work started before the output was checked")


@pytest.mark.parametrize("kind", ["read-only", "file-as-parent", "directory"])
def test_eval_record_unwritable_refused_before_the_evaluation(tmp_path, capsys, monkeypatch, kind):
    monkeypatch.setattr("policies.learning.evaluate", _no_work)  # the name the command reads
    assert eval_main(["random", "--task", "follow_target", "--episodes", "1",
                      "--record", _bad(tmp_path, kind, "x.rrd")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("rodlab eval: ") and "Traceback" not in err, err


@pytest.mark.parametrize("kind", ["read-only", "file-as-parent"])
def test_train_run_dir_unwritable_refused_before_training(tmp_path, capsys, monkeypatch, kind):
    monkeypatch.setattr("policies.learning.train", _no_work)  # the name the command reads
    run_dir = _bad(tmp_path, kind, "run")
    assert train_main(["follow_target", "--steps", "10", "--run-dir", run_dir]) == 2
    err = capsys.readouterr().err
    assert err.startswith("rodlab train: --run-dir: ") and "Traceback" not in err, err


def test_train_run_dir_that_is_a_file_is_refused(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr("policies.learning.train", _no_work)  # the name the command reads
    f = tmp_path / "run"
    f.write_text("x")
    assert train_main(["follow_target", "--steps", "10", "--run-dir", str(f)]) == 2
    assert "is a file, not a folder" in capsys.readouterr().err


def test_eval_progress_bar_on_request(capsys):
    assert eval_main(["random", "--task", "follow_target", "--episodes", "2", "--envs", "2", "--json",
                      "--progress"]) == 0
    err = capsys.readouterr().err
    assert "rodlab eval" in err and "2/2" in err
