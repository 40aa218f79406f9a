"""Rendering: frames, H.264 MP4 (decoded back with PyAV and checked pixel by pixel), the
``render`` / ``run --video`` commands, large layouts, and the simulation staying free of
cv2 and av when nobody asks for a video."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import warnings
from pathlib import Path

import av
import cv2
import numpy as np
import pytest
import shapely
from typer.testing import CliRunner

from warerover_phys.cli import app
from warerover_phys.config import load_scenario
from warerover_phys.executors.recording import EXEC_STATES
from warerover_phys.outputs import write_outputs
from warerover_phys.render import (
    PALETTE,
    Recording,
    Style,
    auto_speed,
    draw_frame,
    frame_geometry,
    frame_times,
    load_trajectory,
    parse_size,
    recording_from_episode,
    render_video,
    status_of,
    write_png,
)
from warerover_phys.sim import Simulation

REPO = Path(__file__).resolve().parents[2]
HETERO = REPO / "layouts" / "paper_heterogeneous.yaml"
FAILED_AGV = 7
"""A 2x2 AGV (1.6 m body) of paper_heterogeneous, failed at tick ``FAIL_TICK``."""
FAIL_TICK = 6
STATUS = ("idle", "moving", "loaded", "failed")


def _episode(executor: str, ticks: int, fail_at: int = FAIL_TICK):
    sc = load_scenario(HETERO, [("executor.name", executor), ("max_ticks", ticks)])
    sim = Simulation(sc)
    for _ in range(fail_at):
        sim.step()
    sim.fail(FAILED_AGV)
    return sim.run()


@pytest.fixture(scope="module")
def physics_run(tmp_path_factory) -> Path:
    """A physics episode of paper_heterogeneous with a failure, written as a run folder."""
    out = tmp_path_factory.mktemp("phys")
    write_outputs(_episode("physics", 24), out)
    return out


@pytest.fixture(scope="module")
def grid_result():
    return _episode("grid", 24)


def _decode(path: Path) -> tuple[list[np.ndarray], str, tuple[int, int]]:
    with av.open(str(path)) as container:
        stream = container.streams.video[0]
        codec = stream.codec_context.name
        size = (stream.codec_context.width, stream.codec_context.height)
        frames = [f.to_ndarray(format="bgr24") for f in container.decode(stream)]
    return frames, codec, size


def _patch(img: np.ndarray, x: float, y: float, r: int = 1) -> np.ndarray:
    xi, yi = int(round(x)), int(round(y))
    return np.median(img[yi - r:yi + r + 1, xi - r:xi + r + 1].reshape(-1, 3), axis=0)


def _near(got: np.ndarray, want, tol: float = 28.0) -> bool:
    return bool(np.abs(got.astype(float) - np.asarray(want, dtype=float)).max() <= tol)


def _seg_dist(p: np.ndarray, pts: np.ndarray) -> float:
    a, b = pts[:-1], pts[1:]
    ab = b - a
    t = np.clip(((p - a) * ab).sum(1) / np.maximum((ab * ab).sum(1), 1e-12), 0, 1)
    return float(np.linalg.norm(a + t[:, None] * ab - p, axis=1).min())


# ----------------------------------------------------------------------------- the MP4


def test_mp4_of_paper_heterogeneous_with_failure(physics_run, tmp_path):
    """60 frames to H.264, decoded with PyAV: count, size, codec, then pixels: the failed
    AGV in the failure colour at its recorded pose, every other lone AGV in the colour of
    what it was recorded doing (``exec_state``), and the corridor colour on a free corridor
    cell."""
    rec = load_trajectory(physics_run / "trajectories.npz")
    assert rec.corridors and rec.corridors[0]["agv"] == FAILED_AGV
    style = Style(size=(1280, 720))
    video = tmp_path / "hetero.mp4"
    info = render_video(rec, video, fps=30, speed=6.0, start_s=8.0, max_frames=60, style=style)
    frames, codec, size = _decode(video)
    assert (len(frames), codec, size) == (60, "h264", (1280, 720))
    assert info["frames"] == 60 and info["codec"] == "h264"
    times = frame_times(8.0, rec.end_s, 30, 6.0, 60)
    geo = frame_geometry(rec.scene(), style)
    cell_names = ("floor", "obstacle", "shelf", "station", "parking")
    checked_agvs = checked_corridor = 0
    for k in (0, 30, 59):
        img, snap = frames[k], rec.at(float(times[k]), style.path_ticks)
        status = status_of(snap.state, snap.loaded)
        assert status[FAILED_AGV] == 3 and EXEC_STATES[snap.exec_state[FAILED_AGV]] == "failed"
        cx, cy = geo.to_px(snap.x, snap.y)
        for i in range(rec.num_agvs):
            others = np.hypot(snap.x - snap.x[i], snap.y - snap.y[i])
            others[i] = np.inf
            if others.min() < 1.8:          # touching another body: skip
                continue
            # Behind the centre along the body axis: clear of id, cargo and heading mark.
            back = 0.7 * rec.body_m[i, 0] / 2 * geo.scale
            px = cx[i] - np.cos(snap.heading[i]) * back
            py = cy[i] - np.sin(snap.heading[i]) * back
            got = _patch(img, px, py)
            doing = EXEC_STATES[snap.exec_state[i]]
            assert _near(got, PALETTE[doing]), (k, i, got, doing)
            checked_agvs += i == FAILED_AGV
        # A corridor cell away from AGVs and drawn paths shows the corridor tint.
        cols = rec.grid.shape[1]
        zone = shapely.Polygon(rec.corridors[0]["zone"][0]).buffer(-0.2)
        for node in rec.corridors[0]["cells"]:
            r, c = divmod(node, cols)
            p = np.array([(c + 0.5) * rec.cell_m, (r + 0.5) * rec.cell_m])
            clear = np.hypot(snap.x - p[0], snap.y - p[1]) - rec.body_m.max(axis=1) * 0.71
            if not zone.contains(shapely.Point(p)) or clear.min() < 0.4:
                continue
            if any(_seg_dist(p, q) < 0.4 for q in snap.paths.points):
                continue
            got = _patch(img, *geo.to_px(p[0], p[1]), r=2)
            under = PALETTE[cell_names[rec.grid[r, c]]]
            want = _blend(under, PALETTE["corridor"], style.corridor_alpha)
            assert _near(got, want), (k, r, c, got, want)
            assert not _near(got, under, 10)
            checked_corridor += 1
            break
    assert checked_agvs == 3 and checked_corridor >= 2


def test_closed_loop_header_keeps_orders_and_throughput(physics_run):
    """A run with orders is no plan execution: its heads-up line gives orders and TP (and
    what the AGVs do), not the plan-execution figures."""
    from warerover_phys.render.frame import _hud_text

    rec = load_trajectory(physics_run)
    assert not rec.plan_execution and rec.exec_state is not None
    snap = rec.at(rec.end_s, 4)
    assert snap.progress is None and snap.orders_total
    text = _hud_text(snap, 1)
    assert f"orders {snap.orders_done}/{snap.orders_total}" in text and "TP " in text
    assert "makespan" not in text and "waiting " in text


def _blend(under, over, alpha):
    return [u * (1 - alpha) + o * alpha for u, o in zip(under, over, strict=True)]


def test_grid_episode_renders_like_physics(grid_result, tmp_path):
    """A grid run gives the same kind of recording: one sample per tick at cell centres,
    the failure from the events, order counts, and frames of the right size."""
    rec = recording_from_episode(grid_result)
    w = grid_result.world
    n = len(w.agvs)
    assert rec.x.shape == (len(grid_result.actual[0]), n)
    assert np.allclose(rec.t, np.arange(len(rec.t)) * w.scenario.tick_s)
    a = w.agvs[0]
    r, c = divmod(grid_result.actual[0][0][0], w.layout.cols)
    assert (rec.x[0, 0], rec.y[0, 0]) == pytest.approx(((c + a.k / 2) * w.layout.cell_m,
                                                        (r + a.k / 2) * w.layout.cell_m))
    assert (rec.state[FAIL_TICK:, FAILED_AGV] == 7).all()
    assert (rec.state[:FAIL_TICK, FAILED_AGV] != 7).all()
    snap = rec.at(rec.end_s)
    assert snap.orders_done == grid_result.metrics["orders_completed"]
    assert snap.orders_total == grid_result.metrics["orders_generated"]
    png = write_png(rec, tmp_path / "g.png", 10.5, Style(size=(1920, 1080)))
    img = cv2.imread(str(png))
    assert img.shape == (1080, 1920, 3)
    with pytest.raises(ValueError, match="outside the recording"):
        write_png(rec, tmp_path / "bad.png", rec.ticks + 5)


def test_interpolation_between_samples():
    """Positions linear, headings along the shorter arc, discrete fields from the earlier
    sample; frame times follow fps and speed, not the recording rate."""
    t = np.array([0.0, 1.0])
    rec = Recording(t=t, x=np.array([[0.0], [2.0]]), y=np.array([[1.0], [1.0]]),
                    heading=np.array([[3.0], [-3.0]]), state=np.array([[1], [7]], np.int8),
                    loaded=np.array([[False], [True]]), footprint=np.array([1]),
                    body_m=np.array([[0.7, 0.7]]), cell_m=1.0, tick_s=1.0,
                    grid=np.zeros((3, 3), np.int8))
    mid = rec.at(0.5)
    assert mid.x[0] == pytest.approx(1.0)
    assert abs(abs(mid.heading[0]) - np.pi) < 0.3          # through pi, not through 0
    assert mid.state[0] == 1 and not mid.loaded[0]
    assert rec.at(1.0).state[0] == 7 and rec.at(5.0).x[0] == pytest.approx(2.0)
    assert np.allclose(frame_times(0.0, 1.0, 10, 0.5), np.arange(21) * 0.05)
    assert len(frame_times(0.0, 100.0, 30, 2.0, max_frames=60)) == 60
    assert auto_speed(30) == 1.0 and auto_speed(95) == 2.0 and auto_speed(1000) == 20.0
    assert parse_size("1080p") == (1920, 1080) and parse_size("640x360") == (640, 360)
    with pytest.raises(ValueError):
        parse_size("huge")


# ----------------------------------------------------------------------------- large layouts


def _crowd(rows: int, cols: int, n: int, seed: int = 0) -> Recording:
    """``n`` AGVs at random, the first eight in a row at (x, y) = (24 + 4 i, 15.5) m."""
    rng = np.random.default_rng(seed)
    grid = np.zeros((rows, cols), np.int8)
    grid[2:-2:4, 2:-2] = 2
    x = rng.uniform(1, cols - 1, n)
    y = rng.uniform(1, rows - 1, n)
    x[:8], y[:8] = 24.0 + 4 * np.arange(8), 15.5
    return Recording(t=np.array([0.0, 1.0]), x=np.stack([x, x]), y=np.stack([y, y]),
                     heading=np.zeros((2, n)), state=np.full((2, n), 1, np.int8),
                     loaded=np.zeros((2, n), bool), footprint=np.ones(n, int),
                     body_m=np.full((n, 2), 0.7), cell_m=1.0, tick_s=1.0, grid=grid)


def test_large_layout_scales_and_zooms():
    """1000 AGVs on a 300 x 520 floor: every body still shows (drawn ``min_agv_px`` wide
    though 0.7 m is less); a viewport zooms in so bodies are big and labelled again."""
    rec = _crowd(300, 520, 1000)
    snap = rec.at(0.0)
    style = Style(size=(1280, 720))
    geo = frame_geometry(rec.scene(), style)
    assert 0.7 * geo.scale < 0.6 * style.min_agv_px
    img = draw_frame(snap, style)
    cx, cy = geo.to_px(snap.x, snap.y)
    hits = [_near(img[int(round(b)), int(round(a))], PALETTE["moving"], 60)
            for a, b in zip(cx, cy, strict=True)]
    assert np.mean(hits) > 0.97
    zoom = Style(size=(1280, 720), viewport=(10, 20, 29, 59))
    zgeo = frame_geometry(rec.scene(), zoom)
    assert zgeo.scale > 10 * geo.scale and 0.7 * zgeo.scale > zoom.label_min_px
    zimg = draw_frame(snap, zoom)
    inside = np.flatnonzero((snap.x > 21) & (snap.x < 59) & (snap.y > 11) & (snap.y < 29))
    lone = [i for i in inside if np.sort(np.hypot(snap.x - snap.x[i], snap.y - snap.y[i]))[1] > 1.5]
    assert len(lone) >= 5
    for i in lone:
        zx, zy = zgeo.to_px(snap.x[i] - 0.1, snap.y[i] + 0.22)   # below the id
        assert _near(_patch(zimg, zx, zy), PALETTE["moving"], 10)
    # Nothing of the map spills into the heads-up line or the legend.
    assert (zimg[:zgeo.top - 1] == PALETTE["hud_bg"]).all(axis=2).mean() > 0.9


def test_fallback_to_mp4v_without_pyav(tmp_path, monkeypatch):
    """No PyAV: a warning, and an MPEG-4 Part 2 file that still decodes."""
    monkeypatch.setitem(sys.modules, "av", None)
    rec = _crowd(20, 30, 20)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        info = render_video(rec, tmp_path / "f.mp4", fps=10, speed=0.5,
                            style=Style(size=(320, 240)))
    assert info["codec"] == "mp4v" and any("PyAV" in str(w.message) for w in caught)
    monkeypatch.undo()
    frames, codec, size = _decode(tmp_path / "f.mp4")
    assert codec == "mpeg4" and size == (320, 240) and len(frames) == info["frames"] == 21


# ----------------------------------------------------------------------------- command line


def test_cli_render_and_errors(physics_run, tmp_path):
    runner = CliRunner()
    traj = physics_run / "trajectories.npz"
    out = tmp_path / "r.mp4"
    res = runner.invoke(app, ["render", str(traj), "--out", str(out), "--fps", "10",
                              "--speed", "8", "--size", "640x360"])
    assert res.exit_code == 0, res.output
    frames, codec, size = _decode(out)
    rec = load_trajectory(traj)
    assert codec == "h264" and size == (640, 360)
    assert len(frames) == len(frame_times(rec.start_s, rec.end_s, 10, 8))
    png = tmp_path / "still.png"
    res = runner.invoke(app, ["render", str(physics_run), "--out", str(png), "--png", "12",
                              "--size", "1080p", "--viewport", "2,0,12,12"])
    assert res.exit_code == 0, res.output
    assert cv2.imread(str(png)).shape == (1080, 1920, 3)
    bad = [(["render", str(tmp_path / "none.npz"), "--out", str(out)], "not found"),
           (["render", str(traj), "--out", str(out), "--size", "big"], "size"),
           (["render", str(traj), "--out", str(png), "--png", "999"], "outside"),
           (["render", str(traj), "--out", str(out), "--viewport", "1,2,3"], "viewport"),
           (["render", str(traj), "--out", str(out), "--viewport", "40,0,50,5"], "viewport"),
           (["render", str(traj), "--out", str(out), "--fps", "0"], "fps"),
           (["run", str(HETERO), "--video", str(out), "--size", "12x"], "size")]
    for args, word in bad:
        res = runner.invoke(app, args)
        lines = [ln for ln in res.output.splitlines() if ln.strip()]
        assert res.exit_code == 2 and len(lines) == 1 and word in lines[0], (args, res.output)


def test_cli_run_video_on_grid(tmp_path):
    """``run --video`` on the grid executor writes the MP4 and a trajectories.npz that
    ``render`` can redo."""
    runner = CliRunner()
    out, video = tmp_path / "run", tmp_path / "v.mp4"
    res = runner.invoke(app, ["run", str(REPO / "layouts" / "paper_homogeneous.yaml"),
                              "--set", "max_ticks=20", "--out", str(out), "--quiet",
                              "--video", str(video), "--fps", "5", "--size", "480p"])
    assert res.exit_code == 0, res.output
    frames, codec, size = _decode(video)
    assert codec == "h264" and size == (854, 480) and len(frames) == 20 * 5 + 1
    assert (out / "trajectories.npz").is_file()
    rec = load_trajectory(out)
    assert rec.order_done is not None and rec.plans


# ----------------------------------------------------------------------------- browser


CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser") or \
    shutil.which("google-chrome")
PAGE = """<!doctype html><html><body><div id="out">pending</div>
<video id="v" muted preload="auto"></video><script>
const v = document.getElementById('v'), out = document.getElementById('out');
v.src = new URLSearchParams(location.search).get('src'); let done = false;
function report(tag) { if (done) return; out.textContent = JSON.stringify({event: tag,
  readyState: v.readyState, duration: v.duration, currentTime: v.currentTime,
  width: v.videoWidth, height: v.videoHeight, error: v.error ? v.error.code : null}); }
