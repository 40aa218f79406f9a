"""Space-time reservation table: which AGV holds which cell at which tick."""

from __future__ import annotations

from .paths import TimedPath, occupancy

__all__ = ["ReservationTable", "FOREVER"]

FOREVER = 1 << 60


class ReservationTable:
    """Cells held per tick by committed paths, plus where each path ends and stays.

    Keys are flat cell indices (``row * cols + col``). Every AGV has exactly one committed
    path; :meth:`commit` replaces the previous one.
    """

    def __init__(self, cols: int) -> None:
        self.cols = cols
        self._occ: dict[int, dict[int, int]] = {}
        self._rest: dict[int, tuple[int, int]] = {}
        self._keys: dict[int, list[tuple[int, int]]] = {}
        self._rest_keys: dict[int, tuple[int, ...]] = {}
        self.paths: dict[int, TimedPath] = {}
        self.sizes: dict[int, int] = {}

    def commit(self, path: TimedPath, k: int) -> int:
        """Reserve ``path`` for its AGV (footprint ``k``), dropping its previous path.

        Returns how many (cell, tick) entries already belonged to another AGV: 0 for a
        conflict-free plan.
        """
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
        self._keys[agv] = keys
        self._rest_keys[agv] = rest_cells
        self.paths[agv] = path
        self.sizes[agv] = k
        return clashes

    def copy(self) -> ReservationTable:
        """An independent copy: what a planner gets to work in (the loop commits the paths
        the planner returns into the world's own table)."""
        new = ReservationTable.__new__(ReservationTable)
        new.cols = self.cols
        new._occ = {cell: dict(slot) for cell, slot in self._occ.items()}
        new._rest = dict(self._rest)
        new._keys = {agv: list(keys) for agv, keys in self._keys.items()}
        new._rest_keys = dict(self._rest_keys)
        new.paths = dict(self.paths)
        new.sizes = dict(self.sizes)
        return new

    def release(self, agv: int) -> None:
        """Forget the committed path of ``agv`` (if any)."""
        for cell, t in self._keys.pop(agv, ()):
            slot = self._occ.get(cell)
            if slot is not None and slot.get(t) == agv:
                del slot[t]
                if not slot:
                    del self._occ[cell]
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
