# %% [markdown]
# # 11 · The invisible saddle marker
#
# **What you will learn**
# - how a static shot of the standing horse places the saddle marker in a body frame of the three skin
#   markers (eq. 6.40-6.47, Figure 6.1, Appendix A step 12);
# - its position during the ride, when the rider hides it (eq. 6.48-6.53, Figure 8.22);
# - its velocity and acceleration from each skin marker and their mean (eq. 6.54-6.55,
#   Figures 8.23-8.24), and a second estimate that fits the saddle's own path;
# - how accurate the saddle's vertical acceleration — the input of every comfort indicator — is on the
#   default virtual session, and what limits it.
#
# Body frame of markers 1, 2, 3 (origin at marker 1, marker 2 on $+x$):
#
# $$\mathbf u_1 = \frac{\mathbf r_2-\mathbf r_1}{|\mathbf r_2-\mathbf r_1|},\quad
#   \mathbf u_2' = \frac{\mathbf r_3-\mathbf r_1}{|\mathbf r_3-\mathbf r_1|},\quad
#   \mathbf u_3 = \frac{\mathbf u_1\times\mathbf u_2'}{|\mathbf u_1\times\mathbf u_2'|},\quad
#   \mathbf u_2 = \mathbf u_3\times\mathbf u_1,\quad \mathbf R_{MB} = [\mathbf u_1|\mathbf u_2|\mathbf u_3] \quad (6.41\text{-}6.45)$$
#
# $$\mathbf r^{(B)}_{BS} = \mathbf R_{MB}^{-1}\big(\mathbf r^{(M)}_{MS} - \mathbf r^{(M)}_{MB}\big)\ \text{(static shot, 6.47)},\qquad
#   \mathbf r^{(M)}_{MS}(t) = \mathbf R_{MB}(t)\,\mathbf r^{(B)}_{BS} + \mathbf r^{(M)}_{MB}(t)\ \text{(ride, 6.48)}$$
#
# $$\mathbf v_S = \mathbf v_i + \boldsymbol\omega\times\mathbf r_{iS},\qquad
#   \mathbf a_S = \mathbf a_i + \boldsymbol\omega\times(\boldsymbol\omega\times\mathbf r_{iS}) + \boldsymbol\alpha\times\mathbf r_{iS}
#   \qquad (6.54, 6.55),\ i = 1, 2, 3,\ \text{then the mean.}$$

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
from IPython.display import display

from horsemocap import accuracy, data, frames, pipeline, plots, rigid, widgets
from horsemocap.widgets.markers_guard import thesis_three_note, thesis_view
from horsemocap.workspace import NO_TRUTH, results_for, session_truth

# %% [markdown]
# ## The data: the pipeline's own
#
# `results_for` runs (or loads) the pipeline up to the rigid-body step with the automatic choices. The
# static shot (`static`: the three skin markers and the saddle marker, in the detector's order, motion
# frame) was matched to the motion markers in notebook 08; the registered markers (from positions smoothed
# with the pipeline's default `loess`), fits and angular estimates come from notebooks 08-10. The truth (virtual laboratory: the saddle marker's position,
# velocity and acceleration, in the pipeline's motion frame) only measures errors.
#
# The body frame and eq. 6.54/6.55 take three markers. On a session with more, they are shown on markers
# 1, 2, 3 (the first three of the pipeline's model, the ones its own body frame uses); where the thesis'
# fits are absent (more than three markers, or no period), the cells say so and use the pipeline's
# smoothed pose instead (`horsemocap.widgets.markers_guard.thesis_view`).

# %%
an = results_for(until="rigid_body")
rb = an.rigid_body.body
prm = an.params
t, static = rb.t, an.motion_frame.static
n_markers = an.session.marker_count                  # session.json 'markers.count' (3 in the thesis)
print(f"{len(t)} frames; static shot {static.shape}: markers 1-{n_markers} "
      f"are static points {rb.static_index.tolist()}, the saddle marker is point {rb.saddle_index}")
print(f"the pipeline's choices: smoothing '{prm.smooth.method}', omega/alfa by '{prm.rigid_body.fits.angular_method}', "
      f"saddle v/a by '{prm.rigid_body.fits.saddle_method}'")

truth = session_truth(ws.session_dir)                   # None for a recorded session (no truth/ folder)
a, b = an.triangulate.segment
S_true = dict.fromkeys(("pos", "vel", "acc"))           # the truth's saddle, where there is one
if truth is None:
    print(NO_TRUTH, "(a recorded session): the errors below are left out, the rest goes on")
