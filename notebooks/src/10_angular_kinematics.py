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
from horsemocap.widgets.markers_guard import thesis_three_note, thesis_view

# %% [markdown]
# ## The data: the pipeline's own
#
# `results_for` runs (or loads) the pipeline up to the rigid-body step with the automatic choices. Its
# `RigidBodyAnalysis` holds the registered markers (notebook 08, from positions smoothed with the pipeline's
# default `loess`), their fitted velocities and accelerations (notebook 09) and every angular estimate: the
# six thesis versions (raw and smoothed with `rloess`, span 0.1, as Appendix A step 11: this smoothing of
# the versions follows the thesis whatever `smoothing_method` the positions had), least squares, and the
# fit of the registered orientation. The pipeline passes on the one its `angular_method` names. The truth
# (virtual laboratory, in the pipeline's motion frame) only measures errors.
#
# The thesis' formulas take exactly three markers and its fits a periodic record. On a session with four or
# more markers, or without a period, the pipeline does not run that chain (`motion_fit` is None): the cell
# below says why, and the versions are then computed on markers 1, 2, 3 of the pipeline's smoothed pose
# (`horsemocap.widgets.markers_guard.thesis_view`), with least squares over all markers and the pipeline's
# pose trajectory in place of the orientation fit.

# %%
from horsemocap import accuracy, data, frames, pipeline
from horsemocap.workspace import NO_TRUTH, results_for, session_truth

an = results_for(until="rigid_body")
rb = an.rigid_body.body
prm = an.params
view = thesis_view(rb)                                  # the pipeline's own arrays when its chain ran
t, pos, vel, acc = rb.t, view.pos, view.vel, view.acc
if view.chain:
    print(f"{len(t)} frames; orders (x, y, z) per marker {rb.motion_fit.orders.tolist()}; "
          f"angular method '{prm.rigid_body.fits.angular_method}'; versions used: omega {sum(prm.rigid_body.fits.omega_versions)}, alfa {sum(prm.rigid_body.fits.alpha_versions)}")
else:
    print(f"{len(t)} frames; {view.note}")
    print(thesis_three_note(an.session.marker_count) or "the thesis' three markers: markers 1, 2, 3",
          "- the versions below use them, from the pipeline's smoothed pose")

truth = session_truth(ws.session_dir)                   # None for a recorded session (no truth/ folder)
a, b = an.triangulate.segment
omega_true = alpha_true = None
if truth is None:
    print(NO_TRUTH, "(a recorded session): below, the rms of each estimate stands where its error would")
else:
    tt = accuracy.analysed_truth(an, truth)              # the truth at the analysed frames, pipeline's frame
    omega_true, alpha_true = tt["omega"], tt["alpha"]

# %% [markdown]
# ## First, on exact data
#
# With the true positions and velocities every version is exact and the compatibility condition holds
# to rounding — except where $\boldsymbol\omega$ lies in the markers' plane:

# %%
if truth is None:
    print(NO_TRUTH)
else:
    P, V = tt["marker_pos"], tt["marker_vel"]
    with np.errstate(all="ignore"):
        exact = rigid.angular_velocity_versions(P, V)
    ang_true = rigid.singularity_angle(P, omega_true)
    far = np.abs(ang_true - 90) > 10
    print(f"compatibility residual (eq. 6.20) below 1e-12 m^2/s: {np.nanmax(np.abs(rigid.compatibility_residual(P, V))) < 1e-12}")
    print(f"versions vs truth where |angle - 90| > 10 deg ({far.sum()} frames): exact to 1e-6 rad/s: "
          f"{np.nanmax(np.abs(exact[:, far] - omega_true[far])) < 1e-6}")
    print(f"least squares vs truth, all frames: exact to 1e-6 rad/s: "
          f"{np.nanmax(np.abs(rigid.angular_velocity_lstsq(P, V) - omega_true)) < 1e-6}")
    print(f"angle(omega, n) of the true motion: {np.nanmin(ang_true):.0f} to {np.nanmax(ang_true):.0f} deg; "
          f"within 15 deg of 90 in {np.mean(np.abs(ang_true - 90) < 15) * 100:.0f} % of the frames")

