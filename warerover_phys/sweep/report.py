"""Aggregate a sweep's results: SR (%), CT and TP per environment x method (scheduler +
planner), pooled over order patterns and per pattern, as mean and 95% confidence interval
(Student t, n - 1 degrees of freedom, over the repetitions).

Where the episodes' metrics have them, the tables gain execution columns (blank for the
groups whose episodes lack them; a column no group has is left out of ``report.md`` and the
PNGs, and kept empty in ``report.csv``): the closed-loop gap (a physics episode's length in
ticks over the grid episode's of the same scenario, method, pattern, seed and other
overrides, when the sweep ran both executors), contacts (AGV-AGV + AGV-static), minimum
clearance (the episode's smallest AGV-AGV separation, metres), corridor intrusions and
deadlocks.

Writes ``report.md``, ``report.csv`` and heat-map tables styled like the paper's Table 1
(``table.png`` pooled, ``table_PATTERN.png`` per pattern; needs matplotlib, the ``report``
extra). In the heat maps a cell whose confidence interval overlaps the best cell's of its
column is hatched and coloured as the best: it is not shown to differ from it.

>>> m, h = mean_ci([1.0, 2.0, 3.0])
>>> round(m, 3), round(h, 3)
(2.0, 2.484)
"""

from __future__ import annotations

import csv
import io
import json
import logging
import math
import os
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import WareroverError
from .results import RESULTS_NAME, ResultsFile

__all__ = ["Group", "mean_ci", "load_rows", "aggregate", "markdown_table", "write_report",
           "heatmap", "ci_marks", "method_label", "METRICS", "EXTRA_METRICS"]

log = logging.getLogger(__name__)

SCHEDULER_LABEL = {"ta": "TA", "rd": "RD"}
PLANNER_LABEL = {"astar": "A*", "cbs": "CBS", "pibt": "PIBT", "lacam": "LaCAM"}
PATTERN_ORDER = ("oneshot", "constant", "wave", "hotspot", "burst")

METRICS: dict[str, tuple[str, str, int, bool]] = {
    # name: (metrics key, column title, decimals, higher is better)
    "sr_pct": ("success_rate", "SR (%)", 1, True),
    "ct_ms": ("ct_mean_ms", "CT (ms/tick)", 2, False),
    "ct_total_s": ("ct_total_s", "CT (s/episode)", 3, False),
    "tp": ("throughput", "TP (orders/tick)", 3, True),
}
HEATMAP_COLUMNS = ("sr_pct", "ct_ms", "tp")
"""The paper's three columns: SR, CT, TP."""

GAP_KEY = "_gap_ticks_ratio"
"""Where :func:`aggregate` puts a physics episode's closed-loop gap (it is not an episode
metric: it pairs the physics episode with its grid twin)."""
EXTRA_METRICS: dict[str, tuple[tuple[str, ...], str, int, bool]] = {
    # name: (metrics keys, summed; column title; decimals; higher is better)
    "gap": ((GAP_KEY,), "gap (ticks, phys/grid)", 3, False),
    "contacts": (("agv_contacts", "static_contacts"), "contacts", 1, False),
    "min_clear_m": (("min_separation_m",), "min clearance (m)", 3, True),
    "intrusions": (("corridor_intrusions",), "intrusions", 1, False),
    "deadlocks": (("deadlocks",), "deadlocks", 1, False),
}
"""Execution columns, shown where the episodes' metrics have them."""


def mean_ci(values: Sequence[float], level: float = 0.95) -> tuple[float, float]:
    """Mean and half-width of the ``level`` confidence interval (Student t, n - 1 dof).

    The half-width is NaN for fewer than two values and 0 when all values are equal.
    """
    from scipy import stats

    n = len(values)
    if n == 0:
        return math.nan, math.nan
    mean = math.fsum(values) / n
    if n < 2:
        return mean, math.nan
    var = math.fsum((v - mean) ** 2 for v in values) / (n - 1)
    if var <= 0.0:
        return mean, 0.0
    return mean, float(stats.t.ppf(0.5 + level / 2, n - 1) * math.sqrt(var / n))


