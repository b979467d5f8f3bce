"""The compiled candidate search against the Python path (issue 16; horsemocap.detection.regions_core).

The contract: the same regions, in the same order, with the same areas and
border flags; centres (and light terms) within 1e-9 px. Every comparison
runs both paths on the same input: the compiled one as the package runs it,
the Python one with the core set aside (``regions_core.CORE = None``).
Random and rendered images: crops at the image border, touching regions,
regions cut by the crop edge, empty crops, ``max_count`` ties, 1-pixel
regions, thresholds 0 and 255. Skipped (with the reason) when the core is
not built.
"""
import os
import subprocess
import sys

import cv2
import numpy as np
import pytest

from horsemocap.detection import identification as idn
from horsemocap.detection import regions_core, tracking
from horsemocap.detection.thresholds import connected_components
from horsemocap.virtuallab.render import add_image_disc

needs_core = pytest.mark.skipif(regions_core.CORE is None, reason=f"compiled core not active: {regions_core.ACTIVE_REASON}")
TOL = 1e-9


@pytest.fixture
def python_path(monkeypatch):
    """A function running ``fn(*a, **k)`` by the Python path."""
    def run(fn, *a, **k):
        with monkeypatch.context() as m:
            m.setattr(regions_core, "CORE", None)
            return fn(*a, **k)
    return run


def assert_same(fast, ref, what=""):
    assert len(fast) == len(ref), what
    np.testing.assert_array_equal(fast.area, ref.area, err_msg=what)
    np.testing.assert_array_equal(fast.cut, ref.cut, err_msg=what)
    assert fast.centre.shape == ref.centre.shape
    if len(ref):
        assert np.max(np.abs(fast.centre - ref.centre)) <= TOL, what
    assert (fast.slope is None) == (ref.slope is None), what
    if ref.slope is not None:
        np.testing.assert_allclose(fast.slope, ref.slope, rtol=0, atol=TOL, err_msg=what)
        np.testing.assert_allclose(fast.moments, ref.moments, rtol=0, atol=TOL, err_msg=what)


def scene(rng, H, W, n, radius=(0, 7), noise=3.0, background=30.0):
    """A gray image of anti-aliased discs (some overlapping or cut by the border), with sensor noise."""
    img = np.full((H, W), background)
    for _ in range(n):
        add_image_disc(img, rng.uniform(-4, W + 4), rng.uniform(-4, H + 4), rng.uniform(*radius),
                       rng.uniform(40, 220))
    img += rng.normal(0, noise, img.shape)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def random_crop(rng, W, H):
    """A crop (u0, v0, u1, v1) that may reach beyond the image (clipped) or be empty (one in ten)."""
    u0, v0 = int(rng.integers(-12, W)), int(rng.integers(-12, H))
    if rng.random() < 0.1:
        return u0, v0, u0 - int(rng.integers(0, 3)), v0 + 5
    return u0, v0, u0 + int(rng.integers(1, W + 12)), v0 + int(rng.integers(1, H + 12))


@needs_core
def test_frame_candidates_random_scenes(python_path):
    rng = np.random.default_rng(1)
    counts = {"regions": 0, "cut": 0, "slopes": 0}
    for it in range(600):
        H, W = (int(x) for x in rng.integers(6 if it % 10 == 0 else 40, 160, 2))
        g = scene(rng, H, W, int(rng.integers(0, 40)), radius=(1.5, 6), noise=float(rng.choice([0.0, 3.0, 12.0])))
        thr = int(rng.choice([0, 60, 90, 90, 130, 130, 254, 255]))
        crop = None if it % 4 == 0 else random_crop(rng, W, H)
        args = dict(area_range=(float(rng.choice([1, 3])), None if it % 3 == 0 else 400.0), min_circularity=rng.choice([None, None, 0.5, 0.8]),
                    crop=crop, centroid="binary" if it % 7 == 0 else "weighted",
                    max_count=int(rng.choice([24, 24, 24, 3, 1, 0])), light=bool(it % 2))
        fast = idn.frame_candidates(g, thr, **args)
        ref = python_path(idn.frame_candidates, g, thr, **args)
        assert_same(fast, ref, f"scene {it}: {args}")
        counts["regions"] += len(ref)
        counts["cut"] += int(ref.cut.sum())
        counts["slopes"] += 0 if ref.slope is None else int(np.isfinite(ref.slope[:, 0]).sum())
    # the comparison saw what it is meant to see
    assert counts["regions"] > 500 and counts["cut"] > 100 and counts["slopes"] > 30, counts


