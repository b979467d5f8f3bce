# %% [markdown]
# # 08 · Registration: making the three markers a rigid body again
#
# **What you will learn**
# - why the measured markers are not rigid, and how a *static shot* of the standing horse gives a
#   rigid model of them (thesis section 5.4, Appendix A step 8);
# - which static-shot marker is which motion marker, found from the inter-marker distances
#   (the thesis picked the labels by hand);
# - the closed-form quaternion solution of Horn (1987) used by Besl and McKay (1992), eq. 5.14-5.21;
# - that after registration the inter-marker distances equal the model's in every frame (Figure 8.12).
#
# The model points $\mathbf{x}^m_m$ (static shot) and the measured points $\mathbf{x}_m$ (one frame)
# are related by the rotation $\mathbf{R}(\mathbf{q}_R)$ and translation $\mathbf{q}_t$ that minimise
#
# $$f(\mathbf{q}) = \frac{1}{M}\sum_{m=1}^{M}\left\|\mathbf{x}^m_m - \mathbf{R}(\mathbf{q}_R)\,\mathbf{x}_m - \mathbf{q}_t\right\|^2 \qquad (5.14)$$
#
# with the unit quaternion $\mathbf{q}_R = [q_0\,q_1\,q_2\,q_3]^T$ (5.15) giving $\mathbf{R}$ by eq. 5.16.
# The registered (rigid) markers are the model moved back into the frame's pose,
#
# $$\mathbf{x}^r_m = \mathbf{R}^{-1}\left(\mathbf{x}^m_m - \mathbf{q}_t\right) \qquad (5.20)$$
#
# **Closed form.** With centred sets, the cross-covariance
# $\mathbf{S} = \sum_m (\mathbf{x}^m_m - \boldsymbol\mu^m)(\mathbf{x}_m - \boldsymbol\mu)^T$ fills a symmetric
# $4\times4$ matrix $\mathbf{Q}(\mathbf{S})$ whose eigenvector of the largest eigenvalue is the optimal
# $\mathbf{q}_R$. `horsemocap.rigid.register` returns the *pose* of the model in each frame,
# `registered = rotation @ model + translation`, so the thesis' $\mathbf{R} = $ `rotation.T`.

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
import warnings

import matplotlib.pyplot as plt
import numpy as np

from horsemocap import plots, rigid
from horsemocap.widgets.markers_guard import marker_numbers, marker_pairs, thesis_three_note

# %% [markdown]
# ## The data: the pipeline's own
#
# The default session is Horse 2 at canter from the virtual laboratory. `results_for` runs (or loads) the
# pipeline's steps up to the rigid body with the automatic choices: synchronisation, calibration, the plumb
# line and the static shot, marker detection, triangulation, smoothing, the motion frame (notebooks 02-06).
# Its `motion_frame` step hands the
# rigid-body step the marker positions in the motion frame (`positions`, smoothed with the pipeline's default
# `smoothing_method="loess"`: MATLAB's `smooth(y, 0.1, 'loess')`, see notebook 06) and the four static-shot
# points in the same frame (`static`, in the detector's order). The virtual laboratory's truth is used only to
# measure errors: its rows for the analysed frames, expressed in the pipeline's motion frame.
#
# The thesis smoothed with `rloess`, the same local regression followed by robust iterations that give
# outlying samples less weight. The pipeline leaves the robust iterations out by default, on a measurement
# over the 16 virtual herd sessions (`benchmarks/bench_herd.py`, same detections and rig for each method,
# made with the thesis' per-camera detection; quoted here, not recomputed by this notebook): the median
# |error| of the Wb-weighted rms of the saddle's
# vertical acceleration was 7.9 % with `loess`, 9.5 % with `rloess` and 20.4 % without smoothing (worst
# session 17.6 %, 140 % and 53.5 %). On a record of a few dozen frames a 0.1 span is only a few points, and
# the robust iterations then reject good samples near the ends of the record.

# %%
from horsemocap import accuracy, data, frames
from horsemocap.workspace import NO_TRUTH, results_for, session_truth

