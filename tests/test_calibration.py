"""Calibration (thesis 3.4-3.5, 8.2-8.3): real toolbox example and synthetic rigs with exact truth."""
from pathlib import Path

import numpy as np
import pytest

from horsemocap.calibration import (MAX_GRID_IRREGULARITY, CalibrationError, board_points, calibrate_command, calibrate_rig,
                                    compare_rigs, detect_board, format_calibration_tables,
                                    format_comparison, format_per_view_errors, grid_distance_check,
                                    grid_irregularity,
                                    load_bouguet_single, load_bouguet_stereo, pair_closure, parse_board,
                                    read_rig, rig_from_bouguet_stereo, subpix_window, views_from_corners,
                                    write_rig)
from horsemocap.calibration.synthetic import random_board_poses, render_board
from horsemocap.camera import Camera, Rig, rotation_matrix, rotation_vector
from horsemocap.data import data_samples_dir

BS = data_samples_dir() / "bouguet_stereo"

# The toolbox's own numbers (data_samples/bouguet_stereo/PROVENANCE.md)
TOOLBOX = {
    "left": dict(fc=[533.00371, 533.15260], cc=[341.58612, 234.25940]),
    "right": dict(fc=[536.98262, 536.56938], cc=[326.47209, 249.33257]),
}
TOOLBOX_T_MM = np.array([-99.80198, 1.12443, 0.05041])
TOOLBOX_OM = np.array([0.00669, 0.00452, -0.00350])


@pytest.fixture(scope="module")
def real():
    return calibrate_rig({"left": BS / "left", "right": BS / "right"}, (9, 6), 0.030, mode="pairwise")


def test_real_single_camera_agrees_with_toolbox(real):
    for cam, ref in TOOLBOX.items():
        s = real.singles[cam]
        assert s.used.all(), f"{cam}: board not found in {real.views[cam].missing()}"
        np.testing.assert_allclose(s.fc, ref["fc"], rtol=0.002)         # fc within 0.2 %
        np.testing.assert_allclose(s.cc, ref["cc"], atol=1.0)           # cc within 1 px
        assert s.kc[4] == 0.0
        # 3-sigma uncertainties of the same size as the toolbox's (+-1.1 px)
        assert np.all((s.fc_error > 0.5) & (s.fc_error < 2.5))
        assert s.rms < 0.3


def test_real_stereo_agrees_with_toolbox(real):
    pair = real.pairs[("left", "right")]
    np.testing.assert_allclose(1000 * pair.T, TOOLBOX_T_MM, atol=0.5)   # T within 0.5 mm
    np.testing.assert_allclose(pair.om, TOOLBOX_OM, atol=0.001)
    s = load_bouguet_stereo(BS / "Calib_Results_stereo.mat")
    np.testing.assert_allclose(1000 * pair.translation_sigma3[1], s.T_error, rtol=0.25)
    np.testing.assert_allclose(pair.intrinsics["left"].fc, s.left["fc"], rtol=0.002)
    np.testing.assert_allclose(pair.intrinsics["right"].cc, s.right["cc"], atol=1.0)


def test_real_grid_distances_and_tables(real):
    chk = grid_distance_check(real.rig, real.views, 0.030)
    assert chk.actual_mm[0] == pytest.approx(150.0)
    assert len(chk.view_names) == 14
    assert np.nanmean(chk.error_pct) < 0.5
    text = format_calibration_tables(real)
    assert "Table 8.1 Intrinsic parameters of the left camera" in text and "Table 8.4" in text
    assert "533.0" in text
    assert "01" in format_per_view_errors(real)
    assert "left-right" in format_comparison(real)


def test_bouguet_importer_returns_the_files_numbers():
    import scipy.io as sio

    left = load_bouguet_single(BS / "Calib_Results_left.mat")
    raw = sio.loadmat(BS / "Calib_Results_left.mat", mat_dtype=True)
    assert np.array_equal(left.fc, raw["fc"].ravel())
    assert np.array_equal(left.kc, raw["kc"].ravel())
    assert np.array_equal(left.fc_error, raw["fc_error"].ravel())
    np.testing.assert_allclose(left.fc, TOOLBOX["left"]["fc"], atol=5e-6)
    np.testing.assert_allclose(left.cc, TOOLBOX["left"]["cc"], atol=5e-6)
    assert left.n_ima == 14 and left.size == (640, 480) and left.dX == 30.0
    np.testing.assert_allclose(left.err_std, [0.13404, 0.13007], atol=1e-5)
    assert np.array_equal(left.omc[0], raw["omc_1"].ravel())
    st = load_bouguet_stereo(BS / "Calib_Results_stereo.mat")
    np.testing.assert_allclose(st.T, TOOLBOX_T_MM, atol=5e-6)
    np.testing.assert_allclose(st.om, TOOLBOX_OM, atol=5e-6)
    np.testing.assert_allclose(st.T_error, [0.142, 0.114, 0.498], atol=1e-3)
    np.testing.assert_allclose(rotation_matrix(st.om), st.R, atol=1e-9)
    assert st.names == ("left", "right")