@needs_core
def test_whole_frame_search_random_scenes(python_path):
    rng = np.random.default_rng(2)
    seen = 0
    for it in range(300):
        H, W = (int(x) for x in rng.integers(20, 260, 2))
        g = scene(rng, H, W, int(rng.integers(0, 60)), radius=(0, 5))
        thr = int(rng.choice([0, 70, 120, 255]))
        for mc in (None, 0.5):
            for max_count in (24, 2, 200):
                fast = idn._whole_frame_search(g, thr, (1.0, 400.0), mc, "weighted", max_count)
                ref = python_path(idn._whole_frame_search, g, thr, (1.0, 400.0), mc, "weighted", max_count)
                assert_same(fast, ref, f"scene {it}, min_circularity {mc}, max_count {max_count}")
                seen += len(ref)
    assert seen > 3000


@needs_core
def test_many_regions_take_the_sums_path(python_path):
    """More than 8 (and more than 64) regions: circularity by sums, in crop or full-image pixels."""
    rng = np.random.default_rng(3)
    for it in range(20):
        g = scene(rng, 300, 400, 250, radius=(0.5, 4), noise=2.0)
        for crop in (None, (37, 21, 351, 280)):
            a = dict(area_range=(1.0, None), min_circularity=0.6, crop=crop, max_count=500, light=True)
            ref = python_path(idn.frame_candidates, g, 80, **a)
            assert len(ref) > 64
            assert_same(idn.frame_candidates(g, 80, **a), ref)
        ref = python_path(idn._whole_frame_search, g, 80, (1.0, None), 0.6, "weighted", 500)
        assert len(ref) > 64
        assert_same(idn._whole_frame_search(g, 80, (1.0, None), 0.6, "weighted", 500), ref)


@needs_core
def test_binary_patterns(python_path):
    """Salt-and-pepper images: 1-pixel regions, touching and diagonal regions, ties of area everywhere."""
    rng = np.random.default_rng(4)
    for it in range(400):
        H, W = (int(x) for x in rng.integers(1, 50, 2))
        g = ((rng.random((H, W)) < rng.uniform(0.05, 0.7)) * rng.integers(100, 256, (H, W))).astype(np.uint8)
        for thr in (0, 99, 255):
            for max_count in (24, 3):
                a = dict(area_range=(1.0, 1e9), min_circularity=None, crop=random_crop(rng, W, H),
                         max_count=max_count, light=True)
                assert_same(idn.frame_candidates(g, thr, **a), python_path(idn.frame_candidates, g, thr, **a),
                            f"pattern {it}, threshold {thr}")
                fast = idn._whole_frame_search(g, thr, (1.0, 1e9), None, "weighted", max_count)
                ref = python_path(idn._whole_frame_search, g, thr, (1.0, 1e9), None, "weighted", max_count)
                assert_same(fast, ref, f"pattern {it}, threshold {thr}")


@needs_core
def test_edge_cases(python_path):
    g = np.zeros((40, 50), np.uint8)
    g[0:3, 0:3] = 200                      # in the image corner
    g[10, 10] = 200                        # one pixel
    g[20:25, 20:25] = 200                  # two squares touching diagonally: one region
    g[25:28, 25:28] = 200
    g[30:33, 40:43] = 200                  # two of equal area (a max_count tie)
    g[30:33, 45:48] = 200
    cases = [dict(crop=(0, 0, 0, 0)), dict(crop=(60, 60, 70, 70)), dict(crop=(5, 5, 5, 30)),
             dict(crop=(21, 0, 50, 40)), dict(crop=None, max_count=1), dict(crop=None, max_count=2),
             dict(crop=(-5, -5, 100, 100)), dict(crop=(0.7, 1.9, 30.2, 29.9))]
    for case in cases:
        for thr in (0, 100, 255):
            a = dict(area_range=(1.0, None), min_circularity=None, light=True, **case)
            assert_same(idn.frame_candidates(g, thr, **a), python_path(idn.frame_candidates, g, thr, **a), str(case))
    empty = np.zeros((30, 30), np.uint8)
    assert len(idn.frame_candidates(empty, 10)) == 0
    assert len(idn._whole_frame_search(empty, 10, (1.0, None), None)) == 0


