"""Hostile inputs by class (issue 31), part two (part one: ``test_hostile_inputs.py``):
output paths and formats checked before any work, silent acceptance (duplicate YAML keys,
AGV ids, ``numTasksReveal``, ``serve --speed``), unbounded work (seed ranges, frame counts,
npz headers and zip bombs, huge plans, impossible instances), interrupts and services
(Ctrl-C in ``solve --refine``, an unreachable ``--ray``). Each input is built in a
temporary folder and the command runs as its own process: exit 2 (130 for Ctrl-C), one
line on stderr, no traceback, nothing written.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest
from hardening_helpers import (
    DATA,
    HOMO,
    LAYOUTS,
    LORR,
    MAP,
    SCEN,
    cli_argv,
    cli_env,
    make_box,
    refuse,
)


@pytest.fixture
def box(tmp_path):
    return make_box(tmp_path)


# ----------------------------------------------------------------------------- late checks

def _late_cases(inputs: Path) -> dict[str, list]:
    afile = inputs / "afile"
    afile.write_text("x")
    under = afile / "sub"  # under a regular file: no one can create it, root included
    plan = inputs / "plan.txt"
    (inputs / "none.json").write_text(json.dumps({"paths": []}))
    (inputs / "sw.yaml").write_text(f"scenarios: {{Ho: {HOMO}}}\nrepetitions: 1\n")
    return {
        "run --out is a file": ["run", HOMO, "--out", afile],
        "run --out under a file": ["run", HOMO, "--out", under],
        "run --video under a file": ["run", HOMO, "--video", under / "v.mp4"],
        "gap --out is a file": ["gap", HOMO, "--out", afile],
        "gap --plan --out under a file": ["gap", MAP, "--plan", plan, "--out", under],
        "execute --out is a file": ["execute", MAP, "--plan", plan, "--out", afile],
        "execute --video under a file": ["execute", MAP, "--plan", plan, "--video",
                                         under / "v.mp4"],
        "execute --video not mp4": ["execute", MAP, "--plan", plan, "--video", "v.avi"],
        "execute --export under a file": ["execute", MAP, "--plan", plan, "--export",
                                          under / "e.txt"],
        "execute export cannot hold": ["execute", MAP, "--plan", inputs / "none.json",
                                       "--export", "e.txt", "--export-format", "lns"],
        "lorr --out is a file": ["lorr", LORR, "--out", afile],
        "solve --out under a file": ["solve", MAP, SCEN, "--out", under / "p.txt"],
        "sweep --out is a file": ["sweep", inputs / "sw.yaml", "--out", afile],
        "render --out under a file": ["render", inputs, "--out", under / "x.mp4"],
        "export-glb under a file": ["export-glb", under / "x.glb", HOMO],
    }


LATE = ["run --out is a file", "run --out under a file", "run --video under a file",
        "gap --out is a file", "gap --plan --out under a file", "execute --out is a file",
        "execute --video under a file", "execute --video not mp4",
        "execute --export under a file", "execute export cannot hold",
        "lorr --out is a file", "solve --out under a file", "sweep --out is a file",
        "render --out under a file", "export-glb under a file"]


@pytest.mark.parametrize("case", LATE)
def test_outputs_are_checked_before_any_work(box, case):
    """Refused in seconds (the work would take longer), nothing written; the file in the
    way is left as it was."""
    inputs, work = box
    args = _late_cases(inputs)[case]
    refuse(work, *args, timeout=20)
    assert (inputs / "afile").read_text() == "x"


# ----------------------------------------------------------------------------- silent

def test_duplicate_yaml_keys_are_refused_naming_the_key(box):
    """The last one used to win: a scenario ran 5 ticks instead of 1,000."""
    inputs, work = box
    text = HOMO.read_text().replace("max_ticks: 1000", "max_ticks: 1000\nmax_ticks: 5")
    (inputs / "maps").symlink_to(LAYOUTS / "maps")
    (inputs / "dup.yaml").write_text(text)
    refuse(work, "run", inputs / "dup.yaml", needles=["duplicate key 'max_ticks'", "line"])
    (inputs / "sw.yaml").write_text(f"scenarios: {{Ho: {HOMO}}}\nrepetitions: 1\n"
                                    "repetitions: 2\n")
    refuse(work, "sweep", inputs / "sw.yaml", "--out", "sw",
           needles=["duplicate key 'repetitions'"])


@pytest.mark.parametrize("args, needles", [
    (["gap", HOMO, "--agvs", "99"], ["--agvs", "9 AGVs", "99"]),
    (["gap", MAP, "--plan", "PLAN", "--agvs", "0,5"], ["--agvs", "1 AGVs", "5"]),
    (["serve", HOMO, "--speed", "nan", "--port", "0"], ["--speed"]),
    (["serve", HOMO, "--speed", "-2", "--port", "0"], ["--speed"]),
])
def test_values_accepted_silently_are_refused(box, args, needles):
    inputs, work = box
    refuse(work, *[inputs / "plan.txt" if a == "PLAN" else a for a in args], needles=needles)


@pytest.mark.slow  # a Robot Runners instance loaded in a subprocess: make test-all
def test_a_huge_numtasksreveal_is_refused(box):
    inputs, work = box
    doc = json.loads(LORR.read_text())
    for key in ("mapFile", "agentFile", "taskFile"):
        doc[key] = str(LORR.parent / doc[key])
    for value in (10**12, 0, -1, "3"):
        (inputs / "p.json").write_text(json.dumps({**doc, "numTasksReveal": value}))
        refuse(work, "lorr", inputs / "p.json", needles=["numTasksReveal"])


# ----------------------------------------------------------------------------- unbounded

def _npy_header(shape: tuple) -> bytes:
    header = f"{{'descr': '<f8', 'fortran_order': False, 'shape': {shape!r}, }}"
    header += " " * (63 - (len(header) + 10) % 64) + "\n"
    return b"\x93NUMPY\x01\x00" + len(header).to_bytes(2, "little") + header.encode()


def test_gap_seed_ranges_are_capped_before_any_list_is_made(box):
    inputs, work = box
    refuse(work, "gap", HOMO, "--seeds", "0..10000000", needles=["--seeds", "100,000"],
           timeout=10)
    refuse(work, "gap", HOMO, "--seeds", f"0..{2**62}", needles=["--seeds"], timeout=10)


@pytest.mark.slow  # an episode run before the refusal: make test-all
def test_a_video_of_too_many_frames_is_refused_before_the_first(box):
    inputs, work = box
    rec = inputs / "rec"
    done = subprocess.run(cli_argv("execute", MAP, "--plan", inputs / "plan.txt", "--out",
                                   rec), cwd=inputs, env=cli_env(), capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    refuse(work, "render", rec, "--out", "x.mp4", "--speed", "1e-9", needles=["frames"],
           timeout=20)
    refuse(work, "run", HOMO, "--video", "x.mp4", "--speed", "1e-9", needles=["frames"],
           timeout=20)


def test_an_npz_header_claiming_10e12_rows_is_refused_unread(box):
    inputs, work = box
    folder = inputs / "claim"
    folder.mkdir()
    with zipfile.ZipFile(folder / "trajectories.npz", "w") as z:
        z.writestr("x.npy", _npy_header((10**12, 3)))
    for command in (["render", folder, "--out", "x.mp4"], ["check-trajectory", folder]):
        refuse(work, *command, needles=["header says shape"], timeout=10)


def test_a_zip_bomb_is_refused_from_its_directory(tmp_path):
    """64 MiB of zeros in ~64 KiB, read with a 32 MiB limit: refused before inflating
    (the commands' limit is 2 GiB; the battery tries a 2.25 GiB bomb through them)."""
    from warerover_phys.errors import ScenarioError
    from warerover_phys.inputs import load_npz

    bomb = tmp_path / "bomb.npz"
    with zipfile.ZipFile(bomb, "w", compression=zipfile.ZIP_DEFLATED) as z, \
            z.open("x.npy", "w", force_zip64=True) as f:
        f.write(_npy_header((8 * 2**20,)))
        for _ in range(4):
            f.write(bytes(2**24))
    assert bomb.stat().st_size < 2**20
    with pytest.raises(ScenarioError, match="would take"):
        load_npz(bomb, limit=32 * 2**20)
    assert load_npz(bomb, limit=80 * 2**20)["x"].shape == (8 * 2**20,)


def test_an_npz_with_an_object_array_is_refused(tmp_path):
    from warerover_phys.errors import ScenarioError
    from warerover_phys.inputs import load_npz

    f = tmp_path / "o.npz"
    np.savez(f, a=np.array([{"x": 1}], dtype=object))
    with pytest.raises(ScenarioError, match="Python objects"):
        load_npz(f)


def test_a_plan_of_too_many_agents_is_refused_before_it_is_parsed(box):
    inputs, work = box
    (inputs / "many.txt").write_text("0:" + "(1,1)," * 100_001 + "\n")
    refuse(work, "execute", MAP, "--plan", inputs / "many.txt", needles=["100,000 agents"],
           timeout=10)


def test_two_agents_on_one_start_are_refused_at_once(box):
    inputs, work = box
    lines = SCEN.read_text().splitlines()
    second = lines[2].split("\t")
    second[4:6] = lines[1].split("\t")[4:6]
    (inputs / "same.scen").write_text("\n".join([lines[0], lines[1], "\t".join(second),
                                                 *lines[3:]]) + "\n")
    refuse(work, "solve", MAP, inputs / "same.scen", "--agents", "5",
           needles=["agents 0 and 1", "same start"], timeout=10)


# ----------------------------------------------------------------------------- interrupts

@pytest.mark.slow  # 8 s of refinement before the interrupt: make test-all
def test_ctrl_c_in_solve_refine_is_one_line_and_130(box):
    """The search runs compiled code: Python's KeyboardInterrupt surfaced there as a
    SystemError with two tracebacks."""
    inputs, work = box
    proc = subprocess.Popen(cli_argv("solve", DATA / "warehouse-10-20-10-2-1.map",
                                     DATA / "warehouse-10-20-10-2-1-random-1.scen",
                                     "--agents", "100", "--refine", "--time-limit", "60",
                                     "--json", "--out", "plan.txt"),
                            cwd=work, env=cli_env(), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)
    time.sleep(8)  # start-up, the first solution; then the refinement runs
    os.killpg(proc.pid, signal.SIGINT)
    out, err = proc.communicate(timeout=30)
    assert proc.returncode == 130, err
    assert err.strip() == "interrupted" and "Traceback" not in err + out
    assert list(work.iterdir()) == []


def test_an_unreachable_ray_address_is_refused_fast_leaving_nothing(box):
    inputs, work = box
    (inputs / "sw.yaml").write_text(f"scenarios: {{Ho: {HOMO}}}\nrepetitions: 1\n")
    refuse(work, "sweep", inputs / "sw.yaml", "--out", "sw", "--ray", "127.0.0.1:1",
           needles=["--ray", "cannot reach"], timeout=10)


