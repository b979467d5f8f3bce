# %% [markdown]
# # 14 · Accuracy: the error of every stage, and what a better rig buys
#
# **What you will learn**
# - how to measure a motion-capture pipeline stage by stage against an exact truth, with the
#   metrics of Guchin et al. (section 6): *match the points, then measure the Euclidean
#   distance*, in pixels per camera and in metres in 3D;
# - how a small error in the images grows on its way to the saddle's acceleration and the comfort
#   indicators (noise injection, Guchin et al. section 6.3);
# - why the thesis' rig (640x480, 30 fps, cameras 0.24 and 0.45 m apart at 7.5 m) limits what it can
#   measure, and how much resolution, frame rate and baseline each buy.
#
# Thesis equations involved: the whole chain, eq. 3.11 (sync) to eq. 7.25 (distances). Depth
# resolution of a stereo pair: $\delta Z \approx Z^2 \, \delta u / (f B)$, with $Z$ the distance,
# $f$ the focal length in pixels, $B$ the baseline and $\delta u$ the pixel error.

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
import numpy as np
import matplotlib.pyplot as plt

from horsemocap import accuracy, plots, vibration
from horsemocap.pipeline import AnalysisError
from horsemocap.data import default_session_dir
from horsemocap.virtuallab import thesis_rig
from horsemocap.workspace import NO_TRUTH, results_for, session_truth

analysis = results_for(ws.session_dir)
truth = session_truth(ws.session_dir)      # None for a recorded session (no truth/ folder)
if truth is None:
    print(NO_TRUTH, "(a recorded session): this notebook measures errors against a truth, so most of it is "
          "left out; the simulated rigs of section 6 still run: they ride the virtual laboratory's Horse 2 at "
          "canter (its three markers) with this session's pipeline parameters")

# %% [markdown]
# ## 1. Synchronisation
#
# The flash frame found in each camera against the frame the virtual laboratory switched it on.

# %%
for cam in analysis.session.cameras:
    true = NO_TRUTH if truth is None else f"{truth.offsets[cam]:4d}"
    print(f"{cam:6s} found {analysis.synchronisation.offsets[cam]:4d}   true {true}")

# %% [markdown]
# ## 2. Marker detection (2D)
#
# Each detected centroid is matched to the true projected centre of the marker (an optimal
# one-to-one assignment per frame, so a swap of two markers would show up as a mismatch of
# identities), then the distance in pixels is measured.

# %%
if truth is None:
    print(NO_TRUTH)
else:
    err2d = accuracy.errors_2d(analysis, truth)
    print("camera  median_px  p99_px  max_px  swaps  found/visible")
    for cam, e in err2d.items():
        print(f"{cam:6s}  {e['median']:9.3f}  {e['p99']:6.3f}  {e['max']:6.3f}  {e['swaps']:5d}  {e['found']}/{e['true_visible']}")

# %%
if truth is None:
    print(NO_TRUTH)
else:
    fig = plots.plot_errors_2d(err2d)
    plt.show()

# %% [markdown]
# ## 3. From pixels to the saddle (3D)
#
# Every later stage is compared in the *true* motion frame, so the error of the estimated motion
# frame itself is included. Watch the z-motion column: z is the depth seen from the cameras.

# %%
if truth is None:
    print(NO_TRUTH)
else:
    st = accuracy.stage_errors(analysis, truth)
    print(f"analysed frames: {st['frames']}")
    print(f"gravity direction error: {st['gravity_deg']:.3f} deg;  x-motion axis error: {st['x_axis_deg']:.3f} deg")
    print("stage                      RMSE x       y       z")
    for key, unit, scale in (("triangulated", "mm", 1000), ("smoothed", "mm", 1000), ("registered", "mm", 1000),
                             ("velocity", "mm/s", 1000), ("acceleration", "m/s²", 1), ("omega", "rad/s", 1),
                             ("alpha", "rad/s²", 1), ("saddle_position", "mm", 1000),
                             ("saddle_acceleration", "m/s²", 1)):
        x, y, z = scale * st[key]
        print(f"{key:20s} {unit:>6s} {x:7.2f} {y:7.2f} {z:7.2f}")
    print(f"saddle vertical acceleration RMSE: {st['saddle_acc_y_rmse_pct_of_rms']:.2f} % of its rms")

