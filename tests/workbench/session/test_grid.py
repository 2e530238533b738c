"""Grid of envs without a page: each env has its own obstacles (3-D Random Obstacles re-places them per env), the
merged obstacle mesh puts every env's obstacles in its own cell, and a finished episode restarts only that env."""
from __future__ import annotations

import numpy as np

from workbench.session.grid import GridSession
from workbench.view.grid import obstacle_mesh


def test_random_obstacles_per_env_in_their_cells():
    s = GridSession("random_obstacles_3d", "zero", 3)
    a, b = s.obstacles(0), s.obstacles(1)
    assert len(a) == len(b) > 0
    assert not np.allclose([o.position for o in a], [o.position for o in b])  # each env its own fences
    v, f = obstacle_mesh(s)
    assert f.max() < len(v)
    # every vertex lies within half a cell of some env's own obstacles' centre region
    centres = np.concatenate([[o.position + s.offsets[e] for o in s.obstacles(e)] for e in range(3)])
    d = np.linalg.norm(v[:, None, :2] - centres[None, :, :2], axis=-1).min(axis=1)
    assert d.max() < 0.5 * s.spacing


def test_finished_episode_restarts_only_that_env():
    s = GridSession("follow_target", "random", 2)
    for _ in range(3):
        s.step()
    s.core.step_count[1] = s.core.config.timeout_steps  # env 1's next step is its last
    s.step()
    assert s.episodes.tolist() == [0, 1]
    assert int(s.core.step_count[0]) == 4 and int(s.core.step_count[1]) == 0
    assert s.returns[1] == 0.0 and s.returns[0] != 0.0
