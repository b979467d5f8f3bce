"""Import the result files of Bouguet's Camera Calibration Toolbox for MATLAB.

The thesis calibrated with the toolbox (Appendix A steps 2-3) and saved
``Calib_Results_left.mat`` ... and ``Calib_Results_stereo_left_middle.mat``
...; a lab with such files brings them along here. The toolbox's model is
OpenCV's (thesis eq. 3.4-3.10): ``KK = [fc(1) alpha_c*fc(1) cc(1); 0 fc(2)
cc(2); 0 0 1]``, ``kc = [k1 k2 p1 p2 k3]``, pixel ``[0, 0]`` at the centre of
the top-left pixel (checked: the toolbox's stored corners ``x_i`` of the
stereo example agree with OpenCV's to 0.002 px). Stereo: ``x_right = R
x_left + T`` with ``om`` the Rodrigues vector of ``R``. Lengths are in the
unit of the board squares ``dX`` (mm in the thesis and the example).

Numbers are returned exactly as stored (``scipy.io.loadmat(...,
mat_dtype=True)``); only :func:`rig_from_bouguet_stereo` converts lengths to
metres.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.io as sio

from ..camera import Camera, Rig
from .board import CalibrationError


def _load(path) -> dict:
    path = Path(path)
    if not path.is_file():
        raise CalibrationError(f"{path}: Bouguet result file not found")
    try:
        return sio.loadmat(str(path), mat_dtype=True)
    except Exception as exc:  # scipy raises several types for a bad file
        raise CalibrationError(f"{path}: not a MATLAB .mat file readable by scipy ({exc})") from None


def _get(d, key, path, n=None, default=None):
    if key not in d:
        if default is not None:
            return default
        raise CalibrationError(f"{path}: variable '{key}' missing (is this a Calib_Results file of Bouguet's toolbox?)")
    v = np.asarray(d[key], float).ravel()
    if n is not None and v.size != n:
        raise CalibrationError(f"{path}: variable '{key}' has {v.size} values, expected {n}")
    return v


@dataclass(frozen=True)
class BouguetSingle:
    """One camera's ``Calib_Results.mat`` (toolbox's ``calib_gui``).

    Attributes mirror the toolbox's variables: ``fc, cc, kc, alpha_c, KK`` and
    their 3-sigma errors ``fc_error, cc_error, kc_error, alpha_c_error``;
    ``err_std`` (pixel error std), ``n_ima``, ``active_images`` (bool),
    ``size = (nx, ny)``, ``dX, dY``; per view ``omc, Tc`` (n_ima, 3; NaN for
    inactive views) and ``x`` (list of (N, 2) corners, None for inactive).
    """

    path: Path
    fc: np.ndarray
    cc: np.ndarray
    kc: np.ndarray
    alpha_c: float
    KK: np.ndarray
    fc_error: np.ndarray
    cc_error: np.ndarray
    kc_error: np.ndarray
    alpha_c_error: float
    err_std: np.ndarray
    n_ima: int
    active_images: np.ndarray
    size: tuple
    dX: float
    dY: float
    omc: np.ndarray
    Tc: np.ndarray
    x: tuple

    def camera(self, name: str = "camera") -> Camera:
        """The toolbox's camera as a :class:`~horsemocap.camera.Camera` at the origin."""
        return Camera(name, self.size, self.KK, self.kc)


def load_bouguet_single(path) -> BouguetSingle:
    """Read a single-camera ``Calib_Results.mat`` of Bouguet's toolbox (exact numbers)."""
    path = Path(path)
    d = _load(path)
    n = int(_get(d, "n_ima", path, 1)[0])
    active = _get(d, "active_images", path, default=np.ones(n)).astype(bool)
    omc, Tc, xs = np.full((n, 3), np.nan), np.full((n, 3), np.nan), []
    for i in range(1, n + 1):
        if f"omc_{i}" in d and active[i - 1]:
            omc[i - 1] = _get(d, f"omc_{i}", path, 3)
            Tc[i - 1] = _get(d, f"Tc_{i}", path, 3)
        x = d.get(f"x_{i}")
        xs.append(np.asarray(x, float).T.copy() if x is not None and active[i - 1] and np.size(x) else None)
    alpha = float(_get(d, "alpha_c", path, default=np.zeros(1))[0])
    return BouguetSingle(
        path, _get(d, "fc", path, 2), _get(d, "cc", path, 2), _get(d, "kc", path, 5), alpha,
        np.asarray(d["KK"], float) if "KK" in d else None,
        _get(d, "fc_error", path, 2), _get(d, "cc_error", path, 2), _get(d, "kc_error", path, 5),
        float(_get(d, "alpha_c_error", path, default=np.zeros(1))[0]),
        _get(d, "err_std", path, 2), n, active,
        (int(_get(d, "nx", path, 1)[0]), int(_get(d, "ny", path, 1)[0])),
        float(_get(d, "dX", path, 1)[0]), float(_get(d, "dY", path, 1)[0]), omc, Tc, tuple(xs))


