"""``rodlab bench throughput``: batched step cost, rodlab against PyElastica, and how cost grows.

Parts (``--parts``, default all):

* ``tasks``   -- per task, one parallel control step of ``--envs`` (500) envs through the task core
  (policies.tasks), against PyElastica at the paper's settings (dt 2e-4, 500 or 2500 sim steps per
  control step, damping ν = 10, ``RodCylinderContact`` for the obstacle tasks) measured in the same run
  with several rods in one PyElastica simulator and scaled to 500 envs; reported as a ratio.
* ``envs``    -- rodlab sim step against the number of envs (1 ... 1000), paper arm.
* ``nodes``   -- against node count (11 ... 201), 100 envs.
* ``obstacles`` -- against obstacle count (0 ... 64) and mesh triangle count, 100 envs
  (benchmarks.throughput_contact, when the contact model is available); contact cost with no / far /
  near obstacles.
* ``modes``   -- 2D mode against 3D on a planar command; early Newton exit against fixed iterations.
* ``pairs``   -- self- and rod–rod contact (benchmarks.throughput_pairs): the self_contact switch with nothing
  near (ratio), a rod resting on itself, two rods resting across each other.

Every figure is the median of several repeats; the load average is stored with each one.
"""
from __future__ import annotations

import sys
from pathlib import Path

from . import throughput_pairs as tp
from . import throughput_tasks as tt
from .common import base_parser, have_elastica, load, machine_info, pyplot, save_figure, write_json
from .rodlab_runs import Solver
from .throughput_timing import PAPER_SOLVER, arm_doc, time_sim

PARTS = ("tasks", "envs", "nodes", "obstacles", "modes", "pairs")


def _say(msg: str) -> None:
    print(msg, flush=True)


# ------------------------------------------------------------------------------------------------
def part_envs(quick: bool, repeats: int) -> list[dict]:
    rows = []
    for B in ([1, 10, 100] if quick else [1, 10, 100, 500, 1000]):
        r = time_sim(arm_doc(), envs=B, repeats=repeats, steps=10 if B < 500 else 5)
        rows.append(r)
        _say(f"  envs {B:5d}: {r['ms_per_step']:8.3f} ms/step (CPU {r['cpu_ms_per_step']:8.3f})  "
             f"{r['us_per_env_step']:8.2f} us/env-step  it {r['iters_mean']:.2f}  load {r['load'][0]}")
    return rows


def part_nodes(quick: bool, repeats: int) -> list[dict]:
    rows = []
    B = 20 if quick else 100
    for n in ([11, 21, 51] if quick else [11, 21, 51, 101, 201]):
        r = time_sim(arm_doc(nodes=n), envs=B, repeats=repeats)
        r["nodes"] = n
        rows.append(r)
        _say(f"  nodes {n:4d} (B={B}): {r['ms_per_step']:8.3f} ms/step (CPU {r['cpu_ms_per_step']:8.3f})  "
             f"it {r['iters_mean']:.2f}")
    return rows


def part_modes(quick: bool, repeats: int) -> dict:
    B = 20 if quick else 100
    out = {}
    for mode in ("3d", "2d"):
        r = time_sim(arm_doc(mode=mode), envs=B, repeats=repeats, planar=True)
        out[f"planar_{mode}"] = r
        _say(f"  planar command, mode {mode} (B={B}): {r['ms_per_step']:8.3f} ms/step (CPU "
             f"{r['cpu_ms_per_step']:8.3f})  it {r['iters_mean']:.2f}")
    out["speedup_2d_over_3d"] = out["planar_3d"]["ms_per_step"] / out["planar_2d"]["ms_per_step"]
    out["speedup_2d_over_3d_cpu"] = out["planar_3d"]["cpu_ms_per_step"] / out["planar_2d"]["cpu_ms_per_step"]
    for name, sol in (("early_exit_tol1e-3_max5", Solver(tol=1e-3, max_iter=5)),
                      ("fixed_5_iterations", Solver(tol=1e-300, max_iter=5, dtol=1e-300)),
                      ("early_exit_tol1e-3_max2", PAPER_SOLVER),
                      ("fixed_2_iterations", Solver(tol=1e-300, max_iter=2, dtol=1e-300))):
        r = time_sim(arm_doc(solver=sol), envs=B, repeats=repeats)
        out[name] = r
        _say(f"  {name:26s} (B={B}): {r['ms_per_step']:8.3f} ms/step (CPU {r['cpu_ms_per_step']:8.3f})  "
             f"it {r['iters_mean']:.2f}")
    return out


