"""``warerover render`` on bad input: corrupt, truncated or inconsistent trajectories,
``paths.json`` and ``events.jsonl``, mixed run folders, wrong output extensions. Each is one
clean error (exit 2) and never leaves a partial output; an existing video survives."""

from __future__ import annotations

import hashlib
import io
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from hardening_helpers import LAYOUTS, assert_clean_error, run_cli

from warerover_phys.errors import WareroverError
from warerover_phys.render import load_trajectory
from warerover_phys.util.atomic import MANIFEST, check_set


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory) -> Path:
    from warerover_phys import load_scenario, run_episode
    from warerover_phys.outputs import write_outputs

    sc = load_scenario(LAYOUTS / "paper_homogeneous.yaml",
                       [("executor.name", "physics"), ("max_ticks", 30)])
    out = tmp_path_factory.mktemp("run") / "r"
    write_outputs(run_episode(sc, seed=1), out)
    return out


def copy_run(run_dir: Path, tmp_path: Path, keep_manifest: bool = False) -> Path:
    dst = tmp_path / "copy"
    shutil.copytree(run_dir, dst)
    if not keep_manifest:
        (dst / MANIFEST).unlink()
    return dst


def arrays(run_dir: Path) -> dict[str, np.ndarray]:
    with np.load(run_dir / "trajectories.npz") as data:
        return {k: data[k] for k in data.files}


def save(path: Path, traj: dict) -> None:
    buf = io.BytesIO()
    np.savez(buf, **traj)
    path.write_bytes(buf.getvalue())


