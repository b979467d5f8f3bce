# %% [markdown]
# # 12 · Whole-body vibration: what the saddle does to the rider
#
# **What you will learn**
# - the frequency weightings $W_b$ (BS 6841), $W_k$ and $W_d$ (ISO 2631-1) from their analogue
#   definitions, and that they match the standards' tables (thesis Table 7.1, Figure 7.1);
# - why $W_b$ is written with $K = 0.4$ in BS 6841 and $K = 1.024$ in ISO 2631-4, and that it is
#   one filter;
# - when a digital weighting filter is good enough at a given sampling rate;
# - the indicators of section 7.2: weighted rms (eq. 7.3-7.4), peak (7.5-7.6), crest factor (7.7),
#   vibration dose value VDV (7.8-7.9);
# - the exposure times to the EU action and limit values (eq. 7.10-7.17, Table 7.2) — with the typo
#   of eq. 7.14-7.17 corrected — and the allowable daily distances (eq. 7.18-7.25);
# - how thesis Table 8.7 was computed, and how far its "one weight for the whole signal" differs
#   from the per-frequency weighting the standards mean;
# - the comfort table of a session, as `comfort.csv` and as a spreadsheet.
#
# The equations, with $A_y(t)$ the saddle's vertical acceleration and $\tau$ the analysed time
# (two gait periods):
#
# $$A_{wb}(t) = W_b \cdot A_y(t),\quad A_{wk}(t) = W_k \cdot A_y(t) \qquad (7.1\text{-}7.2)$$
#
# $$a_{w,\mathrm{rms}} = \sqrt{\tfrac{1}{\tau}\int_0^\tau A_w^2\,dt},\qquad
#   VDV_w = \Big(\int_0^\tau A_w^4\,dt\Big)^{1/4},\qquad CF = \frac{a_{w,\mathrm{peak}}}{a_{w,\mathrm{rms}}}$$
#
# $$T_{A(8)} = 8\Big(\frac{A(8)_\mathrm{threshold}}{a_{w,\mathrm{rms}}}\Big)^2\ \mathrm{h},\qquad
#   T_{VDV} = \tau\Big(\frac{VDV_\mathrm{threshold}}{VDV_w}\Big)^{4},\qquad D = V_{x,avg}\,T$$

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
import tempfile
import warnings
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from IPython.display import display

from horsemocap import herd, plots, vibration, weighting_filters, widgets

# %% [markdown]
# ## 1 · Frequency weightings
#
# People feel vertical vibration most between about 4 and 12 Hz; a weighting $W(f)$ scales each
# frequency by how much it matters. Every weighting of ISO 2631-1 Annex A (and ISO 8041) is a
# product of four analogue filters, $s = 2\pi i f$:
#
# - band limiting: a 2nd-order Butterworth high-pass at $f_1 = 0.4$ Hz and low-pass at $f_2 = 100$ Hz
#   (a Butterworth filter is the one whose gain is flattest in its pass band; at 2nd order the high-pass
#   gain is $1/\sqrt{1 + (f_1/f)^4}$, $1/\sqrt 2$ at $f_1$ itself);
# - acceleration–velocity transition $\dfrac{1 + s/\omega_3}{1 + s/(Q_4\omega_4) + s^2/\omega_4^2}$;
# - upward step $\dfrac{s^2 + s\,\omega_5/Q_5 + \omega_5^2}{s^2 + s\,\omega_6/Q_6 + \omega_6^2}$;
# - a gain $K$.
#
# The parameters:

# %%
for name, p in vibration.WEIGHTINGS.items():
    print(f"{name}: f3={p.f3:g} f4={p.f4:g} Q4={p.Q4:g} f5={p.f5:g} Q5={p.Q5:g} "
          f"f6={p.f6:g} Q6={p.Q6:g} K={p.K:g}  ({p.source})")

