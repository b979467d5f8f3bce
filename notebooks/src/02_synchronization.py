# %% [markdown]
# # 02 · Synchronization: the flashlight frame in each camera
#
# **What you will learn**
# - why three consumer cameras need to be synchronised, and how the thesis did it with a flashlight
#   (section 3.5, Figure 3.9, section 8.2);
# - the frame relations of eq. 3.11-3.14 and the `sync.offsets` of a session;
# - how `horsemocap.sync` finds the flash automatically, and why the horse's own bright spots
#   (reflective markers, bandages, a helmet, glints) do not fool it;
# - how to check and override the offsets frame by frame with a widget.
#
# **Thesis equations.** The thesis' Casio cameras had no remote trigger; each was started by hand, so
# the same instant has a different frame number in each video. A flashlight switched on in view marks
# one instant in all of them. With $F_L(k)$ the $k$-th frame of the left camera,
#
# $$F_L(k) \Leftrightarrow F_M(k + \Delta F_{LM}) \quad (3.11) \qquad
#   F_M(k) \Leftrightarrow F_R(k + \Delta F_{MR}) \quad (3.12) \qquad
#   F_L(k) \Leftrightarrow F_R(k + \Delta F_{LR}) \quad (3.13)$$
#
# with $\Delta F > 0$ (3.14) when the cameras were started left, middle, right. The thesis found
# $\Delta F_{LM} = 53$ and $\Delta F_{MR} = 73$ by looking at the frames (section 8.2).
# `horsemocap` stores the flash frame of each camera, `offsets`, so that
# $\Delta F_{LM}$ = `offsets["middle"] - offsets["left"]`.

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
import json

import matplotlib.pyplot as plt
import numpy as np
from IPython.display import display

from horsemocap import plots, widgets
from horsemocap.data import default_session_dir
from horsemocap.sources import FrameSource
from horsemocap.sync import aligned_index, detect_flash, flash_offsets, frame_differences

session = ws.session_dir
meta = json.loads((session / "session.json").read_text())
sources = {cam: FrameSource(session / path) for cam, path in meta["motion"].items()}
for cam, src in sources.items():
    print(f"{cam:7s} {src.path.name}: {len(src)} frames")

# %% [markdown]
# ## How the flash is found
#
# A pixel *rises* at frame $t$ when it is brighter by at least `min_rise` gray levels in each of the
# next `min_on_frames` frames than in the two frames before $t$ (frame $t$ itself is skipped, because
# a flash may switch on during its exposure). Many things make pixels rise:
#
# - the flashlight: a blob of pixels, all rising at the same frame, that stays where it is;
# - a moving bright object (a marker, a bandage, the rider's helmet, a bright horse's head, the fence
#   seen past the horse): only a sliver at its leading edge rises, right next to its own body, which
#   was already bright a frame before; the sliver grows or moves over the next frames, and the place
#   the object left goes dark;
# - glints and noise: a few pixels, for a frame.
#
# `detect_flash` labels every region that starts rising in the searched frames and rejects what a light
# switched on in place cannot do: touch the image edge (an object coming into view), be a bright thing
# that was there before and is only uncovered again (`lit_before`), brighten next to its own body that
# was bright a frame before (`surround_bright` above `max_surround_bright`), grow or move over its
# on-frames (`stays`: 1 for a light, about $2/(m+1)$ for the leading edge of an object moving over $m$
# frames), or leave a place that goes dark (`vacated`). Among the rest the flash is the one with the best
# score (near 1: large, in place, nothing bright or darkening beside it), **not the earliest**: a bright
# horse's head entering the picture before the flash would otherwise win. When another candidate at another
# frame scores nearly as well, the detection is `ambiguous` and the pipeline asks the markers to settle
# it. The flash frame is then measured on the chosen region: the first frame whose mean brightness is
# above half-way between the region's off and on levels.

# %%
detections = {cam: detect_flash(src) for cam, src in sources.items()}
for cam, det in detections.items():
    rejected = sum(not c["accepted"] for c in det.candidates)
    print(f"{cam:7s} flash at frame {det.frame:4d}  region {det.area_px:5d} px  "
          f"off {det.off_level:4.0f} -> on {det.on_level:4.0f} gray levels  score {det.score:.2f}"
          f"{'  AMBIGUOUS' if det.ambiguous else ''}  ({rejected} of {len(det.candidates)} candidates rejected)")

