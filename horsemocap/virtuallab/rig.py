"""The thesis' 3-camera rig (Dogan 2009, section 8.1-8.2, Tables 8.1-8.4).

Three Casio EX-Z750 cameras, 640 x 480 at 30 fps, placed "as parallel as
possible" about 7.5 m from the path (Figure 8.1). Intrinsics come from
Tables 8.1-8.3, extrinsics from Table 8.4. The toolbox convention is
``x_right = R x_left + T`` (Bouguet), which is OpenCV's ``x_cam = R x_world +
t`` with the left camera as the world frame (thesis ``CM_L``).

Each camera was calibrated twice (once in each stereo pair it belongs to); the
rig uses, for every camera, the intrinsics of the pair that also gives its
extrinsics: left and middle from the left-middle calibration, right from the
left-right calibration. Table 8.4's three pairwise results do not compose
exactly (``R_RL != R_RM R_ML``): :func:`pair_disagreement` measures by how
much the middle-right pair disagrees with the rig built from the other two.
The table's rotation matrices are printed to 4 decimals and are not exactly
orthonormal; they are projected onto SO(3) (nearest rotation, SVD) first.
"""
from __future__ import annotations

import numpy as np

from ..camera import Camera, Rig, rotation_matrix, rotation_vector

SIZE = (640, 480)
FPS = 30.0

#: Table 8.1-8.3: per camera and per calibration pair, focal [fx, fy],
#: principal point [u0, v0] (pixels) and distortion [k1, k2, p1, p2].
INTRINSICS = {
    "left": {
        "left-middle": dict(fc=[729.84486, 728.16638], cc=[326.62643, 234.60562],
                            kc=[-0.12752, 0.01808, -0.00097, 0.00176]),
        "left-right": dict(fc=[723.61911, 722.43205], cc=[329.24776, 234.55332],
                           kc=[-0.13068, 0.02705, -0.00147, 0.00287]),
    },
    "middle": {
        "left-middle": dict(fc=[734.75323, 733.19973], cc=[314.71229, 232.66709],
                            kc=[-0.13507, 0.00775, -0.00087, 0.00122]),
        "middle-right": dict(fc=[736.99696, 735.78218], cc=[316.70410, 229.73023],
                             kc=[-0.13766, 0.00772, -0.00191, 0.00238]),
    },
    "right": {
        "left-right": dict(fc=[717.21907, 715.47318], cc=[309.66787, 230.92801],
                           kc=[-0.13740, 0.06109, -0.00216, -0.00039]),
        "middle-right": dict(fc=[722.57069, 720.80392], cc=[309.43864, 228.05798],
                             kc=[-0.13461, 0.04621, -0.00266, -0.00006]),
    },
}

#: Table 8.4: x_second = R x_first + t, t in mm, for the pairs
#: left-middle (R_ML, t_ML), left-right (R_RL, t_RL), middle-right (R_RM, t_RM).
EXTRINSICS = {
    "left-middle": dict(
        R=[[0.9998, 0.0046, 0.0208], [-0.0043, 0.9999, -0.0108], [-0.0208, 0.0107, 0.9997]],
        t_mm=[-238.05656, -4.25963, -13.06120]),
    "left-right": dict(
        R=[[0.9963, 0.0363, 0.078], [-0.0355, 0.9993, -0.0123], [-0.0784, 0.0095, 0.9969]],
        t_mm=[-446.97074, -3.85081, 10.56836]),
    "middle-right": dict(
        R=[[0.9979, 0.0314, 0.0573], [-0.0314, 0.9995, -0.0007], [-0.0573, -0.0011, 0.9984]],
        t_mm=[-217.29207, -6.69612, -18.79435]),
}

#: Which calibration pair supplies each camera's intrinsics in the rig.
RIG_INTRINSICS_FROM = {"left": "left-middle", "middle": "left-middle", "right": "left-right"}


