# %% [markdown]
# # 06 · Smoothing and the motion reference frame
#
# **What you will learn**
# - what MATLAB's `smooth(y, 0.1, 'rloess')` — the thesis' smoother (section 5.2.2, Appendix A
#   step 6) — computes, rule by rule, and why robust smoothing resists outliers (Figure 5.2);
# - why those rules misbehave on a record as short as the thesis' (38 frames), and why the
#   pipeline therefore smooths by default with plain `loess` (the same local quadratic, **without**
#   the robust iterations) rather than the thesis' `rloess` — a measured deviation from the thesis;
#   no smoothing (`"none"`) stays an option;
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

from horsemocap import accuracy, frames, plots, reconstruction, smoothing, widgets
from horsemocap.data import default_session_dir
from horsemocap.pipeline import run_steps
from horsemocap.workspace import NO_TRUTH, results_for, session_truth

# %% [markdown]
# ## The data
#
# The pipeline, up to this notebook's steps, on the default session (as in notebook 05): flashlight
# offsets, the rig calibrated from the checkerboard views, the plumb markers detected in the plumb
# stills and triangulated, the static shot, the marker centres identified by all cameras together,
# joint triangulation of the analysed frames (the longest run in which every marker has a 3D
# position), then the smoothing step, the period and the motion frame. Its automatic choices are
# printed; the widgets below start from them.

# %%
session_dir = ws.session_dir
analysis = results_for(session_dir, until="motion_frame")
rig = analysis.rig.rig                                      # calibrated by the pipeline
a, b = analysis.triangulate.segment                         # the pipeline's analysed frames a..b-1
points = analysis.smooth.raw                                # CM_L, triangulated, (n, markers, 3)
gravity = analysis.plumb.gravity                            # u2e, from the plumb (section 3)
mf_pipeline = analysis.motion_frame.frame
fps = analysis.session.fps
n = points.shape[0]
par = analysis.params
rig_from = analysis.rig.origin(par.rig.mode)
print(f"rig {rig_from}; {n:d} analysed frames ({a:d}..{b - 1:d}), {points.shape[1]:d} markers, "
      f"{analysis.params.triangulate.mode} triangulation")
T_pipeline = analysis.motion_frame.period_frames           # None: the pipeline found no period
if mf_pipeline.n_periods > 0:   # the thesis' frame, eq. 5.6/5.7
    chosen_frame = (f"x-motion marker {mf_pipeline.marker + 1:d}, period {mf_pipeline.period_frames:.2f} frames "
                    f"({'given' if par.motion_frame.period_frames is not None else 'estimated'}), "
                    f"{mf_pipeline.n_periods:d} period(s) for u1")
else:                           # no period: x-motion from the whole record
    chosen_frame = ("x-motion from the markers' net displacement over the whole record ("
                    + ("no period found" if T_pipeline is None else f"period {T_pipeline:.2f} frames, not used") + ")")
print(f"pipeline choices: smoothing_method '{par.smooth.method}' (span {par.smooth.span:.2f} if used), {chosen_frame}")

# %% [markdown]
# The truth is used only to measure errors: the true positions of the analysed frames, the true
# gravity and the true motion axes. As in notebook 05, each error is given as the RMSE along the true
# motion axes and as the RMSE once the constant offset (the calibrated rig's absolute
# bias, which no velocity, acceleration or angle sees) is removed.

# %%
truth = session_truth(session_dir)                         # None for a recorded session (no truth/ folder)
true_pos = A_true = None
if truth is None:
    print(NO_TRUTH, "(a recorded session): the errors below are left out, the rest goes on")
else:
    frames_ref = analysis.synchronisation.offsets[analysis.session.reference_camera] + np.arange(a, b)
    rows = np.searchsorted(truth.ref_frames, frames_ref).clip(0, len(truth.ref_frames) - 1)
    known = truth.ref_frames[rows] == frames_ref            # the truth covers the frames all cameras see whole
    print(f"truth known for {int(known.sum()):d} of {b - a:d} analysed frames; errors are measured on those")
    true_pos = np.where(known[:, None, None], truth.marker_pos[rows], np.nan)   # NaN where the truth has no row
    A_true = truth.motion_axes                              # rows: true x-, y-, z-motion directions


def errors_mm(pts, ref=None):
    """RMSE per true motion axis, and the RMSE once the constant offset is removed, in mm."""
    est, ref = pts @ A_true.T, (true_pos if ref is None else ref) @ A_true.T
    _, motion = accuracy.offset_and_motion(est, ref)
    return 1000 * accuracy.rmse_axes(est, ref), 1000 * motion


