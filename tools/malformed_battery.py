"""A battery of malformed and hostile inputs, tried as a new user and as a hostile tester
would, beside the hardening tests.

Each case runs the ``warerover`` command line in a child process, in a fresh empty working
folder (its inputs live elsewhere), and passes when:

- it exits with the expected code (2 for bad input, 130 for an interrupt),
- stderr holds exactly one line (the message) and nothing is a traceback,
- nothing was written: the working folder is still empty and the inputs are unchanged,
- it took less than ``--max-s`` seconds (10) and its peak memory stayed under ``--max-mb``
  (1,024 MB; the child's address space is capped at 4 GB so a runaway read cannot take the
  machine).

Cases are grouped by class (``--only CLASS`` runs one). Prints a table (class, case, exit
code, seconds, peak MB, what failed) and ``N/M clean``; ``--json PATH`` writes every row.
Run from anywhere::

    .venv/bin/python tools/malformed_battery.py [--only CLASS ...] [--json tools/out/battery.json]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
W = str(Path(sys.executable).parent / "warerover")
HOMO = str(REPO / "layouts" / "paper_homogeneous.yaml")
MAP = str(REPO / "tests" / "data" / "random-32-32-10.map")
SCEN = str(REPO / "tests" / "data" / "random-32-32-10-random-1.scen")
LORR = str(REPO / "tests" / "data" / "lorr2023_warehouse_small" / "warehouse_small_50.json")
AS_LIMIT = 4 * 2**30
"""Address-space cap of each case (bytes): a runaway read fails instead of eating the box."""

cases: list[dict] = []
F = Path(".")
"""Where the inputs are (set by :func:`main`)."""


def w(name: str, text: str | bytes) -> str:
    """Write an input file under ``F``; its absolute path."""
    p = F / name
    p.parent.mkdir(parents=True, exist_ok=True)
    if isinstance(text, bytes):
        p.write_bytes(text)
    else:
        p.write_text(text)
    return str(p)


def case(cls: str, name: str, *args: str, expect: int = 2, interrupt_after: float | None = None,
         needle: str | None = None) -> None:
    """One case: ``warerover ARGS`` must exit ``expect``; ``interrupt_after``: send SIGINT
    after this many seconds; ``needle``: a word the message must hold."""
    cases.append({"cls": cls, "name": name, "args": list(args), "expect": expect,
                  "interrupt_after": interrupt_after, "needle": needle})


def _inputs() -> dict[str, str]:
    """Special files and helper inputs shared by the cases."""
    out = {}
    for ext in ("yaml", "map", "scen", "json", "txt", "npz"):
        fifo = F / f"fifo.{ext}"
        os.mkfifo(fifo)
        out[f"fifo.{ext}"] = str(fifo)
        zero = F / f"zero.{ext}"
        zero.symlink_to("/dev/zero")
        out[f"zero.{ext}"] = str(zero)
    out["plan"] = w("ok.txt", "Agent 0:(0,0)->(0,1)->\n")
    (F / "emptyrun").mkdir()
    w("garb/trajectories.npz", "hello")
    w("sw_ok.yaml", f"scenarios: {{Ho: {HOMO}}}\nrepetitions: 1\n")
    out["fleet2"] = w("fleet2.yaml", "types: {a: {footprint: 1}}\nagents: [{type: a, count: 1}]\n")
    return out


# ----------------------------------------------------------------------------- the cases

def earlier_cases(i: dict[str, str]) -> None:
    """The first 60 (2026-11-23): malformed files and options, one by one."""
    c = "earlier"
    case(c, "empty yaml", "run", w("empty.yaml", ""))
    case(c, "yaml list", "run", w("list.yaml", "- a\n- b\n"))
    case(c, "yaml tab indent", "run", w("tab.yaml", "name: x\n\tfleet: 3\n"))
    case(c, "binary file", "run", w("bin.yaml", b"\x00\x01\x02\xff\xfe"))
    case(c, "utf16 yaml", "run", w("u16.yaml", "name: x\n".encode("utf-16")))
    case(c, "nan seed", "run", HOMO, "--seed", "nan")
    case(c, "neg seed", "run", HOMO, "--seed", "-5")
    case(c, "huge seed", "run", HOMO, "--seed", str(2**70))
    case(c, "set no equals", "run", HOMO, "--set", "executor")
    case(c, "set unknown", "run", HOMO, "--set", "foo.bar=1")
    case(c, "set bad type", "run", HOMO, "--set", "executor.dt_s=abc")
    case(c, "set negative dt", "run", HOMO, "--set", "executor.dt_s=-0.1")
    case(c, "set list for int", "run", HOMO, "--set", "max_ticks=[1,2]")
    case(c, "unknown planner", "run", HOMO, "--planner", "dijkstra")
    case(c, "unknown executor", "run", HOMO, "--executor", "mujoco")
    case(c, "dotted bad path", "run", HOMO, "--planner", "os:path")
    case(c, "dotted missing mod", "run", HOMO, "--planner", "nosuchmod.x:Y")
    case(c, "out is file", "run", HOMO, "--out", w("afile.txt", "x"))
    case(c, "video bad ext", "run", HOMO, "--video", "x.avi")
    case(c, "missing scenario", "run", str(F / "nope.yaml"))
    case(c, "scenario is dir", "run", str(F))
    case(c, "freeze_s negative", "run", HOMO, "--set", "executor.freeze_s=-1")
    case(c, "trajectory_hz zero", "run", HOMO, "--set", "executor.trajectory_hz=0")
    case(c, "requeue negative", "run", HOMO, "--set", "orders.requeue_after_ticks=-3")
    case(c, "orders count huge", "run", HOMO, "--set", "orders.count=1e30")
    case(c, "fleet zero", "run", HOMO, "--set", "fleet.count=0")
    case(c, "check bad body", "check", HOMO, "--set", "fleet.types.agv.body_m=[0,0.7]")
    case(c, "check body str", "check", HOMO, "--set", "fleet.types.agv.body_m=big")
    case(c, "render missing", "render", str(F / "nope_dir"), "--out", "x.mp4")
    case(c, "render empty dir", "render", str(F / "emptyrun"), "--out", "x.mp4")
    case(c, "render garbage npz", "render", str(F / "garb"), "--out", "x.mp4")
    case(c, "render bad fps", "render", HOMO, "--fps", "0", "--out", "x.mp4")
    case(c, "solve bad map", "solve", w("bad.map", "type octile\nheight 2\nwidth 2\nmap\n..\n"),
         SCEN)
    case(c, "solve scen other map", "solve", MAP,
         str(REPO / "tests/data/warehouse-10-20-10-2-1-random-1.scen"))
    case(c, "solve too many agents", "solve", MAP, SCEN, "--agents", "100000")
    case(c, "solve bad planner", "solve", MAP, SCEN, "--planner", "cbs")
    case(c, "solve nan time", "solve", MAP, SCEN, "--time-limit", "nan")
    case(c, "solve scen garbage", "solve", MAP, w("g.scen", "version 1\nfoo bar\n"))
    case(c, "execute empty plan", "execute", MAP, "--plan", w("empty.txt", ""))
    case(c, "execute json garbage", "execute", MAP, "--plan", w("g.json", "{\"a\": 1}"))
    case(c, "execute plan neg coords", "execute", MAP, "--plan",
         w("neg.txt", "Agent 0:(-1,0)->(0,0)->\n"))
    case(c, "execute bad delays", "execute", MAP, "--plan", i["plan"], "--delays", "bernoulli:2")
    case(c, "execute bad fleet", "execute", MAP, "--plan", i["plan"], "--fleet",
         w("fleet.yaml", "types: 3\n"))
    case(c, "execute dt nan", "execute", MAP, "--plan", i["plan"], "--dt-s", "nan")
    case(c, "execute tick zero", "execute", MAP, "--plan", i["plan"], "--tick-s", "0")
    case(c, "execute format bad", "execute", MAP, "--plan", i["plan"], "--format", "xml")
    case(c, "execute export fmt bad", "execute", MAP, "--plan", i["plan"], "--export", "e.txt",
         "--export-format", "xml", "--executor", "grid")
    case(c, "execute lorr out no start", "execute", MAP, "--plan",
         w("rr.json", json.dumps({"actualPaths": ["F"]})))
    case(c, "lorr not json", "lorr", w("p.json", "nope"))
    case(c, "lorr list json", "lorr", w("p2.json", "[1,2]"))
    case(c, "lorr map missing", "lorr", w("p3.json", json.dumps(
        {"mapFile": "x.map", "agentFile": "a", "taskFile": "t", "teamSize": 1,
         "numTasksReveal": 1})))
    case(c, "lorr ticks neg", "lorr", LORR, "--ticks", "-1")
    case(c, "sweep missing", "sweep", str(F / "nope.yaml"), "--out", "sw")
    case(c, "sweep bad grid", "sweep", w("sw.yaml", "scenarios: [x.yaml]\ngrid: 3\n"),
         "--out", "sw2")
    case(c, "report missing", "report", str(F / "nothing"))
    case(c, "report empty dir", "report", str(F / "emptyrun"))
    case(c, "gap bad seeds", "gap", HOMO, "--seeds", "a..b")
    case(c, "execute fleet agents int", "execute", MAP, "--plan", i["plan"], "--fleet",
         w("fleet2b.yaml", "types: {a: {footprint: 1}}\nagents: 5\n"))
    case(c, "execute fleet agents dict", "execute", MAP, "--plan", i["plan"], "--fleet",
         w("fleet3.yaml", "types: {a: {footprint: 1}}\nagents: [{x: 1}]\n"))
    case(c, "serve bad port", "serve", HOMO, "--port", "70000")


def special_file_cases(i: dict[str, str]) -> None:
    """A FIFO (would hang) and /dev/zero (endless bytes) wherever a file is read."""
    c = "special files"
    for kind in ("fifo", "zero"):
        k = kind
        case(c, f"run scenario {k}", "run", i[f"{k}.yaml"])
        case(c, f"check scenario {k}", "check", i[f"{k}.yaml"])
        case(c, f"gap scenario {k}", "gap", i[f"{k}.yaml"])
        case(c, f"gap --plan {k}", "gap", MAP, "--plan", i[f"{k}.txt"])
        case(c, f"gap --fleet {k}", "gap", MAP, "--plan", i["plan"], "--fleet", i[f"{k}.yaml"])
        case(c, f"solve map {k}", "solve", i[f"{k}.map"], SCEN)
        case(c, f"solve scen {k}", "solve", MAP, i[f"{k}.scen"])
        case(c, f"execute floor {k}", "execute", i[f"{k}.map"], "--plan", i["plan"])
        case(c, f"execute floor yaml {k}", "execute", i[f"{k}.yaml"], "--plan", i["plan"])
        case(c, f"execute plan {k}", "execute", MAP, "--plan", i[f"{k}.txt"])
        case(c, f"execute fleet {k}", "execute", MAP, "--plan", i["plan"], "--fleet",
             i[f"{k}.yaml"])
        case(c, f"lorr problem {k}", "lorr", i[f"{k}.json"])
        case(c, f"lorr mapFile {k}", "lorr", w(f"lorr_{k}/p.json", json.dumps(
            {"mapFile": i[f"{k}.map"], "agentFile": "a", "taskFile": "t", "teamSize": 1,
             "numTasksReveal": 1})))
        case(c, f"render recording {k}", "render", i[f"{k}.npz"], "--out", "x.mp4")
        case(c, f"check-trajectory {k}", "check-trajectory", i[f"{k}.npz"])
        case(c, f"sweep spec {k}", "sweep", i[f"{k}.yaml"], "--out", "sw")
        case(c, f"serve scenario {k}", "serve", i[f"{k}.yaml"], "--port", "0")
        case(c, f"export-glb scenario {k}", "export-glb", "x.glb", i[f"{k}.yaml"])
        case(c, f"layout file {k}", "check", w(f"lay_{k}.yaml",
             f"name: x\nlayout: {i[f'{k}.yaml']}\nfleet: {{agvs: [{{type: agv, count: 1}}]}}\n"))
        case(c, f"layout.map {k}", "check", w(f"laymap_{k}.yaml", _scenario_with_map(
            i[f"{k}.map"])), needle="FIFO" if kind == "fifo" else "device")
        rdir = F / f"report_{k}"
        rdir.mkdir()
        (rdir / "results.jsonl").symlink_to(i[f"{k}.json"])
        case(c, f"report results {k}", "report", str(rdir))


def _scenario_with_map(map_path: str) -> str:
    text = Path(HOMO).read_text()
    return text.replace("layout: maps/paper_20x15.yaml",
                        f"layout:\n  map: {map_path}\n  stations: [[0, 0]]\n"
                        f"  parking: [{{origin: [1, 1], rows: 1, cols: 9}}]")


def seed_cases(i: dict[str, str]) -> None:
    """One seed rule (0 .. 2**63 - 1) for every command."""
    c = "seeds"
    for bad in ("-1", str(2**63), str(2**70)):
        case(c, f"run --seed {bad[:6]}", "run", HOMO, "--seed", bad)
        case(c, f"gap --seed {bad[:6]}", "gap", HOMO, "--seed", bad)
        case(c, f"gap --plan --seed {bad[:6]}", "gap", MAP, "--plan", i["plan"], "--seed", bad)
        case(c, f"solve --seed {bad[:6]}", "solve", MAP, SCEN, "--seed", bad)
        case(c, f"execute --seed {bad[:6]}", "execute", MAP, "--plan", i["plan"], "--seed", bad)
        case(c, f"lorr --seed {bad[:6]}", "lorr", LORR, "--seed", bad)
        case(c, f"serve --seed {bad[:6]}", "serve", HOMO, "--seed", bad, "--port", "0")
        case(c, f"export-glb --seed {bad[:6]}", "export-glb", "x.glb", HOMO, "--seed", bad)
    case(c, "gap --seeds -1..3", "gap", HOMO, "--seeds", "-1..3")
    case(c, "gap --seeds huge", "gap", HOMO, "--seeds", f"{2**63}")


def late_check_cases(i: dict[str, str]) -> None:
    """Output paths and formats checked before any work; nothing written on refusal."""
    c = "late checks"
    afile = w("outfile.txt", "x")
    unw = "/sys/warerover-battery/sub"  # not writable, even by root
    case(c, "run --out unwritable", "run", HOMO, "--out", unw)
    case(c, "run --out under a file", "run", HOMO, "--out", afile + "/run")
    case(c, "run --video unwritable", "run", HOMO, "--video", unw + ".mp4")
    case(c, "gap --out is a file", "gap", HOMO, "--out", afile)
    case(c, "gap --out unwritable", "gap", HOMO, "--out", unw)
    case(c, "gap --video unwritable", "gap", HOMO, "--video", unw + ".mp4")
    case(c, "gap --plan --out is a file", "gap", MAP, "--plan", i["plan"], "--out", afile)
    case(c, "execute --out is a file", "execute", MAP, "--plan", i["plan"], "--out", afile)
    case(c, "execute --out unwritable", "execute", MAP, "--plan", i["plan"], "--out", unw)
    case(c, "execute --video unwritable", "execute", MAP, "--plan", i["plan"], "--video",
         unw + ".mp4")
    case(c, "execute --video bad ext", "execute", MAP, "--plan", i["plan"], "--video", "v.avi")
    case(c, "execute --export unwritable", "execute", MAP, "--plan", i["plan"], "--export",
         unw + ".txt")
    case(c, "execute --export is a dir", "execute", MAP, "--plan", i["plan"], "--export", str(F))
    empty_plan = w("noagents.json", json.dumps({"paths": []}))
    case(c, "execute export cannot hold", "execute", MAP, "--plan", empty_plan, "--export",
         "e.txt", "--export-format", "lns", "--executor", "grid")
    case(c, "lorr --out is a file", "lorr", LORR, "--ticks", "5", "--out", afile)
    case(c, "lorr --out unwritable", "lorr", LORR, "--ticks", "5", "--out", unw)
    case(c, "solve --out unwritable", "solve", MAP, SCEN, "--agents", "5", "--out",
         unw + ".txt")
    case(c, "solve --out is a dir", "solve", MAP, SCEN, "--agents", "5", "--out", str(F))
    case(c, "sweep --out is a file", "sweep", str(F / "sw_ok.yaml"), "--out", afile)
    case(c, "sweep --out unwritable", "sweep", str(F / "sw_ok.yaml"), "--out", unw)
    case(c, "render --out unwritable", "render", str(F / "garb"), "--out", unw + ".mp4")
    case(c, "export-glb out unwritable", "export-glb", unw + ".glb", HOMO)
    case(c, "export-glb out bad ext", "export-glb", "x.obj", HOMO)


def silent_cases(i: dict[str, str]) -> None:
    """Values that were accepted silently: each must be refused, naming file, key or option."""
    c = "silent acceptance"
    dup = Path(HOMO).read_text().replace("max_ticks: 1000", "max_ticks: 1000\nmax_ticks: 5")
    dup_path = w("layouts_dup/dup.yaml", dup)
    shutil.copytree(REPO / "layouts" / "maps", F / "layouts_dup" / "maps")
    case(c, "duplicate key scenario", "run", dup_path, needle="max_ticks")
    case(c, "duplicate key check", "check", dup_path, needle="max_ticks")
    case(c, "duplicate key nested", "check", w("layouts_dup/dup2.yaml", Path(HOMO).read_text()
         .replace("footprint: 1", "footprint: 1\n      footprint: 2")), needle="footprint")
    case(c, "duplicate key sweep", "sweep", w("swdup.yaml", f"scenarios: {{Ho: {HOMO}}}\n"
         "repetitions: 1\nrepetitions: 2\n"), "--out", "sw", needle="repetitions")
    case(c, "duplicate key fleet", "execute", MAP, "--plan", i["plan"], "--fleet",
         w("fleetdup.yaml", "types: {a: {footprint: 1}}\ntypes: {b: {footprint: 1}}\n"),
         needle="types")
    case(c, "gap --agvs 99", "gap", HOMO, "--agvs", "99", needle="--agvs")
    case(c, "gap --plan --agvs 99", "gap", MAP, "--plan", i["plan"], "--agvs", "99",
         needle="--agvs")
    case(c, "numTasksReveal 1e12", "lorr", w("lorr_reveal/p.json", json.dumps(
        {**json.loads(Path(LORR).read_text()), "numTasksReveal": 10**12,
         "mapFile": str(Path(LORR).parent / "maps/warehouse_small.map"),
         "agentFile": str(Path(LORR).parent / "agents/warehouse_small_50.agents"),
         "taskFile": str(Path(LORR).parent / "tasks/warehouse_small.tasks")})),
         needle="numTasksReveal")
    case(c, "serve --speed nan", "serve", HOMO, "--speed", "nan", "--port", "0",
         needle="--speed")
    case(c, "serve --speed -1", "serve", HOMO, "--speed", "-1", "--port", "0",
         needle="--speed")


def _npy_header(shape: tuple[int, ...]) -> bytes:
    """A ``.npy`` (version 1.0) header of float64 ``shape``."""
    header = f"{{'descr': '<f8', 'fortran_order': False, 'shape': {shape!r}, }}"
    header = header + " " * (63 - (len(header) + 10) % 64) + "\n"
    return b"\x93NUMPY\x01\x00" + len(header).to_bytes(2, "little") + header.encode()


def _npz_claiming(rows: int) -> bytes:
    """An npz whose one array's header claims ``rows`` x 3 float64 but holds no data."""
    import io

    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        z.writestr("pos.npy", _npy_header((rows, 3)))
    return buf.getvalue()


