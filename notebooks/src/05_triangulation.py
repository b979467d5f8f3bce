# %% [markdown]
# # 05 · Triangulation: from three images to one 3D point
#
# **What you will learn**
# - how a stereo pair turns two pixels into a 3D point (Bouguet's `stereo_triangulation`, the
#   midpoint of the two viewing rays);
# - the thesis' recipe for three cameras (section 5.1, Appendix A step 5): triangulate the pairs
#   left-middle, left-right and middle-right, move the middle-right result from the middle camera
#   frame into the left one, and average the three (eq. 5.1-5.5);
# - a joint alternative that uses every camera seeing a point at once (linear DLT refined by
#   minimising the reprojection error), which also works with two cameras or more than three;
# - reprojection residuals per camera and frame, and what happens to a marker seen by one camera;
# - why the depth of the thesis rig (baselines 0.24 m and 0.45 m, 7.5 m away) is its weak axis.
#
# The equations (thesis 5.1). A stereo pair relates its two camera frames by
#
# $$\mathbf{x}_R = \mathbf{R}_{RL}\mathbf{x}_L + \mathbf{t}_{RL}\qquad(5.1)$$
#
# so for the left-middle pair $\mathbf{x}_M = \mathbf{R}_{ML}\mathbf{x}_L + \mathbf{t}_{ML}$ (5.2), hence
#
# $$\mathbf{x}_L = \mathbf{R}_{ML}^{-1}(\mathbf{x}_M - \mathbf{t}_{ML})\qquad(5.3)$$
#
# applied to every marker $m$ and frame $k$ of the middle-right result, $\mathbf{CM}_{MR,L}(m,:,k) =
# \mathbf{R}_{ML}^{-1}(\mathbf{CM}_{MR,M}^T(m,:,k) - \mathbf{t}_{ML})$ (5.4), and finally
#
# $$\mathbf{CM}_L = \tfrac{1}{3}\left(\mathbf{CM}_{LM,L} + \mathbf{CM}_{LR,L} + \mathbf{CM}_{MR,L}\right)\qquad(5.5)$$

# %%
import json

import matplotlib.pyplot as plt
import numpy as np
from IPython.display import display

from horsemocap import detection, frames, plots, reconstruction, smoothing, widgets
from horsemocap.camera import read_rig
from horsemocap.data import default_session_dir
from horsemocap.sources import FrameSource
from horsemocap.virtuallab import load_truth

# %% [markdown]
# ## The data
#
# The default session (Horse 2, canter, rendered by the virtual laboratory, notebook 01). The
# pixels are what the pipeline uses: the marker centres found by the detector of notebook 04 in
# each camera's video (`detection.detect_markers`), over the synchronised frames (left-camera frame
# $k$ is frame $k + \mathrm{offset}_c - \mathrm{offset}_L$ of camera $c$, eq. 3.11-3.13). The rig
# is the session's calibrated `rig.toml`. The ground truth, saved beside the session, is used to
# choose the analysed frames and the offsets (notebook 02 finds the offsets; here we skip that
# step) and to measure errors — never by the algorithms.

# %%
session = default_session_dir()
meta = json.loads((session / "session.json").read_text())
truth = load_truth(session)
rig = read_rig(session / "calibration" / "rig.toml")
fps = float(meta["fps"])
ref_frames = truth.ref_frames                      # analysed left-camera frames
marker_px = {}
for cam in rig.names:
    k = ref_frames - truth.offsets["left"] + truth.offsets[cam]
    video = FrameSource(session / meta["motion"][cam])
    marker_px[cam] = detection.detect_markers(video.read(int(k[0]), int(k[-1]) + 1), 3).marker_px
true_pos = truth.marker_pos                        # (n, 3, 3) world = left camera frame
print(f"{len(ref_frames)} frames ({ref_frames[0]}..{ref_frames[-1]} of the left camera), "
      f"{true_pos.shape[1]} markers, cameras {rig.names}")
