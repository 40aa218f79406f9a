"""A watchdog that ends what a sweep started when the sweep itself is killed (SIGKILL gives
it no chance to clean up): the Ray processes of ``--ray local`` (raylet, GCS, dashboard agent,
workers) and any other descendant of the driver.

:func:`start_reaper` spawns a small Python process that, every half second, records the
driver's descendants (pid and start time, from ``/proc``); once the driver is gone it sends
SIGTERM, then SIGKILL, to every recorded process still alive (same pid *and* start time, so a
reused pid is never hit) and to their own descendants. The driver stops the reaper when it
ends normally. Linux only (``/proc``); elsewhere :func:`start_reaper` returns None.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

__all__ = ["start_reaper", "stop_reaper"]

_CODE = r'''
import os, signal, sys, time
driver, me = int(sys.argv[1]), os.getpid()

def table():
    out = {}
    for name in os.listdir("/proc"):
        if name.isdigit():
            try:
                with open(f"/proc/{name}/stat") as f:
                    rest = f.read().rsplit(")", 1)[1].split()
            except OSError:
                continue
            out[int(name)] = (int(rest[1]), rest[19], rest[0])   # ppid, start time, state
    return out

def below(roots, procs):
    seen, frontier = set(), set(roots)
    while frontier:
        frontier = {p for p, (pp, _, _) in procs.items() if pp in frontier} - seen
        seen |= frontier
    return seen

known = {}
while True:
    procs = table()
    if driver not in procs or procs[driver][2] == "Z":
        break
    for pid in below({driver}, procs) - {me}:
        known[pid] = procs[pid][1]
    time.sleep(0.5)
for sig in (signal.SIGTERM, signal.SIGKILL):
    procs = table()
    live = {p for p, start in known.items() if p in procs and procs[p][1] == start}
    targets = (live | below(live, procs)) - {me}
    if not targets:
        break
    for pid in targets:
        try:
            os.kill(pid, sig)
        except OSError:
            pass
    time.sleep(2.0)
'''


def start_reaper() -> subprocess.Popen | None:
    """Start the watchdog for this process (None where ``/proc`` is missing)."""
    if not Path("/proc/self/stat").exists():
        return None
    return subprocess.Popen([sys.executable, "-c", _CODE, str(os.getpid())],
                            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, start_new_session=True)


def stop_reaper(proc: subprocess.Popen | None) -> None:
    """Stop the watchdog (the driver is ending normally and cleaned up itself)."""
    if proc is not None and proc.poll() is None:
        proc.kill()
        proc.wait(timeout=5)
