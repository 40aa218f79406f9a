"""Outputs that are whole or absent: single files through a temporary name and a rename, and
a run's output files as one set.

- :func:`replacing` gives a temporary path beside the target (same folder, same suffix, so
  writers that pick a format by extension still work); the target is replaced only when the
  block ends without an error. A killed or failed writer leaves the old file untouched.
- :func:`write_set` writes a run's files into a fresh folder beside the output folder, with
  a ``manifest.json`` naming every file with its size and SHA-256 and the run id, and then
  puts that folder in place of the output folder in one step (Linux ``renameat2`` with
  ``RENAME_EXCHANGE``; elsewhere two renames, recovered from on the next write). Files in
  the old folder that are not run outputs (a video, notes) are carried over as hard links.
  A folder that is more than a run folder (subfolders, many files, the working folder) is
  written in place instead, behind a manifest marked incomplete until the set is whole.
- :func:`check_set` is what readers call: a folder whose files are not the ones its manifest
  lists (a mixed or half-written set) is refused with a :class:`~.errors.WareroverError`.

>>> import tempfile, pathlib
>>> d = pathlib.Path(tempfile.mkdtemp()) / "run"
>>> files = write_set(d, {"a.txt": lambda p: p.write_text("1")})
>>> sorted(p.name for p in d.iterdir()), check_set(d)["files"]["a.txt"]["bytes"]
(['a.txt', 'manifest.json'], 1)
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import datetime as _dt
import hashlib
import itertools
import json
import os
import shutil
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from ..errors import WareroverError

__all__ = ["replacing", "write_text", "write_set", "check_set", "MANIFEST", "RUN_FILES"]

MANIFEST = "manifest.json"
RUN_FILES = ("metrics.json", "events.jsonl", "paths.json", "trajectories.npz")
"""Files a run writes; one of these in a folder but not in its manifest is a mixed set."""


def _tmp_name(path: Path, tag: str = "tmp") -> Path:
    return path.with_name(f".{path.stem}.{tag}-{os.getpid()}-{uuid.uuid4().hex[:8]}"
                          f"{path.suffix}")


@contextlib.contextmanager
def replacing(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; rename it onto ``path`` when the block ends
    without an error, remove it otherwise."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = _tmp_name(path)
    try:
        try:
            yield tmp
        except OSError as err:     # name the target, not the temporary file (or nothing)
            raise OSError(err.errno, err.strerror or str(err), str(path)) from None
        if not tmp.exists():
            raise OSError(f"{path}: nothing was written")
        os.replace(tmp, path)
        _remove_stale(path)
    finally:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _remove_stale(path: Path) -> None:
    """Remove temporary files of ``path`` left by writers that were killed (dead pids)."""
    prefix = f".{path.stem}.tmp-"
    for entry in path.parent.iterdir():
        name = entry.name
        if not (name.startswith(prefix) and name.endswith(path.suffix)):
            continue
        pid = name[len(prefix):].split("-", 1)[0]
        if pid.isdigit() and not _alive(int(pid)):
            with contextlib.suppress(OSError):
                entry.unlink()


def write_text(path: str | Path, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` through a temporary file and a rename."""
    with replacing(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def _digest(path: Path) -> str:
    h = hashlib.sha256()
    with path.open("rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


_RENAME_EXCHANGE = 2
_AT_FDCWD = -100


def _exchange(a: Path, b: Path) -> bool:
    """Swap two paths atomically (Linux ``renameat2``); False where that is not possible."""
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        fn = libc.renameat2
    except (OSError, AttributeError):
        return False
    fn.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    rc = fn(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE)
    return rc == 0


def _carry_over(old: Path, new: Path, ours: set[str]) -> None:
    """Hard-link (or copy) what ``old`` holds that a run does not write into ``new``."""
    for entry in old.iterdir():
        if entry.name in ours or entry.name == MANIFEST:
            continue
        target = new / entry.name
        if entry.is_dir() and not entry.is_symlink():
            shutil.copytree(entry, target, symlinks=True, copy_function=_link_or_copy)
        else:
            _link_or_copy(entry, target)


def _link_or_copy(src: Any, dst: Any) -> None:
    if os.path.islink(src):
        os.symlink(os.readlink(src), dst)
        return
    try:
        os.link(src, dst)
    except OSError:
        shutil.copy2(src, dst)


def _recover(out: Path) -> None:
    """Finish what a killed :func:`write_set` left: a missing folder with a complete new set
    beside it is put in place; leftovers are removed."""
    parent = out.parent
    if not parent.is_dir():
        return
    for entry in sorted(parent.iterdir(), key=lambda e: ".new-" not in e.name):
        if not entry.name.startswith(f".{out.name}.") or not entry.is_dir():
            continue
        if ".new-" in entry.name and not out.exists() and (entry / MANIFEST).is_file():
            os.rename(entry, out)
        elif ".old-" in entry.name and not out.exists():
            os.rename(entry, out)
        else:
            shutil.rmtree(entry, ignore_errors=True)


SWAP_MAX_ENTRIES = 64
"""A folder with more entries than this is written in place, not swapped (see
:func:`write_set`)."""


def _swappable(out: Path) -> bool:
    """Whether the set may replace ``out`` whole: it is missing, or holds only a few regular
    files (a run folder, maybe with a video beside) and is not the working folder or above it.
    """
    if not out.exists():
        return True
    if out.is_symlink() or Path.cwd().resolve().is_relative_to(out.resolve()):
        return False
    entries = list(itertools.islice(out.iterdir(), SWAP_MAX_ENTRIES + 1))
    return len(entries) <= SWAP_MAX_ENTRIES and all(
        e.is_file() and not e.is_symlink() for e in entries)


def write_set(out_dir: str | Path, writers: dict[str, Callable[[Path], Any]],
              meta: dict[str, Any] | None = None) -> dict[str, Path]:
    """Write files as one set: ``writers`` maps a file name to a function that writes that
    file at the path it is given. Returns name -> final path.

    A missing folder, or one holding only a few regular files, is replaced whole (a new
    folder swapped in; its other files carried over as hard links). Any other folder (one
    with subfolders, the working folder, ``.``) is written in place: first a manifest marked
    incomplete (readers refuse the folder from then on), then every file through a
    temporary file and a rename, then the complete manifest.
    """
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise WareroverError(f"{out}: output folder is a file")
    target = Path(os.path.abspath(out))
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise WareroverError(f"{out}: cannot write the output folder here "
                             f"({err.strerror or err})") from None
    _recover(target)
    run_id = uuid.uuid4().hex
    base = {"run_id": run_id, **(meta or {})}
    if _swappable(target):
        _swap_in(target, writers, base, out)
    else:
        _write_in_place(target, writers, base)
    return {name: out / name for name in writers}


def _manifest(base: dict[str, Any], files: dict[str, Any], complete: bool) -> str:
    data = {**base, "created": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
            "files": files, "complete": complete}
    return json.dumps(data, indent=2, sort_keys=True) + "\n"


def _write_files(folder: Path, writers: dict[str, Callable[[Path], Any]],
                 atomic: bool) -> dict[str, Any]:
    files: dict[str, Any] = {}
    for name, write in writers.items():
        if atomic:
            with replacing(folder / name) as tmp:
                write(tmp)
        else:
            write(folder / name)
        files[name] = {"bytes": (folder / name).stat().st_size,
                       "sha256": _digest(folder / name)}
    return files


def _swap_in(out: Path, writers: dict[str, Callable[[Path], Any]], base: dict[str, Any],
             shown: Path) -> None:
    new = out.with_name(f".{out.name}.new-{base['run_id'][:12]}")
    try:
        new.mkdir()
    except OSError as err:
        raise WareroverError(f"{shown}: cannot write the output folder here "
                             f"({err.strerror or err})") from None
    try:
        files = _write_files(new, writers, atomic=False)
        if out.is_dir():
            _carry_over(out, new, set(writers) | set(RUN_FILES))
        (new / MANIFEST).write_text(_manifest(base, files, True), encoding="utf-8")
        _fsync_dir(new)
        if not out.exists():
            os.rename(new, out)
        elif _exchange(new, out):
            shutil.rmtree(new, ignore_errors=True)       # ``new`` now holds the old folder
        else:
            old = out.with_name(f".{out.name}.old-{base['run_id'][:12]}")
            os.rename(out, old)
            os.rename(new, out)
            shutil.rmtree(old, ignore_errors=True)
        _fsync_dir(out.parent)
    except BaseException:
        shutil.rmtree(new, ignore_errors=True)
        raise


def _write_in_place(out: Path, writers: dict[str, Callable[[Path], Any]],
                    base: dict[str, Any]) -> None:
    write_text(out / MANIFEST, _manifest(base, {}, False))   # readers refuse from here on
    for name in RUN_FILES:
        if name not in writers:
            with contextlib.suppress(FileNotFoundError):
                (out / name).unlink()                        # a file of an older set
    files = _write_files(out, writers, atomic=True)
    write_text(out / MANIFEST, _manifest(base, files, True))


def _fsync_dir(path: Path) -> None:
    with contextlib.suppress(OSError):
        for entry in path.iterdir() if path != path.parent else ():
            if entry.is_file():
                fd = os.open(entry, os.O_RDONLY)
                try:
                    os.fsync(fd)
                finally:
                    os.close(fd)
        fd = os.open(path, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def check_set(folder: str | Path) -> dict[str, Any] | None:
    """The manifest of a run folder after checking that its files are the ones it lists
    (sizes and SHA-256); None for a folder written before manifests existed. Raises a
    :class:`WareroverError` naming the folder and the file for a mixed or incomplete set."""
    folder = Path(folder)
    path = folder / MANIFEST
    if not path.is_file():
        return None
    try:
        manifest = json.loads(path.read_text(encoding="utf-8"))
        files = manifest["files"]
        run_id = str(manifest["run_id"])
        if not isinstance(files, dict):
            raise TypeError
    except (ValueError, KeyError, TypeError, UnicodeDecodeError):
        raise WareroverError(f"{path}: not a run manifest (corrupt or truncated)") from None
    if manifest.get("complete") is False:
        raise WareroverError(f"{folder}: incomplete run outputs: run {run_id[:12]} was "
                             "interrupted while writing them; run the episode again")
    for name, info in files.items():
        f = folder / name
        if not f.is_file():
            raise WareroverError(f"{folder}: incomplete run outputs: {name} is missing "
                                 f"(run {run_id[:12]} wrote it); run the episode again")
        try:
            ok = f.stat().st_size == info["bytes"] and _digest(f) == info["sha256"]
        except (KeyError, TypeError):
            raise WareroverError(f"{path}: not a run manifest (bad entry for {name})") from None
        if not ok:
            raise WareroverError(f"{folder}: mixed run outputs: {name} is not the file run "
                                 f"{run_id[:12]} wrote; run the episode again")
    for name in RUN_FILES:
        if name not in files and (folder / name).exists():
            raise WareroverError(f"{folder}: mixed run outputs: {name} is not from run "
                                 f"{run_id[:12]} (its manifest does not list it)")
    return manifest
