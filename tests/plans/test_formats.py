"""Tests for warerover_phys.plans: plan files of the field, read and written."""

from __future__ import annotations

import doctest
import json
import os
import shutil
import subprocess
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from warerover_phys.errors import PlanFormatError
from warerover_phys.plans import (
    FORMATS,
    HEADING_STEPS,
    Plan,
    detect_format,
    format_plan,
    parse_plan,
    read_plan,
    write_plan,
)
from warerover_phys.plans import formats as formats_module

DATA = Path(__file__).resolve().parents[1] / "data"

# ---------------------------------------------------------------- hand-written examples

LACAM = """\
agents=2
map_file=tiny.map
width=8
height=6
solver=handmade
solved=1
comp_time=1.5
soc=3
makespan=3
starts=(0,1),(4,5),
goals=(2,2),(4,5),
solution=
0:(0,1),(4,5),
1:(1,1),(4,5),
2:(1,1),(4,5),
3:(2,1),(4,4)
"""


def test_lacam_example_by_hand():
    plan = parse_plan(LACAM, source="tiny.txt")
    # x = column, y = row: (0,1) is row 1, column 0
    assert plan.paths == (((1, 0), (1, 1), (1, 1), (1, 2)),
                          ((5, 4), (5, 4), (5, 4), (4, 4)))
    assert plan.headings is None
    assert (plan.rows, plan.cols, plan.map_name, plan.fmt) == (6, 8, "tiny.map", "lacam")
    assert plan.meta["solver"] == "handmade" and plan.meta["comp_time"] == 1.5
    assert plan.meta["starts"] == [[1, 0], [5, 4]]
    assert plan.makespan == 3 and plan.sum_of_costs == 3 + 3


def test_line_endings_and_byte_order_mark_do_not_matter():
    for text in (LACAM, LNS, TIMED):
        plan = parse_plan(text)
        assert parse_plan(text.replace("\n", "\r\n")) == plan
        assert parse_plan("\ufeff" + text) == plan


def test_lacam_without_header_and_with_blank_lines():
    plan = parse_plan("0:(3,1),\n\n1:(4,1),\n\n")
    assert plan.paths == (((1, 3), (1, 4)),)


LNS = """\
Agent 1:(5,5)->
Agent 0: (1,0)->(2,0)->(2,0)->(3,0)
"""


def test_lns_example_by_hand():
    plan = parse_plan(LNS)
    assert plan.fmt == "lns"
    assert plan.paths == (((1, 0), (2, 0), (2, 0), (3, 0)), ((5, 5),))
    assert plan.sum_of_costs == 3 and plan.makespan == 3


TIMED = "Agent 0:(0,1,0)->(2,1,2)->(2,3,3)->\nAgent 1:(4,4,1)->\n"


def test_timed_example_by_hand_xy():
    plan = parse_plan(TIMED)  # (x = column, y = row, t)
    assert plan.fmt == "timed"
    # the gap 0 -> 2 is a wait at the first point, then a jump (the reader does not check moves)
    assert plan.paths == (((1, 0), (1, 0), (1, 2), (3, 2)), ((4, 4),))


def test_timed_example_by_hand_row_col():
    plan = parse_plan(TIMED, xy=False)  # (row, col, t)
    assert plan.paths == (((0, 1), (0, 1), (2, 1), (2, 3)), ((4, 4),))


def test_timed_xy_flag_both_ways():
    plan = Plan(paths=(((0, 1), (0, 2), (0, 2), (1, 2)), ((3, 0),)))
    xy = format_plan(plan, "timed", xy=True)
    yx = format_plan(plan, "timed", xy=False)
    assert xy.splitlines()[0] == "Agent 0:(1,0,0)->(2,0,1)->(2,1,3)->"
    assert yx.splitlines()[0] == "Agent 0:(0,1,0)->(0,2,1)->(1,2,3)->"
    assert parse_plan(xy, xy=True) == plan and parse_plan(yx, xy=False) == plan
    swapped = parse_plan(xy, xy=False)  # read the wrong way: the transposed plan
    assert swapped.paths == tuple(tuple((c, r) for r, c in p) for p in plan.paths)


ROBOTRUNNERS = {
    "actionModel": "MAPF_T", "AllValid": "Yes", "teamSize": 2,
    "start": [[1, 0, "S"], [5, 5, "E"]],
    "numTaskFinished": 0, "sumOfCost": 4, "makespan": 4,
    "actualPaths": ["F,F,W,C,F", "R,T"],
    "plannerPaths": ["F,F,W,W,W", "R,W"],
    "plannerTimes": [0.1], "errors": [], "events": [[]], "tasks": [],
}


