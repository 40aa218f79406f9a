"""The report of a study: tables with 95% confidence intervals, the rank correlation of sum
of costs and executed time, pictures, and ``report.md``.

Tables (each also a CSV in the results folder):

- **planners** (``report_planners.csv``): per instance x agent count x planner, the share of
  plans solved, solve time, SoC / lower bound (per distinct plan; for a rotation-aware
  planner, the plans for the reference robot model), and the executed figures
  (AET, executed makespan, makespan ratio, contacts) under the *reference condition*: the
  first robot model, mismatch level and delay setting of the study file;
- **conditions** (``report_conditions.csv``): AET per instance x agents x planner x robot x
  mismatch x delays, over scens and seeds;
- **mismatch** (``report_mismatch.csv``): per planner x robot x mismatch, AET over AET of
  the same plan and delays without mismatch (the first mismatch level), paired cell by cell;
- **correlation** (``report_correlation.csv``): per instance group (instance x agents x
  robot x mismatch x delays) Spearman's rho and Kendall's tau between the plans' sum of
  costs and their AET, over every planner, scen and seed of the group, each with a 95%
  bootstrap interval (percentile, :data:`BOOTSTRAP` resamples of the cells, seeded);
- **lifelong** (``report_lifelong.csv``): throughput and success rate per scenario x planner
  x variant.

Means come with the half-width of a Student-t 95% interval over the cells (NaN for one).
"""

from __future__ import annotations

import csv
import io
import math
import os
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import WareroverError
from ..sweep.report import mean_ci
from .runner import load_results

__all__ = ["write_study_report", "rank_correlation", "bootstrap_ci", "spearman_rows",
           "kendall_rows", "tables", "BOOTSTRAP"]

BOOTSTRAP = 2000
"""Bootstrap resamples of a rank correlation's interval."""


def bootstrap_ci(x: Sequence[float], y: Sequence[float],
                 stat: Callable[[np.ndarray, np.ndarray], np.ndarray], *,
                 resamples: int = BOOTSTRAP, level: float = 0.95,
                 seed: int = 0) -> tuple[float, float]:
    """Percentile interval of ``stat`` over ``resamples`` resamples of the pairs ``(x, y)``.
    ``stat`` takes ``(R, n)`` arrays (one resample per row) and returns ``R`` values, NaN
    where it is undefined (e.g. all x equal); those resamples are skipped, and the interval
    is NaN when more than half are."""
    xa, ya = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    n = len(xa)
    if n < 3:
        return math.nan, math.nan
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, n, size=(resamples, n))
    chunk = max(1, 2_000_000 // (n * n))  # Kendall's pairs: bound the (chunk, n, n) arrays
    vals = np.concatenate([stat(xa[idx[i:i + chunk]], ya[idx[i:i + chunk]])
                           for i in range(0, resamples, chunk)])
    vals = vals[np.isfinite(vals)]
    if len(vals) < resamples // 2:
        return math.nan, math.nan
    lo, hi = np.quantile(vals, [(1 - level) / 2, (1 + level) / 2])
    return float(lo), float(hi)


def spearman_rows(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Spearman's rho of each row pair of ``(R, n)`` arrays (average ranks for ties; NaN
    for a constant row)."""
    from scipy.stats import rankdata

    rx = rankdata(x, axis=-1)
    ry = rankdata(y, axis=-1)
    rx -= rx.mean(axis=-1, keepdims=True)
    ry -= ry.mean(axis=-1, keepdims=True)
    den = np.sqrt((rx * rx).sum(-1) * (ry * ry).sum(-1))
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 0, (rx * ry).sum(-1) / np.where(den > 0, den, 1), np.nan)


def kendall_rows(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Kendall's tau-b of each row pair of ``(R, n)`` arrays (NaN for a constant row)."""
    dx = np.sign(x[:, :, None] - x[:, None, :]).astype(np.int8)
    dy = np.sign(y[:, :, None] - y[:, None, :]).astype(np.int8)
    num = (dx * dy).sum((1, 2), dtype=np.int64)
    den = np.sqrt((dx * dx).sum((1, 2), dtype=np.int64).astype(float) *
                  (dy * dy).sum((1, 2), dtype=np.int64))
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 0, num / np.where(den > 0, den, 1), np.nan)


def rank_correlation(x: Sequence[float], y: Sequence[float], seed: int = 0) -> dict[str, Any]:
    """Spearman's rho and Kendall's tau of the pairs with their bootstrap 95% intervals."""
    xa, ya = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    out: dict[str, Any] = {"points": len(xa)}
    for name, fn in (("spearman", spearman_rows), ("kendall", kendall_rows)):
        out[name] = float(fn(xa[None], ya[None])[0]) if len(xa) >= 3 else math.nan
        out[f"{name}_lo"], out[f"{name}_hi"] = bootstrap_ci(xa, ya, fn, seed=seed)
    return out


