"""Riding sessions with more markers and with markers partly covered.

A real rig often carries a fourth or fifth marker on the horse's back (one
spare for when another is hidden), and a real ride covers markers in part:
the rider's leg giving an aid, a rein, the rider's hand. This module builds
such sessions on the hard set's scenarios (:mod:`.hard`):

- :func:`horse_with_markers` adds skin markers (body frame) to a herd horse,
  keeping the markers ordered rear to front;
- :class:`Cover` is a dark shape lying on the horse's flank in front of one
  marker (a boot, a rein, a gloved hand), drawn only in the cameras it names
  and only over a time span. It covers the part of the marker's disc beyond
  a chord at a chosen direction and depth (``fraction`` of its area), so the
  visible part's centroid is pulled away from the marker's centre the same
  way in every camera that sees the cover (consistent across views: a vote
  of cameras does not find it);
- :class:`CoverScenario` names a session: a hard scenario, the extra
  markers and the covers; :func:`cover_session` renders it into the cache
  on demand.

The truth marks a covered marker ``"occluded_in_camera"`` in the frames and
cameras it is covered in, and ``extras["cover_fraction__<name>__<camera>"]``
holds the covered share of its disc per frame.
"""
from __future__ import annotations

import hashlib
import json
import math
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from ..camera import Camera
from .hard import HARD_SESSIONS, HARD_VERSION, HardScenario, _r, plan, render_hard
from .herd import RENDER_VERSION, free_running_timings, scenario_session, timing_render_versions
from .horse import HERD, Horse
from .noise import MarkerNoise
from .render import fill_polygon
from .session import MARKER_DIAMETER, Scene

#: Bumped whenever the covered sessions' rendering changes (part of the cache key).
COVERS_VERSION = 1
#: Colours of the covers: a dark boot, a leather rein, a dark glove.
COVER_RGB = {"leg": (22.0, 20.0, 20.0), "rein": (70.0, 45.0, 28.0), "hand": (35.0, 32.0, 30.0)}


def _unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def horse_with_markers(horse: Horse, extra_body, extra_normals=None) -> Horse:
    """A herd horse with more skin markers, all ordered rear to front (body x).

    Parameters
    ----------
    horse : Horse
    extra_body : (k, 3) array_like
        The added markers' centres in the body frame (x forward, y down,
        z lateral; the camera-facing flank at negative z).
    extra_normals : (k, 3) array_like, optional
        Their disc normals (default: facing the cameras, -z, tilted a little up).

    Examples
    --------
    >>> h = horse_with_markers(HERD["Horse 2"], [[-0.86, -0.02, -0.28]])
    >>> h.marker_body.shape, float(h.marker_body[0, 0])
    ((4, 3), -0.86)
    """
    extra = np.atleast_2d(np.asarray(extra_body, float))
    if extra.shape[1] != 3:
        raise ValueError(f"extra_body: expected (k, 3) body-frame points, got shape {extra.shape}")
    normals = (np.tile(_unit([0.0, 0.12, -1.0]), (len(extra), 1)) if extra_normals is None
               else _unit(np.atleast_2d(np.asarray(extra_normals, float))))
    body = np.vstack([horse.marker_body, extra])
    nrm = np.vstack([horse.marker_normal, normals])
    order = np.argsort(body[:, 0], kind="stable")
    return replace(horse, marker_body=body[order], marker_normal=nrm[order])


def segment_depth(fraction: float) -> float:
    """Distance of the chord (in disc radii) beyond which ``fraction`` of a disc's area lies.

    Examples
    --------
    >>> abs(segment_depth(0.5)) < 1e-9, round(segment_depth(0.0), 6), round(segment_depth(1 / 3), 3)
    (True, 1.0, 0.265)
    """
    f = float(np.clip(fraction, 0.0, 1.0))
    lo, hi = -1.0, 1.0
    for _ in range(60):       # area beyond d: (acos d - d sqrt(1 - d^2)) / pi, decreasing in d
        d = 0.5 * (lo + hi)
        area = (math.acos(d) - d * math.sqrt(1 - d * d)) / math.pi
        lo, hi = (d, hi) if area > f else (lo, d)
    return 0.5 * (lo + hi)


