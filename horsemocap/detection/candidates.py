"""Candidate marker regions of one camera's image, and their centres freed of uneven light.

The multi-view identification (:mod:`~horsemocap.detection.tracker3d`) looks
for the markers among the *candidates* of every camera: the regions of a gray
image above the threshold ``l`` (thesis eq. 4.5), 8-connected (4.5.2), in the
area range (4.5.3) and round enough (circularity by geometric moments, seed
000), each with its centre (intensity-weighted by default).

- :func:`frame_candidates`: the candidates of one image or of a crop of it
  (the tracker's search around a predicted marker);
- :func:`whole_frame_search`, :func:`whole_frame_candidates`: the candidates
  of whole images, labelled only in crops around their bright pixels (the
  search for the marker set without a prediction);
- :func:`candidate_area_range`, :func:`candidate_min_circularity`: the
  candidate rules a camera's :class:`~horsemocap.detection.DetectionParams`
  give;
- :func:`correct_light`: a marker's centres freed of the pull of uneven light,
  pooled over its track.

Example
-------
>>> import numpy as np
>>> gray = np.zeros((60, 80), np.uint8)
>>> gray[20:25, 30:35] = 200
>>> cands = frame_candidates(gray, 100)
>>> len(cands), cands.centre.round(1).tolist()
(1, [[32.0, 22.0]])
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .base import (AUTO_MIN_CIRCULARITY, GENERIC_AREA, GENERIC_MAX_AREA_FRACTION, DetectionParams, Regions)
from .filters import clip_crop, find_candidates, light_terms, region_circularity, region_weights, weighted_centroids
from .thresholds import bright_crops, connected_components, region_order_key

__all__ = [
    "MAX_CANDIDATES_PER_CAMERA", "LIGHT_WINDOW", "Candidates", "frame_candidates", "whole_frame_search",
    "whole_frame_candidates", "whole_frame_count", "WholeFrameSearches", "ClockFollowingFrames", "source_frame",
    "candidate_area_range", "candidate_min_circularity",
    "correct_light",
]

#: The most candidates kept per camera and image (the largest).
MAX_CANDIDATES_PER_CAMERA = 24
#: Up to this many regions in a crop, the whole-frame search filters them in Python (NumPy's per-call cost
#: is larger for a few).
FEW_REGIONS = 16
#: Frames on either side whose light slopes are pooled (:func:`correct_light`).
LIGHT_WINDOW = 100


# --------------------------------------------------------------------------
# candidates of one image
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class Candidates:
    """Marker-like regions of one image (thesis 4.5.2-4.5.3 and circularity).

    Attributes
    ----------
    centre : ndarray (K, 2)
        ``(u, v)`` intensity-weighted (or binary) centres, full-image pixels.
    area : ndarray (K,)
        Pixel count.
    cut : ndarray (K,) bool
        Region touching the image border (its centre from the part symmetric
        about it; used only as described in :func:`_whole_inside`).
    slope, moments : ndarray (K, 2) and (K, 2, 2), optional
        The light across the region and its weights' second moments
        (:func:`~horsemocap.detection.filters.light_terms`), when asked for.
    """

    centre: np.ndarray
    area: np.ndarray
    cut: np.ndarray
    slope: np.ndarray | None = None
    moments: np.ndarray | None = None

    def __len__(self):
        return len(self.area)


def frame_candidates(gray: np.ndarray, threshold: int, area_range=(GENERIC_AREA[0], None),
                     min_circularity: float | None = AUTO_MIN_CIRCULARITY, crop=None,
                     centroid: str = "weighted", max_count: int = MAX_CANDIDATES_PER_CAMERA,
                     light: bool = False) -> Candidates:
    """Candidate marker regions of one gray image, or of a crop of it.

    Threshold ``l`` (eq. 4.5), 8-connected labels (4.5.2), area range (4.5.3),
    circularity ``>= min_circularity`` (seed 000), at most ``max_count`` of the
    largest. Regions cut by the image border are kept with ``cut=True`` (the
    tracker needs to know a marker is there but unusable); regions cut by
    the crop edge are dropped (:func:`~horsemocap.detection.find_candidates`).

    Parameters
    ----------
    gray : (h, w) uint8 full image
    threshold : int
    area_range : (min, max) pixels; ``max=None``: 0.5 % of the image
    min_circularity : float or None
    crop : (u0, v0, u1, v1) or None
    centroid : {"weighted", "binary"}

    light : bool
        Also measure the light across each region (``slope``, ``moments``;
        :func:`correct_light`).

    Returns
    -------
    Candidates

    Example
    -------
    >>> import numpy as np
    >>> gray = np.zeros((60, 80), np.uint8)
    >>> gray[20:25, 30:35] = 200
    >>> gray[40:43, 0:3] = 200                        # cut by the image border
    >>> cands = frame_candidates(gray, 100)
    >>> cands.area.tolist(), cands.cut.tolist()
    ([25.0, 9.0], [False, True])
    """
    regions, keep = find_candidates(gray, threshold, (area_range[0], _max_area(area_range, gray)), None, crop=crop)
    return _candidates_of(gray, regions, keep, min_circularity, centroid, max_count, light)


def _max_area(area_range, gray) -> float:
    """The area range's upper end; None: 0.5 % of the image (at least 50 pixels)."""
    H, W = gray.shape[:2]
    return area_range[1] if area_range[1] is not None else max(50.0, GENERIC_MAX_AREA_FRACTION * H * W)


