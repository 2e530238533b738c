"""SAC as configured in the reference (docs/tasks.md §8.1-8.2), as a small extension of stable-baselines3.

What SB3's ``SAC`` lacks and how it is added here (nothing else is changed):

* **LayerNorm MLPs** (``LayerNormSACPolicy``): actor trunk and both critics are
  ``Linear -> LayerNorm -> ReLU`` x 3 (256 units), built with SB3's own ``create_mlp``
  (``post_linear_modules=[nn.LayerNorm]``). The Gaussian head (mean, log-std; log-std clipped to
  [-20, 2] by SB3) is initialised with Xavier-uniform gain 0.3 and zero bias (reference head init).
* **No entropy term in the critic target** (``RodSAC(entropy_in_target=False)``): the TD target is
  ``r + gamma * (1 - done) * min_i Q_target_i(s', a')`` with ``a' ~ pi(s')``; alpha enters only the
  actor and alpha losses (reference ``use_entropy_reward=False``).
* **Target update every k gradient updates counted globally** (SB3 counts inside one ``train()``
  call, so with 4 updates per call and interval 8 it would update every 4th update).
* **Adam eps 1e-7** for all three optimizers (AdamTF); SB3 keeps three Adam instances where the
  reference shares one. Adam is element-wise, so this is the same update rule.
* **bfloat16 updates** (``RodSAC.bf16_updates``, ``rodlab train --precision bfloat16``, and ``auto``'s fast path): the updates run under
  ``torch.autocast(dtype=bfloat16)`` with the input and output layers and the LayerNorms kept in float32
  (``Float32Linear``, ``Float32LayerNorm``): only the hidden 256x256 products run in bfloat16, so observations,
  actions, Q values and log-probabilities are not rounded to bfloat16's 8-bit mantissa. ``set_bf16_layout(policy,
  "all")`` (``rodlab train --bf16-layout all``, the default) turns them back into plain layers: every product in bfloat16.
* **Compiled updates** (``RodSAC.compile_updates``, ``rodlab train --compile``): each update is one call of
  ``_fused_update`` through ``torch.compile``: the same loss methods as the eager updates, gradients by
  ``torch.func.grad_and_value`` and the Adam steps written out on the optimizers' own state (docs/training.md);
  inductor compiles it with the graph pass ``UnitProductLoops`` (policies/learning/compile_passes.py). The policy noise is
  drawn eagerly and passed in.
* **Replay batches** (``_sample_replay``): SB3's sampling draws and batch, gathered in one pass per field.
* **Timing**: ``last_update_time`` [s] of the most recent ``train()`` call, for logging/benchmarks.

Policy-only files (``save_policy`` / ``load_policy``) are a small zip holding ``meta.json`` (task id,
spaces, network config, format version) and ``policy.pt`` (actor + critic weights as a plain
``state_dict``, loaded with ``torch.load(weights_only=True)``). No optimizer state, no replay buffer,
no pickled classes. Errors while loading raise ``PolicyLoadError`` with a readable message. Loading never
unpickles: a full SB3 checkpoint (which holds cloudpickled objects) is refused unless ``trust_pickle=True``.
"""
from __future__ import annotations

import contextlib
import importlib
import io
import json
import os
import sys
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import torch as th
import torch.nn.functional as F
from gymnasium import spaces
from sim.support.atomicio import write_bytes
from stable_baselines3 import SAC
from stable_baselines3.common.buffers import ReplayBuffer
from stable_baselines3.common.torch_layers import create_mlp
from stable_baselines3.common.type_aliases import ReplayBufferSamples
from stable_baselines3.common.utils import polyak_update
from stable_baselines3.sac.policies import Actor, SACPolicy
from torch import nn
from torch.func import functional_call, grad_and_value

from policies.learning.compile_passes import UnitProductLoops

POLICY_FORMAT = "rodlab-sac-policy/1"


#: modules whose classes SB3 checkpoints written before the learning package existed name (their policy class and
#: activation were pickled as ``policies.sac.*``); ``legacy_module_names`` lets such a checkpoint load
LEGACY_MODULES = {"policies.sac": "policies.learning.sac", "policies.crossq": "policies.learning.crossq"}


@contextlib.contextmanager
def legacy_module_names():
    """While loading an SB3 checkpoint: the modules of ``LEGACY_MODULES`` importable under their old names, so the
    classes a checkpoint of an older rodlab pickled by name are found. Only names that are not already importable
    are added, and they are removed again afterwards."""
    added = []
    for old, new in LEGACY_MODULES.items():
        if old not in sys.modules:
            sys.modules[old] = importlib.import_module(new)
            added.append(old)
    try:
        yield
    finally:
        for old in added:
            sys.modules.pop(old, None)


class PolicyLoadError(Exception):
    """A policy file could not be used (missing, corrupt, or made for a different task/shape)."""


