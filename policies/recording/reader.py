"""Read a rodlab .rrd back into numpy arrays, one :class:`EpisodeData` per episode.

Reads chunks with ``rerun.chunk.RrdReader`` and pyarrow only (no datafusion query engine), so it
also works on files without an RRD footer. The layout is described in
:mod:`policies.recording.schema`.
"""
from __future__ import annotations

import os
import warnings
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa

from . import schema as S
from .schema import EpisodeData, RecordingError, StaticScene

__all__ = ["read_recording", "list_episodes", "summarize"]


def _open(path: str | os.PathLike[str]):
    import rerun as rr  # lazy: importing this module stays cheap
    p = Path(path)
    if not p.is_file():
        raise RecordingError(f"{p}: no such recording file")
    try:
        with warnings.catch_warnings():  # files without a footer are read by a whole-file scan (fine)
            warnings.simplefilter("ignore")
            return rr.chunk.RrdReader(str(p))
    except Exception as exc:  # rerun raises RuntimeError/ValueError with a long message
        raise RecordingError(f"{p}: not a readable .rrd file ({str(exc).splitlines()[0]})") from None


def _damaged(path: str | os.PathLike[str], exc: BaseException) -> RecordingError:
    first = (str(exc).splitlines() or [type(exc).__name__])[0]
    return RecordingError(f"{path}: not a readable .rrd file (truncated or damaged? {first})")


def _entries(reader: Any, path: str | os.PathLike[str]) -> list[Any]:
    try:
        return list(reader.recordings())
    except Exception as exc:  # rerun decodes lazily: a truncated file fails here with a RuntimeError
        raise _damaged(path, exc) from None


def list_episodes(path: str | os.PathLike[str]) -> list[str]:
    """Recording ids in the file (one per episode), in file order."""
    return [e.recording_id for e in _entries(_open(path), path)]


class _Entity:
    """Rows of one entity gathered over its chunks (temporal rows only, plus its static row)."""

    def __init__(self) -> None:
        self.batches: list[pa.RecordBatch] = []
        self.static: dict[str, Any] = {}

    def column(self, name: str) -> pa.ChunkedArray | None:
        cols = [b.column(name) for b in self.batches if name in b.schema.names]
        if not cols:
            return None
        return pa.chunked_array(cols)

    def keys(self, has_sim_step: bool) -> list[tuple[int, int, int]]:
        out: list[tuple[int, int, int]] = []
        for b in self.batches:
            cs = b.column("control_step").to_numpy()
            ns = b.column("sim_time").cast(pa.int64()).to_numpy()
            ss = b.column("sim_step").to_numpy() if has_sim_step else np.full(len(cs), -1)
            out.extend(zip(cs.tolist(), ns.tolist(), ss.tolist()))
        return out


def _ragged(col: pa.ChunkedArray, width: int) -> tuple[np.ndarray, np.ndarray]:
    """list<fixed_size_list<float>[width]> -> (counts (R,), values (sum, width))."""
    counts, values = [], []
    for ch in col.chunks:
        offs = ch.offsets.to_numpy()
        counts.append(np.diff(offs))
        vals = ch.values.slice(offs[0], offs[-1] - offs[0]) if len(offs) else ch.values
        flat = vals.flatten().to_numpy(zero_copy_only=False) if width > 1 else \
            vals.to_numpy(zero_copy_only=False)
        values.append(np.asarray(flat).reshape(-1, width) if width > 1 else np.asarray(flat))
    return np.concatenate(counts), (np.concatenate(values) if values else np.zeros((0, width)))


def _strips(col: pa.ChunkedArray, width: int) -> np.ndarray:
    """list<list<fixed_size_list[width]>> -> (R, n, width): the points of each row's strips in order (one strip
    per frame, or one per rod of a scene of several rods); every row must hold the same number of points."""
    out = []
    for ch in col.chunks:
        offs = ch.offsets.to_numpy()
        if np.any(np.diff(offs) < 1):
            raise RecordingError("a frame without a line strip")
        inner = ch.values.slice(offs[0], offs[-1] - offs[0])
        ioffs = inner.offsets.to_numpy()
        per_row = ioffs[offs[1:] - offs[0]] - ioffs[offs[:-1] - offs[0]]  # points of each row
        if len(per_row) and np.any(per_row != per_row[0]):
            raise RecordingError("line strips of different lengths in one episode")
        pts = inner.values.slice(ioffs[0], ioffs[-1] - ioffs[0]).flatten().to_numpy(zero_copy_only=False)
        out.append(np.asarray(pts, np.float32).reshape(len(per_row), -1, width))
    return np.concatenate(out) if out else np.zeros((0, 0, width), np.float32)