def _candidates_of(gray, regions, keep, min_circularity, centroid: str, max_count: int, light: bool) -> Candidates:
    """The labelled regions ``keep`` (area already filtered) of ``gray`` as :class:`Candidates`:
    circularity, at most ``max_count`` of the largest, their centres (and light, when asked)."""
    if len(keep) and min_circularity is not None:
        circ = region_circularity(regions.subset(keep))
        keep = keep[circ >= min_circularity]
    if len(keep) > max_count:
        keep = keep[np.argsort(-regions.area[keep], kind="stable")[:max_count]]
    if len(keep) == 0:
        return Candidates(np.zeros((0, 2)), np.zeros(0), np.zeros(0, bool))
    slope = moments = None
    if centroid == "binary":
        centre = regions.centroid[keep].astype(float)
    else:
        u0, v0 = regions.origin
        sub = gray[v0:v0 + regions.labels.shape[0], u0:u0 + regions.labels.shape[1]]
        patches = region_weights(sub, regions, keep, 2) if light else None   # made once for both
        centre = weighted_centroids(sub, regions, keep, symmetric_border=True, patches=patches)
        if light:
            slope, moments = light_terms(sub, regions, keep, patches=patches)
    return Candidates(centre, regions.area[keep].astype(float), regions.touches_border[keep].copy(), slope, moments)



# --------------------------------------------------------------------------
# the candidate rules of a camera's parameters
# --------------------------------------------------------------------------
def candidate_area_range(params: DetectionParams) -> tuple:
    """The area range ``(min, max)`` (pixels) of a camera's candidates.

    ``params.area_min`` (default ``GENERIC_AREA[0]``, 3 px) and
    ``params.area_max`` (None: 0.5 % of the image, decided per image by
    :func:`frame_candidates`).

    Example
    -------
    >>> from horsemocap.detection import DetectionParams
    >>> candidate_area_range(DetectionParams()), candidate_area_range(DetectionParams(area_min=5, area_max=80))
    ((3, None), (5, 80))
    """
    return (params.area_min if params.area_min is not None else GENERIC_AREA[0], params.area_max)


def candidate_min_circularity(params: DetectionParams) -> float:
    """The smallest circularity of a camera's candidates: ``params.min_circularity``, default
    ``AUTO_MIN_CIRCULARITY`` (0.5).

    Example
    -------
    >>> from horsemocap.detection import DetectionParams
    >>> candidate_min_circularity(DetectionParams()), candidate_min_circularity(DetectionParams(min_circularity=0.7))
    (0.5, 0.7)
    """
    return params.min_circularity if params.min_circularity is not None else AUTO_MIN_CIRCULARITY


# --------------------------------------------------------------------------
# candidates of whole images (no prediction)
# --------------------------------------------------------------------------
def whole_frame_candidates(frames: dict, k: int, cams, thr: dict, cparams: dict) -> dict:
    """Candidates of frame ``k`` of every camera, searched in the whole image (no prediction).

    Parameters
    ----------
    frames : dict camera -> sequence of (h, w) uint8 gray frames
    k : int
    cams : sequence of camera names
    thr : dict camera -> threshold
    cparams : dict camera -> DetectionParams (:func:`candidate_area_range`,
        :func:`candidate_min_circularity`, ``centroid``)

    Returns
    -------
    dict camera -> Candidates (:func:`whole_frame_search`)
    """
    return {c: whole_frame_search(frames[c][k], thr[c], candidate_area_range(cparams[c]),
                                  candidate_min_circularity(cparams[c]), centroid=cparams[c].centroid)
            for c in cams}


