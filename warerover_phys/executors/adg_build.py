"""Building the action dependency graph (:mod:`.adg`): an AGV's plan becomes its actions and
their visits in the cells' queues (:meth:`PlanBuilding.set_plan`), one AGV at a time or a
whole fleet in bulk. A mixin of :class:`~.adg.ActionGraph` (its state is the graph's)."""

from __future__ import annotations

from collections import deque

from ..planning.base import TimedPath, footprint_nodes
from ..planning.sweep import Sweep
from .adg_types import Action, _Agent, _Step, _Visit, path_moves

__all__ = ["PlanBuilding"]


class PlanBuilding:
    """The plan-building half of :class:`~.adg.ActionGraph`."""

    def begin_bulk(self) -> bool:
        """Start registering many AGVs at once (the first plans of a whole fleet): until
        :meth:`end_bulk`, :meth:`set_plan` appends visits to their queues and the queues
        are sorted once at the end, into the order that inserting them one by one gives
        (held cells first in registration order, then by planned tick and insertion
        order): one sort per queue instead of a search per visit. Only on an empty graph
        (returns False, and does nothing, otherwise). Between the two calls nothing may
        read the queues."""
        if self._agents or self._bulk is not None:
            return False
        self._bulk = set()
        return True

    def end_bulk(self) -> None:
        """Sort the queues that got visits since :meth:`begin_bulk`."""
        cells, self._bulk = self._bulk, None
        self.plan_version += 1
        for c in cells or ():
            self._queues[c].sort(key=_bulk_key)

    def set_plan(self, agv: int, path: TimedPath) -> None:
        """Commit cut and rebuild for one AGV.

        Keeps the AGV's finished actions and its started one, drops every not-started action
        (and its visits), then appends the actions of ``path``. ``path.states[0]`` must be the
        AGV standing where it will be after the cut (``dst`` of the running action, else its
        anchor); otherwise ``ValueError``. The visits of the cells it holds after the cut stay
        where they are in their queues; only their leaving action changes. The first call for
        an AGV registers where it stands (its cells go to the head of their queues).
        """
        if agv not in self._sizes:
            raise KeyError(f"AGV {agv} has no footprint size")
        if path.agv != agv:
            raise ValueError(f"set_plan for AGV {agv} got the path of AGV {path.agv}")
        moves = path_moves(path, self.cols)
        here = path.states[0][0]
        rec = self._agents.get(agv)
        if rec is None:
            rec = self._register(agv, here, path.start_tick)
        else:
            cut = self.cut_node(agv)
            if here != cut:
                raise ValueError(f"AGV {agv}: the new path starts at "
                                 f"{divmod(here, self.cols)} but the AGV will stand at "
                                 f"{divmod(cut, self.cols)} after the cut")
            self._drop_unclaimed(rec)
        self._append_moves(agv, rec, moves)
        self.woken.add(agv)
        self.ext_woken.add(agv)
        self._plans_changed()
        self.plan_version += 1
        self._dirty.add(agv)

    def _register(self, agv: int, here: int, tick: int) -> _Agent:
        """The first plan of ``agv``: it stands on ``here`` (its cells' queues get its
        visits, entered)."""
        cols = self.cols
        cells = footprint_nodes(here, self._sizes[agv], cols)
        for c in cells:
            q = self._queues.get(c)
            if q and (q[0].entered and not q[0].sweep if self._bulk is None
                      else any(w.entered for w in q)):
                raise ValueError(f"AGV {agv} cannot start at {divmod(here, cols)}: cell "
                                 f"{divmod(c, cols)} is held by AGV {q[0].agv}")
        rec = _Agent(k=self._sizes[agv], node=here, held={}, pending=deque(),
                     heading=self._heading0)
        for c in cells:
            rec.held[c] = self._new_visit(c, agv, None, tick, entered=True)
        self._agents[agv] = rec
        return rec

    def _drop_unclaimed(self, rec: _Agent) -> None:
        """The commit cut: drop the AGV's not-claimed pending actions and their visits;
        visits they would have left are left by nothing for now."""
        kept = [s for s in rec.pending if s.claimed]
        gone = [s for s in rec.pending if not s.claimed]
        dropped = {id(s.action) for s in gone}
        for step in gone:
            for v in step.enter_visits:
                self._queues[v.cell].remove(v)
                self._n_visits -= 1
                self._touch(v.cell)
        for step in [rec.running, *kept]:
            if step is None:
                continue
            for v in step.enter_visits:
                if v.leave is not None and id(v.leave) in dropped:
                    v.leave = None
        for v in rec.held.values():
            if v.leave is not None and id(v.leave) in dropped:
                v.leave = None
        rec.pending = deque(kept)

    def _append_moves(self, agv: int, rec: _Agent,
                      moves: list[tuple[int, int, int, int]]) -> None:
        """Append the actions of ``moves`` (:func:`~.adg_types.path_moves`) after the AGV's
        committed ones, with their visits."""
        k, cols = rec.k, self.cols
        # Cells the AGV holds (or has claimed) after the cut, and not left by then.
        committed = [s for s in (rec.running, *rec.pending) if s is not None]
        open_visits = dict(rec.held)
        for step in committed:
            for v in step.leave_visits:
                if not v.sweep:
                    open_visits.pop(v.cell, None)
            for v in step.enter_visits:
                if not v.sweep:
                    open_visits[v.cell] = v
        offsets = self._sweeps.get(agv)
        heading = committed[-1].action.direction if committed else rec.heading
        # (path_moves checked every move: its direction is the step's offset.)
        dirs = {1: (0, 1), -1: (0, -1), cols: (1, 0), -cols: (-1, 0)}
        for src, dst, tick, ticks in moves:
            direction = dirs[dst - src]
            if k == 1:
                fs, fd = (src,), (dst,)
                enters, leaves = fd, fs
            else:
                fs, fd = footprint_nodes(src, k, cols), footprint_nodes(dst, k, cols)
                enters = tuple(c for c in fd if c not in fs)
                leaves = tuple(c for c in fs if c not in fd)
            swept: tuple[int, ...] = ()
            shelf: tuple[int, ...] = ()
            if offsets and direction != heading:
                swept = tuple(c for c in self._sweep_cells(src, offsets)
                              if c not in fs and c not in fd)
                shelf = tuple(c for c in self._shelf_cells(src, offsets)
                              if c not in fs and c not in fd)
            heading = direction
            action = Action(agv=agv, seq=rec.next_seq, src=src, dst=dst, tick=tick,
                            ticks=ticks, enters=enters, leaves=leaves,
                            direction=direction, sweeps=swept + shelf)
            rec.next_seq += 1
            rec.pending.append(self._step_visits(action, open_visits, swept, shelf))

    def _step_visits(self, action: Action, open_visits: dict[int, _Visit],
                     swept: tuple[int, ...], shelf: tuple[int, ...]) -> _Step:
        """The visits ``action`` leaves (its open ones) and enters (new, and the turn's
        sweep visits, entered and left by the action itself)."""
        agv, tick = action.agv, action.tick
        leave_visits = [open_visits.pop(c) for c in action.leaves]
        for v in leave_visits:
            v.leave = action
        enter_visits = []
        for c in action.enters:
            v = self._new_visit(c, agv, action, tick + 1, entered=False)
            open_visits[c] = v
            enter_visits.append(v)
        for c in swept + shelf:
            # The turn happens at the move's start tick; the same action leaves it.
            v = self._new_visit(c, agv, action, tick, entered=False)
            v.leave = action
            v.sweep = True
            v.shelf = c in shelf
            enter_visits.append(v)
            leave_visits.append(v)
        return _Step(action, enter_visits, leave_visits)

    def _sweep_cells(self, anchor: int, sweep: Sweep) -> tuple[int, ...]:
        """Queue keys of a turn at ``anchor``: swept cells, then locks (``-1 - anchor``)."""
        cols, rows = self.cols, self.rows
        r, c = divmod(anchor, cols)

        def inside(dr: int, dc: int) -> bool:
            return 0 <= c + dc < cols and r + dr >= 0 and (rows is None or r + dr < rows)

        return tuple((r + dr) * cols + c + dc for dr, dc in sweep.cells if inside(dr, dc)) \
            + tuple(-1 - ((r + dr) * cols + c + dc) for dr, dc in sweep.locks
                    if inside(dr, dc))

    def _shelf_cells(self, anchor: int, sweep: Sweep) -> tuple[int, ...]:
        """Cells of a turn at ``anchor`` held only against AGVs that carry a shelf."""
        cols, rows = self.cols, self.rows
        r, c = divmod(anchor, cols)
        return tuple((r + dr) * cols + c + dc for dr, dc in sweep.shelf_cells
                     if 0 <= c + dc < cols and r + dr >= 0 and (rows is None or r + dr < rows))


def _bulk_key(v: _Visit) -> tuple[int, int, int]:
    """Queue order of visits registered in bulk (:meth:`ActionGraph.begin_bulk`): held
    cells first, in registration order, then by (planned enter tick, insertion order)."""
    return (0, 0, v.order) if v.entered else (1, v.tick, v.order)