def _zip_bomb(gib: float = 2.25) -> bytes:
    """An npz of one float64 array, true to its header, that inflates from a few MB to
    ``gib`` GiB of zeros (over the 2 GiB a recording may hold)."""
    import io

    blocks = int(gib * 64)  # 16 MiB each
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_DEFLATED) as z, \
            z.open("pos.npy", "w", force_zip64=True) as f:
        f.write(_npy_header((blocks * 2**21,)))
        block = bytes(2**24)
        for _ in range(blocks):
            f.write(block)
    return buf.getvalue()


def unbounded_cases(i: dict[str, str]) -> None:
    """Requests for unbounded work: capped and refused at once."""
    c = "unbounded work"
    case(c, "gap --seeds 0..10000000", "gap", HOMO, "--seeds", "0..10000000", needle="--seeds")
    case(c, "render --speed 1e-9", "render", _small_recording(), "--out", "x.mp4", "--speed",
         "1e-9", needle="frames")
    w("hdr/trajectories.npz", _npz_claiming(10**12))
    case(c, "npz header 1e12 rows", "render", str(F / "hdr"), "--out", "x.mp4")
    case(c, "npz header check-trajectory", "check-trajectory", str(F / "hdr"))
    w("bomb/trajectories.npz", _zip_bomb())
    case(c, "npz zip bomb", "render", str(F / "bomb"), "--out", "x.mp4")
    case(c, "npz zip bomb check-trajectory", "check-trajectory", str(F / "bomb"))
    many = "0:" + ",".join("(1,1)" for _ in range(2_000_000)) + "\n"
    case(c, "plan 2M agents one line", "execute", MAP, "--plan", w("many.txt", many))
    scen = Path(SCEN).read_text().splitlines()
    first = scen[1].split("\t")
    second = scen[2].split("\t")
    second[4:6] = first[4:6]
    same = "\n".join([scen[0], scen[1], "\t".join(second), *scen[3:]]) + "\n"
    case(c, "solve two agents same start", "solve", MAP, w("same.scen", same), "--agents", "5",
         needle="start")