if truth is not None:
    r, rc = errors_mm(points)
    print(f"triangulated: RMSE x {r[0]:.2f}, y {r[1]:.2f}, z {r[2]:.2f} mm; bias removed x {rc[0]:.2f}, "
          f"y {rc[1]:.2f}, z {rc[2]:.2f} mm")

# %% [markdown]
# ## 1 · Smoothing, the MATLAB way
#
# `smooth(y, span, 'rloess')` (MathWorks, *Curve Fitting Toolbox: Smoothing Data*; the rules as
# `horsemocap.smoothing` implements them):
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
# are dragged by them, `rloess` is not. So is plain `loess`, the pipeline's default (section 3
# says why it is still the default): it is not robust, and relies on outliers being kept out
# before it — a marker centre the detector rejects is NaN, and the joint triangulation's residual
# check drops a camera that disagrees (notebook 05, section 6).

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
# remain: **the interior is not smoothed at all**. Every interior
# residual is then zero, the robust scale $\mathrm{median}|r|$ collapses, every end sample is
# rejected, and the end windows slide inwards and *extrapolate* — iteration after iteration.
# MATLAB would do exactly this. `smoothing.smooth_positions` keeps the thesis' `rloess` with span
# 0.1 but (a) raises a span too small to smooth to the smallest that does (7 for a quadratic:
# `smoothing.minimum_span`), and (b) keeps each sample's first-pass window in the robust
# iterations, only multiplying the weights (Cleveland's original robust lowess), so that a
# rejected end sample cannot make a window extrapolate. Errors of each variant against the truth,
# along the true motion axes, on the pipeline's positions and on the **true** positions (no
# measurement error at all: what the smoother alone does to the motion):

# %%
if truth is None:
    print(NO_TRUTH)
else:
    variants = {
        "none (an option)": None,
        "MATLAB rloess exactly (span 5)": dict(method="rloess", min_span=None, windows="matlab"),
        "MATLAB windows, span >= 7": dict(method="rloess", min_span="auto", windows="matlab"),
        "rloess 0.1, fixed windows, span >= 7": dict(method="rloess", min_span="auto", windows="fixed"),
        "loess, span >= 7 (pipeline default)": dict(method="loess", min_span="auto"),
        "rlowess, fixed windows": dict(method="rlowess", min_span="auto", windows="fixed"),
    }
    print(f"{'':38s} {'measured positions':^36s} | {'true positions':^17s}")
    print(f"{'':38s} {'RMSE x':>7s} {'y':>5s} {'z':>6s} | {'no bias x':>9s} {'y':>5s} {'z':>5s} | "
          f"{'x':>5s} {'y':>5s} {'z':>5s}   (mm)")
    for label, kw in variants.items():
        s_meas = points if kw is None else smoothing.smooth_positions(points, 0.1, nan="omit", **kw)
        s_true = true_pos if kw is None else smoothing.smooth_positions(true_pos, 0.1, nan="omit", **kw)
        r, rc = errors_mm(s_meas)
        rt, _ = errors_mm(s_true)
        print(f"{label:38s} {r[0]:7.2f} {r[1]:5.2f} {r[2]:6.2f} | {rc[0]:9.2f} {rc[1]:5.2f} {rc[2]:5.2f} | "
              f"{rt[0]:5.2f} {rt[1]:5.2f} {rt[2]:5.2f}")

# %% [markdown]
# ## 3 · Why the pipeline smooths with `loess`, not `rloess`
#
# The thesis smooths every coordinate with `rloess`, span 0.1 (Appendix A step 6). The pipeline's
# default is `smoothing_method = "loess"` (`horsemocap.params.AnalysisParams`): the same span
# (raised to 7 frames on short records) and the same tricube-weighted local quadratic, but **no
# robust iterations** — a deliberate, measured deviation. `"rloess"` (the thesis' choice) and
# `"none"` (positions kept as triangulated) stay available.
#
# 1. **Robust smoothing moves good samples.** The robust step rejects samples whose residual
#    exceeds six times the median residual. When the measurement noise is much smaller than what a
#    7-point quadratic cannot follow, good samples are rejected as if they were outliers, and the
#    local fits rest on the few that remain. On this record it happens mostly at the end, where
#    the window is one-sided and the vertical motion turns sharply (the figure and the numbers
#    below Figure 8.9 b). Even on the *true* positions — nothing to remove — `rloess` moves the
#    markers by millimetres, while plain `loess` with the same window hardly does (the table of
#    section 2, last three columns).
# 2. **Not smoothing leaves the detection noise in the accelerations.** The saddle's acceleration
#    is a second derivative; on sessions whose detections are noisier than this one's, the noise
#    passes into the fits of section 5.5 and into the comfort indicators.
# 3. **The window is a large part of a stride.** 7 frames are a sizeable fraction of a canter
#    stride (printed below): any local smoother of that width attenuates the higher harmonics
#    the comfort analysis of chapter 7 needs. On a session as clean as this one that cost can
#    outweigh the noise it removes.
#
# The consequence downstream on **this** session, measured by running the later pipeline steps
# (registration, fits, saddle marker) on the same detections with each smoothing method: the
# error of the saddle marker's vertical acceleration, the quantity the thesis is about, as a
# percentage of its RMS. Twice: with the thesis' chain of fits (`kinematics="fits"`, sections
# 5.5-6, which starts from these smoothed positions) and with the pipeline's default pose
# trajectory (`kinematics="pose_spline"`, notebooks 08-11), which is smoothed from the
# *unsmoothed* positions with a smoothing chosen from their own noise.

