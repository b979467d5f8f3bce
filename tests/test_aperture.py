"""The camera's temporal aperture in the smoothing: known motions observed through a box or two fields."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from horsemocap import pose, splines
from horsemocap.aperture import Aperture, box_aperture, camera_aperture, mean_aperture, session_aperture
from horsemocap.params import PoseParams
from horsemocap.session import Session, SessionError

FPS = 25.0
F0 = 1.4                                  # a trot's stride frequency
AMPLITUDES = {1: 8e-3, 2: 15e-3, 4: 1.6e-3, 6: 0.45e-3}     # harmonics of a saddle's height (m)


def _motion(t, derivative=0):
    """The true height and its derivatives: a sum of stride harmonics."""
    out = np.zeros_like(t)
    for k, a in AMPLITUDES.items():
        w = 2 * np.pi * k * F0
        out += a * w ** derivative * np.sin(w * t + 0.3 * k + derivative * np.pi / 2)
    return out


def _observed(t, aperture):
    """What each frame observes of the motion: exactly, harmonic by harmonic, times the aperture's gain."""
    out = np.zeros_like(t)
    for k, a in AMPLITUDES.items():
        w = 2 * np.pi * k * F0
        out += a * np.abs(aperture.gain(k * F0)) * np.sin(w * t + 0.3 * k + np.angle(aperture.gain(k * F0)))
    return out


def _rel(a, b):
    return float(np.sqrt(np.mean((a - b) ** 2)) / np.sqrt(np.mean(b ** 2)))


def test_box_and_fields_gains_are_the_known_filters():
    """The quadrature's gains against the exact filters (Gauss nodes: within 1e-6 up to 8.4 Hz)."""
    f = np.array([1.4, 8.4])
    np.testing.assert_allclose(box_aperture(0.02).gain(f).real, np.sinc(f * 0.02), atol=1e-6)
    both = camera_aperture(FPS, 0.02, interlaced=True).gain(f)
    np.testing.assert_allclose(both.real, np.cos(np.pi * f * 0.02) * np.sinc(f * 0.02), atol=1e-6)
    np.testing.assert_allclose(both.imag, 0, atol=1e-12)
    fields_only = camera_aperture(FPS, None, interlaced=True)
    np.testing.assert_allclose(fields_only.gain(f).real, np.cos(np.pi * f * 0.02), atol=1e-12)


def test_the_quadrature_is_exact_for_a_quintic_on_each_half_of_the_box():
    """Each box is split at the frame's instant: a polynomial of degree 5 on each side (a quintic spline with
    a knot there) is averaged exactly."""
    a = box_aperture(0.03)

    def piece(u):
        return np.where(u < 0, 1 + 2 * u + 3 * u ** 5, 1 - u ** 4 + 7 * u ** 5)

    h = 0.015
    exact = ((h - h ** 2 - h ** 6 / 2) + (h - h ** 5 / 5 + 7 * h ** 6 / 6)) / (2 * h)
    assert abs(a.average(piece, np.zeros(1))[0] - exact) < 1e-14


@pytest.mark.parametrize("aperture", [box_aperture(0.02), camera_aperture(FPS, 0.02, interlaced=True)],
                         ids=["box 20 ms", "two fields 20 ms apart"])
def test_a_harmonic_motion_seen_through_the_aperture_is_recovered_with_its_second_derivative(aperture):
    t = np.arange(75) / FPS
    y = _observed(t, aperture)
    inner = slice(3, -3)
    fit = splines.smoothing_spline(t, y, fundamental_hz=F0, aperture=aperture)
    assert fit.info["harmonic_indices"][-1] >= 6
    assert _rel(fit(t)[inner], _motion(t)[inner]) < 1e-6
    assert _rel(fit(t, 2)[inner], _motion(t, 2)[inner]) < 1e-6
    np.testing.assert_allclose(fit.observed(t), y, atol=1e-9)
    # the same samples taken for the motion at their instants: the acceleration is the blurred one
    plain = splines.smoothing_spline(t, y, fundamental_hz=F0)
    blur = 1 - np.abs(aperture.gain(6 * F0))
    assert _rel(plain(t, 2)[inner], _motion(t, 2)[inner]) > 0.3 * blur


