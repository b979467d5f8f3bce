"""Equal results of the faster paths of issue 16 (no timing here: see benchmarks/)."""
import cv2
import numpy as np
import pytest

from horsemocap.detection import AUTO_MIN_CIRCULARITY, GENERIC_AREA, frame_candidates, whole_frame_search
from horsemocap.detection.thresholds import connected_components, label_bright
from horsemocap.virtuallab.longsession import EmptyArena, pass_starts


def _sparse_image(seed, size=(477, 634)):
    """Dark noisy image with glints, discs, a big blob and spots on the border (size not a multiple of 8)."""
    rng = np.random.default_rng(seed)
    H, W = size
    img = rng.normal(40, 6, size).clip(0, 255).astype(np.uint8)
    for _ in range(25):
        cv2.circle(img, (int(rng.integers(-3, W + 3)), int(rng.integers(-3, H + 3))), int(rng.integers(0, 9)),
                   int(rng.integers(120, 256)), -1)
    cv2.rectangle(img, (50, 60), (120, 130), 230, -1)
    img[0, :5] = 255
    img[-2:, -3:] = 255
    return img


@pytest.mark.parametrize("seed", range(6))
def test_label_bright_equals_labelling_the_whole_image(seed):
    img = _sparse_image(seed)
    for thr in (90, 127, 200, 255):
        a = cv2.connectedComponentsWithStats(cv2.threshold(img, thr, 255, cv2.THRESH_BINARY)[1], connectivity=8,
                                             ltype=cv2.CV_32S)
        b = label_bright(img, thr)
        assert a[0] == b[0]
        assert np.array_equal(a[1], b[1])
        assert np.array_equal(a[2], b[2])
        assert np.array_equal(a[3][1:], b[3][1:])


@pytest.mark.parametrize("seed", range(4))
def test_connected_components_equal_opencvs_default_call(seed):
    """The block-based labelling (faster in OpenCV 5.0) gives the default call's labels, stats and centres."""
    rng = np.random.default_rng(seed)
    images = [cv2.threshold(_sparse_image(seed), t, 255, cv2.THRESH_BINARY)[1] for t in (60, 127, 200)]
    images.append(((rng.random((97, 131)) < 0.45) * 255).astype(np.uint8))        # dense noise: many regions
    images.append(images[0][1:, 3:])                                               # odd offsets, a view
    for b in images:
        a = cv2.connectedComponentsWithStats(b, connectivity=8, ltype=cv2.CV_32S)
        c = connected_components(b)
        assert a[0] == c[0] and np.array_equal(a[1], c[1]) and np.array_equal(a[2], c[2])
        assert np.array_equal(a[3], c[3])


def test_label_bright_on_a_bright_image_labels_it_whole():
    img = np.full((64, 80), 200, np.uint8)
    img[::3] = 0
    a = cv2.connectedComponentsWithStats(cv2.threshold(img, 127, 255, cv2.THRESH_BINARY)[1], connectivity=8,
                                         ltype=cv2.CV_32S)
    b = label_bright(img, 127)
    assert a[0] == b[0] and np.array_equal(a[1], b[1]) and np.array_equal(a[2], b[2])


@pytest.mark.parametrize("seed", range(6))
def test_whole_frame_search_equals_frame_candidates(seed):
    img = _sparse_image(seed + 10) if seed < 4 else _sparse_image(seed + 10, (480, 640))[:, :200]  # few regions
    for centroid in ("weighted", "binary"):
        for max_count in (3, 24):
            a = frame_candidates(img, 127, (GENERIC_AREA[0], None), AUTO_MIN_CIRCULARITY, centroid=centroid,
                                 max_count=max_count)
            b = whole_frame_search(img, 127, (GENERIC_AREA[0], None), AUTO_MIN_CIRCULARITY, centroid=centroid,
                                    max_count=max_count)
            assert np.array_equal(a.centre, b.centre) and np.array_equal(a.area, b.area)
            assert np.array_equal(a.cut, b.cut)