@needs_core
def test_label_matches_opencv():
    """The core's labelling: OpenCV's labels (its block-based numbering), stats and centres."""
    rng = np.random.default_rng(5)
    for it in range(600):
        H, W = (int(x) for x in rng.integers(1, 80, 2))
        if it % 2:
            g = rng.integers(0, 256, (H, W), dtype=np.uint8)
        else:
            g = scene(rng, H, W, int(rng.integers(0, 20)))
        big = np.zeros((H + 3, W + 5), np.uint8)
        big[1:1 + H, 2:2 + W] = g
        view = big[1:1 + H, 2:2 + W]                      # a crop: rows not contiguous with each other
        for thr in (0, 100, 255):
            n, lab, st, ce = regions_core.core_label(view, thr)
            n2, lab2, st2, ce2 = connected_components(cv2.threshold(g, thr, 255, cv2.THRESH_BINARY)[1])
            assert n == n2
            np.testing.assert_array_equal(lab, lab2)
            np.testing.assert_array_equal(st[1:], st2[1:])
            assert st[0, 4] == st2[0, 4]
            np.testing.assert_array_equal(ce[1:], ce2[1:])


@needs_core
def test_thesis_chain_unchanged(python_path):
    """detect_markers (its crops labelled by the core) gives the Python path's result."""
    rng = np.random.default_rng(6)
    n, H, W = 30, 240, 320
    t = np.arange(n)
    base = np.array([[100.0, 120.0], [160.0, 100.0], [220.0, 125.0]])
    frames = []
    for k in t:
        img = np.full((H, W), 35.0)
        for u, v in base + [1.5 * k, 2.0 * np.sin(k / 4)]:
            add_image_disc(img, u, v, 5.0, 180.0)
        add_image_disc(img, 30 + 2 * k, 200.0, 3.0, 150.0)      # a distractor
        img += rng.normal(0, 2, img.shape)
        frames.append(np.clip(np.rint(img), 0, 255).astype(np.uint8))
    frames = np.stack(frames)
    fast = tracking.detect_markers(frames, 3)
    ref = python_path(tracking.detect_markers, frames, 3)
    assert fast.params == ref.params
    np.testing.assert_array_equal(fast.reason, ref.reason)
    np.testing.assert_array_equal(np.isnan(fast.marker_px), np.isnan(ref.marker_px))
    assert np.nanmax(np.abs(fast.marker_px - ref.marker_px)) <= TOL
    assert fast.found.sum() > 80


@needs_core
def test_bad_arguments_raise_clearly():
    core = regions_core.CORE
    g = np.zeros((10, 12), np.uint8)
    with pytest.raises(ValueError, match="2-D uint8"):
        core.candidates(g.astype(np.uint16), 5, [(0, 0, 12, 10)], 1.0, 10.0, None, False, 5, True, False)
    with pytest.raises(ValueError, match="2-D uint8"):
        core.candidates(np.zeros((2, 3, 4), np.uint8), 5, [(0, 0, 1, 1)], 1.0, 10.0, None, False, 5, True, False)
    with pytest.raises(ValueError, match="C-contiguous"):
        core.candidates(np.zeros((10, 12), np.uint8)[:, ::2], 5, [(0, 0, 1, 1)], 1.0, 10.0, None, False, 5, True,
                        False)
    for box in [(0, 0, 13, 10), (-1, 0, 5, 5), (5, 5, 4, 6), (0, 0, 12, 11)]:
        with pytest.raises(ValueError, match="not inside"):
            core.candidates(g, 5, [box], 1.0, 10.0, None, False, 5, True, False)
    with pytest.raises(ValueError, match="4 values"):
        core.candidates(g, 5, [(0, 0, 5)], 1.0, 10.0, None, False, 5, True, False)
    with pytest.raises(ValueError, match="max_count"):
        core.candidates(g, 5, [(0, 0, 5, 5)], 1.0, 10.0, None, False, -1, True, False)
    with pytest.raises(ValueError, match="2-D uint8"):
        core.label(np.zeros(5, np.uint8), 5)
    with pytest.raises(ValueError, match="contiguous"):
        core.label(np.zeros((10, 12), np.uint8)[:, ::2], 5)