an = results_for(until="rigid_body")
mf = an.motion_frame
markers, static = mf.positions, mf.static
rb = an.rigid_body.body                           # horsemocap.rigid.RigidBodyAnalysis of the pipeline
t = an.rigid_body.t
a, b = an.triangulate.segment
print(f"{len(t)} frames ({a}..{b - 1} of the synchronised record) at {an.session.fps:.0f} fps; "
      f"markers {markers.shape}; static shot {static.shape}")
moved = 1000 * np.linalg.norm(an.smooth.smoothed - an.smooth.raw, axis=-1)
print(f"smoothing: {an.params.smooth.method}, span {an.params.smooth.span}; it moved the triangulated "
      f"markers by median {np.nanmedian(moved):.2f} mm, max {np.nanmax(moved):.2f} mm")   # where seen

truth = session_truth(ws.session_dir)            # None for a recorded session (no truth/ folder)
if truth is None:
    print(NO_TRUTH, "(a recorded session): the comparison with the truth below is left out")
else:
    true_pos = accuracy.analysed_truth(an, truth)["marker_pos"]   # the truth at the analysed frames, pipeline's frame

# %% [markdown]
# ## Which static marker is which?
#
# The static shot holds the skin markers and the saddle marker (four points in the thesis: three skin
# markers) in no particular order. Every assignment of as many of them as the ride has markers to the
# motion markers is scored by how well its distances agree with the motion markers' median distances. The skin markers sit in a row along the
# back, so two assignments can differ by only a few millimetres; among the near-ties the one needing
# the smallest rotation wins (the horse heads along $+x$ in both the static shot and the ride).

# %%
n_markers = an.session.marker_count                   # session.json 'markers.count' (3 in the thesis)
order, saddle_index = rigid.match_static_markers(static, markers)
head = f"static index of motion markers {marker_numbers(n_markers)}:"
print(head, order.tolist(), "; saddle marker:", saddle_index)
choice = "the pipeline's choice:"
print(f"{choice:{len(head)}s}", rb.static_index.tolist(), "; saddle marker:", rb.saddle_index)
d_motion = np.nanmedian(rigid.pairwise_distances(markers), axis=0)
d_model = rigid.pairwise_distances(static[order])
for i, j in marker_pairs(n_markers):
    print(f"|r{i + 1}{j + 1}|  motion (median) {1000 * d_motion[i, j]:.1f} mm   static {1000 * d_model[i, j]:.1f} mm")

# %% [markdown]
# ## Registering every frame

# %%
model = static[order]
reg = rigid.register(markers, model)
d_before = rigid.pairwise_distances(markers)
d_after = rigid.pairwise_distances(reg.registered)
iu = np.triu_indices(n_markers, 1)
dev_before = 1000 * np.nanmax(np.abs(d_before - d_model)[:, iu[0], iu[1]])
print(f"distance deviation from the model, before: max {dev_before:.2f} mm")
dev_after = 1000 * np.nanmax(np.abs(d_after - d_model)[:, iu[0], iu[1]])     # over the frames registered
print(f"distance deviation from the model, after:  below 1e-9 mm: {dev_after < 1e-9}")
print(f"residual |e_m| (Figure 5.3): median {1000 * np.nanmedian(reg.residual):.2f} mm, "
      f"max {1000 * np.nanmax(reg.residual):.2f} mm")
print("frames not registered:", int(np.sum(reg.reason != "")))
print(f"same registration as the pipeline's (to 1e-12 m): {np.nanmax(np.abs(reg.registered - rb.pos)) < 1e-12}")

# %% [markdown]
# Figure 8.12 of the thesis shows frame 27 before and after the rigid-body correction:

# %%
fig = plots.plot_registration(markers, reg.registered, frame=26)
plt.show()

# %%
fig = plots.plot_marker_distances(t, markers, reg.registered)
plt.show()

# %% [markdown]
# ## Does registration bring us closer to the truth?
#
# The registered markers are rigid; are they also more accurate? Against the virtual laboratory's truth,
# per axis of the motion frame (`accuracy.stage_errors` measures the same in the *true* motion frame,
# which differs from the pipeline's by a fraction of a degree):

