"""The moving frames' noise at the saddle against the saddle's motion (horsemocap.uncertainty.saddle_scatter)
and its quality check (horsemocap.quality.check_saddle_scatter), against exact answers."""
from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from horsemocap import quality
from horsemocap.uncertainty import MIN_SCATTER_FRAMES, SaddleScatter, saddle_scatter

SADDLE = np.array([0.5, 0.0, 0.0])      # half a metre behind the markers' centre, in the model frame


def _tilted(n=100, tilt=0.01, height=0.03):
    """A saddle moving up and down (``height`` rms) whose frames are each tilted by +-``tilt`` rad about z (a
    thin triangle's pitch noise): the per-frame registration and the written (true) position."""
    t = np.arange(n) / 50.0
    written = np.zeros((n, 3))
    written[:, 1] = height * np.sqrt(2) * np.sin(2 * np.pi * 1.5 * t)
    theta = np.where(np.arange(n) % 2, tilt, -tilt)
    rotation = Rotation.from_rotvec(np.outer(theta, [0, 0, 1])).as_matrix()
    translation = written - SADDLE         # with no tilt each frame would carry the saddle to the written point
    return rotation, translation, written


def test_a_tilt_about_the_markers_swings_the_far_saddle_by_its_lever():
    rotation, translation, written = _tilted(tilt=0.01, height=0.03)
    out = saddle_scatter(rotation, translation, SADDLE, written)
    assert out.scatter_m == pytest.approx(0.5 * np.sin(0.01), rel=1e-9)
    assert out.motion_m == pytest.approx(0.03, rel=1e-3)
    assert out.pct_of_motion == pytest.approx(100 * 0.5 * np.sin(0.01) / out.motion_m, rel=1e-12)
    assert out.frames == 100


def test_frames_without_a_pose_are_left_out_and_counted():
    rotation, translation, written = _tilted()
    rotation[:10] = np.nan
    written[-5:] = np.nan
    out = saddle_scatter(rotation, translation, SADDLE, written)
    assert out.frames == 85
    swing = 0.5 * np.sin(np.where(np.arange(100) % 2, 0.01, -0.01))[10:-5]
    assert out.scatter_m == pytest.approx(np.std(swing), rel=1e-9)


def test_bad_input_is_refused_naming_it():
    rotation, translation, written = _tilted(n=20)
    with pytest.raises(ValueError, match="written_position"):
        saddle_scatter(rotation, translation, SADDLE, written[:-1])
    rotation[MIN_SCATTER_FRAMES - 1:] = np.nan
    with pytest.raises(ValueError, match=f"{MIN_SCATTER_FRAMES - 1} frames .* at least {MIN_SCATTER_FRAMES}"):
        saddle_scatter(rotation, translation, SADDLE, written)


def test_a_standing_horse_has_no_motion_to_compare_with():
    rotation, translation, written = _tilted(height=0.0005)
    with pytest.raises(ValueError, match="moves 0.5 mm rms vertically, less than 1 mm"):
        saddle_scatter(rotation, translation, SADDLE, written)


@pytest.mark.parametrize("pct, level", [(10.0, "ok"), (33.3, "ok"), (34.0, "warning"), (60.0, "warning"),
                                        (60.1, "unreliable"), (100.0, "unreliable"), (float("inf"), "unreliable")])
def test_check_levels(pct, level):
    check = quality.check_saddle_scatter(SaddleScatter(0.001 * pct / 100, 0.001, pct, 100))
    assert (check.name, check.level) == ("saddle_scatter", level)
    assert "mm rms from the written height" in check.message
    if level == "unreliable":
        assert "the smoothing's guess, not a measurement" in check.message


def test_post_checks_read_the_written_saddle_and_the_per_frame_registration(monkeypatch):
    from horsemocap.pipeline import Analysis
    from horsemocap.rigid import Conditioning
    from horsemocap.steps import RigidBodyResult

    def unset(cls, **given):      # a result with only the fields the checks read
        return cls(**{**{f.name: None for f in dataclasses.fields(cls)}, **given})

    monkeypatch.setattr(quality, "predicted_registration_rms", lambda registration: None)  # not this check's
    rotation, translation, written = _tilted(tilt=0.1, height=0.03)
    body = SimpleNamespace(pose_registration=SimpleNamespace(rotation=rotation, translation=translation),
                           static_saddle=SADDLE)
    model = np.array([[0.3, 0.0, 0.0], [-0.15, 0.1, 0.0], [-0.15, -0.1, 0.05]])
    rb = unset(RigidBodyResult, model=model, body=body, saddle_position=written,
               saddle_acceleration=np.zeros((100, 3)),
               conditioning=unset(Conditioning, registration_rms_m=np.full(100, 0.0008), warnings=[]))
    checks = {c.name: c for c in quality.post_checks(Analysis(SimpleNamespace(fps=50.0), None, rigid_body=rb))}
    assert checks["saddle_scatter"].level == "unreliable"
    assert checks["saddle_scatter"].figure == pytest.approx(100 * 0.5 * np.sin(0.1) / 0.03, rel=1e-3)
    skipped = rb.replace(body=SimpleNamespace(pose_registration=None, static_saddle=SADDLE))
    checks = {c.name: c for c in quality.post_checks(Analysis(SimpleNamespace(fps=50.0), None, rigid_body=skipped))}
    assert checks["saddle_scatter"].level == "skipped"
    assert "no per-frame registration" in checks["saddle_scatter"].message
