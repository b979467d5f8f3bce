"""Decoding a video once: the flash search's frames kept for the detection, read ahead and behind."""
import cv2
import numpy as np

from horsemocap import sources


def _video(path, n=60):
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 30, (40, 30))
    for k in range(n):
        w.write(np.full((30, 40, 3), 4 * k, np.uint8))
    w.release()
    return sources.FrameSource(path)


def test_the_flash_search_frames_stay_while_other_readers_fill_the_cache(tmp_path, monkeypatch):
    monkeypatch.setattr(sources, "_SHARED", sources._SharedGray(30 * 40 * 20))     # room for 20 frames
    src = _video(tmp_path / "v.avi")
    list(src.iter_frames(0, 20, color=False, share=True))                          # the flash search's 20 frames
    pinned = set(sources._SHARED.frames)
    seq = src.sequence(20, 60, color=False)
    for k in range(40):                                                            # another reader, further on
        seq[k]
    seq.close()
    assert set(sources._SHARED.frames) == pinned and len(pinned) == 20 and sources._SHARED.size <= 30 * 40 * 20


def test_reading_backwards_takes_the_shared_frames_without_decoding(tmp_path, monkeypatch):
    monkeypatch.setattr(sources, "_SHARED", sources._SharedGray(30 * 40 * 60))
    src = _video(tmp_path / "v.avi")
    arr = src.read(0, 60, color=False)
    list(src.iter_frames(0, 30, color=False, share=True))
    reads = []
    decode = sources.FrameSequence._decode
    monkeypatch.setattr(sources.FrameSequence, "_decode",
                        lambda self, cap, count: (reads.append(count), decode(self, cap, count))[1])
    seq = src.sequence(0, 60, color=False, cache_frames=12)
    for k in list(range(59, -1, -1)) + list(range(0, 60)):                        # down to the start, then up again
        np.testing.assert_array_equal(seq[k], arr[k])
    seq.close()
    # frames 0..29 are shared: the blocks behind decode only frames from 30 on, and reading up again decodes
    # the rest once more (the cache holds 12 frames): at most 30 + 30 frames decoded by the reading thread
    assert sum(reads) <= 60


def test_reading_ahead_stays_inside_the_cache(tmp_path):
    src = _video(tmp_path / "v.avi")
    arr = src.read(0, 60, color=False)
    for cache in (8, 12, 128):
        seq = src.sequence(0, 60, color=False, cache_frames=cache)
        seen_ahead = 0
        for k in range(60):
            np.testing.assert_array_equal(seq[k], arr[k])
            assert len(seq._cache) <= max(8, cache)
            seen_ahead = max(seen_ahead, sum(1 for j in seq._cache if j > k))
        seq.close()
        assert seen_ahead >= 1              # frames decoded ahead of the one read


def _flash_video(path, flash_at: int, n=40):
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 30, (160, 120))
    for k in range(n):
        frame = np.full((120, 160, 3), 20, np.uint8)
        if k >= flash_at:
            frame[40:60, 70:90] = 230
        w.write(frame)
    w.release()
    return sources.FrameSource(path)


def test_the_cameras_flash_searches_side_by_side_find_what_one_by_one_finds(tmp_path, monkeypatch):
    from horsemocap import sync

    cams = {name: _flash_video(tmp_path / f"{name}.avi", at) for name, at in (("left", 7), ("middle", 12),
                                                                               ("right", 3))}
    side_by_side = sync.flash_detections(cams)
    monkeypatch.setattr(sync, "_flash_readers", lambda *a: 1)
    one_by_one = sync.flash_detections(cams)
    assert {c: d.frame for c, d in side_by_side.items()} == {"left": 7, "middle": 12, "right": 3}
    assert list(side_by_side) == ["left", "middle", "right"]
    for c in cams:
        assert side_by_side[c].frame == one_by_one[c].frame
        np.testing.assert_array_equal(side_by_side[c].signal, one_by_one[c].signal)
        np.testing.assert_array_equal(side_by_side[c].region, one_by_one[c].region)