_REC: list[str] = []


def _small_recording() -> str:
    """A real recording (a 10-tick grid run of the paper floor), made once."""
    if not _REC:
        d = F / "rec"
        subprocess.run([W, "run", HOMO, "--set", "max_ticks=10", "--out", str(d), "--video",
                        str(F / "rec.mp4"), "--quiet"], capture_output=True, timeout=300)
        _REC.append(str(d))
    return _REC[0]


def interrupt_cases(i: dict[str, str]) -> None:
    """Ctrl-C and unreachable services."""
    c = "interrupts"
    case(c, "Ctrl-C in solve --refine", "solve", str(REPO / "tests/data/warehouse-10-20-10-2-1.map"),
         str(REPO / "tests/data/warehouse-10-20-10-2-1-random-1.scen"), "--agents", "100",
         "--refine", "--time-limit", "30", "--json", expect=130, interrupt_after=6.0,
         needle="interrupted")
    case(c, "Ctrl-C in solve --refine (python -m)", sys.executable, "-m", "warerover_phys",
         "solve", str(REPO / "tests/data/warehouse-10-20-10-2-1.map"),
         str(REPO / "tests/data/warehouse-10-20-10-2-1-random-1.scen"), "--agents", "100",
         "--refine", "--time-limit", "30", "--json", expect=130, interrupt_after=6.0,
         needle="interrupted")
    case(c, "sweep --ray unreachable", "sweep", str(F / "sw_ok.yaml"), "--out", "sw", "--ray",
         "10.255.255.1:6379", needle="--ray")


