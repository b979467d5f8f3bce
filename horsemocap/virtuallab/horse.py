"""Horse, saddle and markers: a rigid body with analytic periodic motion.

The thesis (chapter 6) treats the three skin markers near the saddle and the
saddle marker as one rigid body. Here that body moves with

- a steady forward speed ``v`` along the path plus a periodic surge and,
  optionally, a smooth change of speed in its own (slower) rhythm
  (``SaddleMotion.speed_change``: the horse slows down and speeds up; forward
  only, so the vertical and rotational motion and the comfort indicators of
  the saddle's vertical acceleration stay periodic in the stride),
- periodic vertical and lateral translation,
- periodic yaw ``psi`` (about the downward axis), pitch ``theta`` (about the
  lateral axis) and roll ``phi`` (about the forward axis),

each a short Fourier series in the stride frequency ``f`` (chapter 2: walk,
trot, canter; speeds 5-7, 8-10 and 16-20 km/h). Positions, velocities and
accelerations, the angular velocity ``omega`` and angular acceleration
``alpha`` are analytic (no differentiation of samples), all in the world
frame = left camera frame (metres, seconds).

Frames
------
*Ground frame* ``G``: X along the path (horizontal), Y along gravity
(down), Z = X x Y (horizontal, away from the cameras). The left camera sits at
``camera_position_g`` with a small pitch/roll/yaw (``camera_rotation_g``),
so gravity and the path are not aligned with the camera axes:
``x_world = R_wg (x_G - c_G)``.

*Body frame* ``B``: origin at the body reference point (between the skin
markers), axes = ``G`` axes when all angles are zero (x forward, y down,
z lateral); ``R_wb(t) = R_wg Ry(psi) Rz(theta) Rx(phi)``.

*Motion frame* (thesis 5.3): x along the net displacement (the path
direction, exactly, because every periodic term repeats over a stride),
y along gravity (down), z = x cross y. In the world frame its axes are
``R_wg`` columns 0, 1, 2.

The amplitudes are invented but plausible (saddle vertical acceleration
peaks of ~1 g at canter, thesis Table 8.7: 11.7 m/s^2); they are not
measurements of the thesis' horses.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from ..camera import axis_rotations, rotation_matrix

HORSES = ("Horse 1", "Horse 2", "Horse 3", "Horse 4")
GAITS = ("walk", "sitting_trot", "rising_trot", "canter")

KMH = 1.0 / 3.6
DEG = math.pi / 180.0


@dataclass(frozen=True)
class Harmonics:
    """``s(t) = sum_j amp_j sin(2 pi k_j f t + phase_j)`` (SI units or rad)."""

    k: tuple = ()
    amp: tuple = ()
    phase: tuple = ()

    def _w(self, f):
        return 2 * math.pi * np.asarray(self.k, float) * f

    def value(self, t, f, deriv: int = 0) -> np.ndarray:
        """The series or its first / second time derivative at times ``t``."""
        t = np.asarray(t, float)
        out = np.zeros_like(t)
        for k, a, p in zip(self.k, self.amp, self.phase):
            w = 2 * math.pi * k * f
            arg = w * t + p
            if deriv == 0:
                out = out + a * np.sin(arg)
            elif deriv == 1:
                out = out + a * w * np.cos(arg)
            elif deriv == 2:
                out = out - a * w * w * np.sin(arg)
            else:
                raise ValueError(f"deriv must be 0, 1 or 2, got {deriv}")
        return out

    def scaled(self, factor: float) -> "Harmonics":
        return Harmonics(self.k, tuple(a * factor for a in self.amp), self.phase)

    def shifted(self, dphase: float) -> "Harmonics":
        return Harmonics(self.k, self.amp, tuple(p + k * dphase for k, p in zip(self.k, self.phase)))

    def to_dict(self):
        return {"k": list(self.k), "amp": [float(a) for a in self.amp], "phase": [float(p) for p in self.phase]}


def _h(*terms) -> Harmonics:
    return Harmonics(tuple(t[0] for t in terms), tuple(t[1] for t in terms), tuple(t[2] for t in terms))


@dataclass(frozen=True)
class Gait:
    """Speed, stride frequency and the periodic terms of one gait.

    ``vertical``, ``lateral``, ``surge`` in metres (vertical positive DOWN),
    ``yaw``, ``pitch``, ``roll`` in radians.
    """

    name: str
    speed_mps: float
    stride_hz: float
    vertical: Harmonics
    lateral: Harmonics
    surge: Harmonics
    yaw: Harmonics
    pitch: Harmonics
    roll: Harmonics
    leg_phases: tuple = (0.0, 0.5, 0.25, 0.75)  # LF, RF, LH, RH in strides

    def to_dict(self):
        d = {"name": self.name, "speed_mps": self.speed_mps, "speed_kmh": self.speed_mps * 3.6,
             "stride_hz": self.stride_hz}
        for key in ("vertical", "lateral", "surge", "yaw", "pitch", "roll"):
            d[key] = getattr(self, key).to_dict()
        d["leg_phases"] = list(self.leg_phases)
        return d


#: Base gaits (Horse 2's). Speeds: thesis chapter 2; canter: Table 8.7
#: vel_x_avg = 17.6 km/h and period 18 frames at 30 fps (section 8.4.1).
BASE_GAITS = {
    "walk": Gait(
        "walk", 6.0 * KMH, 0.95,
        vertical=_h((2, 0.022, 0.0), (4, 0.004, 0.7), (1, 0.004, 1.2)),
        lateral=_h((1, 0.025, 0.3), (3, 0.003, 1.0)),
        surge=_h((2, 0.010, 0.5)),
        yaw=_h((1, 1.5 * DEG, 2.0)),
        pitch=_h((2, 1.2 * DEG, 0.4)),
        roll=_h((1, 2.0 * DEG, 1.0), (2, 0.4 * DEG, 0.2)),
        leg_phases=(0.0, 0.5, 0.75, 0.25)),
    "sitting_trot": Gait(
        "sitting_trot", 9.0 * KMH, 1.40,
        vertical=_h((2, 0.019, 0.0), (4, 0.0018, 1.0), (6, 0.0003, 0.3)),
        lateral=_h((1, 0.015, 0.2), (3, 0.002, 0.8)),
        surge=_h((2, 0.012, 0.8)),
        yaw=_h((1, 1.2 * DEG, 1.7)),
        pitch=_h((2, 1.5 * DEG, 0.9)),
        roll=_h((1, 1.5 * DEG, 0.4), (2, 0.5 * DEG, 1.1)),
        leg_phases=(0.0, 0.5, 0.5, 0.0)),
    "rising_trot": Gait(
        "rising_trot", 9.4 * KMH, 1.45,
        vertical=_h((2, 0.021, 0.0), (4, 0.0016, 1.3), (6, 0.0003, 2.0)),
        lateral=_h((1, 0.016, 0.5), (3, 0.002, 0.1)),
        surge=_h((2, 0.013, 0.6)),
        yaw=_h((1, 1.3 * DEG, 1.5)),
        pitch=_h((2, 1.6 * DEG, 1.2)),
        roll=_h((1, 1.6 * DEG, 0.2), (2, 0.4 * DEG, 0.9)),
        leg_phases=(0.0, 0.5, 0.5, 0.0)),
    "canter": Gait(
        "canter", 17.6 * KMH, 30.0 / 18.0,
        vertical=_h((1, 0.065, 0.0), (2, 0.010, 1.1), (3, 0.0015, 0.5)),
        lateral=_h((1, 0.030, 0.9), (2, 0.006, 0.3)),
        surge=_h((1, 0.040, 1.5)),
        yaw=_h((1, 2.0 * DEG, 2.4)),
        pitch=_h((1, 4.0 * DEG, 1.9), (2, 0.8 * DEG, 0.6)),
        roll=_h((1, 2.5 * DEG, 0.6)),
        leg_phases=(0.30, 0.15, 0.0, 0.15)),
}


@dataclass(frozen=True)
class Horse:
    """One horse of the virtual herd (Table 8.6 plus invented gait factors).

    ``marker_body`` (3, 3): skin markers in the body frame (x forward, y down,
    z lateral, the camera-facing flank at negative z), ordered rear to front,
    which is also their left-to-right order in every image (the horse moves
    towards +u). ``saddle_body`` (3,): the saddle marker. ``*_normal``: disc
    normals (unit, body frame). Factors scale the base gait of
    :data:`BASE_GAITS`.
    """

    name: str
    age: int
    breed: str
    withers_m: float
    coat_rgb: tuple
    speed_factor: float
    freq_factor: float
    amp_factor: float
    rot_factor: float
    phase_shift: float
    path_depth_m: float
    marker_body: np.ndarray
    marker_normal: np.ndarray
    saddle_body: np.ndarray
    saddle_normal: np.ndarray

    def gait(self, gait: str) -> Gait:
        """This horse's version of a base gait."""
        if gait not in BASE_GAITS:
            raise ValueError(f"unknown gait {gait!r}; expected one of {GAITS}")
        g = BASE_GAITS[gait]
        a, r, s = self.amp_factor, self.rot_factor, self.phase_shift
        return replace(
            g, speed_mps=g.speed_mps * self.speed_factor, stride_hz=g.stride_hz * self.freq_factor,
            vertical=g.vertical.scaled(a).shifted(s), lateral=g.lateral.scaled(a).shifted(s),
            surge=g.surge.scaled(a).shifted(s), yaw=g.yaw.scaled(r).shifted(s),
            pitch=g.pitch.scaled(r).shifted(s), roll=g.roll.scaled(r).shifted(s))

    def to_dict(self):
        return {"name": self.name, "age": self.age, "breed": self.breed, "withers_m": self.withers_m,
                "coat_rgb": list(self.coat_rgb), "speed_factor": self.speed_factor,
                "freq_factor": self.freq_factor, "amp_factor": self.amp_factor,
                "rot_factor": self.rot_factor, "phase_shift": self.phase_shift,
                "path_depth_m": self.path_depth_m,
                "marker_body": np.asarray(self.marker_body).tolist(),
                "saddle_body": np.asarray(self.saddle_body).tolist()}


