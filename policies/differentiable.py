"""A rodlab rollout as a differentiable torch function (its gradients: :mod:`sim.analysis.gradients`, the adjoint mode).

    from policies.differentiable import DifferentiableRollout
    roll = DifferentiableRollout(sim, sim.reset())                  # the start state is copied, never changed
    kb = torch.zeros(T, B, N, 2, dtype=torch.float64, requires_grad=True)   # natural curvature per step
    dof, vel = roll(kb)                                             # (B, n) each, at the end of the rollout
    loss = ((dof.view(B, -1, 4)[:, -1, :3] - target) ** 2).sum(); loss.backward()   # kb.grad: exact

The natural curvature ``kappa_bar`` (T, B, N, 2) and optionally the natural twist ``tau_bar`` (T, B, N) are the
inputs (the absolute values each step reads); the outputs are the final DOFs and velocities. Gradients come from one
backward pass of transposed solves (``Tape.vjp``), so any number of per-step controls costs the same. float64 only.
``DifferentiableRollout(sim, state, checkpoint=K)`` keeps the state every K steps instead of every state and steps
the segments again in the backward pass (``rollout(checkpoint=K)``: the same gradients, less memory).
"""
from __future__ import annotations

import numpy as np
import torch
from sim.analysis import GradientError, Tape, rollout

__all__ = ["DifferentiableRollout"]


class _Rollout(torch.autograd.Function):
    @staticmethod
    def forward(ctx, kappa_bar, tau_bar, runner):
        tape = runner.run(kappa_bar.detach().cpu().numpy(), tau_bar.detach().cpu().numpy())
        ctx.tape = tape
        runner.last_tape = tape
        dof = torch.from_numpy(tape.dof[-1].copy())
        vel = torch.from_numpy(tape.vel[-1].copy())
        return dof, vel

    @staticmethod
    def backward(ctx, g_dof, g_vel):
        tape = ctx.tape
        cot = {}
        if g_dof is not None:
            cot["dof"] = g_dof.detach().cpu().numpy().astype(np.float64)
        if g_vel is not None:
            cot["vel"] = g_vel.detach().cpu().numpy().astype(np.float64)
        grads = tape.vjp(cot, params=("kappa_bar", "tau_bar"))
        return torch.from_numpy(grads["kappa_bar"]), torch.from_numpy(grads["tau_bar"]), None


class DifferentiableRollout:
    """Rollouts of ``sim`` from a copy of ``state`` as a torch function of the per-step natural curvature and twist.
    :attr:`last_tape` is the :class:`sim.analysis.gradients.Tape` of the last call (its states, ``unconverged``)."""

    def __init__(self, sim, state, *, checkpoint: int | None = None):
        self.sim = sim
        self.state = state.copy()
        self.checkpoint = checkpoint
        self.last_tape: Tape | None = None

    def run(self, kappa_bar: np.ndarray, tau_bar: np.ndarray) -> Tape:
        B, N = self.sim.envs, self.sim.model.node_count
        if kappa_bar.ndim != 4 or kappa_bar.shape[1:] != (B, N, 2):
            raise GradientError(f"kappa_bar has shape {kappa_bar.shape}, expected (T, {B}, {N}, 2)")
        if tau_bar.shape != kappa_bar.shape[:3]:
            raise GradientError(f"tau_bar has shape {tau_bar.shape}, expected {kappa_bar.shape[:3]}")
        if not (np.all(np.isfinite(kappa_bar)) and np.all(np.isfinite(tau_bar))):
            raise GradientError("kappa_bar / tau_bar have non-finite values")
        ctrls = []
        for k in range(kappa_bar.shape[0]):
            c = self.sim.make_control()
            c.kappa_bar[...] = kappa_bar[k]
            c.tau_bar[...] = tau_bar[k]
            ctrls.append(c)
        return rollout(self.sim, self.state.copy(), ctrls, checkpoint=self.checkpoint)

    def __call__(self, kappa_bar: torch.Tensor, tau_bar: torch.Tensor | None = None):
        if kappa_bar.dtype != torch.float64:
            raise TypeError(f"kappa_bar must be float64 (the simulator's precision), got {kappa_bar.dtype}")
        B, N = self.sim.envs, self.sim.model.node_count
        if kappa_bar.ndim != 4 or tuple(kappa_bar.shape[1:]) != (B, N, 2):
            raise GradientError(f"kappa_bar has shape {tuple(kappa_bar.shape)}, expected (T, {B}, {N}, 2)")
        if tau_bar is None:  # the rest twist at every step
            rest = torch.from_numpy(self.sim.make_control().tau_bar.astype(np.float64))
            tau_bar = rest.expand(kappa_bar.shape[:3]).clone()
        return _Rollout.apply(kappa_bar, tau_bar, self)