def test_rig_from_bouguet_stereo_round_trip(tmp_path):
    rig = rig_from_bouguet_stereo(BS / "Calib_Results_stereo.mat")
    assert rig.names == ["left", "right"]
    np.testing.assert_allclose(rig["right"].translation, TOOLBOX_T_MM / 1000, atol=5e-9)
    back = read_rig(write_rig(rig, tmp_path / "rig.toml"))
    np.testing.assert_allclose(back["right"].matrix, rig["right"].matrix)
    np.testing.assert_allclose(back["right"].rotation, rig["right"].rotation)
    with pytest.raises(CalibrationError, match="not found"):
        load_bouguet_single(tmp_path / "nope.mat")


def test_calibrate_command_writes_rig_and_prints_tables(tmp_path):
    out = tmp_path / "sub" / "rig.toml"
    text = calibrate_command([BS / "left", BS / "right"], "9x6", 0.03, out)
    rig = read_rig(out)
    assert rig.names == ["left", "right"]
    np.testing.assert_allclose(rig["left"].focal, TOOLBOX["left"]["fc"], rtol=0.003)
    assert "Focal length uncertainty" in text and "± [" in text and "RMS reprojection error" in text
    assert f"wrote {out}" in text
    with pytest.raises(CalibrationError, match="COLSxROWS"):
        calibrate_command([BS / "left"], "9by6", 0.03, out)
    with pytest.raises(CalibrationError, match="not found"):
        calibrate_command([tmp_path / "missing"], "9x6", 0.03, out)


# ---------------------------------------------------------------------------
# synthetic rigs with exact truth
# ---------------------------------------------------------------------------

def _truth_rig():
    from horsemocap.virtuallab.rig import thesis_rig

    return thesis_rig()


def _synthetic_views(rig, n=10, noise=0.1, seed=0, inner=(15, 29), square=0.05):
    poses = random_board_poses(rig, inner, square, n, seed=seed, distance=(3.5, 6.5))
    pts = board_points(inner, square)
    rng = np.random.default_rng(seed)
    views = {}
    for cam in rig:
        c = np.array([cam.project(pts @ rotation_matrix(r).T + t) for r, t in poses])
        views[cam.name] = views_from_corners(cam.name, c + rng.normal(0, noise, c.shape), cam.size, inner)
    return views, poses


@pytest.fixture(scope="module")
def synthetic():
    rig = _truth_rig()
    views, _ = _synthetic_views(rig)
    return rig, views, calibrate_rig(None, (15, 29), 0.05, views=views, mode="joint")


def test_joint_and_pairwise_recover_the_true_rig(synthetic):
    truth, _, res = synthetic
    for name in truth.names:
        t, c = truth[name], res.rig[name]
        np.testing.assert_allclose(c.focal, t.focal, rtol=0.005)
        np.testing.assert_allclose(c.principal_point, t.principal_point, atol=2.0)
        np.testing.assert_allclose(c.distortions[:2], t.distortions[:2], atol=0.02)
    for (a, b), pair in res.pairs.items():
        true_base = np.linalg.norm(truth[a].center - truth[b].center)
        est = np.linalg.norm(pair.T)
        assert abs(est - true_base) / true_base < 0.01
    assert res.rms < 0.3 and res.joint.rms == pytest.approx(0.1 * np.sqrt(2), rel=0.1)
    cmp_ = compare_rigs(truth, res.rig)
    assert np.all(cmp_.center_mm < 20) and np.all(cmp_.angle_deg < 0.2)
    # the joint rig is consistent by construction; the separately calibrated pairs nearly are
    closure = pair_closure(res)
    assert closure[0]["pair"] == ("middle", "right") and closure[0]["translation_mm"] < 20


