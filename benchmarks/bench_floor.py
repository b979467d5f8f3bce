"""Every hot step against its floor on equal work, in one run (issue 16).

Floors (what nothing doing the same job can beat), each timed in the same
run as the step, the two taking turns, medians of ``--repeat`` rounds, one
OpenCV thread, with the machine's load average (``os.getloadavg``) printed
before and after:

* **detection, equal work**: while a detector runs once, every
  ``cv2.cvtColor`` it calls (input shape) and every image it thresholds and
  labels (``filters._candidates_in``: the gray crop itself) are recorded;
  the floor is ``cvtColor`` on RGB arrays of the same shapes plus
  ``threshold`` + labelling on the same gray crops (for the whole-frame
  search, ``identification._whole_frame_search``: the whole frame
  thresholded and the crops of ``thresholds.bright_crops`` labelled).
  Labelling: ``thresholds.connected_components``, the detectors' own call
  (OpenCV's block-based algorithm, faster in OpenCV 5.0 than the default
  ``cv2.connectedComponentsWithStats`` with int32 labels, same result); the
  ratio against the default call (the floor of the runs before 2026-11-24
  10:00) is printed beside it.
  Ratio = floor time / detector time (1 = no overhead beyond OpenCV).
  Thesis chain: ``detect_markers`` with the parameters of its automatic run
  given back (RGB frames). Identification: the default multi-view
  ``identify_markers`` on gray frames (as the pipeline's decoder gives
  them: no conversion), its 2D stage timed alone (every call of
  ``frame_candidates`` and ``_whole_frame_search`` it made, replayed: the
  equal-work ratio) and whole (3D matching, the rigid model and the
  tracking included: its time per frame, and the 2D floor over it).
  ``--compare-with CHECKOUT`` times that checkout's detectors (thesis chain,
  2D stage replayed) in the same rounds, against the same floor.
  Which path finds the candidates (``horsemocap.detection.ACTIVE_PATH``: the
  compiled core ``_regions.c`` or pure Python) is printed; with the core
  active, the thesis chain, the 2D stage, the whole identification and the
  whole-frame search are also timed by the pure-Python path (the core set
  aside) in the same rounds, against the same floors.
* **detection, whole frame**: the floor is ``cvtColor(RGB2GRAY) + threshold
  + labelling`` of every whole frame the detector was given (what a
  detector without the thesis' sliding window must do).
  Sessions: the bundled one (640 x 480) and the hard 1080p session
  ``canter1080_toedin_50_speed`` (render cache, rendered on first use).
* **whole-frame search**: identification's search of a whole frame
  (``_whole_frame_search``, labelling crops around the bright pixels), the
  same search labelling whole frames (``frame_candidates``) and the floor
  ``threshold`` + labelling of the whole frame, on the first synchronised
  frames (the horse not in view yet).
* **decoding**: reading every frame of every video (gray, as the pipeline
  reads them): the floor of the whole pipeline.
* **joint triangulation** (``reconstruction.triangulate``, all cameras, DLT
  + refinement + consistency check) against ``cv2.undistortPoints`` +
  ``cv2.triangulatePoints`` of one camera pair on the same points (the
  session's identified markers, tiled to ``--points`` points).
* **calibration**: the solve of ``calibrate_rig`` (each camera, the three
  pairs, the joint bundle adjustment) against ``cv2.calibrateCamera`` per
  camera + ``cv2.stereoCalibrate`` per pair on the same detected corners;
  board detection (``detect_views``) timed on its own.
* **the bundled analysis**: ``pipeline.analyze`` into a fresh results
  folder, then again into the same folder (the cached calibration), against
  calibration (board detection + solve) + decoding.

Usage: ``python benchmarks/bench_floor.py [--repeat 3] [--frames 80] [--points 20000]
[--out benchmarks/results/floor.json] [--compare-with CHECKOUT]``
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

HARD_1080 = "canter1080_toedin_50_speed"


def load():
    return tuple(round(x, 2) for x in os.getloadavg())


def rounds(fns: dict, repeat: int) -> dict:
    """Median seconds of each function over ``repeat`` rounds, the functions taking turns."""
    times = {k: [] for k in fns}
    for _ in range(repeat):
        for k, fn in fns.items():
            t0 = time.perf_counter()
            fn()
            times[k].append(time.perf_counter() - t0)
    return {k: float(np.median(v)) for k, v in times.items()}


# ---------------------------------------------------------------------------
# recording what a detector asks of OpenCV
# ---------------------------------------------------------------------------

class Recorder:
    """Patches ``cv2.cvtColor`` and the detectors' labelling calls to record their inputs.

    Thesis chain: every gray crop ``filters._candidates_in`` thresholds and
    labels. Identification: every call of its 2D stage
    (``identification.frame_candidates``: a crop around the predicted
    markers, whose gray crop ``_candidates_in`` records too;
    ``identification._whole_frame_search``: the whole frame thresholded, the
    crops of ``thresholds.bright_crops`` labelled), kept to be replayed.
    """

    def __init__(self):
        self.convert_shapes = []
        self.labelled = []          # (gray crop copy, threshold)
        self.bright = []            # (gray frame, threshold, crops): the whole-frame search's work
        self.calls = []             # (function name, args, kwargs): identification's 2D stage

    def __enter__(self):
        from horsemocap.detection import filters, identification, thresholds, tracking

        self._orig = (cv2.cvtColor, filters._candidates_in, tracking._candidates_in,
                      identification.frame_candidates, identification._whole_frame_search)
        orig_cvt, orig_cand, _, orig_fc, orig_search = self._orig

        def search(gray, threshold, *a, **k):
            self.bright.append((gray, int(threshold), thresholds.bright_crops(gray, threshold)[1]))
            self.calls.append(("_whole_frame_search", (gray, threshold, *a), k))
            return orig_search(gray, threshold, *a, **k)

        inside = []                 # frame_candidates records its crop itself, whichever path labels it

        def frame_cands(*a, **k):
            self.calls.append(("frame_candidates", a, k))
            gray, threshold = a[0], a[1]
            crop = k.get("crop", a[4] if len(a) > 4 else None)
            u0, v0, u1, v1 = filters._clip_crop(crop, gray.shape[1], gray.shape[0])
            if u1 > u0 and v1 > v0:
                self.labelled.append((np.array(gray[v0:v1, u0:u1]), int(threshold)))
            inside.append(1)
            try:
                return orig_fc(*a, **k)
            finally:
                inside.pop()

        def cvt(src, code, *a, **k):
            if code == cv2.COLOR_RGB2GRAY:
                self.convert_shapes.append(src.shape)
            return orig_cvt(src, code, *a, **k)

        def cand(sub, origin, size, threshold, *a, **k):
            if sub.size and not inside:
                self.labelled.append((np.array(sub), int(threshold)))
            return orig_cand(sub, origin, size, threshold, *a, **k)

        cv2.cvtColor = cvt
        filters._candidates_in = cand
        tracking._candidates_in = cand
        identification.frame_candidates = frame_cands
        identification._whole_frame_search = search
        return self

    def __exit__(self, *exc):
        from horsemocap.detection import filters, identification, tracking

        (cv2.cvtColor, filters._candidates_in, tracking._candidates_in, identification.frame_candidates,
         identification._whole_frame_search) = self._orig

    def floor(self, rgb_like: np.ndarray, default_cc: bool = False):
        """A function doing the recorded OpenCV work alone.

        Labelling by ``thresholds.connected_components`` (the detectors' own
        call: OpenCV's block-based algorithm), or with ``default_cc`` by
        ``cv2.connectedComponentsWithStats`` as called by default (slower in
        OpenCV 5.0 with int32 labels; the floor of the earlier runs).
        """
        from horsemocap.detection.thresholds import connected_components

        H, W = rgb_like.shape[:2]
        conv = [rgb_like[:s[0], :s[1]] for s in self.convert_shapes if s[0] <= H and s[1] <= W]
        lab = self.labelled
        bright = self.bright
        label = (lambda b: cv2.connectedComponentsWithStats(b, connectivity=8)) if default_cc else connected_components

        def run():
            for a in conv:
                cv2.cvtColor(a, cv2.COLOR_RGB2GRAY)
            for g, t in lab:
                label(cv2.threshold(g, t, 255, cv2.THRESH_BINARY)[1])
            for g, t, boxes in bright:          # the whole frame thresholded, the crops labelled
                b = cv2.threshold(g, t, 255, cv2.THRESH_BINARY)[1]
                for u0, v0, u1, v1 in boxes:
                    label(b[v0:v1, u0:u1])
        return run

    def replay(self, identification=None, pure_python: bool = False):
        """A function making the recorded calls of identification's 2D stage again (of ``identification``:
        another checkout's module, default this one's; ``pure_python``: by its Python path, the compiled
        core left out, where the module has both)."""
        if identification is None:
            from horsemocap.detection import identification

        calls = [(getattr(identification, name), a, k) for name, a, k in self.calls]

        def run():
            for fn, a, k in calls:
                fn(*a, **k)
        return pure_path(run) if pure_python else run

    def summary(self):
        px_conv = sum(s[0] * s[1] for s in self.convert_shapes)
        px_lab = sum(g.size for g, _ in self.labelled) + sum((b[2] - b[0]) * (b[3] - b[1])
                                                            for _, _, boxes in self.bright for b in boxes)
        return {"conversions": len(self.convert_shapes), "converted_px": int(px_conv),
                "labellings": len(self.labelled) + sum(len(boxes) for _, _, boxes in self.bright),
                "labelled_px": int(px_lab), "whole_frames_searched_in_crops": len(self.bright),
                "thresholded_whole_px": int(sum(g.size for g, _, _ in self.bright)),
                "calls_2d_stage": len(self.calls)}


def whole_frame_floor(rgb_frames: list, thresholds: list):
    from horsemocap.detection.thresholds import connected_components

    def run():
        for frames, t in zip(rgb_frames, thresholds):
            for f in frames:
                g = cv2.cvtColor(f, cv2.COLOR_RGB2GRAY)
                connected_components(cv2.threshold(g, t, 255, cv2.THRESH_BINARY)[1])
    return run


def _active_path() -> str:
    """Which path finds the candidates (``horsemocap.detection.ACTIVE_PATH``; "python" before it existed)."""
    import horsemocap.detection as d
    return getattr(d, "ACTIVE_PATH", "python")


def _core_active() -> bool:
    return _active_path() == "compiled"


def pure_path(fn):
    """``fn`` run by the pure-Python path (the compiled core set aside while it runs)."""
    from horsemocap.detection import regions_core

    def run():
        core, regions_core.CORE = regions_core.CORE, None
        try:
            return fn()
        finally:
            regions_core.CORE = core
    return run


# ---------------------------------------------------------------------------
# the steps
# ---------------------------------------------------------------------------

def prepare(folder, rig=None):
    """Sync, rig (given or from rig.toml), plumb, static and detect of a session."""
    from horsemocap.pipeline import resolve_params, run_steps
    from horsemocap.session import load_session
    from horsemocap.steps import RigResult

    s = load_session(folder)
    p = resolve_params(s)
    if rig is not None:
        synced = run_steps(s, p, {}, ["sync"])
        given = {"sync": synced.sync, "rig": RigResult(rig=rig, rig_from="given")}
        a = run_steps(s, p, given, ["plumb", "static", "detect"])
    else:
        a = run_steps(s, p, {}, ["sync", "rig", "plumb", "static", "detect"])
    return s, a


def bench_detection(name, s, an, n_frames, repeat, out, compare_with=None):
    from horsemocap.detection import DetectionParams, detect_markers, identify_markers
    from horsemocap.sources import FrameSource

    off, n = an.synchronisation.offsets, an.synchronisation.n_frames
    a, b = an.detect.segment
    mid = (a + b) // 2
    k0 = int(np.clip(mid - n_frames // 2, 0, max(n - n_frames, 0)))
    k1 = min(n, k0 + n_frames)
    cams = list(s.cameras)
    rgb = {c: FrameSource(s.motion[c]).read(off[c] + k0, off[c] + k1) for c in cams}
    # the identification reads gray frames, as the pipeline's decoder gives them (FrameSequence, color=False)
    gray = {c: np.stack([cv2.cvtColor(f, cv2.COLOR_RGB2GRAY) for f in rgb[c]]) for c in cams}
    H, W = rgb[cams[0]].shape[1:3]

    # thesis chain, one camera at a time, parameters of its automatic run given back
    given, rec_t = {}, Recorder()
    for c in cams:
        given[c] = detect_markers(rgb[c], s.marker_count).params
    with rec_t:
        for c in cams:
            detect_markers(rgb[c], s.marker_count, given[c])

    def thesis():
        for c in cams:
            detect_markers(rgb[c], s.marker_count, given[c])

    # multi-view identification
    rig, static = an.rig.rig, an.static.static_points
    thr = {}

    def ident():
        idn = identify_markers(gray, rig, static, s.marker_count, params={c: DetectionParams() for c in cams})
        thr.update(idn.thresholds)
    rec_i = Recorder()
    with rec_i:
        ident()

    fns = {}
    pure = _core_active()
    if pure:                    # the same work by the pure-Python path, in the same rounds
        fns["thesis_python"] = pure_path(thesis)
        fns["ident_python"] = pure_path(ident)
        fns["ident_2d_python"] = rec_i.replay(pure_python=True)
    if compare_with:            # the same work by another checkout's detectors, in the same rounds
        other = _other_detection(compare_with)
        given_o = {c: other.DetectionParams.from_dict(given[c].to_dict()) for c in cams}
        fns["thesis_compared"] = lambda: [other.detect_markers(rgb[c], s.marker_count, given_o[c]) for c in cams]
        fns["ident_2d_compared"] = rec_i.replay(other.identification)
    t = rounds({**fns, "thesis": thesis, "thesis_floor_crops": rec_t.floor(rgb[cams[0]][0]),
                "thesis_floor_crops_default_cc": rec_t.floor(rgb[cams[0]][0], default_cc=True),
                "ident": ident, "ident_2d": rec_i.replay(), "ident_floor_crops": rec_i.floor(rgb[cams[0]][0]),
                "ident_floor_crops_default_cc": rec_i.floor(rgb[cams[0]][0], default_cc=True),
                "floor_whole_thesis": whole_frame_floor([rgb[c] for c in cams], [given[c].threshold for c in cams]),
                "floor_whole_ident": whole_frame_floor([rgb[c] for c in cams], [int(thr[c]) for c in cams])},
               repeat)
    per = len(cams) * (k1 - k0)
    rows = {
        "session": name, "size": [W, H], "cameras": len(cams), "frames_per_camera": k1 - k0,
        "thesis_ms_per_frame": 1e3 * t["thesis"] / per,
        "thesis_equal_work_ratio": t["thesis_floor_crops"] / t["thesis"],
        "thesis_equal_work_ratio_default_cc": t["thesis_floor_crops_default_cc"] / t["thesis"],
        "thesis_whole_frame_ratio": t["floor_whole_thesis"] / t["thesis"],
        "thesis_work": rec_t.summary(),
        "ident_ms_per_frame": 1e3 * t["ident"] / per,
        "ident_2d_ms_per_frame": 1e3 * t["ident_2d"] / per,
        "ident_2d_equal_work_ratio": t["ident_floor_crops"] / t["ident_2d"],
        "ident_2d_equal_work_ratio_default_cc": t["ident_floor_crops_default_cc"] / t["ident_2d"],
        "ident_equal_work_ratio": t["ident_floor_crops"] / t["ident"],
        "ident_whole_frame_ratio": t["floor_whole_ident"] / t["ident"],
        "ident_work": rec_i.summary(),
        "bare_whole_ms_per_frame": 1e3 * t["floor_whole_thesis"] / per,
        "seconds": t,
    }
    rows["path"] = _active_path()
    if pure:
        rows["thesis_python_ms_per_frame"] = 1e3 * t["thesis_python"] / per
        rows["thesis_python_equal_work_ratio"] = t["thesis_floor_crops"] / t["thesis_python"]
        rows["ident_python_ms_per_frame"] = 1e3 * t["ident_python"] / per
        rows["ident_2d_python_ms_per_frame"] = 1e3 * t["ident_2d_python"] / per
        rows["ident_2d_python_equal_work_ratio"] = t["ident_floor_crops"] / t["ident_2d_python"]
    if compare_with:
        rows["compared"] = {"code": str(compare_with),
                            "thesis_ms_per_frame": 1e3 * t["thesis_compared"] / per,
                            "thesis_equal_work_ratio": t["thesis_floor_crops"] / t["thesis_compared"],
                            "ident_2d_ms_per_frame": 1e3 * t["ident_2d_compared"] / per,
                            "ident_2d_equal_work_ratio": t["ident_floor_crops"] / t["ident_2d_compared"]}
    print(f"detection, {name} ({W}x{H}, {len(cams)} cameras x {k1 - k0} frames; bare OpenCV whole frame "
          f"{rows['bare_whole_ms_per_frame']:.2f} ms/frame):")
    print(f"  thesis chain         {rows['thesis_ms_per_frame']:7.2f} ms/frame  equal work "
          f"{rows['thesis_equal_work_ratio']:.2f} (default labelling call as floor: "
          f"{rows['thesis_equal_work_ratio_default_cc']:.2f})  whole frame {rows['thesis_whole_frame_ratio']:.2f}"
          f"   ({rec_t.summary()}; path: {rows['path']})")
    print(f"  identification, 2D   {rows['ident_2d_ms_per_frame']:7.2f} ms/frame  equal work "
          f"{rows['ident_2d_equal_work_ratio']:.2f} (default labelling call as floor: "
          f"{rows['ident_2d_equal_work_ratio_default_cc']:.2f})   ({rec_i.summary()}; path: {rows['path']})")
    if pure:
        print(f"  thesis chain, pure-Python path       {rows['thesis_python_ms_per_frame']:7.2f} ms/frame  "
              f"equal work {rows['thesis_python_equal_work_ratio']:.2f} (same rounds)")
        print(f"  identification, 2D, pure-Python path {rows['ident_2d_python_ms_per_frame']:7.2f} ms/frame  "
              f"equal work {rows['ident_2d_python_equal_work_ratio']:.2f} (same rounds)")
    print(f"  identification, all  {rows['ident_ms_per_frame']:7.2f} ms/frame  equal work (2D floor / all) "
          f"{rows['ident_equal_work_ratio']:.2f}  whole frame {rows['ident_whole_frame_ratio']:.2f}"
          + (f"; pure-Python path {rows['ident_python_ms_per_frame']:.2f} ms/frame" if pure else ""), flush=True)
    if compare_with:
        cmp = rows["compared"]
        print(f"  the code of {compare_with}: thesis chain {cmp['thesis_ms_per_frame']:.2f} ms/frame, equal work "
              f"{cmp['thesis_equal_work_ratio']:.2f}; identification, 2D {cmp['ident_2d_ms_per_frame']:.2f} ms/frame, "
              f"equal work {cmp['ident_2d_equal_work_ratio']:.2f}", flush=True)
    out.setdefault("detection", []).append(rows)
    del rgb, gray


def bench_whole_frame(name, s, an, repeat, out, n_frames=150):
    """The whole-frame candidate search (identification's, in crops) against labelling whole frames.

    Frames: the synchronised gray frames of every camera from the start (the
    horse not yet in view: what a long session is mostly made of), up to
    ``n_frames`` per camera, in memory. Rows: ``_whole_frame_search`` (the
    search the identification runs while the horse is out of view),
    ``frame_candidates`` on the whole frame (the same result, labelling the
    whole image) and the floor ``threshold`` + labelling (``connected_components``).
    """
    from horsemocap.detection.identification import AUTO_MIN_CIRCULARITY, GENERIC_AREA, _whole_frame_search, \
        frame_candidates
    from horsemocap.detection.thresholds import connected_components
    from horsemocap.sources import FrameSource

    off, n = an.synchronisation.offsets, an.synchronisation.n_frames
    thr = {c: int(an.detect.detection[c]["threshold"]) for c in s.cameras}
    gray = {c: FrameSource(s.motion[c]).read(off[c], off[c] + min(n, n_frames), color=False) for c in s.cameras}
    area = (GENERIC_AREA[0], None)

    def crops():
        for c in s.cameras:
            for g in gray[c]:
                _whole_frame_search(g, thr[c], area, AUTO_MIN_CIRCULARITY)

    def whole():
        for c in s.cameras:
            for g in gray[c]:
                frame_candidates(g, thr[c], area, AUTO_MIN_CIRCULARITY)

    def floor():
        for c in s.cameras:
            for g in gray[c]:
                connected_components(cv2.threshold(g, thr[c], 255, cv2.THRESH_BINARY)[1])
    fns = {"crops": crops, "whole": whole, "floor": floor}
    if _core_active():          # the search in crops by the pure-Python path, in the same rounds
        fns["crops_python"] = pure_path(crops)
    t = rounds(fns, repeat)
    count = sum(len(g) for g in gray.values())
    row = {"session": name, "frames": count, "path": _active_path(),
           **{f"{k}_ms_per_frame": 1e3 * v / count for k, v in t.items()},
           "crops_ratio": t["floor"] / t["crops"], "whole_ratio": t["floor"] / t["whole"]}
    pure = ""
    if "crops_python" in t:
        row["crops_python_ratio"] = t["floor"] / t["crops_python"]
        pure = f"; pure-Python path in crops {row['crops_python_ms_per_frame']:.2f} ({row['crops_python_ratio']:.2f})"
    print(f"whole-frame search, {name} ({count} frames from the start): in crops {row['crops_ms_per_frame']:.2f} "
          f"ms/frame (floor/step {row['crops_ratio']:.2f}), labelling whole frames {row['whole_ms_per_frame']:.2f} "
          f"({row['whole_ratio']:.2f}), bare threshold + labels {row['floor_ms_per_frame']:.2f}{pure} "
          f"(path: {row['path']})", flush=True)
    out.setdefault("whole_frame_search", []).append(row)


def bench_decode(name, s, repeat, out):
    from horsemocap.sources import FrameSource

    def dec():
        n = 0
        for c in s.cameras:
            for _ in FrameSource(s.motion[c]).iter_frames(color=False):
                n += 1
        return n
    count = dec()
    t = rounds({"decode": dec}, repeat)["decode"]
    row = {"session": name, "camera_frames": count, "seconds": t, "ms_per_frame": 1e3 * t / count,
           "frames_per_s": count / t}
    print(f"decoding, {name}: {count} camera-frames (gray) in {t:.2f} s, {row['ms_per_frame']:.2f} ms/frame, "
          f"{row['frames_per_s']:.0f} frames/s", flush=True)
    out.setdefault("decode", []).append(row)
    return row


def pair_floor(rig, px, a, b):
    """cv2.undistortPoints + cv2.triangulatePoints of cameras a, b on the points both see."""
    def cam_arrays(cam):
        return np.asarray(cam.matrix, float), np.asarray(cam.distortions, float)
    ca, cb = rig[a], rig[b]
    Ka, da = cam_arrays(ca)
    Kb, db = cam_arrays(cb)
    Pa = np.hstack([ca.rotation_matrix, ca.translation[:, None]])
    Pb = np.hstack([cb.rotation_matrix, cb.translation[:, None]])
    pa, pb = px[a].reshape(-1, 2), px[b].reshape(-1, 2)
    ok = np.all(np.isfinite(pa), 1) & np.all(np.isfinite(pb), 1)
    pa, pb = np.ascontiguousarray(pa[ok]), np.ascontiguousarray(pb[ok])

    def run():
        na = cv2.undistortPoints(pa.reshape(-1, 1, 2), Ka, da).reshape(-1, 2)
        nb = cv2.undistortPoints(pb.reshape(-1, 1, 2), Kb, db).reshape(-1, 2)
        X = cv2.triangulatePoints(Pa, Pb, na.T, nb.T)
        return (X[:3] / X[3]).T
    return run, int(ok.sum())


def _other_triangulate(checkout):
    """``triangulate`` of another checkout's ``reconstruction.py`` (e.g. the code before a change)."""
    import importlib.util
    import sys

    spec = importlib.util.spec_from_file_location("horsemocap._compared_reconstruction",
                                                  Path(checkout) / "horsemocap" / "reconstruction.py")
    mod = importlib.util.module_from_spec(spec)
    mod.__package__ = "horsemocap"
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return mod.triangulate


def _other_detection(checkout):
    """``horsemocap.detection`` of another checkout (e.g. the code before a change), as its own package."""
    import importlib
    import importlib.util
    import sys

    name = "horsemocap_compared"
    if name not in sys.modules:
        root = Path(checkout) / "horsemocap"
        spec = importlib.util.spec_from_file_location(name, root / "__init__.py", submodule_search_locations=[str(root)])
        mod = importlib.util.module_from_spec(spec)
        sys.modules[name] = mod
        spec.loader.exec_module(mod)
    return importlib.import_module(name + ".detection")


def bench_triangulation(name, s, an, n_points, repeat, out, compare_with=None):
    from horsemocap.reconstruction import triangulate

    rig = an.rig.rig
    px0 = an.detect.marker_px
    cams = list(s.cameras)
    m = next(iter(px0.values())).shape[1]
    reps = max(1, int(np.ceil(n_points / (len(next(iter(px0.values()))) * m))))
    px = {c: np.tile(np.asarray(px0[c], float), (reps, 1, 1)) for c in cams}
    total = px[cams[0]].shape[0] * m
    seen = int(np.sum(np.sum([np.all(np.isfinite(px[c]), -1) for c in cams], 0) >= 2))
    floor, n_pair = pair_floor(rig, px, cams[0], cams[1])
    fns = {"joint": lambda: triangulate(rig, px), "pair": floor}
    if compare_with:
        other = _other_triangulate(compare_with)
        fns["compared"] = lambda: other(rig, px)
        a, b = triangulate(rig, px), other(rig, px)
        diff = float(np.nanmax(np.abs(a.points - b.points)))
    t = rounds(fns, repeat)
    row = {"session": name, "points": total, "points_two_or_more_views": seen, "pair_points": n_pair,
           "joint_ms_per_1000": 1e3 * t["joint"] / seen * 1000, "pair_ms_per_1000": 1e3 * t["pair"] / n_pair * 1000}
    row["ratio"] = row["joint_ms_per_1000"] / row["pair_ms_per_1000"]
    if compare_with:
        row["compared"] = {"code": str(compare_with), "ms_per_1000": 1e3 * t["compared"] / seen * 1000,
                           "ratio": t["compared"] / seen / (t["pair"] / n_pair), "max_point_difference_m": diff}
        print(f"  the code of {compare_with}: {row['compared']['ms_per_1000']:.2f} ms per 1000 points, "
              f"{row['compared']['ratio']:.2f} x the floor; points differ by {diff:.1e} m at most", flush=True)
    print(f"joint triangulation, {name}: {seen} points seen by two or more cameras; joint "
          f"{row['joint_ms_per_1000']:.2f} ms per 1000 points, OpenCV pair floor {row['pair_ms_per_1000']:.2f} "
          f"ms per 1000 ({n_pair} points): {row['ratio']:.2f} x the floor", flush=True)
    out.setdefault("triangulation", []).append(row)


def bench_calibration(s, repeat, out):
    from horsemocap.calibration import board_points, calibrate_rig, detect_views
    from horsemocap.calibration.rig import align_views

    inner = tuple(s.board.inner_corners)
    sq = s.board.square_size_m
    cams = list(s.cameras)
    views = {}

    def detect():
        views.update({c: detect_views(Path(s.calibration_images[c]), inner, camera=c) for c in cams})
    cal = {}

    def solve():
        cal["r"] = calibrate_rig(None, inner, sq, reference=s.reference_camera, views=dict(views))

    detect()
    al = align_views(dict(views))
    bp = board_points(inner, sq).astype(np.float32)
    W, H = al[cams[0]].size
    found = {c: al[c].found for c in cams}
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-12)

    def floor():
        K = {}
        for c in cams:
            idx = np.flatnonzero(found[c])
            img = [al[c].corners[k].astype(np.float32).reshape(-1, 1, 2) for k in idx]
            _, K[c], d, _, _ = cv2.calibrateCamera([bp] * len(idx), img, (W, H), None, None,
                                                   flags=cv2.CALIB_FIX_K3, criteria=crit)
            K[c] = (K[c], d)
        for i, a in enumerate(cams):
            for b in cams[i + 1:]:
                idx = np.flatnonzero(found[a] & found[b])
                ia = [al[a].corners[k].astype(np.float32).reshape(-1, 1, 2) for k in idx]
                ib = [al[b].corners[k].astype(np.float32).reshape(-1, 1, 2) for k in idx]
                cv2.stereoCalibrate([bp] * len(idx), ia, ib, K[a][0], K[a][1], K[b][0], K[b][1], (W, H),
                                    flags=cv2.CALIB_USE_INTRINSIC_GUESS | cv2.CALIB_FIX_K3, criteria=crit)
    t = rounds({"board_detection": detect, "solve": solve, "opencv": floor}, repeat)
    n_views = sum(len(views[c].names) for c in cams)
    row = {"views": n_views, "board_detection_s": t["board_detection"], "solve_s": t["solve"],
           "opencv_s": t["opencv"], "solve_ratio": t["solve"] / t["opencv"]}
    print(f"calibration, bundled session ({n_views} views): board detection {t['board_detection']:.2f} s "
          f"({1e3 * t['board_detection'] / n_views:.0f} ms/view); solve {t['solve']:.2f} s against "
          f"calibrateCamera x {len(cams)} + stereoCalibrate x pairs {t['opencv']:.2f} s: "
          f"{row['solve_ratio']:.2f} x the floor", flush=True)
    out["calibration"] = row
    return row, cal["r"].rig


