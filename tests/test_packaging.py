"""Packaging promises: every package marked typed (pyproject ships ``py.typed``) has the marker,
``python -m sim.warmup`` runs without the runpy warning (``import sim`` must not import ``sim.warmup``), pyproject
installs exactly the product's packages, and the shipped scenes, meshes and policies are package data found through
``sim.support.assets`` in the checkout and in a built wheel."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tomllib
import zipfile
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


# ------------------------------------------------------------------ package data: assets, shipped policies

def _tree_packages() -> set[str]:
    return {".".join(p.parent.relative_to(ROOT).parts) for pkg in ("sim", "policies", "workbench")
            for p in (ROOT / pkg).rglob("__init__.py") if "__pycache__" not in p.parts}


def test_pyproject_lists_every_package_and_the_asset_folders():
    st = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    listed = set(st["packages"])
    assert listed == _tree_packages() | {"sim.assets.scenes", "sim.assets.meshes"}
    assert not any(p.split(".")[0] in ("benchmarks", "tests", "tools", "examples") for p in listed)
    assert st["package-dir"] == {"sim.assets": "assets"}


def test_scenes_and_meshes_are_found_through_the_resource_function():
    from sim import load_scene
    from sim.support.assets import asset_path, assets_dir

    assert assets_dir().resolve() == (ROOT / "assets").resolve()
    shipped = sorted(p.relative_to(ROOT / "assets") for p in (ROOT / "assets").rglob("*") if p.is_file())
    assert any(p.parts[0] == "scenes" for p in shipped) and any(p.parts[0] == "meshes" for p in shipped)
    for rel in shipped:
        assert asset_path(rel).is_file() and asset_path(Path("assets") / rel) == asset_path(rel)
    assert len(load_scene(asset_path("scenes/mesh_course.toml")).obstacles) > 0  # its meshes by relative path
    for bad in ("/etc/passwd", "../pyproject.toml", "scenes/../../pyproject.toml"):
        with pytest.raises(ValueError):
            asset_path(bad)


def test_product_modules_read_shipped_data_through_the_resource_function():
    from policies.learning.training_report import PRETRAINED
    from policies.tasks.scenes import ARM_SCENE, scene_path
    from sim.support.assets import asset_path
    from workbench.serve import cli
    from workbench.session import files, obstacles

    assert scene_path(ARM_SCENE) == asset_path("scenes/arm.toml")
    assert scene_path("my/scene.toml") == Path("my/scene.toml")  # the working directory's
    assert files.SHIPPED_SCENES == asset_path("scenes") and obstacles.MESH_DIR == asset_path("meshes")
    assert cli.default_scene() == asset_path("scenes/default.toml")
    assert PRETRAINED.resolve() == (ROOT / "policies" / "pretrained").resolve() and any(PRETRAINED.glob("*.zip"))


def test_wheel_holds_the_assets_and_finds_them_installed(tmp_path):
    """Build the wheel from a copy of the package files (no network: the venv's setuptools), unpack it as pip
    would, and read a scene through the resource function from there."""
    pytest.importorskip("setuptools")
    src = tmp_path / "src"
    for rel in ["pyproject.toml", "README.md", "rodlab_cli.py"]:
        (src / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(ROOT / rel, src / rel)
    for folder in ["sim", "policies", "workbench", "assets"]:
        shutil.copytree(ROOT / folder, src / folder, ignore=shutil.ignore_patterns("__pycache__", "*.nb?"))
    out = subprocess.run([sys.executable, "-m", "pip", "wheel", str(src), "--no-deps", "--no-build-isolation",
                          "--no-index", "-q", "-w", str(tmp_path / "dist")], capture_output=True, text=True,
                         timeout=600)
    if out.returncode != 0 and "No module named pip" in out.stderr:
        pytest.skip("pip is not installed in this environment")
    assert out.returncode == 0, out.stderr[-2000:]
    (wheel,) = (tmp_path / "dist").glob("rodlab-*.whl")
    with zipfile.ZipFile(wheel) as z:
        names = set(z.namelist())
        z.extractall(tmp_path / "site")
    shipped = {"sim/assets/" + p.relative_to(ROOT / "assets").as_posix()
               for p in (ROOT / "assets").rglob("*") if p.is_file() and not p.name.startswith(".")}
    assert shipped <= names
    assert {n.split("/")[0] for n in names if not n.startswith("rodlab-")} == {
        "sim", "policies", "workbench", "rodlab_cli.py"}
    assert any(n.startswith("policies/pretrained/") and n.endswith(".zip") for n in names)
    code = ("import json; from sim.support.assets import asset_path, package_data_dir; import sim; "
            "print(json.dumps([str(asset_path('scenes/arm.toml')), str(package_data_dir('policies', 'pretrained')),"
            " sim.__file__]))")
    run = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=600,
                         env={**os.environ, "PYTHONPATH": str(tmp_path / "site")})
    assert run.returncode == 0, run.stderr[-2000:]
    arm, pretrained, sim_file = json.loads(run.stdout.strip().splitlines()[-1])
    site = (tmp_path / "site").resolve()
    assert Path(sim_file).resolve().is_relative_to(site)
    assert Path(arm).resolve() == site / "sim" / "assets" / "scenes" / "arm.toml" and Path(arm).is_file()
    assert Path(pretrained).resolve() == site / "policies" / "pretrained"
