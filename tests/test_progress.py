"""Progress on long work: `warerover run` (ticks / orders, then video frames) and
`warerover render` (frames) show a rich bar on a terminal, nothing with --json, --quiet or
when stderr is not a terminal."""

from __future__ import annotations

import io
from pathlib import Path

import pytest
from rich.console import Console
from typer.testing import CliRunner

from warerover_phys.cli import app
from warerover_phys.cli import options as cli_options
from warerover_phys.cli import render as cli_render

REPO = Path(__file__).resolve().parents[1]
HOMO = str(REPO / "layouts" / "paper_homogeneous.yaml")


@pytest.fixture
def terminal(monkeypatch) -> io.StringIO:
    """stderr as a terminal: the CLI's error console writes to a buffer that says it is one."""
    buf = io.StringIO()
    console = Console(file=buf, force_terminal=True, width=120)
    for module in (cli_options, cli_render):  # the progress bar's and render's console
        monkeypatch.setattr(module, "err_console", console)
    return buf


def test_simulation_reports_ticks_and_orders():
    from warerover_phys import load_scenario
    from warerover_phys.sim import Simulation

    seen = []
    sim = Simulation(load_scenario(HOMO, [("max_ticks", 15)]))
    sim.run(lambda t, done, gen: seen.append((t, done, gen)))
    assert [s[0] for s in seen] == list(range(1, 16))
    assert all(gen == 20 and 0 <= done <= gen for _, done, gen in seen)


def test_render_video_reports_every_frame(tmp_path):
    pytest.importorskip("av")
    from warerover_phys import load_scenario, run_episode
    from warerover_phys.render import recording_from_episode, render_video

    rec = recording_from_episode(run_episode(load_scenario(HOMO, [("max_ticks", 6)])))
    calls = []
    info = render_video(rec, tmp_path / "v.mp4", fps=4, speed=1.0,
                        progress=lambda done, total: calls.append((done, total)))
    assert calls == [(i, info["frames"]) for i in range(1, info["frames"] + 1)]


def test_run_shows_a_bar_on_a_terminal_only(terminal, tmp_path):
    runner = CliRunner()
    res = runner.invoke(app, ["run", HOMO, "--set", "max_ticks=30", "--out",
                              str(tmp_path / "a")])
    assert res.exit_code == 0, res.output
    shown = terminal.getvalue()
    assert "paper_homogeneous" in shown and "tick" in shown and "orders" in shown
    for flag in ("--json", "--quiet"):
        terminal.truncate(0)
        terminal.seek(0)
        res = runner.invoke(app, ["run", HOMO, "--set", "max_ticks=30", "--out",
                                  str(tmp_path / flag.strip("-")), flag])
        assert res.exit_code == 0, res.output
        assert terminal.getvalue() == "", flag


def test_run_without_a_terminal_is_silent(monkeypatch, tmp_path):
    buf = io.StringIO()
    for module in (cli_options, cli_render):
        monkeypatch.setattr(module, "err_console", Console(file=buf, force_terminal=False))
    res = CliRunner().invoke(app, ["run", HOMO, "--set", "max_ticks=10", "--out",
                                   str(tmp_path / "a")])
    assert res.exit_code == 0, res.output
    assert buf.getvalue() == ""


def test_render_prints_progress(terminal, tmp_path):
    pytest.importorskip("av")
    runner = CliRunner()
    run_dir, video = tmp_path / "run", tmp_path / "v.mp4"
    res = runner.invoke(app, ["run", HOMO, "--set", "max_ticks=8", "--out", str(run_dir),
                              "--quiet", "--video", str(video), "--fps", "4",
                              "--size", "480p"])
    assert res.exit_code == 0, res.output
    terminal.truncate(0)
    terminal.seek(0)
    res = runner.invoke(app, ["render", str(run_dir), "--out", str(tmp_path / "r.mp4"),
                              "--fps", "4", "--size", "480p"])
    assert res.exit_code == 0, res.output
    shown = terminal.getvalue()
    assert "reading" in shown and "render r.mp4" in shown and "frame" in shown
    terminal.truncate(0)
    terminal.seek(0)
    res = runner.invoke(app, ["render", str(run_dir), "--out", str(tmp_path / "q.mp4"),
                              "--fps", "4", "--size", "480p", "--quiet"])
    assert res.exit_code == 0, res.output
    assert terminal.getvalue() == ""
