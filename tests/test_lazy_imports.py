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


FACES = ("sim", "sim.scene", "sim.geometry", "sim.analysis", "sim.contact", "policies", "policies.learning",
         "policies.recording", "workbench", "workbench.session", "workbench.view", "workbench.panels", "workbench.serve")


def test_every_public_name_of_a_lazy_face_loads_from_its_module():
    """Each package's ``_LAZY`` table (sim.support.lazy) names modules that define those names; dir() lists them,
    and an unknown name is an AttributeError naming the package."""
    import importlib

    import pytest

    for face in FACES:
        pkg = importlib.import_module(face)
        assert set(pkg._LAZY) <= set(dir(pkg)), face
        for name, module in pkg._LAZY.items():
            value = getattr(pkg, name)
            assert getattr(importlib.import_module(module), name) is value, (face, name)
        with pytest.raises(AttributeError, match=f"module '{face}' has no attribute 'no_such_name'"):
            pkg.no_such_name  # noqa: B018


def test_no_face_name_is_also_a_submodule():
    """A face's name equal to one of its submodules would be replaced by that module as soon as anything imports
    the submodule (Python binds a submodule on its package)."""
    import importlib

    for face in FACES:
        folder = Path(importlib.import_module(face).__file__).parent
        clash = sorted(n for n in importlib.import_module(face)._LAZY if (folder / f"{n}.py").exists()
                       or (folder / n / "__init__.py").exists())
        assert not clash, (face, clash)