def test_robotrunners_example_by_hand():
    plan = parse_plan(json.dumps(ROBOTRUNNERS))
    assert plan.fmt == "robotrunners"
    # agent 0 faces S (+row): F, F, wait, turn counter-clockwise to E, F (+col)
    assert plan.paths[0] == ((1, 0), (2, 0), (3, 0), (3, 0), (3, 0), (3, 1))
    assert plan.headings[0] == (1, 1, 1, 1, 0, 0)
    # agent 1 faces E, turns clockwise to S, then T (no action in time) = wait, trimmed
    assert plan.paths[1] == ((5, 5), (5, 5))
    assert plan.headings[1] == (0, 1)
    assert plan.meta["AllValid"] == "Yes" and plan.meta["plannerTimes"] == [0.1]
    assert "actualPaths" not in plan.meta and "start" not in plan.meta
    planner = parse_plan(json.dumps(ROBOTRUNNERS), which="planner")
    assert planner.paths[0] == ((1, 0), (2, 0), (3, 0))


def test_robotrunners_start_kit_heading_quirk():
    """Some start-kits print a start facing S as [row, col, "S", "W"]."""
    data = {"teamSize": 1, "start": [[2, 2, "S", "W"]], "actualPaths": ["F"]}
    assert parse_plan(json.dumps(data)).paths == (((2, 2), (3, 2)),)


ROBOTRUNNERS_2026 = {"teamSize": 2, "agentMaxCounter": 3, "outputSegmentSize": 4,
                     "start": [[2, 2, "E"], [0, 0, "S"]],
                     "actualPaths": ["[(0,2,2,0,0):(F 3,W 1)][(4,2,2,0,0):(R 3,F 1)]"
                                     "[(8,2,2,0,0):(F 2,W 1)]", "[(0,0,0,1,0):(W 2,F 1,C 2)]"]}


def test_robotrunners_2026_segmented_paths_by_hand():
    """Three execution ticks per action; segments of four ticks."""
    plan = parse_plan(json.dumps(ROBOTRUNNERS_2026))
    # agent 0: moves E on tick 3, waits, turns to S on tick 7, moves S on tick 10
    assert plan.paths[0] == ((2, 2),) * 3 + ((2, 3),) * 7 + ((3, 3),)
    assert plan.headings[0] == (0,) * 7 + (1,) * 4
    # agent 1: waits two ticks, then its counter runs 1, 2, 3 over F, C, C: it turns on tick 5
    # (the counter is the robot's, whatever the action), having never moved
    assert plan.paths[1] == ((0, 0),) * 6 and plan.headings[1] == (1,) * 5 + (0,)
    assert plan.meta["agentMaxCounter"] == 3


PATHS_JSON = {
    "agvs": {"0": {"type": "small", "footprint": 1, "ticks_per_move": 2},
             "1": {"type": "small", "footprint": 1, "ticks_per_move": 1}},
    "planned": [
        {"agv": 0, "tick": 0, "states": [[[1, 0], [1, 0]], [[1, 0], [2, 0]], [[2, 0], [2, 0]],
                                         [[2, 0], [3, 0]], [[3, 0], [3, 0]]]},
        {"agv": 1, "tick": 1, "states": [[[4, 4], [4, 4]], [[4, 5], [4, 5]]]},
        # AGV 0 replans at tick 2: from there on it goes right instead
        {"agv": 0, "tick": 2, "states": [[[2, 0], [2, 0]], [[2, 0], [2, 1]], [[2, 1], [2, 1]]]},
    ],
    "actual": {"0": [[[1, 0], [1, 0]], [[1, 0], [2, 0]], [[2, 0], [2, 0]]],
               "1": [[[4, 4], [4, 4]], [[4, 4], [4, 4]], [[4, 5], [4, 5]]]},
}


def test_paths_json_example_by_hand():
    text = json.dumps(PATHS_JSON)
    actual = parse_plan(text)
    assert actual.fmt == "paths_json"
    # a moving state [a, b] counts as cell a
    assert actual.paths == (((1, 0), (1, 0), (2, 0)), ((4, 4), (4, 4), (4, 5)))
    assert actual.meta["agvs"]["0"]["ticks_per_move"] == 2
    planned = parse_plan(text, which="planner")
    assert planned.paths == (((1, 0), (1, 0), (2, 0), (2, 0), (2, 1)),
                             ((4, 4), (4, 4), (4, 5)))


