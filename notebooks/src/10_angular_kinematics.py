# %% [markdown]
# # 10 · Angular velocity and acceleration of the saddle's rigid body
#
# **What you will learn**
# - the relative-velocity equations of three points of a rigid body and the thesis' two closed-form
#   solutions for $\boldsymbol\omega$ (eq. 6.1-6.18) and $\boldsymbol\alpha$ (eq. 6.36-6.39);
# - the compatibility condition (eq. 6.19-6.28) that makes the two solutions equal;
# - the six *versions* (three base markers × two solutions), their smoothing and the check boxes that
#   choose which enter the average (Appendix A step 11, Figures 8.14-8.20);
# - the **singularity** $\boldsymbol\omega\cdot\mathbf n = 0$ (eq. 6.31-6.35), measured frame by frame, and
#   why the thesis' own canter example fell into it;
# - two solutions without that singularity: least squares over all markers and a fit of the
#   registered orientation — and how their errors compare with the thesis versions.
#
# $$\mathbf v_1 = \mathbf v_2 + \boldsymbol\omega\times\mathbf r_{21},\qquad
#   \mathbf v_1 = \mathbf v_3 + \boldsymbol\omega\times\mathbf r_{31} \qquad (6.1, 6.2)$$
#
# $$\boldsymbol\omega^1 = \frac{(\mathbf v_2-\mathbf v_1)\times(\mathbf v_3-\mathbf v_1)}{-\mathbf r_{31}\cdot(\mathbf v_2-\mathbf v_1)},\qquad
#   \boldsymbol\omega^2 = \frac{(\mathbf v_2-\mathbf v_1)\times(\mathbf v_3-\mathbf v_1)}{\mathbf r_{21}\cdot(\mathbf v_3-\mathbf v_1)} \qquad (6.3, 6.4)$$
#
# with $\mathbf r_{21} = \mathbf r_1 - \mathbf r_2$ (from marker 2 to marker 1, as eq. 6.1 requires).
# "Version $i$" expresses $\mathbf v_i$ through the two others, taken cyclically (1,2,3), (2,3,1), (3,1,2).
# For $\boldsymbol\alpha$ (eq. 6.38-6.39) the same algebra uses
# $\mathbf K_2 = \mathbf a_2 - \mathbf a_1 + \boldsymbol\omega\times(\boldsymbol\omega\times\mathbf r_{21})$ and
# $\mathbf K_4 = \mathbf a_3 - \mathbf a_1 + \boldsymbol\omega\times(\boldsymbol\omega\times\mathbf r_{31})$:
# the printed eq. 6.38/6.39 omit the $-\mathbf a_1$, which is exact only when $\mathbf a_1 = 0$
# (compare eq. 6.3, which has $\mathbf v_2 - \mathbf v_1$).
#
# Both solutions become $0/0$ when $\boldsymbol\omega\cdot\mathbf n = 0$,
# $\mathbf n = \mathbf r_{21}\times\mathbf r_{31}/|\mathbf r_{21}\times\mathbf r_{31}|$ (eq. 6.33-6.35).

# %%
import warnings

import matplotlib.pyplot as plt
import numpy as np
from IPython.display import display

from horsemocap import fitting, plots, rigid, widgets

# %% [markdown]
# ## The data
#
# **Until the pipeline runs end to end**, this cell stands in for it (see notebook 08): truth + noise,
# thesis smoothing, true motion frame; then registration (notebook 08) and the automatic fits (notebook 09).

# %%
from horsemocap import data, smoothing, virtuallab

truth = virtuallab.load_truth(data.default_session_dir())
to_motion = lambda x: np.asarray(x) @ truth.motion_axes.T
rng = np.random.default_rng(0)
sigma = np.array([0.0015, 0.0015, 0.005])
t = truth.time_s
markers = smoothing.smooth_positions(to_motion(truth.marker_pos + rng.normal(size=truth.marker_pos.shape) * sigma), 0.1)
static = to_motion(truth.static_pos + rng.normal(size=truth.static_pos.shape) * sigma)[rng.permutation(4)]
order, saddle_index = rigid.match_static_markers(static, markers)
reg = rigid.register(markers, static[order])
pos = reg.registered
mfit = fitting.fit_motion(t, pos)
vel, acc = mfit.velocity(t), mfit.acceleration(t)
omega_true, alpha_true = to_motion(truth.omega), to_motion(truth.alpha)
print(f"orders (x, y, z) per marker: {mfit.orders.tolist()}")