def message_cases(i: dict[str, str]) -> None:
    """Messages that said the wrong thing."""
    c = "messages"
    case(c, "render a JSON file", "render", w("notnpz.json", json.dumps({"a": 1})), "--out",
         "x.mp4", needle="npz")
    case(c, "sweep --only nonsense", "sweep", str(F / "sw_ok.yaml"), "--out", "sw", "--only",
         "nonsense", needle="--only")
    case(c, "layout.map is /dev/zero", "check", w("laymap_dev.yaml",
         _scenario_with_map("/dev/zero")), needle="device")


CLASSES = {"earlier": earlier_cases, "special files": special_file_cases,
           "seeds": seed_cases, "late checks": late_check_cases,
           "silent acceptance": silent_cases, "unbounded work": unbounded_cases,
           "interrupts": interrupt_cases, "messages": message_cases}


# ----------------------------------------------------------------------------- running

def _snapshot(root: Path) -> dict[str, tuple[int, int]]:
    out = {}
    for dirpath, dirnames, filenames in os.walk(root):
        for n in filenames + dirnames:
            p = Path(dirpath) / n
            st = p.lstat()
            out[str(p)] = (st.st_size, st.st_mtime_ns)
    return out


def _limit() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (AS_LIMIT, AS_LIMIT))
    os.setsid()