def _scalar_value(v: Any) -> Any:
    v = v.as_py() if hasattr(v, "as_py") else v
    if isinstance(v, list) and len(v) == 1:
        return v[0]
    return v


def _read_store(reader, entry) -> EpisodeData:
    ents: dict[str, _Entity] = defaultdict(_Entity)
    props: dict[str, Any] = {}
    rods: dict[str, Any] = {}
    rods_path = f"/__properties/{S.RODS_PROPERTY}"
    for chunk in reader.stream(store=entry).to_chunks():
        path = chunk.entity_path
        rb = chunk.to_record_batch()
        if path.startswith("/__properties"):
            for name in rb.schema.names:
                if name.startswith("rerun.controls"):
                    continue
                if path == rods_path:  # arrays, kept whole (a one-element list stays a list)
                    rods[name.split(":")[-1]] = rb.column(name)[rb.num_rows - 1].as_py()
                else:
                    props[name.split(":")[-1]] = _scalar_value(rb.column(name)[rb.num_rows - 1])
            continue
        e = ents[path.lstrip("/")]
        if chunk.is_static:
            for name in rb.schema.names:
                if not name.startswith("rerun.controls"):
                    e.static[name] = rb.column(name)[rb.num_rows - 1].as_py()
        elif rb.num_rows:
            e.batches.append(rb)
    rod = ents.get(S.ROD)
    if rod is None or not rod.batches:
        raise RecordingError(f"recording {entry.recording_id}: no rod centreline ({S.ROD}) in it")
    meta = dict(props)
    has_ss = "sim_step" in rod.batches[0].schema.names
    rkeys = rod.keys(has_ss)
    P = _strips(rod.column("LineStrips3D:strips"), 3)
    order = sorted(range(len(rkeys)), key=lambda i: rkeys[i])
    keys = [rkeys[i] for i in order]
    frame_of = {k: i for i, k in enumerate(keys)}
    nf = len(keys)
    n = P.shape[1]
    ks = np.array(keys, np.int64).reshape(nf, 3)
    scene = _scene(ents, meta, rods)
    if scene.rod_node_offsets is not None and int(scene.rod_node_offsets[-1]) != n:
        raise RecordingError(f"recording {entry.recording_id}: rod node offsets {scene.rod_node_offsets.tolist()} "
                             f"do not end at the centreline's {n} nodes")
    ep = EpisodeData(meta=meta, scene=scene, control_step=ks[:, 0], sim_time=ks[:, 1] * 1e-9,
                     positions=P[order], sim_step=ks[:, 2] if has_ss else None,
                     recording_id=entry.recording_id)
    fscale = float(meta.get("frame_scale", S.DEFAULT_FRAME_SCALE))
    force_scale = float(meta.get("force_scale", S.DEFAULT_FORCE_SCALE))

    def rows_of(ent: _Entity) -> np.ndarray:
        return np.array([frame_of[k] for k in ent.keys(has_ss)], np.int64)

    def dense(ent: _Entity, values: np.ndarray, fill: float = np.nan) -> np.ndarray:
        out = np.full((nf, *values.shape[1:]), fill, dtype=values.dtype if fill == 0 else
                      np.result_type(values.dtype, np.float32))
        out[rows_of(ent)] = values
        return out

    for name in S.FRAME_ENTITIES:
        ent = ents.get(f"{S.ROD}/{name}")
        if ent is not None and ent.batches:
            cnt, v = _ragged(ent.column("Arrows3D:vectors"), 3)
            setattr(ep, name, dense(ent, (v / fscale).reshape(len(cnt), n - 1, 3).astype(np.float32)))
    _read_contacts(ep, ents, rows_of, nf, fscale, force_scale)
    for comp in ("kappa1", "kappa2"):
        for kind, attr in (("commanded", "kappa_bar"), ("actual", "kappa")):
            ent = ents.get(f"{S.CURVATURE}/{comp}/{kind}")
            if ent is not None and ent.batches:
                y = dense(ent, S.CURVE_Y_SIGN * _strips(ent.column("LineStrips2D:strips"), 2)[..., 1])
                prev = getattr(ep, attr)
                setattr(ep, attr, y[..., None] if prev is None else np.concatenate([prev, y[..., None]], -1))
    for kind, attr in (("commanded", "tau_bar"), ("actual", "tau")):
        ent = ents.get(f"{S.CURVATURE}/twist/{kind}")
        if ent is not None and ent.batches:
            setattr(ep, attr, dense(ent, S.CURVE_Y_SIGN * _strips(ent.column("LineStrips2D:strips"), 2)[..., 1]))
    tgt = ents.get(S.TARGET)
    if tgt is not None and tgt.batches:
        _, tp = _ragged(tgt.column("Transform3D:translation"), 3)
        ep.target_pos = dense(tgt, tp.astype(np.float32))
        qc = tgt.column("Transform3D:quaternion")
        if qc is not None:
            _, q = _ragged(qc, 4)
            ep.target_quat = dense(tgt, q.astype(np.float32))
    prefix = S.SCALARS + "/"
    for path, ent in sorted(ents.items()):
        if path.startswith(prefix) and ent.batches:
            _, v = _ragged(ent.column("Scalars:scalars"), 1)
            ep.scalars[path[len(prefix):]] = dense(ent, np.asarray(v, np.float64).reshape(-1))
    ev = ents.get(S.EVENTS)
    if ev is not None and ev.batches:
        texts = ev.column("TextLog:text").to_pylist()
        ep.events = sorted((int(f), str(t[0] if isinstance(t, list) else t))
                           for f, t in zip(rows_of(ev), texts))
    return ep


