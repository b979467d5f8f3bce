"""The notebooks' guards for sessions other than the thesis' (horsemocap.widgets.markers_guard) and
accuracy.simulate_rig for a session with four markers and free-running cameras (notebook 14, section 6)."""
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from horsemocap import accuracy, rigid
from horsemocap.params import AnalysisParams
from horsemocap.pipeline import AnalysisError
from horsemocap.session import Session
from horsemocap.virtuallab import thesis_rig
from horsemocap.widgets.markers_guard import (fits_note, marker_numbers, marker_pairs, table_8_7_ride,
                                              thesis_three_note, thesis_view)


def test_marker_text_follows_the_count():
    assert marker_numbers(3) == "1, 2, 3"
    assert marker_numbers(4) == "1, 2, 3, 4"
    assert marker_pairs(3) == [(0, 1), (1, 2), (0, 2)]           # the thesis' order of the distances
    pairs = marker_pairs(5)
    assert len(pairs) == 10 and len(set(pairs)) == 10 and all(i < j for i, j in pairs)
    assert thesis_three_note(3) == ""
    assert "markers 1, 2, 3" in thesis_three_note(4) and "all 4" in thesis_three_note(4)


def test_fits_note_names_why():
    assert fits_note(SimpleNamespace(motion_fit=object(), chain_error="")) == ""
    text = fits_note(SimpleNamespace(motion_fit=None, chain_error="no period found"))
    assert "no period found" in text and "pose" in text


def test_table_8_7_ride():
    assert table_8_7_ride({"horse": "Horse 2", "gait": "canter"})[0]
    same, text = table_8_7_ride({"horse": "Horse 1", "gait": "canter"})
    assert not same and "Horse 2 at canter" in text and "Horse 1 at canter" in text
    assert not table_8_7_ride({})[0]


def _pose_only_body(n=40, m=4, seed=0):
    """A rigid body of m markers turning and moving smoothly, as a pose-only RigidBodyAnalysis would hold it."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 50.0
    model = rng.normal(0, 0.15, (m, 3))
    w = np.array([0.3, 1.1, -0.6])                               # constant angular velocity (rad/s)
    v = np.array([4.0, 0.1, 0.0])
    from scipy.spatial.transform import Rotation
    rot = Rotation.from_rotvec(t[:, None] * w)
    pos = np.einsum("kij,mj->kmi", rot.as_matrix(), model) + (t[:, None] * v)[:, None]
    vel = np.cross(w, pos - (t[:, None] * v)[:, None]) + v
    acc = np.cross(w, vel - v)
    saddle_body = rigid.saddle_in_body_versions(pos[0, :3], pos[0, :3].mean(0) + [0, 0.3, 0.2])
    return SimpleNamespace(motion_fit=None, chain_error="it uses three markers (eq. 6.3-6.55); the ride has 4",
                           marker_kinematics=(pos, vel, acc), omega=np.tile(w, (n, 1)), alpha=np.zeros((n, 3)),
                           saddle_body=saddle_body, saddle_velocity=np.zeros((n, 3)),
                           saddle_acceleration=np.zeros((n, 3))), w


def test_thesis_view_without_the_chain_uses_three_markers_of_the_pose():
    body, w = _pose_only_body()
    view = thesis_view(body)
    assert not view.chain and "the ride has 4" in view.note
    assert view.pos.shape == (40, 3, 3)
    assert view.omega_raw.shape == view.alpha_raw.shape == (6, 40, 3)
    np.testing.assert_allclose(view.omega_raw, np.broadcast_to(w, view.omega_raw.shape), atol=1e-9)
    np.testing.assert_allclose(view.omega_lstsq, np.broadcast_to(w, (40, 3)), atol=1e-9)   # all four markers
    assert np.nanmax(np.abs(view.alpha_raw)) < 1e-8                # alpha = 0 (NaN only where eq. 6.38/6.39 are 0/0)
    assert np.isfinite(view.saddle.acceleration).all()
    np.testing.assert_allclose(view.saddle.position_versions, np.broadcast_to(view.saddle.position, (3, 40, 3)),
                               atol=1e-9)                          # a rigid pose: the three bases agree


def _session(marker_count=4):
    timing = {c: {"nominal_fps": 50.0, "exposure_s": 0.01, "rolling_shutter_s": 0.005} for c in ("left", "middle", "right")}
    return Session(root=Path("."), name="ride4", fps=50.0, cameras=("left", "middle", "right"),
                   reference_camera="left", motion={}, sync_method="flash", sync_offsets=None, rig_path=None,
                   calibration_images=None, board=None, plumb=None, static=None, marker_count=marker_count,
                   marker_diameter_m=0.06, metadata={"horse": "Horse 1", "gait": "canter", "camera_timing": timing})


def test_simulate_rig_runs_for_a_four_marker_session_without_truth():
    analysis = SimpleNamespace(session=_session(4), params=AnalysisParams())
    sim, truth = accuracy.simulate_rig(analysis, thesis_rig(), 30.0, 0.25, seed=2)
    assert sim.session.marker_count == 3                          # the virtual horse's markers, not the session's
    assert "camera_timing" not in sim.session.metadata            # simulated cameras are genlocked
    a, b = sim.triangulate.segment
    assert b - a >= 8
    st = accuracy.stage_errors(sim, truth)
    assert np.isfinite(st["saddle_acc_y_rmse_pct_of_rms"])


def test_simulate_rig_without_a_segment_names_what_is_missing(monkeypatch):
    def nothing_seen(truth, offsets, n_frames, n_markers, sigma_px, rng):
        return {c: np.full((n_frames, n_markers, 2), np.nan) for c in truth.marker_px}

    monkeypatch.setattr(accuracy, "noisy_projections", nothing_seen)
    analysis = SimpleNamespace(session=_session(4), params=AnalysisParams())
    with pytest.raises(AnalysisError, match="sees all 3 skin markers"):
        accuracy.simulate_rig(analysis, thesis_rig(), 30.0, 0.25, seed=2)
    rows = accuracy.rig_study(analysis, {"blind": (thesis_rig(), 30.0)}, sigma_px=0.25)
    assert "sees all 3 skin markers" in rows[0]["failed"]


def test_simulate_rig_takes_the_defaults_of_choices_that_name_the_sessions_markers():
    """A four-marker session whose motion frame follows marker 4: the three-marker simulated ride follows the
    default marker (the thesis' motion frame, eq. 5.6/5.7), not a silent fallback to the whole record."""
    params = AnalysisParams().updated({"motion_frame.x_marker": 3})
    analysis = SimpleNamespace(session=_session(4), params=params)
    sim, _ = accuracy.simulate_rig(analysis, thesis_rig(), 30.0, 0.25, seed=2)
    assert sim.params.motion_frame.x_marker == 0
    assert sim.motion_frame.frame.marker == 0


def test_period_plot_without_a_period_draws_the_autocorrelation_alone():
    import matplotlib
    matplotlib.use("Agg")
    from horsemocap.plots.frames import plot_period_estimate

    acf = np.cos(np.linspace(0, 3, 20))
    ax = plot_period_estimate(acf, None, 50.0)
    assert ax.get_title() == "no period found" and len(ax.lines) == 2      # the curve and the zero line
    ax = plot_period_estimate(acf, 12.0, 50.0)
    assert len(ax.lines) == 3 and "T = 12.00 frames" in ax.get_legend().get_texts()[0].get_text()
