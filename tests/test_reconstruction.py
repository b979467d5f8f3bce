"""Tests of horsemocap.reconstruction on synthetic scenes with exact truth."""
import numpy as np
import pytest

from horsemocap import reconstruction as rc
from horsemocap.camera import Camera, Rig, rotation_vector
from horsemocap.virtuallab.rig import thesis_rig


def scene(n=20, m=3, seed=0):
    rng = np.random.default_rng(seed)
    return np.stack([rng.uniform(-1.2, 1.2, (n, m)), rng.uniform(-0.6, 0.6, (n, m)),
                     rng.uniform(7.0, 8.0, (n, m))], axis=-1)


@pytest.fixture(scope="module")
def rig():
    return thesis_rig()


@pytest.mark.parametrize("mode", ["thesis", "joint"])
def test_exact_pixels_give_exact_points(rig, mode):
    P = scene()
    px = rig.project(P)
    tri = rc.triangulate(rig, px, mode=mode)
    np.testing.assert_allclose(tri.points, P, atol=1e-6)
    assert np.all(tri.reason == "")
    for r in tri.residual_px.values():
        assert np.nanmax(r) < 1e-5


def test_thesis_pairs_frames_eq_5_1_to_5_5(rig):
    P = scene(n=5)
    tri = rc.triangulate(rig, rig.project(P), mode="thesis")
    assert set(tri.pairs) == {"left-middle", "left-right", "middle-right"}
    mr = tri.pairs["middle-right"]
    # CM_MR,M is in the middle camera frame; eq. 5.3 brings it back to the left
    np.testing.assert_allclose(mr.points_local, rig["middle"].world_to_camera(P), atol=1e-6)
    np.testing.assert_allclose(mr.points, P, atol=1e-6)
    mean = np.mean([p.points for p in tri.pairs.values()], axis=0)
    np.testing.assert_allclose(tri.points, mean, atol=1e-12)


def test_stereo_triangulation_is_the_midpoint_of_skew_rays():
    R = np.eye(3)
    T = np.array([-0.5, 0.0, 0.0])
    # left ray along +z through the origin; right camera at x = 0.5 (left frame)
    # looking at a point offset in y by 0.02 m: rays are skew
    target_left = np.array([0.0, 0.0, 5.0])
    target_right = np.array([0.0, 0.02, 5.0]) + T
    xl = target_left[:2] / target_left[2]
    xr = target_right[:2] / target_right[2]
    XL, XR = rc.stereo_triangulation(xl, xr, R, T)
    # independent: closest points of the two rays by the 2x2 normal equations
    o1, d1 = np.zeros(3), np.array([*xl, 1.0])
    o2, d2 = -T, np.array([*xr, 1.0])  # right centre and direction in the left frame (R = I)
    A = np.array([[d1 @ d1, -d1 @ d2], [d1 @ d2, -d2 @ d2]])
    b = np.array([(o2 - o1) @ d1, (o2 - o1) @ d2])
    s_, u_ = np.linalg.solve(A, b)
    mid = 0.5 * ((o1 + s_ * d1) + (o2 + u_ * d2))
    np.testing.assert_allclose(XL, mid, atol=1e-12)
    assert 0.0 < XL[1] < 0.02
    np.testing.assert_allclose(XR, XL + T, atol=1e-12)


def test_joint_minimises_reprojection_error_better_than_thesis(rig):
    rng = np.random.default_rng(5)
    P = scene(n=40)
    px = {c: v + rng.normal(0, 0.3, v.shape) for c, v in rig.project(P).items()}
    th = rc.triangulate(rig, px, mode="thesis")
    jo = rc.triangulate(rig, px, mode="joint")
    sse = lambda t: sum(r**2 for r in t.residual_px.values())
    assert np.all(sse(jo) <= sse(th) + 1e-9)
    err = np.linalg.norm(jo.points - P, axis=-1)
    assert np.sqrt(np.mean(err**2)) < 0.1