def test_paths_json_flat_nodes_need_cols():
    data = {"actual": {"0": [[5, 5], [5, 6], [6, 6]]}}
    with pytest.raises(PlanFormatError, match=r"actual\.0\[0\]\[0\].*cols"):
        parse_plan(json.dumps(data))
    assert parse_plan(json.dumps(data), cols=4).paths == (((1, 1), (1, 1), (1, 2)),)
    data["cols"] = 4
    assert parse_plan(json.dumps(data)).paths == (((1, 1), (1, 1), (1, 2)),)


def test_paths_json_agv_ids_kept():
    data = {"actual": {"7": [[[0, 0], [0, 0]]], "3": [[[1, 1], [1, 1]]]}}
    plan = parse_plan(json.dumps(data))
    assert plan.paths == (((1, 1),), ((0, 0),)) and plan.meta["agv_ids"] == [3, 7]
    back = json.loads(format_plan(plan, "paths_json"))
    assert set(back["actual"]) == {"3", "7"}


# ---------------------------------------------------------------- the Plan itself

def test_plan_trims_trailing_repeats_and_figures():
    plan = Plan(paths=([(0, 0), (0, 1), (0, 1), (0, 2), (0, 2)], [[3, 3]]))
    assert plan.paths == (((0, 0), (0, 1), (0, 1), (0, 2)), ((3, 3),))
    assert plan.costs == (3, 0) and plan.sum_of_costs == 3 and plan.makespan == 3
    assert plan.at(0, 99) == (0, 2) and plan.num_agents == 2
    turning = Plan(paths=(((0, 0), (0, 0), (0, 0)),), headings=((0, 1, 1),))
    assert turning.paths == (((0, 0), (0, 0)),) and turning.makespan == 1
    assert turning.sum_of_costs == 0  # turning in place on the goal costs nothing
    assert Plan(paths=()).makespan == 0
    # meta and fmt are provenance: not compared
    assert Plan(paths=(((1, 1),),), meta={"a": 1}, fmt="x") == Plan(paths=(((1, 1),),))


def test_plan_rejects_bad_shapes():
    with pytest.raises(ValueError):
        Plan(paths=((),))
    with pytest.raises(ValueError):
        Plan(paths=(((0, 0), (0, 1)),), headings=((0,),))
    with pytest.raises(ValueError):
        Plan(paths=(((0, 0),),), headings=((7,),))


# ---------------------------------------------------------------- round trips

CELL_FORMATS = ("lacam", "lns", "timed", "paths_json")
MAP_FORMATS = ("lacam", "paths_json")  # carry rows, cols and the map name


def _for(fmt: str, plan: Plan) -> Plan:
    """``plan`` without what ``fmt`` cannot carry."""
    if fmt in MAP_FORMATS:
        return plan
    return Plan(paths=plan.paths, headings=plan.headings)


@st.composite
def cell_plans(draw, max_agents: int = 6, max_len: int = 12):
    """Random plans: walks of 4-neighbour moves and waits (jumps too, sometimes)."""
    n = draw(st.integers(0, max_agents))
    paths = []
    for _ in range(n):
        r, c = draw(st.integers(0, 40)), draw(st.integers(0, 40))
        path = [(r, c)]
        for step in draw(st.lists(st.integers(0, 5), max_size=max_len)):
            if step < 4:
                dr, dc = HEADING_STEPS[step]
                r, c = max(0, r + dr), max(0, c + dc)
            elif step == 5:
                r, c = draw(st.integers(0, 9_999_000)), draw(st.integers(0, 50))
            path.append((r, c))
        paths.append(path)
    sized = draw(st.booleans())
    return Plan(paths=tuple(paths), rows=50 if sized else None, cols=60 if sized else None,
                map_name="m.map" if sized else None)


@st.composite
def heading_plans(draw, max_agents: int = 5, max_len: int = 15):
    """Random Robot Runners plans: F / R / C / W actions from random starts."""
    n = draw(st.integers(0, max_agents))
    paths, headings = [], []
    for _ in range(n):
        r, c, h = draw(st.integers(20, 30)), draw(st.integers(20, 30)), draw(st.integers(0, 3))
        cells, heads = [(r, c)], [h]
        for a in draw(st.lists(st.sampled_from("FRCW"), max_size=max_len)):
            if a == "F":
                r, c = r + HEADING_STEPS[h][0], c + HEADING_STEPS[h][1]
            elif a == "R":
                h = (h + 1) % 4
            elif a == "C":
                h = (h + 3) % 4
            cells.append((r, c))
            heads.append(h)
        paths.append(cells)
        headings.append(heads)
    return Plan(paths=tuple(paths), headings=tuple(headings))


