"""Writing frames: H.264 MP4 through PyAV, still PNGs, and whole recordings to video.

:class:`VideoWriter` takes BGR frames of one size. With PyAV (``av``) it writes H.264
(``libx264``, ``yuv420p``, ``movflags=+faststart``: plays in browsers, starts before it has
fully loaded). Without PyAV it falls back to OpenCV's ``mp4v`` (MPEG-4 Part 2) with a warning:
that file plays in VLC/ffmpeg but not in Chrome or Firefox. With ``threaded=True`` the colour
conversion (OpenCV, BGR to I420) and the encoding run in a thread of their own, beside the
drawing (both release the GIL): a bounded queue hands the frames over.

:func:`render_video` samples a :class:`~.trajectory.Recording` at the video's own frame times:
frame ``k`` shows simulated time ``start + k * speed / fps``, so the frame rate and playback
speed are independent of the physics step and of the recording rate. With ``workers > 1``
the frames are cut into that many runs, each drawn and encoded by a process of its own, and
the pieces are joined into one H.264 file without re-encoding (:mod:`.parallel`).

Videos and images are written to a temporary file beside the target and renamed into place
when complete: a killed or failed render leaves an existing file as it was.
"""

from __future__ import annotations

import logging
import math
import queue
import threading
import time
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import cv2
import numpy as np

from ..util.atomic import replacing
from .frame import Style, draw_frame

if TYPE_CHECKING:
    from .trajectory import Recording

__all__ = ["VideoWriter", "render_video", "write_png", "frame_times", "frame_count",
           "MAX_FRAMES", "auto_speed", "parse_size", "SIZES", "draw_frames", "FrameRate"]

log = logging.getLogger(__name__)

SIZES = {"720p": (1280, 720), "1080p": (1920, 1080), "480p": (854, 480), "4k": (3840, 2160)}
MAX_VIDEO_S = 60.0
"""Default playback speed aims at videos no longer than this (seconds)."""
MAX_FRAMES = 200_000
"""Most frames one video may have (about 1.9 hours at 30 fps); more is refused before the
first frame (``--speed 1e-9`` asked for terabytes)."""


def parse_size(text: str) -> tuple[int, int]:
    """``720p``, ``1080p``, ``480p``, ``4k`` or ``WxH`` (pixels) -> (width, height)."""
    key = text.strip().lower()
    if key in SIZES:
        return SIZES[key]
    parts = key.split("x")
    if len(parts) == 2 and all(p.strip().isdigit() for p in parts):
        w, h = int(parts[0]), int(parts[1])
        if 16 <= w <= 8192 and 16 <= h <= 8192:
            return w, h
    raise ValueError(f"size must be 720p, 1080p, 480p, 4k or WxH with 16..8192 pixels a side "
                     f"(got {text!r})")


