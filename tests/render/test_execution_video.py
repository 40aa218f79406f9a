"""Videos that explain an execution (issue 36): what each AGV does is recorded per sample and
drawn in its colour (checked on decoded H.264 frames of a small execution whose states are
known), the path ahead starts from each AGV's own progress in its plan (no path pixel inside
an obstacle, where the clock's path would cross shelves), arrows point at blockers, the
header of a plan execution, pieces rendered by two workers joined into one playable file,
heat maps and stills from the command line."""

from __future__ import annotations

import dataclasses
import json
import shutil
import subprocess
import sys
from pathlib import Path

import av
import cv2
import numpy as np
import pytest
from typer.testing import CliRunner

from warerover_phys.cli import app
from warerover_phys.executors.recording import DRIVING, FINISHED, WAITING
from warerover_phys.render import (
    PALETTE,
    PathSet,
    Style,
    draw_frame,
    frame_geometry,
    frame_times,
    load_trajectory,
    render_video,
)
from warerover_phys.render.frame import _hud_text
from warerover_phys.render.heat import draw_heat, heat_values

REPO = Path(__file__).resolve().parents[2]
POCKET = "type octile\nheight 2\nwidth 9\nmap\n.........\n@@@@.@@@@\n"
"""A corridor (row 0) with a pocket below its middle cell (1, 4)."""
PLAN = ("Agent 0:(0,1)->(0,2)->(0,3)->(0,4)->(0,5)->(0,6)->(0,7)->(0,8)->\n"
        "Agent 1:(1,4)->(1,4)->(1,4)->(1,4)->(1,4)->(0,4)->(0,4)->(0,4)->\n")
"""AGV 0 drives the corridor east; AGV 1 leaves the pocket into (0, 4) once AGV 0 has
passed: on physics it waits on that dependency for several seconds."""


def _execute(tmp: Path, floor: str, plan: str, *extra: str) -> Path:
    (tmp / "floor.map").write_text(floor)
    (tmp / "plan.txt").write_text(plan)
    r = CliRunner().invoke(app, ["execute", str(tmp / "floor.map"), "--plan",
                                 str(tmp / "plan.txt"), "--out", str(tmp / "run"), "--json",
                                 *extra])
    assert r.exit_code == 0, r.output
    return tmp / "run"


@pytest.fixture(scope="module")
def pocket(tmp_path_factory) -> Path:
    return _execute(tmp_path_factory.mktemp("pocket"), POCKET, PLAN)


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, end) index runs where ``mask`` holds."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(int), [0]])))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist(), strict=True))


def test_the_recording_knows_who_waits_on_whom(pocket):
    rec = load_trajectory(pocket)
    t, st, bl, pt = rec.t, rec.exec_state, rec.blocker, rec.plan_tick
    waits = _runs(st[:, 1] == WAITING)
    assert len(waits) == 1
    a, b = waits[0]
    assert t[b - 1] - t[a] >= 3.0                        # held for more than 3 s ...
    assert (bl[a:b, 1] == 0).all()                       # ... by AGV 0
    assert (bl[st != WAITING] == -1).all()
    assert (pt[a:b, 1] == -1).all()                      # not started: at its plan's start
    after = st[b:, 1]
    assert DRIVING in after and after[-1] == FINISHED
    drive = np.flatnonzero(st[:, 1] == DRIVING)
    assert (pt[drive, 1] == 5).all()                     # driving to its tick-5 state
    # AGV 0 drives from the start (its progress goes up one tick per cell), then finishes.
    assert st[0, 0] == DRIVING and st[-1, 0] == FINISHED
    assert (np.diff(pt[:, 0]) >= 0).all() and pt[-1, 0] == 7
    # While AGV 1 waits, AGV 0 has not yet left the cell AGV 1 must enter.
    assert (rec.x[a:b, 0] <= 5.5 + 1e-6).all()


