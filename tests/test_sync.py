"""Flash synchronisation (thesis 3.5, eq. 3.11-3.14) on synthetic frames with known truth."""
import numpy as np
import pytest

from horsemocap.sync import (SyncError, aligned_index, detect_flash, flash_frame, flash_offsets,
                             frame_differences)

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
