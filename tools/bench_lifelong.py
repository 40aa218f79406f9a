"""Lifelong PIBT on the Robot Runners ``warehouse_small`` map: ms per tick.

Each agent starts where the ``.agents`` file says; tasks from the ``.tasks`` file are handed
out in order to agents that reach their goal (the 2023 "greedy" system assignment). Every
tick one PIBT step (with swap) moves all agents. Prints and writes (JSON) ms per tick (mean,
p99), tasks finished and agent-ticks; validates every step (no vertex or swap conflicts).

    .venv/bin/python tools/bench_lifelong.py --agents 400 --ticks 500
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path

import numpy as np

from warerover_phys.movingai import read_map
from warerover_phys.planning.oneshot import grid_graph
from warerover_phys.planning.pibt import pibt_step

DATA = Path(__file__).resolve().parent / "data"


def read_ints(path: Path) -> list[int]:
    lines = [ln.strip() for ln in path.read_text().splitlines()
             if ln.strip() and not ln.startswith("#")]
    count = int(lines[0])
    return [int(ln.split(",")[0]) for ln in lines[1:count + 1]]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--agents", type=int, default=400)
    ap.add_argument("--ticks", type=int, default=500)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", type=Path, default=Path(__file__).parent / "out" /
                    "bench_lifelong.json")
    args = ap.parse_args()

    grid = read_map(DATA / "warehouse_small.map")
    graph = grid_graph(grid.obstacles)
    cols = grid.cols
    starts = read_ints(DATA / "warehouse_small_400.agents")[: args.agents]
    tasks = read_ints(DATA / "warehouse_small.tasks")
    # Linearised locations use the map width; our nodes are row * cols + col: the same.
    config = list(starts)
    next_task = 0
    goals = []
    for _ in config:
        goals.append(tasks[next_task % len(tasks)])
        next_task += 1
    rng = np.random.default_rng(args.seed)
    dists = [graph.dist_to(divmod(g, cols)) for g in goals]
    since = [0] * len(config)
    done = 0
    times = []
    for tick in range(args.ticks):
        t0 = time.perf_counter()
        for i, (q, g) in enumerate(zip(config, goals, strict=True)):
            if q == g:  # arrived: next task
                done += 1
                goals[i] = tasks[next_task % len(tasks)]
                next_task += 1
                dists[i] = graph.dist_to(divmod(goals[i], cols))
                since[i] = tick
        prio = [tick - s + i / (len(config) + 1) for i, s in enumerate(since)]
        nxt = pibt_step(graph, config, dists, prio, rng.random(graph.num_nodes) * 0.5,
                        goals=goals)
        times.append(time.perf_counter() - t0)
        assert nxt is not None
        assert len(set(nxt)) == len(nxt), "vertex conflict"
        moved_into = {v: i for i, v in enumerate(nxt)}
        for i, (a, b) in enumerate(zip(config, nxt, strict=True)):
            j = moved_into.get(a)
            assert not (j is not None and j != i and config[j] == b), "swap conflict"
            assert a == b or b in graph.neighbors[a], "jump"
        config = nxt
        if tick % 100 == 0:
            print(f"  tick {tick}: {np.mean(times) * 1e3:.2f} ms/tick, {done} tasks",
                  file=sys.stderr)
    ms = np.array(times) * 1e3
    out = {"map": "warehouse_small", "agents": len(config), "ticks": args.ticks,
           "ms_per_tick_mean": float(ms.mean()), "ms_per_tick_p99": float(np.percentile(ms, 99)),
           "ms_per_tick_max": float(ms.max()), "tasks_finished": done,
           "target_ms": 20.0, "python": platform.python_version(), "cpus": __import__(
               "os").cpu_count(), "platform": platform.platform()}
    print(f"lifelong PIBT, warehouse_small, {out['agents']} agents, {args.ticks} ticks: "
          f"{out['ms_per_tick_mean']:.2f} ms/tick mean, {out['ms_per_tick_p99']:.2f} p99, "
          f"{out['ms_per_tick_max']:.2f} max (target < 20 ms); {done} tasks finished; "
          "0 conflicts")
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(out, indent=2) + "\n")


if __name__ == "__main__":
    main()