@dataclass(frozen=True)
class Cover:
    """Something lying on the flank over part of one skin marker, seen by some cameras.

    Attributes
    ----------
    marker : int
        Skin marker covered (0 = rear).
    cameras : tuple of str
        The cameras that see the cover (the others' line of sight passes it).
    start_s, duration_s : float
        When (s after the flash) and for how long; the cover slides in and
        out over ``ramp_s`` at both ends.
    fraction : float
        Largest share of the disc's area covered (0-1).
    angle_deg : float
        Direction, in the body's x-y plane (0 = forward, 90 = down), from the
        marker's centre towards the cover.
    kind : str
        ``"leg"`` (a boot: everything beyond the chord), ``"rein"`` (a band
        ``band`` radii wide whose near edge is the chord) or ``"hand"`` (a
        glove: a blob two radii wide beyond the chord).
    band : float
        The rein's width in disc radii.
    ramp_s : float
    name : str
    """

    marker: int = 1
    cameras: tuple = ("left", "middle")
    start_s: float = 1.0
    duration_s: float = 0.32
    fraction: float = 0.33
    angle_deg: float = 90.0
    kind: str = "leg"
    band: float = 0.6
    ramp_s: float = 0.06
    name: str = "cover"

    def fraction_at(self, t) -> np.ndarray:
        """Covered share of the disc at times ``t`` (0 outside the span)."""
        t = np.atleast_1d(np.asarray(t, float))
        a, b = self.start_s, self.start_s + self.duration_s
        r = max(self.ramp_s, 1e-9)
        ramp = np.clip(np.minimum(t - a, b - t) / r, 0.0, 1.0)
        return self.fraction * ramp

    def _polygon_body(self, scene: Scene, fraction: float) -> np.ndarray:
        """The cover's outline in the body frame, just in front of the marker's disc."""
        h = scene.motion.horse
        c, n = np.asarray(h.marker_body[self.marker], float), _unit(h.marker_normal[self.marker])
        ang = math.radians(self.angle_deg)
        e1 = np.array([math.cos(ang), math.sin(ang), 0.0])
        e1 = _unit(e1 - (e1 @ n) * n)
        e2 = np.cross(n, e1)
        R = MARKER_DIAMETER / 2
        d = segment_depth(fraction)
        if self.kind == "rein":
            a0, a1, w = d, d + self.band, 4.0
        elif self.kind == "hand":
            a0, a1, w = d, d + 2.2, 1.2
        else:
            a0, a1, w = d, d + 4.0, 3.0
        corners = [(a0, -w), (a0, w), (a1, w), (a1, -w)]
        lift = 0.004 * n               # in front of the disc (the normal faces the cameras)
        return np.array([c + lift + R * (a * e1 + b * e2) for a, b in corners])

    def draw(self, img, scene: Scene, cam: Camera, t: float, exposure_s: float):
        if cam.name not in self.cameras:
            return
        f = float(self.fraction_at(t)[0])
        if f <= 0:
            return
        pose = scene.motion.pose(np.array([t]))
        body = self._polygon_body(scene, f)
        world = pose.position[0] + body @ pose.rotation[0].T
        fill_polygon(img, cam.project(world), COVER_RGB.get(self.kind, COVER_RGB["leg"]))

    def hides(self, scene: Scene, cam: Camera, t, marker_px) -> np.ndarray:
        out = np.zeros(marker_px.shape[:2], bool)
        if cam.name in self.cameras:
            out[:, self.marker] = self.fraction_at(t) > 0
        return out

    def truth(self, scene: Scene, offsets: dict, n_frames: dict, fps: float) -> dict:
        out = {f"cover_{self.name}": asdict(self)}
        for cam in self.cameras:
            t = (np.arange(n_frames[cam]) - offsets[cam]) / fps
            out[f"cover_fraction__{self.name}__{cam}"] = self.fraction_at(t)
        return out


@dataclass(frozen=True)
class CoverScenario:
    """A hard scenario with more skin markers and covers.

    ``extra_markers``: body-frame centres added to the horse's three
    (:func:`horse_with_markers`); ``covers``: :class:`Cover` s whose
    ``start_s`` is a FRACTION (0-1) of the fully visible run at which the
    cover starts (placed when the session is planned); ``drop_markers``:
    skin markers (indices after adding) left off the horse, for the same
    session with fewer markers; ``marker_noise``: correlated centroid noise
    and biases of the cameras (:class:`.noise.MarkerNoise`, none by default);
    ``free_running``: cameras that run free, their timings draw number
    ``free_running`` of :func:`.herd.free_running_timings` (set 0; none by
    default: the cameras expose together).
    """

    name: str
    base: HardScenario
    extra_markers: tuple = ()
    covers: tuple = ()
    drop_markers: tuple = ()
    exercises: str = ""
    marker_noise: MarkerNoise | None = None
    free_running: int | None = None

    def horse(self) -> Horse:
        h = HERD[self.base.horse]
        if self.extra_markers:
            h = horse_with_markers(h, self.extra_markers)
        if self.drop_markers:
            keep = [i for i in range(len(h.marker_body)) if i not in set(self.drop_markers)]
            h = replace(h, marker_body=h.marker_body[keep], marker_normal=h.marker_normal[keep])
        return h

    def to_dict(self) -> dict:
        out = {"name": self.name, "base": self.base.to_dict(),
               "extra_markers": [list(map(float, m)) for m in self.extra_markers],
               "covers": [asdict(c) for c in self.covers],
               "drop_markers": list(self.drop_markers), "exercises": self.exercises}
        if self.marker_noise is not None:          # absent otherwise: the sessions without it keep their keys
            out["marker_noise"] = self.marker_noise.to_dict()
        if self.free_running is not None:          # likewise
            out["free_running"] = int(self.free_running)
        return json.loads(json.dumps(out))