class ClockFollowingFrames:
    """A camera's synchronised frames read at the reference camera's instants when its clock drifts.

    A free-running camera whose clock runs at another rate gains or loses
    whole frames against the reference camera over a long recording: at
    synchronised frame ``k`` the frame that keeps its delay where it was at
    frame 0 (its phase there, within a frame) is ``k - gained[k]``
    (:func:`horsemocap.subframe.whole_frames_gained`). Frame ``k`` of this
    sequence is that frame of ``frames``, so the delay between the frames
    compared at one instant stays within half a frame of the phase at frame 0
    however long the record; a frame before the first or after the last of
    ``frames`` is black (nothing found there). :meth:`source_index` says
    which frame of ``frames`` it is, :meth:`holds` whether it is one.

    Examples
    --------
    >>> base = [np.full((2, 2), i, np.uint8) for i in range(5)]
    >>> seq = ClockFollowingFrames(base, np.array([0, 0, 1, 1, 1]))
    >>> [int(seq[k][0, 0]) for k in range(5)], seq.source_index(4)
    ([0, 1, 1, 2, 3], 3)
    >>> int(ClockFollowingFrames(base, np.array([0, 0, 0, -1, -1]))[4].max())     # past the last frame: black
    0
    """

    def __init__(self, frames, gained):
        self.frames = frames
        self._black = None
        self.gained = np.asarray(gained, int)
        if self.gained.shape != (len(frames),):
            raise ValueError(f"ClockFollowingFrames: gained must have one entry per frame ({len(frames)}), "
                             f"got shape {self.gained.shape}")

    def __len__(self) -> int:
        return len(self.frames)

    def source_index(self, k: int) -> int:
        """The frame of the wrapped sequence that frame ``k`` (``-1`` the last, as a list's) is; may lie outside it."""
        k = int(k) + (len(self) if int(k) < 0 else 0)
        return k - int(self.gained[k])

    def holds(self, k: int) -> bool:
        """Is frame ``k`` one of the wrapped sequence's (not black)?"""
        return 0 <= self.source_index(k) < len(self.frames)

    def __getitem__(self, k):
        if self.holds(k):
            return self.frames[self.source_index(k)]
        if self._black is None:          # read once: a video's frame 0 may be a seek away
            self._black = np.zeros_like(np.asarray(self.frames[0]))
        return self._black

    def close(self) -> None:
        close = getattr(self.frames, "close", None)
        if close is not None:
            close()


def source_frame(seq, k: int) -> tuple:
    """``(sequence, index)``: the sequence and index a frame ``k`` of ``seq`` is read from (the wrapped sequence
    of a :class:`ClockFollowingFrames`, else ``seq`` and ``k`` themselves).

    Examples
    --------
    >>> base = [0, 1, 2]
    >>> source_frame(ClockFollowingFrames(base, [0, 1, 1]), 2) == (base, 1), source_frame(base, 2) == (base, 2)
    (True, True)
    """
    if isinstance(seq, ClockFollowingFrames):
        return seq.frames, seq.source_index(k)
    return seq, int(k)


class WholeFrameSearches:
    """The whole-frame searches of one recording, kept for every identification of it.

    The detect step identifies the markers several times when the cameras
    run free (trial phases, rounds at the phases the markers measured);
    each time the same frames are searched whole, for the anchor and to
    take up lost markers, while only the phases differ. A search depends on
    the image (the camera and the frame of its video), the threshold and
    the candidates' rules: kept by those, each is made once.
    :meth:`of_offsets` gives the search of :func:`whole_frame_candidates`
    for sequences that start at given frames of the videos.

    Examples
    --------
    >>> from horsemocap.detection import DetectionParams
    >>> gray = np.zeros((40, 40), np.uint8)
    >>> gray[10:14, 10:14] = 255
    >>> searches = WholeFrameSearches()
    >>> search = searches.of_offsets({"a": 5})
    >>> args = ({"a": [gray]}, 0, ["a"], {"a": 100}, {"a": DetectionParams(area_min=4)})
    >>> first = search(*args)
    >>> search(*args)["a"] is first["a"], searches.count
    (True, 1)
    """

    def __init__(self):
        self._found: dict = {}

    @property
    def count(self) -> int:
        """Searches made (one per camera and frame of its video, threshold and rules)."""
        return len(self._found)

    def of_offsets(self, offsets: dict):
        """:func:`whole_frame_candidates` of sequences whose frame ``k`` of camera ``c`` is its video's frame
        ``offsets[c] + k`` (of a :class:`ClockFollowingFrames`, the frame it reads: :func:`source_frame`), each
        search made once."""
        def search(frames: dict, k: int, cams, thr: dict, cparams: dict) -> dict:
            out = {}
            for c in cams:
                cp = cparams[c]
                rules = (candidate_area_range(cp), candidate_min_circularity(cp), cp.centroid)
                seq, j = source_frame(frames[c], k)
                if not 0 <= j < len(seq):       # a black frame past the video's: not one of its frames, not kept
                    out[c] = whole_frame_search(frames[c][k], thr[c], *rules[:2], centroid=rules[2])
                    continue
                key = (c, int(offsets[c]) + j, thr[c], rules)
                if key not in self._found:
                    self._found[key] = whole_frame_search(frames[c][k], thr[c], *rules[:2], centroid=rules[2])
                out[c] = self._found[key]
            return out
        return search