else:
    tt = accuracy.analysed_truth(an, truth)              # the truth at the analysed frames, pipeline's frame
    S_true = {"pos": tt["saddle_pos"], "vel": tt["saddle_vel"], "acc": tt["saddle_acc"]}

# %% [markdown]
# ## The saddle marker in the body frame (static shot)

# %%
model3 = rb.model[:3]                                # the thesis' three markers (all of them on a 3-marker session)
if thesis_three_note(n_markers):
    print(thesis_three_note(n_markers))
R_MB, origin = rigid.body_frame(model3)
r_BS = rigid.saddle_in_body(model3, rb.static_saddle)
print("R_MB (columns u1 u2 u3):")
print(np.array2string(R_MB, precision=3, suppress_small=True))
print("r_BS^(B) (m):", np.array2string(r_BS, precision=3))
print(f"the pipeline's r_BS^(B) (base marker 1) is the same (to 1e-12 m): {np.abs(rb.saddle_body[0] - r_BS).max() < 1e-12}")

# %% [markdown]
# ## The whole rigid-body step with your choices
#
# The controls default to the pipeline's choices: all six versions of $\boldsymbol\omega$ and
# $\boldsymbol\alpha$, its angular method, and its saddle method. The last control chooses which saddle
# velocity/acceleration is passed on to the comfort step: the thesis' mean of eq. 6.54/6.55 (with the
# $\boldsymbol\omega$, $\boldsymbol\alpha$ of the angular method), or the derivatives of a fit (section 5.5)
# of the saddle's own path — eq. 6.48 frame by frame ("direct"), or eq. 6.48 with the registered orientation
# first fitted over time ("pose"). Not in the thesis: the y and z fits also carry a linear trend term,
# because an estimated motion frame is never exactly level. The next cell runs the pipeline's rigid-body
# step again with your choices and measures it with `accuracy.stage_errors` (in the true motion frame).

# %% tags=["nbval-ignore-output"]
ui_w = widgets.ui_versions("omega", value=prm.rigid_body.fits.omega_versions)
ui_a = widgets.ui_versions("alfa", value=prm.rigid_body.fits.alpha_versions)
ui_method = widgets.ui_angular_method(value=prm.rigid_body.fits.angular_method)
ui_saddle = widgets.ui_saddle_method(value=prm.rigid_body.fits.saddle_method)
for ui, name in ((ui_w, "omega_versions"), (ui_a, "alpha_versions"), (ui_method, "angular_method"),
                 (ui_saddle, "saddle_method")):
    ws.bind(ui, name)
display(ui_w, ui_a, ui_method, ui_saddle)

# %%
chosen = accuracy.with_params(an, omega_versions=[bool(v) for v in ui_w.value],
                              alpha_versions=[bool(v) for v in ui_a.value],
                              angular_method=ui_method.value, saddle_method=ui_saddle.value)
with warnings.catch_warnings():
    warnings.simplefilter("ignore", RuntimeWarning)
    run = pipeline.run_steps(an.session, chosen, an, ["rigid_body"])
res = run.rigid_body.body
view = thesis_view(res)                              # the pipeline's own arrays when its chain ran
# what the comfort step receives: the smoothed pose trajectory's saddle (the default) or a fit of the chain
passed_on = ("the pipeline's pose trajectory" if chosen.rigid_body.kinematics == "pose_spline"
             else f"fit of the saddle path ({res.saddle_method})")
if not view.chain:
    print(view.note)
if truth is None:
    print(f"{NO_TRUTH}; the saddle passed on ({res.saddle_method}): vertical acceleration rms "
          f"{np.sqrt(np.nanmean(run.rigid_body.saddle_acceleration[:, 1] ** 2)):.2f} m/s²")
else:
    st = accuracy.stage_errors(run, truth)
    print("saddle position (eq. 6.48) RMSE x/y/z (mm): "
          + "  ".join(f"{1000 * e:.1f}" for e in frames.rmse_per_axis(view.saddle.position, S_true["pos"])))
    print(f"saddle passed on ({passed_on}) RMSE x/y/z (mm): "
          + "  ".join(f"{1000 * e:.1f}" for e in st["saddle_position"]))
print("per-base position versions agree (to 1e-9 m):",
      bool(np.abs(view.saddle.position_versions - view.saddle.position).max() < 1e-9))
if res.saddle_fit is not None:
    print(f"fit of the saddle path: orders {res.saddle_fit.orders.tolist()}")
else:
    print("fit of the saddle path: none (no thesis fits); the saddle passed on is the pipeline's smoothed pose's")
if truth is not None:
    print("saddle acceleration RMSE x/y/z (m/s²): " + "  ".join(f"{e:.2f}" for e in st["saddle_acceleration"])
          + f"; vertical: {st['saddle_acc_y_rmse_pct_of_rms']:.1f} % of its rms")