FIXED = Plan(paths=(((1, 0), (1, 1), (1, 1), (2, 1)), ((5, 5),), ((0, 3), (0, 2))),
             rows=10, cols=12, map_name="fixed.map")


@pytest.mark.parametrize("fmt", CELL_FORMATS)
def test_fixed_plan_round_trips(fmt, tmp_path):
    path = tmp_path / f"plan.{fmt}"
    write_plan(FIXED, path, fmt)
    assert read_plan(path) == _for(fmt, FIXED)
    assert read_plan(path, fmt).fmt == fmt
    assert [p.name for p in tmp_path.iterdir()] == [path.name]  # no temporary file left


@pytest.mark.parametrize("fmt", CELL_FORMATS)
@settings(max_examples=60, deadline=None)
@given(plan=cell_plans())
def test_random_plans_round_trip(fmt, plan):
    if fmt in ("lns", "timed") and not plan.num_agents:
        with pytest.raises(PlanFormatError, match="no agents"):
            format_plan(plan, fmt)
        return
    text = format_plan(plan, fmt)
    assert parse_plan(text, fmt) == _for(fmt, plan)
    if plan.num_agents:
        assert detect_format(text) == fmt
        assert parse_plan(text) == _for(fmt, plan)


@settings(max_examples=60, deadline=None)
@given(plan=cell_plans())
def test_random_plans_round_trip_timed_row_col(plan):
    if not plan.num_agents:
        return
    text = format_plan(plan, "timed", xy=False)
    assert parse_plan(text, "timed", xy=False) == _for("timed", plan)


@settings(max_examples=100, deadline=None)
@given(plan=heading_plans())
def test_random_robotrunners_plans_round_trip(plan):
    text = format_plan(plan, "robotrunners")
    back = parse_plan(text)
    assert back == plan and back.headings == plan.headings
    assert detect_format(text) == "robotrunners"
    # and through the cell formats, the cells survive
    for fmt in CELL_FORMATS if plan.num_agents else ("lacam", "paths_json"):
        assert parse_plan(format_plan(plan, fmt), fmt).paths == Plan(paths=plan.paths).paths


def test_robotrunners_without_headings_turns_during_waits():
    # right, wait (turn to S), down, wait, wait (U-turn to N), up
    plan = Plan(paths=(((0, 0), (0, 1), (0, 1), (1, 1), (1, 1), (1, 1), (0, 1)),))
    data = json.loads(format_plan(plan, "robotrunners"))
    assert data["start"] == [[0, 0, "E"]]
    assert data["actualPaths"] == ["F,R,F,R,R,F"]
    assert data["teamSize"] == 1 and data["sumOfCost"] == 6
    back = parse_plan(json.dumps(data))
    assert back.paths == plan.paths and back.headings == ((0, 0, 1, 1, 2, 3, 3),)


def test_robotrunners_writer_refuses_instant_turns():
    plan = Plan(paths=(((0, 0), (0, 1), (1, 1)),))  # E then S with no time to turn
    with pytest.raises(PlanFormatError, match=r"paths\[0\]\[2\].*moves S at t=1 while facing E"):
        format_plan(plan, "robotrunners")
    jump = Plan(paths=(((0, 0), (2, 2)),))
    with pytest.raises(PlanFormatError, match="4-neighbour"):
        format_plan(jump, "robotrunners")
    u_turn = Plan(paths=(((0, 0), (0, 0)),), headings=((0, 2),))
    with pytest.raises(PlanFormatError, match="180 degrees"):
        format_plan(u_turn, "robotrunners")
    sideways = Plan(paths=(((0, 0), (1, 0)),), headings=((0, 0),))
    with pytest.raises(PlanFormatError, match="forward"):
        format_plan(sideways, "robotrunners")


def test_lacam_and_lns_read_to_the_same_plan():
    plan = Plan(paths=(((3, 3), (3, 4), (4, 4)), ((0, 0), (0, 0), (1, 0), (1, 1))))
    assert parse_plan(format_plan(plan, "lacam")) == parse_plan(format_plan(plan, "lns"))
    assert parse_plan(format_plan(plan, "lacam")) == plan


