"""Render complete riding sessions (docs/sessions.md) with their truth.

Timeline (thesis 3.5, 8.2): the cameras are started one after the other and
record the same instants (frame-locked). A flashlight in view switches on at
motion time ``t = 0``; its first lit frame is frame ``offsets[cam]`` of each
camera: ``offsets = {left: o, middle: o + 53, right: o + 126}`` (thesis
``Delta F_LM = 53``, ``Delta F_MR = 73``). Frame ``k`` of camera ``c`` shows
time ``t = (k - offsets[c]) / fps``. The horse enters from the left shortly
after the flash, crosses the view at the gait speed and leaves on the right.

At another frame rate (:func:`render_session` ``fps=``) the same instants
are kept: the offsets between the cameras (``53/30`` s and ``73/30`` s unless
``sync_deltas_s`` is given) and the flash's duration (``4/30`` s) are scaled
to whole frames of that rate. Any rig (any cameras, any image size) and
scene extras (:mod:`horsemocap.virtuallab.hard`: a swinging stirrup, a
reflector crossing the markers, an occluder in front of one camera) can be
rendered; the defaults render the thesis' laboratory byte for byte as before.

Free-running cameras (:func:`render_session` ``timing=``, see
:mod:`horsemocap.virtuallab.timing`): camera ``c``'s frame ``offsets[c]``
has the middle of its row-0 exposure ``phase_frames`` of a frame after the
flash's onset (``t = 0``) and its frames follow at its own rate; each image
row is exposed at its own instant (rolling shutter), each field of an
interlaced frame at its own (each field's image blurred by the lens on its
own before the sensor reads its rows), the horse and markers are smeared
over each exposure, and the flash (on from ``t = 0`` for :func:`flash_frames` frames)
lights each frame in proportion to the part of its exposure it is on. The
truth then gives every camera's instants (:func:`build_truth`).
"""
from __future__ import annotations

import math
import shutil
import time
from dataclasses import dataclass, replace
from pathlib import Path

import cv2
import numpy as np

from ..camera import Camera, Rig, write_rig
from ..store import atomic_write_json
from .calibration import render_calibration_views
from .horse import saddle_motion, SaddleMotion
from .render import (add_glints, Arena, blend, disc_boundary, draw_disc, draw_disc_blurred, fill_polygon, finish,
                     horse_parts, interlaced_readout, perspective_centroid_bias, polygon_coverage, project_parts,
                     render_arena, rider_parts, sphere_silhouette)
from .noise import MarkerNoise
from .rig import FPS, thesis_rig
from .timing import (CameraTiming, field_rows, field_start_times, flash_fraction, frame_start_times)
from .truth import save_truth, Truth

DELTA_F_LM = 53
DELTA_F_MR = 73
FLASH_FRAMES = 4
MARKER_DIAMETER = 0.06
CAMERA_NAMES = ("left", "middle", "right")
#: Flashlight in the ground frame (m) and its lens radius.
FLASH_POSITION_G = np.array([2.3, -1.05, 9.6])
FLASH_RADIUS = 0.06
#: Plumb line (thesis 5.3): upper (tail) and lower (tip) markers, ground frame.
PLUMB_TAIL_G = np.array([0.45, -1.85, 7.7])
PLUMB_TIP_G = np.array([0.45, -0.45, 7.7])
PLUMB_MARKER_DIAMETER = 0.05
JPEG_QUALITY = 82


def _seed(*parts) -> np.random.Generator:
    return np.random.default_rng(np.random.SeedSequence([int(p) for p in parts]))


def _cam_index(name):
    return CAMERA_NAMES.index(name)


@dataclass(frozen=True)
class Scene:
    """Everything needed to draw any frame of one session."""

    rig: Rig
    motion: SaddleMotion
    seed: int
    arena: Arena = Arena()
    #: Flashlight lens and plumb markers (tip = lower, tail = upper), ground frame (m).
    flash_g: tuple = tuple(FLASH_POSITION_G)
    plumb_tip_g: tuple = tuple(PLUMB_TIP_G)
    plumb_tail_g: tuple = tuple(PLUMB_TAIL_G)
    #: Scene extras drawn after the horse and rider, in order; each has
    #: ``draw(img, scene, cam, t, exposure_s)``, ``hides(scene, cam, t, px) -> (n, 4) bool``
    #: and ``truth(scene, offsets, n_frames, fps) -> dict`` (see :mod:`.hard`).
    extras: tuple = ()
    #: Correlated marker-centroid noise with per-marker biases (:class:`.noise.MarkerNoise`); None: the images' own.
    marker_noise: MarkerNoise | None = None

    def ground_to_world(self, p_g):
        return self.motion.ground_to_world_points(p_g)

    def marker_geometry(self, pose, with_saddle=True):
        """World centres (n, m, 3) and disc normals (n, m, 3) of the markers."""
        h = self.motion.horse
        body = np.vstack([h.marker_body, h.saddle_body[None]]) if with_saddle else h.marker_body
        nrm = np.vstack([h.marker_normal, h.saddle_normal[None]]) if with_saddle else h.marker_normal
        pos = pose.position[:, None, :] + np.einsum("nij,mj->nmi", pose.rotation, body)
        nw = np.einsum("nij,mj->nmi", pose.rotation, nrm)
        return pos, nw


def marker_gradients(scene: Scene) -> np.ndarray:
    """Per-marker uneven-illumination gradients (m + 1, 2) (skin markers and saddle), fixed for a session seed."""
    rng = _seed(scene.seed, 21)
    count = len(scene.motion.horse.marker_body) + 1
    ang = rng.uniform(0, 2 * np.pi, count)
    mag = rng.uniform(0.02, 0.06, count)
    return np.column_stack([mag * np.cos(ang), mag * np.sin(ang)])


def draw_horse_frame(img, scene: Scene, cam: Camera, pose, t: float, *, rider: bool, standing: bool,
                     markers: bool = True, exposure_s: float = 0.0, n_sub: int = 7, uneven: bool = False,
                     noise_t: float | None = None):
    """Draw horse, saddle, markers and (optionally) the rider for one pose (index 0).

    ``exposure_s > 0`` smears the markers over the exposure centred on ``t``
    (motion blur; the rest of the scene is drawn at ``t``). ``uneven``: the
    markers' tape is lit unevenly (:func:`marker_gradients`). ``noise_t``: the
    time of the scene's marker noise (default ``t``; a static clip's frames
    draw the standing horse at one instant with the noise of their own).
    """
    noise_t = t if noise_t is None else noise_t
    m = scene.motion
    parts = horse_parts(m.horse, m.gait, t, m.height, rider=rider, standing=standing)
    pos0, R0 = pose.position[0], pose.rotation[0]
    projected = project_parts(cam, pos0, R0, parts)
    w, h = cam.size
    allpx = np.concatenate([p[0] for p in projected])
    if not np.any(np.isfinite(allpx)):
        return
    if (np.nanmax(allpx[:, 0]) < -5 or np.nanmin(allpx[:, 0]) > w + 5
            or np.nanmax(allpx[:, 1]) < -5 or np.nanmin(allpx[:, 1]) > h + 5):
        return
    for px, rgb, kind in projected:
        fill_polygon(img, px, rgb)
    if markers:
        if exposure_s > 0 and not standing:
            ts = t + (np.arange(n_sub) + 0.5) / n_sub * exposure_s - exposure_s / 2
            centres, normals = scene.marker_geometry(m.pose(ts))
            if scene.marker_noise is not None:
                centres = scene.marker_noise.displace(centres, cam, noise_t, scene.seed)
            grads = marker_gradients(scene) if uneven else [None] * centres.shape[1]
            for j in range(centres.shape[1]):
                draw_disc_blurred(img, cam, centres[:, j], normals[:, j], MARKER_DIAMETER / 2, gradient=grads[j])
        else:
            centres, normals = scene.marker_geometry(pose)
            if scene.marker_noise is not None:
                centres = scene.marker_noise.displace(centres, cam, noise_t, scene.seed)
            for j in range(centres.shape[1]):
                draw_disc(img, cam, centres[0, j], normals[0, j], MARKER_DIAMETER / 2)
    if rider:
        for px, rgb, kind in project_parts(cam, pos0, R0, rider_parts(t, m.gait)):
            fill_polygon(img, px, rgb)
    # a shiny girth buckle near the markers: its glint depends on the pitch
    buckle = np.array([[-0.04, 0.17, -0.35], [0.02, 0.17, -0.35], [0.02, 0.215, -0.35], [-0.04, 0.215, -0.35]])
    pitch_now = m.gait.pitch.value(np.array([t]), m.gait.stride_hz)[0] if not standing else 0.0
    shine = 0.55 + 0.45 * math.cos(pitch_now * 25.0)
    fill_polygon(img, project_parts(cam, pos0, R0, [(buckle, None, "buckle")])[0][0],
                 (235.0 * shine, 230.0 * shine, 200.0 * shine))