# %%
if truth is None:
    print(NO_TRUTH)
else:
    fig = plots.plot_stage_rmse(st)
    plt.show()

# %% [markdown]
# These are the pipeline's default kinematics: the pose trajectory smoothed from all markers
# (notebooks 08-11), with no model imposed on any axis. The thesis' chain of fits
# (`kinematics="fits"`) fits x-motion with a straight line (degree 1, section 5.5.2.1), so there the
# surge of the canter (the horse speeding up and slowing down within a stride) is not in the model
# and the x-motion acceleration error is large by construction; the section "The thesis' own chain
# beside the default" below runs it whole.
#
# ## 4. The comfort indicators
#
# The truth's indicators come from the exact harmonic series of the true saddle acceleration.

# %%
if truth is None:
    print(NO_TRUTH)
else:
    ind = analysis.comfort.indicators
    cerr = accuracy.comfort_errors(ind, truth.comfort)
    print("indicator                     measured      truth   error %")
    for key, e in cerr.items():
        print(f"{key:28s} {ind[key]:9.4f}  {truth.comfort[key]:9.4f}  {e:7.2f}")

# %% [markdown]
# ## 5. Noise injection: how detection error propagates
#
# As Guchin et al. did, replace the detections by the true projections plus Gaussian noise of
# standard deviation $\sigma$ (up to 3 px) and run every later step again with the same choices.

# %%
if truth is None:
    print(NO_TRUTH)
else:
    rows = accuracy.noise_study(analysis, truth, sigmas_px=(0.0, 0.1, 0.25, 0.5, 1.0, 2.0, 3.0), seed=1)
    print("sigma_px  runs  z_RMSE_mm  saddle_Ay_%  Wk_rms_%  VDV_Wk_%   (medians over the runs that completed)")
    for r in rows:
        if not r["draws"]:
            print(f"{r['sigma_px']:8.2f}  0/{len(r['failed'])}  every run stopped: {r['failed'][0][:90]}")
            continue
        c = r["comfort_pct"]
        print(f"{r['sigma_px']:8.2f}  {r['draws']}/{r['draws'] + len(r['failed'])}  {1000 * r['smoothed_m'][2]:9.1f}"
              f"  {r['saddle_acc_y_pct']:11.1f}  {c.get('acc_y_Wk_rms', np.nan):8.1f}  {c.get('VDV_y_Wk', np.nan):8.1f}")

# %%
if truth is None:
    print(NO_TRUTH)
else:
    fig = plots.plot_noise_study(rows)
    plt.show()

# %% [markdown]
# The pose is registered with each marker weighted by its triangulation covariance
# (`pose.register_pose(covariance=...)`), so depth, measured about ten times worse than across the
# viewing rays, counts less; and each rotation component is smoothed with every frame weighted by its
# predicted variance where that noise model explains the residuals better than equal weights
# (`pose_rotation_weights`): a few frames' poses are ten times noisier than the rest (the thin marker
# triangle seen almost edge-on), and the weights take them out. A tenth of a pixel then costs the
# saddle's acceleration a few percent (the equal-weight registration of the thesis' eq. 5.14-5.21
# gave about 31 %), a quarter of a pixel about 12 % in this draw (the goal set for this reproduction is 20 %;
# 5.9-9.2 % on five other virtual sessions, medians of three noise draws each, `benchmarks/README.md`). The depth formula explains what remains:
# with $Z = 7.5$ m, $f \approx 725$ px and $B = 0.45$ m, one pixel of error is
# $\delta Z \approx 7.5^2 / (725 \cdot 0.45) \approx 0.17$ m of depth. The markers' depth noise becomes
# a pitch error of the rigid body (rotation about the lateral axis), and the saddle, about 0.5 m along
# the back from the markers (notebook 11), swings with it; from half a pixel on, the smoothing
# usually cannot tell the pitch's 2nd stride harmonic from the noise, and differentiating twice
# multiplies what is left by $(2\pi f)^2$: about 30 % and more. Beyond a pixel the per-frame pose
# is so far off that its linearised noise (the weights) no longer means much; the numbers there only
# say that such a rig cannot measure the saddle.