def adapt_scene(sc: CoverScenario, covers=()):
    """``scene -> scene`` for :func:`horsemocap.virtuallab.hard.plan`: the scenario's horse and ``covers``."""
    horse = sc.horse()
    noise = None if sc.marker_noise is None else replace(sc.marker_noise, frame_rate_hz=float(sc.base.fps))

    def adapt(scene: Scene) -> Scene:
        scene = replace(scene, motion=replace(scene.motion, horse=horse), extras=tuple(scene.extras) + tuple(covers))
        return scene if noise is None else replace(scene, marker_noise=noise)
    return adapt


def placed_covers(sc: CoverScenario) -> tuple:
    """The scenario's covers with ``start_s`` in seconds after the flash (from its fully visible run)."""
    if not sc.covers:
        return ()
    truth = plan(sc.base, adapt_scene(sc))["truth"]
    ref = truth.ref_frames - truth.offsets["left"]
    if len(ref) < 8:
        raise ValueError(f"cover scenario {sc.name!r}: only {len(ref)} fully visible frames")
    t0, t1 = ref[0] / sc.base.fps, ref[-1] / sc.base.fps
    out = []
    for c in sc.covers:
        start = t0 + float(c.start_s) * max(t1 - t0 - c.duration_s, 0.0)
        out.append(replace(c, start_s=start))
    return tuple(out)


def scenario_timing(sc: CoverScenario) -> dict | None:
    """The cameras' timings of ``sc`` (camera -> :class:`.timing.CameraTiming`), None when they expose together.

    Examples
    --------
    >>> t = scenario_timing(COVER_SESSIONS["ride4_canter"])
    >>> sorted(t), t["left"].phase_frames
    (['left', 'middle', 'right'], 0.0)
    >>> scenario_timing(COVER_SESSIONS["leg4_canter"]) is None
    True
    """
    if sc.free_running is None:
        return None
    return free_running_timings(0, int(sc.free_running), float(sc.base.fps))


def render_covered(out_dir, sc: CoverScenario, *, noise: bool = True, compress: bool = True) -> Path:
    """Render one cover scenario into ``out_dir`` (a session folder with its truth)."""
    covers = placed_covers(sc)
    meta = {"cover_scenario": sc.to_dict(), "exercises": sc.exercises}
    return render_hard(out_dir, replace(sc.base, name=sc.name), noise=noise, compress=compress,
                       metadata=meta, adapt=adapt_scene(sc, covers), timing=scenario_timing(sc))


def cover_key(sc: CoverScenario) -> str:
    """Cache key: the scenario, the horse and the renderer versions (and the timings' when the cameras run free)."""
    parts = {"v": COVERS_VERSION, "hard": HARD_VERSION, "render": RENDER_VERSION,
             "scenario": sc.to_dict(), "horse": sc.horse().to_dict()}
    timing = scenario_timing(sc)
    if timing is not None:                    # absent otherwise: the other sessions keep their keys
        parts.update({"timing": {c: t.to_dict() for c, t in timing.items()}, **timing_render_versions(timing)})
    blob = json.dumps(parts, sort_keys=True)
    return hashlib.sha256(blob.encode()).hexdigest()[:12]


#: Croup and lower-flank markers added to the horse's three (body frame, m).
CROUP = (-0.86, -0.02, -0.28)
LOWER_FLANK = (-0.26, 0.20, -0.34)
#: A marker high on the back behind the saddle pad's cantle (body frame, m): with it the rig spreads over the
#: flank's height instead of lying along one line.
UPPER_BACK = (-0.48, -0.16, -0.29)
#: Marker-centroid noise of the spread rigs' sessions: correlated over frames, with per-camera biases.
RIG_NOISE = MarkerNoise(sigma_px=0.15, rho=0.8, bias_px=0.1)


