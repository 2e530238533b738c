"""The training bar says what the run is doing: SB3's warm-up of random actions (env steps only, fast), the first
updates (slow while compiled updates compile), then training, so a bar that races ahead and then slows down is
explained on the terminal."""
from __future__ import annotations

import sys

from policies.learning.train_monitor import bar_phase
from policies.learning.training import train
from tests.helpers.training import train_args


def test_bar_phases():
    assert bar_phase(0, 16, 0, False) == "warm-up: random actions"
    assert bar_phase(16, 16, 0, True) == "warm-up: random actions"  # SB3 updates once past learning_starts
    assert bar_phase(17, 16, 0, True) == "first updates: compiling"
    assert bar_phase(17, 16, 0, False) == "first updates"
    assert bar_phase(40, 16, 3, True) == "training"


def test_the_bar_shows_each_phase_in_order(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)  # the bar is drawn on a terminal only
    train(train_args(tmp_path / "run", 48, learning_starts=16, updates_per_iter=1, eval_episodes=0))
    err = capsys.readouterr().err
    at = [err.find(p) for p in ("warm-up: random actions", "first updates", "training:")]
    assert all(i >= 0 for i in at) and at == sorted(at), err[-2000:]