def test_pairwise_rig_is_consistent_and_mixed_intrinsics_are_not(synthetic):
    from horsemocap.calibration import pair_rig, pairwise_rig, rig_from_pairs

    truth, views, res = synthetic
    pw = pairwise_rig(res)
    for name in truth.names:
        np.testing.assert_allclose(pw[name].matrix, res.singles[name].matrix)   # one set of intrinsics
        assert np.linalg.norm(pw[name].center - truth[name].center) < 0.02
    assert abs(grid_distance_check(pw, views, 0.05).summary()["segments_bias_pct"]) < 0.3
    lr = pair_rig(res, "left", "right")
    np.testing.assert_allclose(lr["right"].translation, res.pairs[("left", "right")].T)
    mixed = rig_from_pairs(res.pairs, res.cameras, "left")
    assert mixed["left"].matrix[0, 2] == res.pairs[("left", "middle")].intrinsics["left"].matrix[0, 2]


def test_grid_distance_check_on_truth_and_calibration(synthetic):
    truth, views, res = synthetic
    exact = grid_distance_check(truth, views, 0.05)
    assert exact.actual_mm.tolist() == pytest.approx([500.0, 500.0, 707.1068], abs=1e-3)
    # 0.1 px of corner noise at 3.5-6.5 m with 0.24-0.45 m baselines: ~1 % per single segment
    assert exact.summary()["abcd_mean_abs_pct"] < 1.5 and abs(exact.summary()["segments_bias_pct"]) < 0.2
    calibrated = grid_distance_check(res.rig, views, 0.05).summary()
    assert calibrated["abcd_mean_abs_pct"] < 1.5           # thesis Table 8.5: 2.2-4.6 %
    assert abs(calibrated["segments_bias_pct"]) < 0.3
    # a rig with a 3 % wrong baseline measures the board 3 % too large: the check notices
    bad = Rig(tuple(c if c.name == "left" else c.with_pose(c.rotation, c.translation * 1.03) for c in res.rig))
    assert grid_distance_check(bad, views, 0.05).summary()["segments_bias_pct"] > 2.0


def test_bad_view_is_seen_and_can_be_excluded():
    rig = _truth_rig()
    views, _ = _synthetic_views(rig, n=8, seed=3, inner=(7, 9), square=0.1)
    c = views["middle"].corners.copy()
    c[4] += np.random.default_rng(0).normal(0, 1.5, c[4].shape)   # a blurred, badly detected view
    from dataclasses import replace

    views["middle"] = replace(views["middle"], corners=c)
    res = calibrate_rig(None, (7, 9), 0.1, views=views)
    worst = int(np.nanargmax(res.singles["middle"].per_view_rms))
    assert res.view_names[worst] == "05"
    res2 = calibrate_rig(None, (7, 9), 0.1, views=views, exclude={"middle": ["05"]})
    assert res2.singles["middle"].reasons[4] == "excluded" and np.isnan(res2.singles["middle"].per_view_rms[4])
    assert res2.singles["middle"].rms < 0.5 * res.singles["middle"].rms
    assert "Excluded views: middle:05" in format_calibration_tables(res2)
    with pytest.raises(CalibrationError, match="unknown views"):
        calibrate_rig(None, (7, 9), 0.1, views=views, exclude=["99"])


def test_reversed_corner_order_is_harmonised():
    rig = _truth_rig().subset(["left", "middle"])
    views, _ = _synthetic_views(rig, n=6, seed=5, inner=(7, 9), square=0.1)
    from dataclasses import replace

    c = views["middle"].corners.copy()
    c[2] = c[2][::-1]
    views["middle"] = replace(views["middle"], corners=c)
    res = calibrate_rig(None, (7, 9), 0.1, views=views)
    assert res.flipped == (("middle", "03"),)
    assert res.rms < 0.3


def test_detection_on_a_rendered_view_and_window_rule():
    cam = Camera("left", (320, 240), [[400, 0, 161], [0, 400, 118], [0, 0, 1]], [-0.1, 0.01, 0, 0, 0])
    inner, sq = (7, 5), 0.05
    r, t = np.array([0.3, -0.2, 0.1]), np.array([-0.15, -0.1, 1.2])
    img = render_board(cam, r, t, inner, sq, seed=1)
    corners, w, why = detect_board(img, inner)
    assert why == "" and w in (3, 4, 5)
    true = cam.project(board_points(inner, sq) @ rotation_matrix(r).T + t)
    if np.linalg.norm(corners[0] - true[0]) > np.linalg.norm(corners[0] - true[-1]):
        true = true[::-1]
    assert np.sqrt(np.mean(np.sum((corners - true) ** 2, axis=1))) < 0.1
    none, w0, why0 = detect_board(np.full((240, 320), 90, np.uint8), inner)
    assert none is None and w0 == 0 and "not found" in why0
    assert subpix_window(28.0) == 7 and subpix_window(6.0) == 4 and subpix_window(200.0) == 15
    assert parse_board("15x29") == (15, 29)


