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
# - why the depth of the thesis rig (baselines 0.24 m and 0.45 m, 7.5 m away) is its weak axis;
# - how far the pipeline's positions (calibrated rig, detected centres, then its default `loess`
#   smoothing) are from the truth, per motion axis, and which part of that error is a constant
#   offset that no kinematic quantity sees.
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
import matplotlib.pyplot as plt
import numpy as np
from IPython.display import display

from horsemocap import accuracy, plots, reconstruction, smoothing, widgets
from horsemocap.data import default_session_dir
from horsemocap.sources import FrameSource
from horsemocap.steps.triangulate import common_instants
from horsemocap.workspace import NO_TRUTH, results_for, session_truth

# %% [markdown]
# ## The data: what the pipeline gives triangulation
#
# The default session (Horse 2, canter, rendered by the virtual laboratory, notebook 01) holds
# three motion videos, plumb and static stills, and checkerboard views, nothing else. The pipeline
# (`horsemocap.pipeline`, the same one `horsemocap analyze` runs) takes it up to this step with its
# automatic choices: the frame offsets from the flashlight (notebook 02), the rig **calibrated**
# from the checkerboard views (notebook 03), the plumb and static stills (the static shot is the
# markers' rigid model), the marker centres identified by all cameras together in every
# synchronised frame (notebook 04, section 9), and the analysed frames — the longest run in which
# every marker has a 3D position (seen by two or more cameras, or bridged over a short gap). A
# camera may miss a marker inside that run (the cell below prints how many centres each camera found).
# Cameras that run free (no genlock: each starts its frames at its own instant, the sync step measures
# the phase) are first brought to the reference camera's instants: the triangulate step interpolates
# each camera's tracks there (`common_instants`), and this notebook triangulates the same pixels.
# `results_for` loads what an earlier notebook computed, or computes it (the calibration takes
# about 20 s).

# %%
session_dir = ws.session_dir
analysis = results_for(session_dir, until="triangulate")
sync = analysis.synchronisation                           # the frame offsets the results are in
rig = analysis.rig.rig                                    # calibrated by the pipeline
offsets = sync.offsets                                    # from the flashlight
# the centres at the reference camera's instants: as detected for genlocked cameras, interpolated along each
# camera's tracks for free-running ones (what the pipeline's triangulate step triangulates)
px_ref, _ = common_instants(analysis.detect, lambda *_: None)
a, b = analysis.triangulate.segment                       # the pipeline's analysed frames a..b-1 (synchronised)
marker_px = {cam: px[a:b] for cam, px in px_ref.items()}  # PM per camera, (n, markers, 2)
fps = analysis.session.fps
# where the rig comes from ("(cached ...)" when an earlier run calibrated it: the same rig)
rig_from = analysis.rig.origin(analysis.params.rig.mode)
print(f"rig: {rig_from}; cameras {list(rig.names)}")
print("sync offsets (" + sync.offsets_from + "): "
      + ", ".join(f"{c} {v:d}" for c, v in offsets.items()))
print(f"{sync.n_frames:d} synchronised frames; analysed {a:d}..{b - 1:d} ({b - a:d} frames, "
      f"{b - a:d} / {fps:.0f} = {(b - a) / fps:.2f} s), {analysis.session.marker_count:d} markers")
if analysis.detect.segment != (a, b):
    a_d, b_d = analysis.detect.segment
    print(f"  (the detection kept frames {a_d:d}..{b_d - 1:d}; the triangulate step analyses the longest run of "
          "them in which the markers have 3D positions)")
if analysis.detect.sync.free_running:
    print("free-running cameras: each camera's tracks interpolated to the reference camera's instants (phases "
          + ", ".join(f"{c} {v:+.3f}" for c, v in analysis.detect.sync.phase_frames.items()) + " frame)")
print(f"pipeline's triangulation: {analysis.params.triangulate.mode} mode, median reprojection residual "
      + ", ".join(f"{c} {np.nanmedian(r[a:b]):.3f} px" for c, r in analysis.triangulate.residual_px.items()))

# %% [markdown]
# The ground truth saved beside the session (`truth/`) is used **only to measure errors**: the
# true positions of the analysed frames, the true projections, and the true rig to see how far
# the calibration is from it.

# %%
truth = session_truth(session_dir)                        # None for a recorded session (no truth/ folder)
if truth is None:
    print(NO_TRUTH, "(a recorded session): the errors below are left out, the rest goes on")