def bench_analyze(folder, repeat, out, calibrate_s, decode_s):
    from horsemocap.pipeline import analyze

    times = {"fresh": [], "repeated": []}
    steps = {}
    for _ in range(repeat):
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            a = analyze(folder, tmp, progress=lambda *x: None)
            times["fresh"].append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            b = analyze(folder, tmp, progress=lambda *x: None)
            times["repeated"].append(time.perf_counter() - t0)
            steps = {"fresh": {k: round(v, 3) for k, v in a.timings.items()},
                     "repeated": {k: round(v, 3) for k, v in b.timings.items()}}
    med = {k: float(np.median(v)) for k, v in times.items()}
    row = {"fresh_s": med["fresh"], "repeated_s": med["repeated"], "steps_last_round": steps,
           "calibrate_plus_decode_s": calibrate_s + decode_s,
           "fresh_ratio": med["fresh"] / (calibrate_s + decode_s),
           "repeated_ratio_to_decode": med["repeated"] / decode_s}
    print(f"bundled analyze: fresh {med['fresh']:.2f} s ({row['fresh_ratio']:.2f} x calibrate + decode "
          f"{calibrate_s + decode_s:.2f} s); repeated into the same results folder {med['repeated']:.2f} s "
          f"({row['repeated_ratio_to_decode']:.1f} x decode); steps {steps}", flush=True)
    out["analyze"] = row


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--frames", type=int, default=80, help="frames per camera for detection")
    ap.add_argument("--points", type=int, default=20000, help="points for triangulation (tiled)")
    ap.add_argument("--skip", nargs="*", default=[], choices=["hard", "analyze", "calibration"])
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "floor.json"))
    ap.add_argument("--compare-with", default=None,
                    help="another checkout of horsemocap whose joint triangulation and detectors are timed in the "
                         "same rounds")
    args = ap.parse_args(argv)
    cv2.setNumThreads(1)
    from horsemocap.data import default_session_dir

    out = {"date_utc": time.strftime("%Y-%m-%d %H:%M", time.gmtime()), "machine": platform.machine(),
           "cpus": os.cpu_count(), "opencv": cv2.__version__, "numpy": np.__version__,
           "repeat": args.repeat, "load_before": load()}
    import horsemocap.detection as det
    out["detection_path"] = _active_path()
    print(f"OpenCV {cv2.__version__} (1 thread), numpy {np.__version__}, {os.cpu_count()} cpus; "
          f"load average {out['load_before']}; medians of {args.repeat}; candidate search: "
          f"{getattr(det, 'ACTIVE_REASON', 'pure Python')}", flush=True)
    bundled = default_session_dir()
    from horsemocap.session import load_session
    sb = load_session(bundled)
    cal_row, rig = bench_calibration(sb, args.repeat, out) if "calibration" not in args.skip else (None, None)
    s, an = prepare(bundled, rig)
    dec_b = bench_decode("bundled", s, args.repeat, out)
    bench_detection("bundled", s, an, args.frames, args.repeat, out, args.compare_with)
    bench_whole_frame("bundled", s, an, args.repeat, out)
    bench_triangulation("bundled", s, an, args.points, args.repeat, out, args.compare_with)
    if "hard" not in args.skip:
        from horsemocap.virtuallab.hard import hard_session
        hs, han = prepare(hard_session(HARD_1080))
        bench_decode(HARD_1080, hs, args.repeat, out)
        bench_detection(HARD_1080, hs, han, args.frames, args.repeat, out, args.compare_with)
        bench_whole_frame(HARD_1080, hs, han, args.repeat, out)
        bench_triangulation(HARD_1080, hs, han, args.points, args.repeat, out, args.compare_with)
    if "analyze" not in args.skip and cal_row is not None:
        bench_analyze(bundled, args.repeat, out, cal_row["board_detection_s"] + cal_row["solve_s"],
                      dec_b["seconds"])
    out["load_after"] = load()
    print(f"load average after: {out['load_after']}")
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(out, indent=1, default=float) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