def _yawed_board(yaw_deg, seed=1):
    """A 7 x 14 board of 100 mm squares at 7.7 m, turned by ``yaw_deg`` (thesis left camera)."""
    from horsemocap.virtuallab.session import thesis_rig

    cam = thesis_rig()["left"]
    inner, sq = (7, 14), 0.1
    pts = board_points(inner, sq)
    R = rotation_matrix([0, np.deg2rad(yaw_deg), 0]) @ rotation_matrix([0, 0, np.deg2rad(5)])
    t = np.array([0.2, -0.1, 7.7]) - R @ pts.mean(axis=0)
    img = render_board(cam, rotation_vector(R), t, inner, sq, seed=seed)
    return img, cam.project(pts @ R.T + t), inner


def test_grid_irregularity_of_regular_and_pulled_grids():
    inner = (4, 3)
    g = np.stack(np.meshgrid(np.arange(4.0), np.arange(3.0)), -1).reshape(-1, 2) * 10
    assert grid_irregularity(g, inner) < 1e-12
    bent = g.copy()
    bent[5] += [5.0, 0.0]          # an interior corner pulled half a square along its row
    assert grid_irregularity(bent, inner) == pytest.approx(1.0)
    two_rows = np.stack(np.meshgrid(np.arange(3.0), np.arange(2.0)), -1).reshape(-1, 2)
    assert grid_irregularity(two_rows, (3, 2)) < 1e-12
    bent[0] = np.nan                   # a missing corner is not a regular grid
    assert grid_irregularity(bent, inner) == np.inf
    with pytest.raises(CalibrationError, match="at least 2"):
        detect_board(np.full((60, 80), 90, np.uint8), (4, 3), window=1)


@pytest.mark.parametrize("yaw", [55, 56])
def test_foreshortened_board_is_not_pulled_onto_its_neighbours(yaw):
    # squares of ~5 px: cornerSubPix's 9 x 9 window reaches the next corner and
    # pulled whole rows 2.5 px off; the detector must not return such corners
    img, true, inner = _yawed_board(yaw)
    corners, w, why = detect_board(img, inner)
    assert why == "" and corners is not None
    if np.linalg.norm(corners[0] - true[0]) > np.linalg.norm(corners[0] - true[-1]):
        true = true[::-1]
    err = np.linalg.norm(corners - true, axis=1)
    assert err.max() < 0.5, err.max()
    assert grid_irregularity(corners, inner) <= MAX_GRID_IRREGULARITY


def test_board_detection_in_threads_gives_the_same_views_in_order(tmp_path):
    """detect_cameras shares the views among threads: corners, reasons, windows and ticks as one thread gives."""
    import shutil

    from horsemocap.calibration.board import detect_cameras

    src = data_samples_dir() / "horse2_canter" / "calibration"
    # views found by the classic detector, views only the sector detector finds (left17, middle3) and one
    # where neither finds the board (middle1)
    picks = {"left": ["left1", "left17", "left2"], "middle": ["middle1", "middle3", "middle2"]}
    dirs = {}
    for cam, names in picks.items():
        dirs[cam] = tmp_path / cam
        dirs[cam].mkdir()
        for name in names:
            shutil.copy(src / cam / f"{name}.jpg", dirs[cam])
    ticks = {cam: [] for cam in dirs}
    alone = detect_cameras(dirs, (7, 14), workers=1)
    shared = detect_cameras(dirs, (7, 14), workers=3,
                            ticks={cam: (lambda d, t, cam=cam: ticks[cam].append((d, t))) for cam in dirs})
    assert list(shared) == ["left", "middle"]
    for cam in dirs:
        a, b = alone[cam], shared[cam]
        assert a.names == b.names and a.files == b.files and a.reasons == b.reasons and a.size == b.size
        np.testing.assert_array_equal(a.corners, b.corners)          # NaN where not found, bit for bit
        np.testing.assert_array_equal(a.windows, b.windows)
        assert ticks[cam] == [(1, 3), (2, 3), (3, 3)]
    assert alone["middle"].reasons[0] != "" and alone["middle"].found[1:].all() and alone["left"].found.all()
    with pytest.raises(CalibrationError, match="at least 1 worker"):
        detect_cameras(dirs, (7, 14), workers=0)


