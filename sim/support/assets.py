"""Where rodlab's shipped data files are: the scenes and meshes of ``assets/``, a package's data folders.

Read through :mod:`importlib.resources`, so the same call works in a source checkout and in an installed wheel:

* installed: pyproject maps the checkout's ``assets/`` into the wheel as package data ``sim/assets/`` (scenes
  and meshes), and ``policies/pretrained/`` is package data of ``policies``;
* checkout (editable install, or ``PYTHONPATH`` = the checkout): ``sim`` has no ``assets`` folder and the shipped
  ``assets/`` is the folder beside the ``sim`` package.

No other module knows either layout: scenes and meshes are found by :func:`asset_path`, a package's data folder by
:func:`package_data_dir`. Data is read from files on disk (scenes name their meshes by relative paths), so rodlab
must be installed unpacked (as pip installs wheels), not imported from a zip.
"""
from __future__ import annotations

import os
from importlib.resources import files
from pathlib import Path

__all__ = ["assets_dir", "asset_path", "package_data_dir"]


def package_data_dir(package: str, *parts: str) -> Path:
    """The folder (or file) ``parts`` inside the installed package ``package`` (e.g. ``"policies", "pretrained"``),
    as a Path on disk. Imports ``package`` (not its submodules); raises RuntimeError if it is not on disk."""
    root = files(package)
    if not isinstance(root, Path):
        raise RuntimeError(f"package {package!r} is not installed as files on disk ({root!r}); "
                           "install rodlab unpacked (pip install) to read its data files")
    return root.joinpath(*parts)


def assets_dir() -> Path:
    """The shipped assets folder (``scenes/``, ``meshes/``): ``sim/assets`` of an installed rodlab, else the
    ``assets/`` folder beside the ``sim`` package (a source checkout)."""
    sim_dir = package_data_dir("sim")
    installed = sim_dir / "assets"
    return installed if installed.is_dir() else sim_dir.parent / "assets"


def asset_path(relative: str | os.PathLike) -> Path:
    """The shipped asset ``relative`` (e.g. ``"scenes/arm.toml"``, ``"meshes/torus.stl"``; a leading ``assets/``
    is allowed, so ``"assets/scenes/arm.toml"`` names the same file). Raises ValueError for an absolute path or
    one that leaves the assets folder; the file need not exist (the caller's load names it when it is missing)."""
    p = Path(os.fspath(relative))
    if p.is_absolute() or ".." in p.parts:
        raise ValueError(f"{p}: not a path inside the shipped assets (relative, no '..')")
    if p.parts[:1] == ("assets",):
        p = Path(*p.parts[1:]) if len(p.parts) > 1 else Path()
    return assets_dir() / p
