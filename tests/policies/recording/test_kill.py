"""A recording process killed with SIGKILL never leaves a corrupt file under the final name."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from policies.recording import read_recording
from tests.helpers.paths import REPO

CHILD_MID_EPISODE = r"""
import sys, time, numpy as np
from policies.recording import Recorder, StaticScene
rec = Recorder(sys.argv[1])
rng = np.random.default_rng(0)
rec.begin_episode({"task": "t"}, StaticScene(capsules=np.zeros((1, 2, 3)) + [[0, 0, 0], [0, 0, 1]], capsule_radii=[0.1]))
for k in range(40):
    rec.log_step(control_step=k, sim_time=0.1 * k, node_pos=rng.normal(size=(21, 3)), scalars={"reward": 1.0})
rec.end_episode()                     # one finished episode (part file complete)
rec.begin_episode({"task": "t"})
for k in range(40):
    rec.log_step(control_step=k, sim_time=0.1 * k, node_pos=rng.normal(size=(21, 3)))
print("READY", flush=True)            # mid-episode: killed here
time.sleep(120)
"""

CHILD_LOOP = r"""
import sys, numpy as np
from policies.recording import Recorder
rng = np.random.default_rng(0)
print("READY", flush=True)
while True:                          # rewrite the same file again and again until killed
    with Recorder(sys.argv[1]) as rec:
        for e in range(2):
            rec.begin_episode({"task": "t"}, env=e)
        for k in range(60):
            for e in range(2):
                rec.log_step(env=e, control_step=k, sim_time=0.1 * k, node_pos=rng.normal(size=(21, 3)),
                             m1=rng.normal(size=(20, 3)), m2=rng.normal(size=(20, 3)), scalars={"reward": 1.0})
        for e in range(2):
            rec.end_episode(env=e)
"""


def _spawn(code: str, out: Path) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    p = subprocess.Popen([sys.executable, "-c", code, str(out)], cwd=REPO, env=env, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
    line = p.stdout.readline()
    if "READY" not in line:
        p.kill()
        raise AssertionError(f"child did not start: {line!r} {p.stderr.read()}")
    return p


def test_sigkill_mid_episode_leaves_no_file(tmp_path):
    out = tmp_path / "killed.rrd"
    p = _spawn(CHILD_MID_EPISODE, out)
    os.kill(p.pid, signal.SIGKILL)
    p.wait(timeout=600)
    assert p.returncode == -signal.SIGKILL
    assert not out.exists()
    # only the hidden part folder of the dead process is left (never anything named like the output)
    left = list(tmp_path.iterdir())
    assert left and all(x.name.startswith(".killed.rrd.parts-") for x in left)
    # the next recorder to the same name removes the dead process's leftovers
    from policies.recording import Recorder
    Recorder(out).abort()
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("delay", [0.5, 2.0, 4.0])
def test_sigkill_at_any_time_leaves_no_file_or_a_valid_one(tmp_path, delay, verify):
    out = tmp_path / "loop.rrd"
    p = _spawn(CHILD_LOOP, out)
    time.sleep(delay)
    os.kill(p.pid, signal.SIGKILL)
    p.wait(timeout=600)
    if out.exists():                     # a finished earlier round: must be complete and valid
        verify(out)
        eps = read_recording(out)
        assert len(eps) == 2 and all(e.steps == 60 for e in eps)
    for x in tmp_path.iterdir():
        assert x.name == "loop.rrd" or x.name.startswith(".loop"), x.name
