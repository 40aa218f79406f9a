"""The pictures of a study report (matplotlib, the ``report`` extra; imported only here):

- ``fig_aet_vs_soc.png``: each plan's AET against its sum of costs per agent, one panel per
  instance, one colour per planner (reference condition);
- ``fig_aet_vs_agents.png``: AET against the agent count, a line per planner (mean and 95%
  interval over scens and seeds; reference condition);
- ``fig_aet_vs_mismatch.png``: AET over AET without mismatch, per mismatch level, a line per
  planner, one panel per robot model;
- ``fig_solve_vs_agents.png``: solve time against the agent count, a line per planner
  (solved plans; a cross where none of an agent count's plans was solved).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..sweep.report import mean_ci

__all__ = ["draw_all"]


def _plt():
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt


def _colors(planners: list[str]) -> dict[str, Any]:
    plt = _plt()
    cmap = plt.get_cmap("tab10" if len(planners) <= 10 else "tab20")
    return {p: cmap(i % cmap.N) for i, p in enumerate(planners)}


def _panels(count: int, width: float = 4.2, height: float = 3.4):
    plt = _plt()
    cols = min(count, 3)
    rows = -(-count // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(width * cols + 1.6, height * rows),
                             squeeze=False, layout="constrained")
    for ax in axes.flat[count:]:
        ax.set_visible(False)
    return fig, list(axes.flat[:count])


def _legend(fig, planners: list[str], rows: list[dict], marker: str = "o") -> None:
    """One legend for the figure: every planner that has a row, in study order."""
    from matplotlib.lines import Line2D

    col = _colors(planners)
    present = {r["planner"] for r in rows}
    handles = [Line2D([], [], color=col[p], marker=marker, ls="", label=p)
               for p in planners if p in present]
    fig.legend(handles=handles, loc="outside right center", fontsize=8)


def _save(fig, path: Path) -> Path:
    tmp = path.with_name(path.stem + ".tmp.png")
    fig.savefig(tmp, dpi=110)
    _plt().close(fig)
    tmp.replace(path)
    return path


def _ok(rows: list[dict], ref: dict[str, str]) -> list[dict]:
    return [r for r in rows if r.get("status") == "ok" and r.get("aet_s") is not None
            and all(r.get(k) == v for k, v in ref.items())]


def _by_instance(rows: list[dict], planners: list[str], xlabel: str, ylabel: str):
    """The figure, and per instance its panel (titled, labelled) and its rows; the caller
    draws each panel and adds the legend to the first."""
    insts = list(dict.fromkeys(r["instance"] for r in rows))
    fig, axes = _panels(len(insts))
    for ax, inst in zip(axes, insts, strict=True):
        ax.set_title(inst, fontsize=9)
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
    return fig, [(ax, [r for r in rows if r["instance"] == inst])
                 for ax, inst in zip(axes, insts, strict=True)]


def aet_vs_soc(rows: list[dict], ref: dict[str, str], planners: list[str], path: Path) -> Path:
    col = _colors(planners)
    fig, panels = _by_instance(rows, planners, "planned SoC per agent (ticks)", "AET (s)")
    for ax, mine in panels:
        mine = _ok(mine, ref)
        for p in planners:
            pts = [(r["soc"] / r["agents"], r["aet_s"]) for r in mine if r["planner"] == p]
            if pts:
                ax.scatter(*zip(*pts, strict=True), s=14, color=col[p], label=p, alpha=0.8)
    _legend(fig, planners, rows)
    fig.suptitle(f"AET vs sum of costs ({ref['robot']}, {ref['mismatch']}, {ref['delays']})",
                 fontsize=10)
    return _save(fig, path)


def _line(ax, xs_ys: dict[Any, list[float]], color, label: str, marker: str = "o") -> None:
    xs = sorted(xs_ys)
    stats = [mean_ci(xs_ys[x]) for x in xs]
    means = [m for m, _ in stats]
    errs = [h if h == h else 0.0 for _, h in stats]
    ax.errorbar(xs, means, yerr=errs, color=color, label=label, marker=marker, ms=4, capsize=2)


def aet_vs_agents(rows: list[dict], ref: dict[str, str], planners: list[str],
                  path: Path) -> Path:
    col = _colors(planners)
    fig, panels = _by_instance(rows, planners, "agents", "AET (s)")
    for ax, mine in panels:
        mine = _ok(mine, ref)
        for p in planners:
            by: dict[int, list[float]] = {}
            for r in mine:
                if r["planner"] == p:
                    by.setdefault(r["agents"], []).append(r["aet_s"])
            if by:
                _line(ax, by, col[p], p)
    _legend(fig, planners, rows)
    return _save(fig, path)


def aet_vs_mismatch(rows: list[dict], mismatch: list[str], planners: list[str],
                    path: Path) -> Path:
    robots = list(dict.fromkeys(r["robot"] for r in rows))
    fig, axes = _panels(len(robots))
    col = _colors(planners)
    pair = ("instance", "agents", "scen", "planner", "robot", "delays", "seed")
    base = {tuple(r.get(k) for k in pair): r["aet_s"] for r in rows
            if r.get("mismatch") == mismatch[0] and r.get("status") == "ok" and r.get("aet_s")}
    for ax, robot in zip(axes, robots, strict=True):
        for p in planners:
            by: dict[int, list[float]] = {}
            for r in rows:
                b = base.get(tuple(r.get(k) for k in pair))
                if r["robot"] == robot and r["planner"] == p and r.get("status") == "ok" and b:
                    by.setdefault(mismatch.index(r["mismatch"]), []).append(r["aet_s"] / b)
            if by:
                _line(ax, by, col[p], p)
        ax.set_xticks(range(len(mismatch)), mismatch, fontsize=8)
        ax.set_title(f"robot {robot}", fontsize=9)
        ax.set_ylabel(f"AET / AET ({mismatch[0]})")
    _legend(fig, planners, rows)
    return _save(fig, path)


def solve_vs_agents(rows: list[dict], planners: list[str], path: Path) -> Path:
    col = _colors(planners)
    fig, panels = _by_instance(rows, planners, "agents", "solve time (s); x: no plan")
    for ax, mine in panels:
        plans: dict[str, dict] = {}
        for r in mine:
            plans.setdefault(r.get("plan_id") or r["key"], r)
        for p in planners:
            by: dict[int, list[float]] = {}
            unsolved = set()
            for r in plans.values():
                if r["planner"] != p:
                    continue
                if r.get("solved") and r.get("solve_s") is not None:
                    by.setdefault(r["agents"], []).append(r["solve_s"])
                else:
                    unsolved.add(r["agents"])
            if by:
                _line(ax, by, col[p], p)
            none = sorted(unsolved - set(by))
            if none:
                tl = max((r.get("time_limit_s") or 1.0) for r in plans.values()
                         if r["planner"] == p)
                ax.scatter(none, [tl] * len(none), marker="x", color=col[p], s=30)
        ax.set_yscale("log")
    _legend(fig, planners, rows)
    return _save(fig, path)


def draw_all(rows: list[dict], spec: dict | None, out_dir: Path,
             ref: dict[str, str]) -> dict[str, Path]:
    """Every picture that the rows allow (``ref``: the reference robot, mismatch and delays
    labels); raises ImportError without matplotlib."""
    _plt()
    one = [r for r in rows if r.get("kind") == "oneshot"]
    if not one:
        return {}
    planners = list((spec or {}).get("planners") or {}) or list(dict.fromkeys(
        r["planner"] for r in one))
    mismatch = list((spec or {}).get("mismatch") or {}) or list(dict.fromkeys(
        r["mismatch"] for r in one))
    out = {"AET vs SoC": aet_vs_soc(one, ref, planners, out_dir / "fig_aet_vs_soc.png"),
           "AET vs agents": aet_vs_agents(one, ref, planners, out_dir / "fig_aet_vs_agents.png"),
           "solve time vs agents": solve_vs_agents(one, planners,
                                                   out_dir / "fig_solve_vs_agents.png")}
    if len(mismatch) > 1:
        out["AET vs mismatch"] = aet_vs_mismatch(one, mismatch, planners,
                                                 out_dir / "fig_aet_vs_mismatch.png")
    return out