# %% [markdown]
# Thesis Table 7.1, the weightings of the standards and what each is for (this notebook uses $W_b$ and
# $W_k$ for the vertical axis, as the thesis did, and $W_d$ for the two horizontal axes of the EU
# Directive, section 4):
#
# | weighting | direction | application area | standard |
# |---|---|---|---|
# | $W_b$ | vertical | whole body | BS 6841 |
# | $W_c$ | fore-aft | whole body | ISO 2631-1, BS 6841 |
# | $W_d$ | lateral, fore-aft | whole body | ISO 2631-1, BS 6841 |
# | $W_e$ | roll, pitch, yaw | whole body (rotational) | ISO 2631-1, BS 6841 |
# | $W_f$ | vertical | motion sickness | ISO 2631-1, BS 6841 |
# | $W_g$ | vertical | activity interference | BS 6841 |
# | $W_h$ | lateral, fore-aft, vertical | hand-arm | ISO 5349-1 |
# | $W_j$ | vertical | head | ISO 2631-1 |
# | $W_k$ | vertical | whole body | ISO 2631-1 |
# | $W_m$ | all | building | ISO 2631-2 |
#
# The thesis could not find closed forms and derived its own from Rimell and Mansfield (2007); it
# does not print them. We start again from the definitions and check them against the factors
# ISO 2631-1:1997 tabulates (Table 3) at the one-third-octave frequencies.

# %%
f_tab = np.array([0.5, 0.63, 0.8, 1, 1.25, 1.6, 2, 2.5, 3.15, 4, 5, 6.3, 8, 10, 12.5, 16, 20])
wk_tab = np.array([0.418, 0.459, 0.477, 0.482, 0.484, 0.494, 0.531, 0.631, 0.804, 0.967, 1.039,
                   1.054, 1.036, 0.988, 0.902, 0.768, 0.636])      # ISO 2631-1:1997 Table 3
wd_tab = np.array([0.853, 0.944, 0.992, 1.011, 1.008, 0.968, 0.890, 0.776, 0.642, 0.512, 0.409,
                   0.323, 0.253, 0.212, 0.161, 0.125, 0.100])      # ISO 2631-1:1997 Table 3
for name, tab in (("Wk", wk_tab), ("Wd", wd_tab)):
    dev = np.abs(vibration.weighting(name, f_tab)) / tab - 1
    worst = int(np.argmax(np.abs(dev)))
    ok = f_tab != 10 if name == "Wd" else np.ones(f_tab.size, bool)
    print(f"{name}: largest deviation from the table 0.5-20 Hz {100 * np.abs(dev[ok]).max():.2f}%"
          f" (at {f_tab[ok][np.argmax(np.abs(dev[ok]))]:g} Hz); all entries: {100 * dev[worst]:+.2f}%"
          f" at {f_tab[worst]:g} Hz")

# %% [markdown]
# Every entry agrees within 0.35 % except $W_d$ at 10 Hz: the table prints 0.212, the definition
# gives 0.202. Above 2 Hz $W_d \approx 2/f$, and $f\,W_d$ is 2.02 at 8 Hz, 2.01 at 12.5 Hz, but 2.12
# at 10 Hz: the printed entry is the odd one out, a misprint.
#
# **$W_b$, two ways.** BS 6841 writes the upward step as
# $\frac{1 + s/(Q_5\omega_5) + s^2/\omega_5^2}{1 + s/(Q_6\omega_6) + s^2/\omega_6^2}$ (1 at low
# frequency) with $K = 0.4$; ISO 2631-4 writes it as above, $(f_5/f_6)^2$ at low frequency, with
# $K = 1.024 = 0.4\,(4/2.5)^2$. Same filter:

# %%
f = np.geomspace(0.1, 400, 500)
diff = np.max(np.abs(vibration.weighting("Wb", f) - vibration.weighting_bs6841_wb(f)))
print(f"max |W_b(ISO, K=1.024) - W_b(BS 6841, K=0.4)| = {diff:.1e}")
print(f"W_b plateau below 2 Hz (no band limiting): {abs(vibration.weighting('Wb', 0.01, band_limiting=False)):.4f}")

