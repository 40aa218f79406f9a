"""The corridor bookkeeping kept on the world: exit grants and intrusion totals.

Only data and its own updates; the checks that fill it are in :mod:`.intrusion_log`. Kept
apart so that ``world`` can hold a book without importing the checks (which read the world).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Protocol

__all__ = ["CorridorBook", "EventLog", "Grant"]


class EventLog(Protocol):
    """What the book needs of the world: its event log."""

    def log(self, event: str, **fields: Any) -> None: ...


@dataclass
class Grant:
    """The exit allowed to AGV ``agv`` caught by corridor ``corridor`` when it opened."""

    agv: int
    corridor: int
    open_s: float
    bound_s: float
    reason: str
    """``inside`` (in the zone when it opened), ``cannot_stop`` (its move in progress, or
    its braking distance, takes it in) or ``repaired_inside`` (down in the zone when it
    opened, caught when repaired there: ``open_s`` is then the repair time)."""
    seen_inside: bool = False
    """A check has found it inside (an AGV caught while still outside has not "left"
    before it has been in)."""
    exit_s: float | None = None
    """Seconds from the opening to the first check that found it out after it had been
    inside (None: not yet)."""
    overran: bool = False
    """Still inside at its deadline."""
    closed: bool = False
    """The corridor closed (or the episode ended) before it left and before its deadline."""

    @property
    def deadline_s(self) -> float:
        return self.open_s + self.bound_s

    @property
    def settled(self) -> bool:
        return self.exit_s is not None or self.overran or self.closed


@dataclass
class CorridorBook:
    """Intrusion figures and exit grants of an episode (kept on the world, written only by
    the loop through :func:`record_check`, :meth:`catch` and :meth:`closed`)."""

    grants: dict[tuple[int, int], Grant] = field(default_factory=dict)
    """(agv, corridor id) -> its exit grant, in the order they were given."""
    intrusions: int = 0
    intrusion_s: float = 0.0
    inside_s: float = 0.0
    _visits: dict[tuple[int, int], float] = field(default_factory=dict, repr=False)
    """Intrusions in progress: (agv, corridor id) -> largest depth so far."""

    def catch(self, agv: int, corridor: int, open_s: float, bound_s: float,
              reason: str) -> Grant:
        """AGV ``agv`` is caught by ``corridor`` opening at ``open_s``: it may take
        ``bound_s`` seconds to leave."""
        g = Grant(agv, corridor, float(open_s), float(bound_s), reason,
                  seen_inside=reason in ("inside", "repaired_inside"))
        self.grants[(agv, corridor)] = g
        return g

    def closed(self, world: EventLog, corridor: int) -> None:
        """Corridor ``corridor`` closed: caught AGVs still inside before their deadline
        are settled as exits within the bound."""
        for g in self.grants.values():
            if g.corridor == corridor and not g.settled:
                g.closed = True
                world.log("corridor_exit", agv=g.agv, corridor=corridor, exit_s=None,
                          bound_s=round(g.bound_s, 3), within=True, closed=True)
        for key in [k for k in self._visits if k[1] == corridor]:
            del self._visits[key]

    def summary(self) -> dict[str, Any]:
        """Figures for ``metrics.json`` (see :mod:`warerover_phys.metrics`)."""
        grants = list(self.grants.values())
        exits = [g.exit_s for g in grants if g.exit_s is not None]
        return {
            "corridor_intrusions": self.intrusions,
            "corridor_intrusion_agv_s": round(self.intrusion_s, 6),
            "corridor_inside_agv_s": round(self.inside_s, 6),
            "corridor_caught_inside": len(grants),
            "corridor_exits_within_bound": sum(1 for g in grants if not g.overran),
            "corridor_exits_overrun": sum(1 for g in grants if g.overran),
            "corridor_exit_max_s": round(max(exits), 6) if exits else None,
        }
