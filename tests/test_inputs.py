"""``warerover_phys.inputs``: the checks every command makes on its files and options."""

from __future__ import annotations

import os
import threading

import pytest

from warerover_phys.errors import ScenarioError, WareroverError
from warerover_phys.inputs import (
    MAX_SEED,
    check_output_dir,
    check_output_file,
    check_regular_file,
    check_seed,
    read_bytes,
    read_text,
)


def test_seeds():
    assert check_seed(0) == 0 and check_seed(MAX_SEED) == MAX_SEED
    for bad in (-1, MAX_SEED + 1, 2**70, 1.0, True, "3"):
        with pytest.raises(WareroverError, match="--seed"):
            check_seed(bad)


def test_special_files_are_refused_unopened(tmp_path):
    fifo = tmp_path / "f.yaml"
    os.mkfifo(fifo)
    done = threading.Event()

    def read() -> None:
        with pytest.raises(ScenarioError, match="FIFO"):
            read_bytes(fifo)
        done.set()

    t = threading.Thread(target=read, daemon=True)
    t.start()
    t.join(10)
    assert done.is_set(), "blocked on the FIFO"
    with pytest.raises(ScenarioError, match="character device"):
        read_bytes("/dev/zero")
    with pytest.raises(ScenarioError, match="directory"):
        check_regular_file(tmp_path)
    with pytest.raises(ScenarioError, match="not found"):
        check_regular_file(tmp_path / "none")


def test_reads_stop_at_the_limit(tmp_path):
    f = tmp_path / "a.txt"
    f.write_bytes(b"x" * 100)
    assert read_bytes(f, limit=100) == b"x" * 100
    with pytest.raises(ScenarioError, match="larger than 99 bytes"):
        read_bytes(f, limit=99)
    f.write_bytes(b"\xff\xfe")
    with pytest.raises(ScenarioError, match="not UTF-8"):
        read_text(f)


def test_output_checks_leave_nothing_behind(tmp_path):
    before = sorted(tmp_path.iterdir())
    assert check_output_dir(tmp_path / "new" / "deeper") == tmp_path / "new" / "deeper"
    assert check_output_file(tmp_path / "x.mp4", suffixes=(".mp4",)) == tmp_path / "x.mp4"
    assert sorted(tmp_path.iterdir()) == before
    afile = tmp_path / "afile"
    afile.write_text("x")
    with pytest.raises(WareroverError, match="not a folder"):
        check_output_dir(afile)
    with pytest.raises(WareroverError, match="not a folder"):
        check_output_dir(afile / "sub")
    with pytest.raises(WareroverError, match="not a file"):
        check_output_file(tmp_path)
    with pytest.raises(WareroverError, match="expected a .mp4"):
        check_output_file(tmp_path / "x.avi", "--video", suffixes=(".mp4",))
    assert sorted(tmp_path.iterdir()) == sorted([*before, afile])
