"""Step ``comfort``: whole-body vibration indicators of the saddle's motion (thesis chapter 7)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..params import ComfortParams
from ..vibration import saddle_comfort
from .base import StepResult
from .rigid_body import RigidBodyResult


@dataclass(frozen=True)
class ComfortResult(StepResult):
    """The comfort indicators, or why they were not computed.

    Attributes
    ----------
    indicators : dict or None
        The indicators of thesis Table 8.7 (the ``indicator`` column of comfort.csv -> value).
    reason : str
        Why ``indicators`` is None ("" when computed).
    """

    indicators: dict | None
    reason: str = ""


def step_comfort(section: ComfortParams, rigid_body: RigidBodyResult, f0_hz: float | None, progress) -> ComfortResult:
    """Whole-body vibration indicators of the saddle's vertical motion (chapter 7).

    The indicators are harmonic series of the stride frequency ``f0_hz``
    (the motion-frame step's period), or, if it is None, one estimated from
    the saddle's vertical position; if neither exists the indicators are not
    computed (``indicators`` None, ``reason`` says why) and the earlier
    results stand.
    """
    rb = rigid_body
    pos, acc, vel = rb.saddle_position, rb.saddle_acceleration, rb.saddle_velocity
    ok = np.all(np.isfinite(pos), axis=1) & np.all(np.isfinite(acc), axis=1) & np.all(np.isfinite(vel), axis=1)
    try:
        ind = saddle_comfort(rb.t[ok], pos[ok], acc[ok], vel[ok], mode=section.weighting_mode, f0_hz=f0_hz)
    except ValueError as exc:
        why = f"no stride frequency could be estimated ({exc})" if f0_hz is None else str(exc)
        progress("comfort", f"comfort indicators not computed: {why}")
        return ComfortResult(indicators=None, reason=why)
    # no figure here: the command prints the comfort figures only beside the quality verdict (horsemocap.run)
    progress("comfort", "indicators of chapter 7 computed")
    return ComfortResult(indicators=ind)
