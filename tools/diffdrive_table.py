"""The no-slip differential drive checked from the outside (issue 37): contacts, static
contacts, limit violations, peak ratios, lateral speed and clearance of every shipped
scenario x planner x seed, with and without random delays, and of large MAPF plans.

Every episode runs with ``robot: diffdrive`` (``executor.no_slip: true`` and wheel limits,
``warerover_phys.executors.diffdrive``) on the physics executor, recording every physics
step (``executor.trajectory_hz = 1 / dt_s``); ``tools/diffdrive_checks.py`` then measures
``trajectories.npz`` with shapely and finite differences alone, and the table shows those
figures with the executor's own counters beside them (``exec``)::

    .venv/bin/python tools/diffdrive_table.py [--scenarios A.yaml ...] [--planners astar cbs
        pibt lacam] [--seeds 20] [--delays both] [--jobs 2] [--json tools/out/diffdrive.json]

Variants: ``paper_heterogeneous`` and ``warerover_hetero`` also run as ``*+2x2diff``, their
2x2 type on differential drive with a 1.4 m body (a 1.6 m one sweeps a disc of radius
1.13 m turning in place, beyond its 2 m footprint: it touches walls on any robot model).

Plans (``--plans DIR``): ``DIR/planN.txt`` (lacam3) and ``DIR/ownN.txt`` or
``DIR/lacam-planN.txt`` (the project's LaCAM; ``tools/bench_execute.py --solver lacam --plans
DIR`` makes them) for ``--agents``, on ``warehouse-10-20-10-2-1``, executed as ``warerover execute``
does with the default 1x1 fleet, once with ``robot: diffdrive``'s settings and once with
the default model; poses recorded at 10 Hz (the overlap checks run on those samples; the
peaks are the executor's per-step monitors), or with ``--plan-every-step`` at every physics
step (peaks from every step, overlaps from every ``--plan-overlap-stride``-th, both
checked against the executor's). ``--plans-only`` skips the episodes. Rows are
also appended to ``NAME.jsonl`` beside ``--json`` as they come; ``--resume`` keeps those and
runs the rest; ``--table-only`` runs nothing and prints the table of the rows there (a run
cut short: ``--seeds N`` keeps seeds 0 to N-1). Plan rows go to ``NAME.plans.jsonl``.

Columns: ``eps`` episodes, ``SR`` mean success rate, ``contacts`` / ``static`` AGV-AGV and
AGV-wall contacts (independent: samples with an overlap; ``exec``: the executor's
counters), ``viol`` limit violations (executor, wheel speeds included), ``speed`` /
``accel`` / ``turn`` / ``wheel`` the largest peak / limit (independent), ``lat`` the largest
lateral speed of a differential-drive body (m/s), ``clear`` the smallest AGV-AGV clearance
(m), ``agree``: whether the independent figures and the executor's say the same (contacts
zero on both sides or neither, peaks within 1e-6).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tools"))
SHIPPED = sorted(p.name for p in (ROOT / "layouts").glob("*.yaml") if p.stem != "industrial")
VARIANTS = {"2x2diff": [("fleet.types.large.drive", "diff"),
                        ("fleet.types.large.body_m", [1.4, 1.4])]}
"""Extra fleets: name -> overrides (for scenarios with a ``large`` type)."""
MAP = ROOT / "tests" / "data" / "warehouse-10-20-10-2-1.map"
DELAYS = [("executor.delays.model", "bernoulli"), ("executor.delays.prob", 0.05)]
PEAKS = ("peak_speed_ratio", "peak_accel_ratio", "peak_turn_rate_ratio",
         "peak_wheel_speed_ratio")


def episode(job: tuple) -> dict:
    """Run one episode with ``robot: diffdrive`` and check it (in a worker process)."""
    from diffdrive_checks import check_npz

    from warerover_phys import load_scenario, run_episode
    from warerover_phys.outputs import write_outputs

    name, variant, planner, seed, delays, max_ticks = job
    path = ROOT / "layouts" / name
    over = [("executor.name", "physics"), ("planner.name", planner), ("robot", "diffdrive"),
            ("max_ticks", max_ticks), *VARIANTS.get(variant, [])]
    dt = load_scenario(path, over).executor.dt_s
    over.append(("executor.trajectory_hz", 1.0 / dt))
    if delays:
        over += DELAYS
    sc = load_scenario(path, over)
    t0 = time.process_time()
    result = run_episode(sc, seed=seed)
    cpu = time.process_time() - t0
    with tempfile.TemporaryDirectory() as tmp:
        write_outputs(result, Path(tmp) / "run", with_trajectory=True)
        d = dict(np.load(Path(tmp) / "run" / "trajectories.npz"))
    diff = np.array([a.spec.drive == "diff" for a in result.world.agvs])
    row = check_npz(d, diff)
    m = result.metrics
    row.update(scenario=name + (f"+{variant}" if variant else ""), planner=planner, seed=seed,
               delays=delays, cpu_s=round(cpu, 2), success_rate=m.get("success_rate"),
               exec={k: m.get(k) for k in ("agv_contacts", "static_contacts",
                                           "limit_violations", "min_clearance_m",
                                           "peak_lateral_speed_mps", "off_reference", *PEAKS)})
    return row


def plan_run(job: tuple) -> dict:
    """Execute one plan file with no-slip drive or the default model (in a worker)."""
    from diffdrive_checks import check_npz

    from warerover_phys.execute import (
        DEFAULT_TYPE,
        execute_plan,
        load_floor,
        repair_cycles,
        robot_model,
        validate_plan,
    )
    from warerover_phys.plans import read_plan

    plan_file, solver, no_slip, dt_s, every_step, stride, checks = job
    layout, _, _ = load_floor(MAP)
    plan = read_plan(plan_file)
    sizes = [1] * plan.num_agents
    validate_plan(plan, layout, sizes)
    plan, repairs = repair_cycles(plan, layout, sizes)
    # robot: diffdrive as `warerover execute --set robot=diffdrive` has it (no_slip and
    # the wheel limits of the default type); the default model unchanged
    options, types = robot_model({"robot": "diffdrive" if no_slip else "default"},
                                 [DEFAULT_TYPE] * plan.num_agents)
    assert not no_slip or types[0].max_wheel_speed_mps is not None
    t0, c0 = time.perf_counter(), time.process_time()
    res = execute_plan(plan, layout, types, executor="physics", seed=0, repairs=repairs,
                       dt_s=dt_s, trajectory_hz=1.0 / dt_s if every_step else 10.0,
                       options=options)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    m = res.metrics
    row: dict = {"agv_overlap_samples": None, "static_overlap_samples": None,
                 "min_agv_clearance_m": None}  # --no-plan-checks: the timing alone
    if checks:
        d = {k: np.asarray(v) for k, v in res.trajectory.items()}
        row = check_npz(d, np.ones(plan.num_agents, dtype=bool),
                        overlap_stride=stride if every_step else 1)
        del d
    if not every_step:  # 10 Hz differences say little about per-step peaks: the executor's
        for k in PEAKS:
            row[k] = m.get(k)
        row["peak_lateral_speed_mps"] = m.get("peak_lateral_speed_mps")
    row.update(plan=plan_file.name, solver=solver, agents=plan.num_agents, no_slip=no_slip,
               dt_s=dt_s, peaks_from="poses, every step" if every_step else "executor",
               wall_s=round(wall, 1), cpu_s=round(cpu, 1),
               load_avg=round(os.getloadavg()[0], 2),
               real_time_factor=m.get("real_time_factor"),
               rtf_cpu=m["ticks"] * m["tick_s"] / cpu,
               executed_makespan=m.get("executed_makespan_ticks"),
               planned_makespan=m.get("planned_makespan_ticks"),
               exec={k: m.get(k) for k in ("agv_contacts", "static_contacts",
                                           "limit_violations", "min_clearance_m",
                                           "off_reference", "peak_lateral_speed_mps",
                                           *PEAKS)})
    return row


def agree(row: dict) -> bool | None:
    """The independent figures and the executor's say the same (None: not checked)."""
    ex = row["exec"]
    if row["agv_overlap_samples"] is None:
        return None
    same = (row["agv_overlap_samples"] > 0) == (ex["agv_contacts"] > 0) and (
        row.get("static_overlap_samples", 0) > 0) == (ex["static_contacts"] > 0)
    for k in PEAKS:
        a, b = row.get(k), ex.get(k)
        if a is not None and b is not None and abs(a - b) > 1e-6:
            same = False
    return same


