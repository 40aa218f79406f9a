"""The socket protocol of ``warerover serve``: client messages (validated with pydantic) and
the binary live frame.

Every client message is one JSON object with a ``type``; :func:`parse_message` returns the
validated model or raises :class:`ProtocolError` with a one-line reason (the server answers
``{"type": "error", ...}`` and keeps the connection). ``docs/serve.md`` lists every message.

>>> parse_message('{"type": "fail", "agv": 3}')
Fail(id=None, type='fail', agv=3, repair_ticks=None)
>>> parse_message('{"type": "fail", "agv": -1}')
Traceback (most recent call last):
...
warerover_phys.serve.protocol.ProtocolError: agv: Input should be greater than or equal to 0
"""

from __future__ import annotations

import json
import struct
from typing import Annotated, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, TypeAdapter, ValidationError

__all__ = ["ProtocolError", "ClientMessage", "parse_message", "encode_frame", "FRAME_MAGIC",
           "MAX_MESSAGE_BYTES", "LayoutDoc"]

MAX_MESSAGE_BYTES = 4 * 1024 * 1024
"""A client message longer than this is refused (a 500 x 500 layout is ~0.3 MB)."""
FRAME_MAGIC = 0x31465257
"""``b"WRF1"`` little-endian: the first 4 bytes of a live frame."""
_HEADER = struct.Struct("<IIffIHHf8x")
"""magic, tick, time_s, tick_s, n, path_len, flags, sim ticks per second, 8 spare bytes."""
assert _HEADER.size == 36


class ProtocolError(ValueError):
    """A client message that is not valid; the text says why (one line)."""


