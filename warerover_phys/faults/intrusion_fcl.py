"""Corridor intrusions through python-fcl (``faults.checker: fcl``), without its abort.

fcl's *signed distance* runs libccd's GJK/EPA, which aborted the whole process on an AGV
box centred on a corridor rectangle (issue 13, see :mod:`.intrusion`). This checker never
asks for a distance. It keeps

- one ``fcl.Box`` per AGV body (``2 hx x 2 hy`` in plan) in a
  ``DynamicAABBTreeCollisionManager``; before each check the bodies that moved get their
  new translation / rotation (about ``z``) and the tree is refitted;
- one ``fcl.Box`` per corridor rectangle grown on every side by its corridor's margin plus
  a slack (:attr:`FclIntrusionChecker.slack_m`), in a second manager, rebuilt when the open
  corridors change;

and makes one ``collide`` call between the two managers per check. The managers give the
broad phase (AABB tree against AABB tree); for each overlapping pair of bounding boxes the
callback asks fcl's boolean ``collide`` (no contacts), which for two boxes is fcl's
dedicated box-box separating-axis routine (``boxBox2``), never GJK/EPA.

**Naming the pair.** Callbacks get new wrapper objects, and the usual way to name them, the
geometries of the contact (``id(geometry)``), needs ``enable_contact``: with contacts on,
fcl's box-box routine reports *no collision* when it finds no contact point, which happens
for a zero-length or zero-width box standing inside another (found by the fuzz test). So
contacts stay off and every box carries its name in its height: AGV ``i`` stands centred at
``z = i / 2^30``, rectangle ``j`` at ``z = -(1 + j) / 2^30`` (exact in a float, read back
exactly by the wrapper's ``getTranslation()``). All boxes are 1 m tall, so their heights
overlap whatever their names (up to half a million boxes) and never separate a pair
(rotations are about ``z`` only); kept that small, the heights do not steer the AABB trees,
which split along the floor's axes. (Integer heights with boxes tall enough to overlap made
the trees split along ``z``: 100 times slower.)

**fcl proposes, the closed form decides.** The pairs fcl reports are candidates: they are
measured by :func:`~warerover_phys.faults.intrusion.box_rect_signed_distance` (through
:meth:`IntrusionChecker._measure <warerover_phys.faults.intrusion.IntrusionChecker>`),
which keeps those with ``sd < margin_m`` and gives the depth. fcl cannot decide alone:

- the protected zone (points within ``margin_m`` of the rectangle) has rounded corners,
  which a grown box overstates by up to ``(sqrt 2 - 1) margin_m`` at each corner;
- fcl's box-box routine counts touching boxes as colliding, but only as far as its
  rounding lets it see the touch: a box touching an edge at ``x = 2`` collides, one rotated
  by ``pi`` onto the same corner does not (``cos(pi / 2)`` is ``6e-17``, not 0); the closed
  form's rule (strict: ``sd < margin``; with a zero margin, touching is *not* an intrusion)
  cannot be met by fcl alone on touching and degenerate poses.

So the rectangles are grown by the margin plus ``slack_m`` (1 micrometre, or ``1e-10`` of
the scene's coordinates where they are larger than 10 km), far above fcl's rounding,
which makes fcl's pairs a superset of the intruding ones; both checkers then give the same
intrusions and depths, to the bit (tested on degenerate poses in a subprocess, and on whole
fault episodes).
"""

from __future__ import annotations

from collections.abc import Sequence

import fcl
import numpy as np

from .corridors import Corridor
from .intrusion import _REACH_EPS_M, IntrusionChecker

__all__ = ["FclIntrusionChecker"]

HEIGHT_M = 1.0
"""Height of every box (the problem is planar)."""
NAME_Z = 2.0 ** -30
"""Height step that names a box: AGV ``i`` stands at ``z = i NAME_Z``, rectangle ``j`` at
``-(1 + j) NAME_Z``."""
MAX_BOXES = 2 ** 19
"""Most AGVs (and most rectangles) one checker names: their heights stay within
``HEIGHT_M / 2`` of each other."""

SLACK_REL = 1e-10
"""Slack on the grown rectangles relative to the scene's largest coordinate (see
:attr:`FclIntrusionChecker.slack_m`)."""


