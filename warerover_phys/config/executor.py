"""Scenario schema: the executor (grid or physics, delays) and faults."""

from __future__ import annotations

from typing import Literal

from pydantic import (
    Field,
    model_validator,
)

from .types import (
    Bool,
    ExecutorName,
    NonNegFloat,
    NonNegInt,
    NonNegTicks,
    Params,
    PosFloat,
    PosInt,
    Prob,
    Ticks,
    _Model,
)


class DelaySpec(_Model):
    """Random execution delays (the Robot Runners 2026 ``delayConfig`` model): each tick,
    each AGV draws a delay event (``bernoulli``: with probability ``prob``; ``poisson``:
    a Poisson(``prob``) count, any count > 0 starts one); a delay stops the AGV for a
    duration in ticks drawn ``uniform`` from [``min_ticks``, ``max_ticks``] or ``gaussian``
    (``mean_ticks``, ``std_ticks``, rounded, clipped to [``min_ticks``, ``max_ticks``])."""

    model: Literal["none", "bernoulli", "poisson"] = "none"
    prob: Prob = 0.0
    duration: Literal["uniform", "gaussian"] = "uniform"
    min_ticks: Ticks = 1
    max_ticks: Ticks = 10
    mean_ticks: PosFloat = 5.0
    std_ticks: NonNegFloat = 2.0

    @model_validator(mode="after")
    def _range(self) -> DelaySpec:
        if self.max_ticks < self.min_ticks:
            raise ValueError(f"max_ticks {self.max_ticks} is below min_ticks {self.min_ticks}")
        return self


