"""How long an AGV type needs for a straight run and a turn: the motion model (issue 15).

Derived from how the physics executor drives a body (:mod:`warerover_phys.executors.control`),
so that a plan timed with it is what that executor needs when nothing gets in the way:

- **Straight runs.** Along a run of collinear moves the executor's reference point runs a
  trapezoid from rest to rest: accelerate at ``max_accel_mps2`` to ``max_speed_mps``,
  cruise, brake at ``max_accel_mps2`` so as to stop exactly on the run's last cell centre
  (the executor evaluates it analytically, whatever ``dt``). A run too short to reach top
  speed is a triangle that peaks at ``sqrt(a d)``. The body tracks the reference exactly
  when nothing blocks it (it is driven kinematically), so it arrives when the reference
  does. A run of ``k`` cells therefore
  takes :meth:`MotionModel.run_s` ``(k)``, less than ``k`` separate moves
  (``k x run_s(1)``). A 2x2 body moves its anchor one cell per move, so its moves are
  runs of ``cell_m`` metres too, at its own limits.
- **Loaded AGVs.** With ``executor.payload`` a loaded AGV's acceleration limit is
  :attr:`~warerover_phys.config.AgvTypeSpec.loaded_accel_mps2`
  (:meth:`MotionModel.of` ``loaded=True``); its top speed and turn rate are unchanged.
- **Turns in place** (differential drive). A reference heading turns at
  ``max_turn_rate_radps`` by the shorter way (a half turn: ``pi``) and the body follows it
  through its gear joint, whose torque allows an angular acceleration of 200 rad/s^2, so the
  rate is reached within one step: there is no angular acceleration phase worth modelling.
  A quarter turn takes ``(pi / 2) / max_turn_rate_radps`` (:meth:`MotionModel.turn_s`).
  Omnidirectional AGVs never turn (``turn_s`` is 0).

This is the differential-drive profile: turn in place, then accelerate along the heading.
With ``executor.no_slip`` (or ``robot: diffdrive``) the physics executor drives exactly it
(:mod:`warerover_phys.executors.diffdrive`: each driving body's reference starts from the
body itself, the velocity stays along the heading), and the wheel limits
(``wheel_base_m``, ``max_wheel_speed_mps``) are validated to allow the top speed straight
and the turn rate in place, so the durations here are those of both drives (measured:
``docs/results/diffdrive.md``).

Times are continuous (seconds). The executor ends turns and runs at their exact times inside
a physics step, but decides for standing AGVs only every 0.1 s (``executors.follow.DECIDE_S``);
the model leaves that out (measured against physics: ``tests/planning/test_motion.py``).

>>> from warerover_phys.config import AgvTypeSpec
>>> m = MotionModel.of(AgvTypeSpec(max_speed_mps=1.5, max_accel_mps2=1.0), cell_m=1.0)
>>> m.run_s(1), m.run_s(3), round(m.turn_s(1), 4)
(2.0, 3.5, 0.6283)
>>> m.ticks(m.run_s(3), tick_s=1.0)
4
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from ..config import AgvTypeSpec

__all__ = ["MotionModel", "quarter_turns"]


def quarter_turns(heading: tuple[int, int] | None, direction: tuple[int, int]) -> int:
    """Quarter turns (0, 1 or 2: the shorter way round) from facing ``heading`` to facing
    ``direction``, both ``(drow, dcol)`` unit steps; ``heading`` None (unknown) counts as
    a quarter turn.

    >>> quarter_turns((0, 1), (0, 1)), quarter_turns((0, 1), (1, 0)), quarter_turns((0, 1), (0, -1))
    (0, 1, 2)
    """
    if heading is None:
        return 1
    if heading == direction:
        return 0
    if heading == (-direction[0], -direction[1]):
        return 2
    return 1


@dataclass(frozen=True)
class MotionModel:
    """Durations of one AGV type's runs and turns (see the module docstring).

    ``max_speed_mps`` (m/s), ``max_accel_mps2`` (m/s^2, the limit in force: loaded or not),
    ``max_turn_rate_radps`` (rad/s), ``omni`` (omnidirectional drive: no turns),
    ``cell_m`` (metres per cell), ``footprint`` (cells per side; informational: a k x k
    body's move is one cell of its anchor, a run of ``cell_m``).
    """

    max_speed_mps: float
    max_accel_mps2: float
    max_turn_rate_radps: float
    omni: bool = False
    cell_m: float = 1.0
    footprint: int = 1

    def __post_init__(self) -> None:
        for name in ("max_speed_mps", "max_accel_mps2", "max_turn_rate_radps", "cell_m"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"MotionModel.{name} must be a positive number, got {v!r}")

    @classmethod
    def of(cls, spec: AgvTypeSpec, cell_m: float, *, loaded: bool = False,
           payload: bool = False, speed_scale: float = 1.0) -> MotionModel:
        """The model of AGV type ``spec`` on cells of ``cell_m`` metres. ``loaded`` with
        ``payload`` (``executor.payload``): the loaded acceleration limit. ``speed_scale``:
        the executor's speed factor of one AGV (``executor.speed_scale``)."""
        accel = spec.loaded_accel_mps2 if (loaded and payload) else spec.max_accel_mps2
        return cls(max_speed_mps=spec.max_speed_mps * speed_scale, max_accel_mps2=accel,
                   max_turn_rate_radps=spec.max_turn_rate_radps, omni=spec.drive == "omni",
                   cell_m=cell_m, footprint=spec.footprint)

    # ----------------------------------------------------------------- straight runs

    def _peak(self, d_m: float) -> float:
        """Peak speed (m/s) of a rest-to-rest run of ``d_m`` metres."""
        return min(self.max_speed_mps, math.sqrt(self.max_accel_mps2 * d_m))

    def distance_s(self, d_m: float) -> float:
        """Seconds of a straight run of ``d_m`` metres from rest to rest (trapezoid, or a
        triangle when it is too short to reach top speed)."""
        if d_m <= 0:
            return 0.0
        v, a = self.max_speed_mps, self.max_accel_mps2
        if d_m >= v * v / a:
            return d_m / v + v / a
        return 2.0 * math.sqrt(d_m / a)

    def at_s(self, x_m: float, d_m: float) -> float:
        """Seconds from the start of a rest-to-rest run of ``d_m`` metres until the body
        has covered ``x_m`` of them (``0 <= x_m <= d_m``)."""
        if x_m <= 0 or d_m <= 0:
            return 0.0
        x_m = min(x_m, d_m)
        a = self.max_accel_mps2
        vp = self._peak(d_m)
        x_acc = vp * vp / (2 * a)
        if x_m <= x_acc:
            return math.sqrt(2 * x_m / a)
        total = self.distance_s(d_m)
        if x_m <= d_m - x_acc:
            return vp / a + (x_m - x_acc) / vp
        return total - math.sqrt(max(0.0, 2 * (d_m - x_m) / a))

    def run_s(self, k: int) -> float:
        """Seconds of a straight run of ``k`` cells from rest to rest (``k`` collinear moves
        driven as one)."""
        return self.distance_s(k * self.cell_m)

    def reach_s(self, j: int, k: int) -> float:
        """Seconds from the start of a ``k``-cell run from rest to rest until the body is on
        the centre of its ``j``-th cell (the end of the run's ``j``-th move, ``0 <= j <= k``)."""
        return self.at_s(j * self.cell_m, k * self.cell_m)

    def state_at(self, t_s: float, d_m: float) -> tuple[float, float]:
        """Distance covered (m) and speed (m/s) ``t_s`` seconds into a rest-to-rest run of
        ``d_m`` metres (at rest on its end after :meth:`distance_s`)."""
        if d_m <= 0 or t_s <= 0:
            return 0.0, 0.0
        total = self.distance_s(d_m)
        if t_s >= total:
            return d_m, 0.0
        a = self.max_accel_mps2
        vp = self._peak(d_m)
        t_acc = vp / a
        if t_s <= t_acc:
            return 0.5 * a * t_s * t_s, a * t_s
        if t_s <= total - t_acc:
            return vp * vp / (2 * a) + vp * (t_s - t_acc), vp
        left = total - t_s
        return d_m - 0.5 * a * left * left, a * left

    def pass_s(self, k: int) -> float:
        """Seconds to cross ``k`` cells at top speed, without stopping: the middle of a long
        run (a lower bound of any ``k`` moves)."""
        return k * self.cell_m / self.max_speed_mps

    # ----------------------------------------------------------------- turns

    def turn_s(self, quarters: int) -> float:
        """Seconds of a turn in place by ``quarters`` quarter turns (taken the shorter way
        round: 3 is 1); 0 for omnidirectional AGVs."""
        q = quarters % 4
        q = 4 - q if q > 2 else q
        if self.omni or q == 0:
            return 0.0
        return q * (math.pi / 2) / self.max_turn_rate_radps

    # ----------------------------------------------------------------- ticks

    @staticmethod
    def ticks(seconds: float, tick_s: float) -> int:
        """Whole ticks of ``tick_s`` seconds that ``seconds`` take (rounded up; a tiny
        tolerance keeps exact multiples exact; at least 1 for any positive time)."""
        if seconds <= 0:
            return 0
        return max(1, math.ceil(seconds / tick_s - 1e-9))