class FclIntrusionChecker(IntrusionChecker):
    """:class:`~warerover_phys.faults.intrusion.IntrusionChecker` whose candidate pairs
    come from python-fcl (see the module docstring); same constructor, same answers.

    >>> import numpy as np
    >>> from warerover_phys.config import LayoutSpec
    >>> from warerover_phys.layout import build_layout
    >>> from warerover_phys.faults import plan_corridor
    >>> lay = build_layout(LayoutSpec(grid=["#####", "#..S#", "#...A", "#R..#", "#####"]))
    >>> cor = plan_corridor(lay, 0, agv=0, footprint_cells=[11], width_m=1.0, margin_m=0.3)
    >>> chk = FclIntrusionChecker(np.array([[0.4, 0.3], [0.4, 0.3], [0.4, 0.3]]))
    >>> chk.set_corridors([cor])
    >>> poses = np.array([[1.5, 2.5, 0.0], [3.0, 1.5, 0.0], [3.0, 0.5, 0.0]])
    >>> [(i.agv, i.corridor, round(i.depth_m, 9)) for i in chk.check(poses, skip={0})]
    [(1, 0, 0.1)]
    """

    name = "fcl"

    def __init__(self, half_sizes: np.ndarray) -> None:
        super().__init__(half_sizes)
        hs = self.half_sizes
        if self.n > MAX_BOXES:
            raise ValueError(f"the fcl checker names at most {MAX_BOXES} AGVs, got {self.n}")
        self._agv_objs = [
            fcl.CollisionObject(fcl.Box(2 * hx, 2 * hy, HEIGHT_M),
                                fcl.Transform(np.array([0.0, 0.0, i * NAME_Z])))
            for i, (hx, hy) in enumerate(hs.tolist())]
        self._agv_mgr = fcl.DynamicAABBTreeCollisionManager()
        if self._agv_objs:
            self._agv_mgr.registerObjects(self._agv_objs)
            self._agv_mgr.setup()
        self._rect_mgr = fcl.DynamicAABBTreeCollisionManager()
        self._given = np.full((self.n, 3), np.nan)
        """The poses fcl's AGV boxes stand at (NaN: never placed)."""
        self._trans = np.zeros((self.n, 3))
        self._trans[:, 2] = np.arange(self.n) * NAME_Z
        """Each AGV box's translation: ``(x, y, i NAME_Z)``, its name in its height."""
        self._request = fcl.CollisionRequest()
        self.slack_m = _REACH_EPS_M
        """How much farther than the margin the fcl rectangles reach (m): ``1e-6``, or
        ``1e-10`` of the largest coordinate of the rectangles plus the largest body, if
        more."""
        self.fcl_pairs = 0
        """Pairs fcl reported in all, over every check (all measured in closed form)."""

    def set_corridors(self, corridors: Sequence[Corridor]) -> None:
        """Replace the open corridors: their grown rectangles become a new fcl manager."""
        count = sum(len(c.rects) for c in corridors)
        if count > MAX_BOXES:
            raise ValueError(f"the fcl checker names at most {MAX_BOXES} corridor "
                             f"rectangles, got {count}")
        super().set_corridors(corridors)
        r = self._rects
        scale = float(np.abs(r).max(initial=0.0) + self.half_sizes.sum(axis=1).max(initial=0.0))
        self.slack_m = max(_REACH_EPS_M, SLACK_REL * scale)
        grow = self._margins[self._owner] + self.slack_m
        objs = [fcl.CollisionObject(
            fcl.Box(x1 - x0 + 2 * g, y1 - y0 + 2 * g, HEIGHT_M),
            fcl.Transform(np.array([(x0 + x1) / 2, (y0 + y1) / 2, -(1.0 + j) * NAME_Z])))
            for j, ((x0, y0, x1, y1), g) in enumerate(zip(r.tolist(), grow.tolist(),
                                                           strict=True))]
        self._rect_mgr = fcl.DynamicAABBTreeCollisionManager()
        if objs:
            self._rect_mgr.registerObjects(objs)
            self._rect_mgr.setup()

    def _candidates(self, poses: np.ndarray, live: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The ``(agv, rectangle)`` pairs whose fcl boxes collide, live AGVs only."""
        self._place(poses)
        found: list[float] = []
        errors: list[BaseException] = []
        request = self._request

        def on_pair(o1, o2, _data) -> bool:
            # An exception must not cross fcl's C++ frames: keep it and stop.
            try:
                if fcl.collide(o1, o2, request):
                    found.append(o1.getTranslation()[2])
                    found.append(o2.getTranslation()[2])
                return False
            except BaseException as err:  # noqa: BLE001 - re-raised after collide
                errors.append(err)
                return True

        self._agv_mgr.collide(self._rect_mgr, None, on_pair)
        if errors:
            raise errors[0]
        z = np.array(found).reshape(-1, 2) / NAME_Z  # exact: a power of two
        self.fcl_pairs += len(z)
        agv = z.max(axis=1).astype(np.int64)  # AGVs stand at z >= 0, rectangles below
        rect = (-1.0 - z.min(axis=1)).astype(np.int64)
        keep = live[agv]
        return agv[keep], rect[keep]

    def _place(self, poses: np.ndarray) -> None:
        """Move the fcl boxes of the AGVs whose pose changed (finite poses only: a skipped
        AGV's non-finite pose leaves its box where it was) and refit the tree."""
        given = self._given
        with np.errstate(invalid="ignore"):
            moved = np.isfinite(poses).all(axis=1) & (poses != given).any(axis=1)
        idx = np.flatnonzero(moved)
        if not len(idx):
            return
        turned = (poses[idx, 2] != given[idx, 2]).tolist()
        half = poses[idx, 2] / 2
        quat = np.zeros((len(idx), 4))
        quat[:, 0], quat[:, 3] = np.cos(half), np.sin(half)
        trans = self._trans
        trans[idx, :2] = poses[idx, :2]
        objs = self._agv_objs
        for k, i in enumerate(idx.tolist()):
            obj = objs[i]
            obj.setTranslation(trans[i])
            if turned[k]:
                obj.setQuatRotation(quat[k])
        given[idx] = poses[idx]
        self._agv_mgr.update()
