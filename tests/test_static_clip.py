"""The static shot as a short clip of the horse standing: read, checked, averaged, its uncertainty lowered."""
import json
import shutil
from types import SimpleNamespace

import cv2
import numpy as np
import pytest

from horsemocap.camera import Camera, Rig, read_rig
from horsemocap.params import StillsParams, TriangulateParams
from horsemocap.quality import _static_independent_frames, check_static_shot
from horsemocap.session import SessionError, load_session
from horsemocap.steps import AnalysisError, StaticResult, step_plumb, step_static, still_params, still_points
from horsemocap.steps.stills import align_onto, average_static_clip, clip_points, effective_frame_count
from horsemocap.uncertainty import saddle_acceleration_sensitivity, static_shot_uncertainty
from horsemocap.virtuallab.session import render_session

CAMS = ("left", "middle", "right")
SHAPE = np.array([[0.0, 0.0, 3.0], [0.45, 0.02, 3.1], [0.1, 0.2, 2.95], [0.25, -0.1, 3.3]])


def _turned(angle, axis=2):
    c, s = np.cos(angle), np.sin(angle)
    i, j = [a for a in range(3) if a != axis]
    R = np.eye(3)
    R[i, i], R[i, j], R[j, i], R[j, j] = c, -s, s, c
    return R


def _quiet(*_):
    pass


@pytest.fixture(scope="module")
def still_session(tmp_path_factory):
    """A small virtual session (clean render, PNG stills, the true rig) whose static shot is one still per camera."""
    return render_session(tmp_path_factory.mktemp("clip") / "ride", n_motion_frames=2, calibration_views=0,
                          noise=False, compress=False)


def _with_static(still_session, tmp_path, frames_per_camera: dict, kind: str = "static"):
    """A copy of ``still_session``'s session.json whose static shot (or plumb, ``kind``) is a folder of frames per
    camera: ``frames_per_camera[camera]`` lists the frames, each the still (``"still"``) or a blank image."""
    root = tmp_path / "ride"
    root.mkdir()
    doc = json.loads((still_session / "session.json").read_text())
    for key in ("motion", "plumb", "static"):
        doc[key] = {c: str(still_session / p) for c, p in doc[key].items()}
    doc["calibration"] = {"rig": str(still_session / "calibration" / "rig.toml")}
    for cam in CAMS:
        folder = root / kind / cam
        folder.mkdir(parents=True)
        still = cv2.imread(str(still_session / kind / f"{cam}.png"))
        for k, frame in enumerate(frames_per_camera[cam]):
            cv2.imwrite(str(folder / f"{cam}{k}.png"), still if frame == "still" else np.zeros_like(still))
    doc[kind] = {c: f"{kind}/{c}" for c in CAMS}
    (root / "session.json").write_text(json.dumps(doc))
    return root


def _static(session):
    rig = read_rig(session.rig_path)
    return step_static(session, StillsParams(), rig, TriangulateParams().mode, _quiet), rig


# ---------------------------------------------------------------------------
# the average (pure)
# ---------------------------------------------------------------------------

def test_a_clip_of_identical_frames_averages_to_its_points():
    avg = average_static_clip(np.repeat(SHAPE[None], 12, axis=0))
    assert np.allclose(avg.points, SHAPE, atol=1e-12, rtol=0)
    assert avg.used.all() and avg.left_out == ()
    assert np.allclose(avg.scatter_m, 0.0, atol=1e-12)
    assert avg.effective_frames == 1.0          # the same error twelve times: nothing averaged away


def test_a_clip_with_a_known_rigid_sway_averages_to_the_reference_frames_shape():
    frames = np.stack([SHAPE @ _turned(0.03 * np.sin(0.7 * f), axis=f % 3).T + [0.004 * f, -0.002 * f, 0.001]
                       for f in range(25)])
    frames[:, [0, 2]] = frames[:, [2, 0]]              # the points in another order than the reference's
    avg = average_static_clip(frames)
    assert avg.used.all() and avg.left_out == ()
    reference = frames[0]
    assert np.allclose(align_onto(avg.points, reference), reference, atol=1e-9, rtol=0)
    assert np.allclose(avg.scatter_m, 0.0, atol=1e-9)
    assert (avg.order == np.arange(4)).all()           # every frame's order that of the reference frame


