"""The harder virtual laboratory: sessions the thesis' lab never had.

The herd (:mod:`.herd`) is the thesis' laboratory: 640 x 480 at 30 fps, three
nearly parallel cameras 0.45 m apart, a steady speed. A marker detector that
only ever saw those sessions can be tuned to them without knowing it. The
hard set renders riding sessions that differ in every way a new user's
recording may differ, each with the same exact truth as the herd:

- other rigs (:func:`hard_rig`): 1280 x 720 and 1920 x 1080 sensors, cameras
  spread 0.5-1.2 m apart, *wide* (nearly parallel, small overlap) or
  *toed-in* (converging on the path), a focal length scaled to the sensor so
  the horse fills about the thesis' share of the frame (``focal_per_width``
  1.14 = the thesis' 730 px / 640 px), the thesis' kind of lens distortion;
  one camera may be aimed so the markers pass 10-20 px from its top or bottom
  edge for part of the ride (``RigSpec.border``);
- other frame rates (50, 60, 100 fps): the flash and the sync offsets keep
  their durations in seconds (:func:`horsemocap.virtuallab.session.plan_timeline`);
- a horse that slows down and speeds up: a smooth forward speed change
  ``v(t) = v_mean + dv cos(2 pi (t - t_c) / T)`` (fastest or slowest when it
  passes the rig's centre at ``t_c``) with exact position, velocity and
  acceleration (:attr:`horsemocap.virtuallab.horse.SaddleMotion.speed_change`);
  the vertical and rotational motion stay periodic in the stride, so the
  comfort indicators of the saddle's vertical acceleration stay exact;
- scene extras with their own truth (:class:`Stirrup`, :class:`Reflector`,
  :class:`Occluder`): a shining stirrup iron swinging below the markers, a
  marker-sized reflector on the rider's whip whose image path crosses the
  markers' paths, and a dark blot in front of one camera's lens that hides
  one marker in that camera only for a chosen number of frames (truth
  reason ``"occluded_in_camera"``).

:data:`HARD_SESSIONS` names the set; :func:`hard_session` renders one on
demand into the cache (never into the repository), like
:func:`horsemocap.virtuallab.herd_session`. Every hard session carries its rig
in ``calibration/rig.toml`` (no checkerboard views). The truth's
``extras`` hold each extra's true image path per camera and frame
(``stirrup_px__<camera>``, ``reflector_px__<camera>``, ...) so a test can check
that a detector never labels one of them as a marker.
"""
from __future__ import annotations

import hashlib
import json
import math
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from ..camera import Camera, Rig, rotation_matrix, rotation_vector
from ..data import cache_dir
from .herd import free_running_timings, RENDER_VERSION, render_into_cache, scenario_session, timing_render_versions
from .horse import HERD, Harmonics, marker_height, SaddleMotion
from .render import disc_boundary, draw_disc_blurred, fill_polygon
from .session import (CAMERA_NAMES, EXPOSURE_S, FLASH_POSITION_G, MARKER_DIAMETER, PLUMB_TAIL_G, PLUMB_TIP_G,
                      build_truth, plan_timeline, render_session, Scene)
from .truth import load_truth, save_truth

#: Bumped whenever the hard set's rendering changes (part of the cache key).
HARD_VERSION = 2
SIZES = {"720p": (1280, 720), "1080p": (1920, 1080)}
#: Thesis focal length per image width (730 px / 640 px, Tables 8.1-8.3).
THESIS_FOCAL_PER_WIDTH = 1.14
#: Image colour of the occluding blot (a dark rope or glove close to the lens).
OCCLUDER_RGB = (28.0, 24.0, 22.0)


def _unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def _rng(*parts) -> np.random.Generator:
    return np.random.default_rng(np.random.SeedSequence([int(p) for p in parts]))


# ---------------------------------------------------------------------------
# rigs
# ---------------------------------------------------------------------------

@dataclass(frozen=True)
class RigSpec:
    """A 3-camera rig in the arena's ground frame (X along the path, Y down, Z to the path).

    Attributes
    ----------
    size : (int, int)
        Image width, height (px).
    kind : {"toed_in", "wide"}
        ``toed_in``: every camera aims at the rig's centre on the path;
        ``wide``: the cameras look nearly parallel (as the thesis' did), so
        the views overlap less the wider they stand.
    baseline_m : float
        Spacing of neighbouring cameras along the path (m; thesis ~0.23).
    depth_m : float
        Distance from the cameras to the point they aim at (m).
    height_m : float
        Camera height above ground (m).
    focal_per_width : float
        ``fx / width`` (1.14 = the thesis; smaller = wider angle).
    border : (camera, "top" | "bottom", px) or None
        Aim that camera so that the skin markers' centres come within ``px``
        of that image edge at their closest (the camera is also rolled by
        ``border_roll_deg`` so this happens for part of the ride only).
    border_roll_deg : float
    centre_x_m : float
        Ground X of the middle camera (the static shot stands at X = 0.3).
    """

    size: tuple = (1280, 720)
    kind: str = "toed_in"
    baseline_m: float = 0.6
    depth_m: float = 8.0
    height_m: float = 1.4
    focal_per_width: float = THESIS_FOCAL_PER_WIDTH
    border: tuple | None = None
    border_roll_deg: float = 3.0
    centre_x_m: float = 0.3


def _look_at(C, T, roll):
    """``R`` (camera from ground) of a camera at ``C`` aiming at ``T``, rolled by ``roll`` rad."""
    z = _unit(np.asarray(T, float) - C)
    x = _unit(np.cross([0.0, 1.0, 0.0], z))
    y = np.cross(z, x)
    return rotation_matrix(np.array([0.0, 0.0, roll])) @ np.stack([x, y, z])


