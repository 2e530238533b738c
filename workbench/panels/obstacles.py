"""GUI: add/import/delete obstacles (moved with their transform gizmo), save/load the scene.

Scene names and uploads go through ``workbench.session.files`` (scenes folder, uploads folder, size limit); every
dropdown value is checked against its options (``workbench.panels.guard``).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from sim.support.atomicio import write_bytes
from workbench.panels.guard import cap_uploads
from workbench.panels.host import PanelHost
from workbench.session import (
    MESH_DIR,
    MESH_SUFFIXES,
    NEW_OBSTACLE_AT,
    FileAccessError,
    ObstacleEdit,
    default_edit,
    free_position,
    mesh_catalogue,
    page_error,
    quat_from_rpy_deg,
    rest_overlaps,
    rpy_deg_from_quat,
)

NO_MESH = "(none in assets/meshes)"
NONE = "(none)"  # the Selected dropdown with no obstacle selected (no gizmo, the fields below disabled)
KEEP = object()  # scene changed: keep the selected obstacle if it is still there (see ``ObstaclesPanel._refresh``)


class ObstaclesPanel:
    def __init__(self, app: PanelHost):
        self.app = app
        gui = app.server.gui
        with app.tabs["Obstacles"]:
            self.kind = gui.add_dropdown("Shape", ("sphere", "capsule", "cylinder", "box"), initial_value="sphere",
                                         hint="shape of the next obstacle")
            self.add_btn = gui.add_button("Add obstacle", hint="add one; drag its gizmo to move it")
            meshes = mesh_catalogue() or [NO_MESH]
            self.mesh = gui.add_dropdown("Mesh file", meshes, initial_value=meshes[0], hint="meshes in assets/meshes")
            self.add_mesh_btn = gui.add_button("Add mesh", hint="add the chosen mesh as an obstacle")
            self.upload = gui.add_upload_button("Upload mesh", mime_type="*/*",
                                                hint="a mesh file from this computer (size-limited)")
            self.selected = gui.add_dropdown("Selected", self._names(), initial_value=NONE,
                                             hint="the obstacle with the gizmo (a click on an obstacle selects it; "
                                                  "a new obstacle is selected); Delete and the fields below act on "
                                                  "it")
            self.position = gui.add_vector3("Position [m]", initial_value=(0.0, 0.0, 0.0), step=0.01,
                                            hint="centre of the selected obstacle (world x, y, z)")
            self.rotation = gui.add_vector3("Rotation [deg]", initial_value=(0.0, 0.0, 0.0), step=1.0,
                                            min=(-180.0, -180.0, -180.0), max=(180.0, 180.0, 180.0),
                                            hint="roll, pitch, yaw of the selected obstacle: rotations about the "
                                                 "world x, then y, then z axis (R = Rz(yaw)·Ry(pitch)·Rx(roll))")
            self.size = gui.add_vector3("Size [m]", initial_value=(0.08, 0.4, 0.08), step=0.005,
                                        min=(0.005, 0.005, 0.005), max=(2.0, 2.0, 2.0),
                                        hint="sphere: radius; capsule: radius, length; box: half sizes x, y, z; "
                                             "mesh: scale [-] (first value)")
            self.delete_btn = gui.add_button("Delete obstacle", hint="remove the selected obstacle")
            self.path = gui.add_text("Scene file", initial_value=app.files.default_save_name(app.wb.scene_path),
                                     hint="name in the scenes folder")
            self.save_btn = gui.add_button("Save scene", hint="write the scene with its obstacles (TOML)")
            self.load_btn = gui.add_button("Load scene", hint="open that scene file (the rod is reset)")
            self.msg = gui.add_markdown("")
            self.warning = gui.add_markdown("")
        self._syncing = False
        self._checked: tuple | None = None
        self._next_selection = KEEP  # what the next scene change selects: KEEP, None or an index
        for h in (self.kind, self.mesh, self.selected):
            app.checks.track(h)
        cap_uploads(app.server, app.files.max_upload_bytes,
                    lambda name, size: self._say(f"⚠ upload refused: over the limit of "
                                                 f"{app.files.max_upload_bytes / 2**20:.0f} MB (--max-upload-mb)"))
        self._wire()
        self._show_fields()
        app.wb.on_scene_changed.append(self._refresh)

    def _names(self) -> list[str]:
        return [NONE, *(f"{i}: {e.name or e.kind}" for i, e in enumerate(self.app.wb.obstacles))]

    def _refresh(self) -> None:
        """The scene changed: the list follows; the selection is the obstacle just added (``_next_selection``), else
        the one selected before when it is still there (a task re-placing its obstacles), else none."""
        names = self._names()
        want, self._next_selection = self._next_selection, KEEP
        if want is KEEP:
            current = str(self.selected.value)
            value = current if current in names else NONE
        else:
            value = NONE if want is None or not 0 <= want < len(names) - 1 else names[want + 1]
        self._syncing = True  # the app redraws the obstacles (with the gizmo on the selection) after this
        try:
            self.selected.options = names
            self.selected.value = value
        finally:
            self._syncing = False
        self.app.checks.accept(self.selected)
        self._show_fields()

    # ------------------------------------------------------------------ selection (page <-> 3-D view)
    def selected_index(self) -> int | None:
        v = str(self.selected.value)
        if not self.app.wb.obstacles or ":" not in v:
            return None
        i = int(v.split(":")[0])
        return i if 0 <= i < len(self.app.wb.obstacles) else None

    def select(self, index: int) -> None:
        """Select obstacle ``index`` (a click in the 3-D view, or the dropdown): gizmo, dropdown and fields follow."""
        names = self._names()
        if not self.app.wb.obstacles or not 0 <= index < len(names) - 1:
            return
        if self.selected.value != names[index + 1]:
            self.selected.value = names[index + 1]  # runs the dropdown's callback, which moves the gizmo
            self.app.checks.accept(self.selected)
        elif self.app.view.selected != index:
            self.app.view.select(index)
            self._show_fields()

    def show_pose(self, index: int) -> None:
        """The Position field follows a gizmo drag of the selected obstacle."""
        if index == self.selected_index():
            self._show_fields()

    def _show_fields(self) -> None:
        """The fields show the selected obstacle; with none selected they are disabled."""
        i = self.selected_index()
        for h in (self.position, self.rotation, self.size, self.delete_btn):
            if h.disabled != (i is None):
                h.disabled = i is None
        if i is None:
            return
        e = self.app.wb.obstacles[i]
        size = {"sphere": (e.radius, e.radius, e.radius), "capsule": (e.radius, e.length, e.radius),
                "cylinder": (e.radius, e.length, e.radius),
                "box": tuple(e.half_extents), "mesh": (e.scale, e.scale, e.scale)}.get(e.kind, (0.1, 0.1, 0.1))
        self._syncing = True
        try:
            self.position.value = tuple(round(float(v), 4) for v in e.position)
            self.rotation.value = tuple(round(float(v), 3) for v in rpy_deg_from_quat(e.wxyz))
            self.size.value = tuple(round(float(min(max(v, 0.005), 2.0)), 4) for v in size)
        finally:
            self._syncing = False

    def _vector(self, handle, lo: float, hi: float) -> np.ndarray | None:
        try:
            v = np.asarray(handle.value, dtype=np.float64).reshape(3)
        except (TypeError, ValueError):
            v = np.full(3, np.nan)
        if not (np.all(np.isfinite(v)) and np.all(v >= lo) and np.all(v <= hi)):
            self._say(f"⚠ {handle.label}: three finite numbers in [{lo}, {hi}]")
            self._show_fields()  # the page shows the obstacle's values again
            return None
        return v

    def _new_edit(self, edit: "ObstacleEdit") -> "ObstacleEdit":
        """``edit`` moved to where it overlaps neither the rod nor another obstacle."""
        wb = self.app.wb
        with wb.lock:
            nodes, r = np.asarray(wb.live.state.node_pos[0], np.float64), float(wb.live.rod_radius)
            edit.position = free_position(edit, nodes, r, wb.obstacles)
        return edit

    def update_status(self) -> None:
        """Warn when an obstacle lies on the rod's rest shape (checked again after every edit)."""
        wb = self.app.wb
        if wb.mode != "teleop":
            return
        key = tuple((e.kind, *np.round(e.position, 4), *np.round(e.wxyz, 4), e.radius, e.length,
                     *np.round(e.half_extents, 4), e.scale, e.mesh) for e in wb.obstacles)
        if key == self._checked:
            return
        self._checked = key
        try:
            text = rest_overlaps(wb.live.base_spec, list(wb.obstacles))
        except Exception as exc:  # noqa: BLE001 - the check is advice: say why it could not run
            text = f"overlap check failed: {page_error(exc)}"
        self.warning.content = f"⚠ {text}" if text else ""

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
            dest = files.upload_path(name, len(content), MESH_SUFFIXES)
            write_bytes(dest, content)
        except (FileAccessError, OSError) as exc:
            self._say(f"⚠ {page_error(exc)}")
            return None
        self._add(ObstacleEdit(kind="mesh", mesh=str(dest), position=NEW_OBSTACLE_AT, name=dest.stem),
                  "uploaded")
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
            if self._syncing:
                return
            if ok.option(self.selected, self._say):
                self.app.view.select(self.selected_index())
                self._show_fields()

        @self.position.on_update
        def _(_e) -> None:
            i = self.selected_index()
            if self._syncing or i is None:
                return
            p = self._vector(self.position, -10.0, 10.0)
            if p is not None:
                e = wb.obstacles[i]
                wb.set_obstacle_pose(i, p, e.wxyz)
                self.app.view.move_obstacle(i, p, e.wxyz)
                self.app.request_render()

        @self.rotation.on_update
        def _(_e) -> None:
            i = self.selected_index()
            if self._syncing or i is None:
                return
            rpy = self._vector(self.rotation, -180.0, 180.0)
            if rpy is not None:
                e = wb.obstacles[i]
                q = quat_from_rpy_deg(rpy)
                wb.set_obstacle_pose(i, e.position, q)
                self.app.view.move_obstacle(i, e.position, q)
                self.app.request_render()

        @self.size.on_update
        def _(_e) -> None:
            i = self.selected_index()
            if self._syncing or i is None:
                return
            v = self._vector(self.size, 0.005, 2.0)
            if v is not None:
                self._guard(lambda: wb.resize_obstacle(i, v), "resized")
                self.select(i)

        @self.add_btn.on_click
        def _(_e) -> None:
            if ok.option(self.kind, self._say):
                self._add(default_edit(self.kind.value), "added")

        @self.add_mesh_btn.on_click
        def _(_e) -> None:
            if not ok.option(self.mesh, self._say) or self.mesh.value == NO_MESH:
                return
            path = MESH_DIR / self.mesh.value
            self._add(ObstacleEdit(kind="mesh", mesh=str(path), position=NEW_OBSTACLE_AT, name=path.stem),
                      "mesh added")

        @self.upload.on_upload
        def _(_e) -> None:
            f = self.upload.value
            self.receive_upload(f.name, f.content)

        @self.delete_btn.on_click
        def _(_e) -> None:
            if not wb.obstacles or not ok.option(self.selected, self._say):
                return
            idx = self.selected_index()
            if idx is None:
                return
            self._next_selection = None
            self._guard(lambda: wb.delete_obstacle(idx), "deleted")
            self._next_selection = KEEP

        @self.save_btn.on_click
        def _(_e) -> None:
            self.save()

        @self.load_btn.on_click
        def _(_e) -> None:
            self.load()

    def _add(self, edit: "ObstacleEdit", ok: str) -> None:
        """Add ``edit`` where it is free (beside the rod, in view) and select it (its gizmo, its fields)."""
        wb = self.app.wb
        self._next_selection = len(wb.obstacles)
        self._guard(lambda: wb.add_obstacle(self._new_edit(edit)), ok)
        self._next_selection = KEEP

    def _guard(self, fn, ok: str) -> None:
        try:
            fn()
        except Exception as exc:  # noqa: BLE001 - show the error in the page
            self._say(f"⚠ {page_error(exc)}")
            return
        self._say(ok)
        self.app.request_render()
