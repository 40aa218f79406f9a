"""Experiment sweeps: many episodes over a grid of overrides and seeds, run in parallel
(local processes or Ray), recorded resumably, aggregated into tables with confidence
intervals.

``warerover sweep SWEEP.yaml --out DIR`` and ``warerover report DIR`` on the command line;
:func:`load_sweep`, :func:`run_sweep` and :func:`aggregate` from Python.
"""

from __future__ import annotations

from .report import aggregate, load_rows, mean_ci, write_report
from .results import ResultsFile
from .runner import SweepSummary, Task, plan_sweep, run_sweep, run_task
from .spec import Episode, SweepError, SweepSpec, episode_key, expand, load_sweep

__all__ = ["SweepSpec", "SweepError", "Episode", "load_sweep", "expand", "episode_key",
           "ResultsFile", "Task", "SweepSummary", "plan_sweep", "run_sweep", "run_task",
           "aggregate", "load_rows", "mean_ci", "write_report"]
