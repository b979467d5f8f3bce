# %% [markdown]
# # 04 · Marker detection: from video frames to marker pixels
#
# **What you will learn**
# - the thesis' chain of filters that turns each frame into the image centres of the markers
#   (chapter 4, Appendix A step 4): gray conversion, a global threshold, 8-connected labelling,
#   an area filter, a sliding window, a distance filter and a cross-product filter;
# - how every prompt of `left_data_from_first_image_2.m` (threshold, labels, area range, window,
#   distance tolerance) gets an automatic value, and how to change it with a widget;
# - why an intensity-weighted centroid is several times more precise than the geometric centre
#   of the binary region, measured against the virtual laboratory's truth;
# - how markers that are hidden or leave the image become NaN with a reason, never a guess;
# - how the pipeline's default identifies the markers with all cameras together (section 9):
#   consistent triangulation and the static shot's rigid shape reject what one camera cannot.
#
# **The equations.** Gray level of an RGB pixel (eq. 4.4) and the global threshold $l$ (eq. 4.5):
#
# $$\mathrm{Gray} = 0.2989R + 0.5870G + 0.1140B \qquad
#   H(u,v) = \begin{cases}1 & I(u,v) > l\\ 0 & I(u,v)\le l\end{cases}$$
#
# The distance filter compares the distances between the $M$ markers of a reference frame,
# $DM_{ij}=\lVert(u_i,v_i)-(u_j,v_j)\rVert$ (eq. 4.6, $D_M = M(M-1)/2$ of them, eq. 4.7), with the
# distances $DC_{ij}$ between the $C$ regions of the current frame (eq. 4.8-4.9) and keeps the
# combinations whose distances all fall in $DI_{ij} = [-DM_{ij}DT,\ +DM_{ij}DT]$ around
# $DM_{ij}$ (eq. 4.10-4.11). The cross-product filter (Figure 4.13) keeps a choice only if
# $\mathrm{sgn}[(\mathbf r_{12}\times\mathbf r_{23})_3]$ is the same as in the first frame, so
# that a mirrored second marker cannot take the place of the true one. The window of size
# $(W_{du}, W_{dv})$ slides with the markers' overall centre: $W_c(k+1) = W_c^e(k)$ (Figure 4.11).

# %% tags=["nbval-ignore-output"]
# The riding session of this notebook and of the next ones: a session of data_samples/ or any session
# folder (default: the bundled Horse 2 canter). After choosing another, run the cells below again. The
# choices made with this notebook's widgets are kept for the session and used by every later notebook.
from IPython.display import display
from horsemocap.widgets import ui_session
from horsemocap.workspace import open_workspace

ws = open_workspace()
display(ui_session(ws))

# %%
import dataclasses
import tempfile
import time
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from IPython.display import display

from horsemocap import detection, plots, widgets, workspace
from horsemocap.data import default_session_dir
from horsemocap.sources import FrameSource, read_image
from horsemocap.session import load_session
from horsemocap.widgets.markers_guard import marker_pairs
from horsemocap.workspace import NO_TRUTH, results_for, session_truth

# %% [markdown]
# ## The data
#
# The default session (Horse 2 at canter, rendered by the virtual laboratory) has one video per
# camera. The horse crosses the field of view, so the markers enter and leave the image; the
# rider's leg hides the saddle marker, and there are pseudo markers on purpose: the white fence
# rail, the leg bandages, the helmet, a girth buckle, the stirrup and random glints. We start
# with the left camera.

# %%
session = ws.session_dir
truth = session_truth(session)     # None for a recorded session (no truth/ folder)
meta = load_session(session, open_sources=False)
videos = meta.motion                   # camera -> video file
n_markers = meta.marker_count          # the markers on the horse (session.json 'markers.count'; 3 in the thesis)
cameras = list(videos)
frames = FrameSource(videos["left"]).read()
n_frames, height, width = frames.shape[:3]
print(f"left camera: {n_frames} frames of {width}x{height} px, RGB {frames.dtype}")

