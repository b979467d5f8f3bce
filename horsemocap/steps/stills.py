"""Steps ``plumb`` and ``static``: the markers of one still per camera (thesis sections 5.3 and 6.3)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..camera import Rig
from ..detection import DetectionParams, detect_still, detect_still_views
from ..frames import gravity_from_plumb
from ..params import StillsParams
from ..reconstruction import triangulate
from ..session import Session
from ..sources import read_image
from .base import AnalysisError, StepResult


@dataclass(frozen=True)
class PlumbResult(StepResult):
    """Gravity from the plumb line's two markers (section 5.3).

    Attributes
    ----------
    plumb_points : (2, 3) array
        The two markers (world frame), the upper one first.
    plumb_px : dict
        Camera -> (2, 2) their centroids (px).
    gravity : (3,) array
        Unit vector of gravity (downward) in the world frame.
    """

    plumb_points: np.ndarray
    plumb_px: dict
    gravity: np.ndarray


@dataclass(frozen=True)
class StaticResult(StepResult):
    """The static shot: the horse standing, every marker and the saddle marker visible (section 6.3).

    Attributes
    ----------
    static_points : (m + 1, 3) array or None
        The markers and the saddle marker (world frame), ascending image u in
        the reference camera; None when the session has no static shot.
    static_px : dict or None
        Camera -> their centroids (px).
    missing : str
        Why there is no static shot ("" when there is one).
    """

    static_points: np.ndarray | None
    static_px: dict | None
    missing: str = ""


def still_params(section: StillsParams, kind: str, cameras) -> dict:
    """The detector parameters of one still per camera (``section.plumb`` or ``.static``: "all" then the camera).

    Returns ``{camera: DetectionParams}`` (empty when every choice is automatic).

    Examples
    --------
    >>> p = still_params(StillsParams(static={"all": {"threshold": 150}}), "static", ["left"])
    >>> p["left"].threshold
    150
    """
    given = getattr(section, kind)
    if not given:
        return {}
    out = {}
    for c in cameras:
        d = {**given.get("all", {}), **given.get(c, {})}
        if "labels" in d:
            d["labels"] = tuple(d["labels"])
        out[c] = DetectionParams(**d)
    return out


def still_points(session: Session, rig: Rig, images: dict, count: int, step: str, mode: str,
                 given: dict | None = None):
    """Markers of one still per camera, matched across the cameras and triangulated.

    :func:`horsemocap.detection.detect_still_views` keeps only candidates that
    triangulate consistently in every camera (a glint or a buckle seen by one
    camera is not a marker), then picks the most marker-like ones. ``given``
    (:func:`still_params`): per-camera thresholds for that matching, or, with
    labels for every camera, the thesis' way (Appendix A 7a, 8a, 12a): the
    labelled regions of each camera taken as they are
    (:func:`horsemocap.detection.detect_still`). Returns ``(points, px)``.
    """
    given = given or {}
    try:
        imgs = {c: read_image(images[c]) for c in session.cameras}
        if given and all(given[c].labels is not None for c in session.cameras):
            px = {c: detect_still(imgs[c], count, given[c]) for c in session.cameras}
        else:
            px = detect_still_views(imgs, rig, count, given or None)
    except ValueError as exc:
        files = ", ".join(str(images[c]) for c in session.cameras)
        raise AnalysisError(step, f"{files}: {exc}") from None
    return triangulate(rig, {c: p[None] for c, p in px.items()}, mode=mode).points[0], px


def step_plumb(session: Session, section: StillsParams, rig: Rig, triangulation: str, progress) -> PlumbResult:
    """Gravity from the plumb line's two markers (section 5.3), triangulated as ``triangulation`` says."""
    if session.plumb is None:
        raise AnalysisError("plumb", f"{session.json_path}: no 'plumb' stills; gravity cannot be found")
    pts, px = still_points(session, rig, session.plumb, 2, "plumb", triangulation,
                           still_params(section, "plumb", session.cameras))
    # the still's two markers come top first (image v): the upper one is the tail, the lower one
    # the tip, and gravity points from tail to tip (down)
    gravity = gravity_from_plumb(tip_world=pts[1], tail_world=pts[0])
    progress("plumb", f"gravity {np.round(gravity, 4).tolist()}")
    return PlumbResult(plumb_points=pts, plumb_px=px, gravity=gravity)


def step_static(session: Session, section: StillsParams, rig: Rig, triangulation: str, progress) -> StaticResult:
    """The static shot's markers and saddle marker, all visible (section 6.3)."""
    if session.static is None:
        return StaticResult(static_points=None, static_px=None,
                            missing=f"{session.json_path}: no 'static' stills; the saddle marker cannot be placed")
    pts, px = still_points(session, rig, session.static, session.marker_count + 1, "static", triangulation,
                           still_params(section, "static", session.cameras))
    return StaticResult(static_points=pts, static_px=px)