def _n(v) -> str:
    return "-" if v is None else str(v)


def _fmt(v, digits: int = 4) -> str:
    return "-" if v is None else f"{v:.{digits}f}"


def table(rows: list[dict]) -> str:
    """One line per scenario x planner x delays."""
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        groups.setdefault((r["scenario"], r["planner"], r["delays"]), []).append(r)
    head = (f"{'scenario':34s} {'planner':7s} {'delays':6s} {'eps':>3s} {'SR':>5s} "
            f"{'contacts':>9s} {'static':>9s} {'viol':>4s} {'speed':>7s} {'accel':>7s} "
            f"{'turn':>7s} {'wheel':>7s} {'lat':>8s} {'clear':>7s} agree")
    lines = [head, "-" * len(head)]
    for (sc, pl, dl), rs in sorted(groups.items()):
        def mx(k: str, rs: list[dict] = rs):
            vals = [r[k] for r in rs if r.get(k) is not None]
            return max(vals) if vals else None
        clear = [r["min_agv_clearance_m"] for r in rs if r["min_agv_clearance_m"] is not None]
        lines.append(
            f"{sc:34s} {pl:7s} {'on' if dl else 'off':6s} {len(rs):3d} "
            f"{np.mean([r['success_rate'] for r in rs]):5.2f} "
            f"{sum(r['agv_overlap_samples'] > 0 for r in rs):3d}/"
            f"{sum(r['exec']['agv_contacts'] for r in rs):<5d}"
            f"{sum(r['static_overlap_samples'] > 0 for r in rs):3d}/"
            f"{sum(r['exec']['static_contacts'] for r in rs):<5d}"
            f"{sum(r['exec']['limit_violations'] for r in rs):4d} "
            f"{_fmt(mx('peak_speed_ratio'), 6):>7s} {_fmt(mx('peak_accel_ratio'), 6):>7s} "
            f"{_fmt(mx('peak_turn_rate_ratio'), 6):>7s} "
            f"{_fmt(mx('peak_wheel_speed_ratio'), 6):>7s} "
            f"{mx('peak_lateral_speed_mps'):8.1e} {_fmt(min(clear) if clear else None):>7s} "
            f"{'yes' if all(agree(r) for r in rs) else 'NO'}")
    return "\n".join(lines)


