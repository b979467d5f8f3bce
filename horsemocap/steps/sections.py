"""transitional: the parameter section a step is given, from the flat AnalysisParams of before the sections.

Removed when horsemocap.params.AnalysisParams holds the sections itself.
"""
from __future__ import annotations

from ..params import (ComfortParams, DetectParams, FitsParams, MotionFrameParams, PoseParams, RigidBodyParams,
                      RigParams, SmoothParams, StillsParams, SyncParams, TriangulateParams)

SECTION_OF_STEP = {"sync": "sync", "rig": "rig", "plumb": "stills", "static": "stills", "detect": "detect",
                   "triangulate": "triangulate", "smooth": "smooth", "motion_frame": "motion_frame",
                   "rigid_body": "rigid_body", "comfort": "comfort"}


def section(params, name: str):
    """The section ``name`` of ``params`` (sectioned or flat)."""
    got = getattr(params, name, None)
    if got is not None and not isinstance(got, (str, dict)):
        return got
    p = params
    return {
        "sync": lambda: SyncParams(offsets=p.sync_offsets),
        "rig": lambda: RigParams(recalibrate=p.recalibrate, exclude=p.calibration_exclude, mode=p.calibration_mode),
        "stills": lambda: StillsParams(plumb=p.stills.get("plumb", {}), static=p.stills.get("static", {})),
        "detect": lambda: DetectParams(method=p.detection_method, cameras=p.detection, max_gap_frames=p.max_gap_frames),
        "triangulate": lambda: TriangulateParams(mode=p.triangulation),
        "smooth": lambda: SmoothParams(method=p.smoothing_method, span=p.smoothing_span),
        "motion_frame": lambda: MotionFrameParams(mode=p.motion_frame, x_marker=p.x_marker,
                                                  period_frames=p.period_frames, n_periods=p.n_periods),
        "rigid_body": lambda: RigidBodyParams(
            kinematics=p.kinematics, saddle_marker=p.saddle_marker,
            fits=FitsParams(x_degree=p.x_degree, fourier_orders=p.fourier_orders, order_rule=p.order_rule,
                            trend=p.fourier_trend, angular_method=p.angular_method,
                            omega_versions=p.omega_versions, alpha_versions=p.alpha_versions,
                            saddle_method=p.saddle_method),
            pose=PoseParams(smoothing=p.pose_smoothing, partial_frames=p.pose_partial_frames,
                            harmonics=p.pose_harmonics, weights=p.pose_weights,
                            rotation_weights=p.pose_rotation_weights, events=p.pose_events)),
        "comfort": lambda: ComfortParams(weighting_mode=p.weighting_mode),
    }[name]()