def test_a_noisy_motion_through_two_fields_loses_less_acceleration_with_the_aperture():
    """With noise (the plain spline's GCV chooses the smoothing) the aperture model removes the fields'
    low-pass: the acceleration's rms error is smaller over ten draws."""
    aperture = camera_aperture(FPS, 0.02, interlaced=True)
    t = np.arange(75) / FPS
    rng = np.random.default_rng(3)
    errors = {True: [], False: []}
    for _ in range(10):
        y = _observed(t, aperture) + rng.normal(0, 5e-5, t.size)
        for use in (True, False):
            fit = splines.smoothing_spline(t, y, fundamental_hz=F0, aperture=aperture if use else None)
            errors[use].append(_rel(fit(t, 2)[3:-3], _motion(t, 2)[3:-3]))
    assert np.median(errors[True]) < 0.8 * np.median(errors[False])


def test_without_an_aperture_nothing_changes():
    t = np.arange(60) / FPS
    y = _motion(t) + np.random.default_rng(0).normal(0, 1e-4, t.size)
    a = splines.smoothing_spline(t, y, fundamental_hz=F0)
    b = splines.smoothing_spline(t, y, fundamental_hz=F0, aperture=None)
    np.testing.assert_array_equal(a(t, 2), b(t, 2))
    assert session_aperture(FPS, [{}, {}, {}]) is None
    assert session_aperture(FPS, {"left": {"exposure_s": 0}, "right": {}}) is None


def test_a_camera_timing_without_exposure_gets_the_documented_default_of_half_a_frame():
    """As the synchronisation times the flash: a camera with a camera_timing entry but no exposure_s is
    exposed half a frame; exposure 0 is an instant."""
    f = np.array([1.4, 8.4])
    rolling = session_aperture(FPS, {"left": {"rolling_shutter_s": 0.02}})
    np.testing.assert_allclose(rolling.gain(f), box_aperture(0.5 / FPS).gain(f), atol=1e-12)
    fields = session_aperture(FPS, {"left": {"interlaced": "top_first"}})
    np.testing.assert_allclose(fields.gain(f), camera_aperture(FPS, 0.02, interlaced=True).gain(f), atol=1e-12)
    instants = session_aperture(FPS, {"left": {"interlaced": "top_first", "exposure_s": 0}})
    np.testing.assert_allclose(instants.gain(f), np.cos(np.pi * f * 0.02), atol=1e-12)


def test_exposures_a_camera_cannot_have_are_refused_naming_the_camera_field():
    with pytest.raises(ValueError, match=r"camera_timing\.left\.exposure_s.*one frame"):
        session_aperture(FPS, {"left": {"exposure_s": 8}})
    with pytest.raises(ValueError, match=r"camera_timing\.right\.exposure_s.*one field"):
        session_aperture(FPS, {"left": {}, "right": {"exposure_s": 0.03, "interlaced": "bottom_first"}})
    with pytest.raises(ValueError, match=r"camera_timing\.left\.interlaced"):
        session_aperture(FPS, {"left": {"interlaced": "progressive"}})
    with pytest.raises(ValueError, match="exposure_s"):
        camera_aperture(FPS, 0.041)
    assert camera_aperture(FPS, 0.04) is not None and camera_aperture(FPS, 0.02, interlaced=True) is not None


@pytest.mark.parametrize("given, field", [({"interlaced": "progressive"}, "interlaced"),
                                          ({"interlaced": "none"}, "interlaced"),
                                          ({"exposure_s": 8}, "exposure_s"),
                                          ({"exposure_s": 0.03, "interlaced": "top_first"}, "exposure_s"),
                                          ({"exposure_s": "fast"}, "exposure_s"),
                                          ({"rolling_shutter_s": -0.01}, "rolling_shutter_s")])
def test_session_camera_timing_refuses_values_a_camera_cannot_have(given, field):
    session = Session(root=Path("."), name="s", fps=FPS, cameras=("left",), reference_camera="left", motion={},
                      sync_method="flash", sync_offsets=None, rig_path=None, calibration_images=None, board=None,
                      plumb=None, static=None, marker_count=3, marker_diameter_m=0.06,
                      metadata={"camera_timing": {"left": given}})
    with pytest.raises(SessionError, match=rf"session\.json: field 'metadata\.camera_timing\.left\.{field}'"):
        session.camera_timing("left")


