"""Readers for MovingAI MAPF benchmark files (``.map`` grids and ``.scen`` scenarios).

Grid cells are ``(row, col)`` with row 0 at the top. MovingAI scenario files give
``x = column, y = row``; :func:`read_scen` converts them to ``(row, col)``.
Every problem with the input raises :class:`~warerover_phys.errors.ScenarioError` naming the
file, the field and the offending value.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import ScenarioError

__all__ = ["MovingAIMap", "ScenarioAgent", "read_map", "read_scen"]

OBSTACLE_CHARS = "@OTW"
PASSABLE_CHARS = ".GSE"
"""Free cells: MovingAI uses `.`, `G`, `S`; Robot Runners maps mark task sites `E` and `S`."""

# Byte -> class lookup: 0 passable, 1 obstacle, 2 unknown character.
_LUT = np.full(256, 2, dtype=np.uint8)
for _c in PASSABLE_CHARS:
    _LUT[ord(_c)] = 0
for _c in OBSTACLE_CHARS:
    _LUT[ord(_c)] = 1
del _c


@dataclass(frozen=True, eq=False)
class MovingAIMap:
    """A MovingAI grid: ``obstacles[row, col]`` is True for blocked cells (read-only)."""

    name: str
    rows: int
    cols: int
    obstacles: np.ndarray
    chars: tuple[str, ...]

    def __post_init__(self) -> None:
        obstacles = np.asarray(self.obstacles, dtype=bool)
        if obstacles.shape != (self.rows, self.cols):
            raise ValueError(f"obstacles has shape {obstacles.shape}, "
                             f"expected {(self.rows, self.cols)}")
        if obstacles.flags.writeable:
            obstacles = obstacles.copy()
            obstacles.setflags(write=False)
        object.__setattr__(self, "obstacles", obstacles)

    def in_bounds(self, cell: tuple[int, int]) -> bool:
        """Whether ``cell`` = (row, col) lies on the grid."""
        r, c = cell
        return 0 <= r < self.rows and 0 <= c < self.cols

    def is_free(self, cell: tuple[int, int]) -> bool:
        """Whether ``cell`` = (row, col) is on the grid and not an obstacle."""
        return self.in_bounds(cell) and not bool(self.obstacles[cell[0], cell[1]])


@dataclass(frozen=True, slots=True)
class ScenarioAgent:
    """One line of a ``.scen`` file; ``start``/``goal`` are (row, col)."""

    bucket: int
    map_name: str
    start: tuple[int, int]
    goal: tuple[int, int]
    optimal_length: float


MAX_FILE_BYTES = 64 * 2**20
"""Largest ``.map`` or ``.scen`` file read (64 MiB; a 4,096 x 4,096 map is 16 MiB)."""


def _read_lines(path: str | os.PathLike[str], file: str) -> list[str]:
    """The file's lines (UTF-8, else latin-1), without line ends."""
    from ..inputs import read_bytes

    what = "map" if str(path).endswith(".map") else "scenario" if str(path).endswith(
        ".scen") else "MovingAI"
    try:
        data = read_bytes(path, what, MAX_FILE_BYTES)  # a regular file, size-limited
    except ScenarioError as err:
        raise ScenarioError(err.message, file=file, field="file", value=file) from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        text = data.decode("latin-1")
    lines = text.split("\n")
    if lines and lines[-1] == "":
        lines.pop()
    return [line[:-1] if line.endswith("\r") else line for line in lines]


def _header_int(lines: list[str], index: int, key: str, file: str) -> int:
    """Parse header line ``index`` as ``KEY N`` with N a positive integer."""
    line = lines[index] if index < len(lines) else None
    if line is None:
        raise ScenarioError(f"missing '{key} N' header line (file ends early)", file=file,
                            field=key, value="")
    parts = line.split()
    if len(parts) != 2 or parts[0].lower() != key:
        raise ScenarioError(f"expected '{key} N' on line {index + 1}", file=file, field=key,
                            value=line)
    try:
        number = int(parts[1])
    except ValueError:
        raise ScenarioError(f"{key} must be an integer", file=file, field=key,
                            value=parts[1]) from None
    if number <= 0:
        raise ScenarioError(f"{key} must be positive", file=file, field=key, value=number)
    return number


def read_map(path: str | os.PathLike[str]) -> MovingAIMap:
    """Read a MovingAI ``.map`` file.

    Obstacles are ``@ O T W``; passable cells are ``. G S``; any other cell character is an
    error. Rows are reported 0-based (grid row index), as are columns.
    """
    file = str(path)
    lines = _read_lines(path, file)

    first = lines[0] if lines else ""
    if first.split() != ["type", "octile"]:
        raise ScenarioError("first line must be 'type octile'", file=file, field="header",
                            value=first)
    height = _header_int(lines, 1, "height", file)
    width = _header_int(lines, 2, "width", file)
    marker = lines[3] if len(lines) > 3 else ""
    if marker.strip() != "map":
        raise ScenarioError("line 4 must be 'map'", file=file, field="header", value=marker)

    body = lines[4:]
    while body and body[-1].strip() == "":  # tolerate blank lines after the grid
        body.pop()
    if len(body) < height:
        raise ScenarioError(f"too few rows: header says height {height}, file has "
                            f"{len(body)}", file=file, field="rows", value=len(body))
    if len(body) > height:
        raise ScenarioError(f"too many rows: header says height {height}, file has "
                            f"{len(body)}", file=file, field="rows", value=len(body))
    for r, row in enumerate(body):
        if len(row) != width:
            raise ScenarioError(f"row has {len(row)} characters, width is {width} "
                                f"(file line {r + 5})", file=file, field=f"row {r}",
                                value=row)

    joined = "".join(body)
    if joined.isascii():
        kind = _LUT[np.frombuffer(joined.encode("ascii"), dtype=np.uint8)]
    else:  # non-ASCII characters are all unknown; index by code point
        codes = np.frombuffer(joined.encode("utf-32-le"), dtype=np.uint32)
        kind = np.where(codes < 256, _LUT[np.minimum(codes, 255)], np.uint8(2))
    kind = kind.reshape(height, width)
    if (kind == 2).any():
        r, c = (int(i) for i in np.argwhere(kind == 2)[0])
        raise ScenarioError(f"unknown cell character (file line {r + 5}); expected one of "
                            f"'{PASSABLE_CHARS}' (free) or '{OBSTACLE_CHARS}' (obstacle)",
                            file=file, field=f"row {r}, column {c}", value=body[r][c])
    obstacles = kind == 1
    obstacles.setflags(write=False)
    return MovingAIMap(name=Path(path).name, rows=height, cols=width, obstacles=obstacles,
                       chars=tuple(body))