true_pos = None
frames_ref = offsets[analysis.session.reference_camera] + np.arange(a, b)   # reference-camera frames
for cam in rig.names if truth is None else ():
    print(f"  {cam:6s}: {int(np.isfinite(marker_px[cam][..., 0]).sum()):d} of {marker_px[cam][..., 0].size:d} "
          f"centres found | focal {rig[cam].focal.mean():7.1f} px")
known = np.ones(b - a, bool) if truth is None else np.isin(frames_ref, truth.ref_frames)
if truth is not None:
    # the truth covers the frames all cameras see whole
    print(f"truth known for {int(known.sum()):d} of {b - a:d} analysed frames (errors below are measured on those); "
          "true offsets " + ", ".join(f"{c} {v:d}" for c, v in truth.offsets.items()))
a, b = a + int(np.argmax(known)), a + len(known) - int(np.argmax(known[::-1]))
marker_px = {cam: px[a:b] for cam, px in px_ref.items()}
frames_ref = offsets[analysis.session.reference_camera] + np.arange(a, b)
if truth is not None:
    true_pos = truth.marker_pos[np.searchsorted(truth.ref_frames, frames_ref)]   # (n, 3, 3), world = left camera frame
for cam in rig.names if truth is not None else ():
    err = np.linalg.norm(marker_px[cam] - truth.marker_px[cam][offsets[cam] + np.arange(a, b), :3], axis=-1)
    cal, tru = rig[cam], truth.rig[cam]
    print(f"  {cam:6s}: {int(np.isfinite(err).sum()):d} of {err.size:d} centres found, RMS error "
          f"{np.sqrt(np.nanmean(err ** 2)):.3f} px | calibrated centre off by "
          f"{1000 * np.linalg.norm(cal.center - tru.center):5.1f} mm, focal {cal.focal.mean():7.1f} px "
          f"(true {tru.focal.mean():7.1f})")

# %% [markdown]
# ## 1 · One stereo pair
#
# Each pixel is first undistorted into normalised coordinates $\mathbf{x}_n = (X/Z, Y/Z)$
# (the inverse of eq. 3.1-3.10). A camera centre and $\mathbf{x}_n$ define a ray; two rays of a
# calibrated pair almost meet. Bouguet's toolbox returns the midpoint of the shortest segment
# between them, in the left camera's frame (and the same point in the right's).

# %%
R_ML, t_ML = reconstruction.relative_pose(rig["left"], rig["middle"])
k = int(np.flatnonzero(np.isfinite(marker_px["left"][:, 0, 0]) & np.isfinite(marker_px["middle"][:, 0, 0]))[0])
xn_L = rig["left"].pixels_to_normalized(marker_px["left"][k, 0])      # the first frame both see marker 1
xn_M = rig["middle"].pixels_to_normalized(marker_px["middle"][k, 0])
XL, XM = reconstruction.stereo_triangulation(xn_L, xn_M, R_ML, t_ML)
print("R_ML =", np.array2string(R_ML, precision=4, suppress_small=True))
print("t_ML (mm) =", np.array2string(t_ML * 1000, precision=2))
print(f"marker 1, frame {k}, left-middle pair, left frame (m):", np.array2string(XL, precision=4))
if truth is None:
    print("true position:", NO_TRUTH)
else:
    print("                               true position (m):   ", np.array2string(true_pos[k, 0], precision=4))
    print(f"error: {1000 * np.linalg.norm(XL - true_pos[k, 0]):.1f} mm")

# %% [markdown]
# **The geometry of one pair.** Below, the same left-middle pair in a frame where the middle camera
# sees marker 1 near its image centre. Left: seen from above, each camera's ray through the marker's
# pixel; the two rays meet at the marker, at a small angle (the baseline is short against the depth),
# which is why depth is the least precise coordinate. Right: all the points of the left camera's ray
# project in the middle camera onto one line, the *epipolar line* (it ends where the ray's far end
# vanishes). The marker's pixel in the middle camera lies on it: a second camera need only search that
# line for the match, and a pixel far from it is the wrong region or a bad calibration.

