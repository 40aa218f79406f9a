"""An outside check of the physics executor: do AGV bodies ever overlap?

Runs shipped scenarios x planners on the physics executor (optionally with random delays, a
bigger body, or more scenarios), records poses at every physics step
(``executor.trajectory_hz = 1 / dt_s``) and then, using only ``trajectories.npz`` as its
documentation says (``x``, ``y``, ``heading``, ``body_m``, ``shelf_m``), builds each AGV's
outline with shapely at every sample and looks for two outlines that overlap. It shares no
code with the executor's own clearance figure, which it prints beside its own for
comparison.

    .venv/bin/python tools/overlap_check.py [--scenarios A.yaml ...] [--planners astar cbs
        pibt lacam] [--seeds 1] [--delays] [--body 0.8] [--json tools/out/overlap.json]

A row per episode: samples, the smallest edge-to-edge clearance between bodies and between
outlines with carried shelves (negative: overlap depth is not measured here, only that an
overlap exists), the number of samples with an overlap, and the executor's own
``min_clearance_m`` and ``agv_contacts``. It also measures each AGV's peak speed and
acceleration from the recorded poses alone (finite differences over the physics-step samples;
acceleration against the loaded limit while the sample says loaded) and prints the largest
ratio to the limit over the fleet (the issue asks at most 1.05).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np
import shapely

ROOT = Path(__file__).resolve().parent.parent
SHIPPED = sorted(p.name for p in (ROOT / "layouts").glob("*.yaml") if p.stem != "industrial")
"""Default scenarios: every shipped one but ``industrial`` (320 AGVs: give it with
``--scenarios industrial.yaml`` and a small ``--max-ticks``)."""


def outlines(x: np.ndarray, y: np.ndarray, heading: np.ndarray, body: np.ndarray,
             shelf: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """Body rectangles (N,) and body-or-shelf outlines (N,) of one sample, as shapely
    geometries."""
    half_l, half_w = body[:, 0] / 2, body[:, 1] / 2
    c, s = np.cos(heading), np.sin(heading)
    corners = []
    for sl, sw in ((1, 1), (-1, 1), (-1, -1), (1, -1)):
        corners.append(np.stack([x + sl * half_l * c - sw * half_w * s,
                                 y + sl * half_l * s + sw * half_w * c], axis=1))
    rings = np.stack(corners, axis=1)  # (N, 4, 2)
    bodies = shapely.polygons(rings)
    if shelf is None or not np.any(shelf > 0):
        return bodies, bodies
    boxes = shapely.box(x - shelf[:, 0] / 2, y - shelf[:, 1] / 2, x + shelf[:, 0] / 2,
                        y + shelf[:, 1] / 2)
    carrying = shelf[:, 0] > 0
    full = bodies.copy()
    full[carrying] = shapely.union(bodies[carrying], boxes[carrying])
    return bodies, full


def peak_ratios(d) -> tuple[float, float]:
    """Largest speed / limit and acceleration / limit over every AGV and sample, from the
    poses alone (central finite differences at the recorded rate)."""
    t = np.asarray(d["t"], dtype=float)
    x, y = np.asarray(d["x"], dtype=float), np.asarray(d["y"], dtype=float)
    if len(t) < 3:
        return 0.0, 0.0
    dt = np.diff(t)[:, None]
    vx, vy = np.diff(x, axis=0) / dt, np.diff(y, axis=0) / dt
    speed = np.hypot(vx, vy) / np.asarray(d["limit_speed_mps"], dtype=float)
    acc = np.hypot(np.diff(vx, axis=0), np.diff(vy, axis=0)) / dt[1:]
    amax = np.broadcast_to(np.asarray(d["limit_accel_mps2"], dtype=float), acc.shape)
    if "limit_accel_loaded_mps2" in d.files and "loaded" in d.files:
        loaded = np.asarray(d["loaded"], dtype=bool)
        # The sample between the two velocity intervals decides which limit applies.
        amax = np.where(loaded[1:-1], np.asarray(d["limit_accel_loaded_mps2"], dtype=float),
                        amax)
    return float(speed.max()), float((acc / amax).max())


def check(npz: Path) -> dict:
    d = np.load(npz)
    speed_ratio, accel_ratio = peak_ratios(d)
    x, y, heading = d["x"], d["y"], d["heading"]
    body = np.asarray(d["body_m"], dtype=float)
    shelf = d["shelf_m"] if "shelf_m" in d.files else None
    t_count, n = x.shape
    worst = {"body": np.inf, "outline": np.inf}
    overlaps = {"body": 0, "outline": 0}
    first = None
    reach = float(np.max(np.hypot(body[:, 0], body[:, 1]))) + 1.0
    for t in range(t_count):
        geoms = outlines(x[t], y[t], heading[t], body,
                         None if shelf is None else np.asarray(shelf[t], dtype=float))
        for kind, g in zip(("body", "outline"), geoms, strict=True):
            tree = shapely.STRtree(g)
            a, b = tree.query(g, predicate="dwithin", distance=reach)
            keep = a < b
            a, b = a[keep], b[keep]
            if not len(a):
                continue
            dist = shapely.distance(g[a], g[b])
            hit = shapely.intersects(g[a], g[b]) & (shapely.area(
                shapely.intersection(g[a], g[b])) > 1e-9)
            if hit.any():
                overlaps[kind] += 1
                if first is None:
                    first = (kind, float(d["t"][t]), int(a[hit][0]), int(b[hit][0]))
            worst[kind] = min(worst[kind], float(dist.min()))
    return {"samples": int(t_count), "agvs": int(n),
            "min_body_clearance_m": None if np.isinf(worst["body"]) else worst["body"],
            "min_outline_clearance_m": None if np.isinf(worst["outline"]) else
            worst["outline"],
            "samples_with_body_overlap": overlaps["body"],
            "samples_with_outline_overlap": overlaps["outline"], "first_overlap": first,
            "peak_speed_ratio": speed_ratio, "peak_accel_ratio": accel_ratio}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenarios", nargs="+", default=SHIPPED)
    ap.add_argument("--planners", nargs="+", default=["astar", "cbs", "pibt", "lacam"])
    ap.add_argument("--seeds", type=int, default=1)
    ap.add_argument("--delays", action="store_true", help="bernoulli delays, prob 0.05")
    ap.add_argument("--body", type=float, help="body side in metres for every AGV type")
    ap.add_argument("--max-ticks", type=int, default=600)
    ap.add_argument("--json", type=Path, default=ROOT / "tools" / "out" / "overlap.json")
    args = ap.parse_args()

    from warerover_phys import load_scenario, run_episode
    from warerover_phys.outputs import write_outputs

    rows = []
    for name in args.scenarios:
        path = Path(name) if Path(name).exists() else ROOT / "layouts" / name
        for planner in args.planners:
            for seed in range(args.seeds):
                sc = load_scenario(path, [("executor.name", "physics"),
                                          ("planner.name", planner),
                                          ("max_ticks", args.max_ticks)])
                dt = sc.executor.dt_s
                over = [("executor.trajectory_hz", 1.0 / dt)]
                if args.delays:
                    over += [("executor.delays.model", "bernoulli"),
                             ("executor.delays.prob", 0.05)]
                if args.body:
                    over += [(f"fleet.types.{k}.body_m", [args.body * t.footprint] * 2)
                             for k, t in sc.fleet.types.items()]
                sc = load_scenario(path, [("executor.name", "physics"),
                                          ("planner.name", planner),
                                          ("max_ticks", args.max_ticks), *over])
                result = run_episode(sc, seed=seed)
                with tempfile.TemporaryDirectory() as tmp:
                    write_outputs(result, Path(tmp) / "run", with_trajectory=True)
                    row = check(Path(tmp) / "run" / "trajectories.npz")
                m = result.metrics
                row.update(scenario=path.name, planner=planner, seed=seed,
                           delays=args.delays, body=args.body,
                           success_rate=m.get("success_rate"),
                           failure_cause=m.get("failure_cause"),
                           deadlocks=m.get("deadlocks"), freezes=m.get("freezes"),
                           reported_min_clearance_m=m.get("min_clearance_m"),
                           agv_contacts=m.get("agv_contacts"))
                rows.append(row)
                print(f"{path.name:28s} {planner:6s} seed {seed}: {row['samples']} samples, "
                      f"min clearance body {row['min_body_clearance_m']}, outline "
                      f"{row['min_outline_clearance_m']}; overlapping samples "
                      f"{row['samples_with_body_overlap']} / "
                      f"{row['samples_with_outline_overlap']}; executor: "
                      f"{row['reported_min_clearance_m']}, contacts {row['agv_contacts']}; "
                      f"SR {row['success_rate']} (cause {row['failure_cause']}), deadlocks "
                      f"{row['deadlocks']} (freezes {row['freezes']}); "
                      f"peak speed / accel ratio "
                      f"{row['peak_speed_ratio']:.4f} / {row['peak_accel_ratio']:.4f}",
                      flush=True)
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(rows, indent=2, default=float) + "\n")
    bad = sum(r["samples_with_body_overlap"] > 0 for r in rows)
    fast = sum(max(r["peak_speed_ratio"], r["peak_accel_ratio"]) > 1.05 for r in rows)
    print(f"{len(rows)} episodes, {bad} with a body overlap, {fast} with a peak over 1.05 x "
          "its limit", file=sys.stderr)


if __name__ == "__main__":
    main()
