"""Open-loop trajectory optimisation (sim.analysis.trajectory): the objective's gradient against central differences,
a reachable target path followed to well below a millimetre from rest controls, the delta bound kept, batched envs
optimised alone, bad input refused by name."""
from __future__ import annotations

import numpy as np
import pytest

from sim.analysis import optimise_controls
from sim.analysis import trajectory as TR
from sim.scene.model import build_model
from sim.step import Simulator
from tests.helpers.rodspec import make_spec

T = 10


def simulator(mode: str, envs: int = 1) -> Simulator:
    spec = make_spec(nodes=8, length=0.5, radius=0.02, dt=0.02, gravity=(0.0, 0.0, -9.8), damping=2.0, tol=1e-11,
                     dtol=1e-12, mode=mode, direction=(0.0, 0.0, 1.0))
    return Simulator(build_model(spec), envs=envs)


def reachable(sim, rng, max_delta=0.03):
    """The tip's path under a random sequence of bounded deltas: a target path the controls can follow exactly."""
    st = sim.reset()
    c = sim.make_control()
    comps = 1 if sim.model.mode == "2d" else 2
    path = []
    for _ in range(T):
        c.kappa_bar[:, 1:-1, :comps] += rng.uniform(-max_delta, max_delta, (sim.envs, sim.model.node_count - 2, comps))
        sim.step(st, c)
        path.append(_tip(sim, st))
    return np.stack(path, axis=0)  # (T, B, 3)


def _tip(sim, st):
    dof = st.dof.reshape(sim.envs, -1)
    if sim.model.mode == "2d":
        return np.stack([dof[:, -2], np.full(sim.envs, sim.model.plane_y), dof[:, -1]], axis=1)
    return dof.reshape(sim.envs, -1, 4)[:, -1, :3].copy()


@pytest.mark.parametrize("mode", ["2d", "3d"])
def test_a_reachable_path_is_followed_from_rest_controls(mode):
    rng = np.random.default_rng(0)
    sim = simulator(mode)
    targets = reachable(sim, rng)
    res = optimise_controls(sim, sim.reset(), targets, max_delta=0.03, max_iterations=150)
    assert res.cost[0] < 1e-3 * res.cost0[0], (res.cost0, res.cost)
    assert np.abs(res.positions - targets).max() < 1e-3, np.abs(res.positions - targets).max()
    deltas = np.diff(np.concatenate([sim.make_control().kappa_bar[None], res.kappa_bar]), axis=0)
    assert np.abs(deltas).max() <= 0.03 + 1e-12  # the delta bound holds


def test_the_objective_gradient_matches_central_differences(monkeypatch):
    """evaluate's gradient (one adjoint pass through the cumulative deltas) against central differences of the
    objective, in random directions."""
    rng = np.random.default_rng(1)
    sim = simulator("3d")
    targets = reachable(sim, rng) + 0.01
    seen = {}

    def spy(fun, z0, jac, method, bounds, options):
        seen["fun"], seen["n"] = fun, z0.size

        class R:
            x = z0
        return R()

    import scipy.optimize
    monkeypatch.setattr(scipy.optimize, "minimize", spy)  # hands over the objective instead of minimising it
    optimise_controls(sim, sim.reset(), targets, twist=True, effort=0.3)
    fun, n = seen["fun"], seen["n"]
    z = rng.uniform(-0.02, 0.02, n)
    f0, g = fun(z)
    for _ in range(3):
        d = rng.normal(0.0, 1.0, n)
        eps = 1e-6
        fd = (fun(z + eps * d)[0] - fun(z - eps * d)[0]) / (2 * eps)
        assert g @ d == pytest.approx(fd, rel=1e-6, abs=1e-12 * abs(f0))


def test_envs_are_optimised_alone():
    """Two envs with different targets, optimised together: each follows its own, as the env alone does."""
    rng = np.random.default_rng(2)
    sim = simulator("2d", envs=2)
    targets = reachable(sim, rng)
    both = optimise_controls(sim, sim.reset(), targets, max_delta=0.03, max_iterations=150)
    assert np.all(both.cost < 1e-3 * both.cost0)
    one = simulator("2d")
    alone = optimise_controls(one, one.reset(), targets[:, 1], max_delta=0.03, max_iterations=150)
    assert np.abs(both.positions[:, 1] - targets[:, 1]).max() < 1e-3
    assert np.abs(alone.positions[:, 0] - targets[:, 1]).max() < 1e-3


def test_bad_input_is_refused_by_name():
    sim = simulator("2d")
    st = sim.reset()
    with pytest.raises(ValueError, match="targets"):
        optimise_controls(sim, st, np.zeros((T, 2)))
    with pytest.raises(ValueError, match="node 99"):
        optimise_controls(sim, st, np.zeros((T, 3)), node=99)
    with pytest.raises(ValueError, match="max_delta"):
        optimise_controls(sim, st, np.zeros((T, 3)), max_delta=0.0)
    with pytest.raises(ValueError, match="weights"):
        optimise_controls(sim, st, np.zeros((T, 3)), weights=np.ones(3))
    assert TR.__all__ == ["TrajectoryResult", "optimise_controls"]
