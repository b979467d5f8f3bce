# %% [markdown]
# # 00 · Start here: the saddle of a horse, seen by three cameras
#
# **What you will learn**
# - what the thesis behind this suite measured, and why (G. Dogan, *Development of a 3-camera
#   vision system and the saddle motion analysis of horses via this system*, METU 2009);
# - the pipeline from three videos to comfort indicators, and which notebook teaches each step;
# - how the widgets of these notebooks stand in for the questions the thesis' MATLAB code asked;
# - how to run the whole analysis with one function call, or one command.
#
# **Before you start.** Use the kernel of the Python environment where `horsemocap` is installed
# (`pip install -r environment.txt`, README). The notebooks are stored with their outputs; their
# controls (sliders, pickers, check boxes) draw as controls once the notebook is trusted
# (`jupyter trust notebooks/*.ipynb`, once after cloning) or once their cells have run:
# **Run > Run All Cells** first, then move a control and re-run the cells below it. Before the cells
# have run, each stored control carries a small red broken-link sign: it is a picture of the control,
# not yet connected to Python, and moving it changes nothing until its cell has run.
#
# A horse's back moves the rider up and down a few centimetres several times a second. The thesis
# filmed four horses in four gaits with three cameras, followed reflective markers stuck near the
# saddle, and reconstructed the motion of the saddle point under the rider — which no camera can
# see, because the rider's leg covers it. From the saddle's vertical acceleration it computed the
# whole-body vibration indicators of ISO 2631-1 and BS 6841, and how long a rider may ride before
# reaching the exposure values of the EU directive 2002/44/EC.

# %% tags=["nbval-ignore-output"]
# The riding session of this notebook and of the next ones: a session of data_samples/ or any session
# folder (default: the bundled Horse 2 canter). After choosing another, run the cells below again. The
# choices made with this notebook's widgets are kept for the session and used by every later notebook.
from IPython.display import display
from horsemocap.widgets import ui_session
from horsemocap.workspace import open_workspace

ws = open_workspace()
display(ui_session(ws))

# %% [markdown]
# **Which chain.** The notebooks run the pipeline's automatic choices. The switch below runs every
# notebook of this session with the thesis' own chain instead (`--preset thesis` on the command
# line): stereo pairs with the left camera, each camera alone for the markers, the three pairs
# averaged, MATLAB's robust loess, the Fourier order $E/2$, the averaged omega and alpha versions
# and one weight per record. Notebook 14 puts both chains' numbers side by side and explains the
# differences. The thesis' pairwise calibration takes a minute or two the first time.

# %% tags=["nbval-ignore-output"]
from horsemocap.widgets import ui_preset

display(ui_preset(ws))

# %%
import json

import matplotlib.pyplot as plt

from horsemocap import data, plots
from horsemocap.pipeline import STEPS
from horsemocap.session import load_session

# %% [markdown]
# ## The thesis in one figure
#
# Every box below is one pure function of the `horsemocap` package, and every arrow is a notebook
# of this suite. The numbers are the thesis sections. The figure follows the thesis' order; the
# pipeline itself (last section) reads the plumb line and the static shot *before* it detects the
# markers, because the static shot gives the model the markers are identified by.

# %%
fig = plots.plot_pipeline()
plt.show()

# %% [markdown]
# ## The notebooks, in order
#
# | notebook | step | thesis |
# | --- | --- | --- |
# | 01 virtual laboratory | synthetic rides with exact truth (the thesis videos are not public) | Guchin et al. §3, 8.1 |
# | 02 synchronization | the flashlight frame in each camera | 3.5, eq. 3.11-3.14 |
# | 03 calibration | checkerboards, intrinsics, stereo pairs, a joint rig | 3.3-3.6, 8.2 |
# | 04 marker detection | threshold, labels, area, window, distance and cross-product filters; all cameras together in 3D (the default) | 4 |
# | 05 triangulation | three stereo pairs averaged vs all cameras at once | 5.1 |
# | 06 smoothing and motion frame | loess and the thesis' robust loess; x along the displacement, y along the plumb line | 5.2-5.3 |
# | 07 gravity check | g from a falling ball | 8.3 |
# | 08 registration | the rigid body against the static shot | 5.4 |
# | 09 curve fitting | polynomial x, Fourier y and z, velocity and acceleration | 5.5 |
# | 10 angular kinematics | omega and alpha, six thesis versions and least squares | 6.1-6.2 |
# | 11 saddle marker | the hidden saddle point | 6.3-6.4 |
# | 12 whole-body vibration | Wb, Wk, Wd, rms, VDV, exposure times and distances | 7, Table 8.7 |
# | 13 horses and gaits | four horses, four gaits, riders' grades | 8.5 |
# | 14 accuracy | the error of every stage, and what a better rig buys | Guchin et al. §6 |
#
# Section numbers alone are the thesis'. *Guchin et al.* is A. Guchin, G. Pereira, G. Ottado, M. Ramos
# and J. Cardelino, *Biomechanic motion capture system*: an open-source marker-based capture system
# whose virtual laboratory, three-class Otsu threshold, circularity filter and accuracy metrics these
# notebooks borrow.

