"""A camera whose clock drifts by whole frames over the record: the identification compares, at each reference
instant, the camera's frame nearest it (horsemocap.detection.candidates.ClockFollowingFrames) and gives its 2D
values back in the camera's own frames."""
import numpy as np

from horsemocap.detection import identify_markers
from horsemocap.detection import tracker3d
from horsemocap.detection.candidates import ClockFollowingFrames, source_frame
from horsemocap.steps.detect import free_running_tolerance
from horsemocap.steps.detect import clocks_not_measured_hint
from horsemocap.subframe import NTSC_FRAMES_PER_GAINED_FRAME, whole_frames_gained
from horsemocap.virtuallab.render import disc_frames
from horsemocap.virtuallab.rig import thesis_rig

RIG = thesis_rig()
FPS = 30.0
THREE = np.array([[-0.24, 0.0, 0.0], [0.02, -0.09, 0.0], [0.22, 0.03, 0.01]])
SADDLE = np.array([0.45, -0.25, 0.02])
#: The right camera: its frame j at the reference instant PHASE + RATE j; over 70 frames it falls 2.7 frames behind.
PHASE, RATE, N = 0.1, 1.04, 70


def _world(t):
    """A body running along x at 2.5 m/s bouncing 8 cm at 3 Hz (28 m/s^2 peak: a frame's linear extrapolation
    misses by centimetres)."""
    t = np.atleast_1d(t)
    pos = np.column_stack([-1.6 + 2.5 * t, -0.05 + 0.08 * np.sin(2 * np.pi * 3.0 * t), 7.7 + 0.0 * t])
    return pos[:, None, :] + THREE[None]


def _render():
    """Frames of every camera: left and middle at the reference instants, right at its own drifting instants."""
    frames, truth_px = {}, {}
    for cam in RIG:
        instants = (PHASE + RATE * np.arange(N)) if cam.name == "right" else np.arange(N, dtype=float)
        truth_px[cam.name] = cam.project(_world(instants / FPS))
        frames[cam.name] = disc_frames(truth_px[cam.name], cam.size)
    static = np.vstack([THREE, SADDLE]) + [0.2, -0.05, 7.7]
    return frames, static, truth_px


def test_clock_following_frames_read_the_nearest_frame():
    gained = whole_frames_gained(RATE, N)
    seq = ClockFollowingFrames(list(range(N)), gained)
    own = np.array([source_frame(seq, k)[1] for k in range(N)])
    instants = PHASE + RATE * own                      # when the frame compared at reference instant k was taken
    assert gained.max() == 3 and np.all(np.abs(instants - np.arange(N)) <= 0.5 + PHASE + 1e-9)


def test_a_drifting_camera_is_identified_at_its_nearest_frames(monkeypatch):
    frames, static, truth_px = _render()
    timing = {"phase": {"right": PHASE}, "rate_ratio": {"right": RATE}, "max_residual_px": free_running_tolerance(RIG)}
    idn = identify_markers(frames, RIG, static, 3, **timing)
    used = idn.reason["right"] == ""
    inside = np.all((truth_px["right"] > 8) & (truth_px["right"] < np.array(RIG["right"].size) - 8), axis=-1)
    assert used[inside].mean() > 0.9, np.unique(idn.reason["right"][inside], return_counts=True)
    # the 2D values are the camera's own frames' (frame j at its own instant)
    err = np.linalg.norm(idn.marker_px["right"] - truth_px["right"], axis=-1)
    assert np.nanmax(err[used]) < 0.5
    # its last frames, past the reference's last instant, were compared at no instant
    assert set(idn.reason["right"][-2:].ravel()) == {"not_read"}
    # without following the clock the same record loses most of the right camera's views once it is a frame behind
    monkeypatch.setattr(tracker3d, "whole_frames_gained", lambda rate, n: np.zeros(int(n), int))
    held = identify_markers(frames, RIG, static, 3, **timing)
    late = inside & (np.arange(N) >= 40)[:, None]
    assert (held.reason["right"][late] == "").mean() < (idn.reason["right"][late] == "").mean() - 0.2


