"""A Robot Runners problem with more agents: the same map and tasks, the given agents plus
more drawn on free cells with a fixed seed (not committed data: write it under tools/out/).

    .venv/bin/python tools/make_lorr_agents.py \\
        ../shared/data/robotrunners/lorr2026_warehouse_fulfill/fulfill-example_2500.json \\
        --agents 5000 --out tools/out/fulfill_5000

writes ``OUT/problem.json`` (the problem's keys, ``teamSize`` changed, file paths pointing
at the original map and tasks) and ``OUT/agents.agents``. The extra agents stand on free
cells (not ``@`` / ``T``) that no agent stands on, drawn uniformly by
``numpy.random.default_rng(seed)`` in one draw, so the same seed gives the same file.
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

import numpy as np

from warerover_phys.problems.robotrunners import read_problem


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("problem", type=Path)
    ap.add_argument("--agents", type=int, required=True)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, default=Path(__file__).parent / "out" / "lorr_agents")
    args = ap.parse_args()
    problem = read_problem(args.problem)
    data = json.loads(args.problem.read_text(encoding="utf-8"))
    starts = list(problem.starts[:args.agents])
    extra = args.agents - len(starts)
    if extra > 0:
        free = np.flatnonzero(~problem.grid.obstacles.ravel())
        free = np.setdiff1d(free, np.asarray(starts))
        if extra > len(free):
            raise SystemExit(f"only {len(free)} free cells left for {extra} more agents")
        rng = np.random.default_rng(args.seed)
        starts += rng.choice(free, size=extra, replace=False).tolist()
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    base = args.problem.parent.resolve()
    (out / "agents.agents").write_text(
        f"# {len(starts)} agents: {problem.team_size} from {args.problem.name}, "
        f"{max(0, extra)} more, seed {args.seed}\n{len(starts)}\n"
        + "".join(f"{s}\n" for s in starts), encoding="utf-8")
    data.update(teamSize=len(starts), agentFile="agents.agents",
                mapFile=os.path.relpath(base / data["mapFile"], out.resolve()),
                taskFile=os.path.relpath(base / data["taskFile"], out.resolve()))
    (out / "problem.json").write_text(json.dumps(data, indent=4) + "\n", encoding="utf-8")
    print(f"wrote {out / 'problem.json'}: {len(starts)} agents")


if __name__ == "__main__":
    main()