def _ground_cameras(spec: RigSpec, seed: int):
    """Per camera ``(name, K, kc, R_cg, C_g)`` (camera from ground, centre in ground)."""
    if spec.kind not in ("toed_in", "wide"):
        raise ValueError(f"RigSpec.kind must be 'toed_in' or 'wide', got {spec.kind!r}")
    w, h = spec.size
    rng = _rng(seed, 41)
    out = []
    aim_h = 1.3
    for i, name in enumerate(CAMERA_NAMES):
        C = np.array([spec.centre_x_m + (i - 1) * spec.baseline_m + rng.uniform(-0.02, 0.02),
                      -spec.height_m + rng.uniform(-0.03, 0.03), rng.uniform(-0.05, 0.05)])
        if spec.kind == "toed_in":
            T = np.array([spec.centre_x_m, -aim_h, spec.depth_m])
        else:
            T = np.array([C[0] + spec.depth_m * math.tan(math.radians(rng.uniform(-1.0, 1.0))),
                          -aim_h, spec.depth_m])
        T = T + np.array([0.0, rng.uniform(-0.05, 0.05), 0.0])
        R = _look_at(C, T, math.radians(rng.uniform(-0.8, 0.8)))
        f = spec.focal_per_width * w * (1 + rng.uniform(-0.01, 0.01))
        K = np.array([[f, 0.0, w / 2 - 0.5 + rng.uniform(-0.012, 0.012) * w],
                      [0.0, f * (1 + rng.uniform(-0.003, 0.003)), h / 2 - 0.5 + rng.uniform(-0.015, 0.015) * h],
                      [0.0, 0.0, 1.0]])
        kc = [rng.uniform(-0.14, -0.11), rng.uniform(0.005, 0.06), rng.uniform(-0.002, 0.002),
              rng.uniform(-0.002, 0.002), 0.0]
        out.append([name, K, kc, R, C])
    return out


def hard_rig(spec: RigSpec = RigSpec(), seed: int = 0) -> tuple[Rig, np.ndarray, np.ndarray]:
    """A wider or toed-in rig at any image size, left camera = world frame.

    Returns
    -------
    rig : Rig
        Cameras ``left``, ``middle``, ``right`` (world = left camera frame).
    R_wg, c_g : ndarray
        The arena's ground frame in the world: ``x_world = R_wg (x_G - c_G)``
        (pass them to :class:`~horsemocap.virtuallab.horse.SaddleMotion`).

    The border aim (``spec.border``) needs the ride and is applied by
    :func:`build_scene`.
    """
    cams = _ground_cameras(spec, seed)
    return _assemble(cams, spec)


def _assemble(cams, spec: RigSpec):
    _, _, _, R_l, C_l = cams[0]
    out = []
    for name, K, kc, R, C in cams:
        out.append(Camera(name, spec.size, K, kc, rotation_vector(R @ R_l.T), R @ (C_l - C)))
    meta = {"adjusted": False, "source": f"virtual laboratory hard rig ({spec.kind}, {spec.size[0]}x{spec.size[1]}, "
                                         f"baseline {spec.baseline_m} m)"}
    return Rig(tuple(out), meta), R_l.copy(), np.asarray(C_l, float).copy()


def _ground_camera(cam_entry, size) -> Camera:
    """One camera with the ground frame as its world (for planning)."""
    name, K, kc, R, C = cam_entry
    return Camera(name, size, K, kc, rotation_vector(R), -R @ C)


# ---------------------------------------------------------------------------
# scene extras
# ---------------------------------------------------------------------------

def _marker_radius_px(cam: Camera, centres: np.ndarray) -> np.ndarray:
    """Approximate image radius (px) of a marker disc at world ``centres`` (n, 3)."""
    z = cam.world_to_camera(centres)[..., 2]
    return cam.focal.mean() * (MARKER_DIAMETER / 2) / z


def _smear_px(scene: Scene, cam: Camera, t, exposure_s, body_point) -> np.ndarray:
    """Image length (px) of a body point's streak over the exposure."""
    if exposure_s <= 0:
        return np.zeros(len(np.atleast_1d(t)))
    t = np.atleast_1d(np.asarray(t, float))
    a = cam.project(scene.motion.pose(t - exposure_s / 2).points(np.asarray(body_point)[None])[0][:, 0])
    b = cam.project(scene.motion.pose(t + exposure_s / 2).points(np.asarray(body_point)[None])[0][:, 0])
    return np.hypot(*(b - a).T)


