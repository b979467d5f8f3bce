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