def draw_flash(img, scene: Scene, cam: Camera):
    """The switched-on flashlight: a saturated lens with a glow."""
    c = scene.ground_to_world(np.asarray(scene.flash_g, float)[None])[0]
    uv = cam.project(c)
    w, h = cam.size
    yy, xx = np.mgrid[0:h, 0:w]
    r2 = (xx - uv[0]) ** 2 + (yy - uv[1]) ** 2
    img += (120.0 * np.exp(-r2 / (2 * 14.0 ** 2)))[..., None] + 6.0
    normal = cam.center - c
    draw_disc(img, cam, c, normal, FLASH_RADIUS, rgb=(255.0, 255.0, 250.0))


def marker_projection_truth(scene: Scene, cam: Camera, t: np.ndarray, ride: bool):
    """True 2D centres (n, 4, 2), visibility (n, 4) and reasons (n, 4)."""
    pose = scene.motion.pose(t)
    centres, normals = scene.marker_geometry(pose)
    px = cam.project(centres)
    n, m = centres.shape[:2]
    w, h = cam.size
    visible = np.zeros((n, m), bool)
    reason = np.full((n, m), "", dtype="U24")
    for i in range(n):
        for j in range(m):
            rim = cam.project(disc_boundary(centres[i, j], normals[i, j], MARKER_DIAMETER / 2, 32))
            inside = cam.in_image(rim, margin=0.5)
            if not np.any(inside):
                reason[i, j] = "outside_image"
            elif not np.all(inside):
                reason[i, j] = "partly_outside_image"
            elif ride and j == m - 1:      # the saddle marker (last), under the rider's thigh
                reason[i, j] = "occluded_by_rider"
            else:
                visible[i, j] = True
    for extra in scene.extras:
        hidden = extra.hides(scene, cam, t, px) & visible
        visible[hidden] = False
        reason[hidden] = "occluded_in_camera"
    return px, visible, reason


def flash_frames(fps: float = FPS) -> int:
    """Frames the flash stays on: ``FLASH_FRAMES`` at 30 fps, the same duration at ``fps``."""
    return FLASH_FRAMES if fps == FPS else max(3, int(round(FLASH_FRAMES * fps / FPS)))


def plan_timeline(scene: Scene, fps: float = FPS, left_offset: int = 8, max_seconds: float = 30.0,
                  sync_deltas_s=None):
    """Offsets and number of frames after the flash (until the markers left every view).

    ``sync_deltas_s = (left->middle, middle->right)`` start delays in seconds
    (default: the thesis' 53 and 73 frames at 30 fps), rounded to frames at ``fps``.
    """
    if sync_deltas_s is None:
        d_lm, d_mr = ((DELTA_F_LM, DELTA_F_MR) if fps == FPS
                      else (int(round(DELTA_F_LM * fps / FPS)), int(round(DELTA_F_MR * fps / FPS))))
    else:
        d_lm, d_mr = (int(round(d * fps)) for d in sync_deltas_s)
    offsets = {"left": left_offset, "middle": left_offset + d_lm, "right": left_offset + d_lm + d_mr}
    n = int(max_seconds * fps)
    t = np.arange(n) / fps
    pose = scene.motion.pose(t)
    centres, _ = scene.marker_geometry(pose, with_saddle=False)
    last = 0
    for cam in scene.rig:
        px = cam.project(centres)
        inside = cam.in_image(px, margin=-4.0).any(axis=1)
        if inside.any():
            last = max(last, int(np.nonzero(inside)[0].max()))
    return offsets, last + 4


def _write_video(path: Path, frames_iter, size, fps, compress: bool):
    """MJPEG AVI (lossy, deterministic) or, with ``compress=False``, a PNG folder."""
    if compress:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".tmp.avi")
        # FFmpeg's MJPEG encoder (like the Casio EX-Z750's Motion-JPEG AVI);
        # OpenCV's own MJPEG writer is the fallback (3x larger files).
        vw = cv2.VideoWriter(str(tmp), cv2.CAP_FFMPEG, cv2.VideoWriter_fourcc(*"MJPG"), fps, size)
        if not vw.isOpened():
            vw = cv2.VideoWriter(str(tmp), cv2.CAP_OPENCV_MJPEG, cv2.VideoWriter_fourcc(*"MJPG"), fps, size)
            if not vw.isOpened():
                raise RuntimeError(f"{path}: OpenCV cannot open an MJPEG writer")
            vw.set(cv2.VIDEOWRITER_PROP_QUALITY, JPEG_QUALITY)
        for frame in frames_iter:
            vw.write(cv2.cvtColor(frame, cv2.COLOR_RGB2BGR))
        vw.release()
        tmp.replace(path)
    else:
        path.mkdir(parents=True, exist_ok=True)
        for k, frame in enumerate(frames_iter):
            cv2.imwrite(str(path / f"{path.name}{k}.png"), cv2.cvtColor(frame, cv2.COLOR_RGB2BGR))


def write_stills(out: Path, scene, backgrounds: dict, noise: bool = True, compress: bool = True,
                 static_clip_times=None, fps: float = FPS) -> dict:
    """Render and write every camera's plumb and static still into ``out``; returns
    ``{"plumb": {camera: path}, "static": {camera: path}}`` relative to ``out`` (session.json's).

    ``static_clip_times`` (s, two or more): the static shot as a clip of those frames' marker noise
    (:func:`render_static` ``noise_t``), an MJPEG video ``static/<camera>.avi`` at ``fps`` (``compress``)
    or a PNG folder ``static/<camera>/``; None: one still per camera."""
    stills = {"plumb": {}, "static": {}}
    for cam in scene.rig:
        stills["plumb"][cam.name] = "plumb/" + _write_still(
            out / "plumb" / f"{cam.name}.png", render_plumb(scene, cam, backgrounds[cam.name], noise=noise), compress)
        if static_clip_times is None:
            img = render_static(scene, cam, backgrounds[cam.name], noise=noise)
            stills["static"][cam.name] = "static/" + _write_still(out / "static" / f"{cam.name}.png", img, compress)
            continue
        frames = (render_static(scene, cam, backgrounds[cam.name], noise=noise, noise_t=float(t), clip_frame=j)
                  for j, t in enumerate(static_clip_times))
        name = f"{cam.name}.avi" if compress else cam.name
        _write_video(out / "static" / name, frames, cam.size, fps, compress)
        stills["static"][cam.name] = f"static/{name}"
    return stills


def _write_still(path: Path, img_rgb: np.ndarray, compress: bool) -> str:
    path.parent.mkdir(parents=True, exist_ok=True)
    bgr = cv2.cvtColor(img_rgb, cv2.COLOR_RGB2BGR)
    if compress:
        path = path.with_suffix(".jpg")
        cv2.imwrite(str(path), bgr, [cv2.IMWRITE_JPEG_QUALITY, 90])
    else:
        path = path.with_suffix(".png")
        cv2.imwrite(str(path), bgr)
    return path.name


EXPOSURE_S = 1.0 / 120.0