# %% [markdown]
# ## 1 · Gray image and threshold (eq. 4.4, 4.5)
#
# The thesis asks the user for $l$ and to check that "the markers are visible and isolated in all
# motion images". The automatic start is Otsu's method on the histogram of frames sampled over
# the whole motion. The plain two-class Otsu splits the dark arena from everything lit; the
# three-class Otsu of Guchin et al. (section 5.2.1) gives two levels, and its upper one separates the
# brightest class (markers, rail, bandages) from the horse's coat.

# %%
sample = [detection.to_gray(frames[k]) for k in np.linspace(0, n_frames - 1, 8).round().astype(int)]
hist = sum(np.bincount(g.ravel(), minlength=256) for g in sample)
l_otsu = detection.otsu_threshold(hist)
l1, l2 = detection.otsu3_thresholds(hist)
print(f"Otsu: l = {l_otsu};  three-class Otsu: l1 = {l1}, l2 = {l2}  (automatic threshold = l2)")

# %%
fig, ax = plt.subplots(figsize=(7, 3))
ax.semilogy(np.arange(256), hist + 1, color="k", lw=1)
for lv, name, c in ((l_otsu, "Otsu", "tab:blue"), (l1, "3-class l1", "tab:orange"), (l2, "3-class l2", "tab:red")):
    ax.axvline(lv, color=c, ls="--", label=f"{name} = {lv}")
ax.set_xlabel("gray level")
ax.set_ylabel("pixels + 1")
ax.legend(fontsize=8)
plt.show()

# %% [markdown]
# **One threshold, or one per image?** The thesis (4.5.1) keeps the threshold constant when it holds for
# all images of the motion, and lets its user type a different level per image when the light changes
# across the video. The three-class Otsu level of each frame on its own shows whether one level fits
# this video:

# %%
per_frame = np.array([detection.otsu3_thresholds(np.bincount(detection.to_gray(f).ravel(), minlength=256))[1]
                      for f in frames])
fig, ax = plt.subplots(figsize=(7, 2.6))
ax.plot(per_frame, "k.-", lw=0.8, label="three-class Otsu l2 of each frame")
ax.axhline(l2, color="tab:red", ls="--", label=f"from 8 frames over the motion: {l2}")
ax.set_xlabel("frame (left camera)")
ax.set_ylabel("threshold")
ax.legend(fontsize=8)
plt.show()
print(f"per-frame levels {per_frame.min()}-{per_frame.max()} (median {np.median(per_frame):.0f}); "
      f"from 8 frames over the motion: {l2}")

# %% [markdown]
# The automatic run below makes every choice; we then revisit each one with a widget. It follows as many
# markers as the session has (`markers.count` of its `session.json`: three in the thesis and in the bundled
# session; the distance filter then compares all $M(M-1)/2$ distances).

# %%
track = detection.detect_markers(frames, n_markers)
p = track.params
print(f"threshold l = {p.threshold}, first frame = {p.first_frame}, labels = {list(p.labels)}")
print(f"area range = [{p.area_min:.0f}, {p.area_max:.0f}] px, window = {p.window} px, "
      f"DT = {p.distance_tolerance:.3f}")
print(f"frames with all {n_markers} markers: {int(track.all_found.sum())} of {n_frames}")

# %% [markdown]
# **The threshold slider.** Move the threshold and the frame: the preview shows the binary image
# (regions in the area range in green) and the number of white regions. Under the threshold the
# markers merge with the coat; well above it they shrink to a few pixels. (The preview only
# draws; the next cell reads the value.)

# %% tags=["nbval-ignore-output"]
ui_thr = widgets.ui_threshold(frames, p)
ws.bind(ui_thr, "detection.left.threshold", automatic=p.threshold)  # the pipeline's threshold from now on
display(ui_thr)