v.addEventListener('canplaythrough', () => { report('canplaythrough'); v.play(); });
v.addEventListener('timeupdate', () => { if (v.currentTime > 0.5) { report('played');
  done = true; } });
v.addEventListener('error', () => { report('error'); done = true; });
</script></body></html>"""


def browser_probe(video: Path, workdir: Path) -> dict:
    """Load ``video`` in a ``<video>`` element of headless Chromium and return what the
    page saw (readyState, duration, size, error)."""
    page = workdir / "probe.html"
    page.write_text(PAGE, encoding="utf-8")
    local = workdir / video.name
    if local != video:
        shutil.copy(video, local)
    proc = subprocess.run(
        [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--mute-audio",
         "--allow-file-access-from-files", "--autoplay-policy=no-user-gesture-required",
         "--virtual-time-budget=10000", "--dump-dom", f"{page.as_uri()}?src={local.name}"],
        capture_output=True, text=True, timeout=90)
    start = proc.stdout.find('<div id="out">')
    text = proc.stdout[start + len('<div id="out">'):].split("</div>")[0]
    return json.loads(text) if text.startswith("{") else {"event": text}


@pytest.mark.skipif(CHROMIUM is None, reason="no chromium on PATH (apt-get install chromium)")
def test_mp4_plays_in_headless_chromium(physics_run, tmp_path):
    """Our H.264 file plays (readyState 4, duration right, time advances); an mp4v file —
    what OpenCV alone writes — does not, so the check can tell them apart."""
    rec = load_trajectory(physics_run)
    video = tmp_path / "ok.mp4"
    render_video(rec, video, fps=20, speed=4.0, style=Style(size=(640, 360)))
    seen = browser_probe(video, tmp_path)
    frames = len(frame_times(rec.start_s, rec.end_s, 20, 4.0))
    assert seen["event"] == "played" and seen["readyState"] == 4 and seen["error"] is None, seen
    assert seen["duration"] == pytest.approx(frames / 20, abs=0.1)
    assert (seen["width"], seen["height"]) == (640, 360)
    bad = tmp_path / "bad.mp4"
    render_video(rec, bad, fps=20, speed=4.0, style=Style(size=(640, 360)), codec="mp4v",
                 max_frames=20)
    assert browser_probe(bad, tmp_path)["event"] == "error"
    demo = REPO / "videos" / "demo.mp4"
    if demo.is_file():                       # written by ``make demo``
        seen = browser_probe(demo, tmp_path)
        assert seen["event"] == "played" and seen["readyState"] == 4 and seen["duration"] > 1


# ----------------------------------------------------------------------------- imports


def test_simulation_imports_neither_cv2_nor_av(tmp_path):
    """Running episodes (both executors, with outputs, via the CLI module too) loads no
    renderer; asking for a video does."""
    code = f"""
