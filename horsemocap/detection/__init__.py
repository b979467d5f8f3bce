"""Marker detection on the image plane (thesis chapter 4, Appendix A step 4).

The thesis finds the passive (retroreflective) markers of one camera with a
chain of filters, each of which is a pure function here:

1. gray conversion, eq. (4.4): :func:`to_gray` (``thresholds.py``);
2. global threshold ``l`` (``left_levelinput``), eq. (4.5): :func:`binarize`,
   with automatic starting values by Otsu's method (:func:`otsu_threshold`)
   and the three-class Otsu of seed 000 section 5.2.1 (:func:`otsu3_thresholds`,
   :func:`auto_threshold`) (``thresholds.py``);
3. 8-connected labelling and region centres (4.5.2): :func:`label_regions`
   (``filters.py``, as are steps 4 to 7);
4. area filter ``[area_min, area_max]`` (4.5.3): :func:`filter_area`, and
   the circularity filter by geometric moments of seed 000 (Hu's first
   invariant): :func:`region_circularity`, :func:`filter_circularity`;
5. the sliding window ``W_c(k+1) = W_c^e(k)`` of size ``(W_du, W_dv)``
   (4.5.4, Figure 4.11): :func:`filter_window`, :func:`window_center`;
6. the distance filter over combinations of regions, eq. (4.6)-(4.11):
   :func:`marker_distances`, :func:`filter_distance`;
7. the cross-product filter that keeps the marker order (Figure 4.13):
   :func:`cross_product_signs`, :func:`filter_cross_product`.

:func:`filter_stages` (``filters.py``) returns every stage for one frame
(Figure 4.15); :func:`weighted_centroids` and :func:`find_candidates` live
beside the filters.

The thesis' per-camera chain is ``thesis_chain.py``: :func:`detect_markers`
runs it over a sequence (the thesis' ``left_image_centroids_3.m``) and
returns ``marker_px`` (``PM_L``, Figure 4.14, transposed to the house layout
``(frames, markers, 2)``); every prompt of ``left_data_from_first_image_2.m``
is a field of :class:`DetectionParams` and is chosen automatically when left
at ``None`` (:class:`CandidateCache`, :func:`choose_markers`,
:func:`follow_cluster`, :func:`cluster_persistence`, with
:func:`valid_frames` and :func:`usable_frames`). :func:`detect_still`
(``stills.py``) serves the plumb and static stills (Appendix A steps 7a, 8a,
12a) of one camera; :func:`detect_still_views` finds them in all cameras at
once, keeping only the candidates that are projections of one 3D point in
every camera (thesis 5.1) and choosing among those the ones that look most
like markers. ``markers2d.py`` is the one writer of ``markers_2d.csv``
(:func:`marker_label`, :func:`markers_2d_csv_text`,
:func:`write_markers_2d_csv`). ``base.py`` holds what they share:
:class:`DetectionParams`, :class:`MarkerTrack`, :class:`Regions`,
:data:`REASONS`, :class:`DetectionError` and the default candidate rules.

The pipeline's default is not this per-camera chain but the multi-view
identification (seed 000 sec. 5), in five modules named by what they do:

- ``candidates.py``: the candidates of every camera (the same threshold,
  labels, area and circularity rules; :func:`frame_candidates`,
  :func:`whole_frame_search`, :func:`candidate_area_range`,
  :func:`candidate_min_circularity`) and :func:`correct_light`;
- ``matching.py``: matched across the cameras by triangulation
  (:func:`match_views`: the epipolar constraint, validation by a further
  camera);
- ``marker_model.py``: labelled by the rigid marker model of the static shot
  (:func:`fit_marker_model`: 3D side lengths and handedness;
  :func:`label_frame`);
- ``tracker3d.py``: followed in 3D with a minimum-acceleration prediction
  (:func:`identify_markers`, :class:`Identification`,
  :data:`IDENTIFICATION_REASONS`, :func:`reason_counts`);
- ``gaps.py``: short gaps bridged in 3D (:func:`bridge_gaps`,
  :func:`default_max_gap`).

A stirrup, a buckle or a glint fails the 3D tests that one camera cannot
make. The thesis' chain stays selectable (``detection_method="thesis"``).
``timeshift.py`` checks the synchronisation with the identified markers
(:func:`frame_shift_residuals`, :func:`best_frame_shift`). ``fields.py``
measures an interlaced camera's identified markers in each field
(:func:`remeasure_by_fields`, :func:`marker_in_fields`, :func:`row_aliasing`).

Pixel coordinates are ``(u, v)`` = (column, row), 0-based, with the centre of
pixel ``(i, j)`` at ``u = j, v = i`` (OpenCV convention; MATLAB's regionprops
is 1-based). Centres are, by default, intensity-weighted centroids of the gray
image above the local background (``centroid="weighted"``); the thesis'
geometric centre of the binary region is ``centroid="binary"``.

Everything runs in Python with NumPy and OpenCV; :data:`ACTIVE_PATH` (always
``"python"``) is what ``analysis.json`` records as ``software.detection_core``.

Every name below is importable from ``horsemocap.detection``.
"""
from __future__ import annotations