def test_a_frame_without_points_and_a_frame_off_the_shape_are_left_out_with_their_reasons():
    rng = np.random.default_rng(3)
    frames = np.repeat(SHAPE[None], 30, axis=0) + 1e-4 * rng.standard_normal((30, 4, 3))
    frames[4] = np.nan
    frames[9, 3] += [0.0, 0.0, 0.02]                   # one point 20 mm off (a glint taken for it)
    avg = average_static_clip(frames)
    assert [f for f, _ in avg.left_out] == [4, 9]
    assert "not finite" in avg.left_out[0][1] and "not rigid" in avg.left_out[1][1]
    assert avg.used.sum() == 28
    assert np.abs(avg.points - SHAPE).max() < 2e-4


def test_the_average_is_worth_fewer_independent_frames_when_the_scatter_is_correlated():
    rng = np.random.default_rng(5)
    rho, n = 0.8, 400
    e = np.zeros((n, 4, 3))
    e[0] = rng.standard_normal((4, 3))
    for f in range(1, n):
        e[f] = rho * e[f - 1] + np.sqrt(1 - rho ** 2) * rng.standard_normal((4, 3))
    avg = average_static_clip(SHAPE[None] + 1e-3 * e)
    assert 0.7 < avg.lag1 < 0.85
    assert avg.effective_frames == pytest.approx(effective_frame_count(n, avg.lag1))
    assert 35 < avg.effective_frames < 70               # about n (1 - rho) / (1 + rho) = 44


def test_the_average_refuses_a_clip_without_a_complete_frame():
    with pytest.raises(ValueError, match="none of the 3 frames"):
        average_static_clip(np.full((3, 4, 3), np.nan))


# ---------------------------------------------------------------------------
# the step and the session contract
# ---------------------------------------------------------------------------

def test_image_stills_read_and_give_the_stills_points_as_before(still_session):
    session = load_session(still_session)
    assert all(p.suffix == ".png" for p in session.static.values())
    result, rig = _static(session)
    pts, px = still_points(session, rig, session.static, session.marker_count + 1, "static", TriangulateParams().mode,
                           still_params(StillsParams(), "static", session.cameras))
    assert np.array_equal(result.static_points, pts)
    assert all(np.array_equal(result.static_px[c], px[c]) for c in CAMS)
    assert result.frames_used is None and result.effective_frames is None and result.frames_left_out == ()


def test_a_clip_of_the_still_repeated_gives_the_stills_points(still_session, tmp_path):
    still, _ = _static(load_session(still_session))
    clip, _ = _static(load_session(_with_static(still_session, tmp_path, {c: ["still"] * 3 for c in CAMS})))
    assert clip.frames_used == 3 and clip.frames_left_out == ()
    assert np.allclose(clip.static_points, still.static_points, atol=1e-9, rtol=0)
    assert all(np.allclose(clip.static_px[c], still.static_px[c], atol=1e-9) for c in CAMS)


def test_a_clip_frame_without_markers_is_left_out_and_counted(still_session, tmp_path):
    frames = {c: ["still", "blank" if c == "middle" else "still", "still"] for c in CAMS}
    session = load_session(_with_static(still_session, tmp_path, frames))
    clip, _ = _static(session)
    still, _ = _static(load_session(still_session))
    assert clip.frames_used == 2
    assert [f for f, _ in clip.frames_left_out] == [1]
    assert "markers not found" in clip.frames_left_out[0][1]
    assert np.allclose(clip.static_points, still.static_points, atol=1e-9, rtol=0)


def test_clips_of_different_lengths_are_refused_naming_the_files(still_session, tmp_path):
    frames = {"left": ["still"] * 3, "middle": ["still"] * 2, "right": ["still"] * 3}
    root = _with_static(still_session, tmp_path, frames)
    with pytest.raises(SessionError) as err:
        load_session(root)
    message = str(err.value)
    assert "field 'static'" in message and "one frame count in every camera" in message
    assert str(root / "static" / "middle") in message and "2 frames" in message and "3 frames" in message
    session = load_session(root, open_sources=False)      # not checked on loading: the step says it
    with pytest.raises(AnalysisError, match=r"clip of camera 'middle' \(.*static/middle\) ends after 2 frames"):
        clip_points(session, read_rig(session.rig_path), session.static, 4, "static", TriangulateParams().mode)