# %%
fig, ax = plt.subplots(figsize=(8, 3.2))
plots.plot_flash_signal(detections, ax=ax)
plt.show()

# %% [markdown]
# The frames around the flash, as in the thesis' Figure 3.9 (cropped around the flashlight): the
# column "+0" is the first frame with the flash on.

# %%
offsets = {cam: det.frame for cam, det in detections.items()}
fig = plots.plot_flash_frames(sources, offsets, detections)
plt.show()

# %% [markdown]
# ## The offsets and eq. 3.11-3.13
#
# `flash_offsets` gives the frames the pipeline uses (it calls `flash_detections`, which also says when a camera
# had two candidates of similar score). The virtual laboratory started its cameras with the
# thesis' offsets (53 and 73 frames), so the differences must come out as in section 8.2; the truth
# saved beside the session says which frame the flash really switched on in.

# %%
offsets = flash_offsets(sources)
print("offsets:", offsets)
for pair, df in frame_differences(offsets).items():
    print(f"Delta F_{pair} = {df}")
truth_file = session / "truth" / "truth.json"
if truth_file.is_file():
    true_offsets = json.loads(truth_file.read_text())["offsets"]
    print("true offsets:", true_offsets, "| found exactly:", offsets == true_offsets)
else:
    print("true offsets: no ground truth for this session")

# %% [markdown]
# Frame 20 of the left camera and the frames of the same instant in the other cameras (eq. 3.11, 3.13):

# %%
print(aligned_index(offsets, 20))

# %% [markdown]
# ## Check and override, frame by frame
#
# The widget shows the flashlight in the three cameras at the chosen offsets; move `frame - flash` to
# step through the frames before and after, and type another offset if a camera's flash was found at
# the wrong frame (for instance, a flash that switched on at the very end of an exposure). Its default
# is the automatic result, so running the notebook top to bottom gives the pipeline's offsets.

# %% tags=["nbval-ignore-output"]
ui = widgets.ui_sync(sources, offsets, {cam: det.region for cam, det in detections.items()})
ws.bind(ui, "sync_offsets")  # the offsets chosen here are the pipeline's from now on
display(ui)

# %%
chosen = ui.value
print("offsets used:", chosen)
print("Delta F:", frame_differences(chosen))

# %% [markdown]
# The chosen offsets are saved in the session's `choices.json` (in the notebooks' results store, never
# in the session folder) as `"sync_offsets": {...}` when they differ from the automatic ones; the
# later notebooks, and `horsemocap analyze SESSION --params choices.json`, then use them instead of
# searching for the flash.
#
# ## Robust to the horse's bright spots: a test you can see
#
# A synthetic video: dark noisy frames, three "markers" crossing at 6 px per frame, a large bright
# "helmet" crawling at 1.5 px per frame (each of its pixels stays bright for many frames, so a plain
# "pixels that stay bright" rule would take it for the flash), glints, and a flash at frame 37.

# %%
def synthetic_frames(n=70, flash_at=37, seed=0):
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[:96, :128]
    frames = np.clip(rng.normal(30, 3, (n, 96, 128)), 0, 255)
    for t in range(n):
        for j, y in enumerate((40, 52, 64)):
            frames[t][(xx - ((5 + 6 * t + 9 * j) % 148 - 10)) ** 2 + (yy - y) ** 2 <= 9] = 235
        frames[t][(xx - (10 + 1.5 * t)) ** 2 + (yy - 80) ** 2 <= 81] = 220
        if t % 7 == 3:
            frames[t][(xx - rng.integers(10, 118)) ** 2 + (yy - rng.integers(10, 86)) ** 2 <= 2] = 250
        if flash_at is not None and t >= flash_at:
            frames[t][(xx - 100) ** 2 + (yy - 20) ** 2 <= 36] = 250
    return frames.astype(np.uint8)


det = detect_flash(synthetic_frames())
print(f"flash found at frame {det.frame} (true 37); candidates rejected: "
      f"{sum(not c['accepted'] for c in det.candidates)} of {len(det.candidates)}")
for c in [c for c in det.candidates if not c["accepted"]][:4]:
    print(f"  frame {c['frame']:3d}, {c['area_px']:4d} px: {c['reason']}")