@dataclass(frozen=True)
class _DiscExtra:
    """A bright flat disc that moves with the horse plus its own motion (base of the extras).

    Subclasses give :meth:`body_position` (body frame, (n, 3)) and
    :meth:`brightness` ((n,) in [0, 1]).
    """

    name: str = "disc"
    diameter_m: float = 0.06
    normal_body: tuple = (0.0, 0.0, -1.0)
    rgb: tuple = (250.0, 250.0, 244.0)

    def body_position(self, t) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError

    def brightness(self, t) -> np.ndarray:
        return np.ones(len(np.atleast_1d(t)))

    def world(self, scene: Scene, t):
        """World centres (n, 3) and normals (n, 3) at times ``t``."""
        t = np.atleast_1d(np.asarray(t, float))
        pose = scene.motion.pose(t)
        b = self.body_position(t)
        pos = pose.position + np.einsum("nij,nj->ni", pose.rotation, b)
        nrm = np.einsum("nij,j->ni", pose.rotation, _unit(self.normal_body))
        return pos, nrm

    def draw(self, img, scene: Scene, cam: Camera, t: float, exposure_s: float):
        n_sub = 7 if exposure_s > 0 else 1
        ts = t + ((np.arange(n_sub) + 0.5) / n_sub - 0.5) * exposure_s
        pos, nrm = self.world(scene, ts)
        px = cam.project(pos)
        w, h = cam.size
        if not np.all(np.isfinite(px)) or px[:, 0].max() < -20 or px[:, 0].min() > w + 20 \
                or px[:, 1].max() < -20 or px[:, 1].min() > h + 20:
            return
        rgb = np.asarray(self.rgb) * float(self.brightness(np.array([t]))[0])
        draw_disc_blurred(img, cam, pos, nrm, self.diameter_m / 2, rgb=tuple(rgb))

    def image_path(self, scene: Scene, cam: Camera, t):
        """True image centre (n, 2) and whether the whole disc is inside the image (n,)."""
        pos, nrm = self.world(scene, t)
        px = cam.project(pos)
        inside = np.array([bool(np.all(cam.in_image(cam.project(disc_boundary(p, q, self.diameter_m / 2, 16)),
                                                    margin=0.5))) for p, q in zip(pos, nrm)])
        return px, inside

    def hides(self, scene: Scene, cam: Camera, t, marker_px) -> np.ndarray:
        """Markers whose image disc this extra overlaps (it is nearer the camera than the flank)."""
        t = np.atleast_1d(np.asarray(t, float))
        pos, _ = self.world(scene, t)
        px = cam.project(pos)
        r_self = cam.focal.mean() * (self.diameter_m / 2) / cam.world_to_camera(pos)[:, 2]
        centres, _ = scene.marker_geometry(scene.motion.pose(t))
        r_m = np.stack([_marker_radius_px(cam, centres[:, j]) for j in range(centres.shape[1])], 1)
        d = np.hypot(*(marker_px - px[:, None, :]).transpose(2, 0, 1))
        return np.nan_to_num(d, nan=np.inf) < r_self[:, None] + r_m + 3.0

    def truth(self, scene: Scene, offsets: dict, n_frames: dict, fps: float) -> dict:
        out = {f"{self.name}_description": self.describe()}
        for cam in scene.rig:
            t = (np.arange(n_frames[cam.name]) - offsets[cam.name]) / fps
            px, inside = self.image_path(scene, cam, t)
            out[f"{self.name}_px__{cam.name}"] = px
            out[f"{self.name}_inside__{cam.name}"] = inside
            out[f"{self.name}_brightness__{cam.name}"] = self.brightness(t)
        return out

    def describe(self) -> dict:
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(self).items()}


@dataclass(frozen=True)
class Stirrup(_DiscExtra):
    """A shining stirrup iron swinging on its leather below the markers.

    Hung from ``pivot_body`` (body frame: x forward, y down, z lateral; the
    camera-facing flank is at z = -0.33) on a leather of ``length_m``, it
    swings about the lateral axis with ``swing_deg`` at the stride frequency
    (its own phase) and its tread flashes as it twists: brightness
    ``0.35 + 0.65 (1 + sin(2 pi f t + shine_phase)) / 2`` of ``rgb`` (marker
    white at the peak). Its disc is marker-sized (``diameter_m``).
    """

    name: str = "stirrup"
    diameter_m: float = 0.065
    pivot_body: tuple = (-0.38, 0.12, -0.42)
    length_m: float = 0.30
    swing_deg: float = 14.0
    stride_hz: float = 1.4
    phase: float = 0.7
    shine_phase: float = 2.0

    def angle(self, t):
        return math.radians(self.swing_deg) * np.sin(2 * math.pi * self.stride_hz * np.asarray(t, float) + self.phase)

    def body_position(self, t) -> np.ndarray:
        a = self.angle(np.atleast_1d(t))
        p = np.asarray(self.pivot_body, float)
        return np.column_stack([p[0] + self.length_m * np.sin(a), p[1] + self.length_m * np.cos(a),
                                np.full(len(a), p[2])])

    def brightness(self, t) -> np.ndarray:
        t = np.atleast_1d(np.asarray(t, float))
        return 0.35 + 0.65 * 0.5 * (1 + np.sin(2 * math.pi * self.stride_hz * t + self.shine_phase))

    def draw(self, img, scene, cam, t, exposure_s):
        # the leather: a dark strap from the pivot to the iron (drawn first)
        pose = scene.motion.pose(np.array([t]))
        b = self.body_position(np.array([t]))[0]
        p = np.asarray(self.pivot_body, float)
        d = _unit(b[:2] - p[:2])
        nrm = np.array([-d[1], d[0]]) * 0.012
        quad = np.array([[*(p[:2] + nrm), p[2]], [*(b[:2] + nrm - d * 0.03), p[2]],
                         [*(b[:2] - nrm - d * 0.03), p[2]], [*(p[:2] - nrm), p[2]]])
        world = pose.position[0] + quad @ pose.rotation[0].T
        fill_polygon(img, cam.project(world), (45.0, 30.0, 20.0))
        super().draw(img, scene, cam, t, exposure_s)


@dataclass(frozen=True)
class Reflector(_DiscExtra):
    """A marker-sized reflective band on the rider's whip, moving across the markers' band.

    Body-frame centre ``(x_c + ax sin(2 pi f t + phx), y_c + ay sin(2 pi f t + phy), z)``
    with its own rhythm ``f`` (the rider's taps): its vertical sweep
    (``y_c +- ay``) covers the skin markers' heights (body y 0.02-0.09), so
    its image path crosses theirs, while it stays ``>= 0.14 m`` ahead of the
    front marker (it never covers one).
    """

    name: str = "reflector"
    diameter_m: float = 0.05
    centre_body: tuple = (0.07, 0.05, -0.46)
    ax: float = 0.06
    ay: float = 0.24
    freq_hz: float = 0.9
    phx: float = 0.3
    phy: float = 0.0

    def body_position(self, t) -> np.ndarray:
        t = np.atleast_1d(np.asarray(t, float))
        w = 2 * math.pi * self.freq_hz * t
        c = np.asarray(self.centre_body, float)
        return np.column_stack([c[0] + self.ax * np.sin(w + self.phx), c[1] + self.ay * np.sin(w + self.phy),
                                np.full(len(t), c[2])])


