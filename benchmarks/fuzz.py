"""``rodlab bench fuzz``: random bad input against the validation layer (docs/conventions.md, "Input bounds").

Each case is classified as

* ``ok``            -- accepted, and a short run left no NaN/inf in the state, observations or statistics, and
  every accepted value was kept as given (vectors: the same direction);
* ``clear_error``   -- refused with a SceneError/ValueError (or a CLI exit status 2) whose message names the
  file or field / key (``sim.dt``, ``obstacle[1].radius``, ``ctrl.kappa_bar``, ``--duration`` ...);
* ``crash``         -- any other exception, an error message naming nothing, or a traceback from a CLI;
* ``silent_wrong``  -- accepted but NaN/inf appeared, a value was changed (e.g. 2.5 read as 2), or a
  derived quantity is zero / not finite (e.g. zero mass).

Parts: ``scene`` (scene documents: the paper arm with one obstacle of each analytic kind, 1-3 random edits:
huge, tiny, negative, non-finite, wrong-type, missing or unknown keys), ``control`` (``Simulator.step`` with
random control arrays and state corruption), ``env`` (``make_vec_env`` overrides and actions), ``cli``
(``rodlab sim`` / ``record`` arguments). The same case functions drive the property test
tests/test_fuzz_properties.py (hypothesis).

    rodlab bench fuzz --n 2000 --out docs/bench/fuzz.json [--seed 0] [--parts scene,control,env,cli]
"""
from __future__ import annotations

import argparse
import contextlib
import copy
import io
import json
import math
import re
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

import rodlab_cli
from sim import STATE_FLOAT_ARRAYS
from sim.support.assets import asset_path
from sim.support.atomicio import write_text
from sim.support.paths import check_output_path
from sim.support.progress import add_progress_flag, progress_bar, progress_wanted

PARTS = ("scene", "control", "env", "cli")
OUTCOMES = ("ok", "clear_error", "crash", "silent_wrong")
WHERE = "fuzz.toml"

BASE: dict[str, Any] = {
    "sim": {"dt": 0.05, "gravity": [0.0, 0.0, -9.8], "newton_tol": 1e-3, "newton_max_iter": 2,
            "accept_unconverged": True},
    "rod": {"nodes": 21, "length": 1.0, "radius": 0.05, "density": 1000.0, "youngs_modulus": 1e7,
            "poisson_ratio": 0.5, "start": [0.0, 0.0, 0.0], "direction": [0.0, 0.0, 1.0]},
    "obstacle": [
        {"type": "sphere", "center": [0.6, 0.0, 0.8], "radius": 0.1},
        {"type": "capsule", "start": [-0.6, -0.2, 0.5], "end": [-0.6, 0.2, 0.5], "radius": 0.05},
        {"type": "plane", "point": [0.0, 0.0, -0.5], "normal": [0.0, 0.0, 1.0]},
        {"type": "box", "position": [0.0, 0.7, 0.5], "half_extents": [0.1, 0.1, 0.1],
         "orientation": [1.0, 0.0, 0.0, 0.0]},
    ],
    "contact": {"stiffness": 1e6, "delta": 5e-3, "margin": 5e-2},
}
# every editable key: (table, obstacle index or None, key)
KEYS: list[tuple[str, int | None, str]] = (
    [("sim", None, k) for k in ("dt", "gravity", "newton_tol", "newton_max_iter", "accept_unconverged", "damping",
                                "mode", "integrator", "line_search", "newton_dtol", "divergence_guard")]
    + [("rod", None, k) for k in ("nodes", "length", "radius", "density", "youngs_modulus", "poisson_ratio",
                                  "start", "direction", "clamp")]
    + [("obstacle", i, k) for i, ob in enumerate(BASE["obstacle"]) for k in ob if k != "type"]
    + [("contact", None, k) for k in ("stiffness", "delta", "friction", "friction_velocity_tol", "margin",
                                      "max_penetration", "enabled", "step_limit")]
)
NASTY: list[Any] = [0, -1, 1, 2.5, 3, 1e-300, 5e-324, 1e-9, 1e200, 1.7e308, -1e200, math.nan, math.inf, -math.inf,
                    2 ** 62, -(2 ** 62), 10_001, True, False, "x", "2d", "", [], [1.0, 2.0], [0, 0, 0], [0, 0, 1e200],
                    [1e300, 1e300, 0, 0], [math.nan, 0, 0], [1e-300, 0, 0], [0, 1, 0, 0], None, {"a": 1}]