# %%
dz = 7.5 ** 2 / (np.mean(thesis_rig()["right"].focal) * np.linalg.norm(thesis_rig()["right"].translation))
print(f"depth error per pixel with the left-right pair: {dz:.3f} m")

# %% [markdown]
# ## 6. The thesis' limits, and better rigs
#
# The same virtual ride (Horse 2, canter) seen through other rigs, with the same detection noise
# ($\sigma$ = 0.25 px, a good real detector) and the same pipeline. The truth and the noisy detections
# are generated at the 2D level (no images are rendered), to isolate the geometry: pixel size, frame rate
# and baseline. The simulated ride is always the virtual Horse 2 at canter with its three skin markers
# (`accuracy.simulate_rig`): a session of another horse, with four markers or without truth, lends it only
# its pipeline parameters, so the numbers below describe the rigs, not that session's ride.

# %%
rig = thesis_rig()
variants = {
    "thesis 640x480, 30 fps": (rig, 30.0),
    "3x resolution (1920x1440)": (accuracy.scaled_rig(rig, 3.0), 30.0),
    "60 fps": (rig, 60.0),
    "1.5 m baseline": (accuracy.wide_baseline_rig(rig, 1.5), 30.0),
    "3x resolution + 1.5 m baseline": (accuracy.wide_baseline_rig(accuracy.scaled_rig(rig, 3.0), 1.5), 30.0),
}
study = accuracy.rig_study(analysis, variants, sigma_px=0.25, seed=2)
print("rig                              frames  z_RMSE_mm  saddle_z_mm  saddle_Ay_%  Wk_rms_%")
for r in study:
    if "failed" in r:
        print(f"{r['rig']:32s} stopped: {r['failed'][:80]}")
        continue
    print(f"{r['rig']:32s} {r['frames']:6d}  {1000 * r['smoothed_m'][2]:9.1f}  {1000 * r['saddle_position_m'][2]:11.1f}"
          f"  {r['saddle_acc_y_pct']:11.1f}  {r['comfort_pct'].get('acc_y_Wk_rms', np.nan):8.1f}")

# %% [markdown]
# Resolution and baseline both shrink the depth error; together they bring the saddle's vertical
# acceleration within a few percent even with a quarter pixel of noise. A wider baseline is the
# cheaper of the two (no new cameras, only a different stand) but narrows the volume that every camera
# sees. A higher frame rate alone does not help: more samples of an equally noisy depth are not a
# better depth. Each row is one draw of the noise, on the detections *and* on the plumb and static
# stills; section 3 kept the session's own stills and gives the median of three draws, hence its 11.6 %
# against this thesis row's 30 % at the same noise. The 60 fps row's large error is its static still's
# draw: the same run with the still's true points gives 4.7 % (27.7 % at 30 fps). The saddle's place
# is measured once, in the static shot, whatever the frame rate.
#
# The thesis' own chain of fits (section 5.5), which the pipeline computes beside its default pose
# trajectory and uses with `kinematics="fits"` (notebook 11 compares the two), has a frame-rate problem of
# its own, in the Fourier orders it chooses. The cell below prints the orders that chain chose for the body's
# rotation (section 6.1 fit of the rotation angles) and for the saddle's path, at both frame rates.

# %%
for fps in (30.0, 60.0):
    sim, sim_truth = accuracy.simulate_rig(analysis, rig, fps, 0.25, seed=2)
    fit = sim.rigid_body.body
    first, end = sim.triangulate.segment
    print(f"{fps:.0f} fps, {end - first} analysed frames: rotation orders "
          f"{fit.rotation_fit.orders.tolist()}, saddle path orders {fit.saddle_fit.orders.tolist()} (the chain); "
          f"the default's saddle A_y error {accuracy.stage_errors(sim, sim_truth)['saddle_acc_y_rmse_pct_of_rms']:.0f} %")

