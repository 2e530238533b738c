"""What the 3-D scene draws: :class:`SceneView` (rod tube, markers, obstacles, contacts, pins, colour bar, camera),
the grid of envs (:class:`GridView`), the boundary glyphs, and pictures and videos of the view as the browser draws
it (:func:`screenshot`, :func:`record_replay`). Reads :mod:`workbench.session`; never edits it.
"""
from __future__ import annotations

from sim.support.lazy import lazy_face

_LAZY = {
    "boundary_of": "workbench.view.boundary",
    "GridView": "workbench.view.grid",
    "MAX_VIDEO_FRAMES": "workbench.view.render",
    "RenderError": "workbench.view.render",
    "has_mp4_writer": "workbench.view.render",
    "record_replay": "workbench.view.render",
    "screenshot": "workbench.view.render",
    "SWAP_DELAY": "workbench.view.rod",
    "scene_info": "workbench.view.rod",
    "ARROW_MODES": "workbench.view.scene",
    "CAMERAS": "workbench.view.scene",
    "GIZMO_SCALE": "workbench.view.scene",
    "GROUND_SIZE": "workbench.view.scene",
    "SceneView": "workbench.view.scene",
    "fit_camera_along": "workbench.view.scene",
    "place_camera": "workbench.view.scene",
}

__all__ = sorted(_LAZY)

__getattr__, __dir__ = lazy_face(__name__, _LAZY)