# %%
if truth is None:
    print(NO_TRUTH)
else:
    downstream = {}
    for kin in ("fits", "pose_spline"):
        for method in ("none", "loess", "rloess"):
            run = run_steps(analysis.session, accuracy.with_params(analysis, smoothing_method=method, kinematics=kin),
                            analysis, ("smooth", "motion_frame", "rigid_body"))
            st = accuracy.stage_errors(run, truth)
            downstream[kin, method] = st
            print(f"{kin:11s} smoothing {method:7s}: marker RMSE y-motion {1000 * st['smoothed'][1]:5.2f} mm, "
                  f"marker acceleration RMSE y-motion {st['acceleration'][1]:5.3f} m/s², "
                  f"saddle vertical acceleration error {st['saddle_acc_y_rmse_pct_of_rms']:5.1f} % of its RMS")
    pct = {m: downstream["fits", m]["saddle_acc_y_rmse_pct_of_rms"] for m in ("none", "loess", "rloess")}
    best = min(pct, key=pct.get)
    print(f"chain of fits: best on this session {best} ({pct[best]:.1f} %); rloess / {par.smooth.method} = "
          f"{pct['rloess'] / pct[par.smooth.method]:.1f} times the error")
    pose_pct = [downstream["pose_spline", m]["saddle_acc_y_rmse_pct_of_rms"] for m in ("none", "loess", "rloess")]
    print(f"pose trajectory (the default): {min(pose_pct):.1f}-{max(pose_pct):.1f} % whatever the smoothing here")
    k_win = smoothing.effective_span(n, par.smooth.span, "loess", "auto")
    print(f"window: {k_win:d} frames = {k_win / fps:.2f} s, {k_win / mf_pipeline.period_frames:.2f} of the "
          f"estimated stride ({mf_pipeline.period_frames / fps:.2f} s)")

# %% [markdown]
# The pipeline's default pose trajectory does not see this choice (the last line above): it
# starts from the positions as triangulated. For the thesis' chain of fits, on this one session
# no smoothing is slightly better than `loess` (the cell above): its detections are clean, so
# there is little noise to remove, and the window's attenuation of the peaks (reason 3) can
# weigh more than the noise removed. `rloess` is clearly the worst. One session is not enough
# to choose a default, so
# the choice was measured over the 16 sessions of the virtual herd (every horse and gait,
# notebook 13), the same detections and rig for each method, with
# `python benchmarks/bench_herd.py --params '{"smoothing_method": "none"}'` (then `"loess"`,
# `"rloess"`). It takes minutes, so it is **not** computed here. The measurements below were made
# with the thesis' per-camera detection, not with the pipeline's default identification in 3D
# (notebook 04, section 9; notebook 13, section 6, measures the default's errors); medians over the
# 16 sessions of |error| against the truth:
#
# | smoothing | saddle vertical acceleration error (% of its RMS) | Wb-weighted rms | Wk-weighted rms | VDV (Wb) | VDV (Wk) | worst session |
# |---|---|---|---|---|---|---|
# | `none`   | 39 %   | 20.4 % | — | — | — | Wb rms 53.5 % |
# | `rloess` | 30.8 % | 9.5 %  | 10.1 % | 8.6 % | 8.3 % | 140-164 % over the four indicators (Horse 3 and Horse 4, rising trot) |
# | `loess`  | 24.6 % | 7.9 %  | 6.7 %  | 9.2 % | 7.8 % | 17.6 % |
#
# (—: not part of the quoted measurement.) Across the herd, `loess` has the smallest median saddle
# error, the smallest medians of three of the four comfort indicators and by far the smallest
# worst case; `rloess` is close on the medians (slightly better on VDV Wb) but fails badly on two
# sessions, and no smoothing has the largest errors. Hence the default: `loess`, at a small
# cost on clean sessions like this one. It is a choice about the pipeline, not a claim
# about this record. The smoothers stay available:
# `results_for(params={"smoothing_method": "rloess"})` (or `"none"`), `horsemocap analyze --params`,
# or the widget below. Choose the smoother (default: the pipeline's, `loess`):

