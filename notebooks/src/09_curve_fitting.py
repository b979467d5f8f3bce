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

from horsemocap import fitting, plots, rigid, widgets

# %% [markdown]
# ## The data: the pipeline's own
#
# `results_for` runs (or loads) the pipeline up to the rigid-body step with the automatic choices; its
# registered markers (notebook 08: the triangulated positions smoothed with the pipeline's default `loess`,
# where the thesis used `rloess`, then registered) are the data fitted here, with the pipeline's own parameters: the
# order rule, the start of every fit's $w$ at the stride period the motion-frame step estimated, and a
# linear trend term in y and z (`fourier_trend`, not in the thesis: an estimated motion frame is never
# exactly level, and 0.1° at 4.9 m/s is 8.5 mm/s of drift, which a Fourier series cannot follow). The
# truth (marker positions, velocities, accelerations of the virtual laboratory, in the pipeline's motion
# frame) only measures the errors.

# %%
from horsemocap import accuracy, data, frames
from horsemocap.workspace import NO_TRUTH, results_for, session_truth

an = results_for(until="rigid_body")
rb = an.rigid_body.body
t, registered, auto = rb.t, rb.pos, rb.motion_fit        # the pipeline's registration and fits
prm = an.params
M = registered.shape[1]                                   # markers
if an.motion_frame.period_frames is None:                 # the motion-frame step found no period
    period_s = w0 = None                                  # every w starts at MATLAB's spectral start point
    period_text = "no period found by the motion-frame step (every w starts at MATLAB's start point)"
else:
    period_s = an.motion_frame.period_frames / an.session.fps
    w0 = 2 * np.pi / period_s                             # start point of every w (the thesis typed period = 18)
    period_text = f"period {an.motion_frame.period_frames:.2f} frames = {period_s:.3f} s"
print(f"{len(t)} frames, {t[-1]:.3f} s; smoothing '{prm.smooth.method}'; order rule '{prm.rigid_body.fits.order_rule}', "
      f"trend {prm.rigid_body.fits.trend}, x degree {prm.rigid_body.fits.x_degree}; {period_text}")
pipeline_fits = auto is not None
if not pipeline_fits:   # the pipeline's thesis chain of fits did not run; fit here what it would have fitted
    print(f"the pipeline fitted no curves to this session (the thesis' chain of fits: {rb.chain_error}); its "
          "kinematics come from the pose spline (notebook 11). The fits below are this notebook's own "
          f"(fitting.fit_motion with the pipeline's order rule) on the pipeline's registered {M} markers")
    auto = fitting.fit_motion(t, registered, x_degree=prm.rigid_body.fits.x_degree, rule=prm.rigid_body.fits.order_rule,
                              w0=w0, trend=prm.rigid_body.fits.trend)

truth = session_truth(ws.session_dir)                   # None for a recorded session (no truth/ folder)
a, b = an.triangulate.segment
true_kin = None
if truth is None:
    print(NO_TRUTH, "(a recorded session): the fits are shown without the truth beside them")
else:
    tt = accuracy.analysed_truth(an, truth)              # the truth at the analysed frames, pipeline's frame
    true_kin = {"pos": tt["marker_pos"], "vel": tt["marker_vel"], "acc": tt["marker_acc"]}
    stride_hz = truth.extras["motion"]["gait"]["stride_hz"]
    print(f"stride period of the virtual horse {1 / stride_hz:.3f} s (w = {2 * np.pi * stride_hz:.2f} rad/s); "
          + ("the pipeline found no period" if w0 is None else f"the pipeline's estimate w = {w0:.2f} rad/s"))

# %% [markdown]
# ## x-motion: a straight line
#
# The horse was warmed up to a steady speed, so $P_x(t) = p_1 t + p_2$ and $V_x = p_1$, $A_x = 0$.

# %%
fx = auto.fits[0][0]
print(fx.summary())
print(f"V_x,avg = {fx.coefficients[0]:.3f} m/s = {3.6 * fx.coefficients[0]:.2f} km/h")
if truth is None:
    print("truth:", NO_TRUTH)
else:
    print(f"truth mean {3.6 * np.nanmean(true_kin['vel'][:, 0, 0]):.2f} km/h")
    x_true = true_kin["pos"][:, 0, 0]
    known = np.isfinite(x_true)                          # frames the truth covers
    surge = x_true - np.polyval(np.polyfit(t[known], x_true[known], 1), t)
    print(f"true surge of marker 1 about a straight line: {100 * np.nanmin(surge):+.1f} to {100 * np.nanmax(surge):+.1f} cm; "
          f"rms of its true A_x {np.sqrt(np.nanmean(true_kin['acc'][:, 0, 0] ** 2)):.2f} m/s²")

