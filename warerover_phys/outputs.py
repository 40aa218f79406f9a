"""Episode outputs: ``metrics.json``, ``events.jsonl``, ``paths.json`` and (physics
executor) ``trajectories.npz`` in one folder.

``paths.json`` holds ``agvs`` (id -> type, footprint, ticks per move), ``planned`` (every
committed path: AGV, start tick, per-tick ``[[row, col], [row, col]]`` from/to anchors) and
``actual`` (per AGV, the executed ``[[row, col], [row, col]]`` per tick from tick 0). With
``planner.rotations`` a planned path also has ``headings`` (direction index per state: 0
east, 1 south, 2 west, 3 north) and ``headings`` maps each rotation-aware AGV to its
executed heading per tick.
The files are written as one set (:func:`warerover_phys.util.atomic.write_set`): into a new
folder beside the output folder, with a ``manifest.json`` (run id, every file's size and
SHA-256), which then takes the output folder's place in one step. An interrupted run leaves
the previous complete set; readers refuse a folder whose files do not match its manifest.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from .util.atomic import replacing, write_set

if TYPE_CHECKING:
    from .sim import EpisodeResult

__all__ = ["write_outputs"]


def write_outputs(result: EpisodeResult, out_dir: str | Path, *,
                  with_trajectory: bool = False,
                  extra: dict[str, Callable[[Path], object]] | None = None) -> dict[str, Path]:
    """Write the output files of an episode into ``out_dir`` (created if missing), as one
    set. ``with_trajectory``: a grid episode also gets ``trajectories.npz`` (for rendering).
    ``extra``: more files of the set, file name -> writer (e.g. ``warerover lorr``'s
    ``output.json``); returned under their file names.
    """
    cols = result.world.layout.cols

    def cell(node: int) -> list[int]:
        return list(divmod(int(node), cols))

    paths = {
        "agvs": {str(a.id): {"type": a.type_name, "footprint": a.k,
                             "ticks_per_move": a.ticks_per_move}
                 for a in result.world.agvs},
        "planned": [{"agv": p["agv"], "tick": p["tick"],
                     "states": [[cell(a), cell(b)] for a, b in p["states"]],
                     **({"headings": p["headings"]} if "headings" in p else {})}
                    for p in result.planned],
        "actual": {str(aid): [[cell(a), cell(b)] for a, b in states]
                   for aid, states in result.actual.items()},
    }
    if getattr(result, "headings", None):
        paths["headings"] = {str(aid): hs for aid, hs in result.headings.items()}
    finite = {k: (None if isinstance(v, float) and not math.isfinite(v) else v)
              for k, v in result.metrics.items()}          # JSON has no inf / nan
    metrics = json.dumps(finite, indent=2, sort_keys=True) + "\n"
    events = "".join(json.dumps(e, sort_keys=True) + "\n" for e in result.events)
    paths_text = json.dumps(paths, separators=(",", ":")) + "\n"
    writers: dict[str, Callable[[Path], object]] = {
        "metrics.json": lambda p: p.write_text(metrics, encoding="utf-8"),
        "events.jsonl": lambda p: p.write_text(events, encoding="utf-8"),
        "paths.json": lambda p: p.write_text(paths_text, encoding="utf-8"),
    }
    trajectory = result.trajectory
    if trajectory is None and with_trajectory:
        from .render.trajectory import grid_trajectory

        trajectory = grid_trajectory(result)
    if trajectory is not None:
        writers["trajectories.npz"] = lambda p: _savez(p, trajectory)
    writers.update(extra or {})
    sc = result.world.scenario
    written = write_set(out_dir, writers, meta={"scenario": sc.name, "seed": sc.seed,
                                                "source": sc.source})
    names = {"metrics.json": "metrics", "events.jsonl": "events", "paths.json": "paths",
             "trajectories.npz": "trajectory"}
    return {names.get(n, n): p for n, p in written.items()}


def _savez(path: Path, trajectory: dict) -> None:
    import numpy as np

    with path.open("wb") as f:
        np.savez_compressed(f, **trajectory)


def write_trajectory(trajectory: dict, path: Path) -> None:
    """Executed poses (see ``PhysicsExecutor.trajectory``), compressed numpy arrays."""
    with replacing(path) as tmp:
        _savez(tmp, trajectory)