# %%
level = ui_thr.value
binary = detection.binarize(detection.to_gray(frames[p.first_frame]), level)
regions = detection.label_regions(binary)
print(f"threshold {level}: {len(regions)} white regions in frame {p.first_frame}, "
      f"{int(detection.filter_area(regions.area, p.area_min, p.area_max).sum())} in the area range")

# %% [markdown]
# ## 2 · Labels in the first image (4.5.2)
#
# The thesis labels the white regions with 8-connectivity and asks for the labels of the markers
# in the first image. Here the markers are chosen automatically: among round regions (the
# circularity by geometric moments of Guchin et al., $c = A / (2\pi(\sigma_u^2+\sigma_v^2))$, 1 for a
# disc) of similar area, the cluster of as many regions as the session has markers that keeps its shape over the next frames, moves, and
# looks most like a marker (round and white) is followed through the sequence; the cluster
# followed through the most frames wins (chance clusters of bandages, stirrup and glints break
# up). The picker shows the numbered regions at the threshold of section 1 (run its cells first after
# moving the slider: a threshold renumbers the regions); the default selection is the automatic choice
# at the automatic threshold. A selection other than the automatic one is saved as this session's
# `detection.left` labels, with the frame they name (`first_frame`), and every later notebook uses it.

# %% tags=["nbval-ignore-output"]
auto_labels = tuple(p.labels) if level == p.threshold else ()   # the automatic labels name regions at p.threshold
ui_labels = widgets.ui_label_picker(frames[p.first_frame], dataclasses.replace(p, threshold=level, labels=auto_labels))
stored = ws.choices.get("detection", {}).get("left", {})
if stored.get("labels") and stored.get("first_frame") == p.first_frame and stored.get("threshold", p.threshold) == level:
    ui_labels.relabel(frames[p.first_frame], level, stored["labels"])   # the labels chosen earlier


def save_labels(change=None):
    """The picked labels (with their frame) as this session's choice; the automatic ones leave none."""
    picked = list(ui_labels.value)
    chosen = bool(picked) and tuple(picked) != auto_labels
    ws.choose("detection.left.labels", picked if chosen else None)
    ws.choose("detection.left.first_frame", p.first_frame if chosen else None)


ui_labels.select.observe(save_labels, "value")
display(ui_labels)

# %%
picked = ui_labels.value
r = ui_labels.regions
idx = [int(np.flatnonzero(r.ids == lab)[0]) for lab in picked]
for lab, i in zip(picked, idx):
    print(f"label {lab}: area {int(r.area[i])} px, centre ({r.centroid[i, 0]:.2f}, {r.centroid[i, 1]:.2f})")

# %% [markdown]
# ## 3 · Area range, window and distance tolerance (4.5.3-4.5.5)
#
# The automatic area range is a quarter of the smallest to four times the largest marker area in
# the first image; the window covers the markers plus a pad for the motion between frames (its
# centre follows the predicted marker centre); the tolerance is 10 % plus 2 px of centre noise
# over the smallest marker spacing. One control gathers all the prompts; its `.value` is a
# `DetectionParams` that `detect_markers` takes as it is.

# %% tags=["nbval-ignore-output"]
ui_all = widgets.ui_detection(frames, p)
ws.bind(ui_all, "detection.left", automatic={}, convert=lambda chosen, q=p: workspace.detection_changes(chosen, q))
display(ui_all)

# %%
chosen = ui_all.value
track2 = detection.detect_markers(frames, n_markers, chosen)
same = np.array_equal(track2.reason, track.reason) and np.allclose(track2.marker_px, track.marker_px, equal_nan=True)
print(f"{int(track2.all_found.sum())} frames with all markers; same as the automatic run: {same}")

# %% [markdown]
# ## 4 · The stages on one frame (Figure 4.15)
#
# `filter_stages` returns every intermediate result for one frame: the window is centred on the
# previous frame's marker centre $W_c^e(k-1)$, and the previous frame gives $DM_{ij}$.