def test_lacam_writer_header():
    text = format_plan(FIXED, "lacam")
    head = text.split("solution=")[0].splitlines()
    assert head[:5] == ["agents=3", "map_file=fixed.map", "width=12", "height=10", "soc=4"]
    assert "makespan=3" in head
    assert text.splitlines()[-1] == "3:(1,2),(5,5),(2,0),"


def test_writers_refuse_bad_cells():
    with pytest.raises(PlanFormatError, match=r"paths\[0\]\[1\]"):
        format_plan(Plan(paths=(((0, 0), (-1, 0)),)), "lns")
    with pytest.raises(PlanFormatError, match="unknown plan format"):
        format_plan(FIXED, "yaml")


def test_write_plan_failure_leaves_nothing(tmp_path):
    target = tmp_path / "out.json"
    with pytest.raises(PlanFormatError):
        write_plan(Plan(paths=(((0, 0), (0, 1), (1, 1)),)), target, "robotrunners")
    assert list(tmp_path.iterdir()) == []
    write_plan(FIXED, target, "lns")
    old = target.read_text()
    with pytest.raises(PlanFormatError):
        write_plan(Plan(paths=(((0, 0), (0, 1), (1, 1)),)), target, "robotrunners")
    assert target.read_text() == old


# ---------------------------------------------------------------- malformed input

HEADER = "agents=2\nsolution=\n"
RR = {"teamSize": 1, "start": [[0, 0, "E"]], "actualPaths": ["F"]}


def rr(**changes) -> str:
    return json.dumps({**RR, **changes})


