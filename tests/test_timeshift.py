"""The synchronisation checked by the markers (horsemocap.detection.timeshift)."""
import dataclasses

import numpy as np
import pytest

from horsemocap.detection import best_frame_shift, frame_shift_residuals

from test_identification import BODY, RIG, render, world


@pytest.mark.parametrize("late", [0, 2, -3])
def test_a_camera_whose_flash_was_found_off_by_frames_is_put_back(late):
    """The left camera's synchronised frame k shows the instant k + late (a flash found off by
    ``late`` frames); the markers seen by the two other cameras say by how much."""
    n, lead = 40, 5
    frames, truth, _ = render(n=n + 2 * lead, blob=False, stirrup=True)
    t = (np.arange(n) + lead) / 30.0
    points = world(BODY, t)                                   # what the middle and right cameras measure
    N = n + 2 * lead
    first = -lead                                             # left[i] is synchronised frame first + i,
    left = [frames["left"][min(max(i + late, 0), N - 1)] for i in range(N)]   # showing instant i + late
    shifts, med, npts = frame_shift_residuals(RIG["left"], points, left, first, range(-lead, lead + 1), 120,
                                              (3, None), 0.5)
    fs = best_frame_shift(shifts, med, npts)
    assert fs.best == -late
    assert fs.best_px < 0.3
    if late:
        assert fs.current_px > 1.0


def test_no_shift_without_evidence():
    shifts = np.arange(-3, 4)
    assert best_frame_shift(shifts, np.array([5, 4, 3, 0.4, 0.3, 3, 4.0]), 100).best == 0   # sub-frame timing
    assert best_frame_shift(shifts, np.array([5, 4, 3, 9, 0.3, 3, 4.0]), 10).best == 0      # too few points
    assert best_frame_shift(shifts, np.array([5, 4, 3, 9, 0.3, 3, 4.0]), 100).best == 1


def test_the_pipeline_corrects_a_flash_found_two_frames_early(monkeypatch):
    """The bundled session with the right camera's flash found two frames early: the detect
    step finds it by the markers, corrects the offset and says so."""
    from horsemocap import sync
    from horsemocap.data import default_session_dir
    from horsemocap.pipeline import resolve_params, run_steps
    from horsemocap.session import load_session

    session = load_session(default_session_dir())
    params = resolve_params(session)
    true = run_steps(session, params, {}, ["sync"]).sync.offsets
    real = sync.flash_detections

    def early(sources, **kw):
        found = real(sources, **kw)
        return {**found, "right": dataclasses.replace(found["right"], frame=true["right"] - 2)}

    monkeypatch.setattr(sync, "flash_detections", early)
    an = run_steps(session, params, {}, ["sync", "rig", "plumb", "static", "detect"])
    got = an.synchronisation
    assert got.offsets == true and an.detect.sync_corrected
    assert got.flash_offsets["right"] == true["right"] - 2 and "corrected by the markers" in got.offsets_from
    assert an.sync.offsets["right"] == true["right"] - 2          # the sync step's own result stays as it was
    check = an.detect.sync_check
    assert check["right"].shift == 2 and check["left"].shift == 0 and check["middle"].shift == 0


def test_an_ambiguous_flash_is_recorded_and_settled_by_the_markers(monkeypatch):
    """A camera with two flash candidates of similar score: the sync step records it, the markers check
    it (the right frame was taken here, so they confirm it) and the verdict's check is ok."""
    from horsemocap import quality, sync
    from horsemocap.data import default_session_dir
    from horsemocap.pipeline import resolve_params, run_steps
    from horsemocap.session import load_session

    real = sync.flash_detections

    def ambiguous(sources, **kw):
        found = real(sources, **kw)
        return {**found, "middle": dataclasses.replace(found["middle"], ambiguous=True,
                                                       runner_up={"frame": 39, "on_frame": 40, "score": 0.8})}

    monkeypatch.setattr(sync, "flash_detections", ambiguous)
    session = load_session(default_session_dir())
    an = run_steps(session, resolve_params(session), {}, ["sync", "rig", "plumb", "static", "detect"])
    assert an.synchronisation.flash_ambiguous == {"middle": 40}
    check = {c.name: c for c in quality.post_checks(an)}["sync_by_markers"]     # as the verdict sees it
    assert check.level == "ok" and an.detect.sync_check["middle"].decided
    from horsemocap.results import analysis_record
    assert analysis_record(an)["chosen"]["sync"]["flash_ambiguous"] == {"middle": 40}