def _read_contacts(ep: EpisodeData, ents, rows_of, nf: int, fscale: float, force_scale: float) -> None:
    base = ents.get(S.CONTACTS)
    if base is None or not base.batches:
        return
    cnt, pts = _ragged(base.column("Points3D:positions"), 3)
    fcol = base.column("normal_force")
    fn = _ragged(fcol, 1)[1] if fcol is not None else np.zeros(len(pts))
    rows = rows_of(base)
    cmax = int(cnt.max()) if len(cnt) else 0
    count = np.zeros(nf, np.int64)
    count[rows] = cnt
    starts = np.concatenate([[0], np.cumsum(cnt)[:-1]])

    def pad(flat: np.ndarray, width: int | None, fill: float, dtype) -> np.ndarray:
        shape = (nf, cmax) if width is None else (nf, cmax, width)
        out = np.full(shape, fill, dtype=dtype)
        for r, s, c in zip(rows, starts, cnt):
            out[r, :c] = flat[s:s + c]
        return out

    ep.contact_count = count
    ep.contact_points = pad(pts, 3, 0.0, np.float32)
    ep.contact_normal_force = pad(np.asarray(fn, np.float64), None, 0.0, np.float64)
    nrm = ents.get(f"{S.CONTACTS}/normal")
    if nrm is not None and nrm.batches:
        _, v = _ragged(nrm.column("Arrows3D:vectors"), 3)
        ep.contact_normals = pad(v / fscale, 3, 0.0, np.float32)
    fr = ents.get(f"{S.CONTACTS}/friction_force")
    if fr is not None and fr.batches:
        _, v = _ragged(fr.column("Arrows3D:vectors"), 3)
        ep.contact_friction = pad(v / force_scale, 3, 0.0, np.float32)
    for name, attr in (("edge", "contact_edge"), ("obstacle", "contact_obstacle"),
                       ("partner_edge", "contact_partner_edge")):
        col = base.column(name)
        if col is not None:
            _, v = _ragged(col, 1)
            setattr(ep, attr, pad(np.asarray(v, np.int64), None, -1, np.int64))
        elif cnt.sum() == 0:          # no contact at all: ids were not stored
            setattr(ep, attr, np.full((nf, 0), -1, np.int64))