# %% tags=["nbval-ignore-output"]
ui_smooth = widgets.ui_smoothing(par.smooth.method, par.smooth.span)
ws.bind(ui_smooth.method, "smoothing_method")
ws.bind(ui_smooth.span, "smoothing_span")
display(ui_smooth)

# %%
choice = ui_smooth.value
run = run_steps(analysis.session, accuracy.with_params(analysis, smoothing_method=choice["method"],
                                                       smoothing_span=choice["span"]), analysis, ("smooth",))
smoothed = run.smooth.smoothed                               # what the pipeline's smoothing step returns
if choice["method"] == "none":
    print("no smoothing: the positions stay as triangulated")
else:
    k_used = smoothing.effective_span(n, choice["span"], choice["method"], "auto")
    print(f"{choice['method']} span {choice['span']:.2f} -> {k_used:d} frames per window")
if truth is None:
    print("RMSE vs truth:", NO_TRUTH)
else:
    r, rc = errors_mm(smoothed)
    print(f"RMSE vs truth: x-motion {r[0]:.2f} mm, y-motion {r[1]:.2f} mm, z-motion {r[2]:.2f} mm; "
          f"bias removed: {rc[0]:.2f}, {rc[1]:.2f}, {rc[2]:.2f} mm")

# %% [markdown]
# Thesis Figure 8.9 (b) with the thesis' smoother: the first marker before and after `rloess` 0.1,
# left camera frame, and (bottom row) the errors against the truth. The offset of the bottom
# curves from zero is the calibrated rig's bias; the smoother's own damage is where the orange
# curve leaves the blue one, mostly in the last frames. The cell after it measures the vertical
# changes each smoother makes, `rloess` and the pipeline's `loess`.

# %%
thesis_smoothed = smoothing.smooth_positions(points, 0.1, "rloess", nan="omit")
_ = plots.plot_smoothed_marker(points, thesis_smoothed, marker=0, truth=true_pos, label="rloess 0.1 (thesis)",
                               errors=True, title="marker 1, camera frame")
plt.show()

# %%
# vertical, worst marker seen in the frame (a marker hidden in a frame, NaN there, is left out of its figure)
change_mm = 1000 * np.nanmax(np.abs((thesis_smoothed - points) @ gravity), axis=1)
worst = np.sort(np.argsort(np.nan_to_num(change_mm, nan=-1.0))[-4:])
rest = np.setdiff1d(np.arange(n), worst)
print("largest vertical changes made by rloess 0.1: " + ", ".join(f"frame {k:d} {change_mm[k]:.1f} mm" for k in worst))
print(f"every other frame: at most {np.nanmax(change_mm[rest]):.1f} mm, median {np.nanmedian(change_mm[rest]):.2f} mm")
loess_smoothed = smoothing.smooth_positions(points, par.smooth.span, "loess", nan="omit")
change_loess = 1000 * np.nanmax(np.abs((loess_smoothed - points) @ gravity), axis=1)
print(f"loess {par.smooth.span:.1f} (pipeline): largest vertical change {np.nanmax(change_loess):.1f} mm "
      f"(frame {int(np.nanargmax(change_loess)):d}), median {np.nanmedian(change_loess):.2f} mm")

# %% [markdown]
# ## 4 · Gravity from the plumb
#
# A plumb line hangs in view with a marker near its top (the *tail* of the gravity vector) and one
# near its bottom (the *tip*). The pipeline's `plumb` step detects them in the plumb stills
# (`detection.detect_still`, top marker first), triangulates them like any marker and gives
# $\mathbf{u}_2^e$, pointing down. The line is 1.4 m long and its ends are 7.7 m away, so a
# millimetre of depth error at one end tilts the vector by 0.04°.

# %%
tail_w, tip_w = analysis.plumb.plumb_points
u2e = frames.gravity_from_plumb(tip_w, tail_w)
plumb_res = reconstruction.reprojection_residuals(rig, analysis.plumb.plumb_points, analysis.plumb.plumb_px)
print("u2e (estimated gravity, down) =", np.array2string(u2e, precision=5))
print("pipeline's gravity            =", np.array2string(gravity, precision=5))
if truth is None:
    print("true gravity:", NO_TRUTH)