# %% [markdown]
# Each order comes from the number of extremes E of the curve (section 5.5.2.2: N = E/2 or E/2 + 1).
# For the rotation angles E is counted on the thesis' `rloess` 0.1 of the angle. On the 30 fps
# record that is a 5-point window, whose robust iterations throw the record's ends far off (notebook
# 06, section 2); measured against that range, few of the noisy angle's wiggles reach the 10 %
# prominence that counts as an extreme, so the orders stay at 1-3, which happens to suppress the
# noise. At 60 fps the same span is 9 points, the smoother behaves, and the extremes of the noise
# are counted: orders up to 9 (printed above). A harmonic of order N is multiplied by $(N\omega)^2$ in the acceleration,
# so fitted noise at high orders swamps it. Requiring every kept harmonic to be significant
# (`order_rule="every_significant"`) lowers such orders, but on the 16 herd sessions it also drops
# real high harmonics that the comfort weightings need: `benchmarks/bench_herd.py --params
# '{"order_rule": "every_significant"}'` (with the thesis' per-camera detection) measured the median
# saddle error 24.6 → 19.4 % but the median error of the Wb-weighted rms 7.9 → 11.2 %
# (underestimated). The pipeline keeps the default
# rule; a frame-rate-proof order choice is still open.
#
# %% [markdown]
# ## The thesis' own chain beside the default (`--preset thesis`)
#
# Everything above uses the pipeline's automatic choices. The thesis made other ones, and the
# package can run them all at once: `horsemocap analyze SESSION --out DIR --preset thesis` on the
# command line, `{"preset": "thesis"}` in a parameter file, or
# `results_for(params={"preset": "thesis"})` in a notebook (options given beside it override it, and
# `analysis.json` records `"preset": "thesis"`). The preset's values, with the default's:

# %%
import dataclasses
import json

from horsemocap import pipeline
from horsemocap.data import repository_file
from horsemocap.params import AnalysisParams, params_fields
from horsemocap.report import format_value

default_params = analysis.params
thesis_params = AnalysisParams.from_dict({"preset": "thesis"})
print(f"{'choice':32s} {'default':40s} thesis")
for field in params_fields():
    d, th = default_params.value(field.path), thesis_params.value(field.path)
    if d != th and field.path != "preset":
        print(f"{field.path:32s} {format_value(d)[:40]:40s} {format_value(th)}")

# %% [markdown]
# ### On this session, step by step
#
# The cell below runs the thesis' chain from the detection on, on top of this session's
# synchronisation, rig, plumb line and static shot (`pipeline.run_steps`; the preset's pairwise
# calibration is the only step it skips; the measurement in the next section runs the preset whole,
# pairwise calibration included). Then it swaps single thesis choices back to the default's, keeping the
# thesis' detections and positions, to see which choice makes the difference.

# %%
if truth is None:
    print(NO_TRUTH)