def test_a_camera_without_flash_is_the_error_even_when_searched_beside_others(tmp_path):
    import pytest

    from horsemocap import sync

    cams = {"left": _flash_video(tmp_path / "left.avi", 5), "middle": _flash_video(tmp_path / "m.avi", 99),
            "right": _flash_video(tmp_path / "right.avi", 99)}
    with pytest.raises(sync.SyncError, match="camera 'middle'"):
        sync.flash_detections(cams)


def test_flash_searches_at_once_are_bounded_by_the_memory_they_hold(tmp_path, monkeypatch):
    from horsemocap import sync

    cams = {name: _video(tmp_path / f"{name}.avi") for name in ("a", "b", "c")}    # 60 frames of 40 x 30
    assert cams["a"].gray_bytes() == 60 * 40 * 30 and cams["a"].gray_bytes(10) == 10 * 40 * 30
    monkeypatch.setattr(sync.os, "cpu_count", lambda: 2)
    assert sync._flash_readers(cams, None) == 3
    monkeypatch.setattr(sync, "FLASH_SEARCH_BYTES", 2 * 60 * 40 * 30)
    assert sync._flash_readers(cams, None) == 2 and sync._flash_readers(cams, 30) == 3
    monkeypatch.setattr(sync.os, "cpu_count", lambda: 1)
    assert sync._flash_readers(cams, None) == 1


def test_frame_counts_are_kept_for_the_file_as_it_is(tmp_path):
    path = tmp_path / "v.avi"
    assert len(_video(path, 60)) == 60
    assert len(_video(path, 25)) == 25          # written again: another size, counted again


def test_a_video_rewritten_unreadable_is_refused_again(tmp_path):
    import pytest

    path = tmp_path / "v.avi"
    _video(path, 10)
    sources.FrameSource(path)                      # checked once
    path.write_bytes(b"not a video at all")
    with pytest.raises(sources.SourceError, match="cannot be opened as a video"):
        sources.FrameSource(path)


def test_a_video_without_a_declared_count_is_not_taken_as_empty(tmp_path, monkeypatch):
    """A container that declares no frame count: the flash searches' memory bound counts the frames searched
    (or those that decode), not zero, so it still applies."""
    cam = _video(tmp_path / "a.avi")                           # 60 frames of 40 x 30
    real_get = cv2.VideoCapture.get
    monkeypatch.setattr(cv2.VideoCapture, "get",
                        lambda self, prop: 0.0 if prop == cv2.CAP_PROP_FRAME_COUNT else real_get(self, prop))
    assert cam.gray_bytes(10) == 10 * 40 * 30
    assert cam.gray_bytes() == len(cam) * 40 * 30 > 0


def test_the_shared_frames_leave_in_the_order_the_scan_over_every_frame_gives(monkeypatch):
    """The store's eviction (least recently used frame not pinned, else the oldest pinned) against the rule
    written out as a scan of every frame, over random puts and gets."""
    rng = np.random.default_rng(3)
    frame = np.zeros((3, 4), np.uint8)
    store = sources._SharedGray(frame.nbytes * 15)
    ref, ref_pinned = [], set()                     # keys in use order, and the pinned ones
    for _ in range(3000):
        key = ("v", int(rng.integers(0, 60)))
        if rng.random() < 0.4:
            store.get(*key)
            if key in ref:
                ref.remove(key)
                ref.append(key)
            continue
        pinned = bool(rng.random() < 0.2)
        store.put(*key, frame, pinned=pinned)
        if key in ref or (not pinned and len(ref) == 15 and len(ref_pinned) == len(ref)):
            continue
        ref.append(key)
        if pinned:
            ref_pinned.add(key)
        if len(ref) > 15:
            old = next((k for k in ref if k not in ref_pinned), ref[0])
            ref.remove(old)
            ref_pinned.discard(old)
        assert list(store.frames) == ref and store.pinned == ref_pinned
    assert store.size == frame.nbytes * len(ref) <= frame.nbytes * 15