# %% [markdown]
# ## First, on exact data
#
# With the true positions and velocities every version is exact and the compatibility condition holds
# to rounding — except where $\boldsymbol\omega$ lies in the markers' plane:

# %%
P, V = to_motion(truth.marker_pos), to_motion(truth.marker_vel)
with np.errstate(all="ignore"):
    exact = rigid.angular_velocity_versions(P, V)
ang_true = rigid.singularity_angle(P, omega_true)
far = np.abs(ang_true - 90) > 10
print(f"compatibility residual (eq. 6.20), max |.|: {np.abs(rigid.compatibility_residual(P, V)).max():.1e} m^2/s")
print(f"versions vs truth where |angle - 90| > 10 deg: max error {np.nanmax(np.abs(exact[:, far] - omega_true[far])):.1e} rad/s")
print(f"least squares vs truth, all frames: max error {np.abs(rigid.angular_velocity_lstsq(P, V) - omega_true).max():.1e} rad/s")
print(f"angle(omega, n) of the true motion: {ang_true.min():.0f} to {ang_true.max():.0f} deg; "
      f"within 15 deg of 90 in {np.mean(np.abs(ang_true - 90) < 15) * 100:.0f} % of the frames")

# %% [markdown]
# ## The six versions on measured data (Figures 8.14-8.16)

# %%
with np.errstate(all="ignore"):
    w_raw = rigid.angular_velocity_versions(pos, vel)
w_s = rigid.smooth_versions(w_raw)                      # rloess, span 0.1, as the thesis
print(f"compatibility residual on fitted data: median |.| {np.median(np.abs(rigid.compatibility_residual(pos, vel))):.2e} m^2/s")
for c in range(3):
    fig = plots.plot_angular_versions(t, w_raw, w_s, c, truth=omega_true)
    plt.show()

# %% [markdown]
# ## Choosing the versions (the thesis' y/n prompts)
#
# All six are checked by default. The thesis' user unchecked `omega1_ver2` and `omega1_ver3` in the canter
# example. The method selects what the saddle step uses: the average of the checked versions, or the
# least-squares solution.

# %% tags=["nbval-ignore-output"]
ui_w = widgets.ui_versions("omega")
ui_a = widgets.ui_versions("alfa")
ui_method = widgets.ui_angular_method()
display(ui_w, ui_a, ui_method)

# %%
use_w, use_a, method = ui_w.value, ui_a.value, ui_method.value
omega_avg = rigid.average_versions(w_s, use_w)
omega_ls = rigid.smooth_versions(rigid.angular_velocity_lstsq(pos, vel)[None])[0]
rot = rigid.fit_rotations(t, reg.rotation)
omega_rot = rot.omega(t)
omega = omega_avg if method == "thesis" else omega_ls
rmse = lambda a, b: float(np.sqrt(np.nanmean((a - b) ** 2)))
print(f"rms of the true omega: {np.sqrt(np.mean(omega_true ** 2)):.3f} rad/s")
for i, lab in enumerate(rigid.VERSION_LABELS):
    print(f"  {lab}: RMSE {rmse(w_s[i], omega_true):8.3f} rad/s" + ("" if use_w[i] else "  (not used)"))
print(f"average of chosen versions: RMSE {rmse(omega_avg, omega_true):.3f} rad/s")
print(f"least squares (all markers): RMSE {rmse(omega_ls, omega_true):.3f} rad/s")
print(f"fit of the registered orientation: RMSE {rmse(omega_rot, omega_true):.3f} rad/s")

# %% [markdown]
# Figures 8.17-8.18: all smoothed versions, the average of the chosen ones, least squares and truth.

# %%
fig = plots.plot_angular_average(t, w_s, use_w, omega_avg, truth=omega_true, lstsq=omega_ls)
plt.show()

