"""Fixtures for the ``warerover serve`` tests: a server on an ephemeral port (uvicorn in a
thread) and headless Chromium driven by Playwright (Debian's ``chromium``; the browser
tests skip, saying why, where it is not installed, and fail under ``CI``: see
``tests/conftest.py``)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

SERVE_EXTRA = "needs the serve extra: pip install '.[serve]'"

REPO = Path(__file__).resolve().parents[2]
CHROMIUM = next((p for p in ("/usr/bin/chromium", "/usr/bin/chromium-browser",
                             shutil.which("chromium") or "") if p and Path(p).exists()), None)


@pytest.fixture
def serve(tmp_path):
    """Start a server in ``tmp_path`` (the served folder); yields a function that starts one
    with the given ``create_app`` options and returns the running ``ServerThread``."""
    for mod in ("starlette", "uvicorn", "websockets"):
        pytest.importorskip(mod, reason=SERVE_EXTRA)
    from warerover_phys.serve.server import ServerThread, create_app

    started = []

    def start(scenario: Path | None = None, **kw):
        kw.setdefault("ticks_per_s", 20.0)
        app = create_app(root=tmp_path, scenario=scenario, **kw)
        srv = ServerThread(app).start()
        started.append(srv)
        return srv

    yield start
    for srv in started:
        srv.stop()
        assert not srv.thread.is_alive(), "server thread did not stop"


@pytest.fixture(scope="session")
def browser():
    if CHROMIUM is None:
        pytest.skip("chromium is not installed (apt-get install chromium); browser tests skipped")
    sync_api = pytest.importorskip("playwright.sync_api",
                                   reason="playwright is not installed (pip install playwright)")
    with sync_api.sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=["--no-sandbox"])
        yield b
        b.close()


@pytest.fixture
def page(browser):
    ctx = browser.new_context(viewport={"width": 1000, "height": 640}, accept_downloads=True)
    pg = ctx.new_page()
    errors: list[str] = []
    pg.on("pageerror", lambda e: errors.append(str(e)))
    pg.errors = errors
    yield pg
    ctx.close()
    assert not errors, f"JavaScript errors on the page: {errors}"


class Client:
    """A blocking WebSocket client speaking the serve protocol."""

    def __init__(self, url: str, **kw) -> None:
        import contextlib

        from websockets.sync.client import connect

        self._stack = contextlib.ExitStack()
        self.ws = self._stack.enter_context(
            connect(url.replace("http", "ws", 1) + "/ws", max_size=2**26, **kw))
        self.hello = self.recv_type("hello")

    def send(self, msg) -> None:
        self.ws.send(msg if isinstance(msg, str | bytes) else json.dumps(msg))

    def recv_type(self, *kinds: str, timeout: float = 20.0) -> dict:
        """The next JSON message of one of ``kinds`` (frames and others are skipped)."""
        import time

        end = time.monotonic() + timeout
        while True:
            raw = self.ws.recv(timeout=max(0.01, end - time.monotonic()))
            if isinstance(raw, bytes):
                continue
            msg = json.loads(raw)
            if msg["type"] in kinds:
                return msg

    def request(self, msg: dict, *kinds: str) -> dict:
        self.send(msg)
        return self.recv_type(*(kinds or ("ack", "error")))

    def close(self) -> None:
        self._stack.close()


@pytest.fixture
def client_for():
    made = []

    def make(srv, **kw) -> Client:
        c = Client(srv.url, **kw)
        made.append(c)
        return c

    yield make
    for c in made:
        c.close()