# %% [markdown]
# The virtual horse, like a real one, surges a little within each stride (printed above): a straight
# line cannot follow that, so $A_x$ of every marker is zero and misses the surge (its true rms, above).
# The thesis accepted this; the comfort indicators use the vertical direction only.
#
# ## Goodness of every fit (MATLAB's `gof`)
#
# The pipeline's fits of every marker and axis, with the numbers MATLAB's `fit` returns:

# %%
print("marker axis  fit              E       sse    rsquare  adjrsquare      rmse")
for m in range(M):
    for ax in range(3):
        f, g = auto.fits[m][ax], auto.fits[m][ax].gof
        e = auto.n_extremes[m, ax]
        print(f"  {m + 1}     {'xyz'[ax]}    {f.label:15s} {e if e >= 0 else '-':>2}  {g.sse:9.3e}  {g.rsquare:8.5f}  "
              f"{g.adjrsquare:9.5f}  {g.rmse:9.3e}")

# %% [markdown]
# ## y-motion of marker 1: counting extremes and two proposed fits (Figure 5.8)
#
# $E$ is counted on the data (detrended, since the fit has a trend term); the two proposed orders are
# $E/2$ and $E/2+1$.

# %%
y = registered[:, 0, 1]
E = int(auto.n_extremes[0, 1])
N1, N2 = fitting.proposed_orders(E)
f1, f2 = (fitting.fit_fourier(t, y, n, w0=w0, trend=prm.rigid_body.fits.trend) for n in (N1, N2))
print(f"E = {E} extremes -> proposed fourier{N1} and fourier{N2}; the {'pipeline' if pipeline_fits else 'order rule'} "
      f"chose fourier{auto.orders[0, 1]}")
for f in (f1, f2):
    print(f.summary())
truth_y = None if truth is None else {"t": t, **{k: true_kin[k][:, 0, 1] for k in ("pos", "vel", "acc")}}
fig = plots.plot_fit_choice(f1, f2, truth=truth_y, suptitle="marker 1, y-motion (down)")
plt.show()

# %% [markdown]
# Look at the fundamental $w$ of each fit. MATLAB's start point takes the strongest FFT bin $k$ and tries
# $w_{peak}/j$, $j = 1..N$: on a record of about two strides the *half* frequency can win, and a `fourier2`
# then holds only the first stride harmonic — the truth needs three (its vertical motion has 65, 10 and
# 1.5 mm at 1, 2 and 3 times the stride frequency). The pipeline starts every $w$ at its estimated stride
# period instead:

# %%
if truth is None:
    print(NO_TRUTH)
else:
    for N in (1, 2, 3, 4):
        fm = fitting.fit_fourier(t, y, N, trend=prm.rigid_body.fits.trend)
        fp = fitting.fit_fourier(t, y, N, w0=w0, trend=prm.rigid_body.fits.trend)
        err = lambda f: np.sqrt(np.nanmean((f.evaluate(t, 2) - truth_y["acc"]) ** 2))
        print(f"fourier{N}: MATLAB start w = {fm.frequency:6.3f} rad/s, acc RMSE {err(fm):5.2f} m/s² | "
              f"start at the period, w = {fp.frequency:6.3f}, acc RMSE {err(fp):5.2f} m/s²")

# %% [markdown]
# ## z-motion of marker 1 (Figure 5.9)
#
# Lateral motion is smaller and lies along the cameras' depth, where the triangulation error is largest
# (notebook 05): note the lower R².

# %%
z = registered[:, 0, 2]
Ez = int(auto.n_extremes[0, 2])
g1, g2 = (fitting.fit_fourier(t, z, n, w0=w0, trend=prm.rigid_body.fits.trend) for n in fitting.proposed_orders(Ez))
print(f"E = {Ez} -> fourier{g1.order} (adj R2 {g1.gof.adjrsquare:.4f}) or fourier{g2.order} "
      f"(adj R2 {g2.gof.adjrsquare:.4f}); the {'pipeline' if pipeline_fits else 'order rule'} chose fourier{auto.orders[0, 2]}")
truth_z = None if truth is None else {"t": t, **{k: true_kin[k][:, 0, 2] for k in ("pos", "vel", "acc")}}
fig = plots.plot_fit_choice(g1, g2, truth=truth_z, suptitle="marker 1, z-motion")
plt.show()