# %%
both = np.isfinite(marker_px["left"][:, 0, 0]) & np.isfinite(marker_px["middle"][:, 0, 0])
k_mid = int(np.nanargmin(np.where(both, np.abs(marker_px["middle"][:, 0, 0] - rig["middle"].size[0] / 2), np.nan)))
frame_mid = FrameSource(analysis.session.motion["middle"]).frame(offsets["middle"] + a + k_mid)
fig = plots.plot_stereo_geometry(rig["left"], rig["middle"], marker_px["left"][k_mid, 0],
                                 marker_px["middle"][k_mid, 0], image_b=frame_mid)
plt.show()

# %% [markdown]
# ## 2 · The thesis mode: three pairs, averaged
#
# `triangulate(..., mode="thesis")` does the three pairs. The middle-right result comes out in the
# middle camera frame ($\mathbf{CM}_{MR,M}$) and is moved into the left frame with eq. 5.3-5.4.

# %%
thesis = reconstruction.triangulate(rig, marker_px, mode="thesis")
for name, pair in thesis.pairs.items():
    seen_pair = np.flatnonzero(np.isfinite(pair.points_local[:, 0, 0]))   # frames where the pair sees marker 1
    first = (f"marker 1 first seen in frame {seen_pair[0]:2d} at {np.array2string(pair.points_local[seen_pair[0], 0], precision=3)}"
             if len(seen_pair) else "marker 1 never seen by both")
    print(f"{name:13s} in {pair.cameras[0]:6s} frame: {first}", end="")
    if truth is None:
        print()
        continue
    err = 1000 * np.linalg.norm(pair.points - true_pos, axis=-1)
    print(f"   error vs truth: median {np.nanmedian(err):5.1f} mm, max {np.nanmax(err):5.1f} mm")
if truth is None:
    print("errors vs truth:", NO_TRUTH)
else:
    err = 1000 * np.linalg.norm(thesis.points - true_pos, axis=-1)
    print(f"average (eq. 5.5)                                        error vs truth: median {np.nanmedian(err):5.1f} mm, max {np.nanmax(err):5.1f} mm")

# %% [markdown]
# Each pair's error is mostly depth. Under all of them sits the calibrated rig's constant offset,
# mostly in depth (section 5 measures and separates it), so the pairs differ less than their baselines
# suggest; the long left-right pair (0.45 m) has the smallest spread. The average of eq. 5.5 is
# about as good as the best pair, not $\sqrt{3}$ times better: the pairs share cameras, so their
# errors are correlated, and the short-baseline pairs weigh as much as the long one.
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
ui_mode = widgets.ui_triangulation_mode(analysis.params.triangulate.mode)
ws.bind(ui_mode, "triangulation")
display(ui_mode)

# %%
tri = reconstruction.triangulate(rig, marker_px, mode=ui_mode.value)
print(f"mode: {tri.mode}; valid points: {int(tri.valid.sum()):d} of {tri.valid.size:d}")
for cam, rms in tri.rms_residual_px().items():
    print(f"  RMS reprojection residual {cam:6s}: {rms:.3f} px")
if tri.mode == analysis.params.triangulate.mode:
    diff = np.nanmax(np.abs(tri.points - analysis.triangulate.points[a:b]))
    print(f"largest difference from the pipeline's points (analysis.triangulate.points, frames "
          f"{a:d}..{b - 1:d}): {1e6 * diff:.3f} micrometres")

# %% [markdown]
# The residuals printed above are small fractions of a pixel: the calibrated geometry is
# consistent with the detections. A residual much larger than the detector's precision would point
# to a wrong detection or a bad calibration. (Small residuals do not prove the calibration right:
# a rig slightly wrong in scale or position reprojects just as well; section 5 measures that.)

# %%
_ = plots.plot_triangulation_residuals(tri)
plt.show()

# %% [markdown]
# ## 4 · Thesis Figure 8.9 (a): the markers in the left camera frame
#
# X is the direction of travel across the image, Y points down, Z away from the cameras (the
# depth). The thin black lines are the truth.

# %%
_ = plots.plot_camera_positions(tri.points, truth=true_pos, title=f"{analysis.session.name}, left camera frame")
plt.show()

