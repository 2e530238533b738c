"""Layout of a rodlab recording (.rrd): data classes, entity paths and scales shared by the
recorder and the reader. No rerun import here (importing this module is cheap).

File layout (schema version 1)
------------------------------
One ``.rrd`` file holds **one rerun recording per episode** (application id ``rodlab``,
recording id ``<run id>/env<e>/ep<k>``, recording name ``"<task> ep<k> env<e>"``). The rerun
viewer lists the episodes in its recordings panel; :func:`policies.recording.read_recording`
returns them as separate :class:`EpisodeData`, sorted by episode index.

Inside every recording (all positions in metres, world frame, z up):

==================================  ===========================================================
``/__properties/episode``           metadata: task, seed, policy, scene, env, episode,
                                    rodlab_version, git_commit, force_scale, frame_scale, ...
``/__properties/rods``              layout of a scene of several rods (docs/physics.md §1.7):
                                    ``node_offsets`` (R+1,) int64, each rod's first node in the
                                    centreline, then N; ``names`` (R,) str. Absent: one rod
                                    (older recordings have none)
``world/obstacles/{capsules,spheres,boxes}``, ``world/obstacles/mesh_<i>``  static geometry
``world/rod``                       LineStrips3D: centreline (N, 3), radius = rod radius; with
                                    several rods one strip per rod (node_offsets), whose points
                                    in order are the chain of all their nodes
``world/rod/m1``, ``world/rod/m2``  Arrows3D at edge midpoints: material directors x frame_scale
                                    (one per edge; zero length on the joint edges between rods)
``world/rod/d1``, ``world/rod/d2``  same for the reference frame (optional)
``world/contacts``                  Points3D at the rod contact points + raw ``normal_force`` [N],
                                    ``edge``, ``obstacle``, ``partner_edge`` (AnyValues components; a row
                                    of two touching edges: obstacle -1, partner_edge the other edge)
``world/contacts/normal``           Arrows3D: unit normal (other body -> rod) x frame_scale
``world/contacts/normal_force``     Arrows3D: normal x normal force [N] x force_scale [m/N]
``world/contacts/friction_force``   Arrows3D: friction force [N] x force_scale
``world/target``                    Transform3D (translation, quaternion x y z w) per step;
                                    static marker + axes below it
``curvature/kappa1/{commanded,actual}``  LineStrips2D: (s, -kappa) per node, s = node/(N-1)
                                    (y negated because 2-D views draw +y downwards)
``curvature/kappa2/...``, ``curvature/twist/...``  likewise (only what was logged)
``scalars/<name>``                  Scalars, one entity per name (``reward``,
                                    ``reward_terms/<term>``, ``tip_error``, ``energy/<kind>``,
                                    ``solver/newton_iters``, ``solver/residual``,
                                    ``solver/converged``, ``solver/wall_time``, ...)
``events``                          TextLog at the frames of the episode's events (``policies.recording.events``:
                                    episode start/end, first contact, failed and unconverged steps,
                                    reward spikes, pulls, take-overs), found from the scalars
==================================  ===========================================================

The first episode of a file also carries a default viewer layout (blueprint).

Timelines: ``control_step`` (sequence, 0 = first logged frame of the episode), ``sim_time``
(duration, seconds since reset) and, only when frames were logged per simulation step,
``sim_step`` (sequence). Several frames may share a ``control_step`` (per-sim-step logging).
"""
from __future__ import annotations

import functools
import os
import re
import subprocess
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

SCHEMA_VERSION = 1
APPLICATION_ID = "rodlab"

ROD = "world/rod"
FRAME_ENTITIES = ("m1", "m2", "d1", "d2")          # world/rod/<name>
CONTACTS = "world/contacts"
CONTACT_ARROWS = ("normal", "normal_force", "friction_force")   # world/contacts/<name>
TARGET = "world/target"
OBSTACLES = "world/obstacles"
CURVATURE = "curvature"
CURVATURE_KINDS = ("kappa1", "kappa2", "twist")
SCALARS = "scalars"
EVENTS = "events"
META_PROPERTY = "episode"
RODS_PROPERTY = "rods"       # /__properties/rods: node_offsets, names (absent: one rod)