def test_board_detection_in_threads_names_a_view_of_another_size(tmp_path):
    from horsemocap.calibration.board import detect_cameras

    d = tmp_path / "left"
    d.mkdir()
    import cv2

    cv2.imwrite(str(d / "01.png"), np.full((60, 80), 90, np.uint8))
    cv2.imwrite(str(d / "02.png"), np.full((50, 80), 90, np.uint8))
    with pytest.raises(CalibrationError, match=r"02\.png: image size 80x50 differs from 80x60"):
        detect_cameras({"left": d}, (7, 5), workers=2)


def test_opencv_single_threaded_blocks_overlapping_in_threads_restore_the_setting():
    """Two blocks interleaved (A in, B in, A out, B out) leave OpenCV's thread count as it was."""
    import cv2

    from horsemocap.calibration.board import opencv_single_threaded

    before = cv2.getNumThreads()
    cv2.setNumThreads(2)
    try:
        a, b = opencv_single_threaded(), opencv_single_threaded()
        a.__enter__()
        assert cv2.getNumThreads() == 1
        b.__enter__()
        a.__exit__(None, None, None)
        assert cv2.getNumThreads() == 1          # B still inside: not restored under it
        b.__exit__(None, None, None)
        assert cv2.getNumThreads() == 2
    finally:
        cv2.setNumThreads(before)


def test_blas_single_threaded_blocks_overlapping_in_threads_restore_the_setting():
    """The BLAS thread limit counts its blocks as OpenCV's does: one thread inside any block, the
    setting found before the first block back after the last (A in, B in, A out, B out)."""
    from threadpoolctl import threadpool_info, threadpool_limits

    from horsemocap.threads import blas_single_threaded

    def blas_threads():
        return {i["filepath"]: i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"}

    if not blas_threads():
        pytest.skip("no BLAS library with a thread pool is loaded")
    with threadpool_limits(limits=2, user_api="blas"):
        before = blas_threads()
        a, b = blas_single_threaded(), blas_single_threaded()
        a.__enter__()
        assert set(blas_threads().values()) == {1}
        b.__enter__()
        a.__exit__(None, None, None)
        assert set(blas_threads().values()) == {1}      # B still inside: not restored under it
        b.__exit__(None, None, None)
        assert blas_threads() == before


def test_calibration_tables_wrap_by_columns():
    """``max_width``: a table too wide is split into blocks of whole columns, each line within the width and
    every row label repeated; without it one line per row, columns as wide as their longest entry."""
    from horsemocap.calibration.report import _table_lines

    cols = [["alone", "[1.000 2.000]", "± [0.1 0.2]"], ["pair", "[1.500 2.500]", "± [0.3 0.4]"],
            ["joint (all cameras)", "[1.250 2.250]", "± [0.05 0.06]"]]
    labels = ["", "Focal length", "Focal length uncertainty"]
    one = _table_lines(labels, cols, 26)
    assert len(one) == 3 and one[1].split() == ["Focal", "length", "[1.000", "2.000]", "[1.500", "2.500]", "[1.250", "2.250]"]
    wrapped = _table_lines(labels, cols, 26, max_width=60)
    assert all(len(line) <= 60 for line in wrapped)
    assert sum(line.startswith("Focal length uncertainty") for line in wrapped) == 2   # the labels in each block
    assert "" in wrapped and "joint (all cameras)" in "\n".join(wrapped)


def test_grid_may_continue_beyond_the_image_edge():
    from horsemocap.calibration.board import grid_may_continue

    u, v = np.meshgrid(np.arange(7) * 10.0, np.arange(4) * 10.0, indexing="ij")
    grid = np.stack([u, v], -1)                           # 7 x 4 corners, 10 px apart
    assert not grid_may_continue(grid + [100, 100], (300, 300))
    assert grid_may_continue(grid + [5, 100], (300, 300))          # the next column would be at -5
    assert grid_may_continue(grid + [12, 100], (300, 300))         # at 2 px: within a square of the edge
    assert not grid_may_continue(grid + [21, 100], (300, 300))     # at 11 px: a square clear
    assert grid_may_continue(grid + [100, 255], (300, 300))        # the next row at 295 px, of 300