def test_an_empty_clip_folder_and_an_unreadable_frame_are_refused_naming_the_file(still_session, tmp_path):
    root = _with_static(still_session, tmp_path, {c: ["still"] * 2 for c in CAMS})
    shutil.rmtree(root / "static" / "right")
    (root / "static" / "right").mkdir()
    with pytest.raises(SessionError, match=r"field 'static'.*static/right: folder holds no image files"):
        load_session(root)
    shutil.copy(root / "static" / "left" / "left0.png", root / "static" / "right" / "right0.png")
    data = (root / "static" / "left" / "left1.png").read_bytes()
    (root / "static" / "right" / "right1.png").write_bytes(data[: len(data) // 2])       # cut short
    with pytest.raises(SessionError, match=r"field 'static'.*right1.png: PNG whose chunks do not reach IEND"):
        load_session(root)


def test_a_still_beside_a_clip_is_refused(still_session, tmp_path):
    root = _with_static(still_session, tmp_path, {c: ["still"] * 2 for c in CAMS})
    doc = json.loads((root / "session.json").read_text())
    doc["static"]["left"] = str(still_session / "static" / "left.png")
    (root / "session.json").write_text(json.dumps(doc))
    with pytest.raises(SessionError, match="a still is an image in every camera.*'left' .*left.png an image"):
        load_session(root)


# ---------------------------------------------------------------------------
# the static_shot check's uncertainty
# ---------------------------------------------------------------------------

def test_the_static_shots_uncertainty_falls_with_the_square_root_of_the_independent_frames():
    K = [[800.0, 0.0, 320.0], [0.0, 800.0, 240.0], [0.0, 0.0, 1.0]]
    rig = Rig((Camera("left", (640, 480), K), Camera("right", (640, 480), K, translation=[-0.5, 0, 0])))
    still = np.array([[-0.3, 0, 3.0], [0.3, 0, 3.0], [0, -0.05, 3.0], [0, 0.3, 3.0]])
    n = 50
    t = np.arange(n) / 50
    alpha = np.zeros((n, 3))
    alpha[:, 0] = 20 * np.sin(2 * np.pi * 2 * t)
    G = saddle_acceleration_sensitivity(np.zeros((n, 3)), alpha, np.repeat(np.eye(3)[None], n, 0))
    ay = 5 * np.sin(2 * np.pi * 2 * t)
    one = static_shot_uncertainty(rig, still, [0, 1, 2], 3, np.eye(3), 0.2, G, ay)
    four = static_shot_uncertainty(rig, still, [0, 1, 2], 3, np.eye(3), 0.2, G, ay, independent_frames=4.0)
    assert one.independent_frames == 1.0 and four.independent_frames == 4.0
    assert np.allclose(four.offset_sd_m, one.offset_sd_m / 2, rtol=1e-12)
    assert four.pct_of_rms == pytest.approx(one.pct_of_rms / 2, rel=1e-12)
    with pytest.raises(ValueError, match="independent_frames"):
        static_shot_uncertainty(rig, still, [0, 1, 2], 3, np.eye(3), 0.2, G, ay, independent_frames=0.5)


def test_the_static_shot_check_reads_the_clips_independent_frames_and_says_so():
    still = StaticResult(static_points=SHAPE, static_px=None)
    clip = StaticResult(static_points=SHAPE, static_px=None, frames_used=60, effective_frames=11.0)
    assert _static_independent_frames(SimpleNamespace(static=still)) == 1.0
    assert _static_independent_frames(SimpleNamespace(static=clip)) == 11.0
    K = [[800.0, 0.0, 320.0], [0.0, 800.0, 240.0], [0.0, 0.0, 1.0]]
    rig = Rig((Camera("left", (640, 480), K), Camera("right", (640, 480), K, translation=[-0.5, 0, 0])))
    world = np.array([[-0.3, 0, 3.0], [0.3, 0, 3.0], [0, -0.05, 3.0], [0, 0.3, 3.0]])
    t = np.arange(50) / 50
    alpha = np.zeros((50, 3))
    alpha[:, 0] = 20 * np.sin(2 * np.pi * 2 * t)
    G = saddle_acceleration_sensitivity(np.zeros((50, 3)), alpha, np.repeat(np.eye(3)[None], 50, 0))
    shot = static_shot_uncertainty(rig, world, [0, 1, 2], 3, np.eye(3), 0.2, G, 5 * np.sin(2 * np.pi * 2 * t),
                                   independent_frames=11.0)
    check = check_static_shot(shot)
    assert check.figure == pytest.approx(shot.pct_of_rms)
    assert "average worth 11.0 independent frames" in check.message
    assert "constant centroid error not averaged away" in check.message
    assert "a clip per camera, averaged" in check.input and "the still's" not in check.message
    one = check_static_shot(static_shot_uncertainty(rig, world, [0, 1, 2], 3, np.eye(3), 0.2, G,
                                                    5 * np.sin(2 * np.pi * 2 * t)))
    assert one.message.startswith("the still's pixel noise (0.2 px, measured on the moving frames) places")
    assert "one still per camera" in one.input
    alike = check_static_shot(static_shot_uncertainty(rig, world, [0, 1, 2], 3, np.eye(3), 0.2, G,
                                                      5 * np.sin(2 * np.pi * 2 * t)), clip_frames=12)
    assert "a clip per camera, averaged" in alike.input and alike.message.startswith("the static clip's")


def test_a_plumb_clip_averages_to_the_stills_gravity_its_blank_frame_counted(still_session, tmp_path):
    mode = TriangulateParams().mode
    session = load_session(still_session)
    rig = read_rig(session.rig_path)
    still = step_plumb(session, StillsParams(), rig, mode, _quiet)
    frames = {c: ["still", "blank" if c == "left" else "still", "still"] for c in CAMS}
    clip_session = load_session(_with_static(still_session, tmp_path, frames, kind="plumb"))
    clip = step_plumb(clip_session, StillsParams(), rig, mode, _quiet)
    assert still.frames_used is None and clip.frames_used == 2
    assert [f for f, _ in clip.frames_left_out] == [1] and "markers not found" in clip.frames_left_out[0][1]
    assert np.allclose(clip.plumb_points, still.plumb_points, atol=1e-12, rtol=0)
    assert np.allclose(clip.gravity, still.gravity, atol=1e-12, rtol=0)


def test_the_clips_frames_left_out_and_scatter_are_recorded_and_a_still_records_nothing(still_session, tmp_path):
    from horsemocap.results import _clip_record
    frames = {c: ["still", "blank" if c == "middle" else "still", "still"] for c in CAMS}
    clip, _ = _static(load_session(_with_static(still_session, tmp_path, frames)))
    record = _clip_record(clip)
    assert record["frames_used"] == 2
    assert [d["frame"] for d in record["frames_left_out"]] == [1]
    assert "markers not found" in record["frames_left_out"][0]["reason"]
    assert len(record["scatter_mm"]) == len(clip.static_points) and max(record["scatter_mm"]) < 1e-6
    assert record["effective_frames"] >= 1
    json.dumps(record)                                   # analysis.json holds it as it is
    still, _ = _static(load_session(still_session))
    assert _clip_record(still) == {} and _clip_record(None) == {}


def test_a_glint_in_the_first_frame_does_not_become_the_reference():
    rng = np.random.default_rng(3)
    clip = SHAPE[None] + 1e-4 * rng.standard_normal((30,) + SHAPE.shape)
    clip[0, 3] += [0.0, 0.0, 0.2]                     # frame 0: one point 200 mm off (a glint taken for it)
    avg = average_static_clip(clip)
    assert int(avg.used.sum()) == 29 and [f for f, _ in avg.left_out] == [0]
    assert np.abs(avg.points - SHAPE).max() < 2e-4


def test_frames_alike_are_worth_one_frame_and_none_is_left_out():
    square = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    for shape in (square, SHAPE):
        avg = average_static_clip(np.repeat(shape[None], 12, axis=0))
        assert avg.effective_frames == 1.0 and avg.used.all() and avg.left_out == ()


def test_an_image_file_whose_suffix_is_not_an_images_is_still_a_still(tmp_path):
    from horsemocap.sources import is_still_image
    img = tmp_path / "left.still"
    ok, data = cv2.imencode(".png", np.zeros((8, 8, 3), np.uint8))
    img.write_bytes(data.tobytes())
    (tmp_path / "left.avi").write_bytes(b"RIFF0000AVI LIST")
    assert is_still_image(img) and not is_still_image(tmp_path / "left.avi") and not is_still_image(tmp_path)


def test_a_clip_without_a_frame_giving_every_marker_stops_naming_the_files_and_reasons(still_session, tmp_path):
    session = load_session(_with_static(still_session, tmp_path, {c: ["blank", "blank"] for c in CAMS}))
    with pytest.raises(AnalysisError) as err:
        _static(session)
    message = str(err.value)
    assert "no frame of the 2-frame static clip gave every marker" in message
    assert "frame 0: markers not found" in message and "static/left" in message