@dataclass(frozen=True)
class Occluder:
    """A dark blot right in front of one camera's lens hiding one marker there only.

    Something close to one lens (a swaying rope or a glove, within ~0.3 m:
    outside the other cameras' views) covers skin marker ``marker`` (0 = rear)
    in camera ``camera`` in exactly the frames ``first .. first + n - 1``
    counted from the flash (frame ``offsets[camera] + first`` of that camera's
    own numbering), and is out of the way in every other frame. Its image is
    a round blot centred on the marker's streak, ``margin_px`` wider than the
    marker's image plus half its smear, so not one pixel of the marker shows.
    Truth: ``marker_visible`` False, reason ``"occluded_in_camera"`` in those
    frames (and for any other marker the blot would touch).
    """

    camera: str = "right"
    marker: int = 1
    first: int = 60
    n: int = 8
    fps: float = 60.0
    margin_px: float = 4.0
    name: str = "occluder"

    def active(self, cam: Camera, t) -> np.ndarray:
        i = np.rint(np.atleast_1d(np.asarray(t, float)) * self.fps).astype(int)
        on = (i >= self.first) & (i < self.first + self.n)
        return on & (cam.name == self.camera)

    def blot(self, scene: Scene, cam: Camera, t, exposure_s: float = EXPOSURE_S):
        """Image centre (n, 2) and radius (n,) of the blot."""
        t = np.atleast_1d(np.asarray(t, float))
        body = scene.motion.horse.marker_body[self.marker]
        c = cam.project(scene.motion.pose(t).points(body[None])[0][:, 0])
        centres = scene.motion.pose(t).points(body[None])[0][:, 0]
        r = _marker_radius_px(cam, centres) + 0.5 * _smear_px(scene, cam, t, exposure_s, body) + self.margin_px
        return c, r

    def draw(self, img, scene: Scene, cam: Camera, t: float, exposure_s: float):
        if not self.active(cam, t)[0]:
            return
        c, r = self.blot(scene, cam, np.array([t]), exposure_s)
        ang = np.linspace(0, 2 * np.pi, 48, endpoint=False)
        poly = c[0] + r[0] * np.column_stack([np.cos(ang), np.sin(ang)])
        fill_polygon(img, poly, OCCLUDER_RGB)

    def hides(self, scene: Scene, cam: Camera, t, marker_px) -> np.ndarray:
        t = np.atleast_1d(np.asarray(t, float))
        out = np.zeros(marker_px.shape[:2], bool)
        on = self.active(cam, t)
        if not on.any():
            return out
        c, r = self.blot(scene, cam, t[on])
        centres, _ = scene.marker_geometry(scene.motion.pose(t[on]))
        r_m = np.stack([_marker_radius_px(cam, centres[:, j]) for j in range(centres.shape[1])], 1)
        d = np.hypot(*(marker_px[on] - c[:, None, :]).transpose(2, 0, 1))
        hit = np.nan_to_num(d, nan=np.inf) < r[:, None] + r_m + 1.5
        hit[:, self.marker] = True
        out[on] = hit
        return out

    def truth(self, scene: Scene, offsets: dict, n_frames: dict, fps: float) -> dict:
        cam = scene.rig[self.camera]
        k = np.arange(n_frames[self.camera])
        t = (k - offsets[self.camera]) / fps
        on = self.active(cam, t)
        c, r = self.blot(scene, cam, t)
        c[~on], r[~on] = np.nan, np.nan
        return {"occluder_description": {"camera": self.camera, "marker": self.marker, "first_after_flash": self.first,
                                         "n_frames": self.n,
                                         "frames": (k[on]).tolist()},
                "occluder_px__" + self.camera: c, "occluder_radius_px__" + self.camera: r}


# ---------------------------------------------------------------------------
# scenarios
# ---------------------------------------------------------------------------

@dataclass(frozen=True)
class HardScenario:
    """One session of the hard set.

    Attributes
    ----------
    name : str
    horse, gait : str
        A herd horse and one of its gaits.
    seed : int
    fps : float
    rig : RigSpec
    speed_factor : float
        Mean speed relative to the horse's gait.
    speed_change : (dv_mps, period_s) or None
        ``v(t) = v_mean + dv cos(2 pi (t - t_c) / period)``, ``t_c`` when the
        body reference point passes the middle camera (dv < 0: slowest there).
    stirrup, reflector : bool
    occlusion : (camera, marker, first, n) or None
        :class:`Occluder` (``first`` = frames after the flash).
    sync_deltas_s : (float, float)
        Start delays left->middle, middle->right.
    enter_time_s : float
        When the front skin marker enters the first view (s after the flash).
        The horse's head is ~1.5 m ahead of it: with 0.3 s it is in some
        views before the flash (a bright helmet and bandages moving in while
        the flash goes off, which misleads a flash detector); the sessions
        that set it near ``0.3 + 1.5 m / speed`` let the whole horse enter
        after the flash, as in the thesis' protocol.
    n_motion_frames : int or None
        Frames after the flash (default: ``strides`` stride periods of fully
        visible markers, or until they leave a view, plus 0.15 s).
    strides : float
        Stride periods of fully visible markers to keep (render time).
    exercises : str
        What the session is for.
    plumb : (tip_height_m, length_m) or None
        Where the plumb hangs (at the thesis' X and depth); default: the
        thesis' plumb (0.45 m to 1.85 m high), raised or lowered until every
        camera sees it (an error if none does).
    """

    name: str
    horse: str
    gait: str
    seed: int
    fps: float
    rig: RigSpec
    speed_factor: float = 1.0
    speed_change: tuple | None = None
    stirrup: bool = False
    reflector: bool = False
    occlusion: tuple | None = None
    sync_deltas_s: tuple = (0.45, 0.30)
    n_motion_frames: int | None = None
    enter_time_s: float = 0.3
    strides: float = 3.3
    exercises: str = ""
    plumb: tuple | None = None

    def to_dict(self) -> dict:
        d = asdict(self)
        d["rig"] = asdict(self.rig)
        if d["plumb"] is None:
            del d["plumb"]          # (keeps the cache keys of the scenarios rendered before the field)
        return json.loads(json.dumps(d))