# --------------------------------------------------------------------------------------- networks
class InplaceReLU(nn.ReLU):
    """ReLU applied in place (saves one 1024x256 allocation per layer; safe after LayerNorm)."""

    def __init__(self) -> None:
        super().__init__(inplace=True)


class Float32Linear(nn.Linear):
    """``nn.Linear`` computed in float32 even inside a bfloat16 autocast region (same parameters and state_dict
    keys as ``nn.Linear``; without autocast it is ``nn.Linear``)."""

    def forward(self, x: th.Tensor) -> th.Tensor:
        with th.autocast(x.device.type, enabled=False):
            return F.linear(x.float(), self.weight, self.bias)


class Float32LayerNorm(nn.LayerNorm):
    """``nn.LayerNorm`` computed in float32 even inside a bfloat16 autocast region (CPU autocast would run it in
    bfloat16; its backward subtracts means and loses the small gradients there)."""

    def forward(self, x: th.Tensor) -> th.Tensor:
        with th.autocast(x.device.type, enabled=False):
            return F.layer_norm(x.float(), self.normalized_shape, self.weight, self.bias, self.eps)


_FLOAT32_CLASSES = {nn.Linear: Float32Linear, nn.LayerNorm: Float32LayerNorm}
_PLAIN_CLASSES = {v: k for k, v in _FLOAT32_CLASSES.items()}

#: where bfloat16 updates use bfloat16: ``float32_io`` keeps the input/output layers and LayerNorms in float32 (only the
#: hidden products in bfloat16), ``all`` runs every layer in bfloat16 (docs/training.md, "bfloat16 updates")
BF16_LAYOUTS = ("float32_io", "all")


def _keep_float32(layer: nn.Module) -> nn.Module:
    """Make an existing ``nn.Linear`` / ``nn.LayerNorm`` its float32 variant in place (no new parameters, so no
    random numbers are drawn and a seed's initialisation is unchanged)."""
    cls = _FLOAT32_CLASSES.get(type(layer))
    if cls is None:
        raise TypeError(f"expected nn.Linear or nn.LayerNorm, found {type(layer).__name__}")
    layer.__class__ = cls
    layer._bf16_guarded = True  # remembered by set_bf16_layout (a plain attribute: not in the state_dict)
    return layer


def set_bf16_layout(policy: nn.Module, layout: str) -> None:
    """Switch the guarded layers of ``policy`` between their float32 variants (``float32_io``) and plain layers
    that autocast runs in bfloat16 (``all``), in place. Parameters, state_dict and seeds are unchanged; without
    autocast both layouts compute the same float32 network."""
    if layout not in BF16_LAYOUTS:
        raise ValueError(f"bf16 layout must be one of {', '.join(BF16_LAYOUTS)}, got {layout!r}")
    for m in policy.modules():
        if not getattr(m, "_bf16_guarded", False):
            continue
        if layout == "all" and type(m) in _PLAIN_CLASSES:
            m.__class__ = _PLAIN_CLASSES[type(m)]
        elif layout == "float32_io" and type(m) in _FLOAT32_CLASSES:
            m.__class__ = _FLOAT32_CLASSES[type(m)]


def _bf16_guard(mlp: nn.Sequential, *, output_layer: bool) -> None:
    """Keep in float32 what bfloat16 (8-bit mantissa) would spoil in an MLP: the input layer (observations and
    actions rounded to bfloat16 shift Q by ~0.05 and turn dQ/da by ~20 %), the LayerNorms and the output layer
    (a Q of 100 in bfloat16 is a multiple of 0.5). Only the hidden 256x256 products, most of the work, run in
    bfloat16 in bfloat16 training."""
    linears = [m for m in mlp if isinstance(m, nn.Linear)]
    _keep_float32(linears[0])
    if output_layer:
        _keep_float32(linears[-1])
    for m in mlp:
        if isinstance(m, nn.LayerNorm):
            _keep_float32(m)


class LayerNormSACPolicy(SACPolicy):
    """SB3 ``SACPolicy`` whose actor trunk and critics use Linear -> LayerNorm -> ReLU blocks.

    Observation: flat Box (obs_dim,) float32. Action: Box (act_dim,) in [-1, 1] (tanh-squashed).
    """

    def __init__(self, *args: Any, head_init_gain: float = 0.3, **kwargs: Any):
        self.head_init_gain = head_init_gain
        super().__init__(*args, **kwargs)

    def make_actor(self, features_extractor=None) -> Actor:
        actor = super().make_actor(features_extractor)
        arch = self.actor_kwargs["net_arch"]
        actor.latent_pi = nn.Sequential(*create_mlp(actor.features_dim, -1, arch, actor.activation_fn,
                                                    post_linear_modules=[nn.LayerNorm]))
        if not actor.use_sde:
            for head in (actor.mu, actor.log_std):
                nn.init.xavier_uniform_(head.weight, gain=self.head_init_gain)
                nn.init.zeros_(head.bias)
                _keep_float32(head)
        _bf16_guard(actor.latent_pi, output_layer=False)
        return actor.to(self.device)

    def make_critic(self, features_extractor=None):
        critic = super().make_critic(features_extractor)
        arch = self.critic_kwargs["net_arch"]
        act_dim = int(np.prod(self.action_space.shape))
        in_dim = int(critic.features_extractor.features_dim) + act_dim
        critic.q_networks = []
        for idx in range(critic.n_critics):
            q_net = nn.Sequential(*create_mlp(in_dim, 1, arch, self.net_args["activation_fn"],
                                              post_linear_modules=[nn.LayerNorm]))
            _bf16_guard(q_net, output_layer=True)
            critic.add_module(f"qf{idx}", q_net)  # replaces the plain MLP registered by SB3
            critic.q_networks.append(q_net)
        return critic.to(self.device)

    def _get_constructor_parameters(self) -> dict[str, Any]:
        data = super()._get_constructor_parameters()
        data["head_init_gain"] = self.head_init_gain
        return data