# %% [markdown]
# ## The bundled riding session
#
# Every notebook works on the same session: Horse 2 at canter, rendered by the virtual laboratory
# with the thesis' own camera rig (Tables 8.1-8.4). A session is a folder with a `session.json`
# (the contract is in `docs/sessions.md`):

# %%
session_dir = ws.session_dir
doc = json.loads((session_dir / "session.json").read_text())
print(json.dumps({k: doc[k] for k in ("name", "fps", "cameras", "reference_camera", "sync", "markers")}, indent=1))
session = load_session(session_dir)
print("motion sources:", {cam: p.name for cam, p in session.motion.items()})

# %% [markdown]
# ## Widgets stand in for the MATLAB prompts
#
# The thesis' scripts stopped and asked: *enter the threshold* (`left_levelinput = 115`), *pick the
# marker labels*, *enter the period* (`period = 18`), *choose the Fourier order*, *which omega versions
# to average*. Here each question is a widget whose **default is the automatic choice**, so a notebook
# run top to bottom without a person gives exactly the numbers of the command line:
#
# | thesis prompt (Appendix A step) | widget | notebook | command line |
# | --- | --- | --- | --- |
# | frame offsets from the flashlight (1) | frame-by-frame flash checker | 02 | `--offsets` |
# | calibration views to leave out (2, 3) | a checkbox per view | 03 | `--exclude-views` |
# | gray-level threshold, every camera (4.i) | threshold slider with a live binary preview | 04 | `--threshold` |
# | first image, marker labels, area range, window size, distance tolerance (4.ii) | a tab of sliders and a label picker per camera | 04 | `--first-frame`, `--set detection.left.labels=[3,4,5]` ... |
# | smoothing (6) | method and span | 06 | `--smoothing`, `--span` |
# | period (6), marker for x-motion (7c) | dropdown and sliders | 06 | `--period`, `--x-marker` |
# | plumb still: threshold and labels, every camera (7a) | still picker | 07 | `--plumb-threshold`, `--set stills.plumb....` |
# | static shot: threshold and labels, every camera (8a) | still picker | 08 | `--static-threshold`, `--set stills.static....` |
# | fit type for x (9.i) | polynomial degree | 09 | `--x-degree` |
# | number of extremes, Fourier order (9.ii-iii) | per marker and axis: the number of extremes and the order's buttons | 09 | `--fourier-orders` |
# | omega / alfa versions (11) | six checkboxes each | 10 | `--angular thesis`, `--omega-versions`, `--alpha-versions` |
# | saddle marker in the static shot (12a; the static shot's threshold and labels as in 8a) | dropdown of the static shot's points | 11 | `--saddle-marker` |
# | weighting of the comfort indicators (10, 13) | iso / thesis toggle | 12 | `--weighting` |
#
# Every choice is a field of `horsemocap.params.AnalysisParams`. On the command line, `--set NAME=VALUE`
# gives any of them by the name it has in `analysis.json` (one camera's labels, area range, window and
# tolerance included), and `--params choices.json` gives all the choices made in the notebooks at once.
#
# The pattern is always the same: one cell shows the widget, the next cell reads `widget.value` and
# calls the same package function the pipeline calls.

# %% [markdown]
# ## The whole analysis in one call
#
# `horsemocap.pipeline.analyze(session, out_dir)` runs every step with its automatic choices and
# writes the result files; from a terminal, `horsemocap demo` does the same on this session.
# The steps, in order:

# %%
print(" -> ".join(STEPS))

# %% [markdown]
# ## Exercises
#
# 1. Open `data_samples/horse2_canter/session.json` and find where the three videos and the calibration
#    views are. Which field would you change to give the frame offsets by hand?
# 2. Run `horsemocap analyze --help` in a terminal. Which of its options correspond to the widgets above?
# 3. In the figure, which steps need the static shot, and which the plumb line?
#
# <details><summary>Solutions</summary>
#
# 1. `motion` and `calibration.images`; `sync` becomes `{"offsets": {"left": ..., "middle": ..., "right": ...}}`.
# 2. The last column of the table above: `--threshold` (threshold slider), `--period` and `--x-marker`
#    (motion frame), `--x-degree` and `--fourier-orders` (the order buttons), `--angular` (how omega/alfa are computed: `thesis` averages the versions ticked in
#    the six checkboxes), `--omega-versions` and `--alpha-versions` (those checkboxes, e.g. `1,2,4`),
#    `--weighting` (iso/thesis toggle), `--offsets`, `--preset thesis` (every
#    thesis choice at once).
# 3. The static shot: detection (the default identifies the markers by its rigid shape), registration
#    (the rigid model) and the saddle marker. The plumb line: the motion
#    frame (gravity gives y-motion).
#
# </details>
