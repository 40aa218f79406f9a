"""Ghost mode: each AGV's planned pose drawn as an outline beside its real body (the
open-loop gap's video). Frames stay a pure function of the snapshot; the MP4 is decoded
back with PyAV (H.264, yuv420p) and the ghost's colour is looked for."""

from __future__ import annotations

import av
import numpy as np
import pytest

from warerover_phys.errors import WareroverError
from warerover_phys.render import (
    PALETTE,
    Style,
    draw_frame,
    ghost_poses,
    recording_with_ghosts,
    render_video,
)

COLS, ROWS = 8, 4


def _trajectory() -> dict:
    """Two AGVs driving east along rows 1 and 2 at 1 m/s, sampled at 10 Hz for 5 s."""
    t = np.arange(51) / 10.0
    x = np.stack([0.5 + t, 0.5 + t * 0.5], axis=1)
    y = np.tile([1.5, 2.5], (len(t), 1))
    return {"t": t, "x": x, "y": y, "heading": np.zeros_like(x),
            "state": np.ones_like(x, dtype=np.int8), "loaded": np.zeros_like(x, dtype=bool),
            "footprint": np.array([1, 1]), "body_m": np.full((2, 2), 0.7), "cell_m": 1.0,
            "tick_s": 1.0, "grid": np.zeros((ROWS, COLS), dtype=np.int8)}


def _plan() -> dict[int, list]:
    """Both planned one cell per tick east (AGV 1 falls behind its plan)."""
    return {0: [(8 + c, 8 + c) for c in range(6)], 1: [(16 + c, 16 + c) for c in range(6)]}


def _near(img_bgr: np.ndarray, bgr: tuple[int, int, int], tol: int = 40) -> int:
    return int((np.abs(img_bgr.astype(int) - np.array(bgr)).max(axis=2) < tol).sum())


def test_ghost_poses_follow_the_plan_timing():
    g = ghost_poses(_plan(), np.array([1, 1]), COLS, 1.0, 0.5)
    assert g["t"][:3].tolist() == [0.0, 0.5, 1.0]
    assert g["x"][2, 0] == pytest.approx(2.5) and g["y"][2, 1] == pytest.approx(2.5)
    assert np.allclose(g["heading"], 0.0)  # facing east, the way it moves


def test_ghost_is_drawn_beside_the_body_and_frames_are_pure():
    rec = recording_with_ghosts(_trajectory(), ghost_poses(_plan(), np.array([1, 1]), COLS,
                                                           1.0, 1.0))
    snap = rec.at(3.0)
    gx, gy, _ = snap.ghosts
    assert gx[1] == pytest.approx(3.5) and snap.x[1] == pytest.approx(2.0)  # 1.5 m behind
    on, off = Style(size=(480, 300), ghosts=True), Style(size=(480, 300))
    a, b = draw_frame(snap, on), draw_frame(snap, on)
    assert np.array_equal(a, b)  # a pure function of the snapshot
    plain = draw_frame(snap, off)
    assert _near(a, PALETTE["ghost"], 8) > 200 and _near(plain, PALETTE["ghost"], 8) == 0
    # a ghost with no planned pose (NaN) is not drawn
    import dataclasses

    none = dataclasses.replace(snap, ghosts=tuple(np.full(2, np.nan) for _ in range(3)))
    assert _near(draw_frame(none, Style(size=(480, 300), ghosts=True, show_legend=False)),
                 PALETTE["ghost"], 8) == 0


def test_ghost_video_decodes_as_h264_with_the_ghost_colour(tmp_path):
    rec = recording_with_ghosts(_trajectory(), ghost_poses(_plan(), np.array([1, 1]), COLS,
                                                           1.0, 1.0))
    out = tmp_path / "ghost.mp4"
    info = render_video(rec, out, fps=10, speed=1.0,
                        style=Style(size=(480, 300), ghosts=True, show_legend=False))
    assert info["codec"] == "h264" and info["frames"] == 51
    with av.open(str(out)) as c:
        s = c.streams.video[0]
        assert s.codec_context.name == "h264" and s.codec_context.pix_fmt == "yuv420p"
        frames = [f.to_ndarray(format="bgr24") for f in c.decode(video=0)]
    assert len(frames) == 51 and frames[0].shape == (300, 480, 3)
    # the ghost's colour (after yuv420p) in the late frames, where AGV 1 is far behind
    assert all(_near(f, PALETTE["ghost"]) > 150 for f in frames[20::10])


def test_ghost_shape_is_checked():
    g = ghost_poses(_plan(), np.array([1, 1]), COLS, 1.0, 1.0)
    g["x"] = g["x"][:, :1]
    with pytest.raises(WareroverError, match="ghost x"):
        recording_with_ghosts(_trajectory(), g)


def test_switched_edges_show_for_a_while_after_their_switch():
    from warerover_phys.render.trajectory import SWITCH_SHOW_S

    sw = {"t_s": 2.0, "first": 1, "then": 0, "cells": [[1, 4], [1, 5]]}
    rec = recording_with_ghosts(_trajectory(), ghost_poses(_plan(), np.array([1, 1]), COLS,
                                                           1.0, 1.0), switches=(sw,))
    assert rec.at(1.9).switches == () and rec.at(2.0).switches == (sw,)
    assert rec.at(2.0 + SWITCH_SHOW_S - 0.01).switches == (sw,)
    assert rec.at(2.0 + SWITCH_SHOW_S).switches == ()
    snap = rec.at(3.0)
    on = Style(size=(480, 300), ghosts=True, switches=True, show_legend=False)
    drawn = draw_frame(snap, on)
    off = draw_frame(snap, Style(size=(480, 300), ghosts=True, show_legend=False))
    # the switched cells' outlines (the switch colour) appear; elsewhere nothing changes
    changed = np.abs(drawn.astype(int) - off.astype(int)).max(axis=2) > 0
    assert changed.sum() > 100
    assert _near(drawn, PALETTE["switch"], 8) > _near(off, PALETTE["switch"], 8)
    assert np.array_equal(draw_frame(snap, on), drawn)
