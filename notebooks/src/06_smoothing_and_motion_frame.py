# %% [markdown]
# # 06 · Robust smoothing and the motion reference frame
#
# **What you will learn**
# - what MATLAB's `smooth(y, 0.1, 'rloess')` — the thesis' smoother (section 5.2.2, Appendix A
#   step 6) — computes, rule by rule, and why robust smoothing resists outliers (Figure 5.2);
# - why those rules misbehave on a record as short as the thesis' (38 frames), and what the
#   pipeline does instead;
# - the gravity direction from a plumb line with two markers;
# - the gait period, found from the data (the thesis user typed `period = 18`);
# - the motion reference frame of section 5.3: x along the net displacement over one or two
#   periods, y along gravity (down), z = x × y (Figures 8.9 b and 8.10).
#
# The equations (thesis 5.3):
#
# $$\mathbf{u}_1 = \frac{\mathbf{x}(T) - \mathbf{x}(0)}{|\mathbf{x}(T) - \mathbf{x}(0)|}\ (5.6)\quad\text{or}\quad
#   \mathbf{u}_1 = \frac{\mathbf{x}(2T) - \mathbf{x}(0)}{|\mathbf{x}(2T) - \mathbf{x}(0)|}\ (5.7)$$
#
# $$\mathbf{u}_3 = \frac{\mathbf{u}_1\times\mathbf{u}_2^e}{|\mathbf{u}_1\times\mathbf{u}_2^e|}\ (5.8),\qquad
#   \mathbf{u}_2 = \mathbf{u}_3\times\mathbf{u}_1\ (5.9),\qquad
#   \mathbf{R}_{CM} = [\mathbf{u}_1\,|\,\mathbf{u}_2\,|\,\mathbf{u}_3]\ (5.10)$$
#
# $$\mathbf{x}_C = \mathbf{R}_{CM}\mathbf{x}_M\ (5.11),\qquad \mathbf{x}_M = \mathbf{R}_{CM}^{-1}\mathbf{x}_C\ (5.12),\qquad
#   t = (k-1)/\mathrm{fps}\ (5.13)$$
#
# with $\mathbf{u}_2^e$ the gravity direction estimated from the plumb and $k$ the 1-based frame
# number (0-based here: $t = k/\mathrm{fps}$).

# %%
import json

import matplotlib.pyplot as plt
import numpy as np
from IPython.display import display

from horsemocap import detection, frames, plots, reconstruction, smoothing, widgets
from horsemocap.camera import read_rig
from horsemocap.data import default_session_dir
from horsemocap.sources import FrameSource, read_image
from horsemocap.virtuallab import load_truth

# %% [markdown]
# ## The data
#
# As in notebook 05: the default session, its calibrated rig, the synchronised frames, the marker
# centres found by the detector (`detection.detect_markers`) and triangulated in joint mode. The
# plumb markers are found by the detector in the plumb stills (`detection.detect_still`, top marker
# first). The truth chooses the analysed frames and offsets (notebook 02's job) and measures
# errors.

# %%
session = default_session_dir()
meta = json.loads((session / "session.json").read_text())
truth = load_truth(session)
rig = read_rig(session / "calibration" / "rig.toml")
fps = float(meta["fps"])
ref_frames = truth.ref_frames
marker_px = {}
for cam in rig.names:
    k = ref_frames - truth.offsets["left"] + truth.offsets[cam]
    video = FrameSource(session / meta["motion"][cam])
    marker_px[cam] = detection.detect_markers(video.read(int(k[0]), int(k[-1]) + 1), 3).marker_px
plumb_px = {cam: detection.detect_still(read_image(session / meta["plumb"][cam]), 2)[None]
            for cam in rig.names}          # (1, 2, 2): upper marker (tail) then lower (tip)
tri = reconstruction.triangulate(rig, marker_px, mode="joint")
points = tri.points                        # CM_L, (frames, markers, 3)
true_pos = truth.marker_pos
A_true = truth.motion_axes                 # rows: true x-, y-, z-motion directions
n = points.shape[0]
print(f"{n} frames, {points.shape[1]} markers, {int(tri.valid.sum())} of {tri.valid.size} positions valid; "
      f"plumb found in {len(plumb_px)} cameras")

