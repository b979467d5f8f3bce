"""Guards for the notebooks whose cells show the thesis' three-marker construction.

The thesis' chain (body frame of markers 1, 2, 3, eq. 6.41-6.48; the six
versions of omega and alfa, eq. 6.3/6.4, 6.38/6.39; the Fourier motion fits
of section 5.5) follows exactly three skin markers. The pipeline registers
four or more over all markers seen (:mod:`horsemocap.pose`) and leaves the
chain out when the session has more than three markers or no period
(``RigidBodyAnalysis.motion_fit`` is then None and ``chain_error`` says
why). These helpers let a notebook say so in plain words and show the
thesis' formulas on the thesis' three markers (the first three of the
pipeline's static-shot model, the ones its body frame uses) with the
pipeline's own smoothed kinematics, instead of a traceback or a silent NaN.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["marker_numbers", "marker_pairs", "thesis_three_note", "fits_note", "thesis_view", "table_8_7_ride"]

THESIS_MARKERS = 3
"""The skin markers the thesis' formulas take (markers 1, 2, 3)."""

TABLE_8_7_RIDE = ("Horse 2", "canter")
"""The ride of the thesis' Table 8.7 (section 8.5)."""


def marker_numbers(n: int, sep: str = ", ") -> str:
    """The markers' numbers 1..n as text.

    Parameters
    ----------
    n : int
        The session's marker count (``Session.marker_count``).
    sep : str
        Between two numbers.

    Examples
    --------
    >>> marker_numbers(3)
    '1, 2, 3'
    >>> marker_numbers(4)
    '1, 2, 3, 4'
    """
    return sep.join(str(i + 1) for i in range(int(n)))


def marker_pairs(n: int) -> list[tuple[int, int]]:
    """Every pair of n markers: neighbours first (1-2, 2-3, ...), then the others.

    For three markers this is the thesis' order of the distances: 1-2, 2-3, 1-3.

    Examples
    --------
    >>> marker_pairs(3)
    [(0, 1), (1, 2), (0, 2)]
    >>> marker_pairs(4)
    [(0, 1), (1, 2), (2, 3), (0, 2), (0, 3), (1, 3)]
    """
    n = int(n)
    near = [(i, i + 1) for i in range(n - 1)]
    return near + [(i, j) for i in range(n) for j in range(i + 2, n)]


def thesis_three_note(n: int) -> str:
    """What a cell of the thesis' three-marker construction does with n markers ("" for three).

    Examples
    --------
    >>> thesis_three_note(3)
    ''
    >>> thesis_three_note(4)[:60]
    "the session has 4 markers; the thesis' construction takes th"
    """
    if int(n) == THESIS_MARKERS:
        return ""
    if int(n) < THESIS_MARKERS:
        return f"the session has {n} marker(s); the thesis' construction needs three"
    return (f"the session has {n} markers; the thesis' construction takes three: markers 1, 2, 3 (the first "
            f"three of the pipeline's static-shot model, as the pipeline's body frame does); the pipeline's "
            f"registration uses all {n} (markers {marker_numbers(n)})")


def fits_note(body) -> str:
    """Why the thesis' Fourier fits (``motion_fit``) are absent, in plain words ("" when they were computed).

    Parameters
    ----------
    body : horsemocap.rigid.RigidBodyAnalysis

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> fits_note(SimpleNamespace(motion_fit=None, chain_error="no period found"))[:58]
    "the thesis' Fourier fits (section 5.5) and its chain of eq"
    """
    if body.motion_fit is not None:
        return ""
    why = body.chain_error or "the record does not allow them"
    return (f"the thesis' Fourier fits (section 5.5) and its chain of eq. 6.3-6.55 were not computed for this "
            f"session: {why}. What stands in their place below is the pipeline's own result: every frame's pose "
            f"registered from all markers seen, its trajectory smoothed by splines (kinematics 'pose_spline', "
            f"no period needed), velocities and accelerations from that smoothed pose")


@dataclass(frozen=True)
class ThesisView:
    """The thesis' angular and saddle results on its three markers (:func:`thesis_view`).

    Attributes
    ----------
    chain : bool
        True when they are the pipeline's own (the thesis' chain ran).
    note : str
        Why not, in plain words (:func:`fits_note`); ``""`` when ``chain``.
    pos, vel, acc : (n, 3, 3) arrays
        Markers 1, 2, 3 and their derivatives.
    omega_raw, omega_versions, alpha_raw, alpha_versions : (6, n, 3) arrays
        The six versions of eq. 6.3/6.4 and 6.38/6.39, before and after smoothing.
    omega_lstsq, alpha_lstsq : (n, 3) arrays
        Least squares over all markers.
    omega_fit, alpha_fit : (n, 3) arrays
        The third estimate, named by ``fit_label``.
    fit_label : str
    saddle : horsemocap.rigid.SaddleKinematics
        Eq. 6.54/6.55 on the three markers.
    saddle_fit_label : str
    saddle_fit_velocity, saddle_fit_acceleration : (n, 3) arrays
        The saddle by the method ``saddle_fit_label`` names.
    """

    chain: bool
    note: str
    pos: np.ndarray
    vel: np.ndarray
    acc: np.ndarray
    omega_raw: np.ndarray
    omega_versions: np.ndarray
    alpha_raw: np.ndarray
    alpha_versions: np.ndarray
    omega_lstsq: np.ndarray
    alpha_lstsq: np.ndarray
    omega_fit: np.ndarray
    alpha_fit: np.ndarray
    fit_label: str
    saddle: object
    saddle_fit_label: str
    saddle_fit_velocity: np.ndarray
    saddle_fit_acceleration: np.ndarray


