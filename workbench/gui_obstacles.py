"""GUI: add/import/delete obstacles (moved with their transform gizmo), save/load the scene.

Scene names and uploads go through ``workbench.files`` (scenes folder, uploads folder, size limit); every
dropdown value is checked against its options (``workbench.gui_guard``).
"""
from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from sim.atomicio import write_bytes
from workbench import obstacles as obst
from workbench.files import FileAccessError, page_error
from workbench.gui_guard import cap_uploads

if TYPE_CHECKING:
    from workbench.app import WorkbenchApp

NO_MESH = "(none in assets/meshes)"


class ObstaclesPanel:
    def __init__(self, app: "WorkbenchApp"):
        self.app = app
        gui = app.server.gui
        with gui.add_folder("Obstacles", expand_by_default=False):
            self.kind = gui.add_dropdown("Shape", ("sphere", "capsule", "box"), initial_value="sphere")
            self.add_btn = gui.add_button("Add obstacle")
            meshes = obst.mesh_catalogue() or [NO_MESH]
            self.mesh = gui.add_dropdown("Mesh file", meshes, initial_value=meshes[0])
            self.add_mesh_btn = gui.add_button("Add mesh")
            self.upload = gui.add_upload_button("Upload mesh", mime_type="*/*")
            self.selected = gui.add_dropdown("Selected", self._names(), initial_value=self._names()[0])
            self.delete_btn = gui.add_button("Delete obstacle")
            self.path = gui.add_text("Scene file", initial_value=app.files.default_save_name(app.wb.scene_path))
            self.save_btn = gui.add_button("Save scene")
            self.load_btn = gui.add_button("Load scene")
            self.msg = gui.add_markdown("")
        for h in (self.kind, self.mesh, self.selected):
            app.checks.track(h)
        cap_uploads(app.server, app.files.max_upload_bytes,
                    lambda name, size: self._say(f"⚠ upload refused: over the limit of "
                                                 f"{app.files.max_upload_bytes / 2**20:.0f} MB (--max-upload-mb)"))
        self._wire()
        app.wb.on_scene_changed.append(self._refresh)

    def _names(self) -> list[str]:
        names = [f"{i}: {e.name or e.kind}" for i, e in enumerate(self.app.wb.obstacles)]
        return names or ["(no obstacles)"]

    def _refresh(self) -> None:
        names = self._names()
        self.selected.options = names
        self.selected.value = names[-1]
        self.app.checks.accept(self.selected)

    def _say(self, text: str) -> None:
        self.msg.content = text

    # ------------------------------------------------------------------ actions (also used by tests)
    def save(self) -> Path | None:
        """Save the scene under the name in the text field, inside the scenes folder."""
        wb, files = self.app.wb, self.app.files
        try:
            path = files.scene_for_save(self.path.value, wb.scene_path)
            wb.save_scene(path)
        except (FileAccessError, OSError, ValueError) as exc:
            self._say(f"⚠ {page_error(exc)}")
            return None
        self._say(f"saved `{path.name}` in {files.scenes}")
        return path

    def load(self) -> Path | None:
        """Load the scene named in the text field (scenes folder first, then the shipped scenes)."""
        wb, files = self.app.wb, self.app.files
        path = None
        try:
            path = files.scene_for_load(self.path.value)
            wb.load_scene(path)
        except (FileAccessError, OSError, ValueError) as exc:
            self._say(f"⚠ {page_error(exc, path)}")
            return None
        self.path.value = files.default_save_name(path)
        self.app.controls.sync_sliders()
        self.app.request_render()
        self._say(f"loaded `{path.name}`")
        return path

    def receive_upload(self, name: str, content: bytes) -> Path | None:
        """Store an uploaded mesh in the per-launch uploads folder and add it as an obstacle."""
        files = self.app.files
        try:
            dest = files.upload_path(name, len(content), obst.MESH_SUFFIXES)
            write_bytes(dest, content)
        except (FileAccessError, OSError) as exc:
            self._say(f"⚠ {page_error(exc)}")
            return None
        self._guard(lambda: self.app.wb.add_obstacle(obst.ObstacleEdit(
            kind="mesh", mesh=str(dest), position=(0.45, 0.0, 0.6), name=dest.stem)), "uploaded")
        return dest

    def _wire(self) -> None:
        wb, ok = self.app.wb, self.app.checks

        @self.kind.on_update
        def _(_e) -> None:
            ok.option(self.kind, self._say)

        @self.mesh.on_update
        def _(_e) -> None:
            ok.option(self.mesh, self._say)

        @self.selected.on_update
        def _(_e) -> None:
            ok.option(self.selected, self._say)

        @self.add_btn.on_click
        def _(_e) -> None:
            if ok.option(self.kind, self._say):
                self._guard(lambda: wb.add_obstacle(obst.default_edit(self.kind.value)), "added")

        @self.add_mesh_btn.on_click
        def _(_e) -> None:
            if not ok.option(self.mesh, self._say) or self.mesh.value == NO_MESH:
                return
            path = obst.MESH_DIR / self.mesh.value
            self._guard(lambda: wb.add_obstacle(obst.ObstacleEdit(
                kind="mesh", mesh=str(path), position=(0.45, 0.0, 0.6), name=path.stem)), "mesh added")

        @self.upload.on_upload
        def _(_e) -> None:
            f = self.upload.value
            self.receive_upload(f.name, f.content)

        @self.delete_btn.on_click
        def _(_e) -> None:
            if not wb.obstacles or not ok.option(self.selected, self._say):
                return
            idx = int(str(self.selected.value).split(":")[0])
            self._guard(lambda: wb.delete_obstacle(idx), "deleted")

        @self.save_btn.on_click
        def _(_e) -> None:
            self.save()

        @self.load_btn.on_click
        def _(_e) -> None:
            self.load()

    def _guard(self, fn, ok: str) -> None:
        try:
            fn()
        except Exception as exc:  # noqa: BLE001 - show the error in the page
            self._say(f"⚠ {page_error(exc)}")
            return
        self._say(ok)
        self.app.request_render()
