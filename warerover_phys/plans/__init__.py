"""MAPF plan files of the field (LaCAM, MAPF-LNS2 / EECBS, SMART, Robot Runners, paths.json),
read into and written from one in-memory :class:`Plan`."""

from ..errors import PlanFormatError
from .formats import (
    FORMATS,
    check_format,
    detect_format,
    format_plan,
    parse_plan,
    read_plan,
    write_plan,
)
from .model import HEADING_NAMES, HEADING_STEPS, Plan

__all__ = ["Plan", "PlanFormatError", "FORMATS", "HEADING_NAMES", "HEADING_STEPS",
           "detect_format", "parse_plan", "read_plan", "format_plan", "write_plan",
           "check_format"]
