"""Benchmark the live browser view: 1,000 AGVs on the industrial floor in headless Chromium.

Runs ``warerover serve``'s app (uvicorn in a thread, ephemeral port) on
``layouts/industrial.yaml`` with the fleet raised to ``--agvs`` (lifelong PIBT on the grid
executor, a steady order stream), opens the page in Debian's headless ``chromium``
(Playwright), and for ``--seconds`` measures:

- ``page_fps``: requestAnimationFrame callbacks per second (every callback interpolates and
  draws the whole view: floor, corridors, planned paths, 1,000 bodies);
- ``frames_per_s``: live frames the page received per second (the server sends at most 30);
- ``server_ticks_per_s``: simulation ticks per second while serving, and
  ``sim_only_ticks_per_s``: the same simulation stepped alone (no server, no page), so the
  cost of serving shows as the ratio ``keeps_up``;
- ``frame_bytes``: size of one binary live frame.

Target: ``page_fps >= 30``.

    .venv/bin/python tools/bench_serve.py
    .venv/bin/python tools/bench_serve.py --agvs 1000 --seconds 15 --speed 0

Prints the figures and writes ``tools/out/bench_serve.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
SCENARIO = REPO / "layouts" / "industrial.yaml"
TARGET_FPS = 30.0


def overrides(agvs: int) -> list[tuple[str, object]]:
    return [("fleet.agvs.0.count", agvs), ("max_ticks", 1_000_000),
            ("orders.duration_ticks", 1_000_000), ("planner.name", "pibt"),
            ("executor.name", "grid")]


def sim_only(agvs: int, ticks: int) -> tuple[float, float]:
    """(build seconds, ticks per second) of the simulation alone, after a short warm-up."""
    from warerover_phys.serve.session import LiveSession

    t0 = time.perf_counter()
    s = LiveSession(SCENARIO, REPO, overrides=overrides(agvs))
    build = time.perf_counter() - t0
    s.step(5)
    t0 = time.perf_counter()
    s.step(ticks)
    return build, ticks / (time.perf_counter() - t0)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--agvs", type=int, default=1000)
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--speed", type=float, default=0.0,
                    help="ticks per second asked of the server (0: as fast as it runs)")
    ap.add_argument("--size", default="1280x720", help="browser viewport, WxH")
    ap.add_argument("--tab", choices=("live", "3d"), default="live",
                    help="which view to measure (the 2D live view or the WebGL 3D view)")
    ap.add_argument("--chromium", default=shutil.which("chromium") or "/usr/bin/chromium")
    ap.add_argument("--out", type=Path, default=REPO / "tools" / "out" / "bench_serve.json")
    args = ap.parse_args()
    if not Path(args.chromium).exists():
        print(f"chromium not found at {args.chromium} (apt-get install chromium)",
              file=sys.stderr)
        return 2
    from playwright.sync_api import sync_playwright

    from warerover_phys.serve.server import ServerThread, create_app

    build_s, alone = sim_only(args.agvs, 30)
    print(f"simulation alone: {args.agvs} AGVs, built in {build_s:.1f} s, "
          f"{alone:.1f} ticks/s")
    w, h = (int(v) for v in args.size.lower().split("x"))
    root = Path(tempfile.mkdtemp(prefix="bench_serve_"))
    app = create_app(root, SCENARIO, overrides=overrides(args.agvs), ticks_per_s=args.speed)
    hub = app.state.hub
    with ServerThread(app) as srv, sync_playwright() as p:
        browser = p.chromium.launch(executable_path=args.chromium, args=["--no-sandbox"])
        page = browser.new_page(viewport={"width": w, "height": h})
        page.goto(srv.url)
        page.wait_for_function("window.wr && window.wr.frames >= 3", timeout=120_000)
        if args.tab == "3d":
            page.click("button[data-tab='3d']")
        page.wait_for_timeout(1500)                     # settle (first layout image, JIT)
        r0 = page.evaluate("[wr.rafFrames, wr.frames, performance.now()]")
        tick0, t0 = hub.session.sim.world.tick, time.perf_counter()
        page.wait_for_timeout(args.seconds * 1000)
        r1 = page.evaluate("[wr.rafFrames, wr.frames, performance.now()]")
        tick1, t1 = hub.session.sim.world.tick, time.perf_counter()
        frame_bytes = len(hub._frame()[2])
        shot = Path(tempfile.gettempdir()) / "bench_serve.png"
        page.screenshot(path=str(shot))
        browser.close()
    page_s = (r1[2] - r0[2]) / 1000
    served = (tick1 - tick0) / (t1 - t0)
    result = {
        "agvs": args.agvs, "scenario": str(SCENARIO.relative_to(REPO)), "planner": "pibt",
        "executor": "grid", "view": args.tab, "viewport": args.size, "seconds": round(page_s, 2),
        "page_fps": round((r1[0] - r0[0]) / page_s, 1),
        "frames_per_s": round((r1[1] - r0[1]) / page_s, 1),
        "server_ticks_per_s": round(served, 1), "sim_only_ticks_per_s": round(alone, 1),
        "keeps_up": round(served / alone, 2) if alone else None,
        "frame_bytes": frame_bytes, "target_fps": TARGET_FPS,
        "meets_target": (r1[0] - r0[0]) / page_s >= TARGET_FPS,
        "machine": {"python": platform.python_version(), "cpus": os.cpu_count(),
                    "platform": platform.platform()},
    }
    for k, v in result.items():
        if k != "machine":
            print(f"{k:>22}: {v}")
    if args.tab != "live" and args.out.name == "bench_serve.json":
        args.out = args.out.with_name(f"bench_serve_{args.tab}.json")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n")
    print(f"wrote {args.out} (screenshot {shot})")
    return 0 if result["meets_target"] else 1


if __name__ == "__main__":
    raise SystemExit(main())
