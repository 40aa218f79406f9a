"""Headless rendering of episodes: frames drawn with OpenCV, H.264 MP4 through PyAV.

Importing this package imports ``cv2`` (and :class:`VideoWriter` imports ``av`` when it opens
a file); the simulation never imports it, so runs without ``--video`` do not need either.

>>> from warerover_phys.render import load_trajectory, render_video, Style  # doctest: +SKIP
>>> rec = load_trajectory("runs/demo/trajectories.npz")                      # doctest: +SKIP
>>> render_video(rec, "videos/demo.mp4", fps=30, style=Style(size=(1280, 720)))  # doctest: +SKIP
"""

from .frame import PALETTE, Geometry, Scene, Snapshot, Style, draw_frame, frame_geometry, status_of
from .plans import PathSet, PlanIndex, PlanProgress
from .trajectory import (
    Recording,
    ghost_poses,
    grid_trajectory,
    load_trajectory,
    recording_from_episode,
    recording_with_ghosts,
)
from .video import (
    SIZES,
    FrameRate,
    VideoWriter,
    auto_speed,
    draw_frames,
    frame_times,
    parse_size,
    render_video,
    write_png,
)

__all__ = ["PALETTE", "Geometry", "Scene", "Snapshot", "Style", "draw_frame", "frame_geometry",
           "status_of",
           "Recording", "grid_trajectory", "load_trajectory", "recording_from_episode",
           "ghost_poses", "recording_with_ghosts",
           "SIZES", "VideoWriter", "auto_speed", "frame_times", "parse_size", "render_video",
           "write_png", "draw_frames", "FrameRate", "PathSet", "PlanIndex", "PlanProgress"]
