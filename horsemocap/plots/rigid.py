"""Figures of registration, angular kinematics and the saddle marker
(thesis Figures 8.12, 8.14-8.20, 8.22-8.24)."""
from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

__all__ = ["plot_body_frame", "plot_registration", "plot_marker_distances", "plot_angular_versions",
           "plot_angular_average", "plot_singularity", "plot_saddle_position",
           "plot_saddle_kinematics"]

_XYZ = ("x", "y", "z")
_LABELS = ("1,ver1", "2,ver1", "1,ver2", "2,ver2", "1,ver3", "2,ver3")


def plot_registration(measured, registered, frame: int, ax=None):
    """Figure 8.12: the markers of one frame before and after registration
    (motion frame, mm), with the triangle edges and their lengths."""
    if ax is None:
        fig = plt.figure(figsize=(6, 5))
        ax = fig.add_subplot(projection="3d")
    fig = ax.figure
    for pts, style, name in ((measured[frame], "o--", "measured"),
                             (registered[frame], "s-", "registered")):
        loop = np.vstack([pts, pts[:1]]) * 1000
        ax.plot(loop[:, 0], loop[:, 2], loop[:, 1], style, label=name)
        for i, p in enumerate(pts * 1000):
            if name == "registered":
                ax.text(p[0], p[2], p[1], f" {i + 1}", fontsize=8)
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("z (mm)")
    ax.set_zlabel("y, down (mm)")
    ax.invert_zaxis()
    ax.set_title(f"frame {frame + 1}")
    ax.legend(fontsize=8)
    return fig


def plot_marker_distances(t, measured, registered, model=None, ax=None):
    """Inter-marker distances over time before and after registration: after
    it they equal the static shot's (the rigid-body constraint)."""
    if ax is None:
        fig, ax = plt.subplots(figsize=(7, 3.2))
    fig = ax.figure
    pairs = ((0, 1), (1, 2), (0, 2))
    for c, (i, j) in enumerate(pairs):
        d0 = np.linalg.norm(measured[:, i] - measured[:, j], axis=-1) * 1000
        d1 = np.linalg.norm(registered[:, i] - registered[:, j], axis=-1) * 1000
        ax.plot(t, d0, f"C{c}.:", label=f"|r{i + 1}{j + 1}| measured")
        ax.plot(t, d1, f"C{c}-", label=f"|r{i + 1}{j + 1}| registered")
    ax.set_xlabel("t (s)")
    ax.set_ylabel("distance (mm)")
    ax.legend(fontsize=7, ncol=3)
    return fig


def plot_angular_versions(t, raw, smoothed, component: int, name="omega", unit="rad/s", truth=None):
    """Figures 8.14-8.16: the six versions of one component, original and smoothed."""
    fig, axes = plt.subplots(2, 3, figsize=(10, 5), sharex=True, sharey=True)
    for i, ax in enumerate(axes.ravel()):
        ax.plot(t, raw[i, :, component], "0.6", lw=0.8, marker=".", ms=3, label="original")
        ax.plot(t, smoothed[i, :, component], "C0-", label="smoothed")
        if truth is not None:
            ax.plot(t, truth[:, component], "k--", lw=0.8, label="truth")
        ax.set_title(f"{name}{_LABELS[i]}", fontsize=9)
    lim = _robust_limits(np.concatenate([smoothed[..., component].ravel()]
                                        + ([] if truth is None else [truth[:, component]])))
    axes[0, 0].set_ylim(*lim)
    axes[0, 0].legend(fontsize=7)
    for ax in axes[1]:
        ax.set_xlabel("t (s)")
    fig.suptitle(f"{name} about the {_XYZ[component]} axis ({unit}); y range clipped to the bulk of the data")
    fig.tight_layout()
    return fig


def _robust_limits(v):
    v = v[np.isfinite(v)]
    if v.size == 0:
        return -1, 1
    lo, hi = np.percentile(v, [2, 98])
    pad = 0.15 * (hi - lo + 1e-12)
    return lo - pad, hi + pad