def method_label(scheduler: str, planner: str) -> str:
    """``ta``, ``astar`` -> ``TA + A*``; a plugin ``pkg.mod:Cls`` shows as ``Cls``."""
    def short(name: str, table: dict[str, str]) -> str:
        return name.rsplit(":", 1)[-1] if ":" in name else table.get(name, name)
    return f"{short(scheduler, SCHEDULER_LABEL)} + {short(planner, PLANNER_LABEL)}"


@dataclass
class Group:
    """One row of a table: an environment x method (x pattern x variant) cell."""

    env: str
    scheduler: str
    planner: str
    pattern: str
    """An order pattern, or ``all`` (pooled)."""
    variant: str = ""
    """Other grid overrides, ``path=value; ...`` (empty when there are none)."""
    n: int = 0
    failed: int = 0
    stats: dict[str, tuple[float, float]] = field(default_factory=dict)
    """Metric name (see :data:`METRICS`) -> (mean, 95% CI half-width)."""

    @property
    def method(self) -> str:
        return method_label(self.scheduler, self.planner)


def load_rows(out_dir: str | Path) -> tuple[list[dict[str, Any]], dict[str, Any] | None, int]:
    """The result rows of the sweep in ``out_dir``: the rows whose key belongs to the sweep
    as last run there (``sweep.json``), that spec, and how many rows were left out."""
    from .runner import SPEC_NAME
    from .spec import SweepSpec, expand

    out_dir = Path(out_dir)
    results = out_dir / RESULTS_NAME
    if not out_dir.is_dir():
        raise WareroverError(f"{out_dir}: no such folder")
    if not os.path.lexists(results):
        raise WareroverError(f"{out_dir}: no {RESULTS_NAME} here (run `warerover sweep "
                             f"SWEEP.yaml --out {out_dir}` first)")
    rows = ResultsFile(results).load()
    for key, row in rows.items():
        _check_row(row, key, results)
    spec_data = None
    spec_path = out_dir / SPEC_NAME
    if spec_path.exists():
        from ..inputs import read_text

        try:
            spec_data = json.loads(read_text(spec_path, "sweep spec", 64 * 2**20))
            spec = SweepSpec.model_validate(spec_data)
        except (ValueError, TypeError) as err:
            raise WareroverError(f"{spec_path}: not a sweep spec ({err})") from None
        keys = {ep.key for ep in expand(spec)}
        kept = [r for k, r in rows.items() if k in keys]
        return kept, spec_data, len(rows) - len(kept)
    return list(rows.values()), None, 0


def _check_row(row: Any, key: str, path: Path) -> None:
    """A row the report can use, or a :class:`WareroverError` naming the file, the row and
    the field (rows are written by ``warerover sweep``; this catches edited or foreign ones).
    """
    def bad(field: str, value: Any) -> WareroverError:
        text = repr(value)
        text = text if len(text) <= 60 else text[:57] + "..."
        return WareroverError(f"{path}: row {key}: {field}: missing or of the wrong type "
                              f"(got {text})")

    if not isinstance(row, dict):
        raise bad("row", row)
    for name in ("scenario", "scheduler", "planner", "pattern", "status"):
        if not isinstance(row.get(name), str):
            raise bad(name, row.get(name, "nothing"))
    if not isinstance(row.get("variant") or {}, dict):
        raise bad("variant", row.get("variant"))
    if row["status"] != "ok":
        return
    metrics = row.get("metrics")
    if not isinstance(metrics, dict):
        raise bad("metrics", metrics if "metrics" in row else "nothing")
    for mkey, *_rest in METRICS.values():
        v = metrics.get(mkey)
        if v is not None and (isinstance(v, bool) or not isinstance(v, int | float)
                              or not math.isfinite(v)):
            raise bad(f"metrics.{mkey}", v)


def _variant(row: dict[str, Any]) -> str:
    return "; ".join(f"{k}={json.dumps(v)}" for k, v in sorted((row.get("variant") or {}).items()))