def summary(rows: list[dict]) -> str:
    """One sentence over every episode: seeds covered, contacts, agreement, largest peaks."""
    per_seed: dict[int, int] = {}
    for r in rows:
        per_seed[r["seed"]] = per_seed.get(r["seed"], 0) + 1
    bad = sum(1 for r in rows if r["agv_overlap_samples"] or r["static_overlap_samples"] or
              r["exec"]["agv_contacts"] or r["exec"]["static_contacts"] or
              r["exec"]["limit_violations"])
    peak = {k: max((r[k] for r in rows if r.get(k) is not None), default=None) for k in PEAKS}
    clear = [r["min_agv_clearance_m"] for r in rows if r["min_agv_clearance_m"] is not None]
    return (f"{len(rows)} episodes ({dict(sorted(per_seed.items()))} per seed), {bad} with a "
            f"contact, an overlap or a limit violation; independent and executor figures "
            f"agree in {sum(agree(r) for r in rows)} of {len(rows)}; largest peaks / limit: "
            + ", ".join(f"{k[5:-6].replace('_', ' ')} {_fmt(v, 12)}" for k, v in peak.items())
            + f"; largest lateral speed "
            f"{max(r['peak_lateral_speed_mps'] for r in rows):.1e} m/s; smallest AGV-AGV "
            f"clearance {_fmt(min(clear) if clear else None)} m")