def plot_angular_average(t, smoothed, use, average, name="omega", unit="rad/s", truth=None, lstsq=None):
    """Figures 8.17-8.20: every smoothed version (thin; unused dotted), their
    chosen average (bold), and optionally the least-squares solution and the truth."""
    fig, axes = plt.subplots(3, 1, figsize=(8, 7), sharex=True)
    use = np.asarray(use, bool)
    for c, ax in enumerate(axes):
        for i in range(smoothed.shape[0]):
            ax.plot(t, smoothed[i, :, c], lw=0.8, ls="-" if use[i] else ":", label=f"{name}{_LABELS[i]}")
        ax.plot(t, average[:, c], "k-", lw=2.2, label="average of chosen")
        if lstsq is not None:
            ax.plot(t, lstsq[:, c], "m-", lw=1.6, label="least squares")
        if truth is not None:
            ax.plot(t, truth[:, c], "g--", lw=1.6, label="truth")
        ax.set_ylabel(f"{name}_{_XYZ[c]} ({unit})")
        vals = [average[:, c]] + ([] if truth is None else [truth[:, c]]) + ([] if lstsq is None else [lstsq[:, c]])
        ax.set_ylim(*_robust_limits(np.concatenate(vals)))
    axes[0].legend(fontsize=6, ncol=5)
    axes[-1].set_xlabel("t (s)")
    fig.tight_layout()
    return fig


def plot_singularity(t, angle_deg, tolerance_deg: float = 15.0, ax=None):
    """Angle between omega and the markers' plane normal (eq. 6.33-6.35); the
    band around 90 degrees is where eq. 6.3/6.4 and 6.38/6.39 are unreliable."""
    if ax is None:
        fig, ax = plt.subplots(figsize=(7, 3))
    fig = ax.figure
    ax.axhspan(90 - tolerance_deg, 90 + tolerance_deg, color="C3", alpha=0.15,
               label=f"unreliable: 90 ± {tolerance_deg:g}°")
    ax.axhline(90, color="C3", lw=0.8)
    ax.plot(t, angle_deg, "k.-", label="angle(omega, n)")
    ax.set_ylim(0, 180)
    ax.set_xlabel("t (s)")
    ax.set_ylabel("degrees")
    ax.legend(fontsize=8)
    return fig


def plot_saddle_position(t, saddle, markers=None, truth=None):
    """Figure 8.22: the saddle marker's position (a) alone and (b) with the
    visible markers, motion frame."""
    fig, axes = plt.subplots(3, 1, figsize=(7, 6.5), sharex=True)
    for c, ax in enumerate(axes):
        ax.plot(t, saddle[:, c], "k-", lw=2, label="saddle S")
        if markers is not None:
            for m in range(markers.shape[1]):
                ax.plot(t, markers[:, m, c], lw=0.9, label=f"marker {m + 1}")
        if truth is not None:
            ax.plot(t, truth[:, c], "g--", lw=1.2, label="S truth")
        ax.set_ylabel(f"P_{_XYZ[c]} (m)")
    if 1 < len(axes):
        axes[1].invert_yaxis()
        axes[1].set_ylabel("P_y, down (m)")
    axes[0].legend(fontsize=7, ncol=3)
    axes[-1].set_xlabel("t (s)")
    fig.tight_layout()
    return fig


def plot_saddle_kinematics(t, velocity_versions, acceleration_versions, velocity=None,
                           acceleration=None, truth_vel=None, truth_acc=None, extra=None):
    """Figures 8.23-8.24: saddle velocity and acceleration from markers 1, 2, 3
    (eq. 6.54, 6.55) and their mean; optionally other estimates and the truth.

    ``extra``: dict label -> (vel (n, 3), acc (n, 3)). The y range follows the
    truth and the extra estimates when given (curves beyond it are clipped).
    """
    fig, axes = plt.subplots(3, 2, figsize=(10, 7), sharex=True)
    for c in range(3):
        for col, vers, mean, tru in ((0, velocity_versions, velocity, truth_vel),
                                     (1, acceleration_versions, acceleration, truth_acc)):
            ax = axes[c, col]
            for i in range(vers.shape[0]):
                ax.plot(t, vers[i, :, c], lw=0.8, label=f"from marker {i + 1}")
            if mean is not None:
                ax.plot(t, mean[:, c], "k-", lw=2, label="mean (thesis)")
            if extra:
                for j, (lab, (v, a)) in enumerate(extra.items()):
                    ax.plot(t, (v if col == 0 else a)[:, c], color=f"C{4 + j}", lw=1.6, label=lab)
            if tru is not None:
                ax.plot(t, tru[:, c], "g--", lw=1.4, label="truth")
            ref = ([] if tru is None else [tru[:, c]]) + [(v if col == 0 else a)[:, c] for v, a in (extra or {}).values()]
            vals = ref if ref else [vers[..., c].ravel()]
            lo, hi = _robust_limits(np.concatenate(vals))
            pad = 0.5 * (hi - lo)
            ax.set_ylim(lo - pad, hi + pad)
        axes[c, 0].set_ylabel(f"V_{_XYZ[c]} (m/s)")
        axes[c, 1].set_ylabel(f"A_{_XYZ[c]} (m/s²)")
    axes[0, 1].legend(fontsize=6)
    axes[-1, 0].set_xlabel("t (s)")
    axes[-1, 1].set_xlabel("t (s)")
    fig.tight_layout()
    return fig


