"""The ``rodlab`` command line.

Every subcommand lives next to the code it drives and exposes ``main(argv: list[str]) -> int``.
This file only dispatches (imports are lazy, so ``rodlab sim`` never imports torch or viser).
"""
from __future__ import annotations

import importlib
import importlib.util
import sys
from pathlib import Path

OWN_PACKAGES = ("sim", "policies", "workbench", "benchmarks")

# command -> "module:function"; "bench" has its own table below.
COMMANDS: dict[str, tuple[str, str]] = {
    "sim": ("sim.cli:sim_main", "simulate a scene headless and write an .npz"),
    "fit": ("policies.recording.fitdata:fit_main", "calibrate a scene's parameters to measured motion (real-to-sim)"),
    "train": ("policies.cli:train_main", "train a SAC policy on a task (headless)"),
    "eval": ("policies.cli:eval_main", "evaluate a policy file on a task"),
    "sweep": ("policies.learning.sweep:main", "seeds x tasks x settings sweep of training runs on Ray"),
    "report": ("policies.learning.report:main", "learning curves and time-to-plateau table of a sweep"),
    "record": ("policies.recording.cli:record_main", "record episodes to a rerun .rrd file"),
    "inspect": ("policies.recording.cli:inspect_main", "summarise a recorded .rrd file"),
    "export": ("policies.recording.export:main", "export a recorded episode to a standalone HTML player / PNG"),
    "workbench": ("workbench.serve.cli:workbench_main", "open the interactive web workbench"),
}
BENCH: dict[str, tuple[str, str]] = {
    "sim": ("sim.cli:bench_sim_main", "time one batched sim step / control step"),
    "env": ("policies.cli:bench_env_main", "time one batched vector-env step of a task"),
    "accuracy": ("benchmarks.accuracy:main", "run time against error, with PyElastica"),
    "stress": ("benchmarks.stress:main", "numerical stress test"),
    "throughput": ("benchmarks.throughput:main", "throughput and scaling, with PyElastica"),
    "train": ("policies.cli:bench_train_main", "time one training iteration (env step + updates)"),
    "order": ("benchmarks.time_order:main", "observed time order of the integrators (fitted first mode)"),
    "gradients": ("benchmarks.gradients:main", "derivative cost, fit vs finite-difference probing, inverse statics"),
    "fuzz": ("benchmarks.fuzz:main", "random bad input: tried / clear error / crash / silent-wrong counts"),
    "stability": ("benchmarks.stability:main", "static stability check: banded against dense eigensolver"),
}


# `rodlab bench` kinds whose code is the checkout's benchmarks/ folder: developer benchmarks (PyElastica peer, output
# into docs/bench), not installed with rodlab (docs/architecture.md "Package boundaries").
CHECKOUT_BENCH = tuple(k for k, (target, _) in BENCH.items() if target.startswith("benchmarks."))


def _find_benchmarks() -> bool:
    """True when the ``benchmarks`` package can be imported: on the import path, or in the working directory (a
    checkout's root: it is then put on the import path, as ``python -m`` would)."""
    if importlib.util.find_spec("benchmarks") is not None:
        return True
    if (Path.cwd() / "benchmarks" / "__init__.py").is_file():
        sys.path.insert(0, str(Path.cwd()))
        importlib.invalidate_caches()
        return True
    return False


def _usage() -> str:
    lines = ["usage: rodlab COMMAND [options]   (rodlab COMMAND --help for details)", "", "commands:"]
    for name, (_, doc) in COMMANDS.items():
        lines.append(f"  {name:<11} {doc}")
    lines.append("  bench KIND  benchmarks: " + ", ".join(k for k in BENCH if k not in CHECKOUT_BENCH)
                 + "; from a checkout's root also " + ", ".join(CHECKOUT_BENCH))
    return "\n".join(lines)


def _call(target: str, argv: list[str]) -> int:
    mod_name, fn_name = target.split(":")
    try:
        mod = importlib.import_module(mod_name)
    except ModuleNotFoundError as exc:
        missing = exc.name or ""
        if missing == mod_name or mod_name.startswith(missing + "."):
            print(f"rodlab: this command is not available (module {mod_name!r} not found)", file=sys.stderr)
            return 2
        if missing.split(".")[0] in OWN_PACKAGES:
            raise  # a broken import inside rodlab itself: show the traceback
        print(f"rodlab: the Python package {missing.split('.')[0]!r} is not installed but {mod_name!r} needs it; "
              "install rodlab's dependencies (`make install`, or `pip install -e .[dev,peers]` in the venv)",
              file=sys.stderr)
        return 2
    rc = getattr(mod, fn_name)(argv)
    return int(rc or 0)


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help"):
        print(_usage())
        return 0
    cmd, rest = argv[0], argv[1:]
    if cmd == "bench":
        if not rest or rest[0] not in BENCH:
            print("usage: rodlab bench {" + ",".join(BENCH) + "} [options]", file=sys.stderr)
            return 2
        if rest[0] in CHECKOUT_BENCH and not _find_benchmarks():
            print(f"rodlab bench {rest[0]}: this benchmark runs from a rodlab source checkout (its benchmarks/ "
                  "folder is not installed); in the checkout's root folder run "
                  f"`rodlab bench {rest[0]}` or `python -m rodlab_cli bench {rest[0]}`", file=sys.stderr)
            return 2
        return _call(BENCH[rest[0]][0], rest[1:])
    if cmd not in COMMANDS:
        print(f"rodlab: unknown command {cmd!r}\n\n{_usage()}", file=sys.stderr)
        return 2
    return _call(COMMANDS[cmd][0], rest)


if __name__ == "__main__":
    sys.exit(main())