def test_session_camera_timing_passes_what_a_camera_can_have():
    given = {"left": {"interlaced": "bottom_first", "exposure_s": 0.02, "rolling_shutter_s": 0.0},
             "right": {"interlaced": None, "exposure_s": 0.04}, "top": {"interlaced": False}}
    session = Session(root=Path("."), name="s", fps=FPS, cameras=tuple(given), reference_camera="left", motion={},
                      sync_method="flash", sync_offsets=None, rig_path=None, calibration_images=None, board=None,
                      plumb=None, static=None, marker_count=3, marker_diameter_m=0.06,
                      metadata={"camera_timing": given})
    assert {c: session.camera_timing(c) for c in given} == given


def test_the_pose_trajectory_through_the_aperture_recovers_the_motion():
    """A body moving up and down with the stride harmonics, each frame's markers the mean over the aperture:
    the pose trajectory fitted through it has the true vertical acceleration; taken at the instants, not."""
    aperture = camera_aperture(FPS, 0.02, interlaced=True)
    t = np.arange(75) / FPS
    model = np.array([[0.0, 0, 0], [0.25, 0, 0], [0.1, 0.05, 0.2]])
    height = _observed(t, aperture)
    pts = model[None] + np.stack([np.zeros_like(t), height, np.zeros_like(t)], -1)[:, None]
    reg = pose.register_pose(pts, model)
    params = PoseParams(smoothing="gcv", partial_frames=False)
    inner = slice(3, -3)
    fitted = pose.fit_pose_trajectory(t, reg, model, params, fundamental_hz=F0, aperture=aperture)
    acc = fitted.points(t, model).acceleration[:, 0, 1]
    assert _rel(acc[inner], _motion(t, 2)[inner]) < 1e-3
    instants = pose.fit_pose_trajectory(t, reg, model, params, fundamental_hz=F0)
    assert _rel(instants.points(t, model).acceleration[inner, 0, 1], _motion(t, 2)[inner]) > 0.05


def test_bad_apertures_are_refused_by_name():
    with pytest.raises(ValueError, match="exposure_s"):
        camera_aperture(FPS, -0.01)
    with pytest.raises(ValueError, match="weights summing to 1"):
        Aperture((0.0, 0.01), (0.5, 0.6))
    with pytest.raises(ValueError, match="aperture"):
        splines.smoothing_spline(np.arange(20.0), np.arange(20.0), order=3, aperture=box_aperture(0.5))


def test_cameras_with_different_apertures_average_them():
    a = mean_aperture([box_aperture(0.02), camera_aperture(FPS, 0.02, interlaced=True), None])
    f = 8.4
    expected = (np.sinc(f * 0.02) + np.cos(np.pi * f * 0.02) * np.sinc(f * 0.02) + 1) / 3
    assert abs(a.gain(f).real - expected) < 1e-6


@pytest.mark.parametrize("smoothing, modelled", [("gcv", True), ("gcv_cubic", False), ("auto", True)])
def test_a_smoothing_asked_for_by_name_records_whether_the_aperture_was_modelled(smoothing, modelled):
    """The record (the trajectory's smoothing choice) says whether the pose was fitted through the aperture,
    for a named method as for the automatic choice; a settled re-fit keeps the named method."""
    aperture = camera_aperture(FPS, 0.02, interlaced=True)
    t = np.arange(75) / FPS
    model = np.array([[0.0, 0, 0], [0.25, 0, 0], [0.1, 0.05, 0.2]])
    pts = model[None] + np.stack([np.zeros_like(t), _observed(t, aperture), np.zeros_like(t)], -1)[:, None]
    reg = pose.register_pose(pts, model)
    params = PoseParams(smoothing=smoothing, partial_frames=False)
    fitted = pose.fit_pose_trajectory(t, reg, model, params, fundamental_hz=F0, aperture=aperture)
    reason = fitted.smoothing_choice["reason"]
    assert (fitted.centre_splines[1].aperture is not None) == modelled
    assert ("fitted through the frames' temporal aperture" in reason) == modelled
    assert ("temporal aperture (two fields 20 ms apart, each exposure 20 ms) not modelled" in reason) != modelled
    if smoothing != "auto":
        assert fitted.smoothing_choice["method"] == smoothing
        assert pose.settle_pose_smoothing(fitted, params).method == smoothing
    assert pose.fit_pose_trajectory(t, reg, model, PoseParams(smoothing="gcv", partial_frames=False),
                                    fundamental_hz=F0).smoothing_choice is None


