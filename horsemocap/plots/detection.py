"""Figures of marker detection (thesis Figures 4.11, 4.15, 8.7-8.8)."""
from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.patches import Rectangle

from ._layout import label_away_from_centre

__all__ = ["plot_detection_stages", "plot_marker_track", "plot_centroid_errors", "plot_identification",
           "plot_filtered_images", "plot_filter_removals", "filter_removals"]

FILTER_COLOURS = {"area": "tab:red", "window": "tab:orange", "distance": "magenta",
                  "cross product": "tab:blue", "marker": "lime"}


def _zoom(ax, box, shape=None):
    if box is not None:
        u0, v0, u1, v1 = box
        if shape is not None:          # stay inside the image
            u0, v0 = max(u0, -0.5), max(v0, -0.5)
            u1, v1 = min(u1, shape[1] - 0.5), min(v1, shape[0] - 0.5)
        ax.set_xlim(u0, u1)
        ax.set_ylim(v1, v0)


def plot_detection_stages(image, stages: dict, window=None, center=None, zoom=None, fig=None):
    """The six stages of thesis Figure 4.15 for one frame.

    Parameters
    ----------
    image : the original RGB (or gray) frame
    stages : dict from :func:`horsemocap.detection.filter_stages`
    window, center : window size ``(W_du, W_dv)`` and centre ``W_c(k)`` (drawn)
    zoom : ``(u0, v0, u1, v1)`` region shown in panels iii-vi (None = whole image)

    Returns
    -------
    matplotlib Figure
    """
    fig = fig or plt.figure(figsize=(12, 7))
    axes = fig.subplots(2, 3)
    r = stages["regions"]
    img = np.asarray(image)
    axes[0, 0].imshow(img, cmap=None if img.ndim == 3 else "gray")
    axes[0, 0].set_title("i) original image")
    axes[0, 1].imshow(stages["binary"], cmap="gray")
    axes[0, 1].set_title(f"ii) binary (eq. 4.5), {len(r)} regions")
    ax = axes[0, 2]
    ax.imshow(stages["binary"], cmap="gray")
    for i in range(len(r)):
        ax.plot(*r.centroid[i], "r+", ms=4)
    ax.set_title("iii) labelled regions and centres")
    _zoom(ax, zoom, img.shape)
    for ax, key, title in ((axes[1, 0], "area_ok", "iv) area filtered"),
                           (axes[1, 1], "window_ok", "v) regions in the window")):
        keep = np.zeros(len(r) + 1, bool)
        keep[r.ids[stages[key]]] = True
        ax.imshow(keep[r.labels], cmap="gray")
        ax.set_title(f"{title}: {len(stages[key])}")
        _zoom(ax, zoom, img.shape)
    if window is not None and center is not None:
        w = np.asarray(window, float)
        c = np.asarray(center, float)
        axes[1, 1].add_patch(Rectangle(c - w / 2, w[0], w[1], fill=False, ec="c", lw=1.2))
        axes[1, 1].plot(*c, "cx")
    ax = axes[1, 2]
    ax.imshow(img, cmap=None if img.ndim == 3 else "gray")
    if stages.get("marker_px") is not None:
        px = stages["marker_px"]
        ax.plot(px[:, 0], px[:, 1], "o", mfc="none", mec="lime", ms=10)
        for m, (u, v) in enumerate(px):
            ax.annotate(str(m + 1), (u, v), xytext=(6, -6), textcoords="offset points", color="lime")
    n_kept = 0 if stages.get("kept") is None else len(stages["kept"])
    ax.set_title(f"vi) markers after distance + cross product ({n_kept} choice)")
    _zoom(ax, zoom, img.shape)
    for a in axes.ravel():
        a.set_xticks([])
        a.set_yticks([])
    fig.tight_layout()
    return fig