# %% [markdown]
# ## The six versions on measured data (Figures 8.14-8.16)
#
# Grey: the versions from eq. 6.3/6.4 frame by frame; blue: smoothed (`rloess`, span 0.1); dashed: truth.

# %%
w_raw, w_s = view.omega_raw, view.omega_versions
print(f"compatibility residual on {'fitted' if view.chain else 'smoothed-pose'} data: median |.| {np.median(np.abs(rigid.compatibility_residual(pos, vel))):.2e} m^2/s")
for c in range(3):
    fig = plots.plot_angular_versions(t, w_raw, w_s, c, truth=omega_true)
    plt.show()

# %% [markdown]
# ## Choosing the versions and the method (the thesis' y/n prompts)
#
# The defaults are the pipeline's: all six versions checked for $\boldsymbol\omega$ and for
# $\boldsymbol\alpha$, and its `angular_method`. The thesis' user unchecked `omega1_ver2` and `omega1_ver3` in
# the canter example. The method selects what the saddle step uses: the average of the checked versions
# (the thesis), the least-squares solution, or the fit of the registered orientation. The next cell runs the
# pipeline's rigid-body step again with your choices. Where the pipeline does not run the thesis' chain
# (the cell at the top said so), the versions and the method do not change what it passes on; the table then
# shows the versions on markers 1, 2, 3 beside the pipeline's pose trajectory.

# %% tags=["nbval-ignore-output"]
ui_w = widgets.ui_versions("omega", value=prm.rigid_body.fits.omega_versions)
ui_a = widgets.ui_versions("alfa", value=prm.rigid_body.fits.alpha_versions)
ui_method = widgets.ui_angular_method(value=prm.rigid_body.fits.angular_method)
ws.bind(ui_w, "omega_versions")
ws.bind(ui_a, "alpha_versions")
ws.bind(ui_method, "angular_method")
display(ui_w, ui_a, ui_method)

# %%
use_w, use_a, method = ui_w.value, ui_a.value, ui_method.value
chosen = accuracy.with_params(an, omega_versions=[bool(v) for v in use_w],
                              alpha_versions=[bool(v) for v in use_a], angular_method=method)
with warnings.catch_warnings():
    warnings.simplefilter("ignore", RuntimeWarning)
    rb2 = pipeline.run_steps(an.session, chosen, an, ["rigid_body"]).rigid_body.body
view2 = thesis_view(rb2)
omega_avg = rigid.average_versions(view2.omega_versions, use_w)
# the error against the truth; on a session without truth, the estimate's own rms
rmse = lambda e, tr: float(np.sqrt(np.nanmean((e - (0 if tr is None else tr)) ** 2)))
per_axis = lambda e, tr: "  ".join(f"{v:6.3f}" for v in frames.rmse_per_axis(e, np.zeros_like(e) if tr is None else tr))
if truth is None:
    print(f"true omega: {NO_TRUTH}; method used: {rb2.method}")
    print("omega rms (rad/s, all components; smoothed versions; no truth to subtract):")
else:
    print(f"rms of the true omega: {np.sqrt(np.nanmean(omega_true ** 2)):.3f} rad/s, x/y/z "
          + "  ".join(f"{v:6.3f}" for v in np.sqrt(np.nanmean(omega_true ** 2, axis=0))) + f"; method used: {rb2.method}")
    print("omega RMSE (rad/s, all components; smoothed versions):")
for i, lab in enumerate(rigid.VERSION_LABELS):
    print(f"  {lab}: {rmse(view2.omega_versions[i], omega_true):8.3f}" + ("" if use_w[i] else "  (not used)"))
print(f"  average of chosen versions:        {rmse(omega_avg, omega_true):8.3f}   x/y/z {per_axis(omega_avg, omega_true)}")
print(f"  least squares (all markers):       {rmse(view2.omega_lstsq, omega_true):8.3f}   x/y/z {per_axis(view2.omega_lstsq, omega_true)}")
print(f"  {view2.fit_label + ':':35s}{rmse(view2.omega_fit, omega_true):8.3f}   x/y/z {per_axis(view2.omega_fit, omega_true)}")