def plan_table(rows: list[dict]) -> str:
    head = (f"{'plan':14s} {'solver':7s} {'model':8s} {'agents':>6s} {'ms exec':>7s} "
            f"{'contacts':>9s} {'static':>9s} {'viol':>4s} {'speed':>7s} {'accel':>7s} "
            f"{'turn':>7s} {'wheel':>7s} {'clear':>7s} {'RTF':>6s} {'RTFcpu':>6s} {'load':>5s} "
            f"peaks agree")
    lines = [head, "-" * len(head)]
    for r in rows:
        ex = r["exec"]
        lines.append(
            f"{r['plan']:14s} {r['solver']:7s} {'no_slip' if r['no_slip'] else 'default':8s} "
            f"{r['agents']:6d} {r['executed_makespan']:7d} "
            f"{_n(r['agv_overlap_samples']):>3s}/{ex['agv_contacts']:<5d}"
            f"{_n(r['static_overlap_samples']):>3s}/{ex['static_contacts']:<5d}"
            f"{ex['limit_violations']:4d} {_fmt(r['peak_speed_ratio'], 5):>7s} "
            f"{_fmt(r['peak_accel_ratio'], 5):>7s} {_fmt(r['peak_turn_rate_ratio'], 5):>7s} "
            f"{_fmt(r['peak_wheel_speed_ratio'], 5):>7s} "
            f"{_fmt(r['min_agv_clearance_m']):>7s} {r['real_time_factor']:6.1f} "
            f"{r['rtf_cpu']:6.1f} {r['load_avg']:5.1f} "
            f"{'poses' if r.get('peaks_from', '').startswith('poses') else 'exec':5s} "
            f"{ {True: 'yes', False: 'NO', None: '-'}[agree(r)]}")
    return "\n".join(lines)


def _key(scenario: str, planner: str, seed: int, delays: bool) -> str:
    return f"{scenario}|{planner}|{seed}|{delays}"


