# %% [markdown]
# # 09 · Curve fitting: from positions to velocity and acceleration
#
# **What you will learn**
# - why the thesis fits curves instead of differencing samples, and keeps the *registered* positions
#   (section 5.5.2);
# - the x-motion polynomial (degree 1: constant speed, section 5.5.2.1);
# - Fourier series with a fitted fundamental frequency for y and z (eq. 5.23), computed as MATLAB's
#   `fit(t, y, 'fourierN')` does: spectral start point, separable nonlinear least squares on $w$;
# - the order rule of section 5.5.2.2: with $E$ extremes, fit $N = E/2$ or $E/2 + 1$;
# - the goodness of fit MATLAB reports (SSE, R², adjusted R², RMSE, 95 % bounds, section 5.5.1);
# - the widgets that replace the prompts `no_of_extreme` and `fit_choice` (Figures 5.8, 5.9, 8.13).
#
# $$g_F(t) = a_0 + \sum_{n=1}^{N} a_n\cos(n w t) + b_n \sin(n w t) \qquad (5.23)$$
#
# $$SSE = \sum (g - g_F)^2 \;(5.22),\quad R^2 = 1 - \frac{SSE}{SST},\quad
#   \bar R^2 = 1 - \frac{SSE\,(n-1)}{SST\,(n-m)},\quad RMSE = \sqrt{\frac{SSE}{n-m}}$$
#
# with $m = 2N + 2$ coefficients. The 95 % bounds are $b \pm t_{0.975,\,n-m}\sqrt{\mathrm{diag}((J^TJ)^{-1})\,SSE/(n-m)}$,
# $J$ the Jacobian of all coefficients (including $w$) at the solution.
#
# **The order rule.** $dg_F/d\theta$ becomes a polynomial of degree $2N$ in $\xi = \tan(\theta/2)$
# (eq. 5.24-5.33), so $g_F$ has at most $2N$ extremes per period of its fundamental: $E$ observed
# extremes need $N \ge E/2$ (rounded up for odd $E$). The thesis offers $E/2$ and $E/2+1$ and lets the
# user choose; here $E$ is counted on the data (a swing must exceed 10 % of the range to count) and
# the default choice takes $E/2+1$ only if it raises the adjusted R² *and* its extra harmonic is
# significant (a 95 % bound excludes zero).

# %%
import warnings

import matplotlib.pyplot as plt
import numpy as np
from IPython.display import display

from horsemocap import fitting, plots, rigid, widgets

# %% [markdown]
# ## The data
#
# **Until the pipeline runs end to end**, this cell stands in for it (as in notebook 08): truth markers
# plus noise (1.5 mm across, 5 mm in depth), thesis smoothing, true motion frame; then the registration
# of notebook 08.

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
registered = rigid.register(markers, static[order]).registered
true_kin = {"pos": to_motion(truth.marker_pos), "vel": to_motion(truth.marker_vel), "acc": to_motion(truth.marker_acc)}
print(f"{len(t)} frames, {t[-1]:.3f} s; stride period of the virtual horse {1 / 1.6667:.3f} s")

# %% [markdown]
# ## x-motion: a straight line
#
# The horse was warmed up to a steady speed, so $P_x(t) = p_1 t + p_2$ and $V_x = p_1$, $A_x = 0$.

# %%
fx = fitting.fit_polynomial(t, registered[:, 0, 0], degree=1)
print(fx.summary())
print(f"V_x,avg = {fx.coefficients[0]:.3f} m/s = {3.6 * fx.coefficients[0]:.2f} km/h "
      f"(truth mean {3.6 * true_kin['vel'][:, 0, 0].mean():.2f} km/h)")

# %% [markdown]
# The virtual horse, like a real one, surges a little within each stride (±4 cm here): a straight
# line cannot follow that, so $A_x$ of every marker is zero and misses the surge (about 2.5 m/s² rms).
# The thesis accepted this; the comfort indicators use the vertical direction only.
#
# ## y-motion of marker 1: counting extremes and two proposed fits (Figure 5.8)

# %%
y = registered[:, 0, 1]
E = fitting.count_extremes(y)
N1, N2 = fitting.proposed_orders(E)
f1, f2 = fitting.fit_fourier(t, y, N1), fitting.fit_fourier(t, y, N2)
print(f"E = {E} extremes -> proposed fourier{N1} and fourier{N2}")
for f in (f1, f2):
    print(f.summary())
truth_y = {"t": t, "pos": true_kin["pos"][:, 0, 1], "vel": true_kin["vel"][:, 0, 1], "acc": true_kin["acc"][:, 0, 1]}
fig = plots.plot_fit_choice(f1, f2, truth=truth_y, suptitle="marker 1, y-motion (down)")
plt.show()

# %% [markdown]
# Look at the fundamental $w$ of each fit. The stride frequency is $2\pi \cdot 1.667 = 10.47$ rad/s.
# MATLAB's start point takes the strongest FFT bin $k$ and tries $w_{peak}/j$, $j = 1..N$: on a
# record of about two strides the *half* frequency often wins, and a `fourier2` then holds only the
# first stride harmonic — the truth needs three (its vertical motion has 75, 12 and 2 mm at 1, 2 and 3
# times the stride frequency, i.e. 8.2, 5.3 and 2.0 m/s² of acceleration).

