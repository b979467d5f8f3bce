"""The analysis steps: each takes its parameter section and the typed results it needs, and returns one
typed, frozen result of its own (DESIGN.md's arrows).

========================  =====================================  ===================================
step                      function                               result
========================  =====================================  ===================================
``sync``                  :func:`step_sync`                      :class:`SyncResult`
``rig``                   :func:`step_rig`                       :class:`RigResult`
``plumb``                 :func:`step_plumb`                     :class:`PlumbResult`
``static``                :func:`step_static`                    :class:`StaticResult`
``detect``                :func:`step_detect`                    :class:`DetectResult`
``triangulate``           :func:`step_triangulate`               :class:`TriangulateResult`
``smooth``                :func:`step_smooth`                    :class:`SmoothResult`
``motion_frame``          :func:`step_motion_frame`              :class:`MotionFrameResult`
``rigid_body``            :func:`step_rigid_body`                :class:`RigidBodyResult`
``comfort``               :func:`step_comfort`                   :class:`ComfortResult`
========================  =====================================  ===================================

:func:`horsemocap.pipeline.analyze` runs them in this order.
"""
from .base import AnalysisError, StepResult, frames_text, longest_run
from .comfort import ComfortResult, step_comfort
from .detect import (CameraSyncCheck, DetectResult, IdentificationSummary, camera_detection_params, gaps_inside,
                     max_gap_frames, step_detect, synchronised_frames)
from .motion_frame import MotionFrameResult, step_motion_frame
from .rig import RigResult, step_rig
from .rigid_body import RigidBodyResult, pose_margin, step_rigid_body
from .smooth import SmoothResult, step_smooth
from .stills import PlumbResult, StaticResult, step_plumb, step_static, still_params, still_points
from .sync import SyncResult, step_sync
from .triangulate import TriangulateResult, step_triangulate

STEPS = ("sync", "rig", "plumb", "static", "detect", "triangulate", "smooth", "motion_frame", "rigid_body", "comfort")
"""The steps in the order they run."""

RESULT_TYPES = {"sync": SyncResult, "rig": RigResult, "plumb": PlumbResult, "static": StaticResult,
                "detect": DetectResult, "triangulate": TriangulateResult, "smooth": SmoothResult,
                "motion_frame": MotionFrameResult, "rigid_body": RigidBodyResult, "comfort": ComfortResult}
"""Each step's result type."""