# %% [markdown]
# Figure 8.22: the saddle marker (a) alone and (b) with the visible markers (y points down).

# %%
fig = plots.plot_saddle_position(t, res.saddle_path, res.pos, truth=S_true["pos"])
plt.show()

# %% [markdown]
# The lateral (z) position is the weak one: the skin markers form a thin triangle (7 cm high, 48 cm long),
# a few millimetres of depth error on marker 2 roll it by degrees about the markers' row (the roll notebook
# 10 could not measure), and the saddle sits 0.45 m from that row.
#
# Figures 8.23-8.24: velocity and acceleration from each marker (eq. 6.54, 6.55), their mean, the fit of the
# saddle path, the saddle the comfort step receives (the pipeline's pose trajectory, by default), and the
# truth. The thesis' fit of the saddle path models the forward motion x as a polynomial in time (section
# 5.5.2.1, degree `x_degree`, 1: a line), so its forward velocity is constant and its forward acceleration zero,
# while the horse surges at every stride; y and z are its Fourier series. Without the thesis' fits: eq.
# 6.54/6.55 on markers 1, 2, 3 of the smoothed pose, beside the pipeline's own saddle.

# %%
extra = {view.saddle_fit_label: (view.saddle_fit_velocity, view.saddle_fit_acceleration)}
if view.chain and chosen.rigid_body.kinematics == "pose_spline":   # the saddle passed on is not the chain's
    extra[f"{passed_on} (passed on)"] = (run.rigid_body.saddle_velocity, run.rigid_body.saddle_acceleration)
fig = plots.plot_saddle_kinematics(t, view.saddle.velocity_versions, view.saddle.acceleration_versions,
                                   view.saddle.velocity, view.saddle.acceleration, S_true["vel"], S_true["acc"],
                                   extra=extra)
plt.show()

# %% [markdown]
# ## How accurate is the saddle's vertical acceleration?
#
# The accuracy goal of this reproduction: RMSE of the saddle's vertical acceleration at most 5 % of the rms of the true
# one. Every saddle method, with the pipeline's other choices, and the thesis' whole chain (its six-version
# $\boldsymbol\omega$, $\boldsymbol\alpha$ in eq. 6.55), each a run of the pipeline's rigid-body step
# measured by `accuracy.stage_errors`:

# %%
if truth is None:
    print(NO_TRUTH)
else:
    variants = [("eq. 6.55 mean", prm.rigid_body.fits.angular_method, "thesis"),
                ("eq. 6.55 mean", "thesis", "thesis"),
                ("eq. 6.55 mean", "lstsq", "thesis"),
                ("fit of eq. 6.48 path", prm.rigid_body.fits.angular_method, "direct"),
                ("fit of pose path", prm.rigid_body.fits.angular_method, "pose")]
    ay = S_true["acc"][:, 1]
    print(f"rms of the true vertical acceleration: {np.sqrt(np.nanmean(ay ** 2)):.2f} m/s²")
    print("saddle v/a from          omega/alfa  position RMSE x/y/z (mm)   vertical acc RMSE        target <= 5 %")
    fits_default = prm.rigid_body.kinematics == "fits"
    for label, am, sm in variants + [("smoothed pose trajectory", "-", "-")]:
        change = dict(kinematics="fits", angular_method=am, saddle_method=sm) if am != "-" else \
            dict(kinematics="pose_spline")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            r = pipeline.run_steps(an.session, accuracy.with_params(an, **change), an, ["rigid_body"])
        e = accuracy.stage_errors(r, truth)
        pct = e["saddle_acc_y_rmse_pct_of_rms"]
        default = (am == "-" and not fits_default) or \
            (fits_default and (am, sm) == (prm.rigid_body.fits.angular_method, prm.rigid_body.fits.saddle_method))
        print(f"{label:24s} {am:10s}  " + " ".join(f"{1000 * v:6.1f}" for v in e["saddle_position"])
              + f"   {e['saddle_acceleration'][1]:8.3f} m/s² {pct:8.1f} %   {'met' if pct <= 5 else 'MISSED'}"
              + ("   <- pipeline default" if default else ""))

