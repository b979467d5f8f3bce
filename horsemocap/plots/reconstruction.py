"""Figures of thesis 5.1 and 8.4.1: marker positions in the camera frame (Figure 8.9 a),
reprojection residuals, and the thesis-vs-joint triangulation comparison."""
from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

__all__ = ["plot_camera_positions", "plot_triangulation_residuals", "plot_triangulation_modes",
           "plot_stereo_geometry", "epipolar_curve", "closest_points_of_rays"]

AXIS_NAMES = ("X", "Y", "Z")


def plot_camera_positions(points, t=None, truth=None, title: str = "", fig=None):
    """Thesis Figure 8.9 (a): X, Y, Z of every marker in the left camera frame (``CM_L``).

    Parameters
    ----------
    points : ndarray (n, m, 3), metres.
    t : ndarray (n,), optional
        Abscissa (default: frame number, as the thesis).
    truth : ndarray (n, m, 3), optional
        Drawn as thin black lines.
    """
    p = np.asarray(points, float)
    x = np.arange(p.shape[0]) if t is None else np.asarray(t)
    fig = fig or plt.figure(figsize=(10, 3.4))
    axes = fig.subplots(1, 3)
    for a, ax in enumerate(axes):
        for m in range(p.shape[1]):
            ax.plot(x, p[:, m, a], ".-", ms=3, lw=0.8, label=f"marker {m + 1}")
            if truth is not None:
                ax.plot(x, np.asarray(truth)[:, m, a], "k-", lw=0.6, alpha=0.7,
                        label="truth" if m == 0 else None)
        ax.set_title(f"{AXIS_NAMES[a]} (left camera)")
        ax.set_xlabel("frame" if t is None else "t (s)")
        ax.set_ylabel("m")
        ax.grid(True, alpha=0.3)
    axes[0].legend(fontsize=7)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return fig


def plot_triangulation_residuals(triangulation, ax=None):
    """Reprojection residual (px) per camera and frame, all markers (``Triangulation.residual_px``)."""
    if ax is None:
        _, ax = plt.subplots(figsize=(8, 3))
    for cam, r in triangulation.residual_px.items():
        r = np.asarray(r, float)
        for m in range(r.shape[1]):
            ax.plot(r[:, m], ".", ms=4, alpha=0.8, label=cam if m == 0 else None)
    ax.set_xlabel("frame")
    ax.set_ylabel("reprojection error (px)")
    ax.set_title(f"reprojection residuals, {triangulation.mode} mode")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    return ax


def plot_triangulation_modes(errors: dict, ax=None, unit: str = "mm", target: float | None = None):
    """Bar chart of the RMSE per motion axis for each mode.

    Parameters
    ----------
    errors : dict of label -> (3,) RMSE along x-, y-, z-motion, in ``unit``.
    target : float, optional
        A target RMSE (same unit), drawn as a dashed line.
    """
    if ax is None:
        _, ax = plt.subplots(figsize=(6, 3.2))
    labels = list(errors)
    width = 0.8 / max(len(labels), 1)
    xs = np.arange(3)
    for i, lab in enumerate(labels):
        vals = np.asarray(errors[lab], float)
        bars = ax.bar(xs + (i - (len(labels) - 1) / 2) * width, vals, width, label=lab)
        for b, v in zip(bars, vals):
            ax.annotate(f"{v:.1f}", (b.get_x() + b.get_width() / 2, b.get_height()), ha="center",
                        va="bottom", fontsize=7)
    ax.set_xticks(xs, ["x-motion", "y-motion (gravity)", "z-motion (depth)"])
    if target is not None:
        ax.axhline(target, color="k", ls="--", lw=0.8, label=f"target {target:g} {unit}")
    ax.set_ylabel(f"RMSE ({unit})")
    ax.grid(True, axis="y", alpha=0.3)
    ax.legend(fontsize=8)
    return ax


def closest_points_of_rays(origin_a, dir_a, origin_b, dir_b):
    """The two points, one on each ray, that are closest to each other (their midpoint is Bouguet's point).

    Returns
    -------
    (point_a, point_b, depth_a, depth_b): the points (3,) and their distances along each unit direction.

    Examples
    --------
    >>> import numpy as np
    >>> pa, pb, sa, sb = closest_points_of_rays([0, 0, 0], [0, 0, 1], [1, 0.1, 0], [-0.6, 0, 0.8])
    >>> np.round(pa, 3) + 0.0, np.round(pb, 3) + 0.0              # + 0.0: no negative zero
    (array([0.   , 0.   , 1.333]), array([0.   , 0.1  , 1.333]))
    """
    oa, da, ob, db = (np.asarray(v, float) for v in (origin_a, dir_a, origin_b, dir_b))
    w = oa - ob
    a, b, c, d, e = da @ da, da @ db, db @ db, da @ w, db @ w
    den = a * c - b * b
    if den <= 1e-15 * a * c:
        raise ValueError("closest_points_of_rays: the rays are parallel")
    sa, sb = (b * e - c * d) / den, (a * e - b * d) / den
    return oa + sa * da, ob + sb * db, sa, sb


