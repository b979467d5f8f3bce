"""The centres, light terms and shape measures of few NumPy calls equal the plain per-region definitions.

Issue 16 removed per-region Python work from the detectors (one dilation by a
square instead of iterated 3 x 3 ones, ``cv2.moments`` for the sums, the
plane's normal equations, the circularity's sums region by region). The
weights are multiples of 1/2 and the pixel indices integers, so the sums are
exact: the centres and circularities must be the very same numbers as the
plain definitions give; the light terms equal them to rounding.
"""
import cv2
import numpy as np
import pytest

from horsemocap import detection as det
from horsemocap.detection import filters, thesis_chain
from horsemocap.virtuallab.render import add_image_disc


def _image(seed, n=40, size=(200, 150)):
    """Anti-aliased discs of many sizes (some touching, some at the border), a sloped light, a bar."""
    rng = np.random.default_rng(seed)
    W, H = size
    yy, xx = np.mgrid[0:H, 0:W]
    img = 20 + 0.05 * xx + rng.normal(0, 2, (H, W))
    for _ in range(n):
        add_image_disc(img, rng.uniform(-3, W + 3), rng.uniform(-3, H + 3), rng.uniform(0.8, 6), rng.uniform(80, 220))
    img[30:53, 10:80] = 20 + rng.normal(0, 2, (23, 70))   # room for a bar 3 px high: its interior is one line
    img[40:43, 20:70] += 150
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def _plain_weights(gray, regions, i, margin=2):
    """The definition, region by region: grown masks by iterated 3 x 3 dilations, ``np.median`` of the ring."""
    k3 = np.ones((3, 3), np.uint8)
    lab = regions.labels
    h, w = lab.shape
    u0, v0 = regions.origin
    bx, by, bw, bh = (int(x) for x in regions.bbox[i])
    bx, by = bx - u0, by - v0
    g = 2 * margin + 2
    x0, y0, x1, y1 = max(bx - g, 0), max(by - g, 0), min(bx + bw + g, w), min(by + bh + g, h)
    sl = lab[y0:y1, x0:x1]
    own = sl == regions.ids[i]
    other = cv2.dilate(((sl != 0) & ~own).astype(np.uint8), k3).astype(bool)
    near = cv2.dilate(own.astype(np.uint8), k3, iterations=margin).astype(bool)
    far = cv2.dilate(near.astype(np.uint8), k3, iterations=2).astype(bool)
    sub = gray[y0:y1, x0:x1].astype(float)
    ring = far & ~near & ~other
    b = float(np.median(sub[ring])) if ring.any() else float(sub[own].min()) - 1
    wgt = np.where(near & ~(other & ~own), np.maximum(sub - b, 0.0), 0.0)
    return wgt, sub - b, own, x0, y0


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_weighted_centres_are_the_plain_definition_bit_for_bit(seed):
    gray = _image(seed)
    regions, keep = det.find_candidates(gray, 60, (1, 10 ** 6))
    assert len(keep) > 20
    got = det.weighted_centroids(gray, regions, keep)
    for k, i in enumerate(keep):
        wgt, _, _, x0, y0 = _plain_weights(gray, regions, i)
        s = wgt.sum()
        cols, rows = np.arange(x0, x0 + wgt.shape[1]), np.arange(y0, y0 + wgt.shape[0])
        want = (wgt.sum(axis=0) @ cols / s, wgt.sum(axis=1) @ rows / s) if s > 0 else regions.centroid[i]
        np.testing.assert_array_equal(got[k], want)


@pytest.mark.parametrize("seed", [0, 1])
def test_light_terms_equal_a_least_squares_plane(seed):
    gray = _image(seed)
    regions, keep = det.find_candidates(gray, 60, (1, 10 ** 6))
    slope, moments = det.light_terms(gray, regions, keep)
    fitted = on_line = 0
    for k, i in enumerate(keep):
        wgt, above, own, _, _ = _plain_weights(gray, regions, i)
        s = wgt.sum()
        yy, xx = np.mgrid[0:wgt.shape[0], 0:wgt.shape[1]]
        cu, cv = (wgt * xx).sum() / s, (wgt * yy).sum() / s
        du, dv = xx - cu, yy - cv
        S = np.array([[(wgt * du * du).sum(), (wgt * du * dv).sum()], [(wgt * du * dv).sum(), (wgt * dv * dv).sum()]]) / s
        np.testing.assert_allclose(moments[k], S, rtol=1e-12, atol=1e-12)
        inner = cv2.erode(own.astype(np.uint8), np.ones((3, 3), np.uint8), borderType=cv2.BORDER_CONSTANT,
                          borderValue=0).astype(bool)
        bx, by, bw, bh = regions.bbox[i]
        cut = bx <= 0 or by <= 0 or bx + bw >= gray.shape[1] or by + bh >= gray.shape[0]
        if cut or inner.sum() < 5:
            assert np.isnan(slope[k]).all()
            continue
        iy, ix = np.nonzero(inner)
        a, gu, gv = np.linalg.lstsq(np.column_stack([np.ones(len(ix)), ix - cu, iy - cv]), above[inner], rcond=None)[0]
        if a > 0:
            np.testing.assert_allclose(slope[k], (gu / a, gv / a), rtol=1e-9, atol=1e-12)
            fitted += 1
            on_line += len(set(iy.tolist())) == 1
    assert fitted > 10 and on_line >= 1            # the bar's one-line interior: least squares' own answer