def _idn_of(reason_right):
    n = len(reason_right)
    px = np.arange(n, dtype=float)[:, None, None] * np.ones((1, 1, 2))
    return tracker3d.Identification(marker_px={"right": px}, reason={"right": np.array(reason_right, object)[:, None]},
                                    area={"right": np.full((n, 1), 20.0)}, points=np.zeros((n, 1, 3)),
                                    model_index=np.arange(1), rigid_rms_m=np.zeros(n), thresholds={}, anchor_frame=0,
                                    anchor_margin=1.0)


def test_values_go_back_to_the_cameras_own_frames():
    """A slow clock: its frame 1 was compared at the reference instants 1 and 2 (the used view kept) and its frame 3
    at none; a fast clock: its frame 1 at none."""
    slow = tracker3d.CameraDelay(0.0, 0.0, 480.0, 0.0, gained=np.array([0, 0, 1, 1]))
    out = tracker3d._in_own_frames(_idn_of(["", "lost", "", ""]), {"right": slow})
    assert out.marker_px["right"][:3, 0, 0].tolist() == [0.0, 2.0, 3.0]
    assert out.reason["right"][:, 0].tolist() == ["", "", "", "not_read"] and np.isnan(out.marker_px["right"][3]).all()
    fast = tracker3d.CameraDelay(0.0, 0.0, 480.0, 0.0, gained=np.array([0, -1, -1, -1]))
    out = tracker3d._in_own_frames(_idn_of(["", "", "", ""]), {"right": fast})
    assert out.reason["right"][:, 0].tolist() == ["", "not_read", "", ""]
    assert out.marker_px["right"][[0, 2, 3], 0, 0].tolist() == [0.0, 1.0, 2.0]


def test_not_read_is_written_whole_into_reasons_of_any_width():
    """The tracker's reasons are strings as wide as the longest it wrote: ``not_read`` must not be cut to it."""
    idn = _idn_of(["", "", "", ""])
    idn = tracker3d.Identification(**{**idn.__dict__, "reason": {"right": np.array([[""], ["lost"], [""], [""]])}})
    slow = tracker3d.CameraDelay(0.0, 0.0, 480.0, 0.0, gained=np.array([0, 0, 1, 1]))
    out = tracker3d._in_own_frames(idn, {"right": slow})
    assert out.reason["right"][:, 0].tolist() == ["", "", "", "not_read"]


def test_a_black_frame_past_the_video_is_not_kept_as_one_of_its_frames():
    """A fast clock's last reference instant reads past the sequence (black): that search must not stand for the
    video's frame there when another identification, at an offset one larger, reads it."""
    from horsemocap.detection import DetectionParams
    from horsemocap.detection.candidates import WholeFrameSearches
    gray = np.zeros((40, 40), np.uint8)
    gray[10:14, 10:14] = 255
    base = [gray] * 6
    searches = WholeFrameSearches()
    rules = ({"a": 100}, {"a": DetectionParams(area_min=4)})
    black = searches.of_offsets({"a": 0})({"a": ClockFollowingFrames(base, [0, 0, 0, 0, 0, -1])}, 5, ["a"], *rules)
    later = searches.of_offsets({"a": 1})({"a": base}, 5, ["a"], *rules)
    assert len(black["a"]) == 0 and len(later["a"]) == 1


def test_clocks_not_measured_are_named_from_half_a_frame_at_the_record_middle():
    """When no markers in the first frames after the flash measured the clocks, the detect step's failure names a
    clock at another rate once, at 30000/1001 fps beside 30, the record's middle (where the markers are then first
    labelled, at the flash's phases) is half a frame off or more."""
    n = NTSC_FRAMES_PER_GAINED_FRAME
    assert clocks_not_measured_hint(n - 1) == ""
    hint = clocks_not_measured_hint(n)
    assert hint.startswith("; the cameras run free") and "0.5 frames off" in hint and f"{n} frames" in hint
    assert "1.4 frames off" in clocks_not_measured_hint(2787)
