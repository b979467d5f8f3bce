"""Rendering of the virtual laboratory's images.

Every image is built in floating point RGB (0-255), in layers:

1. the arena (per camera, static): a dark sand floor and a dark far wall
   with procedural texture, fence posts and a bright fence rail, found by
   intersecting every pixel's ray with the floor / wall planes;
2. the horse (barrel, neck, head, tail, legs with bright bandages), the
   saddle, the girth with a shiny buckle: planar polygons in the body frame,
   projected with the full camera model (distortion included) and filled
   with anti-aliased edges;
3. the retroreflective markers: flat discs of 60 mm (or spheres, by their
   exact silhouette) whose boundary is projected with the full camera model
   and whose per-pixel coverage is computed by supersampling, so the disc
   edge is sub-pixel exact;
4. the rider (torso, bright helmet, leg hiding the saddle marker, boot, shiny
   stirrup) during the ride;
5. a flashlight in view (synchronisation, thesis 3.5), random small glints,
   optical blur, sensor noise; lossy compression happens when writing. An
   interlaced frame is two images, one per field's instant, each blurred on
   its own before the sensor reads its rows (:func:`interlaced_readout`).

Truth of a marker's 2D position = projection of its 3D centre (with
distortion). Under perspective the centroid of the projected disc differs
from it by a tiny amount (:func:`perspective_centroid_bias` measures it:
~1e-3 px for 60 mm discs at 8 m).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from matplotlib.path import Path as MplPath

from ..camera import Camera

MARKER_RGB = (246.0, 246.0, 242.0)


# ---------------------------------------------------------------------------
# geometry helpers
# ---------------------------------------------------------------------------

def pixel_rays(cam: Camera, pixels: np.ndarray) -> np.ndarray:
    """World-frame unit ray directions through distorted pixels ``(..., 2)``
    (:meth:`horsemocap.camera.Camera.rays`)."""
    return cam.rays(pixels)[1]


def disc_boundary(center, normal, radius: float, n: int = 128) -> np.ndarray:
    """``n`` points on the rim of a flat disc (world frame), shape (n, 3)."""
    c = np.asarray(center, float)
    nv = np.asarray(normal, float)
    nv = nv / np.linalg.norm(nv)
    a = np.array([1.0, 0.0, 0.0]) if abs(nv[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(nv, a)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(nv, e1)
    ang = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return c + radius * (np.cos(ang)[:, None] * e1 + np.sin(ang)[:, None] * e2)


def sphere_silhouette(center, radius: float, cam: Camera):
    """Rim circle of a sphere seen from a camera: (centre, normal, radius).

    The viewing cone touches the sphere along a circle of radius
    ``r sqrt(1 - r^2/d^2)`` centred ``r^2/d`` from the centre towards the
    camera; its projection is the sphere's exact outline.
    """
    c = np.asarray(center, float)
    o = cam.center
    d_vec = o - c
    d = np.linalg.norm(d_vec)
    u = d_vec / d
    return c + (radius ** 2 / d) * u, u, radius * math.sqrt(1 - (radius / d) ** 2)


def star_inside(points: np.ndarray, centre: np.ndarray, rim: np.ndarray) -> np.ndarray:
    """Inside test for a region star-shaped about ``centre`` (a projected disc).

    The rim ``(n, 2)`` is described in polar coordinates about the centre;
    a point is inside when its radius is below the rim radius interpolated
    at its angle. With 128 rim points this equals the polygon test except
    within a tiny distance of the edge, and it is much faster than a generic
    point-in-polygon test.
    """
    d = rim - centre
    ang = np.arctan2(d[:, 1], d[:, 0])
    rad = np.hypot(d[:, 0], d[:, 1])
    order = np.argsort(ang)
    ang, rad = ang[order], rad[order]
    q = points - centre
    qa = np.arctan2(q[:, 1], q[:, 0])
    qr = np.hypot(q[:, 0], q[:, 1])
    return qr < np.interp(qa, ang, rad, period=2 * np.pi)


def polygon_coverage(poly_px: np.ndarray, size, ss: int = 8, pad: int = 2, centre=None):
    """Per-pixel area coverage of a polygon by ``ss x ss`` supersampling.

    Pixel ``(i, j)`` is the square centred on ``(u, v) = (j, i)``.

    Returns
    -------
    (x0, y0, cov) : the patch origin and coverage (h, w) in [0, 1], or
    ``None`` if the polygon is outside the image.
    """
    w, h = size
    poly = np.asarray(poly_px, float)
    if not np.all(np.isfinite(poly)):
        return None
    x0 = int(math.floor(poly[:, 0].min())) - pad
    x1 = int(math.ceil(poly[:, 0].max())) + pad
    y0 = int(math.floor(poly[:, 1].min())) - pad
    y1 = int(math.ceil(poly[:, 1].max())) + pad
    x0c, y0c, x1c, y1c = max(x0, 0), max(y0, 0), min(x1, w - 1), min(y1, h - 1)
    if x1c < x0c or y1c < y0c:
        return None
    off = (np.arange(ss) + 0.5) / ss - 0.5
    us = (np.arange(x0c, x1c + 1)[:, None] + off[None, :]).ravel()
    vs = (np.arange(y0c, y1c + 1)[:, None] + off[None, :]).ravel()
    U, V = np.meshgrid(us, vs)
    pts = np.column_stack([U.ravel(), V.ravel()])
    inside = MplPath(poly).contains_points(pts) if centre is None else star_inside(pts, np.asarray(centre, float), poly)
    hh, ww = y1c - y0c + 1, x1c - x0c + 1
    cov = inside.reshape(hh, ss, ww, ss).mean(axis=(1, 3))
    return x0c, y0c, cov


def add_image_disc(img: np.ndarray, cx: float, cy: float, r: float, amp: float, ss: int = 8) -> None:
    """Add to a gray float image an image-plane disc of height ``amp``, anti-aliased
    by ``ss`` x ``ss`` supersampling of each pixel's coverage (synthetic frames for
    tests and benchmarks; the sessions use :func:`draw_disc`, projected discs)."""
    h, w = img.shape
    x0, x1 = max(int(np.floor(cx - r - 1)), 0), min(int(np.ceil(cx + r + 2)), w)
    y0, y1 = max(int(np.floor(cy - r - 1)), 0), min(int(np.ceil(cy + r + 2)), h)
    if x1 <= x0 or y1 <= y0:
        return
    o = (np.arange(ss) + 0.5) / ss - 0.5
    yy, xx = np.mgrid[y0:y1, x0:x1]
    sx = xx[..., None, None] + o[None, None, None, :]
    sy = yy[..., None, None] + o[None, None, :, None]
    img[y0:y1, x0:x1] += amp * (((sx - cx) ** 2 + (sy - cy) ** 2) <= r * r).mean(axis=(-1, -2))


def disc_frames(marker_px, size, radius: float = 3.2, amp: float = 200.0, background: float = 40.0) -> list:
    """The simplest marker video: gray frames (uint8) of anti-aliased discs (:func:`add_image_disc`) at the
    image points ``marker_px`` (n, M, 2; NaN: not drawn) on a flat background, ``size`` = (width, height).

    For tests and worked examples of detection and identification; the sessions draw projected discs on
    a rendered arena (:func:`draw_disc`).

    Examples
    --------
    >>> frames = disc_frames(np.array([[[10.0, 12.0]], [[np.nan, np.nan]]]), (32, 24))
    >>> len(frames), frames[0].shape, int(frames[0][12, 10]), int(frames[1].max())
    (2, (24, 32), 240, 40)
    """
    width, height = size
    out = []
    for points in np.asarray(marker_px, float):
        img = np.full((height, width), float(background))
        for u, v in points:
            if np.isfinite(u) and np.isfinite(v):
                add_image_disc(img, u, v, radius, amp)
        out.append(np.clip(np.rint(img), 0, 255).astype(np.uint8))
    return out


def blend(img: np.ndarray, x0: int, y0: int, cov: np.ndarray, rgb) -> None:
    """``img = img (1 - cov) + rgb cov`` in the patch at ``(x0, y0)`` (in place)."""
    h, w = cov.shape
    sub = img[y0:y0 + h, x0:x0 + w]
    c = cov[..., None]
    sub *= 1 - c
    sub += c * np.asarray(rgb, float)


def draw_disc(img: np.ndarray, cam: Camera, center, normal, radius, rgb=MARKER_RGB, ss: int = 8):
    """Draw a flat disc with exact anti-aliased edges. Returns the coverage patch."""
    poly = cam.project(disc_boundary(center, normal, radius))
    patch = polygon_coverage(poly, cam.size, ss=ss, centre=cam.project(np.asarray(center, float)))
    if patch is not None:
        blend(img, *patch, rgb)
    return patch


def draw_disc_blurred(img: np.ndarray, cam: Camera, centers, normals, radius, rgb=MARKER_RGB, ss: int = 8,
                      gradient=None):
    """A disc moving during the exposure: coverage averaged over sub-exposure poses.

    ``centers`` / ``normals`` (S, 3) sample the exposure uniformly; the
    centroid of the streak is the mean of the sampled centres' images, i.e.
    the image of the mid-exposure position to within the (negligible)
    curvature of the path over the exposure.

    ``gradient = (gu, gv)``: uneven lamp light on the retroreflective tape,
    brightness ``1 + (gu (u - u_c) + gv (v - v_c)) / r_px`` across the disc;
    it shifts the intensity centroid by about ``|g| r_px / 4`` (a real
    difficulty, not part of the truth, which stays the projected centre).
    """
    polys = [cam.project(disc_boundary(c, n, radius)) for c, n in zip(centers, normals)]
    mids = cam.project(np.asarray(centers, float))
    allp = np.concatenate(polys)
    if not np.all(np.isfinite(allp)):
        return None
    w, h = cam.size
    x0 = max(int(math.floor(allp[:, 0].min())) - 2, 0)
    x1 = min(int(math.ceil(allp[:, 0].max())) + 2, w - 1)
    y0 = max(int(math.floor(allp[:, 1].min())) - 2, 0)
    y1 = min(int(math.ceil(allp[:, 1].max())) + 2, h - 1)
    if x1 < x0 or y1 < y0:
        return None
    off = (np.arange(ss) + 0.5) / ss - 0.5
    us = (np.arange(x0, x1 + 1)[:, None] + off[None, :]).ravel()
    vs = (np.arange(y0, y1 + 1)[:, None] + off[None, :]).ravel()
    U, V = np.meshgrid(us, vs)
    pts = np.column_stack([U.ravel(), V.ravel()])
    inside = np.zeros(len(pts))
    for poly, mid in zip(polys, mids):
        inside += star_inside(pts, mid, poly)
    hh, ww = y1 - y0 + 1, x1 - x0 + 1
    cov = (inside / len(polys)).reshape(hh, ss, ww, ss).mean(axis=(1, 3))
    colour = np.asarray(rgb, float)
    if gradient is not None:
        mid = mids.mean(axis=0)
        r_px = float(np.mean(np.hypot(*(polys[len(polys) // 2] - mids[len(polys) // 2]).T)))
        yy, xx = np.mgrid[y0:y1 + 1, x0:x1 + 1]
        f = 1.0 + (gradient[0] * (xx - mid[0]) + gradient[1] * (yy - mid[1])) / r_px
        colour = colour * f[..., None]
    blend(img, x0, y0, cov, colour)
    return x0, y0, cov


def fill_polygon(img: np.ndarray, poly_px: np.ndarray, rgb, alpha: float = 1.0, shift: int = 4):
    """Fill a polygon with anti-aliased edges (OpenCV, 1/16 px vertices)."""
    poly = np.asarray(poly_px, float)
    if not np.all(np.isfinite(poly)) or len(poly) < 3:
        return
    h, w = img.shape[:2]
    x0, y0 = int(max(math.floor(poly[:, 0].min()) - 2, 0)), int(max(math.floor(poly[:, 1].min()) - 2, 0))
    x1, y1 = int(min(math.ceil(poly[:, 0].max()) + 2, w - 1)), int(min(math.ceil(poly[:, 1].max()) + 2, h - 1))
    if x1 <= x0 or y1 <= y0:
        return
    mask = np.zeros((y1 - y0 + 1, x1 - x0 + 1), np.uint8)
    pts = np.round((poly - [x0, y0]) * (1 << shift)).astype(np.int32)
    if np.abs(pts).max() > 2 ** 28:
        return
    cv2.fillPoly(mask, [pts.reshape(-1, 1, 2)], 255, lineType=cv2.LINE_AA, shift=shift)
    blend(img, x0, y0, mask.astype(np.float32) * (alpha / 255.0), rgb)


def ellipse_pts(cx, cy, ax, ay, n=36, z=0.0, a0=0.0, a1=2 * np.pi):
    a = np.linspace(a0, a1, n, endpoint=a1 - a0 < 2 * np.pi - 1e-9)
    return np.column_stack([cx + ax * np.cos(a), cy + ay * np.sin(a), np.full(n, z)])


def segment_quad(p0, p1, w0, w1, z=0.0):
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    d = p1 - p0
    nrm = np.array([-d[1], d[0]]) / (np.hypot(*d) + 1e-12)
    q = np.array([p0 + nrm * w0 / 2, p1 + nrm * w1 / 2, p1 - nrm * w1 / 2, p0 - nrm * w0 / 2])
    return np.column_stack([q, np.full(4, z)])


# ---------------------------------------------------------------------------
# the arena background
# ---------------------------------------------------------------------------

@dataclass(frozen=True)
class Arena:
    """Static surroundings in the ground frame (m): floor Y=0, far wall Z=wall_z."""

    wall_z: float = 13.0
    rail_height: float = 0.62
    rail_thickness: float = 0.09
    top_rail_height: float = 1.25
    post_spacing: float = 2.4
    post_width: float = 0.12
    floor_rgb: tuple = (46.0, 40.0, 33.0)
    wall_rgb: tuple = (30.0, 30.0, 34.0)
    rail_rgb: tuple = (232.0, 232.0, 226.0)


def _value_noise(x, y, seed: int, scale: float) -> np.ndarray:
    """Smooth deterministic noise in [-1, 1] from a sum of seeded sinusoids."""
    rng = np.random.default_rng(seed)
    out = np.zeros_like(x)
    for octave in range(4):
        f = (2 ** octave) / scale
        for _ in range(3):
            th = rng.uniform(0, 2 * np.pi)
            ph = rng.uniform(0, 2 * np.pi)
            out += np.sin(f * (np.cos(th) * x + np.sin(th) * y) * 2 * np.pi + ph) / (2 ** octave)
    return out / 5.0


def render_arena(cam: Camera, R_wg: np.ndarray, c_g: np.ndarray, arena: Arena = Arena(), seed: int = 0) -> np.ndarray:
    """The empty arena seen by one camera: float RGB (h, w, 3)."""
    w, h = cam.size
    u, v = np.meshgrid(np.arange(w, dtype=float), np.arange(h, dtype=float))
    d_w = pixel_rays(cam, np.stack([u, v], -1))
    o_g = R_wg.T @ cam.center + c_g          # camera centre in ground frame
    d_g = d_w @ R_wg                          # ray directions in ground frame
    with np.errstate(divide="ignore", invalid="ignore"):
        t_wall = (arena.wall_z - o_g[2]) / d_g[..., 2]
        t_floor = np.where(d_g[..., 1] > 1e-9, (0.0 - o_g[1]) / d_g[..., 1], 1e9)
    mpp_wall = t_wall / cam.matrix[1, 1]        # metres per pixel on the wall

    def soft(dist, mpp):
        """Anti-aliased coverage of a region at signed distance ``dist`` (m)."""
        return np.clip(0.5 + dist / mpp, 0.0, 1.0)

    Pw = o_g + t_wall[..., None] * d_g
    X, height = Pw[..., 0], -Pw[..., 1]
    # wall: dark boards, posts, bright rail, dim top rail (analytic AA edges)
    nw = _value_noise(X * 0.7, height * 4.0, seed * 7 + 3, 1.0)
    wl = np.asarray(arena.wall_rgb) * (1 + 0.2 * nw)[..., None]
    dx = np.abs(((X + 1.1) / arena.post_spacing) % 1.0 - 0.5) * arena.post_spacing
    post = np.minimum(soft(arena.post_width / 2 - dx, mpp_wall), soft(1.4 - height, mpp_wall))
    wl += post[..., None] * (np.array([62.0, 55.0, 48.0]) - wl)
    top = soft(0.05 - np.abs(height - arena.top_rail_height), mpp_wall)
    wl += top[..., None] * (np.array([95.0, 92.0, 88.0]) - wl)
    rail = soft(arena.rail_thickness / 2 - np.abs(height - arena.rail_height), mpp_wall)
    wl += rail[..., None] * (np.asarray(arena.rail_rgb) * (0.92 + 0.08 * nw)[..., None] - wl)
    # floor: sand with tracks, darker far away
    tf = np.minimum(t_floor, 60.0)
    Pf = o_g + tf[..., None] * d_g
    Xf, Zf = Pf[..., 0], Pf[..., 2]
    n1 = _value_noise(Xf, Zf, seed * 7 + 1, 1.7)
    n2 = _value_noise(Xf * 3.1, Zf * 2.3, seed * 7 + 2, 0.35)
    fl = np.asarray(arena.floor_rgb) * (1 + 0.22 * n1 + 0.08 * n2)[..., None]
    fl *= np.clip(1.15 - 0.025 * tf, 0.6, 1.2)[..., None]
    floor_cov = soft(-height, mpp_wall)         # the wall below ground is floor
    img = wl + floor_cov[..., None] * (fl - wl)
    # vignetting of the lamps: brighter towards the middle
    r2 = ((u - w / 2) / w) ** 2 + ((v - h / 2) / h) ** 2
    img *= (1.0 - 0.5 * r2)[..., None]
    return img


# ---------------------------------------------------------------------------
# the horse, saddle and rider as body-frame polygons
# ---------------------------------------------------------------------------

def _shade(rgb, f):
    return tuple(float(np.clip(c * f, 0, 255)) for c in rgb)


def horse_parts(horse, gait, t: float, height: float, rider: bool, standing: bool = False):
    """Body-frame polygons ``[(points (n, 3), rgb, kind), ...]`` in drawing order.

    ``kind`` names the part (for documentation and tests); bright parts are
    the pseudo markers: ``bandage``, ``helmet``, ``stirrup``, ``buckle``.
    """
    coat = horse.coat_rgb
    parts = []
    f = gait.stride_hz
    hip_y = 0.28
    L = height - hip_y - 0.02

    def leg(x_hip, phase, z, far):
        if standing:
            a, bend = 0.0, 0.0
        else:
            s = math.sin(2 * math.pi * (f * t + phase))
            a = 0.38 * s if gait.name == "canter" else (0.22 if gait.name == "walk" else 0.3) * s
            bend = 0.5 * max(0.0, math.cos(2 * math.pi * (f * t + phase)))
        hip = np.array([x_hip, hip_y])
        knee = hip + 0.5 * L * np.array([math.sin(a), math.cos(a)])
        hoof = knee + 0.5 * L * np.array([math.sin(a - bend), math.cos(a - bend)])
        col = _shade(coat, 0.7 if far else 0.95)
        parts.append((segment_quad(hip, knee, 0.16, 0.10, z), col, "leg"))
        parts.append((segment_quad(knee, hoof, 0.09, 0.08, z), col, "leg"))
        band0 = knee + 0.35 * (hoof - knee)
        band1 = knee + 0.88 * (hoof - knee)
        parts.append((segment_quad(band0, band1, 0.105, 0.105, z - 0.01),
                      (214.0, 214.0, 206.0) if not far else (150.0, 150.0, 144.0), "bandage"))
        parts.append((segment_quad(band1 + 0.0, hoof, 0.09, 0.10, z), (25.0, 22.0, 20.0), "hoof"))

    ph = gait.leg_phases
    # far side legs first (left fore, left hind)
    leg(0.38, ph[0], 0.22, True)
    leg(-1.02, ph[2], 0.22, True)
    # tail, barrel, neck, head
    tail_a = 0.15 * math.sin(2 * math.pi * f * t) if not standing else 0.0
    parts.append((segment_quad([-1.12, -0.18], [-1.25 + tail_a * 0.3, 0.55], 0.10, 0.16, 0.0), _shade(coat, 0.45), "tail"))
    parts.append((ellipse_pts(-0.32, 0.04, 0.88, 0.33, 48, 0.0), coat, "barrel"))
    parts.append((np.array([[0.30, -0.26, 0], [0.62, 0.02, 0], [1.02, -0.55, 0], [0.88, -0.82, 0]]), _shade(coat, 1.05), "neck"))
    head = ellipse_pts(0.0, 0.0, 0.30, 0.12, 24, 0.0) @ _rot2(0.95) + np.array([1.06, -0.62, 0.0])
    parts.append((head, _shade(coat, 1.1), "head"))
    # near side legs (right fore, right hind)
    leg(0.30, ph[1], -0.22, False)
    leg(-0.95, ph[3], -0.22, False)
    # saddle pad and saddle (flap on the near flank), girth and its buckle
    parts.append((np.array([[-0.26, -0.31, -0.30], [0.35, -0.31, -0.30], [0.33, -0.06, -0.31], [-0.22, -0.06, -0.31]]), (200.0, 196.0, 185.0) if horse.name == "Horse 4" else (60.0, 58.0, 70.0), "saddle_pad"))
    parts.append((np.array([[-0.18, -0.36, -0.31], [0.30, -0.36, -0.31], [0.26, -0.06, -0.32], [-0.10, -0.06, -0.32]]), (52.0, 30.0, 18.0), "saddle"))
    parts.append((segment_quad([0.02, -0.05], [0.04, 0.36], 0.07, 0.07, -0.33), (40.0, 30.0, 22.0), "girth"))
    return parts


def _rot2(a):
    c, s = math.cos(a), math.sin(a)
    # rotate about the head centre approximately (x, y only)
    M = np.eye(3)
    M[:2, :2] = [[c, s], [-s, c]]
    return M


def rider_parts(t: float, gait) -> list:
    """The rider: torso, helmet (bright), thigh over the saddle marker, lower leg, boot, stirrup."""
    f = gait.stride_hz
    rise = 0.0
    if gait.name == "rising_trot":
        rise = 0.06 * max(0.0, math.sin(2 * math.pi * f * t))
    sway = 0.03 * math.sin(2 * math.pi * f * t + 1.0)
    parts = []
    seat = np.array([0.02, -0.34 - rise])
    shoulder = seat + np.array([-0.02 + sway, -0.58])
    parts.append((segment_quad(seat, shoulder, 0.30, 0.36, -0.05), (34.0, 36.0, 48.0), "torso"))
    parts.append((segment_quad(shoulder + [0.02, 0.05], shoulder + [0.28, 0.30], 0.08, 0.07, -0.22), (34.0, 36.0, 48.0), "arm"))
    parts.append((ellipse_pts(shoulder[0] + 0.02, shoulder[1] - 0.13, 0.085, 0.10, 20, -0.05), (190.0, 150.0, 130.0), "face"))
    hx, hy = shoulder[0] + 0.01, shoulder[1] - 0.19
    parts.append((ellipse_pts(hx, hy, 0.115, 0.10, 20, -0.05, np.pi, 2 * np.pi), (236.0, 236.0, 236.0), "helmet"))
    knee = np.array([0.30, -0.02 - rise * 0.5])
    ankle = np.array([0.14, 0.38])
    parts.append((segment_quad(seat + [0, 0.02], knee, 0.24, 0.16, -0.33), (120.0, 112.0, 100.0), "thigh"))
    parts.append((segment_quad(knee, ankle, 0.12, 0.10, -0.40), (22.0, 20.0, 20.0), "boot"))
    parts.append((segment_quad(ankle, ankle + [0.17, 0.03], 0.07, 0.06, -0.40), (22.0, 20.0, 20.0), "boot"))
    parts.append((segment_quad(ankle + [0.05, 0.05], ankle + [0.12, 0.06], 0.030, 0.030, -0.42), (240.0, 240.0, 236.0), "stirrup"))
    return parts


def project_parts(cam: Camera, pose_pos, pose_rot, parts):
    """Project body-frame polygons to pixels with one call."""
    pts = np.concatenate([p[0] for p in parts], 0)
    world = pose_pos + pts @ pose_rot.T
    px = cam.project(world)
    out, i = [], 0
    for p, rgb, kind in parts:
        out.append((px[i:i + len(p)], rgb, kind))
        i += len(p)
    return out


# ---------------------------------------------------------------------------
# per-image effects
# ---------------------------------------------------------------------------

def add_glints(img, rng, n_mean: float, avoid_px=(), min_dist: float = 7.0, region=None):
    """Small bright specks (1-3 px) at random places (not on true markers)."""
    h, w = img.shape[:2]
    n = rng.poisson(n_mean)
    for _ in range(n):
        if region is None:
            u, v = rng.uniform(0, w - 1), rng.uniform(0, h - 1)
        else:
            u, v = rng.uniform(region[0], region[2]), rng.uniform(region[1], region[3])
        if any((u - a) ** 2 + (v - b) ** 2 < min_dist ** 2 for a, b in avoid_px):
            continue
        r = rng.uniform(0.5, 1.6)
        amp = rng.uniform(120, 255)
        x0, x1 = int(max(u - 4, 0)), int(min(u + 5, w))
        y0, y1 = int(max(v - 4, 0)), int(min(v + 5, h))
        if x1 <= x0 or y1 <= y0:
            continue
        yy, xx = np.mgrid[y0:y1, x0:x1]
        g = np.exp(-((xx - u) ** 2 + (yy - v) ** 2) / (2 * r * r))
        img[y0:y1, x0:x1] = np.maximum(img[y0:y1, x0:x1], (g * amp)[..., None])


def optical_blur(img, blur_sigma: float = 0.55) -> np.ndarray:
    """The lens' blur of one continuous image: a Gaussian of ``blur_sigma`` px, as float32.

    The lens blurs the light arriving at one instant (a progressive frame's,
    or one field's of an interlaced frame) before the sensor samples its rows.

    Examples
    --------
    >>> img = np.zeros((5, 5, 3)); img[2, 2] = 100.0
    >>> out = optical_blur(img)
    >>> out.dtype.name, [round(float(x)) for x in out[1:4, 2, 0]]
    ('float32', [10, 52, 10])
    """
    return cv2.GaussianBlur(img.astype(np.float32), (0, 0), blur_sigma) if blur_sigma > 0 else img.astype(np.float32)


def sensor_readout(light: np.ndarray, rng=None, noise: bool = True, noise_sigma: float = 2.2) -> np.ndarray:
    """Sensor noise (read + shot) on the light each pixel received, quantised to uint8 in place.

    Each pixel's noise depends on its own light only: ``sqrt(noise_sigma^2 +
    0.04 max(light, 0))`` times a standard normal draw from ``rng``.

    Examples
    --------
    >>> sensor_readout(np.array([[[-3.0, 12.4, 300.0]]], np.float32), noise=False).tolist()
    [[[0, 12, 255]]]
    """
    out = light
    if noise:
        # sig = sqrt(noise_sigma^2 + 0.04 max(out, 0)); out += sig * N(0, 1): in place (the same
        # float32 operations in the same order as the expression, fewer full-frame temporaries)
        sig = np.clip(out, 0, None)
        sig *= 0.04
        sig += noise_sigma ** 2
        np.sqrt(sig, out=sig)
        z = rng.standard_normal(out.shape, dtype=np.float32)
        z *= sig
        out += z
    np.rint(out, out=out)
    np.clip(out, 0, 255, out=out)
    return out.astype(np.uint8)


def finish(img, rng=None, noise: bool = True, blur_sigma: float = 0.55, noise_sigma: float = 2.2) -> np.ndarray:
    """Optical blur (:func:`optical_blur`), sensor noise and quantisation (:func:`sensor_readout`)."""
    return sensor_readout(optical_blur(img, blur_sigma), rng, noise=noise, noise_sigma=noise_sigma)


def interlaced_readout(field_images, field_rows, rng=None, noise: bool = True, blur_sigma: float = 0.55,
                       noise_sigma: float = 2.2) -> np.ndarray:
    """An interlaced frame from its fields' images: each blurred on its own, its rows sampled, noised.

    A camera's lens blurs the continuous image of each field's own instant;
    the sensor then reads that field's rows. So each field's image is
    blurred whole (:func:`optical_blur`), the frame takes field ``f``'s rows
    ``field_rows[f]`` from it, and the sensor's noise and quantisation
    (:func:`sensor_readout`, pixel by pixel) follow. Blurring the interleaved
    frame instead would mix a third of the other field's light into each row.

    Parameters
    ----------
    field_images : sequence of (h, w, 3) float
        Each field's image at the frame's full size (exposure order).
    field_rows : sequence of int arrays
        The image rows each field holds (together every row once).

    Examples
    --------
    Two fields, a bright line (row 3) in the first field's image only: the
    second field's rows 2 and 4 stay dark (no light crosses from the other
    field), where blurring the interleaved frame would light them.

    >>> first = np.zeros((6, 4, 3)); first[3] = 200.0
    >>> second = np.zeros((6, 4, 3))
    >>> out = interlaced_readout([first, second], [np.arange(1, 6, 2), np.arange(0, 6, 2)], noise=False)
    >>> out[:, 0, 0].tolist()
    [0, 0, 0, 144, 0, 0]
    >>> finish(first, noise=False)[:, 0, 0].tolist()
    [0, 0, 28, 144, 28, 0]
    """
    if len(field_images) != len(field_rows):
        raise ValueError(f"interlaced_readout: {len(field_images)} field images but {len(field_rows)} row sets")
    height = field_images[0].shape[0]
    covered = np.sort(np.concatenate([np.asarray(r, int) for r in field_rows]))
    if not np.array_equal(covered, np.arange(height)):
        raise ValueError(f"interlaced_readout: the fields' rows must hold each of the {height} rows once")
    light = np.empty(field_images[0].shape, np.float32)
    for image, rows in zip(field_images, field_rows):
        light[rows] = optical_blur(image, blur_sigma)[rows]
    return sensor_readout(light, rng, noise=noise, noise_sigma=noise_sigma)


def perspective_centroid_bias(cam: Camera, center, normal, radius: float, n: int = 4096) -> np.ndarray:
    """Area centroid of the projected disc minus the projected centre (px).

    Computed from a dense polygon of the projected rim (shoelace moments),
    no rasterisation: the part of the 2D error that is geometry, not pixels.
    """
    poly = cam.project(disc_boundary(center, normal, radius, n))
    x, y = poly[:, 0], poly[:, 1]
    xs, ys = np.roll(x, -1), np.roll(y, -1)
    cr = x * ys - xs * y
    A = cr.sum() / 2
    cx = ((x + xs) * cr).sum() / (6 * A)
    cy = ((y + ys) * cr).sum() / (6 * A)
    return np.array([cx, cy]) - cam.project(np.asarray(center, float))