class VideoWriter:
    """Write BGR frames to an MP4 file; use as a context manager.

    ``codec="h264"`` (default) needs PyAV and falls back to ``mp4v`` with a warning when it is
    missing; ``codec="mp4v"`` always uses OpenCV. Odd frame sizes are padded by one pixel
    (yuv420p needs even sides). ``preset`` and ``crf`` are libx264's speed/quality knobs.
    """

    def __init__(self, path: str | Path, fps: float, size: tuple[int, int], *,
                 codec: str = "h264", preset: str = "superfast", crf: int = 23,
                 threaded: bool = False, threads: int = 0) -> None:
        if fps <= 0:
            raise ValueError(f"fps must be positive (got {fps})")
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.size = (int(size[0]), int(size[1]))
        self.enc_size = (self.size[0] + self.size[0] % 2, self.size[1] + self.size[1] % 2)
        self.fps = fps
        self.frames = 0
        self._av = None
        self._cv = None
        self._queue: queue.Queue | None = None
        self._thread: threading.Thread | None = None
        self._error: BaseException | None = None
        self.threads = int(threads)
        """libx264 threads (0: its own choice)."""
        if codec == "h264":
            try:
                import av
            except ImportError:
                warnings.warn("PyAV (av) is not installed: writing mp4v MPEG-4, which browsers "
                              "do not play; pip install av for H.264", stacklevel=2)
                codec = "mp4v"
            else:
                self._open_av(av, preset, crf)
        if threaded:
            self._queue = queue.Queue(maxsize=8)
            self._thread = threading.Thread(target=self._drain, name="video-encoder",
                                            daemon=True)
            self._thread.start()
        if codec == "mp4v":
            self.codec = "mp4v"
            self._cv = cv2.VideoWriter(str(self.path), cv2.VideoWriter_fourcc(*"mp4v"),
                                       float(fps), self.enc_size)
            if not self._cv.isOpened():
                raise OSError(f"{self.path}: OpenCV cannot open an mp4v writer")
        elif codec != "h264":
            raise ValueError(f"codec must be h264 or mp4v (got {codec!r})")

    def _open_av(self, av, preset: str, crf: int) -> None:
        from fractions import Fraction

        self.codec = "h264"
        self._container = av.open(str(self.path), mode="w", format="mp4",
                                  options={"movflags": "+faststart"})
        rate = Fraction(self.fps).limit_denominator(1001)
        stream = self._container.add_stream("libx264", rate=rate)
        stream.width, stream.height = self.enc_size
        stream.pix_fmt = "yuv420p"
        stream.options = {"preset": preset, "crf": str(crf),
                          **({"threads": str(self.threads)} if self.threads > 0 else {})}
        self._stream = stream
        self._av = av

    def write(self, frame: np.ndarray) -> None:
        """Append one ``(height, width, 3)`` BGR uint8 frame of the writer's size (threaded:
        the writer keeps it; do not change it afterwards)."""
        h, w = frame.shape[:2]
        if (w, h) != self.size or frame.ndim != 3 or frame.dtype != np.uint8:
            raise ValueError(f"frame must be {self.size[1]}x{self.size[0]}x3 uint8 "
                             f"(got {frame.shape} {frame.dtype})")
        if self._queue is None:
            self._encode(frame)
            return
        while True:                       # wait for room, but not on a dead encoder
            if self._error is not None:
                raise OSError(f"{self.path}: encoding failed ({self._error})")
            try:
                self._queue.put(frame, timeout=0.5)
                return
            except queue.Full:
                continue

    def _encode(self, frame: np.ndarray) -> None:
        h, w = frame.shape[:2]
        if self.enc_size != self.size:
            frame = cv2.copyMakeBorder(frame, 0, self.enc_size[1] - h, 0, self.enc_size[0] - w,
                                       cv2.BORDER_REPLICATE)
        if self._av is not None:
            # OpenCV's conversion (BT.601, limited range, as libswscale's) is quicker than
            # PyAV's and lets go of the GIL.
            yuv = cv2.cvtColor(frame, cv2.COLOR_BGR2YUV_I420)
            vf = self._av.VideoFrame.from_ndarray(yuv, format="yuv420p")
            for packet in self._stream.encode(vf):
                self._container.mux(packet)
        else:
            self._cv.write(frame)
        self.frames += 1

    def _drain(self) -> None:
        """The encoder thread: encode queued frames until the None that ends them."""
        while True:
            frame = self._queue.get()
            if frame is None:
                return
            if self._error is None:
                try:
                    self._encode(frame)
                except BaseException as err:  # noqa: BLE001 - re-raised in write/close
                    self._error = err

    def close(self) -> None:
        if self._thread is not None:
            self._queue.put(None)
            self._thread.join()
            self._thread = None
            if self._error is not None:
                self._abandon()
                raise OSError(f"{self.path}: encoding failed ({self._error})")
        if self._av is not None:
            for packet in self._stream.encode():
                self._container.mux(packet)
            self._container.close()
            self._av = None
        elif self._cv is not None:
            self._cv.release()
            self._cv = None

    def _abandon(self) -> None:
        """Close the file without flushing (after a failure)."""
        if self._av is not None:
            try:
                self._container.close()
            except Exception:  # noqa: BLE001 - the first error is the one reported
                pass
            self._av = None

    def __enter__(self) -> VideoWriter:
        return self

    def __exit__(self, exc_type, *exc) -> None:
        if exc_type is None:
            self.close()
            return
        if self._thread is not None:           # an error while drawing: stop the encoder
            self._error = self._error or RuntimeError("stopped")
            self._queue.put(None)
            self._thread.join()
            self._thread = None
        self._abandon()
        if self._cv is not None:
            self._cv.release()
            self._cv = None


def auto_speed(duration_s: float) -> float:
    """Playback speed (simulated s per video s): real time, or faster so the video lasts at
    most ``MAX_VIDEO_S``; rounded up to 1, 2 or 5 times a power of ten."""
    need = max(1.0, duration_s / MAX_VIDEO_S)
    mag = 10 ** math.floor(math.log10(need))
    for m in (1, 2, 5, 10):
        if m * mag >= need - 1e-9:
            return float(m * mag)
    return float(10 * mag)


def frame_count(duration_s: float, fps: float, speed: float) -> int:
    """Frames of a video of ``duration_s`` simulated seconds (no array is made)."""
    return int(math.floor(duration_s * fps / speed + 1e-9)) + 1


