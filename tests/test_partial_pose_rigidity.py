"""A frame with two markers joins the pose smoothing only when their distance is the rigid body's."""
from __future__ import annotations

import numpy as np

from horsemocap import pose
from horsemocap.params import PoseParams

from test_rigid import random_rigid_motion


def _motion(seed=20):
    rng = np.random.default_rng(seed)
    m = random_rigid_motion(rng, n=60, markers=3, duration=1.0)
    pts = m["pos"] + rng.normal(0, 5e-4, m["pos"].shape)
    pts[:3, 2] = np.nan                     # the first three frames see markers 0 and 1 only
    return m, pts


def test_departure_is_measured_against_the_pair_in_the_frames_with_a_pose():
    m, pts = _motion()
    ok = np.all(np.isfinite(pts), axis=(1, 2))
    pts[1, 1] += 0.03 * (pts[1, 1] - pts[1, 0]) / np.linalg.norm(pts[1, 1] - pts[1, 0])   # 30 mm further apart
    z = pose.two_marker_distance_departure(pts, ok)
    assert np.all(np.isnan(z[3:]))                         # frames with a pose are not tested
    d = np.linalg.norm(pts[ok, 0] - pts[ok, 1], axis=1)
    scatter = 1.4826 * np.median(np.abs(d - np.median(d)))
    assert abs(z[1] - (np.linalg.norm(pts[1, 0] - pts[1, 1]) - np.median(d)) / scatter) < 1e-9
    assert z[1] > 20 and abs(z[0]) < pose.PARTIAL_POSE_RIGIDITY_LIMIT and abs(z[2]) < pose.PARTIAL_POSE_RIGIDITY_LIMIT


def test_a_two_marker_frame_off_the_rigid_distance_gets_no_partial_pose_and_says_why():
    m, pts = _motion()
    reg = pose.register_pose(pts, m["body"])
    params = PoseParams(smoothing="gcv", partial_frames=True)
    clean = pose.fit_pose_trajectory(m["t"], reg, m["body"], params, points=pts)
    assert all(r.startswith("partial pose: 2 markers") for r in clean.reason[:3])
    bad = pts.copy()
    bad[0, 1] += 0.04 * (bad[0, 1] - bad[0, 0]) / np.linalg.norm(bad[0, 1] - bad[0, 0])
    tr = pose.fit_pose_trajectory(m["t"], reg, m["body"], params, points=bad)
    assert not tr.valid[0] and "no partial pose" in tr.reason[0] and "robust sd" in tr.reason[0]
    assert all(r.startswith("partial pose: 2 markers") for r in tr.reason[1:3])
    # what the refused frame would have done: the smoothing over the frames kept is the one without it
    without = bad.copy()
    without[0] = np.nan
    ref = pose.fit_pose_trajectory(m["t"], reg, m["body"], params, points=without)
    inner = m["t"][3:]
    np.testing.assert_allclose(tr.points(inner, m["body"]).acceleration, ref.points(inner, m["body"]).acceleration,
                               rtol=0, atol=1e-12)


def test_consistent_two_marker_frames_are_kept_as_before(monkeypatch):
    """The gate refuses nothing when the pair's distance is within the noise: the trajectory is the same
    as with every two-marker frame taken (the gate switched off)."""
    limit = pose.PARTIAL_POSE_RIGIDITY_LIMIT
    m, pts = _motion(21)
    ok = np.all(np.isfinite(pts), axis=(1, 2))
    assert np.all(np.abs(pose.two_marker_distance_departure(pts, ok)[:3]) < pose.PARTIAL_POSE_RIGIDITY_LIMIT)
    reg = pose.register_pose(pts, m["body"])
    tr = pose.fit_pose_trajectory(m["t"], reg, m["body"], PoseParams(smoothing="gcv"), points=pts)
    assert tr.valid.all() and not any("no partial pose" in r for r in tr.reason)
    monkeypatch.setattr(pose, "PARTIAL_POSE_RIGIDITY_LIMIT", np.inf)
    every = pose.fit_pose_trajectory(m["t"], reg, m["body"], PoseParams(smoothing="gcv"), points=pts)
    for gated, taken in zip(tr.centre_splines + tr.rotvec_splines, every.centre_splines + every.rotvec_splines):
        np.testing.assert_array_equal(gated.spline.c, taken.spline.c)
        assert gated.info["lam"] == taken.info["lam"]
    np.testing.assert_array_equal(tr.rotvec_data, every.rotvec_data)
    # and the comparison sees a frame the gate refuses: its trajectory is not the one with every frame
    bad = pts.copy()
    bad[0, 1] += 0.04 * (bad[0, 1] - bad[0, 0]) / np.linalg.norm(bad[0, 1] - bad[0, 0])
    monkeypatch.setattr(pose, "PARTIAL_POSE_RIGIDITY_LIMIT", limit)
    refused = pose.fit_pose_trajectory(m["t"], reg, m["body"], PoseParams(smoothing="gcv"), points=bad)
    monkeypatch.setattr(pose, "PARTIAL_POSE_RIGIDITY_LIMIT", np.inf)
    kept = pose.fit_pose_trajectory(m["t"], reg, m["body"], PoseParams(smoothing="gcv"), points=bad)
    assert not np.array_equal(refused.centre_splines[0].spline.c, kept.centre_splines[0].spline.c)