# %% [markdown]
# Thesis Figure 7.1: (a) the factors over the whole band, (b) the 0.8-1.8 Hz band the thesis says
# matters for the saddle (the fundamental of walk to canter; the harmonics go higher).

# %%
fig = plots.plot_weightings(("Wb", "Wk", "Wd"), table={"Wk": (f_tab, wk_tab), "Wd": (f_tab, wd_tab)})
plt.show()

# %% [markdown]
# The weights are complex: each one also shifts the phase of its harmonic, which changes the shape
# of the weighted signal and so its peak and VDV.

# %%
for f0 in (1.0, 1.67, 3.5, 5.0):
    wb, wk = vibration.weighting("Wb", f0), vibration.weighting("Wk", f0)
    print(f"{f0:4.2f} Hz: |Wb| {abs(wb):.4f} ({np.degrees(np.angle(wb)):+6.1f} deg)   "
          f"|Wk| {abs(wk):.4f} ({np.degrees(np.angle(wk)):+6.1f} deg)   |Wk|/|Wb| {abs(wk) / abs(wb):.5f}")

# %% [markdown]
# ## 2 · Digital weighting filters
#
# For an accelerometer's samples the weighting becomes a digital filter: each analogue section is
# mapped by the bilinear transform, pre-warped at its own frequency. The transform squeezes the
# frequency axis near the Nyquist frequency, so the filter is only right well below $f_s/2$.
# `weighting_filters.weighting_filter` warns when $|H|$ departs from $|W|$ by more than 5% between
# 0.5 and 20 Hz.

# %%
bands = np.array([1, 2, 4, 8, 12.5, 16, 20])
print("fs (Hz)  weighting  error of |H| at " + " ".join(f"{b:g}" for b in bands) + " Hz (%)")
for fs in (30, 100, 200, 1000):
    for name in ("Wb", "Wk", "Wd"):
        fb = bands[bands < 0.45 * fs]
        err = weighting_filters.digital_weighting_error(name, fs, fb)
        print(f"{fs:7d}  {name:9s}  " + " ".join(f"{100 * e:+5.1f}" for e in err))

# %%
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    weighting_filters.weighting_filter("Wk", 100.0)
print(caught[0].message if caught else "no warning")

# %% [markdown]
# Video at 30 fps cannot carry a good digital weighting (and 100 Hz is marginal for $W_k$ at the top
# of the band). That is why the analysis below does not filter samples: it weights each harmonic of
# the fitted Fourier series by $W$ at its own frequency — exact at any frame rate.
#
# ## 3 · Thesis Table 8.7, reproduced
#
# Table 8.7 lists the indicators of Horse 2 at canter. From its own rms, VDV and speed we recompute
# its times and distances. Two things in the printed equations must be corrected:
#
# - eq. 7.14-7.17 print $T_{VDV} = \tau\,(VDV_\mathrm{threshold}/VDV)$, without the fourth power
#   (VDV grows as the fourth root of time, so the time to reach a threshold scales with the fourth
#   power of the ratio);
# - eq. 7.16-7.17 put the *action* value into the *limit* times.
#
# The thresholds are those of thesis Table 7.2, the EU Directive 2002/44/EC's exposure action value
# (EAV: above it, the employer must act) and exposure limit value (ELV: never to be exceeded), for the
# daily exposure $A(8)$ (an rms over 8 hours) and for the VDV:
#
# | | EAV | ELV |
# |---|---|---|
# | $A(8)$ | 0.5 m/s² | 1.15 m/s² |
# | $VDV_\mathrm{threshold}$ | 9.1 m/s$^{1.75}$ | 21 m/s$^{1.75}$ |
#
# (`vibration.EU_2002_44_EC` holds them.) The table itself was computed correctly, with $\tau = 1.2$ s
# (two periods of 18 frames at 30 fps):

