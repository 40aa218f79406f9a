"""Conformance checkers for plug-ins, in the spirit of Gymnasium's ``check_env``.

Each checker builds a plug-in, runs it through small *fixed* cases on tiny worlds built in
code, and either returns a :class:`ConformanceReport` (the checks it passed) or raises a
:class:`ConformanceError` whose message says what is wrong and how to fix it:

- :func:`check_scheduler`: the Protocol's ``assign(world, rng)``; a list of
  :class:`~warerover_phys.schedulers.base.Assignment` for idle AGVs, free shelves holding
  the orders' SKUs and pending orders, none twice; the world left as it was; the same
  assignments for the same seed.
- :func:`check_planner`: ``plan(request)``, ``name``, ``replans_all``; a
  :class:`~warerover_phys.planning.base.PlanResult` with paths only for the asked AGVs that
  start at the request's tick where each AGV stands, use edges of its motion graph (its
  footprint and speed), and conflict neither with the committed reservations nor with each
  other (:func:`warerover_phys.validate.validate_states`); goals reached in easy cases; the
  request's agents and graphs untouched; the same result for the same seed. With
  ``rotations=True`` the same cases are planned rotation-aware (``planner.rotations``:
  every AGV has ``turn_ticks`` and a heading), and every returned path must also carry one
  heading per state, start facing the AGV's heading, and move only straight ahead with turns
  that take their ticks (:func:`warerover_phys.validate.validate_headings`).
- :func:`check_executor`: ``bind``, ``step``, ``remaining``, ``stop_short``, ``summary``,
  ``trajectory``; a :class:`~warerover_phys.executors.base.StepReport` every tick with a
  valid state for every AGV; fixed conflict-free plans followed to their ends in bounded
  time, with no collisions reported; the same states for the same seed; a JSON-serialisable
  ``summary()`` and a ``trajectory()`` that is None or a dict of numpy arrays.

A target is a registry name (``"astar"``, an entry point, ``"pkg.mod:Class"``), a plug-in
class (built as ``cls(spec)``, or ``cls(spec, params)`` with its ``Params`` model and the
spec's ``params``), a factory (called with the spec if it takes an argument, else with
none) or, for schedulers and planners, an instance.

>>> from warerover_phys.testing import check_planner
>>> report = check_planner("astar")
>>> report.kind, report.name, "determinism" in report.passed
('planner', 'astar', True)
"""

from __future__ import annotations

from .common import (  # noqa: F401
    MIXED_GRID,
    SCHED_GRID,
    SIGNATURES,
    STEP_TICKS,
    ConformanceError,
    ConformanceReport,
    _check_members,
    _check_name,
    _check_params_model,
    _Checker,
    _factory,
    _is_instance,
    _label,
    _mixed_world,
    _new,
    _sched_world,
    _short,
    _spec_class,
    _timed,
)
from .executor import (  # noqa: F401
    EXEC_PLANS,
    STANDSTILL_TICKS,
    TRACE_FIELDS,
    _check_executed,
    _check_progress,
    _check_remaining,
    _check_report,
    _check_results,
    _check_state,
    _run_executor,
    _trace_difference,
    check_executor,
)
from .plan_checks import (  # noqa: F401
    _check_edges,
    _check_goals,
    _check_headings,
    _check_paths,
    plan_turn_conflicts,
)
from .planner import (  # noqa: F401
    _DIRS,
    PLAN_CASES,
    _check_graphs,
    _plan_difference,
    _plan_once,
    _PlanCase,
    _run_plan_case,
    check_planner,
)
from .scheduler import (  # noqa: F401
    SCHED_CASES,
    SNAPSHOT_PARTS,
    _assign_checked,
    _case_all_busy,
    _case_busy,
    _case_fresh,
    _case_no_orders,
    _check_assignments,
    _order,
    _world_snapshot,
    check_scheduler,
)

__all__ = ["ConformanceError", "ConformanceReport", "check_scheduler", "check_planner",
           "check_executor"]

# doctest.testmod(warerover_phys.testing) finds only this module's own docstrings: name the
# checkers (defined in the submodules) whose docstrings hold examples.
__test__ = {"check_scheduler": check_scheduler, "check_planner": check_planner,
            "check_executor": check_executor}