def epipolar_curve(cam_a, cam_b, px_a, depths=None) -> np.ndarray:
    """Where camera ``cam_b`` sees the ray of camera ``cam_a`` through pixel ``px_a``.

    Every point of the ray projects onto one line of ``cam_b``'s undistorted
    image, the epipolar line; in the distorted pixels of the camera it is
    slightly curved. ``depths`` (m along the ray, default 0.2 to 50 m) are
    the ray's points projected; points behind ``cam_b`` are NaN.

    Returns
    -------
    ndarray (len(depths), 2) pixels of ``cam_b``.

    Examples
    --------
    >>> import numpy as np
    >>> from horsemocap.camera import Camera
    >>> K = [[800.0, 0.0, 320.0], [0.0, 800.0, 240.0], [0.0, 0.0, 1.0]]
    >>> left = Camera("left", (640, 480), K)
    >>> right = Camera("right", (640, 480), K, translation=[-0.5, 0.0, 0.0])
    >>> np.round(epipolar_curve(left, right, np.array([320.0, 300.0]), [1.0, 2.0, 4.0]), 1)
    array([[-81.1, 300. ],
           [119.4, 300. ],
           [219.7, 300. ]])
    """
    depths = np.geomspace(0.2, 50.0, 200) if depths is None else np.asarray(depths, float)
    origin, direction = cam_a.rays(np.asarray(px_a, float))
    points = origin + depths[:, None] * direction
    return cam_b.project(points)


def plot_stereo_geometry(cam_a, cam_b, px_a, px_b, image_b=None, fig=None):
    """Two cameras, one marker: the rays that (almost) meet, and the epipolar line (thesis 3.6, 5.1).

    Left: top view (x, z of the world frame) of the two optical centres, their
    optical axes, the baseline, and the ray of each camera through the
    marker's pixel, to the two closest points of the rays; their midpoint is
    the triangulated marker (Bouguet's ``stereo_triangulation``) and their
    gap is printed. Right: camera ``cam_b``'s image with the marker's pixel
    ``px_b`` and the epipolar line of ``px_a``: where ``cam_b`` sees the
    ray of ``cam_a``. A correct match lies on it (up to noise and
    calibration error), which is why a second camera needs to search one line only.

    Parameters
    ----------
    cam_a, cam_b : :class:`horsemocap.camera.Camera` of one rig
    px_a, px_b : (2,) the marker's pixel in each camera
    image_b : cam_b's frame (drawn if given)

    Returns
    -------
    matplotlib Figure
    """
    px_a, px_b = np.asarray(px_a, float), np.asarray(px_b, float)
    oa, da = cam_a.rays(px_a)
    ob, db = cam_b.rays(px_b)
    pa, pb, sa, sb = closest_points_of_rays(oa, da, ob, db)
    marker = (pa + pb) / 2
    fig = fig or plt.figure(figsize=(12, 4.8))
    ax, ax_img = fig.subplots(1, 2, gridspec_kw={"width_ratios": [1, 1.25]})
    # top view in the frame of cam_a's ray: depth along it, sideways offset across it (in mm: stretched)
    across = np.cross([0.0, 1.0, 0.0], da)
    across /= np.linalg.norm(across)

    def top(points):
        q = np.atleast_2d(points) - oa
        return 1000 * q @ across, q @ da

    reach = 1.15 * max(sa, sb)
    for cam, origin, direction, colour in ((cam_a, oa, da, "tab:blue"), (cam_b, ob, db, "tab:red")):
        ax.plot(*top(origin), "^", color=colour, ms=10, label=f"{cam.name} camera")
        ax.plot(*top(np.vstack([origin, origin + reach * direction])), "-", color=colour, lw=1.3,
                label=f"ray through the marker's pixel in {cam.name}")
    ax.plot(*top(np.vstack([oa, ob])), "k-", lw=2.5, label=f"baseline {1000 * np.linalg.norm(ob - oa):.0f} mm")
    ax.plot(*top(marker), "o", mfc="none", mec="k", ms=12,
            label=f"marker: midpoint of the closest points,\nrays {1000 * np.linalg.norm(pa - pb):.1f} mm apart")
    angle = np.degrees(np.arccos(np.clip(da @ db, -1, 1)))
    ax.set_xlabel(f"sideways, across the {cam_a.name} camera's ray (mm)")
    ax.set_ylabel(f"along the {cam_a.name} camera's ray (m)")
    ax.set_title(f"top view, sideways stretched: the rays meet at {angle:.1f}°", fontsize=10)
    ax.legend(fontsize=7, loc="upper right")

    w, h = cam_b.size
    if image_b is not None:
        img = np.asarray(image_b)
        ax_img.imshow(img, cmap=None if img.ndim == 3 else "gray")
    curve = epipolar_curve(cam_a, cam_b, px_a)
    inside = np.all(np.isfinite(curve), axis=1)
    ax_img.plot(*curve[inside].T, "-", color="cyan", lw=1.5, label=f"epipolar line of {cam_a.name}'s pixel")
    ax_img.plot(*px_b, "o", mfc="none", mec="red", ms=14, mew=2, label=f"the marker in {cam_b.name}")
    gap = np.min(np.linalg.norm(epipolar_curve(cam_a, cam_b, px_a, np.linspace(0.5 * sa, 1.5 * sa, 2001))
                                - px_b, axis=1))
    epipole = cam_b.project(cam_a.center)
    if np.all(np.isfinite(epipole)) and -w < epipole[0] < 2 * w and -h < epipole[1] < 2 * h:
        ax_img.plot(*epipole, "x", color="cyan", ms=9, label=f"epipole: where {cam_b.name} sees {cam_a.name}")
    ax_img.set_xlim(-0.5, w - 0.5)
    ax_img.set_ylim(h - 0.5, -0.5)
    ax_img.set_title(f"{cam_b.name} camera: the marker is {gap:.2f} px from the epipolar line", fontsize=10)
    ax_img.legend(fontsize=7, loc="lower left")
    fig.tight_layout()
    return fig