else:
    keys = ("acc_y_Wb_rms", "VDV_y_Wb")


    def errors(a):
        st = accuracy.stage_errors(a, truth)
        ce = accuracy.comfort_errors(a.comfort.indicators, truth.comfort, keys)
        return st["saddle_acc_y_rmse_pct_of_rms"], ce["acc_y_Wb_rms"], ce["VDV_y_Wb"]


    # the synchronisation the default's detection checked, the rig, the plumb line and the static shot
    before = {"sync": analysis.synchronisation, "rig": analysis.rig, "plumb": analysis.plumb, "static": analysis.static}
    thesis = pipeline.run_steps(analysis.session, thesis_params, before,
                                ["detect", "triangulate", "smooth", "motion_frame", "rigid_body", "comfort"])
    rows = [("default (every automatic choice)", errors(analysis)), ("thesis preset", errors(thesis))]
    for label, change in [("thesis, omega by the fitted orientation", dict(angular_method="rotation")),
                          ("thesis, saddle by the fitted pose", dict(saddle_method="pose")),
                          ("thesis, orders E/2 or E/2+1 with a drift term",
                           dict(order_rule="significant", fourier_trend=True)),
                          ("thesis, weighting per harmonic (iso)", dict(weighting_mode="iso")),
                          ("thesis, kinematics from the smoothed pose", dict(kinematics="pose_spline"))]:
        a = pipeline.run_steps(analysis.session, thesis_params.updated(change), thesis,
                               ["rigid_body", "comfort"])
        rows.append((label, errors(a)))
    a = pipeline.run_steps(analysis.session, default_params, thesis,
                           ["triangulate", "smooth", "motion_frame", "rigid_body", "comfort"])
    rows.append(("default after the thesis' detection", errors(a)))
    print(f"{'chain':48s} {'saddle A_y RMSE':>16s} {'Wb rms error':>13s} {'VDV Wb error':>13s}")
    for label, (ay, wb, vdv) in rows:
        print(f"{label:48s} {ay:14.1f} % {wb:+12.1f} % {vdv:+12.1f} %")
    print("warnings of the thesis chain:", *thesis.rigid_body.warnings, sep="\n  ")

# %% [markdown]
# What the table says, choice by choice:
#
# - **The detection, calibration and triangulation are not the difference.** The default's later
#   steps on the thesis' per-camera detections and pair-averaged triangulation give about the
#   default's own errors (last row).
# - **The thesis' angular velocity is.** Its six versions (eq. 6.3/6.4, 6.38/6.39) divide by the
#   component of $\boldsymbol\omega$ normal to the markers' plane; at canter $\boldsymbol\omega$ lies
#   within 15° of that plane in most frames (the warning above, eq. 6.35), so the division amplifies
#   the noise without bound and the saddle acceleration of eq. 6.55, built on $\boldsymbol\omega$ and
#   $\boldsymbol\alpha$, follows. Replacing either the angular velocity (by the fitted orientation)
#   or the saddle's kinematics (by the fitted pose) brings the error down by two to three orders
#   of magnitude. How large the blow-up is depends on the noise of the positions, so it changes
#   from one rig to another (compare the bundled session's row in the next section, measured with the
#   pairwise rig).
# - **The remaining difference** (tens of per cent after that swap) is the order E/2 without a drift
#   term and `rloess`: with fewer harmonics the fits miss part of the saddle's vertical
#   acceleration, so the thesis chain *under*estimates the comfort indicators once its
#   singularity is removed.
# - **The single-scalar weighting** changes only the comfort step: it weights every harmonic at the
#   dominant one's frequency. On this session it makes the blown-up rms *smaller* (the noise sits at
#   high frequencies where one scalar at the stride frequency weights less); on the true motion it
#   underestimates the weighted rms (notebook 12, "iso vs thesis mode"; the herd's "weighting only"
#   column below).

# %% [markdown]
# ### On the 16 herd sessions
#
# `benchmarks/bench_preset.py` runs both, whole, on the bundled session and on the 16 sessions of
# the virtual herd (`benchmarks/results/preset_thesis.json`; read here, not recomputed: it takes
# about 20 minutes). The herd sessions carry a rig file, so the pairwise calibration applies to the
# bundled session only. "weighting only" is the thesis' single-scalar weighting applied to the *true*
# motion, against the standards' per-harmonic weighting: the part of the error that is the weighting.

# %%
bench = json.loads(repository_file("benchmarks/results/preset_thesis.json").read_text())
print(f"{'session':24s} {'default A_y':>11s} {'thesis A_y':>11s} {'default Wb':>11s} {'thesis Wb':>11s} "
      f"{'weighting only':>15s}")
for row in bench["rows"]:
    d, th = row["default"], row["thesis"]
    cell = lambda r, v: f"{v:10.1f}%" if r["completed"] else "   stopped"
    w = row.get("weighting_only_pct", {}).get("acc_y_Wb_rms")
    print(f"{row['session']:24s} {cell(d, d.get('saddle_acc_y_pct')):>11s} {cell(th, th.get('saddle_acc_y_pct')):>11s} "
          f"{cell(d, d.get('comfort_error_pct', {}).get('acc_y_Wb_rms')):>11s} "
          f"{cell(th, th.get('comfort_error_pct', {}).get('acc_y_Wb_rms')):>11s} "
          + (f"{w:+14.1f}%" if w is not None else ""))