# ----------------------------------------------------------------------------------------------- scene
def random_value(rng: np.random.Generator, current: Any) -> Any:
    """A random replacement for a value: from the nasty pool, or the current value scaled wildly."""
    r = rng.random()
    if r < 0.45:
        return copy.deepcopy(NASTY[int(rng.integers(len(NASTY)))])
    if isinstance(current, bool):
        return not current
    if isinstance(current, int):
        return int(current * 10 ** rng.uniform(-1, 1.2)) * int(rng.choice([1, -1], p=[0.9, 0.1]))
    if isinstance(current, float):
        return float(current * 10 ** rng.uniform(-12, 12) * rng.choice([1.0, -1.0], p=[0.85, 0.15]))
    if isinstance(current, list):
        return [float(c + rng.normal() * 10 ** rng.uniform(-6, 6)) for c in current]
    return copy.deepcopy(NASTY[int(rng.integers(len(NASTY)))])


def random_scene(rng: np.random.Generator) -> tuple[dict, list[tuple]]:
    """(scene document, edits) with 1-3 random edits of BASE (value, deletion or unknown key)."""
    doc = copy.deepcopy(BASE)
    edits = []
    for _ in range(int(rng.integers(1, 4))):
        table, idx, key = KEYS[int(rng.integers(len(KEYS)))]
        t = doc[table][idx] if idx is not None else doc[table]
        r = rng.random()
        if r < 0.07:
            t.pop(key, None)
            edits.append((table, idx, key, "<deleted>"))
        elif r < 0.1:
            t[key + "_typo"] = 1.0
            edits.append((table, idx, key + "_typo", 1.0))
        else:
            v = random_value(rng, t.get(key, BASE[table][idx][key] if idx is not None else BASE[table].get(key, 1.0)))
            t[key] = v
            edits.append((table, idx, key, v))
    return doc, edits


_KEY_RE = re.compile(r"\b(sim|rod|contact|obstacle)(\[\d+\])?(\.\w+)?")


def _names_a_key(msg: str) -> bool:
    return msg.startswith(WHERE + ": ") and bool(_KEY_RE.search(msg[len(WHERE):]))


def _same_direction(a: Any, b: Any) -> bool:
    a, b = np.asarray(a, float), np.asarray(b, float)
    big = np.max(np.abs(a))
    return bool(big > 0 and np.allclose(a / big / np.linalg.norm(a / big), b, atol=1e-9))


def _kept_as_given(spec: Any, doc: dict) -> str:
    """'' when every value of ``doc`` is what ``spec`` holds, else the first difference."""
    rods = doc.get("rod") or {}
    rods = rods if isinstance(rods, list) else [rods]  # [rod], or [[rod]] tables (several rods)
    tables = [("sim", spec.sim, doc.get("sim") or {}), ("contact", spec.contact, doc.get("contact") or {})]
    tables += [("rod", r, t) for t, r in zip(rods, spec.rods)]
    for table, obj, given in tables:
        for k, v in given.items():
            got = getattr(obj, k, None)
            if k in ("direction",):
                if not _same_direction(v, got):
                    return f"{table}.{k}: {v!r} became {got!r}"
            elif isinstance(v, list):
                if [float(x) for x in v] != [float(x) for x in got]:
                    return f"{table}.{k}: {v!r} became {got!r}"
            elif v != got:
                return f"{table}.{k}: {v!r} became {got!r}"
    for i, (t, ob) in enumerate(zip(doc.get("obstacle", []), spec.obstacles)):
        for k, v in t.items():
            if k in ("type", "name"):
                continue
            got = getattr(ob, k)
            if k in ("normal", "orientation"):
                if not _same_direction(v, got):
                    return f"obstacle[{i}].{k}: {v!r} became {got!r}"
            elif isinstance(v, list) and [float(x) for x in v] != [float(x) for x in got]:
                return f"obstacle[{i}].{k}: {v!r} became {got!r}"
            elif not isinstance(v, list) and float(v) != float(got):
                return f"obstacle[{i}].{k}: {v!r} became {got!r}"
    return ""


