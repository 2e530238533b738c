"""Every script in examples/ documents itself (title, purpose, run command, ``main()``) and runs: its short
``--smoke`` mode is executed here as a user would run it, and must print its result and exit 0."""
from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = sorted((ROOT / "examples").glob("*.py"))


def test_examples_exist():
    names = {p.stem for p in EXAMPLES}
    assert {"teleop_headless", "evaluate_policy", "read_recording", "custom_scene"} <= names


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.stem)
def test_example_documents_itself(path):
    tree = ast.parse(path.read_text(encoding="utf-8"))
    doc = ast.get_docstring(tree) or ""
    title = doc.splitlines()[0] if doc else ""
    assert title and title.endswith("."), f"{path.name}: docstring must open with a one-line title"
    assert "Purpose:" in doc and "Run:" in doc and f"examples/{path.name}" in doc, path.name
    assert any(isinstance(n, ast.FunctionDef) and n.name == "main" for n in tree.body), f"{path.name}: no main()"


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.stem)
def test_example_runs(path):
    out = subprocess.run([sys.executable, str(path), "--smoke"], cwd=ROOT, capture_output=True, text=True,
                         timeout=600)
    assert out.returncode == 0, f"{path.name} failed:\n{out.stdout}\n{out.stderr}"
    assert out.stdout.strip(), f"{path.name} printed nothing"


def _readme_snippets() -> list[str]:
    import re

    text = (ROOT / "README.md").read_text(encoding="utf-8")
    return re.findall(r"```python\n(.*?)```", text, re.S)


def test_readme_has_python_snippets():
    assert len(_readme_snippets()) >= 2


@pytest.mark.parametrize("index", range(len(_readme_snippets())))
def test_readme_python_snippet_runs(index):
    code = _readme_snippets()[index]
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, f"README snippet {index} failed:\n{code}\n{out.stderr}"