def plot_body_frame(markers, saddle, R_MB, origin, ax=None, title: str = "", axis_length: float = 0.15):
    """Figures 6.1/6.2: the motion frame, the body frame of three markers and the saddle marker.

    Drawn in the motion frame's x-y plane (x forward, y down, so y points
    down the page): the motion frame's axes (in a corner: its origin ``O_M``
    is metres away, the coordinates on the axes are measured from it), the
    markers 1-3, the body frame's origin ``O_B`` (marker 1, at ``r_MB``) with
    its axes ``u1, u2`` (eq. 6.41-6.44; ``u3`` points out of or into the
    page) and ``r_BS`` from ``O_B`` to the saddle marker ``S`` (eq. 6.40,
    6.48).

    Parameters
    ----------
    markers : (3, 3)
        Markers 1-3 in the motion frame (m).
    saddle : (3,)
        The saddle marker in the motion frame (m).
    R_MB : (3, 3)
        Columns ``u1 | u2 | u3`` (:func:`horsemocap.rigid.body_frame`).
    origin : (3,)
        ``r_MB``, the body frame's origin in the motion frame.
    """
    if ax is None:
        _, ax = plt.subplots(figsize=(6, 4))
    m, s, o = np.asarray(markers, float), np.asarray(saddle, float), np.asarray(origin, float)
    ax.plot(m[:, 0], m[:, 1], "o", color="tab:blue", ms=7, label="markers 1-3")
    for j, pt in enumerate(m):
        ax.annotate(f"{j + 1}", pt[:2], textcoords="offset points", xytext=(5, -10), fontsize=8)
    ax.plot(*s[:2], "s", color="tab:red", ms=7, label="saddle marker S")
    for vec, name, colour in ((R_MB[:, 0], "u1", "tab:green"), (R_MB[:, 1], "u2", "tab:purple")):
        ax.annotate("", o[:2] + axis_length * vec[:2], o[:2], arrowprops=dict(arrowstyle="->", color=colour, lw=1.8))
        ax.annotate(name, o[:2] + 1.1 * axis_length * vec[:2], color=colour, fontsize=9)
    ax.annotate("", s[:2], o[:2], arrowprops=dict(arrowstyle="->", color="tab:red", lw=1, ls="--"))
    ax.annotate("r_BS", (o[:2] + s[:2]) / 2, color="tab:red", fontsize=8)
    ref = np.array([min(m[:, 0].min(), s[0]) - 0.25, min(m[:, 1].min(), s[1]) - 0.1])   # the axes, in a corner
    for vec, name in (((axis_length, 0), "x"), ((0, axis_length), "y")):
        ax.annotate("", ref + vec, ref, arrowprops=dict(arrowstyle="->", color="k", lw=1.2))
        ax.annotate(name, ref + 1.15 * np.array(vec), fontsize=9)
    ax.annotate("motion frame axes", ref, textcoords="offset points", xytext=(-10, -12), fontsize=7)
    ax.set_aspect("equal")
    ax.invert_yaxis()                       # y down, as the motion frame
    ax.set_xlabel("x-motion (m)")
    ax.set_ylabel("y-motion, down (m)")
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=7, loc="lower right")
    return ax
