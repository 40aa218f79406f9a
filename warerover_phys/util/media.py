"""Checks of video and image output paths, done before any work (no OpenCV imported).

>>> check_media_path("videos/a.mp4", "--out")
>>> check_media_path("fig.gif", "--out", still=True)
Traceback (most recent call last):
...
warerover_phys.errors.WareroverError: --out: a still frame is written as .png, .jpg or .jpeg (got 'fig.gif')
"""

from __future__ import annotations

from pathlib import Path

from ..errors import WareroverError

__all__ = ["check_media_path", "VIDEO_SUFFIXES", "IMAGE_SUFFIXES"]

VIDEO_SUFFIXES = (".mp4", ".m4v")
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")


def check_media_path(path: str | Path, option: str, *, still: bool = False) -> None:
    """Raise a :class:`WareroverError` naming ``option`` when ``path`` cannot take a video
    (MP4) or, with ``still``, an image: a wrong extension, or an existing folder."""
    p = Path(path)
    allowed = IMAGE_SUFFIXES if still else VIDEO_SUFFIXES
    if p.suffix.lower() not in allowed:
        what = "a still frame" if still else "a video"
        raise WareroverError(f"{option}: {what} is written as {', '.join(allowed[:-1])} or "
                             f"{allowed[-1]} (got {str(path)!r})")
    if p.is_dir():
        raise WareroverError(f"{option}: {str(path)!r} is a folder, not a file")
