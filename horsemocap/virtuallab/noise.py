"""Realistic marker noise for the virtual laboratory: correlated over frames, with small systematic biases.

The images' own noise (sensor noise, glints, unevenly lit tape, compression)
gives marker centroids whose errors are nearly independent from frame to
frame. Real systems do not behave so: a marker's centroid in one camera
wanders slowly (the tape's wobble, the cluster's and the camera's vibration,
the tracker's own filtering), and each marker in each camera is seen a
little off its centre for the whole record (its tape's shape and lighting
seen from that camera). :class:`MarkerNoise` adds both to the drawing of the
markers, in pixels of each camera:

- a per-camera, per-marker AR(1) sequence over the camera's frames,
  ``e_k = rho e_(k-1) + sqrt(1 - rho^2) sigma_px w_k`` (``w_k`` standard
  normal, each image axis apart), whose standard deviation is ``sigma_px``
  and lag-1 autocorrelation ``rho``;
- a per-camera, per-marker constant offset drawn once, normal with standard
  deviation ``bias_px`` per axis.

The marker disc is drawn moved, in its own depth, so that its centre's
projection moves by the offset; the ground truth keeps the true projection,
so the offset is measurement error. Every value is a pure function of the
session seed, the camera's name, the marker and the frame.
"""
from __future__ import annotations

import zlib
from dataclasses import asdict, dataclass
from functools import lru_cache

import numpy as np

from ..iir_filters import ar1_filter

__all__ = ["MarkerNoise"]

#: Frames of innovations drawn per seeded block (the sequence is continuous across blocks).
BLOCK_FRAMES = 1024
#: Frame index of time 0: frames before the flash (negative times) have their own noise too.
FRAME_ORIGIN = 4096


def _camera_key(name: str) -> int:
    return zlib.crc32(str(name).encode())


@lru_cache(maxsize=64)
def _ar1_series(seed: int, camera: int, marker: int, blocks: int, rho: float) -> np.ndarray:
    """Unit-variance AR(1) offsets (blocks * BLOCK_FRAMES, 2), read-only."""
    w = np.concatenate([np.random.default_rng(np.random.SeedSequence([seed, 41, camera, marker, b]))
                        .standard_normal((BLOCK_FRAMES, 2)) for b in range(blocks)])
    w[1:] *= np.sqrt(1 - rho * rho)
    e = ar1_filter(w, rho, axis=0)
    e.flags.writeable = False
    return e


