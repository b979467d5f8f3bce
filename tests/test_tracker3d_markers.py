"""Following more than three markers in 3D (horsemocap.detection.tracker3d).

A set of five markers, two of them close together, crosses the thesis rig
faster than their smallest spacing per frame (a canter seen at 30 fps): the
set moves as a whole, so its labels are told by how the markers move
against each other, not by how far the set moved.
"""
import numpy as np

from horsemocap.detection import identify_markers
from horsemocap.detection.tracker3d import same_marker_set
from horsemocap.virtuallab.render import disc_frames
from horsemocap.virtuallab.rig import thesis_rig

RIG = thesis_rig()
#: Five skin markers (body frame, m); markers 3 and 4 are 0.13 m apart, the smallest spacing.
FIVE = np.array([[-0.24, 0.0, 0.0], [0.0, -0.07, 0.0], [0.22, 0.0, 0.01], [0.10, 0.12, 0.0], [-0.03, 0.12, 0.02]])
SADDLE = np.array([0.45, -0.25, 0.02])
FPS = 30.0
#: Forward speed (m/s): 0.167 m per frame, more than the smallest marker spacing.
SPEED = 5.0


def _world(points_body, t):
    """The markers of a body running along x at ``SPEED`` with a small bounce (n, M, 3)."""
    t = np.atleast_1d(t)
    pos = np.column_stack([-2.2 + SPEED * t, -0.05 + 0.03 * np.sin(2 * np.pi * 2.0 * t), 7.7 + 0.0 * t])
    return pos[:, None, :] + np.asarray(points_body)[None]


def _render(n):
    """Gray frames per camera of the five markers (anti-aliased discs), the static shot and the truth."""
    t = np.arange(n) / FPS
    markers = _world(FIVE, t)
    frames = {}
    for cam in RIG:
        frames[cam.name] = disc_frames(cam.project(markers), cam.size)
    static = np.vstack([FIVE, SADDLE]) + [0.2, -0.05, 7.7]
    return frames, static, markers


def _seen_by_two(markers):
    """(frames, markers): does the marker's whole disc lie inside two or more images?"""
    count = 0
    for cam in RIG:
        W, H = cam.size
        px = cam.project(markers)
        count = count + ((px[..., 0] >= 4) & (px[..., 1] >= 4) & (px[..., 0] <= W - 5) & (px[..., 1] <= H - 5))
    return count >= 2


def test_five_markers_moving_more_than_their_spacing_per_frame_are_followed():
    smallest = min(np.linalg.norm(FIVE[a] - FIVE[b]) for a in range(5) for b in range(a + 1, 5))
    assert SPEED / FPS > smallest          # the scene is the case in question
    frames, static, markers = _render(28)
    idn = identify_markers(frames, RIG, static, 5)
    seen = _seen_by_two(markers)
    have = np.all(np.isfinite(idn.points), axis=-1)
    assert seen.sum() > 60
    assert have[seen].mean() > 0.95, np.argwhere(seen & ~have).tolist()
    err = np.linalg.norm(idn.points - markers, axis=-1)
    assert np.nanmax(err) < 0.02


def test_same_marker_set_judges_the_motion_against_the_set():
    X = FIVE + [0.0, 0.0, 7.7]
    half = 0.5 * 0.13
    assert same_marker_set(X, X + [0.4, 0.01, -0.02], half)            # far, but together
    assert not same_marker_set(X, X[[0, 1, 2, 4, 3]], half)             # the two close markers swapped
    moved = X + [0.1, 0.0, 0.0]
    moved[2] += [0.0, 0.0, 0.1]                                          # one marker a spacing off the others
    assert not same_marker_set(X, moved, half)
    missing = X.copy()
    missing[1] = np.nan
    assert not same_marker_set(X, missing, half)