def _unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _horse(name, age, breed, withers, coat, sf, ff, af, rf, ph, depth, dx=0.0, dy=0.0):
    mk = np.array([[-0.62, 0.02, -0.31], [-0.38, 0.09, -0.33], [-0.14, 0.03, -0.33]])
    mk = mk + np.array([[dx, dy, 0.0], [0.0, -dy, 0.0], [-dx, dy * 0.5, 0.0]])
    normals = _unit([[-0.12, 0.12, -1.0], [0.0, 0.18, -1.0], [0.10, 0.10, -1.0]])
    return Horse(name, age, breed, withers, coat, sf, ff, af, rf, ph, depth,
                 mk, normals, np.array([0.10, -0.235, -0.30]), _unit([0.0, -0.10, -1.0]))


#: The virtual herd; ages, breeds and heights from thesis Table 8.6.
HERD = {
    "Horse 1": _horse("Horse 1", 20, "German", 1.70, (150, 80, 45), 0.96, 0.97, 1.20, 1.15, 0.4, 8.1, 0.02, 0.01),
    "Horse 2": _horse("Horse 2", 10, "Dutch", 1.73, (78, 48, 30), 1.00, 1.00, 1.00, 1.00, 0.0, 8.0),
    "Horse 3": _horse("Horse 3", 19, "French", 1.58, (125, 122, 115), 1.04, 1.03, 0.85, 0.90, 1.1, 7.9, -0.02, -0.01),
    "Horse 4": _horse("Horse 4", 13, "English", 1.57, (40, 34, 32), 0.93, 1.06, 1.30, 1.25, 2.3, 8.0, 0.01, 0.02),
}