def _finite_run(sim: Any, steps: int, ctrl: Any = None, rng: np.random.Generator | None = None) -> str:
    """'' when ``steps`` steps left state and statistics finite, else what was not."""
    state = sim.reset()
    ctrl = ctrl if ctrl is not None else sim.make_control()
    for _ in range(steps):
        st = sim.step(state, ctrl)
        for name in STATE_FLOAT_ARRAYS:
            if not np.isfinite(getattr(state, name)).all():
                return f"state.{name} not finite"
        for name, a in vars(st).items():
            if isinstance(a, np.ndarray) and a.dtype.kind == "f" and not np.isfinite(a).all():
                return f"stats.{name} not finite"
    return ""


def run_scene_case(doc: dict, *, steps: int = 3) -> tuple[str, str]:
    """(outcome, detail) of one scene document (see module doc)."""
    from sim import Simulator, build_model
    from sim.scene import parse_scene

    try:
        spec = parse_scene(copy.deepcopy(doc), WHERE)
    except ValueError as exc:
        return ("clear_error" if _names_a_key(str(exc)) else "crash"), str(exc)[:300]
    except Exception as exc:  # noqa: BLE001 - a crash is what is being counted
        return "crash", f"{type(exc).__name__}: {exc}"[:300]
    changed = _kept_as_given(spec, doc)
    if changed:
        return "silent_wrong", changed
    try:
        model = build_model(spec)
        if not (np.all(model.node_mass > 0) and np.isfinite(model.node_mass).all() and model.EA_max > 0
                and model.EI1_max > 0 and model.GJ_max > 0
                and math.isfinite(model.EA_max + model.EI1_max + model.GJ_max)):
            return "silent_wrong", "zero or non-finite mass / stiffness"
        sim = Simulator(model, envs=2)
        q = sim.reset().obstacle_orientation
        if not (np.isfinite(q).all() and np.allclose(np.linalg.norm(q, axis=-1), 1.0)):
            return "silent_wrong", "obstacle orientation not a unit quaternion"
        bad = _finite_run(sim, steps)
    except ValueError as exc:
        return ("clear_error" if _names_a_key(str(exc)) else "crash"), str(exc)[:300]
    except Exception as exc:  # noqa: BLE001
        return "crash", f"{type(exc).__name__}: {exc}"[:300]
    return ("silent_wrong", bad) if bad else ("ok", "")


# ----------------------------------------------------------------------------------------------- control
_SIMS: dict[str, Any] = {}


def _arm_sim(mode: str = "3d"):
    if mode not in _SIMS:
        from sim import Simulator, build_model, load_scene

        _SIMS[mode] = Simulator(build_model(load_scene(asset_path("scenes/arm.toml" if mode == "3d"
                                                                  else "scenes/arm_2d.toml"))), envs=3)
    return _SIMS[mode]


def random_control_case(rng: np.random.Generator) -> dict:
    """A control/state fuzz case: which field, how it is corrupted."""
    kinds = ["scale", "nan", "inf", "complex", "object", "str", "shape", "list", "none", "state_nan", "state_huge",
             "float32", "int"]
    return {"mode": str(rng.choice(["3d", "2d"])), "kind": str(rng.choice(kinds)),
            "field": str(rng.choice(["kappa_bar", "tau_bar"])),
            "state_field": str(rng.choice(list(STATE_FLOAT_ARRAYS))),
            "scale": float(10 ** rng.uniform(-3, 3)), "seed": int(rng.integers(2 ** 31))}