def render_motion_frame(scene: Scene, cam: Camera, k: int, offset: int, bg: np.ndarray, *, noise: bool,
                        fps: float = FPS, markers: bool = True, exposure_s: float = EXPOSURE_S) -> np.ndarray:
    """Frame ``k`` of camera ``cam`` (its own numbering) as uint8 RGB.

    The frame shows time ``t = (k - offset) / fps`` (mid-exposure); markers
    are smeared over ``exposure_s`` (motion blur, 0 disables).
    """
    t = (k - offset) / fps
    img = bg.copy()
    ci = _cam_index(cam.name)
    rng = _seed(scene.seed, 1, ci, k)
    if 0 <= k - offset < flash_frames(fps):
        draw_flash(img, scene, cam)
    pose = scene.motion.pose(np.array([t]))
    draw_horse_frame(img, scene, cam, pose, t, rider=True, standing=False, markers=markers, exposure_s=exposure_s,
                     uneven=noise)
    for extra in scene.extras:
        extra.draw(img, scene, cam, t, exposure_s)
    if noise:
        centres, _ = scene.marker_geometry(pose)
        _add_marker_glints(img, cam, centres[0], rng)
    return finish(img, rng, noise=noise)


# ---------------------------------------------------------------------------
# free-running cameras: every frame, row and field at its own instant
# ---------------------------------------------------------------------------

#: Sub-exposure samples of the horse's body and rider (motion blur of the large parts).
BODY_SUBSAMPLES = 5
#: Sub-exposure samples of each marker's disc (as the genlocked markers).
MARKER_SUBSAMPLES = 7


def free_running_frame_starts(timing: CameraTiming, offset: int, n: int) -> np.ndarray:
    """Exposure start of row 0 of a free-running camera's frames ``0 .. n-1`` (s, flash onset = 0).

    The camera's frame ``offset`` has the middle of its row-0 exposure at
    ``phase_frames / fps`` (a genlocked camera with phase 0 shows ``t = 0``,
    as :func:`render_motion_frame` does); the frames follow at the camera's
    own rate (:func:`horsemocap.virtuallab.timing.frame_start_times`).
    """
    t0 = (timing.phase_frames - offset) / timing.fps - timing.exposure / 2
    return frame_start_times(timing, n, t0)


def marker_instants(scene: Scene, cam: Camera, timing: CameraTiming, exposure_starts, *,
                    both_fields: bool = True, n_iter: int = 3) -> np.ndarray:
    """Instant (s) each marker is seen at, per frame: (n, 4).

    The middle of the exposure of the image row of the marker's own centre
    (:func:`horsemocap.virtuallab.timing.row_time`), found by a fixed-point
    iteration (the row depends on where the marker is at that instant). For
    a marker of a few pixels this stands for the whole disc: its rows span a
    few readout steps (microseconds), so evaluating the marker at the time
    of its centre row misplaces it by far less than a pixel. In an
    interlaced frame the disc spans both fields; with ``both_fields`` its
    instant is the middle of the two fields' (the centroid of the combed
    disc), otherwise that of the field starting at ``exposure_starts``.
    """
    base = np.asarray(exposure_starts, float) + timing.exposure / 2
    if both_fields:
        base = base + timing.field_delay_s / 2
    n_markers = len(scene.motion.horse.marker_body) + 1
    h = cam.size[1]
    t = np.repeat(base[:, None], n_markers, axis=1)
    if timing.rolling_shutter_s <= 0:
        return t
    t = t + 0.5 * timing.rolling_shutter_s
    for _ in range(n_iter):
        centres, _ = scene.marker_geometry(scene.motion.pose(t.ravel()))
        own = centres.reshape(t.shape[0], n_markers, n_markers, 3)[:, np.arange(n_markers), np.arange(n_markers)]
        v = cam.project(own)[..., 1]
        v = np.clip(np.nan_to_num(v, nan=h / 2), 0.0, h - 1.0)
        t = base[:, None] + v / h * timing.rolling_shutter_s
    return t


def draw_flash_fraction(img, scene: Scene, cam: Camera, fraction: float):
    """The flashlight lit for ``fraction`` (0..1) of the exposure: :func:`draw_flash` scaled."""
    c = scene.ground_to_world(np.asarray(scene.flash_g, float)[None])[0]
    uv = cam.project(c)
    w, h = cam.size
    yy, xx = np.mgrid[0:h, 0:w]
    r2 = (xx - uv[0]) ** 2 + (yy - uv[1]) ** 2
    img += fraction * ((120.0 * np.exp(-r2 / (2 * 14.0 ** 2)))[..., None] + 6.0)
    poly = cam.project(disc_boundary(c, cam.center - c, FLASH_RADIUS))
    patch = polygon_coverage(poly, cam.size, ss=8, centre=uv)
    if patch is not None:
        x0, y0, cov = patch
        blend(img, x0, y0, cov * fraction, (255.0, 255.0, 250.0))


def _layers_bbox(projected_sets, size, pad: int = 3):
    """Pixel box ``(x0, y0, x1, y1)`` holding every finite polygon point (clipped), or None."""
    pts = np.concatenate([px for parts in projected_sets for px, _, _ in parts])
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    if not len(pts):
        return None
    w, h = size
    x0, y0 = max(int(math.floor(pts[:, 0].min())) - pad, 0), max(int(math.floor(pts[:, 1].min())) - pad, 0)
    x1, y1 = min(int(math.ceil(pts[:, 0].max())) + pad, w - 1), min(int(math.ceil(pts[:, 1].max())) + pad, h - 1)
    return None if x1 < x0 or y1 < y0 else (x0, y0, x1, y1)


def _draw_averaged(img, projected_sets, size):
    """Draw each set of projected polygons on its own copy and average them in place (motion blur)."""
    box = _layers_bbox(projected_sets, size)
    if box is None:
        return
    x0, y0, x1, y1 = box
    crop = img[y0:y1 + 1, x0:x1 + 1]
    acc = np.zeros_like(crop)
    for parts in projected_sets:
        layer = crop.copy()
        for px, rgb, _ in parts:
            fill_polygon(layer, px - [x0, y0], rgb)
        acc += layer
    crop[...] = acc / len(projected_sets)


def _rider_and_buckle(scene: Scene, cam: Camera, pose, t: float):
    """Projected rider polygons and the girth buckle (its glint at time ``t``)."""
    m = scene.motion
    pos0, R0 = pose.position[0], pose.rotation[0]
    parts = project_parts(cam, pos0, R0, rider_parts(t, m.gait))
    buckle = np.array([[-0.04, 0.17, -0.35], [0.02, 0.17, -0.35], [0.02, 0.215, -0.35], [-0.04, 0.215, -0.35]])
    pitch_now = m.gait.pitch.value(np.array([t]), m.gait.stride_hz)[0]
    shine = 0.55 + 0.45 * math.cos(pitch_now * 25.0)
    parts.append((project_parts(cam, pos0, R0, [(buckle, None, "buckle")])[0][0],
                  (235.0 * shine, 230.0 * shine, 200.0 * shine), "buckle"))
    return parts


