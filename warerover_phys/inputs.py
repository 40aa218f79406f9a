"""What every command checks the same way before it works: input files, output paths, seeds.

- **Input files** (:func:`check_regular_file`, :func:`read_bytes`, :func:`read_text`):
  anything that is not a regular file is refused before it is opened (a FIFO would block
  the reader forever, ``/dev/zero`` never ends; ``stat`` gives 0 bytes for both), and at
  most the size limit + 1 byte is read, so a file that grows while it is read is refused
  too.
- **Output paths** (:func:`check_output_dir`, :func:`check_output_file`): checked before
  any work, without writing anything that stays: an existing path of the wrong kind, a
  path under a file, a place this process cannot create files in (tried with a temporary
  file, removed at once: permission bits alone do not tell, e.g. for root or read-only
  mounts).
- **Seeds** (:func:`check_seed`): one rule for every command, 0 .. 2**63 - 1 (what a
  scenario file's ``seed`` takes).

Every refusal is a :class:`~.errors.ScenarioError` (inputs: naming the file) or a
:class:`~.errors.WareroverError` (options), printed by the commands as one line.

>>> check_seed(7)
7
>>> check_seed(-1)
Traceback (most recent call last):
...
warerover_phys.errors.WareroverError: --seed: expected a whole number from 0 to 9223372036854775807 (got -1)
>>> describe("/dev/zero")
'a character device'
"""

from __future__ import annotations

import contextlib
import os
import stat
import tempfile
from pathlib import Path

from .errors import ScenarioError, WareroverError

__all__ = ["MAX_SEED", "check_seed", "check_regular_file", "read_bytes", "read_text",
           "describe", "check_output_dir", "check_output_file", "DEFAULT_LIMIT"]

MAX_SEED = 2**63 - 1
"""Largest seed (numpy's ``SeedSequence`` takes any, a scenario file's ``seed`` this)."""
DEFAULT_LIMIT = 256 * 2**20
"""Largest input file read when the caller names no limit (256 MiB)."""

_KINDS = ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
          (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
          (stat.S_ISSOCK, "a socket"))


def check_seed(value: int, option: str = "--seed") -> int:
    """``value`` if it is a seed (a whole number 0 .. :data:`MAX_SEED`), else a
    :class:`WareroverError` naming ``option``."""
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= MAX_SEED:
        raise WareroverError(f"{option}: expected a whole number from 0 to {MAX_SEED} "
                             f"(got {value!r})")
    return value


def describe(path: str | Path) -> str:
    """What ``path`` is, in words (``"a regular file"``, ``"a FIFO (named pipe)"``, ...;
    ``"missing"`` if nothing is there)."""
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        return "missing"
    except OSError as err:
        return f"unreadable ({err.strerror or err})"
    for test, words in _KINDS:
        if test(mode):
            return words
    return "a regular file" if stat.S_ISREG(mode) else "not a regular file"


def check_regular_file(path: str | Path, what: str = "input") -> Path:
    """``path`` if it is a regular file (symlinks followed), else a :class:`ScenarioError`
    naming the file and what it is instead. Nothing is opened."""
    p = Path(path)
    kind = describe(p)
    if kind == "missing":
        raise ScenarioError(f"{what} file not found", file=str(p))
    if kind != "a regular file":
        raise ScenarioError(f"{what} is {kind}, not a regular file", file=str(p))
    return p


def read_bytes(path: str | Path, what: str = "input", limit: int = DEFAULT_LIMIT) -> bytes:
    """The bytes of the regular file ``path``, at most ``limit`` of them: a longer file is
    refused (only ``limit + 1`` bytes are ever read)."""
    p = check_regular_file(path, what)
    try:
        with open(p, "rb") as f:
            data = f.read(limit + 1)
    except OSError as err:
        raise ScenarioError(f"cannot read the {what} file: {err.strerror or err}",
                            file=str(p)) from None
    if len(data) > limit:
        raise ScenarioError(f"{what} file is larger than {_size(limit)}", file=str(p))
    return data


def read_text(path: str | Path, what: str = "input", limit: int = DEFAULT_LIMIT,
              encoding: str = "utf-8") -> str:
    """:func:`read_bytes` decoded (a file that is not ``encoding`` text is refused)."""
    data = read_bytes(path, what, limit)
    try:
        return data.decode(encoding)
    except UnicodeDecodeError as err:
        raise ScenarioError(f"{what} file is not {encoding.upper()} text (byte {err.start})",
                            file=str(path)) from None


MAX_NPZ_BYTES = 2 * 2**30
"""Largest sum of the arrays of an ``.npz`` read (2 GiB, as its headers declare them)."""


