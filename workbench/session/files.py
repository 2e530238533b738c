"""Where the page may read and write files: the scenes folder, the recordings folder, the uploads folder.

* scenes: saved and loaded only inside ``scenes_dir`` (default ``scenes/`` in the working directory, made on
  the first save); the shipped ``assets/scenes`` are readable but never written. A save never replaces a
  file other than the scene that is open from the scenes folder, so nothing a user saved is lost.
* recordings: opened only inside ``recordings_dir`` (default ``recordings/`` in the working directory).
* data: measured motion and commanded curvature for the Fit tab (CSV, .npz), read only inside ``data_dir`` (default
  ``data/`` in the working directory); nothing is written there.
* uploads: written only into a per-launch temporary folder (removed by :meth:`Folders.cleanup`), at most
  ``max_upload_bytes`` each.

Names typed or sent by the page are plain file names: a path separator, ``..`` or a control character is
refused with a message saying so. Messages never quote a file's contents.
"""
from __future__ import annotations

import atexit
import dataclasses
import re
import secrets
import shutil
import tempfile
from pathlib import Path

from sim.support.assets import asset_path

SHIPPED_SCENES = asset_path("scenes")
MAX_NAME = 100
_NAME = re.compile(r"^\w[\w .()+,=-]*$")
_GOT = re.compile(r",? got .*$")


class FileAccessError(ValueError):
    """A file name or place the page may not use (the message says why)."""


def check_name(name: object, *, suffix: str) -> str:
    """A plain file name ending in ``suffix`` (added when missing); FileAccessError otherwise."""
    if not isinstance(name, str):
        raise FileAccessError("the file name must be text")
    name = name.strip()
    if not name:
        raise FileAccessError("give a file name")
    if "/" in name or "\\" in name:
        raise FileAccessError("give a plain file name without folders (no / or \\)")
    if ".." in name:
        raise FileAccessError("a file name must not contain '..'")
    if len(name) > MAX_NAME:
        raise FileAccessError(f"a file name has at most {MAX_NAME} characters")
    if not _NAME.match(name):
        raise FileAccessError("use letters, digits, spaces and - _ . ( ) + , = in file names")
    if not name.lower().endswith(suffix):
        name += suffix
    return name


def inside(path: Path, folder: Path) -> bool:
    """``path`` (symbolic links followed) lies in ``folder``."""
    try:
        return path.resolve().is_relative_to(folder.resolve())
    except OSError:
        return False


def page_error(exc: BaseException, path: Path | None = None) -> str:
    """An error for the page: no traceback, the file's name instead of its full path, and no ``got <value>``
    tail (values read from a file are not echoed)."""
    text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    if path is not None:
        text = text.replace(str(path), path.name)
    parts = [_GOT.sub("", p) for p in text.split(": ")]
    return ": ".join(p for p in parts if p)[:300]


def _listed(folder: Path, rel: object, suffixes: tuple[str, ...], refusal: str) -> Path:
    """The existing file ``rel`` (a path relative to ``folder``, as the page's lists name them) with one of
    ``suffixes``; FileAccessError(``refusal``) for anything else, a name leading outside ``folder`` included."""
    if not isinstance(rel, str) or not rel or ".." in rel.split("/") or rel.startswith("/") or "\\" in rel:
        raise FileAccessError(refusal)
    p = folder / rel
    if p.suffix not in suffixes or not inside(p, folder) or not p.is_file():
        raise FileAccessError(refusal)
    return p


