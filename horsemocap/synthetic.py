"""Non-periodic rigid motions with exact kinematics, for tests and benchmarks.

:func:`lift_with_ringing` is a non-periodic motion the kinematics must hold
on (what a rigid box of optical markers does in a lab): a lift, a hold, a
set-down and a decaying 10 Hz ringing after the set-down, sampled at 100 Hz
with marker noise. Every angle and translation is built from smooth
elementary functions whose first and second derivatives are carried along
exactly (:class:`Jet`), so the truth (position, velocity, acceleration of
any body point, omega, alpha) has no numerical error.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .camera import axis_rotations

__all__ = ["Jet", "minimum_jerk_step", "ringing", "lift_with_ringing"]


@dataclass(frozen=True)
class Jet:
    """A function of time with its first two derivatives: ``(f, f', f'')``.

    Examples
    --------
    The product rule carried along: ``t^2`` from ``t``.

    >>> import numpy as np
    >>> t = Jet(np.array([0.0, 0.5, 1.0]), np.ones(3), np.zeros(3))
    >>> square = t * t
    >>> square.f, square.d1, square.d2
    (array([0.  , 0.25, 1.  ]), array([0., 1., 2.]), array([2., 2., 2.]))
    """

    f: np.ndarray
    d1: np.ndarray
    d2: np.ndarray

    def __add__(self, o):
        if not isinstance(o, Jet):
            return Jet(self.f + o, self.d1, self.d2)
        return Jet(self.f + o.f, self.d1 + o.d1, self.d2 + o.d2)

    __radd__ = __add__

    def __mul__(self, o):
        if not isinstance(o, Jet):
            return Jet(self.f * o, self.d1 * o, self.d2 * o)
        return Jet(self.f * o.f, self.d1 * o.f + self.f * o.d1,
                   self.d2 * o.f + 2 * self.d1 * o.d1 + self.f * o.d2)

    __rmul__ = __mul__

    def __neg__(self):
        return Jet(-self.f, -self.d1, -self.d2)

    def __sub__(self, o):
        return self + (-o)


def minimum_jerk_step(t, t0: float, duration: float, height: float) -> Jet:
    """``height * (10 s^3 - 15 s^4 + 6 s^5)``, ``s = (t - t0)/duration`` clipped to [0, 1].

    Examples
    --------
    >>> import numpy as np
    >>> step = minimum_jerk_step(np.array([0.0, 0.5, 1.0]), t0=0.0, duration=1.0, height=2.0)
    >>> step.f, step.d1                         # halfway up at the middle, at its fastest there
    (array([0., 1., 2.]), array([0.  , 3.75, 0.  ]))
    """
    t = np.asarray(t, float)
    s = np.clip((t - t0) / duration, 0, 1)
    inside = (t > t0) & (t < t0 + duration)
    f = height * (10 * s ** 3 - 15 * s ** 4 + 6 * s ** 5)
    d1 = np.where(inside, height * (30 * s ** 2 - 60 * s ** 3 + 30 * s ** 4) / duration, 0.0)
    d2 = np.where(inside, height * (60 * s - 180 * s ** 2 + 120 * s ** 3) / duration ** 2, 0.0)
    return Jet(f, d1, d2)


def ringing(t, t0: float, amplitude: float, freq_hz: float = 10.0, decay_s: float = 0.3,
            rise_s: float = 0.02, phase: float = 0.0) -> Jet:
    """A decaying oscillation starting smoothly at ``t0``:
    ``A (1 - exp(-u/rise))^3 exp(-u/decay) sin(2 pi f u + phase)``, ``u = t - t0 >= 0``
    (position, velocity and acceleration continuous at ``t0``).

    Examples
    --------
    >>> import numpy as np
    >>> ring = ringing(np.array([0.0, 0.5]), t0=0.5, amplitude=0.01)    # nothing before or at its onset
    >>> ring.f.tolist(), ring.d1.tolist(), ring.d2.tolist()
    ([0.0, 0.0], [0.0, 0.0], [0.0, 0.0])
    """
    t = np.asarray(t, float)
    u = np.clip(t - t0, 0, None)
    on = t > t0
    e = np.exp(-u / rise_s)
    g = 1 - e
    rise = Jet(g ** 3, 3 * g ** 2 * e / rise_s, 6 * g * e ** 2 / rise_s ** 2 - 3 * g ** 2 * e / rise_s ** 2)
    d = np.exp(-u / decay_s)
    dec = Jet(d, -d / decay_s, d / decay_s ** 2)
    w = 2 * np.pi * freq_hz
    s, c = np.sin(w * u + phase), np.cos(w * u + phase)
    osc = Jet(s, w * c, -w * w * s)
    out = rise * dec * osc * amplitude
    return Jet(np.where(on, out.f, 0.0), np.where(on, out.d1, 0.0), np.where(on, out.d2, 0.0))


def _rotation_jets(a: Jet, b: Jet, c: Jet):
    """``R = Rz(a) Ry(b) Rx(c)`` with exact omega and alpha (spatial frame)."""
    Rz, Ry, Rx = axis_rotations("z", a.f), axis_rotations("y", b.f), axis_rotations("x", c.f)
    R = Rz @ Ry @ Rx
    n = a.f.size
    e1 = np.broadcast_to(np.eye(3)[2], (n, 3))
    e2 = Rz @ np.eye(3)[1]
    e3 = (Rz @ Ry) @ np.eye(3)[0]
    w12 = a.d1[:, None] * e1 + b.d1[:, None] * e2
    omega = w12 + c.d1[:, None] * e3
    alpha = (a.d2[:, None] * e1 + b.d2[:, None] * e2 + b.d1[:, None] * np.cross(a.d1[:, None] * e1, e2)
             + c.d2[:, None] * e3 + c.d1[:, None] * np.cross(w12, e3))
    return R, omega, alpha


def lift_with_ringing(fps: float = 100.0, duration_s: float = 4.0, noise_m: float = 3e-4, seed: int = 0,
                      ring_hz: float = 10.0, ring_decay_s: float = 0.3, ring_rise_s: float = 0.02,
                      ring_start_s: float = 2.8, second_ring_hz: float | None = None,
                      ring_scale: float = 1.0) -> dict:
    """A marker box lifted, held, set down, ringing at ``ring_hz``; exact truth.

    The defaults are the ringing fixture of the kinematics benchmarks. ``ring_decay_s``, ``ring_rise_s`` (the onset's time
    constant), ``ring_start_s`` and ``second_ring_hz`` (a second mode, half the amplitude, in the
    rotation about x and the vertical, from the same onset) and ``ring_scale`` (every ringing
    amplitude times it; 0: no ringing) build other non-periodic motions with the same exact truth.

    The box (0.40 x 0.30 x 0.20 m) carries 4 markers on its top and sides;
    the hidden point is a bottom corner. Motion (y up): lift of 0.30 m over
    0.8 s from t = 0.5 s while turning 5 deg about z and 8 deg about y and
    drifting 0.15 m in x; hold; set-down over 0.6 s from 2.2 s; from 2.8 s a
    10 Hz ringing decaying in 0.3 s: 6 mm vertically, 2 mm in z, 3 deg about x
    and 1.5 deg about y.

    Returns
    -------
    dict with ``t`` (n,), ``markers`` (n, 4, 3) noisy, ``markers_true``,
    ``model`` (4, 3) (the box's markers at rest: the static shot),
    ``hidden_body`` (3,) (the hidden point in the same frame),
    ``hidden_pos``/``hidden_vel``/``hidden_acc`` (n, 3), ``omega``,
    ``alpha`` (n, 3), ``R`` (n, 3, 3), ``noise_m``.

    Examples
    --------
    >>> motion = lift_with_ringing()
    >>> motion["t"].size, motion["markers"].shape, motion["hidden_acc"].shape
    (400, (400, 4, 3), (400, 3))
    """
    rng = np.random.default_rng(seed)
    t = np.arange(int(round(duration_s * fps))) / fps
    lift, down, t_ring = 0.5, 2.2, ring_start_s

    def ring(amplitude, phase=0.0, hz=ring_hz):
        return ringing(t, t_ring, amplitude * ring_scale, hz, ring_decay_s, ring_rise_s, phase)

    y = minimum_jerk_step(t, lift, 0.8, 0.30) + minimum_jerk_step(t, down, 0.6, -0.30) + ring(0.006)
    x = minimum_jerk_step(t, lift, 0.8, 0.15) + minimum_jerk_step(t, down, 0.6, -0.05)
    z = ring(0.002, phase=1.0)
    # angles about z, y and x (y up): R = Rz(tilt_z) Ry(turn_y) Rx(roll_x)
    pitch = minimum_jerk_step(t, lift, 0.8, np.radians(8)) + minimum_jerk_step(t, down, 0.6, -np.radians(8)) \
        + ring(np.radians(1.5), phase=0.5)
    roll = ring(np.radians(3.0))
    if second_ring_hz is not None:
        y = y + ring(0.003, 0.8, second_ring_hz)
        roll = roll + ring(np.radians(1.5), 2.0, second_ring_hz)
    yaw = minimum_jerk_step(t, lift, 0.8, np.radians(5))
    R, omega, alpha = _rotation_jets(yaw, pitch, roll)          # about z, y, x in that order
    # box centre at the origin of its own frame
    model = np.array([[0.20, 0.10, 0.15], [-0.20, 0.10, 0.15], [0.05, 0.10, -0.15], [-0.20, -0.02, -0.15]])
    hidden = np.array([0.20, -0.10, -0.15])
    c = np.stack([x.f, y.f, z.f], -1) + [0.0, 1.0, 0.0]
    cd = np.stack([x.d1, y.d1, z.d1], -1)
    cdd = np.stack([x.d2, y.d2, z.d2], -1)
    mk = np.einsum("kij,mj->kmi", R, model) + c[:, None]
    r = R @ hidden
    pos = c + r
    vel = cd + np.cross(omega, r)
    acc = cdd + np.cross(alpha, r) + np.cross(omega, np.cross(omega, r))
    return {"t": t, "markers": mk + rng.normal(0, noise_m, mk.shape), "markers_true": mk, "model": model,
            "hidden_body": hidden, "hidden_pos": pos, "hidden_vel": vel, "hidden_acc": acc,
            "omega": omega, "alpha": alpha, "R": R, "noise_m": noise_m}
