"""Rigid static obstacles and IMC contact parameters: scene specs, TOML parse/dump, runtime arrays.

Scene keys (SI units; every obstacle may carry ``name = "..."``)::

    [[obstacle]] type = "capsule"  start [m], end [m], radius [m]
    [[obstacle]] type = "cylinder" start [m], end [m], radius [m] (flat ends; contacted as a 48-sided prism)
    [[obstacle]] type = "sphere"   center [m], radius [m]
    [[obstacle]] type = "plane"    point [m], normal (normalised here; contact side = +normal)
    [[obstacle]] type = "box"      position [m], orientation (quaternion w,x,y,z; default identity),
                                   half_extents [m]
    [[obstacle]] any type may add friction = μ [-] (default: the [contact] friction)
    [[obstacle]] type = "mesh"     file (relative to the scene file; STL/OBJ/PLY/GLB...), scale (number or
                                   3 numbers, default 1), position [m], orientation (wxyz)
    [contact] stiffness [N/m] (1e6), delta [m] (5e-3), friction mu [-] (0),
              friction_velocity_tol [m/s] (1e-2), margin [m] (5e-2, broad-phase inflation), enabled (true),
              max_penetration [m] (4 * delta; a (sub)step ending deeper is retried with more sub-steps),
              self_contact (false: edges of one rod touching each other, sim/contact/edge_pairs.py),
              rod_contact (default true when the scene has several rods: edges of different rods touching)

Poses: every obstacle has a per-env pose (position, quaternion wxyz). For capsule/sphere/plane the spec's
coordinates are the obstacle's local frame (initial pose = identity); box and mesh start at their spec
pose with geometry centred in the local frame. The poses are arrays of the State (``state.obstacle_position`` …,
:mod:`sim.contact.world`), changed per env in place (``Simulator.set_obstacle_pose`` / ``set_capsules``; no rebuild,
mesh BVHs stay in the mesh frame).
"""
from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from sim.contact.mesh import MeshError, load_mesh_triangles
from sim.geometry.rotations import quat_to_matrix  # noqa: F401  (re-exported: sim.scene.obstacles.quat_to_matrix)
from sim.scene.kinds import KIND_CODES
from sim.scene.tomlio import (
    SceneError,
    check_unknown,
    format_value,
    take_bool,
    take_float,
    take_str,
    take_vec3,
)
from sim.scene.validate import unit_vector

__all__ = ["ObstacleSpec", "PlaneSpec", "SphereSpec", "CapsuleSpec", "CylinderSpec", "BoxSpec", "MeshSpec", "ContactSpec",
           "parse_obstacles", "parse_contact", "dump_obstacles", "dump_contact", "KIND_CODES"]

Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]
_IDQ: Quat = (1.0, 0.0, 0.0, 0.0)


@dataclass(frozen=True)
class ObstacleSpec:
    """Base of the rigid obstacle specs (use the subclasses)."""


@dataclass(frozen=True)
class PlaneSpec(ObstacleSpec):
    """Half-space boundary through ``point`` [m] with unit ``normal`` (rod kept on the +normal side)."""

    point: Vec3
    normal: Vec3
    name: str = ""
    friction: float | None = None  # Coulomb μ of this obstacle; None = the [contact] friction
    type = "plane"


@dataclass(frozen=True)
class SphereSpec(ObstacleSpec):
    """Sphere: ``center`` [m], ``radius`` [m]."""

    center: Vec3
    radius: float
    name: str = ""
    friction: float | None = None  # Coulomb μ of this obstacle; None = the [contact] friction
    type = "sphere"


@dataclass(frozen=True)
class CapsuleSpec(ObstacleSpec):
    """Capsule: axis segment ``start``-``end`` [m], ``radius`` [m] (the paper's obstacles)."""

    start: Vec3
    end: Vec3
    radius: float
    name: str = ""
    friction: float | None = None  # Coulomb μ of this obstacle; None = the [contact] friction
    type = "capsule"


@dataclass(frozen=True)
class CylinderSpec(ObstacleSpec):
    """Flat-ended cylinder: axis segment ``start``-``end`` [m], ``radius`` [m]; contacted as a closed 48-sided
    prism (radial error 0.21 % of the radius), its pose set like a mesh's."""

    start: Vec3
    end: Vec3
    radius: float
    name: str = ""
    friction: float | None = None  # Coulomb μ of this obstacle; None = the [contact] friction
    type = "cylinder"


@dataclass(frozen=True)
class BoxSpec(ObstacleSpec):
    """Box: centre ``position`` [m], ``orientation`` (wxyz, unit), ``half_extents`` [m] (> 0)."""

    position: Vec3
    half_extents: Vec3
    orientation: Quat = _IDQ
    name: str = ""
    friction: float | None = None  # Coulomb μ of this obstacle; None = the [contact] friction
    type = "box"