else:
    print("true gravity                  =", np.array2string(truth.gravity, precision=5))
    print(f"angle to the true gravity: {frames.angle_deg(gravity, truth.gravity):.3f} deg (target: within 0.2 deg)")
print("plumb reprojection residuals (px): " + ", ".join(f"{c} {np.max(v):.3f}" for c, v in plumb_res.items()))

# %% [markdown]
# ## 5 · The period
#
# The thesis asked the user for the period in frames. The vertical motion of the markers is
# periodic: the autocorrelation of its detrended projection on gravity peaks at the period; a
# parabola through the peak and a least-squares fit of a trend plus two harmonics refine it to a
# fraction of a frame.

# %%
vertical = smoothed @ gravity
acf = frames.autocorrelation(vertical, max_lag=int(0.6 * n))
try:   # the pipeline's estimate: a horse's stride the bound (frames.HORSE_STRIDE_HZ)
    period, _ = frames.stride_period(smoothed, fps, gravity=gravity)
    print(f"estimated period: {period:.2f} frames = {period / fps:.3f} s (the pipeline's: "
          + ("none found" if T_pipeline is None else f"{T_pipeline:.2f} frames") + ")")
except ValueError as exc:
    period = None
    print(f"no period found in these {n:d} frames ({n / fps:.2f} s): {exc}")
    print("the pipeline found none either: its motion_frame step took x-motion from the net displacement over "
          "the whole record (frames.motion_frame_from_record); only the comfort step needs a period, and it estimates "
          "the stride frequency from the saddle's vertical position" if T_pipeline is None else f"(the pipeline's: {T_pipeline:.2f} frames)")
if truth is None:
    print("true stride period:", NO_TRUTH)
else:
    stride_hz = truth.extras["motion"]["gait"]["stride_hz"]
    print(f"true stride period: {fps / stride_hz:.2f} frames (the thesis user typed 18 for Horse 2 at canter)")

# %%
_ = plots.plot_period_estimate(acf, period, fps)          # period None: the autocorrelation alone
plt.show()

# %% [markdown]
# ## 6 · The motion reference frame
#
# Choose the marker whose net displacement defines x-motion (thesis: typed 1, 2 or 3), the period
# and whether one or two periods are used. The defaults are the pipeline's choices printed above:
# marker 1, the estimated period, two periods when the record holds them. When the pipeline found no
# period (a record shorter than the stride's two periods, or not periodic), it built the frame from the
# net displacement over the whole record; the widgets are then not shown, and a period is given with
# `ws.choose("period_frames", T)` (T in frames), the cells run again.

# %% tags=["nbval-ignore-output"]
if mf_pipeline.n_periods > 0:
    ui_marker = widgets.ui_motion_marker(points.shape[1], mf_pipeline.marker)
    ui_T = widgets.ui_period(mf_pipeline.period_frames, n - 1)
    ui_np = widgets.ui_n_periods(mf_pipeline.n_periods)
    ws.bind(ui_marker, "x_marker")
    ws.bind(ui_T, "period_frames")
    ws.bind(ui_np, "n_periods")
    display(ui_marker, ui_T, ui_np)
else:
    print(f"the pipeline's frame has no period to choose ({chosen_frame}); to give one: "
          "ws.choose('period_frames', T) with T in frames, then run the cells again")

# %%
if mf_pipeline.n_periods > 0:
    mf = frames.motion_frame(smoothed, gravity, marker=ui_marker.value, period=ui_T.value, n_periods=ui_np.value)
else:   # what the pipeline's motion_frame step did without a period
    mf = frames.motion_frame_from_record(smoothed, gravity, T_pipeline)
print("R_CM = [u1 | u2 | u3] =")
print(np.array2string(mf.R_CM, precision=5, suppress_small=True))
if mf.n_periods > 0:
    print(f"u1 from marker {mf.marker + 1:d} over {mf.n_periods:d} period(s) of {mf.period_frames:.2f} frames")
else:
    print(f"u1 from the markers' centroid over the whole record ({n:d} frames, no period); largest angle to the "
          f"pipeline's axes {max(frames.angle_deg(mf.axes[i], mf_pipeline.axes[i]) for i in range(3)):.4f} deg")
print(f"gravity correction (u2e -> u2, eq. 5.8-5.9): {mf.gravity_correction_deg:.3f} deg")
if truth is None:
    print("angles to the true axes:", NO_TRUTH)
