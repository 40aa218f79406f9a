"""Rendering one video with several processes, joined without re-encoding.

:func:`render_parallel` cuts the frame times into ``workers`` runs of consecutive frames.
Each run is drawn and encoded (H.264, the same settings) by a forked process of its own into
a piece of its own; the pieces are then joined into one MP4 by copying their packets
(:func:`join_h264`: the time stamps are shifted, nothing is decoded or encoded again). Each
piece starts with a key frame, and all were made with the same encoder settings, so the
joined stream is one valid H.264 stream (the pieces' decoder set-ups are compared first).

Processes are forked (``can_fork``): they share the recording with the parent without
copying or pickling it. OpenCV's thread pool is shut (one thread) in the parent before the
fork and set back after: a pool's threads do not exist in a forked child, and touching the
pool there (even to shut it) can wait forever on them. The workers draw, encode and count
frames; nothing the parent's other threads (a progress bar's) hold is needed there. Each reports its frames done through shared memory; the parent
calls ``progress`` as they come in. A piece that fails stops the render with its error.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import shutil
import sys
import tempfile
import time
import traceback
from collections.abc import Callable
from fractions import Fraction
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from .frame import Style
    from .trajectory import Recording

__all__ = ["can_fork", "render_parallel", "join_h264", "split"]


def can_fork() -> bool:
    """Whether worker processes can be forked here (POSIX, not macOS' default)."""
    return sys.platform.startswith("linux") and "fork" in mp.get_all_start_methods()


def split(count: int, parts: int) -> list[tuple[int, int]]:
    """``count`` frames cut into ``parts`` runs ``[lo, hi)`` of nearly equal length.

    >>> split(10, 3)
    [(0, 4), (4, 7), (7, 10)]
    """
    edges = np.linspace(0, count, parts + 1).round().astype(int)
    return [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:], strict=True) if b > a]


def _piece(recording: Recording, path: str, times: np.ndarray, fps: float, style: Style,
           preset: str, threads: int, done, slot: int, errors, draw: Callable,
           writer_type: type) -> None:
    """A worker: draw and encode ``times`` into ``path``; count frames in ``done[slot]``."""
    try:
        with writer_type(path, fps, style.size, preset=preset, threaded=True,
                         threads=threads) as writer:
            for img in draw(recording, times, style):
                writer.write(img)
                done[slot] += 1
        if writer.codec != "h264":
            raise OSError("PyAV is missing in the worker")
    except BaseException:  # noqa: BLE001 - reported to the parent, which raises
        errors.put(traceback.format_exc(limit=4))
        os._exit(1)
    os._exit(0)


def render_parallel(recording: Recording, path: Path, times: np.ndarray, fps: float,
                    style: Style, preset: str, workers: int,
                    progress: Callable[[int, int], None] | None, *, draw: Callable,
                    writer_type: type) -> int:
    """Render ``times`` to ``path`` (H.264 MP4) with ``workers`` processes; frames written.
    ``draw(recording, times, style)`` yields the frames (``video.draw_frames``),
    ``writer_type`` writes them (``video.VideoWriter``)."""
    import cv2

    ctx = mp.get_context("fork")
    runs = split(len(times), workers)
    threads = max(1, (os.cpu_count() or 1) // len(runs))
    folder = Path(tempfile.mkdtemp(prefix=".render-", dir=Path(path).parent))
    done = ctx.Array("q", len(runs), lock=False)
    errors = ctx.SimpleQueue()
    pool = cv2.getNumThreads()
    procs = []
    try:
        cv2.setNumThreads(1)
        # Draw one frame first, so that every worker inherits the drawn floor and the
        # loaded compiled kernels instead of making them again.
        next(draw(recording, times[:1], style))
        for k, (lo, hi) in enumerate(runs):
            p = ctx.Process(target=_piece, name=f"render-{k}", daemon=True, args=(
                recording, str(folder / f"{k}.mp4"), times[lo:hi], fps, style, preset,
                threads, done, k, errors, draw, writer_type))
            p.start()
            procs.append(p)
        _wait(procs, done, len(times), errors, progress)
        join_h264([folder / f"{k}.mp4" for k in range(len(runs))], path, fps)
    finally:
        for p in procs:
            if p.is_alive():
                p.terminate()
            p.join()
        shutil.rmtree(folder, ignore_errors=True)
        cv2.setNumThreads(pool)
    return len(times)


def _wait(procs: list, done, total: int, errors,
          progress: Callable[[int, int], None] | None) -> None:
    """Until every worker has ended: report progress; raise the first failure."""
    last = -1
    while True:
        alive = [p for p in procs if p.is_alive()]
        count = int(sum(done))
        if progress is not None and count != last:
            progress(count, total)
            last = count
        failed = [p for p in procs if not p.is_alive() and p.exitcode not in (0, None)]
        if failed:
            why = errors.get() if not errors.empty() else f"exit code {failed[0].exitcode}"
            raise OSError(f"a render worker failed: {why.strip().splitlines()[-1]}")
        if not alive:
            return
        time.sleep(0.05)


def join_h264(pieces: list[Path], out: Path, fps: float) -> None:
    """Join H.264 MP4 ``pieces`` (same size and settings, each from a key frame) into one
    MP4 at ``out`` by copying packets, their time stamps shifted piece after piece."""
    import av

    rate = Fraction(fps).limit_denominator(1001)
    with av.open(str(pieces[0])) as first:
        template = first.streams.video[0]
        extradata = template.codec_context.extradata
        with av.open(str(out), mode="w", format="mp4",
                     options={"movflags": "+faststart"}) as dst:
            stream = dst.add_stream_from_template(template)
            offset_s = Fraction(0)
            for piece in pieces:
                with av.open(str(piece)) as src:
                    s = src.streams.video[0]
                    if s.codec_context.extradata != extradata:
                        raise OSError(f"{piece}: encoder set-up differs; cannot join")
                    tb = s.time_base
                    shift = int(round(offset_s / tb))
                    frames = 0
                    for packet in src.demux(s):
                        if packet.dts is None:      # the demuxer's end-of-stream marker
                            continue
                        packet.pts += shift
                        packet.dts += shift
                        packet.stream = stream
                        dst.mux(packet)
                        frames += 1
                    offset_s += frames / rate
