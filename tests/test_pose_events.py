"""Change points (known events) in the pose smoothing: truncated-power columns of a partial spline."""
import numpy as np
import pytest

from horsemocap import pose, splines, synthetic
from horsemocap.params import PoseParams


def _jump_signal(t, tau):
    """A smooth curve plus an exact jump of 3 m/s^2 in acceleration at tau: ``1.5 (t - tau)_+^2``."""
    smooth = 0.1 * np.sin(1.3 * t) + 0.02 * t ** 2
    acc = -0.1 * 1.3 ** 2 * np.sin(1.3 * t) + 0.04 + 3.0 * (t > tau)
    return smooth + 1.5 * np.clip(t - tau, 0, None) ** 2, acc


def test_truncated_power_columns_derivatives():
    t = np.linspace(0, 1, 11)
    c = splines.truncated_power_columns(t, [0.35], 2)
    assert np.allclose(c[:, 0], np.clip(t - 0.35, 0, None) ** 2)
    assert np.allclose(splines.truncated_power_columns(t, [0.35], 2, 1)[:, 0], 2 * np.clip(t - 0.35, 0, None))
    assert np.allclose(splines.truncated_power_columns(t, [0.35], 2, 2)[:, 0], 2.0 * (t > 0.35))
    assert np.all(splines.truncated_power_columns(t, [0.35], 2, 3) == 0)


@pytest.mark.parametrize("method", ["gcv", "adaptive"])
def test_exact_acceleration_jump_is_recovered(method):
    t = np.arange(300) / 100.0
    tau = 1.503
    y, acc = _jump_signal(t, tau)
    s = splines.smoothing_spline(t, y, method=method, events=[tau])
    err = np.max(np.abs(s(t, 2) - acc))
    assert err < 0.01                          # a 3 m/s^2 jump, everywhere including at tau (measured 0.002)
    assert s.events.coef[0] == pytest.approx(1.5, rel=0.005)
    plain = splines.smoothing_spline(t, y, method=method)
    assert np.max(np.abs(plain(t, 2) - acc)) > 10 * err          # the plain spline spreads the jump
    assert s.info["events"] == [tau]


def test_no_events_is_the_plain_spline():
    t = np.arange(120) / 50.0
    y = np.sin(3 * t) + np.random.default_rng(1).normal(0, 1e-3, t.size)
    a = splines.smoothing_spline(t, y)
    b = splines.smoothing_spline(t, y, events=[])
    assert np.array_equal(a(t, 2), b(t, 2)) and b.events is None


def test_bad_events_raise():
    t = np.arange(50) / 10.0
    y = np.sin(t)
    with pytest.raises(ValueError, match="events"):
        splines.smoothing_spline(t, y, events=[7.0])
    with pytest.raises(ValueError, match="events"):
        splines.smoothing_spline(t, y, events=[2.0], order=3)
    with pytest.raises(ValueError, match="events"):
        splines.smoothing_spline(t, y, events=[2.0], fundamental_hz=1.0)


def _rigid_with_jump(tau):
    """An exact rigid motion whose centre has a jump of acceleration at tau (no noise)."""
    t = np.arange(200) / 100.0
    y, acc = _jump_signal(t, tau)
    ang = 0.2 * np.sin(2.0 * t)
    c, s = np.cos(ang), np.sin(ang)
    R = np.zeros((t.size, 3, 3))
    R[:, 0, 0], R[:, 0, 1], R[:, 1, 0], R[:, 1, 1], R[:, 2, 2] = c, -s, s, c, 1
    model = np.array([[0.2, 0.1, 0.15], [-0.2, 0.1, 0.15], [0.05, 0.1, -0.15], [-0.2, -0.02, -0.15]])
    centre = np.stack([0.3 * t, 1.0 + y, np.zeros_like(t)], -1)
    markers = np.einsum("kij,mj->kmi", R, model - model.mean(0)) + centre[:, None]
    return t, markers, model, acc


@pytest.mark.parametrize("method", ["gcv", "adaptive"])
def test_pose_trajectory_with_event_gives_exact_derivatives(method):
    tau = 1.004
    t, markers, model, acc = _rigid_with_jump(tau)
    reg = pose.register_pose(markers, model)
    tr = pose.fit_pose_trajectory(t, reg, model, PoseParams(smoothing=method, harmonics="none", events=[tau]))
    away = (np.abs(t - tau) > 0.02) & (t > 0.05) & (t < t[-1] - 0.05)
    assert np.max(np.abs(tr.centre(t, 2)[:, 1] - acc)[away]) < 0.05
    assert np.max(np.abs(tr.centre(t, 2)[:, 0])[away]) < 0.05
    omega_true = 0.4 * np.cos(2.0 * t)
    assert np.max(np.abs(tr.omega(t)[:, 2] - omega_true)[away]) < 1e-3
    assert tr.smoothing["cy"]["events"] == [tau]


def test_pose_events_need_a_spline_without_harmonics():
    d = synthetic.lift_with_ringing(duration_s=2.0, ring_start_s=1.2, seed=0)
    reg = pose.register_pose(d["markers"], d["model"])
    with pytest.raises(ValueError, match="events"):
        pose.fit_pose_trajectory(d["t"], reg, d["model"], PoseParams(smoothing="gcv_cubic", events=[1.2]))


def test_pose_events_parameter_reaches_the_pipelines_pose_smoothing():
    """``pose_events`` (analyze's ``--pose-events``): the known instants reach every pose component's
    smoothing on the bundled session (the saddle's acceleration changes); times outside the smoothed
    record, and the options that cannot fit change points, are refused naming the parameter."""
    from horsemocap.data import default_session_dir
    from horsemocap.params import AnalysisParams, ParamsError
    from horsemocap.pipeline import AnalysisError, analyze, run_steps

    assert AnalysisParams().rigid_body.pose.events is None
    base = analyze(default_session_dir(), None, {}, until="motion_frame", progress=lambda *a: None)
    n = len(base.motion_frame.positions)
    tau = round(0.5 * (n - 1) / base.session.fps, 4)
    runs = {k: run_steps(base.session, base.params.updated({"rigid_body.pose.events": ev}), base, ["rigid_body"])
            .rigid_body for k, ev in (("none", None), ("event", [tau]))}
    smoothing = runs["event"].body.pose.smoothing
    assert all(v["events"] == [tau] for v in smoothing.values())
    assert all("events" not in v for v in runs["none"].body.pose.smoothing.values())
    assert not np.allclose(runs["event"].saddle_acceleration, runs["none"].saddle_acceleration)
    with pytest.raises(AnalysisError, match="pose_events.*outside"):
        run_steps(base.session, base.params.updated({"rigid_body.pose.events": [100.0]}), base, ["rigid_body"])
    for bad in ({"pose_events": [1.0], "kinematics": "fits"}, {"pose_events": [1.0], "pose_smoothing": "gcv"},
                {"pose_events": ["1.0"]}, {"pose_events": [1.0, 1.0]}):
        with pytest.raises(ParamsError, match="pose_events"):
            AnalysisParams.from_dict(bad)
    assert AnalysisParams.from_dict({"pose_events": [1.0], "pose_smoothing": "gcv",
                                     "pose_harmonics": "none"}).rigid_body.pose.events == [1.0]


def test_pose_events_option_is_parsed_or_refused(tmp_path, capsys):
    from horsemocap.cli import main
    from horsemocap.data import default_session_dir

    assert main(["analyze", str(default_session_dir()), "--out", str(tmp_path / "o"), "--pose-events", "0.5,x"]) == 2
    assert "--pose-events" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()