def run_control_case(case: dict, *, steps: int = 3) -> tuple[str, str]:
    sim = _arm_sim(case["mode"])
    rng = np.random.default_rng(case["seed"])
    state, ctrl = sim.reset(), sim.make_control()
    k, f = case["kind"], case["field"]
    a = getattr(ctrl, f)
    if k == "scale":
        a[...] = rng.normal(size=a.shape) * case["scale"]
    elif k in ("nan", "inf"):
        a.flat[int(rng.integers(a.size))] = math.nan if k == "nan" else math.inf
    elif k == "complex":
        setattr(ctrl, f, a.astype(complex) + 1j)
    elif k in ("object", "str"):
        setattr(ctrl, f, a.astype(object if k == "object" else "U8"))
    elif k == "shape":
        setattr(ctrl, f, np.zeros(a.shape[:-1] + (a.shape[-1] + 1,)))
    elif k == "list":
        setattr(ctrl, f, a.tolist())
    elif k == "float32":
        setattr(ctrl, f, (a + 0.1 * rng.normal(size=a.shape)).astype(np.float32))
    elif k == "int":
        setattr(ctrl, f, np.zeros(a.shape, dtype=np.int64))
    elif k in ("state_nan", "state_huge"):
        s = getattr(state, case["state_field"])
        if s.size == 0:  # an obstacle pose of a scene without obstacles: corrupt the rod instead
            s = state.dof
        s.flat[int(rng.integers(s.size))] = math.nan if k == "state_nan" else 1e300
    try:
        for _ in range(steps):
            st = sim.step(state, None if k == "none" else ctrl)
            for name in STATE_FLOAT_ARRAYS:
                if not np.isfinite(getattr(state, name)).all():
                    return "silent_wrong", f"state.{name} not finite"
            for name, arr in vars(st).items():
                if isinstance(arr, np.ndarray) and arr.dtype.kind == "f" and not np.isfinite(arr).all():
                    return "silent_wrong", f"stats.{name} not finite"
        if k == "state_nan" and not state.failed.any():
            return "silent_wrong", "NaN state not reported as failed"
    except ValueError as exc:
        msg = str(exc)
        return ("clear_error" if re.search(r"\b(state|ctrl)\.\w+|step: (state|ctrl)", msg) else "crash"), msg[:300]
    except Exception as exc:  # noqa: BLE001
        return "crash", f"{type(exc).__name__}: {exc}"[:300]
    return "ok", ""


# ----------------------------------------------------------------------------------------------- env
_ENVS: dict[str, Any] = {}


def random_env_case(rng: np.random.Generator) -> dict:
    over_keys = ["dt", "substeps", "newton_max_iter", "newton_tol", "timeout_steps", "smoothing", "scene", "mode"]
    case: dict[str, Any] = {"seed": int(rng.integers(2 ** 31))}
    if rng.random() < 0.5:
        key = str(rng.choice(over_keys))
        case["override"] = {key: copy.deepcopy(NASTY[int(rng.integers(len(NASTY)))]) if rng.random() < 0.7
                            else random_value(rng, {"dt": 0.05, "substeps": 2, "newton_max_iter": 2,
                                                    "newton_tol": 1e-3, "timeout_steps": 500}.get(key, "x"))}
    else:
        case["action"] = str(rng.choice(["nan", "inf", "huge", "uniform", "shape", "object", "str", "int"]))
    return case


def run_env_case(case: dict) -> tuple[str, str]:
    from policies import make_vec_env

    try:
        if "override" in case:
            ov = case["override"]
            key = next(iter(ov))
            if key == "scene" and isinstance(ov[key], str):
                ov = {key: "/nonexistent/" + ov[key] + ".toml"}
            env = make_vec_env("follow_target", 2, seed=0, **ov)
            obs, _ = env.reset(seed=0)
            for _ in range(2):
                obs, rew, *_ = env.step(np.zeros((2, env.single_action_space.shape[0]), np.float32))
            if not (np.isfinite(obs).all() and np.isfinite(rew).all()):
                return "silent_wrong", "observation/reward not finite"
            got = getattr(env.config, key)
            if ov[key] is not None and got != ov[key]:
                return "silent_wrong", f"{key}: {ov[key]!r} became {got!r}"
            return "ok", ""
        if "ft" not in _ENVS:
            _ENVS["ft"] = make_vec_env("follow_target", 2, seed=0)
        env = _ENVS["ft"]
        rng = np.random.default_rng(case["seed"])
        dim = env.single_action_space.shape[0]
        k = case["action"]
        act: Any = rng.uniform(-1, 1, (2, dim)).astype(np.float32)
        if k in ("nan", "inf", "huge"):
            act[0, int(rng.integers(dim))] = {"nan": np.nan, "inf": np.inf, "huge": 1e30}[k]
        elif k == "shape":
            act = np.zeros((2, dim + 1), np.float32)
        elif k in ("object", "str"):
            act = act.astype(object if k == "object" else "U8")
        elif k == "int":
            act = np.ones((2, dim), np.int64)
        obs, rew, term, trunc, info = env.step(act)
        if not (np.isfinite(obs).all() and np.isfinite(rew).all()):
            return "silent_wrong", "observation/reward not finite"
        return "ok", ""
    except ValueError as exc:
        msg = str(exc)
        named = re.search(r"\w+\.\w+|action|scene|num_envs|seed|field|\.toml", msg)
        return ("clear_error" if named else "crash"), msg[:300]
    except Exception as exc:  # noqa: BLE001
        return "crash", f"{type(exc).__name__}: {exc}"[:300]