# ---------------------------------------------------------------------------
# the arena: where the left camera stands in the ground frame
# ---------------------------------------------------------------------------
#: Left camera optical centre in the ground frame (m): 1.40 m above ground.
CAMERA_POSITION_G = np.array([0.0, -1.40, 0.0])
#: Rodrigues vector of R_gw (camera axes in the ground frame): pitched down
#: ~1.5 deg, rolled ~0.6 deg, yawed ~2 deg relative to the path.
CAMERA_ROTATION_G = np.array([-1.5 * DEG, 2.0 * DEG, 0.6 * DEG])


def ground_to_world() -> tuple[np.ndarray, np.ndarray]:
    """``(R_wg, c_G)`` with ``x_world = R_wg (x_G - c_G)``."""
    R_gw = rotation_matrix(CAMERA_ROTATION_G)
    return R_gw.T, CAMERA_POSITION_G.copy()


@dataclass(frozen=True)
class Pose:
    """Body pose and its derivatives at times ``t`` (world frame).

    ``position/velocity/acceleration`` (n, 3) of the body origin,
    ``rotation`` (n, 3, 3) body->world, ``omega``/``alpha`` (n, 3).
    """

    t: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    rotation: np.ndarray
    omega: np.ndarray
    alpha: np.ndarray

    def points(self, body_points) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """World position, velocity, acceleration of body-fixed points.

        ``r = p + R b``, ``v = v_p + omega x (R b)``,
        ``a = a_p + alpha x (R b) + omega x (omega x (R b))`` (thesis eq. 6.1-6.3
        in the rigid-body form). Shapes (n, m, 3).
        """
        b = np.asarray(body_points, float).reshape(-1, 3)
        rb = np.einsum("nij,mj->nmi", self.rotation, b)
        w = self.omega[:, None, :]
        al = self.alpha[:, None, :]
        pos = self.position[:, None, :] + rb
        vel = self.velocity[:, None, :] + np.cross(w, rb)
        acc = self.acceleration[:, None, :] + np.cross(al, rb) + np.cross(w, np.cross(w, rb))
        return pos, vel, acc


