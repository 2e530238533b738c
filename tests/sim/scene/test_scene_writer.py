"""Scene writer: plain TOML numbers (never ``np.float64(...)``), atomic save with the usual file mode, and
load -> dump -> load round trips for random scenes with every obstacle kind and for every shipped scene."""
from __future__ import annotations

import dataclasses
import os
import stat
import tomllib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sim import dump_scene, load_scene
from sim.scene import obstacles as so
from sim.scene.spec import scene_to_toml

REPO = Path(__file__).resolve().parents[3]
SCENES = sorted((REPO / "assets" / "scenes").glob("*.toml"))
MESH = REPO / "assets" / "meshes" / "unit_box.obj"


def _reload(spec, folder: Path, name: str):
    out = folder / name
    dump_scene(spec, out)
    return load_scene(out), out.read_text()


def test_every_shipped_scene_is_covered():
    names = {p.name for p in SCENES}
    assert {"default.toml", "arm.toml", "mesh_course.toml"} <= names


@pytest.mark.parametrize("path", SCENES, ids=lambda p: p.name)
def test_shipped_scene_round_trip(tmp_path, path):
    spec = load_scene(path)
    spec1, text1 = _reload(spec, tmp_path, "a.toml")
    assert "np." not in text1 and "float64" not in text1
    assert spec1.sim == spec.sim and spec1.rods == spec.rods and spec1.contact == spec.contact
    assert spec1.obstacles == spec.obstacles
    spec2, text2 = _reload(spec1, tmp_path, "b.toml")
    assert spec2.obstacles == spec1.obstacles and text2 == text1


def test_numpy_scalars_are_written_as_plain_numbers(tmp_path):
    """The workbench builds specs from numpy arrays: a capsule end as np.float64 used to be written as
    ``np.float64(0.35)``, which no TOML reader accepts."""
    base = load_scene(REPO / "assets" / "scenes" / "default.toml")
    caps = so.CapsuleSpec(start=tuple(np.array([0.35, -0.2, 0.4])), end=tuple(np.array([0.35, 0.2, 0.4])),
                          radius=np.float64(0.03), name="bar")
    spec = dataclasses.replace(base, obstacles=(caps,),
                               sim=dataclasses.replace(base.sim, newton_max_iter=np.int64(5)))
    text = scene_to_toml(spec)
    assert "np." not in text
    doc = tomllib.loads(text)
    assert doc["obstacle"][0]["start"] == [0.35, -0.2, 0.4] and doc["sim"]["newton_max_iter"] == 5
    spec1, _ = _reload(spec, tmp_path, "caps.toml")
    assert spec1.obstacles[0] == caps


def test_save_is_atomic_with_the_usual_mode(tmp_path):
    spec = load_scene(REPO / "assets" / "scenes" / "default.toml")
    target = tmp_path / "mine.toml"
    target.write_text("old")
    os.chmod(target, 0o600)
    old = os.umask(0o022)
    try:
        dump_scene(spec, target)
    finally:
        os.umask(old)
    assert stat.S_IMODE(target.stat().st_mode) == 0o644
    assert load_scene(target).rod == spec.rod
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine.toml"]  # no temporary file left behind
    # a failing write leaves the old file untouched and no temporary file
    bad = dataclasses.replace(spec, sim=dataclasses.replace(spec.sim, dt=float("nan")))
    with pytest.raises(ValueError):
        dump_scene(bad, target)
    assert load_scene(target).rod == spec.rod
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine.toml"]


# ------------------------------------------------------------------ random scenes (hypothesis)
coord = st.floats(-2.0, 2.0, allow_nan=False, allow_infinity=False)
size = st.floats(1e-3, 0.5, allow_nan=False, allow_infinity=False)
as_np = st.booleans()


def vec3(draw_np: bool):
    return st.tuples(coord, coord, coord).map(lambda v: tuple(np.array(v)) if draw_np else v)