for cam in rig.names:
    k = ref_frames - truth.offsets["left"] + truth.offsets[cam]
    err = np.linalg.norm(marker_px[cam] - truth.marker_px[cam][k, :3], axis=-1)
    print(f"  {cam:6s}: {int(np.isfinite(err).sum())} of {err.size} centres found, "
          f"error vs the true projection RMS {np.sqrt(np.nanmean(err ** 2)):.3f} px")

# %% [markdown]
# ## 1 · One stereo pair
#
# Each pixel is first undistorted into normalised coordinates $\mathbf{x}_n = (X/Z, Y/Z)$
# (the inverse of eq. 3.1-3.10). A camera centre and $\mathbf{x}_n$ define a ray; two rays of a
# calibrated pair almost meet. Bouguet's toolbox returns the midpoint of the shortest segment
# between them, in the left camera's frame (and the same point in the right's).

# %%
R_ML, t_ML = reconstruction.relative_pose(rig["left"], rig["middle"])
xn_L = rig["left"].pixels_to_normalized(marker_px["left"][0, 0])
xn_M = rig["middle"].pixels_to_normalized(marker_px["middle"][0, 0])
XL, XM = reconstruction.stereo_triangulation(xn_L, xn_M, R_ML, t_ML)
print("R_ML =", np.array2string(R_ML, precision=4, suppress_small=True))
print("t_ML (mm) =", np.array2string(t_ML * 1000, precision=2))
print("marker 1, frame 0, left-middle pair, left frame (m):", np.array2string(XL, precision=4))
print("                               true position (m):   ", np.array2string(true_pos[0, 0], precision=4))
print(f"error: {1000 * np.linalg.norm(XL - true_pos[0, 0]):.1f} mm")

# %% [markdown]
# ## 2 · The thesis mode: three pairs, averaged
#
# `triangulate(..., mode="thesis")` does the three pairs. The middle-right result comes out in the
# middle camera frame ($\mathbf{CM}_{MR,M}$) and is moved into the left frame with eq. 5.3-5.4.

# %%
thesis = reconstruction.triangulate(rig, marker_px, mode="thesis")
for name, pair in thesis.pairs.items():
    err = 1000 * np.linalg.norm(pair.points - true_pos, axis=-1)
    print(f"{name:13s} in {pair.cameras[0]:6s} frame: first point {np.array2string(pair.points_local[0, 0], precision=3)}"
          f"   error vs truth: median {np.median(err):5.1f} mm, max {err.max():5.1f} mm")
err = 1000 * np.linalg.norm(thesis.points - true_pos, axis=-1)
print(f"average (eq. 5.5)                                        error vs truth: median {np.median(err):5.1f} mm, max {err.max():5.1f} mm")

# %% [markdown]
# Each pair's error is mostly depth, and it shrinks with the pair's baseline (left-right, 0.45 m,
# is the best). The average of eq. 5.5 is about as good as the best pair, not $\sqrt{3}$ times
# better: the pairs share cameras, so their errors are correlated, and the short-baseline pairs
# weigh as much as the long one.
#
# ## 3 · The joint mode
#
# With $P_c = [R_c\,|\,t_c]$ the pose of camera $c$ and $\mathbf{x}_{n,c}$ its normalised
# observation, each camera contributes two linear equations
# $x_c\,P_c^{(3)}\tilde{\mathbf{X}} - P_c^{(1)}\tilde{\mathbf{X}} = 0$,
# $y_c\,P_c^{(3)}\tilde{\mathbf{X}} - P_c^{(2)}\tilde{\mathbf{X}} = 0$; the least-squares solution
# (SVD) starts a damped Gauss-Newton that minimises the sum of squared pixel reprojection errors
# over the cameras that saw the point — the maximum-likelihood point for Gaussian pixel noise.
# Choose the mode the rest of the notebook uses (default: the pipeline's, joint):

# %% tags=["nbval-ignore-output"]
ui_mode = widgets.ui_triangulation_mode()
display(ui_mode)

# %%
tri = reconstruction.triangulate(rig, marker_px, mode=ui_mode.value)
print(f"mode: {tri.mode}; valid points: {int(tri.valid.sum())} of {tri.valid.size}")
for cam, rms in tri.rms_residual_px().items():
    print(f"  RMS reprojection residual {cam:6s}: {rms:.3f} px")

