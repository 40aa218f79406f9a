"""Editor back end (load / check / save), replay readers and glTF export."""

from __future__ import annotations

import json
import struct

import numpy as np
import pytest
from typer.testing import CliRunner

from warerover_phys.serve.layout_edit import check_doc, doc_from_file, layout_dict, save_doc
from warerover_phys.serve.protocol import LayoutDoc
from warerover_phys.serve.replay import encode_replay, open_replay

from .conftest import REPO


def _check_cli(path):
    from warerover_phys.cli import app

    return CliRunner().invoke(app, ["check", str(path)])


def test_layout_round_trip_and_check(tmp_path):
    doc = doc_from_file(REPO / "layouts" / "paper_heterogeneous.yaml")
    assert doc.big_shelves and "B" in doc.cells and "R" in doc.cells
    assert check_doc(doc) == []
    files = save_doc(doc, tmp_path / "het.yaml")
    again = doc_from_file(files[0])
    assert again.cells == doc.cells and sorted(again.big_shelves) == sorted(doc.big_shelves)
    result = _check_cli(files[1])
    assert result.exit_code == 0, result.output
    assert "ok" in result.output


def test_check_names_the_bad_cells():
    rows = ["R#.......",
            "##.......",
            "...SS....",
            ".........",
            "PPPP....."]
    doc = LayoutDoc(rows=5, cols=9, cells="".join(rows))
    errors = check_doc(doc)
    assert errors and [0, 0] in errors[0]["cells"], errors
    assert "station" in errors[0]["message"]
    assert check_doc(doc.model_copy(update={"cells": "R" + "." + "".join(rows)[2:]})) == []


def test_layout_dict_shapes():
    doc = LayoutDoc(rows=3, cols=4, cells="BB.R" "BB.P" "..AP", big_shelves=[(0, 0)])
    d = layout_dict(doc)
    assert d["grid"] == ["...R", "...P", "..AP"]
    assert d["shelf_blocks"] == [{"origin": [0, 0], "size": 2}]


def _episode(executor: str, ticks: int):
    from warerover_phys.config import load_scenario
    from warerover_phys.sim import run_episode

    sc = load_scenario(REPO / "layouts" / "paper_homogeneous.yaml",
                       [("executor.name", executor), ("max_ticks", ticks)])
    return sc, run_episode(sc)


def test_replay_of_physics_trajectory_and_paths_json(tmp_path):
    from warerover_phys.outputs import write_outputs

    sc, result = _episode("physics", 40)
    write_outputs(result, tmp_path / "run")
    data = open_replay(tmp_path / "run" / "trajectories.npz")
    n = len(result.world.agvs)
    assert data.x.shape[1] == n and data.gx is not None and data.kind == "trajectories.npz"
    assert data.t[-1] >= 39
    body = encode_replay(data)
    t, nn, flags = struct.unpack_from("<III", body, 4)
    assert (t, nn, flags) == (len(data.t), n, 1)
    # paths.json alone: the layout comes from the fallback grid (the live scenario's)
    grid = np.asarray(result.world.layout.grid)
    pj = open_replay(tmp_path / "run" / "paths.json", None, grid, 1.0)
    assert pj.x.shape == (41, n) and pj.gx is not None
    # executed and planned agree on the grid... at the first tick
    assert np.allclose(pj.x[0], pj.gx[0])


def test_replay_of_robot_runners_output(tmp_path):
    (tmp_path / "m.map").write_text("type octile\nheight 4\nwidth 5\nmap\n.....\n.....\n"
                                    ".@...\n.....\n")
    out = {"teamSize": 2, "start": [[0, 0, "E"], [3, 4, "N"]],
           "actualPaths": ["F,F,R,F", "W,F,C,F"], "plannerPaths": ["F,F,R,F", "F,C,F,W"]}
    (tmp_path / "out.json").write_text(json.dumps(out))
    data = open_replay(tmp_path / "out.json", tmp_path / "m.map")
    assert data.x.shape == (5, 2) and data.kind == "Robot Runners output"
    # agent 0: (0,0)E -> F (0,1) -> F (0,2) -> R faces S -> F (1,2)
    assert (data.y[-1, 0], data.x[-1, 0]) == (1.5, 2.5)
    assert data.heading[-1, 0] == pytest.approx(np.pi / 2)
    # agent 1 waited first: its ghost is one move ahead at t=1
    assert data.gy[1, 1] == 2.5 and data.y[1, 1] == 3.5


def test_glb_export_with_animation(tmp_path):
    pytest.importorskip("trimesh", reason="glTF export needs trimesh (the serve extra)")
    from warerover_phys.serve.glb import _read_glb, export_episode_glb, export_layout_glb
    from warerover_phys.serve.session import LiveSession

    s = LiveSession.from_default(tmp_path)
    assert export_layout_glb(s, tmp_path / "l.glb") > 1000
    s.step(12)
    export_episode_glb(s, tmp_path / "e.glb")
    doc, binary = _read_glb((tmp_path / "e.glb").read_bytes())
    names = {n.get("name") for n in doc["nodes"]}
    assert {"shelves", "floor", "agv_0", "agv_8"} <= names
    (anim,) = doc["animations"]
    assert len(anim["channels"]) == 2 * 9
    times = doc["accessors"][anim["samplers"][0]["input"]]
    assert times["count"] == 13 and times["max"] == [12.0]
    # The buffer ends where its last view ends; the BIN chunk is that, padded to 4 bytes
    # with zeros (glTF 2.0, 4.4.3.3).
    length = doc["buffers"][0]["byteLength"]
    assert length == max(v["byteOffset"] + v["byteLength"] for v in doc["bufferViews"])
    assert len(binary) == length + (-length) % 4 and not binary[length:].strip(b"\0")
    # 13 key times + per AGV 13 translations (3 floats) and 13 rotations (4 floats)
    anim_bytes = 4 * 13 * (1 + 9 * (3 + 4))
    assert sum(doc["bufferViews"][doc["accessors"][s["output"]]["bufferView"]]["byteLength"]
               for s in anim["samplers"]) + 4 * 13 == anim_bytes
    import trimesh

    scene = trimesh.load(tmp_path / "e.glb")
    assert len(scene.geometry) >= 9


def test_export_glb_command(tmp_path, monkeypatch):
    pytest.importorskip("trimesh", reason="glTF export needs trimesh (the serve extra)")
    import typer

    from warerover_phys.cli.serve import register

    app = typer.Typer()
    register(app)
    monkeypatch.chdir(tmp_path)
    r = CliRunner().invoke(app, ["export-glb", "ep.glb", "--ticks", "5"])
    assert r.exit_code == 0, r.output
    assert (tmp_path / "ep.glb").stat().st_size > 1000
