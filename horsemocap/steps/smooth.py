"""Step ``smooth``: smoothing of every coordinate of the analysed frames (thesis section 5.2)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..params import SmoothParams
from ..smoothing import smooth_positions
from .base import StepResult
from .triangulate import TriangulateResult


@dataclass(frozen=True)
class SmoothResult(StepResult):
    """The analysed frames' positions before and after smoothing.

    Attributes
    ----------
    raw : (n, m, 3) array
        The triangulated positions of the analysed segment (world frame).
    smoothed : (n, m, 3) array
        The same smoothed (a copy of ``raw`` with method ``"none"``).
    """

    raw: np.ndarray
    smoothed: np.ndarray


def step_smooth(section: SmoothParams, triangulated: TriangulateResult, progress) -> SmoothResult:
    """Smoothing of every coordinate (section 5.2), or none.

    The thesis smooths with ``smooth(y, 0.1, 'rloess')``; ``"none"`` keeps
    the triangulated positions (the Fourier fits of section 5.5 filter them).
    """
    a, b = triangulated.segment
    raw = triangulated.points[a:b]
    if section.method == "none":
        return SmoothResult(raw=raw, smoothed=raw.copy())
    gaps = "omit" if raw.shape[1] > 3 else "raise"      # four or more markers: one may be hidden (NaN kept)
    return SmoothResult(raw=raw, smoothed=smooth_positions(raw, span=section.span, method=section.method, nan=gaps))