def frame_times(start_s: float, end_s: float, fps: float, speed: float,
                max_frames: int | None = None) -> np.ndarray:
    """Simulated times of the video frames: ``start + k * speed / fps`` up to ``end``."""
    if fps <= 0 or speed <= 0:
        raise ValueError(f"fps and speed must be positive (got fps={fps}, speed={speed})")
    n = frame_count(end_s - start_s, fps, speed)
    if max_frames is not None:
        n = min(n, max_frames)
    elif n > MAX_FRAMES:
        raise ValueError(f"{end_s - start_s:g} s at {speed:g}x and {fps:g} fps would take "
                         f"{n:,} frames (at most {MAX_FRAMES:,}): raise --speed or lower --fps")
    return start_s + np.arange(max(n, 1)) * (speed / fps)


def draw_frames(recording: Recording, times: np.ndarray, style: Style) -> Iterator[np.ndarray]:
    """The frames of ``recording`` at simulated ``times`` (seconds), drawn in ``style``."""
    horizon = style.path_ticks if style.show_paths and recording.plans else 0
    for t in times:
        yield draw_frame(recording.at(float(t), horizon, ghosts=style.ghosts), style)


class FrameRate:
    """Frames per second and time left of a render, for a progress line:
    ``FrameRate()(done, total)`` -> ``"41.7 fps, ETA 0:12"``."""

    def __init__(self) -> None:
        self.t0 = time.perf_counter()

    def __call__(self, done: int, total: int) -> str:
        dt = time.perf_counter() - self.t0
        if done <= 0 or dt <= 0:
            return ""
        rate = done / dt
        left = int(round((total - done) / rate))
        return f"{rate:.1f} fps, ETA {left // 60}:{left % 60:02d}"


def render_video(recording: Recording, path: str | Path, *, fps: float = 30.0,
                 speed: float | None = None, style: Style | None = None,
                 start_s: float | None = None, end_s: float | None = None,
                 max_frames: int | None = None, codec: str = "h264",
                 preset: str = "superfast", workers: int = 1,
                 progress: Callable[[int, int], None] | None = None) -> dict:
    """Render ``recording`` to an MP4 at ``fps`` frames per video second, ``speed`` simulated
    seconds per video second (None: :func:`auto_speed`). The encoder runs in a thread of its
    own; ``workers > 1`` (H.264 only) draws and encodes that many runs of frames in
    processes of their own and joins them without re-encoding. ``progress(frames_done,
    frames)`` is called as frames are done. Returns what was written."""
    style = style or Style()
    start = recording.start_s if start_s is None else max(start_s, recording.start_s)
    end = recording.end_s if end_s is None else min(end_s, recording.end_s)
    if speed is None:
        speed = auto_speed(end - start)
    if workers < 1:
        raise ValueError(f"workers must be at least 1 (got {workers})")
    times = frame_times(start, end, fps, speed, max_frames)
    from .parallel import can_fork, render_parallel

    with replacing(path) as tmp:    # ``path`` is replaced only once the video is whole
        if workers > 1 and codec == "h264" and len(times) >= 2 * workers and can_fork() \
                and _has_av():
            frames, used = render_parallel(recording, tmp, times, fps, style, preset, workers,
                                           progress, draw=draw_frames,
                                           writer_type=VideoWriter), "h264"
        else:
            frames, used = _render_serial(recording, tmp, times, fps, style, codec, preset,
                                          progress)
            workers = 1
    log.info("wrote %s: %d frames, %s", path, frames, used)
    return {"path": str(path), "frames": int(frames), "fps": fps, "speed": speed,
            "codec": used, "size": list(style.size), "start_s": float(times[0]),
            "end_s": float(times[-1]), "workers": workers}


def _has_av() -> bool:
    try:
        import av  # noqa: F401
    except ImportError:
        return False
    return True


def _render_serial(recording: Recording, path: Path, times: np.ndarray, fps: float,
                   style: Style, codec: str, preset: str,
                   progress: Callable[[int, int], None] | None) -> tuple[int, str]:
    """Draw here, encode in the writer's thread; (frames written, codec)."""
    with VideoWriter(path, fps, style.size, codec=codec, preset=preset,
                     threaded=True) as writer:
        for i, img in enumerate(draw_frames(recording, times, style)):
            writer.write(img)
            if progress is not None:
                progress(i + 1, len(times))
    return writer.frames, writer.codec


def write_png(recording: Recording, path: str | Path, tick: float,
              style: Style | None = None) -> Path:
    """Write the frame at ``tick`` (``tick * tick_s`` simulated seconds) as a PNG."""
    style = style or Style()
    if not 0 <= tick <= recording.end_s / recording.tick_s + 1e-9:
        raise ValueError(f"tick {tick} is outside the recording (0..{recording.ticks})")
    img = next(draw_frames(recording, np.array([tick * recording.tick_s]), style))
    out = Path(path)
    with replacing(out) as tmp:
        try:
            ok = cv2.imwrite(str(tmp), img)
        except cv2.error:
            ok = False
        if not ok:
            raise OSError("cannot write the image (unsupported extension or unwritable "
                          "folder)")
    return out