# %%
T = vibration.THESIS_TABLE_8_7
ours = vibration.indicators_from_values(
    T["acc_y_Wb_rms"], T["acc_y_Wk_rms"], T["VDV_y_Wb"], T["VDV_y_Wk"], T["acc_y_max"],
    T["crest_factor_y"], 1.2, T["vel_x_avg"], T["amplitude_y"], f0_hz=30 / 18)
print(f"{'indicator':26s} {'Table 8.7':>10s} {'recomputed':>11s}")
for k in T:
    if k.startswith(("T", "Distance")):
        print(f"{k:26s} {T[k]:10.4f} {ours[k]:11.4f}")

# %% [markdown]
# All eight times agree to the printed 4 decimals. Five distances differ in the 4th decimal (by at
# most 5e-4): the table multiplied unrounded speeds and times, we multiply the printed, rounded ones.
# The rounding of $V_{x,avg}$ and $a_{rms}$ (±5e-5) moves e.g. $D = V\,8(1.15/a)^2$ by
# $18.33\,(5\cdot10^{-5}/17.64 + 2\cdot5\cdot10^{-5}/3.19) = 6\cdot10^{-4}$ km. More can be
# shown: one set of unrounded inputs, each within ±5e-5 of its printed value, reproduces every
# printed time and distance to 4 decimals — and no such set exists for the equations as printed.
# The printed form would give:

# %%
tau = 1.2
for w in ("Wb", "Wk"):
    printed = tau * (9.1 / T[f"VDV_y_{w}"]) / 3600
    correct = vibration.time_to_vdv(T[f"VDV_y_{w}"], tau, 9.1)
    print(f"TVDV_action_{w}: as printed (eq. 7.14-7.15) {printed:.6f} h, corrected {correct:.4f} h,"
          f" Table 8.7 {T[f'TVDV_action_{w}']:.4f} h")

# %% [markdown]
# **One weight, or one per frequency?** In Table 8.7, $W_k$/$W_b$ is the same for rms and VDV, and
# the crest factor is the same for both weightings (as eq. 7.7 states). That only happens when one
# real number multiplies the whole signal — eq. 7.1-7.2 read literally. Does the ratio tell which
# frequency the thesis weighted at? With the standards' $W_k$ and $W_b$, $|W_k|/|W_b| = 1.15988$ only
# at 3.50 Hz, which is not a harmonic of the 1.667 Hz canter of Table 8.7.

# %%
print(f"Table 8.7: Wk/Wb from rms {T['acc_y_Wk_rms'] / T['acc_y_Wb_rms']:.5f}, "
      f"from VDV {T['VDV_y_Wk'] / T['VDV_y_Wb']:.5f}")
ff = np.linspace(0.5, 10, 19001)
ratio = np.abs(vibration.weighting("Wk", ff)) / np.abs(vibration.weighting("Wb", ff))
f_match = ff[np.flatnonzero(np.diff(np.sign(ratio - 1.15988)))]
print("frequencies where |Wk|/|Wb| = 1.15988: " + ", ".join(f"{x:.2f} Hz" for x in f_match))
unweighted_rms = T["acc_y_max"] / T["crest_factor_y"]
print(f"acc_y_max / CF = {unweighted_rms:.3f} m/s², but rms_Wb / |Wb(3.5 Hz)| = "
      f"{T['acc_y_Wb_rms'] / abs(vibration.weighting('Wb', 3.5)):.3f} m/s²")
f_canter = 2 / tau                     # Table 8.7: tau = 1.2 s, two canter periods
for k in (1, 2, 3):
    print(f"canter harmonic {k} ({k * f_canter:.3f} Hz): |Wk|/|Wb| = {ratio[np.argmin(abs(ff - k * f_canter))]:.4f}")