from .base import (AUTO_MIN_CIRCULARITY, GENERIC_AREA, REASONS, DetectionError, DetectionParams, MarkerTrack,
                   Regions)
from .candidates import (candidate_area_range, candidate_min_circularity, correct_light, frame_candidates,
                         whole_frame_search)
from .filters import (cross_product_signs, filter_area, filter_circularity, filter_cross_product,
                      filter_distance, filter_stages, filter_window, find_candidates, label_regions,
                      light_terms, marker_distances, region_circularity, weighted_centroids, window_center)
from .fields import (FIELD_NOT_FOUND, FIELDS_DISAGREE, FieldMeasurement, aliasing_removable, corrected_mean,
                     field_centroids, field_window, marker_in_fields, remeasure_by_fields, row_aliasing)
from .gaps import bridge_gaps, default_max_gap
from .marker_model import fit_marker_model, label_frame
from .markers2d import marker_label, markers_2d_csv_text, markers_2d_rows, write_markers_2d_csv
from .matching import match_views
from .stills import (MarkerCountError, StillCandidates, StillViews, detect_still, detect_still_views,
                     match_still_views, still_candidates)
from .thesis_chain import (CandidateCache, choose_markers, cluster_persistence, detect_markers, follow_cluster,
                           usable_frames, valid_frames)
from .thresholds import auto_threshold, binarize, otsu3_thresholds, otsu_threshold, to_gray
from .timeshift import FrameShift, best_frame_shift, frame_shift_residuals
from .tracker3d import IDENTIFICATION_REASONS, Identification, identify_markers, reason_counts

#: The path that finds the candidate regions, as ``analysis.json`` records it (``software.detection_core``).
ACTIVE_PATH = "python"

__all__ = [
    "ACTIVE_PATH",
    "REASONS", "DetectionError", "MarkerCountError", "DetectionParams", "MarkerTrack", "Regions",
    "GENERIC_AREA", "AUTO_MIN_CIRCULARITY",
    "to_gray", "binarize", "otsu_threshold", "otsu3_thresholds", "auto_threshold",
    "label_regions", "region_circularity", "filter_area", "filter_circularity",
    "filter_window", "window_center", "marker_distances", "filter_distance",
    "cross_product_signs", "filter_cross_product", "weighted_centroids", "light_terms", "correct_light",
    "find_candidates", "follow_cluster", "choose_markers", "cluster_persistence", "CandidateCache", "filter_stages",
    "detect_markers", "detect_still",
    "StillCandidates", "still_candidates", "StillViews", "match_still_views", "detect_still_views",
    "valid_frames", "usable_frames", "markers_2d_rows", "markers_2d_csv_text", "marker_label", "write_markers_2d_csv",
    "IDENTIFICATION_REASONS", "Identification", "identify_markers", "frame_candidates", "whole_frame_search",
    "match_views", "fit_marker_model", "label_frame", "bridge_gaps", "default_max_gap",
    "candidate_area_range", "candidate_min_circularity", "reason_counts",
    "FrameShift", "frame_shift_residuals", "best_frame_shift",
    "FIELD_NOT_FOUND", "FIELDS_DISAGREE", "FieldMeasurement", "marker_in_fields", "field_centroids", "field_window",
    "row_aliasing", "aliasing_removable", "corrected_mean", "remeasure_by_fields",
]