#: Marker-centroid noise of the hard set's noisy sessions (``noisy_<hard session>``): the level the herd was measured
#: with (``bench_marker_noise.py --herd``), AR(1) over each session's own frames.
HARD_NOISE = MarkerNoise(sigma_px=0.1, rho=0.8, bias_px=0.05)


#: More rides of the spread rigs (gait, horse, seed, suffix): the same horse, gait, cameras' layout, markers and
#: marker noise as ``spread4_<gait>`` / ``spread5_<gait>``, with another seed. The herd horse's gait is the same
#: periodic motion; the seed places the cameras anew within the layout's tolerances (so the record starts a few
#: frames off, at another phase of the stride) and draws new image noise and new marker noise and biases. The
#: session ``spread5_canter_b`` is ``spread5_canter``'s rig on ride ``b``.
SPREAD_RIDES = (("canter", "Horse 2", 3141, "b"), ("rising_trot", "Horse 1", 3142, "b"),
                ("canter", "Horse 2", 3151, "c"), ("rising_trot", "Horse 1", 3152, "c"),
                ("canter", "Horse 2", 3161, "d"), ("rising_trot", "Horse 1", 3162, "d"),
                ("canter", "Horse 2", 3171, "e"), ("rising_trot", "Horse 1", 3172, "e"),
                ("canter", "Horse 2", 3181, "f"), ("rising_trot", "Horse 1", 3182, "f"))


def _base(name, horse, gait, seed, fps=50.0, strides=3.0, **kw) -> HardScenario:
    return HardScenario(name, horse, gait, seed, fps, _r("720p", "toed_in", 0.6, 0.8), strides=strides,
                        enter_time_s=0.6, **kw)


def _scenarios():
    out = []
    for gait, horse, seed in (("canter", "Horse 2", 3101), ("rising_trot", "Horse 1", 3102)):
        b = _base(f"markers_{gait}", horse, gait, seed)
        out.append(CoverScenario(f"four_{gait}", b, (CROUP,), exercises=f"four markers, {gait}"))
        out.append(CoverScenario(f"five_{gait}", b, (CROUP, LOWER_FLANK), exercises=f"five markers, {gait}"))
        out.append(CoverScenario(f"three_{gait}", b, exercises=f"the same ride with the three markers, {gait}"))
    for gait, horse, seed in (("canter", "Horse 2", 3131), ("rising_trot", "Horse 1", 3132)):
        b = _base(f"spread_{gait}", horse, gait, seed)
        out.append(CoverScenario(f"spread4_{gait}", b, (UPPER_BACK,), marker_noise=RIG_NOISE,
                                 exercises=f"four markers spread over the flank's height, marker noise, {gait}"))
        out.append(CoverScenario(f"spread5_{gait}", b, (UPPER_BACK, LOWER_FLANK), marker_noise=RIG_NOISE,
                                 exercises=f"five markers spread over the flank's height, marker noise, {gait}"))
    for gait, horse, seed, ride in SPREAD_RIDES:
        b = _base(f"spread_{gait}_{ride}", horse, gait, seed)
        out.append(CoverScenario(f"spread4_{gait}_{ride}", b, (UPPER_BACK,), marker_noise=RIG_NOISE,
                                 exercises=f"spread4_{gait} on another ride ({ride}): its own ride and noise draw"))
        out.append(CoverScenario(f"spread5_{gait}_{ride}", b, (UPPER_BACK, LOWER_FLANK), marker_noise=RIG_NOISE,
                                 exercises=f"spread5_{gait} on another ride ({ride}): its own ride and noise draw"))
    for gait, horse, seed in (("walk", "Horse 3", 3111), ("sitting_trot", "Horse 4", 3112),
                              ("rising_trot", "Horse 2", 3113), ("canter", "Horse 1", 3114)):
        b = _base(f"cover_{gait}", horse, gait, seed, strides=3.0 if gait != "walk" else 2.6)
        out.append(CoverScenario(f"leg_{gait}", b, covers=(
            Cover(marker=2, cameras=("left", "middle"), start_s=0.85, duration_s=0.32, fraction=0.33,
                  angle_deg=60.0, kind="leg", name="leg"),), exercises=f"the rider's leg over a third of the "
                  f"front marker in the left and middle cameras for 0.32 s near the record's end, {gait}"))
        # the same ride and leg with a fourth marker on the croup (the front marker is then index 3)
        out.append(CoverScenario(f"leg4_{gait}", b, (CROUP,), covers=(
            Cover(marker=3, cameras=("left", "middle"), start_s=0.85, duration_s=0.32, fraction=0.33,
                  angle_deg=60.0, kind="leg", name="leg"),), exercises=f"leg_{gait} with a fourth marker on the "
                  "croup"))
    b = _base("cover_rein", "Horse 2", "sitting_trot", 3121)
    out.append(CoverScenario("rein_sitting_trot", b, covers=(
        Cover(marker=1, cameras=("middle", "right"), start_s=0.5, duration_s=0.4, fraction=0.25, angle_deg=-80.0,
              kind="rein", band=0.5, name="rein"),), exercises="a rein across the middle marker in two cameras"))
    b = _base("cover_hand", "Horse 3", "canter", 3122)
    out.append(CoverScenario("hand_canter", b, (CROUP,), covers=(
        Cover(marker=0, cameras=("left", "middle"), start_s=0.3, duration_s=0.3, fraction=0.4, angle_deg=180.0,
              kind="hand", name="hand"),), exercises="four markers; the rider's hand over the croup marker"))
    out += ride_scenarios()
    out += noisy_hard_scenarios()
    return {s.name: s for s in out}


