"""Editable obstacles of the workbench and their translation to/from the ``sim`` scene spec.

The workbench keeps a list of :class:`ObstacleEdit` (one per obstacle of the scene, same order)
and writes poses through the simulator's obstacle-set pose API, so contact follows a drag
immediately without rebuilding the model.
"""
from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Literal

import numpy as np
from scipy.spatial import cKDTree

from sim import build_model
from sim.geometry import matrix_to_quat, quat_to_matrix, quat_z_to
from sim.scene import (
    BoxSpec,
    CapsuleSpec,
    CylinderSpec,
    MeshSpec,
    PlaneSpec,
    SphereSpec,
    dump_scene,
    overlap_warning,
    rod_obstacle_overlaps,
)
from sim.support.assets import asset_path

ObstacleKind = Literal["sphere", "capsule", "cylinder", "box", "mesh", "plane"]
KINDS: tuple[str, ...] = ("sphere", "capsule", "cylinder", "box", "mesh", "plane")
PLANE_DRAW_SIZE = 2.4  # [m] side of the square drawn for a plane
MESH_DIR = asset_path("meshes")
MESH_SUFFIXES = (".stl", ".obj", ".ply", ".glb", ".gltf", ".off")


@dataclasses.dataclass
class ObstacleEdit:
    """One obstacle as the workbench edits it.

    Attributes:
        kind: sphere | capsule | cylinder | box | mesh | plane.
        position: (3,) centre [m]; wxyz: (4,) orientation (unit quaternion, scalar first).
        radius: sphere/capsule/cylinder radius [m]; length: capsule/cylinder axis length (local z) [m].
        half_extents: (3,) box half sizes [m]; mesh: mesh file path; scale: mesh scale [-].
        name: label shown in the page; mesh_data: (vertices, faces) of a recorded mesh (display only).
    """

    kind: str
    position: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(3))
    wxyz: np.ndarray = dataclasses.field(default_factory=lambda: np.array([1.0, 0.0, 0.0, 0.0]))
    radius: float = 0.08
    length: float = 0.4
    half_extents: np.ndarray = dataclasses.field(default_factory=lambda: np.full(3, 0.08))
    mesh: str | None = None
    scale: float = 1.0
    name: str = ""
    mesh_data: tuple | None = dataclasses.field(default=None, repr=False)  # (V, F) for display only
    mesh_scale3: tuple | None = None  # per-axis mesh scale (from a scene file)
    # where the obstacle sits in the built model (sim_pose is relative to it) and its original spec
    base_position: np.ndarray | None = dataclasses.field(default=None, repr=False)
    base_wxyz: np.ndarray | None = dataclasses.field(default=None, repr=False)
    source: object = dataclasses.field(default=None, repr=False, compare=False)

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"obstacle kind must be one of {KINDS}, got {self.kind!r}")
        self.position = np.asarray(self.position, dtype=np.float64).reshape(3)
        self.wxyz = np.asarray(self.wxyz, dtype=np.float64).reshape(4)
        self.half_extents = np.asarray(self.half_extents, dtype=np.float64).reshape(3)
        if self.kind == "mesh" and not self.mesh:
            raise ValueError("a mesh obstacle needs a mesh file path")


def mesh_catalogue() -> list[str]:
    """Mesh files shipped in assets/meshes (names)."""
    if not MESH_DIR.is_dir():
        return []
    return sorted(p.name for p in MESH_DIR.iterdir() if p.suffix.lower() in MESH_SUFFIXES)


#: [m] where a new obstacle goes (moved clear of the rod and the others, :func:`free_position`): beside the arm's
#: middle, in the start view of the arm (``workbench.view.scene.fit_camera``)
NEW_OBSTACLE_AT = (0.4, 0.0, 0.6)


def default_edit(kind: str, *, position=NEW_OBSTACLE_AT) -> ObstacleEdit:
    """A reasonable new obstacle of ``kind`` placed beside the rod."""
    return ObstacleEdit(kind=kind, position=np.asarray(position, dtype=np.float64), name=kind)


def bounding_radius(e: ObstacleEdit) -> float:
    """Radius of a sphere about ``e.position`` that holds the obstacle [m]."""
    if e.kind == "sphere":
        return float(e.radius)
    if e.kind == "capsule":
        return float(e.radius + 0.5 * e.length)
    if e.kind == "cylinder":
        return float(np.hypot(e.radius, 0.5 * e.length))
    if e.kind == "box":
        return float(np.linalg.norm(e.half_extents))
    try:
        v, _f = mesh_for_edit(e)
        return float(np.max(np.linalg.norm(np.asarray(v, np.float64), axis=1)))
    except Exception:  # noqa: BLE001 - unreadable mesh: a generous guess
        return 0.3


