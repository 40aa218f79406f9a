"""The physics executor's per-AGV arrays, shared by its parts (index = AGV id).

One mutable record read and written by the control law (:mod:`.control`), the plan follower
(:mod:`.follow`) and the accounting (:mod:`.accounting`), so each part holds a reference to
the same numpy arrays instead of copies. Modes are an AGV's driving state, not its task state.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["HOLD", "TURN", "DRIVE", "FleetState"]

HOLD, TURN, DRIVE = 0, 1, 2
"""Driving modes: standing on a cell centre, turning in place, driving a run of actions."""


@dataclass(eq=False)
class FleetState:
    """Limits, references and progress of every AGV (arrays of length ``n``)."""

    cols: int
    cell_m: float
    tick_s: float
    dt: float
    """Seconds per physics step."""
    k: np.ndarray
    """Footprint sizes (cells)."""
    vmax: np.ndarray
    """Top speed times the AGV's drawn speed scale (m/s)."""
    amax: np.ndarray
    """Acceleration limit (m/s^2)."""
    wmax: np.ndarray
    """Turn-rate limit (rad/s)."""
    omni: np.ndarray
    """Omnidirectional drive (never turns)."""
    origin: np.ndarray
    """(N, 2) start of the current straight run (metres)."""
    no_slip: np.ndarray | None = None
    """Bodies that cannot move sideways (``executor.no_slip``, differential drive): the
    control law commands velocity only along their heading and steers onto the path.
    None: none."""
    diff: object | None = None
    """The no-slip law's per-AGV constants (:class:`.diffdrive.DiffParams`: half widths,
    wheel limits) when ``no_slip`` is set; None: its defaults."""
    decide_every: int = 1
    """Physics steps between decisions for standing AGVs (``follow.DECIDE_S`` seconds)."""
    sim_s: float = 0.0
    """Simulated time (seconds)."""
    mode: np.ndarray = field(init=False)
    direction: np.ndarray = field(init=False)
    """(N, 2) unit direction (x, y) of the current run."""
    hold_xy: np.ndarray = field(init=False)
    """(N, 2) cell centre a standing AGV holds."""
    heading: np.ndarray = field(init=False)
    """Heading to hold (radians)."""
    ang_ref: np.ndarray = field(init=False)
    """Reference heading while turning (radians)."""
    cur_end: np.ndarray = field(init=False)
    """End of the running action along the run (metres from its origin)."""
    stop_s: np.ndarray = field(init=False)
    """Stop point along the run: the end of the released collinear actions."""
    speed: np.ndarray = field(init=False)
    """Reference speed along the run (m/s)."""
    s_ref: np.ndarray = field(init=False)
    """Reference position along the current run (metres from its origin)."""
    delayed_until: np.ndarray = field(init=False)
    """Simulated time until which an injected delay holds the AGV."""
    waiting: np.ndarray = field(init=False)
    """Waiting on a dependency of its next action (at the last decision)."""
    failed: np.ndarray = field(init=False)
    has_next: np.ndarray = field(init=False)
    """AGVs with a not-started action (kept up to date on every ADG change)."""
    pending: np.ndarray = field(init=False)
    """AGVs that had an action left at the end of the last tick."""
    last_finish: np.ndarray = field(init=False)
    """Simulated time at which each AGV last finished an action."""
    listening: np.ndarray = field(init=False)
    """Its next action's cells are free but the message saying so has not arrived yet
    (``executor.comm_latency_s``; at the last decision)."""
    hold_until: np.ndarray = field(init=False)
    """Simulated time until which a planned dwell (``TickView.dwells``) holds the AGV."""

    def __post_init__(self) -> None:
        n = self.n
        self.mode = np.full(n, HOLD, dtype=np.int8)
        self.direction = np.zeros((n, 2))
        self.hold_xy = self.origin.copy()
        self.heading = np.zeros(n)
        self.ang_ref = np.zeros(n)
        self.cur_end = np.zeros(n)
        self.stop_s = np.zeros(n)
        self.speed = np.zeros(n)
        self.s_ref = np.zeros(n)
        self.delayed_until = np.zeros(n)
        self.waiting = np.zeros(n, dtype=bool)
        self.failed = np.zeros(n, dtype=bool)
        self.has_next = np.zeros(n, dtype=bool)
        self.pending = np.zeros(n, dtype=bool)
        self.last_finish = np.zeros(n)
        self.listening = np.zeros(n, dtype=bool)
        self.hold_until = np.zeros(n)

    @property
    def n(self) -> int:
        return len(self.k)

    def ref_xy(self) -> np.ndarray:
        """(N, 2) reference points (metres): along the run while driving, the hold point
        (cell centre) while standing or turning."""
        run = self.origin + self.direction * self.s_ref[:, None]
        return np.where((self.mode == DRIVE)[:, None], run, self.hold_xy)

    def along(self, pos: np.ndarray) -> np.ndarray:
        """Distance of each body (N, 2 positions) along its current run from its origin."""
        return ((pos - self.origin) * self.direction).sum(axis=1)
