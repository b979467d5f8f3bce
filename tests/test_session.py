"""Session validation: every way session.json can be wrong, one by one."""
import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from horsemocap.session import SessionError, check_frame_counts, load_session
from horsemocap.sources import FrameSource, SourceError, natural_sorted

CAMS = ["left", "middle", "right"]


def _write_frames(folder: Path, n: int, names=None):
    folder.mkdir(parents=True, exist_ok=True)
    for i in range(n):
        img = np.full((24, 32, 3), i * 10 % 255, np.uint8)
        cv2.imwrite(str(folder / (names[i] if names else f"f{i + 1}.png")), img)


@pytest.fixture
def session_dir(tmp_path):
    root = tmp_path / "ride"
    for cam in CAMS:
        _write_frames(root / "motion" / cam, 5)
        _write_frames(root / "calibration" / cam, 2)
        cv2.imwrite(str(root / f"plumb_{cam}.png"), np.zeros((24, 32, 3), np.uint8))
        cv2.imwrite(str(root / f"static_{cam}.png"), np.zeros((24, 32, 3), np.uint8))
    doc = {
        "format": "horsemocap-session/1", "name": "test", "fps": 30.0,
        "cameras": CAMS, "reference_camera": "left",
        "motion": {c: f"motion/{c}" for c in CAMS},
        "sync": {"method": "flash"},
        "calibration": {"images": {c: f"calibration/{c}" for c in CAMS},
                        "board": {"inner_corners": [4, 3], "square_size_m": 0.05}},
        "plumb": {c: f"plumb_{c}.png" for c in CAMS},
        "static": {c: f"static_{c}.png" for c in CAMS},
        "markers": {"count": 3, "diameter_m": 0.06},
        "analysis": {}, "metadata": {"horse": "Horse 2"},
    }
    (root / "session.json").write_text(json.dumps(doc))
    return root


def _edit(root, fn):
    doc = json.loads((root / "session.json").read_text())
    fn(doc)
    (root / "session.json").write_text(json.dumps(doc))


def test_valid_session_loads(session_dir):
    s = load_session(session_dir)
    assert s.cameras == tuple(CAMS) and s.fps == 30.0 and s.sync_method == "flash"
    assert s.board.inner_corners == (4, 3) and s.marker_count == 3
    assert s.motion["left"] == (session_dir / "motion/left").resolve()


def test_missing_file(tmp_path):
    with pytest.raises(SessionError, match="session.json: session file not found"):
        load_session(tmp_path)


def test_invalid_json(session_dir):
    (session_dir / "session.json").write_text("{nope")
    with pytest.raises(SessionError, match="not valid JSON"):
        load_session(session_dir)


@pytest.mark.parametrize("edit, pattern", [
    (lambda d: d.update(fsp=30), r"unknown field 'fsp'; did you mean 'fps'\?"),
    (lambda d: d.pop("fps"), r"required field 'fps' is missing"),
    (lambda d: d.update(format="other/2"), r"field 'format': expected \"horsemocap-session/1\""),
    (lambda d: d.update(fps=0), r"field 'fps': expected a positive number, got 0"),
    (lambda d: d.update(fps="30"), r"field 'fps': expected a positive number"),
    (lambda d: d.update(fps=1e6), r"field 'fps': expected frames per second"),
    (lambda d: d.update(cameras=[]), r"field 'cameras': expected a non-empty list"),
    (lambda d: d.update(cameras=["left", "left", "right"]), r"field 'cameras': expected unique"),
    (lambda d: d.update(reference_camera="centre"), r"field 'reference_camera': expected one of"),
    (lambda d: d["motion"].update(top="motion/left"), r"field 'motion.top': expected a camera listed"),
    (lambda d: d["motion"].pop("right"), r"field 'motion': expected an entry for every camera; 'right' is missing"),
    (lambda d: d["motion"].update(left="motion/nowhere"), r"field 'motion.left': expected an existing video file or image folder"),
    (lambda d: d.update(sync={"method": "clap"}), r"field 'sync': expected"),
    (lambda d: d.update(sync={"offsets": {"left": 0, "middle": -1, "right": 3}}), r"field 'sync.offsets.middle': expected a frame index"),
    (lambda d: d.update(sync={"offsets": {"left": 0, "middle": 1, "rigth": 3}}), r"unknown field 'sync.offsets.rigth'; did you mean 'right'"),
    (lambda d: d.update(calibration={}), r"field 'calibration': expected a 'rig' file or 'images' \+ 'board'"),
    (lambda d: d["calibration"].update(rig="calibration/rig.toml"), r"field 'calibration.rig': expected an existing rig file"),
    (lambda d: d["calibration"]["board"].update(inner_corners=[4]), r"field 'calibration.board.inner_corners'"),
    (lambda d: d["calibration"]["board"].update(square_size_m=-1), r"field 'calibration.board.square_size_m'"),
    (lambda d: d["calibration"].pop("board"), r"'calibration.board' is required"),
    (lambda d: d["plumb"].update(left="nope.png"), r"field 'plumb.left': expected an existing image"),
    (lambda d: d["markers"].update(count=0), r"field 'markers.count'"),
    (lambda d: d["markers"].update(colour="red"), r"unknown field 'markers.colour'"),
    (lambda d: d.update(analysis=[]), r"field 'analysis': expected an object"),
])
def test_each_error_names_file_and_field(session_dir, edit, pattern):
    _edit(session_dir, edit)
    with pytest.raises(SessionError, match=pattern) as info:
        load_session(session_dir)
    assert str(session_dir / "session.json") in str(info.value)


