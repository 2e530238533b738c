"""GUI: add/import/delete obstacles (moved with their transform gizmo), save/load the scene."""
from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING

from workbench import obstacles as obst

if TYPE_CHECKING:
    from workbench.app import WorkbenchApp

UPLOAD_DIR = Path(tempfile.gettempdir()) / "rodlab_uploads"


class ObstaclesPanel:
    def __init__(self, app: "WorkbenchApp"):
        self.app = app
        gui = app.server.gui
        with gui.add_folder("Obstacles", expand_by_default=False):
            self.kind = gui.add_dropdown("Shape", ("sphere", "capsule", "box"), initial_value="sphere")
            self.add_btn = gui.add_button("Add obstacle")
            meshes = obst.mesh_catalogue() or ["(none in assets/meshes)"]
            self.mesh = gui.add_dropdown("Mesh file", meshes, initial_value=meshes[0])
            self.add_mesh_btn = gui.add_button("Add mesh")
            self.upload = gui.add_upload_button("Upload mesh", mime_type="*/*")
            self.selected = gui.add_dropdown("Selected", self._names(), initial_value=self._names()[0])
            self.delete_btn = gui.add_button("Delete obstacle")
            default = app.wb.scene_path or Path("scene.toml")
            self.path = gui.add_text("Scene file", initial_value=str(default))
            self.save_btn = gui.add_button("Save scene")
            self.load_btn = gui.add_button("Load scene")
            self.msg = gui.add_markdown("")
        self._wire()
        app.wb.on_scene_changed.append(self._refresh)

    def _names(self) -> list[str]:
        names = [f"{i}: {e.name or e.kind}" for i, e in enumerate(self.app.wb.obstacles)]
        return names or ["(no obstacles)"]

    def _refresh(self) -> None:
        names = self._names()
        self.selected.options = names
        self.selected.value = names[-1]

    def _say(self, text: str) -> None:
        self.msg.content = text

    def _wire(self) -> None:
        app, wb = self.app, self.app.wb

        @self.add_btn.on_click
        def _(_e) -> None:
            self._guard(lambda: wb.add_obstacle(obst.default_edit(self.kind.value)), "added")

        @self.add_mesh_btn.on_click
        def _(_e) -> None:
            path = obst.MESH_DIR / self.mesh.value
            if not path.is_file():
                self._say("no mesh file selected")
                return
            self._guard(lambda: wb.add_obstacle(obst.ObstacleEdit(
                kind="mesh", mesh=str(path), position=(0.45, 0.0, 0.6), name=path.stem)), "mesh added")

        @self.upload.on_upload
        def _(_e) -> None:
            f = self.upload.value
            suffix = Path(f.name).suffix.lower()
            if suffix not in obst.MESH_SUFFIXES:
                self._say(f"unsupported mesh type {suffix!r} (use {', '.join(obst.MESH_SUFFIXES)})")
                return
            UPLOAD_DIR.mkdir(parents=True, exist_ok=True)
            dest = UPLOAD_DIR / Path(f.name).name
            fd, tmp = tempfile.mkstemp(dir=UPLOAD_DIR, suffix=suffix)
            with os.fdopen(fd, "wb") as fh:
                fh.write(f.content)
            os.replace(tmp, dest)
            self._guard(lambda: wb.add_obstacle(obst.ObstacleEdit(
                kind="mesh", mesh=str(dest), position=(0.45, 0.0, 0.6), name=dest.stem)), "uploaded")

        @self.delete_btn.on_click
        def _(_e) -> None:
            if not wb.obstacles:
                return
            idx = int(str(self.selected.value).split(":")[0])
            self._guard(lambda: wb.delete_obstacle(idx), "deleted")

        @self.save_btn.on_click
        def _(_e) -> None:
            self._guard(lambda: wb.save_scene(self.path.value), f"saved {self.path.value}")

        @self.load_btn.on_click
        def _(_e) -> None:
            self._guard(lambda: wb.load_scene(self.path.value), f"loaded {self.path.value}")
            app.controls.sync_sliders()

    def _guard(self, fn, ok: str) -> None:
        try:
            fn()
        except Exception as exc:  # noqa: BLE001 - show the error in the page
            self._say(f"⚠ {exc}")
            return
        self._say(ok)
        self.app.request_render()