def run_episodes(jobs: list[tuple], workers: int, log: Path, resume: bool,
                 run: bool = True) -> list[dict]:
    """Run ``jobs`` in ``workers`` processes; each row is appended to ``log`` (JSON lines)
    as it comes, and with ``resume`` the rows already there are kept and not run again.
    ``run=False`` only reads ``log``: the rows of ``jobs`` already there."""
    rows = []
    if (resume or not run) and log.exists():
        rows = [json.loads(line) for line in log.read_text().splitlines() if line.strip()]
    keys = {_key(j[0] + (f"+{j[1]}" if j[1] else ""), j[2], j[3], j[4]): j for j in jobs}
    rows = [r for r in rows if _key(r["scenario"], r["planner"], r["seed"], r["delays"])
            in keys]
    done = {_key(r["scenario"], r["planner"], r["seed"], r["delays"]) for r in rows}
    todo = [j for k, j in keys.items() if k not in done] if run else []
    if not todo:
        return rows
    log.parent.mkdir(parents=True, exist_ok=True)
    with ProcessPoolExecutor(max_workers=workers) as pool, \
            log.open("a" if resume else "w") as out:
        futures = [pool.submit(episode, j) for j in todo]
        for fut in as_completed(futures):
            row = fut.result()
            rows.append(row)
            out.write(json.dumps(row, default=float) + "\n")
            out.flush()
            print(f"{row['scenario']} {row['planner']} seed {row['seed']} delays "
                  f"{row['delays']}: overlaps {row['agv_overlap_samples']}/"
                  f"{row['static_overlap_samples']}, exec {row['exec']['agv_contacts']}/"
                  f"{row['exec']['static_contacts']}/{row['exec']['limit_violations']}, "
                  f"{row['cpu_s']} s", file=sys.stderr, flush=True)
    return rows


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenarios", nargs="+", default=SHIPPED)
    ap.add_argument("--planners", nargs="+", default=["astar", "cbs", "pibt", "lacam"])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--delays", choices=["off", "on", "both"], default="both")
    ap.add_argument("--variants", action=argparse.BooleanOptionalAction, default=True,
                    help="also the 2x2 differential-drive fleets")
    ap.add_argument("--max-ticks", type=int, default=1000)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--plans", type=Path, help="folder with planN.txt (lacam3), ownN.txt")
    ap.add_argument("--agents", type=int, nargs="+", default=[100, 500, 1000])
    ap.add_argument("--plan-dt", type=float, default=0.02)
    ap.add_argument("--plans-only", action="store_true")
    ap.add_argument("--plan-every-step", action="store_true",
                    help="record the plan runs' poses at every physics step and recompute "
                         "the peaks from them (slower: the real-time factor is then not "
                         "the plain execution's)")
    ap.add_argument("--plan-checks", action=argparse.BooleanOptionalAction, default=True,
                    help="--no-plan-checks: time the plan runs only (no independent "
                         "checks: for real-time factors on a quiet machine)")
    ap.add_argument("--plan-overlap-stride", type=int, default=5,
                    help="with --plan-every-step: the overlap checks on every K-th sample "
                         "(5 at dt 0.02: 10 Hz, as without it; 1: every step)")
    ap.add_argument("--models", nargs="+", choices=["no_slip", "default"],
                    default=["no_slip", "default"], help="the robot models to run plans on")
    ap.add_argument("--json", type=Path, default=ROOT / "tools" / "out" / "diffdrive.json",
                    help="the rows (and, as they come, JSON lines beside it: NAME.jsonl)")
    ap.add_argument("--resume", action="store_true",
                    help="keep the episodes already in NAME.jsonl, run the others")
    ap.add_argument("--table-only", action="store_true",
                    help="run nothing: the table of the episodes in NAME.jsonl (those of "
                         "--scenarios x --planners x --seeds x --delays)")
    args = ap.parse_args()
    delays = {"off": [False], "on": [True], "both": [False, True]}[args.delays]
    jobs = []
    if not args.plans_only:
        for name in args.scenarios:
            variants = [""] + ([v for v in VARIANTS if "hetero" in name] if args.variants
                               else [])
            jobs += [(name, v, p, s, d, args.max_ticks) for v in variants
                     for p in args.planners for d in delays for s in range(args.seeds)]
    jobs.sort(key=lambda j: j[3])  # seed by seed: a run cut short covers every case
    rows, plan_rows = run_episodes(jobs, args.jobs, args.json.with_suffix(".jsonl"),
                                   args.resume, run=not args.table_only), []
    plan_log = args.json.with_suffix(".plans.jsonl")
    if args.plans and not args.table_only:
        plan_log.parent.mkdir(parents=True, exist_ok=True)
        plan_log.write_text("")
    if args.plans and not args.table_only:
        for n in args.agents:  # one at a time: the 1,000-agent runs want the memory
            for stem, solver in (("plan", "lacam3"), ("own", "lacam")):
                f = args.plans / f"{stem}{n}.txt"
                if not f.exists() and stem == "own":  # tools/bench_execute.py --solver lacam
                    f = args.plans / f"lacam-plan{n}.txt"
                if not f.exists():
                    print(f"{f}: missing, skipped", file=sys.stderr)
                    continue
                for no_slip in [m == "no_slip" for m in args.models]:
                    plan_rows.append(plan_run((f, solver, no_slip, args.plan_dt,
                                                args.plan_every_step,
                                                args.plan_overlap_stride,
                                                args.plan_checks)))
                    with plan_log.open("a") as out:  # kept if the run is cut short
                        out.write(json.dumps(plan_rows[-1], default=float) + "\n")
                    print(plan_table(plan_rows[-1:]).splitlines()[-1], file=sys.stderr,
                          flush=True)
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps({"episodes": rows, "plans": plan_rows,
                                     "load_avg": os.getloadavg()[0]}, indent=1,
                                    default=float) + "\n")
    if rows:
        print(table(rows))
        print(summary(rows))
    if plan_rows:
        print(plan_table(plan_rows))
    bad = [r for r in rows + plan_rows if r["agv_overlap_samples"] or
           r.get("static_overlap_samples") or r["exec"]["agv_contacts"] or
           r["exec"]["static_contacts"] or r["exec"]["limit_violations"]]
    print(f"{len(rows)} episodes, {len(plan_rows)} plan runs; {len(bad)} with a contact, an "
          f"overlap or a limit violation", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
