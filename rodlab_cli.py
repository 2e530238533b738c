"""The ``rodlab`` command line.

Every subcommand lives next to the code it drives and exposes ``main(argv: list[str]) -> int``.
This file only dispatches (imports are lazy, so ``rodlab sim`` never imports torch or viser).
"""
from __future__ import annotations

import importlib
import sys

OWN_PACKAGES = ("sim", "policies", "workbench", "benchmarks")

# command -> "module:function"; "bench" has its own table below.
COMMANDS: dict[str, tuple[str, str]] = {
    "sim": ("sim.cli:sim_main", "simulate a scene headless and write an .npz"),
    "train": ("policies.cli:train_main", "train a SAC policy on a task (headless)"),
    "eval": ("policies.cli:eval_main", "evaluate a policy file on a task"),
    "sweep": ("policies.sweep:main", "seeds x tasks x settings sweep of training runs on Ray"),
    "report": ("policies.report:main", "learning curves and time-to-plateau table of a sweep"),
    "record": ("policies.recording.cli:record_main", "record episodes to a rerun .rrd file"),
    "inspect": ("policies.recording.cli:inspect_main", "summarise a recorded .rrd file"),
    "export": ("workbench.export:main", "export a recorded episode to a standalone HTML player / PNG"),
    "workbench": ("workbench.cli:workbench_main", "open the interactive web workbench"),
}
BENCH: dict[str, tuple[str, str]] = {
    "sim": ("sim.cli:bench_sim_main", "time one batched sim step / control step"),
    "env": ("policies.cli:bench_env_main", "time one batched vector-env step of a task"),
    "accuracy": ("benchmarks.accuracy:main", "run time against error, with PyElastica"),
    "stress": ("benchmarks.stress:main", "numerical stress test"),
    "throughput": ("benchmarks.throughput:main", "throughput and scaling, with PyElastica"),
    "train": ("policies.cli:bench_train_main", "time one training iteration (env step + updates)"),
    "order": ("benchmarks.time_order:main", "observed time order of the integrators (fitted first mode)"),
    "fuzz": ("benchmarks.fuzz:main", "random bad input: tried / clear error / crash / silent-wrong counts"),
}


def _usage() -> str:
    lines = ["usage: rodlab COMMAND [options]   (rodlab COMMAND --help for details)", "", "commands:"]
    for name, (_, doc) in COMMANDS.items():
        lines.append(f"  {name:<11} {doc}")
    lines.append("  bench KIND  benchmarks: " + ", ".join(BENCH))
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
        return _call(BENCH[rest[0]][0], rest[1:])
    if cmd not in COMMANDS:
        print(f"rodlab: unknown command {cmd!r}\n\n{_usage()}", file=sys.stderr)
        return 2
    return _call(COMMANDS[cmd][0], rest)


if __name__ == "__main__":
    sys.exit(main())
