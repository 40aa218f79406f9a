"""Pose samples streamed to disk: memory stays bounded however long the episode runs.

At 1,000 AGVs one sample is ~51 kB (``x``, ``y``, ``heading`` float64, ``state`` int8,
``loaded`` bool, ``shelf_m`` 2 x float32, ``exec_state`` int8, ``blocker`` and
``plan_tick`` int32 per AGV); kept in memory at 10 Hz that is ~1.8 GB per simulated hour.

What the executor was doing at each sample (the fields added by issue 36; a recording made
before has none of them, and readers treat them as absent):

- ``exec_state`` (T, N) int8, one of :data:`EXEC_STATES` (index = code): ``standing`` (a
  released next action that has not started yet), ``driving``, ``turning`` (in place,
  before a move), ``waiting`` (its next action waits on the dependency graph: another
  AGV's visit is ahead at a cell it must enter), ``delayed`` (an injected random delay
  holds it), ``failed``, ``finished`` (no action left: the end of its plan) and ``working``
  (a planned dwell: pick, hand-over, place). Priorities as in :mod:`.causes`.
- ``blocker`` (T, N) int32: the AGV a ``waiting`` AGV waits for (-1: none, or not waiting).
- ``plan_tick`` (T, N) int32: how far the AGV is along its committed plan, in the plan's
  ticks: the arrival tick of the move it is driving, else of the last move it finished
  (-1: none yet, it stands where its plan starts). A renderer draws the path still ahead
  from there, whatever the clock says.
:class:`TrajectoryStore` fills a fixed buffer of :data:`CHUNK` samples and appends it to one
raw file per field in a temporary folder when full. :meth:`TrajectoryStore.arrays` gives
read-only :class:`numpy.memmap` s over those files (a short run that never filled a chunk
gets in-memory copies and never touches the disk). The folder goes when the store is
garbage collected (the mapped arrays stay readable on POSIX systems until dropped).

Example::

    >>> import numpy as np
    >>> s = TrajectoryStore(2, chunk=2)
    >>> for t in range(3):
    ...     s.append(float(t), np.zeros((2, 2)), np.zeros(2), np.zeros(2, np.int8),
    ...              np.zeros(2, bool), np.zeros((2, 2)))
    >>> a = s.arrays()
    >>> a["t"].tolist(), a["x"].shape, a["state"].dtype, a["shelf_m"].shape
    ([0.0, 1.0, 2.0], (3, 2), dtype('int8'), (3, 2, 2))
    >>> a["exec_state"].tolist(), a["blocker"][0].tolist()   # not given: standing, none
    ([[0, 0], [0, 0], [0, 0]], [-1, -1])
"""

from __future__ import annotations

import shutil
import tempfile
import weakref
from pathlib import Path

import numpy as np

__all__ = ["CHUNK", "TrajectoryStore", "EXEC_STATES", "EXEC_FIELDS", "STANDING", "DRIVING",
           "TURNING", "WAITING", "DELAYED", "FAILED", "FINISHED", "WORKING"]

CHUNK = 256
"""Samples buffered in memory before they are appended to the files."""

EXEC_STATES = ("standing", "driving", "turning", "waiting", "delayed", "failed", "finished",
               "working")
"""What an AGV is doing at a sample (``exec_state`` code = index); see the module docstring."""
STANDING, DRIVING, TURNING, WAITING, DELAYED, FAILED, FINISHED, WORKING = range(len(EXEC_STATES))
EXEC_FIELDS = ("exec_state", "blocker", "plan_tick")
"""The per-sample execution fields (absent from recordings made before them)."""

_FIELDS = (("t", np.float64), ("x", np.float64), ("y", np.float64), ("heading", np.float64),
           ("state", np.int8), ("loaded", np.bool_), ("shelf_m", np.float32),
           ("exec_state", np.int8), ("blocker", np.int32), ("plan_tick", np.int32))
_UNSET = {"exec_state": STANDING, "blocker": -1, "plan_tick": -1}
"""Value of an execution field that :meth:`TrajectoryStore.append` was not given."""
_TAIL = {"shelf_m": (2,)}
"""Per-AGV trailing shape of a field (scalar per AGV otherwise)."""


def _shape(name: str, rows: int, n: int) -> tuple[int, ...]:
    return (rows,) if name == "t" else (rows, n, *_TAIL.get(name, ()))


class TrajectoryStore:
    """Append-only ``t`` (T,), ``x``, ``y``, ``heading``, ``state``, ``loaded`` (T, N),
    ``shelf_m`` (T, N, 2: carried shelf length and width, 0 when not carrying) and the
    execution fields ``exec_state``, ``blocker``, ``plan_tick`` (T, N)."""

    def __init__(self, n: int, chunk: int = CHUNK) -> None:
        self.n = n
        self.chunk = max(1, chunk)
        self._buf = {name: np.zeros(_shape(name, self.chunk, n), dtype) for name, dtype in _FIELDS}
        self._fill = 0
        """Samples in the buffer."""
        self._on_disk = 0
        """Samples already in the files."""
        self._dir: Path | None = None
        self._cleanup: weakref.finalize | None = None

    def __len__(self) -> int:
        return self._on_disk + self._fill

    @property
    def folder(self) -> Path | None:
        """The temporary folder (None until the first chunk is written)."""
        return self._dir

    def append(self, t: float, pos: np.ndarray, ang: np.ndarray, state: np.ndarray,
               loaded: np.ndarray, shelf_m: np.ndarray,
               execution: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> None:
        """One sample: time, positions (N, 2), headings, task states, loaded flags,
        carried-shelf sizes (N, 2) and ``execution``: ``(exec_state, blocker, plan_tick)``
        (None: standing, no blocker, no progress)."""
        b, r = self._buf, self._fill
        if execution is None:
            for name in EXEC_FIELDS:
                b[name][r] = _UNSET[name]
        else:
            for name, value in zip(EXEC_FIELDS, execution, strict=True):
                b[name][r] = value
        b["t"][r] = t
        b["x"][r] = pos[:, 0]
        b["y"][r] = pos[:, 1]
        b["heading"][r] = ang
        b["state"][r] = state
        b["loaded"][r] = loaded
        b["shelf_m"][r] = shelf_m
        self._fill = r + 1
        if self._fill == self.chunk:
            self._flush()

    def _flush(self) -> None:
        if self._fill == 0:
            return
        if self._dir is None:
            self._dir = Path(tempfile.mkdtemp(prefix="warerover-traj-"))
            self._cleanup = weakref.finalize(self, shutil.rmtree, str(self._dir), True)
        for name, _ in _FIELDS:
            with (self._dir / f"{name}.raw").open("ab") as f:
                f.write(self._buf[name][:self._fill].tobytes())
        self._on_disk += self._fill
        self._fill = 0

    def arrays(self) -> dict[str, np.ndarray]:
        """Every sample so far, by field: memory maps of the files, or in-memory copies if
        nothing has been written yet. Recording may go on afterwards."""
        if self._on_disk == 0:
            return {name: self._buf[name][:self._fill].copy() for name, _ in _FIELDS}
        self._flush()
        total = self._on_disk
        out: dict[str, np.ndarray] = {}
        for name, dtype in _FIELDS:
            shape = _shape(name, total, self.n)
            if self.n == 0 and name != "t":
                out[name] = np.zeros(shape, dtype)
            else:
                out[name] = np.memmap(self._dir / f"{name}.raw", dtype=dtype, mode="r",
                                      shape=shape)
        return out

    def close(self) -> None:
        """Remove the temporary folder now (arrays already mapped stay readable on POSIX)."""
        if self._cleanup is not None:
            self._cleanup()