# ----------------------------------------------------------------------------- grouping


def _group(rows: Iterable[dict[str, Any]], keys: Sequence[str]) -> dict[tuple, list[dict]]:
    out: dict[tuple, list[dict]] = {}
    for r in rows:
        out.setdefault(tuple(r.get(k) for k in keys), []).append(r)
    return out


def _values(rows: Iterable[dict[str, Any]], key: str) -> list[float]:
    return [float(r[key]) for r in rows if isinstance(r.get(key), int | float)
            and not isinstance(r.get(key), bool) and math.isfinite(float(r[key]))]


def _stat(rows: list[dict[str, Any]], key: str) -> tuple[float, float]:
    return mean_ci(_values(rows, key))


def _plans(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per distinct plan (solve figures are the plan's, not the cell's)."""
    seen: dict[str, dict] = {}
    for r in rows:
        seen.setdefault(r.get("plan_id") or r["key"], r)
    return list(seen.values())


def _reference(spec: dict[str, Any] | None, rows: list[dict[str, Any]]) -> dict[str, str]:
    """The first robot, mismatch and delays label of the study (of the rows if no spec)."""
    out = {}
    for dim, col in (("robots", "robot"), ("mismatch", "mismatch"), ("delays", "delays")):
        labels = list((spec or {}).get(dim) or {}) or [r[col] for r in rows]
        out[col] = labels[0] if labels else ""
    return out


def tables(rows: list[dict[str, Any]], spec: dict[str, Any] | None) -> dict[str, list[dict]]:
    """Every table of the report as a list of flat dicts."""
    one = [r for r in rows if r.get("kind") == "oneshot"]
    ref = _reference(spec, one) if one else {}
    return {"planners": _planner_table(one, ref), "conditions": _condition_table(one),
            "mismatch": _mismatch_table(one, spec), "correlation": _correlation_table(one),
            "lifelong": _lifelong_table([r for r in rows if r.get("kind") == "lifelong"])}


def _ci_cols(name: str, stat: tuple[float, float]) -> dict[str, float]:
    return {name: stat[0], f"{name}_ci": stat[1]}


def _planner_table(rows: list[dict], ref: dict[str, str]) -> list[dict]:
    out = []
    for (inst, n, planner), group in _group(rows, ("instance", "agents", "planner")).items():
        # a rotation-aware planner's plans differ by robot model: those of the reference
        plans = _plans([r for r in group if r.get("robot") == ref.get("robot")] or group)
        nominal = [r for r in group if all(r.get(k) == v for k, v in ref.items())
                   and r.get("status") == "ok"]
        out.append({
            "instance": inst, "agents": n, "planner": planner, "cells": len(group),
            "plans": len(plans),
            "solved_pct": 100.0 * sum(1 for p in plans if p.get("solved")) / len(plans),
            "executed_pct": 100.0 * sum(1 for r in group if r.get("status") == "ok") / len(group),
            **_ci_cols("solve_s", _stat([p for p in plans if p.get("solved")], "solve_s")),
            **_ci_cols("soc_over_lb", _stat(plans, "soc_over_lb")),
            **_ci_cols("soc_per_agent", mean_ci([v / n for v in _values(plans, "soc")])),
            "nominal_cells": len(nominal),
            **_ci_cols("aet_s", _stat(nominal, "aet_s")),
            **_ci_cols("executed_makespan_s", _stat(nominal, "executed_makespan_s")),
            **_ci_cols("aet_over_planned", _stat(nominal, "aet_over_planned")),
            **_ci_cols("contacts", mean_ci([float((r.get("agv_contacts") or 0) +
                                                  (r.get("static_contacts") or 0))
                                            for r in nominal])),
        })
    return out


def _condition_table(rows: list[dict]) -> list[dict]:
    keys = ("instance", "agents", "planner", "robot", "mismatch", "delays")
    out = []
    for vals, group in _group(rows, keys).items():
        ok = [r for r in group if r.get("status") == "ok"]
        out.append({**dict(zip(keys, vals, strict=True)), "cells": len(group), "ok": len(ok),
                    **_ci_cols("aet_s", _stat(ok, "aet_s")),
                    **_ci_cols("aet_over_planned", _stat(ok, "aet_over_planned")),
                    **_ci_cols("makespan_ratio", _stat(ok, "makespan_ratio")),
                    **_ci_cols("lost_turning_s", mean_ci([v / r["agents"] for r in ok for v in
                                                          _values([r], "lost_turning_s_total")])),
                    **_ci_cols("lost_dependency_s", mean_ci([
                        v / r["agents"] for r in ok for v in
                        _values([r], "lost_dependency_s_total")]))})
    return out


def _mismatch_table(rows: list[dict], spec: dict[str, Any] | None) -> list[dict]:
    labels = list((spec or {}).get("mismatch") or {}) or list(dict.fromkeys(
        r["mismatch"] for r in rows))
    if len(labels) < 2:
        return []
    base = labels[0]
    pair = ("instance", "agents", "scen", "planner", "robot", "delays", "seed")
    exact = {tuple(r.get(k) for k in pair): r for r in rows
             if r.get("mismatch") == base and r.get("status") == "ok"}
    out = []
    for (planner, robot, mm), group in _group(rows, ("planner", "robot", "mismatch")).items():
        if mm == base:
            continue
        ratios = []
        for r in group:
            b = exact.get(tuple(r.get(k) for k in pair))
            if r.get("status") == "ok" and b is not None and b.get("aet_s"):
                ratios.append(r["aet_s"] / b["aet_s"])
        out.append({"planner": planner, "robot": robot, "mismatch": mm, "versus": base,
                    "pairs": len(ratios), **_ci_cols("aet_ratio", mean_ci(ratios))})
    return out


def _correlation_table(rows: list[dict]) -> list[dict]:
    keys = ("instance", "agents", "robot", "mismatch", "delays")
    out = []
    for i, (vals, group) in enumerate(_group(rows, keys).items()):
        ok = [r for r in group if r.get("status") == "ok" and r.get("aet_s") is not None
              and r.get("soc") is not None]
        corr = rank_correlation([r["soc"] for r in ok], [r["aet_s"] for r in ok], seed=i)
        out.append({**dict(zip(keys, vals, strict=True)),
                    "planners": len({r["planner"] for r in ok}), **corr})
    return out


def _lifelong_table(rows: list[dict]) -> list[dict]:
    out = []
    for (scn, planner, variant), group in _group(rows, ("instance", "planner",
                                                        "variant")).items():
        ok = [r for r in group if r.get("status") == "ok"]
        out.append({"scenario": scn, "planner": planner, "variant": variant,
                    "cells": len(group), "ok": len(ok),
                    **_ci_cols("throughput", _stat(ok, "throughput")),
                    **_ci_cols("success_rate", _stat(ok, "success_rate"))})
    return out


# ----------------------------------------------------------------------------- output


def _fmt(v: Any, ci: Any = None, digits: int = 2) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    if isinstance(v, float):
        text = f"{v:.{digits}f}"
        if ci is not None and isinstance(ci, float) and math.isfinite(ci) and ci > 0:
            text += f" ± {ci:.{digits}f}"
        return text
    return str(v)


def _md(rows: list[dict], cols: list[tuple[str, str, int]]) -> str:
    """A Markdown table: (key, title, digits) per column; ``KEY_ci`` is shown as ± CI."""
    if not rows:
        return "_(none)_\n"
    head = "| " + " | ".join(t for _, t, _ in cols) + " |\n"
    head += "|" + "|".join("---" if d < 0 else "---:" for _, _, d in cols) + "|\n"
    body = "".join("| " + " | ".join(_fmt(r.get(k), r.get(f"{k}_ci"), max(d, 0))
                                     for k, _, d in cols) + " |\n" for r in rows)
    return head + body


def _interval(r: dict, name: str) -> str:
    v, lo, hi = r.get(name), r.get(f"{name}_lo"), r.get(f"{name}_hi")
    if v is None or not math.isfinite(v):
        return "-"
    if lo is None or not math.isfinite(lo):
        return f"{v:.2f}"
    return f"{v:.2f} [{lo:.2f}, {hi:.2f}]"


def _csv(rows: list[dict]) -> str:
    buf = io.StringIO()
    if rows:
        cols = list(dict.fromkeys(k for r in rows for k in r))
        w = csv.writer(buf)
        w.writerow(cols)
        for r in rows:
            w.writerow(["" if r.get(c) is None else r.get(c) for c in cols])
    return buf.getvalue()


def _atomic(path: Path, text: str) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, path)


PLANNER_COLS = [("instance", "instance", -1), ("agents", "agents", 0),
                ("planner", "planner", -1), ("solved_pct", "solved %", 0),
                ("solve_s", "solve (s)", 2), ("soc_over_lb", "SoC / LB", 3),
                ("aet_s", "AET (s)", 1), ("aet_over_planned", "AET / planned mean", 2),
                ("executed_makespan_s", "exec. makespan (s)", 1), ("contacts", "contacts", 1)]
MISMATCH_COLS = [("planner", "planner", -1), ("robot", "robot", -1),
                 ("mismatch", "mismatch", -1), ("pairs", "pairs", 0),
                 ("aet_ratio", "AET / AET exact", 3)]
LIFELONG_COLS = [("scenario", "scenario", -1), ("planner", "planner", -1),
                 ("variant", "variant", -1), ("ok", "episodes", 0),
                 ("throughput", "TP (orders/tick)", 4), ("success_rate", "SR", 3)]


def _markdown(t: dict[str, list[dict]], rows: list[dict], spec: dict | None,
              pictures: dict[str, Path], notes: list[str]) -> str:
    one = [r for r in rows if r.get("kind") == "oneshot"]
    ref = _reference(spec, one) if one else {}
    name = (spec or {}).get("name", "study")
    failed = sum(1 for r in rows if r.get("status") != "ok")
    parts = [f"# Study `{name}`\n",
             f"{len(rows)} cells ({len(one)} one-shot, {len(rows) - len(one)} lifelong), "
             f"{failed} without an executed result. Means ± 95% CI half-width (Student t).\n"]
    if one:
        parts += ["\n## Planners\n",
                  f"Executed figures under the reference condition: robot `{ref['robot']}`, "
                  f"mismatch `{ref['mismatch']}`, delays `{ref['delays']}`. SoC / LB and solve "
                  "time per distinct plan; solved % of the plans.\n\n",
                  _md(t["planners"], PLANNER_COLS),
                  "\n## Model mismatch\n", "AET of the same plan with the robots' true model "
                  "off the planner's, over AET without mismatch (paired).\n\n",
                  _md(t["mismatch"], MISMATCH_COLS),
                  "\n## Does SoC predict AET?\n",
                  "Rank correlation between a plan's sum of costs and its AET, per instance "
                  "group, over every planner, scen and seed in it; [95% bootstrap interval].\n\n",
                  _corr_md(t["correlation"])]
    if t["lifelong"]:
        parts += ["\n## Lifelong cells\n\n", _md(t["lifelong"], LIFELONG_COLS)]
    if pictures:
        parts.append("\n## Pictures\n\n")
        parts += [f"![{k}]({p.name})\n\n" for k, p in pictures.items()]
    errors = _errors(rows)
    if errors:
        parts.append("\n## Cells without a result\n\n")
        parts += [f"- {planner}: {count} x `{err}`\n" for (planner, err), count in errors]
    if notes:
        parts.append("\n" + "".join(f"_Note: {n}_\n" for n in notes))
    return "".join(parts)


def _corr_md(rows: list[dict]) -> str:
    if not rows:
        return "_(none)_\n"
    out = ["| instance | agents | robot | mismatch | delays | points | Spearman rho | "
           "Kendall tau |\n|---|---:|---|---|---|---:|---:|---:|\n"]
    for r in rows:
        out.append(f"| {r['instance']} | {r['agents']} | {r['robot']} | {r['mismatch']} | "
                   f"{r['delays']} | {r['points']} | {_interval(r, 'spearman')} | "
                   f"{_interval(r, 'kendall')} |\n")
    return "".join(out)


def _errors(rows: list[dict]) -> list[tuple[tuple[str, str], int]]:
    from collections import Counter

    c: Counter = Counter()
    for r in rows:
        if r.get("status") != "ok":
            err = str(r.get("error") or "?")
            c[(r.get("planner", "?"), err[:160])] += 1
    return sorted(c.items(), key=lambda kv: (kv[0][0], -kv[1]))


def write_study_report(out_dir: str | Path, *, pictures: bool = True) -> dict[str, Any]:
    """Write ``report.md``, the ``report_*.csv`` tables and (with matplotlib) the pictures
    into ``out_dir``; returns the Markdown, the files written and notes."""
    out_dir = Path(out_dir)
    if not (out_dir / "results.jsonl").exists():
        raise WareroverError(f"{out_dir}: no results.jsonl (run `warerover study SPEC.yaml "
                             f"--out {out_dir}` first)")
    rows, spec = load_results(out_dir)
    if not rows:
        raise WareroverError(f"{out_dir}: the study has no result rows yet")
    t = tables(rows, spec)
    files: dict[str, Path] = {}
    for name, table in t.items():
        if table:
            path = out_dir / f"report_{name}.csv"
            _atomic(path, _csv(table))
            files[name] = path
    notes: list[str] = []
    pics: dict[str, Path] = {}
    if pictures:
        from .figures import draw_all

        try:
            one = [r for r in rows if r.get("kind") == "oneshot"]
            pics = draw_all(rows, spec, out_dir, _reference(spec, one) if one else {})
        except ImportError:
            notes.append("no pictures: matplotlib is not installed (pip install "
                         "'warerover-phys[report]')")
    files.update(pics)
    md = _markdown(t, rows, spec, pics, notes)
    _atomic(out_dir / "report.md", md)
    files["markdown"] = out_dir / "report.md"
    return {"markdown": md, "files": files, "notes": notes, "tables": t}
