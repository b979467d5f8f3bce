"""Measurements that characterise the rendered data against its truth.

These are not detectors (``horsemocap.detection`` is): they use the true
positions to say how good the images are (an *oracle* centroid in a window
at the true centre) and how hard (what a naive threshold + area filter,
thesis 4.5.1-4.5.3 without window and distance filters, keeps).
"""
from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np

from ..sources import FrameSource
from .truth import load_truth


def oracle_centroids(gray: np.ndarray, px_true: np.ndarray, half: int = 6, rel_floor: float = 0.25) -> np.ndarray:
    """Intensity-weighted centroids in windows centred at the true positions.

    The window's border median is subtracted as background, values below
    ``rel_floor`` of the window's peak are dropped (noise). NaN where the
    window leaves the image or the position is NaN.

    Parameters
    ----------
    gray : (h, w) image
    px_true : (m, 2) true centres (u, v)
    """
    h, w = gray.shape
    out = np.full((len(px_true), 2), np.nan)
    for j, (u, v) in enumerate(np.asarray(px_true, float)):
        if not np.isfinite(u + v):
            continue
        x0, y0 = int(round(u)) - half, int(round(v)) - half
        n = 2 * half + 1
        if x0 < 0 or y0 < 0 or x0 + n > w or y0 + n > h:
            continue
        win = gray[y0:y0 + n, x0:x0 + n].astype(float)
        bg = np.median(np.concatenate([win[0], win[-1], win[:, 0], win[:, -1]]))
        d = np.clip(win - bg, 0, None)
        if d.max() <= 0:
            continue
        d[d < rel_floor * d.max()] = 0
        yy, xx = np.mgrid[y0:y0 + n, x0:x0 + n]
        out[j] = [(d * xx).sum() / d.sum(), (d * yy).sum() / d.sum()]
    return out


def naive_regions(gray: np.ndarray, threshold: float = 115, area_range=(15, 240)):
    """Regions a naive detector keeps: gray > threshold, 8-connected, area in range.

    Returns ``(centroids (n, 2), areas (n,))`` (thesis 4.5: threshold 115,
    area 15-240 px in section 8.4.1).
    """
    n, lab, st, cen = cv2.connectedComponentsWithStats((gray > threshold).astype(np.uint8), connectivity=8)
    keep = [i for i in range(1, n) if area_range[0] <= st[i, 4] <= area_range[1]]
    return cen[keep].reshape(-1, 2), st[keep, 4]


def session_centroid_errors(session_dir, truth=None, half: int = 6) -> dict:
    """Oracle centroid errors (px) of every visible skin marker, per camera."""
    session_dir = Path(session_dir)
    truth = truth or load_truth(session_dir)
    meta = json.loads((session_dir / "session.json").read_text())
    out = {}
    for cam in truth.cameras:
        frames = FrameSource(session_dir / meta["motion"][cam]).read(0, None, False)
        errs = []
        for k in range(min(len(frames), len(truth.marker_px[cam]))):
            vis = truth.marker_visible[cam][k, :3]
            if not vis.any():
                continue
            c = oracle_centroids(frames[k], truth.marker_px[cam][k, :3], half)
            e = np.hypot(*(c - truth.marker_px[cam][k, :3]).T)
            errs.extend(e[vis & np.isfinite(e)])
        out[cam] = np.asarray(errs)
    return out
