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

# %%
import warnings

import matplotlib.pyplot as plt
import numpy as np
from IPython.display import display

from horsemocap import plots, rigid, widgets

# %% [markdown]
# ## The data
#
# **Until the pipeline runs end to end**, this cell stands in for it (see notebook 08): the true marker
# centres plus noise (1.5 mm across, 5 mm in depth), thesis smoothing, true motion frame; the static shot
# (skin markers and saddle marker) with the same noise, in arbitrary order.

# %%
from horsemocap import data, smoothing, virtuallab

truth = virtuallab.load_truth(data.default_session_dir())
to_motion = lambda x: np.asarray(x) @ truth.motion_axes.T
rng = np.random.default_rng(0)
sigma = np.array([0.0015, 0.0015, 0.005])
t = truth.time_s
markers = smoothing.smooth_positions(to_motion(truth.marker_pos + rng.normal(size=truth.marker_pos.shape) * sigma), 0.1)
static = to_motion(truth.static_pos + rng.normal(size=truth.static_pos.shape) * sigma)[rng.permutation(4)]
S_true = {"pos": to_motion(truth.saddle_pos), "vel": to_motion(truth.saddle_vel), "acc": to_motion(truth.saddle_acc)}

# %% [markdown]
# ## The saddle marker in the body frame (static shot)

# %%
order, saddle_index = rigid.match_static_markers(static, markers)
R_MB, origin = rigid.body_frame(static[order])
r_BS = rigid.saddle_in_body(static[order], static[saddle_index])
print("R_MB (columns u1 u2 u3):")
print(np.array2string(R_MB, precision=3, suppress_small=True))
print("r_BS^(B) (m):", np.array2string(r_BS, precision=3))

# %% [markdown]
# ## The whole rigid-body step with your choices
#
# `rigid.analyse_rigid_body` runs notebooks 08-10 and this one with the defaults of their widgets:
# registration, fits, the six versions of $\boldsymbol\omega$ and $\boldsymbol\alpha$ (all checked), and the
# saddle. The last control chooses which saddle velocity/acceleration is passed on to the comfort step:
# the thesis' mean of eq. 6.54/6.55, or the derivatives of a fit (section 5.5) of the saddle's own path —
# eq. 6.48 frame by frame ("direct"), or eq. 6.48 with the registered orientation first fitted over time
# ("pose", the default). Not in the thesis: the y and z fits also carry a linear trend term, because an
# estimated motion frame is never exactly level (0.1° at 4.9 m/s is 8.5 mm/s of drift).

# %% tags=["nbval-ignore-output"]
ui_w = widgets.ui_versions("omega")
ui_a = widgets.ui_versions("alfa")
ui_method = widgets.ui_angular_method()
ui_saddle = widgets.ui_saddle_method()
display(ui_w, ui_a, ui_method, ui_saddle)

# %%
with warnings.catch_warnings():
    warnings.simplefilter("ignore", RuntimeWarning)
    res = rigid.analyse_rigid_body(t, markers, static, omega_use=ui_w.value, alpha_use=ui_a.value,
                                   method=ui_method.value, saddle_method=ui_saddle.value)
pos_rmse = np.sqrt(np.mean((res.saddle.position - S_true["pos"]) ** 2, axis=0))
print("saddle position (eq. 6.48) RMSE x/y/z (mm): " + "  ".join(f"{1000 * e:.1f}" for e in pos_rmse))
path_rmse = np.sqrt(np.mean((res.saddle_path - S_true["pos"]) ** 2, axis=0))
print(f"saddle path fitted ({res.saddle_method}) RMSE x/y/z (mm): " + "  ".join(f"{1000 * e:.1f}" for e in path_rmse))
print("per-base position versions, max spread (mm): "
      f"{1000 * np.abs(res.saddle.position_versions - res.saddle.position).max():.2f}")
print(f"fits of the saddle path: orders {res.saddle_fit.orders.tolist()}")

# %% [markdown]
# Figure 8.22: the saddle marker (a) alone and (b) with the visible markers (y points down).

# %%
fig = plots.plot_saddle_position(t, res.saddle.position, res.pos, truth=S_true["pos"])
plt.show()

# %% [markdown]
# Figures 8.23-8.24: velocity and acceleration from each marker (eq. 6.54, 6.55), their mean, the fit of the
# saddle path, and the truth.

# %% [markdown]
# The lateral (z) position is the weak one: the skin markers form a thin triangle (7 cm high, 48 cm long),
# a few millimetres of depth error on marker 2 roll it by degrees about the markers' row, and the saddle sits
# 0.45 m from that row.

# %%
fig = plots.plot_saddle_kinematics(t, res.saddle.velocity_versions, res.saddle.acceleration_versions,
                                   res.saddle.velocity, res.saddle.acceleration, S_true["vel"], S_true["acc"],
                                   extra={f"fit of the saddle path ({res.saddle_method})": (res.saddle_velocity_direct, res.saddle_acceleration_direct)})
plt.show()

# %% [markdown]
# ## How accurate is the saddle's vertical acceleration?
#
# The target of issue 7: RMSE at most 5 % of the rms of the true vertical acceleration.