# %%
k = p.first_frame + 5
prev = track.marker_px[k - 1]
stages = detection.filter_stages(frames[k], p, center=detection.window_center(prev), reference_px=prev,
                                 first_px=track.marker_px[p.first_frame])
c = detection.window_center(prev)
zoom = (c[0] - 1.2 * p.window[0], c[1] - 1.2 * p.window[1], c[0] + 1.2 * p.window[0], c[1] + 1.2 * p.window[1])
print(f"frame {k}: {len(stages['regions'])} regions, {len(stages['area_ok'])} after the area filter, "
      f"{len(stages['window_ok'])} in the window, {len(stages['choices'])} choices after the distance "
      f"filter, {len(stages['kept'])} after the cross product")
if truth is None:
    print("centre errors vs truth:", NO_TRUTH)
else:
    err_k = np.linalg.norm(stages["marker_px"] - truth.marker_px["left"][k, :n_markers], axis=1)
    print("centre errors vs truth (px):", ", ".join(f"{e:.3f}" for e in err_k))

# %%
fig = plots.plot_detection_stages(frames[k], stages, window=p.window, center=c, zoom=zoom)
plt.show()

# %% [markdown]
# **What each filter removes.** A frame of the same run (the first after the first image in which
# the area, window and distance filters all have something to remove), every white region coloured by
# the filter that removed it. The area filter (4.5.3) removes what is too big or too small: the rail, the helmet,
# the bandages, single-pixel glints. The sliding window (4.5.4) removes what is too far from where
# the markers were in the previous frame. The regions left are many more than three, so the distance
# filter (4.5.5, eq. 4.6-4.11) tries every *ordered* choice of three of them (region $a_1$ for
# marker 1, $a_2$ for marker 2, ...) and keeps a choice only if its three distances match the
# previous frame's $DM_{ij}$ within the tolerance $DT$. A choice and the same regions taken in
# another order can pass together when two distances are alike; the cross-product filter
# (Figure 4.13) then keeps the order whose path 1-2-3 turns the same way as in the first frame
# (right: the choice it removed is the same three regions numbered the other way round).

# %%
# a frame of the tracked run where the area, window and distance filters each remove something
# (the frame above if there is none)
k_f = k
for k_try in range(p.first_frame + 1, n_frames):
    prev_try = track.marker_px[k_try - 1]
    if not np.all(np.isfinite(prev_try)):
        continue
    stages_try = detection.filter_stages(frames[k_try], p, center=detection.window_center(prev_try),
                                         reference_px=prev_try, first_px=track.marker_px[p.first_frame])
    removed = plots.filter_removals(stages_try)
    if all((removed == name).any() for name in ("area", "window", "distance")):
        k_f = k_try
        break
prev_f = track.marker_px[k_f - 1]
c_f = detection.window_center(prev_f)
stages_f = detection.filter_stages(frames[k_f], p, center=c_f, reference_px=prev_f,
                                   first_px=track.marker_px[p.first_frame])
zoom_f = (c_f[0] - 1.2 * p.window[0], c_f[1] - 1.2 * p.window[1], c_f[0] + 1.2 * p.window[0], c_f[1] + 1.2 * p.window[1])
fig = plots.plot_filter_removals(frames[k_f], stages_f, prev_f, window=p.window, center=c_f, zoom=zoom_f)
print(f"left camera, frame {k_f}: {len(stages_f['regions'])} regions")
plt.show()

# %% [markdown]
# ## 5 · Through the sequence, with reasons
#
# Where a marker is not found it is NaN, and `track.reason` says why: `left_image` (predicted
# outside the image, or its region is cut by the border), `occluded`, `partly_occluded`,
# `ambiguous`. The thin lines are the truth.

# %%
true_left = None if truth is None else truth.marker_px["left"][:, :n_markers]   # drawn thin where known
fig, ax = plt.subplots(2, 1, figsize=(10, 5), sharex=True)
plots.plot_marker_track(track, true_left, ax=ax)
plt.show()
reasons, counts = np.unique(track.reason, return_counts=True)
print("reasons:", ", ".join(f"{r or 'found'}: {c}" for r, c in zip(reasons, counts)))

