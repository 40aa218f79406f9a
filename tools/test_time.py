"""Time ``make test`` (the default set) as a newcomer meets it: a fresh clone, its own venv,
an empty numba compile cache. Prints one JSON document: wall clock, CPU time (user + sys of
``make test`` and every process it started and waited for), the load average before and
after, the outcome counts, the 20 slowest tests and the heaviest files.

    .venv/bin/python tools/test_time.py                    # clone HEAD of this checkout
    .venv/bin/python tools/test_time.py --ref main --json build/test_time.json
    .venv/bin/python tools/test_time.py --in-place         # this checkout, no clone

The clone gets ``../shared`` beside it (a link to this checkout's ``../shared``), as CI has.
``make .venv/.installed`` in the clone is timed apart: it is not part of ``make test``.
On a shared machine the wall clock measures the others' load as well; the CPU time and the
load average say how far to trust it.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
from collections import defaultdict
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent


def _children_cpu() -> tuple[float, float]:
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime, ru.ru_stime


def _timed(cmd: list[str], cwd: Path, env: dict[str, str], log: Path) -> dict:
    """Run ``cmd``; its wall clock and the CPU time of it and its waited-for descendants."""
    u0, s0 = _children_cpu()
    load0 = os.getloadavg()
    t0 = time.monotonic()
    with log.open("w") as out:
        rc = subprocess.run(cmd, cwd=cwd, env=env, stdout=out, stderr=subprocess.STDOUT).returncode
    wall = time.monotonic() - t0
    u1, s1 = _children_cpu()
    return {"rc": rc, "wall_s": round(wall, 1), "cpu_user_s": round(u1 - u0, 1),
            "cpu_sys_s": round(s1 - s0, 1), "cpu_s": round(u1 - u0 + s1 - s0, 1),
            "loadavg_start": [round(x, 2) for x in load0],
            "loadavg_end": [round(x, 2) for x in os.getloadavg()], "log": str(log)}


def _junit(path: Path, top: int) -> dict:
    """Outcome counts, the ``top`` slowest tests (setup + call + teardown) and the heaviest
    files, from pytest's JUnit XML."""
    cases = []
    counts = defaultdict(int)
    for case in ET.parse(path).getroot().iter("testcase"):
        outcome = "passed"
        for tag in ("failure", "error", "skipped"):
            if case.find(tag) is not None:
                outcome = {"failure": "failed", "error": "error"}.get(tag, tag)
        counts[outcome] += 1
        name = f"{case.get('classname', '').replace('.', '/')}.py::{case.get('name')}"
        cases.append((float(case.get("time", 0.0)), name))
    cases.sort(reverse=True)
    per_file: dict[str, float] = defaultdict(float)
    for t, name in cases:
        per_file[name.split("::")[0]] += t
    files = sorted(per_file.items(), key=lambda kv: -kv[1])[:top]
    return {"counts": dict(counts), "tests": len(cases),
            "sum_of_test_times_s": round(sum(t for t, _ in cases), 1),
            "slowest": [{"test": n, "s": round(t, 2)} for t, n in cases[:top]],
            "heaviest_files": [{"file": f, "s": round(t, 1)} for f, t in files]}


def _cpu(folder: Path, top: int) -> dict:
    """The sum of the tests' CPU times and the ``top`` dearest, from tools/pytest_cpu.py."""
    rows = [json.loads(line) for f in sorted(folder.glob("*.jsonl")) for line in f.open()]
    rows.sort(key=lambda r: -r["cpu_s"])
    per_worker = defaultdict(float)
    for f in sorted(folder.glob("*.jsonl")):
        per_worker[f.stem] = round(sum(json.loads(line)["cpu_s"] for line in f.open()), 1)
    return {"sum_of_test_cpu_s": round(sum(r["cpu_s"] for r in rows), 1),
            "test_cpu_per_worker_s": dict(per_worker),
            "dearest_cpu": [{"test": r["test"], "cpu_s": r["cpu_s"], "wall_s": r["wall_s"]}
                            for r in rows[:top]]}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--ref", default="HEAD", help="what to clone (default: HEAD)")
    ap.add_argument("--in-place", action="store_true",
                    help="time this checkout's make test instead of a fresh clone")
    ap.add_argument("--workdir", type=Path, help="where to clone (default: a new temp folder)")
    ap.add_argument("--keep", action="store_true", help="keep the clone afterwards")
    ap.add_argument("--top", type=int, default=20, help="how many slowest tests (default 20)")
    ap.add_argument("--json", type=Path, help="also write the JSON document here")
    args = ap.parse_args(argv)

    work = args.workdir or Path(tempfile.mkdtemp(prefix="test_time."))
    work.mkdir(parents=True, exist_ok=True)
    result: dict = {"nproc": os.cpu_count()}
    if args.in_place:
        repo = REPO
    else:
        repo = work / "repo"
        ref = subprocess.run(["git", "rev-parse", args.ref], cwd=REPO, check=True,
                             capture_output=True, text=True).stdout.strip()
        subprocess.run(["git", "clone", "-q", "--no-checkout", str(REPO), str(repo)], check=True)
        subprocess.run(["git", "checkout", "-q", ref], cwd=repo, check=True)
        shared = (REPO.parent / "shared").resolve()
        if shared.exists() and not (work / "shared").exists():
            (work / "shared").symlink_to(shared)
        result["install"] = _timed(["make", ".venv/.installed"], repo, dict(os.environ),
                                   work / "install.log")
        if result["install"]["rc"] != 0:
            print(json.dumps(result, indent=1))
            return 1
    result["commit"] = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=repo,
                                      capture_output=True, text=True).stdout.strip()
    nb = work / "numba_cache"
    shutil.rmtree(nb, ignore_errors=True)
    nb.mkdir()
    env = {k: v for k, v in os.environ.items() if k not in ("CI", "HYPOTHESIS_PROFILE")}
    env["NUMBA_CACHE_DIR"] = str(nb)  # an empty compile cache: every kernel compiles
    junit, cpu_dir = work / "junit.xml", work / "cpu"
    shutil.rmtree(cpu_dir, ignore_errors=True)
    # tools/pytest_cpu.py (from this checkout) records each test's CPU time.
    env["PYTHONPATH"] = os.pathsep.join([str(REPO / "tools"), env.get("PYTHONPATH", "")])
    env["PYTEST_CPU_OUT"] = str(cpu_dir)
    result["make_test"] = _timed(
        ["make", "test", f"TEST_ARGS=--junitxml={junit} -p pytest_cpu"], repo, env,
        work / "make_test.log")
    if junit.exists():
        result["make_test"].update(_junit(junit, args.top))
    result["make_test"].update(_cpu(cpu_dir, args.top))
    result["workdir"] = str(work)
    ok = result["make_test"]["rc"] == 0
    if ok and not args.keep and not args.in_place and args.workdir is None:
        shutil.rmtree(work, ignore_errors=True)
        result["workdir"] = None
    doc = json.dumps(result, indent=1)
    print(doc)
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(doc + "\n")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
