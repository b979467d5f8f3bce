"""Tests of horsemocap.frames (thesis 5.3 and 8.3) with exact synthetic truth."""
import numpy as np
import pytest

from horsemocap import frames as fr
from horsemocap.camera import rotation_matrix


def synthetic_motion(n=60, T=18.4, tilt=(0.1, 0.2, -0.05)):
    """Markers moving along u1 with periodic y/z, expressed in a tilted camera frame."""
    t = np.arange(n, dtype=float)
    R_CM = rotation_matrix(tilt)  # columns u1, u2, u3
    offsets = np.array([[0.0, 0.0, 0.0], [0.4, 0.05, 0.1], [0.8, -0.02, 0.05]])
    xm = np.empty((n, 3, 3))
    for k, off in enumerate(offsets):
        xm[:, k, 0] = -1.5 + 0.12 * t + 0.01 * np.sin(2 * np.pi * t / T + k) + off[0]
        xm[:, k, 1] = 0.3 + 0.04 * np.sin(2 * np.pi * t / T + 0.3 * k) + 0.01 * np.sin(4 * np.pi * t / T) + off[1]
        xm[:, k, 2] = 7.5 + 0.01 * np.cos(2 * np.pi * t / T + k) + off[2]
    return xm @ R_CM.T, xm, R_CM


