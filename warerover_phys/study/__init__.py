"""Studies: planners x MAPF instances x robot models, every plan executed on physics, in one
command (``warerover study SPEC.yaml --out DIR``), with a report of tables with confidence
intervals, rank correlations of sum of costs and executed time, and pictures
(``warerover study report DIR``).

:func:`load_study`, :func:`run_study` and :func:`write_study_report` from Python.
"""

from __future__ import annotations

from .cells import Cell, LifelongTask, PlanTask, expand
from .runner import StudySummary, load_results, run_study, write_tables
from .spec import StudyError, StudySpec, load_study

__all__ = ["StudySpec", "StudyError", "load_study", "Cell", "PlanTask", "LifelongTask",
           "expand", "StudySummary", "run_study", "load_results", "write_tables"]
