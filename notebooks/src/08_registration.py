# %% [markdown]
# # 08 · Registration: making the three markers a rigid body again
#
# **What you will learn**
# - why the measured markers are not rigid, and how a *static shot* of the standing horse gives a
#   rigid model of them (thesis section 5.4, Appendix A step 8);
# - which static-shot marker is which motion marker, found from the inter-marker distances
#   (the thesis picked the labels by hand);
# - the closed-form quaternion solution of Horn (1987) used by Besl and McKay (1992), eq. 5.14-5.21;
# - that after registration the inter-marker distances equal the model's in every frame (Figure 8.12).
#
# The model points $\mathbf{x}^m_m$ (static shot) and the measured points $\mathbf{x}_m$ (one frame)
# are related by the rotation $\mathbf{R}(\mathbf{q}_R)$ and translation $\mathbf{q}_t$ that minimise
#
# $$f(\mathbf{q}) = \frac{1}{M}\sum_{m=1}^{M}\left\|\mathbf{x}^m_m - \mathbf{R}(\mathbf{q}_R)\,\mathbf{x}_m - \mathbf{q}_t\right\|^2 \qquad (5.14)$$
#
# with the unit quaternion $\mathbf{q}_R = [q_0\,q_1\,q_2\,q_3]^T$ (5.15) giving $\mathbf{R}$ by eq. 5.16.
# The registered (rigid) markers are the model moved back into the frame's pose,
#
# $$\mathbf{x}^r_m = \mathbf{R}^{-1}\left(\mathbf{x}^m_m - \mathbf{q}_t\right) \qquad (5.20)$$
#
# **Closed form.** With centred sets, the cross-covariance
# $\mathbf{S} = \sum_m (\mathbf{x}^m_m - \boldsymbol\mu^m)(\mathbf{x}_m - \boldsymbol\mu)^T$ fills a symmetric
# $4\times4$ matrix $\mathbf{Q}(\mathbf{S})$ whose eigenvector of the largest eigenvalue is the optimal
# $\mathbf{q}_R$. `horsemocap.rigid.register` returns the *pose* of the model in each frame,
# `registered = rotation @ model + translation`, so the thesis' $\mathbf{R} = $ `rotation.T`.

# %%
import warnings

import matplotlib.pyplot as plt
import numpy as np

from horsemocap import plots, rigid

# %% [markdown]
# ## The data
#
# The default session is Horse 2 at canter from the virtual laboratory (38 frames, two strides).
# **Until the pipeline (detection → triangulation → smoothing → motion frame) runs end to end**,
# this cell stands in for it: the true marker centres plus Gaussian noise along the left camera's
# axes (1.5 mm across, 5 mm in depth), smoothed with the thesis' `rloess` (span 0.1), expressed in
# the true motion frame; the static shot gets the same noise and is shuffled (detection order is
# arbitrary). The lead will replace this one cell with the pipeline's output.

# %%
from horsemocap import data, smoothing, virtuallab

truth = virtuallab.load_truth(data.default_session_dir())
to_motion = lambda x: np.asarray(x) @ truth.motion_axes.T       # rows of motion_axes: x, y, z (left camera frame)
rng = np.random.default_rng(0)
sigma = np.array([0.0015, 0.0015, 0.005])                        # m, along the left camera's x, y, depth
t = truth.time_s
markers = smoothing.smooth_positions(to_motion(truth.marker_pos + rng.normal(size=truth.marker_pos.shape) * sigma), 0.1)
static = to_motion(truth.static_pos + rng.normal(size=truth.static_pos.shape) * sigma)[rng.permutation(4)]
print(f"{len(t)} frames at {truth.fps:.0f} fps; markers {markers.shape}; static shot {static.shape}")

# %% [markdown]
# ## Which static marker is which?
#
# The static shot holds four markers (the three skin markers and the saddle marker) in no particular
# order. Every assignment of three of them to the motion markers is scored by how well its three
# distances agree with the motion markers' median distances. The skin markers sit in a row along the
# back, so two assignments can differ by only a few millimetres; among the near-ties the one needing
# the smallest rotation wins (the horse heads along $+x$ in both the static shot and the ride).