# %% [markdown]
# Figures 8.17-8.18: all smoothed versions, the average of the chosen ones, least squares and truth.

# %%
fig = plots.plot_angular_average(t, view2.omega_versions, use_w, omega_avg, truth=omega_true, lstsq=view2.omega_lstsq)
plt.show()

# %% [markdown]
# ## Where the thesis formulas break: the singularity, frame by frame
#
# The three skin markers lie almost in a vertical plane along the back ($\mathbf n$ nearly lateral),
# and at canter the body pitches about the lateral axis but also rolls and yaws: whenever
# $\boldsymbol\omega$ swings through the markers' plane, the denominators of eq. 6.3/6.4 vanish. The
# thesis observed exactly this (section 8.4.1: "very close to the singularity ... quite unreliable").
# The angle is measured with the $\boldsymbol\omega$ the pipeline passes on (`singularity_deg`).

# %%
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    rep = rigid.singularity_report(rb2.singularity_deg, tolerance_deg=15)
print(f"angle(omega, n): median {rep['median_angle_deg']:.0f} deg; within 15 deg of 90 in "
      f"{100 * rep['fraction']:.0f} % of the frames; closest {rep['min_margin_deg']:.1f} deg from 90")
print("warning:", str(caught[0].message) if caught else "none")
fig = plots.plot_singularity(t, rb2.singularity_deg)
plt.show()

# %% [markdown]
# ## Angular acceleration (Figures 8.19-8.20)
#
# The versions of eq. 6.38/6.39 use the chosen $\boldsymbol\omega$ (without the thesis' chain: the
# $\boldsymbol\omega$ the pipeline passes on).

# %%
alpha_avg = rigid.average_versions(view2.alpha_versions, use_a)
if truth is None:
    print(f"true alpha: {NO_TRUTH}; alpha rms (rad/s², all components; no truth to subtract):")
else:
    print(f"rms of the true alpha: {np.sqrt(np.nanmean(alpha_true ** 2)):.2f} rad/s²")
    print("alpha RMSE (rad/s², all components):")
for i, lab in enumerate(rigid.VERSION_LABELS):
    print(f"  {lab.replace('omega', 'alfa')}: {rmse(view2.alpha_versions[i], alpha_true):9.2f}" + ("" if use_a[i] else "  (not used)"))
print(f"  average of chosen versions:        {rmse(alpha_avg, alpha_true):9.2f}")
print(f"  least squares:                     {rmse(view2.alpha_lstsq, alpha_true):9.2f}")
print(f"  {view2.fit_label + ':':35s}{rmse(view2.alpha_fit, alpha_true):9.2f}")
fig = plots.plot_angular_average(t, view2.alpha_versions, use_a, alpha_avg, name="alfa", unit="rad/s²",
                                 truth=alpha_true, lstsq=view2.alpha_lstsq)
plt.show()

# %% [markdown]
# **Reading the numbers** (the omega RMSE table above). Near the singularity a thesis version divides the
# noise by a vanishing denominator; averaging several such versions does not help: one bad version spoils
# the average, and on this session every version and their average is off by more than the rms of
# $\boldsymbol\omega$ itself. Least squares over all markers has no $\boldsymbol\omega\cdot\mathbf n$
# singularity (only collinear markers make it singular), but the rotation about the markers' row (roll, x) is
# poorly conditioned: the markers are only about 7 cm apart across it, and that axis lies along the cameras'
# depth; on this session it is still off by more than the rms. The fit of the registered orientation uses all
# markers *and* the smoothness of a periodic motion, and is the only estimate better than the rms: its pitch
# (z) and yaw (y) rate errors are well below those rates' true rms, but compare its roll-rate (x) error with the rms of the true
# roll rate (both printed above): the error is the larger, roll is not measured by this marker layout. None
# of this is needed for the saddle's vertical acceleration if the saddle's own path is fitted (notebook 11).
#

