"""``warerover serve``: a live browser view of a running warehouse (watch, steer, fail and
repair AGVs), a layout editor, a replay of recorded runs and glTF export.

Needs the ``serve`` extra (``pip install 'warerover-phys[serve]'``: starlette, uvicorn,
websockets, trimesh); nothing here is imported by the simulation. See ``docs/serve.md``.
"""

__all__ = ["create_app", "LiveSession", "ServerThread"]


def __getattr__(name: str):
    if name in ("create_app", "ServerThread"):
        from . import server

        return getattr(server, name)
    if name == "LiveSession":
        from .session import LiveSession

        return LiveSession
    raise AttributeError(name)