class ExecutorSpec(_Model):
    """How plans are carried out: ``grid`` (ideal discrete moves) or ``physics`` (pymunk
    rigid bodies with kinematic limits, following an action dependency graph)."""

    name: ExecutorName = "grid"
    """``grid``, ``physics``, an entry point, or a plugin class ``package.module:ClassName``."""
    params: Params = {}
    """Parameters of a plug-in executor (its ``Params`` model)."""
    dt_s: PosFloat = 0.02
    """Physics step (seconds); the planning tick is ``tick_s``."""
    adg: Bool = True
    """Follow the action dependency graph; ``false`` = naive time-indexed following (an
    action starts at its planned tick whatever the other AGVs do)."""
    delays: DelaySpec = DelaySpec()
    speed_scale: tuple[PosFloat, PosFloat] = (1.0, 1.0)
    """Each AGV's top speed is scaled by a factor drawn uniformly from this range."""
    deviation_m: PosFloat = 0.35
    """An AGV farther than this from its path is stopped and replanned."""
    trajectory_hz: PosFloat = 10.0
    """Rate at which executed poses are recorded (``trajectories.npz``), in Hz: every
    ``round(1 / (trajectory_hz x dt))`` th physics step; at most the physics rate
    ``1 / dt_s`` (that value records every step)."""
    freeze_s: NonNegFloat = 30.0
    """Physics: a freeze is found when AGVs make no progress towards their goals for this
    many simulated seconds while nothing they wait on can still move (``freeze.py``); it
    is counted in ``deadlocks`` / ``freezes``, logged (``freeze`` event) and the AGVs are
    replanned from where they stand. 0 turns the detector off."""
    payload: Bool = False
    """Physics: a loaded AGV's acceleration limit drops to
    ``mass_kg x max_accel_mps2 / (mass_kg + payload_kg)`` of its type (and its body's mass
    grows by ``payload_kg``) while it carries a shelf; the command limiter, the braking
    profile and the measured-limit checks use the limit in force."""
    no_slip: Bool = False
    """Physics: differential-drive AGVs cannot move sideways: the unicycle law of
    :mod:`~warerover_phys.executors.diffdrive` commands velocity only along the body's
    heading, turns in place where the path turns, corrects lateral error by steering and
    keeps speed, acceleration, turn rate and wheel speeds (``wheel_base_m``,
    ``max_wheel_speed_mps``) within their limits at every step (``robot: diffdrive`` sets
    it). Off: the default controller also pulls sideways (``peak_lateral_speed_mps`` shows
    how much)."""
    comm_latency_s: NonNegFloat = 0.0
    """Physics with ``adg: true``: seconds before an AGV hears that another AGV's action it
    depends on is done (the dependency graph's messages arrive late): an action whose
    dependency finished at time t starts at t + latency at the earliest."""
    shelf_contacts: Bool = False
    """Physics: a loaded AGV's collision shape includes its carried shelf (a square
    ``0.9 x shelf size x cell_m`` with sides along the grid, as in ``min_clearance_m``);
    contacts of a carried shelf with another AGV or its shelf count as AGV contacts, with a
    wall as static contacts."""
    shelf_sweeps: Bool = False
    """Physics: a turn in place whose disc reaches the shelf a *neighbour* may carry (but
    not its body: an 0.8 m body next to a 0.9 m shelf on 1 m cells, 1.6 cm deep) waits in
    the dependency graph until that neighbour carries no shelf
    (:attr:`~warerover_phys.planning.sweep.Sweep.shelf_cells`). The planners do not reserve
    these cells yet, so AGVs often block each other: on the padded paper floors with 0.8 m
    bodies the shelf overlaps fell from 177-548 samples per episode to 0-10, but success
    fell from 1.0 to 0.15-0.35 (``tools/README.md``). ``false`` (default): such a turn
    goes ahead, the overlap is reported in ``min_clearance_m``. No effect on bodies whose
    disc stays clear of neighbours' shelves (the default 0.7 m)."""
    turn_in_place: Bool = False
    """Physics: a differential-drive AGV whose committed plan only stands on its cell and
    changes its heading (``TimedPath.headings``) turns in place to the plan's last heading
    at once, at its turn rate (if its turn sweeps no cell beyond its own). ``false``
    (default): plan headings are not followed; the AGV turns when its next move comes. The
    environments (``warerover_phys.envs``) turn it on for their turn actions."""
    park: Bool = True
    """Physics: an AGV that stands still on its hold point (within 1 mm, at rest, facing its
    heading) has its drive joints taken out of the pymunk world until it moves again, so
    the solver does not iterate over them (most of pymunk's step at 1,000 AGVs). Nothing
    can move a parked body: AGV-AGV contacts are not solved. ``false``: every joint always
    in the world (for comparison; figures agree to within the 1 mm)."""

    reorder: Literal["none", "greedy", "milp"] = "none"
    """Physics with ``adg: true``: reorder the dependency graph while executing (switchable
    action dependency graph, Berndt et al. 2020; ``executors/reorder.py``). ``none``: the
    plan's passing order at every shared cell (the plain graph). ``greedy``: an AGV that
    waits at a cell reserved for another AGV that has not reached it yet passes first
    when the motion model says it clears the cells they share sooner than the other's
    delay lasts. ``milp``: the order at the switchable cells of a receding window chosen
    by a mixed-integer program (scipy ``milp``, HiGHS), greedy where it finds no optimum
    within its node limit. Every switch keeps the graph acyclic (checked)."""
    reorder_estimates: Literal["model", "clairvoyant"] = "model"
    """How ``greedy`` and ``milp`` estimate when AGVs pass: ``model``, the motion model
    stretched by the share of time the random delays are expected to hold an AGV.
    ``clairvoyant``: the motion model past the delays each AGV *will* have (the
    executor's draws replayed ahead, ``executors/delays.py``). No fleet knows its delays
    ahead: a diagnostic, the bound on what better estimates could win."""
    reorder_every_s: PosFloat = 0.5
    """Simulated seconds between reorder decisions (rounded up to the follower's
    decisions, every 0.1 s)."""
    reorder_margin_s: NonNegFloat = 0.5
    """A switch must win at least this many estimated seconds."""
    reorder_ahead_s: NonNegFloat = 2.0
    """A driving AGV whose next collinear action waits on the graph is a candidate too,
    once it would have to start braking for it within this many seconds at top speed:
    switched, it drives on instead of stopping (0: only standing AGVs are candidates)."""
    reorder_horizon: PosInt = 8
    """``milp``: actions per AGV in the program's window (at least those of the cells
    it may switch)."""
    reorder_node_limit: PosInt = 500
    """``milp``: branch-and-bound nodes per program; without a proved optimum within them
    the decision falls back to greedy. A node limit, not a clock: the same seed gives
    the same result on any machine."""
    reorder_time_limit_s: PosFloat | None = None
    """``milp``: wall-clock seconds per program as well (None: none). Set, results may
    depend on the machine's speed."""
    reorder_milp_band_s: NonNegFloat | None = 2.0
    """``milp``: a lone candidate (no other shares an AGV with it) whose estimated gain is
    further than this from the margin is decided by the greedy rule, without a program
    (None: every candidate goes to the program)."""
    reorder_milp_max_vars: PosInt | None = 120
    """``milp``: a problem whose program would have more variables than this (start times
    and binaries) is decided by the greedy rule, without a program (None: no limit). A
    size, not a clock: HiGHS takes about 20 ms for 200 variables, and the larger programs
    took most of the decision time at 1,000 agents (2026-11-29: 200 before; with 120,
    LaCAM's 1,000-agent plan, bernoulli 0.1, seed 0, takes about 1.9x instead of 2.1x the
    wall clock of ``none``, for the same AET, and 400 agents gain as much over 20 seeds)."""

    @model_validator(mode="after")
    def _physics_fields(self) -> ExecutorSpec:
        lo, hi = self.speed_scale
        if lo > hi:
            raise ValueError(f"speed_scale [{lo}, {hi}] must be [low, high]")
        if self.reorder != "none" and not self.adg:  # (a physics setting: the grid
            # executor ignores it, as it does the others, so that gap can run both)
            raise ValueError(f"reorder: {self.reorder!r} switches edges of the physics "
                             f"executor's dependency graph: it needs adg: true (got adg: "
                             f"false)")
        return self


