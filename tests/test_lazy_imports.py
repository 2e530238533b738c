"""`import sim` must not load the heavy UI / learning stacks (dependency direction sim <- policies <- workbench)."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BANNED = ("viser", "rerun", "torch", "gymnasium", "stable_baselines3")


def test_import_sim_loads_no_heavy_modules():
    code = ("import sys, json; import sim; import sim.cli; "
            "print(json.dumps(sorted(m for m in sys.modules if m.split('.')[0] in %r)))" % (BANNED,))
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    assert json.loads(out.stdout.strip().splitlines()[-1]) == []