def whole_frame_search(gray: np.ndarray, threshold: int, area_range, min_circularity, centroid: str = "weighted",
                       max_count: int = MAX_CANDIDATES_PER_CAMERA) -> Candidates:
    """:func:`frame_candidates` of a whole image, labelled in crops around its bright pixels.

    The same candidates (same regions, same order, same centres), without a
    label image of the whole frame: each crop of
    :func:`~horsemocap.detection.thresholds.bright_crops` (padded groups of
    bright 8 x 8 blocks; in a frame without the horse, most of a long
    session, only glints, lamps and rails are bright) is labelled alone
    (:func:`_bright_regions`); its regions in the area range get their
    circularity (by the method the whole image's would:
    :func:`~horsemocap.detection.filters.region_circularity`) and their
    centres from the crop (a weighted centre looks at most 7 px beyond its
    region, a crop holds 10); the candidates of all crops are put in the
    order OpenCV's labelling of the whole image gives them
    (:func:`~horsemocap.detection.thresholds.region_order_key`) before the
    ``max_count`` largest are kept (:func:`_crop_candidates`).

    Parameters
    ----------
    gray : (h, w) uint8 image
    threshold : int
    area_range : (min, max) pixels (``max=None``: 0.5 % of the image)
    min_circularity : float or None
    centroid : {"weighted", "binary"}
    max_count : int

    Returns
    -------
    Candidates

    Example
    -------
    >>> import numpy as np
    >>> gray = np.zeros((120, 160), np.uint8)
    >>> gray[20:25, 30:35] = gray[90:96, 120:126] = 200
    >>> whole = whole_frame_search(gray, 100, (3, None), 0.5)
    >>> same = frame_candidates(gray, 100, (3, None), 0.5)
    >>> bool(np.array_equal(whole.centre, same.centre)), len(whole)
    (True, 2)
    """
    return _crop_candidates(gray, _bright_regions(gray, threshold, area_range), min_circularity, centroid, max_count)


def whole_frame_count(gray: np.ndarray, threshold: int, area_range):
    """The regions of a whole image that can be markers, counted before the shape rule, and their search.

    Parameters
    ----------
    gray : (h, w) uint8 image
    threshold : int
    area_range : (min, max) pixels (``max=None``: 0.5 % of the image)

    Returns
    -------
    count : int
        Regions in the area range not touching the image border.
    search : :class:`WholeFrameSearch`
        ``search(min_circularity, centroid, max_count) -> Candidates``:
        :func:`whole_frame_search`'s candidates of the same image, from the
        same labels (made once); ``search.whole_count(min_circularity,
        max_count)``: how many of them the border does not cut, without
        their centres.
    """
    H, W = gray.shape[:2]
    components = _bright_components(gray, threshold, area_range)
    count = 0
    for u0, v0, _, _, st, _, keep in components:          # the count from the labelling's boxes alone
        if len(keep) <= FEW_REGIONS:                      # a few regions (an empty arena): in Python
            count += sum(1 for x, y, w, h, _ in st[1:][keep].tolist()
                         if x + u0 > 0 and y + v0 > 0 and x + u0 + w < W and y + v0 + h < H)
        else:
            x, y, w, h = st[1:, :4][keep].T
            x, y = x + u0, y + v0
            count += int(np.count_nonzero((x > 0) & (y > 0) & (x + w < W) & (y + h < H)))
    return count, WholeFrameSearch(gray, components)


