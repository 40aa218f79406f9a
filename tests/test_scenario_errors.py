"""Bad scenarios: every one must end the CLI with exit code 2 and ONE line on stderr that
names the file and the field path (``FILE: FIELD: MESSAGE (got VALUE)``), never a traceback.

Each malformed scenario is written to its own temporary folder. Every case is loaded and
built in-process (``load_scenario`` + ``World.build``) and its error checked field by field;
the cases marked ``cli`` (all the required ones and the bugs) also go through the real
``warerover`` console script. Those subprocesses are started together by a module fixture
(each costs about a second, mostly imports) and one test per case checks its result.
"""

from __future__ import annotations

import copy
import os
import shutil
import subprocess
import sys
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
import yaml

from warerover_phys.config import load_scenario, parse_override, scenario_from_dict
from warerover_phys.errors import LayoutError, ScenarioError
from warerover_phys.registry import check_plugins
from warerover_phys.world import World

REPO = Path(__file__).resolve().parent.parent
LAYOUTS = REPO / "layouts"
WAREROVER = Path(sys.executable).parent / "warerover"

# A tiny valid scenario: 2 stations, 2 shelves, 2 parking spots, 1-wide aisles.
TINY_GRID = [
    "#########",
    "#R.....P#",
    "#..S.S..#",
    "#R.....P#",
    "#########",
]
BASE: dict[str, Any] = {
    "name": "tiny",
    "seed": 0,
    "max_ticks": 200,
    "layout": {"grid": TINY_GRID},
    "fleet": {"types": {"agv": {"footprint": 1, "body_m": [0.7, 0.7], "max_speed_mps": 1.5}},
              "agvs": [{"type": "agv", "count": 2}]},
    "orders": {"pattern": "oneshot", "oneshot": {"count": 3}},
}


def cli_env() -> dict[str, str]:
    """A narrow, colourless terminal: the one-line error must not be wrapped or styled."""
    env = {k: v for k, v in os.environ.items() if k not in ("FORCE_COLOR", "CLICOLOR_FORCE")}
    env.update(COLUMNS="60", NO_COLOR="1", TERM="dumb")
    return env