# %% [markdown]
# ## 1 · Smoothing, the MATLAB way
#
# `smooth(y, span, 'rloess')` (MathWorks, *Curve Fitting Toolbox: Smoothing Data*; rules written
# down in `shared/notes/matlab-algorithms.md`):
#
# 1. **span** — a fraction becomes `ceil(span * n)` points, at most $n$; on uniform data an even
#    span is made odd: $n = 100 \to 11$, $n = 89 \to 9$, $n = 38 \to 5$.
# 2. **local fit** — at each sample a weighted least-squares quadratic (`loess`; linear for
#    `lowess`) over the span nearest samples; at the ends the window is shifted so it still holds
#    `span` samples (no padding, no reflection). The smoothed value is the fit at the sample.
# 3. **tricube weights** $w = (1 - (d/d_{max})^3)^3$: the farthest sample of the window gets zero.
# 4. **robustness** (`r` prefix) — 5 iterations: residuals $r$, scale $s = \mathrm{median}|r|$,
#    bisquare weights $(1 - (r/6s)^2)^2$ for $|r| < 6s$, else 0, and the fits are redone with
#    tricube × bisquare weights; a window holding a sample of zero weight is re-chosen among the
#    samples of non-zero weight.
#
# Thesis Figure 5.2 on a signal of 100 samples with two outliers: the moving average and `lowess`
# are dragged by them, `rloess` is not.

# %%
t100 = np.arange(100)
clean = 0.05 * np.sin(2 * np.pi * t100 / 50) + 0.001 * t100
y100 = clean + np.random.default_rng(52).normal(0, 0.002, 100)
outliers = [30, 71]
y100[outliers] += [0.06, -0.05]
for meth in ("moving", "lowess", "loess", "rlowess", "rloess"):
    span = 0.1 if meth != "moving" else smoothing.span_points(0.1, 100)
    err = smoothing.smooth(y100, span, meth) - clean
    print(f"{meth:8s} max error near the outliers {1000 * np.max(np.abs(err[25:77])):5.1f} mm, "
          f"RMS error {1000 * np.sqrt(np.mean(err ** 2)):5.2f} mm")

# %%
_ = plots.plot_smoothing_comparison(y100, span=0.1, methods=("moving", "lowess", "rloess"),
                                    truth=clean, outliers=outliers)
plt.show()

# %% [markdown]
# ## 2 · The thesis' record is too short for those rules
#
# With 38 frames the span is 5 samples. The tricube weights give the two farthest samples of an
# interior window zero weight, so the quadratic (3 coefficients) passes exactly through the 3 that
# remain: **the interior is not smoothed at all** (the unit tests check it). Every interior
# residual is then zero, the robust scale $\mathrm{median}|r|$ collapses, every end sample is
# rejected, and the end windows slide inwards and *extrapolate* — iteration after iteration.
# MATLAB would do exactly this. The pipeline keeps the thesis' `rloess` with span 0.1 but
# (a) raises a span too small to smooth to the smallest that does (7 for a quadratic:
# `smoothing.minimum_span`), and (b) keeps each sample's first-pass window in the robust
# iterations, only multiplying the weights (Cleveland's original robust lowess), so that a
# rejected end sample cannot make a window extrapolate. Errors of each variant against the truth,
# along the true motion axes:

# %%
variants = {
    "MATLAB rloess exactly (span 5)": dict(method="rloess", min_span=None, windows="matlab"),
    "MATLAB windows, span >= 7": dict(method="rloess", min_span="auto", windows="matlab"),
    "pipeline: fixed windows, span >= 7": dict(method="rloess", min_span="auto", windows="fixed"),
    "loess (not robust), span >= 7": dict(method="loess", min_span="auto"),
    "rlowess, fixed windows": dict(method="rlowess", min_span="auto", windows="fixed"),
}
print(f"{'':38s} {'x-motion':>9s} {'y-motion':>9s} {'z-motion':>9s}  (RMSE, mm)")
e = 1000 * frames.rmse_per_axis(points @ A_true.T, true_pos @ A_true.T)
print(f"{'triangulated, not smoothed':38s} {e[0]:9.2f} {e[1]:9.2f} {e[2]:9.2f}")
for label, kw in variants.items():
    s = smoothing.smooth_positions(points, 0.1, nan="omit", **kw)
    e = 1000 * frames.rmse_per_axis(s @ A_true.T, true_pos @ A_true.T)
    print(f"{label:38s} {e[0]:9.2f} {e[1]:9.2f} {e[2]:9.2f}")