# --------------------------------------------------------------------------------------- compiled-update helpers
class _BoundMethod(nn.Module):
    """``module.<method>`` as this module's forward, so ``torch.func.functional_call`` can run a method other than
    ``forward`` with other parameters (their names prefixed ``module.``)."""

    def __init__(self, module: nn.Module, method: str):
        super().__init__()
        self.module = module
        self.method = method

    def forward(self, *args: Any) -> Any:
        return getattr(self.module, self.method)(*args)


@contextlib.contextmanager
def _frozen(params):
    """Inside the block the parameters of ``params`` that required grad do not; afterwards (also after an error)
    they do again."""
    changed = [p for p in params if p.requires_grad]
    for p in changed:
        p.requires_grad_(False)
    try:
        yield
    finally:
        for p in changed:
            p.requires_grad_(True)


def _adam_state(opt: th.optim.Optimizer) -> None:
    """Check that ``opt`` is the Adam that ``_adam_`` writes out and create its per-parameter state as
    ``torch.optim.Adam`` does at its first step (float32 step counter, zero moments)."""
    if type(opt) is not th.optim.Adam or len(opt.param_groups) != 1:
        raise ValueError(f"compiled updates need one torch.optim.Adam parameter group, found {type(opt).__name__} "
                         f"with {len(opt.param_groups)} group(s)")
    group = opt.param_groups[0]
    unsupported = {k: group.get(k) for k in ("weight_decay", "amsgrad", "maximize", "differentiable")
                   if group.get(k)}
    if unsupported:
        raise ValueError(f"compiled updates write out plain Adam; this optimizer sets {unsupported}")
    for p in group["params"]:
        state = opt.state[p]
        if not state:
            state["step"] = th.zeros((), dtype=th.float32, device=p.device)
            state["exp_avg"] = th.zeros_like(p, memory_format=th.preserve_format)
            state["exp_avg_sq"] = th.zeros_like(p, memory_format=th.preserve_format)


def _adam_(opt: th.optim.Optimizer, grads: dict[str, th.Tensor], params: dict[str, th.Tensor],
           lr: th.Tensor) -> None:
    """One ``torch.optim.Adam`` step (no weight decay, no AMSGrad) of ``params`` with ``grads`` (same keys), in place
    on the optimizer's own state, so the optimizer, its checkpoints and an eager resume see the usual state:
    m <- b1 m + (1 - b1) g, v <- b2 v + (1 - b2) g^2, p <- p - lr/(1 - b1^t) m / (sqrt(v / (1 - b2^t)) + eps)."""
    group = opt.param_groups[0]
    beta1, beta2 = group["betas"]
    eps = group["eps"]
    for name, p in params.items():
        g = grads[name]
        state = opt.state[p]
        step, m, v = state["step"], state["exp_avg"], state["exp_avg_sq"]
        step.add_(1)
        m.lerp_(g, 1 - beta1)
        v.mul_(beta2).addcmul_(g, g, value=1 - beta2)
        step_size = lr / (1 - beta1 ** step)
        denom = (v.sqrt() / (1 - beta2 ** step).sqrt()).add_(eps)
        p.sub_(step_size * m / denom)