def _scene(ents: dict[str, _Entity], meta: dict[str, Any], rods: dict[str, Any] | None = None) -> StaticScene:
    kw: dict[str, Any] = {"rod_radius": float(meta.get("rod_radius", 0.05)), "planar": bool(meta.get("planar", False))}
    if rods and rods.get("node_offsets") is not None:  # several rods; a recording without the property: one rod
        kw["rod_node_offsets"], kw["rod_names"] = S.check_rod_layout(rods["node_offsets"], rods.get("names") or ())
    o = S.OBSTACLES
    cap = ents.get(f"{o}/capsules")
    if cap is not None and "axis_points" in cap.static:
        kw["capsules"] = np.asarray(cap.static["axis_points"], np.float64).reshape(-1, 2, 3)
        kw["capsule_radii"] = np.asarray(cap.static["Capsules3D:radii"], np.float64)
    sph = ents.get(f"{o}/spheres")
    if sph is not None and "Ellipsoids3D:centers" in sph.static:
        kw["sphere_centers"] = np.asarray(sph.static["Ellipsoids3D:centers"], np.float64).reshape(-1, 3)
        kw["sphere_radii"] = np.asarray(sph.static["sphere_radii"], np.float64)
    box = ents.get(f"{o}/boxes")
    if box is not None and "Boxes3D:centers" in box.static:
        kw["box_centers"] = np.asarray(box.static["Boxes3D:centers"], np.float64).reshape(-1, 3)
        kw["box_half_sizes"] = np.asarray(box.static["Boxes3D:half_sizes"], np.float64).reshape(-1, 3)
        if box.static.get("has_box_quats") in (True, [True]):
            kw["box_quats"] = np.asarray(box.static["box_quats"], np.float64).reshape(-1, 4)
    meshes = []
    i = 0
    while f"{o}/mesh_{i}" in ents:
        m = ents[f"{o}/mesh_{i}"].static
        meshes.append((np.asarray(m["Mesh3D:vertex_positions"], np.float64).reshape(-1, 3),
                       np.asarray(m["Mesh3D:triangle_indices"], np.int64).reshape(-1, 3)))
        i += 1
    kw["meshes"] = tuple(meshes)
    return StaticScene(**kw)


def read_recording(path: str | os.PathLike[str]) -> list[EpisodeData]:
    """All episodes of a rodlab .rrd file, sorted by episode index (then recording id)."""
    reader = _open(path)
    entries = _entries(reader, path)
    if not entries:
        raise RecordingError(f"{path}: contains no recordings")
    eps = []
    for e in entries:
        try:
            eps.append(_read_store(reader, e))
        except RecordingError as exc:
            raise RecordingError(f"{path}: {exc}") from None
        except Exception as exc:  # damaged content that still decodes (missing columns, bad arrays)
            raise _damaged(path, exc) from None
    eps.sort(key=lambda ep: (int(ep.meta.get("episode", 0)), ep.recording_id))
    return eps


def summarize(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Summary used by ``rodlab inspect``: per episode task, policy, seed, env, steps, return,
    max contact force, sim time span; totals."""
    eps = read_recording(path)
    rows = []
    for ep in eps:
        m = ep.meta
        rows.append({
            "episode": int(m.get("episode", len(rows))), "env": int(m.get("env", 0)),
            "task": m.get("task", ""), "policy": m.get("policy", ""), "seed": m.get("seed", -1),
            "steps": ep.steps, "control_steps": int(len(np.unique(ep.control_step))),
            "sim_time_s": float(ep.sim_time[-1]) if ep.steps else 0.0,
            "return": ep.episode_return, "max_contact_force_N": ep.max_contact_force,
            "complete": bool(m.get("complete", True)),
            "scalars": sorted(ep.scalars),
        })
    size = Path(path).stat().st_size
    rets = [r["return"] for r in rows if np.isfinite(r["return"])]
    first = eps[0].meta if eps else {}
    return {
        "file": str(path), "bytes": size, "episodes": len(rows),
        "steps": int(sum(r["steps"] for r in rows)),
        "mean_return": float(np.mean(rets)) if rets else float("nan"),
        "max_contact_force_N": float(max((r["max_contact_force_N"] for r in rows), default=0.0)),
        "rodlab_version": first.get("rodlab_version", ""), "git_commit": first.get("git_commit", ""),
        "episode_list": rows,
    }