def test_missing_views_reasons_and_subsets(rig):
    P = scene(n=4, m=2)
    px = {c: v.copy() for c, v in rig.project(P).items()}
    px["middle"][1, 0] = np.nan
    px["right"][1, 0] = np.nan   # frame 1 marker 0: left only
    px["left"][2, 1] = np.nan    # frame 2 marker 1: middle + right
    for mode in ("joint", "thesis"):
        tri = rc.triangulate(rig, px, mode=mode)
        assert tri.reason[1, 0] == rc.REASON_FEW_CAMERAS
        assert np.all(np.isnan(tri.points[1, 0]))
        assert tri.reason[2, 1] == ""
        np.testing.assert_allclose(tri.points[2, 1], P[2, 1], atol=1e-6)
        assert tri.n_views[2, 1] == 2 and tri.n_views[0, 0] == 3
        assert np.isnan(tri.residual_px["left"][2, 1])


def test_joint_with_two_and_four_cameras(rig):
    P = scene(n=6)
    two = rig.subset(["left", "right"])
    tri = rc.triangulate(two, two.project(P), mode="joint")
    np.testing.assert_allclose(tri.points, P, atol=1e-6)
    extra = Camera("top", (640, 480), rig["left"].matrix, rotation=rotation_vector(np.eye(3)),
                   translation=[0.3, 0.8, 0.1])
    four = Rig(tuple(rig.cameras) + (extra,))
    tri4 = rc.triangulate(four, four.project(P), mode="joint")
    np.testing.assert_allclose(tri4.points, P, atol=1e-6)
    assert set(tri4.residual_px) == {"left", "middle", "right", "top"}
    with pytest.raises(ValueError, match="three cameras"):
        rc.triangulate(four, four.project(P), mode="thesis")
    tri2 = rc.triangulate(two, two.project(P), mode="thesis", pairs=[("left", "right")])
    np.testing.assert_allclose(tri2.points, P, atol=1e-6)


def test_bad_inputs_are_named(rig):
    P = scene(n=3)
    px = rig.project(P)
    px["middle"] = px["middle"][:2]
    with pytest.raises(ValueError, match="middle"):
        rc.triangulate(rig, px)
    with pytest.raises(ValueError, match="not in the rig"):
        rc.triangulate(rig, {"left": rig["left"].project(P), "back": rig["left"].project(P)})
    with pytest.raises(ValueError, match="mode"):
        rc.triangulate(rig, rig.project(P), mode="magic")


def test_joint_rejects_a_swapped_detection(rig):
    P = scene(n=6, m=3)
    px = {c: v.copy() for c, v in rig.project(P).items()}
    px["middle"][2, [0, 1]] = px["middle"][2, [1, 0]]   # markers 1 and 2 swapped in one camera
    jo = rc.triangulate(rig, px, mode="joint")
    np.testing.assert_allclose(jo.points[2, :2], P[2, :2], atol=1e-6)
    assert jo.rejected["middle"][2, 0] and jo.rejected["middle"][2, 1]
    assert jo.n_views[2, 0] == 2 and jo.residual_px["middle"][2, 0] > 10
    assert not jo.rejected["left"].any()
    th = rc.triangulate(rig, px, mode="thesis")
    assert np.linalg.norm(th.points[2, 0] - P[2, 0]) > 0.05  # the thesis average is pulled away
    off = rc.triangulate(rig, px, mode="joint", max_residual_px=None)
    assert not any(r.any() for r in off.rejected.values())
    # two inconsistent views cannot be resolved: NaN with its reason
    two = rig.subset(["left", "middle"])
    pair = rc.triangulate(two, {c: px[c] for c in two.names}, mode="joint")
    assert pair.reason[2, 0] in (rc.REASON_INCONSISTENT, rc.REASON_BEHIND)
    assert np.all(np.isnan(pair.points[2, 0]))
    assert pair.reason[3, 0] == ""