def test_empty_image_folder_is_rejected(session_dir):
    for f in (session_dir / "motion/middle").iterdir():
        f.unlink()
    with pytest.raises(SessionError, match=r"motion.middle.*holds no image files"):
        load_session(session_dir)


def test_unreadable_video_is_rejected(session_dir):
    (session_dir / "broken.avi").write_bytes(b"not a video at all")
    _edit(session_dir, lambda d: d["motion"].update(right="broken.avi"))
    with pytest.raises(SessionError, match=r"motion.right.*cannot be opened as a video"):
        load_session(session_dir)


def test_frame_counts_against_offsets(session_dir):
    s = load_session(session_dir)
    assert check_frame_counts(s, {"left": 5, "middle": 5, "right": 5}, {"left": 0, "middle": 1, "right": 2}) == 3
    with pytest.raises(SessionError, match=r"camera 'right' has 5 frames, but its sync offset is frame 7"):
        check_frame_counts(s, {"left": 5, "middle": 5, "right": 5}, {"left": 0, "middle": 1, "right": 7})


def test_natural_order(tmp_path):
    names = ["left10.png", "left2.png", "left1.png", "Left3.png"]
    _write_frames(tmp_path / "cam", 4, names)
    assert [p.name for p in natural_sorted((tmp_path / "cam").iterdir())] == ["left1.png", "left2.png", "Left3.png", "left10.png"]
    frames = FrameSource(tmp_path / "cam").read()
    # frame values were written in the order of `names`: left10 got 0, left2 10, left1 20, Left3 30
    assert [int(f[0, 0, 0]) for f in frames] == [20, 10, 30, 0]


def test_video_source_and_truncation(tmp_path):
    path = tmp_path / "v.avi"
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 30, (32, 24))
    for i in range(6):
        w.write(np.full((24, 32, 3), 40 * i, np.uint8))
    w.release()
    src = FrameSource(path)
    assert len(src) == 6
    assert abs(int(src.frame(3)[5, 5, 0]) - 120) <= 3
    with pytest.raises(SourceError, match=r"v.avi: expected frames 2..9, but the source ends after 6 frames"):
        src.read(2, 10)


def _numbered_video(path, n=90, size=(40, 30)):
    """A video whose frame k shows the number k (as a bright block's position and a gray level)."""
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 30, size)
    for k in range(n):
        img = np.full((size[1], size[0], 3), 2 * k % 250, np.uint8)
        img[5:10, (k % 30):(k % 30) + 5] = 255
        w.write(img)
    w.release()
    return FrameSource(path)


def test_frame_sequence_equals_read_in_any_order(tmp_path):
    src = _numbered_video(tmp_path / "n.avi")
    for color in (False, True):
        arr = src.read(7, 83, color=color)
        seq = src.sequence(7, 83, color=color, cache_frames=10)
        assert len(seq) == len(arr) and seq.shape == arr.shape and seq.ndim == arr.ndim and seq.dtype == arr.dtype
        order = list(range(40, 76)) + list(range(39, -1, -1)) + [3, 70, 0, 75, 38, -1]
        for k in order:
            np.testing.assert_array_equal(seq[k], arr[k])
        assert len(seq._cache) <= 10               # bounded memory, whatever the order
        seq.close()
    frames_dir = tmp_path / "imgs"
    _write_frames(frames_dir, 5, [f"f{i}.png" for i in range(5)])
    folder = FrameSource(frames_dir)
    np.testing.assert_array_equal(folder.sequence(1, 4)[2], folder.read(1, 4)[2])


def test_frame_sequence_errors(tmp_path):
    src = _numbered_video(tmp_path / "n.avi", n=12)
    with pytest.raises(SourceError, match=r"n.avi: expected frames 5..19, but the source ends after 12 frames"):
        src.sequence(5, 20)
    with pytest.raises(SourceError, match="no frame from index 4"):
        src.sequence(4, 4)
    seq = src.sequence(0, 12)
    with pytest.raises(IndexError):
        seq[12]
    with pytest.raises(TypeError, match="one frame number"):
        seq[2:5]


def test_detection_on_a_frame_sequence_is_the_same():
    from horsemocap.data import default_session_dir
    from horsemocap.detection import detect_markers

    src = FrameSource(default_session_dir() / "motion" / "left.avi")
    a = detect_markers(src.read(8, 60, color=False), 3)
    b = detect_markers(src.sequence(8, 60, color=False, cache_frames=16), 3)
    np.testing.assert_array_equal(a.marker_px, b.marker_px)
    np.testing.assert_array_equal(a.reason, b.reason)
    assert a.params == b.params


def test_video_length_without_decoding_and_when_truncated(tmp_path):
    src = _numbered_video(tmp_path / "n.avi", n=40)
    assert len(src) == 40 == sum(1 for _ in src.iter_frames(color=False))
    data = (tmp_path / "n.avi").read_bytes()
    (tmp_path / "cut.avi").write_bytes(data[: len(data) * 2 // 3])   # no index, frames missing
    cut = FrameSource(tmp_path / "cut.avi")
    assert len(cut) == sum(1 for _ in cut.iter_frames(color=False)) < 40


def test_the_session_keeps_its_name_after_the_stills_are_checked():
    """The loop over the plumb and static stills once reused ``name`` and every session was called "static"
    (analysis.json's session_name, the report's title, the results store's folder)."""
    from horsemocap.data import default_session_dir
    from horsemocap.session import load_session

    assert load_session(default_session_dir()).name == "horse2_canter"
    assert load_session(default_session_dir(), open_sources=False).name == "horse2_canter"