@dataclass(frozen=True)
class BouguetStereo:
    """A ``Calib_Results_stereo.mat`` of the toolbox's ``stereo_gui``.

    Attributes
    ----------
    left, right : dict
        ``fc, cc, kc, alpha_c, KK`` and ``fc_error, cc_error, kc_error`` of each
        camera as refined by the stereo optimisation.
    om, R, T : ndarray
        ``x_right = R x_left + T``; ``om`` Rodrigues vector; ``T`` in ``dX`` units.
    om_error, T_error : ndarray (3,)
        Three standard deviations.
    size : (nx, ny)
    dX : float
    names : (str, str)
        ``calib_name_left``, ``calib_name_right`` (file prefixes of the views).
    """

    path: Path
    left: dict
    right: dict
    om: np.ndarray
    R: np.ndarray
    T: np.ndarray
    om_error: np.ndarray
    T_error: np.ndarray
    size: tuple
    dX: float
    names: tuple


def load_bouguet_stereo(path) -> BouguetStereo:
    """Read a ``Calib_Results_stereo.mat`` of Bouguet's toolbox (exact numbers)."""
    path = Path(path)
    d = _load(path)
    sides = {}
    for side in ("left", "right"):
        s = {k: _get(d, f"{k}_{side}", path, n) for k, n in (("fc", 2), ("cc", 2), ("kc", 5))}
        s.update({f"{k}_error": _get(d, f"{k}_{side}_error", path, n) for k, n in (("fc", 2), ("cc", 2), ("kc", 5))})
        s["alpha_c"] = float(_get(d, f"alpha_c_{side}", path, default=np.zeros(1))[0])
        s["KK"] = np.asarray(d[f"KK_{side}"], float) if f"KK_{side}" in d else None
        sides[side] = s

    def _name(key, default):
        v = d.get(key)
        return str(np.asarray(v).ravel()[0]) if v is not None and np.size(v) else default

    size = (int(_get(d, "nx", path, 1)[0]), int(_get(d, "ny", path, 1)[0]))
    return BouguetStereo(path, sides["left"], sides["right"], _get(d, "om", path, 3),
                         np.asarray(d["R"], float) if "R" in d else None, _get(d, "T", path, 3),
                         _get(d, "om_error", path, 3), _get(d, "T_error", path, 3), size,
                         float(_get(d, "dX", path, default=np.array([np.nan]))[0]),
                         (_name("calib_name_left", "left"), _name("calib_name_right", "right")))


def _kk(fc, cc, alpha):
    return np.array([[fc[0], alpha * fc[0], cc[0]], [0.0, fc[1], cc[1]], [0.0, 0.0, 1.0]])


def rig_from_bouguet_stereo(path, names: tuple[str, str] | None = None, unit_m: float = 1e-3) -> Rig:
    """A two-camera :class:`~horsemocap.camera.Rig` from the toolbox's stereo result.

    Parameters
    ----------
    path : Path
        ``Calib_Results_stereo.mat``.
    names : (str, str), optional
        Camera names; default the toolbox's ``calib_name_left/right``.
    unit_m : float
        Metres per unit of ``dX`` (the toolbox stores lengths in the unit the
        user gave the squares in; mm in the thesis and in the example).
    """
    s = load_bouguet_stereo(path)
    names = names or s.names
    left = Camera(names[0], s.size, _kk(s.left["fc"], s.left["cc"], s.left["alpha_c"]), s.left["kc"])
    right = Camera(names[1], s.size, _kk(s.right["fc"], s.right["cc"], s.right["alpha_c"]), s.right["kc"],
                   s.om, s.T * unit_m)
    return Rig((left, right), {"adjusted": False, "source": f"Bouguet toolbox: {Path(path).name}"})


def rig_from_bouguet_pairs(pair_files: dict, reference: str = "left", unit_m: float = 1e-3) -> Rig:
    """The thesis' 3-camera rig from the toolbox's pair files (Appendix A step 3).

    Parameters
    ----------
    pair_files : dict[(str, str), Path]
        ``{("left", "middle"): "Calib_Results_stereo_left_middle.mat", ...}``;
        the pairs with the reference camera place the other cameras (thesis
        section 5.1 uses ``R_ML, t_ML`` and ``R_RL, t_RL``).
    """
    cams = {}
    for (a, b), f in pair_files.items():
        if reference not in (a, b):
            continue
        if a != reference:
            raise CalibrationError(f"pair {(a, b)}: the reference camera {reference!r} must be the pair's left camera")
        r = rig_from_bouguet_stereo(f, (a, b), unit_m)
        cams.setdefault(a, r[a])
        cams[b] = r[b]
    if reference not in cams:
        raise CalibrationError(f"no pair file includes the reference camera {reference!r}")
    order = [reference] + [c for c in cams if c != reference]
    return Rig(tuple(cams[c] for c in order), {"adjusted": False, "source": "Bouguet toolbox pairs"})
