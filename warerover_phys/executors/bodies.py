"""The pymunk world of a layout: static shapes, AGV bodies and their control bodies.

Kept apart from the executor's logic so the physical set-up reads in one place:

- obstacles (and the map border) are solid static boxes; shelves are *sensors*: unloaded
  AGVs drive under them, and a loaded AGV touching a shelf other than its own is counted as
  a static contact;
- each AGV is a dynamic box of its real size and mass, driven by a kinematic control body
  through a :class:`pymunk.PivotJoint` (``max_bias = 0``, ``max_force`` = mass x max
  acceleration x :data:`FORCE_HEADROOM`) and a :class:`pymunk.GearJoint` (the SMART / ARGoS
  pattern); contacts with obstacles stay physical;
- AGV bodies are never pushed by each other (:func:`unsolved_agv_contacts`): an AGV-AGV
  contact is detected but not solved, and reported as a fault (the executor brakes both).
  A pushed body would leave its speed and acceleration limits (4x and 200x were measured
  with 0.8 m bodies turning next to each other); a body that passes through another keeps
  its limits, and the contact is counted and reported, not hidden;
- with ``executor.shelf_contacts`` a loaded AGV's body also carries the shape of its shelf
  (:meth:`PhysicalFleet.carry_shelves`), kept parallel to the grid while the body turns
  under it (:meth:`PhysicalFleet.orient_shelves`); its contacts are the AGV's;
- :class:`BodyIO` moves poses and velocities in and out through pymunk's batch API (one call
  per step for the whole fleet instead of a Python loop; the module is experimental, so it is
  wrapped here and nowhere else).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pymunk
import pymunk.batch as batch

from ..layout import CellType, Layout
from .step_kernels import body_rows, gather_bodies, obstacle_reach, scatter_commands

__all__ = ["AGV", "OBSTACLE", "SHELF", "FORCE_HEADROOM", "SHELF_SIDE", "BodyIO",
           "ObstacleReach", "PhysicalFleet", "build_space", "unsolved_agv_contacts"]

_IDENTITY = pymunk.Transform.identity()
AGV, OBSTACLE, SHELF = 1, 2, 3
"""Collision types."""
FORCE_HEADROOM = 2.0
"""Pivot force = mass x max acceleration x this: the commanded profile obeys the limit; the
headroom lets the joint correct small errors and push back on contacts."""
SHELF_ANGLE_EPS_RAD = 1e-3
"""A carried shelf's shape is turned back parallel to the grid once its body has turned this
much (``executor.shelf_contacts``)."""
SHELF_SIDE = 0.9
"""A shelf of size ``k`` is a square ``SHELF_SIDE x k x cell_m`` on a side (its sensor box
here, and its footprint while carried in the clearance figures)."""


def cell_centre(node: int, k: int, cols: int, cell_m: float) -> tuple[float, float]:
    """World centre (metres) of a ``k x k`` footprint anchored at flat cell ``node``."""
    r, c = divmod(node, cols)
    return ((c + k / 2) * cell_m, (r + k / 2) * cell_m)


def build_space(layout: Layout) -> tuple[pymunk.Space, dict[int, int]]:
    """A space holding the layout's static shapes; returns it and ``shape id -> shelf id``
    for the shelf sensors."""
    space = pymunk.Space()
    space.gravity = (0.0, 0.0)
    space.iterations = 10
    # pymunk's default bounding-box tree, not its spatial hash: parked AGVs leave the space
    # (PhysicalFleet.park), so late in a run few bodies move among many static shapes,
    # where the tree is cheaper (1,000 AGVs on warehouse-10-20-10-2-1, dt 0.05: 16.0 ->
    # 12.5 s of pymunk steps over the run; the hash had paid at N >= 1,000 when every body
    # stayed dynamic).
    m = layout.cell_m
    rows, cols = layout.rows, layout.cols
    static = space.static_body
    shapes: list[pymunk.Shape] = []
    obstacle = layout.obstacles
    # One box per horizontal run of obstacle cells keeps big maps cheap.
    for r in range(rows):
        c = 0
        while c < cols:
            if not obstacle[r, c]:
                c += 1
                continue
            c0 = c
            while c < cols and obstacle[r, c]:
                c += 1
            shapes.append(_box(static, ((c0 + c) / 2 * m, (r + 0.5) * m), ((c - c0) * m, m)))
    w, h = cols * m, rows * m
    r = 0.05  # the border walls lie just outside the map
    for a, b in (((-r, -r), (w + r, -r)), ((w + r, -r), (w + r, h + r)),
                 ((w + r, h + r), (-r, h + r)), ((-r, h + r), (-r, -r))):
        shapes.append(pymunk.Segment(static, a, b, r))
    for s in shapes:
        s.collision_type = OBSTACLE
        s.friction = 0.0
    shelf_of: dict[int, int] = {}
    for shelf in layout.shelves:
        r, c = shelf.anchor
        k = shelf.size
        box = _box(static, ((c + k / 2) * m, (r + k / 2) * m),
                   (k * m * SHELF_SIDE, k * m * SHELF_SIDE))
        box.sensor = True
        box.collision_type = SHELF
        shelf_of[id(box)] = shelf.id
        shapes.append(box)
    assert all(layout.grid[r, c] != CellType.OBSTACLE for s in layout.shelves
               for r, c in [s.anchor])
    space.add(*shapes)
    return space, shelf_of


def unsolved_agv_contacts(space: pymunk.Space, agv_of_shape: dict[int, int],
                          on_contact, begin=None) -> None:
    """Never solve AGV-AGV contacts (no impulse, so no body is pushed); call
    ``on_contact(a, b, (x, y))`` (AGV ids, a contact point in metres) when two AGVs start
    to touch. Installed as the AGV-AGV handler's ``pre_solve``, with ``begin`` (the contact
    counting of :mod:`.accounting`) as its ``begin``: a handler for that pair alone, so
    pymunk calls no Python for the other pairs (an unloaded AGV under a shelf sensor, every
    step it stays there: a wildcard handler cost ~29 Python calls a step at 1,000 AGVs)."""

    def pre_solve(arbiter, space, data) -> None:
        a, b = arbiter.shapes
        arbiter.process_collision = False
        if arbiter.is_first_contact:
            points = arbiter.contact_point_set.points
            p = points[0].point_a if points else a.body.position
            on_contact(agv_of_shape[id(a)], agv_of_shape[id(b)], (float(p[0]), float(p[1])))

    space.on_collision(AGV, AGV, begin=begin, pre_solve=pre_solve)


def _grid_square(h: float, angle: float) -> list[tuple[float, float]]:
    """Body-frame vertices of a square of half side ``h`` whose sides are along the world
    axes while the body is turned by ``angle``."""
    c, s = np.cos(angle), np.sin(angle)
    return [(float(c * x + s * y), float(-s * x + c * y))
            for x, y in ((-h, -h), (h, -h), (h, h), (-h, h))]


def _box(body: pymunk.Body, centre: tuple[float, float], size: tuple[float, float]) -> pymunk.Poly:
    cx, cy = centre
    hw, hh = size[0] / 2, size[1] / 2
    return pymunk.Poly(body, [(cx - hw, cy - hh), (cx + hw, cy - hh), (cx + hw, cy + hh),
                              (cx - hw, cy + hh)])


@dataclass
class PhysicalFleet:
    """The AGV bodies (index = AGV id) and what the controller needs about each."""

    bodies: list[pymunk.Body]
    ctrl: list[pymunk.Body]
    shapes: list[pymunk.Poly]
    half_size: np.ndarray
    """(N, 2) half length / width in metres."""
    agv_of_shape: dict[int, int] = field(default_factory=dict)
    """``id(shape)`` -> AGV id, for every AGV shape (bodies, and carried shelves with
    ``executor.shelf_contacts``)."""
    shelf_shapes: dict[int, pymunk.Poly] = field(default_factory=dict)
    """AGV id -> the shape of the shelf it carries (in the space while carried)."""
    shelf_side: np.ndarray | None = None
    """(N,) side (metres) of the shelf shape each AGV carries now (0: none)."""
    shelf_ang: np.ndarray | None = None
    """(N,) body angle for which each carried shelf's vertices were last set."""
    joints: list[tuple[pymunk.PivotJoint, pymunk.GearJoint]] = field(default_factory=list)
    """Each AGV's drive joints (pivot, gear) to its control body."""
    parked: np.ndarray | None = None
    """(N,) AGVs standing still with their drive joints out of the space (:meth:`park`;
    :attr:`static` says which of them are static bodies)."""
    static: np.ndarray | None = None
    """(N,) parked AGVs whose bodies are out of the space, static stand-ins of their
    shapes in their place (:meth:`park`)."""
    mass: np.ndarray | None = None
    """(N,) each body's mass (kg)."""
    moment: np.ndarray | None = None
    """(N,) each body's moment of inertia."""
    stand_ins: dict[int, list[pymunk.Poly]] = field(default_factory=dict)
    """AGV id -> the static shapes standing in for its shapes while it is out of the
    space (:meth:`park`)."""
    n_parked: int = 0
    """How many AGVs are parked."""
    jointed: np.ndarray | None = None
    """(N,) AGVs whose drive joints are in the space (:meth:`set_joints`)."""
    _twins: dict[int, pymunk.Poly] = field(default_factory=dict)
    """id of a shape -> its stand-in, kept for the next time it leaves the space."""

    @classmethod
    def add_to(cls, space: pymunk.Space, poses: list[tuple[float, float, float]],
               sizes: list[tuple[float, float]], masses: list[float],
               accels: list[float]) -> PhysicalFleet:
        bodies, ctrls, shapes, joints, moments = [], [], [], [], []
        for (x, y, heading), (length, width), mass, accel in zip(poses, sizes, masses, accels,
                                                                strict=True):
            moment = pymunk.moment_for_box(mass, (length, width))
            body = pymunk.Body(mass, moment)
            body.position = (x, y)
            body.angle = heading
            shape = pymunk.Poly.create_box(body, (length, width))
            shape.collision_type = AGV
            shape.friction = 0.0
            shape.elasticity = 0.0
            ctrl = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
            ctrl.position = (x, y)
            ctrl.angle = heading
            pivot = pymunk.PivotJoint(ctrl, body, (0, 0), (0, 0))
            pivot.max_bias = 0.0
            pivot.max_force = mass * accel * FORCE_HEADROOM
            gear = pymunk.GearJoint(ctrl, body, 0.0, 1.0)
            gear.max_bias = 0.0
            gear.max_force = moment * 200.0
            space.add(body, shape, ctrl, pivot, gear)
            bodies.append(body)
            ctrls.append(ctrl)
            shapes.append(shape)
            joints.append((pivot, gear))
            moments.append(moment)
        half = np.array(sizes, dtype=float) / 2
        return cls(bodies, ctrls, shapes, half, {id(s): i for i, s in enumerate(shapes)},
                   joints=joints, parked=np.zeros(len(bodies), dtype=bool),
                   jointed=np.ones(len(bodies), dtype=bool),
                   static=np.zeros(len(bodies), dtype=bool),
                   mass=np.array(masses, dtype=float), moment=np.array(moments, dtype=float))

    def park(self, space: pymunk.Space, i: int, x: float, y: float, angle: float,
             static: bool) -> None:
        """AGV ``i`` stands still on its hold point: take its drive joints out of the space
        and zero its velocity. Nothing then moves it but the control law's commands (AGV-AGV
        contacts are not solved, and it rests clear of obstacles), and the solver no longer
        iterates over its joints: at 1,000 AGVs most of pymunk's step is those joints.

        ``static``: also put it exactly on its hold point ``(x, y)`` facing ``angle`` (it
        is within :data:`~.physics.PARK_EPS_M` of it: the deadbeat command of the next
        step would take it there) and take its body, its
        shapes and its control body out of the space, leaving in their place static
        stand-in shapes with the same vertices and collision types (:attr:`stand_ins`), so
        that pymunk neither integrates it nor re-indexes its shapes each step, and the batch
        reads and writes (:class:`BodyIO`) no longer visit it. A moving AGV that touches it
        still meets it (static-dynamic pairs are collided; the stand-ins are in
        :attr:`agv_of_shape`). Call :meth:`BodyIO.reorder` after a batch of such parks and
        unparks.

        Call it after the step's velocities were written, before the step."""
        body = self.bodies[i]
        if self.jointed[i]:
            space.remove(*self.joints[i])
            self.jointed[i] = False
        body.velocity = (0.0, 0.0)
        body.angular_velocity = 0.0
        self.parked[i] = True
        self.n_parked += 1
        if static:
            self.leave(space, i, x, y, angle)

    def leave(self, space: pymunk.Space, i: int, x: float, y: float, angle: float) -> None:
        """Parked AGV ``i`` (in the space) leaves it: see :meth:`park` with ``static``."""
        body = self.bodies[i]
        body.position = (x, y)
        body.angle = angle
        self._leave_space(space, i)

    def _leave_space(self, space: pymunk.Space, i: int) -> None:
        """Take parked AGV ``i``'s body, shapes and control body out of the space; static
        stand-ins of its shapes take their place."""
        body = self.bodies[i]
        stand = []
        shapes = self._shapes_in_space(i)
        for s in shapes:
            verts = [body.local_to_world(v) for v in s.get_vertices()]
            twin = self._twins.get(id(s))
            if twin is None or twin.radius != s.radius:
                twin = pymunk.Poly(space.static_body, verts, radius=s.radius)
                self._twins[id(s)] = twin
            else:  # as a new Poly would be: the convex hull of verts (out of the space)
                twin.unsafe_set_vertices(verts, _IDENTITY)
            twin.collision_type = s.collision_type
            twin.friction = s.friction
            twin.elasticity = s.elasticity
            twin.sensor = s.sensor
            self.agv_of_shape[id(twin)] = i
            stand.append(twin)
        space.remove(body, *shapes, self.ctrl[i])
        space.add(*stand)
        self.stand_ins[i] = stand
        self.static[i] = True

    def _enter_space(self, space: pymunk.Space, i: int) -> None:
        """Undo :meth:`_leave_space`."""
        stand = self.stand_ins.pop(i)
        space.remove(*stand)
        for twin in stand:
            self.agv_of_shape.pop(id(twin), None)
        space.add(self.bodies[i], *self._shapes_in_space(i), self.ctrl[i])
        self.static[i] = False

    def _shapes_in_space(self, i: int) -> list[pymunk.Poly]:
        """AGV ``i``'s shapes that belong in the space: its body's, and its carried
        shelf's (a body keeps the shapes of shelves put down, out of the space)."""
        shelf = self.shelf_shapes.get(i)
        return [self.shapes[i]] if shelf is None else [self.shapes[i], shelf]

    def unpark(self, space: pymunk.Space, i: int, velocity: tuple[float, float],
               angular: float) -> bool:
        """AGV ``i`` is about to move: it and its control body get this step's command
        ``velocity`` / ``angular`` (a static one first goes back into the space); its drive
        joints come back with the next :meth:`set_joints` that finds it near an obstacle.
        The joints correct velocities only (``max_bias = 0``), so where its control body was
        meanwhile does not matter. Returns whether it was static (then call
        :meth:`BodyIO.reorder`)."""
        was_static = bool(self.static[i])
        if was_static:
            self._enter_space(space, i)
        for body in (self.bodies[i], self.ctrl[i]):
            body.velocity = velocity
            body.angular_velocity = angular
        self.parked[i] = False
        self.n_parked -= 1
        return was_static

    def set_joints(self, space: pymunk.Space, want: np.ndarray) -> None:
        """Put the drive joints of AGVs ``want`` ((N,) bool) into the space and take every
        other AGV's out.

        A body's joints act only on a body that something else pushed within the step: the
        control law gives a body and its control body the same velocity (kinematic drive),
        so a joint's velocity error is exactly zero and so is its impulse, unless a solved
        contact changed the body's velocity in the step. AGV-AGV contacts are not solved
        (:func:`unsolved_agv_contacts`) and shelves are sensors, so only a contact with an
        obstacle needs them: the executor keeps the joints of bodies that could reach one
        within the step (:class:`ObstacleReach`) and of no other, which gives the same
        velocities as keeping all joints (checked bit for bit by
        ``tools/physics_snapshot.py``), without the solver's iterations over the joints
        of bodies out in the aisles."""
        for i in np.flatnonzero(want != self.jointed):
            i = int(i)
            if want[i]:
                space.add(*self.joints[i])
            else:
                space.remove(*self.joints[i])
        self.jointed[:] = want

    def carry_shelves(self, space: pymunk.Space, side: np.ndarray, ang: np.ndarray) -> bool:
        """``executor.shelf_contacts``: give each AGV the collision shape of the shelf it
        carries, a square ``side[i]`` metres on a side (0: none) centred on its body with
        sides along the grid; shapes of shelves put down leave the space. The shape is an
        :data:`AGV` shape of the AGV's body, so its contacts count as the AGV's. A parked AGV
        out of the space whose shelf changes goes back in (parked, without its joints);
        returns whether any did (then call :meth:`BodyIO.reorder`)."""
        n = len(self.bodies)
        if self.shelf_side is None:
            self.shelf_side = np.zeros(n)
            self.shelf_ang = np.zeros(n)
        back = False
        for i in np.flatnonzero(side != self.shelf_side):
            i = int(i)
            if self.static[i]:  # out of the space: back in, parked (no joints)
                self._enter_space(space, i)
                back = True
            old = self.shelf_shapes.pop(i, None)
            if old is not None:
                space.remove(old)
                self.agv_of_shape.pop(id(old), None)
            self.shelf_side[i] = side[i]
            if side[i] > 0:
                shape = pymunk.Poly(self.bodies[i], _grid_square(side[i] / 2, float(ang[i])))
                shape.collision_type = AGV
                shape.friction = 0.0
                shape.elasticity = 0.0
                space.add(shape)
                self.shelf_shapes[i] = shape
                self.agv_of_shape[id(shape)] = i
                self.shelf_ang[i] = ang[i]
        return back

    def orient_shelves(self, ang: np.ndarray) -> None:
        """Keep carried shelves parallel to the grid while their bodies (at angles ``ang``)
        turn under them: reset the vertices of those whose body turned by more than
        :data:`SHELF_ANGLE_EPS_RAD` since."""
        if not self.shelf_shapes:
            return
        turned = np.abs((ang - self.shelf_ang + np.pi) % (2 * np.pi) - np.pi) > SHELF_ANGLE_EPS_RAD
        for i in np.flatnonzero(turned & (self.shelf_side > 0)):
            i = int(i)
            self.shelf_shapes[i].unsafe_set_vertices(
                _grid_square(self.shelf_side[i] / 2, float(ang[i])))
            self.shelf_ang[i] = ang[i]

    def set_mass(self, i: int, mass: float) -> None:
        """Give AGV ``i``'s body a new mass (kg; a shelf picked up or put down), its moment
        of inertia scaled with it. The drive force (the pivot's ``max_force``) stays. A
        parked body out of the space moves with it when it is back."""
        self.moment[i] = self.moment[i] * mass / self.mass[i]
        self.mass[i] = mass
        body = self.bodies[i]
        body.moment = float(self.moment[i])
        body.mass = mass