#: Scalar names the recorder documents (others are allowed; names are ``[A-Za-z0-9_./-]``).
STANDARD_SCALARS = (
    "reward", "tip_error", "ori_error",
    "energy/stretch", "energy/bend", "energy/twist", "energy/contact", "energy/kinetic", "energy/gravity",
    "solver/newton_iters", "solver/residual", "solver/converged", "solver/failed", "solver/substeps",
    "solver/midpoint_fallbacks", "solver/wall_time",
    "contact/count", "contact/max_normal_force", "contact/max_penetration", "contact/dropped", "contact/net_force",
    "hand/pull_force", "hand/take_over",
)
_SCALAR_NAME = re.compile(r"^[A-Za-z0-9_.\-]+(/[A-Za-z0-9_.\-]+)*$")

CURVE_Y_SIGN = -1.0          # curvature strips store y = -value (rerun 2-D views draw +y downwards)
DEFAULT_FORCE_SCALE = 2e-4   # m of arrow per N of contact force (1 kN -> 0.2 m; penalty forces reach kN)
DEFAULT_FRAME_SCALE = 0.1    # m of arrow for a unit director / normal (sticks out of the 0.05 m rod tube)


class RecordingError(ValueError):
    """Bad input to the recorder or an unreadable recording; the message names the problem."""


def check_scalar_name(name: str) -> str:
    if not isinstance(name, str) or not _SCALAR_NAME.match(name):
        raise RecordingError(f"scalar name {name!r}: use letters, digits, '_', '.', '-' separated by '/'")
    return name


@dataclass(frozen=True)
class StaticScene:
    """Geometry that is constant during one episode (world frame, metres).

    capsules: (K, 2, 3) axis end points (start, end) and ``capsule_radii`` (K,);
    spheres: ``sphere_centers`` (K, 3), ``sphere_radii`` (K,);
    boxes: ``box_centers`` (K, 3), ``box_half_sizes`` (K, 3), ``box_quats`` (K, 4) x y z w or None;
    meshes: tuple of (vertices (V, 3) float, faces (F, 3) int);
    rod_radius: cross-section radius of the rod [m]; planar: True for the x-z 2D tasks;
    rod_node_offsets: (R+1,) int where each rod's nodes start in the centreline, then N
    (``sim.Model.rod_node_offsets``), or None for one rod; rod_names: (R,) names of the rods (may be empty).
    """

    rod_radius: float = 0.05
    capsules: np.ndarray | None = None
    capsule_radii: np.ndarray | None = None
    sphere_centers: np.ndarray | None = None
    sphere_radii: np.ndarray | None = None
    box_centers: np.ndarray | None = None
    box_half_sizes: np.ndarray | None = None
    box_quats: np.ndarray | None = None
    meshes: tuple[tuple[np.ndarray, np.ndarray], ...] = ()
    planar: bool = False
    rod_node_offsets: np.ndarray | None = None
    rod_names: tuple[str, ...] = ()

    def validated(self) -> "StaticScene":
        """Return a copy with float64/int arrays of checked shapes (RecordingError otherwise)."""
        def arr(name: str, shape_tail: tuple[int, ...], dtype=np.float64) -> np.ndarray | None:
            v = getattr(self, name)
            if v is None:
                return None
            a = np.asarray(v, dtype=dtype)
            if a.ndim != 1 + len(shape_tail) or tuple(a.shape[1:]) != shape_tail:
                raise RecordingError(f"StaticScene.{name}: expected shape (K, {', '.join(map(str, shape_tail))})"
                                     f" got {a.shape}".replace(", )", ")"))
            return a

        caps, crad = arr("capsules", (2, 3)), arr("capsule_radii", ())
        sc, sr = arr("sphere_centers", (3,)), arr("sphere_radii", ())
        bc, bh, bq = arr("box_centers", (3,)), arr("box_half_sizes", (3,)), arr("box_quats", (4,))
        for a, b, what in ((caps, crad, "capsules/capsule_radii"), (sc, sr, "sphere_centers/sphere_radii"),
                           (bc, bh, "box_centers/box_half_sizes")):
            if (a is None) != (b is None) or (a is not None and len(a) != len(b)):
                raise RecordingError(f"StaticScene.{what}: give both with the same length K")
        if bq is not None and (bc is None or len(bq) != len(bc)):
            raise RecordingError("StaticScene.box_quats: needs box_centers of the same length")
        meshes = []
        for i, m in enumerate(self.meshes):
            try:
                v, f = m
            except (TypeError, ValueError):
                raise RecordingError(f"StaticScene.meshes[{i}]: expected (vertices, faces)") from None
            v, f = np.asarray(v, np.float64), np.asarray(f, np.int64)
            if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3:
                raise RecordingError(f"StaticScene.meshes[{i}]: vertices (V, 3) and faces (F, 3), got "
                                     f"{v.shape} and {f.shape}")
            meshes.append((v, f))
        r = float(self.rod_radius)
        if not np.isfinite(r) or r <= 0:
            raise RecordingError(f"StaticScene.rod_radius: must be > 0, got {self.rod_radius!r}")
        off, names = check_rod_layout(self.rod_node_offsets, self.rod_names)
        return StaticScene(rod_radius=r, capsules=caps, capsule_radii=crad, sphere_centers=sc, sphere_radii=sr,
                           box_centers=bc, box_half_sizes=bh, box_quats=bq, meshes=tuple(meshes),
                           planar=bool(self.planar), rod_node_offsets=off, rod_names=names)

    @property
    def n_obstacles(self) -> int:
        return sum(0 if a is None else len(a) for a in (self.capsules, self.sphere_centers, self.box_centers)) \
            + len(self.meshes)


