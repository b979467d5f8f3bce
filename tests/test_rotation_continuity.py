"""Property tests: the pose trajectory has no singularity at any rotation (horsemocap.pose).

Seeded random axes, speeds and paths (hypothesis is not installed): a body
turning ten times at a constant speed about a random axis, smooth rotations
whose angle crosses pi with a wandering axis, and a hidden point carried
through the turns.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from horsemocap import pose
from horsemocap.params import PoseParams

RATE_HZ = 100.0


def _cluster(rng):
    """Four markers of a cluster (about 0.1 to 0.2 m across) and a hidden point 0.3 m away."""
    markers = rng.normal(0, 0.08, (4, 3))
    hidden = markers.mean(0) + 0.3 * rng.normal(size=3) / np.sqrt(3)
    return markers, hidden


def _centre(t):
    """A smooth centroid path (m), not periodic, and its acceleration."""
    pos = np.column_stack([0.3 * t - 0.05 * t ** 2, 0.1 * np.exp(-t), 0.02 * t ** 3])
    acc = np.column_stack([-0.1 + 0 * t, 0.1 * np.exp(-t), 0.12 * t])
    return pos, acc


def _turning_body(seed, turns=10.0):
    """A cluster turning ``turns`` times at a constant speed about a random axis."""
    rng = np.random.default_rng(seed)
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    speed = rng.uniform(15.0, 25.0)                     # rad/s: 10 turns in 2.5 to 4.2 s
    t = np.arange(int(turns * 2 * np.pi / speed * RATE_HZ) + 1) / RATE_HZ
    R = Rotation.from_rotvec(np.outer(speed * t, axis)) * Rotation.random(random_state=seed)
    omega = np.broadcast_to(speed * axis, (t.size, 3))
    alpha = np.zeros((t.size, 3))
    return rng, t, R, omega, alpha


def _wandering_body(seed):
    """A smooth rotation ``Exp(phi(t))`` whose angle crosses pi (up to 1.4 pi) about an axis that
    wanders; omega and alpha from the closed forms (valid at any phi: Exp is smooth)."""
    rng = np.random.default_rng(seed)
    t = np.arange(301) / RATE_HZ
    a, f, p = rng.normal(0, 0.4, 3), rng.uniform(0.3, 1.0, 3), rng.uniform(0, 6, 3)
    u0 = rng.normal(size=3)
    u0 /= np.linalg.norm(u0)
    w = 2 * np.pi * f
    th = 1.4 * np.pi * np.sin(np.pi * t / t[-1])[:, None]
    dth = 1.4 * np.pi * np.pi / t[-1] * np.cos(np.pi * t / t[-1])[:, None]
    ddth = -1.4 * np.pi * (np.pi / t[-1]) ** 2 * np.sin(np.pi * t / t[-1])[:, None]
    wob = a * np.sin(w * t[:, None] + p)
    dwob = a * w * np.cos(w * t[:, None] + p)
    ddwob = -a * w * w * np.sin(w * t[:, None] + p)
    phi, dphi, ddphi = th * u0 + wob, dth * u0 + dwob, ddth * u0 + ddwob
    R = Rotation.from_rotvec(phi)
    return (rng, t, R, pose.angular_velocity_from_rotvec(phi, dphi),
            pose.angular_acceleration_from_rotvec(phi, dphi, ddphi), np.linalg.norm(phi, axis=1))


def _observe(rng, t, R, markers, noise_m):
    c, _ = _centre(t)
    m0 = markers.mean(0)
    pts = c[:, None] + np.einsum("kij,mj->kmi", R.as_matrix(), markers - m0)
    return pts + rng.normal(0, noise_m, pts.shape) if noise_m else pts


def _fit(t, pts, markers, smoothing="auto"):
    reg = pose.register_pose(pts, markers)
    return pose.fit_pose_trajectory(t, reg, markers, PoseParams(smoothing=smoothing))


def _worst_relative_omega_error(tr, t, omega):
    err = np.linalg.norm(tr.omega(t) - omega, axis=1) / np.linalg.norm(omega, axis=1)
    return float(np.nanmax(err))


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("noise_m", [0.0, 0.0005])
def test_ten_turns_at_constant_speed_keep_omega_within_one_percent_at_every_frame(seed, noise_m):
    rng, t, R, omega, _ = _turning_body(seed)
    markers, _ = _cluster(rng)
    tr = _fit(t, _observe(rng, t, R, markers, noise_m), markers)
    assert tr.valid.all()
    worst = _worst_relative_omega_error(tr, t, omega)
    assert worst < 0.01, f"omega off by {100 * worst:.3g} % at the worst frame"
    # the rotation itself is continuous: no frame-to-frame jump beyond the motion's own step
    step = np.linalg.norm((Rotation.from_matrix(tr.rotation(t)[1:])
                           * Rotation.from_matrix(tr.rotation(t)[:-1]).inv()).as_rotvec(), axis=1)
    assert step.max() < 1.5 * np.linalg.norm(omega[0]) / RATE_HZ


@pytest.mark.parametrize("seed", range(4))
def test_a_rotation_crossing_pi_with_a_wandering_axis_is_exact_without_noise(seed):
    rng, t, R, omega, alpha, angle = _wandering_body(seed)
    assert angle.max() > np.pi
    markers, _ = _cluster(rng)
    tr = _fit(t, _observe(rng, t, R, markers, 0.0), markers, smoothing="none")
    inner = slice(5, -5)
    scale = np.sqrt(np.mean(np.sum(omega ** 2, 1)))
    assert np.abs(tr.omega(t) - omega).max() < 1e-4 * scale
    ascale = np.sqrt(np.mean(np.sum(alpha ** 2, 1)))
    assert np.abs(tr.alpha(t)[inner] - alpha[inner]).max() < 1e-3 * ascale
    np.testing.assert_allclose(tr.rotation(t), R.as_matrix(), atol=1e-9)


@pytest.mark.parametrize("seed", range(2))
def test_a_rotation_crossing_pi_with_noise_has_no_spike(seed):
    rng, t, R, omega, _, _ = _wandering_body(seed)
    markers, _ = _cluster(rng)
    tr = _fit(t, _observe(rng, t, R, markers, 0.0005), markers)
    err = np.linalg.norm(tr.omega(t) - omega, axis=1)
    scale = np.sqrt(np.mean(np.sum(omega ** 2, 1)))
    assert np.sqrt(np.mean(err ** 2)) < 0.05 * scale
    assert err.max() < 0.25 * scale


@pytest.mark.parametrize("seed", range(3))
def test_a_hidden_point_stays_right_across_the_turns(seed):
    rng, t, R, omega, _ = _turning_body(seed, turns=4.0)
    markers, hidden = _cluster(rng)
    pts = _observe(rng, t, R, markers, 0.0003)
    tr = _fit(t, pts, markers)
    c, c_acc = _centre(t)
    r = R.apply(hidden - markers.mean(0))
    true_pos = c + r
    true_acc = c_acc + np.cross(omega, np.cross(omega, r))
    k = tr.point(t, hidden)
    assert np.abs(k.position - true_pos).max() < 0.003
    acc_err = np.linalg.norm(k.acceleration - true_acc, axis=1)
    rms = np.sqrt(np.mean(np.sum(true_acc ** 2, 1)))
    assert np.sqrt(np.mean(acc_err ** 2)) < 0.05 * rms
    assert acc_err.max() < 0.25 * rms


def test_unwrap_follows_any_number_of_turns():
    rng = np.random.default_rng(11)
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    angle = np.arange(400) * 0.4
    raw = Rotation.from_rotvec(np.outer(angle, axis)).as_rotvec()
    np.testing.assert_allclose(pose.unwrap_rotvec(raw), np.outer(angle, axis), atol=1e-9)


def test_small_rotations_keep_the_fixed_mean_reference():
    rng = np.random.default_rng(5)
    rots = Rotation.from_rotvec(rng.normal(0, 0.2, (50, 3)))
    ref, phi = pose.rotation_reference(np.arange(50) / RATE_HZ, rots)
    assert ref.axis is None
    np.testing.assert_allclose(ref.base, rots.mean().as_matrix())
    np.testing.assert_allclose((Rotation.from_rotvec(phi) * Rotation.from_matrix(ref.base)).as_matrix(),
                               rots.as_matrix(), atol=1e-12)