def run_case(cs: dict, work: Path, max_s: float, max_mb: float) -> dict:
    cwd = work / f"case{len(list(work.iterdir()))}"
    cwd.mkdir()
    before = _snapshot(F)
    argv = cs["args"] if cs["args"][0] == sys.executable else [W, *cs["args"]]
    env = {**os.environ, "COLUMNS": "200", "NO_COLOR": "1", "TERM": "dumb"}
    t0 = time.monotonic()
    proc = subprocess.Popen(argv, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            stdin=subprocess.DEVNULL, env=env, preexec_fn=_limit)
    timed_out = False
    if cs["interrupt_after"] is not None:
        try:
            proc.wait(timeout=cs["interrupt_after"])
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGINT)  # as Ctrl-C does: the whole process group
    try:
        out, err = proc.communicate(timeout=max(1.0, 1.5 * max_s - (time.monotonic() - t0)))
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        out, err = proc.communicate()
        timed_out = True
    seconds = time.monotonic() - t0
    # the child's peak RSS (ru_maxrss of the children waited for so far is a maximum: read
    # this one's own from /proc-less wait4 is not possible after communicate, so use the
    # running maximum of all children, reset per case by running each case last-in)
    peak_mb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
    text_out, text_err = out.decode(errors="replace"), err.decode(errors="replace")
    lines = [ln for ln in text_err.strip().splitlines() if ln.strip()]
    problems = []
    if timed_out:
        problems.append("timeout")
    if proc.returncode != cs["expect"]:
        problems.append(f"rc {proc.returncode}")
    if "Traceback" in text_out + text_err:
        problems.append("traceback")
    if len(lines) != 1:
        problems.append(f"{len(lines)} lines")
    if cs["needle"] and cs["needle"].lower() not in text_err.lower():
        problems.append(f"no '{cs['needle']}'")
    written = sorted(str(p.relative_to(cwd)) for p in cwd.rglob("*"))
    if written:
        problems.append(f"wrote {written[:2]}")
    if _snapshot(F) != before:
        problems.append("inputs changed")
    if seconds > max_s:
        problems.append(f"{seconds:.1f} s")
    if peak_mb > max_mb:
        problems.append(f"{peak_mb:.0f} MB")
    shutil.rmtree(cwd, ignore_errors=True)
    return {"class": cs["cls"], "case": cs["name"], "args": cs["args"], "rc": proc.returncode,
            "expect": cs["expect"], "seconds": round(seconds, 2), "peak_mb": round(peak_mb),
            "message": lines[-1][:200] if lines else "", "problems": problems,
            "clean": not problems}