# %%
if truth is None:
    print(NO_TRUTH)
else:
    err_m = frames.rmse_per_axis(markers, true_pos) * 1000
    err_r = frames.rmse_per_axis(reg.registered, true_pos) * 1000
    print("RMSE per axis x/y/z (mm), triangulated: " + "  ".join(f"{e:5.2f}" for e in err_m))
    print("RMSE per axis x/y/z (mm), registered:   " + "  ".join(f"{e:5.2f}" for e in err_r))
    st = accuracy.stage_errors(an, truth)
    print(f"stage_errors (true motion frame, x axis {st['x_axis_deg']:.2f} deg off), registered: "
          + "  ".join(f"{1000 * e:5.2f}" for e in st["registered"]) + " mm")

# %% [markdown]
# The depth (z, along the cameras' optical axes) is the weak axis of the rig: triangulation errors are
# largest there, and registration cannot remove an error that the three markers share (a shift or a
# rotation of the whole triangle is a rigid motion). What it removes is the part that changes the
# triangle's shape. The static shot has its own error too: every registered frame inherits the model's
# shape error, a constant per marker.
#
# The quaternion and the thesis' form (eq. 5.20 gives back the registered points with them):
#
# $$\mathbf{R}_\mathrm{thesis} = \texttt{rotation}^T, \qquad \mathbf{q}_t = -\mathbf{R}_\mathrm{thesis}\,\texttt{translation}$$

# %%
k = 26
R_th = reg.rotation[k].T
q_t = -R_th @ reg.translation[k]
x_r = (np.linalg.inv(R_th) @ (model - q_t).T).T                   # eq. 5.20 / 5.21
print(f"eq. 5.20 gives the registered points of frame 27 (to 1e-12 m): {np.abs(x_r - reg.registered[k]).max() < 1e-12}")
print(f"det R = {np.linalg.det(R_th):.6f};  rotation angle {np.degrees(np.arccos((np.trace(R_th) - 1) / 2)):.2f} deg")

# %% [markdown]
# ## The static shot of the session: threshold and labels (Appendix A 8a, 12a)
#
# The static shot shows the three markers and the saddle marker; the thesis asked for each camera's
# threshold and the labels of the markers. The tabs show the automatic choice of each camera; a change
# becomes the session's choice for the static shot, which the registration above and every later
# notebook use.

# %% tags=["nbval-ignore-output"]
from horsemocap import widgets
from horsemocap.sources import read_still

ui_static = widgets.ui_still({c: read_still(p) for c, p in an.session.static.items()},
                             an.session.marker_count + 1, an.static.static_px)
ws.bind(ui_static, "stills.static")
display(ui_static)

# %%
print("static-shot prompts:", ui_static.value or "automatic")

# %% [markdown]
# ## Chapter 8's images, filtered and labelled (Figures 8.3, 8.4, 8.7, 8.11, 8.21)
#
# The thesis shows each image its user worked on next to what the chosen threshold and area range
# left of it. Here, from the same analysis: the **top** row is the original image with the markers
# the pipeline found circled and labelled, the **bottom** row the black-and-white image of the
# threshold (eq. 4.5), restricted to the regions of the area range (4.5.3) where the thesis used one.
# The stills' thresholds and area ranges are those of the pipeline's automatic still detector
# (`detection.still_candidates`).

# %%
from horsemocap import detection, sources

session = an.session
cam = session.cameras[0]


def still_figure(image, marker_px, labels, title):
    """The original still and what its automatic threshold and area range keep."""
    cand = detection.still_candidates(image)
    return plots.plot_filtered_images([image], cand.threshold, (cand.area.min(), cand.area.max()),
                                      marker_px=[marker_px], labels=labels, titles=[title], zoom="markers")


plumb = sources.read_still(session.plumb[cam])
fig = still_figure(plumb, an.plumb.plumb_px[cam], ["top", "tip"],
                   f"Figure 8.4: plumb line, {cam} camera")