def load_npz(path: str | Path, what: str = "recording",
             limit: int = MAX_NPZ_BYTES) -> dict:
    """The arrays of the ``.npz`` archive ``path`` (a regular file), checked from the zip
    directory and each array's ``.npy`` header before anything is inflated: at most
    ``limit`` bytes in all (a zip bomb is refused unread), no object arrays, and each
    header's shape must be what its member holds (a header claiming 10**12 rows is
    refused). Every refusal is a :class:`ScenarioError` naming the file."""
    import zipfile

    import numpy as np

    p = check_regular_file(path, what)
    with open(p, "rb") as f:
        magic = f.read(6)
    if magic == b"\x93NUMPY":
        raise ScenarioError(f"{what} is a single .npy array, not an .npz archive", file=str(p))
    if not zipfile.is_zipfile(p):
        raise ScenarioError(f"{what} is not an .npz archive (a zip of numpy arrays)",
                            file=str(p))
    try:
        with zipfile.ZipFile(p) as z:
            infos = z.infolist()
            total = sum(i.file_size for i in infos)
            if total > limit:
                raise ScenarioError(f"{what}: its arrays would take {_size(total)} (more than "
                                    f"{_size(limit)})", file=str(p))
            for info in infos:
                _check_npy_header(z, info, what, str(p))
            out = {}
            for info in infos:
                with z.open(info) as member:
                    out[info.filename.removesuffix(".npy")] = np.lib.format.read_array(
                        member, allow_pickle=False)
            return out
    except ScenarioError:
        raise
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile, RuntimeError,
            NotImplementedError) as err:
        why = str(err).splitlines()[0] if str(err) else type(err).__name__
        raise ScenarioError(f"{what}: cannot read the .npz archive ({why})",
                            file=str(p)) from None


def _check_npy_header(z, info, what: str, file: str) -> None:
    """Refuse a member whose ``.npy`` header does not describe exactly what it holds."""
    import numpy as np

    fmt = np.lib.format
    if not info.filename.endswith(".npy"):
        raise ScenarioError(f"{what}: {info.filename!r} is not a .npy array", file=file)
    with z.open(info) as member:
        version = fmt.read_magic(member)
        reader = fmt.read_array_header_1_0 if version == (1, 0) else \
            fmt.read_array_header_2_0
        shape, _, dtype = reader(member, max_header_size=10_000)
        start = member.tell()
    if dtype.hasobject:
        raise ScenarioError(f"{what}: array {info.filename!r} holds Python objects",
                            file=file)
    count = 1
    for n in shape:
        count *= int(n)
    if start + count * dtype.itemsize != info.file_size:
        raise ScenarioError(f"{what}: array {info.filename!r}: its header says shape "
                            f"{tuple(shape)} ({_size(count * dtype.itemsize)}) but the "
                            f"archive holds {_size(info.file_size - start)}", file=file)


def _size(n: int) -> str:
    return f"{n / 2**20:g} MiB" if n >= 2**20 else f"{n} bytes"


def _nearest_existing(p: Path) -> Path:
    p = p.absolute()
    while not os.path.lexists(p) and p != p.parent:
        p = p.parent
    return p


def _check_creatable(p: Path, option: str) -> None:
    """Refuse ``p`` unless files can be created where it would go: its nearest existing
    ancestor must be a folder this process can write (tried with a temporary file)."""
    base = _nearest_existing(p.parent if p.parent != p else p)
    if not base.is_dir():
        raise WareroverError(f"{option}: cannot write {str(p)!r}: {str(base)!r} is "
                             f"{describe(base)}, not a folder")
    try:
        fd, name = tempfile.mkstemp(prefix=".warerover-probe-", dir=base)
    except OSError as err:
        raise WareroverError(f"{option}: cannot write {str(p)!r}: {err.strerror or err} "
                             f"({base})") from None
    os.close(fd)
    with contextlib.suppress(OSError):
        os.unlink(name)


def check_output_dir(path: str | Path, option: str = "--out") -> Path:
    """``path`` if a run's output folder can be written there: an existing folder, or a
    place where one can be created. Nothing is left behind."""
    p = Path(path)
    if os.path.lexists(p) and not p.is_dir():
        raise WareroverError(f"{option}: {str(p)!r} is {describe(p)}, not a folder")
    _check_creatable(p / "x", option)
    return p


def check_output_file(path: str | Path, option: str = "--out",
                      suffixes: tuple[str, ...] = ()) -> Path:
    """``path`` if a file can be written there (not a folder nor a device; ``suffixes``:
    the extensions allowed, if any). Nothing is left behind."""
    p = Path(path)
    if suffixes and p.suffix.lower() not in suffixes:
        raise WareroverError(f"{option}: expected a {' or '.join(suffixes)} file (got "
                             f"{str(p)!r})")
    if os.path.lexists(p) and not p.is_file():
        raise WareroverError(f"{option}: {str(p)!r} is {describe(p)}, not a file")
    _check_creatable(p, option)
    return p
