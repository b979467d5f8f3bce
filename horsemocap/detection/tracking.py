"""Transitional: ``horsemocap.detection.tracking`` is now :mod:`~horsemocap.detection.thesis_chain`.

Import from ``horsemocap.detection`` (or ``horsemocap.detection.base`` for the
candidate rules) instead; this module goes when nothing imports it any more.
"""
from __future__ import annotations

from .base import GENERIC_AREA  # transitional (horsemocap/widgets/detection.py)

__all__ = ["GENERIC_AREA"]