# %%
ay = S_true["acc"][:, 1]
rms = np.sqrt(np.mean(ay ** 2))
def pct(a):
    return 100 * np.sqrt(np.mean((a[:, 1] - ay) ** 2)) / rms
print(f"rms of the true vertical acceleration: {rms:.2f} m/s^2")
with warnings.catch_warnings():
    warnings.simplefilter("ignore", RuntimeWarning)
    for m in ("thesis", "lstsq", "rotation"):
        r = rigid.analyse_rigid_body(t, markers, static, method=m)
        print(f"eq. 6.55 mean, omega/alpha by {m:8s}: vertical acc RMSE {pct(r.saddle.acceleration):9.1f} % of rms")
    for sm in ("direct", "pose"):
        for trend in (False, True):
            r = rigid.analyse_rigid_body(t, markers, static, saddle_method=sm, fourier_trend=trend)
            print(f"fit of the saddle path, {sm:6s} trend {str(trend):5s}: vertical acc RMSE "
                  f"{pct(r.saddle_acceleration):9.1f} % of rms")

# %% [markdown]
# Eq. 6.55 needs $\boldsymbol\alpha$ and $\boldsymbol\omega$ at a lever arm of 0.45 m, and notebook 10 showed how
# badly they are determined in this marker layout — exactly the thesis' experience at canter. The fit of the
# saddle's own path avoids them. What remains is noise: 38 frames, a fit with 8 coefficients, and a third
# stride harmonic (2 mm of motion, 2 m/s² of acceleration) that the noise hides. The same chain on the exact
# truth and for smaller noise (a few seeds each):

# %%
def chain(noise_scale, seed, smooth=True):
    g = np.random.default_rng(100 + seed)
    p = truth.marker_pos + g.normal(size=truth.marker_pos.shape) * sigma * noise_scale
    s = truth.static_pos + g.normal(size=truth.static_pos.shape) * sigma * noise_scale
    pts = smoothing.smooth_positions(to_motion(p), 0.1) if smooth else to_motion(p)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        r = rigid.analyse_rigid_body(t, pts, to_motion(s), static_index=[0, 1, 2], saddle_index=3)
    return pct(r.saddle_acceleration)

print(f"exact markers, no smoothing: {chain(0, 0, smooth=False):.2f} %")
print(f"exact markers, rloess smoothing: {chain(0, 0):.2f} %")
for scale in (0.25, 0.5, 1.0):
    v = [chain(scale, s) for s in range(3)]
    print(f"noise x{scale:4.2f} ({1.5 * scale:.2f} mm across, {5 * scale:.2f} mm depth): "
          + ", ".join(f"{x:.1f}" for x in v) + " % of rms")

# %% [markdown]
# So the method meets the 5 % target on exact data, and the thesis' own smoothing costs a few percent
# (MATLAB `rloess` bends the curve of a canter over 7 frames). With the stand-in noise the target is missed.
# The depth noise matters most: the three skin markers form a thin triangle (7 cm high, 48 cm long), a few
# millimetres of depth error on marker 2 roll it by degrees, and the saddle marker sits 0.45 m from the
# markers' row, so its path inherits that roll. `tests/test_rigid.py::test_default_session_saddle_acc`
# measures the same on the pipeline's own triangulated markers (there the depth noise is similar, the
# vertical noise much smaller, and the thesis' `rloess` smoothing is the largest error left).
#
# ## Exercises
#
# 1. Use the base-2 body frame (`rigid.saddle_in_body(static[order], static[saddle_index], base=1)`) and
#    eq. 6.48 with `base=1`: is the saddle's path the same? Why must it be for registered markers?
# 2. Which term of eq. 6.55 dominates the error of the thesis estimate: $\boldsymbol\alpha\times\mathbf r_{iS}$
#    or $\boldsymbol\omega\times(\boldsymbol\omega\times\mathbf r_{iS})$? Compute both with `res.alpha`, `res.omega`
#    and the true values.
# 3. The thesis reports the saddle's peak vertical acceleration (`acc_y_max`, Table 8.7: 11.7 m/s² at
#    canter). Compare the peak of the fitted vertical acceleration with the truth's.
#
# <details><summary>Solutions</summary>
#
# 1. `rigid.saddle_position(res.pos, rigid.saddle_in_body(static[order], static[saddle_index], base=1), base=1)`
#    equals `res.saddle.position` to rounding: registered markers are the static shot moved rigidly, so
#    any body frame built on them moves with the same rotation and translation.
# 2. `r = res.saddle.position - res.pos[:, 0]`; compare `np.cross(res.alpha, r)` with
#    `np.cross(res.omega, np.cross(res.omega, r))` and the same with the true values: the angular
#    acceleration term carries most of the error (tens of rad/s² of error times 0.45 m).
# 3. `np.abs(res.saddle_acceleration_direct[:, 1]).max()` vs `np.abs(ay).max()`: the fit smooths the peak,
#    typically by 0.5-1.5 m/s² with this noise.
#
# </details>