# %% [markdown]
# Choose the smoother (default: the pipeline's, `rloess` with span 0.1 and the two safeguards):

# %% tags=["nbval-ignore-output"]
ui_smooth = widgets.ui_smoothing()
display(ui_smooth)

# %%
choice = ui_smooth.value
smoothed = smoothing.smooth_positions(points, choice["span"], choice["method"], nan="omit")
k_used = smoothing.effective_span(n, choice["span"], choice["method"], "auto")
e = 1000 * frames.rmse_per_axis(smoothed @ A_true.T, true_pos @ A_true.T)
print(f"{choice['method']} span {choice['span']:.2f} -> {k_used} frames per window")
print(f"RMSE vs truth: x-motion {e[0]:.2f} mm, y-motion {e[1]:.2f} mm, z-motion {e[2]:.2f} mm")

# %% [markdown]
# Thesis Figure 8.9 (b): the first marker before and after smoothing, left camera frame.

# %%
_ = plots.plot_smoothed_marker(points, smoothed, marker=0, truth=true_pos, title="marker 1, camera frame")
plt.show()

# %% [markdown]
# ## 3 · Gravity from the plumb
#
# A plumb line hangs in view with a marker near its top (the *tail* of the gravity vector) and one
# near its bottom (the *tip*). Triangulated like any marker, they give $\mathbf{u}_2^e$, pointing
# down. The line is 1.4 m long and its ends are 7.7 m away, so a millimetre of depth error at one
# end tilts the vector by 0.04°.

# %%
plumb = reconstruction.triangulate(rig, plumb_px, mode="joint")
tail_w, tip_w = plumb.points[0, 0], plumb.points[0, 1]
gravity = frames.gravity_from_plumb(tip_w, tail_w)
print("u2e (estimated gravity, down) =", np.array2string(gravity, precision=5))
print("true gravity                  =", np.array2string(truth.gravity, precision=5))
print(f"angle to the true gravity: {frames.angle_deg(gravity, truth.gravity):.3f} deg")
print(f"plumb reprojection residuals (px): " + ", ".join(f"{c} {r:.3f}" for c, r in plumb.rms_residual_px().items()))

# %% [markdown]
# ## 4 · The period
#
# The thesis asked the user for the period in frames. The vertical motion of the markers is
# periodic: the autocorrelation of its detrended projection on gravity peaks at the period; a
# parabola through the peak and a least-squares fit of a trend plus two harmonics refine it to a
# fraction of a frame.

# %%
vertical = smoothed @ gravity
acf = frames.autocorrelation(vertical, max_lag=int(0.6 * n))
period = frames.estimate_period(smoothed, fps, gravity=gravity)
stride_hz = truth.extras["motion"]["gait"]["stride_hz"]
print(f"estimated period: {period:.2f} frames = {period / fps:.3f} s")
print(f"true stride period: {fps / stride_hz:.2f} frames (the thesis user typed 18 for this horse and gait)")

# %%
_ = plots.plot_period_estimate(acf, period, fps)
plt.show()

# %% [markdown]
# ## 5 · The motion reference frame
#
# Choose the marker whose net displacement defines x-motion (thesis: typed 1, 2 or 3), the period
# and whether one or two periods are used. The defaults are the pipeline's: marker 1, the
# estimated period, two periods when the record holds them.

# %% tags=["nbval-ignore-output"]
ui_marker = widgets.ui_motion_marker(points.shape[1])
ui_T = widgets.ui_period(period, n - 1)
ui_np = widgets.ui_n_periods(2 if 2 * period <= n - 1 else 1)
display(ui_marker, ui_T, ui_np)

# %%
mf = frames.motion_frame(smoothed, gravity, marker=ui_marker.value, period=ui_T.value, n_periods=ui_np.value)
print("R_CM = [u1 | u2 | u3] =")
print(np.array2string(mf.R_CM, precision=5, suppress_small=True))
print(f"u1 from marker {mf.marker + 1} over {mf.n_periods} period(s) of {mf.period_frames:.2f} frames")
print(f"gravity correction (u2e -> u2, eq. 5.8-5.9): {mf.gravity_correction_deg:.3f} deg")
for i, name in enumerate(("x-motion", "y-motion", "z-motion")):
    print(f"angle of {name} to the truth: {frames.angle_deg(mf.axes[i], A_true[i]):.3f} deg")

