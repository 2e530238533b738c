"""Hardening, `rodlab sim`: unwritable --out refused before the simulation, --duration inf refused, progress bar
on request, and a warning when the rod starts inside an obstacle (sim/scene/check.py)."""
from __future__ import annotations

import numpy as np
import pytest

from sim import build_model, load_scene
from sim.cli import sim_main
from sim.scene.check import rod_obstacle_overlaps

ARM = "assets/scenes/arm.toml"
SPHERE_IN_ROD = '\n[[obstacle]]\ntype = "sphere"\nname = "ball"\ncenter = [0.0, 0.0, 0.5]\nradius = 0.1\n'


def _bad_outputs(tmp_path):
    f = tmp_path / "a_file"
    f.write_text("x")
    d = tmp_path / "a_dir.npz"
    d.mkdir()
    return {"read-only": "/proc/rodlab_hardening/out.npz", "file-as-parent": str(f / "out.npz"),
            "directory": str(d)}


@pytest.mark.parametrize("kind", ["read-only", "file-as-parent", "directory"])
def test_unwritable_out_is_refused_before_the_work(tmp_path, capsys, kind, monkeypatch):
    out = _bad_outputs(tmp_path)[kind]
    import sim.cli as cli

    def no_work(*a, **k):  # the simulation must not even be built
        raise AssertionError("the simulation started before the output was checked")

    monkeypatch.setattr(cli, "build_model", no_work)
    rc = cli.sim_main([ARM, "--duration", "0.1", "--out", out])
    err = capsys.readouterr().err
    assert rc == 2 and out.split("/")[-1] in err and "rodlab sim:" in err and "Traceback" not in err, err


def test_missing_parent_folders_are_created_and_the_file_written(tmp_path, capsys):
    out = tmp_path / "new" / "deeper" / "run.npz"
    assert sim_main([ARM, "--duration", "0.1", "--out", str(out), "--no-progress"]) == 0
    with np.load(out) as z:
        assert z["node_pos"].shape == (2, 1, 21, 3) and np.isfinite(z["node_pos"]).all()


@pytest.mark.parametrize("dur", ["inf", "nan", "-1", "0"])
def test_duration_must_be_finite_and_positive(capsys, dur):
    assert sim_main([ARM, "--duration", dur]) == 2
    assert "--duration must be a finite number > 0" in capsys.readouterr().err


def test_too_many_frames_in_memory_refused_up_front(tmp_path, capsys):
    assert sim_main([ARM, "--duration", "1e12", "--out", str(tmp_path / "x.npz")]) == 2
    err = capsys.readouterr().err
    assert "GiB in memory" in err and "--every" in err and not (tmp_path / "x.npz").exists()


def test_progress_bar_with_eta_on_request(capsys):
    assert sim_main([ARM, "--duration", "0.5", "--progress"]) == 0
    err = capsys.readouterr().err
    assert "rodlab sim" in err and "10/10" in err and "<" in err  # tqdm: elapsed<remaining


def test_no_progress_bar_when_not_a_terminal(capsys):
    assert sim_main([ARM, "--duration", "0.5"]) == 0  # pytest's stderr is not a TTY
    assert "10/10" not in capsys.readouterr().err


def test_rod_inside_an_obstacle_is_found_and_warned(tmp_path, capsys):
    p = tmp_path / "inside.toml"
    p.write_text(open(ARM).read() + SPHERE_IN_ROD)
    ov = rod_obstacle_overlaps(build_model(load_scene(p)))
    assert [(o.index, o.name, o.type) for o in ov] == [(0, "ball", "sphere")]
    assert ov[0].depth == pytest.approx(0.1 + 0.05, abs=1e-9)  # centre on the axis: sphere radius + rod radius
    assert sim_main([str(p), "--duration", "0.1"]) == 0
    err = capsys.readouterr().err
    assert "warning:" in err and "obstacle[0] 'ball' (sphere" in err


def test_shipped_scenes_do_not_start_inside_obstacles(scenes_dir):
    for p in sorted(scenes_dir.glob("*.toml")):
        assert rod_obstacle_overlaps(build_model(load_scene(p))) == [], p.name
