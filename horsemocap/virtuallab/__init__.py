"""The virtual laboratory: synthetic riding sessions with exact ground truth.

As Guchin et al. (section 3) built a motion-capture laboratory in Blender, this
package builds the thesis' laboratory in NumPy/OpenCV: the 3-camera rig of
Tables 8.1-8.4, four horses in four gaits with analytic saddle motion,
rendered videos with the difficulties of real recordings, stills (plumb,
static shot, checkerboards), a free-fall ball (section 8.3), and the exact
truth beside every session; and a harder laboratory (:mod:`.hard`)
of other rigs, sizes, frame rates, scene extras and speed changes.
"""
from .horse import (GAITS, HERD, HORSES, Gait, Harmonics, Horse, Pose, SaddleMotion,
                    saddle_motion)
from .rig import INTRINSICS, EXTRINSICS, pair_disagreement, thesis_camera, thesis_rig
from .session import Scene, build_truth, render_ball_drop, render_calibration_set, render_session
from .herd import herd_description, herd_seed, herd_session, write_herd_description
from .truth import Truth, load_truth, save_truth
from .hard import HARD_SESSIONS, HardScenario, RigSpec, hard_rig, hard_session

__all__ = ["GAITS", "HERD", "HORSES", "Gait", "Harmonics", "Horse", "Pose", "SaddleMotion",
           "saddle_motion", "INTRINSICS", "EXTRINSICS", "pair_disagreement", "thesis_camera",
           "thesis_rig", "Scene", "build_truth", "render_session", "render_calibration_set", "render_ball_drop",
           "herd_description", "herd_seed", "herd_session", "write_herd_description", "Truth", "load_truth", "save_truth",
           "HARD_SESSIONS", "HardScenario", "RigSpec", "hard_rig", "hard_session"]