def thesis_view(body) -> ThesisView:
    """The thesis' angular and saddle formulas on the thesis' three markers, whatever the session.

    When the thesis' chain ran (three markers and a period), everything is the
    pipeline's own: its registered markers and their fitted derivatives, the
    six versions, least squares and the fit of the registered orientation.
    When it did not (``motion_fit`` None), the same formulas are applied to
    markers 1, 2, 3 of the pipeline's smoothed pose (``marker_kinematics``):
    the six versions of omega (eq. 6.3/6.4, smoothed as Appendix A step 11),
    of alfa (eq. 6.38/6.39, with the omega the pipeline passes on), least
    squares over *all* markers, and eq. 6.54/6.55 for the saddle; the third
    estimate is then the pipeline's pose trajectory.

    Parameters
    ----------
    body : horsemocap.rigid.RigidBodyAnalysis

    Returns
    -------
    ThesisView

    Examples
    --------
    >>> from horsemocap.workspace import results_for                      # doctest: +SKIP
    >>> view = thesis_view(results_for(until="rigid_body").rigid_body.body)  # doctest: +SKIP
    >>> view.omega_versions.shape                                          # doctest: +SKIP
    (6, 39, 3)
    """
    from .. import rigid

    if body.motion_fit is not None:
        return ThesisView(chain=True, note="", pos=body.pos, vel=body.vel, acc=body.acc,
                          omega_raw=body.omega_raw, omega_versions=body.omega_versions,
                          alpha_raw=body.alpha_raw, alpha_versions=body.alpha_versions,
                          omega_lstsq=body.omega_lstsq, alpha_lstsq=body.alpha_lstsq,
                          omega_fit=body.omega_rotation, alpha_fit=body.alpha_rotation,
                          fit_label="fit of the registered orientation", saddle=body.saddle,
                          saddle_fit_label=f"fit of the saddle path ({body.saddle_method})",
                          saddle_fit_velocity=body.saddle_velocity_direct,
                          saddle_fit_acceleration=body.saddle_acceleration_direct)
    pos_all, vel_all, acc_all = body.marker_kinematics
    pos, vel, acc = pos_all[:, :THESIS_MARKERS], vel_all[:, :THESIS_MARKERS], acc_all[:, :THESIS_MARKERS]
    omega, alpha = body.omega, body.alpha
    with np.errstate(all="ignore"):
        omega_raw = rigid.angular_velocity_versions(pos, vel)
        alpha_raw = rigid.angular_acceleration_versions(pos, vel, acc, omega)
        omega_lstsq = rigid.angular_velocity_lstsq(pos_all, vel_all)
        alpha_lstsq = rigid.angular_acceleration_lstsq(pos_all, acc_all, omega)
        saddle = rigid.saddle_kinematics(pos, vel, acc, omega, alpha, body.saddle_body)
    return ThesisView(chain=False, note=fits_note(body), pos=pos, vel=vel, acc=acc,
                      omega_raw=omega_raw, omega_versions=rigid.smooth_versions(omega_raw),
                      alpha_raw=alpha_raw, alpha_versions=rigid.smooth_versions(alpha_raw),
                      omega_lstsq=omega_lstsq, alpha_lstsq=alpha_lstsq, omega_fit=omega, alpha_fit=alpha,
                      fit_label="the pipeline's pose trajectory", saddle=saddle,
                      saddle_fit_label="the pipeline's pose trajectory (passed on)",
                      saddle_fit_velocity=body.saddle_velocity, saddle_fit_acceleration=body.saddle_acceleration)


def table_8_7_ride(metadata: dict) -> tuple[bool, str]:
    """Is a session the ride of the thesis' Table 8.7 (Horse 2, canter)? And the sentence that says so.

    Parameters
    ----------
    metadata : dict
        ``Session.metadata`` (its ``horse`` and ``gait``).

    Examples
    --------
    >>> table_8_7_ride({"horse": "Horse 2", "gait": "canter"})[0]
    True
    >>> table_8_7_ride({"horse": "Horse 1", "gait": "canter"})[1]
    "Table 8.7 is the thesis' Horse 2 at canter; this session is Horse 1 at canter: another ride, so the table is shown on its own, not beside this session's figures"
    """
    horse, gait = metadata.get("horse"), metadata.get("gait")
    same = (horse, gait) == TABLE_8_7_RIDE
    this = f"{horse or 'an unnamed horse'} at {gait or 'an unnamed gait'}"
    if same:
        return True, f"Table 8.7 is the thesis' Horse 2 at canter, the ride of this session ({this})"
    return False, (f"Table 8.7 is the thesis' Horse 2 at canter; this session is {this}: another ride, so the "
                   "table is shown on its own, not beside this session's figures")
