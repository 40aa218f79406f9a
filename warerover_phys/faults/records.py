"""Corridor records for ``trajectories.npz``: enough for an outside checker to recompute
the intrusion figures from the exported poses alone.

Arrays (``C`` corridors of the episode in the order they opened, ``R`` rectangles, ``G``
exit grants):

- ``corridor_id``, ``corridor_agv`` (C,) int64: the corridor's id and the AGV whose failure
  opened it;
- ``corridor_open_s``, ``corridor_close_s`` (C,) float64: simulated seconds
  (``tick x tick_s``) it opened and closed; NaN: still open when the episode ended. It is
  open for samples with ``open_s <= t < close_s``;
- ``corridor_margin_m`` (C,) float64: its safety margin;
- ``corridor_rects`` (R, 4) float64 ``(xmin, ymin, xmax, ymax)`` metres, and
  ``corridor_rect_of`` (R,) int64, the row (in the ``corridor_*`` (C,) arrays) each
  rectangle belongs to: the person's space is the union of a corridor's rectangles. An
  AGV is inside when its body (``x``, ``y``, ``heading``, ``body_m``) is closer than the
  margin to that union (Euclidean distance, 0 if they overlap);
- ``corridor_caught_agv``, ``corridor_caught_corridor`` (G,) int64: AGVs caught inside (or
  unable to stop before) a corridor as it opened, or repaired inside it later, and that
  corridor's id; ``corridor_caught_s`` (G,) float64: simulated seconds it was caught (the
  opening, or the repair); ``corridor_caught_bound_s`` (G,) float64: the time each may take
  to leave; ``corridor_caught_exit_s`` (G,) float64: seconds from being caught to the first
  check that found it out (NaN: it did not leave while the corridor was open);
  ``corridor_caught_overran`` (G,) bool: still inside at ``caught_s + bound_s``.

Recomputing ``corridor_inside_agv_s``: over the samples while a corridor is open, sum
``1 / trajectory_hz`` for every AGV inside, leaving out the corridor's own AGV and AGVs
that are down (``state == 7``). ``corridor_intrusion_agv_s`` is the same sum less, for each
caught AGV, its samples from when it was caught until it first leaves or its deadline,
whichever comes first. The executor checks every physics step and the recording samples at
``trajectory_hz``, so the two agree to within a sample period per entry or exit.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from ..world import World

__all__ = ["corridor_arrays"]


def corridor_arrays(world: World) -> dict[str, np.ndarray]:
    """The corridor arrays of ``world``'s episode so far (see the module docstring)."""
    tick_s = float(world.scenario.tick_s)
    log = world.corridor_log
    rects, rect_of = [], []
    for i, e in enumerate(log):
        for r in e.get("rects", ()):
            rects.append(r)
            rect_of.append(i)
    grants = list(world.corridor_book.grants.values())
    return {
        "corridor_id": np.array([e["id"] for e in log], dtype=np.int64),
        "corridor_agv": np.array([e["agv"] for e in log], dtype=np.int64),
        "corridor_open_s": np.array([e["open_tick"] * tick_s for e in log], dtype=np.float64),
        "corridor_close_s": np.array([np.nan if e["close_tick"] is None
                                      else e["close_tick"] * tick_s for e in log],
                                     dtype=np.float64),
        "corridor_margin_m": np.array([e.get("margin_m", np.nan) for e in log],
                                      dtype=np.float64),
        "corridor_rects": np.array(rects, dtype=np.float64).reshape(-1, 4),
        "corridor_rect_of": np.array(rect_of, dtype=np.int64),
        "corridor_caught_agv": np.array([g.agv for g in grants], dtype=np.int64),
        "corridor_caught_corridor": np.array([g.corridor for g in grants], dtype=np.int64),
        "corridor_caught_s": np.array([g.open_s for g in grants], dtype=np.float64),
        "corridor_caught_bound_s": np.array([g.bound_s for g in grants], dtype=np.float64),
        "corridor_caught_exit_s": np.array([np.nan if g.exit_s is None else g.exit_s
                                            for g in grants], dtype=np.float64),
        "corridor_caught_overran": np.array([g.overran for g in grants], dtype=bool),
    }
