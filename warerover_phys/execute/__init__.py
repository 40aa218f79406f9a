"""One fixed plan, executed as written: no scheduler, no planner, no replanning.

``warerover execute FLOOR --plan FILE`` is built from the pieces here:

1. :func:`load_floor`: a MovingAI ``.map`` (free cells and obstacles are all that matter), a
   layout YAML or a scenario YAML becomes a :class:`~warerover_phys.layout.Layout`;
   :func:`load_fleet` gives every agent an AGV type (default: 1x1, 0.7 m bodies, 1 m/s).
2. :func:`validate_plan`: the plan against the floor and the fleet, vectorised over
   timesteps (bounds, obstacles, jumps of more than one cell, vertex / footprint and swap
   conflicts). The first problem is raised as one line naming the agent, the timestep and
   the cells (:class:`PlanError`).
3. :func:`find_cycles`: groups of agents that move round a cycle in one timestep (a
   *rotation*: each enters the cell the next one leaves). The action dependency graph has no
   order for them and bodies turning a block in lockstep overlap. :func:`repair_cycles`
   replaces each rotation by a *local detour*: single-cell moves, one agent at a time, that
   take the rotation's agents to the cells the rotation gives them while everyone else
   stands (A* on the joint state of the rotation's agents within a few cells of it; if they
   alone have no way, the 1x1 agents next to it may step aside and back). The detour's moves
   are inserted before the rotation's timestep; then the whole plan is *re-timed*: each
   agent makes its moves in turn, never before its timestep in the given plan, each cell is
   visited in the same order as before, following is kept and no cycle is formed. Agents
   that do not wait on a detour keep their timing exactly; a plan without rotations comes
   back unchanged. Each repair is reported; ``strict=True`` raises instead. A rotation that
   no detour within :data:`DETOUR_STAGES` can replace (for example four agents on a floor
   with one free cell: a sliding puzzle cannot make a quarter turn of four) is refused with
   one line naming it.
4. :func:`execute_plan`: the executor (``grid``, ``physics`` or a plug-in) follows exactly
   that plan. The result has planned and executed makespan and sum of costs, per-agent
   finish times, the executor's figures and the executed states per tick.

Times: the plan's timestep is one tick of ``tick_s`` seconds (default 1 s). Executed finish
times are in ticks (an agent has finished at the first tick from which it stands at its final
cell for good).
"""

from __future__ import annotations

from .cycles import (  # noqa: F401
    Cycle,
    _cycles_dense,
    find_cycles,
)
from .floor import (  # noqa: F401
    DEFAULT_TYPE,
    PlanError,
    load_fleet,
    load_floor,
)
from .options import (  # noqa: F401
    REORDER_MODES,
    check_reorder,
    executor_options,
    executor_spec,
    parse_delays,
    robot_model,
)
from .outputs import (  # noqa: F401
    _grid_trajectory,
    executed_plan,
    write_execution,
)
from .repair import (  # noqa: F401
    DETOUR_EXPANSIONS,
    DETOUR_HELPERS,
    DETOUR_STAGES,
    Repair,
    _detour,
    _footprints,
    _PuzzleFloor,
    _region,
    _retime,
    _solve_puzzle,
    _splice,
    _trim,
    repair_cycles,
)
from .run import (  # noqa: F401
    ExecutionResult,
    execute_plan,
    plan_to_paths,
)
from .validation import (  # noqa: F401
    _check_conflicts,
    _dense,
    _occupancy,
    validate_plan,
)

__all__ = ["PlanError", "Repair", "ExecutionResult", "load_floor", "load_fleet", "robot_model",
           "validate_plan", "find_cycles", "repair_cycles", "plan_to_paths", "execute_plan"]