def surface_distance(e: ObstacleEdit, points: np.ndarray) -> np.ndarray:
    """Distance [m] from each of ``points`` (K, 3) to obstacle ``e`` (negative inside a plane's half-space): exact
    for spheres, capsules and planes, a capsule for a cylinder, the bounding sphere for boxes and meshes."""
    p = np.asarray(points, np.float64).reshape(-1, 3)
    c = np.asarray(e.position, np.float64)
    if e.kind == "plane":
        n = quat_to_matrix(np.asarray(e.wxyz, np.float64))[:, 2]
        return (p - c) @ n
    if e.kind in ("capsule", "cylinder"):
        axis = quat_to_matrix(np.asarray(e.wxyz, np.float64))[:, 2]
        s = np.clip((p - c) @ axis, -0.5 * e.length, 0.5 * e.length)
        return np.linalg.norm(p - (c + s[:, None] * axis), axis=1) - float(e.radius)
    return np.linalg.norm(p - c, axis=1) - bounding_radius(e)


def free_position(e: ObstacleEdit, rod_nodes: np.ndarray, rod_radius: float, others: list[ObstacleEdit], *,
                  near=NEW_OBSTACLE_AT, clearance: float = 0.03, reach: float = 0.8) -> np.ndarray:
    """A centre for ``e`` whose bounding sphere keeps ``clearance`` from the rod (its nodes, ``rod_radius``) and from
    the other obstacles (:func:`surface_distance`: a floor plane only rules out what lies below it): the free point
    of a 5 cm grid within ``reach`` of ``near`` (beside the rod, in the start view) nearest to ``near``; else the
    point there clear of the rod alone; else ``near`` itself."""
    r = bounding_radius(e)
    near = np.asarray(near, np.float64)
    ax = np.arange(-reach, reach + 1e-9, 0.05)
    g = near + np.stack(np.meshgrid(ax, ax, ax, indexing="ij"), -1).reshape(-1, 3)
    g = g[np.linalg.norm(g - near, axis=1) <= reach]
    g = g[np.argsort(np.linalg.norm(g - near, axis=1), kind="stable")]
    x = np.asarray(rod_nodes, np.float64).reshape(-1, 3)
    d_rod = cKDTree(x).query(g)[0]  # distance to the nearest node
    clear_of_rod = d_rod > r + rod_radius + clearance
    ok = clear_of_rod.copy()
    for o in others:
        ok &= surface_distance(o, g) > r + clearance
    for cand in (ok, clear_of_rod):
        if cand.any():
            return g[np.argmax(cand)].copy()
    return near.copy()


def rest_overlaps(spec, edits: list[ObstacleEdit]) -> str:
    """Warning line when the rod's rest shape lies inside an obstacle ('' when not; sim.scene.check)."""
    if not edits:
        return ""
    return overlap_warning(rod_obstacle_overlaps(build_model(spec_with(spec, edits))), "scene")


# ---------------------------------------------------------------------- spec translation
def edits_from_spec(spec) -> list[ObstacleEdit]:
    """Fresh editable copies of the obstacles of ``spec`` (same order as the simulator's)."""
    out = []
    for o in getattr(spec, "obstacles", ()) or ():
        out.append(dataclasses.replace(o) if isinstance(o, ObstacleEdit) else _edit_from_obstacle_spec(o))
    return out


def spec_with(spec, edits: list[ObstacleEdit]):
    """A copy of ``spec`` whose obstacles are ``edits``."""
    return dataclasses.replace(spec, obstacles=tuple(_obstacle_spec_from_edit(e) for e in edits))


def apply_pose(live, index: int, edit: ObstacleEdit) -> None:
    """Push one obstacle pose into the running simulator (no model rebuild): every env of the
    live simulator gets it."""
    pos, wxyz = sim_pose(edit)
    live.sim.set_obstacle_pose(live.state, index, pos, wxyz)