# %% [markdown]
# ## 5 · Thesis mode vs joint mode against the truth
#
# Errors are easiest to read along the motion axes of section 5.3 (x along the travel, y along
# gravity, z the rest — here almost exactly the depth). We use the truth's motion axes so that the
# comparison is about triangulation only; notebook 06 builds them from the data.
#
# Two numbers per axis. The **RMSE** against the true positions, and the RMSE once the **constant
# offset** (the mean error over every frame and marker, printed as *bias*) is removed. A calibrated
# rig is never exactly the true one: its reference camera's intrinsics and the baselines are off by
# a fraction of a percent, which moves (and slightly scales) the whole reconstruction by several
# millimetres, up to about a centimetre (notebook 06, section 8, measures it over many calibrations). A constant offset changes no velocity, acceleration or angle, so the second number
# is the one that matters for the kinematics; the first is what a position measurement would get.
# "Smoothed" is the pipeline's smoothing step (`smoothing.smooth_positions`, span 0.1, at least 7
# frames per window) with its default, `loess` (MATLAB's `smooth(y, 0.1, 'loess')`: local quadratic,
# tricube weights, no robust iterations), and with the thesis' `rloess`; "triangulated" is the
# option `smoothing_method="none"`. Notebook 06 explains why the default is `loess` and not the
# thesis' `rloess`. The last rows triangulate the same detections with the **true** rig (a
# comparison only the virtual laboratory allows): what is left is the detector's error.

# %%
if truth is None:
    print(NO_TRUTH)
else:
    A = truth.motion_axes                                      # rows: true x-, y-, z-motion


    def errors_mm(points):
        """RMSE per true motion axis, the mean error (bias) and the RMSE without it, in mm."""
        est, ref = points @ A.T, true_pos @ A.T
        bias = np.nanmean((est - ref).reshape(-1, 3), axis=0)
        return 1000 * accuracy.rmse_axes(est, ref), 1000 * bias, 1000 * accuracy.rmse_axes(est - bias, ref)


    PIPE = analysis.params.smooth.method                    # the pipeline's default: "loess"
    SPAN = analysis.params.smooth.span
    joint = reconstruction.triangulate(rig, marker_px, mode="joint")
    rows_table, errors = {}, {}
    for mode, t in (("thesis", thesis), ("joint", joint)):
        rows_table[f"{mode}, triangulated (none)"] = errors_mm(t.points)
        rows_table[f"{mode}, smoothed: {PIPE} {SPAN:.1f} (pipeline)"] = errors_mm(
            smoothing.smooth_positions(t.points, SPAN, PIPE, nan="omit"))
        rows_table[f"{mode}, smoothed: rloess 0.1 (thesis)"] = errors_mm(
            smoothing.smooth_positions(t.points, 0.1, "rloess", nan="omit"))
    for mode in ("thesis", "joint"):
        rows_table[f"{mode}, TRUE rig, triangulated"] = errors_mm(
            reconstruction.triangulate(truth.rig, marker_px, mode=mode).points)
    print(f"{'':42s} {'RMSE x':>7s} {'y':>6s} {'z':>6s} | {'bias x':>7s} {'y':>6s} {'z':>6s} | "
          f"{'no bias x':>9s} {'y':>6s} {'z':>6s}   (mm)")
    for label, (r, bias, rc) in rows_table.items():
        print(f"{label:42s} {r[0]:7.2f} {r[1]:6.2f} {r[2]:6.2f} | {bias[0]:7.2f} {bias[1]:6.2f} {bias[2]:6.2f} | "
              f"{rc[0]:9.2f} {rc[1]:6.2f} {rc[2]:6.2f}")
        if "TRUE" not in label:
            errors[label.replace(", smoothed: ", " ").replace(", triangulated", "")] = (r, rc)

# %%
if truth is None:
    print(NO_TRUTH)
else:
    fig, (ax_abs, ax_rel) = plt.subplots(1, 2, figsize=(12, 3.6), sharey=True)
    plots.plot_triangulation_modes({k: v[0] for k, v in errors.items()}, ax=ax_abs, target=3.0)
    plots.plot_triangulation_modes({k: v[1] for k, v in errors.items()}, ax=ax_rel, target=3.0)
    ax_abs.set_title("RMSE vs truth (calibrated rig)")
    ax_rel.set_title("RMSE with the constant offset removed")
    fig.tight_layout()
    plt.show()

