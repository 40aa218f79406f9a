"""The in-memory plan: per agent, its cell (and heading) at every timestep.

Conventions (the project's, whatever the file said): cells are ``(row, col)`` with row 0 at
the top; paths are dense per timestep (a wait repeats the cell); headings, where a format has
them, are ``0 = E (+col), 1 = S (+row), 2 = W (-col), 3 = N (-row)``; turning clockwise adds
one (E -> S -> W -> N -> E).
"""

from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["Plan", "Cell", "HEADING_NAMES", "HEADING_STEPS"]

Cell = tuple[int, int]

HEADING_NAMES = ("E", "S", "W", "N")
"""Heading letters by heading number."""

HEADING_STEPS: tuple[Cell, ...] = ((0, 1), (1, 0), (0, -1), (-1, 0))
"""``(drow, dcol)`` of one step forward, by heading number."""


def _trim(path: tuple, headings: tuple | None) -> int:
    """Length of ``path`` without the trailing entries that repeat the last state."""
    n = len(path)
    last = path[-1]
    if headings is None:
        while n > 1 and path[n - 2] == last:
            n -= 1
    else:
        last_h = headings[-1]
        while n > 1 and path[n - 2] == last and headings[n - 2] == last_h:
            n -= 1
    return n


@dataclass(frozen=True)
class Plan:
    """Timed cells (and headings) of every agent, from timestep 0.

    ``paths[i][t]`` is agent ``i``'s cell ``(row, col)`` at timestep ``t``. Each path is as
    long as that agent's own plan; after its last entry the agent stays where it is. The
    constructor drops trailing entries that repeat the last state (cell and heading), so two
    plans that describe the same motion compare equal whatever padding their files had.

    ``headings`` (formats with rotations only) is parallel to ``paths``. ``meta`` (anything
    else the file carried) and ``fmt`` (the format it was read from) are provenance: they are
    not compared, so ``read(write(plan)) == plan`` means "the same motion on the same map".

    >>> p = Plan(paths=(((0, 0), (0, 1), (0, 1)), ((2, 2),)))
    >>> p.paths[0], p.makespan, p.sum_of_costs, p.num_agents
    (((0, 0), (0, 1)), 1, 1, 2)
    """

    paths: tuple[tuple[Cell, ...], ...]
    headings: tuple[tuple[int, ...], ...] | None = None
    rows: int | None = None
    cols: int | None = None
    map_name: str | None = None
    meta: dict = field(default_factory=dict, compare=False)
    fmt: str = field(default="", compare=False)

    def __post_init__(self) -> None:
        paths = []
        for i, path in enumerate(self.paths):
            if type(path) is not tuple or set(map(type, path)) - {tuple}:
                path = tuple(c if type(c) is tuple else tuple(c) for c in path)
            if not path:
                raise ValueError(f"Plan: path of agent {i} is empty")
            paths.append(path)
        heads = None
        if self.headings is not None:
            heads = [tuple(h) for h in self.headings]
            if len(heads) != len(paths):
                raise ValueError(f"Plan: {len(heads)} heading lists for {len(paths)} paths")
            for i, (p, h) in enumerate(zip(paths, heads, strict=True)):
                if len(h) != len(p):
                    raise ValueError(f"Plan: agent {i} has {len(p)} cells but {len(h)} headings")
                if any(type(x) is not int or not 0 <= x <= 3 for x in h):
                    raise ValueError(f"Plan: agent {i} has a heading outside 0..3")
        for i, p in enumerate(paths):
            n = _trim(p, None if heads is None else heads[i])
            if n < len(p):
                paths[i] = p[:n]
                if heads is not None:
                    heads[i] = heads[i][:n]
        object.__setattr__(self, "paths", tuple(paths))
        object.__setattr__(self, "headings", None if heads is None else tuple(heads))

    @property
    def num_agents(self) -> int:
        return len(self.paths)

    @property
    def makespan(self) -> int:
        """Timesteps until the last agent's last action ends (0 for no agents)."""
        return max((len(p) for p in self.paths), default=1) - 1

    @property
    def costs(self) -> tuple[int, ...]:
        """Per agent, the timestep at which it reaches its final cell for good."""
        out = []
        for p in self.paths:
            last, n = p[-1], len(p)
            while n > 1 and p[n - 2] == last:
                n -= 1
            out.append(n - 1)
        return tuple(out)

    @property
    def sum_of_costs(self) -> int:
        """Standard MAPF sum of costs: the sum of :attr:`costs` (turns in place at the end of
        a path do not count, as the agent is already at its goal)."""
        return sum(self.costs)

    def at(self, agent: int, t: int) -> Cell:
        """Cell of ``agent`` at timestep ``t`` (its last cell after its path ends)."""
        path = self.paths[agent]
        return path[min(t, len(path) - 1)]