def write_scene(spec, path: Path) -> Path:
    """Write ``spec`` as a TOML scene file atomically (mesh files referenced relative to ``path``)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    dump_scene(spec, path)
    return path


# ---------------------------------------------------------------------- sim-specific parts
def _rotm(wxyz) -> np.ndarray:
    return quat_to_matrix(np.asarray(wxyz, dtype=np.float64))


def _quat(R: np.ndarray) -> np.ndarray:
    return matrix_to_quat(R)


def _z_to(d) -> np.ndarray:
    return quat_z_to(np.asarray(d, dtype=np.float64))


def _edit_from_obstacle_spec(o) -> ObstacleEdit:
    """sim ObstacleSpec -> ObstacleEdit (world pose of the obstacle's drawing frame)."""
    kind = getattr(o, "type", type(o).__name__.replace("Spec", "").lower())
    name = getattr(o, "name", "") or kind
    if kind == "sphere":
        e = ObstacleEdit(kind="sphere", position=o.center, radius=float(o.radius), name=name)
    elif kind == "capsule":
        a, b = np.asarray(o.start, float), np.asarray(o.end, float)
        e = ObstacleEdit(kind="capsule", position=0.5 * (a + b), wxyz=_z_to(b - a), radius=float(o.radius),
                         length=float(np.linalg.norm(b - a)), name=name)
    elif kind == "cylinder":
        a, b = np.asarray(o.start, float), np.asarray(o.end, float)
        e = ObstacleEdit(kind="cylinder", position=0.5 * (a + b), wxyz=_z_to(b - a), radius=float(o.radius),
                         length=float(np.linalg.norm(b - a)), name=name)
    elif kind == "box":
        e = ObstacleEdit(kind="box", position=o.position, wxyz=o.orientation, half_extents=o.half_extents,
                         name=name)
    elif kind == "mesh":
        sc = np.broadcast_to(np.asarray(o.scale, dtype=np.float64), (3,))
        e = ObstacleEdit(kind="mesh", position=o.position, wxyz=o.orientation, mesh=o.path or o.file,
                         scale=float(sc[0]), name=name, mesh_scale3=tuple(float(v) for v in sc))
    elif kind == "plane":
        e = ObstacleEdit(kind="plane", position=o.point, wxyz=_z_to(o.normal), name=name)
    else:
        raise ValueError(f"unknown obstacle type {kind!r}")
    e.source = o
    e.base_position, e.base_wxyz = e.position.copy(), e.wxyz.copy()
    return e


def _obstacle_spec_from_edit(e: ObstacleEdit):
    """ObstacleEdit -> sim ObstacleSpec with the current pose baked in (world coordinates). An obstacle that
    was not edited gives back its original spec unchanged (a saved scene keeps its numbers exactly)."""
    if e.source is not None and _unchanged(e, _edit_from_obstacle_spec(e.source)):
        return e.source

    R = _rotm(e.wxyz)
    p = tuple(float(v) for v in e.position)
    q = tuple(float(v) for v in (e.wxyz / np.linalg.norm(e.wxyz)))
    name = e.name or ""
    if e.kind == "sphere":
        return SphereSpec(center=p, radius=float(e.radius), name=name)
    if e.kind in ("capsule", "cylinder"):
        ax = R[:, 2] * 0.5 * e.length
        cls = CapsuleSpec if e.kind == "capsule" else CylinderSpec
        return cls(start=tuple(float(v) for v in e.position - ax), end=tuple(float(v) for v in e.position + ax),
                   radius=float(e.radius), name=name)
    if e.kind == "box":
        return BoxSpec(position=p, half_extents=tuple(float(v) for v in e.half_extents), orientation=q,
                          name=name)
    if e.kind == "plane":
        return PlaneSpec(point=p, normal=tuple(float(v) for v in R[:, 2]), name=name)
    src = getattr(e, "source", None)
    path = str(Path(e.mesh).resolve())
    scale = e.mesh_scale3 or (e.scale,) * 3
    return MeshSpec(file=getattr(src, "file", path) if src is not None and src.path == path else path,
                       path=path, scale=tuple(float(v) for v in scale), position=p, orientation=q, name=name)


def _unchanged(e: ObstacleEdit, orig: ObstacleEdit) -> bool:
    same = all(np.array_equal(getattr(e, f), getattr(orig, f)) for f in ("position", "wxyz", "half_extents"))
    return same and (e.kind, e.radius, e.length, e.mesh, e.scale, e.name, e.mesh_scale3) == (
        orig.kind, orig.radius, orig.length, orig.mesh, orig.scale, orig.name, orig.mesh_scale3)


def sim_pose(e: ObstacleEdit) -> tuple[np.ndarray, np.ndarray]:
    """(position (3,), wxyz (4,)) for ``Simulator.set_obstacle_pose``: the rigid motion taking the obstacle
    from its spec placement to the edited one. Capsule/sphere/plane specs are in their local frame
    (initial pose identity); box/mesh/cylinder poses are the obstacle's own pose (a cylinder's frame: centre
    at the axis midpoint, z along the axis)."""
    if e.kind in ("box", "mesh", "cylinder"):
        return e.position.copy(), e.wxyz / np.linalg.norm(e.wxyz)
    R_e = _rotm(e.wxyz)
    if e.base_position is None:  # not from the built model: it was created at its current pose
        return np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0])
    R_0 = _rotm(e.base_wxyz)
    m0 = e.base_position
    R = R_e @ R_0.T
    return e.position - R @ m0, _quat(R)


def mesh_for_edit(e: ObstacleEdit) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (V, 3) [m] in the obstacle's local frame, faces (F, 3)) for drawing."""
    import trimesh

    if e.kind == "sphere":
        m = trimesh.creation.icosphere(subdivisions=3, radius=e.radius)
    elif e.kind == "capsule":
        m = trimesh.creation.capsule(height=e.length, radius=e.radius, count=[24, 12])
    elif e.kind == "cylinder":
        m = trimesh.creation.cylinder(radius=e.radius, height=e.length, sections=48)
    elif e.kind == "box":
        m = trimesh.creation.box(extents=2.0 * e.half_extents)
    elif e.kind == "plane":
        m = trimesh.creation.box(extents=(PLANE_DRAW_SIZE, PLANE_DRAW_SIZE, 0.004))
        m.apply_translation((0.0, 0.0, -0.002))
    elif e.mesh_data is not None:
        return np.asarray(e.mesh_data[0], np.float32), np.asarray(e.mesh_data[1], np.uint32)
    else:
        m = trimesh.load(e.mesh, force="mesh")
        m.apply_scale(e.mesh_scale3 or e.scale)
    return np.asarray(m.vertices, dtype=np.float32), np.asarray(m.faces, dtype=np.uint32)