def _ground_points(motion: SaddleMotion, world_pts):
    return np.asarray(world_pts) @ motion.R_wg + motion.c_g


def _enter_x(cams, size, y_g, z_g, margin_px: float = 8.0) -> float:
    """Smallest ground X (at height ``y_g`` and depth ``z_g``) that any camera sees."""
    xs = np.arange(-20.0, 20.0, 0.01)
    pts = np.column_stack([xs, np.full_like(xs, y_g), np.full_like(xs, z_g)])
    first = np.inf
    for c in cams:
        px = _ground_camera(c, size).project(pts)
        ok = np.isfinite(px[:, 0]) & (px[:, 0] > -margin_px) & (px[:, 0] < size[0] + margin_px)
        if ok.any():
            first = min(first, xs[np.argmax(ok)])
    return float(first)


def _motion(sc: HardScenario, cams, R_wg, c_g) -> SaddleMotion:
    h = HERD[sc.horse]
    g = h.gait(sc.gait)
    g = replace(g, speed_mps=g.speed_mps * sc.speed_factor)
    height = marker_height(h)
    front = h.marker_body[2]
    x_in = _enter_x(cams, sc.rig.size, -height + front[1], h.path_depth_m + front[2]) - 0.08
    m = SaddleMotion(h, g, 0.0, height, R_wg=R_wg, c_g=c_g)
    sc_h, sc_hz = Harmonics(), 0.0
    for _ in range(3):
        m = SaddleMotion(h, g, 0.0, height, R_wg=R_wg, c_g=c_g, speed_change=sc_h, speed_change_hz=sc_hz)
        xf = _ground_points(m, m.markers(np.array([sc.enter_time_s]))[0][0, 2])[0]
        x0 = x_in - xf
        m = replace(m, x0=float(x0))
        if sc.speed_change is None:
            break
        # time when the body passes the middle camera's X
        ts = np.arange(0.0, 20.0, 0.002)
        X = _ground_points(m, m.pose(ts).position)[:, 0]
        t_c = float(ts[np.argmin(np.abs(X - sc.rig.centre_x_m))])
        dv, period = sc.speed_change
        w = 2 * math.pi / period
        # D(t) = (dv / w) sin(w (t - t_c))  =>  D'(t) = dv cos(w (t - t_c))
        sc_h = Harmonics((1,), (dv / w,), (-w * t_c,))
        sc_hz = 1.0 / period
    if sc.speed_change is not None:
        m = replace(m, speed_change=sc_h, speed_change_hz=sc_hz)
        xf = _ground_points(m, m.markers(np.array([sc.enter_time_s]))[0][0, 2])[0]
        m = replace(m, x0=float(m.x0 + x_in - xf))
    return m


def _adjust_border(sc: HardScenario, cams, motion: SaddleMotion):
    """Pitch (and roll) the border camera so the markers come within ``px`` of its edge."""
    cam_name, edge, target = sc.rig.border
    i = CAMERA_NAMES.index(cam_name)
    w, h = sc.rig.size
    ts = np.arange(0.0, 12.0, 1.0 / 200)
    mk_g = _ground_points(motion, motion.markers(ts)[0])        # (n, 3, 3)
    roll = math.radians(sc.rig.border_roll_deg) * (1 if edge == "top" else -1)
    cams[i][3] = rotation_matrix(np.array([0.0, 0.0, roll])) @ cams[i][3]
    for _ in range(8):
        cam = _ground_camera(cams[i], sc.rig.size)
        px = cam.project(mk_g)
        horiz = np.all((px[..., 0] > 15) & (px[..., 0] < w - 15), axis=1)
        v = px[horiz][..., 1]
        dist = (v.min() if edge == "top" else (h - 1 - v.max()))
        err = dist - target
        if abs(err) < 0.05:
            break
        # pitching down by d rad moves the image content up by ~ f d px
        d = err / cam.focal[1] * (1 if edge == "top" else -1)
        cams[i][3] = rotation_matrix(np.array([d, 0.0, 0.0])) @ cams[i][3]
    return cams