for i, name in enumerate(("x-motion", "y-motion", "z-motion") if truth is not None else ()):
    print(f"angle of {name} to the truth: {frames.angle_deg(mf.axes[i], A_true[i]):.3f} deg "
          f"(pipeline's axis: {frames.angle_deg(mf_pipeline.axes[i], A_true[i]):.3f} deg)")

# %% [markdown]
# Thesis Figure 8.10: the first marker in the motion frame against time (eq. 5.12-5.13). The truth
# is drawn in the same (estimated) frame, so the differences are measurement errors only.

# %%
t = frames.time_axis(n, fps)
motion = frames.to_motion_frame(smoothed, mf)
_ = plots.plot_motion_positions(motion, t, marker=0, truth=None if truth is None else frames.to_motion_frame(true_pos, mf),
                                title="marker 1, motion reference frame")
plt.show()

# %% [markdown]
# ## 7 · How good is it? Both triangulation modes, three smoothings, against the truth
#
# The pipeline's steps from triangulation to the motion frame, run again on the same detections
# and the same calibrated rig (`pipeline.run_steps`) for the thesis' triangulation (three pairs
# averaged, eq. 5.5) and the joint one, each with no smoothing, with the pipeline's default `loess`
# and with the thesis' `rloess` 0.1. Position errors are projected on the true motion axes (a rotation of 0.1° moves a
# point 7.5 m from the camera by 13 mm, which would hide the position error in the axis error).

# %%
if truth is None:
    print(NO_TRUTH)
else:
    runs = {}
    for mode in ("thesis", "joint"):
        for method in ("none", "loess", "rloess"):
            run = run_steps(analysis.session, accuracy.with_params(analysis, triangulation=mode, smoothing_method=method),
                            {"sync": analysis.sync, "rig": analysis.rig, "detect": analysis.detect},
                            ("triangulate", "plumb", "static", "smooth", "motion_frame"))
            runs[mode, method] = run
            st = accuracy.stage_errors(run, truth)
            r, rc = errors_mm(run.smooth.smoothed)
            print(f"{mode:6s} + {method:6s}: RMSE x {r[0]:5.2f}, y {r[1]:5.2f}, z {r[2]:6.2f} mm | bias removed "
                  f"x {rc[0]:5.2f}, y {rc[1]:5.2f}, z {rc[2]:5.2f} mm | gravity {st['gravity_deg']:.3f} deg, "
                  f"x-motion axis {st['x_axis_deg']:.3f} deg")

# %% [markdown]
# The reproduction's accuracy goals, checked on these numbers (x- and y-motion RMSE below 3 mm after smoothing,
# i.e. with the pipeline's default `loess` — the other two methods are shown for comparison;
# joint no worse than thesis; plumb gravity within 0.2°). Differences under 0.05 mm between the
# modes are counted as equal (they are far below the detector's own error).

# %%
TARGET_MM, TARGET_DEG, TIE_MM = 3.0, 0.2, 0.05   # the accuracy goals named above
if truth is None:
    print(NO_TRUTH)
else:
    def verdict(ok):
        return "meets" if ok else "MISSES"


    for method in (par.smooth.method, "none", "rloess"):
        tag = " (pipeline default)" if method == par.smooth.method else ""
        r, rc = errors_mm(runs["joint", method].smooth.smoothed)
        print(f"joint + {method:6s}{tag}: x {r[0]:.2f} mm {verdict(r[0] < TARGET_MM)}, y {r[1]:.2f} mm "
              f"{verdict(r[1] < TARGET_MM)} (absolute) | x {rc[0]:.2f} mm {verdict(rc[0] < TARGET_MM)}, "
              f"y {rc[1]:.2f} mm {verdict(rc[1] < TARGET_MM)} (bias removed)")
        rt, rct = errors_mm(runs["thesis", method].smooth.smoothed)
        no_worse = bool(np.all(r[:2] - rt[:2] < TIE_MM) and np.all(rc[:2] - rct[:2] < TIE_MM))
        print(f"   joint minus thesis (x, y): absolute " + ", ".join(f"{d:+.2f}" for d in r[:2] - rt[:2])
              + " mm, bias removed " + ", ".join(f"{d:+.2f}" for d in rc[:2] - rct[:2])
              + f" mm -> joint no worse than thesis: {verdict(no_worse)}")
    for mode in ("joint", "thesis"):
        g_err = frames.angle_deg(runs[mode, par.smooth.method].plumb.gravity, truth.gravity)
        print(f"plumb gravity, {mode:6s} triangulation: {g_err:.3f} deg {verdict(g_err < TARGET_DEG)}")

