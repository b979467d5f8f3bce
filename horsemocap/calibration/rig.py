"""Calibration of the whole rig: each camera, the three pairs, and all at once.

Thesis section 3.5 and Appendix A steps 2-3: each camera is calibrated alone
(intrinsics, Tables 8.1-8.3), then each pair with the stereo toolbox (left
-middle, left-right, middle-right: ``R_ML, t_ML, R_RL, t_RL, R_RM, t_RM``,
Table 8.4). The pairs are calibrated separately, so the three results do not
compose exactly (``R_RL != R_RM R_ML``) and each camera gets two sets of
intrinsics. The joint calibration (:func:`~.bundle.bundle_adjust` on all
cameras) refines one set of intrinsics per camera and one pose per camera in
the reference (left) camera's frame: one consistent rig.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..camera import Rig, rotation_matrix, rotation_vector
from ..progress import counter
from ..sources import natural_key
from .board import UNREADABLE, board_points, BoardViews, CalibrationError, detect_cameras
from .bundle import bundle_adjust, BundleResult, calibrate_camera, harmonize_views


@dataclass(frozen=True)
class RigCalibration:
    """Everything one calibration of the rig produced.

    Attributes
    ----------
    rig : Rig
        The calibrated rig (world frame = reference camera), from the joint
        bundle adjustment (``mode="joint"``) or from the pairs with the
        reference camera (``mode="pairwise"``, as the thesis built it).
    mode : str
    reference : str
    cameras : tuple of str
        Session order.
    inner_corners : (cols, rows)
    square_m : float
    views : dict[str, BoardViews]
        Detected corners per camera, aligned so index ``k`` is the same instant
        in every camera, corner order made consistent across cameras.
    singles : dict[str, IntrinsicResult]
        Each camera calibrated alone (3-sigma uncertainties, per-view errors).
    pairs : dict[tuple[str, str], BundleResult]
        Stereo calibration of each pair (Table 8.4), keyed ``(left, right)``.
    joint : BundleResult or None
        All cameras refined together.
    flipped : tuple
        ``(camera, view)`` whose corner order was reversed to match the reference.
    """

    rig: Rig
    mode: str
    reference: str
    cameras: tuple
    inner_corners: tuple
    square_m: float
    views: dict
    singles: dict
    pairs: dict
    joint: BundleResult | None
    flipped: tuple

    @property
    def rms(self) -> float:
        """RMS reprojection error (pixels) of the calibration that gave the rig."""
        if self.mode == "joint" and self.joint is not None:
            return self.joint.rms
        ref = self.reference
        return float(np.sqrt(np.mean([self.pairs[k].rms ** 2 for k in self.pairs if ref in k])))

    @property
    def view_names(self) -> tuple:
        return self.views[self.cameras[0]].names

    def per_view_errors(self) -> dict:
        """RMS reprojection error per view, ``{camera: {"alone": (views,), "joint": (views,)}}``."""
        out = {}
        for c in self.cameras:
            d = {"alone": self.singles[c].per_view_rms}
            if self.joint is not None:
                d["joint"] = self.joint.intrinsics[c].per_view_rms
            out[c] = d
        return out


def align_views(views: dict[str, BoardViews]) -> dict[str, BoardViews]:
    """Put every camera's views on one list of instants (the union of view names).

    A view a camera lacks gets NaN corners and the reason ``"no image"``.
    Cameras that share no view name at all raise :class:`CalibrationError`
    (``left01.jpg`` in folder ``left`` and ``right01.jpg`` in folder ``right``
    do match: :func:`~.board.view_keys` strips the camera name).
    """
    names = [v.names for v in views.values()]
    union = sorted(set().union(*names), key=natural_key)
    if len(set(union)) == 0:
        raise CalibrationError("no calibration views")
    common = set.intersection(*(set(n) for n in names))
    if not common:
        lengths = {c: len(v.names) for c, v in views.items()}
        raise CalibrationError(
            f"the calibration folders share no file name (same name = same instant): {lengths} views; "
            "name the views of one instant alike in every camera folder")
    out = {}
    for cam, v in views.items():
        idx = {n: k for k, n in enumerate(v.names)}
        n = v.corners.shape[1]
        corners = np.full((len(union), n, 2), np.nan)
        reasons, files, windows = [], [], np.zeros(len(union), int)
        for j, name in enumerate(union):
            if name in idx:
                k = idx[name]
                corners[j] = v.corners[k]
                reasons.append(v.reasons[k])
                files.append(v.files[k])
                windows[j] = v.windows[k]
            else:
                reasons.append("no image")
                files.append(None)
        out[cam] = replace(v, names=tuple(union), files=tuple(files), corners=corners,
                           reasons=tuple(reasons), windows=windows)
    return out


def _exclusions(exclude, cameras) -> dict:
    if exclude is None:
        return {c: set() for c in cameras}
    if isinstance(exclude, dict):
        unknown = set(exclude) - set(cameras)
        if unknown:
            raise CalibrationError(f"exclude names unknown cameras {sorted(unknown)}; cameras are {list(cameras)}")
        return {c: _view_set(exclude.get(c, ())) for c in cameras}
    return {c: _view_set(exclude) for c in cameras}


def _view_set(views) -> set:
    """Views given as one name or several."""
    return {views} if isinstance(views, str) else set(views)


def board_view_counter(progress, cam: str):
    """``tick(done, total)`` counting the board views of ``cam`` on ``progress`` (None: no counting)."""
    if progress is None:
        return None

    def tick(done, total):
        counter(progress, "rig", f"camera '{cam}': views searched for the board", total)(done)
    return tick


def unreadable_views(views: dict) -> list[str]:
    """One line per camera with views skipped because their files cannot be read (truncated, corrupt).

    Such a view is left out like a view without a board (its reason starts
    with :data:`~.board.UNREADABLE`, kept in :attr:`BoardViews.reasons`);
    the line names the files and what is wrong with them.
    """
    lines = []
    for cam, v in views.items():
        bad = [(f, r) for f, r in zip(v.files, v.reasons) if r.startswith(UNREADABLE)]
        if bad:
            shown = "; ".join(f"{Path(f).name} ({r[len(UNREADABLE) + 2:]})" for f, r in bad)
            lines.append(f"camera '{cam}': {len(bad)} of {len(v.names)} checkerboard views skipped (as views "
                         f"without a board), their files cannot be read: {shown}")
    return lines


def calibrate_rig(image_dirs: dict, inner_corners=(15, 29), square_m: float = 0.05, *, mode: str = "joint",
                  reference: str = "left", exclude=None, fix_k3: bool = True, views: dict | None = None,
                  pairs: bool = True, progress=None) -> RigCalibration:
    """Calibrate every camera, every pair and the whole rig from checkerboard views.

    Parameters
    ----------
    image_dirs : dict[str, Path]
        One folder of views per camera, keyed by camera name in session order;
        the same file name in every folder is the same instant. May be None
        for cameras whose ``views`` are given.
    inner_corners : (cols, rows)
        Inner corners of the board (thesis board: 15 x 29, 50 mm squares).
    square_m : float
        Side of a square, metres (the toolbox's ``dX = dY``).
    mode : {"joint", "pairwise"}
        Which calibration gives ``.rig``: the joint bundle adjustment, or the
        thesis' pairs (reference-other pair for each camera; the reference
        camera's intrinsics from its pair with the next camera).
    reference : str
        The camera whose frame is the world frame (thesis: left, ``CM_L``).
    exclude : None, iterable of str, or dict[str, iterable of str]
        Views left out, each by its key or its file's name (:func:`~.board.excluded_view_keys`): for every
        camera, or per camera.
    fix_k3 : bool
        Keep ``k3 = 0`` (the thesis' and the toolbox's default).
    views : dict[str, BoardViews], optional
        Already detected corners (skips detection).
    pairs : bool
        Also calibrate every pair (Table 8.4). Always done for ``"pairwise"``.
    progress : callable(step, message[, done, total]), optional
        Reports each camera's board detection view by view (as step
        ``"rig"``; see :func:`horsemocap.progress.counter`) and the
        calibrations as they start.

    Returns
    -------
    RigCalibration
    """
    if mode not in ("joint", "pairwise"):
        raise CalibrationError(f"mode must be 'joint' or 'pairwise', got {mode!r}")
    inner_corners = (int(inner_corners[0]), int(inner_corners[1]))
    report = progress or (lambda *a: None)
    if views is None:
        views = detect_cameras(image_dirs, inner_corners,
                               ticks={c: board_view_counter(progress, c) for c in image_dirs})
    cameras = tuple(views)
    if reference not in cameras:
        raise CalibrationError(f"reference camera {reference!r} is not among the cameras {list(cameras)}")
    for line in unreadable_views(views):
        report("rig", line)
    views = align_views(views)
    bp = board_points(inner_corners, square_m)
    excl = _exclusions(exclude, cameras)
    report("rig", f"calibrating each camera alone ({', '.join(cameras)}) ...")
    # one camera after the other: with one BLAS thread each (calibrate_camera) two cameras in
    # threads took 0.20-0.49 s against 0.17 s in turn (bundled views, 2 processors)
    singles = {c: calibrate_camera(views[c], bp, excl[c], fix_k3=fix_k3) for c in cameras}
    order = [reference] + [c for c in cameras if c != reference]
    hv, hs, flipped = harmonize_views([views[c] for c in order], [singles[c] for c in order], bp)
    views = {c: hv[order.index(c)] for c in cameras}
    singles = {c: hs[order.index(c)] for c in cameras}

    pair_results = {}
    if pairs or mode == "pairwise":
        for a, b in itertools.combinations(cameras, 2):
            both = singles[a].used & singles[b].used
            if both.sum() < 3:
                raise CalibrationError(f"cameras {a!r} and {b!r} saw the board together in only "
                                       f"{int(both.sum())} views (need at least 3)")
            sa = replace(singles[a], used=both)
            sb = replace(singles[b], used=both)
            report("rig", f"stereo calibration of the pair {a}-{b} ({int(both.sum())} views) ...")
            pair_results[(a, b)] = bundle_adjust([views[a], views[b]], [sa, sb], bp, fix_k3=fix_k3)
    report("rig", "joint bundle adjustment of every camera ...")
    joint = bundle_adjust([views[c] for c in order], [singles[c] for c in order], bp, fix_k3=fix_k3)

    result = RigCalibration(None, mode, reference, cameras, inner_corners, float(square_m), views, singles,
                            pair_results, joint, tuple(flipped))
    if mode == "joint":
        rig = joint.rig({"method": "joint bundle adjustment"})
        rig = Rig(tuple(rig[c] for c in cameras), rig.metadata)
    else:
        rig = pairwise_rig(result)
    return replace(result, rig=rig)


def pair_rig(result: "RigCalibration", a: str, b: str) -> Rig:
    """The two cameras of one stereo pair with that pair's own calibration (world = camera ``a``).

    This is how the thesis triangulated (section 5.1): each pair with the
    intrinsics and pose of its own stereo calibration.
    """
    r, t, ia, ib = _pair(result.pairs, a, b)
    return Rig((ia.as_camera(), ib.as_camera(r, t)), {"adjusted": False, "method": f"stereo pair {a}-{b}"})


def pairwise_rig(result: "RigCalibration", fix_k3: bool = True) -> Rig:
    """A consistent rig from pairwise stereo calibrations (one set of intrinsics per camera).

    Each camera keeps its own single-camera calibration (Tables 8.1-8.3,
    "alone"); every other camera is placed by a stereo calibration with the
    reference camera in which the intrinsics are held fixed (only the relative
    pose and the board poses are refined). Unlike :func:`rig_from_pairs`, the
    reference camera has one set of intrinsics for every pair.
    """
    ref = result.reference
    bp = board_points(result.inner_corners, result.square_m)
    cams = []
    errs = []
    for c in result.cameras:
        if c == ref:
            cams.append(result.singles[c].as_camera())
            continue
        both = result.singles[ref].used & result.singles[c].used
        sa = replace(result.singles[ref], used=both)
        sb = replace(result.singles[c], used=both)
        p = bundle_adjust([result.views[ref], result.views[c]], [sa, sb], bp, fix_k3=fix_k3, fix_intrinsics=True)
        errs.append(p.rms)
        cams.append(result.singles[c].as_camera(p.rotations[1], p.translations[1]))
    return Rig(tuple(cams), {"adjusted": False, "method": "pairwise stereo, intrinsics of each camera alone",
                             "error": round(float(np.sqrt(np.mean(np.square(errs)))), 6) if errs else 0.0})


def _pair(pairs: dict, a: str, b: str):
    """Pose of ``b`` relative to ``a`` (rvec, tvec) and the intrinsics of both, from either key order."""
    if (a, b) in pairs:
        p = pairs[(a, b)]
        return p.rotations[1], p.translations[1], p.intrinsics[a], p.intrinsics[b]
    p = pairs[(b, a)]
    R = rotation_matrix(p.rotations[1])
    return rotation_vector(R.T), -R.T @ p.translations[1], p.intrinsics[a], p.intrinsics[b]


def rig_from_pairs(pairs: dict, cameras, reference: str) -> Rig:
    """The thesis' pairs put literally into one rig (mixed intrinsics: a pitfall).

    Camera ``c`` gets the pose ``(R_cRef, t_cRef)`` and the intrinsics of the
    pair (reference, c); the reference camera gets the intrinsics of its pair
    with the first other camera (thesis: left-middle, Table 8.1 column 1).
    The pose of the right camera was estimated together with *other*
    reference intrinsics (Table 8.1 column 2): a few pixels of principal
    point tilt the reference rays, and with short baselines far away the
    depth scale through that pair goes wrong (measured in
    ``notebooks/03_calibration.ipynb``). Use :func:`pairwise_rig` or the joint
    calibration for a rig; use :func:`pair_rig` to triangulate pair by pair.
    """
    cams = []
    others = [c for c in cameras if c != reference]
    for c in cameras:
        if c == reference:
            _, _, ia, _ = _pair(pairs, reference, others[0])
            cams.append(ia.as_camera())
        else:
            r, t, _, ib = _pair(pairs, reference, c)
            cams.append(ib.as_camera(r, t))
    errs = [p.rms for k, p in pairs.items() if reference in k]
    return Rig(tuple(cams), {"adjusted": False, "method": "pairwise stereo (thesis 3.5)",
                             "error": round(float(np.sqrt(np.mean(np.square(errs)))), 6)})


@dataclass(frozen=True)
class RigComparison:
    """How two rigs (e.g. pairwise and joint) differ, camera by camera.

    Attributes
    ----------
    cameras : tuple of str
    center_mm : ndarray (cameras,)
        Distance between the optical centres, mm.
    angle_deg : ndarray (cameras,)
        Angle of the rotation between the orientations, degrees.
    focal_pct : ndarray (cameras, 2)
        Relative difference of ``fx, fy``, percent.
    cc_px : ndarray (cameras, 2)
        Difference of ``cx, cy``, pixels.
    baseline_mm : dict[tuple, tuple]
        ``(a, b) -> (baseline in rig A, baseline in rig B)``, mm.
    """

    cameras: tuple
    center_mm: np.ndarray
    angle_deg: np.ndarray
    focal_pct: np.ndarray
    cc_px: np.ndarray
    baseline_mm: dict


def compare_rigs(rig_a: Rig, rig_b: Rig) -> RigComparison:
    """Differences between two rigs with the same cameras and world frame."""
    names = tuple(rig_a.names)
    cen, ang, foc, ccd = [], [], [], []
    for n in names:
        a, b = rig_a[n], rig_b[n]
        cen.append(1000 * np.linalg.norm(a.center - b.center))
        Rd = a.rotation_matrix.T @ b.rotation_matrix
        ang.append(np.degrees(np.arccos(np.clip((np.trace(Rd) - 1) / 2, -1, 1))))
        foc.append(100 * (b.focal - a.focal) / a.focal)
        ccd.append(b.principal_point - a.principal_point)
    base = {}
    for x, y in itertools.combinations(names, 2):
        base[(x, y)] = (1000 * np.linalg.norm(rig_a[x].center - rig_a[y].center),
                        1000 * np.linalg.norm(rig_b[x].center - rig_b[y].center))
    return RigComparison(names, np.array(cen), np.array(ang), np.array(foc), np.array(ccd), base)


def pair_closure(result: RigCalibration) -> dict:
    """How far the third pair disagrees with the two pairs of the reference camera.

    Thesis Table 8.4 holds three pairs that were calibrated separately; the
    pose of the middle-right pair ``(R_RM, t_RM)`` should equal
    ``R_RL R_ML^T`` and ``t_RL - R_RM t_ML``. Returns, for each pair without the
    reference camera, ``{"pair": (a, b), "angle_deg": .., "translation_mm": ..}``.
    """
    ref = result.reference
    out = []
    for (a, b), p in result.pairs.items():
        if ref in (a, b):
            continue
        ra, ta, _, _ = _pair(result.pairs, ref, a)
        rb, tb, _, _ = _pair(result.pairs, ref, b)
        Ra, Rb = rotation_matrix(ra), rotation_matrix(rb)
        R_ba = Rb @ Ra.T
        t_ba = tb - R_ba @ ta
        Rp = rotation_matrix(p.rotations[1])
        ang = np.degrees(np.arccos(np.clip((np.trace(Rp.T @ R_ba) - 1) / 2, -1, 1)))
        out.append({"pair": (a, b), "angle_deg": float(ang),
                    "translation_mm": float(1000 * np.linalg.norm(p.translations[1] - t_ba)),
                    "composed_T_mm": 1000 * t_ba, "pair_T_mm": 1000 * p.translations[1],
                    "composed_om": rotation_vector(R_ba), "pair_om": p.rotations[1]})
    return out