def build_scene(sc: HardScenario) -> tuple[Scene, dict]:
    """The scene of a hard scenario (rig, motion, extras, flash and plumb places).

    Returns ``(scene, info)``; ``info`` says where the flash and plumb were
    put and the border camera's closest approach.
    """
    cams = _ground_cameras(sc.rig, sc.seed)
    _, R_wg, c_g = _assemble(cams, sc.rig)
    motion = _motion(sc, cams, R_wg, c_g)
    info = {}
    if sc.rig.border is not None:
        # works in the ground frame: the ride (x0, speed change) does not move
        cams = _adjust_border(sc, cams, motion)
    rig, R_wg, c_g = _assemble(cams, sc.rig)
    motion = replace(motion, R_wg=R_wg, c_g=c_g)         # the left camera may have turned
    # flash and plumb: the thesis' places unless a camera cannot see them; then raised
    # to the markers' height band (the plumb hung higher, the flash held up)
    flash_g, tip_g, tail_g = FLASH_POSITION_G.copy(), PLUMB_TIP_G.copy(), PLUMB_TAIL_G.copy()
    for lift in np.arange(0.0, 2.01, 0.05):
        f = FLASH_POSITION_G + [0, -lift, 0]
        if all(_sees(cam, motion, f[None], 25) for cam in rig):
            flash_g = f
            break
    else:
        raise ValueError(f"hard scenario {sc.name!r}: no camera height for the flash is seen by every camera")
    if sc.plumb is not None:
        tip_h, length = sc.plumb
        candidates = [(PLUMB_TIP_G * [1, 0, 1] + [0, -tip_h, 0], PLUMB_TIP_G * [1, 0, 1] + [0, -tip_h - length, 0])]
    else:
        candidates = [(PLUMB_TIP_G + [0, -lift, 0], PLUMB_TAIL_G + [0, -lift, 0]) for lift in np.arange(0.0, 2.01, 0.05)]
        candidates += [(PLUMB_TIP_G + [0, drop, 0], PLUMB_TAIL_G + [0, drop, 0]) for drop in np.arange(0.05, 0.41, 0.05)]
    for tp, tl in candidates:
        if all(_sees(cam, motion, np.vstack([tp, tl]), 25) for cam in rig):
            tip_g, tail_g = tp, tl
            break
    else:
        raise ValueError(f"hard scenario {sc.name!r}: the plumb {'at ' + str(sc.plumb) if sc.plumb else ''} is not "
                         f"seen whole by every camera (give HardScenario.plumb = (tip height, length))")
    extras = []
    if sc.stirrup:
        extras.append(Stirrup(stride_hz=motion.gait.stride_hz, phase=0.3 + sc.seed % 5, shine_phase=1.0 + sc.seed % 3))
    if sc.reflector:
        extras.append(Reflector(phx=0.2 * (sc.seed % 7)))
    if sc.occlusion is not None:
        cam_name, marker, first, n = sc.occlusion
        extras.append(Occluder(cam_name, int(marker), int(first), int(n), float(sc.fps)))
    scene = Scene(rig, motion, int(sc.seed), flash_g=tuple(flash_g), plumb_tip_g=tuple(tip_g),
                  plumb_tail_g=tuple(tail_g), extras=tuple(extras))
    info.update({"flash_g": list(map(float, flash_g)), "plumb_tip_g": list(map(float, tip_g)),
                 "plumb_tail_g": list(map(float, tail_g))})
    return scene, info


def _sees(cam: Camera, motion: SaddleMotion, pts_g, margin) -> bool:
    px = cam.project(motion.ground_to_world_points(pts_g))
    return bool(np.all(cam.in_image(px, margin=margin)))


def exposure_for(fps: float) -> float:
    """The herd's exposure (1/120 s), shortened to 0.8 frame at high frame rates."""
    return min(EXPOSURE_S, 0.8 / fps)


def _with_occluder(sc: HardScenario, scene: Scene, truth) -> Scene:
    """Place the scenario's occluder at its fraction of the fully visible run."""
    cam_name, marker, frac, n = sc.occlusion
    ref = truth.ref_frames - truth.offsets["left"]            # frames after the flash
    if len(ref) < n + 4:
        raise ValueError(f"hard scenario {sc.name!r}: only {len(ref)} fully visible frames, "
                         f"cannot hide a marker for {n}")
    first = int(ref[0] + round(float(frac) * (len(ref) - n)))
    occ = Occluder(cam_name, int(marker), first, int(n), float(sc.fps))
    return replace(scene, extras=tuple(scene.extras) + (occ,))


def plan(sc: HardScenario, adapt=None) -> dict:
    """Everything about a scenario that needs no image: scene, timeline and truth.

    The timeline keeps the durations of the herd's in seconds where it
    matters (flash) and trims the rest to save rendering: the left camera
    starts 0.1 s before the flash, the others ``sync_deltas_s`` later, and
    the record ends 0.15 s after ``strides`` stride periods of frames in
    which every skin marker is inside every image (or after the last such
    frame; unless ``n_motion_frames`` is given).

    Returns a dict with ``scene``, ``offsets``, ``n_frames``, ``truth``
    (:func:`~horsemocap.virtuallab.build_truth`), ``strides_visible`` (fully
    visible stride periods) and ``border_px`` (closest approach of a visible
    skin marker's centre to the image edges, per camera: any edge and top/bottom).
    """
    scene, info = build_scene(sc)
    scene = adapt(scene) if adapt is not None else scene      # e.g. :func:`.covers.adapt_scene`
    left = int(round(0.1 * sc.fps))
    offsets, n_after = plan_timeline(scene, sc.fps, left_offset=left, sync_deltas_s=sc.sync_deltas_s)
    n_frames = {c: offsets[c] + n_after for c in CAMERA_NAMES}
    truth = build_truth(scene, offsets, n_frames, sc.fps)
    if sc.n_motion_frames is not None:
        n_after = int(sc.n_motion_frames)
    elif len(truth.ref_frames):
        last = min(int(truth.ref_frames[-1]),
                   int(truth.ref_frames[0]) + int(math.ceil(sc.strides * sc.fps / scene.motion.gait.stride_hz)))
        n_after = int(last - offsets["left"] + round(0.15 * sc.fps))
    n_frames = {c: offsets[c] + n_after for c in CAMERA_NAMES}
    if sc.occlusion is not None:
        scene = _with_occluder(sc, scene, truth)
    truth = build_truth(scene, offsets, n_frames, sc.fps)
    border = {}
    for cam in scene.rig:
        px = truth.marker_px[cam.name][..., :3, :]
        vis = truth.marker_visible[cam.name][:, :3]
        w, h = cam.size
        d = np.minimum.reduce([px[..., 0], px[..., 1], w - 1 - px[..., 0], h - 1 - px[..., 1]])
        dv = np.minimum(px[..., 1], h - 1 - px[..., 1])
        border[cam.name] = {"any_edge": float(d[vis].min()) if vis.any() else np.nan,
                            "top_bottom": float(dv[vis].min()) if vis.any() else np.nan}
    return {"scene": scene, "info": info, "offsets": offsets, "n_frames": n_frames, "n_after": n_after,
            "truth": truth, "strides_visible": len(truth.ref_frames) / sc.fps * scene.motion.gait.stride_hz,
            "border_px": border}