# %% [markdown]
# ## 6 · Accuracy against the truth, all cameras
#
# The virtual laboratory knows the true projection of each marker centre. We count, per camera:
# the centre error where both the truth and the detector see the marker, the markers swapped (a
# found centre nearer another marker's truth), pseudo markers reported (a centre found where the
# truth says the marker is not visible, or more than 1 px from it), and visible markers missed.
# We compare the weighted centre (default) with the thesis' geometric centre of the binary region.

# %%
def score(track, true_px, visible):
    err = np.linalg.norm(track.marker_px - true_px, axis=-1)
    found = track.found
    d = np.linalg.norm(track.marker_px[:, :, None] - true_px[:, None], axis=-1)
    nearest = np.argmin(np.where(np.isnan(d), np.inf, d), axis=2)
    swaps = int((found & (nearest != np.arange(true_px.shape[1]))).sum())
    pseudo = int((found & (~visible | (err > 1.0))).sum())
    missed = int((visible & ~found).sum())
    return err[found & visible], swaps, pseudo, missed


tracks, errors = {"left": track}, {}
for cam in cameras:
    if cam not in tracks:
        tracks[cam] = detection.detect_markers(FrameSource(videos[cam]).read(), n_markers)
    if truth is None:
        print(f"{cam:6s}: frames with all {n_markers} markers {int(tracks[cam].all_found.sum())} of {len(tracks[cam].found)}; "
              f"centre errors: {NO_TRUTH}")
        continue
    true_px, visible = truth.marker_px[cam][:, :n_markers], truth.marker_visible[cam][:, :n_markers]
    e, swaps, pseudo, missed = score(tracks[cam], true_px, visible)
    errors[cam] = e
    print(f"{cam:6s}: {e.size} centres, median {np.median(e):.3f} px, p99 {np.percentile(e, 99):.3f} px, "
          f"swaps {swaps}, pseudo markers reported {pseudo}, visible markers missed {missed}")

# %% [markdown]
# **Usable frames.** With the thesis' per-camera chain (`detection_method="thesis"`), the frames of
# the analysis are those where every camera sees every marker (in the left camera's numbering, with
# the synchronisation offsets of eq. 3.11-3.13; here the truth's offsets, notebook 02 finds them
# from the flashlight). The pipeline's default asks less (section 9): every marker needs a 3D
# position, from two cameras or more, or bridged over a short gap.

# %%
offsets = results_for(session, until="sync").synchronisation.offsets   # the flash frames (notebook 02)
usable = detection.usable_frames(tracks, offsets, "left")
print(f"usable left frames: {usable[0]}..{usable[-1]} ({len(usable)} frames)")
if n_markers != 3:
    print(f"the pipeline does not analyse this session with the per-camera chain (it follows three markers, "
          f"the session has {n_markers}): it identifies the markers with all cameras together (section 9)")
print(NO_TRUTH if truth is None else f"same as the truth's: {np.array_equal(usable, truth.ref_frames)}")

# %%
if truth is None:
    print(NO_TRUTH)
else:
    binary_track = detection.detect_markers(frames, n_markers, detection.DetectionParams(centroid="binary"))
    e_bin = score(binary_track, true_left, truth.marker_visible["left"][:, :n_markers])[0]
    print(f"left, binary centre (thesis): median {np.median(e_bin):.3f} px, p99 {np.percentile(e_bin, 99):.3f} px")
    print(f"left, weighted centre:        median {np.median(errors['left']):.3f} px, "
          f"p99 {np.percentile(errors['left'], 99):.3f} px")

# %%
if truth is None:
    print(NO_TRUTH)
else:
    ax = plots.plot_centroid_errors({"binary centre (left)": e_bin, "weighted centre (left)": errors["left"]})
    plt.show()