for label in ("default", "thesis"):
    s = bench["summary"][label]
    print(f"{label}: {s['herd_completed']} of 16 herd sessions; saddle A_y error median "
          f"{s['median_saddle_acc_y_pct']:.1f} %, worst {s['worst_saddle_acc_y_pct']:.0f} %; median |error| of "
          f"the Wb rms {s['median_abs_comfort_error_pct']['acc_y_Wb_rms']:.1f} %; "
          f"{s['sessions_with_warnings']} with conditioning warnings")
w = bench["summary"]["weighting_only_median_pct"]
print(f"the thesis' weighting alone, on the true motion: median {w['acc_y_Wb_rms']:+.1f} % (Wb rms), "
      f"{w['VDV_y_Wb']:+.1f} % (VDV Wb)")

# %% [markdown]
# Over the herd the pattern is the same. At walk and the trots, where $\boldsymbol\omega$ stays away
# from the markers' plane, the thesis chain completes with errors of tens of per cent and
# *under*estimates the weighted rms by about half at walk: about half of that is its
# single-scalar weighting (the "weighting only" column), the rest the low Fourier orders and the
# thesis' saddle formula on noisy $\boldsymbol\alpha$. At canter the eq. 6.35 singularity makes the
# thesis' numbers meaningless (errors of thousands of per cent) on every horse. One session (Horse 4,
# sitting trot) does not complete: its triangulation finds the pairs' rays crossing behind a camera
# (`behind_a_camera`) in too many frames, which is what rays of markers labelled differently in two
# cameras do (the per-camera detection labels each camera alone; the default's multi-view
# identification labels all cameras together; not examined further here). This is why the pipeline's defaults differ from
# the thesis' choices, each for a measured reason (`horsemocap.params.AnalysisParams`), and why the
# preset exists: to run the thesis as it was, and to see where each difference comes from.


# %% [markdown]
# ### Where the thesis' chain works: its user's answers, its inputs and Table 8.7
#
# The thesis published plausible values (Table 8.7) from the same chain that explodes above. Its user
# did not run it blind: `angular_velocity.m` showed each of the six versions of $\boldsymbol\omega$
# (eq. 6.3/6.4, one per pair of markers and order) and asked "use it? y/n", the same for
# $\boldsymbol\alpha$, and the saddle's acceleration (eq. 6.55) is built from the average of the
# versions kept. Every version divides by the component of $\boldsymbol\omega$ normal to the markers'
# plane (eq. 6.35); a version kept where that component is small carries the blow-up into the saddle.
# The user also typed the detection inputs (section 8.4.1: threshold 115, area 15-240 px, window
# 84 x 40 px, distance tolerance 0.09) and chose the Fourier orders (fourier2 for y, fourier1 for z).
# First, those inputs beside the ones the thesis' chain finds on this session:

# %%
from horsemocap import thesis_answers
from horsemocap.widgets.markers_guard import table_8_7_ride
from horsemocap.workspace import chain_choices, session_params

THESIS_DETECTION = {"threshold": 115, "area_min": 15, "area_max": 240, "window": [84, 40],
                    "distance_tolerance": 0.09}                      # section 8.4.1 (left camera)
THESIS_ORDERS = [[2, 1]] * 3                                         # fourier2 for y, fourier1 for z
thesis_choices = chain_choices(ws.choices, "thesis")                 # the thesis' chain with this session's choices
try:
    th_auto = results_for(ws.session_dir, params=session_params(ws.session_dir, thesis_choices))
except AnalysisError as exc:        # e.g. four markers: the thesis' per-camera chain follows three
    th_auto = None
    print(f"the thesis' chain on this session: stopped: {exc}")