def draw_horse_exposure(img, scene: Scene, cam: Camera, body_time: float, marker_times, exposure_s: float, *,
                        uneven: bool = False):
    """Horse, markers and rider over one exposure, each part at its own instants.

    The body, saddle and rider are averaged over :data:`BODY_SUBSAMPLES`
    instants across ``[body_time - e/2, body_time + e/2]`` (motion blur of
    the large parts; under a rolling shutter they are drawn at the instant
    of the markers' rows, a shear of the body the markers do not see); each
    marker ``j`` is smeared over :data:`MARKER_SUBSAMPLES` instants across
    its own exposure centred on ``marker_times[j]``. Drawing order as
    :func:`draw_horse_frame`: body, markers, rider (hiding the saddle marker).
    """
    m = scene.motion
    e = float(exposure_s)
    offsets = ((np.arange(BODY_SUBSAMPLES) + 0.5) / BODY_SUBSAMPLES - 0.5) * e if e > 0 else np.zeros(1)
    times = body_time + offsets
    poses = [m.pose(np.array([s])) for s in times]
    body = [project_parts(cam, p.position[0], p.rotation[0], horse_parts(m.horse, m.gait, s, m.height, rider=True,
                                                                         standing=False))
            for s, p in zip(times, poses)]
    w, h = cam.size
    allpx = np.concatenate([px for parts in body for px, _, _ in parts])
    if not np.any(np.isfinite(allpx)) or (np.nanmax(allpx[:, 0]) < -5 or np.nanmin(allpx[:, 0]) > w + 5
                                          or np.nanmax(allpx[:, 1]) < -5 or np.nanmin(allpx[:, 1]) > h + 5):
        return
    _draw_averaged(img, body, cam.size)
    marker_times = np.asarray(marker_times, float)
    sub = ((np.arange(MARKER_SUBSAMPLES) + 0.5) / MARKER_SUBSAMPLES - 0.5) * e if e > 0 else np.zeros(1)
    grads = marker_gradients(scene) if uneven else [None] * len(marker_times)
    for j, tj in enumerate(marker_times):
        centres, normals = scene.marker_geometry(m.pose(tj + sub))
        if scene.marker_noise is not None:
            centres = scene.marker_noise.displace(centres, cam, body_time, scene.seed)
        draw_disc_blurred(img, cam, centres[:, j], normals[:, j], MARKER_DIAMETER / 2, gradient=grads[j])
    _draw_averaged(img, [_rider_and_buckle(scene, cam, p, s) for s, p in zip(times, poses)], cam.size)


def _flash_row(scene: Scene, cam: Camera) -> float:
    c = scene.ground_to_world(np.asarray(scene.flash_g, float)[None])[0]
    v = float(cam.project(c)[1])
    return min(max(v, 0.0), cam.size[1] - 1.0) if np.isfinite(v) else cam.size[1] / 2


def flash_interval(fps: float) -> tuple[float, float]:
    """When the flashlight is on (s): from the onset at 0 for :func:`flash_frames` frames of ``fps``."""
    return 0.0, flash_frames(fps) / fps


def render_free_running_frame(scene: Scene, cam: Camera, k: int, frame_start: float, timing: CameraTiming,
                              bg: np.ndarray, *, noise: bool) -> np.ndarray:
    """Frame ``k`` of a free-running camera whose row 0 starts exposing at ``frame_start`` (s).

    Each field (one, progressive) is drawn at its own instants
    (:func:`_draw_field_image`). Glints, blur and noise as
    :func:`render_motion_frame`; an interlaced frame's two field images are
    each blurred on their own and the frame takes each field's rows from
    its own (:func:`horsemocap.virtuallab.render.interlaced_readout`), as a
    camera's lens blurs each field's instant before the sensor reads its rows.
    """
    rng = _seed(scene.seed, 1, _cam_index(cam.name), k)
    fields = field_start_times(timing, frame_start)
    images = [_draw_field_image(scene, cam, start, timing, bg, noise=noise) for start in fields]
    if len(images) == 1:
        if noise:
            _add_frame_glints(images[0], scene, cam, timing, frame_start, rng)
        return finish(images[0], rng, noise=noise)
    if noise:
        # the specks are still (dust, sparkles of the arena): the same in both fields' images
        specks = np.full_like(images[0], -np.inf)
        _add_frame_glints(specks, scene, cam, timing, frame_start, rng)
        images = [np.maximum(image, specks) for image in images]
    h = cam.size[1]
    return interlaced_readout(images, [field_rows(timing, f, h) for f in range(len(images))], rng, noise=noise)


def _draw_field_image(scene: Scene, cam: Camera, start: float, timing: CameraTiming, bg: np.ndarray, *,
                      noise: bool) -> np.ndarray:
    """The light of one field (or progressive frame) whose row 0 starts exposing at ``start`` (s), float RGB.

    The horse, markers and extras at their own instants
    (:func:`draw_horse_exposure`; markers at the time of their own centre
    row, :func:`marker_instants`); the flashlight lit in proportion to the
    part of its row's exposure it is on
    (:func:`horsemocap.virtuallab.timing.flash_fraction`). No glints, blur or noise.
    """
    e = timing.exposure
    h = cam.size[1]
    on, off = flash_interval(timing.nominal_fps)
    layer = bg.copy()
    # the field's start already holds the field delay: only the readout to the flash's row is added
    lit = flash_fraction(timing, start + _flash_row(scene, cam) / h * timing.rolling_shutter_s, on, off)
    if lit > 0:
        draw_flash_fraction(layer, scene, cam, lit)
    tm = marker_instants(scene, cam, timing, np.array([start]), both_fields=False)[0]
    seen = cam.project(scene.marker_geometry(scene.motion.pose(tm))[0][np.arange(len(tm)), np.arange(len(tm))])
    rows = seen[np.isfinite(seen[:, 1]), 1]
    band = float(np.clip(rows.mean(), 0, h - 1)) if len(rows) else h / 2
    body_time = start + e / 2 + band / h * timing.rolling_shutter_s
    draw_horse_exposure(layer, scene, cam, body_time, tm, e, uneven=noise)
    for extra in scene.extras:
        extra.draw(layer, scene, cam, body_time, e)
    return layer


def _add_frame_glints(img, scene: Scene, cam: Camera, timing: CameraTiming, frame_start: float, rng) -> None:
    """Random small glints over a free-running frame, away from the markers at the frame's middle instant."""
    e = timing.exposure
    t_mid = float(frame_start + e / 2 + timing.field_delay_s / 2 + timing.rolling_shutter_s / 2)
    centres, _ = scene.marker_geometry(scene.motion.pose(np.array([t_mid])))
    _add_marker_glints(img, cam, centres[0], rng)


def _add_marker_glints(img, cam: Camera, centres, rng) -> None:
    """Random small glints over the frame away from the markers' ``centres`` (m, 3), and more of them in a box
    around the first three markers (the saddle's tack shines near them)."""
    avoid = [tuple(p) for p in cam.project(centres)]
    add_glints(img, rng, 5.0, avoid)
    mk = cam.project(centres[:3])
    if np.all(np.isfinite(mk)):
        region = (mk[:, 0].min() - 45, mk[:, 1].min() - 25, mk[:, 0].max() + 45, mk[:, 1].max() + 25)
        add_glints(img, rng, 1.2, avoid, region=region)


def render_static(scene: Scene, cam: Camera, bg, *, noise: bool, noise_t: float | None = None,
                  clip_frame: int | None = None) -> np.ndarray:
    """The static shot (thesis 6.3): the horse standing, no rider, all markers visible.

    ``clip_frame`` (a frame of a static clip, :func:`write_stills`): the image noise and glints of that
    frame, the marker noise at time ``noise_t``; the horse stands in the same pose in every frame.
    None: the still (marker noise at time 0).
    """
    img = bg.copy()
    pose = scene.motion.static_pose()
    draw_horse_frame(img, scene, cam, pose, 0.0, rider=False, standing=True, noise_t=noise_t)
    rng = (_seed(scene.seed, 2, _cam_index(cam.name)) if clip_frame is None
           else _seed(scene.seed, 2, _cam_index(cam.name), 1 + int(clip_frame)))
    if noise:
        add_glints(img, rng, 4.0, [tuple(p) for p in cam.project(scene.marker_geometry(pose)[0][0])])
    return finish(img, rng, noise=noise)


def plumb_world(scene_or_motion) -> np.ndarray:
    """Plumb markers (tip, tail) in the world frame, (2, 3)."""
    if isinstance(scene_or_motion, Scene):
        s = scene_or_motion
        return s.motion.ground_to_world_points(np.vstack([np.asarray(s.plumb_tip_g, float),
                                                          np.asarray(s.plumb_tail_g, float)]))
    return scene_or_motion.ground_to_world_points(np.vstack([PLUMB_TIP_G, PLUMB_TAIL_G]))