def _split_scen_line(line: str) -> list[str]:
    fields = line.split("\t")
    if len(fields) == 9:
        return [f.strip() for f in fields]
    return line.split()


def _parse_agent(line: str, field: str, file: str) -> tuple[ScenarioAgent, int, int]:
    """One scenario line -> (agent, width, height); raises on malformed lines."""
    parts = _split_scen_line(line)
    if len(parts) != 9:
        raise ScenarioError(
            f"expected 9 fields (bucket map width height start_x start_y goal_x goal_y "
            f"optimal_length), found {len(parts)}", file=file, field=field, value=line)
    names = ("bucket", "width", "height", "start_x", "start_y", "goal_x", "goal_y")
    values: dict[str, int] = {}
    for name, text in zip(names, [parts[0], *parts[2:8]], strict=True):
        try:
            values[name] = int(text)
        except ValueError:
            raise ScenarioError(f"{name} must be an integer", file=file, field=field,
                                value=text) from None
    try:
        optimal = float(parts[8])
    except ValueError:
        raise ScenarioError("optimal_length must be a number", file=file, field=field,
                            value=parts[8]) from None
    if not math.isfinite(optimal) or optimal < 0:
        raise ScenarioError("optimal_length must be finite and >= 0", file=file,
                            field=field, value=parts[8])
    width, height = values["width"], values["height"]
    if width <= 0 or height <= 0:
        raise ScenarioError("width and height must be positive", file=file, field=field,
                            value=(width, height))
    agent = ScenarioAgent(
        bucket=values["bucket"], map_name=parts[1],
        start=(values["start_y"], values["start_x"]),
        goal=(values["goal_y"], values["goal_x"]),
        optimal_length=optimal,
    )
    return agent, width, height


def read_scen(path: str | os.PathLike[str], n: int | None = None,
              grid: MovingAIMap | None = None) -> list[ScenarioAgent]:
    """Read a MovingAI ``.scen`` file and return its first ``n`` agents (all if ``n`` is None).

    Every line is checked for syntax. The selected agents are checked to lie inside the
    width/height their line gives; when ``grid`` is given they are checked against it
    instead (same width/height, start and goal inside the map and on free cells).
    """
    file = str(path)
    if n is not None and (isinstance(n, bool) or not isinstance(n, int) or n < 0):
        raise ScenarioError("number of agents must be a non-negative integer", file=file,
                            field="agents", value=n)
    lines = _read_lines(path, file)

    first = lines[0] if lines else ""
    if first.split() not in (["version", "1"], ["version", "1.0"]):
        raise ScenarioError("first line must be 'version 1'", file=file, field="line 1",
                            value=first)

    parsed: list[tuple[int, ScenarioAgent, int, int]] = []
    for k, line in enumerate(lines[1:], start=2):
        if not line.strip():
            continue
        agent, width, height = _parse_agent(line, f"line {k}", file)
        parsed.append((k, agent, width, height))

    if n is not None and n > len(parsed):
        raise ScenarioError(f"{n} agents requested but the file has only {len(parsed)}",
                            file=file, field="agents", value=n)
    selected = parsed if n is None else parsed[:n]

    for index, (k, agent, width, height) in enumerate(selected):
        field = f"line {k}"
        if grid is None:
            for which, (r, c) in (("start", agent.start), ("goal", agent.goal)):
                if not (0 <= r < height and 0 <= c < width):
                    raise ScenarioError(
                        f"agent {index} {which} (row, col)={(r, c)} lies outside the "
                        f"width {width}, height {height} given on this line",
                        file=file, field=field, value=(r, c))
        else:
            if (width, height) != (grid.cols, grid.rows):
                raise ScenarioError(
                    f"agent {index}: scenario says width {width}, height {height} but map "
                    f"'{grid.name}' is width {grid.cols}, height {grid.rows}",
                    file=file, field=field, value=(width, height))
            for which, cell in (("start", agent.start), ("goal", agent.goal)):
                if not grid.in_bounds(cell):
                    raise ScenarioError(
                        f"agent {index} {which} (row, col)={cell} lies outside map "
                        f"'{grid.name}' ({grid.rows} rows x {grid.cols} cols)",
                        file=file, field=field, value=cell)
                if grid.obstacles[cell]:
                    raise ScenarioError(
                        f"agent {index} {which} (row, col)={cell} is an obstacle on map "
                        f"'{grid.name}'", file=file, field=field, value=cell)
    return [agent for _, agent, _, _ in selected]