# %% [markdown]
# The first five rows are the thesis' chain of fits (`kinematics="fits"`) with its choices of
# $\boldsymbol\omega$, $\boldsymbol\alpha$ and saddle path; the last is the pipeline's default
# (`kinematics="pose_spline"`): every frame's pose registered from all markers, its trajectory
# smoothed by splines that keep the stride's harmonics whole (their frequency found in the record), the
# saddle's acceleration from the smoothed pose. On this one session the best of the chain of fits (the pose
# path, fitted) is about as good: the session's motion is exactly a Fourier series of the stride (the
# virtual laboratory builds it that way), the fits' own model. On 24 other sessions (the 16 of the virtual
# herd and 8 harder ones: other rigs, frame rates, a horse that slows down) the pose trajectory is far
# better: saddle error median 2.7 % and 1.1 % against 24.1 % and 17.9 % with the fits (measured by the
# scripts of `benchmarks/`, whose `README.md` lists the numbers), and so it is the default; a real horse's motion is not an exact
# Fourier series, and the pose trajectory needs no period at all (a lift, a transition).
#
# Among the fits, the saddle path built with the fitted orientation ("pose", then fitted) meets the 5 %
# target on this session, and so does the thesis' eq. 6.55 *if* it is fed the
# orientation fit's $\boldsymbol\omega$, $\boldsymbol\alpha$. The thesis' own chain (six-version averages in
# eq. 6.55) misses it by orders of magnitude: $\boldsymbol\alpha$ is wrong by tens to hundreds of rad/s² near
# the singularity of section 6.1 (notebook 10) and the lever arm is 0.45 m — exactly the thesis' experience at
# canter. The least-squares $\boldsymbol\omega$, $\boldsymbol\alpha$ miss it too, and so does the direct fit of
# the eq. 6.48 path: frame by frame that path inherits the poorly measured roll of the marker triangle.
#
# ## Which smoothing?
#
# All of the above used the pipeline's default smoothing of the triangulated positions, `loess` (MATLAB's
# `smooth(y, 0.1, 'loess')`, notebook 06). The thesis smoothed with `rloess`, which adds robust iterations.
# The chain of fits (angular method and saddle method unchanged) with each smoothing, from the smoothing step
# on:

# %%
if truth is None:
    print(NO_TRUTH)