# %% [markdown]
# ## 7 · The stills: plumb line and static shot (Appendix A steps 7a, 8a, 12a)
#
# The same filters serve single images. The plumb still has 2 markers, returned top first
# (`order="v"`); the static shot has the skin markers (3 in the thesis) and the saddle marker (no rider),
# returned by ascending $u$.

# %%
if truth is None:
    print(NO_TRUTH)
else:
    for cam in truth.cameras:
        cm = truth.rig[cam]
        plumb = detection.detect_still(read_image(session / "plumb" / f"{cam}.jpg"), 2)
        true_plumb = cm.project(np.asarray(truth.plumb_pos))
        true_plumb = true_plumb[np.argsort(true_plumb[:, 1])]
        static = detection.detect_still(read_image(session / "static" / f"{cam}.jpg"), n_markers + 1)
        true_static = cm.project(np.asarray(truth.static_pos))
        true_static = true_static[np.argsort(true_static[:, 0])]
        ep = np.linalg.norm(plumb - true_plumb, axis=1).max()
        es = np.linalg.norm(static - true_static, axis=1).max()
        print(f"{cam:6s}: plumb max error {ep:.3f} px, static shot max error {es:.3f} px")

# %% [markdown]
# ## 8 · The output: `markers_2d.csv`
#
# One row per camera, frame (in the camera's own numbering) and marker; empty values where the
# marker was not found. Two more columns: `reason` says why a centre is empty or was not used
# (empty when it was used), and `residual_px` is the distance between the centre and the
# projection of the marker's triangulated 3D point. These per-camera tracks have no 3D point, so
# `residual_px` stays empty here. The pipeline fills it, and writes each marker's 3D position
# (before smoothing, with the number of cameras used and a reason, `interpolated` for a bridged
# gap) to `markers_3d.csv`.

# %%
with tempfile.TemporaryDirectory() as tmp:
    path = detection.write_markers_2d_csv(Path(tmp) / "markers_2d.csv", tracks)
    lines = path.read_text().splitlines()
print(f"{len(lines) - 1} rows")
print("\n".join(lines[:2] + [l for l in lines if l.startswith(f"left,{p.first_frame},")]))

# %% [markdown]
# **Speed of the preview.** The threshold preview must keep up with the slider (aim: well under
# 100 ms per redraw at 640x480). Timing varies from machine to machine, so this cell's output is
# not checked. It moves a preview of its own, never shown, so the threshold chosen above stays.

# %% tags=["nbval-ignore-output"]
timed = widgets.ui_threshold(frames, p)
times = []
for level in range(100, 200, 10):
    timed.slider.value = level
    times.append(timed.last_ms)
t0 = time.perf_counter()
detection.detect_markers(frames, n_markers, p)
t_track = (time.perf_counter() - t0) / n_frames
print(f"threshold preview: median {np.median(times):.1f} ms per redraw (max {max(times):.1f} ms)")
print(f"detection with given parameters: {1e3 * t_track:.2f} ms per frame")

# %% [markdown]
# ## 9 · All cameras together: identification in 3D (the pipeline's default)
#
# Everything above looks at one camera at a time, as the thesis does. One camera cannot tell a
# marker from a round bright pseudo marker of the same size: a shining stirrup, the girth
# buckle, a reflector that crosses the markers. The three cameras together can (Guchin et al.,
# section 5.2.3). The pipeline's default, `detection_method="multiview"`, therefore
#
# 1. takes the candidate regions of every camera (area and circularity rules as above; the
#    threshold is chosen for the candidate search from each camera's own images, so it can
#    differ by a few gray levels from the one-camera choice of the tabs above: the cell below
#    prints it);
# 2. matches them across the cameras: two regions that triangulate with a reprojection error
#    below 2 px satisfy the epipolar constraint, and a third camera validates the point when it
#    has a region at its projection;
# 3. labels the 3D points with the **rigid model of the static shot**: the distances between the
#    markers (all of them: three in the thesis, as many as `markers.count` says) must equal the static
#    shot's within their measured uncertainty, and the markers must face the cameras as they do in the
#    static shot (the cross-product rule of Figure 4.13, in 3D);
# 4. follows the markers in 3D from frame to frame, predicting each with minimum acceleration
#    (constant velocity) and looking for it near the projection of the prediction in every camera.
#
# A marker seen by two cameras still gets a 3D position when the third loses it; a short gap in
# every camera is bridged in 3D and marked `interpolated`. Here is the frame where the pipeline
# labelled the markers, with every candidate region of every camera:

# %%
from horsemocap import accuracy
from horsemocap.detection import frame_candidates, label_frame
analysis = results_for(session, until="triangulate")
k = analysis.detect.identification.anchor_frame
offsets = analysis.synchronisation.offsets
thresholds = {c: analysis.detect.detection[c]["threshold"] for c in cameras}
images = {c: FrameSource(videos[c]).frame(offsets[c] + k, color=False) for c in cameras}
candidates = {c: frame_candidates(images[c], thresholds[c]) for c in cameras}
views, fit, why = label_frame(analysis.rig.rig, candidates, analysis.static.static_points, n_markers, 2.0)
print(f"synchronised frame {k}; thresholds {thresholds}")
print("candidate regions per camera: " + ", ".join(f"{c} {len(candidates[c])}" for c in cameras))
if fit is None:      # the pipeline labelled this frame with its own tracking; this one call could not
    print(f"3D points consistent in two or more cameras: {len(views)}; not labelled by this call: {why}")
else:
    print(f"3D points consistent in two or more cameras: {len(views)}; the markers: points {fit.assignment.tolist()}, "
          f"distances within {1000 * fit.rms_m:.1f} mm rms of the static shot's")
    fig = plots.plot_identification(images, candidates, views, fit)
    plt.show()

# %% [markdown]
# **A pseudo marker rejected by geometry.** Several bright things are consistent in all three
# cameras: they are real 3D objects (the leg bandages, the buckle, the rider's helmet). None of
# them, with the other markers, makes the static shot's shape. The table gives, for each
# consistent 3D point, its distances to the markers (as many as the session has); the static shot's
# distances between the markers are printed first.

# %%
if fit is None:
    print(f"frame {k} was not labelled by the call above ({why}): no table")
else:
    static = analysis.static.static_points[fit.model_index]
    print("static shot: " + ", ".join(f"marker{i + 1}-marker{j + 1} {1000 * np.linalg.norm(static[i] - static[j]):.0f} mm"
                                      for i, j in marker_pairs(n_markers)))
    marker_points = views.points[fit.assignment]
    for point in range(len(views)):
        d = 1000 * np.linalg.norm(marker_points - views.points[point], axis=1)
        role = f"marker{list(fit.assignment).index(point) + 1}" if point in fit.assignment else "pseudo marker"
        seen = "+".join(c for c, j in zip(views.cameras, views.index[point]) if j >= 0)
        print(f"point {point:2d} ({seen:17s}): distances to the markers {' '.join(f'{v:6.0f}' for v in d)} mm -> {role}")

# %% [markdown]
# **Through the sequence.** Every 2D centre that was not used keeps its reason (the
# `reason` column of `markers_2d.csv`); against the truth, no centre carries a wrong identity.

# %%
if truth is None:
    print(NO_TRUTH)
else:
    ident = accuracy.identification_errors(analysis, truth)
    for cam, e in ident["cameras"].items():
        why = ", ".join(f"{r} {n}" for r, n in sorted(e["reasons"].items())) or "none"
        print(f"{cam:6s}: {e['used']:3d} centres used, {e['wrong']} wrong identities, median error "
              f"{e['median_px']:.3f} px; visible but not used: {e['missed']} ({why})")
    print(f"marker-frames seen by two or more cameras: {ident['seen_by_two']}, with a 3D position: {ident['with_3d']}")

