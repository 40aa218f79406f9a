"""Faults: safety corridors around failed AGVs and the checks that keep others out."""

from __future__ import annotations

from .checker import CHECKERS, make_checker
from .corridors import Corridor, cover_mask, plan_corridor
from .intrusion import (
    Intrusion,
    IntrusionChecker,
    agv_boxes,
    box_rect_signed_distance,
    intrusions_shapely,
)

__all__ = ["Corridor", "plan_corridor", "cover_mask", "Intrusion", "IntrusionChecker",
           "agv_boxes", "box_rect_signed_distance", "intrusions_shapely", "CHECKERS",
           "make_checker"]