@dataclass(frozen=True)
class MeshSpec(ObstacleSpec):
    """Triangle mesh: ``file`` as written in the scene, ``path`` resolved absolute path (default: ``file``
    resolved against the working directory; specs compare by ``path``), ``scale``
    (per axis, applied in the mesh frame), ``position`` [m], ``orientation`` (wxyz)."""

    file: str = field(compare=False)
    path: str = ""
    scale: Vec3 = (1.0, 1.0, 1.0)
    position: Vec3 = (0.0, 0.0, 0.0)
    orientation: Quat = _IDQ
    name: str = ""
    friction: float | None = None  # Coulomb μ of this obstacle; None = the [contact] friction
    type = "mesh"

    def __post_init__(self) -> None:  # equality is by resolved path, not by how the file was written
        if not self.path:
            object.__setattr__(self, "path", str(Path(self.file).resolve()))


@dataclass(frozen=True)
class ContactSpec:
    """IMC contact parameters: stiffness k [N/m], delta [m], friction mu [-], friction_velocity_tol [m/s],
    margin [m] (broad-phase distance), enabled, max_penetration [m] (penetration guard: a (sub)step ending
    deeper is retried with more sub-steps; None = 4 * delta), step_limit
    (continuous check of every Newton update against the contact candidates: no update may carry a rod edge
    through an obstacle or push a penetrating pair more than delta deeper; on by default)."""

    stiffness: float = 1e6
    delta: float = 5e-3
    friction: float = 0.0
    friction_velocity_tol: float = 1e-2
    margin: float = 5e-2
    enabled: bool = True
    max_penetration: float | None = None
    step_limit: bool = True
    self_contact: bool = False          # edges of one rod touch each other (sim/contact/edge_pairs.py)
    rod_contact: bool | None = None     # edges of different rods touch; None: on when there are several rods


_KEYS = {
    "plane": {"point", "normal"},
    "sphere": {"center", "radius"},
    "capsule": {"start", "end", "radius"},
    "cylinder": {"start", "end", "radius"},
    "box": {"position", "orientation", "half_extents"},
    "mesh": {"file", "scale", "position", "orientation"},
}


def _take_quat(t: Mapping[str, Any], key: str, p: str, path: str | None) -> Quat:
    v = t.get(key, list(_IDQ))
    where = f"{path or '<scene>'}: {p}{key}"
    if (not isinstance(v, (list, tuple)) or len(v) != 4
            or not all(isinstance(c, (int, float)) and not isinstance(c, bool) for c in v)):
        raise SceneError(f"{where}: expected a quaternion [w, x, y, z] of 4 numbers, got {v!r}")
    q = unit_vector(v, where)  # scaled first: no overflow for huge components (sim/scene/validate.py)
    return (q[0], q[1], q[2], q[3])


def _unit(v: Vec3, where: str) -> Vec3:
    u = unit_vector(v, where)
    return (u[0], u[1], u[2])


def _parse_one(t: Mapping[str, Any], i: int, scene_path: str | None) -> ObstacleSpec:
    spec = _parse_shape(t, i, scene_path)
    if "friction" in t:
        spec = replace(spec, friction=take_float(t, "friction", f"obstacle[{i}].", scene_path, nonnegative=True))
    return spec


def _parse_shape(t: Mapping[str, Any], i: int, scene_path: str | None) -> ObstacleSpec:
    p = f"obstacle[{i}]."
    where = f"{scene_path or '<scene>'}: {p}"
    typ = take_str(t, "type", p, scene_path, choices=tuple(_KEYS))
    check_unknown(t, _KEYS[typ] | {"type", "name", "friction"}, p, scene_path)
    name = take_str(t, "name", p, scene_path, "")
    if typ == "plane":
        return PlaneSpec(point=take_vec3(t, "point", p, scene_path),
                         normal=_unit(take_vec3(t, "normal", p, scene_path), where + "normal"), name=name)
    if typ == "sphere":
        return SphereSpec(center=take_vec3(t, "center", p, scene_path),
                          radius=take_float(t, "radius", p, scene_path, positive=True), name=name)
    if typ == "capsule":
        a = take_vec3(t, "start", p, scene_path)
        b = take_vec3(t, "end", p, scene_path)
        return CapsuleSpec(start=a, end=b, radius=take_float(t, "radius", p, scene_path, positive=True), name=name)
    if typ == "cylinder":
        a = take_vec3(t, "start", p, scene_path)
        b = take_vec3(t, "end", p, scene_path)
        if not float(np.linalg.norm(np.subtract(b, a))) > 0.0:
            raise SceneError(f"{where}end: must differ from start (the cylinder's axis), got {list(b)}")
        return CylinderSpec(start=a, end=b, radius=take_float(t, "radius", p, scene_path, positive=True), name=name)
    if typ == "box":
        h = take_vec3(t, "half_extents", p, scene_path)
        if min(h) <= 0:
            raise SceneError(f"{where}half_extents: all must be > 0, got {list(h)}")
        return BoxSpec(position=take_vec3(t, "position", p, scene_path), half_extents=h,
                       orientation=_take_quat(t, "orientation", p, scene_path), name=name)
    f = take_str(t, "file", p, scene_path)
    sc = t.get("scale", 1.0)
    if isinstance(sc, (int, float)) and not isinstance(sc, bool):
        scale = (float(sc),) * 3
    else:
        scale = take_vec3(t, "scale", p, scene_path)
    if not all(np.isfinite(scale)) or min(scale) <= 0:
        raise SceneError(f"{where}scale: must be > 0 (a number or 3 numbers), got {sc!r}")
    base = Path(scene_path).parent if scene_path else Path.cwd()
    resolved = Path(f) if os.path.isabs(f) else (base / f)
    try:
        load_mesh_triangles(resolved, scale)
    except MeshError as exc:
        raise SceneError(f"{where}file: {exc}") from None
    return MeshSpec(file=f, path=str(resolved.resolve()), scale=(scale[0], scale[1], scale[2]),
                    position=take_vec3(t, "position", p, scene_path, (0.0, 0.0, 0.0)),
                    orientation=_take_quat(t, "orientation", p, scene_path), name=name)