wb_implied = T["acc_y_Wb_rms"] / unweighted_rms          # the |Wb| the table's own rms values imply
f_wb = ff[np.argmin(abs(np.abs(vibration.weighting("Wb", ff[ff < 3.5])) - wb_implied))]
print(f"|Wb| implied by rms_Wb / (acc_y_max / CF): {wb_implied:.4f}, reached at {f_wb:.3f} Hz, "
      f"where |Wk|/|Wb| = {ratio[np.argmin(abs(ff - f_wb))]:.4f}")

# %% [markdown]
# So Table 8.7 does **not** identify the weights the thesis used: its ratio falls at 3.50 Hz, between
# the canter's harmonics (1.262, 1.187 and 1.013 at 1.67, 3.33 and 5 Hz), and its `acc_y_max` and
# crest factor imply an unweighted rms of 7.20 m/s², hence $|W_b| = 0.443$, which the standard's
# $W_b$ has at 2.21 Hz, where the ratio is 1.279, not 1.160. No single frequency of the standard
# weightings fits the table. Either the thesis' closed-form weights differ from the standards', or
# `acc_y_max` was taken from another signal (e.g. the unsmoothed data); we cannot tell which. What
# `mode="thesis"` reproduces is the table's *structure* (one ratio for rms and VDV, one crest
# factor), not its numbers; we report the peak of the analysed signal.
#
# `comfort_indicators` offers both readings:
#
# - `mode="iso"` (default): every harmonic $c_k$ of the fitted acceleration is weighted by the complex
#   $W(f_k)$ at its own frequency — what the standards mean;
# - `mode="thesis"`: one scalar $|W(f_\mathrm{dom})|$ at the dominant harmonic — what Table 8.7 shows.
#
# ## 4 · This session's saddle: its ground truth, or its analysis
#
# For a session of the virtual laboratory the cells below use its **ground truth**: the analytic
# saddle acceleration of its horse and gait (notebook 01), sampled over one stride in the motion
# frame (y down); the videos' analysis (notebooks 02-11, `horsemocap analyze`) estimates the same
# quantity from the rendered frames. A recorded session has no truth: there they use the saddle
# acceleration the analysis found (notebook 11), as a harmonic series of its stride frequency.

# %%
from horsemocap.virtuallab.horse import saddle_motion
from horsemocap.workspace import NO_TRUTH, results_for, session_truth