def render_plumb(scene: Scene, cam: Camera, bg, *, noise: bool, tag: int = 3) -> np.ndarray:
    """A plumb line with two reflective spheres (thesis 5.3, Figure 8.4)."""
    img = bg.copy()
    tip, tail = plumb_world(scene)
    tail_g = np.asarray(scene.plumb_tail_g, float)
    top = scene.ground_to_world(np.array([[tail_g[0], min(-3.5, tail_g[1] - 1.65), tail_g[2]]]))[0]
    line = np.linspace(top, tip, 60)
    px = cam.project(line)
    for a, b in zip(px[:-1], px[1:]):
        if np.all(np.isfinite(a)) and np.all(np.isfinite(b)):
            cv2.line(img, tuple(np.round(a * 16).astype(int)), tuple(np.round(b * 16).astype(int)),
                     (85.0, 85.0, 80.0), 1, cv2.LINE_AA, 4)
    for c in (tail, tip):
        cc, nn, rr = sphere_silhouette(c, PLUMB_MARKER_DIAMETER / 2, cam)
        draw_disc(img, cam, cc, nn, rr)
    rng = _seed(scene.seed, tag, _cam_index(cam.name))
    if noise:
        add_glints(img, rng, 4.0, [tuple(p) for p in cam.project(np.vstack([tip, tail]))])
    return finish(img, rng, noise=noise)


# ---------------------------------------------------------------------------
# comfort indicators of the true saddle motion
# ---------------------------------------------------------------------------

def true_saddle_harmonics(motion: SaddleMotion, n_per_period: int = 512, k_max: int = 40):
    """Exact harmonic series of the true saddle vertical acceleration ``A_y``.

    The whole motion is periodic in the stride period, so ``A_y`` (motion
    frame, y down) is a Fourier series in ``f0 = stride_hz``; its
    coefficients come from an FFT of one period sampled ``n_per_period``
    times (exact up to harmonics above ``n_per_period / 2``, which are zero
    to machine precision here). Returns ``(freq_hz, complex c_k, f0)`` with
    ``A_y(t) = Re(sum c_k exp(2j pi f_k t))`` (zero mean).
    """
    f0 = motion.gait.stride_hz
    ts = np.arange(n_per_period) / (n_per_period * f0)
    a_y = motion.saddle(ts)[2] @ motion.motion_axes[1]
    X = np.fft.rfft(a_y)
    c = 2.0 * X[1:k_max + 1] / n_per_period
    k = np.arange(1, k_max + 1)
    keep = np.abs(c) > 1e-9
    return k[keep] * f0, c[keep], f0


def true_comfort(motion: SaddleMotion, t0: float, t1: float, fps: float = FPS):
    """Comfort indicators (thesis Table 8.7) of the true saddle motion.

    ``horsemocap.vibration.comfort_indicators`` (mode ``"iso"``; the thesis'
    single-scalar weighting in ``extras['comfort_thesis_mode']``) is given the
    exact harmonic series of the true vertical acceleration
    (:func:`true_saddle_harmonics`), tau = two stride periods (thesis 8.4.1:
    two periods), ``vel_x_avg`` = the true mean speed along x-motion and
    ``amplitude_y`` = half the peak-to-peak of the true vertical position.
    If that module is missing, only unweighted quantities are computed here.
    The dense true signals over ``[t0, t1]`` (the analysed frames) are
    returned too, so anything can be recomputed. When the horse changes speed
    (``motion.speed_change``), ``vel_x_avg`` is the exact mean over ``[t0, t1]``
    (displacement over time); the other indicators do not depend on it.
    """
    dense_fs = 1000.0
    td = np.arange(t0, t1 + 0.5 / dense_fs, 1 / dense_fs)
    p, v, a = motion.saddle(td)
    axes = motion.motion_axes
    a_y, p_y, v_x = a @ axes[1], p @ axes[1], v @ axes[0]
    f0 = motion.gait.stride_hz
    tau = 2.0 / f0
    tp = np.linspace(0.0, tau, 4096, endpoint=False)
    pp, vp, ap = motion.saddle(tp)
    ap_y, pp_y = ap @ axes[1], pp @ axes[1]
    amp = float((pp_y.max() - pp_y.min()) / 2)
    vel = float(np.mean(vp @ axes[0]))
    if motion.speed_change.k and t1 > t0:
        # the speed changes: the mean over the analysed frames, exactly (displacement / time)
        p01 = motion.saddle(np.array([t0, t1]))[0]
        vel = float((p01[1] - p01[0]) @ axes[0] / (t1 - t0))
    out = {
        "acc_y_max": float(np.max(np.abs(ap_y))),
        "acc_y_rms_unweighted": float(np.sqrt(np.mean(ap_y ** 2))),
        "VDV_y_unweighted": float((np.sum(ap_y ** 4) * tau / len(tp)) ** 0.25),
        "crest_factor_y_unweighted": float(np.max(np.abs(ap_y)) / np.sqrt(np.mean(ap_y ** 2))),
        "vel_x_avg": vel * 3.6,
        "amplitude_y": amp,
        "duration_s": tau,
        "f0_hz": f0,
        "period_s": 1.0 / f0,
    }
    source = "virtuallab (unweighted only; horsemocap.vibration not available)"
    dense = {"comfort_time_s": td, "comfort_saddle_acc_y": a_y, "comfort_saddle_pos_y": p_y,
             "comfort_saddle_vel_x": v_x}
    try:
        from .. import vibration
    except Exception:  # pragma: no cover - the module exists in the full package
        vibration = None
    if vibration is not None and hasattr(vibration, "comfort_indicators"):
        freq, c, f0 = true_saddle_harmonics(motion)
        h = vibration.Harmonics(freq, c, 0.0)
        res = vibration.comfort_indicators(h, tau, vel, amp, mode="iso", f0_hz=f0)
        out.update({k: float(v) for k, v in res.items()})
        thesis = vibration.comfort_indicators(h, tau, vel, amp, mode="thesis", f0_hz=f0)
        dense["comfort_thesis_mode"] = {k: float(v) for k, v in thesis.items()}
        dense["saddle_acc_y_harmonics_hz"] = freq
        dense["saddle_acc_y_harmonics_re"] = c.real
        dense["saddle_acc_y_harmonics_im"] = c.imag
        source = ("horsemocap.vibration.comfort_indicators(mode='iso') on the exact harmonic series of the "
                  "true saddle A_y, tau = 2 stride periods")
    return out, source, dense


# ---------------------------------------------------------------------------
# the session
# ---------------------------------------------------------------------------

def _clear_generated(out: Path) -> None:
    """Remove what an earlier render wrote into ``out`` (only the session's own sub-folders)."""
    for sub in ("motion", "plumb", "static", "calibration", "truth"):
        if (out / sub).is_dir():
            shutil.rmtree(out / sub)


def session_json(name: str, meta: dict, motion_paths: dict, stills: dict, calib_images: bool,
                 board=(15, 29), square=0.05, marker_count=3, marker_diameter=MARKER_DIAMETER,
                 sync=None, fps=FPS) -> dict:
    """The ``session.json`` content (format ``horsemocap-session/1``)."""
    d = {
        "format": "horsemocap-session/1",
        "name": name,
        "fps": fps,
        "cameras": list(CAMERA_NAMES),
        "reference_camera": "left",
        "motion": motion_paths,
        "sync": sync or {"method": "flash"},
        "calibration": {} if calib_images else {"rig": "calibration/rig.toml"},
        "markers": {"count": marker_count, "diameter_m": marker_diameter},
        "analysis": {},
        "metadata": meta,
    }
    if calib_images:
        d["calibration"]["images"] = {c: f"calibration/{c}" for c in CAMERA_NAMES}
        d["calibration"]["board"] = {"inner_corners": list(board), "square_size_m": square}
    for key, paths in stills.items():
        d[key] = paths
    return d


def _scene_and_backgrounds(horse: str, gait: str, seed: int, scene: Scene | None = None):
    """The thesis rig's scene of ``(horse, gait, seed)`` (or the given ``scene``) and each camera's empty arena."""
    if scene is None:
        scene = Scene(thesis_rig(), saddle_motion(horse, gait), int(seed))
    rig, motion = scene.rig, scene.motion
    bgs = {c.name: render_arena(c, motion.R_wg, motion.c_g, scene.arena, seed=seed) for c in rig}
    return scene, bgs