# %% [markdown]
# Thesis Figure 8.10: the first marker in the motion frame against time (eq. 5.12-5.13). The truth
# is drawn in the same (estimated) frame, so the differences are measurement errors only.

# %%
t = frames.time_axis(n, fps)
motion = frames.to_motion_frame(smoothed, mf)
_ = plots.plot_motion_positions(motion, t, marker=0, truth=frames.to_motion_frame(true_pos, mf),
                                title="marker 1, motion reference frame")
plt.show()

# %% [markdown]
# ## 6 · How good is it? Both triangulation modes against the truth
#
# Position errors after smoothing, projected on the true motion axes (so that they do not mix
# with the small error of the axes themselves: a rotation of 0.1° moves a point 7.5 m from the
# camera by 13 mm). First with the detected pixels (the pipeline), then with the true projections
# plus 0.1 px of Gaussian noise, a less favourable detector.

# %%
rng = np.random.default_rng(2009)
noisy_px = {}
for cam in rig.names:
    k = ref_frames - truth.offsets["left"] + truth.offsets[cam]
    noisy_px[cam] = truth.marker_px[cam][k, :3] + rng.normal(0.0, 0.1, (len(k), 3, 2))
for label, px in (("detected", marker_px), ("0.1 px noise", noisy_px)):
    for mode in ("thesis", "joint"):
        p = reconstruction.triangulate(rig, px, mode=mode).points
        s = smoothing.smooth_positions(p, nan="omit")
        e = 1000 * frames.rmse_per_axis(s @ A_true.T, true_pos @ A_true.T)
        print(f"{label:12s} {mode:6s} after smoothing: RMSE x-motion {e[0]:5.2f} mm, y-motion {e[1]:5.2f} mm, "
              f"z-motion (depth) {e[2]:6.2f} mm")
print(f"gravity direction error: {frames.angle_deg(gravity, truth.gravity):.3f} deg")

# %% [markdown]
# With the detector's pixels both horizontal axes of the motion are within 3 mm and the joint mode
# is at least as good as the thesis' average. The depth (z-motion) is the weak axis of a
# narrow-baseline rig. With 0.1 px of noise the x-motion error passes 3 mm: the depth error
# leaks into the direction of travel when the horse is to the side of the images, and a smoothing
# window of 7 frames (0.4 of a stride) cannot average it away without flattening the vertical
# motion. The curve fits of notebook 09 (a straight line plus harmonics of the stride) use the
# whole record and do better.
#
# ## Exercises
#
# 1. Smooth the positions with `min_span=None, windows="matlab", nan="omit"` (MATLAB exactly) and plot marker 1:
#    where do the errors come from?
# 2. Use one period instead of two for $\mathbf{u}_1$: how much does the x-motion axis change?
# 3. Tilt the estimated gravity by 1° towards the x-motion direction. What do eq. 5.8-5.9 do
#    with that error?
#
# <details><summary>Solutions</summary>
#
# 1. `plots.plot_smoothed_marker(points, smoothing.smooth_positions(points, min_span=None, windows="matlab", nan="omit"), 0, truth=true_pos)`:
#    the middle of the record is the raw data (a 3-point quadratic interpolates), the ends run
#    away — extrapolated quadratics over samples rejected by the collapsed robust scale.
# 2. `frames.motion_frame(smoothed, gravity, period=period, n_periods=1)`; compare the axes with
#    `frames.angle_deg`: here about 0.7° off the truth instead of 0.01°. The periodic motion
#    cancels over any whole number of periods, but the position errors at the two end frames
#    (mostly depth) are divided by half the distance.
# 3. `g2 = gravity + np.tan(np.radians(1)) * mf.axes[0]`; the correction removes the component
#    along $\mathbf{u}_1$ (`gravity_correction_deg` becomes about 1°) and the corrected
#    $\mathbf{u}_2$ is unchanged: only a tilt towards z-motion survives.
#
# </details>