def run_cli(*args: str | Path, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([str(WAREROVER), *map(str, args)], cwd=cwd, env=cli_env(),
                          capture_output=True, text=True, timeout=120)


# ------------------------------------------------------------------------ scenario builders

Builder = Callable[[Path, str], Path]
"""Writes a scenario (and any files it needs) into a folder; returns the scenario path."""


def dump(path: Path, data: Any) -> Path:
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


def tiny(change: Callable[[dict[str, Any]], Any] | None = None) -> Builder:
    """The tiny scenario, changed in place by ``change``."""
    def build(folder: Path, name: str) -> Path:
        data = copy.deepcopy(BASE)
        if change is not None:
            change(data)
        return dump(folder / f"{name}.yaml", data)
    return build


def text(content: str | bytes) -> Builder:
    def build(folder: Path, name: str) -> Path:
        path = folder / f"{name}.yaml"
        if isinstance(content, bytes):
            path.write_bytes(content)
        else:
            path.write_text(content, encoding="utf-8")
        return path
    return build


def paper(change_layout: Callable[[dict[str, Any]], Any] | None = None, *,
          layout_text: str | None = None, with_layout: bool = True) -> Builder:
    """paper_homogeneous.yaml and its layout file copied into the folder (scenario renamed)."""
    def build(folder: Path, name: str) -> Path:
        scen = folder / f"{name}.yaml"
        shutil.copy(LAYOUTS / "paper_homogeneous.yaml", scen)
        if with_layout:
            (folder / "maps").mkdir()
            lay = folder / "maps" / "paper_20x15.yaml"
            shutil.copy(LAYOUTS / "maps" / "paper_20x15.yaml", lay)
            if change_layout is not None:
                data = yaml.safe_load(lay.read_text(encoding="utf-8"))
                change_layout(data)
                dump(lay, data)
            if layout_text is not None:
                lay.write_text(layout_text, encoding="utf-8")
        return scen
    return build


def set_(path: list[Any], value: Any) -> Callable[[dict[str, Any]], None]:
    def change(data: dict[str, Any]) -> None:
        node = data
        for key in path[:-1]:
            node = node[key]
        node[path[-1]] = value
    return change


def agv(**fields: Any) -> Callable[[dict[str, Any]], None]:
    return lambda d: d["fleet"]["types"]["agv"].update(fields)


def grid(*rows: str, count: int | None = None) -> Callable[[dict[str, Any]], None]:
    def change(d: dict[str, Any]) -> None:
        d["layout"] = {"grid": list(rows)}
        if count is not None:
            d["fleet"]["agvs"][0]["count"] = count
    return change


def too_big_for_aisles(k: int) -> Callable[[dict[str, Any]], None]:
    """A k x k shelf and a k x k parking spot in a room; the only station lies behind a
    1-cell-wide gap in a wall. Valid for k = 1 (see test_too_big_map_is_valid_for_1x1)."""
    def change(d: dict[str, Any]) -> None:
        width, height = 12, k + 2
        rows = ["#" * width, "#R" + "." * (width - 3) + "#", "#####.######"]
        rows += ["#" + "." * (width - 2) + "#" for _ in range(height)] + ["#" * width]
        d["layout"] = {"grid": rows, "shelf_blocks": [{"origin": [4, 1], "size": k}],
                       "parking": [{"origin": [4, width - 2 - k], "rows": k, "cols": k}]}
        d["fleet"]["types"]["agv"].update(footprint=k, body_m=[k - 0.3, k - 0.3])
        d["fleet"]["agvs"][0]["count"] = 1
    return change


# ------------------------------------------------------------------------------- the cases


@dataclass(frozen=True)
class Case:
    id: str
    build: Builder
    field: str | None
    """Expected field path: ``err.field`` in-process, ``": FIELD: "`` in the CLI line
    (None: the error is about the file as a whole)."""
    says: tuple[str, ...] = ()
    """Further text the line must contain (message, value)."""
    args: tuple[str, ...] = ()
    """CLI options (--set, --seed, --scheduler, --orders); in-process they become overrides."""
    names: str | None = None
    """File name the line must name (default: the scenario file's)."""
    absent: tuple[str, ...] = ()
    cli: bool = False
    """Also run ``warerover run`` in a subprocess."""
    check_too: bool = False
    """Also run ``warerover check`` (which takes only --set)."""
    in_process: bool = True
    bug: str | None = None


CASES = [
    # ---- schema
    Case("unknown-top-level-key", tiny(set_(["colour"], "red")), "colour",
         ("unknown key", "'red'"), cli=True),
    Case("unknown-nested-key", tiny(agv(wheels=4)), "fleet.types.agv.wheels", ("unknown key",),
         cli=True),
    Case("negative-speed", tiny(agv(max_speed_mps=-1.0)), "fleet.types.agv.max_speed_mps",
         ("greater than 0", "(got -1.0)"), cli=True),
    Case("seed-not-an-int", tiny(set_(["seed"], "abc")), "seed", ("integer", "'abc'"), cli=True),
    Case("unknown-scheduler", tiny(set_(["scheduler"], "fifo")), "scheduler.name",
         ("unknown scheduler", "['errands', 'rd', 'ta']", "'fifo'"), cli=True),
    Case("unknown-order-pattern", tiny(set_(["orders", "pattern"], "zigzag")), "orders.pattern",
         ("'zigzag'",), cli=True),
    Case("unknown-agv-type", tiny(set_(["fleet", "agvs", 0, "type"], "big")), "fleet",
         ("agvs[0].type 'big'",)),
    Case("fleet-missing", tiny(lambda d: d.pop("fleet")), "fleet", ("required",)),
    Case("starts-do-not-match-count", tiny(set_(["fleet", "agvs", 0, "starts"], [[1, 7]])),
         "fleet.agvs[0]", ("starts lists 1 cells for count 2",)),
    Case("wave-min-above-max", tiny(set_(["orders"], {"pattern": "wave",
                                                      "wave": {"min_mult": 3, "max_mult": 1}})),
         "orders.wave", ("min_mult",)),
    Case("two-layout-bases", tiny(set_(["layout", "size"], [5, 9])), "layout",
         ("give exactly one of", "size, grid"), cli=True),
    # ---- file level
    Case("bad-yaml-syntax", text("name: x\nlayout: {grid: [\n  fleet: : :\n"), None,
         ("invalid YAML", "line 3"), cli=True),
    Case("empty-file", text(""), None, ("scenario file is empty",), cli=True),
    Case("comments-only-file", text("# nothing here\n\n"), None, ("scenario file is empty",)),
    Case("top-level-list", text("- a\n- b\n"), None, ("must be a YAML mapping", "'list'")),
    Case("not-utf8", text(b"name: caf\xe9\n"), None, ("not UTF-8",)),
    Case("scenario-file-missing", lambda folder, name: folder / f"{name}.yaml", None,
         ("scenario file not found",)),
    Case("missing-layout-file", paper(with_layout=False), "layout",
         ("layout file not found", "'maps/paper_20x15.yaml'"), cli=True),
    Case("layout-file-bad-yaml", paper(layout_text="size: [15, 20]\nstations: [[3, 0]\n"),
         None, ("invalid YAML",), names="paper_20x15.yaml"),
    # ---- layout
    Case("layout-file-unknown-key", paper(set_(["bogus"], 1)), "layout.bogus", ("unknown key",)),
    Case("station-outside-map", paper(set_(["stations", 0], [3, 25])), "layout.stations[0]",
         ("outside the 15x20 layout", "[3, 25]")),
    Case("station-on-obstacle", tiny(set_(["layout", "stations"], [[0, 4]])),
         "layout.stations[0]", ("already obstacle", "[0, 4]")),
    Case("shelf-block-outside-map",
         paper(set_(["shelf_blocks", 1], {"origin": [4, 17], "rows": 2, "cols": 4})),
         "layout.shelf_blocks[1]", ("outside the 15x20 layout",), cli=True),
    Case("ragged-grid", tiny(set_(["layout", "grid", 2], "#..S.S.#")), "layout.grid[2]",
         ("row 2 has 8 cells",)),
    Case("station-walled-in",
         tiny(grid("#########",
                   "#R#....P#",
                   "##.S.S..#",
                   "#R.....P#",
                   "#########")), "layout.stations[0]", ("station [1, 1]", "(got [1, 1])"),
         cli=True, check_too=True),
    Case("parking-walled-in",
         tiny(grid("#########",
                   "#R.....P#",
                   "#..S.S.##",
                   "#R....#P#",
                   "#########", count=1)), "layout.parking", ("(got [3, 7])",)),
    Case("shelf-block-walled-in", tiny(lambda d: d.update(layout={
        "grid": ["#########",
                 "#R.....P#",
                 "#...#...#",
                 "#..#.#..#",
                 "#...#...#",
                 "#R.....P#",
                 "#########"],
        "shelf_blocks": [{"origin": [3, 1]}, {"origin": [3, 4]}]})),
        "layout.shelf_blocks[1]", ("[3, 4]",)),
    Case("grid-shelf-walled-in",
         tiny(grid("#########",
                   "#R.....P#",
                   "#...#...#",
                   "#.S#S#..#",
                   "#...#...#",
                   "#R.....P#",
                   "#########")), "layout.grid[3]", ("shelf 1 at [3, 4]", "(got [3, 4])"),
         absent=("layout.shelf_blocks",), cli=True),
    # ---- fleet
    Case("footprint-2-wider-than-aisles", tiny(too_big_for_aisles(2)),
         "fleet.types.agv.footprint", ("2x2", "station [1, 1]"), cli=True),
    Case("footprint-3-wider-than-aisles", tiny(too_big_for_aisles(3)),
         "fleet.types.agv.footprint", ("3x3", "station [1, 1]"), cli=True),
    Case("too-many-agvs-for-parking", tiny(set_(["fleet", "agvs", 0, "count"], 5)),
         "fleet.agvs[0].count", ("parking", "(got 5)"), cli=True),
    Case("paper-10-agvs-9-parking-spots", paper(), "fleet.agvs[0].count",
         ("parking", "(got 10)"), args=("--set", "fleet.agvs.0.count=10")),
    Case("body-larger-than-footprint", tiny(agv(body_m=[1.2, 0.7])), "fleet.types.agv.body_m",
         ("1x1 footprint", "[1.2, 0.7]"), cli=True),
    Case("body-larger-than-small-cells", tiny(set_(["layout", "cell_m"], 0.5)),
         "fleet.types.agv.body_m", ("0.5 m cells",)),
    Case("start-on-a-wall", tiny(set_(["fleet", "agvs", 0, "starts"], [[0, 0], [1, 7]])),
         "fleet.agvs[0].starts[0]", ("[0, 0]",)),
    Case("start-outside-map", tiny(set_(["fleet", "agvs", 0, "starts"], [[99, 99], [1, 7]])),
         "fleet.agvs[0].starts[0]", ("[99, 99]",)),
    Case("1x1-fleet-cut-off-from-station",
         tiny(grid("#########",
                   "#R.S.#.P#",
                   "#########", count=1)), "layout.stations[0]", ("station [1, 1]",),
         absent=("footprint",), cli=True),
    # ---- command line overrides
    Case("set-bad-list-index", tiny(), "fleet.agvs.7.count", ("no such list item", "'7'"),
         args=("--set", "fleet.agvs.7.count=2"), cli=True, check_too=True),
    Case("set-unknown-key", tiny(), "orders.foo", ("unknown key",),
         args=("--set", "orders.foo=2")),
    Case("set-inside-plain-value", tiny(), "seed.x", ("plain value",),
         args=("--set", "seed.x=2")),
    Case("set-wrong-type", tiny(), "fleet.agvs[0].count", ("integer", "'abc'"),
         args=("--set", "fleet.agvs.0.count=abc")),
    Case("set-without-equals", tiny(), "--set", ("field.path=value",), args=("--set", "seed"),
         cli=True, in_process=False),
    Case("named-scheduler-flag", tiny(), "scheduler.name", ("'fifo'",),
         args=("--scheduler", "fifo")),
    Case("named-orders-flag", tiny(), "orders.pattern", ("'zigzag'",),
         args=("--orders", "zigzag")),
    Case("negative-seed-flag", tiny(), "seed", ("(got -1)",), args=("--seed", "-1")),
    # ---- errors raised while building the world must still name the scenario file
    Case("generator-stations-and-parking-same-side",
         tiny(set_(["layout"], {"generator": {"block_rows": 1, "block_cols": 1,
                                              "station_side": "left",
                                              "parking_side": "left"}})),
         "layout.generator.parking_side", ("different sides",), cli=True),
    Case("generator-too-many-stations",
         tiny(set_(["layout"], {"generator": {"block_rows": 1, "block_cols": 1,
                                              "stations": 500}})),
         "layout.generator.stations", ("(got 500)",)),
    Case("map-file-missing", tiny(set_(["layout"], {"map": "nope.map"})), "layout.map",
         ("not found", "nope.map"), cli=True),
]
CLI_CASES = [c for c in CASES if c.cli]


def _params(cases: list[Case]) -> list[Any]:
    return [pytest.param(c, id=c.id, marks=[pytest.mark.xfail(strict=True, reason=c.bug)]
                         if c.bug else []) for c in cases]


def _overrides(args: tuple[str, ...]) -> list[tuple[str, Any]]:
    """The overrides the CLI makes of ``args`` (for the in-process runs)."""
    named = {"--seed": "seed", "--scheduler": "scheduler.name", "--orders": "orders.pattern"}
    out = []
    for opt, value in zip(args[::2], args[1::2], strict=True):
        if opt == "--set":
            out.append(parse_override(value))
        else:
            out.append((named[opt], int(value) if opt == "--seed" else value))
    return out


def assert_error_line(line: str, case: Case, path: Path) -> None:
    """``line`` is ``FILE: FIELD: MESSAGE (got VALUE)`` for ``case``."""
    assert "\n" not in line
    name = case.names or path.name
    assert f"{name}: " in line, f"file {name!r} not named: {line}"
    assert "<scenario>" not in line, line
    if case.field is not None:
        assert f": {case.field}: " in line, f"field {case.field!r} not named: {line}"
    for part in case.says:
        assert part in line, f"{part!r} not in: {line}"
    for part in case.absent:
        assert part not in line, f"{part!r} should not be in: {line}"


@pytest.mark.parametrize("case", _params([c for c in CASES if c.in_process]))
def test_bad_scenario_error_in_process(case: Case, tmp_path: Path) -> None:
    """load_scenario + World.build + check_plugins raise a ScenarioError naming the file and
    exact field."""
    path = case.build(tmp_path, case.id)
    with pytest.raises(ScenarioError) as info:
        sc = load_scenario(path, _overrides(case.args))
        World.build(sc)
        check_plugins(sc)
    err = info.value
    assert str(err) == err.oneline()
    assert_error_line(str(err), case, path)
    if case.field is not None:
        assert err.field == case.field
    elif not case.bug:
        assert err.field is None


@dataclass
class Outcome:
    path: Path
    out_dir: Path
    run: Future[subprocess.CompletedProcess[str]]
    check: Future[subprocess.CompletedProcess[str]] | None


@pytest.fixture(scope="module")
def outcomes(tmp_path_factory: pytest.TempPathFactory) -> Any:
    """Build every CLI case and start its subprocesses, a few at a time."""
    pool = ThreadPoolExecutor(max_workers=max(2, min(4, os.cpu_count() or 2)))
    out: dict[str, Outcome] = {}
    for case in CLI_CASES:
        folder = tmp_path_factory.mktemp(case.id)
        path = case.build(folder, case.id)
        out_dir = folder / "out"
        run = pool.submit(run_cli, "run", path, "--out", out_dir, "--json", "--quiet",
                          *case.args, cwd=folder)
        check = pool.submit(run_cli, "check", path, *case.args, cwd=folder) \
            if case.check_too else None
        out[case.id] = Outcome(path, out_dir, run, check)
    yield out
    pool.shutdown(wait=True, cancel_futures=True)


def assert_cli_error(proc: subprocess.CompletedProcess[str], case: Case, path: Path) -> None:
    assert "Traceback" not in proc.stdout + proc.stderr, proc.stderr
    assert proc.returncode == 2, (proc.returncode, proc.stdout, proc.stderr)
    assert proc.stdout == ""
    err = proc.stderr.strip()
    assert err, "nothing on stderr"
    lines = err.splitlines()
    assert len(lines) == 1, f"expected one line, got {len(lines)}:\n{proc.stderr}"
    assert_error_line(lines[0], case, path)


@pytest.mark.parametrize("case", _params(CLI_CASES))
def test_run_bad_scenario_one_line_exit_2(case: Case, outcomes: dict[str, Outcome]) -> None:
    o = outcomes[case.id]
    assert_cli_error(o.run.result(), case, o.path)
    assert not (o.out_dir / "metrics.json").exists(), "a failed run wrote outputs"


@pytest.mark.parametrize("case", _params([c for c in CLI_CASES if c.check_too]))
def test_check_bad_scenario_one_line_exit_2(case: Case, outcomes: dict[str, Outcome]) -> None:
    o = outcomes[case.id]
    assert o.check is not None
    assert_cli_error(o.check.result(), case, o.path)


def test_case_ids_unique() -> None:
    ids = [c.id for c in CASES]
    assert len(ids) == len(set(ids))


def test_failed_run_keeps_earlier_outputs(tmp_path: Path) -> None:
    """A run that fails (schema or layout) into a folder holding a good run's outputs leaves
    every file as it was and leaves no temporary files behind."""
    good = tiny()(tmp_path, "good")
    out = tmp_path / "out"
    first = run_cli("run", good, "--out", out, "--json", "--quiet", cwd=tmp_path)
    assert first.returncode == 0, first.stderr
    names = ("metrics.json", "events.jsonl", "paths.json")
    before = {n: (out / n).read_bytes() for n in names}
    assert all(before.values())
    bad_schema = tiny(agv(max_speed_mps=-1.0))(tmp_path, "bad_schema")
    bad_layout = tiny(set_(["fleet", "agvs", 0, "count"], 5))(tmp_path, "bad_layout")
    for bad in (bad_schema, bad_layout):
        proc = run_cli("run", bad, "--out", out, "--json", "--quiet", cwd=tmp_path)
        assert proc.returncode == 2, proc.stderr
        assert bad.name in proc.stderr
        assert {n: (out / n).read_bytes() for n in names} == before
        assert sorted(p.name for p in out.iterdir()) == sorted((*names, "manifest.json"))


def test_too_big_map_is_valid_for_1x1(tmp_path: Path) -> None:
    """Control for the footprint cases: the same map passes with 1x1 AGVs and shelves."""
    sc = load_scenario(tiny(too_big_for_aisles(1))(tmp_path, "ok"))
    world = World.build(sc)
    assert len(world.agvs) == 1 and len(world.layout.stations) == 1


def test_tiny_base_is_valid(tmp_path: Path) -> None:
    """Control: the unchanged tiny scenario and the copied paper scenario load and build."""
    for name, build in (("tiny", tiny()), ("paper", paper())):
        folder = tmp_path / name
        folder.mkdir()
        world = World.build(load_scenario(build(folder, name)))
        assert world.agvs


# ------------------------------------------------------------------------ in-process errors


def test_load_scenario_negative_speed_field(tmp_path: Path) -> None:
    path = tiny(agv(max_speed_mps=-1.0))(tmp_path, "neg")
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    err = info.value
    assert err.field == "fleet.types.agv.max_speed_mps"
    assert err.file == str(path)
    assert err.value == -1.0
    assert str(err) == err.oneline()
    assert str(err).startswith(f"{path}: fleet.types.agv.max_speed_mps: ")
    assert "\n" not in str(err)


def test_load_scenario_unknown_nested_key_field(tmp_path: Path) -> None:
    with pytest.raises(ScenarioError) as info:
        load_scenario(tiny(set_(["orders", "oneshot", "cnt"], 3))(tmp_path, "typo"))
    assert info.value.field == "orders.oneshot.cnt"
    assert info.value.message == "unknown key"


def test_load_scenario_bad_override_path_field(tmp_path: Path) -> None:
    path = tiny()(tmp_path, "ok")
    with pytest.raises(ScenarioError) as info:
        load_scenario(path, [("fleet.agvs.7.count", 2)])
    assert info.value.field == "fleet.agvs.7.count"
    assert info.value.file == str(path)


def test_load_scenario_missing_layout_file_field(tmp_path: Path) -> None:
    path = paper(with_layout=False)(tmp_path, "nolayout")
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    assert info.value.field == "layout"
    assert info.value.value == "maps/paper_20x15.yaml"
    assert info.value.file == str(path)


def test_load_scenario_empty_file_names_file(tmp_path: Path) -> None:
    path = text("")(tmp_path, "empty")
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    assert info.value.file == str(path)
    assert info.value.field is None


@pytest.mark.parametrize(("change", "error", "field", "value"), [
    pytest.param(grid("#########", "#R#....P#", "##.S.S..#", "#R.....P#", "#########"),
                 LayoutError, "layout.stations[0]", [1, 1], id="station-walled-in"),
    pytest.param(too_big_for_aisles(2), LayoutError, "fleet.types.agv.footprint", 2,
                 id="footprint-2-wider-than-aisles"),
    pytest.param(set_(["fleet", "agvs", 0, "count"], 5), LayoutError, "fleet.agvs[0].count", 5,
                 id="too-many-agvs"),
    pytest.param(agv(body_m=[1.2, 0.7]), ScenarioError, "fleet.types.agv.body_m", [1.2, 0.7],
                 id="body-larger-than-footprint"),
    pytest.param(set_(["layout", "stations"], [[0, 4]]), ScenarioError, "layout.stations[0]",
                 [0, 4], id="station-on-obstacle"),
])
def test_world_build_error_field(tmp_path: Path, change: Callable[[dict[str, Any]], Any],
                                 error: type[ScenarioError], field: str, value: Any) -> None:
    path = tiny(change)(tmp_path, "scen")
    sc = load_scenario(path)
    with pytest.raises(error) as info:
        World.build(sc)
    assert type(info.value) is error
    assert info.value.field == field
    assert info.value.value == value
    assert info.value.file == str(path)
    assert str(info.value).startswith(f"{path}: {field}: ")


def test_parse_override_errors() -> None:
    with pytest.raises(ScenarioError) as info:
        parse_override("seed")
    assert info.value.field == "--set"
    with pytest.raises(ScenarioError) as info:
        parse_override("=3")
    assert info.value.field == "--set"
    assert parse_override("orders.pattern=burst") == ("orders.pattern", "burst")
    assert parse_override("fleet.agvs.0.count=5") == ("fleet.agvs.0.count", 5)


def test_scenario_from_dict_without_file_uses_placeholder() -> None:
    data = copy.deepcopy(BASE)
    data["seed"] = -3
    with pytest.raises(ScenarioError) as info:
        scenario_from_dict(data)
    assert info.value.field == "seed"
    assert str(info.value).startswith("<scenario>: seed: ")
    assert info.value.with_file("x.yaml") is info.value
    assert str(info.value).startswith("x.yaml: seed: ")
