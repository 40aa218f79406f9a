"""Benchmark rendering: frames per second at 720p with 50 and 1000 AGVs, drawing + encoding.

Synthetic trajectories on the floor of ``layouts/industrial.yaml`` (the generated 1,680-shelf
layout): AGVs drive straight along the aisles at 1.5 m/s (positions recorded at 10 Hz, as
the physics executor does), a mix of statuses (about 60% moving, 25% loaded, 10% idle, 5%
failed, each failed AGV with an open safety corridor) and an 8-step planned path ahead of
every working AGV. Each frame samples the recording at its own time (interpolation), draws
it and, for the end-to-end figure, encodes it to H.264 (PyAV, libx264, the default
``superfast`` preset unless ``--preset``).

Reported per case: ``draw_fps`` (sample + draw), ``encode_fps`` (encoding the drawn frames
alone) and ``fps`` (sample + draw + encode, one after another, as ``warerover render`` does).
Targets: >= 60 fps with 50 AGVs, >= 15 with 1000.

    .venv/bin/python tools/bench_render.py
    .venv/bin/python tools/bench_render.py --agvs 50 1000 --frames 300 --size 720p

Prints a table and writes ``tools/out/bench_render.json``.
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

from warerover_phys import load_scenario
from warerover_phys.render import Recording, Style, VideoWriter, draw_frame, parse_size
from warerover_phys.world import World

TARGETS = {50: 60.0, 1000: 15.0}


def synthetic(grid: np.ndarray, n: int, seconds: float = 60.0, hz: float = 10.0,
              seed: int = 0) -> Recording:
    """``n`` AGVs driving straight along free rows or columns (bouncing at the ends)."""
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
    status = rng.choice([1, 2, 0, 7], n, p=[0.6, 0.25, 0.1, 0.05])
    failed = np.flatnonzero(status == 7)
    x[:, failed] = x[0, failed]
    y[:, failed] = y[0, failed]
    heading[:, failed] = heading[0, failed]
    state = np.repeat(np.where(status == 2, 3, status)[None, :], len(t), axis=0).astype(np.int8)
    loaded = np.repeat((status == 2)[None, :], len(t), axis=0)
    corridors = []
    for k, i in enumerate(failed.tolist()):
        cx, cy = float(x[0, i]), float(y[0, i])
        ring = [[cx - 0.7, cy - 0.7], [cx + 0.7, cy - 0.7], [cx + 0.7, rows - 0.0],
                [cx - 0.7, rows - 0.0], [cx - 0.7, cy - 0.7]]
        corridors.append({"id": k, "agv": i, "open_tick": 0, "close_tick": None,
                          "polygon": [ring], "zone": [ring], "cells": []})
    plans = {}
    for i in np.flatnonzero(status != 7).tolist():
        pts = np.stack([x[:, i], y[:, i]], axis=1)[:: int(hz)]
        plans[i] = [(0, pts)]
    return Recording(t=t, x=x, y=y, heading=heading, state=state, loaded=loaded,
                     footprint=np.ones(n, dtype=np.int64), body_m=np.full((n, 2), 0.7),
                     cell_m=1.0, tick_s=1.0, grid=grid, corridors=tuple(corridors),
                     order_created=np.zeros(400), order_done=np.sort(rng.uniform(0, 60, 120)),
                     plans=plans)


def bench(rec: Recording, style: Style, frames: int, preset: str, fps: float = 30.0) -> dict:
    times = rec.start_s + np.arange(frames) * (2.0 / fps)       # 2x real time
    horizon = style.path_ticks if style.show_paths else 0
    draw_frame(rec.at(times[0], horizon), style)                # background cached
    t0 = time.perf_counter()
    drawn = [draw_frame(rec.at(float(t), horizon), style) for t in times]
    draw_s = time.perf_counter() - t0
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        with VideoWriter(Path(tmp) / "a.mp4", fps, style.size, preset=preset) as w:
            for img in drawn:
                w.write(img)
        encode_s = time.perf_counter() - t0
        del drawn
        t0 = time.perf_counter()
        with VideoWriter(Path(tmp) / "b.mp4", fps, style.size, preset=preset) as w:
            for t in times:
                w.write(draw_frame(rec.at(float(t), horizon), style))
        both_s = time.perf_counter() - t0
        size_mb = (Path(tmp) / "b.mp4").stat().st_size / 1e6
    return {"agvs": rec.num_agvs, "frames": frames, "size": list(style.size),
            "preset": preset, "draw_fps": round(frames / draw_s, 1),
            "encode_fps": round(frames / encode_s, 1), "fps": round(frames / both_s, 1),
            "mp4_mb": round(size_mb, 2)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--agvs", type=int, nargs="+", default=[50, 1000])
    ap.add_argument("--frames", type=int, default=300)
    ap.add_argument("--size", default="720p")
    ap.add_argument("--preset", default="superfast")
    ap.add_argument("--json", default="tools/out/bench_render.json")
    args = ap.parse_args()
    grid = World.build(load_scenario("layouts/industrial.yaml")).layout.grid
    style = Style(size=parse_size(args.size))
    rows = []
    print(f"layout industrial {grid.shape[0]}x{grid.shape[1]} cells, {args.size}, "
          f"{args.frames} frames, libx264 {args.preset}")
    print(f"{'AGVs':>6} {'draw fps':>9} {'encode fps':>11} {'draw+encode fps':>16} "
          f"{'target':>7}")
    for n in args.agvs:
        row = bench(synthetic(grid, n), style, args.frames, args.preset)
        row["target_fps"] = TARGETS.get(n)
        row["meets_target"] = None if n not in TARGETS else row["fps"] >= TARGETS[n]
        rows.append(row)
        target = "-" if n not in TARGETS else f">={TARGETS[n]:g}"
        print(f"{n:>6} {row['draw_fps']:>9.1f} {row['encode_fps']:>11.1f} {row['fps']:>16.1f} "
              f"{target:>7}")
    import av
    import cv2

    out = {"cases": rows, "layout": "layouts/industrial.yaml", "grid": list(grid.shape),
           "machine": {"python": platform.python_version(), "cpus": os.cpu_count(),
                       "platform": platform.platform(), "opencv": cv2.__version__,
                       "av": av.__version__}}
    path = Path(args.json)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(out, indent=2) + "\n", encoding="utf-8")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
