"""CPU-time figures of one-shot LaCAM + LNS refinement (``warerover solve --planner lacam
--refine``) on MovingAI warehouse-10-20-10-2-1, for a loaded machine where wall-clock limits
say little.

    python tools/bench_refine.py [--agents 700] [--lns-cpu 20] [--iterations K] [--scen 1]
        [--json tools/out/bench_refine.json] [--profile K]

Prints the CPU seconds (``time.process_time``) of the first solution's parts (distance
tables, guide paths, LaCAM; ``--seed``, no time limit), then runs the LNS
(:func:`warerover_phys.planning.refine.lns.refine`, generator seeded as ``solve`` does) from that
first solution with its clock patched to CPU time, for ``--lns-cpu`` seconds (or exactly
``--iterations`` neighbourhoods: the same plan on any machine), validates the result with
the per-tick validator and prints iterations, SoC and SoC / lower bound. Run it with
``PYTHONPATH`` at another checkout to compare code versions on the same box.
"""

from __future__ import annotations

import argparse
import cProfile
import json
import os
import pstats
import sys
import time
import types
from pathlib import Path

import numpy as np

if not os.environ.get("PYTHONPATH"):  # PYTHONPATH picks the checkout to measure
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from warerover_phys.planning.lacam.reference import _to_paths, lacam_nodes  # noqa: E402
from warerover_phys.planning.oneshot import scatter  # noqa: E402
from warerover_phys.planning.oneshot.core import grid_graph  # noqa: E402
from warerover_phys.planning.refine import lns as refine_mod  # noqa: E402
from warerover_phys.problems.movingai import read_map, read_scen  # noqa: E402
from warerover_phys.validate import validate_states  # noqa: E402

DATA = Path(__file__).resolve().parent.parent / "tests" / "data"
MAP = "warehouse-10-20-10-2-1"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--agents", type=int, default=700)
    ap.add_argument("--lns-cpu", type=float, default=20.0)
    ap.add_argument("--iterations", type=int, default=None)
    ap.add_argument("--scen", type=int, default=1)
    ap.add_argument("--seed", type=int, default=0, help="as `warerover solve --seed`")
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--profile", type=int, default=0, metavar="K",
                    help="profile the LNS (cProfile, CPU clock) and print its K costliest "
                         "functions by own time to stderr")
    args = ap.parse_args(argv)
    cpu = time.process_time
    grid = read_map(DATA / f"{MAP}.map")
    scen = read_scen(DATA / f"{MAP}-random-{args.scen}.scen", args.agents, grid)
    graph = grid_graph(grid.obstacles)
    starts = [graph.node(a.start) for a in scen]
    goals = [graph.node(a.goal) for a in scen]
    out: dict = {"agents": args.agents, "scen": args.scen, "seed": args.seed,
                 "code": refine_mod.__file__}
    c = cpu()
    tables = [graph.dist_to(a.goal) for a in scen]
    dists = [t.tolist() for t in tables]
    out["dist_cpu_s"] = cpu() - c
    lb = sum(d[s] for d, s in zip(dists, starts, strict=True))
    far = time.monotonic() + 1e9
    c = cpu()
    rng = np.random.default_rng(np.random.SeedSequence(args.seed).spawn(1)[0])
    guide = scatter.guide_paths(graph.neighbors, starts, goals, dists, rng)
    out["guide_cpu_s"] = cpu() - c
    c = cpu()
    configs, _ = lacam_nodes(graph, starts, goals, dists, far,
                             np.random.default_rng(args.seed),
                             guide=guide.next)
    out["lacam_cpu_s"] = cpu() - c
    cols = graph.cols
    nodes = [[r * cols + col for r, col in p] for p in _to_paths(graph, configs)]
    out["first_soc"] = sum(len(refine_mod._trim(p, g)) - 1
                           for p, g in zip(nodes, goals, strict=True))
    rng = np.random.default_rng(np.random.SeedSequence(args.seed).spawn(2)[1])
    budget = 1e9 if args.iterations is not None else args.lns_cpu
    wall_clock = refine_mod.time
    refine_mod.time = types.SimpleNamespace(monotonic=cpu)  # the LNS's clock: CPU time
    try:
        prof = cProfile.Profile(cpu) if args.profile else None
        c = cpu()
        if prof is not None:
            prof.enable()
        res = refine_mod.refine(graph.neighbors, nodes, goals, tables, c + budget, rng,
                                max_iterations=args.iterations)
        if prof is not None:
            prof.disable()
        out["lns_cpu_s"] = cpu() - c
    finally:
        refine_mod.time = wall_clock
    out["iterations"] = res.stats["iterations"]
    out["soc"] = res.sum_of_costs
    out["lower_bound"] = lb
    out["soc_over_lb"] = round(res.sum_of_costs / lb, 4)
    horizon = max(len(p) for p in res.paths)
    full = [p + [p[-1]] * (horizon - len(p)) for p in res.paths]
    out["conflicts"] = len(validate_states({i: [(v, v) for v in p] for i, p in enumerate(full)},
                                           grid.obstacles))
    out["endpoints_ok"] = all(p[0] == s and p[-1] == g
                              for p, s, g in zip(full, starts, goals, strict=True))
    out = {k: round(v, 3) if isinstance(v, float) else v for k, v in out.items()}
    if prof is not None:
        pstats.Stats(prof, stream=sys.stderr).sort_stats("tottime").print_stats(args.profile)
    print(json.dumps(out))
    if args.json is not None:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(out, indent=1) + "\n", encoding="utf-8")
    return 0 if out["conflicts"] == 0 and out["endpoints_ok"] else 1


if __name__ == "__main__":
    raise SystemExit(main())
