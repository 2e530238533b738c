"""A rollout as a torch function (policies.differentiable): its gradient is the adjoint of sim.analysis.gradients and matches
central differences; a torch optimiser uses it to bend a rod's tip onto a target."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from policies.differentiable import DifferentiableRollout
from sim.scene.model import build_model
from sim.step import Simulator
from tests.helpers.rodspec import make_spec

T, B = 8, 2


@pytest.fixture(scope="module")
def roll():
    spec = make_spec(nodes=7, length=0.6, radius=0.03, dt=0.05, gravity=(0.0, 0.0, -9.8), damping=2.0, tol=1e-12,
                     dtol=1e-12, max_iter=40, direction=(0.0, 0.0, 1.0))
    sim = Simulator(build_model(spec), envs=B)
    return DifferentiableRollout(sim, sim.reset())


def tip(dof: torch.Tensor) -> torch.Tensor:
    return dof.view(B, -1, 4)[:, -1, :3]


def test_gradient_matches_central_differences(roll):
    N = roll.sim.model.node_count
    rng = np.random.default_rng(0)
    kb0 = rng.normal(0.0, 0.1, (T, B, N, 2))
    kb = torch.tensor(kb0, requires_grad=True)
    target = torch.tensor([[0.2, 0.1, 0.4], [-0.1, 0.0, 0.5]], dtype=torch.float64)
    dof, vel = roll(kb)
    loss = ((tip(dof) - target) ** 2).sum() + 0.1 * (vel**2).sum()
    loss.backward()
    g = kb.grad.numpy()
    assert np.all(np.isfinite(g)) and np.abs(g).max() > 0

    def f(k):
        with torch.no_grad():
            d, v = roll(torch.tensor(k))
            return float(((tip(d) - target) ** 2).sum() + 0.1 * (v**2).sum())

    for _ in range(3):
        direction = rng.normal(0.0, 1.0, kb0.shape)
        eps = 1e-6
        fd = (f(kb0 + eps * direction) - f(kb0 - eps * direction)) / (2 * eps)
        assert np.sum(g * direction) == pytest.approx(fd, rel=1e-6)


def test_a_checkpointed_rollout_gives_the_same_gradient(roll):
    """checkpoint=3 (8 steps: segments of 3, 3 and 2) keeps 3 states and steps the segments again backward: the
    gradient is the whole tape's to the bit."""
    N = roll.sim.model.node_count
    kb0 = np.random.default_rng(1).normal(0.0, 0.1, (T, B, N, 2))
    grads = []
    for r in (roll, DifferentiableRollout(roll.sim, roll.state, checkpoint=3)):
        kb = torch.tensor(kb0, requires_grad=True)
        dof, vel = r(kb)
        (tip(dof).sum() + (vel ** 2).sum()).backward()
        grads.append(kb.grad.numpy())
    assert np.abs(grads[0]).max() > 0 and np.array_equal(grads[0], grads[1])


def test_an_optimiser_bends_the_tip_onto_a_target(roll):
    N = roll.sim.model.node_count
    kb = torch.zeros(T, B, N, 2, dtype=torch.float64, requires_grad=True)
    target = torch.tensor([[0.25, 0.0, 0.45], [0.0, -0.2, 0.5]], dtype=torch.float64)
    opt = torch.optim.Adam([kb], lr=0.05)
    dist = []
    for _ in range(30):
        opt.zero_grad()
        dof, _ = roll(kb)
        loss = ((tip(dof) - target) ** 2).sum()
        loss.backward()
        opt.step()
        dist.append(float(loss.detach()) ** 0.5)
    assert dist[-1] < 0.2 * dist[0], dist
    assert roll.last_tape is not None and roll.last_tape.unconverged == 0


def test_wrong_inputs_are_refused(roll):
    with pytest.raises(TypeError, match="float64"):
        roll(torch.zeros(T, B, roll.sim.model.node_count, 2))
    with pytest.raises(ValueError, match="kappa_bar has shape"):
        roll(torch.zeros(T, B, 3, 2, dtype=torch.float64))