def plot_marker_track(track, truth=None, ax=None):
    """Image coordinates of each marker over the frames (``PM``, Figure 4.14).

    Frames where a marker is missing are marked at the bottom with the
    first letter of the reason (o occluded, l left_image, p partly_occluded,
    a ambiguous). With ``truth`` (frames, markers, 2) the truth is drawn thin.
    """
    if ax is None:
        _, ax = plt.subplots(2, 1, figsize=(10, 5), sharex=True)
    px = track.marker_px
    k = np.arange(px.shape[0])
    for c, (a, name) in enumerate(zip(ax, ("u (px)", "v (px)"))):
        for m in range(px.shape[1]):
            line, = a.plot(k, px[:, m, c], ".-", ms=3, lw=1, label=f"marker {m + 1}")
            if truth is not None:
                a.plot(k, truth[: len(k), m, c], "-", lw=0.6, color=line.get_color(), alpha=0.6)
            miss = np.flatnonzero(track.reason[:, m] != "")
            if len(miss):
                y0 = np.nanmin(px[..., c]) if np.isfinite(px[..., c]).any() else 0
                for j in miss:
                    a.annotate(track.reason[j, m][0], (j, y0), color=line.get_color(), fontsize=6,
                               ha="center")
        a.set_ylabel(name)
    ax[0].legend(fontsize=8, ncol=px.shape[1])
    ax[-1].set_xlabel("frame (camera's own numbering)")
    return ax


def plot_centroid_errors(errors: dict, ax=None, bins=None):
    """Histograms of centre errors in pixels, one per entry of ``errors``."""
    if ax is None:
        _, ax = plt.subplots(figsize=(6, 3.5))
    allv = np.concatenate([np.asarray(v, float).ravel() for v in errors.values()])
    allv = allv[np.isfinite(allv)]
    bins = bins if bins is not None else np.linspace(0, max(1.0, np.percentile(allv, 99.5) if allv.size else 1), 40)
    for name, v in errors.items():
        v = np.asarray(v, float).ravel()
        v = v[np.isfinite(v)]
        ax.hist(v, bins=bins, histtype="step", lw=1.5,
                label=f"{name}: median {np.median(v):.3f}, p99 {np.percentile(v, 99):.3f} px")
    ax.set_xlabel("centre error (px)")
    ax.set_ylabel("count")
    ax.legend(fontsize=8)
    return ax


def plot_identification(images: dict, candidates: dict, views, fit, zoom=None, fig=None):
    """One frame identified by all cameras together, one panel per camera.

    Every candidate region is drawn: a grey ring when no other camera sees a
    point there (a glint, a reflection), an orange square when it is part of a
    3D point consistent in two or more cameras that does not fit the static
    shot's marker shape (a stirrup, a buckle), a labelled green cross for the
    markers.

    Parameters
    ----------
    images : dict camera -> gray or RGB frame
    candidates : dict camera -> :class:`~horsemocap.detection.candidates.Candidates`
    views : :class:`~horsemocap.detection.matching.ViewPoints`
    fit : :class:`~horsemocap.detection.marker_model.ModelFit` or None
    zoom : (u0, v0, u1, v1) per camera (dict) or one box, optional

    Returns
    -------
    matplotlib Figure
    """
    cams = list(views.cameras)
    fig = fig or plt.figure(figsize=(4.2 * len(cams), 3.8))
    axes = fig.subplots(1, len(cams), squeeze=False)[0]
    markers = set(np.asarray(fit.assignment).tolist()) if fit is not None else set()
    for i, (ax, cam) in enumerate(zip(axes, cams)):
        img = np.asarray(images[cam])
        ax.imshow(img, cmap=None if img.ndim == 3 else "gray")
        cand = candidates[cam]
        in3d = set(views.index[:, i][views.index[:, i] >= 0].tolist())
        alone = [j for j in range(len(cand)) if j not in in3d]
        if alone:
            ax.scatter(*cand.centre[alone].T, s=60, facecolors="none", edgecolors="0.6", lw=1,
                       label="seen by this camera only")
        other = [views.index[p, i] for p in range(len(views)) if p not in markers and views.index[p, i] >= 0]
        if other:
            ax.scatter(*cand.centre[other].T, s=60, marker="s", facecolors="none", edgecolors="tab:orange",
                       lw=1.5, label="consistent in 3D, not the marker shape")
        if fit is not None:
            seen = [(m, views.index[p, i]) for m, p in enumerate(fit.assignment) if views.index[p, i] >= 0]
            for m, j in seen:
                ax.plot(*cand.centre[j], "+", color="lime", ms=12, mew=2,
                        label="marker (rigid model)" if m == 0 else None)
            label_away_from_centre(ax, [cand.centre[j] for _, j in seen], [f"marker{m + 1}" for m, _ in seen],
                                   "lime", fontsize=8, bbox=dict(boxstyle="round,pad=0.15", fc="black", ec="none",
                                                                 alpha=0.6))
        box = zoom.get(cam) if isinstance(zoom, dict) else zoom
        _zoom(ax, box, img.shape)
        ax.set_title(cam)
        ax.set_xticks([])
        ax.set_yticks([])
    handles, labels = [], []
    for ax in axes:
        for h, l in zip(*ax.get_legend_handles_labels()):
            if l not in labels:
                handles.append(h)
                labels.append(l)
    fig.legend(handles, labels, loc="lower center", ncol=3, fontsize=8)
    fig.tight_layout(rect=(0, 0.08, 1, 1))
    return fig


