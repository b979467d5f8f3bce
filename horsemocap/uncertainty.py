"""How uncertain the saddle's vertical acceleration is, from what the run itself measured.

The saddle's acceleration comes from a smoothed pose trajectory (:mod:`horsemocap.pose`): the centroid
``c(t)`` and the rotation vector ``phi(t)``, each a partial smoothing spline (stride harmonics kept whole,
the rest penalised), and the saddle's point in the static shot carried by the rotation
(``a = c'' + alpha x r + omega x (omega x r)``). Once its choices are made (the smoothing parameter, the
harmonics kept) the smoother is linear, so three cheap parts bound the vertical acceleration's error:

``noise``
    The registration noise of ``c_y`` (and of the rotation, through the saddle's lever) passed through
    the smoother: away from the record's ends a quintic smoothing spline is the filter
    ``g(f) = 1 / (1 + lam dt (2 pi f)^6)`` (:func:`horsemocap.splines.half_gain_frequency`), each kept
    harmonic is a least-squares term whose cosine and sine carry ``2 sigma^2 / n`` each; differentiated
    twice the variance is ``sigma^2 [2 dt integral (2 pi f)^4 g(f)^2 df + sum_k (2 pi k f0)^4 2 / n]``.
``unresolved``
    The stride harmonics the smoothing did not keep (above the last kept one, up to 0.8 of the Nyquist
    frequency): the spline passes only ``g(f_k)`` of each, and the record cannot tell a harmonic smaller
    than its detection floor (two standard deviations of its least-squares amplitude,
    ``2 sigma sqrt(2 / n)``) from noise. Each may hide up to its measured amplitude plus that floor;
    in acceleration, ``(1 - g(f_k)) (2 pi k f0)^2`` times that, as an rms (``/ sqrt 2``).
``static_offset``
    The saddle's point is known only in the static shot, relative to the marker triangle; a triangle of
    smallest height ``h`` measured with marker noise ``sigma_m`` is tilted by about ``sigma_m sqrt 2 / h``
    and the saddle's lever ``r`` moves by that angle times ``|r|``; the angular acceleration turns that
    offset into an acceleration error ``|alpha| |delta r|``.

The total is the root sum of squares; it is given in m/s^2 and as a percentage of the estimated
vertical acceleration's rms (the measure the accuracy of the saddle's acceleration is reported in).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .pose import PoseTrajectory, pose_noise, smallest_height
from .splines import harmonic_amplitudes

#: Highest harmonic frequency considered, as a share of the sampling rate (0.8 of the Nyquist frequency,
#: as the partial spline's own candidates).
HARMONIC_LIMIT_OF_RATE = 0.4
#: Most stride harmonics considered.
MAX_HARMONICS = 10
#: Standard deviations of a harmonic's least-squares amplitude below which it is not detected.
DETECTION_SD = 2.0


@dataclass(frozen=True)
class AccelerationUncertainty:
    """The parts of the saddle vertical acceleration's uncertainty (rms, m/s^2) and their total.

    ``pct_of_rms``: ``total`` as a percentage of the estimated vertical acceleration's rms."""

    noise: float
    unresolved: float
    static_offset: float
    total: float
    rms: float
    pct_of_rms: float


def spline_gain(freq_hz, lam: float, dt: float) -> np.ndarray:
    """Gain of a quintic smoothing spline of uniformly sampled data at ``freq_hz``.

    Examples
    --------
    >>> dt = 0.01
    >>> lam = 1 / (dt * (2 * np.pi * 6.0) ** 6)
    >>> float(spline_gain(6.0, lam, dt))
    0.5
    """
    w = 2 * np.pi * np.asarray(freq_hz, float)
    return 1.0 / (1.0 + max(float(lam), 0.0) * dt * w ** 6)


def smoothed_acceleration_noise(sigma: float, lam: float, dt: float, n: int, fundamental_hz=None,
                                kept=()) -> float:
    """Standard deviation of the second derivative of a partial quintic smoothing spline fitted to white noise.

    ``sigma``: the samples' noise; ``lam`` and ``dt`` the spline's smoothing parameter and sampling interval;
    ``n`` samples; ``kept`` the harmonic orders of ``fundamental_hz`` fitted unpenalised.

    Examples
    --------
    >>> dt, lam = 0.02, 1 / (0.02 * (2 * np.pi * 5.0) ** 6)
    >>> round(smoothed_acceleration_noise(1e-3, lam, dt, 100), 3)
    0.184
    """
    f = np.linspace(0.0, 0.5 / dt, 2001)
    g = spline_gain(f, lam, dt)
    var = 2 * dt * np.trapezoid((2 * np.pi * f) ** 4 * g ** 2, f)
    if fundamental_hz:
        var += sum((2 * np.pi * k * fundamental_hz) ** 4 * 2.0 / n for k in kept)
    return float(sigma * np.sqrt(var))