if th_auto is not None:
    det = th_auto.detect.detection[th_auto.session.reference_camera]
    area_text, window_text = f"{det['area_min']:.0f}-{det['area_max']:.0f}", f"{det['window'][0]} x {det['window'][1]}"
    orders = th_auto.rigid_body.body.motion_fit.orders if th_auto.rigid_body.body.motion_fit is not None else None
    print(f"{'input':28s} {'section 8.4.1 / 8.4.2':>22s} {'this session (thesis chain)':>28s}")
    print(f"{'threshold':28s} {115:>22d} {det['threshold']:>28d}")
    print(f"{'area range (px)':28s} {'15-240':>22s} {area_text:>28s}")
    print(f"{'window (px)':28s} {'84 x 40':>22s} {window_text:>28s}")
    print(f"{'distance tolerance':28s} {0.09:>22.2f} {det['distance_tolerance']:>28.3f}")
    if orders is None:
        print(f"{'Fourier orders y, z':28s} {'fourier2, fourier1':>22s} {'none: ' + th_auto.rigid_body.body.chain_error}")
    else:
        yz = sorted({(int(y), int(z)) for _, y, z in orders})            # per marker: x degree, y order, z order
        print(f"{'Fourier orders y, z':28s} {'fourier2, fourier1':>22s} "
              f"{'; '.join(f'fourier{y}, fourier{z}' for y, z in yz):>28s}")

# %% [markdown]
# Now the chain under each answer a user is likely to give (all versions, one version alone, all but
# one; the same answer for $\boldsymbol\omega$ and $\boldsymbol\alpha$), with this session's automatic
# inputs, with the thesis' Fourier orders, with the thesis' detection inputs, and with both. An answer
# *keeps the chain finite* when the saddle's peak vertical acceleration passes the plausibility check
# of the quality verdict (ok: 0.5-40 m/s²; a person on a horse is not shaken by tens of g). Among those,
# the answer whose $W_b$ rms is nearest Table 8.7's is shown beside it.

# %%
T = vibration.THESIS_TABLE_8_7
variants = {"session's inputs": {}, "+ thesis' orders": {"fourier_orders": THESIS_ORDERS},
            "+ 8.4.1 detection": {"detection": {"all": THESIS_DETECTION}},
            "+ both": {"fourier_orders": THESIS_ORDERS, "detection": {"all": THESIS_DETECTION}}}
best = {}
if th_auto is None:
    print("the thesis' chain stopped on this session (above): no answers to study")
    variants = {}
else:
    print(f"{'thesis chain':36s} {'all yes: Wb rms':>16s} {'finite answers':>15s}  {'nearest Table 8.7':>18s}  Wb / Wk rms")
for label, change in variants.items():
    params = session_params(ws.session_dir, thesis_choices, overrides=change)
    try:
        run = th_auto if not change else results_for(ws.session_dir, params=params)
    except AnalysisError as exc:
        print(f"{label:36s} stopped: {exc}")
        continue
    rows = thesis_answers.answers_study(run, params, thesis_answers.typical_masks())
    finite = [r for r in rows if r["level"] == "ok"]
    near = min(finite, key=lambda r: abs(r["acc_y_Wb_rms"] - T["acc_y_Wb_rms"]), default=None)
    best[label] = near
    near_text = "none" if near is None else (f"{thesis_answers.mask_text(near['mask']):>18s}  "
                                             f"{near['acc_y_Wb_rms']:.2f} / {near['acc_y_Wk_rms']:.2f} m/s²")
    print(f"{label:36s} {rows[0]['acc_y_Wb_rms']:12.2f} m/s² {len(finite):>8d} of {len(rows):<3d}  {near_text}")

# %%
keys = ("acc_y_Wb_rms", "acc_y_Wk_rms", "VDV_y_Wb", "acc_y_max")
default_ind = analysis.comfort.indicators
comparable, ride_text = table_8_7_ride(analysis.session.metadata)
if comparable:
    print(f"{'indicator':14s} {'Table 8.7':>10s} {'default chain':>14s}" + "".join(f"{k:>18s}" for k in best))
    print(f"{'(answer)':14s} {'':>10s} {'':>14s}" + "".join(
        f"{'' if r is None else thesis_answers.mask_text(r['mask']):>18s}" for r in best.values()))
    for k in keys:
        print(f"{k:14s} {T[k]:10.2f} {default_ind[k]:14.2f}" + "".join(
            f"{'-' if r is None else format(r[k], '.2f'):>18s}" for r in best.values()))