else:
    print("smoothing   saddle path RMSE x/y/z (mm)   vertical acc RMSE        target <= 5 %")
    for sm in ("none", "loess", "rloess"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            r = pipeline.run_steps(an.session, accuracy.with_params(an, smoothing_method=sm, kinematics="fits"),
                                   an, ["smooth", "motion_frame", "rigid_body"])
        e = accuracy.stage_errors(r, truth)
        pct = e["saddle_acc_y_rmse_pct_of_rms"]
        print(f"{sm:10s}  " + " ".join(f"{1000 * v:6.1f}" for v in e["saddle_position"])
              + f"          {e['saddle_acceleration'][1]:8.3f} m/s² {pct:8.1f} %   {'met' if pct <= 5 else 'MISSED'}"
              + ("   <- pipeline default" if sm == prm.smooth.method else ""))

# %% [markdown]
# On this one session no smoothing happens to be the best, and the thesis' `rloess` is the worst: its robust
# iterations reject good samples near the ends of a 39-frame record, where a 0.1 span is only a few points.
# One session is not enough to choose a default. The default comes from the 16 sessions of the virtual herd
# (4 horses × walk, sitting trot, rising trot, canter), measured by the script `benchmarks/bench_herd.py`
# with the same detections and rig for each method (the thesis' per-camera detection); the numbers below
# are quoted from its results, this notebook does not recompute them (it takes many minutes):
#
# | smoothing | saddle vertical acc RMSE, median over the 16 sessions (% of rms) | Wb-weighted rms, median \|error\| | Wb-weighted rms, worst session \|error\| |
# |---|---|---|---|
# | none | 39 % | 20.4 % | 53.5 % |
# | `rloess` (thesis) | 30.8 % | 9.5 % | 140 % |
# | `loess` (default) | 24.6 % | 7.9 % | 17.6 % |
#
# What this means: **the 5 % target is met on this session, not across the herd.** Over the herd the
# saddle's vertical acceleration error of the chain of fits is typically about a quarter of its rms (median
# 24.6 %), and Horse 2 at canter, the session bundled here, is among the easiest of the 16 (the herd's own
# rendering of it gave 2.8 %, the lowest of the 16). The comfort indicators computed from that acceleration
# come out closer to the truth than the acceleration itself (median 7.9 % for the Wb-weighted rms), and the
# default was chosen on them. Notebook 14 follows detection noise through the whole chain.

# %% [markdown]
# ## A record without a stride: a lift, a set-down and ringing
#
# Everything above is periodic: a horse at a steady gait. The pose trajectory needs no period, and a real
# recording may hold none (a transition, an impact). `synthetic.lift_with_ringing` is such a record with
# exact truth: a box of four markers lifted, held, set down, and ringing at 10 Hz after the set-down (100 Hz,
# 0.3 mm marker noise), a deliberately hard test for any smoother.
#
# **How much to smooth: GCV.** A smoothing spline trades closeness to the measured points against
# roughness; one number, the smoothing parameter $\lambda$, sets the trade. *Generalised cross-validation*
# (GCV) chooses $\lambda$ from the data alone: it estimates, for each $\lambda$, how well the spline would
# predict a sample left out of the fit, $\mathrm{GCV}(\lambda) = n\,\mathrm{RSS}(\lambda) / (n -
# \mathrm{tr}\,\mathbf H_\lambda)^2$, where RSS is the sum of squared residuals and
# $\mathrm{tr}\,\mathbf H_\lambda$ the spline's *effective degrees of freedom* (how many free parameters
# the smoothed curve behaves as if it had: $n$ with no smoothing, 2 for a straight line), and keeps the
# $\lambda$ with the smallest value. It assumes the errors are independent from sample to sample.
#
# Which smoothing runs is the pipeline's choice (`pose_smoothing="auto"`, `pose.choose_smoothing`): GCV with
# the stride's harmonics when a stride frequency is found, otherwise the *adaptive* spline, whose penalty
# follows the local roughness so that the calm lift is smoothed harder than the ringing. Below: the hidden corner's acceleration and the body's $\boldsymbol\omega$,
# RMSE as a percentage of their rms, for the default, for plain GCV, and for the default told when the
# ringing starts (`events`, as a force plate would tell it; `horsemocap kinematics ... --events 2.8`).

# %%
from horsemocap import pose, synthetic
from horsemocap.params import PoseParams

box = synthetic.lift_with_ringing(seed=0)
box_reg = pose.register_pose(box["markers"], box["model"])
box_acc = {}
print("smoothing                       hidden-point acc   omega   (RMSE, % of rms)   what ran")
for label, options in (("default (auto)", {}), ("gcv", dict(smoothing="gcv")),
                       ("default, onset given (2.8 s)", dict(events=[2.8]))):
    tr = pose.fit_pose_trajectory(box["t"], box_reg, box["model"], PoseParams(**options))
    box_acc[label] = tr.point(box["t"], box["hidden_body"]).acceleration
    ran = tr.smoothing_choice
    print(f"{label:30s} {accuracy.rmse_pct_of_rms(box_acc[label], box['hidden_acc']):10.1f} %"
          f" {accuracy.rmse_pct_of_rms(tr.omega(box['t']), box['omega']):7.1f} %"
          + (f"                {ran['method']}: {ran['reason']}" if ran else "                gcv (asked)"))

# %%
near = (box["t"] > 2.4) & (box["t"] < 3.4)
fig, ax = plt.subplots(figsize=(8, 3.2))
ax.plot(box["t"][near], box["hidden_acc"][near, 1], "k", lw=2, label="truth")
for label, style in (("gcv", ":"), ("default (auto)", "-"), ("default, onset given (2.8 s)", "--")):
    ax.plot(box["t"][near], box_acc[label][near, 1], style, label=label)
ax.set_xlabel("time (s)")
ax.set_ylabel("vertical acceleration (m/s²)")
ax.set_title("Hidden corner of the box: the set-down and the ringing")
ax.legend(fontsize=8)
fig.tight_layout()
plt.show()

# %% [markdown]
# The goals set for this record are errors below 15 % for the acceleration and 10 % for
# $\boldsymbol\omega$. The table above is one noise draw (seed 0). Over three draws (the script
# `benchmarks/bench_kinematics.py`, medians) the default
# meets the second and misses the first: 18.4 % and 9.6 % (plain GCV 25.0 % and 13.9 %); over ten draws
# 18.0 % and 9.1 %, every draw's omega below 10 %. Most of the error sits in the dozen
# samples where the ringing starts: the acceleration jumps there, and any smoother spreads a jump. Told the
# onset (`events` here; `pose_events` or `--pose-events` for a session, `--events` for 3D markers from
# another system), the spline may jump at it, and the error drops to 14.9 % (median of three draws; this draw
# 15.5 %: at the target, not safely below it). Found from the data, it is not: a scan
# for the onset mistakes the lift's own starts for onsets, or, calibrated against them, finds nothing
# (`benchmarks/bench_kinematics_tries.py --detect`); and no smoother with constant settings can do better than
# 21 % on this record (a bound found by choosing the smoothing with the exact truth in hand, which no real
# measurement has; `benchmarks/README.md`). The acceleration goal is missed, and the miss is kept visible here.

# %% [markdown]
# ## Which point of the static shot is the saddle marker? (Appendix A 12a)
#
# The thesis' user typed the label of the saddle marker in the static shot. The pipeline takes the
# point that the ride's three markers leave over; the dropdown lists the static shot's points (left
# to right in the reference camera) with that choice selected.

# %% tags=["nbval-ignore-output"]
auto_saddle = an.rigid_body.saddle_index
ui_saddle_marker = widgets.ui_saddle_marker(an.static.static_px, auto_saddle)
ws.bind(ui_saddle_marker, "saddle_marker")
display(ui_saddle_marker)

# %%
print(f"saddle marker: static-shot point {ui_saddle_marker.value} (the pipeline's choice: point {auto_saddle})")

# %% [markdown]
# ## A real marker cluster: noise that is correlated over frames
#
# The virtual laboratory's markers carry image noise that is nearly independent from frame to frame. Real
# systems do not: a motion-capture system filters its trajectories, the tape wobbles, skin slides. Here is
# a real record (a tennis player's head, four markers of an OptiTrack system at 50 Hz, from
# `data_samples/real_c3d`, see its `PROVENANCE.md`). Three markers play the skin markers; the fourth
# plays the saddle marker: it is left out of everything and only used to judge. Its *reference*
# acceleration is its own measured path through a Savitzky-Golay filter (order 4, 13 frames: each sample
# replaced by the value, or the second derivative, of a 4th-degree polynomial fitted by least squares to
# the 13 samples around it), and a second reference has no filter at all: its plain second differences
# (noisy, but with nothing chosen).
#
# The markers' rigidity residual (what the rigid fit leaves) is a measurement of the noise the motion
# does not contain. Its frame-to-frame correlation `rho` tells how correlated the noise is (modelled as a
# first-order autoregression, AR(1): each frame's error is `rho` times the previous frame's plus fresh noise);
# GCV (section above) assumes independent errors and, with correlated ones, takes slow noise for motion.

# %%
from scipy.signal import savgol_filter

from horsemocap import io3d, pose
from horsemocap.params import PoseParams

head = io3d.read_c3d(data.data_samples_dir() / "real_c3d" / "kinematics_tennis_serve.c3d")
names = ["Derrick:LFHD", "Derrick:RFHD", "Derrick:LBHD", "Derrick:RBHD"]
cluster = head.subset(names)[:600]
t_head = head.time_s[:600]
rate = 1 / float(np.median(np.diff(t_head)))
seen, static_model = cluster[:, :3], cluster[0]          # the first frame plays the static shot
hidden_point = static_model[3]

reg_head = pose.register_pose(seen, static_model[:3])
rho_all = pose.rigidity_residual_correlation(seen, reg_head)
print(f"{len(t_head)} frames at {rate:.0f} Hz; rigidity residual's correlation rho = {rho_all:.2f}")

# %% [markdown]
# Four smoothings of the same three markers, and the naive filter a biomechanics lab would use: the
# per-frame rigid fit (the rotation and translation that carry the static shot's markers closest, in least
# squares, onto this frame's: Kabsch's method, the registration of notebook 08), then a Savitzky-Golay filter
# of the predicted point (order 3, 7 frames).
#
# - `auto`: the pipeline's choice (with `rho` significant: GCV with the AR(1) correlation);
# - plain GCV (the noise taken as independent);
# - leave one marker out: each visible marker in turn is predicted from the others' smoothed pose, and the
#   smoothing (GCV's, scaled by $10^s$) that predicts the left-out markers' frame-to-frame acceleration
#   best is kept (`pose.marker_cross_validation`). A marker's own noise is not in the pose that predicts
#   it, so this criterion holds whatever the noise's correlation over frames.

# %%
params_gcv = PoseParams(smoothing="gcv", harmonics="none")
fits = {"auto": pose.fit_pose_trajectory(t_head, reg_head, static_model[:3], points=seen),
        "plain GCV": pose.fit_pose_trajectory(t_head, reg_head, static_model[:3], params_gcv, points=seen)}
base_lam = np.array([s.info["lam"] for s in fits["plain GCV"].centre_splines + fits["plain GCV"].rotvec_splines])
lam_cv, cv_info = pose.marker_cross_validation(t_head, reg_head, seen, static_model[:3], base_lam)
fits["leave one out"] = pose.fit_pose_trajectory(t_head, reg_head, static_model[:3], params_gcv, lam=lam_cv)

inside = (t_head > t_head[0] + 0.25) & (t_head < t_head[-1] - 0.25)
ref_acc = savgol_filter(cluster[:, 3], 13, 4, deriv=2, delta=1 / rate, axis=0)
raw_acc = np.diff(cluster[:, 3], 2, axis=0) * rate ** 2
predicted = reg_head.centre + np.einsum("kij,j->ki", reg_head.rotation, hidden_point - static_model[:3].mean(0))
estimates = {name: (fit.point(t_head, hidden_point).position, fit.point(t_head, hidden_point).acceleration)
             for name, fit in fits.items()}
# the naive filter: 7 frames (0.14 s at 50 Hz), order 3
estimates["Kabsch + Savitzky-Golay"] = (savgol_filter(predicted, 7, 3, axis=0),
                                        savgol_filter(predicted, 7, 3, deriv=2, delta=1 / rate, axis=0))


print(f"{'method':26s} {'vs filtered reference %':>24s} {'vs raw differences m/s2':>24s}")
for name, (position, acc) in estimates.items():
    print(f"{name:26s} {accuracy.rmse_pct_of_rms(acc[inside], ref_acc[inside]):24.1f} {accuracy.second_difference_rmse(position, raw_acc, rate, inside):24.2f}")
print(f"auto chose: {fits['auto'].smoothing_choice['reason']}")
print(f"leave one out chose s = {cv_info['cross_validation_decades']:g} (GCV's smoothing times 10^s)")

# %%
fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 3.8))
window = (t_head > 4.0) & (t_head < 7.0)
ax1.plot(t_head[window], ref_acc[window, 1], "k", lw=2, label="hidden marker, filtered (reference)")
for name, (_, acc) in estimates.items():
    ax1.plot(t_head[window], acc[window, 1], lw=1, label=name)