# %% [markdown]
# **Reading the numbers** (the cell below prints each one the text refers to).
#
# - The *bias* is the calibration's: with the true rig the same detections have almost none. It
#   is largest along the depth, then along gravity, smallest along the travel. The bias along
#   gravity is why the absolute y-motion RMSE is several millimetres although the vertical motion
#   itself is measured to a fraction of a millimetre (the "no bias" column).
# - The accuracy goal of this reproduction is x- and y-motion RMSE below 3 mm **after smoothing**, i.e. with the
#   pipeline's default `loess`. The computed check below says, for each mode, whether the absolute
#   and the bias-removed errors meet it.
# - `loess` changes little here: it lowers the x- and z-motion errors a little and adds a few
#   hundredths of a millimetre vertically, where the positions are already good to a fraction of
#   a millimetre and a 7-frame quadratic follows the motion closely. The thesis' `rloess` adds
#   y-motion error once the bias is removed (its robust iterations move the last frames of the
#   record by centimetres, notebook 06).
# - The joint mode is no worse than the thesis' average on these detections (the last line:
#   differences of hundredths of a millimetre; on this rig the three pairs compose almost exactly).

# %%
if truth is None:
    print(NO_TRUTH)
else:
    TARGET_MM = 3.0
    pipe_row = f"smoothed: {PIPE} {SPAN:.1f} (pipeline)"


    def verdict(v):
        return "meets" if v < TARGET_MM else "MISSES"


    for mode in ("thesis", "joint"):
        r, bias, rc = rows_table[f"{mode}, {pipe_row}"]
        print(f"{mode:6s} (pipeline smoothing '{PIPE}'): absolute x {r[0]:.2f} mm {verdict(r[0])}, "
              f"y {r[1]:.2f} mm {verdict(r[1])} | bias removed x {rc[0]:.2f} mm {verdict(rc[0])}, "
              f"y {rc[1]:.2f} mm {verdict(rc[1])} | bias x {bias[0]:+.2f}, y {bias[1]:+.2f}, z {bias[2]:+.2f} mm")
    for label in ("triangulated (none)", "smoothed: rloess 0.1 (thesis)"):
        rc_other = rows_table[f"joint, {label}"][2]
        print(f"joint, {label:30s}: bias removed y {rc_other[1]:.2f} mm, pipeline's {PIPE} minus this: "
              + ", ".join(f"{n} {d:+.2f}" for n, d in zip("xyz", rows_table[f"joint, {pipe_row}"][2] - rc_other)) + " mm")
    rj, rt = rows_table[f"joint, {pipe_row}"][2], rows_table[f"thesis, {pipe_row}"][2]
    print(f"joint minus thesis ({PIPE}), bias removed (mm): " + ", ".join(f"{n} {d:+.2f}" for n, d in zip("xyz", rj - rt)))

# %% [markdown]
# The depth (z-motion) error is the largest: the rig's baselines are short for its distance. For a
# pair of baseline $B$ and focal length $f$ (px), a pixel error $\sigma$ on each image gives a depth
# error $\sigma_Z \approx \sqrt{2}\,Z^2\sigma/(fB)$; with 0.1 px, a typical centroid precision for
# 6 px discs:

# %%
from itertools import combinations

Z = float(np.nanmean(tri.points[..., 2]))          # the markers' depth
f = float(rig["left"].focal.mean())
for cam_a, cam_b in combinations(rig.names, 2):
    pair, B = f"{cam_a}-{cam_b}", float(np.linalg.norm(rig[cam_a].center - rig[cam_b].center))
    print(f"{pair:13s} B = {B:.3f} m: sigma_Z ~ {1000 * Z**2 * np.sqrt(2) * 0.1 / (f * B):5.1f} mm"
          f" for 0.1 px on each image (Z = {Z:.2f} m)")

# %% [markdown]
# The detector is better than 0.1 px on these renders, hence the smaller errors above. The
# x-motion error is larger than the y-motion error for the same reason as the depth: when the
# horse is to the side of the image the viewing rays are oblique, and part of the depth error
# projects onto the direction of travel. How both modes degrade with noisier pixels — the true
# projections plus 0.1 px of Gaussian noise (`accuracy.noisy_projections`), triangulated with the
# calibrated rig:

# %%
if truth is None:
    print(NO_TRUTH)