# %% [markdown]
# **Reading the numbers** (all printed above). With the calibrated rig and the pipeline's `loess`,
# the motion itself (bias removed) is measured well within 3 mm along the travel and vertically,
# in both modes, the joint mode no worse than the thesis' average; the plumb's gravity direction
# is within a small fraction of the 0.2° target. The absolute positions carry the calibration's
# constant offset, so the **absolute** y-motion RMSE **misses** the 3 mm target whatever the
# smoothing; it is a constant shift of the whole reconstruction and drops out of every velocity,
# acceleration and angle. Section 8 measures where that offset comes from. The thesis' `rloess`
# makes the y-motion worse in every column (and with it the joint-versus-thesis comparison
# depends on the smoother, not on the triangulation). Compared with no smoothing, `loess` lowers
# the x- and z-motion errors a little, costs hundredths of a millimetre vertically, and leaves the
# estimated x-motion axis almost where it was (u1 is taken between end frames, where the window is
# one-sided, so the smoother could tilt it). The depth (z-motion) is the weak axis of a
# narrow-baseline rig (notebook 05);
# notebook 14 follows all of this through to the comfort indicators, with noisier detections too.
#
# ## 8 · The absolute offset is the calibration's: how large can it be?
#
# A calibration that is slightly off shifts, turns and scales the reconstructed space as a whole;
# the horse is 7.7 m away, so a principal point off by half a pixel (a ray turned by 0.7 mrad)
# is already about 5 mm at the horse, nearly the same for every marker. On this session it is
# mostly a shift: the plumb's gravity (section 4) is within a hundredth of a degree of the
# truth, while every marker sits several millimetres off along it (section 7). The thesis reports its own calibration
# uncertainty (Table 8.1: principal point ±1.97 px vertically for the left camera, three
# standard deviations, from 90 views): a vertical datum uncertainty of about ±20 mm at the horse.
#
# `benchmarks/bench_calibration.py` measures it on our virtual laboratory. For each seed it renders
# the checkerboard views a session of that seed holds (all boards near the path, as in section
# 8.2: protocol `"path"`), calibrates the rig exactly as the pipeline does, and triangulates the
# **exact** projections of this session's markers with it (`accuracy.calibration_draws`): what is
# left is the calibration's error alone, split into the constant offset and the motion error
# (`accuracy.offset_and_motion`). It also tries 90 views (the thesis' number) and a lab that brings
# the board nearer the cameras and turns it further (protocol `"depths"`,
# `virtuallab.calibration.PROTOCOLS`). Its measured output is committed in
# `benchmarks/results/calibration_draws.json`; seed 0 of `"path"` at 45 views is this session's own
# set of views.

# %%
import json

from horsemocap.data import repository_file

draws = json.loads(repository_file("benchmarks/results/calibration_draws.json").read_text())["rows"]
setups = sorted({(d["protocol"], d["n_views"]) for d in draws}, key=lambda k: (k[0] != "path", k[1]))
print(f"{'protocol':8s} {'views':>5s} {'seed':>4s} | offset x, y, z (mm)        | motion RMSE x, y, z (mm)  | left cy error (px)")
for d in draws:
    o, m = 1000 * np.array(d["offset_m"]), 1000 * np.array(d["motion_rmse_m"])
    print(f"{d['protocol']:8s} {d['n_views']:5d} {d['seed']:4d} | {o[0]:7.2f} {o[1]:7.2f} {o[2]:8.2f} | "
          f"{m[0]:6.2f} {m[1]:6.2f} {m[2]:6.2f} | {d['intrinsic_error']['left'][3]:+.2f}")
for protocol, n_views in setups:
    sel = [d for d in draws if d["protocol"] == protocol and d["n_views"] == n_views]
    off = 1000 * np.array([d["offset_m"] for d in sel])
    mot = 1000 * np.array([d["motion_rmse_m"] for d in sel])
    inside = np.mean(np.abs(off[:, 1]) < TARGET_MM)
    print(f"{protocol}, {n_views} views, {len(sel)} calibrations: offset std x {off[:, 0].std(ddof=1):.1f}, "
          f"y {off[:, 1].std(ddof=1):.1f}, z {off[:, 2].std(ddof=1):.1f} mm; |y offset| < {TARGET_MM:.0f} mm "
          f"in {100 * inside:.0f} % of them; worst motion RMSE x {mot[:, 0].max():.2f}, y {mot[:, 1].max():.2f} mm")

# %%
if truth is None:
    print(NO_TRUTH)