def table_rotation(pair: str) -> np.ndarray:
    """Table 8.4 rotation of a pair, projected onto SO(3) (nearest rotation)."""
    return rotation_matrix(rotation_vector(np.asarray(EXTRINSICS[pair]["R"], float)))


def table_translation(pair: str) -> np.ndarray:
    """Table 8.4 translation of a pair in metres."""
    return np.asarray(EXTRINSICS[pair]["t_mm"], float) / 1000.0


def thesis_camera(name: str, pair: str | None = None, rotation=None, translation=None) -> Camera:
    """One camera with Table 8.1-8.3 intrinsics (``k3 = 0``).

    Parameters
    ----------
    name : {"left", "middle", "right"}
    pair : str, optional
        Which calibration supplied the intrinsics (default: the rig's choice,
        :data:`RIG_INTRINSICS_FROM`).
    """
    pair = pair or RIG_INTRINSICS_FROM[name]
    p = INTRINSICS[name][pair]
    K = np.array([[p["fc"][0], 0.0, p["cc"][0]], [0.0, p["fc"][1], p["cc"][1]], [0.0, 0.0, 1.0]])
    return Camera(name=name, size=SIZE, matrix=K, distortions=list(p["kc"]) + [0.0],
                  rotation=np.zeros(3) if rotation is None else rotation,
                  translation=np.zeros(3) if translation is None else translation)


def thesis_rig() -> Rig:
    """The thesis rig: cameras ``left`` (reference), ``middle``, ``right``.

    World frame = left camera frame (metres, OpenCV axes: x right, y down,
    z forward). Middle from the left-middle pair (``R_ML, t_ML``), right from
    the left-right pair (``R_RL, t_RL``) of Table 8.4.

    Examples
    --------
    >>> rig = thesis_rig()
    >>> rig.names, rig["left"].size
    (['left', 'middle', 'right'], (640, 480))
    """
    cams = [thesis_camera("left")]
    for name, pair in (("middle", "left-middle"), ("right", "left-right")):
        cams.append(thesis_camera(name, rotation=rotation_vector(table_rotation(pair)),
                                  translation=table_translation(pair)))
    return Rig(tuple(cams), {"adjusted": False, "source": "Dogan 2009 Tables 8.1-8.4 (virtual laboratory truth)"})


def rotation_angle_deg(R: np.ndarray) -> float:
    """Angle (degrees) of a rotation matrix."""
    c = (np.trace(R) - 1.0) / 2.0
    return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))


def pair_disagreement(rig: Rig | None = None) -> dict:
    """How far Table 8.4's middle-right pair disagrees with the composed rig.

    The rig implies ``R_RM' = R_RL R_ML^T`` and ``t_RM' = t_RL - R_RM' t_ML``;
    the table gives ``R_RM, t_RM`` from the middle-right calibration.

    Returns
    -------
    dict
        ``translation_mm`` (norm of ``t_RM' - t_RM``), ``translation_diff_mm``
        (the vector), ``rotation_deg`` (angle of ``R_RM' R_RM^T``),
        ``baseline_rig_mm`` and ``baseline_table_mm`` (norms), and the
        composed ``R_RM_rig`` / ``t_RM_rig_mm``.
    """
    rig = rig or thesis_rig()
    Rm, tm = rig["middle"].rotation_matrix, rig["middle"].translation
    Rr, tr = rig["right"].rotation_matrix, rig["right"].translation
    R_rm = Rr @ Rm.T
    t_rm = tr - R_rm @ tm
    R_tab, t_tab = table_rotation("middle-right"), table_translation("middle-right")
    dt = (t_rm - t_tab) * 1000.0
    return {
        "translation_mm": float(np.linalg.norm(dt)),
        "translation_diff_mm": dt,
        "rotation_deg": rotation_angle_deg(R_rm @ R_tab.T),
        "baseline_rig_mm": float(np.linalg.norm(t_rm) * 1000.0),
        "baseline_table_mm": float(np.linalg.norm(t_tab) * 1000.0),
        "R_RM_rig": R_rm,
        "t_RM_rig_mm": t_rm * 1000.0,
    }