@st.composite
def unit_quat(draw):
    q = np.array(draw(st.tuples(coord, coord, coord, coord)))
    if np.linalg.norm(q) < 1e-3:
        q = np.array([1.0, 0.0, 0.0, 0.0])
    return tuple(float(v) for v in q / np.linalg.norm(q))


@st.composite
def obstacle(draw):
    kind = draw(st.sampled_from(sorted(so.KIND_CODES)))
    npy = draw(as_np)
    name = draw(st.text(st.characters(codec="utf-8", exclude_categories=("Cs",)), max_size=12))
    if kind == "plane":
        n = np.array(draw(st.tuples(coord, coord, coord)))
        n = n / np.linalg.norm(n) if np.linalg.norm(n) > 1e-3 else np.array([0.0, 0.0, 1.0])
        return so.PlaneSpec(point=draw(vec3(npy)), normal=tuple(float(v) for v in n), name=name)
    if kind == "sphere":
        return so.SphereSpec(center=draw(vec3(npy)), radius=draw(size), name=name)
    if kind == "capsule":
        return so.CapsuleSpec(start=draw(vec3(npy)), end=draw(vec3(npy)),
                              radius=np.float64(draw(size)) if npy else draw(size), name=name)
    if kind == "box":
        return so.BoxSpec(position=draw(vec3(npy)), half_extents=draw(st.tuples(size, size, size)),
                          orientation=draw(unit_quat()), name=name)
    s = draw(size)
    return so.MeshSpec(file=str(MESH), scale=(s, s, s) if draw(st.booleans()) else draw(st.tuples(size, size, size)),
                       position=draw(vec3(npy)), orientation=draw(unit_quat()), name=name)


@st.composite
def scene(draw):
    base = load_scene(REPO / "assets" / "scenes" / draw(st.sampled_from(["default.toml", "arm.toml"])))
    sim = dataclasses.replace(base.sim, dt=draw(st.floats(1e-5, 0.1)), damping=draw(st.floats(0.0, 10.0)),
                              newton_max_iter=draw(st.integers(1, 50)))
    rod = dataclasses.replace(base.rod, length=draw(st.floats(0.1, 3.0)), radius=draw(st.floats(1e-3, 0.1)))
    contact = dataclasses.replace(base.contact, friction=draw(st.floats(0.0, 2.0)),
                                  max_penetration=draw(st.none() | st.floats(1e-4, 0.1)))
    return dataclasses.replace(base, sim=sim, rod=rod, contact=contact,
                               obstacles=tuple(draw(st.lists(obstacle(), max_size=6))))


UNIT_FIELDS = {"normal", "orientation"}  # re-normalised by the loader: may move by an ulp per reload


def assert_same_obstacles(a_list, b_list, *, rtol: float) -> None:
    assert len(a_list) == len(b_list)
    for a, b in zip(a_list, b_list):
        assert type(a) is type(b) and a.name == b.name
        for f in dataclasses.fields(a):
            va, vb = getattr(a, f.name), getattr(b, f.name)
            if f.name == "file":
                continue
            if isinstance(vb, tuple):
                tol = max(rtol, 1e-15) if f.name in UNIT_FIELDS else rtol
                np.testing.assert_allclose(np.asarray(va, float), np.asarray(vb, float), rtol=tol, atol=tol)
            else:
                assert va == vb or np.isclose(va, vb, rtol=rtol, atol=0.0), (f.name, va, vb)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(spec=scene())
def test_random_scene_round_trip(tmp_path, spec):
    spec1, text1 = _reload(spec, tmp_path, "r1.toml")
    assert "np." not in text1
    assert spec1.sim == spec.sim and spec1.rods == spec.rods and spec1.contact == spec.contact
    assert_same_obstacles(spec.obstacles, spec1.obstacles, rtol=1e-12)
    spec2, _ = _reload(spec1, tmp_path, "r2.toml")
    assert spec2.sim == spec1.sim and spec2.rod == spec1.rod and spec2.contact == spec1.contact
    assert_same_obstacles(spec1.obstacles, spec2.obstacles, rtol=0.0)