def plot_filtered_images(images, threshold: int, area_range=None, marker_px=None, labels=None, titles=None,
                         zoom=None, fig=None):
    """The thesis' image figures (8.3, 8.4, 8.7, 8.11, 8.21): originals above, filtered below.

    Top row: the original image with the markers found circled and labelled;
    bottom row: the black-and-white image of the threshold (eq. 4.5) and, if
    ``area_range`` is given, only the regions of that area (4.5.2), i.e. what
    the thesis' user saw after typing the level and the area range.

    Parameters
    ----------
    images : list of (h, w, 3) or (h, w) images
    threshold : int
        Gray level ``l`` (eq. 4.5).
    area_range : (min, max) pixels, optional
        Keep only regions of that area in the bottom row.
    marker_px : list of (M, 2) arrays (one per image) or None
        Marker centres to draw (NaN rows skipped).
    labels : list of str, optional
        One label per marker (default ``1..M``).
    titles : list of str, optional
        One per image.
    zoom : (u0, v0, u1, v1) or "markers", optional
        Region shown (the thesis crops its figures); ``"markers"``: the
        markers' bounding box with a margin of 8 % of the image width.
    """
    from ..detection import binarize, filter_area, label_regions, to_gray

    images = list(images)
    n = len(images)
    if isinstance(zoom, str):
        if zoom != "markers":
            raise ValueError(f"zoom: expected (u0, v0, u1, v1), 'markers' or None, got {zoom!r}")
        pts = np.vstack([np.atleast_2d(np.asarray(p, float)) for p in (marker_px or []) if p is not None]
                        or [np.full((1, 2), np.nan)])
        pts = pts[np.all(np.isfinite(pts), axis=1)]
        if len(pts):
            m = 0.08 * np.asarray(images[0]).shape[1]
            zoom = (pts[:, 0].min() - m, pts[:, 1].min() - m, pts[:, 0].max() + m, pts[:, 1].max() + m)
        else:
            zoom = None
    fig = fig or plt.figure(figsize=(min(3.2 * n, 16), 5.6) if n > 1 else (11, 4.6))
    axs = np.asarray(fig.subplots(2, n, squeeze=False)) if n > 1 else np.asarray(fig.subplots(1, 2)).reshape(2, 1)
    for i, img in enumerate(images):
        img = np.asarray(img)
        top, bottom = axs[0, i], axs[1, i]
        top.imshow(img, cmap=None if img.ndim == 3 else "gray")
        binary = binarize(to_gray(img), int(threshold))
        if area_range is not None:
            r = label_regions(binary)
            keep = np.zeros(len(r) + 1, bool)
            keep[r.ids[np.flatnonzero(filter_area(r.area, area_range[0], area_range[1]))]] = True
            binary = keep[r.labels]
        bottom.imshow(binary, cmap="gray")
        if marker_px is not None and marker_px[i] is not None:
            px = np.atleast_2d(np.asarray(marker_px[i], float))
            names = labels or [str(m + 1) for m in range(len(px))]
            for (u, v), name in zip(px, names):
                if np.isfinite(u) and np.isfinite(v):
                    for ax in (top, bottom):
                        ax.plot(u, v, "o", mfc="none", mec="lime", ms=11, mew=1.2)
                    top.annotate(name, (u, v), xytext=(7, -7), textcoords="offset points", color="lime", fontsize=8)
        if titles is not None:
            top.set_title(titles[i], fontsize=9)
        what = f"threshold {int(threshold)}" + (f", area {area_range[0]:g}-{area_range[1]:g} px"
                                                 if area_range is not None else "")
        if n == 1:
            bottom.set_title(what, fontsize=9)
        for ax in (top, bottom):
            _zoom(ax, zoom, img.shape)
            ax.set_xticks([])
            ax.set_yticks([])
    if n > 1:
        fig.text(0.5, 0.01, f"bottom row: {what}", ha="center", fontsize=9)
    fig.tight_layout()
    return fig