def _r(size="720p", kind="toed_in", baseline=0.6, focal=THESIS_FOCAL_PER_WIDTH, **kw) -> RigSpec:
    return RigSpec(SIZES[size] if isinstance(size, str) else tuple(size), kind, baseline, focal_per_width=focal, **kw)


#: The hard set. Every session: 3 cameras, truth beside it, rig in calibration/rig.toml.
HARD_SESSIONS = {sc.name: sc for sc in (
    HardScenario("canter720_toedin_60", "Horse 2", "canter", 2001, 60.0, _r("720p", "toed_in", 0.6, 1.0),
                 speed_factor=0.85, speed_change=(-1.0, 3.2), reflector=True,
                 exercises="issue 17's first case: 1280x720, 60 fps, toed-in, canter; slows down mid-view "
                           "and speeds up; a reflector on the whip crossing the markers' band"),
    HardScenario("sitting640_stirrup_30", "Horse 2", "sitting_trot", 2002, 30.0, _r((640, 480), "wide", 0.23),
                 stirrup=True, sync_deltas_s=(53 / 30, 73 / 30),
                 exercises="issue 17's second case: thesis-like 640x480, 30 fps, sitting trot, a shining "
                           "stirrup swinging below the markers"),
    HardScenario("sitting1080_wide_50_occluded", "Horse 3", "sitting_trot", 2003, 50.0, _r("1080p", "wide", 0.4, 1.0),
                 stirrup=True, occlusion=("right", 1, 0.4, 8),
                 exercises="1920x1080, 50 fps, wide nearly parallel rig, sitting trot; the middle marker hidden "
                           "in the right camera for 8 frames; a stirrup"),
    HardScenario("rising720_toedin_100_border", "Horse 1", "rising_trot", 2004, 100.0,
                 _r("720p", "toed_in", 0.8, border=("middle", "bottom", 14.0)), enter_time_s=0.95,
                 exercises="1280x720, 100 fps, toed-in 0.8 m, rising trot; markers within ~14 px of the middle "
                           "camera's bottom edge for part of the ride"),
    HardScenario("canter1080_toedin_50_speed", "Horse 4", "canter", 2005, 50.0, _r("1080p", "toed_in", 1.0, 1.0),
                 speed_factor=0.8, speed_change=(0.9, 3.0), stirrup=True, reflector=True,
                 exercises="1920x1080, 50 fps, toed-in 1.0 m, canter; speeds up mid-view; stirrup and "
                           "reflector together"),
    HardScenario("rising720_wide_60_reflector", "Horse 2", "rising_trot", 2006, 60.0, _r("720p", "wide", 0.5, 1.05),
                 reflector=True, occlusion=("left", 0, 0.6, 15),
                 exercises="1280x720, 60 fps, wide rig, rising trot; the reflector crossing the markers; the "
                           "rear marker hidden in the left camera for 15 frames"),
    HardScenario("sitting720_toedin_100_occluded_border", "Horse 4", "sitting_trot", 2007, 100.0,
                 _r("720p", "toed_in", 1.2, border=("right", "top", 12.0)),
                 speed_change=(-0.5, 2.6), occlusion=("middle", 2, 0.3, 20), plumb=(0.15, 0.95),
                 exercises="1280x720, 100 fps, toed-in 1.2 m (widest), sitting trot; front marker hidden in the "
                           "middle camera for 20 frames; markers within ~12 px of the right camera's top edge "
                           "(so the plumb is a short one, 0.15-1.10 m high); slows down"),
    HardScenario("canter720_wide_50_everything", "Horse 1", "canter", 2008, 50.0,
                 _r("720p", "wide", 0.4, 0.9, border=("left", "bottom", 18.0)),
                 speed_factor=0.8, speed_change=(-0.8, 3.0), stirrup=True, reflector=True,
                 occlusion=("left", 2, 0.5, 5), enter_time_s=0.75,
                 exercises="everything at once: 1280x720, 50 fps, wide rig, canter slowing down, stirrup, "
                           "reflector, front marker hidden in the left camera for 5 frames, markers within "
                           "~18 px of the left camera's bottom edge (the left camera = the world frame)"),
)}


def hard_key(sc: HardScenario) -> str:
    """Cache key of a hard session: the scenario, the horse and the renderer versions."""
    blob = json.dumps({"v": HARD_VERSION, "render": RENDER_VERSION, "scenario": sc.to_dict(),
                       "horse": HERD[sc.horse].to_dict()}, sort_keys=True)
    return hashlib.sha256(blob.encode()).hexdigest()[:12]


