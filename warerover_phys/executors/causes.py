"""Where each AGV's time goes: one label per AGV per physics step, summed per action.

The physics executor calls :class:`CauseRecorder` from its accounting: once per physics step
(:meth:`CauseRecorder.step`, after the follower has decided) and when an action begins or
finishes. Every step of every AGV gets exactly one label, by priority:

=============  =====================================================================
``dwell``      a planned dwell holds it (``TickView.dwells``: pick, hand-over, place,
               parking)
``failed``     it is down (a failure)
``injected``   an injected random delay holds it (``executor.delays``)
``drive``      it drives an action (accelerating, cruising or braking)
``turn``       it turns in place towards its next move
``dependency`` its next action waits on the dependency graph (another AGV's visit is
               ahead of its own at a cell it must enter; that AGV is its *blocker*)
``control``    it stands with a released next action that has not started yet (the
               follower decides every ``DECIDE_EVERY`` steps, and a body settles on its
               cell centre before a turn)
=============  =====================================================================

The steps between the finish of an AGV's previous action (or step 0) and the finish of an
action are that action's *interval*; :meth:`CauseRecorder.log` returns, per finished
action, its planned start tick and duration, the steps at which it started and finished and
the label counts of its interval, which add up to the interval's length exactly. Dependency
waits are also counted per blocker. :mod:`warerover_phys.gap.open_loop` credits the plan's
durations against these counts to split lost time into causes.

Costs a few vectorised numpy operations per physics step (:meth:`CauseRecorder.step`, the
reference), or one compiled loop over the fleet together with the accounting's delay shares
(:meth:`CauseRecorder.step_with_shares`, the same labels); an AGV's blocker is looked up when
it starts to wait and then every ``refresh`` steps (one tick at the default step) while it
waits, so a blocker that changes mid-wait is credited from the next look-up.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .fleet_state import DRIVE, HOLD, TURN

if TYPE_CHECKING:
    from .adg import Action, ActionGraph
    from .fleet_state import FleetState

__all__ = ["LABELS", "DWELL", "FAILED", "INJECTED", "DRIVE_L", "TURN_L", "DEPENDENCY",
           "CONTROL", "CauseLog", "CauseRecorder"]

LABELS = ("dwell", "failed", "injected", "drive", "turn", "dependency", "control")
"""Step labels, in priority order (index = label code)."""
DWELL, FAILED, INJECTED, DRIVE_L, TURN_L, DEPENDENCY, CONTROL = range(len(LABELS))


@dataclass(frozen=True)
class CauseLog:
    """Every finished action with the labelled steps of its interval (arrays of length M,
    in finishing order), and dependency waits per blocker."""

    dt_s: float
    """Seconds per physics step."""
    steps_per_tick: int
    steps: int
    """Physics steps run."""
    agv: np.ndarray
    seq: np.ndarray
    """The action's sequence number (per AGV, from 0 in the order of its plan)."""
    src: np.ndarray
    dst: np.ndarray
    """Anchor nodes (``row * cols + col``) it leaves and enters."""
    tick: np.ndarray
    """Planned start tick (the last tick it stands at ``src``)."""
    ticks: np.ndarray
    """Planned duration in ticks."""
    start_step: np.ndarray
    finish_step: np.ndarray
    """Physics step at which it started / finished (time = step x ``dt_s``)."""
    counts: np.ndarray
    """(M, len(LABELS)) steps of each label in the action's interval (from the AGV's
    previous finish, or step 0, to this finish)."""
    blockers: dict[tuple[int, int], int]
    """``(agv, blocker) -> steps`` the AGV waited on a dependency held up by ``blocker``
    (blocker -1: none found at the look-up)."""
    reorder_gain: np.ndarray | None = None
    """(M,) steps of dependency wait the interval's switched edges saved, as estimated
    when they were switched (``executor.reorder``; zeros without it)."""