MALFORMED = [
    # (format or None, text, what the message must contain)
    (None, "", "empty file"),
    (None, "\n \n", "empty file"),
    (None, "hello world\n", "line 1"),
    (None, "\x00\x01\x02garbage", "binary"),
    ("lacam", "", "empty file"),
    ("lacam", "agents=2\nmap_file=x.map\n", "no 'solution=' line"),
    ("lacam", "agents=2\nthis is not a header\nsolution=\n", "line 2"),
    ("lacam", "agents=1\n0:(1,1),\n", "line 2: a timestep line before 'solution='"),
    ("lacam", "agents=two\nsolution=\n", "line 1"),
    ("lacam", "agents=2\nagents=2\nsolution=\n", "duplicate"),
    ("lacam", HEADER + "0:(1,2),(3,4),\n1:(1,2),\n", "line 4: 1 cells on the line but 2"),
    ("lacam", HEADER + "0:(1,2),(3,4),\n1:(1,2),(3,", "line 4: unclosed tuple"),
    ("lacam", HEADER + "0:(1,2),(3,4),\n1:(1,x),(3,4),\n", "line 4: not an integer"),
    ("lacam", HEADER + "0:(1,2),(3,-4),\n", "line 3: negative coordinate"),
    ("lacam", HEADER + "0:(1,2),(3,4),\n2:(1,2),(3,4),\n", "line 4: timestep out of order"),
    ("lacam", HEADER + "1:(1,2),(3,4),\n", "line 3: timestep out of order"),
    ("lacam", HEADER + "0:(1,2),(123456789012345678901234567890,4),\n", "number too large"),
    ("lacam", HEADER + "0:(1,2)(3,4),\n", "line 3: expected ','"),
    ("lacam", HEADER + "0:(1,2,3),(3,4),\n", "expected 2 numbers"),
    ("lacam", HEADER + "zero:(1,2),(3,4),\n", "line 3: expected a timestep line"),
    ("lacam", "makespan=5\n" + HEADER + "0:(1,2),(3,4),\n1:(1,3),(3,4),\n",
     "line 1: makespan=5 but the solution has 2"),
    ("lacam", "agents=2\nstarts=(1,2),\nsolution=\n", "line 2: starts= lists 1"),
    ("lns", "Agent 0:(1,2)->(1,3)->\nAgent 0:(1,2)->\n", "line 2: agent 0 again"),
    ("lns", "Agent 0:(1,2)->\nAgent 2:(1,2)->\n", "agent 1 is missing"),
    ("lns", "Agent 0:(1,2)->(1,3\n", "line 1: unclosed tuple"),
    ("lns", "Agent 0:\n", "line 1: agent 0 has an empty path"),
    ("lns", "Agent 0:(1,2)->(1,2.5)->\n", "line 1: not an integer"),
    ("lns", "Agents:(1,2)\n", "line 1: expected 'Agent <id>:'"),
    ("lns", "Agent 0:(1,2)=>(1,3)\n", "line 1: expected '->'"),
    ("timed", "Agent 0:(1,2,0)->(1,3,2)->(1,4,2)->\n", "line 1: agent 0: timesteps must "
                                                      "strictly increase"),
    ("timed", "Agent 0:(1,2,0)->(1,3,99999999)->\n", "number too large"),
    ("timed", "Agent 0:(1,2,0)->(1,3,9999999)->\n", "line 1: timestep too large"),
    ("timed", "Agent 0:(1,2)->\n", "expected 3 numbers"),
    ("robotrunners", "[1, 2, 3]", "expected a JSON object"),
    ("robotrunners", '{"teamSize": 1, "start": [[0, 0, "E"]], "actualPaths": ["F"', "not valid "
                                                                                     "JSON"),
    ("robotrunners", rr(start=None), "start: expected a list"),
    ("robotrunners", json.dumps({"teamSize": 1, "start": [[0, 0, "E"]]}), "actualPaths: "
                                                                          "missing key"),
    ("robotrunners", rr(actualPaths=["F,X"]), "actualPaths[0]: unknown action"),
    ("robotrunners", rr(actualPaths=[7]), "actualPaths[0]: expected a string"),
    ("robotrunners", rr(start=[[0, 0, "Q"]]), "start[0][2]: heading"),
    ("robotrunners", rr(start=[[0, -3, "E"]]), "start[0][1]: column must be at least 0"),
    ("robotrunners", rr(start=[[0, 1e30, "E"]]), "start[0][1]: expected column"),
    ("robotrunners", rr(start=[[0, 10**30, "E"]]), "start[0][1]: column too large"),
    ("robotrunners", rr(teamSize=3), "teamSize: teamSize=3 but start has 1"),
    ("robotrunners", rr(actualPaths=["F", "F"]), "actualPaths: 2 paths but start has 1"),
    ("robotrunners", rr(start=[[0, 0, "N"]]), "leaves the map"),
    ("robotrunners", rr(actualPaths=["[(0,0,0,0,0):(F 3)][(2,0,0,0,0):(W 1)]"]),
     "actualPaths[0]: segment starts at tick 2 but the segments before it cover 3"),
    ("robotrunners", rr(actualPaths=["[(0,0,0,0,0):(F 3)"]), "actualPaths[0]: expected a "
                                                             "segment"),
    ("robotrunners", rr(actualPaths=["[(0,0,0,0,0):(F 3,X 2)]"]), "expected 'A n'"),
    ("robotrunners", rr(actualPaths=["[(0,1,0,0,0):(F 3)]"]), "not at the agent's start"),
    ("robotrunners", rr(actualPaths=["[(0,0,0,0,5):(F 3)]"], agentMaxCounter=3),
     "counter 5 must be below agentMaxCounter=3"),
    ("robotrunners", rr(agentMaxCounter=0), "agentMaxCounter: ticks per action must be at "
                                            "least 1"),
    ("robotrunners", rr(actualPaths=["[(0,0,0,0,0):(F 3)]"]), None),  # valid
    ("robotrunners", rr(), None),  # control: valid
    ("paths_json", "{}", "actual: missing key"),
    ("paths_json", '{"actual": []}', "actual: expected an object"),
    ("paths_json", '{"actual": {"a": []}}', "actual.a: AGV ids"),
    ("paths_json", '{"actual": {"0": []}}', "actual.0: empty list"),
    ("paths_json", '{"actual": {"0": [[[1, 2]]]}}', "actual.0[0]: expected a state"),
    ("paths_json", '{"actual": {"0": [[[1, "2"], [1, 2]]]}}', "actual.0[0][0][1]"),
    ("paths_json", '{"actual": {"0": [[[1, 2], [1, 2]]]}, "cols": 0}', "cols: cols must be"),
    ("paths_json", '{"planned": [{"agv": 0, "states": []}]}', "planned[0].tick: missing key"),
    ("paths_json", '{"planned": [{"agv": 0, "tick": -1, "states": [[[0,0],[0,0]]]}]}',
     "planned[0].tick: tick must be at least 0"),
    (None, '{"foo": 1}', "neither actualPaths"),
    (None, "[" * 100000, "not valid JSON"),
]


@pytest.mark.parametrize(("fmt", "text", "expected"), MALFORMED,
                         ids=[f"{i}-{m[0]}" for i, m in enumerate(MALFORMED)])
