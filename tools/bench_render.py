"""Benchmark rendering: frames per second at 720p with 50, 1,000 and 5,000 AGVs: drawing
alone, encoding alone, and end to end (``render_video``) with 1 and 2 workers.

Synthetic recordings on MovingAI ``warehouse-10-20-10-2-1`` (63 x 161 cells; for 5,000 AGVs
the map tiled 2 x 2, 126 x 322 cells): AGVs drive straight along free rows or columns at
1.5 m/s (positions recorded at 10 Hz, as the physics executor does) with what a plan
execution records: about 55% driving, 5% turning, 20% waiting on a dependency (an arrow to
the nearest other AGV), 15% finished, 5% failed (each with an open safety corridor), and a
plan whose progress (``plan_tick``) gives an 8-step path ahead of every AGV. ``--trajectory``
benchmarks a recorded run instead (a ``trajectories.npz`` or its folder).

Reported per case, wall clock: ``draw_fps`` (sample + draw, one thread), ``encode_fps``
(encoding the drawn frames alone: colour conversion + libx264, one thread feeding it), and
``fps_w1`` / ``fps_w2``: ``render_video`` end to end (sample, draw, encode in its own
thread; with 2 workers two processes each draw and encode half the frames, then the pieces
are joined without re-encoding). And the CPU time each took per frame (all threads, worker
processes included: ``draw_cpu_ms``, ``encode_cpu_ms``, ``cpu_ms_w1``, ``cpu_ms_w2``), with
``fps_2core_bound_w2`` = 2000 / ``cpu_ms_w2``: the frame rate two dedicated cores would give
if the 2-worker render's work were spread evenly over them. On a machine shared with other
work the wall-clock figures fall while the CPU figures stay; read both with the load average
printed beside them. The targets (issue 36, 720p on a 2-core machine): >= 150 fps with 50
AGVs, >= 60 with 1,000, >= 25 with 5,000, end to end (wall clock) with the better of 1 and
2 workers.

    .venv/bin/python tools/bench_render.py
    .venv/bin/python tools/bench_render.py --agvs 50 1000 5000 --frames 300 --preset superfast
    .venv/bin/python tools/bench_render.py --trajectory runs/exec1000 --agvs 0

Prints a table (with the load average at the start and the end) and writes
``tools/out/bench_render.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import tempfile
import time
from pathlib import Path

import numpy as np

from warerover_phys.problems.movingai import read_map
from warerover_phys.render import (
    Recording,
    Style,
    VideoWriter,
    draw_frame,
    load_trajectory,
    parse_size,
    render_video,
)

ROOT = Path(__file__).resolve().parent.parent
MAP = ROOT / "tests" / "data" / "warehouse-10-20-10-2-1.map"
TARGETS = {50: 150.0, 1000: 60.0, 5000: 25.0}


def floor(n: int) -> np.ndarray:
    """The benchmark floor for ``n`` AGVs (``CellType`` codes: 0 free, 1 obstacle)."""
    grid = read_map(MAP).obstacles.astype(np.int8)
    return np.tile(grid, (2, 2)) if n > 2000 else grid


def synthetic(grid: np.ndarray, n: int, seconds: float = 60.0, hz: float = 10.0,
              seed: int = 0) -> Recording:
    """``n`` AGVs driving straight along free rows or columns (bouncing at the ends), with
    execution states, blockers and plan progress (see the module docstring)."""
    rng = np.random.default_rng(seed)
    rows, cols = grid.shape
    free = np.argwhere(grid == 0)
    start = free[rng.choice(len(free), n, replace=False)]
    horizontal = rng.random(n) < 0.5
    speed = 1.5 * rng.choice([-1.0, 1.0], n)
    t = np.arange(int(seconds * hz) + 1) / hz
    travel = speed[None, :] * t[:, None]

    def bounce(p0: np.ndarray, span: float) -> tuple[np.ndarray, np.ndarray]:
        lo, hi = 0.5, span - 0.5
        u = (p0[None, :] - lo + travel) % (2 * (hi - lo))
        back = u > hi - lo
        return np.where(back, hi - (u - (hi - lo)), lo + u), back

    xb, xback = bounce(start[:, 1] + 0.5, cols)
    yb, yback = bounce(start[:, 0] + 0.5, rows)
    x = np.where(horizontal, xb, start[:, 1] + 0.5)
    y = np.where(horizontal, start[:, 0] + 0.5, yb)
    forward = np.where(horizontal, np.where(xback, -speed, speed), np.where(yback, -speed, speed))
    heading = np.where(horizontal, np.where(forward > 0, 0.0, np.pi),
                       np.where(forward > 0, np.pi / 2, -np.pi / 2))
    # exec_state codes: 1 driving, 2 turning, 3 waiting, 5 failed, 6 finished
    code = rng.choice([1, 2, 3, 6, 5], n, p=[0.55, 0.05, 0.2, 0.15, 0.05]).astype(np.int8)
    still = np.flatnonzero(code != 1)
    for a in (x, y, heading):
        a[:, still] = a[0, still]
    exec_state = np.repeat(code[None, :], len(t), axis=0)
    blocker = np.full((len(t), n), -1, dtype=np.int32)
    waiting = np.flatnonzero(code == 3)
    if len(waiting):
        from scipy.spatial import cKDTree

        _, near = cKDTree(np.stack([x[0], y[0]], axis=1)).query(
            np.stack([x[0, waiting], y[0, waiting]], axis=1), k=2)
        blocker[:, waiting] = near[:, 1]
    failed = np.flatnonzero(code == 5)
    corridors = []
    for k, i in enumerate(failed.tolist()):
        cx, cy = float(x[0, i]), float(y[0, i])
        ring = [[cx - 0.7, cy - 0.7], [cx + 0.7, cy - 0.7], [cx + 0.7, rows - 0.0],
                [cx - 0.7, rows - 0.0], [cx - 0.7, cy - 0.7]]
        corridors.append({"id": k, "agv": i, "open_tick": 0, "close_tick": None,
                          "polygon": [ring], "zone": [ring], "cells": []})
    step = int(hz)
    plans = {i: [(0, np.stack([x[::step, i], y[::step, i]], axis=1))] for i in range(n)}
    plan_tick = np.repeat(np.minimum(np.floor(t).astype(np.int32) + 1, int(seconds))[:, None],
                          n, axis=1)
    state = np.where(code == 5, 7, 1)[None, :].repeat(len(t), axis=0).astype(np.int8)
    return Recording(t=t, x=x, y=y, heading=heading, state=state,
                     loaded=np.zeros((len(t), n), dtype=bool),
                     footprint=np.ones(n, dtype=np.int64), body_m=np.full((n, 2), 0.7),
                     cell_m=1.0, tick_s=1.0, grid=grid, corridors=tuple(corridors),
                     plans=plans, exec_state=exec_state, blocker=blocker, plan_tick=plan_tick)


def _cpu() -> float:
    """CPU seconds of this process (all its threads) and of its finished children."""
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


def _timed(fn) -> tuple[float, float]:
    """(wall seconds, CPU seconds) of ``fn()``."""
    w0, c0 = time.perf_counter(), _cpu()
    fn()
    return time.perf_counter() - w0, _cpu() - c0


def bench(rec: Recording, style: Style, frames: int, preset: str, fps: float = 30.0) -> dict:
    speed = max(2.0, (rec.end_s - rec.start_s) * fps / frames)
    times = rec.start_s + np.arange(frames) * (speed / fps)
    horizon = style.path_ticks if style.show_paths else 0
    draw_frame(rec.at(times[0], horizon), style)                # background, compiled code
    drawn: list[np.ndarray] = []
    draw_s, draw_cpu = _timed(lambda: drawn.extend(
        draw_frame(rec.at(float(t), horizon), style) for t in times))
    out: dict = {"agvs": rec.num_agvs, "frames": frames, "size": list(style.size),
                 "preset": preset, "speed": speed}
    with tempfile.TemporaryDirectory() as tmp:
        def encode() -> None:
            with VideoWriter(Path(tmp) / "a.mp4", fps, style.size, preset=preset) as w:
                for img in drawn:
                    w.write(img)

        encode_s, encode_cpu = _timed(encode)
        drawn.clear()
        for workers in (1, 2):
            path = Path(tmp) / f"w{workers}.mp4"
            wall, cpu = _timed(lambda w=workers, p=path: render_video(
                rec, p, fps=fps, speed=speed, style=style, max_frames=frames, preset=preset,
                workers=w))
            out[f"fps_w{workers}"] = round(frames / wall, 1)
            out[f"cpu_ms_w{workers}"] = round(1000 * cpu / frames, 2)
            out[f"mp4_mb_w{workers}"] = round(path.stat().st_size / 1e6, 2)
    out.update(draw_fps=round(frames / draw_s, 1), encode_fps=round(frames / encode_s, 1),
               draw_cpu_ms=round(1000 * draw_cpu / frames, 2),
               encode_cpu_ms=round(1000 * encode_cpu / frames, 2))
    # What two dedicated cores would give if the work were spread evenly over them (the
    # CPU time is measured; on a loaded machine the wall-clock figures are lower).
    out["fps_2core_bound_w2"] = round(2000 / out["cpu_ms_w2"], 1)
    return out


def _load() -> str:
    return " ".join(f"{v:.2f}" for v in os.getloadavg())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--agvs", type=int, nargs="+", default=[50, 1000, 5000],
                    help="synthetic fleets (0: none)")
    ap.add_argument("--trajectory", type=Path, help="also benchmark this recorded run")
    ap.add_argument("--frames", type=int, default=300)
    ap.add_argument("--size", default="720p")
    ap.add_argument("--preset", default="superfast")
    ap.add_argument("--json", default="tools/out/bench_render.json")
    args = ap.parse_args()
    style = Style(size=parse_size(args.size))
    cases = [(f"synthetic {n}", n, lambda n=n: synthetic(floor(n), n)) for n in args.agvs if n]
    if args.trajectory:
        cases.append((str(args.trajectory), None, lambda: load_trajectory(args.trajectory)))
    load0 = _load()
    print(f"warehouse-10-20-10-2-1 (5,000 AGVs: tiled 2 x 2), {args.size}, {args.frames} "
          f"frames, libx264 {args.preset}; load average {load0}")
    print(f"{'case':>22} {'AGVs':>6} | {'draw':>6} {'encode':>6} {'1 worker':>8} {'2 workers':>9} "
          f"{'target':>6} | {'draw':>5} {'encode':>6} {'1 wkr':>6} {'2 wkr':>6} {'2-core':>6}")
    print(f"{'':>22} {'':>6} | {'wall-clock frames per second':^41} | "
          f"{'CPU ms per frame':^27} {'bound':>6}")
    rows = []
    for name, n, make in cases:
        rec = make()
        row = {"case": name, **bench(rec, style, args.frames, args.preset)}
        n = row["agvs"]
        best = max(row["fps_w1"], row["fps_w2"])
        row["target_fps"] = TARGETS.get(n) if name.startswith("synthetic") else None
        row["meets_target"] = None if row["target_fps"] is None else best >= row["target_fps"]
        row["load_after"] = _load()
        rows.append(row)
        target = "-" if row["target_fps"] is None else f">={row['target_fps']:g}"
        print(f"{name:>22} {n:>6} | {row['draw_fps']:>6.1f} {row['encode_fps']:>6.1f} "
              f"{row['fps_w1']:>8.1f} {row['fps_w2']:>9.1f} {target:>6} | "
              f"{row['draw_cpu_ms']:>5.1f} {row['encode_cpu_ms']:>6.1f} {row['cpu_ms_w1']:>6.1f} "
              f"{row['cpu_ms_w2']:>6.1f} {row['fps_2core_bound_w2']:>6.1f}", flush=True)
    import av
    import cv2

    load1 = _load()
    print(f"load average at the end: {load1}")
    out = {"cases": rows, "map": MAP.name, "load_average_start": load0,
           "load_average_end": load1,
           "machine": {"python": platform.python_version(), "cpus": os.cpu_count(),
                       "platform": platform.platform(), "opencv": cv2.__version__,
                       "av": av.__version__}}
    path = Path(args.json)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(out, indent=2) + "\n", encoding="utf-8")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