#: A rider's own session at each gait (gait, horse, seed): everything real cameras and markers do at once.
RIDES = (("walk", "Horse 4", 3201), ("sitting_trot", "Horse 3", 3202), ("rising_trot", "Horse 2", 3203),
         ("canter", "Horse 1", 3204))


def ride_scenarios(noise: MarkerNoise = RIG_NOISE) -> list:
    """Sessions as a rider's own would be: ``ride4_<gait>`` for each of :data:`RIDES`.

    Four markers (the horse's three and one high on the back, :data:`UPPER_BACK`),
    free-running cameras (phases, rates and rolling shutters drawn, draw 300 + the
    gait's place in :data:`RIDES`), marker-centroid noise correlated over frames
    with per-camera biases (``noise``), and the rider's leg over a third of the
    front marker in the left and middle cameras for 0.32 s near the record's end.

    Examples
    --------
    >>> [(sc.name, len(sc.horse().marker_body), sc.free_running) for sc in ride_scenarios()][:2]
    [('ride4_walk', 4, 300), ('ride4_sitting_trot', 4, 301)]
    """
    out = []
    for k, (gait, horse, seed) in enumerate(RIDES):
        b = _base(f"ride_{gait}", horse, gait, seed, strides=3.0 if gait != "walk" else 2.6)
        leg = Cover(marker=3, cameras=("left", "middle"), start_s=0.85, duration_s=0.32, fraction=0.33,
                    angle_deg=60.0, kind="leg", name="leg")
        out.append(CoverScenario(f"ride4_{gait}", b, (UPPER_BACK,), covers=(leg,), marker_noise=noise,
                                 free_running=300 + k,
                                 exercises=f"a rider's own session, {gait}: four markers, free-running cameras, "
                                           "correlated marker noise with per-camera biases, the rider's leg over "
                                           "a third of the front marker in two cameras near the record's end"))
    return out


def noisy_hard_scenarios(noise: MarkerNoise = HARD_NOISE, prefix: str = "noisy") -> list:
    """The hard set's sessions (:data:`.hard.HARD_SESSIONS`) with correlated marker noise and their own markers.

    Each is ``<prefix>_<hard name>``: the same ride, cameras, extras and image noise (the hard scenario's seed),
    with ``noise`` added to the markers' drawing (its AR(1) over the session's own frame rate).

    Examples
    --------
    >>> sc = noisy_hard_scenarios()[0]
    >>> sc.name, sc.base.name, sc.marker_noise.sigma_px, sc.extra_markers
    ('noisy_canter720_toedin_60', 'canter720_toedin_60', 0.1, ())
    """
    return [CoverScenario(f"{prefix}_{name}", sc, marker_noise=noise,
                          exercises=f"the hard session {name} with correlated marker noise {noise.to_dict()}")
            for name, sc in HARD_SESSIONS.items()]


#: The sessions of this module (name -> :class:`CoverScenario`).
COVER_SESSIONS = _scenarios()


def cover_session(name: str, cache=None, force: bool = False) -> Path:
    """Path of a cover session, rendering it into the cache if needed (as :func:`.hard.hard_session`)."""
    return scenario_session("cover", name, COVER_SESSIONS, cover_key, render_covered,
                            "horsemocap.virtuallab.covers.cover_session", cache, force)
