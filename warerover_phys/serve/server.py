"""The web server of ``warerover serve``: a Starlette app with one WebSocket (``/ws``) and the
static page.

- A stepping thread runs the live episode (:class:`~.session.LiveSession`) at the chosen
  speed; a broadcaster sends each client the newest binary frame and a status message at
  most ``fps`` times a second (a slow client skips frames, it never queues them).
- Every client message is validated (:func:`~.protocol.parse_message`); a bad one is
  answered with ``{"type": "error", "error": ...}`` and the connection stays open.
- Files are read and written only under ``root`` (the folder the server was started in);
  a path that resolves outside it is refused.
- The socket checks the ``Origin`` header (same host as the page, or one of
  ``allowed_origins``); bound to a loopback address, the server answers only requests whose
  ``Host`` is a loopback name (no DNS rebinding).

>>> app = create_app(root=".")          # doctest: +SKIP
>>> ServerThread(app).start().port      # doctest: +SKIP
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import os
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

from ..errors import WareroverError
from . import protocol as P
from .session import LiveSession

__all__ = ["Hub", "create_app", "ServerThread", "resolve_under", "STATIC_DIR"]

log = logging.getLogger(__name__)
STATIC_DIR = Path(__file__).with_name("static")
LOOPBACK_HOSTS = ("127.0.0.1", "localhost", "::1", "[::1]")
SKIP_DIRS = {".git", ".venv", "venv", "node_modules", "__pycache__", ".mypy_cache",
             ".pytest_cache", ".ruff_cache"}


def resolve_under(root: Path, rel: str, *, suffixes: tuple[str, ...] | None = None,
                  must_exist: bool = False) -> Path:
    """``root / rel`` resolved, refusing anything outside ``root`` (``..``, absolute paths,
    symlinks out) and, when given, other suffixes."""
    if "\0" in rel:
        raise P.ProtocolError("path contains a NUL byte")
    root = root.resolve()
    p = (root / rel).resolve()
    if not p.is_relative_to(root):
        raise P.ProtocolError(f"path {rel!r} is outside the served folder")
    if suffixes is not None and p.suffix.lower() not in suffixes and not (
            must_exist and p.is_dir()):
        raise P.ProtocolError(f"path {rel!r} must end in {' or '.join(suffixes)}")
    if must_exist and not p.exists():
        raise P.ProtocolError(f"{rel}: no such file")
    return p


@dataclass(eq=False)
class _Client:
    ws: Any
    busy: bool = False
    scene_version: int = -1
    sent_version: int = -1
    lock: asyncio.Lock = field(default_factory=asyncio.Lock)


class Hub:
    """The server's state: the live session, its stepping thread and the connected clients."""

    def __init__(self, session: LiveSession, *, fps: float = 30.0,
                 ticks_per_s: float = 4.0, paused: bool = False) -> None:
        self.session = session
        self.root = session.root
        self.fps = fps
        self.ticks_per_s = ticks_per_s
        self.paused = paused
        self.clients: set[_Client] = set()
        self._stop = threading.Event()
        self._wake = threading.Event()
        self._thread: threading.Thread | None = None
        self._broadcaster: asyncio.Task | None = None
        self.frames_sent = 0

    # ------------------------------------------------------------------------- stepping

    def start(self) -> None:
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name="warerover-sim", daemon=True)
            self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        self._wake.set()
        if self._thread is not None:
            self._thread.join(timeout=10)
            self._thread = None

    def set_paused(self, paused: bool) -> None:
        self.paused = paused
        self.session.version += 1
        self._wake.set()

    def set_speed(self, ticks_per_s: float) -> None:
        self.ticks_per_s = ticks_per_s
        self._wake.set()

    def _run(self) -> None:
        next_at = time.perf_counter()
        while not self._stop.is_set():
            if self.paused or self.session.done:
                self._wake.wait(0.05)
                self._wake.clear()
                next_at = time.perf_counter()
                continue
            try:
                self.session.step(1)
            except Exception:  # noqa: BLE001 - keep serving; the page shows the pause
                log.exception("simulation step failed; pausing")
                self.paused = True
                continue
            rate = self.ticks_per_s
            if rate <= 0:
                time.sleep(0)       # let the server thread take the GIL
                continue
            next_at += 1.0 / rate
            delay = next_at - time.perf_counter()
            if delay > 0:
                self._wake.wait(delay)
                self._wake.clear()
            else:
                next_at = time.perf_counter() if delay < -0.5 else next_at
                time.sleep(0)

    # ------------------------------------------------------------------------- broadcasting

    def state(self) -> dict[str, Any]:
        return {"paused": self.paused, "ticks_per_s": self.ticks_per_s}

    def _frame(self) -> tuple[int, int, bytes, dict, dict | None, int]:
        s = self.session
        with s.lock:
            version, scene_version = s.version, s.scene_version
            snap = s.snapshot()
            status = {"type": "status", **s.status(), **self.state()}
            frame = P.encode_frame(snap, float(s.scenario.tick_s), status["sim_ticks_per_s"])
        return version, scene_version, frame, status, None, snap.tick

    async def broadcast_loop(self) -> None:
        last_version = -1
        while True:
            await asyncio.sleep(1.0 / self.fps)
            if not self.clients:
                continue
            if self.session.version == last_version and all(
                    c.sent_version == last_version for c in self.clients):
                continue
            version, scene_version, frame, status, _, _ = await asyncio.to_thread(self._frame)
            last_version = version
            for c in list(self.clients):
                if c.busy:
                    continue
                c.busy = True
                asyncio.create_task(self._send_frame(c, version, scene_version, frame, status))

    async def _send_frame(self, c: _Client, version: int, scene_version: int, frame: bytes,
                          status: dict) -> None:
        try:
            if c.scene_version != scene_version:
                scene = await asyncio.to_thread(self.session.scene)
                await self.send(c, {"type": "scene", **scene})
                c.scene_version = scene_version
            async with c.lock:
                await c.ws.send_bytes(frame)
                await c.ws.send_text(json.dumps(status, separators=(",", ":")))
            c.sent_version = version
            self.frames_sent += 1
        except Exception:  # noqa: BLE001 - a gone client is dropped
            self.clients.discard(c)
        finally:
            c.busy = False

    async def send(self, c: _Client, msg: dict) -> None:
        async with c.lock:
            await c.ws.send_text(json.dumps(msg, separators=(",", ":")))

    async def send_bytes(self, c: _Client, data: bytes) -> None:
        async with c.lock:
            await c.ws.send_bytes(data)

    # ------------------------------------------------------------------------- messages

    async def handle(self, c: _Client, text: str | bytes) -> None:
        """Answer one client message (errors become an ``error`` reply)."""
        mid = None
        try:
            msg = P.parse_message(text)
            mid = msg.id
            reply = await self._dispatch(c, msg)
        except (P.ProtocolError, WareroverError, ValueError) as err:
            reply = {"type": "error", "error": str(err)}
        except Exception as err:  # noqa: BLE001 - never let a message kill the server
            log.exception("message failed")
            reply = {"type": "error", "error": f"internal error: {type(err).__name__}: {err}"}
        if reply is not None:
            if mid is not None:
                reply["id"] = mid
            await self.send(c, reply)

    async def _dispatch(self, c: _Client, msg: Any) -> dict | None:
        s = self.session
        kind = msg.type
        if kind == "ping":
            return {"type": "pong", "tick": s.sim.world.tick}
        if kind in ("pause", "resume"):
            self.set_paused(kind == "pause")
            return {"type": "ack", "of": kind, **self.state()}
        if kind == "speed":
            self.set_speed(msg.ticks_per_s)
            return {"type": "ack", "of": kind, **self.state()}
        if kind == "step":
            self.set_paused(True)
            ran = await asyncio.to_thread(s.step, msg.count)
            return {"type": "ack", "of": kind, "ran": ran, "tick": s.sim.world.tick,
                    **self.state()}
        if kind == "fail":
            await asyncio.to_thread(s.fail, msg.agv, msg.repair_ticks)
            status = await asyncio.to_thread(s.status)
            return {"type": "ack", "of": kind, "agv": msg.agv, "corridors": status["corridors"]}
        if kind == "repair":
            await asyncio.to_thread(s.repair, msg.agv)
            return {"type": "ack", "of": kind, "agv": msg.agv}
        if kind == "add_orders":
            ids = await asyncio.to_thread(s.add_orders, msg.count, msg.station, msg.sku)
            return {"type": "ack", "of": kind, "orders": ids}
        if kind == "restart":
            await asyncio.to_thread(s.restart, msg.executor, msg.seed, msg.planner)
            return {"type": "ack", "of": kind, "executor": s.executor_name}
        if kind == "inspect":
            return {"type": "agv", **(await asyncio.to_thread(s.agv_info, msg.agv))}
        if kind == "list_files":
            files = await asyncio.to_thread(self.list_files, tuple(msg.suffixes))
            return {"type": "files", "files": files}
        if kind == "layout_load":
            from .layout_edit import doc_from_file

            p = resolve_under(self.root, msg.path, suffixes=(".yaml", ".yml"), must_exist=True)
            doc = await asyncio.to_thread(doc_from_file, p)
            return {"type": "layout", "path": msg.path, "layout": doc.model_dump(mode="json")}
        if kind == "layout_check":
            from .layout_edit import check_doc

            return {"type": "check", "errors": await asyncio.to_thread(check_doc, msg.layout)}
        if kind == "layout_save":
            from .layout_edit import check_doc, save_doc

            p = resolve_under(self.root, msg.path, suffixes=(".yaml", ".yml"))
            errors = await asyncio.to_thread(check_doc, msg.layout)
            files = await asyncio.to_thread(save_doc, msg.layout, p, msg.scenario)
            return {"type": "saved", "files": [str(f.relative_to(self.root)) for f in files],
                    "errors": errors, "ok": not errors}
        if kind == "replay_open":
            return await self._replay(c, msg)
        if kind == "export_glb":
            from .glb import export_episode_glb, export_layout_glb

            p = resolve_under(self.root, msg.path, suffixes=(".glb",))
            fn = export_layout_glb if msg.what == "layout" else export_episode_glb
            size = await asyncio.to_thread(fn, s, p)
            return {"type": "exported", "path": str(p.relative_to(self.root)), "bytes": size}
        raise P.ProtocolError(f"message type {kind!r} is not handled")  # pragma: no cover

    async def _replay(self, c: _Client, msg: Any) -> dict | None:
        from .replay import encode_replay, open_replay

        p = resolve_under(self.root, msg.path, suffixes=(".npz", ".json"), must_exist=True)
        lay = None
        if msg.map is not None:
            lay = resolve_under(self.root, msg.map, suffixes=(".yaml", ".yml", ".map"),
                                must_exist=True)
        s = self.session
        with s.lock:
            grid = s.sim.world.layout.grid.copy()
        data = await asyncio.to_thread(open_replay, p, lay, grid, s.cell_m)
        body = await asyncio.to_thread(encode_replay, data)
        head = {"type": "replay", **data.header(), "bytes": len(body)}
        if msg.id is not None:
            head["id"] = msg.id
        async with c.lock:
            await c.ws.send_text(json.dumps(head, separators=(",", ":")))
            await c.ws.send_bytes(body)
        return None

    def list_files(self, suffixes: tuple[str, ...], limit: int = 500) -> list[str]:
        out: list[str] = []
        root = self.root
        for dirpath, dirnames, filenames in os.walk(root):
            rel_dir = Path(dirpath).relative_to(root)
            dirnames[:] = sorted(d for d in dirnames
                                 if d not in SKIP_DIRS and not d.startswith(".")
                                 and len(rel_dir.parts) < 5)
            for name in sorted(filenames):
                if Path(name).suffix.lower() in suffixes:
                    out.append(str(rel_dir / name) if rel_dir.parts else name)
                    if len(out) >= limit:
                        return out
        return out