def render_hard(out_dir, sc: HardScenario, *, noise: bool = True, compress: bool = True, verbose: bool = False,
                timing: dict | None = None, metadata: dict | None = None, adapt=None) -> Path:
    """Render one hard scenario into ``out_dir`` (a session folder with its truth).

    ``timing``: free-running cameras (see :func:`horsemocap.virtuallab.render_session`);
    ``metadata`` is merged into ``session.json``'s; ``adapt(scene) -> scene``
    changes the planned scene (other markers, covers: :mod:`.covers`).
    """
    t0 = time.perf_counter()
    p = plan(sc, adapt)
    meta = {"hard_scenario": sc.to_dict(), "exercises": sc.exercises}
    meta.update(metadata or {})
    out = render_session(out_dir, sc.horse, sc.gait, sc.seed, noise=noise, compress=compress,
                         n_motion_frames=p["n_after"], calibration_views=0, name=sc.name,
                         left_offset=p["offsets"]["left"], exposure_s=exposure_for(sc.fps), scene=p["scene"],
                         fps=sc.fps, sync_deltas_s=sc.sync_deltas_s, metadata=meta, timing=timing)
    # the plan's extras (where flash and plumb went, the border approach) beside the truth

    truth = load_truth(out)
    extras = dict(truth.extras)
    extras.update({"hard_scenario": sc.to_dict(), "hard_layout": p["info"], "border_px": p["border_px"],
                   "strides_visible": float(p["strides_visible"]), "render_s": time.perf_counter() - t0})
    save_truth(replace(truth, extras=extras), out)
    if verbose:
        print(f"rendered {sc.name} in {time.perf_counter() - t0:.1f} s")
    return out


def hard_session(name: str, cache=None, force: bool = False) -> Path:
    """Path of a hard session, rendering it into the cache if needed.

    Like :func:`horsemocap.virtuallab.herd_session`: the folder is
    ``<cache>/virtuallab/hard-<name>-<key>`` (the key hashes the scenario and
    the renderer versions); it is rendered into a ``.partial`` folder first
    and renamed when complete (a ``.complete`` marker inside).

    Parameters
    ----------
    name : str
        One of :data:`HARD_SESSIONS`.
    cache : path, optional
        Root folder (default :func:`horsemocap.data.cache_dir`).
    force : bool
        Render again even if a complete render exists.
    """
    return scenario_session("hard", name, HARD_SESSIONS, hard_key, render_hard,
                            "horsemocap.virtuallab.hard.hard_session", cache, force)


# ---------------------------------------------------------------------------
# free-running versions
# ---------------------------------------------------------------------------

#: Hard sessions filmed by free-running cameras: name -> (scenario, interlacing order or None).
#: Two of the hard set as they are, the thesis-like one at the NTSC rate 30000/1001 ("30 fps"), and a
#: PAL DV camcorder (720 x 576, 25 frames of two fields, bottom field first) on the thesis-like ride.
FREE_RUNNING_HARD = {
    "free_canter720_toedin_60": (HARD_SESSIONS["canter720_toedin_60"], None),
    "free_canter1080_toedin_50_speed": (HARD_SESSIONS["canter1080_toedin_50_speed"], None),
    "free_sitting640_stirrup_2997": (replace(HARD_SESSIONS["sitting640_stirrup_30"], name="sitting640_stirrup_2997",
                                             fps=30000 / 1001, strides=3.0, sync_deltas_s=(0.45, 0.30)), None),
    "free_pal576_sitting_25_interlaced": (replace(HARD_SESSIONS["sitting640_stirrup_30"], name="pal576_sitting_25",
                                                  fps=25.0, rig=_r((720, 576), "wide", 0.3), strides=3.0,
                                                  sync_deltas_s=(0.45, 0.30),
                                                  exercises="a PAL DV camcorder trio: 720x576, 25 frames of two "
                                                            "interlaced fields (bottom first), sitting trot, stirrup"),
                                          "bottom_first"),
}


def hard_free_running(seed: int = 0, *, names=None, cache=None, force: bool = False, genlocked: bool = False) -> dict:
    """Free-running versions of hard sessions, rendered into the cache on demand.

    Each of :data:`FREE_RUNNING_HARD` (its scenario's rig, ride and extras)
    filmed by cameras whose timings are drawn for set ``seed``
    (:func:`horsemocap.virtuallab.herd.free_running_timings`, numbered after
    the herd's free-running sessions: phases uniform in [0, 1), rates within
    +-100 ppm, rolling-shutter readouts 0-30 ms, or interlaced fields without
    rolling shutter; exposure half a frame). Parameters (``genlocked``: the
    control, the cameras locked together) and result as
    :func:`horsemocap.virtuallab.herd.herd_free_running`.
    """
    names = list(FREE_RUNNING_HARD) if names is None else list(names)
    root = Path(cache) if cache else cache_dir()
    out = {}
    for name in names:
        if name not in FREE_RUNNING_HARD:
            raise ValueError(f"unknown free-running hard session {name!r}; expected one of {sorted(FREE_RUNNING_HARD)}")
        sc, interlaced = FREE_RUNNING_HARD[name]
        timing = free_running_timings(seed, 100 + list(FREE_RUNNING_HARD).index(name), sc.fps, interlaced,
                                      genlocked=genlocked)
        blob = json.dumps({"v": HARD_VERSION, "render": RENDER_VERSION, "scenario": sc.to_dict(),
                           "horse": HERD[sc.horse].to_dict(), "timing": {c: t.to_dict() for c, t in timing.items()},
                           **timing_render_versions(timing)}, sort_keys=True)
        tag = "-genlocked" if genlocked else ""
        folder = root / "virtuallab" / f"{name}{tag}-s{int(seed)}-{hashlib.sha256(blob.encode()).hexdigest()[:12]}"
        out[name] = render_into_cache(
            folder, lambda tmp, sc=sc, t=timing: render_hard(tmp, sc, timing=t, metadata={"free_running_set": int(seed)}),
            "horsemocap.virtuallab.hard.hard_free_running", force)
    return out