class ObstacleReach:
    """Which bodies could touch an obstacle (or the map's border) within a physics step:
    those whose axis-aligned box, grown by ``margin`` metres, overlaps an obstacle cell.
    One summed-area table of the obstacle grid (cells off the map count as obstacles)
    answers each box with four look-ups, for the whole fleet at once."""

    def __init__(self, layout: Layout) -> None:
        rows, cols = layout.rows, layout.cols
        grid = np.ones((rows + 2, cols + 2), dtype=np.int64)
        grid[1:-1, 1:-1] = layout.obstacles
        self._sat = np.zeros((rows + 3, cols + 3), dtype=np.int64)
        self._sat[1:, 1:] = grid.cumsum(0).cumsum(1)
        self._rows, self._cols, self._m = rows, cols, layout.cell_m

    def near(self, pos: np.ndarray, half: np.ndarray) -> np.ndarray:
        """(P,) bool: whether the boxes centred at ``pos`` (P, 2) with half extents ``half``
        (P, 2) (metres) overlap an obstacle cell or leave the map."""
        p = len(pos)
        return self.fleet_near(np.asarray(pos, dtype=float), np.zeros(p),
                               np.asarray(half, dtype=float), np.zeros((p, 2)),
                               np.zeros(p), np.zeros(p, dtype=bool))

    def fleet_near(self, pos: np.ndarray, ang: np.ndarray, half: np.ndarray,
                   shelf_half: np.ndarray, margin: np.ndarray,
                   skip: np.ndarray) -> np.ndarray:
        """(N,) bool, per AGV: whether its body (half sizes ``half``, turned by ``ang``) or
        its carried shelf (half sizes ``shelf_half``, along the grid), whichever box is
        wider, grown by ``margin``, :meth:`near` an obstacle; rows ``skip`` are False."""
        return obstacle_reach(pos, ang, half, shelf_half, margin, skip, self._sat,
                              float(self._m), self._rows, self._cols,
                              np.zeros(len(pos), dtype=np.bool_))