# ----------------------------------------------------------------------------------------------- cli
def random_cli_case(rng: np.random.Generator, tmp: str) -> list[str]:
    """Arguments for ``rodlab sim`` or ``rodlab record`` (short runs only: long valid durations excluded)."""
    pick = lambda xs: str(xs[int(rng.integers(len(xs)))])  # noqa: E731
    outs = [f"{tmp}/o.npz", "/proc/rodlab_fuzz/o.npz", f"{tmp}", f"{tmp}/f.txt/o.npz", f"{tmp}/new/dir/o.npz"]
    if rng.random() < 0.6:
        scene = pick(["assets/scenes/arm.toml", "assets/scenes/arm_2d.toml", "/nonexistent.toml", tmp,
                      f"{tmp}/f.txt", "README.md"])
        args = ["sim", scene, "--duration", pick(["inf", "nan", "-1", "0", "1e-12", "0.1", "abc", "1e400", "0.05"])]
        if rng.random() < 0.5:
            args += ["--envs", pick(["0", "-1", "1", "2", "1000000000", "x", "2.5"])]
        if rng.random() < 0.5:
            args += ["--every", pick(["0", "-2", "1", "3", "y"])]
        if rng.random() < 0.5:
            args += ["--out", pick(outs)]
        return args
    args = ["record", "--task", pick(["follow_target", "nope", "ik4d"]), "--max-steps",
            pick(["0", "-1", "1", "2", "x"]), "--out",
            pick([f"{tmp}/r.rrd", "/proc/rodlab_fuzz/r.rrd", f"{tmp}/f.txt/r.rrd", f"{tmp}/r.npz", tmp])]
    if rng.random() < 0.3:
        args += ["--episodes", pick(["0", "-1", "1", "x"])]
    if rng.random() < 0.3:
        args += ["--policy", pick(["policies/pretrained/ik4d.zip", "/nonexistent.zip", "README.md"])]
    return args


def run_cli_case(args: list[str]) -> tuple[str, str]:
    """Run ``rodlab ARGS`` in this process; clear = exit 0 (ok), or 2 with a one-line 'rodlab ...:' message."""
    err, out = io.StringIO(), io.StringIO()
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
            try:
                rc = rodlab_cli.main(list(args))
            except SystemExit as exc:  # argparse usage errors
                rc = exc.code if isinstance(exc.code, int) else 2
    except Exception as exc:  # noqa: BLE001
        return "crash", f"{type(exc).__name__}: {exc}"[:300]
    text = err.getvalue()
    if rc == 0:
        if "nan" in out.getvalue().lower().split("failed envs")[0]:
            return "silent_wrong", out.getvalue()[:300]
        return "ok", ""
    clear = rc == 2 and "Traceback" not in text and re.search(r"(rodlab \w+: |usage: )", text)
    return ("clear_error" if clear else "crash"), text.strip()[-300:]


# ----------------------------------------------------------------------------------------------- driver
class CaseTimeout(BaseException):
    """A case ran past its time limit (a hang counts as a crash); BaseException so no case catches it."""