# ------------------------------------------------------------------------------------------------
def main(argv: list[str] | None = None) -> int:
    p = base_parser("rodlab bench throughput", __doc__.split("\n")[0])
    p.add_argument("--parts", default=",".join(PARTS), help=f"comma-separated subset of {','.join(PARTS)}")
    p.add_argument("--envs", type=int, default=500, help="envs of the per-task step (default 500)")
    p.add_argument("--replot", action="store_true", help="only redraw the figures from OUT/throughput.json")
    args = p.parse_args(argv)
    if args.replot:
        import json
        name = "throughput_quick.json" if args.quick else "throughput.json"
        res = json.loads((Path(args.out) / name).read_text())
        for f in plot(res, args.out, quick=args.quick):
            _say(f"figure: {f}")
        return 0
    parts = [s.strip() for s in args.parts.split(",") if s.strip()]
    for s in parts:
        if s not in PARTS:
            p.error(f"--parts: unknown part {s!r} (choose from {', '.join(PARTS)})")
    if args.envs < 1:
        p.error("--envs must be >= 1")
    peer = have_elastica() and not args.no_peer
    repeats = args.repeats or (3 if args.quick else 5)
    res = {"benchmark": "throughput", "quick": args.quick, "machine": machine_info(),
           "command": "rodlab bench throughput " + " ".join(argv if argv is not None else sys.argv[1:])}
    _say(f"machine: {res['machine']['cpu_model']}, {res['machine']['logical_cores']} cores, "
         f"load {res['machine']['loadavg_at_start']}")
    time_sim(arm_doc(), envs=1, steps=1, repeats=1)  # numba warm-up
    name = "throughput_quick.json" if args.quick else "throughput.json"
    for part in parts:
        _say(f"[{part}]")
        if part == "tasks":
            res["tasks"] = tt.part_tasks(envs=args.envs if not args.quick else min(args.envs, 50),
                                         quick=args.quick, peer=peer, repeats=repeats)
        elif part == "envs":
            res["envs"] = part_envs(args.quick, repeats)
        elif part == "nodes":
            res["nodes"] = part_nodes(args.quick, repeats)
        elif part == "obstacles":
            res["obstacles"] = tt.part_obstacles(quick=args.quick, repeats=repeats)
        elif part == "pairs":
            res["pairs"] = tp.part_pairs(quick=args.quick, repeats=repeats)
        else:
            res["modes"] = part_modes(args.quick, repeats)
        write_json(args.out, name, res)
    res["load_at_end"] = load()
    res["figures"] = plot(res, args.out, quick=args.quick)
    write_json(args.out, name, res)
    for f in res["figures"]:
        _say(f"figure: {f}")
    if args.json:
        import json
        print(json.dumps(res, default=str))
    _say(f"wrote {Path(args.out) / name}")
    return 0


def plot(res: dict, out: Path, *, quick: bool) -> list[str]:
    plt = pyplot()
    sfx = "_quick" if quick else ""
    figs = []
    if res.get("envs") or res.get("nodes"):
        fig, axs = plt.subplots(1, 2, figsize=(10, 4))
        if res.get("envs"):
            e = res["envs"]
            axs[0].loglog([r["envs"] for r in e], [r["ms_per_step"] for r in e], "o-", label="ms per batched step")
            axs[0].loglog([r["envs"] for r in e], [r["cpu_ms_per_step"] for r in e], "o:", label="CPU ms per batched step")
            axs[0].loglog([r["envs"] for r in e], [r["us_per_env_step"] for r in e], "s--", label="µs per env-step (wall)")
            axs[0].set_xlabel("envs")
            axs[0].set_title("rodlab: cost vs envs (arm, N=21, dt .05, 2 it)", fontsize=9)
            axs[0].legend(fontsize=8)
            axs[0].grid(True, which="both", alpha=0.3)
        if res.get("nodes"):
            n = res["nodes"]
            axs[1].loglog([r["nodes"] for r in n], [r["ms_per_step"] for r in n], "o-", label="wall")
            axs[1].loglog([r["nodes"] for r in n], [r["cpu_ms_per_step"] for r in n], "o:", label="CPU")
            axs[1].legend(fontsize=8)
            axs[1].set_xlabel("nodes")
            axs[1].set_ylabel(f"ms per step ({n[0]['envs']} envs)")
            axs[1].set_title("rodlab: cost vs node count", fontsize=9)
            axs[1].grid(True, which="both", alpha=0.3)
        loads = [r["load"][0] for k in ("envs", "nodes") for r in res.get(k, [])]
        fig.text(0.01, -0.02, f"load avg {min(loads):.2f}-{max(loads):.2f}, {res['machine']['cpu_model']}",
                 fontsize=7)
        figs.append(str(save_figure(fig, out, f"throughput_scaling{sfx}.png")))
    if res.get("tasks"):
        f = tt.plot_tasks(plt, res["tasks"], out, sfx)
        if f:
            figs.append(f)
    if res.get("obstacles"):
        f = tt.plot_obstacles(plt, res["obstacles"], out, sfx)
        if f:
            figs.append(f)
    return figs


if __name__ == "__main__":
    sys.exit(main())