class _Msg(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    id: int | str | None = None
    """Echoed in the reply, so a client can match answers to requests."""


AgvId = Annotated[int, Field(ge=0, le=10**6)]
RelPath = Annotated[str, Field(min_length=1, max_length=500)]


class Pause(_Msg):
    type: Literal["pause"]


class Resume(_Msg):
    type: Literal["resume"]


class Step(_Msg):
    type: Literal["step"]
    count: Annotated[int, Field(ge=1, le=10_000)] = 1


class Speed(_Msg):
    type: Literal["speed"]
    ticks_per_s: Annotated[float, Field(ge=0, le=10_000)]
    """Target ticks per second; 0 = as fast as the simulation can go."""


class Fail(_Msg):
    type: Literal["fail"]
    agv: AgvId
    repair_ticks: Annotated[int, Field(ge=1, le=10**6)] | None = None


class Repair(_Msg):
    type: Literal["repair"]
    agv: AgvId


class AddOrders(_Msg):
    type: Literal["add_orders"]
    count: Annotated[int, Field(ge=1, le=1000)] = 1
    station: Annotated[int, Field(ge=0)] | None = None
    sku: Annotated[int, Field(ge=0)] | None = None


class Restart(_Msg):
    type: Literal["restart"]
    executor: Literal["grid", "physics"] | None = None
    planner: Annotated[str, Field(pattern=r"^[a-z_]{1,20}$")] | None = None
    seed: Annotated[int, Field(ge=0, le=2**32 - 1)] | None = None


class Inspect(_Msg):
    type: Literal["inspect"]
    agv: AgvId


class ListFiles(_Msg):
    type: Literal["list_files"]
    suffixes: list[Annotated[str, Field(pattern=r"^\.[a-z0-9]{1,5}$")]] = [
        ".yaml", ".yml", ".npz", ".json"]


class LayoutDoc(BaseModel):
    """A layout as the editor holds it: one character per cell, row by row."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    rows: Annotated[int, Field(ge=1, le=1000)]
    cols: Annotated[int, Field(ge=1, le=1000)]
    cell_m: Annotated[float, Field(gt=0, le=100)] = 1.0
    cells: Annotated[str, Field(max_length=1_000_000)]
    """``rows * cols`` characters: ``.`` floor, ``#`` obstacle, ``S`` 1x1 shelf, ``R``
    station, ``P`` parking, ``A`` access point, ``B`` part of a 2x2 shelf."""
    big_shelves: list[tuple[int, int]] = []
    """Top-left cells of the 2x2 shelves (their four cells are ``B``)."""
    agvs: Annotated[int, Field(ge=1, le=5000)] | None = None
    """Fleet size used to check the layout (default: one per parking cell, at most 20)."""


class LayoutLoad(_Msg):
    type: Literal["layout_load"]
    path: RelPath


class LayoutCheck(_Msg):
    type: Literal["layout_check"]
    layout: LayoutDoc


class LayoutSave(_Msg):
    type: Literal["layout_save"]
    path: RelPath
    layout: LayoutDoc
    scenario: bool = True
    """Also write ``NAME.scenario.yaml`` beside it (a scenario that uses the layout)."""


class ReplayOpen(_Msg):
    type: Literal["replay_open"]
    path: RelPath
    map: RelPath | None = None
    """Layout for files that carry none (``paths.json``, Robot Runners output): a layout or
    scenario YAML or a MovingAI ``.map`` (default: the live scenario's layout)."""


class ExportGlb(_Msg):
    type: Literal["export_glb"]
    path: RelPath
    what: Literal["layout", "episode"] = "layout"
    """``episode``: the live episode so far (AGV bodies animated over its ticks)."""


class Ping(_Msg):
    type: Literal["ping"]


ClientMessage = Annotated[
    Pause | Resume | Step | Speed | Fail | Repair | AddOrders | Restart | Inspect | ListFiles
    | LayoutLoad | LayoutCheck | LayoutSave | ReplayOpen | ExportGlb | Ping,
    Field(discriminator="type")]
_ADAPTER: TypeAdapter = TypeAdapter(ClientMessage)
MESSAGE_TYPES = ("pause", "resume", "step", "speed", "fail", "repair", "add_orders", "restart",
                 "inspect", "list_files", "layout_load", "layout_check", "layout_save",
                 "replay_open", "export_glb", "ping")


def parse_message(text: str | bytes) -> _Msg:
    """Validate one client message; raise :class:`ProtocolError` naming what is wrong."""
    if isinstance(text, bytes | bytearray):
        raise ProtocolError("binary messages are not accepted; send JSON text")
    if len(text) > MAX_MESSAGE_BYTES:
        raise ProtocolError(f"message too long ({len(text)} > {MAX_MESSAGE_BYTES} bytes)")
    try:
        data = json.loads(text)
    except (json.JSONDecodeError, RecursionError) as err:
        raise ProtocolError(f"not JSON: {err}") from None
    if not isinstance(data, dict):
        raise ProtocolError("a message must be a JSON object with a 'type'")
    kind = data.get("type")
    if kind not in MESSAGE_TYPES:
        raise ProtocolError(f"unknown message type {kind!r}; expected one of "
                            f"{', '.join(MESSAGE_TYPES)}")
    try:
        return _ADAPTER.validate_python(data)
    except ValidationError as err:
        first = err.errors()[0]
        loc = [str(p) for p in first["loc"][1:]]
        where = ".".join(loc) + ": " if loc else ""
        raise ProtocolError(f"{where}{first['msg']}") from None


def encode_frame(snap, tick_s: float, ticks_per_s: float) -> bytes:
    """The binary live frame of a :class:`~.session.LiveSnapshot` (little-endian).

    Layout: a 36-byte header (see ``_HEADER``), then ``x``, ``y``, ``heading`` as float32
    (N each, metres / radians), ``state`` and ``loaded`` as uint8 (N each), zero padding to a
    multiple of 4, and ``paths`` as uint32 ``(N, path_len)`` flat anchor nodes ahead
    (``0xFFFFFFFF`` = none)."""
    n = len(snap.x)
    h = int(snap.paths.shape[1]) if snap.paths.ndim == 2 else 0
    head = _HEADER.pack(FRAME_MAGIC, snap.tick, snap.time_s, tick_s, n, h, 0, ticks_per_s)
    body = np.concatenate([snap.x, snap.y, snap.heading]).astype("<f4").tobytes()
    small = np.concatenate([snap.state, snap.loaded]).astype(np.uint8).tobytes()
    pad = (-len(small)) % 4
    return b"".join([head, body, small, b"\0" * pad,
                     np.ascontiguousarray(snap.paths, dtype="<u4").tobytes()])