an = results_for()                          # the chosen session's analysis, with the choices made so far
truth = session_truth(ws.session_dir)       # None for a recorded session (no truth/ folder)
if truth is None:
    print(NO_TRUTH, "(a recorded session): the saddle acceleration below is the analysis' estimate")
    rb = an.rigid_body
    f0 = an.comfort.indicators["f0_hz"]
    kin = (rb.t, rb.saddle_position, rb.saddle_acceleration, rb.saddle_velocity)
    ref_iso = vibration.saddle_comfort(*kin, mode="iso", f0_hz=f0)
    ref_thesis = vibration.saddle_comfort(*kin, mode="thesis", f0_hz=f0)
    period = 1 / f0
    n_h = max(1, int(min(15.0, 0.45 * an.session.fps) // f0))
    harm = vibration.fit_harmonics(rb.t, rb.saddle_acceleration[:, 1], f0, n_h)
    source = f"{an.session.name} (analysis)"
else:
    horse, gait = truth.extras["motion"]["horse"]["name"], truth.extras["motion"]["gait"]["name"]
    ref_iso = herd.analytic_indicators(horse, gait, mode="iso")
    ref_thesis = herd.analytic_indicators(horse, gait, mode="thesis")
    motion = saddle_motion(horse, gait)
    period = motion.period_s
    t1 = np.arange(512) * period / 512
    _, _, acc = motion.saddle(t1)
    acc_y = acc @ motion.motion_axes[1]
    harm = vibration.harmonics_from_periodic_samples(acc_y, period, max_harmonic=40)
    source = f"{horse}, {gait} (ground truth)"
harm = vibration.Harmonics(harm.freq_hz, harm.amplitude, 0.0)   # a mean acceleration is not vibration
fps = an.session.fps                        # the session's frame rate
print(f"{source}: stride {1 / period:.4f} Hz, period {period:.4f} s ({period * fps:.1f} frames at {fps:g} fps)")
for k in range(5):
    print(f"harmonic {k + 1}: {harm.freq_hz[k]:.3f} Hz, |c| = {abs(harm.amplitude[k]):.3f} m/s²")

# %% [markdown]
# Choose the weighting mode and $\tau$ (defaults: the standards' per-harmonic weighting, two
# periods as in the thesis):

# %% tags=["nbval-ignore-output"]
ui_mode = widgets.ui_weighting_mode()
ui_tau = widgets.ui_periods()
ws.bind(ui_mode, "weighting_mode")
display(ui_mode, ui_tau)

# %%
mode, n_periods = ui_mode.value, ui_tau.value
hist = vibration.weighted_histories(harm, n_periods * period, mode=mode)
ind = vibration.comfort_indicators(harm, n_periods * period, ref_iso["vel_x_avg"] / 3.6,
                                   ref_iso["amplitude_y"], mode=mode)
print(f"mode {mode}, tau = {ind['duration_s']:.3f} s")
for k, v, u in vibration.comfort_table_rows(ind):
    print(f"{k:26s} {v:10.4f} {u}")

# %% [markdown]
# `amplitude_y` is half the peak-to-peak of the saddle's vertical position over $\tau$. The thesis
# does not define it (its 0.30 m at canter is large for a saddle; it may be a peak-to-peak of
# another signal), so this is our definition, as in the results' `comfort.csv`.

# %%
plots.plot_weighted_acceleration(hist, f"{source}, mode {mode}")
plt.show()

# %% [markdown]
# ### iso vs thesis mode
#
# The canter's vertical acceleration is dominated by its fundamental (1.67 Hz, where
# $|W_b| = 0.39$), but the harmonics at 3.3 and 5 Hz are weighted up to 1. One scalar at the
# dominant harmonic therefore underestimates the weighted rms:

# %%
for k in ("acc_y_Wb_rms", "acc_y_Wk_rms", "VDV_y_Wb", "VDV_y_Wk", "crest_factor_y",
          "TA_8_limit_Wb", "Distance_TA_8_limit_Wb", "TVDV_limit_Wb"):
    a, b = ref_iso[k], ref_thesis[k]
    print(f"{k:24s} iso {a:9.4f}  thesis {b:9.4f}  thesis/iso - 1 = {100 * (b / a - 1):+6.1f}%")

# %%
plots.plot_mode_comparison(ref_iso, ref_thesis)
plt.show()

# %% [markdown]
# ### From fitted curves sampled at the frame rate
#
# The pipeline calls `vibration.saddle_comfort(t, position, acceleration, velocity)` with the saddle
# marker's kinematics sampled at the video frames (30 fps). It estimates the stride frequency, fits a
# harmonic series to $A_y$ and weights each harmonic. Fed with the exact kinematics at 30 fps over
# 3 s, it recovers the truth — so whatever error the video analysis shows comes from the earlier
# steps, not from this one:

# %%
if truth is None:
    print(NO_TRUTH)
else:
    t = np.arange(0, 3.0, 1 / 30)
    p, v, a = motion.saddle(t)
    axes = motion.motion_axes
    est = vibration.saddle_comfort(t, p @ axes.T, a @ axes.T, v @ axes.T)
    for k in ("f0_hz", "acc_y_Wb_rms", "acc_y_Wk_rms", "VDV_y_Wb", "acc_y_max", "vel_x_avg", "amplitude_y"):
        print(f"{k:14s} from 30 fps samples {est[k]:9.4f}   truth {ref_iso[k]:9.4f}   "
              f"|error| {100 * abs(est[k] / ref_iso[k] - 1):.3f}%")

# %% [markdown]
# ### All three axes: what the EU Directive counts
#
# The thesis (Table 8.7) judges the rider's exposure by the **vertical** acceleration alone, weighted
# with $W_b$ or $W_k$, and calls the times those of the EU Directive 2002/44/EC. The Directive itself
# (Annex B, after ISO 2631-1 for health) takes the *highest* of three axes: $1.4\,a_{wx}$ and
# $1.4\,a_{wz}$ (horizontal, weighted with $W_d$) and $a_{wy}$ (vertical, $W_k$), and the same for
# the VDV. A horse's surge along the path is large at canter, so the fore-aft axis can decide.
# `vibration.directive_indicators` computes it; the pipeline writes it as the `*_directive` rows of
# `comfort.csv`, after the thesis' rows.

# %%
print(f"{'axis':10s}{'weighting':>10s}{'rms m/s²':>10s}{'x factor':>10s}{'counts':>10s}")
k_h = vibration.DIRECTIVE_HORIZONTAL_FACTOR          # the Directive's factor on the horizontal axes
for axis, w, key, k in (("fore-aft", "Wd", "acc_x_Wd_rms", k_h), ("vertical", "Wk", "acc_y_Wk_rms_iso", 1.0),
                        ("lateral", "Wd", "acc_z_Wd_rms", k_h)):
    print(f"{axis:10s}{w:>10s}{ref_iso[key]:10.3f}{k:10.1f}{k * ref_iso[key]:10.3f}")
print(f"the Directive's A_w = {ref_iso['A_w_directive']:.3f} m/s²")
for name in ("TA_8_limit", "TVDV_limit"):
    print(f"{name}: vertical Wb {ref_iso[name + '_Wb']:.3f} h, vertical Wk {ref_iso[name + '_Wk']:.3f} h, "
          f"the Directive (three axes) {ref_iso[name + '_directive']:.3f} h")
if truth is not None:
    print(f"from the exact kinematics at 30 fps: A_w {est['A_w_directive']:.3f} m/s² "
          f"({100 * (est['A_w_directive'] / ref_iso['A_w_directive'] - 1):+.2f}%)")

# %% [markdown]
# On the bundled canter the fore-aft axis decides, and the time to the limit value by A(8) is about 30 %
# shorter than the thesis' vertical $W_k$ time (and half its $W_b$ time): a rider reaches the
# Directive's limit sooner than Table 8.7's reading says. The thesis' own x fit is a straight line
# (section 5.5.2.1), so its fore-aft acceleration is zero and it could not have seen this.

# %% [markdown]
# ## 5 · The comfort table: comfort.csv and a spreadsheet
#
# `write_comfort_csv` writes the spec's `comfort.csv` (`indicator,value,unit`). The thesis saved
# its table "in a format which is compatible with EXCEL"; `write_comfort_spreadsheet` writes a real
# `.xlsx` workbook (numbers stay numbers; a CSV opened in a Turkish or German Excel would read
# `3.19` with the wrong decimal separator). No extra package is needed.

# %%
out = Path(tempfile.mkdtemp(prefix="comfort-"))
csv_path = vibration.write_comfort_csv(out / "comfort.csv", ref_iso)
xlsx_path = vibration.write_comfort_spreadsheet(out / "comfort.xlsx", ref_iso)
print(csv_path.name, "and", xlsx_path.name, "written")
lines = csv_path.read_text().splitlines()
print(f"{lines[0]}  + {len(lines) - 1} rows, e.g. {lines[1].split(',')[0]} ... {lines[-1].split(',')[0]}")
back = vibration.read_comfort_csv(csv_path)
print(f"read back acc_y_Wk_rms = {back['acc_y_Wk_rms']:.4f} m/s²")

# %% [markdown]
# ## Comfort of the visible markers and their amplitudes (Appendix A steps 9 and 10)
#
# Before it turned to the hidden saddle marker, the thesis computed the same performance measures
# for each visible marker (`performance_measure.m`, Appendix A step 10) and saved each marker's
# vertical and lateral amplitudes with its fits (`Z_amplitudes_marker3`, step 9). From this
# session's analysis (the pipeline's fitted marker kinematics in the motion frame, every marker
# weighted on the same stride harmonics as the saddle):

# %%
from horsemocap.report import unit_text

rb = an.rigid_body
period = an.motion_frame.period_frames
f0 = None if period is None else an.session.fps / period
per_marker = vibration.marker_comfort(rb.t, rb.registered, rb.acceleration, rb.velocity, f0_hz=f0)
rows = {f"marker {m + 1}": ind for m, ind in enumerate(per_marker)}
rows["saddle"] = an.comfort.indicators
amp = vibration.half_peak_to_peak(np.concatenate([rb.registered, rb.saddle_position[:, None]], axis=1))
shown = ("acc_y_Wb_rms", "acc_y_Wk_rms", "VDV_y_Wb", "VDV_y_Wk", "TA_8_limit_Wb")
print(f"{'point':9s}" + "".join(f"{k:>15s}" for k in shown) + f"{'y amplitude':>13s}{'z amplitude':>13s}")
print(f"{'':9s}" + "".join(f"{unit_text(vibration.COMFORT_UNITS[k]):>15s}" for k in shown) + f"{'mm':>13s}{'mm':>13s}")
for (label, ind), (ay, az) in zip(rows.items(), amp):
    vals = "".join(f"{'not computed':>15s}" if ind is None else f"{ind[k]:15.3f}" for k in shown)
    print(f"{label:9s}{vals}{1000 * ay:13.1f}{1000 * az:13.1f}")

# %%
plots.plot_marker_comfort(rows)
plt.show()

# %% [markdown]
# The markers sit on the horse's back, the saddle marker behind and below them: each point moves
# differently because the back also pitches and rolls, so its vertical acceleration, and with it
# the time to the EU limits, differ from point to point. This is why the thesis went on to the
# saddle marker (section 6.4): the rider sits there, not on the markers.

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
# 1. A rider on Horse 2 at canter: how many hours until the EU **action** value by A(8) with $W_k$?
#    And by VDV? Which is stricter, and why does the VDV time depend on $\tau$?
# 2. Halve every harmonic amplitude. By what factor do the A(8) times grow? The VDV times?
# 3. An accelerometer at 100 Hz records 20 s of a 2 Hz sine of 3 m/s² amplitude. Compute the
#    $W_k$-weighted rms with `weighting_filters.comfort_from_samples` using `method="iir"` and `method="fft"`,
#    and compare with $3\,|W_k(2)|/\sqrt2$.
# 4. Using the Table 8.7 values, what speed would a horse need so that the rider covers 25 km before
#    the A(8) limit with $W_b$?
#
# <details><summary>Solutions</summary>
#
# 1. `ref_iso["TA_8_action_Wk"]` and `ref_iso["TVDV_action_Wk"]`. The VDV time is the shorter:
#    VDV weights peaks with the fourth power. $T_{VDV} = \tau (VDV_{thr}/VDV)^4$ with VDV measured
#    over $\tau$; VDV$^4$ grows in proportion to $\tau$, so the ratio stays the same — only for whole
#    periods.
# 2. rms halves, $T_{A(8)} \propto 1/a^2$ grows 4×; $T_{VDV} \propto 1/VDV^4$ grows 16×.
# 3. `fs = 100; t = np.arange(2000) / fs; x = 3 * np.sin(2 * np.pi * 2 * t)`, then
#    `weighting_filters.comfort_from_samples(x, fs, method=m)["acc_y_Wk_rms"]` for each `m`. The FFT path
#    gives $3 \cdot 0.531/\sqrt2 = 1.127$; the IIR path is a little lower because the filter starts
#    from rest (its transient is part of the record).
# 4. $D = V \cdot T$: $V = 25 / 1.0393 = 24.1$ km/h.
#
# </details>