def test_path_is_exposed_and_can_be_forced():
    import horsemocap.detection as det
    assert det.ACTIVE_PATH in ("compiled", "python")
    env = {**os.environ, regions_core.PURE_PYTHON_ENV: "1"}
    out = subprocess.run([sys.executable, "-c", "import horsemocap.detection as d; print(d.ACTIVE_PATH)"],
                         env=env, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "python"


@needs_core
def test_bright_boxes_match_bright_crops():
    from horsemocap.detection.thresholds import bright_crops
    rng = np.random.default_rng(7)
    for it in range(300):
        H, W = (int(x) for x in rng.integers(1, 300, 2))
        g = scene(rng, H, W, int(rng.integers(0, 30)), radius=(0.5, 12), noise=2.0)
        if it % 10 == 0:
            g = rng.integers(0, 256, (H, W), dtype=np.uint8)        # bright everywhere: the whole image
        for thr in (-1, 0, 60, 100, 254, 255):
            assert regions_core.core_bright_boxes(g, thr) == bright_crops(g, thr)[1], (it, thr)


@needs_core
def test_whole_count_and_its_search(python_path):
    """The reacquisition's count of whole regions and its search: the same by both paths."""
    rng = np.random.default_rng(8)
    for it in range(100):
        H, W = (int(x) for x in rng.integers(20, 200, 2))
        g = scene(rng, H, W, int(rng.integers(0, 25)), radius=(0.5, 6))
        for thr in (0, 90, 255):
            n_fast, search_fast = idn._whole_count(g, thr, (3.0, None))
            n_ref, search_ref = python_path(idn._whole_count, g, thr, (3.0, None))
            assert n_fast == n_ref
            for mc, count in ((0.5, 24), (None, 2)):
                assert_same(search_fast(mc, "weighted", count), python_path(search_ref, mc, "weighted", count))


@needs_core
def test_inputs_the_core_does_not_take_go_to_the_python_path(python_path):
    """Views with rows that are not contiguous, reversed or broadcast, and counts or thresholds beyond a C
    int, give what the Python path gives (before: a ValueError or an OverflowError of the core)."""
    from horsemocap.detection.filters import find_candidates

    rng = np.random.default_rng(11)
    g = scene(rng, 60, 80, 6)
    for view in (g[::-1], g[:, ::2], np.broadcast_to(g[7], (5, 80))):
        fast, ref = find_candidates(view, 100, (1, 1e9)), python_path(find_candidates, view, 100, (1, 1e9))
        np.testing.assert_array_equal(fast[1], ref[1])
        np.testing.assert_array_equal(fast[0].area, ref[0].area)
    for count in (2 ** 31, 2 ** 70):
        a = dict(area_range=(1.0, None), min_circularity=None, max_count=count)
        assert_same(idn.frame_candidates(g, 100, **a), python_path(idn.frame_candidates, g, 100, **a), str(count))
    for thr in (-2 ** 40, 2 ** 31, 256):
        assert_same(idn.frame_candidates(g, thr), python_path(idn.frame_candidates, g, thr), str(thr))
        assert_same(idn._whole_frame_search(g, thr, (1.0, None), None),
                    python_path(idn._whole_frame_search, g, thr, (1.0, None), None), str(thr))


@needs_core
def test_light_terms_of_regions_on_one_line_and_of_large_regions(python_path):
    """The exact test of a region's interior on one line (the light terms' plane cannot be solved):
    bars and a thin diagonal go to the Python path's least squares, a wide disc is solved in C; both
    paths give the same terms."""
    g = np.full((120, 160), 20, np.uint8)
    g[10:13, 10:60] = 200                               # a 3-px bar: its interior is one row
    for k in range(40):                                 # a 3-px-wide diagonal line
        g[40 + k, 20 + k:23 + k] = 210
    yy, xx = np.mgrid[:120, :160]
    g[(yy - 80) ** 2 + (xx - 120) ** 2 < 30 ** 2] = 180  # a disc of ~2800 pixels
    a = dict(area_range=(1.0, 1e9), min_circularity=None, light=True)
    fast, ref = idn.frame_candidates(g, 100, **a), python_path(idn.frame_candidates, g, 100, **a)
    assert len(ref) == 3
    assert_same(fast, ref)


def test_a_core_built_from_another_source_is_not_used(monkeypatch):
    """An editable install leaves the built module beside its source: one built from another
    ``_regions.c`` (its ``CORE_SOURCE_HASH`` differs from the file's) is refused, with the reason, and the
    Python path runs; the module in use was built from the file beside it."""
    import importlib
    import types
    from pathlib import Path

    source = Path(regions_core.__file__).with_name("_regions.c")
    if regions_core.CORE is not None:
        assert regions_core.CORE.CORE_SOURCE_HASH == regions_core.source_hash(source)
    stale = types.SimpleNamespace(CORE_SOURCE_HASH="0123456789abcdef")
    monkeypatch.delenv(regions_core.PURE_PYTHON_ENV, raising=False)
    monkeypatch.setattr(importlib, "import_module", lambda name: stale)
    core, reason = regions_core._load_core()
    assert core is None and "rebuild" in reason and "another _regions.c" in reason