# %% [markdown]
# ## Cameras that run free: synchronising to a fraction of a frame
#
# The flashlight settles **whole frames**: the thesis took the first frame with the flash on in each
# camera and matched those frames (eq. 3.11-3.13). That is exact only if the three cameras expose their
# frames at the same instants. Ordinary cameras (camcorders, phones, action cameras) are not locked
# together: each runs on its own clock, so the middle camera's frame $k + \Delta F_{LM}$ is exposed a
# random fraction $p$ of a frame after the left camera's frame $k$ (and the clocks differ by tens of
# ppm, so $p$ drifts slowly). The flash itself shows $p$: a frame exposed over $[k, k + e]$ ($e$ the
# exposure as a fraction of the frame) during which the light switches on at $T$ collects light only
# after $T$, so the first lit frame is only partly bright,
#
# $$b = \frac{k + e - T}{e} \quad\Rightarrow\quad T = k + e\,(1 - b),$$
#
# and the difference of the onsets $T$ between two cameras is their offset with its fraction. An
# interlaced camcorder (PAL DV: 25 frames of two fields 20 ms apart) collects light over both fields,
# so its $e$ is the whole frame. The markers then refine the fraction: with the right phase, each
# camera's marker tracks, interpolated in time, meet the other cameras' markers projected into it.
#
# What is a fraction of a frame worth? Two views of the same marker taken $p/\text{fps}$ seconds apart
# see it where it was at two instants. The table gives the saddle's travel along the path in that time,
# and how far the saddle's vertical acceleration read that late lies from the true one (% of its rms,
# computed over a stride of the virtual laboratory's Horse 2).

# %%
from horsemocap.virtuallab.timing import fraction_costs

costs = fraction_costs("Horse 2", fps_values=(25.0, 30.0, 50.0, 60.0), fractions=(0.1, 0.5))
print(f"{'gait':13s} {'fps':>4s} {'fraction':>8s} {'delay':>8s} {'travel':>8s} {'vertical acc.':>14s}")
for c in costs:
    print(f"{c.gait:13s} {c.fps:4.0f} {c.fraction:8.1f} {c.delay_ms:5.1f} ms {c.travel_mm:5.0f} mm "
          f"{c.acc_y_pct:11.1f} %")

# %% [markdown]
# Half a frame at 25 or 30 fps is 4 to 10 cm of travel and a quarter to a third of the saddle's
# vertical acceleration: more than everything else the thesis' error budget holds. A tenth of a frame
# is already a few percent. Synchronising whole frames is not enough for free-running cameras; a
# twentieth of a frame is.
#
# A free-running session of the virtual laboratory (Horse 3, rising trot, 25 fps; three cameras drawn
# with random phases, clock errors and rolling shutters; rendered into the cache on first use, about
# half a minute) is synchronised the way `horsemocap analyze` does it: the flash's partly lit frames
# first, then the markers. A rolling shutter exposes the flash's rows later than the frame's first row,
# by their share of the readout (`subframe.flash_row_delay`: the flash 240 rows down a 480-row image read in
# 18 ms is seen 9 ms later); the flash's fractions take that delay, as the markers' instants take their
# own rows'.

# %%
from horsemocap import subframe
from horsemocap.pipeline import analyze
from horsemocap.virtuallab.herd import herd_free_running
from horsemocap.virtuallab.truth import load_truth, true_offsets_frames

free_session = herd_free_running(0, names=["free_horse3_rising_trot_25"])["free_horse3_rising_trot_25"]
free = analyze(free_session, None, {}, until="detect", progress=lambda *a: None)
by_flash = free.sync.offsets_with_fraction("left")
by_markers = free.synchronisation.offsets_with_fraction("left")
true_free = true_offsets_frames(load_truth(free_session))
for cam in ("middle", "right"):
    unc = free.synchronisation.offset_uncertainty_frames[cam]
    print(f"{cam:7s} frames after the left camera's: flash {by_flash[cam]:7.3f}, markers {by_markers[cam]:7.3f} "
          f"+- {unc:.3f}; true {true_free[cam]:7.3f} (error {by_markers[cam] - true_free[cam]:+.3f})")