@dataclasses.dataclass
class Folders:
    """The folders of one workbench launch (see module docstring)."""

    scenes: Path
    recordings: Path
    uploads: Path
    max_upload_bytes: int
    shipped_scenes: Path = SHIPPED_SCENES
    data: Path = dataclasses.field(default_factory=lambda: (Path.cwd() / "data").absolute())

    @classmethod
    def create(cls, *, scenes_dir: str | Path | None = None, recordings_dir: str | Path | None = None,
               max_upload_mb: float = 50.0, data_dir: str | Path | None = None) -> "Folders":
        scenes = Path(scenes_dir) if scenes_dir else Path.cwd() / "scenes"
        if scenes.resolve() == SHIPPED_SCENES.resolve():
            raise FileAccessError(f"the scenes folder cannot be the shipped {SHIPPED_SCENES} (it is never written)")
        if not max_upload_mb > 0:
            raise FileAccessError(f"--max-upload-mb must be > 0, got {max_upload_mb}")
        folders = cls(scenes=scenes.absolute(),
                      recordings=Path(recordings_dir or Path.cwd() / "recordings").absolute(),
                      uploads=Path(tempfile.mkdtemp(prefix="rodlab-uploads-")),
                      max_upload_bytes=int(max_upload_mb * 1024 * 1024),
                      data=Path(data_dir or Path.cwd() / "data").absolute())
        atexit.register(folders.cleanup)  # also when the process ends without WorkbenchApp.stop()
        return folders

    def cleanup(self) -> None:
        """Remove the uploads folder (at exit)."""
        shutil.rmtree(self.uploads, ignore_errors=True)

    # ------------------------------------------------------------------ scenes
    def is_user_scene(self, path: Path | None) -> bool:
        return path is not None and Path(path).parent.resolve() == self.scenes.resolve()

    def default_save_name(self, current: Path | None) -> str:
        """The scene's own name when it was opened from the scenes folder, else a name not used there yet
        (a shipped scene's first save goes to the scenes folder under a new name)."""
        if current is not None and self.is_user_scene(current):
            return Path(current).name
        return self.new_scene_name((Path(current).stem if current is not None else "scene") + "_edited")

    def new_scene_name(self, stem: str) -> str:
        """``stem``.toml, or ``stem``_2.toml, _3 … : the first name not used in the scenes folder."""
        for i in range(1, 1000):
            name = f"{stem}.toml" if i == 1 else f"{stem}_{i}.toml"
            if not (self.scenes / name).exists():
                return name
        return f"{stem}_{secrets.token_hex(4)}.toml"

    def scene_for_save(self, name: object, current: Path | None) -> Path:
        """Where "Save scene" writes ``name``: inside the scenes folder, never over another existing file."""
        n = check_name(name, suffix=".toml")
        p = self.scenes / n
        if p.is_symlink() or (p.exists() and not (current is not None and self.is_user_scene(current)
                                                 and Path(current).name == n)):
            raise FileAccessError(f"{n} already exists in {self.scenes}: choose another name "
                                  "(load it first to replace it)")
        self.scenes.mkdir(parents=True, exist_ok=True)
        return p

    def scene_for_load(self, name: object) -> Path:
        """The scene ``name`` in the scenes folder, else among the shipped scenes."""
        n = check_name(name, suffix=".toml")
        for folder in (self.scenes, self.shipped_scenes):
            p = folder / n
            if p.is_file() and inside(p, folder):
                return p
        raise FileAccessError(f"no scene named {n} in {self.scenes} or in the shipped scenes")

    # ------------------------------------------------------------------ recordings
    def recording(self, rel: object) -> Path:
        """A recording named relative to the recordings folder, refused when it leads outside it."""
        return _listed(self.recordings, rel, (".rrd",), "choose a recording from the list")

    # ------------------------------------------------------------------ data (the Fit tab)
    DATA_SUFFIXES = (".csv", ".npz")

    def data_files(self) -> list[str]:
        """The measurement and controls files in the data folder (and its subfolders), named relative to it."""
        root = self.data
        if not root.is_dir():
            return []
        out = [str(p.relative_to(root)) for p in sorted(root.rglob("*"))
               if p.suffix in self.DATA_SUFFIXES and p.is_file() and inside(p, root)]
        return out[:1000]

    def data_file(self, rel: object) -> Path:
        """A data file named relative to the data folder, refused when it leads outside it."""
        return _listed(self.data, rel, self.DATA_SUFFIXES, "choose a data file from the list")

    # ------------------------------------------------------------------ uploads
    def upload_path(self, name: object, size: int, suffixes: tuple[str, ...]) -> Path:
        """Where an uploaded file of ``size`` bytes goes (a fresh name in the uploads folder)."""
        if size > self.max_upload_bytes:
            raise FileAccessError(f"upload refused: {size / 2**20:.1f} MB is over the limit of "
                                  f"{self.max_upload_bytes / 2**20:.0f} MB (--max-upload-mb)")
        suffix = Path(name).suffix.lower() if isinstance(name, str) else ""
        if suffix not in suffixes:
            raise FileAccessError(f"unsupported file type {suffix[:10]!r} (use {', '.join(suffixes)})")
        n = check_name(name, suffix=suffix)
        stem, p = Path(n).stem, self.uploads / n
        k = 2
        while p.exists():
            p = self.uploads / f"{stem}_{k}{suffix}"
            k += 1
        return p