@pytest.mark.parametrize("by_moments", [None, False])
def test_circularity_sums_region_by_region_equal_one_pass(monkeypatch, by_moments):
    gray = _image(3, n=120, size=(320, 240))
    binary = det.binarize(gray, 60)
    regions = det.label_regions(binary[30:200, 40:300], origin=(40, 30), image_size=(320, 240))
    assert 8 < len(regions) <= filters.SUMS_BY_REGION
    by_region = det.region_circularity(regions, by_moments)
    monkeypatch.setattr(filters, "SUMS_BY_REGION", 0)
    np.testing.assert_array_equal(det.region_circularity(regions, by_moments), by_region)


# -- fourth pass: the same numbers by fewer NumPy calls ------------------------------------------------

@pytest.mark.parametrize("seed", [0, 4])
def test_centres_without_the_weight_arrays_equal_those_from_them(seed):
    """``weighted_centroids`` by ``_weight_sums`` (uint8 weights for a whole-level background) gives the
    very numbers of the float32 weights of ``region_weights``, with and without ``symmetric_border``."""
    gray = _image(seed)
    regions, keep = det.find_candidates(gray, 60, (1, 10 ** 6))
    inside = keep[~regions.touches_border[keep]]
    assert len(inside) > 20
    patches = filters.region_weights(gray, regions, inside)
    whole = [i for i, r in zip(inside, patches) if float(r.above[0, 0]) == int(r.above[0, 0])]
    assert len(whole) > 5                                   # the uint8 path is taken
    for sym in (False, True):
        np.testing.assert_array_equal(det.weighted_centroids(gray, regions, inside, symmetric_border=sym),
                                      det.weighted_centroids(gray, regions, inside, symmetric_border=sym,
                                                             patches=patches))


def _random_cluster(rng, M, C):
    base = rng.random((M, 2)) * 100
    cent = np.vstack([base + rng.normal(0, 2, base.shape), rng.random((max(C - M, 0), 2)) * 100])
    return base, cent[rng.permutation(len(cent))][:C]


def test_thesis_choices_equal_the_distance_and_cross_product_filters():
    rng = np.random.default_rng(7)
    kept = 0
    for t in range(1500):
        M = int(rng.integers(2, 6))
        base, cent = _random_cluster(rng, M, int(rng.integers(M - 1, 10)))
        tol = float(rng.choice([0.05, 0.1, 0.3, 1.0]))
        d, s = det.marker_distances(base), det.cross_product_signs(base, 0.1)
        want = det.filter_cross_product(cent, det.filter_distance(cent, d, tol), s)
        got = thesis_chain._thesis_choices(cent, d, tol, s)
        assert got.dtype == want.dtype and got.shape == want.shape and (got == want).all()
        kept += len(got)
    assert kept > 500


def test_signs_in_python_floats_equal_cross_product_signs():
    rng = np.random.default_rng(8)
    for t in range(500):
        p = rng.normal(0, 50, (int(rng.integers(1, 7)), 2))
        if t % 5 == 0 and len(p) >= 3:
            p[2] = p[0] + (p[1] - p[0]) * 2.0            # a straight triple: sign 0
        want = det.cross_product_signs(p, 0.1)
        got = thesis_chain._signs_of(p.tolist(), 0.1)
        assert got.dtype == want.dtype and np.array_equal(got, want)


@pytest.mark.parametrize("crop", [(0, 0, 200, 150), (17, 9, 150, 120), (40, 0, 200, 100)])
def test_candidates_kept_in_python_equal_the_array_filters(monkeypatch, crop):
    gray = _image(5, n=80)
    u0, v0, u1, v1 = crop
    args = (gray[v0:v1, u0:u1], (u0, v0), (200, 150), 60, (3, 40))
    monkeypatch.setattr(filters, "KEEP_IN_PYTHON", 10 ** 6)
    regions, keep = filters._candidates_in(*args, None)
    assert 0 < len(keep) < len(regions)
    monkeypatch.setattr(filters, "KEEP_IN_PYTHON", -1)
    assert np.array_equal(filters._candidates_in(*args, None)[1], keep)