@dataclass(frozen=True)
class SaddleMotion:
    """Analytic motion of one horse in one gait (world = left camera frame).

    Parameters
    ----------
    horse : Horse
    gait : Gait
    x0 : float
        Ground-frame X of the body origin at ``t = 0`` (m).
    height : float
        Height of the body origin above the ground (m).
    """

    horse: Horse
    gait: Gait
    x0: float
    height: float
    R_wg: np.ndarray = field(repr=False, default_factory=lambda: ground_to_world()[0])
    c_g: np.ndarray = field(repr=False, default_factory=lambda: ground_to_world()[1])
    #: Extra forward displacement ``D(t) = speed_change.value(t, speed_change_hz)`` (m):
    #: the speed becomes ``v + D'(t)`` (empty: a steady mean speed, the herd).
    speed_change: Harmonics = Harmonics()
    speed_change_hz: float = 0.0

    # -- frames ----------------------------------------------------------------
    @property
    def gravity(self) -> np.ndarray:
        """Unit gravity vector (down) in the world frame."""
        return self.R_wg[:, 1].copy()

    @property
    def motion_axes(self) -> np.ndarray:
        """Rows: x-motion (path), y-motion (gravity, down), z = x cross y (world)."""
        return self.R_wg.T.copy()

    @property
    def period_s(self) -> float:
        return 1.0 / self.gait.stride_hz

    def ground_to_world_points(self, pts_g) -> np.ndarray:
        return (np.asarray(pts_g, float) - self.c_g) @ self.R_wg.T

    # -- pose ------------------------------------------------------------------
    def pose_ground(self, t):
        """Origin position/velocity/acceleration and angles in the ground frame."""
        t = np.atleast_1d(np.asarray(t, float))
        g, f = self.gait, self.gait.stride_hz
        z0 = self.horse.path_depth_m
        P = np.stack([self.x0 + g.speed_mps * t + g.surge.value(t, f),
                      -self.height + g.vertical.value(t, f),
                      z0 + g.lateral.value(t, f)], -1)
        V = np.stack([g.speed_mps + g.surge.value(t, f, 1), g.vertical.value(t, f, 1),
                      g.lateral.value(t, f, 1)], -1)
        A = np.stack([g.surge.value(t, f, 2), g.vertical.value(t, f, 2), g.lateral.value(t, f, 2)], -1)
        if self.speed_change.k:
            fs = self.speed_change_hz
            for d, arr in enumerate((P, V, A)):
                arr[:, 0] += self.speed_change.value(t, fs, d)
        ang = [[getattr(g, k).value(t, f, d) for d in range(3)] for k in ("yaw", "pitch", "roll")]
        return t, P, V, A, ang

    def pose(self, t) -> Pose:
        """Body pose, omega and alpha at times ``t`` (s), world frame.

        ``R_gb = Ry(psi) Rz(theta) Rx(phi)``; with ``e`` the ground axes,
        ``omega_G = e_y psi' + Ry e_z theta' + Ry Rz e_x phi'`` and
        ``alpha_G = d omega_G / dt`` (each rotated axis turns with the
        angular velocity of the rotations before it).
        """
        t, P, V, A, ((psi, dpsi, ddpsi), (th, dth, ddth), (ph, dph, ddph)) = self.pose_ground(t)
        Ry, Rz, Rx = axis_rotations("y", psi), axis_rotations("z", th), axis_rotations("x", ph)
        R_gb = Ry @ Rz @ Rx
        ey = np.array([0.0, 1.0, 0.0])
        a2 = Ry[..., :, 2]                     # Ry e_z
        a3 = (Ry @ Rz)[..., :, 0]              # Ry Rz e_x
        w1 = ey[None, :] * dpsi[:, None]
        w12 = w1 + a2 * dth[:, None]
        omega = w12 + a3 * dph[:, None]
        alpha = (ey[None, :] * ddpsi[:, None] + a2 * ddth[:, None] + np.cross(w1, a2) * dth[:, None]
                 + a3 * ddph[:, None] + np.cross(w12, a3) * dph[:, None])
        Rw = self.R_wg
        return Pose(t, self.ground_to_world_points(P), V @ Rw.T, A @ Rw.T,
                    np.einsum("ij,njk->nik", Rw, R_gb), omega @ Rw.T, alpha @ Rw.T)

    # -- points -----------------------------------------------------------------
    def markers(self, t):
        """Skin markers' (pos, vel, acc), each (n, 3, 3), world frame."""
        return self.pose(t).points(self.horse.marker_body)

    def saddle(self, t):
        """Saddle marker (pos, vel, acc), each (n, 3), world frame."""
        p, v, a = self.pose(t).points(self.horse.saddle_body[None])
        return p[:, 0], v[:, 0], a[:, 0]

    def static_pose(self, x_g: float = 0.3) -> Pose:
        """The horse standing still (static shot, thesis 6.3): no oscillation."""
        P = np.array([[x_g, -self.height, self.horse.path_depth_m]])
        z = np.zeros((1, 3))
        return Pose(np.zeros(1), self.ground_to_world_points(P), z, z, self.R_wg[None].copy(), z, z)

    def forward_speed(self, t) -> np.ndarray:
        """Speed along the path ``v + surge'(t) + D'(t)`` (m/s), ground X."""
        return self.pose_ground(t)[2][:, 0]

    def to_dict(self):
        d = {"horse": self.horse.to_dict(), "gait": self.gait.to_dict(), "x0": self.x0,
             "height": self.height, "R_wg": self.R_wg.tolist(), "c_g": self.c_g.tolist()}
        if self.speed_change.k:
            d["speed_change"] = self.speed_change.to_dict()
            d["speed_change_hz"] = float(self.speed_change_hz)
        return d


