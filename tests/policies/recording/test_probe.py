"""TaskProbe on the real task cores and simulator (a few envs, a few steps), and the `rodlab record` driver; one
slow test of longer scripted recordings."""
from __future__ import annotations

import numpy as np
import pytest

from policies.recording import Recorder, read_recording
from policies.recording.probe import TaskProbe, integrated_twist
from sim.geometry.curvature import material_curvature

F32 = dict(rtol=1e-6, atol=1e-6)
TASKS = ["follow_target", "follow_target_2d", "ik4d", "tight_obstacles_2d", "random_obstacles_3d"]


def test_material_curvature_of_an_arc():
    """Rod along +z turning by phi toward -x per node, frame m1=(-1,0,0), m2=(0,-1,0): kappa1 = 2 tan(phi/2)."""
    phi, N = 0.1, 8
    ang = phi * np.arange(N - 1)
    t = np.stack([-np.sin(ang), np.zeros(N - 1), np.cos(ang)], -1)
    pos = np.concatenate([np.zeros((1, 3)), np.cumsum(0.05 * t, 0)])
    m2 = np.tile([0.0, -1.0, 0.0], (N - 1, 1))
    m1 = np.cross(m2, t)                                   # (m1, m2, t) right-handed
    k = material_curvature(pos, m1, m2)
    np.testing.assert_allclose(k[1:-1, 0], 2 * np.tan(phi / 2), rtol=1e-12)
    np.testing.assert_allclose(k[:, 1], 0.0, atol=1e-12)
    assert k[0, 0] == 0 and k[-1, 0] == 0
    tw = integrated_twist(np.array([0.0, 0.1, 0.3]), np.array([0.0, 0.01, 0.02, 0.0]))
    np.testing.assert_allclose(tw, [0.0, 0.11, 0.22, 0.0])


@pytest.mark.parametrize("task", TASKS)
def test_probe_records_what_the_core_had(task, tmp_path, verify):
    import policies

    B = 2
    venv = policies.make_vec_env(task, B, seed=3, timeout_steps=3)
    core = venv.core
    out = tmp_path / f"{task}.rrd"
    snaps, rewards, targets, fences = [], [], [], []
    rng = np.random.default_rng(0)
    with Recorder(out) as rec:
        probe = TaskProbe(rec, episodes=3, meta={"policy": "test", "seed": 3}).attach(venv)
        venv.reset(seed=3)
        snaps.append(np.asarray(core.state.node_pos).copy())
        if getattr(core, "fences", None) is not None:
            fences.append(core.fences.copy())
        from policies.recording.probe import task_target

        class Spy:                             # a second observer: snapshot before the auto-reset
            def on_reset(self, core, mask):
                pass

            def on_sim_step(self, core, substep, stats):
                pass

            def on_step(self, core, reward, terminated, truncated, info):
                snaps.append(np.asarray(core.state.node_pos).copy())
                rewards.append(np.asarray(reward).copy())
                targets.append(task_target(core)[0].copy())

        spy = Spy()
        core.add_observer(spy)
        while not probe.done:
            venv.step(rng.uniform(-1, 1, size=(B, core.action_dim)).astype(np.float32))
        probe.detach()
        assert core.observers == [spy]                                # detach removes the probe only
    venv.close()
    verify(out)
    eps = read_recording(out)
    assert [int(e.meta["env"]) for e in eps] == [0, 1, 0]            # quota 2 + 1
    assert all(e.meta["complete"] for e in eps)
    for ep in eps:
        assert ep.meta["policy"] == "test" and ep.meta["task"] == policies.TASKS[task]
        assert ep.steps == 5                                          # reset frame + timeout_steps + 1
        np.testing.assert_array_equal(ep.control_step, np.arange(5))
        np.testing.assert_allclose(ep.sim_time, np.arange(5) * core.config.dt * core.config.substeps, atol=1e-9)
        e = int(ep.meta["env"])
        first = 0 if int(ep.meta["episode"]) < 2 else 4               # env 0's 2nd episode starts at step 4
        for k in range(1, 5):
            np.testing.assert_allclose(ep.positions[k], snaps[first + k][e], **F32)
            assert ep.scalars["reward"][k] == rewards[first + k - 1][e]
            np.testing.assert_allclose(ep.target_pos[k], targets[first + k - 1][e], **F32)
        assert np.isnan(ep.scalars["reward"][0])                      # no reward on the reset frame
        assert ep.episode_return == pytest.approx(sum(rewards[first + k - 1][e] for k in range(1, 5)))
        assert {"reward_terms/distance", "tip_error", "energy/bend", "solver/residual"} <= set(ep.scalars)
        assert ep.m1.shape == (5, 20, 3) and ep.kappa_bar is not None and ep.kappa is not None
        planar = task.endswith("_2d")
        assert bool(ep.meta["planar"]) == planar
        assert ep.kappa_bar.shape[-1] == (1 if planar else 2)
        if planar:
            assert np.all(ep.positions[..., 1] == 0) and np.all(ep.target_pos[:, 1] == 0)
        assert (ep.target_quat is not None) == (task == "ik4d")
        assert (ep.tau is not None) == (task == "ik4d")
        if "obstacles" in task:
            assert ep.scene.capsules is not None and ep.contact_count is not None
            assert ep.contact_count.shape == (5,) and np.all(ep.contact_count >= 0)
            assert np.isfinite(ep.max_contact_force) and ep.max_contact_force >= 0.0
        else:
            assert ep.scene.capsules is None and ep.contact_count is None
    if "obstacles" in task:                                            # the rod reaches an obstacle (env 0, 1st episode)
        assert eps[0].contact_count.max() > 0 and eps[0].max_contact_force > 0.0
    if task == "tight_obstacles_2d":
        assert eps[0].scene.capsules.shape == (6, 2, 3)
        np.testing.assert_allclose(eps[0].scene.capsule_radii, 0.1)
    if task == "random_obstacles_3d":                                 # per-env fences, re-sampled per episode
        np.testing.assert_allclose(eps[0].scene.capsules, fences[0][0])
        np.testing.assert_allclose(eps[1].scene.capsules, fences[0][1])
        assert not np.allclose(eps[0].scene.capsules, eps[1].scene.capsules)
        assert not np.allclose(eps[0].scene.capsules, eps[2].scene.capsules)