@dataclass(frozen=True)
class MarkerNoise:
    """Marker-centroid noise of each camera: AR(1) over frames plus a fixed bias per marker.

    Parameters
    ----------
    sigma_px : float
        Standard deviation of the correlated part, per image axis (px).
    rho : float
        Its lag-1 autocorrelation from one frame to the next, in [0, 1).
    bias_px : float
        Standard deviation of the per-camera, per-marker constant offsets, per image axis (px).
    frame_rate_hz : float
        The cameras' frame rate: time ``t`` is frame ``round(t * frame_rate_hz)``
        (:func:`horsemocap.virtuallab.session.render_session` sets it to the session's).

    Examples
    --------
    >>> import numpy as np
    >>> mn = MarkerNoise(sigma_px=0.3, rho=0.8, bias_px=0.1)
    >>> e = mn.offsets(7, "left", np.arange(20000) / 30.0, 4)[:, 2]     # marker 2, (frames, 2)
    >>> e0 = e - mn.bias(7, "left", 4)[2]
    >>> round(float(np.corrcoef(e0[1:, 0], e0[:-1, 0])[0, 1]), 1), round(float(e0.std()), 1)
    (0.8, 0.3)
    """

    sigma_px: float = 0.3
    rho: float = 0.8
    bias_px: float = 0.1
    frame_rate_hz: float = 30.0

    def __post_init__(self):
        if not (np.isfinite(self.sigma_px) and self.sigma_px >= 0):
            raise ValueError(f"sigma_px: expected a standard deviation >= 0 (px), got {self.sigma_px!r}")
        if not (np.isfinite(self.rho) and 0 <= self.rho < 1):
            raise ValueError(f"rho: expected a lag-1 autocorrelation in [0, 1), got {self.rho!r}")
        if not (np.isfinite(self.bias_px) and self.bias_px >= 0):
            raise ValueError(f"bias_px: expected a standard deviation >= 0 (px), got {self.bias_px!r}")
        if not (np.isfinite(self.frame_rate_hz) and self.frame_rate_hz > 0):
            raise ValueError(f"frame_rate_hz: expected a positive frame rate, got {self.frame_rate_hz!r}")

    def to_dict(self) -> dict:
        return {k: float(v) for k, v in asdict(self).items()}

    def bias(self, seed: int, camera: str, markers: int) -> np.ndarray:
        """The constant offsets (markers, 2) of one camera (px)."""
        rng = np.random.default_rng(np.random.SeedSequence([int(seed), 43, _camera_key(camera)]))
        return self.bias_px * rng.standard_normal((markers, 2))

    def offsets(self, seed: int, camera: str, t, markers: int) -> np.ndarray:
        """The offsets (n, markers, 2) of one camera at times ``t`` (s): bias plus the AR(1) part."""
        frames = np.round(np.atleast_1d(np.asarray(t, float)) * self.frame_rate_hz).astype(int) + FRAME_ORIGIN
        if np.any(frames < 0):
            raise ValueError(f"t: times before {-FRAME_ORIGIN / self.frame_rate_hz:.4g} s have no marker noise")
        blocks = int(frames.max()) // BLOCK_FRAMES + 1
        cam = _camera_key(camera)
        ar = np.stack([_ar1_series(int(seed), cam, j, blocks, float(self.rho))[frames] for j in range(markers)], 1)
        return self.bias(seed, camera, markers)[None] + self.sigma_px * ar

    def static_clip_times(self, frames: int, first_motion_time: float) -> np.ndarray:
        """Times (s) of the ``frames`` frames of a static clip: the first frames of the noise series
        (frame index 0 onwards, i.e. from ``-FRAME_ORIGIN / frame_rate_hz``), which no frame of a motion
        record starting at ``first_motion_time`` (s) uses. The per-marker biases are the motion's; the
        AR(1) part is a stretch of the same series that the motion record does not overlap.

        Examples
        --------
        >>> mn = MarkerNoise(frame_rate_hz=30.0)
        >>> t = mn.static_clip_times(3, first_motion_time=-5.0)
        >>> np.round(t * 30).astype(int).tolist()           # the series' frames 0, 1, 2
        [-4096, -4095, -4094]
        >>> mn.static_clip_times(4000, first_motion_time=-5.0)
        Traceback (most recent call last):
        ...
        ValueError: static clip of 4000 frames: at 30 fps the marker noise has 3946 frames before the motion record's first (-5 s)
        """
        frames = int(frames)
        room = int(round(first_motion_time * self.frame_rate_hz)) + FRAME_ORIGIN
        if frames > room:
            raise ValueError(f"static clip of {frames} frames: at {self.frame_rate_hz:g} fps the marker noise has "
                             f"{max(room, 0)} frames before the motion record's first ({first_motion_time:g} s)")
        return (np.arange(frames) - FRAME_ORIGIN) / self.frame_rate_hz

    def displace(self, centres, cam, t: float, seed: int) -> np.ndarray:
        """Marker centres (..., m, 3) moved in their depth so that their projections in ``cam`` move by
        the offsets at time ``t`` (one instant: a blurred exposure's sub-instants move together)."""
        c = np.asarray(centres, float)
        off = self.offsets(seed, cam.name, [t], c.shape[-2])[0]
        uv = cam.project(c) + off
        origin, direction = cam.rays(uv)
        depth = np.linalg.norm(c - origin, axis=-1, keepdims=True)
        moved = origin + direction * depth
        return np.where(np.isfinite(moved), moved, c)