def _static_clip_times(scene: Scene, static_frames: int, offsets: dict, fps: float):
    """The marker-noise times of a static clip's frames (None for one still): ``static_frames`` frames
    before the motion record's first (:meth:`MarkerNoise.static_clip_times`); without marker noise the
    frames differ by their image noise only."""
    if isinstance(static_frames, bool) or not isinstance(static_frames, (int, np.integer)) or static_frames < 1:
        raise ValueError(f"static_frames: expected a number of frames >= 1, got {static_frames!r}")
    if static_frames == 1:
        return None
    first_motion_time = -max(offsets.values()) / fps - 1.0        # a free-running camera's phase: a second spare
    if scene.marker_noise is None:
        return np.zeros(int(static_frames))
    return scene.marker_noise.static_clip_times(int(static_frames), first_motion_time)


def render_session(out_dir, horse: str = "Horse 2", gait: str = "canter", seed: int = 0, *,
                   noise: bool = True, compress: bool = True, n_motion_frames: int | None = None,
                   calibration_views: int | None = 45, name: str | None = None, left_offset: int = 8,
                   exposure_s: float = EXPOSURE_S, verbose: bool = False, scene: Scene | None = None,
                   fps: float = FPS, sync_deltas_s=None, metadata: dict | None = None,
                   timing: dict | None = None, marker_noise: MarkerNoise | None = None,
                   static_frames: int = 1) -> Path:
    """Render a complete session folder and its ground truth.

    Parameters
    ----------
    out_dir : path
        The session folder to create; its ``motion/``, ``plumb/``,
        ``static/``, ``calibration/`` and ``truth/`` sub-folders are replaced.
    horse, gait : str
        See :data:`horsemocap.virtuallab.HORSES`, :data:`~horsemocap.virtuallab.GAITS`.
    seed : int
        Seeds every random choice (noise, glints, textures, board poses).
    noise : bool
        Sensor noise, glints and unevenly lit marker tape (``False``: a clean
        render, for tests).
    compress : bool
        MJPEG videos and JPEG stills (``False``: PNG folders and PNG stills).
    n_motion_frames : int, optional
        Number of frames after the flash (default: until the markers have
        left every view).
    calibration_views : int or None
        Checkerboard views per camera (``None`` or 0: no images, the rig only).
    exposure_s : float
        Exposure time; markers are smeared over it (motion blur). 0: sharp.
    scene : Scene, optional
        Any rig (cameras named left/middle/right, any image size), motion
        and extras (default: the thesis rig and ``saddle_motion(horse, gait)``;
        ``horse`` and ``gait`` then only label the session).
    fps : float
        Frame rate; the sync offsets and the flash keep their durations in seconds.
    sync_deltas_s : (float, float), optional
        Start delays left->middle and middle->right (s), see :func:`plan_timeline`.
    metadata : dict, optional
        Merged into ``session.json``'s ``metadata``.
    timing : dict[str, CameraTiming], optional
        Free-running cameras (:mod:`horsemocap.virtuallab.timing`), one per
        camera, their ``nominal_fps`` equal to ``fps``: every frame, image
        row and field is drawn at its own instants
        (:func:`render_free_running_frame`; each camera's own exposure
        replaces ``exposure_s``), the flash lights each frame in proportion
        to the part of its exposure it is on, and the truth gives every
        camera's instants (:func:`build_truth`). ``session.json`` records the
        timings in ``metadata.camera_timing``. ``None``: the cameras are
        genlocked (every frame at ``(k - offset) / fps``).
    marker_noise : MarkerNoise, optional
        Marker-centroid noise correlated over frames, with per-marker biases
        (:class:`horsemocap.virtuallab.noise.MarkerNoise`, its frame rate set to
        ``fps``), recorded in the truth's extras. None: the images' own noise only.
    static_frames : int
        Frames of the static shot: 1, one still per camera; more, a clip of
        the horse standing (``static/<camera>.avi``, or a PNG folder), its
        marker noise evolving over the clip's frames: the motion's per-marker
        biases, the AR(1) part at times no motion frame uses
        (:meth:`~horsemocap.virtuallab.noise.MarkerNoise.static_clip_times`).

    Returns
    -------
    Path
        The session folder.
    """
    t_start = time.perf_counter()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    _clear_generated(out)
    scene, bgs = _scene_and_backgrounds(horse, gait, seed, scene)
    if marker_noise is not None:
        scene = replace(scene, marker_noise=replace(marker_noise, frame_rate_hz=float(fps)))
    rig, motion = scene.rig, scene.motion
    offsets, n_after = plan_timeline(scene, fps, left_offset=left_offset, sync_deltas_s=sync_deltas_s)
    if n_motion_frames is not None:
        n_after = int(n_motion_frames)
    # motion videos
    motion_paths = {}
    n_frames = {}
    if timing is not None:
        _check_timing(timing, rig, fps)
    for cam in rig:
        o = offsets[cam.name]
        n_frames[cam.name] = o + n_after
        if timing is None:
            frames = (render_motion_frame(scene, cam, k, o, bgs[cam.name], noise=noise, fps=fps, exposure_s=exposure_s)
                      for k in range(n_frames[cam.name]))
        else:
            tc = timing[cam.name]
            starts = free_running_frame_starts(tc, o, n_frames[cam.name])
            frames = (render_free_running_frame(scene, cam, k, float(starts[k]), tc, bgs[cam.name], noise=noise)
                      for k in range(n_frames[cam.name]))
        if compress:
            _write_video(out / "motion" / f"{cam.name}.avi", frames, cam.size, fps, True)
            motion_paths[cam.name] = f"motion/{cam.name}.avi"
        else:
            _write_video(out / "motion" / cam.name, frames, cam.size, fps, False)
            motion_paths[cam.name] = f"motion/{cam.name}"
    stills = write_stills(out, scene, bgs, noise=noise, compress=compress, fps=fps,
                          static_clip_times=_static_clip_times(scene, static_frames, offsets, fps))
    # calibration: checkerboard views for the pipeline to calibrate from (the true rig
    # stays in truth/rig.toml); without views, the session carries the true rig as a
    # lab that calibrated once would carry its rig.toml.
    (out / "calibration").mkdir(exist_ok=True)
    stale = out / "calibration" / "rig.toml"
    if calibration_views:
        stale.unlink(missing_ok=True)
    else:
        write_rig(rig, stale)
    board_info = None
    if calibration_views:
        board_info = render_calibration_views(out / "calibration", scene, bgs, calibration_views,
                                              noise=noise, compress=compress)
    # truth
    truth = build_truth(scene, offsets, n_frames, fps, timing=timing)
    if board_info is not None:
        truth.extras.update(board_info.get("truth_extras", {}))
    truth.extras["exposure_s"] = float(exposure_s if timing is None else timing[rig.names[0]].exposure)
    truth.extras["noise"] = bool(noise)
    if scene.marker_noise is not None:
        truth.extras["marker_noise"] = scene.marker_noise.to_dict()
    truth.extras["compress"] = bool(compress)
    if static_frames != 1:
        truth.extras["static_frames"] = int(static_frames)
    save_truth(truth, out)
    meta = {"horse": horse, "gait": gait, "direction": "CCW", "rider": "A", "seed": int(seed),
            "generator": "horsemocap.virtuallab", "virtual": True}
    meta.update(metadata or {})
    if timing is not None:
        meta["camera_timing"] = {c: timing[c].to_dict() for c in rig.names}
    sname = name or f"{horse.lower().replace(' ', '')}_{gait}"
    board = board_info["board"] if board_info else {"inner_corners": [15, 29], "square_size_m": 0.05}
    sj = session_json(sname, meta, motion_paths, stills, bool(calibration_views),
                      board=board["inner_corners"], square=board["square_size_m"], fps=fps,
                      marker_count=len(motion.horse.marker_body))
    atomic_write_json(out / "session.json", sj)
    if verbose:
        print(f"rendered {out} in {time.perf_counter() - t_start:.1f} s")
    return out


