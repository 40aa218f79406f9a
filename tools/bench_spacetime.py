"""Speed of the space-time validator (warerover_phys.spacetime) at 1,000 AGVs with a few hundred
actions each, on MovingAI warehouse-10-20-10-2-1.

    python tools/bench_spacetime.py [--agents 1000] [--ticks 300] [--body 0.7 0.7]
        [--fcl-agents 100] [--seed 0] [--json tools/out/bench_spacetime.json]

Workloads (all 1x1 AGVs on the map's free cells, one action per tick, League of Robot
Runners style: forward, turn clockwise, turn counter-clockwise, wait; headings kept, so
turns become rotating volumes):

- ``reserved``: a conflict-free random plan: an AGV moves forward only into a cell that is
  empty now and not yet claimed for the next tick (no vertex, no swap, no following), else
  turns or waits. Expected: 0 conflicts, also with 0.7 m bodies.
- ``free``: the same walk ignoring the other AGVs (walls only): many conflicts, the narrow
  phase's worst case.

For each: the space-time check (grid broad phase, every conflict listed, no first-contact
bisection) with its stage timings and pair counts, the default report (the 100 earliest
conflicts with their first contacts to 1 ms), and the per-tick validator (``validate.validate_states``) on the same plan for comparison;
then the fcl broad phase (``DynamicAABBTreeCollisionManager`` over all volumes) against the
grid on the first ``--fcl-agents`` AGVs.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path

import numpy as np

from warerover_phys.plans.model import HEADING_STEPS, Plan
from warerover_phys.problems.movingai import read_map
from warerover_phys.spacetime import from_plan, validate_spacetime
from warerover_phys.spacetime.volumes import build_volumes
from warerover_phys.validate import validate_states

ROOT = Path(__file__).resolve().parent.parent
MAP = ROOT / "tests" / "data" / "warehouse-10-20-10-2-1.map"


def walk(obstacles: np.ndarray, agents: int, ticks: int, reserved: bool, seed: int) -> Plan:
    """A random plan of ``agents`` x ``ticks`` actions (see the module docstring)."""
    rng = np.random.default_rng(seed)
    rows, cols = obstacles.shape
    free = np.argwhere(~obstacles)
    pick = rng.choice(len(free), size=agents, replace=False)
    pos = [tuple(map(int, free[i])) for i in pick]
    head = [int(h) for h in rng.integers(0, 4, agents)]
    occ = {p: a for a, p in enumerate(pos)}
    paths = [[p] for p in pos]
    heads = [[h] for h in head]
    for _ in range(ticks):
        claimed: set = set()
        draws = rng.random(agents)
        turns = rng.integers(0, 2, agents)
        for a in rng.permutation(agents).tolist():
            r, c = pos[a]
            h = head[a]
            if draws[a] < 0.65:
                dr, dc = HEADING_STEPS[h]
                t = (r + dr, c + dc)
                ok = 0 <= t[0] < rows and 0 <= t[1] < cols and not obstacles[t]
                if ok and reserved:
                    ok = t not in occ and t not in claimed
                if ok:
                    pos[a] = t
                    claimed.add(t)
                else:
                    head[a] = (h + (1 if turns[a] else 3)) % 4
            elif draws[a] < 0.9:
                head[a] = (h + (1 if turns[a] else 3)) % 4
            claimed.add(pos[a])
        occ = {p: a for a, p in enumerate(pos)}
        for a in range(agents):
            paths[a].append(pos[a])
            heads[a].append(head[a])
    return Plan(paths=tuple(map(tuple, paths)), headings=tuple(map(tuple, heads)),
                rows=rows, cols=cols)


def per_tick(plan: Plan, obstacles: np.ndarray) -> tuple[float, int]:
    cols = obstacles.shape[1]
    states = {i: [(r * cols + c, r * cols + c) for r, c in p] for i, p in enumerate(plan.paths)}
    t0 = time.perf_counter()
    found = validate_states(states, obstacles, max_conflicts=10 ** 9)
    return time.perf_counter() - t0, sum(c.kind in ("vertex", "swap") for c in found)


def run(name: str, plan: Plan, obstacles: np.ndarray, body: tuple[float, float]) -> dict:
    tp = from_plan(plan, body_m=body)
    c0 = time.process_time()
    res = validate_spacetime(tp, max_conflicts=10 ** 9, contact_resolution_s=None)
    cpu_s = time.process_time() - c0
    tick_s, tick_conflicts = per_tick(plan, obstacles)
    actions = sum(len(p) - 1 for p in plan.paths)
    row = {"workload": name, "agents": plan.num_agents, "actions": actions,
           "samples": res.samples, "volumes": res.volumes, "box_pairs": res.broad_pairs,
           "circle_pairs": res.circle_pairs, "fcl_pairs": res.fcl_pairs,
           "colliding_pairs": res.colliding_pairs,
           "conflicts": len(res.conflicts), "per_tick_vertex_swap": tick_conflicts,
           "timings_s": {k: round(v, 4) for k, v in res.timings_s.items()},
           "per_tick_validator_s": round(tick_s, 4), "cpu_s": round(cpu_s, 4),
           "rotation_bound_m": round(res.max_rotation_bound_m, 5)}
    tm = res.timings_s
    print(f"{name:>9}: {row['agents']} AGVs x {actions // max(1, row['agents'])} actions, "
          f"{res.volumes} volumes; pairs: {res.broad_pairs} box, {res.circle_pairs} circle, "
          f"{res.fcl_pairs} to fcl, {res.colliding_pairs} colliding; {len(res.conflicts)} "
          f"conflicts "
          f"(per-tick: {tick_conflicts} vertex/swap)")
    print(f"{'':>9}  total {tm['total']:.2f} s = build {tm['build']:.2f} + broad "
          f"{tm['broad']:.2f} + circles {tm['circle']:.2f} + fcl {tm['narrow']:.2f} + merge "
          f"{tm['merge']:.2f} (CPU {cpu_s:.2f} s); per-tick validator {tick_s:.2f} s")
    if res.fcl_pairs:  # the narrow phase on fcl.Convex solids instead of BVH models
        c0 = time.process_time()
        solid = validate_spacetime(tp, max_conflicts=10 ** 9, contact_resolution_s=None,
                                   narrow="convex")
        solid_cpu = time.process_time() - c0
        same = solid.conflicts == res.conflicts
        row["narrow_convex"] = {"fcl_s": round(solid.timings_s["narrow"], 4),
                                "total_s": round(solid.timings_s["total"], 4),
                                "cpu_s": round(solid_cpu, 4), "same_conflicts": same}
        print(f"{'':>9}  narrow=convex (fcl.Convex solids): fcl {solid.timings_s['narrow']:.2f}"
              f" s, total {solid.timings_s['total']:.2f} s (CPU {solid_cpu:.2f} s); same "
              f"conflicts: {same}")
    if res.conflicts:  # the default report: the 100 earliest, first contacts to 1 ms
        rep = validate_spacetime(tp)
        row["report_100_s"] = round(rep.timings_s["total"], 4)
        row["report_100_merge_s"] = round(rep.timings_s["merge"], 4)
        print(f"{'':>9}  default report (100 earliest conflicts, first contact to 1 ms): "
              f"{rep.timings_s['total']:.2f} s, of which merge + bisection "
              f"{rep.timings_s['merge']:.2f} s")
    return row


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--agents", type=int, default=1000)
    ap.add_argument("--ticks", type=int, default=300)
    ap.add_argument("--body", type=float, nargs=2, default=(0.7, 0.7))
    ap.add_argument("--fcl-agents", type=int, default=100)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", type=Path, default=ROOT / "tools" / "out" / "bench_spacetime.json")
    args = ap.parse_args()
    obstacles = read_map(MAP).obstacles
    t0 = time.perf_counter()
    import trimesh  # noqa: F401  (the narrow phase's hulls; imported once, not timed there)
    print(f"import trimesh: {time.perf_counter() - t0:.2f} s")
    body = (args.body[0], args.body[1])
    rows = []
    for name, reserved in (("reserved", True), ("free", False)):
        t0 = time.perf_counter()
        plan = walk(obstacles, args.agents, args.ticks, reserved, args.seed)
        print(f"{name:>9}: plan made in {time.perf_counter() - t0:.1f} s")
        rows.append(run(name, plan, obstacles, body))
    # building hulls: numpy faces against trimesh.convex.convex_hull (qhull) per volume
    vol = build_volumes(from_plan(plan, body_m=body))
    idx = np.arange(min(2000, len(vol)))
    hull_us = {}
    for method in ("numpy", "trimesh"):
        vol.hulls(idx[:10], method=method)  # imports
        c0 = time.process_time()
        vol.hulls(idx, method=method)
        hull_us[method] = round((time.process_time() - c0) / len(idx) * 1e6, 1)
    print(f"hulls of {len(idx)} volumes, CPU us per volume (checks included): "
          f"numpy faces {hull_us['numpy']}, trimesh convex_hull {hull_us['trimesh']}")
    # fcl's broad phase against the grid on a smaller plan
    plan = walk(obstacles, args.fcl_agents, args.ticks, False, args.seed)
    tp = from_plan(plan, body_m=body)
    grid = validate_spacetime(tp, max_conflicts=10 ** 9, contact_resolution_s=None)
    tree = validate_spacetime(tp, broad_phase="fcl", max_conflicts=10 ** 9,
                              contact_resolution_s=None)
    same = [(c.agvs, c.t_start_s, c.t_end_s) for c in grid.conflicts] == \
        [(c.agvs, c.t_start_s, c.t_end_s) for c in tree.conflicts]
    cmp = {"agents": args.fcl_agents, "volumes": grid.volumes,
           "grid_s": round(grid.timings_s["total"], 4),
           "fcl_tree_s": round(tree.timings_s["total"], 4),
           "conflicts": len(grid.conflicts), "same_conflicts": same}
    print(f"fcl broad phase, free walk of {args.fcl_agents} AGVs ({grid.volumes} volumes): "
          f"grid {cmp['grid_s']:.2f} s, fcl DynamicAABBTree {cmp['fcl_tree_s']:.2f} s, "
          f"{cmp['conflicts']} conflicts, same: {same}")
    out = {"map": MAP.name, "ticks": args.ticks, "body_m": body, "seed": args.seed,
           "python": sys.version.split()[0], "machine": platform.machine(),
           "workloads": rows, "hull_cpu_us": hull_us, "fcl_broad_phase": cmp}
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(out, indent=2))
    print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
