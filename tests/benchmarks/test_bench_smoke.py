"""Smoke tests: every benchmark runs in a tiny configuration and writes its documented output format."""
import json

import numpy as np
import pytest

from benchmarks import accuracy as acc
from benchmarks import analysis as an
from benchmarks.accuracy_extra import add_orders, plot_scene
from benchmarks.common import pyplot, write_json

TINY = {"dts": [0.05, 0.1], "nodes": [11], "solvers": ["paper", "conv"], "small_dt_solvers": ["conv"],
        "el_nodes": [], "el_factors": [], "max_work": 1e9, "ref_nodes": 11, "ref_dt": 0.05, "el_ref_nodes": 11}


def test_accuracy_static_tiny_writes_points_analysis_and_plots(tmp_path):
    res = acc.bench_static(TINY, peer=False, repeats=1)
    assert res["scene"] == "static" and len(res["points"]) == 4
    for p in res["points"]:
        assert {"sim", "solver", "nodes", "dt", "cost", "cost_wall", "error", "error_root_at_half_edge",
                "newton_iters_mean", "stable", "load"} <= set(p)
        assert p["stable"] and np.isfinite(p["error"]) and p["cost"] > 0
        assert p["error"] < 0.2  # N = 11 clamp offset error is about 0.08
    res["analysis"] = acc.analyse(res)
    add_orders(res)
    plot_scene(pyplot(), res, tmp_path)
    assert (tmp_path / "accuracy_static_pareto.png").stat().st_size > 1000
    path = write_json(tmp_path, "a.json", {"scenes": {"static": res}})
    back = json.loads(path.read_text())
    assert back["scenes"]["static"]["analysis"]["pareto_rodlab"]


def test_accuracy_dynamic_tiny_tracks_the_beam():
    res = acc.bench_dynamic({**TINY, "dts": [0.01], "nodes": [21], "solvers": ["conv"]}, peer=False, repeats=1)
    (p,) = res["points"]
    assert p["error"] < 1.0  # phase error of the N = 21 clamp offset over two periods (about 0.6)


def test_accuracy_cli_rejects_unknown_scene(capsys):
    with pytest.raises(SystemExit) as exc:
        acc.main(["--scenes", "nope"])
    assert exc.value.code == 2
    assert "unknown scene" in capsys.readouterr().err


def test_pareto_and_speedup_helpers():
    pts = [{"cost": 1.0, "error": 0.5}, {"cost": 2.0, "error": 0.6}, {"cost": 3.0, "error": 0.1},
           {"cost": 0.5, "error": None}]
    fr = an.pareto_front(pts)
    assert [p["cost"] for p in fr] == [1.0, 3.0]
    other = [{"cost": 10.0, "error": 0.5}, {"cost": 60.0, "error": 0.1}]
    tab = an.speedup_table(fr, an.pareto_front(other), levels=2)
    assert tab[0]["speedup"] == pytest.approx(20.0) and tab[-1]["speedup"] == pytest.approx(10.0)
    assert an.observed_order([1, 2, 4], [1, 4, 16]) == pytest.approx(2.0)


def test_stress_functions_tiny():
    from benchmarks.stress import SimCase, run_sim_case, run_task
    r = run_sim_case(SimCase("tiny", nodes=11), envs=2, control_steps=3, actions="bang-bang", hold_steps=3)
    assert r["nan"] == 0 and r["env_steps"] == 2 * (3 * 2 + 3)
    assert {"failed_steps", "recovered_steps", "max_penetration_m", "energy_growth_max_J",
            "newton_iters_hist"} <= set(r)
    assert sum(r["newton_iters_hist"]) == r["env_steps"]
    t = run_task("follow_target", envs=2, env_steps=4, actions="random")
    assert t["nan"] == 0 and t["obs_nan"] == 0 and t["env_control_steps"] == 4


def test_throughput_time_sim_tiny():
    from benchmarks.throughput import arm_doc, time_sim
    r = time_sim(arm_doc(nodes=11), envs=2, steps=1, repeats=1)
    assert {"ms_per_step", "cpu_ms_per_step", "us_per_env_step", "iters_mean", "load"} <= set(r)
    assert r["nan"] == 0 and r["ms_per_step"] > 0


def test_bench_train_tiny():
    from policies.cli import bench_train

    r = bench_train("follow_target", envs=8, iters=2, warmup=1)
    assert r["iteration_ms"] > 0 and r["update_ms"] > 0 and r["env_step_ms"] >= 0
    assert r["speed_settings"] == "float32"


def test_throughput_pairs_tiny():
    from benchmarks.throughput_pairs import part_pairs

    res = part_pairs(quick=True, repeats=1)
    for name in ("curl_0.75_turn_no_contact", "curl_1.25_turns_resting_on_itself", "two_rods_apart",
                 "two_rods_apart_rod_contact_off", "two_rods_crossed_resting", "hanging_201_self_contact_off",
                 "hanging_201_self_contact_on"):
        assert res[name]["failed_envs"] == 0 and res[name]["nan"] == 0 and res[name]["ms_per_step"] > 0
    assert res["curl_0.75_turn_no_contact"]["contact_energy_mean"] == 0.0
    assert res["curl_1.25_turns_resting_on_itself"]["contact_energy_mean"] > 0.0
    # the hanging rod touches nothing, however many candidate pairs lie inside the margin
    assert res["hanging_201_self_contact_on"]["contact_energy_mean"] == 0.0
    # the rods apart touch only the floor: the same contact energy with rod contact on and off
    assert res["two_rods_apart"]["contact_energy_mean"] == res["two_rods_apart_rod_contact_off"]["contact_energy_mean"]
    assert res["ratio_rod_contact_on_over_off_apart"] > 0 and res["ratio_self_contact_on_over_off"] > 0


def test_gradients_bench_tiny_measures_a_step_and_both_fits():
    from benchmarks import gradients as gb

    st = gb.bench_step(2, 1)
    assert st["forward_ms_per_env"] > 0 and st["backward_ms_per_env"] > st["backward_cached_ms_per_env"] > 0
    assert st["record_bytes_per_env_step"] > 0 and st["linearisation_bytes_per_env_step"] > 0
    ck = gb.bench_checkpoint(2, 12, 4, 1)  # 3 of 12 states kept: a fraction of the whole tape's bytes
    assert 0 < ck["checkpointed"]["bytes_per_env_step"] < 0.6 * ck["whole"]["bytes_per_env_step"]
    ft = gb.bench_fit(0.5, 1)
    for how in ("exact", "probing"):  # both methods fit the synthetic data to its noise
        assert ft[how]["rms_m"] < 2e-3 and ft[how]["seconds_median"] > 0
    assert ft["probing_over_exact"] > 0
