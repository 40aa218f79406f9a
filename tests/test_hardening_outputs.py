"""Run outputs as one set (``warerover_phys.util.atomic.write_set``): a run folder is replaced
whole; a folder that is more than a run folder is written in place behind an incomplete
manifest; readers refuse anything that is not one whole set."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest
from hardening_helpers import LAYOUTS

from warerover_phys.errors import WareroverError
from warerover_phys.util.atomic import MANIFEST, check_set, write_set


def writers(tag: str, with_npz: bool = True) -> dict:
    out = {"metrics.json": lambda p: p.write_text(json.dumps({"tag": tag})),
           "events.jsonl": lambda p: p.write_text(tag + "\n")}
    if with_npz:
        out["trajectories.npz"] = lambda p: p.write_bytes(tag.encode())
    return out


def test_new_set_replaces_old_and_keeps_foreign_files(tmp_path):
    out = tmp_path / "run"
    write_set(out, writers("a"))
    (out / "video.mp4").write_bytes(b"mine")
    write_set(out, writers("b", with_npz=False))
    assert sorted(p.name for p in out.iterdir()) == ["events.jsonl", "manifest.json",
                                                     "metrics.json", "video.mp4"]
    assert (out / "video.mp4").read_bytes() == b"mine"
    assert check_set(out)["complete"] is True
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


def test_folder_with_subfolders_is_written_in_place(tmp_path):
    out = tmp_path / "project"
    (out / "src").mkdir(parents=True)
    (out / "src" / "keep.py").write_text("x = 1\n")
    write_set(out, writers("a"))
    write_set(out, writers("b", with_npz=False))          # an older trajectory is removed
    assert (out / "src" / "keep.py").read_text() == "x = 1\n"
    assert not (out / "trajectories.npz").exists()
    assert json.loads((out / "metrics.json").read_text()) == {"tag": "b"}
    assert check_set(out)["complete"] is True


def test_dot_and_working_folder_are_written_in_place(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "notes.txt").write_text("n")
    files = write_set(".", writers("a"))
    assert files["metrics.json"] == Path("metrics.json")
    assert (tmp_path / "notes.txt").read_text() == "n" and check_set(tmp_path)
    write_set(tmp_path, writers("b"))                     # the same folder, absolute
    assert json.loads((tmp_path / "metrics.json").read_text()) == {"tag": "b"}


def test_interrupted_in_place_write_is_refused(tmp_path):
    out = tmp_path / "project"
    (out / "sub").mkdir(parents=True)
    write_set(out, writers("a"))

    def boom(path):
        raise OSError(28, "No space left on device")

    with pytest.raises(OSError):
        write_set(out, {**writers("b"), "paths.json": boom})
    with pytest.raises(WareroverError, match="interrupted"):
        check_set(out)


def test_failed_swap_leaves_the_old_set(tmp_path):
    out = tmp_path / "run"
    write_set(out, writers("a"))

    def boom(path):
        raise OSError(28, "No space left on device")

    with pytest.raises(OSError):
        write_set(out, {**writers("b"), "paths.json": boom})
    assert json.loads((out / "metrics.json").read_text()) == {"tag": "a"}
    assert check_set(out)["complete"] is True
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


def test_symlinked_output_folder_is_not_swapped_away(tmp_path):
    real = tmp_path / "real"
    real.mkdir()
    link = tmp_path / "link"
    os.symlink(real, link)
    write_set(link, writers("a"))
    assert link.is_symlink() and (real / "metrics.json").exists() and check_set(real)


def test_run_into_current_folder_from_cli(tmp_path):
    from hardening_helpers import run_cli

    (tmp_path / "sub").mkdir()
    proc = run_cli("run", LAYOUTS / "paper_homogeneous.yaml", "--out", ".", "--json",
                   cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert (tmp_path / "sub").is_dir() and check_set(tmp_path)["complete"] is True
    assert json.loads((tmp_path / MANIFEST).read_text())["scenario"] == "paper_homogeneous"
