"""Tests for warerover_phys.problems.movingai: MovingAI .map / .scen readers."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from warerover_phys.errors import ScenarioError
from warerover_phys.problems.movingai import MovingAIMap, ScenarioAgent, read_map, read_scen

DATA = Path(__file__).parent / "data"
WAREHOUSE_MAP = DATA / "warehouse-10-20-10-2-1.map"
WAREHOUSE_SCEN = DATA / "warehouse-10-20-10-2-1-random-1.scen"
RANDOM_MAP = DATA / "random-32-32-10.map"
RANDOM_SCEN = DATA / "random-32-32-10-random-1.scen"


def raw_grid(path: Path) -> list[str]:
    """The grid rows of a .map file, read independently of the module under test."""
    lines = path.read_text().splitlines()
    return lines[4:]


def raw_scen_fields(path: Path) -> list[list[str]]:
    return [line.split("\t") for line in path.read_text().splitlines()[1:] if line]


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def map_text(rows: list[str], height: int | None = None, width: int | None = None) -> str:
    h = len(rows) if height is None else height
    w = (len(rows[0]) if rows else 0) if width is None else width
    return f"type octile\nheight {h}\nwidth {w}\nmap\n" + "".join(r + "\n" for r in rows)


def check_error(excinfo: pytest.ExceptionInfo[ScenarioError], path: Path, field: str) -> str:
    """The error is one line naming the file and the field; returns the message."""
    err = excinfo.value
    text = str(err)
    assert "\n" not in text
    assert err.file == str(path)
    assert err.field == field
    assert text.startswith(f"{path}: {field}: ")
    return text


# --------------------------------------------------------------------------- real maps


@pytest.mark.parametrize(
    ("path", "rows", "cols", "free"),
    [(WAREHOUSE_MAP, 63, 161, 5699), (RANDOM_MAP, 32, 32, 922)],
)
def test_real_map_dimensions_and_counts(path: Path, rows: int, cols: int, free: int) -> None:
    grid = read_map(path)
    text_rows = raw_grid(path)
    blocked_in_text = sum(row.count(c) for row in text_rows for c in "@OTW")
    free_in_text = sum(row.count(c) for row in text_rows for c in ".GS")

    assert isinstance(grid, MovingAIMap)
    assert (grid.rows, grid.cols) == (rows, cols) == (len(text_rows), len(text_rows[0]))
    assert grid.obstacles.shape == (rows, cols)
    assert grid.obstacles.dtype == bool
    assert int(grid.obstacles.sum()) == blocked_in_text
    assert int((~grid.obstacles).sum()) == free_in_text == free  # shared README's count
    assert grid.chars == tuple(text_rows)
    assert grid.name == path.name


def test_obstacles_read_only() -> None:
    grid = read_map(RANDOM_MAP)
    with pytest.raises(ValueError):
        grid.obstacles[0, 0] = True


def test_row_col_orientation_warehouse() -> None:
    grid = read_map(WAREHOUSE_MAP)
    text = raw_grid(WAREHOUSE_MAP)
    # Shelf block starts at text line 2, character 26; the transposed cell is aisle.
    assert text[2][26] == "T" and text[26][2] == "."
    assert grid.obstacles[2, 26]
    assert not grid.obstacles[26, 2]
    assert grid.is_free((26, 2)) and not grid.is_free((2, 26))
    # The whole top row and left column are walls.
    assert grid.obstacles[0, :].all() and grid.obstacles[:, 0].all()


def test_row_col_orientation_random() -> None:
    grid = read_map(RANDOM_MAP)
    text = raw_grid(RANDOM_MAP)
    assert text[4][0] == "@" and text[0][4] == "."
    assert grid.obstacles[4, 0] and not grid.obstacles[0, 4]
    assert text[0][7] == "@" and text[7][0] == "."
    assert grid.obstacles[0, 7] and not grid.obstacles[7, 0]
    # Every cell agrees with the raw text.
    expected = np.array([[ch == "@" for ch in row] for row in text])
    assert np.array_equal(grid.obstacles, expected)


# --------------------------------------------------------------------------- real scens


@pytest.mark.parametrize(
    ("map_path", "scen_path", "count"),
    [(WAREHOUSE_MAP, WAREHOUSE_SCEN, 1000), (RANDOM_MAP, RANDOM_SCEN, 461)],
)
def test_real_scen_agents_on_free_cells(map_path: Path, scen_path: Path, count: int) -> None:
    grid = read_map(map_path)
    agents = read_scen(scen_path, grid=grid)
    assert len(agents) == count
    for agent in agents:
        assert isinstance(agent, ScenarioAgent)
        assert agent.map_name == map_path.name
        assert not grid.obstacles[agent.start], agent
        assert not grid.obstacles[agent.goal], agent


def test_scen_converts_xy_to_row_col() -> None:
    fields = raw_scen_fields(RANDOM_SCEN)
    agents = read_scen(RANDOM_SCEN)
    assert len(agents) == len(fields)
    for agent, f in zip(agents, fields, strict=True):
        assert agent.bucket == int(f[0])
        assert agent.start == (int(f[5]), int(f[4]))  # (row, col) = (y, x)
        assert agent.goal == (int(f[7]), int(f[6]))
        assert agent.optimal_length == pytest.approx(float(f[8]))
    # First line: "3 random-32-32-10.map 32 32 11 6 7 18 13.65685425"
    assert agents[0] == ScenarioAgent(3, "random-32-32-10.map", (6, 11), (18, 7), 13.65685425)


def test_scen_xy_swap_would_hit_obstacles() -> None:
    """Swapping x/y puts some warehouse agents on shelves, so the test above has teeth."""
    grid = read_map(WAREHOUSE_MAP)
    agents = read_scen(WAREHOUSE_SCEN)
    swapped_bad = [
        a for a in agents
        if not grid.in_bounds(a.start[::-1]) or grid.obstacles[a.start[::-1]]
    ]
    assert swapped_bad


def test_first_n_selection() -> None:
    everything = read_scen(WAREHOUSE_SCEN)
    assert read_scen(WAREHOUSE_SCEN, n=5) == everything[:5]
    assert read_scen(WAREHOUSE_SCEN, n=1000) == everything
    assert read_scen(WAREHOUSE_SCEN, n=0) == []
    first = raw_scen_fields(WAREHOUSE_SCEN)[0]
    assert read_scen(WAREHOUSE_SCEN, n=1)[0].start == (int(first[5]), int(first[4]))


@pytest.mark.no_cover  # a CPU-time bound: measured without coverage's tracer
def test_map_parse_is_fast(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    rows = ["".join(rng.choice(list(".@T"), size=140)) for _ in range(500)]
    path = write(tmp_path, "big.map", map_text(rows))
    times = []
    for _ in range(5):
        t0 = time.process_time()  # CPU time: a loaded machine does not stretch it
        grid = read_map(path)
        times.append(time.process_time() - t0)
    assert grid.obstacles.shape == (500, 140)
    assert min(times) < 0.1


# --------------------------------------------------------------------------- tolerated input


def test_map_accepts_crlf_trailing_blank_lines_and_all_chars(tmp_path: Path) -> None:
    text = "type octile\r\nheight 2\r\nwidth 4\r\nmap\r\n.GS@\r\nOTW.\r\n\r\n"
    grid = read_map(write(tmp_path, "crlf.map", text))
    assert grid.obstacles.tolist() == [[False, False, False, True], [True, True, True, False]]
    assert grid.chars == (".GS@", "OTW.")


def test_scen_accepts_version_1_0_and_spaces(tmp_path: Path) -> None:
    path = write(tmp_path, "a.scen", "version 1.0\n0 m.map 4 3 1 2 3 0 2.5\n\n")
    assert read_scen(path) == [ScenarioAgent(0, "m.map", (2, 1), (0, 3), 2.5)]


# --------------------------------------------------------------------------- map errors


def test_map_missing_file(tmp_path: Path) -> None:
    path = tmp_path / "nope.map"
    with pytest.raises(ScenarioError) as excinfo:
        read_map(path)
    check_error(excinfo, path, "file")


@pytest.mark.parametrize(
    ("text", "field", "value"),
    [
        ("", "header", ""),
        ("type octle\nheight 1\nwidth 1\nmap\n.\n", "header", "type octle"),
        ("height 1\nwidth 1\nmap\n.\n", "header", "height 1"),
        ("type octile\nheight one\nwidth 1\nmap\n.\n", "height", "one"),
        ("type octile\nheight 1.5\nwidth 1\nmap\n.\n", "height", "1.5"),
        ("type octile\nheight 1\nwidth x\nmap\n.\n", "width", "x"),
        ("type octile\nwidth 1\nheight 1\nmap\n.\n", "height", "width 1"),
        ("type octile\nheight 1\n", "width", ""),
        ("type octile\nheight 1\nwidth 1\ngrid\n.\n", "header", "grid"),
    ],
)
def test_map_header_errors(tmp_path: Path, text: str, field: str, value: str) -> None:
    path = write(tmp_path, "bad.map", text)
    with pytest.raises(ScenarioError) as excinfo:
        read_map(path)
    check_error(excinfo, path, field)
    assert excinfo.value.value == value


def test_map_too_few_rows(tmp_path: Path) -> None:
    path = write(tmp_path, "few.map", map_text(["...", "..."], height=3))
    with pytest.raises(ScenarioError) as excinfo:
        read_map(path)
    msg = check_error(excinfo, path, "rows")
    assert "too few" in msg and excinfo.value.value == 2


def test_map_too_many_rows(tmp_path: Path) -> None:
    path = write(tmp_path, "many.map", map_text(["...", "...", "..."], height=2))
    with pytest.raises(ScenarioError) as excinfo:
        read_map(path)
    msg = check_error(excinfo, path, "rows")
    assert "too many" in msg and excinfo.value.value == 3


def test_map_row_wrong_length(tmp_path: Path) -> None:
    path = write(tmp_path, "len.map", map_text(["....", "...", "...."], width=4))
    with pytest.raises(ScenarioError) as excinfo:
        read_map(path)
    check_error(excinfo, path, "row 1")
    assert excinfo.value.value == "..."


@pytest.mark.parametrize("encoding", ["utf-8", "latin-1"])
@pytest.mark.parametrize("bad", ["x", " ", "#", "\t", "é"])
def test_map_unknown_character(tmp_path: Path, bad: str, encoding: str) -> None:
    rows = ["....", "..." + bad, "...."]
    path = tmp_path / "chars.map"
    path.write_bytes(map_text(rows, width=4).encode(encoding))
    with pytest.raises(ScenarioError) as excinfo:
        read_map(path)
    check_error(excinfo, path, "row 1, column 3")
    assert excinfo.value.value == bad


# --------------------------------------------------------------------------- scen errors

SMALL_MAP_ROWS = ["....", ".@..", "...T"]  # obstacles at (1, 1) and (2, 3); 3 rows x 4 cols


@pytest.fixture
def small_grid(tmp_path: Path) -> MovingAIMap:
    return read_map(write(tmp_path, "small.map", map_text(SMALL_MAP_ROWS)))


def scen_text(*lines: str) -> str:
    return "version 1\n" + "".join(line + "\n" for line in lines)


def agent_line(sx: int, sy: int, gx: int, gy: int, width: int = 4, height: int = 3) -> str:
    return "\t".join(map(str, [0, "small.map", width, height, sx, sy, gx, gy, 1.0]))


def test_scen_missing_file(tmp_path: Path) -> None:
    path = tmp_path / "nope.scen"
    with pytest.raises(ScenarioError) as excinfo:
        read_scen(path)
    check_error(excinfo, path, "file")


@pytest.mark.parametrize("header", ["", "version 2", "version", "1 version", "bucket map"])
def test_scen_wrong_header(tmp_path: Path, header: str) -> None:
    path = write(tmp_path, "h.scen", header + "\n" + agent_line(0, 0, 1, 0) + "\n")
    with pytest.raises(ScenarioError) as excinfo:
        read_scen(path)
    check_error(excinfo, path, "line 1")
    assert excinfo.value.value == header


@pytest.mark.parametrize(
    "bad_line",
    [
        "0\tsmall.map\t4\t3\t0\t0\t1\t0",  # 8 fields
        "0\tsmall.map\t4\t3\t0\t0\t1\t0\t1.0\t7",  # 10 fields
        "0\tsmall.map\t4\t3\tA\t0\t1\t0\t1.0",  # non-integer start_x
        "0\tsmall.map\t4\t3\t0\t0\t1\t0.5\t1.0",  # non-integer goal_y
        "b\tsmall.map\t4\t3\t0\t0\t1\t0\t1.0",  # non-integer bucket
        "0\tsmall.map\t4\t3\t0\t0\t1\t0\tlong",  # non-numeric optimal length
        "0\tsmall.map\t4\t3\t0\t0\t1\t0\tnan",  # non-finite optimal length
        "0\tsmall.map\t4\t3\t-1\t0\t1\t0\t1.0",  # negative x (outside the line's width)
        "0\tsmall.map\t4\t3\t0\t0\t4\t0\t1.0",  # goal x == width
        "0\tsmall.map\t0\t3\t0\t0\t0\t0\t1.0",  # zero width
    ],
)
def test_scen_malformed_line(tmp_path: Path, bad_line: str) -> None:
    path = write(tmp_path, "m.scen", scen_text(agent_line(0, 0, 1, 0), "", bad_line))
    with pytest.raises(ScenarioError) as excinfo:
        read_scen(path)
    check_error(excinfo, path, "line 4")  # blank line 3 is skipped but still counted


def test_scen_n_too_large(tmp_path: Path) -> None:
    path = write(tmp_path, "n.scen", scen_text(agent_line(0, 0, 1, 0), agent_line(1, 0, 2, 0)))
    with pytest.raises(ScenarioError) as excinfo:
        read_scen(path, n=3)
    msg = check_error(excinfo, path, "agents")
    assert excinfo.value.value == 3
    assert "has only 2" in msg
    assert len(read_scen(path, n=2)) == 2


def test_scen_n_negative(tmp_path: Path) -> None:
    path = write(tmp_path, "n.scen", scen_text(agent_line(0, 0, 1, 0)))
    with pytest.raises(ScenarioError) as excinfo:
        read_scen(path, n=-1)
    check_error(excinfo, path, "agents")


def test_real_scen_n_too_large_names_count() -> None:
    with pytest.raises(ScenarioError) as excinfo:
        read_scen(RANDOM_SCEN, n=462)
    assert "has only 461" in check_error(excinfo, RANDOM_SCEN, "agents")


def test_scen_matches_small_grid(tmp_path: Path, small_grid: MovingAIMap) -> None:
    path = write(tmp_path, "ok.scen", scen_text(agent_line(3, 0, 0, 2)))
    assert read_scen(path, grid=small_grid) == [
        ScenarioAgent(0, "small.map", (0, 3), (2, 0), 1.0)
    ]


@pytest.mark.parametrize(
    ("sx", "sy", "gx", "gy", "which", "cell"),
    [
        (0, 3, 0, 0, "start", (3, 0)),  # row 3 of a 3-row grid
        (0, 0, 4, 0, "goal", (0, 4)),  # col 4 of a 4-col grid
        (0, 0, 0, 9, "goal", (9, 0)),
    ],
)
def test_scen_start_goal_outside_grid(tmp_path: Path, small_grid: MovingAIMap, sx: int,
                                      sy: int, gx: int, gy: int, which: str,
                                      cell: tuple[int, int]) -> None:
    # The line's own width/height match the grid, but the coordinates are out of range.
    path = write(tmp_path, "o.scen", scen_text(agent_line(0, 0, 1, 0), agent_line(sx, sy, gx, gy)))
    with pytest.raises(ScenarioError) as excinfo:
        read_scen(path, grid=small_grid)
    msg = check_error(excinfo, path, "line 3")
    assert f"agent 1 {which}" in msg and str(cell) in msg and "outside" in msg
    assert excinfo.value.value == cell


def test_scen_outside_without_grid_uses_line_dimensions(tmp_path: Path) -> None:
    path = write(tmp_path, "o.scen", scen_text(agent_line(0, 3, 0, 0)))
    with pytest.raises(ScenarioError) as excinfo:
        read_scen(path)
    assert "outside" in check_error(excinfo, path, "line 2")


@pytest.mark.parametrize(
    ("sx", "sy", "gx", "gy", "which", "cell"),
    [
        (1, 1, 0, 0, "start", (1, 1)),  # '@' at row 1, col 1
        (0, 0, 3, 2, "goal", (2, 3)),  # 'T' at row 2, col 3
    ],
)
def test_scen_on_obstacle(tmp_path: Path, small_grid: MovingAIMap, sx: int, sy: int, gx: int,
                          gy: int, which: str, cell: tuple[int, int]) -> None:
    path = write(tmp_path, "x.scen", scen_text(agent_line(0, 0, 1, 0), agent_line(1, 0, 2, 0),
                                               agent_line(sx, sy, gx, gy)))
    with pytest.raises(ScenarioError) as excinfo:
        read_scen(path, grid=small_grid)
    msg = check_error(excinfo, path, "line 4")
    assert f"agent 2 {which}" in msg and str(cell) in msg and "obstacle" in msg
    assert excinfo.value.value == cell


def test_scen_obstacle_beyond_n_is_not_checked(tmp_path: Path, small_grid: MovingAIMap) -> None:
    path = write(tmp_path, "x.scen", scen_text(agent_line(0, 0, 1, 0), agent_line(1, 1, 0, 0)))
    assert len(read_scen(path, n=1, grid=small_grid)) == 1
    with pytest.raises(ScenarioError):
        read_scen(path, grid=small_grid)


@pytest.mark.parametrize(("width", "height"), [(5, 3), (4, 2), (3, 4)])
def test_scen_dimension_mismatch(tmp_path: Path, small_grid: MovingAIMap, width: int,
                                 height: int) -> None:
    path = write(tmp_path, "d.scen",
                 scen_text(agent_line(0, 0, 1, 0, width=width, height=height)))
    with pytest.raises(ScenarioError) as excinfo:
        read_scen(path, grid=small_grid)
    msg = check_error(excinfo, path, "line 2")
    assert excinfo.value.value == (width, height)
    assert "width 4, height 3" in msg


def test_real_scen_against_wrong_map() -> None:
    with pytest.raises(ScenarioError) as excinfo:
        read_scen(WAREHOUSE_SCEN, n=10, grid=read_map(RANDOM_MAP))
    check_error(excinfo, WAREHOUSE_SCEN, "line 2")


# --------------------------------------------------------------------------- property


@settings(max_examples=60, deadline=None)
@given(
    st.integers(min_value=1, max_value=12).flatmap(
        lambda rows: st.integers(min_value=1, max_value=12).flatmap(
            lambda cols: st.lists(
                st.text(alphabet=".GS@OTW", min_size=cols, max_size=cols),
                min_size=rows, max_size=rows,
            )
        )
    )
)
def test_random_grid_round_trip(tmp_path_factory: pytest.TempPathFactory,
                                rows: list[str]) -> None:
    path = tmp_path_factory.mktemp("prop") / "g.map"
    path.write_text(map_text(rows))
    grid = read_map(path)
    expected = np.array([[ch in "@OTW" for ch in row] for row in rows], dtype=bool)
    assert (grid.rows, grid.cols) == expected.shape
    assert np.array_equal(grid.obstacles, expected)
    assert grid.chars == tuple(rows)