ax1.set(xlabel="t (s)", ylabel="vertical acceleration (m/s²)", title="The hidden marker")
ax1.legend(fontsize=7)
ax2.plot(pose.CROSS_VALIDATION_DECADES, cv_info["cross_validation_scores"], "o-")
ax2.set(xlabel="s (smoothing = GCV's × 10^s)", ylabel="left-out markers' error (m/s², rms)",
        title="Leaving one marker out")
plt.tight_layout()
plt.show()

# %% [markdown]
# What to read here. Plain GCV keeps far too much: its acceleration error against the filtered
# reference is two and a half times the naive filter's. Told the noise's correlation, GCV smooths more and
# does a little better than the naive filter. The left-out markers, however, say something else: what they
# measure frame by frame is predicted best by little smoothing (the curve on the right is lowest near
# $s = 0$), and so is the hidden marker's own frame-by-frame acceleration (second column: there the
# leave-one-out choice is the best of the four and the correlated-noise choice the worst). Much of the fast content that the filtered
# reference removes is shared by all four markers of the head: real motion, or an error common to the
# whole cluster, which no data from the cluster alone can tell apart. The "best" smoothing therefore depends
# on what it is judged against: a fixed filter rewards the smoothing closest to its own, and a comparison
# of methods must say which reference it uses (`benchmarks/README.md` lists both for ten real clusters from three systems).