else:
    print(ride_text)
    print("Table 8.7 (thesis, Horse 2 at canter): " + ", ".join(f"{k} {T[k]:.2f}" for k in keys))
    print(f"this session ({analysis.session.name}), default chain: " + ", ".join(f"{k} {default_ind[k]:.2f}" for k in keys)
          + "".join(f"; thesis chain ({label}, {thesis_answers.mask_text(r['mask'])}): "
                    + ", ".join(f"{k} {r[k]:.2f}" for k in keys) for label, r in best.items() if r is not None))

# %% [markdown]
# (Table 8.7 is the thesis' Horse 2 at canter; on a session of another horse or gait the table is printed on
# its own, not beside that session's figures, which belong to another ride.)
#
# What this shows, on the bundled canter: with the automatic inputs only 3 of the 13 answers stay
# finite (all yes gives a $W_b$ rms of 30 m/s²), each keeping a single version; the thesis' Fourier
# orders alone do not help (all yes: tens of thousands of m/s²). With section 8.4.1's detection inputs
# (a tighter window and tolerance) 11 of 13 answers stay finite, all yes included ($W_b$ rms 2.6 m/s²),
# and the nearest gives Table 8.7's $W_b$ rms (3.19 m/s²) with a $W_k$ rms of 4.0 against the table's
# 3.7: values like the thesis'. The default chain's 3.62 / 4.35 m/s² need no answer at all.
# So the thesis' chain works where its user's inputs and answers keep $\boldsymbol\omega$'s normal
# component away from zero; where $\boldsymbol\omega$ lies in the markers' plane for most of the stride
# (canter), no answer can remove the division, and only a choice that avoids eq. 6.35 (the default
# chain's pose trajectory) gives numbers that do not depend on the answers.

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
# 1. Repeat the noise study with `analysis.params` changed to the thesis triangulation mode
#    (`params=accuracy.with_params(analysis, triangulation="thesis")`). Which mode is more robust?
# 2. Using the depth formula, how wide must the baseline be for 0.25 px of noise to give 5 mm of depth
#    error at 7.5 m with the thesis' cameras?
# 3. Which stage contributes most to the saddle's position error in z-motion on the bundled session?
# 4. Rerun the orders cell with the other rule: `strict = dataclasses.replace(analysis,
#    params=accuracy.with_params(analysis, order_rule="every_significant"))`, then
#    `accuracy.simulate_rig(strict, rig, fps, 0.25, seed=2)`. Which orders change, and does the
#    60 fps saddle error come down to the 30 fps one?
#
# <details><summary>Solutions</summary>
#
# 1. `accuracy.noise_study(analysis, truth, params=accuracy.with_params(analysis, triangulation="thesis"))`;
#    the joint mode uses all rays at once and is at least as good with the pipeline's `loess` or no
#    smoothing (notebook 05 shows it on the truth; with `rloess` the comparison depends on the smoother).
# 2. $B = Z^2 \delta u / (f \delta Z) = 56.25 \cdot 0.25 / (725 \cdot 0.005) \approx 3.9$ m.
# 3. Triangulation: the depth (z) error is already there after triangulation and smoothing does not
#    remove it; registration and the rigid-body formulas carry it to the saddle.
# 4. The 60 fps rotation orders drop, but the saddle path keeps high orders and the 60 fps error
#    stays far above the 30 fps one in this draw: harmonics fitted to the noise pass the
#    significance test too. With a quarter pixel of noise the roll angle is mostly noise at
#    either frame rate, and the 30 fps record's low orders are an accident of its degenerate
#    smoother (explained above), not a better measurement. An order choice that holds at any
#    frame rate is still open.
#
# </details>