def corrupt_npz(kind: str, run_dir: Path, folder: Path) -> None:
    f = folder / "trajectories.npz"
    raw = (run_dir / "trajectories.npz").read_bytes()
    traj = arrays(run_dir)
    if kind == "truncated":
        f.write_bytes(raw[: len(raw) // 2])
    elif kind == "empty":
        f.write_bytes(b"")
    elif kind == "garbage":
        f.write_bytes(b"\x00\x01not a zip" * 100)
    elif kind == "flipped":
        f.write_bytes(raw[:200] + bytes(b ^ 0xFF for b in raw[200:400]) + raw[400:])
    elif kind == "npy":
        np.save(f.open("wb"), np.zeros(3))
    elif kind == "pickle":
        buf = io.BytesIO()
        np.savez(buf, **{**traj, "x": np.array([{"a": 1}], dtype=object)})
        f.write_bytes(buf.getvalue())
    elif kind == "missing-key":
        save(f, {k: v for k, v in traj.items() if k != "heading"})
    elif kind == "short-x":
        save(f, {**traj, "x": traj["x"][:-1]})
    elif kind == "nan-x":
        x = traj["x"].copy()
        x[0, 0] = np.nan
        save(f, {**traj, "x": x})
    elif kind == "t-backwards":
        save(f, {**traj, "t": traj["t"][::-1].copy()})
    elif kind == "t-empty":
        save(f, {**traj, "t": np.zeros(0)})
    elif kind == "grid-1d":
        save(f, {**traj, "grid": np.zeros(5, dtype=np.int8)})
    elif kind == "grid-float":
        save(f, {**traj, "grid": traj["grid"].astype(float)})
    elif kind == "cell-inf":
        save(f, {**traj, "cell_m": np.array(np.inf)})
    elif kind == "tick-zero":
        save(f, {**traj, "tick_s": np.array(0.0)})
    elif kind == "footprint-short":
        save(f, {**traj, "footprint": traj["footprint"][:-1]})
    elif kind == "body-negative":
        save(f, {**traj, "body_m": -traj["body_m"]})
    elif kind == "corridors-bad":
        save(f, {**traj, "corridors_json": np.array("{not json")})
    elif kind == "corridors-shape":
        save(f, {**traj, "corridors_json": np.array("[1, 2]")})
    elif kind == "x-text":
        save(f, {**traj, "x": np.full(traj["x"].shape, "a")})
    else:
        raise AssertionError(kind)


NPZ = ["truncated", "empty", "garbage", "flipped", "npy", "pickle", "missing-key", "short-x",
       "nan-x", "t-backwards", "t-empty", "grid-1d", "grid-float", "cell-inf", "tick-zero",
       "footprint-short", "body-negative", "corridors-bad", "corridors-shape", "x-text"]


@pytest.mark.parametrize("kind", NPZ)
def test_bad_trajectory_is_one_error(run_dir, tmp_path, kind):
    folder = copy_run(run_dir, tmp_path)
    corrupt_npz(kind, run_dir, folder)
    with pytest.raises(WareroverError) as info:
        load_trajectory(folder)
    assert "trajectories.npz" in str(info.value) and "\n" not in str(info.value)


JSONS = {
    "paths-truncated": ("paths.json", lambda t: t[: len(t) // 2]),
    "paths-not-json": ("paths.json", lambda t: "]]]"),
    "paths-list": ("paths.json", lambda t: "[1, 2]"),
    "paths-planned-dict": ("paths.json", lambda t: '{"planned": {"a": 1}}'),
    "paths-plan-missing": ("paths.json", lambda t: '{"planned": [{"agv": 0}]}'),
    "paths-states-ragged": ("paths.json",
                            lambda t: '{"planned": [{"agv": 0, "tick": 0, "states": [[1], 2]}]}'),
    "paths-states-3": ("paths.json",
                       lambda t: '{"planned": [{"agv": 0, "tick": 0, "states": [[1, 2, 3]]}]}'),
    "paths-binary": ("paths.json", lambda t: "\udcff"),
    "paths-deep": ("paths.json", lambda t: "[" * 100000 + "]" * 100000),
    "events-truncated": ("events.jsonl", lambda t: t[: len(t) // 2 + 7]),
    "events-not-objects": ("events.jsonl", lambda t: "1\n2\n"),
    "events-bad-tick": ("events.jsonl", lambda t: '{"event": "order_created", "tick": "x"}\n'),
}


@pytest.mark.parametrize("kind", sorted(JSONS))
def test_bad_side_file_is_one_error(run_dir, tmp_path, kind):
    folder = copy_run(run_dir, tmp_path)
    name, change = JSONS[kind]
    text = change((folder / name).read_text(encoding="utf-8"))
    (folder / name).write_bytes(text.encode("utf-8", "surrogateescape"))
    with pytest.raises(WareroverError) as info:
        load_trajectory(folder)
    assert name in str(info.value) and "\n" not in str(info.value)


@pytest.mark.parametrize("change", ["metrics", "trajectory", "extra", "missing", "manifest"])
def test_mixed_run_folder_is_refused(run_dir, tmp_path, change):
    folder = copy_run(run_dir, tmp_path, keep_manifest=True)
    assert check_set(folder) is not None
    if change == "metrics":
        (folder / "metrics.json").write_text("{}")
    elif change == "trajectory":
        traj = arrays(run_dir)
        save(folder / "trajectories.npz", {**traj, "x": traj["x"] + 1})
    elif change == "extra":
        manifest = json.loads((folder / MANIFEST).read_text())
        del manifest["files"]["trajectories.npz"]
        (folder / MANIFEST).write_text(json.dumps(manifest))
    elif change == "missing":
        (folder / "events.jsonl").unlink()
    else:
        (folder / MANIFEST).write_text('{"run_id": ')
    with pytest.raises(WareroverError, match="mixed|incomplete|manifest"):
        load_trajectory(folder)


def test_failed_render_keeps_existing_video(run_dir, tmp_path, monkeypatch):
    from warerover_phys.render import Style, render_video, video

    rec = load_trajectory(run_dir)
    out = tmp_path / "v.mp4"
    render_video(rec, out, fps=5, max_frames=3, style=Style(size=(160, 120)))
    before = hashlib.sha256(out.read_bytes()).hexdigest()
    calls = []

    def boom(*args, **kwargs):
        calls.append(1)
        if len(calls) > 2:
            raise RuntimeError("renderer died")
        return np.zeros((120, 160, 3), np.uint8)

    monkeypatch.setattr(video, "draw_frame", boom)
    with pytest.raises(RuntimeError):
        render_video(rec, out, fps=5, max_frames=10, style=Style(size=(160, 120)))
    assert hashlib.sha256(out.read_bytes()).hexdigest() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["v.mp4"]


@pytest.fixture(scope="module")
def cli_results(run_dir, tmp_path_factory):
    from concurrent.futures import ThreadPoolExecutor

    root = tmp_path_factory.mktemp("cli")
    bad = root / "bad"
    shutil.copytree(run_dir, bad)
    (bad / MANIFEST).unlink()
    corrupt_npz("truncated", run_dir, bad)
    badpaths = root / "badpaths"
    shutil.copytree(run_dir, badpaths)
    (badpaths / MANIFEST).unlink()
    (badpaths / "paths.json").write_text('{"planned": [1, 2')
    mixed = root / "mixed"
    shutil.copytree(run_dir, mixed)
    (mixed / "metrics.json").write_text("{}")
    cases = {
        "npz": ("render", bad, "--out", root / "a.mp4"),
        "paths": ("render", badpaths, "--out", root / "b.mp4"),
        "mixed": ("render", mixed, "--out", root / "c.mp4"),
        "png-ext": ("render", run_dir, "--out", root / "d.gif", "--png", "3"),
        "png-mp4": ("render", run_dir, "--out", root / "d.mp4", "--png", "3"),
        "video-ext": ("render", run_dir, "--out", root / "e.avi"),
        "video-dir": ("render", run_dir, "--out", root),
        "run-video-ext": ("run", LAYOUTS / "paper_homogeneous.yaml", "--out", root / "r",
                          "--video", root / "f.png"),
    }
    with ThreadPoolExecutor(2) as pool:
        futs = {k: pool.submit(run_cli, *args, cwd=root) for k, args in cases.items()}
        return root, {k: f.result() for k, f in futs.items()}


@pytest.mark.parametrize("case,needles", [
    ("npz", ["trajectories.npz"]), ("paths", ["paths.json"]), ("mixed", ["mixed", "metrics"]),
    ("png-ext", ["--out", "d.gif"]), ("png-mp4", ["--out"]), ("video-ext", ["--out", "e.avi"]),
    ("video-dir", ["--out"]), ("run-video-ext", ["--video", "f.png"])])
def test_cli_render_errors(cli_results, case, needles):
    root, procs = cli_results
    assert_clean_error(procs[case], *needles)
    assert not any(p.suffix in (".mp4", ".gif", ".avi") for p in root.iterdir())
    assert not (root / "r").exists()
