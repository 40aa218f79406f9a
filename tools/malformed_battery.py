"""A battery of malformed inputs, tried as a new user would, beside the hardening tests.

Each case runs the ``warerover`` command line in a child process and passes when it exits
with code 2 and no traceback. Prints the failures and ``N/M clean``. Run from anywhere:

    .venv/bin/python tools/malformed_battery.py
"""

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

M = str(Path(__file__).resolve().parent.parent)
W = str(Path(sys.executable).parent / "warerover")
os.chdir(tempfile.mkdtemp(prefix="warerover-battery-"))
os.makedirs("f", exist_ok=True)


def w(name, text, mode="w"):
    p = os.path.join("f", name)
    with open(p, mode) as f:
        f.write(text)
    return p


cases = []


def case(name, *args, expect=2):
    cases.append((name, list(args), expect))
# scenario yaml variants
case("empty yaml", "run", w("empty.yaml", ""))
case("yaml list", "run", w("list.yaml", "- a\n- b\n"))
case("yaml tab indent", "run", w("tab.yaml", "name: x\n\tfleet: 3\n"))
case("binary file", "run", w("bin.yaml", b"\x00\x01\x02\xff\xfe", "wb"))
case("utf16 yaml", "run", w("u16.yaml", "name: x\n".encode("utf-16"), "wb"))
case("nan seed", "run", f"{M}/layouts/paper_homogeneous.yaml", "--seed", "nan")
case("neg seed", "run", f"{M}/layouts/paper_homogeneous.yaml", "--seed", "-5")
case("huge seed", "run", f"{M}/layouts/paper_homogeneous.yaml", "--seed", str(2**70))
case("set no equals", "run", f"{M}/layouts/paper_homogeneous.yaml", "--set", "executor")
case("set unknown", "run", f"{M}/layouts/paper_homogeneous.yaml", "--set", "foo.bar=1")
case("set bad type", "run", f"{M}/layouts/paper_homogeneous.yaml", "--set", "executor.dt_s=abc")
case("set negative dt", "run", f"{M}/layouts/paper_homogeneous.yaml", "--set", "executor.dt_s=-0.1")
case("set list for int", "run", f"{M}/layouts/paper_homogeneous.yaml", "--set", "max_ticks=[1,2]")
case("unknown planner", "run", f"{M}/layouts/paper_homogeneous.yaml", "--planner", "dijkstra")
case("unknown executor", "run", f"{M}/layouts/paper_homogeneous.yaml", "--executor", "mujoco")
case("dotted bad path", "run", f"{M}/layouts/paper_homogeneous.yaml", "--planner", "os:path")
case("dotted missing mod", "run", f"{M}/layouts/paper_homogeneous.yaml", "--planner", "nosuchmod.x:Y")
case("out is file", "run", f"{M}/layouts/paper_homogeneous.yaml", "--out", w("afile.txt", "x"))
case("video bad ext", "run", f"{M}/layouts/paper_homogeneous.yaml", "--video", "f/x.avi")
case("missing scenario", "run", "f/nope.yaml")
case("scenario is dir", "run", "f")
case("freeze_s negative", "run", f"{M}/layouts/paper_homogeneous.yaml", "--set", "executor.freeze_s=-1")
case("trajectory_hz zero", "run", f"{M}/layouts/paper_homogeneous.yaml", "--set", "executor.trajectory_hz=0")
case("requeue negative", "run", f"{M}/layouts/paper_homogeneous.yaml", "--set", "orders.requeue_after_ticks=-3")
case("orders count huge", "run", f"{M}/layouts/paper_homogeneous.yaml", "--set", "orders.count=1e30")
case("fleet zero", "run", f"{M}/layouts/paper_homogeneous.yaml", "--set", "fleet.count=0")
# check
case("check bad body", "check", f"{M}/layouts/paper_homogeneous.yaml", "--set", "fleet.types.agv.body_m=[0,0.7]")
case("check body str", "check", f"{M}/layouts/paper_homogeneous.yaml", "--set", "fleet.types.agv.body_m=big")
# render
case("render missing", "render", "f/nope_dir")
case("render empty dir", "render", (os.makedirs("f/emptyrun", exist_ok=True), "f/emptyrun")[1])
case("render garbage npz", "render", (os.makedirs("f/garb", exist_ok=True), w("garb/trajectories.npz", "hello"), "f/garb")[2])
case("render bad fps", "render", f"{M}/layouts/paper_homogeneous.yaml", "--fps", "0")
# solve
case("solve bad map", "solve", w("bad.map", "type octile\nheight 2\nwidth 2\nmap\n..\n"), f"{M}/tests/data/random-32-32-10-random-1.scen")
case("solve scen other map", "solve", f"{M}/tests/data/random-32-32-10.map", f"{M}/tests/data/warehouse-10-20-10-2-1-random-1.scen")
case("solve too many agents", "solve", f"{M}/tests/data/random-32-32-10.map", f"{M}/tests/data/random-32-32-10-random-1.scen", "--agents", "100000")
case("solve bad planner", "solve", f"{M}/tests/data/random-32-32-10.map", f"{M}/tests/data/random-32-32-10-random-1.scen", "--planner", "cbs")
case("solve nan time", "solve", f"{M}/tests/data/random-32-32-10.map", f"{M}/tests/data/random-32-32-10-random-1.scen", "--time-limit", "nan")
case("solve scen garbage", "solve", f"{M}/tests/data/random-32-32-10.map", w("g.scen", "version 1\nfoo bar\n"))
# execute
case("execute empty plan", "execute", f"{M}/tests/data/random-32-32-10.map", "--plan", w("empty.txt", ""))
case("execute json garbage", "execute", f"{M}/tests/data/random-32-32-10.map", "--plan", w("g.json", "{\"a\": 1}"))
case("execute plan neg coords", "execute", f"{M}/tests/data/random-32-32-10.map", "--plan", w("neg.txt", "Agent 0:(-1,0)->(0,0)->\n"))
case("execute bad delays", "execute", f"{M}/tests/data/random-32-32-10.map", "--plan", w("ok.txt", "Agent 0:(0,0)->(0,1)->\n"), "--delays", "bernoulli:2")
case("execute bad fleet", "execute", f"{M}/tests/data/random-32-32-10.map", "--plan", "f/ok.txt", "--fleet", w("fleet.yaml", "types: 3\n"))
case("execute dt nan", "execute", f"{M}/tests/data/random-32-32-10.map", "--plan", "f/ok.txt", "--dt-s", "nan")
case("execute tick zero", "execute", f"{M}/tests/data/random-32-32-10.map", "--plan", "f/ok.txt", "--tick-s", "0")
case("execute format bad", "execute", f"{M}/tests/data/random-32-32-10.map", "--plan", "f/ok.txt", "--format", "xml")
case("execute export fmt bad", "execute", f"{M}/tests/data/random-32-32-10.map", "--plan", "f/ok.txt", "--export", "f/e.txt", "--export-format", "xml", "--executor", "grid")
case("execute lorr out no start", "execute", f"{M}/tests/data/random-32-32-10.map", "--plan", w("rr.json", json.dumps({"actualPaths": ["F"]})))
# lorr
case("lorr not json", "lorr", w("p.json", "nope"))
case("lorr list json", "lorr", w("p2.json", "[1,2]"))
case("lorr map missing", "lorr", w("p3.json", json.dumps({"mapFile": "x.map", "agentFile": "a", "taskFile": "t", "teamSize": 1, "numTasksReveal": 1})))
case("lorr ticks neg", "lorr", f"{M}/tests/data/lorr2023_warehouse_small/warehouse_small_50.json", "--ticks", "-1")
# sweep / report
case("sweep missing", "sweep", "f/nope.yaml", "--out", "f/sw")
case("sweep bad grid", "sweep", w("sw.yaml", "scenarios: [x.yaml]\ngrid: 3\n"), "--out", "f/sw2")
case("report missing", "report", "f/nothing")
case("report empty dir", "report", "f/emptyrun")
case("gap bad seeds", "gap", f"{M}/layouts/paper_homogeneous.yaml", "--seeds", "a..b")
case("execute fleet agents int", "execute", f"{M}/tests/data/random-32-32-10.map", "--plan", "f/ok.txt", "--fleet", w("fleet2.yaml", "types: {a: {footprint: 1}}\nagents: 5\n"))
case("execute fleet agents dict", "execute", f"{M}/tests/data/random-32-32-10.map", "--plan", "f/ok.txt", "--fleet", w("fleet3.yaml", "types: {a: {footprint: 1}}\nagents: [{x: 1}]\n"))
case("serve bad port", "serve", f"{M}/layouts/paper_homogeneous.yaml", "--port", "70000")
bad = 0
for name, args, expect in cases:
    try:
        r = subprocess.run([W, *args], capture_output=True, text=True, timeout=120)
        out = r.stdout + r.stderr
        tb = "Traceback" in out
        ok = (r.returncode == expect) and not tb
        lines = [ln for ln in r.stderr.strip().splitlines() if ln.strip()]
    except subprocess.TimeoutExpired:
        ok, tb, lines, r = False, False, ["TIMEOUT"], None
    if not ok:
        bad += 1
        print(f"FAIL {name}: rc={r.returncode if r else None} tb={tb} :: {(lines[-1] if lines else (r.stdout[-200:] if r else ''))[:220]}")
print(f"{len(cases) - bad}/{len(cases)} clean")