else:
    fig, ax = plt.subplots(1, 2, figsize=(10, 3.6))
    for (protocol, n_views), marker in zip(setups, ("o", "s", "^", "v")):
        off = 1000 * np.array([d["offset_m"] for d in draws if d["protocol"] == protocol and d["n_views"] == n_views])
        ax[0].scatter(off[:, 0], off[:, 1], marker=marker, label=f"{protocol}, {n_views} views")
        ax[1].scatter(off[:, 2], off[:, 1], marker=marker, label=f"{protocol}, {n_views} views")
    offset_here, _ = accuracy.offset_and_motion(smoothed @ A_true.T, true_pos @ A_true.T)
    for axis, (i, name) in zip(ax, ((0, "x"), (2, "z"))):
        axis.axhspan(-TARGET_MM, TARGET_MM, color="0.9", label="±3 mm (y target)", zorder=0)
        axis.scatter(1000 * offset_here[i], 1000 * offset_here[1], marker="*", s=150, color="k",
                     label="this session (detected, smoothed)")
        axis.set_xlabel(f"{name}-motion offset (mm)")
        axis.set_ylabel("y-motion offset (mm)")
    ax[0].legend(fontsize=7)
    fig.suptitle("constant offset of the reconstructed markers, one point per calibration")
    plt.tight_layout()
    plt.show()

# %% [markdown]
# **What this says about the 3 mm target.** The motion itself is measured to a fraction of a
# millimetre in x and y by every calibration; the absolute position of the whole reconstruction
# is not: from one set of checkerboard views to the next its offset moves by several millimetres
# (the standard deviations printed above). 90 views (the thesis' number) do not remove it.
# Bringing the board nearer and turning it further narrows the offsets in depth and along the
# travel, but not vertically: the vertical offset follows the principal point's error, which
# stays at a few tenths of a pixel to a pixel with every protocol tried (last column), as the
# thesis' own ±2 px (three standard deviations, Table 8.1) lets expect. Whether one session's
# absolute y-motion error is under 3 mm is therefore a draw of its calibration, not a property
# of triangulation or smoothing; none of the protocols tried makes it reliable. This session's
# own offset is the star above. The kinematics, the rigid-body analysis and the comfort
# indicators only see the motion.

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
# 1. Smooth the positions with `min_span=None, windows="matlab", nan="omit"` (MATLAB exactly) and plot marker 1:
#    where do the errors come from?
# 2. Use one period instead of two for $\mathbf{u}_1$: how much does the x-motion axis change?
# 3. Tilt the estimated gravity by 1° towards the x-motion direction. What do eq. 5.8-5.9 do
#    with that error?
# 4. Run the whole pipeline with the thesis' chain of fits and its smoother,
#    `results_for(params={"kinematics": "fits", "smoothing_method": "rloess"})`, and compare
#    `accuracy.stage_errors(..., truth)["saddle_acc_y_rmse_pct_of_rms"]` with the chain's default smoother
#    (`params={"kinematics": "fits"}`, `loess`). Why does the same comparison without `"kinematics": "fits"`
#    give one number twice?
#
# <details><summary>Solutions</summary>
#
# 1. `plots.plot_smoothed_marker(points, smoothing.smooth_positions(points, min_span=None, windows="matlab", nan="omit"), 0, truth=true_pos, errors=True)`:
#    the middle of the record is the raw data (a 3-point quadratic interpolates), the ends run
#    away — extrapolated quadratics over samples rejected by the collapsed robust scale.
# 2. `frames.motion_frame(smoothed, gravity, period=period, n_periods=1)`; compare the axes with
#    `frames.angle_deg`: on this record (the pipeline's `loess` positions) one period puts the
#    axis a few hundredths of a degree farther from the truth than the two periods of section 6
#    (whose angle is printed there). The periodic motion cancels over any whole number of
#    periods, and two periods divide the position errors of the end frames by twice the distance;
#    but here the calibrated rig's own small tilt dominates. With the true rig
#    (`reconstruction.triangulate(truth.rig, ...)`, not smoothed, a comparison only) the same
#    detections put the two-period axis more than twice as close to the truth as the one-period axis.
# 3. `g2 = gravity + np.tan(np.radians(1)) * mf.axes[0]`; the correction removes the component
#    along $\mathbf{u}_1$ (`gravity_correction_deg` becomes about 1°) and the corrected
#    $\mathbf{u}_2$ is unchanged: only a tilt towards z-motion survives.
# 4. The same numbers as the `downstream` cell of section 3 (`rloess` several times the error of
#    `loess` for the chain of fits on this session): the later steps are the same functions. Without
#    `"kinematics": "fits"` the default pose trajectory runs, which is smoothed from the unsmoothed
#    positions: the smoothing method of this notebook does not reach it.
#
# </details>