# %% [markdown]
# ## The saddle's roll, pitch and yaw
#
# $\boldsymbol\omega$ and $\boldsymbol\alpha$ are rates; a rider feels the saddle's attitude too. The
# saddle's body axes are those of the static shot (x along the back's markers, y down, z across),
# carried by the registered pose of every frame; written as rotations about the motion frame's axes,
# $\mathbf{R} = \mathbf{R}_y(\text{yaw})\,\mathbf{R}_z(\text{pitch})\,\mathbf{R}_x(\text{roll})$: roll about the
# longitudinal axis (x), pitch about the lateral one (z), yaw about the vertical (y). The pipeline
# writes them with every result (`saddle_angles_deg` of the rigid-body step; the `roll_deg`,
# `pitch_deg` and `yaw_deg` columns of `angular.csv`). Roll is the worst observed under a thin marker triangle (the
# markers lie almost along the roll axis).

# %%
ang = an.rigid_body.saddle_angles_deg                   # (n, 3): roll, pitch, yaw in degrees
fig, axes = plt.subplots(1, 3, figsize=(12, 3), sharex=True)
for ax, i, name in zip(axes, range(3), ("roll (about x)", "pitch (about z)", "yaw (about y)")):
    ax.plot(t, ang[:, i], "k-")
    ax.set_title(name, fontsize=9)
    ax.set_xlabel("time (s)")
axes[0].set_ylabel("angle (deg)")
fig.tight_layout()
plt.show()
for i, name in enumerate(("roll", "pitch", "yaw")):
    a_i = ang[:, i]
    print(f"{name:5s}: mean {np.nanmean(a_i):+6.1f} deg, peak to peak {np.nanmax(a_i) - np.nanmin(a_i):5.1f} deg")

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
# 1. Uncheck `omega1_ver2` and `omega1_ver3` as the thesis' user did. Does the average improve? Which
#    versions would you uncheck from the plots alone, without the truth?
# 2. Using `P, V` (exact data), move marker 2 15 cm higher (`P2 = P.copy(); P2[:, 1, 1] -= 0.15`, velocities
#    from the same rigid motion: `V2 = np.cross(omega_true[:, None], P2 - P2[:, :1]) + V[:, :1]`). How does
#    the angle between $\boldsymbol\omega$ and $\mathbf n$ change?
# 3. Check numerically that with $\mathbf a_1 \neq 0$ the printed eq. 6.38 (without $-\mathbf a_1$)
#    does not return $\boldsymbol\alpha$.
#
# <details><summary>Solutions</summary>
#
# 1. Compare `rmse(rigid.average_versions(rb2.omega_versions, mask), omega_true)` for the mask of all six,
#    the thesis' mask (`np.array([1, 1, 0, 1, 0, 1], bool)`) and a mask without the versions that blow up. On this session
#    the thesis' mask makes the average worse, because the versions that blow up here are others:
#    `omega1_ver1` (its denominator passes through zero in some frames; see its RMSE in the table) and
#    `omega2_ver3`. They are the ones with spikes far beyond the bulk in Figures 8.14-8.16; unchecking those
#    two helps a lot, but the average stays several times the rms of $\boldsymbol\omega$ and far from the
#    orientation fit.
# 2. Raising marker 2 tilts the markers' plane towards the horizontal, so $\mathbf n$ turns towards the
#    vertical and away from the pitch axis: the angle moves away from 90° in most frames and the versions
#    become usable — the thesis' advice to "change the locations of the 3 markers".
# 3. `A = tt["marker_acc"]`, `w = omega_true`, `r21 = P[:, 0] - P[:, 1]`, `r31 = P[:, 0] - P[:, 2]`;
#    `K2 = A[:, 1] + np.cross(w, np.cross(w, r21))` and similarly `K4`;
#    `np.cross(K2, K4) / -(K2 * r31).sum(1)[:, None]` differs from `alpha_true` by many rad/s², while
#    subtracting `A[:, 0]` from both makes it exact (away from the singular frames).
#
# </details>