def check_rod_layout(offsets: Any, names: Any = ()) -> tuple[np.ndarray | None, tuple[str, ...]]:
    """``(offsets as int64 (R+1,) or None, names as a tuple)`` of a rod layout, checked: offsets start at 0 and
    grow by at least 2 nodes per rod; names empty or one per rod. RecordingError otherwise."""
    names = tuple(str(n) for n in (names or ()))
    if offsets is None:
        if len(names) > 1:
            raise RecordingError("StaticScene.rod_names: several names need rod_node_offsets")
        return None, names
    try:
        off = np.array(offsets, dtype=np.int64, copy=True)
    except (TypeError, ValueError):
        raise RecordingError(f"StaticScene.rod_node_offsets: not integers ({offsets!r})") from None
    if off.ndim != 1 or len(off) < 2 or off[0] != 0 or np.any(np.diff(off) < 2):
        raise RecordingError("StaticScene.rod_node_offsets: expected (R+1,) node indices starting at 0, at least "
                             f"2 nodes per rod, got {off.tolist()}")
    if names and len(names) != len(off) - 1:
        raise RecordingError(f"StaticScene.rod_names: {len(names)} names for {len(off) - 1} rods")
    off.setflags(write=False)
    return off, names


@dataclass
class EpisodeData:
    """One recorded episode read back from a .rrd (S frames, N nodes, Cmax max contacts per frame).

    Arrays are float32 as stored (scalars float64). ``None`` where the quantity was not logged.
    positions (S, N, 3); m1, m2, d1, d2 (S, N-1, 3); contact_count (S,) and padded contact arrays
    contact_points/contact_normals/contact_friction (S, Cmax, 3), contact_normal_force (S, Cmax),
    contact_edge/contact_obstacle/contact_partner_edge (S, Cmax) int (-1 padding; a row of an edge pair has
    obstacle -1 and the other edge as partner, an obstacle's row partner -1); kappa_bar/kappa (S, N, k) with
    k = 1 or 2, tau_bar/tau (S, N); target_pos (S, 3), target_quat (S, 4) x y z w; scalars: name -> (S,) float64
    (NaN on frames where that scalar was not logged); control_step, sim_step (S,) int64, sim_time (S,) [s].
    """

    meta: dict[str, Any]
    scene: StaticScene
    control_step: np.ndarray
    sim_time: np.ndarray
    positions: np.ndarray
    sim_step: np.ndarray | None = None
    m1: np.ndarray | None = None
    m2: np.ndarray | None = None
    d1: np.ndarray | None = None
    d2: np.ndarray | None = None
    contact_count: np.ndarray | None = None
    contact_points: np.ndarray | None = None
    contact_normals: np.ndarray | None = None
    contact_normal_force: np.ndarray | None = None
    contact_friction: np.ndarray | None = None
    contact_edge: np.ndarray | None = None
    contact_obstacle: np.ndarray | None = None
    contact_partner_edge: np.ndarray | None = None
    kappa_bar: np.ndarray | None = None
    kappa: np.ndarray | None = None
    tau_bar: np.ndarray | None = None
    tau: np.ndarray | None = None
    target_pos: np.ndarray | None = None
    target_quat: np.ndarray | None = None
    scalars: dict[str, np.ndarray] = field(default_factory=dict)
    events: list[tuple[int, str]] = field(default_factory=list)
    recording_id: str = ""

    @property
    def steps(self) -> int:
        """Number of frames S."""
        return int(self.positions.shape[0])

    @property
    def rod_node_offsets(self) -> np.ndarray:
        """(R+1,) where each rod's nodes start in ``positions``, then N: the recorded layout, or ``[0, N]`` (one
        rod) for a recording without one."""
        off = self.scene.rod_node_offsets
        return np.array([0, self.positions.shape[1]], np.int64) if off is None else np.asarray(off, np.int64)

    @property
    def episode_return(self) -> float:
        """Sum of the ``reward`` scalar (NaN frames ignored); NaN if no reward was logged."""
        r = self.scalars.get("reward")
        return float(np.nansum(r)) if r is not None and np.isfinite(r).any() else float("nan")

    @property
    def max_contact_force(self) -> float:
        """Largest normal contact force over the episode [N] (0 if no contacts were logged)."""
        if self.contact_normal_force is None or self.contact_normal_force.size == 0:
            return 0.0
        return float(np.nanmax(np.abs(self.contact_normal_force)))