import sys
import warerover_phys, warerover_phys.cli.commands
from warerover_phys import load_scenario
from warerover_phys.outputs import write_outputs
from warerover_phys.sim import Simulation
for ex in ("grid", "physics"):
    sc = load_scenario({str(HETERO)!r}, [("executor.name", ex), ("max_ticks", 8)])
    sim = Simulation(sc)
    sim.step()
    sim.fail(1)
    write_outputs(sim.run(), {str(tmp_path)!r} + "/" + ex)
from typer.testing import CliRunner
plan = {str(tmp_path)!r} + "/plan.txt"
open(plan, "w").write("Agent 0:(0,0)->(0,1)->(0,2)->\\n")
for ex in ("grid", "physics"):   # plan executions write their recordings too
    r = CliRunner().invoke(warerover_phys.cli.app, ["execute", {str(REPO / "tests/data/random-32-32-10.map")!r},
                           "--plan", plan, "--executor", ex, "--out", {str(tmp_path)!r} + "/x" + ex, "-q"])
    assert r.exit_code == 0, r.output
print(sorted(m for m in ("cv2", "av") if m in sys.modules))
import warerover_phys.render
print(sorted(m for m in ("cv2", "av") if m in sys.modules))
"""
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120, cwd=REPO)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split("\n")[:2] == ["[]", "['cv2']"], proc.stdout


def test_docstring_examples():
    import doctest

    import warerover_phys.render.frame as frame

    result = doctest.testmod(frame)
    assert result.attempted > 0 and result.failed == 0
