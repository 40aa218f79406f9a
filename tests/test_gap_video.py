"""``warerover gap --plan FILE --video PATH``: an imported plan with a rotation (repaired,
planned figures as given) executed on physics and rendered with ghosts."""

from __future__ import annotations

import json

import av
import numpy as np
from hardening_helpers import REPO, assert_clean_error, run_cli

from warerover_phys.render import PALETTE

CW = [(1, 1), (1, 2), (2, 2), (2, 1)]


def _files(tmp_path):
    floor = tmp_path / "open.map"
    floor.write_text("type octile\nheight 4\nwidth 5\nmap\n" + "." * 5 + "\n" * 1
                     + ("." * 5 + "\n") * 3)
    plan = tmp_path / "plan.txt"
    lines = []
    for i, cell in enumerate(CW):  # stand one step, turn the block clockwise, stand
        nxt = CW[(i + 1) % 4]
        lines.append(f"Agent {i}:" + "".join(f"({r},{c})->" for r, c in (cell, cell, nxt)))
    plan.write_text("\n".join(lines) + "\n")
    return floor, plan


def test_plan_with_rotation_gap_and_ghost_video(tmp_path):
    floor, plan = _files(tmp_path)
    video = tmp_path / "ghost.mp4"
    r = run_cli("gap", floor, "--plan", plan, "--out", tmp_path / "g", "--json",
                "--video", video, "--ghost", "--no-pictures", cwd=REPO)
    assert r.returncode == 0, r.stderr[-2000:]
    rep = json.loads(r.stdout)
    assert rep["completed"] and rep["cycle_repairs"] == 1
    assert rep["planned_makespan_s"] == 2.0  # the plan as given
    assert rep["repaired_makespan_s"] > 2.0
    assert rep["lost_rotation_repair_s_fleet_total"] == rep["cycle_repair_added_ticks"]
    assert "repaired a rotation" in r.stderr
    with av.open(str(video)) as c:
        s = c.streams.video[0]
        assert s.codec_context.name == "h264" and s.codec_context.pix_fmt == "yuv420p"
        frames = [f.to_ndarray(format="bgr24") for k, f in enumerate(c.decode(video=0))
                  if k % 30 == 0]
    assert len(frames) > 3 and frames[0].shape == (720, 1280, 3)
    ghost = np.array(PALETTE["ghost"], dtype=np.int16)
    assert max(int((np.abs(f.astype(np.int16) - ghost).max(axis=2) < 40).sum())
               for f in frames) > 500


def test_video_options_are_checked(tmp_path):
    floor, plan = _files(tmp_path)
    r = run_cli("gap", "layouts/paper_homogeneous.yaml", "--seeds", "0..1", "--video",
                tmp_path / "v.mp4", cwd=REPO)
    assert_clean_error(r, "--video", "--seeds")
    r = run_cli("gap", floor, "--plan", plan, "--video", tmp_path / "v.avi", cwd=REPO)
    assert_clean_error(r, "--video", "mp4")
