"""Packaging promises: every package marked typed (pyproject ships ``py.typed``) has the marker, and
``python -m sim.warmup`` runs without the runpy warning (``import sim`` must not import ``sim.warmup``)."""
from __future__ import annotations

import json
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("package", ["sim", "policies", "workbench"])
def test_typed_marker_present(package):
    data = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert "py.typed" in data["tool"]["setuptools"]["package-data"]["*"]
    assert (ROOT / package / "py.typed").is_file()


def test_import_sim_does_not_import_warmup():
    code = "import sys, json, sim; print(json.dumps('sim.warmup' in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    assert json.loads(out.stdout.strip().splitlines()[-1]) is False


def test_warmup_module_runs_without_runtime_warning():
    out = subprocess.run([sys.executable, "-W", "error::RuntimeWarning", "-m", "sim.warmup"], cwd=ROOT,
                         capture_output=True, text=True, timeout=900)
    assert out.returncode == 0, out.stderr
    assert "RuntimeWarning" not in out.stderr and "kernels ready" in out.stdout