def test_malformed_input_raises_plan_format_error(fmt, text, expected, monkeypatch):
    monkeypatch.setattr(formats_module, "_SAFETY_NET", False)
    which = "planner" if fmt == "paths_json" and "planned" in text else "actual"
    if expected is None:
        parse_plan(text, fmt, source="bad.plan", which=which)
        return
    with pytest.raises(PlanFormatError) as info:
        parse_plan(text, fmt, source="bad.plan", which=which)
    message = str(info.value)
    assert "\n" not in message and message.startswith("bad.plan")
    assert expected in message
    assert len(message) < 300


def test_enough_malformed_cases():
    assert sum(1 for m in MALFORMED if m[2] is not None) >= 25


def test_file_level_errors(tmp_path, monkeypatch):
    binary = tmp_path / "garbage.bin"
    binary.write_bytes(bytes(range(256)) * 4)
    with pytest.raises(PlanFormatError, match="garbage.bin: byte 0: binary"):
        read_plan(binary)
    latin = tmp_path / "latin.txt"
    latin.write_bytes(b"agents=1\nmap_file=caf\xe9.map\nsolution=\n0:(1,1),\n")
    with pytest.raises(PlanFormatError, match="byte 21: not UTF-8"):
        read_plan(latin)
    with pytest.raises(PlanFormatError, match="plan file not found"):
        read_plan(tmp_path / "missing.txt")
    big = tmp_path / "big.txt"
    big.write_text(format_plan(FIXED, "lns"))
    monkeypatch.setattr(formats_module, "MAX_FILE_BYTES", 10)
    with pytest.raises(PlanFormatError, match="file too large"):
        read_plan(big)
    with pytest.raises(PlanFormatError, match="unknown plan format"):
        parse_plan("x", "csv")
    with pytest.raises(PlanFormatError, match="which: must be 'actual' or 'planner'"):
        parse_plan(LNS, which="executed")


def test_huge_expansion_is_refused(monkeypatch):
    from warerover_phys.plans import agentlines, lacam
    monkeypatch.setattr(agentlines, "MAX_CELLS", 1000)
    monkeypatch.setattr(lacam, "MAX_CELLS", 1000)
    with pytest.raises(PlanFormatError, match="line 3: plan too large"):
        parse_plan("\n".join(f"Agent {i}:(0,0,0)->(0,1,400)->" for i in range(8)))
    with pytest.raises(PlanFormatError, match="line 2: plan too large"):
        parse_plan("\n".join(f"Agent {i}:" + "(0,0)->" * 600 for i in range(8)))
    with pytest.raises(PlanFormatError, match="line 8: plan too large"):
        parse_plan("agents=200\nsolution=\n" + "".join(
            f"{t}:" + "(1,1)," * 200 + "\n" for t in range(8)))


# ---------------------------------------------------------------- mutations never crash

def _valid_texts() -> list[str]:
    rr_plan = Plan(paths=(((1, 1), (1, 2), (1, 2), (2, 2)),), headings=((0, 0, 1, 1),))
    return [format_plan(FIXED, fmt) for fmt in CELL_FORMATS] + [
        format_plan(FIXED, "timed", xy=False), format_plan(rr_plan, "robotrunners"),
        LACAM, LNS, TIMED, json.dumps(ROBOTRUNNERS), json.dumps(ROBOTRUNNERS_2026),
        json.dumps(PATHS_JSON)]


VALID_TEXTS = _valid_texts()
GARBAGE = st.text(alphabet=st.sampled_from(list("0123456789(),:->=[]{}\"-. \nAgentFRCW\x00é")),
                  min_size=1, max_size=12)


@st.composite
def mutated(draw):
    text = draw(st.sampled_from(VALID_TEXTS))
    for _ in range(draw(st.integers(1, 3))):
        kind = draw(st.sampled_from(["truncate", "flip", "insert", "delete"]))
        pos = draw(st.integers(0, len(text)))
        if kind == "truncate":
            text = text[:pos]
        elif kind == "flip" and pos < len(text):
            data = bytearray(text.encode("utf-8"))
            i = min(pos, len(data) - 1)
            data[i] ^= 1 << draw(st.integers(0, 7))
            text = data.decode("utf-8", errors="replace")
        elif kind == "insert":
            text = text[:pos] + draw(GARBAGE) + text[pos:]
        else:
            text = text[:pos] + text[pos + draw(st.integers(1, 5)):]
    return text


# 400 examples: fuzzed file mutations, one cheap parse each
@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(text=mutated(), fmt=st.sampled_from([None, *FORMATS]), xy=st.booleans(),
       which=st.sampled_from(["actual", "planner"]))
def test_mutations_raise_only_plan_format_error(text, fmt, xy, which, monkeypatch_session):
    try:
        plan = parse_plan(text, fmt, xy=xy, which=which)
    except PlanFormatError as err:
        assert "\n" not in str(err)
        return
    assert isinstance(plan, Plan)