def _order(rows: list[dict[str, Any]], spec: dict[str, Any] | None):
    """Sort key for groups: environments, schedulers, planners, patterns in spec order."""
    def first_seen(name: str) -> list[str]:
        return list(dict.fromkeys(r[name] for r in rows))

    envs = list((spec or {}).get("scenarios", {})) or first_seen("scenario")
    grid = (spec or {}).get("grid", {})
    sched = [str(v) for v in grid.get("scheduler.name", grid.get("scheduler", []))]
    plan = [str(v) for v in grid.get("planner.name", grid.get("planner", []))]
    sched += [s for s in first_seen("scheduler") if s not in sched]
    plan += [p for p in first_seen("planner") if p not in plan]
    pats = ["all", *PATTERN_ORDER]

    def idx(seq: list[str], v: str) -> int:
        return seq.index(v) if v in seq else len(seq)

    return lambda g: (idx(pats, g.pattern), idx(envs, g.env), idx(sched, g.scheduler),
                      idx(plan, g.planner), g.variant)


def aggregate(rows: Iterable[dict[str, Any]], spec: dict[str, Any] | None = None,
              level: float = 0.95) -> list[Group]:
    """Groups per (environment, method, variant), pooled (``pattern == "all"``) and per order
    pattern, with mean and CI of every metric in :data:`METRICS` over the ok episodes."""
    rows = _with_gaps(list(rows))
    buckets: dict[tuple[str, str, str, str, str], list[dict[str, Any]]] = {}
    for r in rows:
        base = (r["scenario"], r["scheduler"], r["planner"])
        for pattern in ("all", r["pattern"]):
            buckets.setdefault((*base, pattern, _variant(r)), []).append(r)
    groups = []
    for (env, sched, plan, pattern, variant), members in buckets.items():
        ok = [r["metrics"] for r in members if r.get("status") == "ok" and r.get("metrics")]
        g = Group(env, sched, plan, pattern, variant, n=len(ok), failed=len(members) - len(ok))
        for name, (key, _, _, _) in METRICS.items():
            scale = 100.0 if name == "sr_pct" else 1.0
            vals = [float(m[key]) * scale for m in ok if m.get(key) is not None]
            g.stats[name] = mean_ci(vals, level)
        for name, (keys, *_rest) in EXTRA_METRICS.items():
            vals = [v for v in (_extra(m, keys) for m in ok) if v is not None]
            g.stats[name] = mean_ci(vals, level)
        groups.append(g)
    groups.sort(key=_order(rows, spec))
    return groups


def _extra(metrics: dict[str, Any], keys: tuple[str, ...]) -> float | None:
    """The sum of ``keys`` in an episode's metrics; None when one is missing or not a
    finite number (a grid episode has no contacts, a lone episode no gap)."""
    total = 0.0
    for key in keys:
        v = metrics.get(key)
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            return None
        total += float(v)
    return total