def filter_removals(stages: dict) -> np.ndarray:
    """Which filter removed each region of one frame's :func:`~horsemocap.detection.filter_stages`.

    Returns
    -------
    ndarray (R,) of str, one per region of ``stages["regions"]``: ``"area"``
    (outside the area range, or not round enough), ``"window"`` (outside the
    sliding window), ``"distance"`` (in no choice the distance filter kept),
    ``"cross product"`` (only in choices the cross-product filter removed),
    ``"marker"`` (in a choice that is left), ``""`` when the distance filters
    were not run (no reference centres).

    Examples
    --------
    >>> import numpy as np
    >>> from horsemocap.detection import DetectionParams, filter_stages
    >>> img = np.zeros((60, 80), np.uint8)
    >>> for u, v in ((10, 10), (50, 12), (20, 40), (70, 50)):
    ...     img[v - 2:v + 3, u - 2:u + 3] = 255
    >>> img[30:32, 60:62] = 255                                 # a 4-pixel glint
    >>> p = DetectionParams(threshold=128, area_min=10, area_max=50, window=(60, 50),
    ...                     distance_tolerance=0.1)
    >>> ref = np.array([[10., 10.], [50., 12.], [20., 40.]])
    >>> stages = filter_stages(img, p, center=ref.mean(0), reference_px=ref)
    >>> [str(w) for w in filter_removals(stages)]
    ['marker', 'marker', 'area', 'marker', 'window']
    """
    r = stages["regions"]
    removed = np.full(len(r), "", dtype=object)
    removed[:] = "area"
    removed[np.asarray(stages["area_ok"], int)] = "window"
    window_ok = np.asarray(stages["window_ok"], int)
    if stages.get("choices") is None:
        removed[window_ok] = ""
        return removed.astype(str)
    removed[window_ok] = "distance"
    choices = np.asarray(stages["choices"], int)
    kept = np.asarray(stages["kept"], int)
    removed[np.unique(choices)] = "cross product"
    removed[np.unique(kept)] = "marker"
    return removed.astype(str)