# %% [markdown]
# The residuals are of the order of the detector's error (a few hundredths of a pixel): the
# geometry is consistent. A residual much larger than the detector's precision would point to a
# wrong detection or a bad calibration.

# %%
_ = plots.plot_triangulation_residuals(tri)
plt.show()

# %% [markdown]
# ## 4 · Thesis Figure 8.9 (a): the markers in the left camera frame
#
# X is the direction of travel across the image, Y points down, Z away from the cameras (the
# depth). The thin black lines are the truth.

# %%
_ = plots.plot_camera_positions(tri.points, truth=true_pos, title="Horse 2 canter, left camera frame")
plt.show()

# %% [markdown]
# ## 5 · Thesis mode vs joint mode against the truth
#
# Errors are easiest to read along the motion axes of section 5.3 (x along the travel, y along
# gravity, z the rest — here almost exactly the depth). We use the truth's motion axes so that the
# comparison is about triangulation only; notebook 06 builds them from the data.

# %%
joint = reconstruction.triangulate(rig, marker_px, mode="joint")
A = truth.motion_axes
errors = {}
for label, t in (("thesis", thesis), ("joint", joint)):
    raw = frames.rmse_per_axis(t.points @ A.T, true_pos @ A.T)
    smoothed = frames.rmse_per_axis(smoothing.smooth_positions(t.points, nan="omit") @ A.T, true_pos @ A.T)
    errors[f"{label} raw"] = 1000 * raw
    errors[f"{label} smoothed"] = 1000 * smoothed
for label, e in errors.items():
    print(f"{label:16s} RMSE x-motion {e[0]:5.2f} mm   y-motion {e[1]:5.2f} mm   z-motion {e[2]:6.2f} mm")

# %%
_ = plots.plot_triangulation_modes(errors)
plt.show()

# %% [markdown]
# **Reading the numbers.** The vertical (y-motion) is measured to a fraction of a millimetre. The
# depth (z-motion) error is about twenty times larger: the rig's baselines are short for its
# distance. For a pair of baseline $B$ and focal length $f$ (px), a pixel error $\sigma$ on each
# image gives a depth error $\sigma_Z \approx \sqrt{2}\,Z^2\sigma/(fB)$; with 0.1 px, a typical
# centroid precision for 6 px discs:

# %%
Z = float(np.mean(true_pos[..., 2]))
f = float(rig["left"].focal.mean())
for a, b in (("left", "middle"), ("left", "right"), ("middle", "right")):
    pair, B = f"{a}-{b}", float(np.linalg.norm(rig[a].center - rig[b].center))
    print(f"{pair:13s} B = {B:.3f} m: sigma_Z ~ {1000 * Z**2 * np.sqrt(2) * 0.1 / (f * B):5.1f} mm"
          f" for 0.1 px on each image (Z = {Z:.2f} m)")

# %% [markdown]
# The detector is better than 0.1 px on these renders, hence the smaller errors above. The
# x-motion error is larger than the y-motion error for the same reason as the depth: when the
# horse is to the side of the image the viewing rays are oblique, and part of the depth error
# projects onto the direction of travel. The joint mode is the maximum-likelihood estimate and is
# no worse than the thesis' average; on this rig (whose three pairs compose exactly) the two are
# close. How both degrade with noisier pixels — the true projections plus 0.1 px of Gaussian
# noise:

# %%
rng = np.random.default_rng(2009)
noisy_px = {}
for cam in rig.names:
    k = ref_frames - truth.offsets["left"] + truth.offsets[cam]
    noisy_px[cam] = truth.marker_px[cam][k, :3] + rng.normal(0.0, 0.1, (len(k), 3, 2))