def _one_case_main() -> None:
    """``--case JSON``: run one case in this (fresh) process and print its row (so that
    RUSAGE_CHILDREN measures this case's child only)."""
    spec = json.loads(sys.argv[sys.argv.index("--case") + 1])
    work = Path(spec["work"])
    global F
    F = Path(spec["inputs"])
    print(json.dumps(run_case(spec["case"], work, spec["max_s"], spec["max_mb"])))


def _one_message(row: dict) -> bool:
    return not any(p.endswith(" lines") or p.startswith("no '") for p in row["problems"])


def _nothing_written(row: dict) -> bool:
    return not any(p.startswith("wrote") or p == "inputs changed" for p in row["problems"])


def main() -> None:
    if "--case" in sys.argv:
        return _one_case_main()
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--only", nargs="*", choices=sorted(CLASSES), help="classes to run")
    ap.add_argument("--max-s", type=float, default=10.0)
    ap.add_argument("--max-mb", type=float, default=1024.0)
    ap.add_argument("--json", type=Path, default=None, help="write every row here")
    ap.add_argument("--verbose", "-v", action="store_true", help="print clean rows too")
    args = ap.parse_args()
    global F
    F = Path(tempfile.mkdtemp(prefix="warerover-battery-inputs-"))
    inputs = _inputs()
    for name in args.only or CLASSES:
        CLASSES[name](inputs)
    work = Path(tempfile.mkdtemp(prefix="warerover-battery-work-"))
    rows = []
    for cs in cases:
        spec = {"case": cs, "work": str(work), "inputs": str(F), "max_s": args.max_s,
                "max_mb": args.max_mb}
        r = subprocess.run([sys.executable, __file__, "--case", json.dumps(spec)],
                           capture_output=True, text=True)
        try:
            row = json.loads(r.stdout.strip().splitlines()[-1])
        except (IndexError, json.JSONDecodeError):
            row = {"class": cs["cls"], "case": cs["name"], "rc": None, "seconds": 0,
                   "peak_mb": 0, "message": r.stderr[-200:], "problems": ["battery error"],
                   "clean": False}
        rows.append(row)
        if args.verbose or not row["clean"]:
            print(f"{'ok  ' if row['clean'] else 'FAIL'} {row['class']:<17} {row['case']:<36} "
                  f"rc={row['rc']} {row['seconds']:5.1f} s {row['peak_mb']:5d} MB  "
                  f"{', '.join(row['problems'])}  :: {row['message'][:110]}", flush=True)
    print()
    print("| class | cases | exit code right | one message | no traceback | nothing written "
          "| max s | max MB | clean |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name in dict.fromkeys(r["class"] for r in rows):
        rs = [r for r in rows if r["class"] == name]

        def ok(word: str, rs=rs) -> int:
            return sum(not any(p.startswith(word) for p in r["problems"]) for r in rs)

        print(f"| {name} | {len(rs)} | {ok('rc')} | {sum(_one_message(r) for r in rs)} | "
              f"{ok('traceback')} | {sum(_nothing_written(r) for r in rs)} | "
              f"{max(r['seconds'] for r in rs):.1f} | {max(r['peak_mb'] for r in rs)} | "
              f"{sum(r['clean'] for r in rs)} |")
    clean = sum(r["clean"] for r in rows)
    print(f"\n{clean}/{len(rows)} clean")
    if args.json is not None:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(rows, indent=1) + "\n")
    shutil.rmtree(work, ignore_errors=True)
    shutil.rmtree(F, ignore_errors=True)
    sys.exit(0 if clean == len(rows) else 1)


if __name__ == "__main__":
    main()