def unresolved_harmonics_acceleration(t, y, sigma: float, lam: float, fundamental_hz, kept,
                                      detection_sd: float = DETECTION_SD) -> float:
    """Rms acceleration the smoothing may have taken from the stride harmonics it did not keep.

    For each harmonic above the last kept one, up to :data:`HARMONIC_LIMIT_OF_RATE` of the sampling rate:
    its least-squares amplitude in ``y`` plus its detection floor (``detection_sd`` standard deviations,
    ``sigma sqrt(2 / n)`` each; 0: the measured amplitudes alone, what the smoothing most likely removed), times the part of it the spline removes and ``(2 pi f_k)^2``; the root sum
    of squares of their rms values.

    Examples
    --------
    >>> t = np.arange(100) / 25.0
    >>> y = 1e-3 * np.sin(2 * np.pi * 1.5 * t)
    >>> a = unresolved_harmonics_acceleration(t, y, 1e-4, 1e-9, 1.5, [1])
    >>> bool(a > 0)
    True
    """
    t = np.asarray(t, float)
    y = np.asarray(y, float)
    if not fundamental_hz or t.size < 8:
        return 0.0
    dt = float(np.median(np.diff(t)))
    kmax = int(min(MAX_HARMONICS, np.floor(HARMONIC_LIMIT_OF_RATE / dt / fundamental_hz + 1e-9)))
    first = max(list(kept), default=0) + 1
    if kmax < first or 3 + 2 * kmax >= t.size - 2:
        return 0.0
    amp = harmonic_amplitudes(t, y, fundamental_hz, kmax)
    floor = detection_sd * sigma * np.sqrt(2.0 / t.size)
    total = 0.0
    for k in range(first, kmax + 1):
        fk = k * fundamental_hz
        hidden = (1 - spline_gain(fk, lam, dt)) * (2 * np.pi * fk) ** 2 * (amp[k - 1] + floor) / np.sqrt(2)
        total += float(hidden) ** 2
    return float(np.sqrt(total))


def _component(info: dict):
    """(lam, fundamental or None, kept harmonic orders) of a pose component's smoothing."""
    f0 = info.get("fundamental_hz")
    kept = [int(k) for k in info.get("harmonic_indices", range(1, int(info.get("harmonics", 0)) + 1))]
    return float(info.get("lam", np.nan)), (float(f0) if f0 else None), kept


def saddle_vertical_uncertainty(pose: PoseTrajectory, model, saddle_static, alpha, saddle_acceleration,
                                axis: int = 1, detection_sd: float = DETECTION_SD) -> AccelerationUncertainty:
    """The saddle vertical acceleration's uncertainty from the pose trajectory it came from (module docstring).

    Parameters
    ----------
    pose : horsemocap.pose.PoseTrajectory
        The smoothed pose (its registration, splines and their choices).
    model : (m, 3) array
        The static shot's markers; ``saddle_static`` (3,) the saddle's point in it.
    alpha : (n, 3) array
        Angular acceleration (rad/s^2); ``saddle_acceleration`` (n, 3) the saddle's (m/s^2).
    axis : int
        The vertical axis of the motion frame.
    detection_sd : float
        The unresolved harmonics' detection floor in standard deviations of their amplitudes
        (:func:`unresolved_harmonics_acceleration`).

    Returns
    -------
    AccelerationUncertainty
    """
    reg = pose.registration
    model = np.asarray(model, float)
    sig = pose_noise(reg, None, model)
    ok = np.isfinite(np.asarray(reg.centre, float)).all(1)
    t = pose.t[ok]
    dt = float(np.median(np.diff(pose.t)))
    n = int(ok.sum())
    info = pose.smoothing
    lam, f0, kept = _component(info["cy"])
    y = np.asarray(reg.centre, float)[ok, axis]
    noise_c, unresolved = float("nan"), 0.0
    if np.isfinite(lam):
        noise_c = smoothed_acceleration_noise(sig[axis], lam, dt, n, f0, kept)
        unresolved = unresolved_harmonics_acceleration(t, y, sig[axis], lam, f0, kept, detection_sd)
    # the rotation's noise through the saddle's lever: the vertical part of delta_alpha x r
    lever = np.asarray(saddle_static, float) - model.mean(0)
    R0 = np.nanmean(pose.rotation(pose.t), axis=0)
    r = R0 @ lever
    others = [i for i in range(3) if i != axis]
    noise_r2 = 0.0
    for i, name in enumerate(("phix", "phiy", "phiz")):
        if i == axis:
            continue
        lam_i, f_i, kept_i = _component(info[name])
        if not np.isfinite(lam_i) or not np.isfinite(sig[3 + i]):
            continue
        s_alpha = smoothed_acceleration_noise(sig[3 + i], lam_i, dt, n, f_i, kept_i)
        partner = others[1] if i == others[0] else others[0]
        noise_r2 += (s_alpha * r[partner]) ** 2
    noise = float(np.sqrt(noise_c ** 2 + noise_r2))
    # the static shot's tilt of a thin triangle moves the saddle's lever
    height = float(np.nanmin(smallest_height(model[None])))
    marker_noise = float(reg.noise_m) if np.isfinite(reg.noise_m) else 0.0
    tilt = marker_noise * np.sqrt(2.0) / max(height, 1e-9)
    al = np.asarray(alpha, float)
    alpha_rms = float(np.sqrt(np.nanmean(np.sum(al ** 2, 1))))
    static_offset = alpha_rms * tilt * float(np.linalg.norm(lever)) * np.sqrt(2.0 / 3.0)
    total = float(np.sqrt(noise ** 2 + unresolved ** 2 + static_offset ** 2))
    ay = np.asarray(saddle_acceleration, float)[:, axis]
    rms = float(np.sqrt(np.nanmean(ay ** 2)))
    return AccelerationUncertainty(noise, unresolved, static_offset, total, rms, 100 * total / rms)