# %% [markdown]
# The markers' estimate is the minimum of a curve: for each trial phase of one camera (the others
# kept), every camera's tracks are read at the reference camera's instants and triangulated together;
# the median reprojection residual is smallest where the views meet. The reported uncertainty adds to
# the spread between parts of the record the residual left at the minimum, expressed in frames (the
# residual over the markers' image speed): what the markers cannot tell from noise and calibration.

# %%
sync_free = free.synchronisation
marker_px_free = free.detect.marker_px
rig_free = free.rig.rig
times_free = free.detect.observation_frames
trials = sync_free.phase_frames["middle"] + np.linspace(-0.5, 0.5, 21)
curve = subframe.residual_curve(rig_free, marker_px_free, sync_free.phase_frames, "middle", trials, times_free,
                                sync_free.rate_ratio)
fig, ax = plt.subplots(figsize=(6, 3))
ax.plot(trials, curve, "o-")
ax.axvline(sync_free.phase_frames["middle"], color="k", lw=0.8, label="estimate")
ax.set_xlabel("middle camera's phase (frames after the left camera's)")
ax.set_ylabel("median residual (px)")
ax.legend()
plt.show()

# %% [markdown]
# Try it: move the middle camera's phase away from the estimate and watch the residual grow; its
# default is the pipeline's estimate.

# %% tags=["nbval-ignore-output"]
phase_ui = widgets.ui_phase("middle", sync_free.phase_frames["middle"],
                            sync_free.offset_uncertainty_frames["middle"])
display(phase_ui)

# %%
chosen_phase = phase_ui.value
at_chosen = subframe.residual_curve(rig_free, marker_px_free, sync_free.phase_frames, "middle", [chosen_phase],
                                    times_free, sync_free.rate_ratio)[0]
print(f"middle phase {chosen_phase:+.3f} frame: median residual {at_chosen:.3f} px "
      f"(the estimate {sync_free.phase_frames['middle']:+.3f}: the curve's minimum)")

# %% [markdown]
# ## Clocks that drift over a long ride
#
# A camera's crystal runs a few tens of ppm fast or slow, so its phase is not constant: with a rate
# ratio $r$ (reference frames per frame of its own) its frame $j$ is exposed at the reference instant
#
# $$t_j = p_0 + r\,j, \qquad\text{its phase at frame } j:\ p_0 + (r - 1)\,j,$$
#
# and the reference instant $k$ is its frame $(k - p_0)/r$ (`subframe.camera_frames`). Over one pass of
# a few seconds 100 ppm is a few thousandths of a frame; over a ride of several laps, a third of a
# frame, as much as the fractions above. The markers measure the drift: `subframe.refine_phases`
# measures every camera's phase again in parts of the record that show the horse (never spanning two
# passes: `subframe.seen_chunks`), fits a straight line through them, and keeps its slope as the rate
# when it is a clock's (`subframe.drift_is_measured`: 3 standard errors, a twentieth of a frame over
# the record, at most 1500 ppm: a camera at 30000/1001 fps labelled 30 is 999 ppm off one at 30). Such
# a camera gains a whole frame every thousand: the identification then compares, at each reference
# instant, its frame that keeps the delay within half a frame of its phase at frame 0
# (`subframe.whole_frames_gained`), so the frames it compares stay a fraction of a frame apart however
# long the ride. The rates are measured once the markers are identified, and the first identification
# holds the flash's phases: on a record longer than 1001 frames of cameras running free at rates not yet
# known, the detect step therefore measures the clocks first on the 1001 frames after the flash, where
# the flash's phases hold best, then on twice as many at the rates found, and identifies the whole
# record at them (a camera at 30000/1001 fps would otherwise be more than half a frame off where the
# markers are first labelled, the record's middle). A worked example: three passes of a marker
# triangle across the thesis rig in 1200 frames, the middle camera 150 ppm fast and 0.3 frame late,
# the right camera exact.

# %%
from horsemocap.virtuallab.rig import thesis_rig

ride_rig = thesis_rig()
base = np.array([[-0.24, 0.0, 0.0], [0.0, -0.07, 0.0], [0.22, 0.0, 0.01]])


def triangle_at(t):
    """The triangle's markers at times t (s) of a pass: across the views at 1.6 m/s with a 2 Hz bounce."""
    centre = np.column_stack([-1.4 + 1.6 * t, -0.05 + 0.05 * np.sin(2 * np.pi * 2.0 * t), 7.7 + 0.0 * t])
    return centre[:, None, :] + base[None]


