"""The static shot check against the chain itself: the bundled session analysed in every kinematics/saddle_method
pair, the static saddle point moved 1 mm along x, y and z, the rigid-body step run again; the written vertical
acceleration's change must be what horsemocap.uncertainty.written_saddle_sensitivity predicts, and
horsemocap.quality.static_shot_of must carry exactly those rows."""
import numpy as np
import pytest

from horsemocap import quality
from horsemocap.data import default_session_dir
from horsemocap.pipeline import analyze, resolve_params
from horsemocap.session import load_session
from horsemocap.steps.rigid_body import step_rigid_body
from horsemocap.uncertainty import StaticShotUncertainty, written_saddle_sensitivity

PAIRS = [("pose_spline", "pose"), ("fits", "pose"), ("fits", "thesis"), ("fits", "direct")]
MOVE_M = 1e-3
_ANALYSES = {}
_MOVED_ROWS = {}


def _analysis(kinematics: str, saddle_method: str):
    """The bundled session analysed up to the rigid-body step with these choices (once per pair)."""
    key = (kinematics, saddle_method)
    if key not in _ANALYSES:
        params = resolve_params(load_session(default_session_dir())).updated(
            {"rigid_body.kinematics": kinematics, "rigid_body.fits.saddle_method": saddle_method})
        _ANALYSES[key] = analyze(default_session_dir(), None, params, progress=lambda *a: None,
                                 write_outputs=False, until="rigid_body")
    return _ANALYSES[key]


def _moved_saddle_rows(a) -> np.ndarray:
    """(n, 3): the written vertical acceleration's change per metre of the static saddle point moved along x, y,
    z, by running the rigid-body step again on the moved static shot (once per analysis)."""
    if id(a) in _MOVED_ROWS:
        return _MOVED_ROWS[id(a)]
    rb, mf = a.rigid_body, a.motion_frame
    rows = []
    for axis in range(3):
        moved = np.array(mf.static, float)
        moved[rb.saddle_index, axis] += MOVE_M
        again = step_rigid_body(a.session, a.params.rigid_body, a.triangulate, a.smooth.raw,
                                mf.replace(static=moved), a.detect.sync.offsets, lambda *x: None)
        rows.append((again.saddle_acceleration[:, 1] - rb.saddle_acceleration[:, 1]) / MOVE_M)
    _MOVED_ROWS[id(a)] = np.stack(rows, -1)
    return _MOVED_ROWS[id(a)]


def _rms(x) -> float:
    return float(np.sqrt(np.nanmean(np.asarray(x) ** 2)))


@pytest.mark.parametrize("kinematics,saddle_method", PAIRS)
def test_sensitivity_predicts_the_moved_saddle(kinematics, saddle_method):
    a = _analysis(kinematics, saddle_method)
    rb, mf = a.rigid_body, a.motion_frame
    predicted = written_saddle_sensitivity(rb.body, np.asarray(mf.static, float)[rb.static_order])[:, 1, :]
    actual = _moved_saddle_rows(a)
    # linear chains to rounding; a refitted Fourier path to its frequency search's tolerance
    exact = kinematics == "pose_spline" or saddle_method == "thesis"
    for axis in range(3):
        assert _rms(actual[:, axis]) > 0.1                          # the move does change the acceleration
        miss = _rms(predicted[:, axis] - actual[:, axis]) / _rms(actual[:, axis])
        assert miss < (1e-9 if exact else 1e-2), f"{'xyz'[axis]}: off by {miss:.2e} of the change's rms"


@pytest.mark.parametrize("kinematics,saddle_method", [("pose_spline", "pose"), ("fits", "pose")])
def test_static_shot_of_carries_the_chains_own_rows(kinematics, saddle_method):
    a = _analysis(kinematics, saddle_method)
    shot = quality.static_shot_of(a)
    assert isinstance(shot, StaticShotUncertainty)
    rows = _moved_saddle_rows(a)
    expected_sd = np.sqrt(np.einsum("ni,ij,nj->n", rows, shot.offset_covariance, rows))
    assert np.allclose(shot.acceleration_sd, expected_sd, rtol=1e-2, atol=1e-6)
    assert shot.rms == pytest.approx(_rms(a.rigid_body.saddle_acceleration[:, 1]))
    assert shot.pct_of_rms == pytest.approx(100 * shot.sd / shot.rms)


def test_static_shot_of_says_why_before_the_rigid_body_step():
    a = analyze(default_session_dir(), None, resolve_params(load_session(default_session_dir())),
                progress=lambda *x: None, write_outputs=False, until="triangulate")
    shot = quality.static_shot_of(a)
    assert shot == quality.StaticShotSkipped("the rigid-body step has not run")
    assert quality.check_static_shot(shot).level == "skipped"
