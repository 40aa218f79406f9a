"""Episode outputs: ``metrics.json``, ``events.jsonl``, ``paths.json`` and (physics
executor) ``trajectories.npz`` in one folder.

``paths.json`` holds ``agvs`` (id -> type, footprint, ticks per move), ``planned`` (every
committed path: AGV, start tick, per-tick ``[[row, col], [row, col]]`` from/to anchors) and
``actual`` (per AGV, the executed ``[[row, col], [row, col]]`` per tick from tick 0).
Files are written to a temporary name and renamed, so an interrupted run never leaves a
half-written file in place of a good one.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from .sim import EpisodeResult

__all__ = ["write_outputs"]


def _atomic_write(path: Path, text: str) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, path)


def write_outputs(result: EpisodeResult, out_dir: str | Path) -> dict[str, Path]:
    """Write the three output files of an episode into ``out_dir`` (created if missing)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    cols = result.world.layout.cols

    def cell(node: int) -> list[int]:
        return list(divmod(int(node), cols))

    paths = {
        "agvs": {str(a.id): {"type": a.type_name, "footprint": a.k,
                             "ticks_per_move": a.ticks_per_move}
                 for a in result.world.agvs},
        "planned": [{"agv": p["agv"], "tick": p["tick"],
                     "states": [[cell(a), cell(b)] for a, b in p["states"]]}
                    for p in result.planned],
        "actual": {str(aid): [[cell(a), cell(b)] for a, b in states]
                   for aid, states in result.actual.items()},
    }
    files = {"metrics": out / "metrics.json", "events": out / "events.jsonl",
             "paths": out / "paths.json"}
    _atomic_write(files["metrics"], json.dumps(result.metrics, indent=2, sort_keys=True) + "\n")
    _atomic_write(files["events"], "".join(json.dumps(e, sort_keys=True) + "\n"
                                           for e in result.events))
    _atomic_write(files["paths"], json.dumps(paths, separators=(",", ":")) + "\n")
    if result.trajectory is not None:
        files["trajectory"] = out / "trajectories.npz"
        write_trajectory(result.trajectory, files["trajectory"])
    return files


def write_trajectory(trajectory: dict, path: Path) -> None:
    """Executed poses (see ``PhysicsExecutor.trajectory``), compressed numpy arrays."""
    import numpy as np

    tmp = path.with_name(path.name + ".tmp.npz")
    np.savez_compressed(tmp, **trajectory)
    os.replace(tmp, path)