# %% [markdown]
# ## Your choices (the thesis' prompts)
#
# One row per marker and axis: the number of extremes $E$ and the choice between the two proposed orders;
# then the x polynomial degree. The defaults are the pipeline's: its counted $E$ and its chosen order.

# %% tags=["nbval-ignore-output"]
ui_orders = {(m, ax): widgets.ui_fourier_order(t, registered[:, m, ax], f"marker {m + 1}, {'xyz'[ax]}",
                                                 rule=prm.rigid_body.fits.order_rule, w0=w0, trend=prm.rigid_body.fits.trend,
                                                 value=auto.orders[m, ax], n_extremes=auto.n_extremes[m, ax])
             for m in range(M) for ax in (1, 2)}
ui_x = widgets.ui_x_degree(prm.rigid_body.fits.x_degree)
if pipeline_fits:   # choices for the pipeline's chain of fits; without it the widgets drive this notebook's fits only
    ws.bind(list(ui_orders.values()), "fourier_orders",
            read=lambda: [[ui_orders[(m, 1)].value, ui_orders[(m, 2)].value] for m in range(M)])
    ws.bind(ui_x, "x_degree")
else:
    print("these choices change this notebook's fits only: the pipeline's chain of fits does not run on this session")
for w in ui_orders.values():
    display(w)
display(ui_x)

# %%
orders = np.array([[ui_orders[(m, 1)].value, ui_orders[(m, 2)].value] for m in range(M)])
mfit = fitting.fit_motion(t, registered, x_degree=ui_x.value, orders=orders, w0=w0, trend=prm.rigid_body.fits.trend)
print("orders (x degree, y, z) per marker:", mfit.orders.tolist(),
      "; the pipeline's:" if pipeline_fits else "; the order rule's:", auto.orders.tolist())
vel, acc = mfit.velocity(t), mfit.acceleration(t)
if pipeline_fits:
    print(f"velocities equal the pipeline's (to 1e-9 m/s): {np.allclose(vel, rb.vel, rtol=0, atol=1e-9)}")
else:
    print("the pipeline's velocities come from its pose spline (notebook 11), not from fits: nothing to compare here")
if truth is None:
    print("velocity and acceleration errors:", NO_TRUTH)
for m in range(M if truth is not None else 0):
    ev = frames.rmse_per_axis(vel[:, m], true_kin["vel"][:, m])
    ea = frames.rmse_per_axis(acc[:, m], true_kin["acc"][:, m])
    print(f"marker {m + 1}: velocity RMSE x/y/z " + " ".join(f"{e:.3f}" for e in ev)
          + " m/s; acceleration RMSE " + " ".join(f"{e:.2f}" for e in ea) + " m/s²")

# %% [markdown]
# Figure 8.13: the kinematics of marker 1 with the chosen fits (positions are the registered data; the
# thesis keeps them and takes only $V$ and $A$ from the fits). The x acceleration misses the surge (see
# above); the vertical one follows the truth closely (its RMSE is printed above).

# %%
fig = plots.plot_marker_fits(t, registered, mfit, marker=0, truth=true_kin)
plt.show()

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
# 1. For marker 2, y: raise $E$ by two in its widget. Which orders are proposed, and does the acceleration
#    error of that marker go down or up?
# 2. Fit `fitting.fit_fourier(t, s, 3)` to $s = \sin(2\pi t / 0.6)$ sampled at the analysed frame times:
#    which $w$ does MATLAB's start point pick, and which does the fit end at?
# 3. The 95 % bounds of the pipeline's fit of marker 1 y (`auto.fits[0][1].confint`): are the highest
#    harmonic's coefficients significant? And those of marker 1 z?
#
# <details><summary>Solutions</summary>
#
# 1. Two more extremes propose one more harmonic; the extra harmonics follow the noise more than the
#    motion, and the acceleration error usually grows (acceleration weighs harmonic $n$ by $(n w)^2$).
# 2. The FFT peak is bin 2 (about two periods in the record), $w_{peak} = 2\pi\cdot 2/(t_{end} - t_0)$;
#    with $N = 3$ the tries $w_{peak}/2$, $w_{peak}/3$ add lower harmonics and can fit better, so the
#    search may end at a sub-multiple of 10.47 rad/s; `fit_fourier(..., w0=10.47)` starts at the stride
#    frequency.
# 3. `f = auto.fits[0][1]; f.confint[:, f.harmonic_slice]`: the order rule `"significant"` kept the
#    highest harmonic only because at least one of its bounds excludes zero. The lateral (z) fits are
#    noisier (depth axis), so their highest harmonics are closer to insignificant.
#
# </details>