# %% [markdown]
# ### When correlated noise looks like the stride
#
# A gait is periodic, and noise correlated over frames has most of its power at low frequencies, where the
# stride's harmonics are. One pose component of a trot (two harmonics of 1.5 Hz, 3 s at 50 Hz) with AR(1)
# noise of lag-1 correlation 0.8, smoothed three ways:
#
# - the partial spline of white noise (`fundamental_hz`: the stride's harmonics unpenalised, GCV taking the
#   noise as independent): the slow noise looks like signal, and it keeps it;
# - the correlated-error GCV without harmonics (`noise_correlation`): it charges every degree of freedom what
#   the correlated noise could imitate there, and the stride is slow enough to be imitated: it is flattened;
# - both (`fundamental_hz` and `noise_correlation`): the harmonics are kept whole, each charged what the noise
#   at its frequency imitates (the criterion's $\mathrm{tr}(\mathbf H \mathbf C)$ instead of
#   $\mathrm{tr}(\mathbf H)$), and only the rest is smoothed.
#
# The pipeline's pose smoothing runs the second when the rigidity residual's correlation is significant; when
# that takes the stride for noise (a component flattened, or the stride's harmonics left in a residual) it
# fits the pose again the third way, and `analysis.json` says so (`chosen.pose_smoothing.correlated_harmonics`).

# %%
from scipy.signal import lfilter

from horsemocap.splines import smoothing_spline

t_stride = np.arange(150) / 50.0
f_stride = 1.5
stride = 0.02 * np.sin(2 * np.pi * f_stride * t_stride) + 0.005 * np.sin(4 * np.pi * f_stride * t_stride + 1)
stride_acc = (-(2 * np.pi * f_stride) ** 2 * 0.02 * np.sin(2 * np.pi * f_stride * t_stride)
              - (4 * np.pi * f_stride) ** 2 * 0.005 * np.sin(4 * np.pi * f_stride * t_stride + 1))