def parse_obstacles(tables: Sequence[Mapping[str, Any]], scene_path: str | None) -> tuple[ObstacleSpec, ...]:
    """Parse the ``[[obstacle]]`` array of tables; mesh files are loaded and validated here."""
    return tuple(_parse_one(t, i, scene_path) for i, t in enumerate(tables))


def parse_contact(table: Mapping[str, Any] | None, scene_path: str | None) -> ContactSpec:
    """Parse the optional ``[contact]`` table."""
    if table is None:
        return ContactSpec()
    p = "contact."
    check_unknown(table, {"stiffness", "delta", "friction", "friction_velocity_tol", "margin", "enabled",
                          "max_penetration", "step_limit", "self_contact", "rod_contact"}, p, scene_path)
    d = ContactSpec()
    return ContactSpec(
        stiffness=take_float(table, "stiffness", p, scene_path, d.stiffness, positive=True),
        delta=take_float(table, "delta", p, scene_path, d.delta, positive=True),
        friction=take_float(table, "friction", p, scene_path, d.friction, nonnegative=True),
        friction_velocity_tol=take_float(table, "friction_velocity_tol", p, scene_path, d.friction_velocity_tol,
                                         positive=True),
        margin=take_float(table, "margin", p, scene_path, d.margin, nonnegative=True),
        enabled=take_bool(table, "enabled", p, scene_path, d.enabled),
        step_limit=take_bool(table, "step_limit", p, scene_path, d.step_limit),
        self_contact=take_bool(table, "self_contact", p, scene_path, d.self_contact),
        rod_contact=take_bool(table, "rod_contact", p, scene_path, True) if "rod_contact" in table else None,
        max_penetration=(take_float(table, "max_penetration", p, scene_path, positive=True)
                         if "max_penetration" in table else None),
    )


def dump_obstacles(obstacles: Sequence[ObstacleSpec], *, base_dir: str | os.PathLike | None = None) -> list[str]:
    """TOML lines for the obstacles. Mesh ``file`` is written as loaded, or relative to ``base_dir``."""
    lines: list[str] = []
    for ob in obstacles:
        if lines:
            lines.append("")
        lines += ["[[obstacle]]", f"type = {format_value(ob.type)}"]  # type: ignore[attr-defined]
        if getattr(ob, "name", ""):
            lines.append(f"name = {format_value(ob.name)}")  # type: ignore[attr-defined]
        if getattr(ob, "friction", None) is not None:
            lines.append(f"friction = {format_value(float(ob.friction))}")  # type: ignore[attr-defined]
        if isinstance(ob, MeshSpec):
            f = ob.file
            if base_dir is not None and ob.path:
                f = os.path.relpath(ob.path, base_dir)
            lines.append(f"file = {format_value(f)}")
            sc = ob.scale[0] if ob.scale[0] == ob.scale[1] == ob.scale[2] else ob.scale
            lines += [f"scale = {format_value(sc)}", f"position = {format_value(ob.position)}",
                      f"orientation = {format_value(ob.orientation)}"]
            continue
        for key in sorted(_KEYS[ob.type]):  # type: ignore[attr-defined]
            lines.append(f"{key} = {format_value(getattr(ob, key))}")
    return lines


def dump_contact(contact: ContactSpec) -> list[str]:
    """TOML lines for the ``[contact]`` table."""
    lines = ["[contact]"]
    for k in ("stiffness", "delta", "friction", "friction_velocity_tol", "margin", "enabled", "step_limit"):
        lines.append(f"{k} = {format_value(getattr(contact, k))}")
    if contact.self_contact:
        lines.append("self_contact = true")
    if contact.rod_contact is not None:  # omitted = on with several rods
        lines.append(f"rod_contact = {format_value(bool(contact.rod_contact))}")
    if contact.max_penetration is not None:  # omitted = 4 * delta (follows delta)
        lines.append(f"max_penetration = {format_value(float(contact.max_penetration))}")
    return lines

