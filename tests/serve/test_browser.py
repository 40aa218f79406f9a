"""The page in a real browser: headless Chromium (Debian's package) driven by Playwright.

Skipped, with the reason, where chromium or playwright is missing; under ``CI`` that skip
is a failure (``tests/conftest.py``).
"""

from __future__ import annotations

import io
import time

import numpy as np
import pytest

from .conftest import REPO

MOVING_BLUE = (0, 114, 178)
LOADED_ORANGE = (230, 159, 0)
IDLE_GREY = (153, 153, 153)


def _pixels(png: bytes) -> np.ndarray:
    Image = pytest.importorskip("PIL.Image", reason="pixel checks need Pillow")

    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(int)


def _count(img: np.ndarray, rgb: tuple[int, int, int], tol: int = 12) -> int:
    return int((np.abs(img - np.array(rgb)).max(axis=2) <= tol).sum())


def _open(page, srv):
    page.goto(srv.url)
    page.wait_for_function("window.wr && window.wr.frames >= 1 && window.wr.scene", timeout=20000)


def test_page_loads_and_draws_agvs(serve, page):
    srv = serve()
    _open(page, srv)
    assert page.title() == "warerover serve"
    page.wait_for_timeout(300)
    img = _pixels(page.locator("#view").screenshot())
    bodies = sum(_count(img, c) for c in (MOVING_BLUE, LOADED_ORANGE, IDLE_GREY))
    n = len(page.evaluate("wr.scene.agvs"))
    # 9 bodies of 0.7 m at >= 20 px per metre: well over 9 * 100 pixels of status colours
    assert bodies > n * 100, f"only {bodies} AGV-coloured pixels"
    assert page.evaluate("wr.rafFrames") > 5


def test_pause_stops_the_tick_counter(serve, page):
    srv = serve(ticks_per_s=30)
    _open(page, srv)
    page.wait_for_function("wr.tick >= 3", timeout=20000)
    page.click("#b-pause")
    page.wait_for_function("wr.paused === true", timeout=10000)
    page.wait_for_timeout(400)
    t0 = int(page.inner_text("#c-tick"))
    page.wait_for_timeout(1200)
    assert int(page.inner_text("#c-tick")) == t0
    assert srv.app.state.hub.session.sim.world.tick == t0
    page.click("#b-step")
    page.wait_for_function(f"wr.tick === {t0 + 1}", timeout=10000)
    page.keyboard.press("n")
    page.wait_for_function(f"wr.tick === {t0 + 2}", timeout=10000)
    page.keyboard.press(" ")                  # resume
    page.wait_for_function(f"wr.tick > {t0 + 4}", timeout=20000)


def test_click_an_agv_and_fail_it_opens_a_corridor(serve, page):
    srv = serve()
    _open(page, srv)
    page.click("#b-pause")
    page.wait_for_function("wr.paused === true", timeout=10000)
    page.wait_for_timeout(500)
    agv = 5
    x, y = page.evaluate(f"""() => {{
        const v = wr.views.live, [sx, sy] = wr.cam.toScreen(v.cur.x[{agv}], v.cur.y[{agv}]);
        const r = document.getElementById('view').getBoundingClientRect();
        return [r.left + sx, r.top + sy]; }}""")
    page.mouse.move(x, y)
    page.wait_for_function(f"document.getElementById('tooltip').textContent.startsWith('AGV {agv} ')"
                           " && !document.getElementById('tooltip').hidden", timeout=10000)
    assert "waiting for" in page.inner_text("#tooltip")
    page.mouse.click(x, y)
    page.wait_for_function(f"wr.selected === {agv}", timeout=5000)
    assert page.inner_text("#sel-id") == str(agv)
    page.click("#b-fail")
    hub = srv.app.state.hub
    t0 = time.monotonic()
    while not hub.session.status()["corridors"] and time.monotonic() - t0 < 10:
        time.sleep(0.05)
    st = hub.session.status()
    assert [c["agv"] for c in st["corridors"]] == [agv] and st["failed"] == [agv]
    page.wait_for_function(f"wr.status.failed.includes({agv})", timeout=10000)
    page.wait_for_function("!document.getElementById('b-repair').disabled", timeout=10000)
    page.click("#b-repair")
    t0 = time.monotonic()
    while hub.session.status()["corridors"] and time.monotonic() - t0 < 10:
        time.sleep(0.05)
    assert hub.session.status()["corridors"] == []