def test_per_sim_step_and_max_steps(tmp_path, verify):
    from policies.recording.cli import record

    out = tmp_path / "sub.rrd"
    res = record("tight_obstacles_2d", out, mode="scripted", episodes=2, envs=1, max_steps=2, per_sim_step=True,
                 ref_frames=True)
    verify(out)
    eps = read_recording(out)
    assert len(eps) == 2 and len(res["episodes"]) == 2
    for ep in eps:
        assert ep.meta["complete"] is False                           # cut at max_steps
        n = 10                                                        # sim steps per control step
        assert ep.steps == 1 + 2 * n
        np.testing.assert_array_equal(ep.sim_step, np.arange(1 + 2 * n))
        np.testing.assert_array_equal(ep.control_step, [0] + [1] * n + [2] * n)
        assert np.isfinite(ep.scalars["reward"]).sum() == 2           # reward only on control-step frames
        assert np.isfinite(ep.scalars["energy/bend"]).sum() == 2 * n
        assert ep.d1 is not None and ep.d2 is not None
    np.testing.assert_allclose(eps[0].positions, eps[1].positions, **F32)   # scripted + fixed task: same


def test_record_and_inspect_cli(tmp_path, verify, capsys):
    import json

    from policies.recording.cli import inspect_main, record_main

    out = tmp_path / "cli.rrd"
    assert record_main(["--task", "ik4d", "--random", "--episodes", "2", "--envs", "2", "--max-steps", "3",
                        "--out", str(out)]) == 0
    verify(out)
    capsys.readouterr()
    assert inspect_main([str(out), "--json"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["episodes"] == 2 and s["steps"] == 8
    assert [r["env"] for r in s["episode_list"]] == [0, 1]
    eps = read_recording(out)
    assert s["mean_return"] == pytest.approx(np.mean([e.episode_return for e in eps]))
    assert inspect_main([str(out)]) == 0
    text = capsys.readouterr().out
    assert "2 episodes" in text and "rodlab/IK4D-v0" in text
    assert inspect_main([str(tmp_path / "nope.rrd")]) == 2
    assert "no such recording" in capsys.readouterr().err
    assert record_main(["--task", "nope", "--out", str(tmp_path / "x.rrd")]) == 2
    assert "unknown task" in capsys.readouterr().err


@pytest.mark.slow
@pytest.mark.parametrize("task", TASKS)
def test_real_simulator_recording(task, tmp_path, verify):
    """Real simulator: commanded and actual curvature agree in sign where the command is large."""
    from policies.recording.cli import record

    out = tmp_path / f"{task}.rrd"
    record(task, out, mode="scripted", episodes=1, max_steps=12)
    verify(out)
    (ep,) = read_recording(out)
    assert ep.steps == 13 and np.all(np.isfinite(ep.positions))
    kb, ka = ep.kappa_bar[-1], ep.kappa[-1]
    big = np.abs(kb) > 0.05
    assert big.any() and np.all(np.sign(kb[big]) == np.sign(ka[big]))


def test_evaluate_env_hook_records_every_evaluated_episode(tmp_path, verify):
    from policies.learning.evaluation import evaluate
    from policies.recording.probe import record_hook

    out = tmp_path / "eval.rrd"
    with record_hook(out, episodes=3, meta={"policy": "random", "seed": 5}) as hook:
        res = evaluate("random", "tight_obstacles_2d", episodes=3, seed=5, num_envs=2, eval_seeds=2, env_hook=hook)
    verify(out)
    eps = read_recording(out)
    assert len(eps) == res["episodes"] == 6
    assert [e.meta["seed"] for e in eps] == [5, 5, 5, 6, 6, 6]
    assert all(e.meta["complete"] and e.steps == 52 for e in eps)
    assert np.mean([e.episode_return for e in eps]) == pytest.approx(res["return_mean"])
