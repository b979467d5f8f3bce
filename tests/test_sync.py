"""Flash synchronisation (thesis 3.5, eq. 3.11-3.14) on synthetic frames with known truth."""
import numpy as np
import pytest

from horsemocap.sync import (SyncError, aligned_index, detect_flash, flash_detections, flash_frame,
                             flash_offsets, frame_differences)

H, W = 96, 128


def _disc(img, cx, cy, r, value):
    yy, xx = np.mgrid[:img.shape[0], :img.shape[1]]
    img[(xx - cx) ** 2 + (yy - cy) ** 2 <= r * r] = value


def make_frames(n=80, flash_at=None, flash_fraction=1.0, seed=0, movers=True, flash_xy=(100, 20),
                flash_len=None, slow_object=True):
    """Dark noisy frames; bright spots moving; a flash disc switching on at ``flash_at``.

    ``flash_fraction`` is the part of the exposure of frame ``flash_at`` during
    which the flash was already on (the frame before is off, the one after on).
    """
    rng = np.random.default_rng(seed)
    frames = np.clip(rng.normal(30, 3, (n, H, W)), 0, 255)
    for t in range(n):
        f = frames[t]
        if movers:
            # reflective markers moving right 6 px/frame, a glint now and then
            for j, y in enumerate((40, 52, 64)):
                _disc(f, (5 + 6 * t + 9 * j) % (W + 20) - 10, y, 3, 235)
            if t % 7 == 3:
                _disc(f, rng.integers(10, W - 10), rng.integers(10, H - 10), 1.5, 250)
        if slow_object:
            # a big bright helmet moving 1.5 px/frame (each pixel stays bright for many frames)
            _disc(f, 10 + 1.5 * t, 80, 9, 220)
        if flash_at is not None:
            end = n if flash_len is None else flash_at + flash_len
            if flash_at < t < end:
                _disc(f, *flash_xy, 6, 250)
            elif t == flash_at:
                _disc(f, *flash_xy, 6, 30 + flash_fraction * 220)
    return frames.astype(np.uint8)


@pytest.mark.parametrize("flash_at", [12, 37, 61])
def test_flash_found_exactly_despite_moving_bright_spots(flash_at):
    frames = make_frames(flash_at=flash_at)
    det = detect_flash(frames)
    assert det.frame == flash_at
    assert det.surround_bright < 0.2
    # the flash region is where the disc is, not on a marker
    ys, xs = np.nonzero(det.region)
    assert abs(xs.mean() - 100) < 2 and abs(ys.mean() - 20) < 2
    # the moving objects were seen and rejected
    assert any(not c["accepted"] for c in det.candidates)


def test_flash_switching_on_during_an_exposure():
    # on for 70 % of frame 30's exposure: frame 30 already counts as on; 30 % of it: frame 31
    assert flash_frame(make_frames(flash_at=30, flash_fraction=0.7)) == 30
    assert flash_frame(make_frames(flash_at=30, flash_fraction=0.3)) == 31


def test_rgb_frames_and_search_window():
    gray = make_frames(flash_at=20)
    rgb = np.repeat(gray[..., None], 3, axis=-1)
    assert flash_frame(rgb) == 20
    with pytest.raises(SyncError, match="no flash"):
        flash_frame(gray, search_frames=18)


def test_no_flash_names_the_camera():
    frames = make_frames(flash_at=None)
    with pytest.raises(SyncError, match=r"camera 'middle'.*no flash.*moving bright object"):
        flash_offsets({"middle": frames})


def test_offsets_and_eq_3_11_to_3_13():
    # cameras started at different times: the flash at 10, 63 and 136 of their own frames (53, 73)
    srcs = {"left": make_frames(150, flash_at=10, seed=1), "middle": make_frames(150, flash_at=63, seed=2),
            "right": make_frames(150, flash_at=136, seed=3)}
    off = flash_offsets(srcs)
    assert off == {"left": 10, "middle": 63, "right": 136}
    dets = flash_detections(srcs)       # what the pipeline reads to warn about an ambiguous camera
    assert {c: d.frame for c, d in dets.items()} == off and not any(d.ambiguous for d in dets.values())
    assert frame_differences(off) == {"LM": 53, "MR": 73, "LR": 126}
    assert aligned_index(off, 0) == {"left": 0, "middle": 53, "right": 126}


def test_frame_source_folder(tmp_path):
    import cv2

    frames = make_frames(40, flash_at=25)
    for i, f in enumerate(frames):
        cv2.imwrite(str(tmp_path / f"left{i}.png"), f)
    from horsemocap.sources import FrameSource

    assert flash_offsets({"left": FrameSource(tmp_path)}) == {"left": 25}
    assert flash_frame(FrameSource(tmp_path), start=10) == 25


def test_default_session_offsets_are_found_exactly():
    """Done-when: the flash offsets of the default session (virtual laboratory) are found exactly."""
    from horsemocap.data import default_session_dir
    from horsemocap.sources import FrameSource

    d = default_session_dir()
    if not (d / "truth" / "truth.json").is_file():
        pytest.skip("default session not rendered yet")
    import json

    truth = json.loads((d / "truth" / "truth.json").read_text())["offsets"]
    srcs = {c: FrameSource(d / "motion" / f"{c}.avi") for c in truth}
    assert flash_offsets(srcs) == truth