plt.show()

# %% [markdown]
# Figure 8.7: the first analysed frame of the left camera, in colour and in black and white at the
# detection's threshold (no area filter: every bright region shows), with the markers the
# detection labelled in that frame.

# %%
offset, det = an.synchronisation.offsets[cam], an.detect
first = sources.FrameSource(session.motion[cam]).sequence(offset + a, offset + a + 1, color=True)[0]
fig = plots.plot_filtered_images([first], det.detection[cam]["threshold"], None,
                                 marker_px=[det.marker_px[cam][a]],
                                 titles=[f"Figure 8.7: frame {a}, {cam} camera"], zoom="markers")
plt.show()

# %% [markdown]
# Figures 8.11 and 8.21: the static shot, where the skin markers **and** the saddle marker are
# visible. The thesis typed the labels of the markers (8.11) and of the saddle marker (8.21) by
# hand; the pipeline found them (`static_order`, `saddle_index` of the rigid-body step).

# %%
static_img = sources.read_still(session.static[cam])
order, saddle = an.rigid_body.static_order, an.rigid_body.saddle_index
labels = ["saddle" if s == saddle else f"marker {order.index(s) + 1}" if s in order else "?"
          for s in range(len(an.static.static_px[cam]))]
fig = still_figure(static_img, an.static.static_px[cam], labels,
                   f"Figures 8.11 and 8.21: static shot, {cam} camera")
plt.show()

# %% [markdown]
# Figure 8.3: ten frames of the falling ball (`data_samples/ball_drop`, notebook 07) in the left
# camera, and what the detection's threshold and area range keep of them (the thesis used [10, 35]
# pixels and a window; the pipeline chose its own range for this ball).

# %%
ball = results_for(data.data_samples_dir() / "ball_drop", until="detect")
bcam = ball.session.cameras[0]
bdet = ball.detect.detection[bcam]
boff, bn = ball.synchronisation.offsets[bcam], ball.synchronisation.n_frames
pick = np.linspace(0, bn - 1, 10).round().astype(int)
bframes = sources.FrameSource(ball.session.motion[bcam]).sequence(boff, boff + bn, color=True)
bpx = ball.detect.marker_px[bcam][pick, 0]                    # (10, 2), NaN where not found
lo, hi = np.nanmin(bpx, axis=0) - 40, np.nanmax(bpx, axis=0) + 40    # the thesis crops its figure too
fig = plots.plot_filtered_images([bframes[k] for k in pick], bdet["threshold"], (bdet["area_min"], bdet["area_max"]),
                                 marker_px=[bpx[i:i + 1] for i in range(len(pick))], labels=["ball"],
                                 titles=[f"frame {k}" for k in pick], zoom=(lo[0], lo[1], hi[0], hi[1]))
fig.suptitle(f"Figure 8.3: the ball in the {bcam} camera, original (top) and area-filtered (bottom)")
plt.show()

# %% [markdown]
# ## Figures 6.1 and 6.2: the body frame, in the static shot and during the motion
#
# The saddle marker is hidden by the rider's leg during the ride, so the thesis fixes a frame to the
# horse's back (section 6.3): its origin $O_B$ is marker 1, $\mathbf{u}_1$ points to marker 2, marker 3
# lies in its $\mathbf{u}_1\mathbf{u}_2$ plane and $\mathbf{u}_3$ completes it (eq. 6.41-6.45). In the
# static shot, where the saddle marker is visible, its position in that frame, $\mathbf{r}_{BS}^{(B)}$
# (eq. 6.47), is measured once; during the motion the registered markers give $\mathbf{R}_{MB}(t)$ and
# $\mathbf{r}_{MB}(t)$, and eq. 6.48 places the saddle marker. Left: the static shot (Figure 6.1); right:
# one frame of the motion (Figure 6.2), both in the motion frame's x-y plane. The construction takes three
# markers; on a session with more, it is drawn on markers 1, 2, 3 (the first three of the pipeline's model,
# as the pipeline's own body frame), while the registration above used them all.

# %%
from horsemocap import pose, rigid