# --------------------------------------------------------------------------------------- algorithm
class RodSAC(SAC):
    """SB3 SAC with the reference's critic target and target-update cadence (see module docstring).

    Extra keyword arguments: ``entropy_in_target`` (default False), ``adam_eps`` (default 1e-7).
    ``target_update_interval`` counts gradient updates over the whole run.
    """

    def __init__(self, *args: Any, entropy_in_target: bool = False, adam_eps: float = 1e-7, **kwargs: Any):
        self.entropy_in_target = entropy_in_target
        self.adam_eps = adam_eps
        self.last_update_time = 0.0
        self.bf16_updates = False  # the gradient updates under bfloat16 autocast (policies/learning/training.py Args.bf16)
        self.compile_updates = False  # each update one torch.compile-d function (Args.compile_updates)
        self._compiled_fns = None
        super().__init__(*args, **kwargs)

    def set_update_settings(self, *, bf16: bool, bf16_layout: str, compile_updates: bool) -> None:
        """How the gradient updates run: under bfloat16 autocast with ``bf16_layout`` (``set_bf16_layout``), as
        compiled functions. Used by ``rodlab train`` (from its ``Args``) and ``rodlab bench train`` (from its
        ``SpeedSettings``)."""
        self.bf16_updates = bool(bf16)
        self.compile_updates = bool(compile_updates)
        set_bf16_layout(self.policy, bf16_layout)

    def _setup_model(self) -> None:
        super()._setup_model()
        if self.ent_coef_optimizer is not None:  # same eps as the other optimizers
            self.ent_coef_optimizer = th.optim.Adam([self.log_ent_coef], lr=self.lr_schedule(1), eps=self.adam_eps)

    @th.no_grad()
    def td_target(self, data, alpha: th.Tensor, noise: th.Tensor | None = None) -> th.Tensor:
        """TD target (batch, 1): r + gamma (1 - done) min_i Q'_i(s', a'), a' ~ pi(s');
        minus alpha * log pi(a'|s') inside the bracket only when ``entropy_in_target``. ``noise``: the standard
        normal draw behind a' (drawn here when None)."""
        next_a, next_logp = self._sample_policy(data.next_observations, noise)
        next_q = th.min(th.cat(self.critic_target(data.next_observations, next_a), dim=1), dim=1, keepdim=True).values
        if self.entropy_in_target:
            next_q = next_q - alpha * next_logp
        discounts = data.discounts if data.discounts is not None else self.gamma
        return data.rewards + (1.0 - data.dones) * discounts * next_q

    def train(self, gradient_steps: int, batch_size: int = 64) -> None:
        import time

        t0 = time.perf_counter()
        self.policy.set_training_mode(True)
        self._update_learning_rate(self._optimizers())

        stats: dict[str, list[float]] = {key: [] for key in self._STAT_KEYS}
        self._updates(gradient_steps, batch_size, stats)
        self.logger.record("train/n_updates", self._n_updates, exclude="tensorboard")
        for key, vals in stats.items():
            if vals:
                self.logger.record(f"train/{key}", float(np.mean(vals)))
        self.last_update_time = time.perf_counter() - t0

    def _amp(self):
        """The autocast region of one forward pass (bfloat16 when ``bf16_updates``). Each forward pass gets its own
        region, closed before its optimizer step: autocast caches the bfloat16 copies of the weights until the
        region ends, so a region spanning several steps would run the later forward passes with stale weights."""
        return th.autocast(self.device.type, dtype=th.bfloat16, enabled=bool(getattr(self, "bf16_updates", False)))

    # The pieces of one update. ``_updates`` runs them with autograd and the torch.optim steps (the default), or,
    # with ``compile_updates``, inside one compiled function per update (``_fused_update``): one source for both.
    def _sample_policy(self, obs: th.Tensor, noise: th.Tensor | None = None,
                       actor_params: dict[str, th.Tensor] | None = None) -> tuple[th.Tensor, th.Tensor]:
        """a ~ pi(s) (reparameterised, differentiable) and log pi(a|s) as float32 (batch, 1): SB3's squashed
        Gaussian (``actor.action_log_prob``) written out without its side effect (the distribution object keeps the
        last sample), so it can run inside a ``torch.func`` transform. ``noise``: the standard normal draw (drawn
        here, as SB3 draws it, when None); ``actor_params``: parameters to use instead of the actor's own."""
        with self._amp():
            if actor_params is None:
                mean, log_std, _ = self.actor.get_action_dist_params(obs)
            else:
                mean, log_std, _ = functional_call(self._compiled_fns["actor_dist_params"],
                                                   {f"module.{k}": v for k, v in actor_params.items()}, (obs,))
            std = th.ones_like(mean) * log_std.exp()
            dist = th.distributions.Normal(mean, std, validate_args=False if noise is not None else None)
            gaussian = dist.rsample() if noise is None else mean + noise.to(mean.dtype) * std
            actions = th.tanh(gaussian)
            log_prob = dist.log_prob(gaussian).sum(dim=1) - th.log(1 - actions ** 2
                                                                   + self.actor.action_dist.epsilon).sum(dim=1)
        return actions, log_prob.float().reshape(-1, 1)

    def _alpha_loss(self, log_ent_coef: th.Tensor, log_prob: th.Tensor) -> th.Tensor:
        """-mean(log alpha * (log pi(a|s) + target entropy)), log pi held fixed."""
        return -(log_ent_coef * (log_prob + self.target_entropy).detach()).mean()

    def _critic_loss(self, data, alpha: th.Tensor, noise: th.Tensor | None = None,
                     critic_params: dict[str, th.Tensor] | None = None) -> tuple[th.Tensor, th.Tensor]:
        """0.5 * sum_i MSE(Q_i(s, a), TD target) and the batch mean of Q_1 (a statistic). ``noise``: the draw
        behind the TD target's a'; ``critic_params``: parameters to use instead of the critic's own."""
        with self._amp():
            target_q = self.td_target(data, alpha, noise)
            if critic_params is None:
                current_q = self.critic(data.observations, data.actions)
            else:
                current_q = functional_call(self.critic, critic_params, (data.observations, data.actions))
            loss = 0.5 * sum(F.mse_loss(q.float(), target_q.float()) for q in current_q)
        return loss, current_q[0].float().mean()

    def _actor_loss(self, obs: th.Tensor, actions_pi: th.Tensor, log_prob: th.Tensor,
                    alpha: th.Tensor) -> th.Tensor:
        """mean(alpha * log pi(a|s) - min_i Q_i(s, a)), a ~ pi(s)."""
        with self._amp():
            q_pi = th.min(th.cat(self.critic(obs, actions_pi), dim=1), dim=1, keepdim=True).values
        return (alpha * log_prob - q_pi.float()).mean()

    def _excluded_save_params(self) -> list[str]:
        return [*super()._excluded_save_params(), "_compiled_fns"]

    def _updates(self, gradient_steps: int, batch_size: int, stats: dict[str, list[float]]) -> None:
        """``gradient_steps`` SAC updates (temperature, critics, actor, target), their statistics into ``stats``."""
        if getattr(self, "compile_updates", False):
            self._compiled_updates(gradient_steps, batch_size, stats)
            return
        for _ in range(gradient_steps):
            data = self._sample_replay(batch_size)
            actions_pi, log_prob = self._sample_policy(data.observations)

            # alpha (temperature) step
            if self.ent_coef_optimizer is not None:
                alpha = th.exp(self.log_ent_coef.detach())
                alpha_loss = self._alpha_loss(self.log_ent_coef, log_prob)
                self.ent_coef_optimizer.zero_grad()
                alpha_loss.backward()
                self.ent_coef_optimizer.step()
                stats["ent_coef_loss"].append(alpha_loss.item())
            else:
                alpha = self.ent_coef_tensor
            stats["ent_coef"].append(alpha.item())

            # critic step
            critic_loss, q_mean = self._critic_loss(data, alpha)
            self.critic.optimizer.zero_grad()
            critic_loss.backward()
            self.critic.optimizer.step()
            stats["critic_loss"].append(critic_loss.item())
            stats["q_mean"].append(q_mean.item())

            # actor step (critic weights frozen meanwhile: their gradients would be discarded anyway)
            with _frozen(self.critic.parameters()):
                actor_loss = self._actor_loss(data.observations, actions_pi, log_prob, alpha)
                self.actor.optimizer.zero_grad()
                actor_loss.backward()
                self.actor.optimizer.step()
            stats["actor_loss"].append(actor_loss.item())
            stats["log_prob"].append(log_prob.mean().item())
            self._target_update()

    def _sample_replay(self, batch_size: int):
        """``replay_buffer.sample(batch_size)``: the same random draws and the same batch as SB3's sampling, in
        half its time (one gather per field from the flattened buffer, no second copy into torch). Buffers SB3
        samples otherwise (shared observation storage, normalisation by a VecNormalize) go to SB3's own method."""
        rb = self.replay_buffer
        if (type(rb) is not ReplayBuffer or rb.optimize_memory_usage or self._vec_normalize_env is not None
                or rb.device.type != "cpu"):
            return rb.sample(batch_size, env=self._vec_normalize_env)
        rows = np.random.randint(0, rb.buffer_size if rb.full else rb.pos, size=batch_size)
        envs = np.random.randint(0, high=rb.n_envs, size=(batch_size,))  # SB3's draws, in SB3's order
        flat = rows * rb.n_envs + envs
        n = rb.buffer_size * rb.n_envs

        def take(array: np.ndarray) -> np.ndarray:
            return np.take(array.reshape(n, -1), flat, axis=0)

        dones = take(rb.dones) * (1 - take(rb.timeouts))
        return ReplayBufferSamples(*(th.from_numpy(a) for a in (
            take(rb.observations), take(rb.actions), take(rb.next_observations), dones, take(rb.rewards))))

    def _target_update(self) -> None:
        """Count the update; every ``target_update_interval`` updates, counted over the whole run, soft-update the
        target critics."""
        self._n_updates += 1
        if self._n_updates % self.target_update_interval == 0:
            polyak_update(self.critic.parameters(), self.critic_target.parameters(), self.tau)
            polyak_update(self.batch_norm_stats, self.batch_norm_stats_target, 1.0)

    # ----------------------------------------------------------------------------- compiled updates
    _STAT_KEYS = ("actor_loss", "critic_loss", "ent_coef", "ent_coef_loss", "log_prob", "q_mean")

    def _compiled_updates(self, gradient_steps: int, batch_size: int, stats: dict[str, list[float]]) -> None:
        """The updates of ``_updates`` with ``compile_updates``: each one a single call of the compiled
        ``_fused_update`` (built once, not saved), the target update eager (docs/training.md, "Compiled updates")."""
        if getattr(self, "_compiled_fns", None) is None:
            for opt in self._optimizers():
                _adam_state(opt)  # created eagerly, as torch.optim would at its first step
            for name, module in (("actor", self.actor), ("critic", self.critic)):
                if {id(p) for p in module.parameters()} != {id(p) for p in module.optimizer.param_groups[0]["params"]}:
                    raise ValueError(f"compiled updates step every {name} parameter; its optimizer holds others")

            options = {"post_grad_custom_post_pass": UnitProductLoops()}
            self._compiled_fns = {"actor_dist_params": _BoundMethod(self.actor, "get_action_dist_params"),
                                  "update": th.compile(self._fused_update, dynamic=False, options=options)}
        fused = self._compiled_fns["update"]
        lrs = [th.tensor(opt.param_groups[0]["lr"], dtype=th.float32, device=self.device)
               for opt in self._optimizers()]
        keys = [k for k in self._STAT_KEYS if k != "ent_coef_loss" or self.ent_coef_optimizer is not None]
        # The parameters stop requiring grad meanwhile (the gradients come from torch.func): the compiled code then
        # writes the Adam steps straight into them instead of copying each updated tensor back afterwards.
        with _frozen(p for opt in self._optimizers() for p in opt.param_groups[0]["params"]):
            for _ in range(gradient_steps):
                data = self._sample_replay(batch_size)
                # The policy's standard normal draws come from torch's generator, outside the compiled function, in
                # the order of the eager update: a ~ pi(s) first, then a' ~ pi(s') of the TD target. (Drawn inside,
                # they would be inductor's per-element generator, a scalar loop several times slower.)
                noise = th.randn(batch_size, *self.action_space.shape, device=self.device)
                next_noise = th.randn_like(noise)
                values = dict(zip(self._STAT_KEYS, fused(data, noise, next_noise, *lrs).tolist()))
                for key in keys:
                    stats[key].append(values[key])
                self._target_update()

    def _optimizers(self) -> list[th.optim.Optimizer]:
        """actor, critic and (with a learned temperature) entropy-coefficient optimizers."""
        return [self.actor.optimizer, self.critic.optimizer,
                *([self.ent_coef_optimizer] if self.ent_coef_optimizer is not None else [])]

    @th.no_grad()
    def _fused_update(self, data, noise: th.Tensor, next_noise: th.Tensor, lr_actor: th.Tensor,
                      lr_critic: th.Tensor, lr_ent_coef: th.Tensor | None = None) -> th.Tensor:
        """One SAC update as one function for ``torch.compile``: the same losses as ``_updates``, their gradients
        by ``torch.func.grad_and_value`` and the Adam steps written out (``_adam_``) on the optimizers' own
        state, so the whole update is one graph with no autograd engine or optimizer code in between. Order and
        values as in ``_updates``: alpha before its step in every loss, the actor loss on the critic after its
        step. ``noise`` and ``next_noise`` (batch, action dims): the standard normal draws behind a ~ pi(s) and
        the TD target's a' ~ pi(s'). Returns the statistics in ``_STAT_KEYS`` order."""
        obs = data.observations
        learn_alpha = self.ent_coef_optimizer is not None
        alpha = th.exp(self.log_ent_coef.detach()) if learn_alpha else self.ent_coef_tensor

        # critic step
        critic_params = dict(self.critic.named_parameters())
        grads, (critic_loss, q_mean) = grad_and_value(
            lambda p: self._critic_loss(data, alpha, next_noise, p), has_aux=True)(
                {k: v.detach() for k, v in critic_params.items()})
        _adam_(self.critic.optimizer, grads, critic_params, lr_critic)

        # actor step on the stepped critic (its weights are constants here)
        def actor_loss(p):
            actions_pi, log_prob = self._sample_policy(obs, noise, p)
            return self._actor_loss(obs, actions_pi, log_prob, alpha), log_prob.detach()

        actor_params = dict(self.actor.named_parameters())
        grads, (actor_loss_value, log_prob) = grad_and_value(actor_loss, has_aux=True)(
            {k: v.detach() for k, v in actor_params.items()})
        _adam_(self.actor.optimizer, grads, actor_params, lr_actor)

        # alpha (temperature) step
        if learn_alpha:
            grad, alpha_loss = grad_and_value(lambda le: self._alpha_loss(le, log_prob))(self.log_ent_coef.detach())
            _adam_(self.ent_coef_optimizer, {"": grad}, {"": self.log_ent_coef}, lr_ent_coef)
        else:
            alpha_loss = th.zeros((), device=obs.device)
        return th.stack([actor_loss_value, critic_loss, alpha.reshape(()), alpha_loss, log_prob.mean(), q_mean])