def _scene(n=70, flash_at=None, seed=0):
    """Dark noisy frames, a flash disc (r = 6) at (100, 20) on from ``flash_at`` for 4 frames."""
    rng = np.random.default_rng(seed)
    frames = np.clip(rng.normal(27, 3, (n, H, W)), 0, 255)
    if flash_at is not None:
        for t in range(flash_at, min(n, flash_at + 4)):
            _disc(frames[t], 100, 20, 6, 250)
    return frames


def _ellipse(img, cx, cy, ax, ay, value):
    yy, xx = np.mgrid[:img.shape[0], :img.shape[1]]
    img[((xx - cx) / ax) ** 2 + ((yy - cy) / ay) ** 2 <= 1] = value


def test_head_entering_from_the_image_edge_before_the_flash():
    # a bright-coated head (gray 110 on 27) enters at the left edge at 3 px/frame, long before the flash;
    # the surroundings test cannot see its body (outside the image): the old rule took it
    frames = _scene(flash_at=45)
    for t in range(70):
        _ellipse(frames[t], -30 + 3 * t, 60, 28, 12, 110)
    det = detect_flash(frames.astype(np.uint8))
    assert det.frame == 45
    early = [c for c in det.candidates if c["frame"] < 40]
    assert early and not any(c["accepted"] for c in early)
    assert any("image edge" in c["reason"] for c in early)
    assert not det.ambiguous


def test_leading_edge_of_a_moving_object_is_not_the_flash():
    # a bright object fully in view, moving 4 px/frame: its leading edge brightens at once with little
    # already bright around it (an elongated shape); its bright area grows frame to frame
    frames = _scene(flash_at=50)
    for t in range(70):
        _ellipse(frames[t], 10 + 4 * max(0, t - 20), 70, 8, 5, 120)
    det = detect_flash(frames.astype(np.uint8))
    assert det.frame == 50
    moving = [c for c in det.candidates if 20 <= c["frame"] < 48]
    assert moving and not any(c["accepted"] for c in moving)


def test_object_landing_and_staying_before_the_flash():
    # a hoof bandage (gray 200) jumps 16 px a frame (more than its size), lands at frame 16 and stays:
    # it brightens at once, in the dark, and stays still; but the place it came from went dark
    frames = _scene(flash_at=40)
    for t in range(12, 70):
        x = 20 + 16 * (min(t, 16) - 12)
        frames[t, 62:76, x - 4:x + 4] = 200
    det = detect_flash(frames.astype(np.uint8))
    assert det.frame == 40
    landing = [c for c in det.candidates if 12 <= c["frame"] <= 17]
    assert landing and not any(c["accepted"] for c in landing)
    assert any("went dark beside it" in c["reason"] for c in landing)


def test_object_that_appears_and_stays_is_taken_only_if_it_is_a_switch_on():
    # the same landing object without any flash: no flash (a clear message), not the object
    frames = _scene(flash_at=None)
    for t in range(12, 70):
        x = 20 + 16 * (min(t, 16) - 12)
        frames[t, 62:76, x - 4:x + 4] = 200
    with pytest.raises(SyncError, match=r"no flash found in frames 0\.\.69.*went dark beside it"):
        detect_flash(frames.astype(np.uint8), name="camera 'left'")
    # a second light switching on in place, as large as the flash: the frames cannot tell which
    # one is the flash, and the detection says so
    frames = _scene(flash_at=40)
    for t in range(20, 70):
        _disc(frames[t], 30, 70, 6, 250)
    det = detect_flash(frames.astype(np.uint8))
    assert det.ambiguous and det.runner_up is not None
    assert det.frame in (20, 40) and abs(det.runner_up["frame"] - (60 - det.frame)) <= 1
    assert det.runner_up["on_frame"] == 60 - det.frame       # measured as the flash's frame: usable as an offset
    # only the flash: not ambiguous
    det = detect_flash(_scene(flash_at=40).astype(np.uint8))
    assert det.frame == 40 and not det.ambiguous and det.runner_up is None


def test_bright_bar_uncovered_by_a_passing_occluder_is_not_the_flash():
    # a white rail (gray 200) behind a dark leg that passes in front of it: the rail's pixels
    # brighten at once when the leg leaves them, and stay; they were as bright before the leg came
    frames = _scene(flash_at=45)
    frames[:, 76:86, :] = 200
    for t in range(70):
        x = 6 * t - 20
        frames[t, 66:96, max(0, x):max(0, x + 14)] = 40
    det = detect_flash(frames.astype(np.uint8))
    assert det.frame == 45
    uncovered = [c for c in det.candidates if c["frame"] < 43]
    assert uncovered and not any(c["accepted"] for c in uncovered)


def test_no_frames_is_a_sync_error():
    with pytest.raises(SyncError, match="no frames to search"):
        detect_flash(np.zeros((0, 10, 10), np.uint8), name="camera 'left'")