# %%
order, saddle_index = rigid.match_static_markers(static, markers)
print("static index of motion markers 1, 2, 3:", order.tolist(), "; saddle marker:", saddle_index)
d_motion = np.nanmedian(rigid.pairwise_distances(markers), axis=0)
d_model = rigid.pairwise_distances(static[order])
for i, j in ((0, 1), (1, 2), (0, 2)):
    print(f"|r{i + 1}{j + 1}|  motion (median) {1000 * d_motion[i, j]:.1f} mm   static {1000 * d_model[i, j]:.1f} mm")

# %% [markdown]
# ## Registering every frame

# %%
model = static[order]
reg = rigid.register(markers, model)
d_before = rigid.pairwise_distances(markers)
d_after = rigid.pairwise_distances(reg.registered)
iu = np.triu_indices(3, 1)
print(f"distance deviation from the model, before: max {1000 * np.abs(d_before - d_model)[:, iu[0], iu[1]].max():.2f} mm")
print(f"distance deviation from the model, after:  max {1000 * np.abs(d_after - d_model)[:, iu[0], iu[1]].max():.2e} mm")
print(f"residual |e_m| (Figure 5.3): median {1000 * np.median(reg.residual):.2f} mm, max {1000 * reg.residual.max():.2f} mm")
print("frames not registered:", int(np.sum(reg.reason != "")))

# %% [markdown]
# Figure 8.12 of the thesis shows frame 27 before and after the rigid-body correction:

# %%
fig = plots.plot_registration(markers, reg.registered, frame=26)
plt.show()

# %%
fig = plots.plot_marker_distances(t, markers, reg.registered)
plt.show()

# %% [markdown]
# ## Does registration bring us closer to the truth?
#
# The registered markers are rigid; are they also more accurate? Against the virtual laboratory's
# truth (the same noise realisation):

# %%
true_m = to_motion(truth.marker_pos)
err_s = np.sqrt(np.mean((markers - true_m) ** 2, axis=(0, 1))) * 1000
err_r = np.sqrt(np.mean((reg.registered - true_m) ** 2, axis=(0, 1))) * 1000
print("RMSE per axis x/y/z (mm), smoothed:  " + "  ".join(f"{e:.2f}" for e in err_s))
print("RMSE per axis x/y/z (mm), registered: " + "  ".join(f"{e:.2f}" for e in err_r))

# %% [markdown]
# The static shot has its own noise: every registered frame inherits the model's shape error, a
# constant per marker, while the frame-to-frame noise is averaged over the three markers.
#
# The quaternion and the thesis' form: $\mathbf{R}_{thesis} = $ `rotation.T`,
# $\mathbf{q}_t = -\mathbf{R}_{thesis}\,$`translation`, and eq. 5.20 gives back the registered points.

# %%
k = 26
R_th = reg.rotation[k].T
q_t = -R_th @ reg.translation[k]
x_r = (np.linalg.inv(R_th) @ (model - q_t).T).T                   # eq. 5.20 / 5.21
print(f"eq. 5.20 vs registered, frame 27: max difference {np.abs(x_r - reg.registered[k]).max():.1e} m")
print(f"det R = {np.linalg.det(R_th):.6f};  rotation angle {np.degrees(np.arccos((np.trace(R_th) - 1) / 2)):.2f} deg")

# %% [markdown]
# ## Exercises
#
# 1. Rerun the registration with the static shot *not* shuffled and check that the assignment does
#    not change. Then swap markers 1 and 3 of the static shot: what does `match_static_markers` do, and why
#    are the distances alone not enough here?
# 2. Set the noise to zero: how large is the registration residual, and why?
# 3. Add a 2 cm outlier to marker 2 in frame 10 (before registration). How does the residual of that
#    frame change, and how far does the error spread to markers 1 and 3?
#
# <details><summary>Solutions</summary>
#
# 1. The order is found from distances and orientation, not from the input order, so shuffling changes
#    only `order`. Markers 1 and 3 are 0.25 m from marker 2 within 3.4 mm of each other, so a swap costs
#    little in distance; the near-tie is broken by the rotation the registration would need (a swap needs a
#    half turn).
# 2. `static = to_motion(truth.static_pos)` and `markers = to_motion(truth.marker_pos)`: the residual is at
#    the level of rounding (1e-16 m); the truth is rigid and the quaternion solution is exact.
# 3. Least squares spreads the error: the frame's residual grows to about 2/3 of 2 cm at marker 2 and the
#    other two markers move by a few mm (rotation and translation absorb part of the outlier).
#    Smoothing with `rloess` before registration is what removes such outliers in the thesis' chain.
#
# </details>