else:
    rng = np.random.default_rng(2009)
    noisy_all = accuracy.noisy_projections(truth, offsets, sync.n_frames, 3, 0.1, rng)
    noisy_px = {cam: px[a:b] for cam, px in noisy_all.items()}
    for mode in ("thesis", "joint"):
        p = reconstruction.triangulate(rig, noisy_px, mode=mode).points
        for label, q in (("none", p), (f"{PIPE} {SPAN:.1f}", smoothing.smooth_positions(p, SPAN, PIPE)),
                         ("rloess 0.1", smoothing.smooth_positions(p, 0.1, "rloess"))):
            r, _, rc = errors_mm(q)
            print(f"0.1 px noise, {mode:6s}, {label:10s}: RMSE x {r[0]:5.2f} {verdict(r[0]):6s}, y {r[1]:5.2f}, "
                  f"z {r[2]:6.2f} mm | bias removed x {rc[0]:5.2f} {verdict(rc[0]):6s}, y {rc[1]:5.2f}, z {rc[2]:6.2f} mm")

# %% [markdown]
# With 0.1 px of noise the x-motion error misses 3 mm in both modes, smoothed or not: the rig, not
# the algorithm, limits it. Here smoothing earns its place: both smoothers lower the z errors and
# `loess` the x errors too (`rloess` can leave x where it was); `loess` lowers the y-motion error
# as well, where the robust iterations of `rloess` add to it.
# That is the situation of the herd sessions of notebook 06, section 3, where `loess` is the best
# of the three; the curve fits of notebook 09 filter further.
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
    print(f"frame {k:d}, marker {m + 1:d}: cameras used {g.n_views[k, m]:d}, reason '{g.reason[k, m]}', "
          f"point {np.array2string(g.points[k, m], precision=3)}")
two = rig.subset(["left", "right"])
if truth is None:
    print("left + right only, errors vs truth:", NO_TRUTH)
else:
    r2, _, rc2 = errors_mm(reconstruction.triangulate(two, {c: marker_px[c] for c in two.names}, mode="joint").points)
    print(f"left + right only: RMSE x {r2[0]:.2f} mm, y {r2[1]:.2f} mm, z {r2[2]:.2f} mm "
          f"(bias removed: {rc2[0]:.2f}, {rc2[1]:.2f}, {rc2[2]:.2f} mm)")

# %% [markdown]
# A wrong detection is worse than a missing one. If a camera swaps two markers, the rays no longer
# meet and the reprojection residual jumps from hundredths of a pixel to tens of pixels. The joint
# mode checks it (`max_residual_px`, default 2 px): with three or more views it leaves out the
# camera whose removal makes the others agree, and records it in `rejected`; the thesis' average
# has no such check.

# %%
# a frame where every camera sees markers 1 and 2 (the one nearest frame 10)
seen12 = np.all([np.isfinite(px[:, :2, 0]).all(axis=1) for px in marker_px.values()], axis=0)
k_sw = int(np.flatnonzero(seen12)[np.argmin(np.abs(np.flatnonzero(seen12) - 10))])
swapped = {c: v.copy() for c, v in marker_px.items()}
swapped["middle"][k_sw, [0, 1]] = swapped["middle"][k_sw, [1, 0]]     # markers 1 and 2 swapped
for mode in ("thesis", "joint"):
    s_ = reconstruction.triangulate(rig, swapped, mode=mode)
    if truth is None:   # how far the swap moves the point, against the same mode without it
        clean = reconstruction.triangulate(rig, marker_px, mode=mode).points[k_sw, 0]
        off = f"moved {1000 * np.linalg.norm(s_.points[k_sw, 0] - clean):6.1f} mm by the swap (no truth)"
    else:
        off = f"{1000 * np.linalg.norm(s_.points[k_sw, 0] - true_pos[k_sw, 0]):6.1f} mm off (vs truth)"
    print(f"{mode:6s}: marker 1 in frame {k_sw} is {off}; middle residual {s_.residual_px['middle'][k_sw, 0]:5.1f} px; "
          f"rejected by the check: {bool(s_.rejected['middle'][k_sw, 0])}")

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
# 2. `accuracy.noisy_projections(truth, offsets, sync.n_frames, 3, 0.3, rng)`, sliced
#    `[a:b]`: the bias-removed errors grow linearly with the noise (three times the noise, three
#    times the RMSE); the calibration's bias does not change.
# 3. With `c = rig["middle"]`, `moved = c.with_pose(c.rotation, c.translation + c.rotation_matrix @ [-1, 0, 0])`
#    (the centre moves by +1 m along x), build `Rig((rig["left"], moved, rig["right"]))`, project
#    `true_pos`, add noise and triangulate: the depth error drops roughly in proportion to the
#    widest baseline.
#
# </details>