def test_long_session_passes_and_empty_frames():
    assert pass_starts(18000, 68, 900) == list(range(0, 17101, 900))
    assert pass_starts(100, 68, 900) == [0]
    bg = np.full((48, 64, 3), 100.0)
    arena = EmptyArena(bg, 3)
    a, b = arena.frame(), arena.frame()
    assert a.dtype == np.uint8 and a.shape == (48, 64, 3)
    assert not np.array_equal(a, b)                          # fresh noise every frame
    assert abs(float(a.mean()) - 100) < 1.5 and 2.0 < float(a.astype(float).std()) < 6.0


def test_frame_sequence_reads_ahead_the_same_frames(tmp_path, monkeypatch):
    from horsemocap.sources import FrameSequence, FrameSource

    blocks = []
    decode_block = FrameSequence._decode_block

    def counted(self, cap, first, count):
        blocks.append((first, count))
        return decode_block(self, cap, first, count)

    monkeypatch.setattr(FrameSequence, "_decode_block", counted)

    w = cv2.VideoWriter(str(tmp_path / "v.avi"), cv2.VideoWriter_fourcc(*"MJPG"), 30, (40, 30))
    for k in range(60):
        img = np.full((30, 40, 3), 4 * k, np.uint8)
        w.write(img)
    w.release()
    src = FrameSource(tmp_path / "v.avi")
    rgb = src.read(3, 60, color=True)                          # (not kept in the shared gray frames)
    arr = np.stack([cv2.cvtColor(cv2.cvtColor(a, cv2.COLOR_RGB2BGR), cv2.COLOR_BGR2GRAY) for a in rgb])
    seq = src.sequence(3, 60, color=False, cache_frames=12)
    order = list(range(0, 30)) + [40, 41, 42, 10, 11, 12] + list(range(56, 30, -1)) + list(range(44, 57))
    for k in order:
        np.testing.assert_array_equal(seq[k], arr[k])
    assert seq._pool is not None and len(seq._cache) <= 12 + 8    # read ahead, bounded
    seq.close()
    # backwards, from a video no reader decoded yet (the gray frames read above are shared, not decoded again)
    (tmp_path / "v.avi").rename(tmp_path / "w.avi")
    src = FrameSource(tmp_path / "w.avi")
    seq = src.sequence(3, 60, color=False, cache_frames=12)
    for k in list(range(56, -1, -1)) + list(range(20, 30)) + list(range(25, 5, -1)):   # backwards, read behind
        np.testing.assert_array_equal(seq[k], arr[k])
        assert len(seq._cache) <= 12
    seq.close()
    assert len(blocks) >= 3 and all(count == 6 or first == 0 for first, count in blocks)   # read behind, by half caches


def test_frames_decoded_once_are_shared_by_the_readers_of_a_video(tmp_path, monkeypatch):
    from horsemocap import sources

    monkeypatch.setattr(sources, "_SHARED", sources._SharedGray(30 * 40 * 20))     # room for 20 frames
    w = cv2.VideoWriter(str(tmp_path / "v.avi"), cv2.VideoWriter_fourcc(*"MJPG"), 30, (40, 30))
    for k in range(60):
        w.write(np.full((30, 40, 3), 4 * k, np.uint8))
    w.release()
    src = sources.FrameSource(tmp_path / "v.avi")
    arr = src.read(0, 60, color=False)
    assert len(sources._SHARED.frames) == 0                  # not shared unless asked
    assert all(np.array_equal(f, arr[i]) for i, f in src.iter_frames(color=False, share=True))
    assert len(sources._SHARED.frames) == 20 and sources._SHARED.size <= 30 * 40 * 20    # the last 20, bounded
    decoded = []
    orig = sources.FrameSequence._seek
    monkeypatch.setattr(sources.FrameSequence, "_seek", lambda self, k: (decoded.append(k), orig(self, k))[1])
    seq = src.sequence(45, 60, color=False)
    for k in range(15):
        np.testing.assert_array_equal(seq[k], arr[45 + k])
    assert decoded == []                                     # every frame came from the shared ones
    seq.close()