def _bright_regions(gray: np.ndarray, threshold: int, area_range) -> list:
    """The regions in the area range of each crop around the bright pixels (:class:`Regions` per crop)."""
    H, W = gray.shape[:2]
    return _regions_of(_bright_components(gray, threshold, area_range), W, H)


def _bright_components(gray: np.ndarray, threshold: int, area_range) -> list:
    """Each crop around the bright pixels that holds a region in the area range, labelled:
    ``(u0, v0, n, labels, stats, centres, keep)`` (:func:`connected_components` of the crop at ``(u0, v0)``,
    ``keep`` the indices in ``stats[1:]`` of its regions in the range)."""
    amin, amax = area_range[0], _max_area(area_range, gray)
    binary, boxes = bright_crops(gray, threshold)
    out = []
    for u0, v0, u1, v1 in boxes:
        n, lab, st, ce = connected_components(binary[v0:v1, u0:u1])
        if n - 1 <= FEW_REGIONS:                          # a few regions: in Python
            keep = np.array([i for i, a in enumerate(st[1:, 4].tolist()) if amin <= a <= amax], np.intp)
        else:
            area = st[1:, 4]
            keep = np.flatnonzero((area >= amin) & (area <= amax))
        if len(keep):
            out.append((u0, v0, n, lab, st, ce, keep))
    return out


def _regions_of(components: list, W: int, H: int) -> list:
    """:class:`Regions` (full-image boxes and centres) of the crops' regions :func:`_bright_components` kept."""
    crops = []
    for u0, v0, n, lab, st, ce, keep in components:
        area = st[1:, 4].astype(np.int64)
        bbox = st[1:, :4].astype(np.int64) + np.array([u0, v0, 0, 0])
        # OpenCV's centre is (sum of coordinates) / area: the sums are integers, recovered exactly
        cents = (np.rint(ce[1:] * area[:, None]) + np.array([u0, v0]) * area[:, None]) / area[:, None]
        crops.append(Regions(labels=lab, ids=np.arange(1, n), area=area, bbox=bbox, centroid=cents,
                             origin=(u0, v0), image_size=(W, H)).subset(keep))
    return crops


def _crop_candidates(gray: np.ndarray, crops: list, min_circularity, centroid: str, max_count: int) -> Candidates:
    """:class:`Candidates` of the regions of :func:`_bright_regions`, in the whole image's labelling order."""
    return _selected_candidates(gray, _crop_selection(gray, crops, min_circularity, max_count), centroid)


def _crop_selection(gray: np.ndarray, crops: list, min_circularity, max_count: int):
    """The candidates :func:`_crop_candidates` keeps, before their centres: ``(crops, crop_of, in_crop, order)``
    (the round regions of each crop, each candidate's crop and index in it, the kept ones in the whole image's
    labelling order), or None when none is left."""
    W = gray.shape[1]
    if min_circularity is not None and crops:
        by_moments = sum(len(r) for r in crops) <= 8
        crops = [r.subset(region_circularity(r, by_moments) >= min_circularity) for r in crops]
    crops = [r for r in crops if len(r)]
    if not crops:
        return None
    crop_of = np.concatenate([np.full(len(r), ci) for ci, r in enumerate(crops)])
    in_crop = np.concatenate([np.arange(len(r)) for r in crops])
    key = np.array([region_order_key(r.labels, rid, y, x, w, r.origin, W) for r in crops
                    for rid, (x, y, w, _) in zip(r.ids.tolist(), r.bbox.tolist())])
    order = np.argsort(key, kind="stable")
    if len(order) > max_count:
        areas = np.concatenate([r.area for r in crops])
        order = order[np.argsort(-areas[order], kind="stable")[:max_count]]
    return crops, crop_of, in_crop, order


def _selection_whole_count(selection) -> int:
    """Candidates of a :func:`_crop_selection` not cut by the image border."""
    if selection is None:
        return 0
    crops, crop_of, in_crop, order = selection
    return sum(int(np.count_nonzero(~r.touches_border[in_crop[order[crop_of[order] == ci]]]))
               for ci, r in enumerate(crops))