# ----------------------------------------------------------------------------- the app


def _origin_ok(headers: Any, allowed: tuple[str, ...]) -> bool:
    origin = headers.get("origin")
    if origin is None:
        return True       # not a browser: nothing a web page can forge
    if origin in allowed:
        return True
    host = headers.get("host", "")
    o = urlsplit(origin)
    return o.scheme in ("http", "https") and o.netloc == host


def create_app(root: str | Path = ".", scenario: Path | None = None, *,
               session: LiveSession | None = None, overrides: list | None = None,
               seed: int | None = None, fps: float = 30.0, ticks_per_s: float = 4.0,
               paused: bool = False, allowed_origins: tuple[str, ...] = (),
               loopback_only: bool = True):
    """The Starlette app (the live session is built now, so errors show before serving)."""
    from starlette.applications import Starlette
    from starlette.middleware import Middleware
    from starlette.middleware.trustedhost import TrustedHostMiddleware
    from starlette.responses import FileResponse, Response
    from starlette.routing import Mount, Route, WebSocketRoute
    from starlette.staticfiles import StaticFiles
    from starlette.websockets import WebSocketDisconnect

    if session is None:
        session = LiveSession(scenario, Path(root), overrides=overrides, seed=seed)
    hub = Hub(session, fps=fps, ticks_per_s=ticks_per_s, paused=paused)

    async def index(request):
        return FileResponse(STATIC_DIR / "index.html",
                            headers={"Cache-Control": "no-store"})

    async def favicon(request):
        return Response(status_code=204)

    async def ws_endpoint(ws):
        if not _origin_ok(ws.headers, allowed_origins):
            await ws.close(code=1008)
            return
        await ws.accept()
        c = _Client(ws)
        try:
            scene = await asyncio.to_thread(session.scene)
            status = await asyncio.to_thread(session.status)
            c.scene_version = session.scene_version
            await hub.send(c, {"type": "hello", "protocol": 1, "scene": scene,
                               "status": {"type": "status", **status, **hub.state()},
                               "messages": list(P.MESSAGE_TYPES)})
            hub.clients.add(c)
            while True:
                m = await ws.receive()
                if m["type"] == "websocket.disconnect":
                    break
                text = m.get("text")
                await hub.handle(c, text if text is not None else (m.get("bytes") or b""))
        except WebSocketDisconnect:
            pass
        except RuntimeError:    # sent on a closed socket
            pass
        finally:
            hub.clients.discard(c)

    @contextlib.asynccontextmanager
    async def lifespan(app):
        hub.start()
        task = asyncio.create_task(hub.broadcast_loop())
        try:
            yield
        finally:
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await task
            hub.stop()

    middleware = []
    if loopback_only:
        middleware.append(Middleware(TrustedHostMiddleware,
                                     allowed_hosts=["127.0.0.1", "localhost", "::1", "[::1]"]))
    app = Starlette(routes=[Route("/", index), Route("/favicon.ico", favicon), WebSocketRoute("/ws", ws_endpoint),
                            Mount("/static", StaticFiles(directory=STATIC_DIR), name="static")],
                    middleware=middleware, lifespan=lifespan)
    app.state.hub = hub
    return app


class ServerThread:
    """uvicorn serving ``app`` in a background thread (tests, benchmarks); port 0 picks a
    free port. ``stop()`` shuts it down cleanly."""

    def __init__(self, app, host: str = "127.0.0.1", port: int = 0) -> None:
        import uvicorn

        self.app = app
        self.config = uvicorn.Config(app, host=host, port=port, log_level="warning",
                                     ws="auto", lifespan="on", ws_max_size=P.MAX_MESSAGE_BYTES)
        self.server = uvicorn.Server(self.config)
        self.thread = threading.Thread(target=self.server.run, name="warerover-serve",
                                       daemon=True)
        self.host = host
        self.port = port

    def start(self, timeout: float = 30.0) -> ServerThread:
        self.thread.start()
        t0 = time.monotonic()
        while not self.server.started:
            if not self.thread.is_alive() or time.monotonic() - t0 > timeout:
                raise RuntimeError("server did not start")
            time.sleep(0.02)
        self.port = self.server.servers[0].sockets[0].getsockname()[1]
        return self

    @property
    def url(self) -> str:
        return f"http://{self.host}:{self.port}"

    def stop(self) -> None:
        self.server.should_exit = True
        self.thread.join(timeout=15)

    def __enter__(self) -> ServerThread:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()