@contextlib.contextmanager
def _time_limit(seconds: float | None):
    import signal
    import threading

    if not seconds or threading.current_thread() is not threading.main_thread():
        yield
        return

    def _raise(signum: int, frame: Any) -> None:
        raise CaseTimeout()

    old = signal.signal(signal.SIGALRM, _raise)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def fuzz(n: int, *, seed: int = 0, parts: tuple[str, ...] = PARTS, time_limit_s: float | None = None,
         tmp: str | None = None, progress: bool = False, case_limit_s: float | None = 60.0) -> dict[str, Any]:
    """Run ``n`` cases spread over ``parts``; return counts per part and outcome, and the first examples of
    every crash and silent-wrong case. A case taking longer than ``case_limit_s`` counts as a crash (hang)."""
    import tempfile

    rng = np.random.default_rng(seed)
    for mode in ("3d", "2d"):  # compile / load both step kernels before any case runs under its time limit
        warm = _arm_sim(mode)
        warm.step(warm.reset(), warm.make_control())
    counts = {p: dict.fromkeys(OUTCOMES, 0) for p in parts}
    bad: list[dict[str, Any]] = []
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as td:
        tmp = tmp or td
        Path(tmp, "f.txt").write_text("not a folder")

        with progress_bar(n, desc="rodlab bench fuzz", unit="case", enabled=progress) as bar:
            for i in range(n):
                if time_limit_s is not None and time.perf_counter() - t0 > time_limit_s:
                    break
                part = parts[i % len(parts)]
                if part == "scene":
                    doc, case = random_scene(rng)
                    fn = lambda: run_scene_case(doc)  # noqa: E731
                elif part == "control":
                    case = random_control_case(rng)
                    fn = lambda: run_control_case(case)  # noqa: E731
                elif part == "env":
                    case = random_env_case(rng)
                    fn = lambda: run_env_case(case)  # noqa: E731
                else:
                    case = random_cli_case(rng, tmp)
                    fn = lambda: run_cli_case(case)  # noqa: E731
                try:
                    with _time_limit(case_limit_s):
                        res = fn()
                except CaseTimeout:
                    res = ("crash", f"no answer within {case_limit_s} s (hang)")
                counts[part][res[0]] += 1
                if res[0] in ("crash", "silent_wrong") and len(bad) < 50:
                    bad.append({"part": part, "outcome": res[0], "case": repr(case)[:400], "detail": res[1]})
                bar.update(1)
    total = {o: sum(c[o] for c in counts.values()) for o in OUTCOMES}
    return {"tried": sum(total.values()), "seed": seed, "parts": list(parts), "total": total, "by_part": counts,
            "wall_s": round(time.perf_counter() - t0, 1), "bad_examples": bad}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="rodlab bench fuzz", description=__doc__.split("\n")[0])
    p.add_argument("--n", type=int, default=400, help="cases to try (spread over the parts)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--parts", default=",".join(PARTS), help="comma-separated subset of " + ",".join(PARTS))
    p.add_argument("--time-limit", type=float, default=None, metavar="S", help="stop after S seconds")
    p.add_argument("--out", default=None, help="write the counts as JSON to this file")
    p.add_argument("--json", action="store_true", help="print the JSON to stdout")

    add_progress_flag(p)
    a = p.parse_args(argv)
    parts = tuple(s.strip() for s in a.parts.split(",") if s.strip())
    if a.n < 1 or not parts or any(s not in PARTS for s in parts):
        p.error(f"--n must be >= 1 and --parts a subset of {','.join(PARTS)}")
    if a.out:

        try:
            check_output_path(a.out)
        except ValueError as exc:
            print(f"rodlab bench fuzz: {exc}", file=sys.stderr)
            return 2
    res = fuzz(a.n, seed=a.seed, parts=parts, time_limit_s=a.time_limit,
               progress=progress_wanted(a.progress, json_output=a.json))
    res["command"] = "rodlab bench fuzz " + " ".join(sys.argv[2:] if argv is None else argv)
    text = json.dumps(res, indent=1)
    if a.out:

        write_text(a.out, text + "\n")
    if a.json:
        print(text)
    else:
        t = res["total"]
        print(f"tried {res['tried']}: ok {t['ok']}, clear error {t['clear_error']}, crash {t['crash']}, "
              f"silent-wrong {t['silent_wrong']} ({res['wall_s']} s)")
        for b in res["bad_examples"][:10]:
            print(f"  {b['outcome']} [{b['part']}] {b['case'][:160]} -> {b['detail'][:160]}")
    return 0 if res["total"]["crash"] == 0 and res["total"]["silent_wrong"] == 0 else 1
