"""Benchmark the environments: steps per second (and agent-steps per second) on a MovingAI map.

For each agent count N: the numpy core (:class:`warerover_phys.envs.GridMAPF`, arrays in and
out, observations included) with random actions; the PettingZoo parallel API (dicts) with
random actions; and the learned policy + PIBT shield choosing every action
(:class:`warerover_phys.envs.LearnedDriver`, inference included). One BLAS thread.

``--executor physics`` (or any executor name) runs the same three on that executor: the
rules pick the intended cells, the executor carries them out (one 1 s tick per step, pymunk
bodies for ``physics``); the figures then include the executor's time. ``--rotations``:
headings and the four rotation actions (wait, forward, turn left, turn right; on a real
executor a turn is carried out by the body at its turn rate). Rates are per wall second;
the core's is also given per CPU second of this process (``time.process_time``), which a
busy shared machine disturbs less.

    PYTHONPATH=. .venv/bin/python tools/bench_env.py
    PYTHONPATH=. .venv/bin/python tools/bench_env.py --agents 64 --steps 200
    PYTHONPATH=. .venv/bin/python tools/bench_env.py --executor physics --agents 16 --steps 200
    PYTHONPATH=. .venv/bin/python tools/bench_env.py --executor physics --rotations --agents 16
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from warerover_phys.envs import EnvConfig, GridMAPF, Instance, LearnedDriver  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
MAP = ROOT / "tests" / "data" / "random-32-32-10.map"


def bench_core(inst, n, steps, lifelong=True, executor="grid", rotations=False):
    """(steps per wall second, steps per CPU second)."""
    core = GridMAPF(inst, EnvConfig(num_agents=n, max_steps=10**9, lifelong=lifelong,
                                    executor=executor, rotations=rotations))
    rng = np.random.default_rng(0)
    core.reset(rng)
    acts = rng.integers(0, core.num_actions, size=(steps, n))
    t0, c0 = time.perf_counter(), time.process_time()
    for a in acts:
        core.step(a)
    return steps / (time.perf_counter() - t0), steps / max(time.process_time() - c0, 1e-9)


def bench_parallel(inst, n, steps, executor="grid", rotations=False):
    from warerover_phys.envs import parallel_env

    env = parallel_env(inst, num_agents=n, max_steps=10**9, lifelong=True, executor=executor,
                       rotations=rotations)
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    k = env.core.num_actions
    t0 = time.perf_counter()
    for _ in range(steps):
        env.step({a: int(rng.integers(k)) for a in env.agents})
    return steps / (time.perf_counter() - t0)


def bench_learned(inst, n, steps, executor="grid", rotations=False):
    core = GridMAPF(inst, EnvConfig(num_agents=n, max_steps=10**9, lifelong=True,
                                    executor=executor, rotations=rotations))
    core.reset(np.random.default_rng(0))
    driver = LearnedDriver(core, seed=0)
    driver.reset()
    t0 = time.perf_counter()
    for _ in range(steps):
        core.step(driver.actions())
    return steps / (time.perf_counter() - t0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--agents", nargs="+", type=int, default=[16, 64, 256])
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--map", type=Path, default=MAP)
    ap.add_argument("--executor", default="grid",
                    help="grid (the step rules alone, default), physics, or any executor name")
    ap.add_argument("--rotations", action="store_true",
                    help="headings and rotation actions (wait, forward, turn left, right)")
    args = ap.parse_args()
    inst = Instance.from_movingai(args.map)
    ex, rot = args.executor, args.rotations
    print(f"map {args.map.name}, executor {ex}{', rotations' if rot else ''}, {args.steps} "
          "steps per run, lifelong goals, one BLAS thread")
    print(f"{'agents':>6} | {'core steps/s':>12} {'agent-steps/s':>13} {'steps/CPU-s':>11} | "
          f"{'PettingZoo steps/s':>18} | {'learned steps/s':>15} {'agent-steps/s':>13}")
    for n in args.agents:
        core, core_cpu = bench_core(inst, n, args.steps, executor=ex, rotations=rot)
        pz = bench_parallel(inst, n, args.steps, executor=ex, rotations=rot)
        learned = bench_learned(inst, n, max(20, args.steps // 3), executor=ex, rotations=rot)
        print(f"{n:>6} | {core:>12.0f} {core * n:>13.0f} {core_cpu:>11.0f} | {pz:>18.0f} | "
              f"{learned:>15.0f} {learned * n:>13.0f}", flush=True)


if __name__ == "__main__":
    main()
