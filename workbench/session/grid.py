"""Many envs at once: N parallel envs of one task (one batched task core, ``policies.tasks``) under one policy,
laid out on a grid of cells for the page (``workbench.view.grid`` draws them, ``workbench.panels.grid`` runs them).

Each :meth:`GridSession.step` is one control step of every env (``BatchedTask.step`` with the policy's actions for
the whole batch); an env whose episode ended is reset on its own (its new target and obstacles included), the
others go on. No viser here.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from sim.geometry import quat_z_to
from workbench.session.obstacles import ObstacleEdit, edits_from_spec
from workbench.session.policy_session import act, load_for
from workbench.session.pull import Pull, control_force, grab, held_point, point

MAX_ENVS = 36


def cell_offsets(n: int, spacing: float, origin=(0.0, 0.0, 0.0)) -> np.ndarray:
    """(n, 3) cell origins [m]: rows of ⌈√n⌉ cells along +x, rows stacked along +y, ``spacing`` apart."""
    cols = max(1, math.ceil(math.sqrt(n)))
    k = np.arange(n)
    return np.asarray(origin, np.float64) + np.stack([(k % cols) * spacing, (k // cols) * spacing,
                                                      np.zeros(n)], 1)


class GridSession:
    """``n`` envs of ``task`` driven by ``policy`` (a zip path, or "zero" / "random").

    Attributes: ``core`` (the batched task), ``offsets`` (n, 3) cell origins [m], ``returns``/``last_reward``/
    ``tip_error`` (n,) per env, ``episodes`` (n,) finished episodes per env, ``obstacles_version`` (bumped when any
    env's obstacles were re-placed). ``origin``: where cell 0 is (default one cell spacing along +y, behind the live
    rod at the world origin); ``centred``: the cells centred on the world origin instead (the page hides the live
    scene while the grid is drawn, so the grid takes its place on the floor grid).
    """

    def __init__(self, task: str, policy: str | Path = "zero", n: int = 16, *, seed: int = 0,
                 deterministic: bool = True, origin=None, centred: bool = False):
        from policies.tasks import TASK_SPECS, TASKS, gym_task_id

        if not (isinstance(n, (int, np.integer)) and 1 <= int(n) <= MAX_ENVS):
            raise ValueError(f"number of envs must be an integer in [1, {MAX_ENVS}] (got {n!r})")
        self.task_id = gym_task_id(task)
        self.task = next((k for k, v in TASKS.items() if v == self.task_id), self.task_id)
        _env_cls, core_cls, cfg_fn = TASK_SPECS[self.task_id].load()
        self.n = int(n)
        self.core = core_cls(cfg_fn(), envs=self.n, seed=seed)
        self.policy = load_for(policy, self.core, self.task)
        self.name = Path(policy).stem if str(policy) not in ("zero", "random") else str(policy)
        self.deterministic = deterministic
        self._rng = np.random.default_rng(seed)
        x0 = np.asarray(self.core.state.node_pos[0], np.float64)
        self.rod_length = float(np.linalg.norm(np.diff(x0, axis=0), axis=1).sum())
        self.rod_radius = float(self.core.model.radius_max)
        self.n_nodes = int(x0.shape[0])
        self.spacing = 2.0 * max(self.rod_length, 0.25)
        # default: the grid starts one cell behind the live rod (at the origin), which stays where it was
        self.offsets = cell_offsets(self.n, self.spacing, (0.0, self.spacing, 0.0) if origin is None else origin)
        if centred:
            mid = 0.5 * (self.offsets.min(axis=0) + self.offsets.max(axis=0))
            self.offsets = self.offsets - np.array([mid[0], mid[1], 0.0])
        spec = getattr(self.core, "scene_spec", None) or getattr(self.core.model, "spec", None)
        self._static = [] if getattr(self.core, "fences", None) is not None else edits_from_spec(spec)
        self.obs = self.core.reset()
        self.returns = np.zeros(self.n)
        self.last_reward = np.zeros(self.n)
        self.tip_error = np.full(self.n, np.nan)
        self.episodes = np.zeros(self.n, dtype=np.int64)
        self.steps = 0
        self.obstacles_version = 0
        self.pull: Pull | None = None  # a hand on one env's rod (workbench.session.pull), in that env's own coordinates
        self.pull_env = -1

    @property
    def control_dt(self) -> float:
        """Simulated seconds per control step."""
        return float(self.core.model.dt) * int(self.core.config.substeps)

    # ------------------------------------------------------------------ the hand
    def grab(self, env: int, at) -> int:
        """Grab env ``env``'s rod at the node nearest ``at`` (3,) [m, page coordinates: the env's cell]; from the next
        control step a spring pulls it toward the hand (:meth:`move_hand`); the policy feels it. Returns the node."""
        if not (isinstance(env, (int, np.integer)) and 0 <= int(env) < self.n):
            raise ValueError(f"env must be an index in [0, {self.n}), got {env!r}")
        env = int(env)
        x = np.asarray(self.core.state.node_pos[env], np.float64)
        self.pull = grab(x, point(at, "grab point") - self.offsets[env])
        self.pull_env = env
        return self.pull.node

    def move_hand(self, to) -> None:
        """Move the hand to ``to`` (3,) [m, page coordinates] (nothing held: ignored)."""
        p = point(to, "hand position")
        if self.pull is not None:
            self.pull.pointer = p - self.offsets[self.pull_env]

    def release(self) -> None:
        self.pull = None

    def hand(self) -> np.ndarray | None:
        """(2, 3) [m, page coordinates]: where the hand holds the rod and the hand; None when nothing is held."""
        if self.pull is None:
            return None
        x = np.asarray(self.core.state.node_pos[self.pull_env], np.float64)
        return np.stack([held_point(self.pull, x), self.pull.pointer]) + self.offsets[self.pull_env]

    def _apply_hand(self) -> None:
        """The pulled env's node forces for the next control step (held over its sim steps, so the springs are
        scaled to the control step), None for every env when nothing is held."""
        ctrl, pull = self.core.ctrl, self.pull
        if pull is None:
            ctrl.force = None
            return
        ctrl.force = control_force(pull, self.core.state, self.pull_env, self.core.model.node_mass, self.control_dt)

    def step(self) -> None:
        """One control step of every env; finished episodes restart (each env on its own)."""
        a = act(self.policy, self.obs, self.core.action_dim, self._rng, self.deterministic)
        self._apply_hand()
        obs, reward, terminated, truncated, info = self.core.step(a)
        self.last_reward = np.asarray(reward, np.float64)
        self.returns += self.last_reward
        d = info.get("tip_distance")
        if d is not None:
            self.tip_error = np.asarray(d, np.float64).reshape(self.n)
        done = np.asarray(terminated, bool) | np.asarray(truncated, bool)
        if done.any():
            if self.pull is not None and done[self.pull_env]:  # a new episode: the hand lets go
                self.pull = None
            obs = self.core.reset(done)
            self.returns[done] = 0.0
            self.episodes[done] += 1
            if getattr(self.core, "fences", None) is not None:
                self.obstacles_version += 1
        self.obs = obs
        self.steps += 1

    # ------------------------------------------------------------------ what to draw
    def positions(self) -> np.ndarray:
        """(n, N, 3) node positions in the page (each env shifted to its cell) [m]."""
        return np.asarray(self.core.state.node_pos, np.float64) + self.offsets[:, None, :]

    def times(self) -> np.ndarray:
        """(n,) simulated time of each env since its episode began [s] (what a load's window is measured in)."""
        return np.broadcast_to(np.asarray(self.core.state.time, np.float64).reshape(-1), (self.n,)).copy()

    def targets(self) -> np.ndarray | None:
        """(n, 3) targets in the page [m], or None (a task without a target)."""
        from policies.recording import task_target

        pos, _q = task_target(self.core)
        return None if pos is None else np.asarray(pos, np.float64).reshape(self.n, 3) + self.offsets

    def obstacles(self, env: int) -> list[ObstacleEdit]:
        """Obstacles of env ``env`` in its own frame (the task's re-placed fences, or the scene's obstacles)."""
        fences = getattr(self.core, "fences", None)
        if fences is None:
            return self._static

        r = float(self.core.config.fence.radius)
        out = []
        for a, b in np.asarray(fences[env], np.float64):
            out.append(ObstacleEdit(kind="capsule", position=0.5 * (a + b), wxyz=quat_z_to(b - a), radius=r,
                                    length=float(np.linalg.norm(b - a)), name="fence"))
        return out

    def readout(self, env: int) -> str:
        """One env's state as a line of text."""
        e = int(env)
        te = self.tip_error[e]
        return (f"env {e} · step {int(self.core.step_count[e])} · reward {self.last_reward[e]:+.3f} · "
                f"return {self.returns[e]:+.2f} · episodes done {int(self.episodes[e])}"
                + ("" if not np.isfinite(te) else f" · tip error {te:.3f} m"))