# %%
w_stride = 2 * np.pi / 0.6
for N in (1, 2, 3, 4):
    fm = fitting.fit_fourier(t, y, N)
    fp = fitting.fit_fourier(t, y, N, w0=w_stride)
    err = lambda f: np.sqrt(np.mean((f.evaluate(t, 2) - truth_y["acc"]) ** 2))
    print(f"fourier{N}: MATLAB start w = {fm.frequency:6.3f} rad/s, acc RMSE {err(fm):5.2f} m/s^2 | "
          f"start at the stride period w = {fp.frequency:6.3f}, acc RMSE {err(fp):5.2f} m/s^2")

# %% [markdown]
# ## z-motion of marker 1 (Figure 5.9)
#
# Lateral motion is smaller and lies along the cameras' depth, where the noise is largest.

# %%
z = registered[:, 0, 2]
Ez = fitting.count_extremes(z)
g1, g2 = (fitting.fit_fourier(t, z, n) for n in fitting.proposed_orders(Ez))
print(f"E = {Ez} -> fourier{g1.order} (adj R2 {g1.gof.adjrsquare:.4f}) or fourier{g2.order} (adj R2 {g2.gof.adjrsquare:.4f})")
truth_z = {"t": t, "pos": true_kin["pos"][:, 0, 2], "vel": true_kin["vel"][:, 0, 2], "acc": true_kin["acc"][:, 0, 2]}
fig = plots.plot_fit_choice(g1, g2, truth=truth_z, suptitle="marker 1, z-motion")
plt.show()

# %% [markdown]
# ## Your choices (the thesis' prompts)
#
# One row per marker and axis: the number of extremes $E$ (default: counted) and the choice between
# the two proposed orders (default: the automatic rule). Then the x polynomial degree.

# %% tags=["nbval-ignore-output"]
ui_orders = {(m, ax): widgets.ui_fourier_order(t, registered[:, m, ax], f"marker {m + 1}, {'xyz'[ax]}")
             for m in range(3) for ax in (1, 2)}
ui_x = widgets.ui_x_degree()
for w in ui_orders.values():
    display(w)
display(ui_x)

# %%
orders = np.array([[ui_orders[(m, 1)].value, ui_orders[(m, 2)].value] for m in range(3)])
mfit = fitting.fit_motion(t, registered, x_degree=ui_x.value, orders=orders)
auto = fitting.fit_motion(t, registered)
print("orders (x degree, y, z) per marker:", mfit.orders.tolist(), "; automatic:", auto.orders.tolist())
vel, acc = mfit.velocity(t), mfit.acceleration(t)
for m in range(3):
    ev = np.sqrt(np.mean((vel[:, m] - true_kin["vel"][:, m]) ** 2, axis=0))
    ea = np.sqrt(np.mean((acc[:, m] - true_kin["acc"][:, m]) ** 2, axis=0))
    print(f"marker {m + 1}: velocity RMSE x/y/z " + " ".join(f"{e:.3f}" for e in ev)
          + " m/s; acceleration RMSE " + " ".join(f"{e:.2f}" for e in ea) + " m/s^2")

# %% [markdown]
# Figure 8.13: the kinematics of marker 1 with the chosen fits (positions are the registered data; the
# thesis keeps them and takes only $V$ and $A$ from the fits).

# %%
fig = plots.plot_marker_fits(t, registered, mfit, marker=0, truth=true_kin)
plt.show()

# %% [markdown]
# ## Exercises
#
# 1. For marker 2, y: set $E = 6$ in its widget. Which orders are proposed, and does the acceleration
#    error of that marker go down or up?
# 2. Fit `fitting.fit_fourier(t, y, 3)` to $y = \sin(2\pi t / 0.6)$ sampled at the 38 frame times: which
#    $w$ does MATLAB's start point pick, and which does the fit end at?
# 3. The 95 % bounds of a `fourier3` fit to marker 1 y: are the third-harmonic coefficients
#    significant? What does that say about over-fitting with this noise?
#
# <details><summary>Solutions</summary>
#
# 1. $E = 6$ proposes `fourier3`/`fourier4`; the extra harmonics follow the noise more than the motion,
#    and the acceleration error grows (acceleration weighs harmonic $n$ by $(n w)^2$).
# 2. The FFT peak is bin 2 (two periods in the record): $w_{peak} = 2\pi\cdot 2/1.233 = 10.19$; with
#    $N = 3$ the tries $w_{peak}/2$, $w_{peak}/3$ add lower harmonics and can fit better, so the search
#    may end at a sub-multiple of 10.47 rad/s; `fit_fourier(..., w0=10.47)` starts at the stride frequency.
# 3. `f = fitting.fit_fourier(t, y, 3); f.confint[:, 5:7]`: with 1.5 mm noise the interval of $a_3$, $b_3$
#    usually contains zero — the rule then keeps the lower order, which misses the 3rd harmonic's
#    2 m/s². Noise, not the rule, limits what 38 frames can tell.
#
# </details>
