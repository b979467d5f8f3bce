"""Ground truth of a rendered session: saving, loading, comfort indicators.

Stored in ``<session>/truth/`` (readers of the session ignore the folder):
``truth.npz`` (arrays), ``truth.json`` (scalars, offsets, comfort,
parameters) and ``rig.toml`` (the true rig).

Conventions (shared brief): time on axis 0; positions (n, markers, 3) in the
world frame = left camera frame (thesis ``CM_L``); pixels (frames, markers,
2) in each camera's own frame numbering (thesis ``PM_L``, ``PM_M``,
``PM_R``), marker order = rear to front = sorted by image u, the 4th row is
the saddle marker (thesis ``S``).
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..camera import Rig, read_rig, write_rig
from ..store import atomic_write_json, atomic_write_npz
from .timing import CameraTiming

TRUTH_FORMAT = "horsemocap-truth/1"


@dataclass(frozen=True)
class Truth:
    """Exact ground truth of a virtual-laboratory session.

    Attributes
    ----------
    fps : float
    offsets : dict[str, int]
        Flash-on frame in each camera's own source (thesis eq. 3.11-3.13:
        ``F_L(k) <-> F_M(k + offsets[middle] - offsets[left])``).
    rig : Rig
        The true rig (same as ``calibration/rig.toml``).
    ref_frames : ndarray (n,)
        Left-camera frame indices of the analysed samples: the longest run of
        frames in which all skin markers are fully inside the image in all
        cameras (a marker occluded in one camera only does not end it).
    time_s : ndarray (n,)
        ``(ref_frames - ref_frames[0]) / fps`` (thesis eq. 5.13).
    motion_time_s : ndarray (n,)
        The analytic motion time of each sample (0 at the flash).
    marker_pos, marker_vel, marker_acc : ndarray (n, 3, 3)
        Skin markers, world frame (m, m/s, m/s^2).
    saddle_pos, saddle_vel, saddle_acc : ndarray (n, 3)
        Saddle marker ``S`` (thesis 6.3-6.4), world frame.
    rotation : ndarray (n, 3, 3)
        Body-to-world rotation (body axes: forward, down, lateral).
    omega, alpha : ndarray (n, 3)
        Angular velocity / acceleration of the body, world frame (rad/s, rad/s^2).
    marker_px : dict[str, ndarray (frames_c, 4, 2)]
        True projections of the 3D centres in every frame of every camera
        (4th = saddle marker).
    marker_visible : dict[str, ndarray (frames_c, 4) bool]
    marker_reason : dict[str, ndarray (frames_c, 4) str]
        ``""`` visible, ``"outside_image"``, ``"partly_outside_image"``,
        ``"occluded_by_rider"``, ``"occluded_in_camera"`` (hidden in this
        camera only by something near its lens; hard sessions,
        :class:`horsemocap.virtuallab.hard.Occluder`).
    gravity : ndarray (3,)
        Unit vector along gravity (down), world frame.
    motion_axes : ndarray (3, 3)
        Rows: x-motion (net displacement), y-motion (gravity, down),
        z-motion = x cross y; ``x_M = motion_axes @ x_C`` (thesis eq. 5.12).
    static_pos : ndarray (4, 3)
        Static-shot positions of the 3 skin markers and the saddle marker.
    plumb_pos : ndarray (2, 3)
        Plumb markers: tip (lower), tail (upper) (thesis 5.3).
    comfort : dict[str, float]
        Indicators from the true saddle vertical acceleration (see
        ``comfort_source``).
    extras : dict
        Everything else (dense true saddle motion, parameters, flash frames...;
        in hard sessions each scene extra's true image path per camera and
        frame: ``stirrup_px__<cam>`` / ``reflector_px__<cam>`` (frames, 2),
        ``*_inside__<cam>`` (whole disc in the image), ``*_brightness__<cam>``,
        ``occluder_px__<cam>`` / ``occluder_radius_px__<cam>`` (NaN when away)
        and ``occluder_description`` (camera, marker, frames)). Sessions of
        free-running cameras (:mod:`horsemocap.virtuallab.timing`) add
        ``camera_timing`` (camera -> :meth:`CameraTiming.to_dict`),
        ``true_offsets_frames`` (camera -> fractional frames after the
        reference camera's: :func:`true_offsets_frames`), ``true_rate_ratio``,
        ``flash_interval_s`` and per camera ``frame_start_s__<cam>`` (exposure
        start of row 0), ``frame_time_s__<cam>`` (middle of row 0's
        exposure), ``marker_time_s__<cam>`` (frames, 4: the instant of each
        ``marker_px`` entry) and ``flash_lit__<cam>`` (part of each frame's
        exposure the flash is on; of the first field when interlaced). ``offsets`` then holds each camera's frame
        whose row-0 exposure is centred ``phase_frames`` of a frame after the
        flash's onset; ``motion_time_s`` and the kinematics are at the
        reference (left) camera's frame instants.
    """

    fps: float
    offsets: dict
    rig: Rig
    ref_frames: np.ndarray
    time_s: np.ndarray
    motion_time_s: np.ndarray
    marker_pos: np.ndarray
    marker_vel: np.ndarray
    marker_acc: np.ndarray
    saddle_pos: np.ndarray
    saddle_vel: np.ndarray
    saddle_acc: np.ndarray
    rotation: np.ndarray
    omega: np.ndarray
    alpha: np.ndarray
    marker_px: dict
    marker_visible: dict
    marker_reason: dict
    gravity: np.ndarray
    motion_axes: np.ndarray
    static_pos: np.ndarray
    plumb_pos: np.ndarray
    comfort: dict
    comfort_source: str = ""
    marker_diameter_m: float = 0.06
    meta: dict = field(default_factory=dict)
    extras: dict = field(default_factory=dict)

    def to_motion(self, x_world: np.ndarray) -> np.ndarray:
        """World-frame vectors ``(..., 3)`` in motion-frame axes (eq. 5.12)."""
        return np.asarray(x_world, float) @ self.motion_axes.T

    @property
    def cameras(self) -> list[str]:
        return list(self.rig.names)

    @property
    def free_running(self) -> bool:
        """True when the cameras ran free (the truth carries ``camera_timing``)."""
        return "camera_timing" in self.extras


def camera_timings(truth: Truth) -> dict:
    """Each camera's :class:`~horsemocap.virtuallab.timing.CameraTiming`.

    Genlocked sessions (no ``camera_timing`` in the truth): every camera at
    phase 0, no rate offset, the session's exposure (``extras['exposure_s']``).
    """
    if truth.free_running:
        return {c: CameraTiming.from_dict(d) for c, d in truth.extras["camera_timing"].items()}
    exposure = truth.extras.get("exposure_s")
    exposure = None if exposure is None else min(float(exposure), 1.0 / truth.fps)
    return {c: CameraTiming(nominal_fps=float(truth.fps), exposure_s=exposure) for c in truth.cameras}


def true_offsets_frames(truth: Truth) -> dict:
    """The true offsets of every camera after the reference (frames, with a fraction).

    Camera ``c``'s frame ``k + offset[c]`` shows the instant of the reference
    camera's frame ``k`` (at the flash's onset; the offsets drift by
    ``extras['true_rate_ratio'] - 1`` frames per frame; ``true_rate_ratio`` is the camera's frame rate over
    the reference's, the reciprocal of the pipeline's ``SyncResult.rate_ratio``, reference frames per frame of
    its own: :func:`horsemocap.subframe.camera_frames`). Genlocked sessions:
    the whole-frame differences of ``offsets``.
    """
    if truth.free_running:
        return {c: float(v) for c, v in truth.extras["true_offsets_frames"].items()}
    ref = truth.offsets[truth.cameras[0]]
    return {c: float(o - ref) for c, o in truth.offsets.items()}


_ARRAYS = ("ref_frames", "time_s", "motion_time_s", "marker_pos", "marker_vel", "marker_acc",
           "saddle_pos", "saddle_vel", "saddle_acc", "rotation", "omega", "alpha",
           "gravity", "motion_axes", "static_pos", "plumb_pos")


def save_truth(truth: Truth, session_dir) -> Path:
    """Write ``<session>/truth/{truth.npz, truth.json, rig.toml}``."""
    folder = Path(session_dir) / "truth"
    folder.mkdir(parents=True, exist_ok=True)
    arrays = {k: np.asarray(getattr(truth, k)) for k in _ARRAYS}
    for cam in truth.marker_px:
        arrays[f"marker_px__{cam}"] = truth.marker_px[cam]
        arrays[f"marker_visible__{cam}"] = truth.marker_visible[cam]
        arrays[f"marker_reason__{cam}"] = np.asarray(truth.marker_reason[cam], dtype="U24")
    for k, v in truth.extras.items():
        if isinstance(v, np.ndarray):
            arrays[f"extra__{k}"] = v
    atomic_write_npz(folder / "truth.npz", **arrays)
    meta = {
        "format": TRUTH_FORMAT,
        "fps": truth.fps,
        "offsets": {k: int(v) for k, v in truth.offsets.items()},
        "cameras": truth.cameras,
        "comfort": {k: float(v) for k, v in truth.comfort.items()},
        "comfort_source": truth.comfort_source,
        "marker_diameter_m": truth.marker_diameter_m,
        "meta": truth.meta,
        "extras": {k: v for k, v in truth.extras.items() if not isinstance(v, np.ndarray)},
    }
    atomic_write_json(folder / "truth.json", meta)
    write_rig(truth.rig, folder / "rig.toml")
    return folder



def load_truth(session_dir) -> Truth:
    """Read the ground truth written beside a rendered session.

    Raises
    ------
    FileNotFoundError
        Naming the missing file if the session has no ``truth/`` folder.
    """
    folder = Path(session_dir) / "truth"
    jpath, npath = folder / "truth.json", folder / "truth.npz"
    for p in (jpath, npath, folder / "rig.toml"):
        if not p.is_file():
            raise FileNotFoundError(f"{p}: ground truth file not found (is {session_dir} a virtual-laboratory session?)")
    meta = json.loads(jpath.read_text())
    if meta.get("format") != TRUTH_FORMAT:
        raise ValueError(f"{jpath}: field 'format' must be {TRUTH_FORMAT!r}, got {meta.get('format')!r}")
    with np.load(npath, allow_pickle=False) as z:
        arr = {k: z[k] for k in z.files}
    cams = meta["cameras"]
    extras = dict(meta.get("extras", {}))
    extras.update({k[len("extra__"):]: v for k, v in arr.items() if k.startswith("extra__")})
    return Truth(
        fps=float(meta["fps"]),
        offsets={k: int(v) for k, v in meta["offsets"].items()},
        rig=read_rig(folder / "rig.toml"),
        **{k: arr[k] for k in _ARRAYS},
        marker_px={c: arr[f"marker_px__{c}"] for c in cams},
        marker_visible={c: arr[f"marker_visible__{c}"] for c in cams},
        marker_reason={c: arr[f"marker_reason__{c}"].astype(str) for c in cams},
        comfort=dict(meta["comfort"]),
        comfort_source=meta.get("comfort_source", ""),
        marker_diameter_m=float(meta.get("marker_diameter_m", 0.06)),
        meta=meta.get("meta", {}),
        extras=extras,
    )