order, s_idx = list(an.rigid_body.static_order), an.rigid_body.saddle_index
static_markers, static_saddle = static[order][:3], static[s_idx]     # the thesis' three markers
if thesis_three_note(n_markers):
    print(thesis_three_note(n_markers))
R_static, o_static = rigid.body_frame(static_markers)                # eq. 6.41-6.45
r_BS = rigid.saddle_in_body(static_markers, static_saddle)           # eq. 6.47
k_mid = len(t) // 2
R_k, o_k = rigid.body_frames(an.rigid_body.registered[k_mid:k_mid + 1, :3])
saddle_k = R_k[0] @ r_BS + o_k[0]                                    # eq. 6.48
print("r_BS^(B) (saddle marker in the body frame): " + ", ".join(f"{1000 * v:+.0f}" for v in r_BS) + " mm")
fig, axes = plt.subplots(1, 2, figsize=(12, 4.2))
plots.plot_body_frame(static_markers, static_saddle, R_static, o_static, ax=axes[0],
                      title="Figure 6.1: the static shot")
plots.plot_body_frame(an.rigid_body.registered[k_mid, :3], saddle_k, R_k[0], o_k[0], ax=axes[1],
                      title=f"Figure 6.2: during the motion, t = {t[k_mid]:.2f} s")
fig.tight_layout()
plt.show()

# %% [markdown]
# The thesis' body frame follows the markers, wherever they sit on the back. The saddle's roll, pitch
# and yaw (notebook 10) need axes that mean something for the horse: as in the body-axes convention of
# human motion analysis (a default pose fixes the body's planes), the static shot fixes them here: the
# body's vertical is gravity (y-motion), its longitudinal axis the direction along which the static
# shot's markers lie, made horizontal and pointed forward, and the lateral axis completes the frame
# (`pose.static_body_axes`). Their angles to the thesis' body axes in the static shot:

# %%
body_axes = pose.static_body_axes(static)                            # columns: longitudinal, down, lateral
for i, name in enumerate(("longitudinal", "vertical (down)", "lateral")):
    ang = np.degrees(np.arccos(np.clip(abs(body_axes[:, i] @ R_static[:, i]), 0, 1)))
    print(f"{name:16s} axis {np.array2string(body_axes[:, i], precision=3)}: {ang:5.1f} deg from the thesis' u{i + 1}")

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
# 1. Shuffle the static shot (`static[np.random.default_rng(1).permutation(4)]`) and rerun
#    `match_static_markers`: does the assignment change? Then swap markers 1 and 3 of the static shot: why
#    are the distances alone not enough here?
# 2. Register the *true* markers (`true_pos`) to the true static shot
#    (`frames.to_motion_frame(truth.static_pos, mf.frame)[:3]`): how large is the residual, and why?
# 3. Add a 2 cm outlier to marker 2 in frame 10 (`m2 = markers.copy(); m2[9, 1, 1] += 0.02`) before
#    registration. How does the residual of that frame change, and how far does the error spread to
#    markers 1 and 3?
#
# <details><summary>Solutions</summary>
#
# 1. The order is found from distances and orientation, not from the input order, so shuffling changes
#    only the indices, not which point is which marker. Markers 1 and 3 are about 0.25 m from marker 2
#    within a few mm of each other, so a swap costs little in distance; the near-tie is broken by the
#    rotation the registration would need (a swap needs a half turn).
# 2. The residual is at the level of rounding (1e-16 m): the truth is rigid and the quaternion solution
#    is exact.
# 3. Least squares spreads the error: the frame's residual grows to about 2/3 of 2 cm at marker 2 and the
#    registered markers of that frame, 1 and 3 included, move by about a third of the outlier (rotation and
#    translation absorb part of it).
#    In the thesis' chain the smoothing before registration removes such outliers: the robust iterations
#    of its `rloess` give an outlier almost no weight. The pipeline's default `loess` has no robust
#    iterations and would spread an outlier over the frames within its span instead (notebook 06); the
#    pipeline's detector and triangulation produce no such outlier on this session.
#
# </details>
