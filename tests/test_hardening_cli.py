"""Bad command-line options, as a new user types them: exit 2, one line naming the option
(or file) and the value, no traceback, nothing written."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import pytest
from hardening_helpers import LAYOUTS, REPO, assert_clean_error, run_cli

PAPER = LAYOUTS / "paper_homogeneous.yaml"
MAP = REPO / "tests" / "data" / "warehouse-10-20-10-2-1.map"
SCEN = REPO / "tests" / "data" / "warehouse-10-20-10-2-1-random-1.scen"

CASES = {
    "speed-inf": (("render", "{run}", "--out", "{tmp}/a.mp4", "--speed", "inf"), ["--speed"]),
    "speed-nan": (("render", "{run}", "--out", "{tmp}/a.mp4", "--speed", "nan"), ["--speed"]),
    "fps-nan": (("render", "{run}", "--out", "{tmp}/a.mp4", "--fps", "nan"), ["--fps"]),
    "fps-inf": (("render", "{run}", "--out", "{tmp}/a.mp4", "--fps", "inf"), ["--fps"]),
    "png-nan": (("render", "{run}", "--out", "{tmp}/a.png", "--png", "nan"), ["--png"]),
    "png-neg": (("render", "{run}", "--out", "{tmp}/a.png", "--png", "-1"), ["--png"]),
    "png-ext": (("render", "{run}", "--out", "{tmp}/a.bmpx", "--png", "1"), ["--out"]),
    "video-unwritable": (("render", "{run}", "--out", "/proc/a.mp4"), ["/proc/a.mp4"]),
    "png-unwritable": (("render", "{run}", "--out", "/proc/a.png", "--png", "1"),
                       ["/proc/a.png"]),
    "render-metrics": (("render", "{run}/metrics.json", "--out", "{tmp}/a.mp4"),
                       ["metrics.json"]),
    "render-missing": (("render", "{tmp}/nope", "--out", "{tmp}/a.mp4"), ["nope"]),
    "viewport-bad": (("render", "{run}", "--out", "{tmp}/a.mp4", "--viewport", "a,b"),
                     ["--viewport"]),
    "size-huge": (("render", "{run}", "--out", "{tmp}/a.mp4", "--size", "99999x99999"),
                  ["--size"]),
    "seed-neg": (("run", PAPER, "--seed", "-5"), ["seed"]),
    "seed-huge": (("run", PAPER, "--seed", "9" * 30), ["seed"]),
    "set-empty": (("run", PAPER, "--set", "="), ["--set"]),
    "set-nopath": (("run", PAPER, "--set", "planner.name"), ["--set"]),
    "set-index": (("run", PAPER, "--set", "fleet.agvs.99.count=1"), ["fleet.agvs.99.count"]),
    "set-inf": (("run", PAPER, "--set", "tick_s=.inf"), ["tick_s"]),
    "set-bool": (("run", PAPER, "--set", "max_ticks=true"), ["max_ticks"]),
    "planner-bad": (("run", PAPER, "--planner", "dijkstra"), ["planner.name"]),
    "executor-bad": (("run", PAPER, "--executor", "quantum"), ["executor.name"]),
    "out-unwritable": (("run", PAPER, "--out", "/proc/x"), ["/proc/x"]),
    "out-is-file": (("run", PAPER, "--out", "{run}/metrics.json"), ["metrics.json"]),
    "run-video-ext": (("run", PAPER, "--out", "{tmp}/r", "--video", "{tmp}/v.txt"),
                      ["--video"]),
    "scenario-dir": (("run", LAYOUTS), ["directory"]),
    "scenario-empty": (("run", "/dev/null"), ["/dev/null"]),
    "solve-agents": (("solve", MAP, SCEN, "--agents", "0"), ["--agents"]),
    "solve-time-nan": (("solve", MAP, SCEN, "--agents", "5", "--time-limit", "nan"),
                       ["--time-limit"]),
    "solve-time-neg": (("solve", MAP, SCEN, "--agents", "5", "--time-limit", "-1"),
                       ["--time-limit"]),
    "solve-swapped": (("solve", SCEN, MAP, "--agents", "5"), [SCEN.name]),
    "sweep-scenario": (("sweep", PAPER, "--out", "{tmp}/sw"), [PAPER.name]),
    "sweep-workers": (("sweep", PAPER, "--out", "{tmp}/sw", "--workers", "0"), ["--workers"]),
    "report-missing": (("report", "{tmp}/nope"), ["nope"]),
    # values that look like rich console markup are printed as typed, never interpreted
    "markup-value": (("run", PAPER, "--set", 'name="[/foo]"'), ["name", "'[/foo]'"]),
    "markup-value2": (("run", PAPER, "--set", 'planner.name="[bold]x"'), ["'[bold]x'"]),
    "markup-path": (("render", "{tmp}/[/b]", "--out", "{tmp}/a.mp4"), ["[/b]"]),
    # a held-out round, tried after the first suite passed
    "fleet-types-int": (("execute", MAP, "--plan", "{tmp}/plan.txt", "--fleet",
                         "{tmp}/fleet_types.yaml"), ["fleet_types.yaml", "types"]),
    "fleet-agents-int": (("execute", MAP, "--plan", "{tmp}/plan.txt", "--fleet",
                          "{tmp}/fleet_agents.yaml"), ["fleet_agents.yaml", "agents"]),
    "fleet-agents-dict": (("execute", MAP, "--plan", "{tmp}/plan.txt", "--fleet",
                           "{tmp}/fleet_dict.yaml"), ["fleet_dict.yaml", "agents[0]"]),
    "serve-port": (("serve", PAPER, "--port", "70000"), ["--port", "70000"]),
    "lorr-ticks": (("lorr", REPO / "tests" / "data" / "lorr2023_warehouse_small" /
                    "warehouse_small_50.json", "--ticks", "-1"), ["--ticks"]),
}


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    from warerover_phys import load_scenario, run_episode
    from warerover_phys.outputs import write_outputs

    tmp = tmp_path_factory.mktemp("cli")
    run = tmp / "run"
    write_outputs(run_episode(load_scenario(PAPER, [("max_ticks", 20)])), run,
                  with_trajectory=True)

    (tmp / "plan.txt").write_text("Agent 0:(1,1)->(1,2)->\n")
    (tmp / "fleet_types.yaml").write_text("types: 3\n")
    (tmp / "fleet_agents.yaml").write_text("types: {a: {footprint: 1}}\nagents: 5\n")
    (tmp / "fleet_dict.yaml").write_text("types: {a: {footprint: 1}}\nagents: [{x: 1}]\n")

    def fmt(a):
        return str(a).format(run=run, tmp=tmp) if isinstance(a, str) else a

    with ThreadPoolExecutor(2) as pool:
        futs = {k: pool.submit(run_cli, *[fmt(a) for a in args], cwd=tmp)
                for k, (args, _) in CASES.items()}
        return tmp, {k: f.result() for k, f in futs.items()}


@pytest.mark.slow  # one fixture runs 40-odd CLI commands: make test-all
@pytest.mark.parametrize("case", sorted(CASES))
def test_bad_option_is_a_clean_error(results, case):
    tmp, procs = results
    assert_clean_error(procs[case], *CASES[case][1])
    assert not list(tmp.glob("*.mp4")) and not list(tmp.glob("*.png"))
    assert not (tmp / "r").exists() and not (tmp / "sw").exists() and not (tmp / "runs").exists()


def test_paths_that_look_like_markup_work(tmp_path):
    out = tmp_path / "r[/x]"
    proc = run_cli("run", PAPER, "--out", out, "--set", "max_ticks=20", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "r[/x]" in proc.stdout and (out / "metrics.json").exists()