def _with_gaps(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Copies of the physics rows that have a grid twin (same scenario, scheduler, planner,
    pattern, seed and other overrides) with their closed-loop gap, physics ticks / grid
    ticks, under :data:`GAP_KEY`; every other row as it is."""
    def twin_key(r: dict[str, Any]) -> tuple:
        variant = {k: v for k, v in (r.get("variant") or {}).items()
                   if k not in ("executor", "executor.name")}
        return (r["scenario"], r["scheduler"], r["planner"], r["pattern"], r.get("seed"),
                json.dumps(variant, sort_keys=True, default=str))

    grid_ticks = {}
    for r in rows:
        m = r.get("metrics")
        if r.get("executor") == "grid" and r.get("status") == "ok" and isinstance(m, dict) \
                and _extra(m, ("ticks",)):
            grid_ticks[twin_key(r)] = float(m["ticks"])
    out = []
    for r in rows:
        m = r.get("metrics")
        base = grid_ticks.get(twin_key(r)) if r.get("executor") == "physics" else None
        if base and r.get("status") == "ok" and isinstance(m, dict) and _extra(m, ("ticks",)):
            r = {**r, "metrics": {**m, GAP_KEY: float(m["ticks"]) / base}}
        out.append(r)
    return out


def _extras_shown(groups: Sequence[Group]) -> list[str]:
    """The execution columns at least one group has a value for."""
    return [name for name in EXTRA_METRICS
            if any(not math.isnan(g.stats.get(name, (math.nan,))[0]) for g in groups)]


def _column(name: str) -> tuple[str, int, bool]:
    """Title, decimals, higher-is-better of a base or execution column."""
    if name in METRICS:
        return METRICS[name][1], METRICS[name][2], METRICS[name][3]
    return EXTRA_METRICS[name][1], EXTRA_METRICS[name][2], EXTRA_METRICS[name][3]


def _fmt(stat: tuple[float, float], decimals: int) -> str:
    mean, half = stat
    if math.isnan(mean):
        return "-"
    if math.isnan(half):
        return f"{mean:.{decimals}f}"
    return f"{mean:.{decimals}f} ± {half:.{decimals}f}"


def markdown_table(groups: Sequence[Group]) -> str:
    """A markdown table of ``groups`` (one pattern's, or the pooled ones)."""
    variants = any(g.variant for g in groups)
    extras = _extras_shown(groups)
    head = ["Env.", "Method"] + (["Variant"] if variants else []) + \
        [METRICS[m][1] for m in METRICS] + [EXTRA_METRICS[m][1] for m in extras] + \
        ["n", "failed"]
    lines = ["| " + " | ".join(head) + " |",
             "|" + "|".join(["---"] * (2 + variants) + ["---:"] * (len(head) - 2 - variants))
             + "|"]
    for g in groups:
        cells = [g.env, g.method] + ([g.variant or "-"] if variants else []) + \
            [_fmt(g.stats[m], METRICS[m][2]) for m in METRICS] + \
            [_blank(g.stats.get(m), EXTRA_METRICS[m][2]) for m in extras] + \
            [str(g.n), str(g.failed)]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _blank(stat: tuple[float, float] | None, decimals: int) -> str:
    """An execution cell: blank where the group's episodes do not have the metric."""
    return "" if stat is None or math.isnan(stat[0]) else _fmt(stat, decimals)


def _csv(groups: Sequence[Group]) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    head = ["env", "method", "scheduler", "planner", "pattern", "variant", "n", "failed"]
    names = [*METRICS, *EXTRA_METRICS]
    for m in names:
        head += [m, f"{m}_ci95"]
    w.writerow(head)
    for g in groups:
        row: list[Any] = [g.env, g.method, g.scheduler, g.planner, g.pattern, g.variant, g.n,
                          g.failed]
        for m in names:
            mean, half = g.stats.get(m, (math.nan, math.nan))
            row += ["" if math.isnan(mean) else repr(mean), "" if math.isnan(half) else repr(half)]
        w.writerow(row)
    return buf.getvalue()


def ci_marks(groups: Sequence[Group], name: str) -> list[str]:
    """Per group, how column ``name`` compares with its best cell: ``"best"``, ``"overlap"``
    (its confidence interval overlaps the best one's, so the two are not shown to differ),
    ``""`` (they differ) or ``"none"`` (no value). A missing CI (one episode) counts as a
    point."""
    higher = _column(name)[2]
    stats = [g.stats.get(name, (math.nan, math.nan)) for g in groups]
    have = [i for i, (m, _) in enumerate(stats) if not math.isnan(m)]
    if not have:
        return ["none"] * len(groups)
    best = (max if higher else min)(have, key=lambda i: stats[i][0])
    mb, hb = stats[best][0], _half(stats[best][1])
    out = []
    for i, (m, h) in enumerate(stats):
        if math.isnan(m):
            out.append("none")
        elif i == best or m == mb:
            out.append("best")
        else:
            out.append("overlap" if abs(m - mb) <= _half(h) + hb else "")
    return out


def _half(h: float) -> float:
    return 0.0 if math.isnan(h) else h


def _rules_and_legend(ax, groups: Sequence[Group], top: float, row_h: float,
                      legend_h: float, width: float) -> None:
    """The heat-map table's rules (one between environments) and the legend under it: what
    bold and hatching mean."""
    from matplotlib.patches import Rectangle

    bottom = top - row_h * (len(groups) + 1)
    for y, lw in ((top, 1.2), (top - row_h, 0.6), (bottom, 1.2)):
        ax.plot([0, width], [y, y], color="black", linewidth=lw)
    for r in range(1, len(groups)):
        if groups[r].env != groups[r - 1].env:
            y = top - row_h * (r + 1)
            ax.plot([0, width], [y, y], color="0.6", linewidth=0.4)
    ly = bottom - legend_h / 2
    ax.add_patch(Rectangle((0.08, ly - 0.09), 0.35, 0.18, facecolor=(0.0, 1.0, 0.0),
                           alpha=0.25, edgecolor="none"))
    ax.add_patch(Rectangle((0.08, ly - 0.09), 0.35, 0.18, facecolor="none",
                           edgecolor=(0.0, 0.0, 0.0, 0.45), hatch="////", linewidth=0.0))
    ax.text(0.5, ly, "95% CI overlaps the best of its column (bold): not shown to differ",
            ha="left", va="center", fontsize=7)


def heatmap(groups: Sequence[Group], path: str | Path, title: str = "") -> Path:
    """Draw ``groups`` as the paper draws Table 1: Env., Method, then SR, CT and TP cells
    (and the execution columns the groups have) filled ``green!p!red`` at 25% opacity, p the
    value's place between the column's minimum and maximum (CT: lower is greener). The best
    cell of a column is bold; a cell whose 95% CI overlaps the best one's is coloured as the
    best and hatched (a legend says so): the data do not show that it differs."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.patches import Rectangle

    variants = any(g.variant for g in groups)
    columns = [*HEATMAP_COLUMNS, *_extras_shown(groups)]
    cols = ["Env.", "Method"] + (["Variant"] if variants else []) + \
        [_column(m)[0] for m in columns]
    widths = [0.7, 1.5] + ([2.2] if variants else []) + [1.6] * len(columns)
    row_h = 0.32
    legend_h = 0.3
    height = row_h * (len(groups) + 1) + legend_h + (0.45 if title else 0.15)
    fig = Figure(figsize=(max(sum(widths), 5.6) + 0.2, height), dpi=150)
    FigureCanvasAgg(fig)  # the Agg canvas, without touching pyplot's global backend
    ax = fig.add_axes((0, 0, 1, 1))
    ax.set_xlim(-0.1, max(sum(widths), 5.6) + 0.1)
    ax.set_ylim(0, height)
    ax.axis("off")
    top = legend_h + row_h * (len(groups) + 1)
    if title:
        ax.text(sum(widths) / 2, top + 0.22, title, ha="center", va="center", fontsize=9)
    lo_hi = {}
    for m in columns:
        vals = [g.stats[m][0] for g in groups if not math.isnan(g.stats[m][0])]
        lo_hi[m] = (min(vals), max(vals)) if vals else (0.0, 0.0)
    marks = {m: ci_marks(groups, m) for m in columns}
    x0 = [sum(widths[:i]) for i in range(len(widths))]
    for i, name in enumerate(cols):
        right = i >= len(cols) - len(columns)
        ax.text(x0[i] + (widths[i] - 0.08 if right else 0.08), top - row_h / 2, name,
                ha="right" if right else "left", va="center", fontsize=8, fontweight="bold")
    for r, g in enumerate(groups):
        y = top - row_h * (r + 1)
        texts = [g.env, g.method] + ([g.variant or "-"] if variants else [])
        for i, t in enumerate(texts):
            ax.text(x0[i] + 0.08, y - row_h / 2, t, ha="left", va="center", fontsize=8)
        for j, m in enumerate(columns):
            i = len(texts) + j
            mean = g.stats[m][0]
            mark = marks[m][r]
            if not math.isnan(mean):
                lo, hi = lo_hi[m]
                p = 1.0 if hi == lo or mark in ("best", "overlap") else (mean - lo) / (hi - lo)
                p = p if _column(m)[2] or mark in ("best", "overlap") else 1.0 - p
                box = (x0[i] + 0.04, y - row_h + 0.03)
                ax.add_patch(Rectangle(box, widths[i] - 0.08, row_h - 0.06,
                                       facecolor=(1.0 - p, p, 0.0), alpha=0.25,
                                       edgecolor="none"))
                if mark == "overlap":
                    ax.add_patch(Rectangle(box, widths[i] - 0.08, row_h - 0.06,
                                           facecolor="none", edgecolor=(0.0, 0.0, 0.0, 0.45),
                                           hatch="////", linewidth=0.0))
            ax.text(x0[i] + widths[i] - 0.08, y - row_h / 2,
                    _blank(g.stats[m], _column(m)[1]) or "", ha="right", va="center",
                    fontsize=8, fontweight="bold" if mark == "best" else "normal")
    _rules_and_legend(ax, groups, top, row_h, legend_h, sum(widths))
    path = Path(path)
    from ..util.atomic import replacing

    with replacing(path) as tmp:      # a killed report never leaves half a PNG
        fig.savefig(tmp, format=path.suffix.lstrip(".") or "png")
    return path


def write_report(out_dir: str | Path, level: float = 0.95) -> dict[str, Any]:
    """Aggregate the sweep in ``out_dir``; write ``report.md``, ``report.csv`` and the PNG
    tables. Returns ``{"markdown", "files", "groups", "rows", "left_out", "notes"}``."""
    out_dir = Path(out_dir)
    rows, spec, left_out = load_rows(out_dir)
    if not rows:
        raise WareroverError(f"{out_dir / RESULTS_NAME}: no results of this sweep yet")
    groups = aggregate(rows, spec, level)
    name = (spec or {}).get("name", out_dir.name)
    ok = sum(1 for r in rows if r.get("status") == "ok")
    notes = []
    if left_out:
        notes.append(f"{left_out} row(s) of earlier versions of the sweep file left out")
    patterns = [p for p in dict.fromkeys(g.pattern for g in groups) if p != "all"]
    md = [f"# Sweep report: {name}", "",
          f"{ok} episodes ok, {len(rows) - ok} failed ({out_dir / RESULTS_NAME}). Cells: mean "
          f"± half-width of the {level:.0%} confidence interval (Student t over the "
          "repetitions). SR = orders completed / generated; CT = scheduler + planner wall "
          "time, mean per tick and total per episode; TP = orders completed per tick. "
          "Failed episodes are counted in `failed`, not in the means.", ""]
    md += [f"_{n}_" for n in notes] + ([""] if notes else [])
    md += ["## All order patterns (pooled)" if len(patterns) > 1 else
           f"## Order pattern: {patterns[0] if patterns else '-'}", "",
           markdown_table([g for g in groups if g.pattern == "all"]), ""]
    if len(patterns) > 1:
        md += ["## Per order pattern", ""]
        for p in patterns:
            md += [f"### {p}", "", markdown_table([g for g in groups if g.pattern == p]), ""]
    failures: dict[str, int] = {}
    for r in rows:
        if r.get("status") != "ok":
            failures[str(r.get("error"))[:160]] = failures.get(str(r.get("error"))[:160], 0) + 1
    if failures:
        md += ["## Failed episodes", "", "| error | episodes |", "|---|---:|"]
        md += [f"| {e.replace('|', '/')} | {n} |" for e, n in sorted(failures.items(),
                                                                      key=lambda x: -x[1])]
        md.append("")
    text = "\n".join(md)
    files = {"markdown": out_dir / "report.md", "csv": out_dir / "report.csv"}
    _atomic_write(files["markdown"], text)
    _atomic_write(files["csv"], _csv(groups))
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        notes.append("no PNG tables: matplotlib is not installed "
                     "(pip install 'warerover-phys[report]')")
    else:
        files["png"] = heatmap([g for g in groups if g.pattern == "all"],
                               out_dir / "table.png",
                               f"{name}: all order patterns" if len(patterns) > 1 else name)
        if len(patterns) > 1:
            for p in patterns:
                files[f"png_{p}"] = heatmap([g for g in groups if g.pattern == p],
                                            out_dir / f"table_{p}.png", f"{name}: {p}")
    return {"markdown": text, "files": files, "groups": groups, "rows": len(rows),
            "left_out": left_out, "notes": notes}


def _atomic_write(path: Path, text: str) -> None:
    import os

    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text if text.endswith("\n") else text + "\n", encoding="utf-8")
    os.replace(tmp, path)