def _rocking_body(t, aperture, model):
    """A body rocking about the x axis (the line of its first two markers) with two stride harmonics, each
    frame's markers their mean over the aperture."""
    def markers(u):
        u = np.atleast_1d(u)
        angle = 0.01 * np.sin(2 * np.pi * 2 * F0 * u) + 0.02 * np.sin(2 * np.pi * 4 * F0 * u + 0.5)
        R = Rotation.from_rotvec(np.outer(angle, [1.0, 0, 0])).as_matrix()
        return np.einsum("nij,mj->nmi", R, model) + np.array([0.0, 0.5, 0.0])

    return aperture.average(markers, t)


def test_two_marker_frames_are_completed_from_what_the_frames_observe():
    """A frame with two markers seen takes the rotation about their line from the smoothed trajectory: through
    an aperture, from its average over the frame (what the other frames' markers hold), so the completed frame
    agrees with the registration of all its (hidden) markers."""
    aperture = camera_aperture(FPS, 0.02, interlaced=True)
    t = np.arange(75) / FPS
    model = np.array([[0.0, 0, 0], [0.25, 0, 0], [0.1, 0.05, 0.2], [0.15, -0.08, 0.12]])
    pts = _rocking_body(t, aperture, model)
    full = pose.register_pose(pts, model)
    two = np.zeros(t.size, bool)
    two[6:-6:4] = True
    seen = pts.copy()
    seen[two, 2:] = np.nan
    reg = pose.register_pose(seen, model)
    params = PoseParams(smoothing="gcv", partial_frames=True)
    # noiseless: a near-interpolating smoothing, so the trajectory between the frames is the motion's
    fitted = pose.fit_pose_trajectory(t, reg, model, params, points=seen, lam=[1e-12] * 6, aperture=aperture)
    completed = Rotation.from_rotvec(fitted.rotvec_data[two]) * fitted._reference().rotation(t[two])
    err = np.abs(completed.as_rotvec()[:, 0] - Rotation.from_matrix(full.rotation[two]).as_rotvec()[:, 0])
    blur = np.abs(fitted.rotvec_splines[0](t[two]) - fitted.rotvec_splines[0].observed(t[two]))
    assert np.max(blur) > 1e-3                      # the aperture's average differs from the instant's
    assert np.max(err) < 0.01 * np.max(blur)


def test_the_smoothing_chosen_by_leaving_markers_out_is_made_through_the_aperture(monkeypatch):
    """Under correlated noise with five markers the smoothing is chosen by leaving each marker out: the
    white-noise GCV it scales and the left-out fits are made through the frames' aperture, as the pose is."""
    from scipy.signal import lfilter
    monkeypatch.setattr(pose, "LEFT_OUT_STACK", False)   # one route (the blend's parts: test_left_out_stack.py)
    aperture = camera_aperture(FPS, 0.02, interlaced=True)
    rng = np.random.default_rng(4)
    t = np.arange(150) / FPS
    model = np.column_stack([rng.uniform(-0.25, 0.25, 5), rng.uniform(-0.03, 0.03, 5), rng.uniform(-0.2, 0.2, 5)])
    clean = model[None] + np.stack([np.zeros_like(t), _observed(t, aperture), np.zeros_like(t)], -1)[:, None]
    noise = lfilter([1.0], [1.0, -0.8], rng.normal(0, 1e-3 * 0.6, clean.shape), axis=0)
    pts = clean + noise
    reg = pose.register_pose(pts, model)
    fitted = pose.fit_pose_trajectory(t, reg, model, PoseParams(smoothing="auto", partial_frames=False),
                                      points=pts, fundamental_hz=F0, aperture=aperture)
    choice = fitted.smoothing_choice
    assert "cross_validation" in choice and "fitted through the frames' temporal aperture" in choice["reason"]
    # the route the choice took (with or without the stride's harmonics) scales its own white-noise GCV
    stride_hz = choice["cross_validation"]["fundamental_hz"]
    white = pose.fit_pose_trajectory(t, reg, model, PoseParams(smoothing="gcv",
                                                               harmonics="none" if stride_hz is None else "auto",
                                                               rotation_weights="equal", partial_frames=False),
                                     iterations=0, aperture=aperture, fundamental_hz=stride_hz)
    base = np.array([s.info["lam"] for s in white.centre_splines + white.rotvec_splines])
    decades = np.array(choice["cross_validation"]["cross_validation_component_decades"])
    chosen = np.array([s.info["lam"] for s in fitted.centre_splines + fitted.rotvec_splines])
    np.testing.assert_allclose(chosen, base * 10.0 ** decades, rtol=1e-9)