class CauseRecorder:
    """Labels every AGV's physics steps (see the module docstring)."""

    def __init__(self, st: FleetState, adg: ActionGraph, refresh: int = 50) -> None:
        n = st.n
        self.st, self.adg, self.refresh = st, adg, refresh
        self._was_waiting = np.zeros(n, dtype=bool)
        self.step_no = 0
        self._cur = np.zeros((n, len(LABELS)), dtype=np.int64)
        self._rows = np.arange(n)
        self._begun: dict[int, tuple[Action, int]] = {}
        self._done: list[tuple] = []
        self._blocker = np.full(n, -1, dtype=np.int64)
        self._wait_run = np.zeros(n, dtype=np.int64)
        self._look = np.zeros(n, dtype=np.intp)
        self.blockers: dict[tuple[int, int], int] = {}
        self._gain = np.zeros(n, dtype=np.int64)

    # ------------------------------------------------------------------------- hooks

    def action_begun(self, i: int, a: Action) -> None:
        self._begun[i] = (a, self.step_no)

    def action_done(self, i: int) -> None:
        got = self._begun.pop(i, None)
        if got is None:
            return
        a, start = got
        self._flush_wait(i)
        self._done.append((i, a.seq, a.src, a.dst, a.tick, a.ticks, start, self.step_no,
                           self._cur[i].copy(), int(self._gain[i])))
        self._cur[i] = 0
        self._gain[i] = 0

    def reorder_gain(self, i: int, steps: int) -> None:
        """A switched edge saves AGV ``i`` an estimated ``steps`` of dependency wait in
        its current interval (:mod:`.reorder`)."""
        self._gain[i] += steps

    def step(self, injected: np.ndarray) -> None:
        """Label the physics step that has just run (modes as the follower left them)."""
        st = self.st
        lab = np.full(st.n, CONTROL, dtype=np.int64)
        lab[st.waiting] = DEPENDENCY
        lab[st.mode == TURN] = TURN_L
        lab[st.mode == DRIVE] = DRIVE_L
        lab[injected & ((st.mode != HOLD) | st.has_next)] = INJECTED
        lab[st.failed] = FAILED
        # A dwell runs from the AGV's last arrival (an exact time inside a step) to
        # hold_until: the steps whose midpoints fall in it are its steps (one per dt of
        # the dwell, whatever the arrival's offset in its step).
        mid = st.sim_s - 0.5 * st.dt
        lab[(st.hold_until > mid) & (st.last_finish <= mid)] = DWELL
        self._cur[self._rows, lab] += 1
        waiting = lab == DEPENDENCY
        if waiting.any():
            # Look the blocker up when an AGV starts to wait, then every ``refresh`` steps
            # while it waits (a look-up reads the cell's queue: too dear for every step).
            look = waiting & ~self._was_waiting if self.step_no % self.refresh else waiting
            for i in np.flatnonzero(look):
                b = self._find_blocker(int(i))
                if b != self._blocker[i]:
                    self._flush_wait(int(i))
                    self._blocker[i] = b
            self._wait_run[waiting] += 1
        self._was_waiting = waiting
        self.step_no += 1

    def step_with_shares(self, injected: np.ndarray, dep_wait: np.ndarray,
                         injected_s: np.ndarray, turn_time: np.ndarray,
                         act_injected: np.ndarray) -> int:
        """:meth:`step` and the accounting's per-AGV delay shares of the step (seconds
        waiting on a dependency, held by an injected delay while busy or pending, turning,
        and held while driving: ``Accounting.after_step``'s numpy reference) in one
        compiled pass (:func:`.step_kernels.step_shares`, the same labels and sums).
        Returns the number of AGVs not holding."""
        from .step_kernels import step_shares

        st = self.st
        active, nl = step_shares(
            st.mode, st.waiting, injected, st.pending, st.failed, st.has_next,
            st.hold_until, st.last_finish, st.sim_s - 0.5 * st.dt, st.dt, dep_wait,
            injected_s, turn_time, act_injected, self._cur, self._was_waiting,
            self._wait_run, self.step_no % self.refresh == 0, self._look)
        # The blocker look-ups (their waits were not counted yet: a changed blocker gets
        # the run so far first), as in step().
        if nl:
            look = self._look[:nl]
            blocker = self._blocker
            for i, b in zip(look.tolist(), self.adg.blockers(look.tolist()), strict=True):
                if b != blocker[i]:
                    self._flush_wait(i)
                    blocker[i] = b
            self._wait_run[look] += 1
        self.step_no += 1
        return int(active)

    @property
    def blocker(self) -> np.ndarray:
        """Per AGV, the blocker found at its last look-up while waiting on a dependency
        (-1: none; stale once it no longer waits). Read-only view."""
        view = self._blocker.view()
        view.flags.writeable = False
        return view

    # ------------------------------------------------------------------------- helpers

    def _find_blocker(self, i: int) -> int:
        """The AGV whose visit is ahead of ``i``'s at the first cell its next action enters
        (the one it waits for); -1 if none."""
        adg = self.adg
        nxt = adg.next_action(i)
        if nxt is None:
            return -1
        for c in nxt.enters:
            h = adg.head(c)  # the holder if the head is entered, else the next in line
            if h is not None and h != i:
                return h
        return -1

    def _flush_wait(self, i: int) -> None:
        run = int(self._wait_run[i])
        if run:
            key = (i, int(self._blocker[i]))
            self.blockers[key] = self.blockers.get(key, 0) + run
            self._wait_run[i] = 0

    def log(self) -> CauseLog:
        """The finished actions so far (see :class:`CauseLog`)."""
        for i in np.flatnonzero(self._wait_run):
            self._flush_wait(int(i))
        rows = self._done
        cols = list(zip(*rows, strict=True)) if rows else [()] * 10

        def arr(k: int) -> np.ndarray:
            return np.asarray(cols[k], dtype=np.int64)

        counts = np.stack(cols[8]) if rows else np.zeros((0, len(LABELS)), dtype=np.int64)
        st = self.st
        return CauseLog(dt_s=float(st.dt), steps_per_tick=int(round(st.tick_s / st.dt)),
                        steps=self.step_no, agv=arr(0), seq=arr(1), src=arr(2), dst=arr(3),
                        tick=arr(4), ticks=arr(5), start_step=arr(6), finish_step=arr(7),
                        counts=counts, blockers=dict(self.blockers), reorder_gain=arr(9))