ar1_noise = lfilter([1.0], [1.0, -0.8], np.random.default_rng(4).normal(0, 0.0012, t_stride.size))
measured = stride + ar1_noise
three_ways = {"white noise, with harmonics": smoothing_spline(t_stride, measured, fundamental_hz=f_stride),
              "AR(1), no harmonics": smoothing_spline(t_stride, measured, noise_correlation=0.8),
              "AR(1), with harmonics": smoothing_spline(t_stride, measured, fundamental_hz=f_stride,
                                                        noise_correlation=0.8)}
fig, ax = plt.subplots(figsize=(10, 3.6))
ax.plot(t_stride, stride_acc, "k", lw=2, label="true")
for name, fit in three_ways.items():
    error = 100 * np.sqrt(np.mean((fit(t_stride, 2) - stride_acc) ** 2) / np.mean(stride_acc ** 2))
    print(f"{name:28s} acceleration error {error:5.1f} % of its rms; harmonics kept "
          f"{fit.info.get('harmonic_indices', [])}")
    ax.plot(t_stride, fit(t_stride, 2), lw=1, label=name)
ax.set(xlabel="t (s)", ylabel="acceleration (m/s²)", title="One pose component of a trot, AR(1) 0.8 noise")
ax.legend(fontsize=8)
plt.show()

# %% [markdown]
# ## Your choices, downstream
#
# What the choices made so far (the saddle-marker picker and the smoothing above, and the widgets of the
# earlier notebooks) give at the end of each chain: the saddle's vertical acceleration (unweighted rms), its
# $W_b$- and $W_k$-weighted rms (chapter 7, notebook 12) and the quality verdict of the run (the
# `quality.json` of a results folder: *ok*, *warning* or *unreliable*, with what each check found). The
# chain followed is the one chosen in notebook 00; both are shown because a choice belongs to one chain.
# Move a widget above, then run this cell again.

# %%
from horsemocap.workspace import downstream_text

print(downstream_text(ws.session_dir))

# %% [markdown]
# ## Exercises
#
# 1. Use the base-2 body frame (`rigid.saddle_in_body(rb.model, rb.static_saddle, base=1)`) and eq. 6.48
#    with `base=1`: is the saddle's path the same? Why must it be for registered markers?
# 2. Choose the thesis' eq. 6.55 mean with the thesis versions (angular method "thesis versions", saddle
#    "eq. 6.54/6.55 mean"). Which term of eq. 6.55 dominates its error: $\boldsymbol\alpha\times\mathbf r_{iS}$ or
#    $\boldsymbol\omega\times(\boldsymbol\omega\times\mathbf r_{iS})$?
# 3. The thesis reports the saddle's peak vertical acceleration (`acc_y_max`, Table 8.7: 11.7 m/s² at
#    canter). Compare the peak of the pipeline's vertical acceleration with the truth's.
# 4. Give the box's onset one sample early or late (`events=[2.79]`, `[2.81]`) or 25-50 ms late. How much of
#    the gain of a known onset is left? What does that say about finding the onset from the data?
#
# <details><summary>Solutions</summary>
#
# 1. `rigid.saddle_position(rb.pos, rigid.saddle_in_body(rb.model, rb.static_saddle, base=1), base=1)`
#    equals `rb.saddle.position` to rounding: registered markers are the static shot moved rigidly, so
#    any body frame built on them moves with the same rotation and translation.
# 2. `r = res.saddle.position - res.pos[:, 0]`; compare `np.cross(res.alpha, r)` with
#    `np.cross(res.omega, np.cross(res.omega, r))` (and the same with `vec`-rotated true values): the
#    angular acceleration term carries most of the error (tens to hundreds of rad/s² of error, notebook 10,
#    times 0.45 m).
# 3. `np.abs(rb.saddle_acceleration[:, 1]).max()` vs `np.abs(S_true["acc"][:, 1]).max()`: the fit smooths
#    the peak a little; 39 frames at 30 fps sample the peak itself only roughly.
# 4. With this draw: no onset 18.9 %, 2.80 s 15.5 %, 2.79 s 19.9 %, 2.81 s 19.7 %, 2.825 s 19.3 %, 2.85 s
#    30.6 % (hidden-point acceleration). One sample off and the gain is gone, later it is worse than
#    nothing: an onset found from the data must be right to the sample, which is why a scan of the noisy
#    record did not help.
#
# </details>
