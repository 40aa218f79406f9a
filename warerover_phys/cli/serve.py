"""The ``warerover serve`` and ``warerover export-glb`` commands.

The main CLI adds them with one line: ``from .serve.cli import register; register(app)``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

__all__ = ["register", "serve", "export_glb"]


from ..util.console import fail as _fail


def _need_extra() -> None:
    try:
        import starlette  # noqa: F401
        import uvicorn  # noqa: F401
    except ImportError:
        _fail(RuntimeError("warerover serve needs the serve extra: "
                           "pip install 'warerover-phys[serve]'"))


def serve(scenario: Annotated[Path | None, typer.Argument(
              help="Scenario YAML to run live (default: a demo on the paper's basic map).")
          ] = None,
          host: Annotated[str, typer.Option(
              help="Address to bind (default loopback only; 0.0.0.0 exposes it).")
          ] = "127.0.0.1",
          port: Annotated[int, typer.Option(help="TCP port.")] = 8000,
          seed: Annotated[int | None, typer.Option(help="Episode seed.")] = None,
          executor: Annotated[str | None, typer.Option(
              help="Override the executor (grid or physics).")] = None,
          speed: Annotated[float, typer.Option(
              help="Ticks per second to start with (0: as fast as it runs).")] = 4.0,
          paused: Annotated[bool, typer.Option(help="Start paused.")] = False,
          allow_origin: Annotated[list[str] | None, typer.Option(
              help="Extra web origin allowed to open the socket (repeatable).")] = None,
          ) -> None:
    """Serve a live browser view of a running warehouse, a layout editor and a replay
    viewer. Files are read and written only under the current folder."""
    _need_extra()
    import uvicorn

    from ..errors import WareroverError
    from ..inputs import check_seed
    from ..serve.protocol import MAX_MESSAGE_BYTES
    from ..serve.server import create_app

    root = Path.cwd()
    overrides = [("executor.name", executor)] if executor else []
    try:
        if not 0 <= port <= 65535:
            raise WareroverError(f"--port: must be 0 to 65535 (got {port})")
        if seed is not None:
            check_seed(seed)
        if not 0 <= speed <= 10_000:  # as the browser's speed control; also refuses nan
            raise WareroverError(f"--speed: expected ticks per second from 0 to 10000 (0: as "
                                 f"fast as it runs) (got {speed})")
        _check_bind(host, port)
        app = create_app(root, scenario, overrides=overrides, seed=seed, ticks_per_s=speed,
                         paused=paused, allowed_origins=tuple(allow_origin or ()),
                         loopback_only=host in ("127.0.0.1", "localhost", "::1"))
    except WareroverError as err:
        _fail(err)
    if host not in ("127.0.0.1", "localhost", "::1"):
        typer.echo(f"warning: serving on {host}: anyone who can reach this address can "
                   "control the simulation and read the folder's layout and run files",
                   err=True)
    typer.echo(f"warerover serve: http://{'127.0.0.1' if host == '0.0.0.0' else host}:{port}/ "
               f"(folder {root})")
    uvicorn.run(app, host=host, port=port, log_level="warning", ws="auto",
                ws_max_size=MAX_MESSAGE_BYTES)


def _check_bind(host: str, port: int) -> None:
    """A clean error now for an address that cannot be served on (in use, not local)."""
    import socket

    from ..errors import WareroverError

    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)
    except (OSError, UnicodeError) as err:
        raise WareroverError(f"--host: cannot resolve {host!r} ({err})") from None
    family, kind, proto, _, addr = infos[0]
    with socket.socket(family, kind, proto) as sock:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            sock.bind(addr)
        except OSError as err:
            raise WareroverError(f"--host/--port: cannot serve on {host}:{port} "
                                 f"({err.strerror or err})") from None


def export_glb(out: Annotated[Path, typer.Argument(help="Output .glb file.")],
               scenario: Annotated[Path | None, typer.Argument(
                   help="Scenario YAML (default: the demo).")] = None,
               ticks: Annotated[int, typer.Option(
                   help="Run this many ticks and export them as an animation "
                        "(0: the layout only).")] = 0,
               seed: Annotated[int | None, typer.Option(help="Episode seed.")] = None,
               ) -> None:
    """Export a layout (and, with --ticks, an episode's AGV motion) as glTF binary."""
    from ..errors import WareroverError
    from ..inputs import check_output_file, check_seed
    from ..serve.glb import export_episode_glb, export_layout_glb
    from ..serve.session import LiveSession

    try:
        if seed is not None:
            check_seed(seed)
        check_output_file(out, "OUT", suffixes=(".glb",))
        session = LiveSession(scenario, Path.cwd(), seed=seed)
        if ticks > 0:
            session.step(ticks)
            size = export_episode_glb(session, out)
        else:
            size = export_layout_glb(session, out)
    except WareroverError as err:
        _fail(err)
    typer.echo(f"{out}: {size} bytes")


def register(app: typer.Typer) -> None:
    """Add ``serve`` and ``export-glb`` to the ``warerover`` command."""
    app.command("serve")(serve)
    app.command("export-glb")(export_glb)