class RandomFaultsSpec(_Model):
    prob_per_tick: Prob = 0.0
    repair_ticks: Ticks = 40
    repair_ticks_max: Ticks | None = None
    """If set, repair time is drawn uniformly from [repair_ticks, repair_ticks_max]."""
    max_down: PosInt | None = None


class ScheduledFaultSpec(_Model):
    agv: NonNegInt
    tick: NonNegTicks
    repair_ticks: Ticks = 40


class FaultsSpec(_Model):
    """Failures, their repairs and the safety corridors around failed AGVs (see
    ``faults/model.py``)."""

    random: RandomFaultsSpec = RandomFaultsSpec()
    scheduled: list[ScheduledFaultSpec] = Field(default_factory=list)
    corridor_width_m: PosFloat = 1.0
    corridor_margin_m: NonNegFloat = 0.2
    orders_of_failed: Literal["reassign", "wait"] = "reassign"
    exit_time_s: PosFloat | None = None
    """Seconds an AGV caught inside a corridor when it opens may take to leave it before
    its time inside counts as intrusion. None: derived per AGV when the corridor opens
    (cells to drive out at the plan's move time plus one move, a half turn, speeding up and
    braking, plus ``exit_margin_s``; see ``faults/intrusion_log.py``)."""
    exit_margin_s: NonNegFloat = 2.0
    """Seconds added to the derived exit time (replanning waits for a tick boundary)."""
    checker: Literal["fcl", "numpy"] = "numpy"
    """How the physics executor finds the AGV bodies in the corridors' margins each step:
    ``numpy`` (bounding boxes against every rectangle) or ``fcl`` (python-fcl's AABB trees
    and boolean box-box collide); the closed form of ``faults/intrusion.py`` measures
    the pairs either finds, so both give the same intrusions and depths. ``numpy`` is the
    default: faster in ``tools/bench_intrusion.py`` (1,000 AGVs x 50 corridors)."""

    @property
    def enabled(self) -> bool:
        return self.random.prob_per_tick > 0 or bool(self.scheduled)
