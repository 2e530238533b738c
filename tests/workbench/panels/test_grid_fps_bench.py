"""tools/fps_bench runs both configurations (one env, a grid) and writes its figures as JSON (a tiny smoke run
without a page; the figures themselves are taken on a quiet machine, BENCHMARKS.md §4)."""
from __future__ import annotations

import json

import pytest


def test_fps_bench_writes_json(tmp_path):
    from tools.fps_bench import main

    out = tmp_path / "fps.json"
    assert main(["--envs", "1,2", "--seconds", "2", "--warmup", "0.3", "--no-browser", "--json", str(out)]) == 0
    doc = json.loads(out.read_text())
    assert [r["envs"] for r in doc["results"]] == [1, 2]
    for r in doc["results"]:
        assert r["frames_per_s"] > 0 and r["steps_per_s"] > 0 and r["browser_animation_frames_per_s"] is None


def test_fps_bench_refuses_bad_counts():
    from tools.fps_bench import main

    with pytest.raises(SystemExit):
        main(["--envs", "0", "--no-browser"])