def _selected_candidates(gray: np.ndarray, selection, centroid: str) -> Candidates:
    """:class:`Candidates` of a :func:`_crop_selection`, with their centres."""
    if selection is None:
        return Candidates(np.zeros((0, 2)), np.zeros(0), np.zeros(0, bool))
    crops, crop_of, in_crop, order = selection
    centre = np.empty((len(order), 2))
    area = np.empty(len(order))
    cut = np.empty(len(order), bool)
    for ci, r in enumerate(crops):
        at = np.flatnonzero(crop_of[order] == ci)
        if len(at) == 0:
            continue
        idx = in_crop[order[at]]
        if centroid == "binary":
            centre[at] = r.centroid[idx]
        else:
            (u0, v0), (h, w) = r.origin, r.labels.shape
            centre[at] = weighted_centroids(gray[v0:v0 + h, u0:u0 + w], r, idx, symmetric_border=True)
        area[at] = r.area[idx]
        cut[at] = r.touches_border[idx]
    return Candidates(centre, area, cut)


class WholeFrameSearch:
    """:func:`whole_frame_search` of one image from labels made once (:func:`whole_frame_count`).

    Called as ``search(min_circularity, centroid, max_count)``: the
    :class:`Candidates`. :meth:`whole_count` gives how many of them are not
    cut by the image border without computing their centres (the centres
    are computed once, on the call).
    """

    def __init__(self, gray: np.ndarray, components: list):
        self.gray, self.components = gray, components
        self._selections: dict = {}

    def _selection(self, min_circularity, max_count: int):
        rule = (min_circularity, int(max_count))
        if rule not in self._selections:
            H, W = self.gray.shape[:2]
            self._selections[rule] = _crop_selection(self.gray, _regions_of(self.components, W, H),
                                                     min_circularity, max_count)
        return self._selections[rule]

    def whole_count(self, min_circularity, max_count: int) -> int:
        """The candidates (``min_circularity``, ``max_count`` as for the call) not cut by the image border."""
        return _selection_whole_count(self._selection(min_circularity, max_count))

    def __call__(self, min_circularity, centroid: str, max_count: int) -> Candidates:
        return _selected_candidates(self.gray, self._selection(min_circularity, max_count), centroid)


# --------------------------------------------------------------------------
# uneven light
# --------------------------------------------------------------------------
def correct_light(marker_px: np.ndarray, slope: np.ndarray, moments: np.ndarray, window: int = LIGHT_WINDOW,
                  min_count: int = 5) -> np.ndarray:
    """Centres of one camera freed of the pull of uneven light, pooled over each marker's track.

    A marker lit unevenly (brightness ``1 + s . (p - p0)`` across it) has its
    weighted centre ``S s`` from its disc's centre (``S`` the weights' second
    moments; :func:`~horsemocap.detection.filters.light_terms`), the same in
    every frame of the marker's track while the lamps and the tape do not
    change. One frame's slope is too
    noisy to correct that frame alone (it would add more noise to the
    centres, and to the accelerations, than the bias it removes); the median
    slope of the marker's frames within ``window`` frames (at least
    ``min_count`` of them, else the nearest ``min_count``) is precise. The
    moments are pooled alike (their median over the same frames): the
    correction is the marker's steady offset, which hardly changes from
    frame to frame, so that it adds no motion of its own (with each frame's
    own moments the offset would follow the streak's length through the
    stride, and the slope, taken from a streak's interior, is not exact for
    a streak longer than the marker). Fewer than ``min_count`` slopes in the
    record: unchanged.

    Parameters
    ----------
    marker_px : (n, M, 2)
    slope : (n, M, 2)
        Per frame and marker (NaN: not measured).
    moments : (n, M, 2, 2)

    Returns
    -------
    (n, M, 2) corrected centres (NaN where ``marker_px`` is NaN).
    """
    out = np.array(marker_px, float, copy=True)
    for m in range(out.shape[1]):
        have = np.flatnonzero(np.all(np.isfinite(slope[:, m]), axis=1))
        if len(have) < min_count:
            continue
        with_s = np.flatnonzero(np.all(np.isfinite(moments[:, m]), axis=(1, 2)))
        if len(with_s) == 0:
            continue
        for k in np.flatnonzero(np.all(np.isfinite(out[:, m]), axis=1)):
            near = have[np.abs(have - k) <= window]
            if len(near) < min_count:
                near = have[np.argsort(np.abs(have - k), kind="stable")[:min_count]]
            near_s = with_s[np.abs(with_s - k) <= window]
            if len(near_s) == 0:
                near_s = with_s[np.argsort(np.abs(with_s - k), kind="stable")[:min_count]]
            S = np.median(moments[near_s, m], axis=0)
            out[k, m] = out[k, m] - S @ np.median(slope[near, m], axis=0)
    return out

