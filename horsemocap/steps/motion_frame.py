"""Step ``motion_frame``: x along the net displacement, y along gravity (thesis section 5.3)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..frames import MotionFrame, motion_frame, motion_frame_from_record, stride_period, to_motion_frame
from ..params import MotionFrameParams
from ..session import Session
from .base import AnalysisError, StepResult


@dataclass(frozen=True)
class MotionFrameResult(StepResult):
    """The motion reference frame and the positions in it.

    Attributes
    ----------
    frame : MotionFrame
        Origin, axes and the period used (eq. 5.6/5.7).
    period_frames : float or None
        The motion's period in frames (given or estimated), None when none was found.
    positions : (n, m, 3) array
        The smoothed positions in the motion frame.
    static : (m + 1, 3) array
        The static shot's points in the motion frame.
    faster_period_frames : float or None
        A faster repetition than a horse strides, passed over for ``period_frames``.
    """

    frame: MotionFrame
    period_frames: float | None
    positions: np.ndarray
    static: np.ndarray
    faster_period_frames: float | None = None

    @property
    def axes(self) -> np.ndarray:
        """Rows x, y, z of the motion frame in the world frame (``frame.axes``)."""
        return self.frame.axes


def step_motion_frame(session: Session, section: MotionFrameParams, smoothed: np.ndarray, gravity: np.ndarray,
                      static_points: np.ndarray | None, segment: tuple, progress,
                      static_missing: str = "") -> MotionFrameResult:
    """Motion reference frame: x along net displacement, y along gravity (5.3).

    ``section.mode = "period"``: the thesis' eq. 5.6/5.7 over one or two
    periods; ``"record"``: x from the net displacement over the whole record
    (:func:`horsemocap.frames.motion_frame_from_record`), the period then only
    estimated for the comfort step and possibly absent; ``"auto"`` (default):
    ``"period"`` when a period is given or found, else ``"record"``.
    ``segment`` (the analysed frames) only names them in messages.
    """
    if static_points is None:
        raise AnalysisError("motion_frame", static_missing)
    a, b = segment
    period, faster, not_found = section.period_frames, None, None
    if period is None:       # estimated once, a horse's stride the bound (frames.HORSE_STRIDE_HZ)
        try:
            period, faster = stride_period(smoothed, session.fps, gravity=gravity)
        except ValueError as exc:
            not_found = exc
    mode = section.mode
    if mode == "auto":
        try:
            motion_frame(smoothed, gravity, marker=section.x_marker, period=period, n_periods=section.n_periods)
            mode = "period"
        except ValueError as exc:
            progress("motion_frame", f"the thesis' motion frame needs a period: {exc}; using the net "
                                     "displacement over the whole record instead")
            mode = "record"
    if mode == "record":
        why = "given" if section.period_frames is not None else \
            "estimated" if not_found is None else f"not found ({not_found})"
        try:
            mf = motion_frame_from_record(smoothed, gravity, period)
        except ValueError as exc:
            raise AnalysisError("motion_frame", f"{exc} (frames {a}..{b - 1}; see trajectories in markers_2d.csv)") from None
        progress("motion_frame", "x-motion from the net displacement over the whole record; "
                 + (f"period {period:.2f} frames ({why})" if period is not None else
                    f"period {why}: only the comfort step needs it"))
    else:
        try:
            mf = motion_frame(smoothed, gravity, marker=section.x_marker, period=period, n_periods=section.n_periods)
        except ValueError as exc:
            raise AnalysisError("motion_frame", f"{exc}. The analysed frames {a}..{b - 1} ({b - a} frames, the "
                                "longest run in which every camera sees every marker; see markers_2d.csv) "
                                "may hold less than the two periods the thesis uses: give the period in frames "
                                "with --period (analysis 'period_frames'), check the motion videos, or use "
                                "motion_frame 'record' (no period needed)") from None
        progress("motion_frame", f"period {mf.period_frames:.2f} frames")
        period = mf.period_frames
    _say_faster(session.fps, period, faster, progress)
    return MotionFrameResult(frame=mf, period_frames=None if period is None else float(period),
                             positions=to_motion_frame(smoothed, mf), static=to_motion_frame(static_points, mf),
                             faster_period_frames=None if faster is None else float(faster))


def _say_faster(fps, period, faster, progress) -> None:
    """Say that the record also repeats faster than a horse strides
    (:func:`horsemocap.frames.stride_period`), so the period taken was searched again among longer lags
    (judged by :func:`horsemocap.quality.check_stride_frequency`)."""
    if faster is not None:
        progress("motion_frame", f"the record also repeats every {faster:.2f} frames ({fps / faster:.3g} Hz), faster "
                                 f"than a horse strides: the period was searched among longer lags and taken as "
                                 f"{float(period):.2f}")