for mode in ("thesis", "joint"):
    p = smoothing.smooth_positions(reconstruction.triangulate(rig, noisy_px, mode=mode).points)
    e = 1000 * frames.rmse_per_axis(p @ A.T, true_pos @ A.T)
    print(f"0.1 px noise, {mode:6s}, smoothed: RMSE x-motion {e[0]:5.2f} mm, y-motion {e[1]:5.2f} mm, "
          f"z-motion {e[2]:6.2f} mm")

# %% [markdown]
# With 0.1 px the x-motion error exceeds 3 mm: the rig, not the algorithm, limits it.
#
# ## 6 · Missing views
#
# A marker seen by fewer than two cameras cannot be triangulated: it becomes NaN with its reason,
# never silently dropped. The joint mode uses whichever cameras remain.

# %%
gappy = {c: v.copy() for c, v in marker_px.items()}
gappy["middle"][5, 0] = np.nan                      # frame 5, marker 1: middle and right lost
gappy["right"][5, 0] = np.nan
gappy["left"][6, 2] = np.nan                        # frame 6, marker 3: left lost
g = reconstruction.triangulate(rig, gappy, mode="joint")
for k, m in ((5, 0), (6, 2)):
    print(f"frame {k}, marker {m + 1}: cameras used {g.n_views[k, m]}, reason '{g.reason[k, m]}', "
          f"point {np.array2string(g.points[k, m], precision=3)}")
two = rig.subset(["left", "right"])
lr = reconstruction.triangulate(two, {c: marker_px[c] for c in two.names}, mode="joint")
e2 = 1000 * frames.rmse_per_axis(lr.points @ A.T, true_pos @ A.T)
print(f"left + right only: RMSE x {e2[0]:.2f} mm, y {e2[1]:.2f} mm, z {e2[2]:.2f} mm")

# %% [markdown]
# A wrong detection is worse than a missing one. If a camera swaps two markers, the rays no longer
# meet and the reprojection residual jumps from a tenth of a pixel to tens of pixels. The joint
# mode checks it (`max_residual_px`, default 2 px): with three or more views it leaves out the
# camera whose removal makes the others agree, and records it in `rejected`; the thesis' average
# has no such check.

# %%
swapped = {c: v.copy() for c, v in marker_px.items()}
swapped["middle"][10, [0, 1]] = swapped["middle"][10, [1, 0]]     # frame 10: markers 1 and 2 swapped
for mode in ("thesis", "joint"):
    s_ = reconstruction.triangulate(rig, swapped, mode=mode)
    err = 1000 * np.linalg.norm(s_.points[10, 0] - true_pos[10, 0])
    print(f"{mode:6s}: marker 1 in frame 10 is {err:6.1f} mm off; middle residual "
          f"{s_.residual_px['middle'][10, 0]:5.1f} px; rejected by the check: {bool(s_.rejected['middle'][10, 0])}")

# %% [markdown]
# ## Exercises
#
# 1. Triangulate with the left-middle pair alone (`mode="thesis", pairs=[("left", "middle")]`) and
#    compare its depth error with the left-right pair. Which baseline wins, and by how much?
# 2. Rebuild `noisy_px` with 0.3 px of noise. How do the three RMSEs scale?
# 3. Move the middle camera 1 m to the right in a copy of the rig (`Camera.with_pose`), project the
#    truth, and triangulate again. What happens to the depth error?
#
# <details><summary>Solutions</summary>
#
# 1. `reconstruction.triangulate(rig, noisy_px, mode="thesis", pairs=[("left", "middle")])`: for
#    random pixel noise the depth error scales like $1/B$, so the 0.24 m pair is about 1.9 times
#    worse than the 0.45 m one. With the detector's pixels the ratio is smaller (section 2): part of
#    their error is the same in neighbouring cameras and cancels in the disparity.
# 2. All errors are linear in the pixel noise: three times the noise, three times the RMSE.
# 3. With `c = rig["middle"]`, `moved = c.with_pose(c.rotation, c.translation + c.rotation_matrix @ [-1, 0, 0])`
#    (the centre moves by +1 m along x), build `Rig((rig["left"], moved, rig["right"]))`, project
#    `true_pos`, add noise and triangulate: the depth error drops roughly in proportion to the
#    widest baseline.
#
# </details>
