"""The dependency direction sim <- policies <- workbench is enforced by ruff (flake8-tidy-imports banned-api in
sim/ruff.toml and policies/ruff.toml), and the tree is lint-clean (what `make lint` checks)."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _make_lint_paths() -> list[str]:
    """The paths `make lint` checks (its `ruff check` line in the Makefile)."""
    for line in (ROOT / "Makefile").read_text().splitlines():
        if "ruff check" in line:
            return line.split("ruff check", 1)[1].split()
    raise AssertionError("Makefile has no `ruff check` line")


def _ruff(*args: str, stdin: str | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "ruff", *args], cwd=ROOT, input=stdin, capture_output=True,
                          text=True, timeout=600)


def test_tree_is_lint_clean():
    paths = _make_lint_paths()
    assert {"sim", "policies", "workbench", "tests", "examples"} <= set(paths)
    missing = [p for p in paths if not (ROOT / p).exists()]
    assert not missing, f"make lint names missing paths {missing}"
    out = _ruff("check", "--output-format", "concise", *paths)
    assert out.returncode == 0, out.stdout + out.stderr


@pytest.mark.parametrize("where,source,banned", [
    ("sim", "import torch\n", True),
    ("sim", "import torch.nn\n", True),
    ("sim", "def f():\n    import viser\n    return viser\n", True),
    ("sim", "from policies.control import ActionConverter\n\nActionConverter\n", True),
    ("sim", "import workbench.session.core\n", True),
    ("sim", "import gymnasium\n", True),
    ("sim", "import rerun\n", True),
    ("sim", "import stable_baselines3\n", True),
    ("sim", "import numpy\n", False),
    ("policies", "def f():\n    from workbench.session import core\n    return core\n", True),
    ("policies", "import sim\n", False),
    ("workbench", "import policies\nimport sim\n", False),
])
def test_banned_imports_are_reported(where, source, banned):
    out = _ruff("check", "--output-format", "concise", "--select", "TID251", "--stdin-filename",
                f"{where}/_layering_probe.py", "-", stdin=source)
    assert ("TID251" in out.stdout) == banned, out.stdout + out.stderr
