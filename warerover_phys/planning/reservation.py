"""Space-time reservation table: which AGV holds which cell at which tick.

Turns in place (issue 13). For AGVs registered with :meth:`ReservationTable.configure_turns`
(differential-drive bodies whose turn sweeps beyond their footprint) a committed path also
holds, for each of its turns (:func:`~warerover_phys.planning.sweep.turn_sweeps`, from the
heading the AGV has at the path's start), the turn's swept cells at the turn's tick and the
next one (as if the AGV occupied them, so every check of ``free`` keeps other AGVs out),
and its turn locks at the turn's tick (:meth:`ReservationTable.locks_free`). Nothing
changes for AGVs that are not registered.
"""

from __future__ import annotations

from collections.abc import Mapping

from .paths import TimedPath, occupancy
from .sweep import EAST, Sweep, lock_keys, sweep_cells, turn_sweeps

__all__ = ["ReservationTable", "FOREVER"]

FOREVER = 1 << 60


class ReservationTable:
    """Cells held per tick by committed paths, plus where each path ends and stays.

    Keys are flat cell indices (``row * cols + col``). Every AGV has exactly one committed
    path; :meth:`commit` replaces the previous one.
    """

    def __init__(self, cols: int, rows: int | None = None) -> None:
        self.cols = cols
        self.rows = rows
        self.turning: dict[int, Sweep] = {}
        """Per AGV what its turns hold (only AGVs whose turns hold cells or locks)."""
        self._head0: dict[int, tuple[int, int] | None] = {}
        self._locks: dict[int, dict[int, int]] = {}
        self._lock_keys: dict[int, list[tuple[int, int]]] = {}
        self._occ: dict[int, dict[int, int]] = {}
        self._rest: dict[int, tuple[int, int]] = {}
        self._keys: dict[int, list[tuple[int, int]]] = {}
        self._rest_keys: dict[int, tuple[int, ...]] = {}
        self.paths: dict[int, TimedPath] = {}
        self.sizes: dict[int, int] = {}

    def configure_turns(self, sweeps: Mapping[int, Sweep], rows: int) -> None:
        """Register the AGVs whose turns in place hold cells or locks (``agv -> Sweep``;
        see the module doc) on a grid of ``rows`` rows. Paths committed from now on hold
        their turns too."""
        self.rows = rows
        self.turning = {a: sw for a, sw in sweeps.items() if sw.cells or sw.locks}

    def heading_at_start(self, agv: int) -> tuple[int, int] | None:
        """The heading ``agv`` had at the start of its committed path (east if never
        given)."""
        return self._head0.get(agv, EAST)

    def commit(self, path: TimedPath, k: int, heading: tuple[int, int] | None | str = "keep",
               ) -> int:
        """Reserve ``path`` for its AGV (footprint ``k``), dropping its previous path.
        ``heading``: the direction the AGV faces at the path's start, for its turns
        (``"keep"``: the one given with its previous path, east if none).

        Returns how many (cell, tick) entries already belonged to another AGV: 0 for a
        conflict-free plan.
        """
        if heading == "keep":
            heading = self._head0.get(path.agv, EAST)
        self._head0[path.agv] = heading  # type: ignore[assignment]
        self.release(path.agv)
        agv, occ, clashes = path.agv, self._occ, 0
        keys: list[tuple[int, int]] = []
        for i, state in enumerate(path.states):
            t = path.start_tick + i
            for cell in occupancy(state, k, self.cols):
                slot = occ.get(cell)
                if slot is None:
                    slot = occ[cell] = {}
                other = slot.get(t)
                if other is not None and other != agv:
                    clashes += 1
                slot[t] = agv
                keys.append((cell, t))
        rest_cells = occupancy(path.states[-1], k, self.cols)
        for cell in rest_cells:
            other = self._rest.get(cell)
            if other is not None and other[1] != agv:
                clashes += 1
            self._rest[cell] = (path.end_tick, agv)
        sweep = self.turning.get(agv)
        if sweep is not None:
            clashes += self._commit_turns(path, sweep, heading, keys)  # type: ignore[arg-type]
        self._keys[agv] = keys
        self._rest_keys[agv] = rest_cells
        self.paths[agv] = path
        self.sizes[agv] = k
        return clashes

    def _commit_turns(self, path: TimedPath, sweep: Sweep, heading: tuple[int, int] | None,
                      keys: list[tuple[int, int]]) -> int:
        agv, occ, cols, clashes = path.agv, self._occ, self.cols, 0
        lkeys: list[tuple[int, int]] = []
        rows = self.rows if self.rows is not None else 1 << 30
        for i, anchor in turn_sweeps(path.states, cols, heading):
            t = path.start_tick + i
            for cell in sweep_cells(anchor, sweep.cells, rows, cols):
                for tt in (t, t + 1):
                    slot = occ.get(cell)
                    if slot is None:
                        slot = occ[cell] = {}
                    other = slot.get(tt)
                    if other is None:
                        slot[tt] = agv
                        keys.append((cell, tt))
                    elif other != agv:
                        clashes += 1
            for key in lock_keys(anchor, sweep.locks, self.rows, cols):
                slot = self._locks.setdefault(key, {})
                other = slot.get(t)
                if other is not None and other != agv:
                    clashes += 1
                    continue
                slot[t] = agv
                lkeys.append((key, t))
        self._lock_keys[agv] = lkeys
        return clashes

    def locks_free(self, keys, t: int, me: int) -> bool:
        """Is no turn lock of ``keys`` (flat anchors) taken by another AGV's turn at
        tick ``t``?"""
        locks = self._locks
        for key in keys:
            slot = locks.get(key)
            if slot is not None:
                a = slot.get(t)
                if a is not None and a != me:
                    return False
        return True

    def copy(self) -> ReservationTable:
        """An independent copy: what a planner gets to work in (the loop commits the paths
        the planner returns into the world's own table)."""
        new = ReservationTable.__new__(ReservationTable)
        new.cols = self.cols
        new.rows = self.rows
        new.turning = self.turning
        new._head0 = dict(self._head0)
        new._locks = {key: dict(slot) for key, slot in self._locks.items()}
        new._lock_keys = {agv: list(keys) for agv, keys in self._lock_keys.items()}
        new._occ = {cell: dict(slot) for cell, slot in self._occ.items()}
        new._rest = dict(self._rest)
        new._keys = {agv: list(keys) for agv, keys in self._keys.items()}
        new._rest_keys = dict(self._rest_keys)
        new.paths = dict(self.paths)
        new.sizes = dict(self.sizes)
        return new

    def snapshot(self) -> ReservationTable:
        """A copy made when first read (:meth:`copy` then): a planner that never reads its
        request's reservations (the compiled lifelong PIBT) costs no copy (12 ms a tick at
        5,000 AGVs). Read it before this table changes again (the loop changes its own
        only after the planner has answered)."""
        lazy = _LazyTable.__new__(_LazyTable)
        object.__setattr__(lazy, "_source", self)
        return lazy

    def release(self, agv: int) -> None:
        """Forget the committed path of ``agv`` (if any)."""
        for cell, t in self._keys.pop(agv, ()):
            slot = self._occ.get(cell)
            if slot is not None and slot.get(t) == agv:
                del slot[t]
                if not slot:
                    del self._occ[cell]
        for key, t in self._lock_keys.pop(agv, ()):
            slot = self._locks.get(key)
            if slot is not None and slot.get(t) == agv:
                del slot[t]
                if not slot:
                    del self._locks[key]
        for cell in self._rest_keys.pop(agv, ()):
            if self._rest.get(cell, (0, -1))[1] == agv:
                del self._rest[cell]
        self.paths.pop(agv, None)

    def owner(self, cell: int, t: int) -> int | None:
        """The AGV holding ``cell`` at tick ``t``, or None."""
        slot = self._occ.get(cell)
        if slot is not None:
            a = slot.get(t)
            if a is not None:
                return a
        rest = self._rest.get(cell)
        if rest is not None and t >= rest[0]:
            return rest[1]
        return None

    def free(self, cell: int, t: int, me: int) -> bool:
        a = self.owner(cell, t)
        return a is None or a == me

    def last_use(self, cell: int, me: int) -> int:
        """Latest tick another AGV holds ``cell`` (FOREVER if one stays there, -1 if none)."""
        rest = self._rest.get(cell)
        if rest is not None and rest[1] != me:
            return FOREVER
        slot = self._occ.get(cell)
        if not slot:
            return -1
        return max((t for t, a in slot.items() if a != me), default=-1)

    def resting_at(self, cell: int) -> int | None:
        rest = self._rest.get(cell)
        return None if rest is None else rest[1]


class _LazyTable(ReservationTable):
    """:meth:`ReservationTable.snapshot`: its state is copied from the source on first
    use."""

    def __getattr__(self, name: str):  # only for attributes not set yet
        if name.startswith("__") or "_source" not in self.__dict__:
            raise AttributeError(name)
        src = self.__dict__.pop("_source")
        self.__dict__.update(src.copy().__dict__)
        return getattr(self, name)