# %% [markdown]
# ## Where the thesis formulas break: the singularity, frame by frame
#
# The three skin markers lie almost in a vertical plane along the back ($\mathbf n$ nearly lateral),
# and at canter the body pitches about the lateral axis but also rolls and yaws: whenever
# $\boldsymbol\omega$ swings through the markers' plane, the denominators of eq. 6.3/6.4 vanish. The
# thesis observed exactly this (section 8.4.1: "very close to the singularity ... quite unreliable").

# %%
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    ang = rigid.singularity_angle(pos, omega_rot)
    rep = rigid.singularity_report(ang, tolerance_deg=15)
print(f"angle(omega, n): median {rep['median_angle_deg']:.0f} deg; within 15 deg of 90 in "
      f"{100 * rep['fraction']:.0f} % of the frames; closest {rep['min_margin_deg']:.1f} deg")
print("warning:", "yes" if caught else "no")
fig = plots.plot_singularity(t, ang)
plt.show()

# %% [markdown]
# ## Angular acceleration (Figures 8.19-8.20)

# %%
with np.errstate(all="ignore"):
    a_raw = rigid.angular_acceleration_versions(pos, vel, acc, omega)
a_s = rigid.smooth_versions(a_raw)
alpha_avg = rigid.average_versions(a_s, use_a)
alpha_ls = rigid.smooth_versions(rigid.angular_acceleration_lstsq(pos, acc, omega)[None])[0]
alpha_rot = rot.alpha(t)
print(f"rms of the true alpha: {np.sqrt(np.mean(alpha_true ** 2)):.2f} rad/s^2")
print(f"average of chosen versions: RMSE {rmse(alpha_avg, alpha_true):.2f} rad/s^2")
print(f"least squares: RMSE {rmse(alpha_ls, alpha_true):.2f} rad/s^2")
print(f"fit of the registered orientation: RMSE {rmse(alpha_rot, alpha_true):.2f} rad/s^2")
fig = plots.plot_angular_average(t, a_s, use_a, alpha_avg, name="alfa", unit="rad/s²", truth=alpha_true, lstsq=alpha_ls)
plt.show()

# %% [markdown]
# **Reading the numbers.** Near the singularity a thesis version divides the noise by a vanishing
# denominator; averaging several such versions does not help. Least squares over all markers has no
# $\boldsymbol\omega\cdot\mathbf n$ singularity (only collinear markers make it singular), but the rotation
# about the markers' row (roll) is poorly conditioned: the markers are only 7 cm apart across it. The fit of
# the registered orientation uses all markers *and* the smoothness of a periodic motion, and is the most
# accurate here. None of this is needed for the saddle's vertical acceleration if the saddle's own path
# is fitted (notebook 11).
#
# ## Exercises
#
# 1. Uncheck `omega1_ver2` and `omega1_ver3` as the thesis' user did. Does the average improve?
# 2. Using `P, V` (exact data), rotate the marker layout so that marker 2 is 15 cm higher
#    (`P2 = P.copy(); P2[:, 1, 1] -= 0.15`, velocities from the same rigid motion). How does the angle
#    between $\boldsymbol\omega$ and $\mathbf n$ change? (Hint: compute `V2` with `np.cross(omega_true[:, None], P2 - P2[:, :1]) + V[:, :1]`.)
# 3. Check numerically that with $\mathbf a_1 \neq 0$ the printed eq. 6.38 (without $-\mathbf a_1$)
#    does not return $\boldsymbol\alpha$.
#
# <details><summary>Solutions</summary>
#
# 1. Usually a little, because those two versions' denominators are the ones that vanish first in this
#    layout; but the result stays far from least squares and the orientation fit.
# 2. Raising marker 2 tilts the markers' plane towards the horizontal, so $\mathbf n$ turns towards the
#    vertical and away from the pitch axis: the angle moves away from 90° in most frames and the versions
#    become usable — the thesis' advice to "change the locations of the 3 markers".
# 3. `K2 = A[:, 1] + np.cross(w, np.cross(w, r21))` (with `A = to_motion(truth.marker_acc)`, `w = omega_true`,
#    `r21 = P[:, 0] - P[:, 1]`) and similarly `K4`; `np.cross(K2, K4) / -(K2 * r31).sum(1)[:, None]` differs
#    from `alpha_true` by many rad/s², while subtracting `A[:, 0]` from both makes it exact.
#
# </details>