# --------------------------------------------------------------------------------------- policy files
def save_policy(model: SAC, path: str | os.PathLike, *, task: str | None, extra: dict | None = None) -> Path:
    """Write the policy only (actor + critics, no optimizer/replay buffer) to ``path`` (.zip), atomically.

    ``task``: task id stored in ``meta.json`` so ``rodlab eval`` needs no ``--task``.
    ``extra``: JSON-serialisable dict stored under ``meta["extra"]`` (e.g. training summary).
    """
    pol = model.policy
    sd = {k: v for k, v in pol.state_dict().items() if not k.startswith("critic_target.")}
    buf = io.BytesIO()
    th.save(sd, buf)
    meta = {
        "format": POLICY_FORMAT,
        "task": task,
        "obs_shape": list(pol.observation_space.shape),
        "obs_low": np.asarray(pol.observation_space.low, dtype=np.float64).clip(-1e30, 1e30).tolist(),
        "obs_high": np.asarray(pol.observation_space.high, dtype=np.float64).clip(-1e30, 1e30).tolist(),
        "action_low": np.asarray(pol.action_space.low, dtype=np.float64).tolist(),
        "action_high": np.asarray(pol.action_space.high, dtype=np.float64).tolist(),
        "net_arch": list(pol.actor_kwargs["net_arch"]),
        "n_critics": int(pol.critic_kwargs["n_critics"]),
        "head_init_gain": float(getattr(pol, "head_init_gain", 0.3)),
        "algorithm": "crossq" if hasattr(pol, "batch_norm_params") else "sac",
        "extra": extra or {},
    }
    if meta["algorithm"] == "crossq":  # policies/learning/crossq.py: critics' layout and batch renormalisation
        meta["critic_net_arch"] = list(pol.critic_kwargs["net_arch"])
        meta.update(pol.batch_norm_params)
    zbuf = io.BytesIO()
    with zipfile.ZipFile(zbuf, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("meta.json", json.dumps(meta, indent=1))
        zf.writestr("policy.pt", buf.getvalue())
    path = Path(path)
    write_bytes(path, zbuf.getvalue())
    return path


def read_policy_meta(path: str | os.PathLike) -> dict:
    """Return ``meta.json`` of a policy zip (raises PolicyLoadError if absent/corrupt). Reads JSON only:
    nothing in the file is unpickled. A full SB3 checkpoint gives ``{"format": "sb3", "task": ...}``."""
    path = Path(path)
    if not path.is_file():
        raise PolicyLoadError(f"policy file not found: {path}")
    try:
        with zipfile.ZipFile(path) as zf:
            names = set(zf.namelist())
            if "meta.json" in names:
                meta = json.loads(zf.read("meta.json"))
                if not isinstance(meta, dict):
                    raise PolicyLoadError(f"policy file {path}: meta.json must be a JSON object "
                                          f"(found a JSON {type(meta).__name__})")
                return meta
            if "data" in names:  # a full SB3 checkpoint (model.zip of a run directory)
                return {"format": "sb3", "task": _sidecar_task(path)}
    except (zipfile.BadZipFile, OSError, json.JSONDecodeError, UnicodeDecodeError, RecursionError) as exc:
        raise PolicyLoadError(f"policy file {path} is not a readable policy zip ({type(exc).__name__})") from None
    raise PolicyLoadError(f"policy file {path} holds neither meta.json (rodlab policy) nor data (SB3 model)")


def _sidecar_task(path: Path) -> str | None:
    """Task id of an SB3 checkpoint: <name>.json next to it, or the run's config.json (one or two levels up)."""
    for cand in (path.with_suffix(".json"), path.parent / "config.json", path.parent.parent / "config.json"):
        if cand.is_file():
            try:
                data = json.loads(cand.read_text())
            except (OSError, json.JSONDecodeError):
                continue
            task = data.get("task") or (data.get("args") or {}).get("task")
            if task:
                return task
    return None


def _load_weights(zf: zipfile.ZipFile, name: str, path: Path, device: str) -> dict:
    """``torch.load(weights_only=True)`` of one zip entry: tensors and plain containers only, never a
    pickled object. Anything else is a PolicyLoadError (the file is not a rodlab weights file)."""
    try:
        sd = th.load(io.BytesIO(zf.read(name)), map_location=device, weights_only=True)
    except KeyError:
        raise PolicyLoadError(f"policy file {path} has no {name}") from None
    except Exception:  # noqa: BLE001 - pickle.UnpicklingError (refused object), EOFError, RuntimeError, ...
        raise PolicyLoadError(f"policy file {path}: {name} is not a plain tensor file (it holds pickled "
                              "objects or is corrupt); rodlab loads weights only and never unpickles "
                              "objects") from None
    if not isinstance(sd, dict) or not all(isinstance(k, str) and isinstance(v, th.Tensor) for k, v in sd.items()):
        raise PolicyLoadError(f"policy file {path}: {name} is not a dict of named tensors")
    return sd


def sb3_policy_weights(path: str | os.PathLike, template: SACPolicy) -> tuple[SACPolicy, float | None]:
    """Weights of a full SB3 checkpoint copied into a copy of ``template`` -> (policy, log entropy coefficient).

    Reads only ``policy.pth`` and ``pytorch_variables.pth`` with ``weights_only=True``; the pickled ``data``
    entry (spaces, schedules) is never read, so the file's spaces are the template's. Raises PolicyLoadError
    when a parameter is missing or has another shape."""
    import copy

    path = Path(path)
    try:
        with zipfile.ZipFile(path) as zf:
            sd = _load_weights(zf, "policy.pth", path, "cpu")
            extra = _load_weights(zf, "pytorch_variables.pth", path, "cpu") if "pytorch_variables.pth" in \
                zf.namelist() else {}
    except (zipfile.BadZipFile, OSError) as exc:
        raise PolicyLoadError(f"policy file {path} is not a readable policy zip ({type(exc).__name__})") from None
    own = template.state_dict()
    bad = sorted(k for k in set(own) | set(sd) if k not in sd or k not in own or sd[k].shape != own[k].shape)
    if bad:
        raise PolicyLoadError(f"the network in {path} does not match this run's; differing parameters: {bad[:4]}")
    pol = copy.deepcopy(template)
    pol.load_state_dict(sd)
    v = extra.get("log_ent_coef")
    return pol, (float(v.detach().reshape(-1)[0]) if v is not None else None)


def load_policy(path: str | os.PathLike, *, device: str = "cpu", trust_pickle: bool = False
                ) -> tuple[SACPolicy, dict]:
    """Load a policy file -> (SB3 ``SACPolicy`` in eval mode, meta dict).

    The policy-only zip written by ``save_policy`` is read as JSON + ``torch.load(weights_only=True)``:
    nothing is unpickled. A full SB3 checkpoint (``checkpoint/model.zip``) holds cloudpickled objects, so
    loading it can run code from the file: it is refused unless ``trust_pickle=True`` (``rodlab eval
    --trust-pickle``), which prints a warning. Raises ``PolicyLoadError`` on a missing, corrupt, untrusted
    or incompatible file.
    """
    path = Path(path)
    meta = read_policy_meta(path)
    try:
        if meta.get("format") == "sb3":
            if not trust_pickle:
                raise PolicyLoadError(
                    f"{path} is a full stable-baselines3 checkpoint: loading it unpickles objects stored in the "
                    "file, which can run any code. rodlab loads its own policy format (runs/*/policy.zip) by "
                    "default; pass --trust-pickle only for a file you made yourself or fully trust")
            print(f"warning: {path}: unpickling a stable-baselines3 checkpoint (--trust-pickle); this runs code "
                  "stored in the file", file=sys.stderr)
            with legacy_module_names():
                model = RodSAC.load(path, device=device)
            pol = model.policy
            meta["obs_shape"] = list(pol.observation_space.shape)
            meta["action_low"] = pol.action_space.low.tolist()
            meta["action_high"] = pol.action_space.high.tolist()
        elif meta.get("format") == POLICY_FORMAT:
            obs_space = spaces.Box(np.asarray(meta["obs_low"], np.float32), np.asarray(meta["obs_high"], np.float32),
                                   dtype=np.float32)
            act_space = spaces.Box(np.asarray(meta["action_low"], np.float32),
                                   np.asarray(meta["action_high"], np.float32), dtype=np.float32)
            algorithm = meta.get("algorithm", "sac")
            if algorithm == "crossq":
                from policies.learning.crossq import crossq_policy

                pol = crossq_policy(obs_space, act_space, meta)
            elif algorithm == "sac":
                pol = LayerNormSACPolicy(obs_space, act_space, lambda _: 1e-3,
                                         net_arch=[int(n) for n in meta["net_arch"]], n_critics=int(meta["n_critics"]),
                                         head_init_gain=float(meta.get("head_init_gain", 0.3)))
            else:
                raise PolicyLoadError(f"policy file {path}: unknown algorithm {str(algorithm)[:40]!r} (sac, crossq)")
            with zipfile.ZipFile(path) as zf:
                sd = _load_weights(zf, "policy.pt", path, device)
            missing, unexpected = pol.load_state_dict(sd, strict=False)
            missing = [k for k in missing if not k.startswith("critic_target.")]
            if missing or unexpected:
                raise PolicyLoadError(f"policy file {path}: weights do not match the network "
                                      f"(missing {missing[:3]}, unexpected {unexpected[:3]})")
            if getattr(pol, "critic_target", None) is not None:
                pol.critic_target.load_state_dict(pol.critic.state_dict())
        else:
            raise PolicyLoadError(f"policy file {path}: unknown format {str(meta.get('format'))[:40]!r}")
    except PolicyLoadError:
        raise
    except (KeyError, ValueError, TypeError, AttributeError, RuntimeError, zipfile.BadZipFile, EOFError,
            OSError) as exc:
        raise PolicyLoadError(f"policy file {path} is corrupt or incompatible ({type(exc).__name__}: "
                              f"{str(exc)[:200]})") from None
    pol.set_training_mode(False)
    return pol.to(device), meta