def test_editor_saves_a_layout_that_check_accepts(serve, page, tmp_path):
    from typer.testing import CliRunner

    from warerover_phys.cli import app

    srv = serve(paused=True)
    _open(page, srv)
    page.click("button[data-tab=editor]")
    page.fill("#e-rows", "8")
    page.fill("#e-cols", "10")
    page.click("#e-new")

    def paint(tool, cells):
        page.click(f"#tools button[data-tool='{tool}']")
        for r, c in cells:
            x, y = page.evaluate(f"""() => {{ const [sx, sy] = wr.cam.toScreen({c} + 0.5, {r} + 0.5);
                const b = document.getElementById('view').getBoundingClientRect();
                return [b.left + sx, b.top + sy]; }}""")
            page.mouse.click(x, y)

    paint("R", [(1, 0), (2, 0)])
    paint("S", [(3, 4), (3, 5), (4, 4), (4, 5)])
    paint("B", [(2, 7)])
    paint("P", [(6, c) for c in range(2, 8)] + [(7, c) for c in range(2, 8)])
    paint("A", [(0, 9)])
    paint("#", [(0, 0)])
    cells = page.evaluate("wr.views.editor.cells.join('')")
    assert cells.count("R") == 2 and cells.count("B") == 4 and cells.count("P") == 12
    page.fill("#e-path", "drawn/floor.yaml")
    page.click("#e-save")
    page.wait_for_function("wr.lastSave !== undefined", timeout=20000)
    saved = page.evaluate("wr.lastSave")
    assert saved["ok"], saved["errors"]
    scen = tmp_path / "drawn" / "floor.scenario.yaml"
    result = CliRunner().invoke(app, ["check", str(scen)])
    assert result.exit_code == 0, result.output
    # a walled-in station: the check names its cell and the page marks it
    paint("#", [(0, 1), (1, 1), (2, 1), (3, 0), (3, 1)])
    page.click("#e-check")
    page.wait_for_function("wr.views.editor.errors.length > 0", timeout=20000)
    errs = page.evaluate("wr.views.editor.errors")
    assert any(c in ([1, 0], [2, 0]) for e in errs for c in e["cells"]), errs
    # and loading the saved file brings the drawing back
    page.click("#e-load")
    page.wait_for_function(f"wr.views.editor.cells.join('') === {cells!r}", timeout=20000)


def test_replay_of_a_recorded_run_reaches_its_last_frame(serve, page, tmp_path):
    from warerover_phys.config import load_scenario
    from warerover_phys.outputs import write_outputs
    from warerover_phys.sim import run_episode

    sc = load_scenario(REPO / "layouts" / "paper_homogeneous.yaml",
                       [("executor.name", "physics"), ("max_ticks", 30)])
    write_outputs(run_episode(sc), tmp_path / "runs" / "demo")
    srv = serve(paused=True)
    _open(page, srv)
    page.click("button[data-tab=replay]")
    page.fill("#r-path", "runs/demo/trajectories.npz")
    page.click("#r-open")
    page.wait_for_function("wr.replay && wr.replay.samples > 10", timeout=30000)
    assert page.evaluate("wr.replay.agvs") == 9
    page.select_option("#r-speed", "30")
    page.click("#r-play")
    page.wait_for_function("wr.replay.atEnd === true", timeout=20000)
    assert page.evaluate("wr.replay.time") == pytest.approx(page.evaluate("wr.replay.end"))
    assert page.inner_text("#r-play") == "Play"
    img = _pixels(page.locator("#view").screenshot())
    assert sum(_count(img, c) for c in (MOVING_BLUE, LOADED_ORANGE, IDLE_GREY)) > 500
    with page.expect_download() as dl:
        page.click("#r-png")
    png = dl.value.path().read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    # scrubbing back to the start
    page.evaluate("""() => { const r = document.getElementById('r-time'); r.value = r.min;
                              r.dispatchEvent(new Event('input')); }""")
    page.wait_for_function("wr.replay.time === wr.replay.start", timeout=5000)


def test_3d_view_draws_the_scene(serve, page):
    srv = serve(scenario=REPO / "layouts" / "paper_heterogeneous.yaml")
    _open(page, srv)
    page.click("button[data-tab='3d']")
    if not page.evaluate("!!wr.views['3d'].gl"):
        pytest.skip("this Chromium has no WebGL2")
    page.wait_for_timeout(500)
    img = _pixels(page.locator("#view3d").screenshot())
    shelves = _count(img, (140, 196, 237), tol=40)     # lit shelf faces
    agvs = sum(_count(img, c, tol=40) for c in (LOADED_ORANGE, MOVING_BLUE, IDLE_GREY))
    assert shelves > 2000 and agvs > 200, (shelves, agvs)
    assert page.is_hidden("#view") and page.is_visible("#view3d")


def test_restart_on_the_physics_executor(serve, page):
    srv = serve(ticks_per_s=10)
    _open(page, srv)
    page.select_option("#executor", "physics")
    page.fill("#seed", "4")
    page.click("#b-restart")
    page.wait_for_function("wr.scene.executor === 'physics' && wr.scene.seed === 4",
                           timeout=20000)
    hub = srv.app.state.hub
    assert hub.session.executor_name == "physics"
    t0 = time.monotonic()
    while hub.session.sim.world.tick < 3 and time.monotonic() - t0 < 30:
        time.sleep(0.05)
    page.wait_for_function("wr.tick >= 3 && wr.frames > 0", timeout=30000)
    assert page.evaluate("Array.from(wr.views.live.cur.x).every(Number.isFinite)")