def render_calibration_set(out_dir, seed: int, n_views: int = 45, horse: str = "Horse 2",
                           gait: str = "canter", *, noise: bool = True, compress: bool = True,
                           protocol: str = "path") -> dict:
    """Render only the checkerboard views a session of this seed would hold.

    The views are those :func:`render_session` writes into
    ``calibration/`` (same board poses, background and noise for the same
    ``seed`` and ``n_views``), one folder per camera in ``out_dir``; for
    studying calibration draws without rendering the motion videos.
    ``protocol`` chooses where the boards stand
    (:data:`horsemocap.virtuallab.calibration.PROTOCOLS`; sessions use ``"path"``).

    Returns
    -------
    dict
        ``images`` (camera -> folder), ``board`` (``inner_corners``,
        ``square_size_m``), ``rig`` (the true rig) and ``truth_extras``
        (board poses).
    """
    out = Path(out_dir)
    scene, bgs = _scene_and_backgrounds(horse, gait, seed)
    rig = scene.rig
    info = render_calibration_views(out, scene, bgs, int(n_views), noise=noise, compress=compress,
                                    protocol=protocol)
    return {"images": {c.name: out / c.name for c in rig}, "board": info["board"], "rig": rig,
            "truth_extras": info["truth_extras"]}


def _check_timing(timing: dict, rig: Rig, fps: float) -> None:
    """A clear error unless ``timing`` holds a CameraTiming at ``fps`` for every camera of the rig."""
    for cam in rig.names:
        tc = timing.get(cam)
        if not isinstance(tc, CameraTiming):
            raise ValueError(f"timing[{cam!r}]: expected a CameraTiming for every camera {list(rig.names)}, got {tc!r}")
        if tc.nominal_fps != fps:
            raise ValueError(f"timing[{cam!r}].nominal_fps: expected the session's fps {fps}, got {tc.nominal_fps}")


def _free_running_projection_truth(scene: Scene, cam: Camera, timing: CameraTiming, offset: int, n: int):
    """Truth of a free-running camera: each marker projected at its own instant.

    Returns ``(px, visible, reason, marker_time, frame_start, frame_time, lit)``:
    the (n, 4) marker arrays of :func:`marker_projection_truth`, the instants
    (n, 4) they were taken at (:func:`marker_instants`), the exposure start of
    row 0 (n,), the frame's own instant (n,: the middle of row 0's exposure,
    of the first field) and the part of each frame's exposure the flash is on (n,).
    """
    starts = free_running_frame_starts(timing, offset, n)
    t_marker = marker_instants(scene, cam, timing, starts)
    m = t_marker.shape[1]
    px = np.full((n, m, 2), np.nan)
    visible = np.zeros((n, m), bool)
    reason = np.full((n, m), "", dtype="U24")
    for j in range(m):
        pj, vj, rj = marker_projection_truth(scene, cam, t_marker[:, j], ride=True)
        px[:, j], visible[:, j], reason[:, j] = pj[:, j], vj[:, j], rj[:, j]
    on, off = flash_interval(timing.nominal_fps)
    lit = flash_fraction(timing, starts + _flash_row(scene, cam) / cam.size[1] * timing.rolling_shutter_s, on, off)
    return px, visible, reason, t_marker, starts, starts + timing.exposure / 2, np.asarray(lit, float)


def free_running_offsets(timing: dict, offsets: dict, reference: str = "left") -> dict:
    """True sub-frame offsets (frames) of free-running cameras at the flash's onset.

    Camera ``c``'s frame ``k + offsets_true[c]`` shows the instant of the
    reference camera's frame ``k`` (frame instants = middle of row 0's
    exposure): ``offsets[c] - offsets[reference] - (phase_c - phase_ref)``,
    the thesis' whole-frame ``Delta F`` (eq. 3.11-3.13) made fractional. The
    rates differ by ppm, so it drifts by ``(fps_c / fps_ref - 1)`` frames per frame.

    Examples
    --------
    >>> t = {"left": CameraTiming(), "middle": CameraTiming(phase_frames=0.25)}
    >>> free_running_offsets(t, {"left": 3, "middle": 56})
    {'left': 0.0, 'middle': 52.75}
    """
    ref = timing[reference]
    return {c: float(offsets[c] - offsets[reference] - (tc.phase_frames - ref.phase_frames)) for c, tc in timing.items()}


