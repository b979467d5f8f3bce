"""Plots of the flash synchronisation (thesis 3.5, Figure 3.9)."""
from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

__all__ = ["plot_flash_signal", "plot_flash_frames"]


def plot_flash_signal(detections: dict, ax=None):
    """Brightness of each camera's flash region against its own frame index.

    Parameters
    ----------
    detections : dict[str, FlashDetection]
        From :func:`horsemocap.sync.detect_flash`, per camera.
    """
    if ax is None:
        _, ax = plt.subplots(figsize=(8, 3.2))
    for cam, det in detections.items():
        idx = det.start + np.arange(det.signal.size)
        line, = ax.plot(idx, det.signal, ".-", label=f"{cam}: flash at frame {det.frame}")
        ax.axvline(det.frame, color=line.get_color(), ls=":", lw=1)
        ax.axhline(0.5 * (det.off_level + det.on_level), color=line.get_color(), ls="--", lw=0.6)
    ax.set_xlabel("frame (each camera's own numbering)")
    ax.set_ylabel("mean gray level of the flash region")
    ax.set_title("Flash switching on (dashed: half-way between off and on)")
    ax.legend(fontsize=8)
    return ax


def plot_flash_frames(frames: dict, offsets: dict, detections: dict | None = None, shifts=(-1, 0, 1),
                      crop: int = 60):
    """Frames around the flash in each camera (rows) at ``offset + shift`` (columns), as Figure 3.9.

    ``frames[cam]`` is a FrameSource or an array of frames; with ``detections``
    the view is cropped around the flash region.
    """
    cams = list(offsets)
    fig, axes = plt.subplots(len(cams), len(shifts), figsize=(2.4 * len(shifts), 2.0 * len(cams)), squeeze=False)
    for r, cam in enumerate(cams):
        for c, s in enumerate(shifts):
            k = offsets[cam] + s
            src = frames[cam]
            img = src.frame(k) if hasattr(src, "frame") else np.asarray(src)[k]
            ax = axes[r, c]
            if detections is not None and cam in detections:
                ys, xs = np.nonzero(detections[cam].region)
                cy, cx = int(ys.mean()), int(xs.mean())
                y0, x0 = max(cy - crop, 0), max(cx - crop, 0)
                img = img[y0:cy + crop, x0:cx + crop]
            ax.imshow(img, cmap="gray" if img.ndim == 2 else None, vmin=0, vmax=255)
            ax.set_xticks([])
            ax.set_yticks([])
            ax.set_title(f"{cam} frame {k} ({s:+d})", fontsize=8)
    fig.tight_layout()
    return fig