def plot_filter_removals(image, stages: dict, reference_px, window=None, center=None, zoom=None, fig=None):
    """What each filter of chapter 4 removes on one frame (sections 4.5.2-4.5.5).

    Left: the frame with every white region of the threshold coloured by the
    filter that removed it (area, sliding window, distance, cross product)
    and the markers left, the window drawn. Right: the ordered choices of
    regions that the distance filter kept, each drawn as a path through its
    regions in marker order 1-2-3-..., beside the reference centres
    ``reference_px`` (the previous frame's): the cross-product filter keeps
    only the choices that turn the same way as the markers of the first frame.

    Parameters
    ----------
    image : the frame (RGB or gray)
    stages : dict from :func:`horsemocap.detection.filter_stages` (with ``reference_px``)
    reference_px : (M, 2) the centres that gave ``DM_ij``
    window, center : the sliding window's size and centre (drawn)
    zoom : ``(u0, v0, u1, v1)`` region shown on the left (None = whole image)

    Returns
    -------
    matplotlib Figure
    """
    img = np.asarray(image)
    r = stages["regions"]
    removed = filter_removals(stages)
    fig = fig or plt.figure(figsize=(12, 4.8))
    ax, ax_ch = fig.subplots(1, 2, gridspec_kw={"width_ratios": [1.5, 1]})
    ax.imshow(img, cmap=None if img.ndim == 3 else "gray", alpha=0.55)
    colour_of = np.zeros((len(r) + 1, 4))
    for name, colour in FILTER_COLOURS.items():
        colour_of[r.ids[removed == name]] = plt.matplotlib.colors.to_rgba(colour)
    ax.imshow(colour_of[r.labels])
    n_choices_removed = len(stages["choices"]) - len(stages["kept"]) if stages.get("choices") is not None else 0
    for name, colour in FILTER_COLOURS.items():
        n = int(np.sum(removed == name))
        if name == "cross product":
            label = (f"{n_choices_removed} ordered choice{'s' * (n_choices_removed != 1)} removed by the "
                     f"cross-product filter (right)" + (f", {n} regions with them" if n else ""))
        else:
            label = f"{n} " + ("markers left" if name == "marker" else f"removed by the {name} filter")
        ax.plot([], [], "s", color=colour, label=label)
    if window is not None and center is not None:
        w, c = np.asarray(window, float), np.asarray(center, float)
        ax.add_patch(Rectangle(c - w / 2, w[0], w[1], fill=False, ec="tab:orange", lw=1.2, ls="--"))
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.01), ncol=2, frameon=False)
    ax.set_title(f"{len(r)} white regions after the threshold", fontsize=10)
    _zoom(ax, zoom, img.shape)
    ax.set_xticks([])
    ax.set_yticks([])

    ref = np.asarray(reference_px, float)
    centres = r.centroid
    ax_ch.plot(*ref.T, "k-", lw=4, alpha=0.25, label="reference (previous frame)")
    for m, (u, v) in enumerate(ref):
        ax_ch.annotate(str(m + 1), (u, v), color="k", alpha=0.6, fontsize=11, ha="center", va="center")
    kept_rows = {tuple(k) for k in np.asarray(stages["kept"], int)}
    for row in np.asarray(stages["choices"], int):
        ok = tuple(row) in kept_rows
        pts = centres[row]
        colour = FILTER_COLOURS["marker"] if ok else FILTER_COLOURS["cross product"]
        ax_ch.plot(*pts.T, "-" if ok else "--", color="green" if ok else colour, lw=1.5 if ok else 2.5,
                   marker="o", mfc="none",
                   label="kept by the cross product" if ok else "removed by the cross product (turns the other way)")
        for m, (u, v) in enumerate(pts):
            ax_ch.annotate(str(m + 1), (u, v), xytext=(5, 5) if ok else (-10, -12), textcoords="offset points",
                           color="green" if ok else colour, fontsize=9)
    handles, labels = ax_ch.get_legend_handles_labels()
    unique = dict(zip(labels, handles))
    ax_ch.legend(unique.values(), unique.keys(), fontsize=7, loc="best")
    n_in = len(stages["window_ok"])
    m = len(ref)
    n_ordered = int(np.prod(np.arange(n_in - m + 1, n_in + 1))) if n_in >= m else 0
    ax_ch.set_title(f"ordered choices of {m} of the {n_in} regions: {n_ordered};\n"
                    f"distance filter kept {len(stages['choices'])}, cross product {len(stages['kept'])}",
                    fontsize=10)
    span = np.ptp(np.vstack([ref, centres[np.unique(np.asarray(stages["choices"], int))]]), axis=0) \
        if len(stages["choices"]) else np.ptp(ref, axis=0)
    ax_ch.margins(0.15)
    ax_ch.invert_yaxis()
    ax_ch.set_xlabel("u (px)")
    ax_ch.set_ylabel("v (px)" + (" (stretched: a turn keeps its sense)" if span[1] < 0.5 * span[0] else ""))
    fig.tight_layout()
    return fig