class BodyIO:
    """Read every AGV's pose and velocity, and set every control body's velocity, in one
    batch call each. AGVs out of the space (parked, :meth:`PhysicalFleet.park`) read as
    they stood when they left it (standing still) and take no commands.

    pymunk's batch functions (:func:`pymunk.batch.get_space_bodies` /
    ``set_space_bodies``) build their C arguments anew on every call; at one read and one
    write per physics step that cost more than the copies themselves, so the arguments are
    built once here and chipmunk's body iterator is called directly (the functions' own
    code, with the arguments kept). Rows go to and from the per-AGV arrays in one compiled
    loop each (:func:`.step_kernels.gather_bodies`, :func:`.step_kernels.scatter_commands`).
    """

    _GET = (batch.BodyFields.POSITION | batch.BodyFields.ANGLE
            | batch.BodyFields.VELOCITY | batch.BodyFields.ANGULAR_VELOCITY)
    """Read per step; the body ids (which row is which body) are read again only when
    bodies leave or enter the space or change type (:meth:`reorder`)."""
    _SET = batch.BodyFields.VELOCITY | batch.BodyFields.ANGULAR_VELOCITY

    def __init__(self, space: pymunk.Space, fleet: PhysicalFleet) -> None:
        from pymunk._chipmunk import ffi, lib

        self.space = space
        self.fleet = fleet
        n = len(fleet.bodies)
        self.buf = batch.Buffer()
        self.set_buf = batch.Buffer()
        self._ffi = ffi
        self._each = lib.cpSpaceEachBody
        self._get_fn = ffi.addressof(lib, "pmSpaceBodyGetIteratorFuncBatched")
        self._set_fn = ffi.addressof(lib, "pmSpaceBodySetIteratorFuncBatched")
        self._get_data = self._batched(self._GET, self.buf)
        self._set_data = self._batched(self._SET, self.set_buf)
        self._id_data = self._batched(batch.BodyFields.BODY_ID, self.buf)
        self._body_ids = np.array([b.id for b in fleet.bodies], dtype=np.uintp)
        self._ctrl_ids = np.array([b.id for b in fleet.ctrl], dtype=np.uintp)
        self._still = np.zeros((n, 6))
        """Per AGV: x, y, angle, vx, vy, w as read; rows of AGVs out of the space are
        their standing poses."""
        self._out = np.zeros(n, dtype=bool)
        """AGVs out of the space at the last :meth:`reorder`."""
        self._rows = np.full(n, -1, dtype=np.int64)
        """Per AGV its body's batch row (-1: out of the space)."""
        self._ctrl = np.full(n, -1, dtype=np.int64)
        """Per AGV its control body's batch row (-1: out of the space)."""
        self._all = np.zeros((0, 6))
        known = np.concatenate([self._body_ids, self._ctrl_ids])
        order = np.argsort(known, kind="stable")
        self._known = known[order]
        """Every AGV body's and control body's id, sorted (:meth:`reorder`) ..."""
        self._known_agv = (order % n).astype(np.int64)
        """... whose AGV ..."""
        self._known_ctrl = order >= n
        """... and whether a control body."""
        self._out_all = np.zeros((0, 3))
        """The commands of every body in the space (:meth:`write`; :attr:`out` is its
        first ``n_rows`` rows), the batch buffer of the writes."""
        self.n_rows = 0
        self.reorder()

    def _batched(self, fields: batch.BodyFields, buf: batch.Buffer):
        """The C argument of chipmunk's batch iterators for ``fields`` and ``buf``."""
        data = self._ffi.new("pmBatchedData *")
        data.fields = fields.value
        data.floatArray = buf._float_arr
        data.intArray = buf._int_arr
        return data

    def reorder(self) -> None:
        """Find which row is which body (the space lists its bodies in an order that
        changes when bodies leave or enter it: :meth:`PhysicalFleet.park`)."""
        self.buf._int_arr.num = 0
        self._each(self.space._space, self._get_fn, self._id_data)
        ids = np.frombuffer(self.buf.int_buf(), dtype=np.uintp)
        body_rows(ids, self._known, self._known_agv, self._known_ctrl, self._rows, self._ctrl)
        self.n_rows = len(ids)
        if self.n_rows > len(self._out_all):
            self._out_all = np.zeros((2 * self.n_rows, 3))
            self.set_buf.set_float_buf(self._out_all.ravel())
        self.out = self._out_all[:self.n_rows]
        out = self.fleet.static
        for i in np.flatnonzero(out & ~self._out):  # left since the last call
            b = self.fleet.bodies[i]
            self._still[i] = (*b.position, b.angle, 0.0, 0.0, 0.0)
        self._out = out.copy()

    def read(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(positions (N, 2), angles (N,), velocities (N, 2), angular velocities (N,)) of
        the AGV bodies, by AGV id: new contiguous arrays on every call."""
        self.buf._float_arr.num = 0
        self._each(self.space._space, self._get_fn, self._get_data)
        data = np.frombuffer(self.buf.float_buf(), dtype=np.float64).reshape(self.n_rows, 6)
        self._all = data
        n = len(self._rows)
        pos, ang, vel, w = np.empty((n, 2)), np.empty(n), np.empty((n, 2)), np.empty(n)
        gather_bodies(data, self._rows, self._still, pos, ang, vel, w)
        return pos, ang, vel, w

    def write(self, velocity: np.ndarray, angular: np.ndarray,
              bodies: np.ndarray | None = None) -> None:
        """Set the control bodies' velocities, and those of the AGV bodies where ``bodies``
        ((N,) bool) is set (every other body keeps what :meth:`read` saw); AGVs out of the
        space are left out."""
        if bodies is None:
            bodies = np.zeros(len(self._rows), dtype=np.bool_)
        scatter_commands(self._all, self._rows, self._ctrl,
                         np.ascontiguousarray(velocity, dtype=np.float64),
                         np.ascontiguousarray(angular, dtype=np.float64),
                         np.ascontiguousarray(bodies, dtype=np.bool_), self.out)
        arr = self.set_buf._float_arr
        num = arr.num
        arr.num = 0  # the set iterator walks the array from its start
        self._each(self.space._space, self._set_fn, self._set_data)
        arr.num = num