# %% [markdown]
# ## Every camera's prompts
#
# The thesis ran `left_data_from_first_image_2.m`, then the same program for the middle and the right
# camera. The left camera's prompts are the controls of section 3 above; below, one tab per other
# camera gathers the same prompts (threshold, first frame, labels, area range, window, tolerance) at
# that camera's automatic choice. What is changed in a tab becomes the session's choice for that camera.

# %% tags=["nbval-ignore-output"]
import ipywidgets as W

cam_frames = {cam: FrameSource(videos[cam]).read() for cam in cameras if cam != "left"}
ui_cams = {"left": ui_all}
for cam, fr in cam_frames.items():
    ui_cams[cam] = widgets.ui_detection(fr, tracks[cam].params)
    ws.bind(ui_cams[cam], f"detection.{cam}", automatic={},
            convert=lambda chosen, q=tracks[cam].params: workspace.detection_changes(chosen, q))
tabs = W.Tab(children=[ui_cams[c] for c in cameras if c != "left"])
for k, cam in enumerate(c for c in cameras if c != "left"):
    tabs.set_title(k, cam)
display(tabs)

# %%
for cam in cameras:
    q = ui_cams[cam].value
    print(f"{cam:6s}: threshold {q.threshold}, first frame {q.first_frame}, labels {list(q.labels or [])}, "
          f"area [{q.area_min:.0f}, {q.area_max:.0f}] px, window {q.window} px, DT {q.distance_tolerance:.3f}")

# %% [markdown]
# ## Your choices, downstream
#
# What the choices made so far (the widgets of this notebook and of the earlier ones) give at the end of
# each chain: the saddle's vertical acceleration (unweighted rms), its $W_b$- and $W_k$-weighted rms
# (chapter 7, notebook 12) and the quality verdict of the run (the `quality.json` of a results folder:
# *ok*, *warning* or *unreliable*, with what each check found). The chain followed is the one chosen in
# notebook 00; both are shown because a choice belongs to one chain: the Fourier orders, the omega/alfa
# versions and the saddle method are read only by the thesis' chain of fits, so they change only its
# row. Move a widget above, then run this cell again.

# %%
from horsemocap.workspace import downstream_text

print(downstream_text(ws.session_dir))

# %% [markdown]
# ## Exercises
#
# 1. Set the threshold to the two-class Otsu level and run the detection again. What happens to
#    the number of white regions and to the centre errors?
# 2. Run the thesis' variant of the distance filter, with $DM_{ij}$ from the first image only
#    (`distance_reference="first"`) and the window centred on the previous centre
#    (`window_predict=False`). Does it still find every visible marker?
# 3. Which reason strings appear in the right camera, and in which frames? Compare them with
#    `truth.marker_reason["right"]`.
# 4. Run the pipeline with the thesis' per-camera chain, `results_for(session, until="detect",
#    params={"detection_method": "thesis"})`, and compare `accuracy.identification_errors` with
#    section 9's.
#
# <details><summary>Solutions</summary>
#
# 1. `detection.detect_markers(frames, 3, detection.DetectionParams(threshold=l_otsu))`: the
#    lower level lets the horse's coat around the markers through, so the marker regions merge
#    or grow; the weighted centres stay close as long as the regions stay separate.
# 2. `detection.detect_markers(frames, 3, detection.DetectionParams(distance_reference="first",
#    window_predict=False))` and compare `track.found` with `truth.marker_visible["left"][:, :3]`.
# 3. `np.unique(tracks["right"].reason, return_counts=True)`; the markers enter and leave the
#    image (`left_image`), which the truth calls `outside_image` / `partly_outside_image`.
# 4. On this session both find the markers. The thesis' chain analyses only the longest run in
#    which every camera sees every marker; the multi-view one the longest run in which every marker
#    has a 3D position (seen by two or more cameras, or bridged over a short gap).
#
# </details>