def build_truth(scene: Scene, offsets: dict, n_frames: dict, fps: float = FPS, timing: dict | None = None,
                ref_window: tuple[int, int] | None = None) -> Truth:
    """Exact truth of a session: analytic kinematics at the analysed frames.

    With free-running cameras (``timing``, see :func:`render_session`) every
    camera's marker projections are taken at each marker's own instant, the
    kinematics at the reference (left) camera's frame instants, and
    ``extras`` gains ``camera_timing``, ``true_offsets_frames``
    (:func:`free_running_offsets`), ``true_rate_ratio`` (each camera's rate
    over the reference's), ``flash_interval_s`` and per camera
    ``frame_start_s__<cam>``, ``frame_time_s__<cam>``,
    ``marker_time_s__<cam>`` and ``flash_lit__<cam>``. Without ``timing`` the
    truth is that of genlocked cameras, as it always was. ``ref_window =
    (k0, k1)``: only the reference camera's frames ``k0 .. k1 - 1`` may be
    analysed (one pass of a recording with several; default: every frame).
    """
    rig, motion = scene.rig, scene.motion
    marker_px, marker_vis, marker_reason, free = {}, {}, {}, {}
    for cam in rig:
        if timing is None:
            k = np.arange(n_frames[cam.name])
            t = (k - offsets[cam.name]) / fps
            px, vis, rs = marker_projection_truth(scene, cam, t, ride=True)
        else:
            px, vis, rs, *free[cam.name] = _free_running_projection_truth(scene, cam, timing[cam.name],
                                                                           offsets[cam.name], n_frames[cam.name])
        marker_px[cam.name], marker_vis[cam.name], marker_reason[cam.name] = px, vis, rs
    # analysed frames: every skin marker inside every image (a marker hidden by an
    # occluder in one camera only stays in: the other cameras still see it)
    kL = np.arange(n_frames["left"])
    ok = np.ones(len(kL), bool)
    for cam in rig:
        kc = kL - offsets["left"] + offsets[cam.name]
        good = (kc >= 0) & (kc < n_frames[cam.name])
        vis = np.zeros(len(kL), bool)
        seen = marker_vis[cam.name][kc[good], :-1] | (marker_reason[cam.name][kc[good], :-1] == "occluded_in_camera")
        vis[good] = seen.all(axis=1)
        ok &= vis
    if ref_window is not None:
        ok &= (kL >= ref_window[0]) & (kL < ref_window[1])
    idx = np.nonzero(ok)[0]
    if idx.size:
        # the longest contiguous run
        splits = np.split(idx, np.nonzero(np.diff(idx) != 1)[0] + 1)
        ref = max(splits, key=len)
    else:
        ref = idx
    t_m = (ref - offsets["left"]) / fps if timing is None else free["left"][2][ref]
    pose = motion.pose(t_m)
    mp, mv, ma = pose.points(motion.horse.marker_body)
    sp, sv, sa = pose.points(motion.horse.saddle_body[None])
    static_pose = motion.static_pose()
    static_pos = np.vstack([static_pose.points(motion.horse.marker_body)[0][0],
                            static_pose.points(motion.horse.saddle_body[None])[0][0]])
    if len(t_m) > 1:
        comfort, source, dense = true_comfort(motion, float(t_m[0]), float(t_m[-1]), fps)
    else:
        comfort, source, dense = {}, "no analysed frames", {}
    # perspective bias of the disc centroid, for the record (px)
    centres, normals = scene.marker_geometry(pose)
    bias = [np.linalg.norm(perspective_centroid_bias(rig["left"], centres[i, j], normals[i, j], MARKER_DIAMETER / 2))
            for i in range(0, len(t_m), max(1, len(t_m) // 8)) for j in range(3)] if len(t_m) else [0.0]
    extras = dict(dense)
    extras.update({
        "motion": motion.to_dict(),
        "flash_frames": flash_frames(fps),
        "flash_position_world": scene.ground_to_world(np.asarray(scene.flash_g, float)[None])[0].tolist(),
        "n_frames": n_frames,
        "perspective_centroid_bias_px_max": float(np.max(bias)),
        "marker_body": motion.horse.marker_body.tolist(),
        "saddle_body": motion.horse.saddle_body.tolist(),
        "plumb_marker_diameter_m": PLUMB_MARKER_DIAMETER,
    })
    for extra in scene.extras:
        extras.update(extra.truth(scene, offsets, n_frames, fps))
    time_s = (ref - (ref[0] if len(ref) else 0)) / fps
    if timing is not None:
        time_s = t_m - (t_m[0] if len(t_m) else 0.0)
        extras.update(_free_running_extras(timing, offsets, free, fps))
    return Truth(
        fps=fps, offsets=dict(offsets), rig=rig, ref_frames=ref.astype(int),
        time_s=time_s, motion_time_s=t_m,
        marker_pos=mp, marker_vel=mv, marker_acc=ma,
        saddle_pos=sp[:, 0], saddle_vel=sv[:, 0], saddle_acc=sa[:, 0],
        rotation=pose.rotation, omega=pose.omega, alpha=pose.alpha,
        marker_px=marker_px, marker_visible=marker_vis, marker_reason=marker_reason,
        gravity=motion.gravity, motion_axes=motion.motion_axes,
        static_pos=static_pos, plumb_pos=plumb_world(scene), comfort=comfort,
        comfort_source=source, marker_diameter_m=MARKER_DIAMETER,
        meta={"horse": motion.horse.name, "gait": motion.gait.name, "seed": scene.seed},
        extras=extras)


def _free_running_extras(timing: dict, offsets: dict, free: dict, fps: float) -> dict:
    """The truth's extras describing free-running cameras (see :func:`build_truth`)."""
    ref = timing["left"]
    out = {"camera_timing": {c: tc.to_dict() for c, tc in timing.items()},
           "true_offsets_frames": free_running_offsets(timing, offsets),
           "true_rate_ratio": {c: tc.fps / ref.fps for c, tc in timing.items()},
           "flash_interval_s": list(flash_interval(fps))}
    for cam, (t_marker, starts, t_frame, lit) in free.items():
        out[f"marker_time_s__{cam}"] = t_marker
        out[f"frame_start_s__{cam}"] = starts
        out[f"frame_time_s__{cam}"] = t_frame
        out[f"flash_lit__{cam}"] = lit
    return out


# ---------------------------------------------------------------------------
# the free-fall ball (thesis 8.3)
# ---------------------------------------------------------------------------
BALL_DIAMETER = 0.065
G = 9.81


def ball_trajectory(t, p0_g=(-0.6, -0.95, 7.9), v0_g=(0.35, None, 0.08), rise_m: float = 0.70):
    """Ground-frame ball position, velocity, acceleration at times ``t``.

    Thrown up from the lower edge of the calibration volume (0.95 m high) so
    that it peaks ``rise_m`` higher (the upper edge), then falls freely;
    ``g = 9.81 m/s^2`` along the ground Y axis (down). No air resistance.
    """
    t = np.asarray(t, float)[:, None]
    vy0 = -math.sqrt(2 * G * rise_m)
    v0 = np.array([v0_g[0], vy0, v0_g[2]])
    a = np.array([0.0, G, 0.0])
    p = np.asarray(p0_g, float) + v0 * t + 0.5 * a * t ** 2
    v = v0 + a * t
    return p, v, np.broadcast_to(a, p.shape).copy()


def render_ball_drop(out_dir, seed: int = 0, *, noise: bool = True, compress: bool = True,
                     n_frames: int = 21, t0: float = 0.023) -> Path:
    """The section 8.3 experiment: a 65 mm reflective ball thrown up and falling.

    Writes a session folder (3 synchronised videos of ``n_frames`` frames,
    0.7 s at 30 fps; sync offsets all 0; plumb stills; the true rig) and its
    truth: ``marker_pos/vel/acc`` (n, 1, 3) of the ball, ``gravity`` and
    ``extras['g'] = 9.81``.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    _clear_generated(out)
    rig = thesis_rig()
    motion = saddle_motion("Horse 2", "canter")
    scene = Scene(rig, motion, int(seed))
    fps = FPS
    t = t0 + np.arange(n_frames) / fps
    pg, vg, ag = ball_trajectory(t)
    pw = motion.ground_to_world_points(pg)
    vw, aw = vg @ motion.R_wg.T, ag @ motion.R_wg.T
    bgs = {c.name: render_arena(c, motion.R_wg, motion.c_g, scene.arena, seed=seed) for c in rig}
    motion_paths, marker_px, marker_vis, marker_reason = {}, {}, {}, {}
    for ci, cam in enumerate(rig):
        frames = []
        for k in range(n_frames):
            img = bgs[cam.name].copy()
            cc, nn, rr = sphere_silhouette(pw[k], BALL_DIAMETER / 2, cam)
            draw_disc(img, cam, cc, nn, rr)
            rng = _seed(seed, 11, ci, k)
            if noise:
                add_glints(img, rng, 5.0, [tuple(cam.project(pw[k]))])
            frames.append(finish(img, rng, noise=noise))
        name = f"motion/{cam.name}.avi" if compress else f"motion/{cam.name}"
        _write_video(out / name, iter(frames), cam.size, fps, compress)
        motion_paths[cam.name] = name
        px = cam.project(pw)[:, None, :]
        vis = cam.in_image(px, margin=4.0)
        marker_px[cam.name], marker_vis[cam.name] = px, vis
        marker_reason[cam.name] = np.where(vis, "", "outside_image").astype("U24")
    stills = {"plumb": {}}
    for cam in rig:
        stills["plumb"][cam.name] = "plumb/" + _write_still(out / "plumb" / f"{cam.name}.png",
                                                            render_plumb(scene, cam, bgs[cam.name], noise=noise, tag=12), compress)
    (out / "calibration").mkdir(exist_ok=True)
    write_rig(rig, out / "calibration" / "rig.toml")
    n = n_frames
    nan3 = np.full((n, 3), np.nan)
    truth = Truth(
        fps=fps, offsets={c: 0 for c in CAMERA_NAMES}, rig=rig, ref_frames=np.arange(n),
        time_s=np.arange(n) / fps, motion_time_s=t, marker_pos=pw[:, None], marker_vel=vw[:, None],
        marker_acc=aw[:, None], saddle_pos=nan3, saddle_vel=nan3, saddle_acc=nan3,
        rotation=np.broadcast_to(np.eye(3), (n, 3, 3)).copy(), omega=np.zeros((n, 3)), alpha=np.zeros((n, 3)),
        marker_px=marker_px, marker_visible=marker_vis, marker_reason=marker_reason,
        gravity=motion.gravity, motion_axes=motion.motion_axes, static_pos=np.zeros((0, 3)),
        plumb_pos=plumb_world(motion), comfort={}, comfort_source="not applicable (ball drop)",
        marker_diameter_m=BALL_DIAMETER, meta={"experiment": "ball_drop", "seed": int(seed)},
        extras={"g": G, "ball_diameter_m": BALL_DIAMETER, "rise_m": 0.70,
                "acc_along_gravity": float(aw[0] @ motion.gravity)})
    save_truth(truth, out)
    sj = session_json("ball_drop", {"experiment": "ball_drop", "object": "tennis ball, 65 mm, reflective",
                                    "seed": int(seed), "generator": "horsemocap.virtuallab", "virtual": True},
                      motion_paths, stills, False, marker_count=1, marker_diameter=BALL_DIAMETER,
                      sync={"offsets": {c: 0 for c in CAMERA_NAMES}})
    atomic_write_json(out / "session.json", sj)
    return out