n_ride, lap, seen, fps_ride = 1200, 500, 60, 30.0
clock = {"left": (0.0, 1.0), "middle": (0.3, 1 / 1.00015), "right": (-0.2, 1.0)}   # (phase at frame 0, rate)
ride_px = {}
for cam in ride_rig:
    p0, r = clock[cam.name]
    at = np.mod(p0 + r * np.arange(n_ride), lap)               # each frame's instant within its lap
    ride_px[cam.name] = cam.project(triangle_at(at / fps_ride))
    ride_px[cam.name][at > seen] = np.nan                      # the horse out of view between passes
ride_fits = subframe.refine_phases(ride_rig, ride_px, {c: 0.0 for c in clock}, "left")
for cam, fit in ride_fits.items():
    print(f"{cam:7s} phase at frame 0 {fit.phase:+.3f} (true {clock[cam][0]:+.3f}), rate ratio {fit.rate_ratio:.6f} "
          f"(true {clock[cam][1]:.6f}), phase uncertainty {fit.uncertainty:.3f} frame")

# %%
k_ride = np.arange(n_ride)
fig, ax = plt.subplots(figsize=(6, 3))
ax.plot(k_ride, clock["middle"][0] + (clock["middle"][1] - 1) * k_ride, "k", lw=2, label="true")
ax.plot(k_ride, ride_fits["middle"].phase + (ride_fits["middle"].rate_ratio - 1) * k_ride, "C1--",
        label="measured: phase and rate")
in_view = np.isfinite(ride_px["middle"][:, 0, 0])
one_phase = float(np.mean(clock["middle"][0] + (clock["middle"][1] - 1) * k_ride[in_view]))
ax.axhline(one_phase, color="C0", ls=":", label="one phase for the ride (its average)")
for i in range(3):
    ax.axvspan(i * lap, i * lap + seen, color="0.9")
ax.set_xlabel("reference frame")
ax.set_ylabel("middle camera's phase (frames)")
ax.legend(fontsize=8)
plt.show()

# %% [markdown]
# The grey bands are the passes. One phase for the whole ride would be right only in the middle pass
# and about 0.08 frame off in the first and last: at a canter, a few percent of the saddle's acceleration
# (the table above). On the virtual laboratory's rides of four laps (`benchmarks/bench_laps.py`), a
# camera 132 ppm fast had left every pass unreliable; with the rate measured every pass is within the
# targets (the measured figures are in `benchmarks/README.md`).

# %% [markdown]
# ## Exercises
#
# 1. Raise `min_on_frames` to 5 on the default session. What happens, and why? (The virtual
#    flashlight stays on for 4 frames.)
# 2. In the synthetic video, move the flash so that it switches on during 30 % of the exposure of
#    frame 37 (value `30 + 0.3 * 220` in frame 37). Which frame does `detect_flash` return? And at 70 %?
# 3. Set `max_surround_bright=1.0` on the synthetic video. Which frame is returned now? Which test
#    still rejects the helmet's leading edge? (Print the candidates' `reason`.)
# 4. In the ride of three passes, make the right camera's clock 40 ppm slow (`1.00004`) and run
#    `refine_phases` again. Is its rate kept? At 400 ppm?
#
# <details><summary>Solutions</summary>
#
# 1. `detect_flash(sources["left"], min_on_frames=5)` raises `SyncError`: no region stays bright for 5
#    frames, and the message names the camera's file and the largest region it saw.
# 2. At 30 % the region's brightness in frame 37 is below half-way, so the flash counts as on from
#    frame 38; at 70 % frame 37 is returned.
# 3. Still frame 37: without the surroundings test the helmet's leading edge is rejected because its
#    bright area grows over its on-frames (`stays`), and the flash has the best score anyway. Each test
#    alone would be fooled by some moving object; together, and with the best score rather than the
#    earliest candidate, they found the right frame on 123 of 123 cameras of rendered sessions
#    (measured by the script `benchmarks/bench_sync.py`).
# 4. At 40 ppm the right camera drifts 0.048 frame over the 1200 frames, below the twentieth of a frame
#    `drift_is_measured` asks for: its rate stays 1 and its phase is the ride's average (0.024 frame
#    off at the ends, less than the markers tell apart). At 400 ppm (0.48 frame) the rate is kept.
#
# </details>