def test_waiting_robot_is_drawn_in_the_waiting_colour_in_the_decoded_video(pocket, tmp_path):
    rec = load_trajectory(pocket)
    style = Style(size=(640, 360))
    video = tmp_path / "pocket.mp4"
    info = render_video(rec, video, fps=10, speed=1.0, style=style)
    with av.open(str(video)) as c:
        s = c.streams.video[0]
        assert (s.codec_context.name, s.codec_context.pix_fmt) == ("h264", "yuv420p")
        frames = [f.to_ndarray(format="bgr24") for f in c.decode(s)]
    assert len(frames) == info["frames"]
    times = frame_times(rec.start_s, rec.end_s, 10, 1.0)
    geo = frame_geometry(rec.scene(), style)
    seen: dict[int, int] = {}
    for img, t in zip(frames, times, strict=True):
        snap = rec.at(float(t))
        doing = int(snap.exec_state[1])
        if doing not in (WAITING, DRIVING, FINISHED):
            continue
        # AGV 1's body, behind its centre along its axis (clear of id and heading mark).
        cx, cy = geo.to_px(snap.x[1], snap.y[1])
        back = 0.25 * rec.body_m[1, 0] * geo.scale
        px, py = cx - np.cos(snap.heading[1]) * back, cy - np.sin(snap.heading[1]) * back
        got = np.median(img[int(py) - 1:int(py) + 2, int(px) - 1:int(px) + 2].reshape(-1, 3),
                        axis=0)
        name = {WAITING: "waiting", DRIVING: "driving", FINISHED: "finished"}[doing]
        assert np.abs(got - PALETTE[name]).max() <= 24, (t, name, got)
        seen[doing] = seen.get(doing, 0) + 1
    assert seen.get(WAITING, 0) >= 30 and seen.get(DRIVING, 0) >= 5 and seen.get(FINISHED)


