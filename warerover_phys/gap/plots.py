"""Pictures of the open-loop gap (PNG, matplotlib with the Agg backend, imported lazily).

- ``time_space.png``: planned vs executed progress of selected AGVs (cells moved against
  time): the plan dashed blue, the physics execution solid orange; flat parts are waits and
  dwells;
- ``lost_by_cause.png``: each AGV's lost time split into causes, a stacked bar per AGV
  (delays above zero, time gained below), the total as a black dot;
- ``gap_hist.png`` (several seeds): the distribution of ``makespan_ratio`` over the seeds,
  with its mean (red line);
- ``wait_heat.png``: where AGVs waited on a dependency: seconds per cell (mean per seed,
  yellow to dark red) over the floor (obstacles dark grey, shelves light blue, stations
  light green, parking light grey).

Every figure has a fixed size in pixels (:data:`SIZES`) so that pictures of different runs
line up; colours are fixed per series (:data:`COLOURS`).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from .open_loop import PARTS

__all__ = ["COLOURS", "SIZES", "available", "writers", "time_space", "lost_by_cause", "gap_hist",
           "wait_heat"]

DPI = 100
SIZES = {"time_space.png": (900, 600), "lost_by_cause.png": (900, 450),
         "gap_hist.png": (700, 420), "wait_heat.png": (900, 600)}
"""Width and height in pixels of each picture."""
COLOURS = {
    "planned": "#1f77b4", "executed": "#ff7f0e", "hist": "#2ca02c", "mean": "#d62728",
    "obstacle": "#404040",
    "dependency": "#d62728", "accel_decel": "#ff7f0e", "turning": "#9467bd",
    "control": "#8c564b", "injected": "#e377c2", "failures": "#7f7f7f",
    "rotation_repair": "#393b79",
    "freeze_recovery": "#bcbd22", "dwell_overrun": "#17becf", "faster_than_plan": "#2ca02c",
    "plan_waits_skipped": "#98df8a", "reorder_gain": "#006d2c",
}


def available() -> bool:
    """Whether matplotlib is installed (``pip install warerover-phys[report]``)."""
    import importlib.util

    return importlib.util.find_spec("matplotlib") is not None


def _plt():
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt


def _figure(name: str, nrows: int = 1):
    plt = _plt()
    w, h = SIZES[name]
    fig, axes = plt.subplots(nrows, 1, figsize=(w / DPI, h / DPI), dpi=DPI, squeeze=False)
    return plt, fig, [a[0] for a in axes]


def _save(plt, fig, path: Path) -> None:
    fig.savefig(str(path), dpi=DPI, format="png")
    plt.close(fig)


def time_space(path: Path, actions: list[dict], agvs: list[int], tick_s: float,
               title: str = "") -> None:
    """Planned vs executed progress of ``agvs`` (at most four), one panel each."""
    agvs = list(agvs)[:4] or [0]
    plt, fig, axes = _figure("time_space.png", len(agvs))
    for ax, i in zip(axes, agvs, strict=True):
        mine = sorted((a for a in actions if a["agv"] == i), key=lambda a: a["seq"])
        pt, py, et, ey = [0.0], [0], [0.0], [0]
        motion = bool(mine) and "planned_start_s" in mine[0]  # planner.timing: motion
        for k, a in enumerate(mine):
            pt += [a["planned_start_s"], a["planned_finish_s"]] if motion else \
                [a["planned_start_tick"] * tick_s, a["planned_finish_tick"] * tick_s]
            py += [k, k + 1]
            et += [a["executed_start_s"], a["executed_finish_s"]]
            ey += [k, k + 1]
        ax.plot(pt, py, "--", color=COLOURS["planned"], lw=2.0,
                label="planned (motion schedule)" if motion else "planned (grid plan)")
        ax.plot(et, ey, "-", color=COLOURS["executed"], lw=2.0, label="executed (physics)")
        ax.set_ylabel(f"AGV {i}\ncells moved")
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper left", fontsize=8)
    axes[-1].set_xlabel("time (s)")
    if title:
        axes[0].set_title(title, fontsize=10)
    fig.tight_layout()
    _save(plt, fig, path)


def lost_by_cause(path: Path, agents: list[dict], title: str = "") -> None:
    """Stacked bars of lost time by cause per AGV (seconds; ``agents`` rows may be means
    over seeds)."""
    plt, fig, (ax,) = _figure("lost_by_cause.png")
    ids = [a["agv"] for a in agents]
    x = np.arange(len(ids))
    up, down = np.zeros(len(ids)), np.zeros(len(ids))
    for part in PARTS:
        v = np.array([a.get(f"lost_{part}_s", 0.0) or 0.0 for a in agents], dtype=float)
        if not np.any(v):
            continue
        pos, neg = np.clip(v, 0, None), np.clip(v, None, 0)
        if pos.any():
            ax.bar(x, pos, bottom=up, color=COLOURS[part], label=part.replace("_", " "))
            up += pos
        if neg.any():
            ax.bar(x, neg, bottom=down, color=COLOURS[part],
                   label=None if pos.any() else part.replace("_", " "))
            down += neg
    # The parts split the lost time against the unit plan (also with motion timing).
    total = np.array([a.get("lost_unit_s", a.get("lost_s", 0.0)) for a in agents], dtype=float)
    ax.plot(x, total, "o", color="black", label="lost time (total)")
    ax.axhline(0, color="black", lw=0.8)
    lo, hi = ax.get_ylim()
    ax.set_ylim(lo, hi + 0.45 * (hi - lo))  # room for the legend above the bars
    ax.set_xticks(x, [str(i) for i in ids])
    ax.set_xlabel("AGV")
    ax.set_ylabel("seconds (executed - planned finish)")
    ax.legend(fontsize=7, ncol=4, loc="upper center")
    if title:
        ax.set_title(title, fontsize=10)
    fig.tight_layout()
    _save(plt, fig, path)


def gap_hist(path: Path, values: list[float], label: str = "makespan_ratio",
             title: str = "") -> None:
    """Histogram of a figure over seeds, with its mean."""
    plt, fig, (ax,) = _figure("gap_hist.png")
    v = np.asarray([x for x in values if x is not None and np.isfinite(x)], dtype=float)
    if len(v):
        ax.hist(v, bins=min(30, max(5, len(v) // 3)), color=COLOURS["hist"],
                edgecolor="black", lw=0.5)
        ax.axvline(float(v.mean()), color=COLOURS["mean"], lw=2,
                   label=f"mean {v.mean():.3f} (n = {len(v)})")
        ax.legend(fontsize=8)
    ax.set_xlabel(f"{label} (executed / planned)")
    ax.set_ylabel("seeds")
    if title:
        ax.set_title(title, fontsize=10)
    fig.tight_layout()
    _save(plt, fig, path)


def wait_heat(path: Path, heat: np.ndarray, grid: np.ndarray, title: str = "") -> None:
    """Dependency-wait seconds per cell over the floor."""
    from ..layout import CellType

    plt, fig, (ax,) = _figure("wait_heat.png")
    g = np.asarray(grid)
    base = np.ones(g.shape + (3,))
    for cell, rgb in ((CellType.OBSTACLE, COLOURS["obstacle"]), (CellType.SHELF, "#c6dbef"),
                      (CellType.STATION, "#c7e9c0"), (CellType.PARKING, "#e0e0e0")):
        base[g == cell] = _rgb(rgb)
    ax.imshow(base, interpolation="nearest")
    masked = np.ma.masked_where(heat <= 0, heat)
    im = ax.imshow(masked, cmap="YlOrRd", interpolation="nearest",
                   vmin=0, vmax=float(heat.max()) if heat.max() > 0 else 1.0)
    fig.colorbar(im, ax=ax, label="dependency wait (s per episode)")
    ax.set_xlabel("column")
    ax.set_ylabel("row")
    if title:
        ax.set_title(title, fontsize=10)
    fig.tight_layout()
    _save(plt, fig, path)


def _rgb(hex_colour: str) -> tuple[float, float, float]:
    h = hex_colour.lstrip("#")
    return tuple(int(h[j:j + 2], 16) / 255 for j in (0, 2, 4))


def _mean_agents(results: list[dict]) -> list[dict]:
    by: dict[int, list[dict]] = {}
    for r in results:
        for a in r.get("agents", ()):
            by.setdefault(a["agv"], []).append(a)
    out = []
    for i, rows in sorted(by.items()):
        keys = ["lost_s", *[f"lost_{p}_s" for p in PARTS]]
        keys += ["lost_unit_s"] if "lost_unit_s" in rows[0] else []
        out.append({"agv": i, **{k: float(np.nanmean([r[k] for r in rows])) for k in keys}})
    return out


def writers(results: list[dict], agvs: list[int] | None = None,
            ) -> dict[str, Callable[[Path], Any]]:
    """Writers (for :func:`warerover_phys.util.atomic.write_set`) of the pictures of one or
    several seeds' open-loop results (see :func:`warerover_phys.gap.stats.seed_gap`)."""
    ratios = [r["report"].get("makespan_ratio") for r in results]
    order = sorted(range(len(results)), key=lambda j: (ratios[j] is None, ratios[j] or 0))
    mid = results[order[len(order) // 2]]  # the median seed (or the only one)
    rep = mid["report"]
    name = f"{rep.get('scenario', '')} seed {mid['seed']}"
    tick_s = rep.get("tick_s", 1.0)
    if agvs is None:
        worst = sorted(mid["agents"], key=lambda a: -(a["lost_s"] if a["lost_s"] == a["lost_s"]
                                                      else 0))
        agvs = [a["agv"] for a in worst[:3]]
    out: dict[str, Callable[[Path], Any]] = {
        "time_space.png": lambda p: time_space(
            p, mid["actions"], agvs, tick_s, f"open loop, {name}: planned vs executed"),
    }
    several = len(results) > 1
    if several:
        agents = _mean_agents(results)
        title = f"{rep.get('scenario', '')}: lost time by cause, mean of {len(results)} seeds"
    else:
        agents = mid["agents"]
        title = f"{name}: lost time by cause"
    out["lost_by_cause.png"] = lambda p: lost_by_cause(p, agents, title)
    if several:
        out["gap_hist.png"] = lambda p: gap_hist(
            p, ratios, "makespan_ratio",
            f"{rep.get('scenario', '')}: open-loop gap over {len(results)} seeds")
    heat = np.mean([r["wait_map"] for r in results], axis=0)
    out["wait_heat.png"] = lambda p: wait_heat(
        p, heat, mid["grid"], f"{rep.get('scenario', '')}: where AGVs waited on a dependency"
        + (f" (mean of {len(results)} seeds)" if several else f" (seed {mid['seed']})"))
    return out
