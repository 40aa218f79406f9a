"""The results file of a sweep: JSON lines, one per finished episode, appended atomically.

Each line is written with a single ``os.write`` on a file opened with ``O_APPEND`` and then
``fsync``-ed, so a line is either whole on disk or (if the process was killed during the
write) a truncated last line. :meth:`ResultsFile.load` tolerates that truncated last line and
:meth:`ResultsFile.open_for_append` cuts it off before anything new is appended, so an
interrupted sweep resumes into a clean file. Rows are keyed by
:func:`~warerover_phys.sweep.spec.episode_key`; a key appears at most once.
"""

from __future__ import annotations

import json
import logging
import os
from pathlib import Path
from typing import Any

from ..errors import WareroverError

__all__ = ["ResultsFile", "RESULTS_NAME", "to_json_line"]

log = logging.getLogger(__name__)

RESULTS_NAME = "results.jsonl"


def _jsonable(value: Any) -> Any:
    """numpy scalars and arrays, tuples and paths as plain JSON values."""
    if hasattr(value, "item") and callable(value.item) and getattr(value, "shape", None) == ():
        return value.item()
    if hasattr(value, "tolist"):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"{type(value).__name__} is not JSON serialisable")


def to_json_line(row: dict[str, Any]) -> bytes:
    """One row as a UTF-8 JSON line (NaN and infinities written as null)."""
    text = json.dumps(_clean(row), default=_jsonable, separators=(",", ":"), allow_nan=False)
    return (text + "\n").encode("utf-8")


def _clean(value: Any) -> Any:
    if isinstance(value, float) and (value != value or value in (float("inf"), float("-inf"))):
        return None
    if isinstance(value, dict):
        return {str(k): _clean(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_clean(v) for v in value]
    return value


MAX_RESULTS_BYTES = 4 * 2**30
"""Largest ``results.jsonl`` read (4 GiB: a million rows of about 4 KiB)."""


class ResultsFile:
    """``DIR/results.jsonl``: read what is there, append new rows atomically."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self._fd: int | None = None

    def load(self) -> dict[str, dict[str, Any]]:
        """Rows by key (the last row of a key wins). A truncated last line is skipped; a bad
        line anywhere else is an error naming the file and line."""
        rows: dict[str, dict[str, Any]] = {}
        if not os.path.lexists(self.path):
            return rows
        from ..inputs import read_bytes

        data = read_bytes(self.path, "results", MAX_RESULTS_BYTES)  # a regular file
        complete = data.endswith(b"\n")
        lines = data.split(b"\n")
        if complete:
            lines.pop()
        for number, line in enumerate(lines, 1):
            if not line.strip():
                continue
            try:
                row = json.loads(line)
                if not isinstance(row, dict) or "key" not in row:
                    raise ValueError("not a result row")
            except ValueError:
                if number == len(lines) and not complete:
                    log.warning("%s: ignoring a truncated last line", self.path)
                    continue
                raise WareroverError(f"{self.path}: line {number}: not a result row (the file "
                                     "is damaged; delete that line to go on)") from None
            rows[row["key"]] = row
        return rows

    def open_for_append(self) -> None:
        """Open for appending. A last line without its newline is cut off if it is not a
        whole row (the write was killed) and ended with a newline if it is."""
        self.path.parent.mkdir(parents=True, exist_ok=True)
        new = not os.path.lexists(self.path)
        if not new:
            from ..inputs import check_regular_file

            check_regular_file(self.path, "results")  # a FIFO would block the append
        fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_APPEND, 0o644)
        try:
            data = self.path.read_bytes()
            if data and not data.endswith(b"\n"):
                cut = data.rfind(b"\n") + 1
                try:
                    whole = isinstance(json.loads(data[cut:]), dict)
                except ValueError:
                    whole = False
                if whole:
                    os.write(fd, b"\n")
                else:
                    log.warning("%s: cutting off a truncated last line", self.path)
                    os.ftruncate(fd, cut)
                os.fsync(fd)
        except BaseException:
            os.close(fd)
            raise
        self._fd = fd
        if new:
            dir_fd = os.open(self.path.parent, os.O_RDONLY)
            try:
                os.fsync(dir_fd)
            finally:
                os.close(dir_fd)

    def append(self, row: dict[str, Any]) -> None:
        """Write ``row`` as one line with one ``os.write`` and ``fsync`` it."""
        if self._fd is None:
            self.open_for_append()
        assert self._fd is not None
        line = to_json_line(row)
        written = os.write(self._fd, line)
        while written < len(line):  # only on a full disk or a signal; still one row
            written += os.write(self._fd, line[written:])
        os.fsync(self._fd)

    def rewrite(self, rows: list[dict[str, Any]]) -> None:
        """Replace the file by ``rows`` (temp file, fsync, rename)."""
        self.close()
        tmp = self.path.with_name(self.path.name + ".tmp")
        with open(tmp, "wb") as fh:
            for row in rows:
                fh.write(to_json_line(row))
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, self.path)

    def drop_failed(self, rows: dict[str, dict[str, Any]], keys: set[str],
                    ) -> tuple[dict[str, dict[str, Any]], set[str]]:
        """``--retry-failed``: take the rows of ``keys`` whose status is not ``ok`` out of
        the file (rewritten) and of ``rows`` (``load()``'s); returns the rows left and the
        keys taken out."""
        retry = {k for k, r in rows.items() if k in keys and r.get("status") != "ok"}
        if retry:
            self.rewrite([r for k, r in rows.items() if k not in retry])
            rows = {k: r for k, r in rows.items() if k not in retry}
        return rows, retry

    def close(self) -> None:
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None

    def __enter__(self) -> ResultsFile:
        self.open_for_append()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