def sanitize_meta(meta: dict[str, Any]) -> dict[str, Any]:
    """Metadata values as str/int/float/bool (others become their str())."""
    out: dict[str, Any] = {}
    for k, v in meta.items():
        if not isinstance(k, str) or not re.match(r"^[A-Za-z_][A-Za-z0-9_]*$", k):
            raise RecordingError(f"metadata key {k!r}: use an identifier (letters, digits, '_')")
        if v is None:
            v = ""
        elif isinstance(v, (bool, np.bool_)):
            v = bool(v)
        elif isinstance(v, (int, np.integer)):
            v = int(v)
        elif isinstance(v, (float, np.floating)):
            v = float(v)
        elif not isinstance(v, str):
            v = str(v)
        out[k] = v
    return out


@functools.lru_cache(maxsize=1)
def provenance() -> dict[str, str]:
    """``rodlab_version`` and ``git_commit`` (``unknown`` outside a git checkout, ``+dirty`` suffix
    when the work tree has changes)."""
    try:
        from importlib.metadata import version
        ver = version("rodlab")
    except Exception:
        ver = "unknown"
    root = Path(__file__).resolve().parent  # git finds the work tree of a checkout from the package folder
    commit = "unknown"
    try:
        env = {**os.environ, "GIT_OPTIONAL_LOCKS": "0"}
        r = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True, text=True,
                           timeout=5, env=env)
        if r.returncode == 0 and r.stdout.strip():
            commit = r.stdout.strip()
            d = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, timeout=5, env=env)
            if d.returncode == 0 and d.stdout.strip():
                commit += "+dirty"
    except (OSError, subprocess.SubprocessError):
        pass
    return {"rodlab_version": ver, "git_commit": commit}
