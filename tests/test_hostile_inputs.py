"""Hostile inputs by class (issue 31), each built in a temporary folder and run as its own
process: exit 2 (130 for Ctrl-C), one line on stderr, no traceback, nothing written.

Here: special files (a FIFO, ``/dev/zero``: 10 s limits), seeds (one rule, 0 .. 2**63 - 1)
and messages; the other classes are in ``test_hostile_work.py``.
"""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

import pytest
from hardening_helpers import (
    HOMO,
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


# ----------------------------------------------------------------------------- special files

SPECIAL_COMMANDS = {
    "run": lambda f, i: ["run", f("yaml")],
    "solve map": lambda f, i: ["solve", f("map"), SCEN],
    "solve scen": lambda f, i: ["solve", MAP, f("scen")],
    "execute plan": lambda f, i: ["execute", MAP, "--plan", f("txt")],
    "execute fleet": lambda f, i: ["execute", MAP, "--plan", i / "plan.txt", "--fleet",
                                   f("yaml")],
    "lorr": lambda f, i: ["lorr", f("json")],
    "render": lambda f, i: ["render", f("npz"), "--out", "x.mp4"],
    "sweep": lambda f, i: ["sweep", f("yaml"), "--out", "sw"],
}


def _special_cases() -> list:
    """Every command with a FIFO in make test; /dev/zero only for ``run`` there, for the
    others in make test-all (each case is a process of its own, about a second)."""
    return [(c, k) if k == "fifo" or c == "run" else pytest.param(c, k, marks=pytest.mark.slow)
            for c in sorted(SPECIAL_COMMANDS) for k in ("fifo", "zero")]


@pytest.mark.parametrize("command,kind", _special_cases())
def test_special_files_are_refused_before_they_are_read(box, kind, command):
    """A FIFO would block the reader for ever; /dev/zero never ends (stat says 0 bytes for
    both): refused unopened, within 10 s, the message saying what the file is."""
    inputs, work = box

    def special(ext: str) -> Path:
        p = inputs / f"{kind}.{ext}"
        if not os.path.lexists(p):
            if kind == "fifo":
                os.mkfifo(p)
            else:
                p.symlink_to("/dev/zero")
        return p

    needle = "FIFO" if kind == "fifo" else "character device"
    refuse(work, *SPECIAL_COMMANDS[command](special, inputs), needles=[needle], timeout=10)


def test_a_map_named_in_a_layout_that_is_a_device_says_what_it_is(box):
    inputs, work = box
    text = HOMO.read_text().replace(
        "layout: maps/paper_20x15.yaml",
        "layout:\n  map: /dev/zero\n  stations: [[0, 0]]\n"
        "  parking: [{origin: [1, 1], rows: 1, cols: 9}]")
    (inputs / "s.yaml").write_text(text)
    err = refuse(work, "check", inputs / "s.yaml", needles=["layout.map", "character device"],
                 timeout=10)
    assert "not found" not in err


# ----------------------------------------------------------------------------- seeds

SEED_COMMANDS = {
    "run": ["run", HOMO], "gap": ["gap", HOMO], "solve": ["solve", MAP, SCEN],
    "execute": ["execute", MAP, "--plan", "PLAN"], "gap --plan": ["gap", MAP, "--plan", "PLAN"],
    "lorr": ["lorr", LORR], "serve": ["serve", HOMO, "--port", "0"],
    "export-glb": ["export-glb", "x.glb", HOMO],
}


def _seed_cases() -> list:
    """Every command with seed -1 in make test; 2**63 only for ``run`` there, for the others
    in make test-all (both values meet the same range check)."""
    return [(c, s) if s == "-1" or c == "run" else pytest.param(c, s, marks=pytest.mark.slow)
            for c in sorted(SEED_COMMANDS) for s in ("-1", str(2**63))]


@pytest.mark.parametrize("command,seed", _seed_cases())
def test_one_seed_rule_for_every_command(box, command, seed):
    inputs, work = box
    args = [inputs / "plan.txt" if a == "PLAN" else a for a in SEED_COMMANDS[command]]
    refuse(work, *args, "--seed", seed, needles=["--seed", str(2**63 - 1)])


def test_the_largest_seed_is_taken(box):
    inputs, work = box
    proc = subprocess.run(cli_argv("solve", MAP, SCEN, "--agents", "4", "--seed",
                                   str(2**63 - 1), "--json"), cwd=work, env=cli_env(),
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0 and json.loads(proc.stdout)["success"], proc.stderr


# ----------------------------------------------------------------------------- messages

def test_a_json_file_given_to_render_is_not_an_npz(box):
    inputs, work = box
    (inputs / "a.json").write_text(json.dumps({"a": 1}))
    err = refuse(work, "render", inputs / "a.json", "--out", "x.mp4",
                 needles=["not an .npz archive"])
    assert "allow_pickle" not in err


def test_sweep_only_names_only(box):
    inputs, work = box
    (inputs / "sw.yaml").write_text(f"scenarios: {{Ho: {HOMO}}}\nrepetitions: 1\n")
    err = refuse(work, "sweep", inputs / "sw.yaml", "--out", "sw", "--only", "nonsense",
                 needles=["--only"])
    assert "--set" not in err