def marker_height(horse: Horse) -> float:
    """Height of the body origin above ground: ~0.42 m below the withers."""
    return horse.withers_m - 0.42


def saddle_motion(horse: str = "Horse 2", gait: str = "canter", *, x0: float | None = None,
                  enter_time_s: float = 0.35) -> SaddleMotion:
    """The analytic saddle motion of one horse in one gait.

    Parameters
    ----------
    horse : str
        One of :data:`HORSES`.
    gait : str
        One of :data:`GAITS`.
    x0 : float, optional
        Ground X of the body origin at ``t = 0``; default: the front marker
        reaches ``X = -4.4 m`` (just outside every camera's view) at
        ``enter_time_s`` after ``t = 0`` (the flash).

    Notes
    -----
    Time ``t`` is the motion time of a rendered session: ``t = 0`` at the
    flash, and frame ``k`` of camera ``c`` shows ``t = (k - offsets[c]) / fps``
    (see :mod:`horsemocap.virtuallab.session`). ``pose(t)``, ``markers(t)``
    and ``saddle(t)`` give world-frame (left camera) kinematics.

    Examples
    --------
    >>> m = saddle_motion("Horse 2", "canter")
    >>> pos, vel, acc = m.markers([0.5, 0.6])      # (2, 3, 3) each
    >>> round(m.period_s, 3)
    0.6
    """
    if horse not in HERD:
        raise ValueError(f"unknown horse {horse!r}; expected one of {HORSES}")
    h = HERD[horse]
    g = h.gait(gait)
    if x0 is None:
        x0 = -4.4 - g.speed_mps * enter_time_s - float(h.marker_body[2, 0])
    return SaddleMotion(h, g, float(x0), marker_height(h))