# 200 examples: random bytes, one cheap parse each
@settings(max_examples=200, deadline=None)
@given(data=st.binary(max_size=200))
def test_random_bytes_raise_only_plan_format_error(data, tmp_path_factory, monkeypatch_session):
    path = tmp_path_factory.mktemp("bytes") / "plan.bin"
    path.write_bytes(data)
    try:
        read_plan(path)
    except PlanFormatError:
        pass


@pytest.fixture(scope="module")
def monkeypatch_session():
    """Reader bugs must surface in these tests, not hide behind the safety net."""
    mp = pytest.MonkeyPatch()
    mp.setattr(formats_module, "_SAFETY_NET", False)
    yield mp
    mp.undo()


# ---------------------------------------------------------------- docs and real output

@pytest.mark.parametrize("module", ["warerover_phys.plans.formats",
                                    "warerover_phys.plans.model"])
def test_docstring_examples(module):
    import importlib
    result = doctest.testmod(importlib.import_module(module))
    assert result.attempted > 0 and result.failed == 0


def _lacam3() -> str | None:
    root = Path(__file__).resolve().parents[2]
    for candidate in (os.environ.get("LACAM3_BIN"), root / "build" / "lacam3" / "main"):
        if candidate and Path(candidate).is_file() and os.access(candidate, os.X_OK):
            return str(candidate)
    return shutil.which("lacam3")


@pytest.mark.skipif(_lacam3() is None, reason="lacam3 binary not built (set LACAM3_BIN or "
                    "build it into build/lacam3, see /work/shared/reference/README.md)")
def test_reads_real_lacam3_output(tmp_path):
    out = tmp_path / "result.txt"
    subprocess.run([_lacam3(), "-m", str(DATA / "random-32-32-10.map"),
                    "-i", str(DATA / "random-32-32-10-random-1.scen"), "-N", "30", "-t", "5",
                    "--no-star", "-v", "0", "-o", str(out)], check=True, timeout=60,
                   capture_output=True)
    plan = read_plan(out)
    assert plan.fmt == "lacam" and plan.num_agents == 30 and plan.meta["solved"] == 1
    assert plan.map_name == "random-32-32-10.map"
    assert plan.sum_of_costs == plan.meta["soc"] and plan.makespan == plan.meta["makespan"]
    scen = [line.split("\t") for line in
            (DATA / "random-32-32-10-random-1.scen").read_text().splitlines()[1:31]]
    for path, fields, start, goal in zip(plan.paths, scen, plan.meta["starts"],
                                         plan.meta["goals"], strict=True):
        assert path[0] == (int(fields[5]), int(fields[4])) == tuple(start)  # scen: x, y
        assert path[-1] == (int(fields[7]), int(fields[6])) == tuple(goal)
        assert all(abs(a[0] - b[0]) + abs(a[1] - b[1]) <= 1 for a, b in zip(path, path[1:], strict=False))
    for fmt in CELL_FORMATS:  # and it survives every format without turns
        assert parse_plan(format_plan(plan, fmt), fmt).paths == plan.paths


def test_reads_paths_json_of_a_real_episode(tmp_path):
    """``warerover run``'s own output: executed cells equal the stitched committed plans on
    the ideal grid executor (slow 2x2 AGVs included), and survive every cell format."""
    from warerover_phys import load_scenario, run_episode, write_outputs

    root = Path(__file__).resolve().parents[2]
    scenario = load_scenario(root / "layouts" / "paper_heterogeneous.yaml",
                             [("max_ticks", 80)])
    result = run_episode(scenario, seed=1)
    files = write_outputs(result, tmp_path)
    actual = read_plan(files["paths"])
    planned = read_plan(files["paths"], which="planner")
    lay = result.world.layout
    assert actual.num_agents == planned.num_agents == len(result.world.agvs)
    for i, agv in enumerate(sorted(result.world.agvs, key=lambda a: a.id)):
        states = result.actual[agv.id]
        assert actual.at(i, len(states) - 1) == divmod(states[-1][0], lay.cols)
        common = min(len(actual.paths[i]), len(planned.paths[i]))
        assert actual.paths[i][:common] == planned.paths[i][:common]
    assert actual.meta["agvs"]["0"]["ticks_per_move"] >= 1
    for fmt in CELL_FORMATS:
        assert parse_plan(format_plan(actual, fmt), fmt).paths == actual.paths
