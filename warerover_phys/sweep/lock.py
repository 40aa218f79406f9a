"""One sweep at a time per results folder: an OS file lock (``filelock``) on
``DIR/.sweep.lock`` held while the sweep runs, and ``DIR/.sweep.lock.json`` naming the holder
(pid, host, start time) so that a second sweep on the same folder can say who holds it.

The lock is released by the OS when the holder dies, even by SIGKILL: a stale
``.sweep.lock.json`` never blocks anyone.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import json
import os
import socket
from collections.abc import Iterator
from pathlib import Path

from ..errors import WareroverError

__all__ = ["sweep_lock", "LOCK_NAME"]

LOCK_NAME = ".sweep.lock"


@contextlib.contextmanager
def sweep_lock(out_dir: str | Path) -> Iterator[None]:
    """Hold the folder's sweep lock, or raise a :class:`WareroverError` naming the holder."""
    from filelock import FileLock, Timeout

    out = Path(out_dir)
    created = not out.exists()
    out.mkdir(parents=True, exist_ok=True)
    info = out / (LOCK_NAME + ".json")
    lock = FileLock(str(out / LOCK_NAME), timeout=0)
    try:
        lock.acquire()
    except Timeout:
        try:
            holder = json.loads(info.read_text(encoding="utf-8"))
            who = (f"pid {holder.get('pid')} on {holder.get('host')}, started "
                   f"{holder.get('started')}")
        except (OSError, ValueError, AttributeError):
            who = "holder unknown"
        raise WareroverError(f"{out}: another sweep is running into this folder ({who}); "
                             "wait for it to end or stop it") from None
    try:
        tmp = info.with_name(info.name + f".{os.getpid()}.tmp")
        tmp.write_text(json.dumps({
            "pid": os.getpid(), "host": socket.gethostname(),
            "started": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")}) + "\n",
            encoding="utf-8")
        os.replace(tmp, info)
        yield
    finally:
        with contextlib.suppress(OSError):
            info.unlink()
        lock.release()
        if created:          # a sweep that failed before writing anything leaves no folder
            with contextlib.suppress(OSError):
                if {p.name for p in out.iterdir()} <= {LOCK_NAME}:
                    (out / LOCK_NAME).unlink(missing_ok=True)
                    out.rmdir()