def test_an_arrow_points_from_the_waiting_robot_to_its_blocker(pocket):
    rec = load_trajectory(pocket)
    a, b = _runs(rec.exec_state[:, 1] == WAITING)[0]
    snap = rec.at(float(rec.t[(a + b) // 2]))
    style = Style(size=(900, 300), show_paths=False, show_legend=False, show_hud=False)
    on, off = draw_frame(snap, style), draw_frame(snap, dataclasses.replace(style, arrows=False))
    ys, xs = np.nonzero((on != off).any(axis=2))
    assert len(xs) > 10
    geo = frame_geometry(rec.scene(), style)
    (x1, x0), (y1, y0) = geo.to_px(snap.x[[1, 0]], snap.y[[1, 0]])
    # every changed pixel lies near the segment from AGV 1 to AGV 0
    d = np.array([x0 - x1, y0 - y1])
    rel = np.stack([xs - x1, ys - y1], axis=1)
    along = rel @ d / (d @ d)
    across = np.abs(rel @ np.array([-d[1], d[0]])) / np.linalg.norm(d)
    assert (along > -0.05).all() and (along < 1.0).all() and (across < 0.25 * geo.scale).all()
    assert np.abs(on[ys, xs].astype(int) - PALETTE["arrow"]).max(axis=1).min() < 40


def test_header_of_a_plan_execution(pocket):
    rec = load_trajectory(pocket)
    assert rec.plan_execution
    metrics = json.loads((pocket / "metrics.json").read_text())
    mid = rec.at(2.0)
    p = mid.progress
    assert (p.finished, p.agvs, p.done) == (0, 2, False)
    assert p.planned_makespan_s == metrics["planned_makespan_ticks"] == 7
    assert p.executed_makespan_s == pytest.approx(2.0)
    end = rec.at(rec.end_s).progress
    assert end.done and end.finished == 2
    assert end.executed_makespan_s == pytest.approx(metrics["executed_makespan_ticks"], abs=1.0)
    # Lost time: AGV 1 finishes late (its planned finish is tick 6), AGV 0 too.
    assert end.lost_s > 0
    assert p.lost_s <= end.lost_s
    text = _hud_text(mid, 0)
    assert "finished 0/2" in text and "makespan planned 7 s" in text and "orders" not in text


# ----------------------------------------------------------------------------- paths


@pytest.fixture(scope="module")
def late_fleet(tmp_path_factory) -> Path:
    """40 AGVs of a LaCAM plan on random-32-32-10 executed on physics: the bodies fall
    behind the plan's unit-time moves (acceleration, turns, waits on one another)."""
    from warerover_phys.planning.oneshot.core import solve, write_plan
    from warerover_phys.problems.movingai import read_map, read_scen

    tmp = tmp_path_factory.mktemp("late")
    data = REPO / "tests" / "data"
    m = read_map(data / "random-32-32-10.map")
    agents = read_scen(data / "random-32-32-10-random-1.scen", 40)
    res = solve(m.obstacles, [a.start for a in agents], [a.goal for a in agents],
                planner="lacam", time_limit_s=30)
    write_plan(tmp / "plan.txt", res)
    return _execute(tmp, (data / "random-32-32-10.map").read_text(),
                    (tmp / "plan.txt").read_text())


def _path_pixels_in_obstacles(rec, snap, style: Style) -> int:
    """Pixels that the paths change (paths drawn vs not) inside obstacle cells, farther
    than the line width from the cell's edges."""
    on = draw_frame(snap, style)
    off = draw_frame(snap, dataclasses.replace(style, show_paths=False))
    ys, xs = np.nonzero((on != off).any(axis=2))
    geo = frame_geometry(rec.scene(), style)
    mx = (xs - geo.ox) / geo.scale / rec.cell_m + geo.x0_m / rec.cell_m
    my = (ys - geo.top - geo.oy) / geo.scale / rec.cell_m + geo.y0_m / rec.cell_m
    r, c = np.floor(my).astype(int), np.floor(mx).astype(int)
    inside = (r >= 0) & (r < rec.grid.shape[0]) & (c >= 0) & (c < rec.grid.shape[1])
    r, c, mx, my = r[inside], c[inside], mx[inside], my[inside]
    margin = 2.0 / (geo.scale * rec.cell_m)     # two pixels, in cells: the line's width
    deep = (np.minimum(mx - c, c + 1 - mx) > margin) & (np.minimum(my - r, r + 1 - my) > margin)
    return int((deep & (rec.grid[r, c] == 1)).sum())


def test_no_path_pixel_inside_an_obstacle(late_fleet):
    rec = load_trajectory(late_fleet)
    style = Style(size=(960, 720), path_ticks=8, arrows=False, show_legend=False)
    index = rec.plan_index()
    late = checked = 0
    for t in np.linspace(rec.start_s + 3, rec.end_s * 0.45, 6):
        snap = rec.at(float(t), style.path_ticks)
        assert _path_pixels_in_obstacles(rec, snap, style) == 0, t
        checked += len(snap.paths.agv)
        # The same frame with paths taken from the clock (the plan at this time) crosses
        # obstacles: the bodies run behind their plans, so this check has teeth.
        entry = index.select(t)
        clock = np.full(rec.num_agvs, int(t / rec.tick_s))
        ahead = index.ahead(entry, clock, None, snap.x, snap.y, style.path_ticks)
        late += _path_pixels_in_obstacles(rec, dataclasses.replace(snap, paths=ahead), style)
    assert checked >= 60 and late > 0


def test_paths_from_progress_start_at_the_body_and_follow_the_plan(late_fleet):
    rec = load_trajectory(late_fleet)
    snap = rec.at(rec.end_s / 3, 6)
    paths: PathSet = snap.paths
    assert np.allclose(paths.points[:, 0, 0], snap.x[paths.agv])
    assert np.allclose(paths.points[:, 0, 1], snap.y[paths.agv])
    step = np.abs(np.diff(paths.points[:, 1:], axis=1)).sum(axis=2)
    assert (step <= rec.cell_m + 1e-9).all()           # plan points: one cell at a time


# ----------------------------------------------------------------------------- workers


def test_two_workers_join_pieces_into_one_playable_h264_file(pocket, tmp_path):
    rec = load_trajectory(pocket)
    style = Style(size=(320, 180))
    one, two = tmp_path / "one.mp4", tmp_path / "two.mp4"
    seen = []
    a = render_video(rec, one, fps=20, speed=1.0, style=style)
    b = render_video(rec, two, fps=20, speed=1.0, style=style, workers=2,
                     progress=lambda k, n: seen.append((k, n)))
    assert b["workers"] == 2 and a["frames"] == b["frames"] and seen[-1] == (b["frames"],) * 2
    decoded = []
    for path in (one, two):
        with av.open(str(path)) as c:
            s = c.streams.video[0]
            assert (s.codec_context.name, s.codec_context.pix_fmt) == ("h264", "yuv420p")
            frames = list(c.decode(s))
        pts = np.array([f.pts for f in frames])
        assert len(frames) == a["frames"] and (np.diff(pts) > 0).all()
        assert float(frames[-1].time) == pytest.approx((a["frames"] - 1) / 20, abs=1e-6)
        decoded.append(np.stack([f.to_ndarray(format="bgr24") for f in frames]))
    assert np.abs(decoded[0].astype(int) - decoded[1]).mean() < 2.0
    if shutil.which("ffprobe"):
        out = subprocess.run(["ffprobe", "-v", "error", "-count_frames", "-show_entries",
                              "stream=codec_name,pix_fmt,nb_read_frames", "-of", "json",
                              str(two)], capture_output=True, text=True, check=True)
        stream = json.loads(out.stdout)["streams"][0]
        assert (stream["codec_name"], stream["pix_fmt"]) == ("h264", "yuv420p")
        assert int(stream["nb_read_frames"]) == a["frames"]


# ----------------------------------------------------------------------------- stills


def test_heat_maps_count_waits_and_passes(pocket):
    rec = load_trajectory(pocket)
    wait, traffic = heat_values(rec, "wait"), heat_values(rec, "traffic")
    a, b = _runs(rec.exec_state[:, 1] == WAITING)[0]
    assert wait.sum() == pytest.approx(rec.t[b] - rec.t[a], abs=1e-9)
    assert wait[1, 4] == wait.sum()                   # all of it in the pocket
    # AGV 0 passes every corridor cell from column 1 once; AGV 1 its pocket and (0, 4).
    want = np.zeros_like(traffic)
    want[0, 1:] = 1
    want[0, 4] += 1
    want[1, 4] = 1
    assert np.array_equal(traffic, want)
    img = draw_heat(rec, "wait", Style(size=(640, 360)))
    geo = frame_geometry(rec.scene(), Style(size=(640, 360)))
    x, y = geo.to_px(4.5, 1.5)
    top = cv2.applyColorMap(np.array([[255]], np.uint8), cv2.COLORMAP_VIRIDIS)[0, 0]
    assert np.abs(img[int(y), int(x)].astype(int) - top).max() <= 2


def test_render_command_stills_workers_and_bad_options(pocket, tmp_path):
    runner = CliRunner()
    for args, name in ((["--heat", "traffic"], "h.png"), (["--png", "3"], "p.png"),
                       (["--workers", "2", "--ghost", "--speed", "2"], "v.mp4")):
        out = tmp_path / name
        r = runner.invoke(app, ["render", str(pocket), "--out", str(out), "-q", *args])
        assert r.exit_code == 0, r.output
        assert out.stat().st_size > 1000
    assert "with 2 workers" in r.output
    for args, needle in ((["--heat", "speed"], "--heat"), (["--workers", "0"], "--workers"),
                         (["--heat", "wait", "--png", "2"], "--png and --heat"),
                         (["--preset", "warp"], "--preset")):
        r = runner.invoke(app, ["render", str(pocket), "--out", str(tmp_path / "x.png"),
                                *args])
        assert r.exit_code == 2 and needle in r.output and "Traceback" not in r.output


def test_grid_execution_records_what_each_agv_does(tmp_path):
    """The grid executor keeps no recording of its own: its states are derived from the
    executed states against the plan (planned waits stand, moves drive, then finished)."""
    rec = load_trajectory(_execute(tmp_path, POCKET, PLAN, "--executor", "grid"))
    assert rec.plan_execution
    assert rec.exec_state[:, 0].tolist()[:8] == [DRIVING] * 7 + [FINISHED]
    assert rec.exec_state[:, 1].tolist()[:6] == [0, 0, 0, 0, DRIVING, FINISHED]
    assert rec.plan_tick[:6, 1].tolist() == [1, 2, 3, 4, 5, 5]
    assert (rec.blocker == -1).all()


def test_marks_of_many_big_bodies_at_once():
    """Detail marks (outline, heading, cargo, failure cross) of several bodies are drawn
    in batches: failed and loaded AGVs in every mix of colours, all in one frame."""
    from warerover_phys.render import Recording

    n = 6
    x = np.array([1.5, 3.5, 5.5, 7.5, 9.5, 11.5])
    rec = Recording(t=np.array([0.0, 1.0]), x=np.stack([x, x]), y=np.full((2, n), 1.5),
                    heading=np.zeros((2, n)), state=np.full((2, n), 1, np.int8),
                    loaded=np.tile([True, False, True, False, False, True], (2, 1)),
                    footprint=np.ones(n, int), body_m=np.full((n, 2), 0.8), cell_m=1.0,
                    tick_s=1.0, grid=np.zeros((3, 13), np.int8),
                    exec_state=np.tile(np.array([5, 5, 1, 3, 5, 6], np.int8), (2, 1)),
                    blocker=np.full((2, n), -1, np.int32), plan_tick=np.zeros((2, n), np.int32))
    style = Style(size=(1300, 300), label_min_px=1e9)       # no ids over the marks
    img = draw_frame(rec.at(0.5), style)
    geo = frame_geometry(rec.scene(), style)
    for i in (0, 1, 4):                     # failed: a white cross through the middle
        cx, cy = geo.to_px(x[i] - 0.2, 1.5 - 0.2)
        assert img[int(round(cy)), int(round(cx))].min() > 200, i
    cx, cy = geo.to_px(x[2] - 0.1, 1.5)     # loaded, driving: the shelf-coloured cargo
    assert np.abs(img[int(cy), int(cx)].astype(int) - PALETTE["shelf"]).max() < 30


@pytest.mark.parametrize("size", [(1200, 400), (300, 120)])   # thick and one-pixel outlines
def test_overlapping_corridors_stay_filled_and_the_cached_zones_follow_the_corridors(size):
    """Two corridors whose zones overlap: the overlap is tinted too (OpenCV's even-odd
    fill would leave it empty); a later frame with other corridors shows those, not the
    zones kept from the frame before."""
    from warerover_phys.render import Recording

    rec = Recording(t=np.array([0.0, 1.0]), x=np.full((2, 1), 0.5), y=np.full((2, 1), 0.5),
                    heading=np.zeros((2, 1)), state=np.zeros((2, 1), np.int8),
                    loaded=np.zeros((2, 1), bool), footprint=np.array([1]),
                    body_m=np.array([[0.5, 0.5]]), cell_m=1.0, tick_s=1.0,
                    grid=np.zeros((4, 12), np.int8))

    def box(x0, x1):
        return {"id": x0, "zone": [[[x0, 1.0], [x1, 1.0], [x1, 3.0], [x0, 3.0]]]}

    style = Style(size=size, show_paths=False, show_legend=False, show_hud=False)
    geo = frame_geometry(rec.scene(), style)
    tint = np.array(PALETTE["floor"]) * (1 - style.corridor_alpha) + \
        np.array(PALETTE["corridor"]) * style.corridor_alpha

    def tinted(img, x, y):
        px, py = geo.to_px(x, y)
        return np.abs(img[int(py), int(px)].astype(float) - tint).max() < 12

    snap = rec.at(0.0)
    first = draw_frame(dataclasses.replace(snap, corridors=(box(2, 6), box(4, 8))), style)
    # (off the grid lines: at cell centres)
    assert all(tinted(first, x, 1.5) for x in (3.5, 5.5, 7.5))      # 5.5: the overlap
    assert not tinted(first, 10.5, 1.5)
    second = draw_frame(dataclasses.replace(snap, corridors=(box(9, 11),)), style)
    assert tinted(second, 10.5, 1.5) and not tinted(second, 5.5, 1.5)


def test_workers_start_after_opencv_used_its_thread_pool(pocket, tmp_path):
    """A forked worker inherits OpenCV's thread pool without its threads; the parent shuts
    the pool before forking. (A worker that touched the pool itself waited forever.) In a
    fresh process whose OpenCV ran a parallel operation first."""
    code = f"""
import cv2, numpy as np
from warerover_phys.render import Style, load_trajectory, render_video
cv2.setNumThreads(4)
big = np.random.default_rng(0).integers(0, 255, (3000, 3000, 3), dtype=np.uint8)
for _ in range(3):
    cv2.GaussianBlur(big, (31, 31), 0)          # runs on OpenCV's thread pool
info = render_video(load_trajectory({str(pocket)!r}), {str(tmp_path / "w.mp4")!r}, fps=10,
                    speed=2.0, style=Style(size=(320, 180)), workers=2)
print(info["workers"], info["frames"], cv2.getNumThreads())
"""
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=240, cwd=REPO)
    assert proc.returncode == 0, proc.stderr[-2000:]
    workers, frames, pool = proc.stdout.split()
    assert workers == "2" and int(frames) > 10 and pool == "4"   # the pool is set back


def test_frame_rate_text_for_the_progress_bar(monkeypatch):
    import warerover_phys.render.video as video

    clock = iter([100.0, 102.0])
    monkeypatch.setattr(video.time, "perf_counter", lambda: next(clock))
    rate = video.FrameRate()
    assert rate(50, 200) == "25.0 fps, ETA 0:06"
