"""Transitional: the names other modules still import from ``horsemocap.detection.identification``.

The multi-view identification now lives in modules named by what they do:
:mod:`~horsemocap.detection.candidates` (2D candidates, light correction),
:mod:`~horsemocap.detection.matching` (across cameras),
:mod:`~horsemocap.detection.marker_model` (the static shot's rigid model),
:mod:`~horsemocap.detection.tracker3d` (the 3D tracker,
:func:`~horsemocap.detection.identify_markers`) and
:mod:`~horsemocap.detection.gaps`. Import from ``horsemocap.detection``
instead; this module goes when nothing imports it any more.
"""
from __future__ import annotations

from .base import AUTO_MIN_CIRCULARITY, GENERIC_AREA  # transitional (tests/test_speed.py)
from .candidates import candidate_area_range as _area_range  # transitional (horsemocap/pipeline.py)
from .candidates import candidate_min_circularity as _min_circ  # transitional (horsemocap/pipeline.py)
from .candidates import frame_candidates  # transitional (notebooks 04, tests/test_speed.py)
from .candidates import whole_frame_search as _whole_frame_search  # transitional (tests/test_speed.py)
from .marker_model import label_frame  # transitional (notebooks 04)
from .tracker3d import reason_counts  # transitional (horsemocap/pipeline.py, tests/test_input_faults.py)

__all__ = ["frame_candidates", "label_frame", "reason_counts"]