def test_motion_frame_recovers_axes_and_coordinates():
    T = 18.0
    xc, xm, R_CM = synthetic_motion(T=T)
    mf = fr.motion_frame(xc, R_CM[:, 1], marker=0, period=T, n_periods=2)
    np.testing.assert_allclose(mf.R_CM, R_CM, atol=1e-12)
    np.testing.assert_allclose(fr.to_motion_frame(xc, mf), xm, atol=1e-12)
    np.testing.assert_allclose(mf.axes @ mf.axes.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(mf.axes) == pytest.approx(1.0)


def test_gravity_correction_eq_5_8_5_9():
    xc, _, R_CM = synthetic_motion(T=18.0)
    u2e = R_CM[:, 1] + 0.02 * R_CM[:, 0]  # plumb tilted 1.15 deg towards x-motion
    u2e /= np.linalg.norm(u2e)
    mf = fr.motion_frame(xc, u2e, period=18.0)
    np.testing.assert_allclose(mf.gravity, R_CM[:, 1], atol=1e-12)
    assert mf.gravity_correction_deg == pytest.approx(np.degrees(np.arctan(0.02)), rel=1e-6)
    np.testing.assert_allclose(np.cross(mf.axes[0], mf.axes[1]), mf.axes[2], atol=1e-12)


def test_fractional_period_interpolates():
    xc, _, R_CM = synthetic_motion(T=18.4)
    mf = fr.motion_frame(xc, R_CM[:, 1], period=18.4)
    assert fr.angle_deg(mf.axes[0], R_CM[:, 0]) < 0.05


def test_n_periods_default_and_error():
    xc, _, R_CM = synthetic_motion(n=30, T=18.4)
    mf = fr.motion_frame(xc, R_CM[:, 1], period=18.4)
    assert mf.n_periods == 1
    with pytest.raises(ValueError, match="record ends at frame 29"):
        fr.motion_frame(xc, R_CM[:, 1], period=18.4, n_periods=2)
    with pytest.raises(ValueError, match="marker 5"):
        fr.motion_frame(xc, R_CM[:, 1], marker=5, period=18.4)


def test_gravity_from_plumb_points_down_from_tail_to_tip():
    tail = np.array([0.1, -1.0, 7.0])
    tip = np.array([0.1, 0.5, 7.0])
    np.testing.assert_allclose(fr.gravity_from_plumb(tip, tail), [0, 1, 0])
    with pytest.raises(ValueError, match="zero"):
        fr.gravity_from_plumb(tip, tip)


@pytest.mark.parametrize("T", [12.5, 18.0, 18.7])
def test_estimate_period_signal_and_positions(T):
    rng = np.random.default_rng(1)
    n = 40
    t = np.arange(n)
    y = 0.03 * np.sin(2 * np.pi * t / T + 1.0) + 0.012 * np.sin(4 * np.pi * t / T) + 0.002 * t
    assert fr.estimate_period(y + rng.normal(0, 5e-4, n), 30.0) == pytest.approx(T, abs=0.15)
    xc, _, R_CM = synthetic_motion(n=n, T=T)
    assert fr.estimate_period(xc, 30.0, gravity=R_CM[:, 1]) == pytest.approx(T, abs=0.05)
    assert fr.estimate_period(xc, 30.0) == pytest.approx(T, abs=0.05)
    # the default of motion_frame uses it
    assert fr.motion_frame(xc, R_CM[:, 1]).period_frames == pytest.approx(T, abs=0.05)


def test_estimate_period_rejects_aperiodic():
    with pytest.raises(ValueError):
        fr.estimate_period(np.arange(40.0) * 0.1, 30.0)


def test_time_axis_eq_5_13():
    np.testing.assert_allclose(fr.time_axis(4, 30.0), [0, 1 / 30, 2 / 30, 3 / 30])
    with pytest.raises(ValueError):
        fr.time_axis(4, 0)


def test_free_fall_g_exact_and_noisy():
    fps, g = 30.0, 9.81
    t = np.arange(21) / fps
    down = np.array([0.02, 0.999, 0.03])
    down /= np.linalg.norm(down)
    side = np.cross(down, [0, 0, 1.0])
    pos = np.array([0.2, -0.8, 7.4]) + np.outer(-2.5 * t + 0.5 * g * t**2, down) + np.outer(0.1 * t, side)
    out = fr.free_fall_g(pos, down, fps)
    assert out["g"] == pytest.approx(g, abs=1e-9)
    assert out["error_pct"] == pytest.approx(0.0, abs=1e-7)
    pos_noisy = pos + np.random.default_rng(0).normal(0, 0.001, pos.shape)
    pos_noisy[4] = np.nan
    out = fr.free_fall_g(pos_noisy, down, fps)
    assert out["n_missing"] == 1 and out["n_used"] == 20
    assert abs(out["g"] - g) < 4 * out["g_std"] + 1e-3


def test_rmse_per_axis():
    a = np.zeros((5, 2, 3))
    b = a.copy()
    b[..., 1] = 0.002
    b[0, 0] = np.nan
    np.testing.assert_allclose(fr.rmse_per_axis(b, a), [0, 0.002, 0])


# ---------------------------------------------------------------------------
# the default virtual session and the ball drop against their truth
# ---------------------------------------------------------------------------
from horsemocap.data import data_samples_dir, default_session_dir  # noqa: E402


def _session_truth(path):
    from horsemocap.virtuallab import load_truth

    if not (path / "truth" / "truth.json").is_file():
        pytest.skip(f"{path} has no ground truth (not rendered)")
    return load_truth(path)


def _noisy_session_pixels(truth, seed, noise_px=0.1):
    rng = np.random.default_rng(seed)
    out = {}
    for cam in truth.rig.names:
        k = truth.ref_frames - truth.offsets["left"] + truth.offsets[cam]
        px = truth.marker_px[cam][k, :3]
        out[cam] = px + rng.normal(0.0, noise_px, px.shape)
    return out


@pytest.fixture(scope="module")
def session_errors():
    """RMSE (mm) along the true motion axes after smoothing, per mode, over 4 noise seeds."""
    from horsemocap import reconstruction, smoothing

    truth = _session_truth(default_session_dir())
    A = truth.motion_axes
    errs = {"thesis": [], "joint": []}
    for seed in range(4):
        px = _noisy_session_pixels(truth, seed)
        for mode in errs:
            p = smoothing.smooth_positions(reconstruction.triangulate(truth.rig, px, mode=mode).points)
            errs[mode].append(1000 * fr.rmse_per_axis(p @ A.T, truth.marker_pos @ A.T))
    return {m: np.array(v) for m, v in errs.items()}


def test_session_y_motion_below_3mm_and_joint_depth_no_worse(session_errors):
    for mode, e in session_errors.items():
        assert np.all(e[:, 1] < 3.0), (mode, e[:, 1])
    assert session_errors["joint"][:, 2].mean() <= session_errors["thesis"][:, 2].mean()


@pytest.mark.xfail(strict=True, reason="sensitivity, not the pipeline path (the detector is ~0.06 px): "
                   "with 0.1 px noise the depth error leaks into x-motion; measured about 4.4-4.9 mm "
                   "RMSE after smoothing (see notebook 06)")
def test_session_x_motion_below_3mm(session_errors):
    for mode, e in session_errors.items():
        assert np.all(e[:, 0] < 3.0), (mode, e[:, 0])


@pytest.fixture(scope="module")
def session_detected_errors():
    """RMSE (mm) along the true motion axes after smoothing, per mode, from the detector's pixels."""
    import json

    from horsemocap import detection, reconstruction, smoothing
    from horsemocap.sources import FrameSource

    session = default_session_dir()
    truth = _session_truth(session)
    meta = json.loads((session / "session.json").read_text())
    px = {}
    for cam in truth.rig.names:
        k = truth.ref_frames - truth.offsets["left"] + truth.offsets[cam]
        video = FrameSource(session / meta["motion"][cam])
        px[cam] = detection.detect_markers(video.read(int(k[0]), int(k[-1]) + 1), 3).marker_px
    A = truth.motion_axes
    out = {}
    for mode in ("thesis", "joint"):
        p = smoothing.smooth_positions(reconstruction.triangulate(truth.rig, px, mode=mode).points, nan="omit")
        out[mode] = 1000 * fr.rmse_per_axis(p @ A.T, truth.marker_pos @ A.T)
    return out


def test_session_detected_pixels_meet_the_targets(session_detected_errors):
    """The issue's targets on the pipeline's path (detected pixels -> triangulate -> smooth)."""
    for mode, e in session_detected_errors.items():
        assert e[0] < 3.0 and e[1] < 3.0, (mode, e)
    assert session_detected_errors["joint"][2] <= session_detected_errors["thesis"][2]


def test_session_plumb_gravity_within_0p2_degree():
    from horsemocap import detection, reconstruction
    from horsemocap.sources import read_image

    session = default_session_dir()
    truth = _session_truth(session)
    px = {}
    for cam in truth.rig.names:
        still = next((session / "plumb").glob(f"{cam}.*"))
        px[cam] = detection.detect_still(read_image(still), 2)[None]  # upper (tail), lower (tip)
    plumb = reconstruction.triangulate(truth.rig, px, mode="joint")
    g = fr.gravity_from_plumb(plumb.points[0, 1], plumb.points[0, 0])
    assert fr.angle_deg(g, truth.gravity) < 0.2


def test_ball_drop_g_within_1p5_percent():
    import json

    from horsemocap import detection, reconstruction
    from horsemocap.sources import FrameSource, read_image

    ball = data_samples_dir() / "ball_drop"
    truth = _session_truth(ball)
    sj = json.loads((ball / "session.json").read_text())
    px = {c: detection.detect_markers(FrameSource(ball / sj["motion"][c]).read(), 1).marker_px
          for c in truth.rig.names}
    plumb_px = {c: detection.detect_still(read_image(ball / sj["plumb"][c]), 2)[None] for c in truth.rig.names}
    plumb = reconstruction.triangulate(truth.rig, plumb_px).points[0]
    gravity = fr.gravity_from_plumb(plumb[1], plumb[0])
    pts = reconstruction.triangulate(truth.rig, px).points[:, 0]
    out = fr.free_fall_g(pts, gravity, truth.fps)
    assert out["error_pct"] < 1.5
    assert out["n_used"] == 21


def test_widgets_default_to_the_automatic_choice():
    from horsemocap import widgets

    assert widgets.ui_motion_marker(3).value == 0
    assert widgets.ui_period(18.37, 37).value == pytest.approx(18.37)
    assert widgets.ui_n_periods().value == 2
    assert widgets.ui_triangulation_mode().value == "joint"
    from horsemocap.params import AnalysisParams

    w = widgets.ui_smoothing()
    assert w.value == {"method": AnalysisParams().smooth.method, "span": AnalysisParams().smooth.span}
    w.method.value = "lowess"
    assert w.value["method"] == "lowess"


def test_a_period_faster_than_a_horse_can_stride_is_searched_again():
    """A trot's vertical motion: two alike bounces per stride (period 18 frames at 25 fps, 1.39 Hz), a
    slight difference between them; 38 frames (2.1 strides). The autocorrelation's first prominent
    peak is the half stride (2.78 Hz: faster than a horse strides); with the stride's upper rate the
    period is searched again among longer lags and found whole."""
    from horsemocap.frames import HORSE_STRIDE_HZ, estimate_period

    k = np.arange(38.0)
    w = 2 * np.pi / 18.0
    y = 0.03 * np.sin(2 * w * k) + 0.006 * np.sin(w * k + 0.4) + 0.004 * np.sin(3 * w * k)
    half = estimate_period(y, 25.0)
    assert half == pytest.approx(9.0, abs=0.5)
    assert estimate_period(y, 25.0, max_rate_hz=HORSE_STRIDE_HZ[1]) == pytest.approx(18.0, abs=0.3)
    # a record too short to show the whole stride keeps the faster period (the quality check flags it)
    assert estimate_period(y[:26], 25.0, max_rate_hz=HORSE_STRIDE_HZ[1]) == pytest.approx(9.0, abs=0.5)
    # a period within a horse's range is left alone
    slow = 0.03 * np.sin(w * k)
    assert estimate_period(slow, 25.0, max_rate_hz=HORSE_STRIDE_HZ[1]) == pytest.approx(18.0, abs=0.3)


def test_estimate_period_on_drifts_returns_or_raises_value_error():
    """Every autocorrelation peak of a drift may be negative: a clear ValueError, never StopIteration
    (which escaped the pipeline's handling before)."""
    from horsemocap.frames import HORSE_STRIDE_HZ, estimate_period

    rng = np.random.default_rng(3)
    for _ in range(200):
        y = np.cumsum(rng.normal(size=36))
        for rate in (None, HORSE_STRIDE_HZ[1]):
            try:
                estimate_period(y, 25.0, max_rate_hz=rate)
            except ValueError:
                pass
