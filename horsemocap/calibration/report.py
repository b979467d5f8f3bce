"""Tables 8.1-8.4 as text, and the ``horsemocap calibrate`` command."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..camera import Rig, rotation_matrix, write_rig
from .board import board_points, CalibrationError, detect_views, parse_board
from .bundle import calibrate_camera
from .rig import calibrate_rig, compare_rigs, pair_closure, pairwise_rig, RigCalibration

_TITLES = {"left": "Table 8.1", "middle": "Table 8.2", "right": "Table 8.3"}


def _vec(v, d: int = 5, fmt: str | None = None) -> str:
    fmt = fmt or "{:.%df}" % d
    return "[" + " ".join(fmt.format(float(x)) for x in v) + "]"


def _intrinsic_rows(res, with_k3: bool, d: int) -> list[str]:
    nk = 5 if with_k3 else 4
    return [_vec(res.fc, d), "± " + _vec(res.fc_error, d), _vec(res.cc, d), "± " + _vec(res.cc_error, d),
            _vec(res.kc[:nk], 5), "± " + _vec(res.kc_error[:nk], 5), f"{res.rms:.4f}"]


def _column_widths(columns, width):
    """Each column's width: ``width`` if given, else its longest entry plus two spaces."""
    return [width if width else 2 + max(len(str(x)) for x in col) for col in columns]


def _table_lines(labels, columns, lw, width=None, max_width=None) -> list:
    """Rows ``labels`` (first column, ``lw`` wide) against ``columns`` (each: header, then one entry per
    label after the first); with ``max_width`` the columns are split into blocks of lines no longer than
    that, each block repeating the labels (a table too wide for the page wraps by columns, not mid-number)."""
    ws = _column_widths(columns, width)
    blocks, block, used = [], [], lw
    for j, w in enumerate(ws):
        if block and max_width and used + w > max_width:
            blocks.append(block)
            block, used = [], lw
        block.append(j)
        used += w
    blocks.append(block)
    out = []
    for b, block in enumerate(blocks):
        if b:
            out.append("")
        for i, lab in enumerate(labels):
            out.append((f"{lab:<{lw}s}" + "".join(f"{columns[j][i]:<{ws[j]}s}" for j in block)).rstrip())
    return out


def format_calibration_tables(result: RigCalibration, width: int | None = None, decimals: int = 5,
                              max_width: int | None = None) -> str:
    """The calibration in the layout of thesis Tables 8.1-8.4.

    One table per camera (Tables 8.1-8.3: focal length, principal point and
    distortion with their 3-sigma uncertainties, pixels) with one column per
    calibration the camera took part in: alone, each stereo pair (as the
    thesis reports), and the joint calibration; then Table 8.4 (translation
    in mm with uncertainty, rotation matrix, per pair), and the joint rig's
    poses. ``decimals`` of pixel and mm values: 5 as in the thesis (distortion
    coefficients and rotations in radians always 5). ``width``: every column's width (characters); default: each column as
    wide as its longest entry. ``max_width``: wrap a wider table by columns into blocks of lines no
    longer than that (a notebook's output is about 120 characters wide).
    """
    d = int(decimals)
    with_k3 = any(r.kc_error[4] > 0 for r in result.singles.values())
    labels = ["Focal length", "Focal length uncertainty", "Principal point [u0 v0]",
              "Principal point uncertainty", "Distortion [k1 k2 p1 p2" + (" k3]" if with_k3 else "]"),
              "Distortion uncertainty", "RMS reprojection error (px)"]
    lw = max(len(s) for s in labels) + 2
    out = []
    for n, cam in enumerate(result.cameras):
        cols = [("alone", result.singles[cam])]
        for (a, b), p in result.pairs.items():
            if cam in (a, b):
                cols.append((f"{a} and {b} pair", p.intrinsics[cam]))
        if result.joint is not None:
            cols.append(("joint (all cameras)", result.joint.intrinsics[cam]))
        title = _TITLES.get(cam, f"Table 8.{n + 1}") if len(result.cameras) == 3 else f"Table 8.{n + 1}"
        used = int(result.singles[cam].used.sum())
        out.append(f"{title} Intrinsic parameters of the {cam} camera (pixels; ± = 3 sigma; {used} views)")
        rows = [_intrinsic_rows(c[1], with_k3, d) for c in cols]
        out += _table_lines(["", *labels], [[c[0], *r] for c, r in zip(cols, rows)], lw, width, max_width)
        out.append("")
    if result.pairs:
        keys = list(result.pairs)
        out.append("Table 8.4 Extrinsic parameters of each camera pair (x_b = R x_a + t; mm; ± = 3 sigma)")
        ps = [result.pairs[k] for k in keys]
        cells = [[f"{a} and {b}", _vec(1000 * p.T, d), "± " + _vec(1000 * p.translation_sigma3[1], d),
                  *[_vec(rotation_matrix(p.om)[i], fmt="{:.4f}") for i in range(3)], _vec(p.om, 5),
                  "± " + _vec(p.rotation_sigma3[1], 5), f"{p.rms:.4f}"] for (a, b), p in zip(keys, ps)]
        pair_labels = ["", "Translation vector t", "Translation uncertainty", "Rotation matrix R", "", "",
                       "Rotation vector om (rad)", "Rotation uncertainty", "RMS reprojection error (px)"]
        out += _table_lines(pair_labels, cells, lw, width, max_width)
        out.append("")
    if result.joint is not None:
        j = result.joint
        out.append(f"Joint calibration: camera poses in the {result.reference} camera's frame "
                   f"(x_c = R x_{result.reference} + t; mm; ± = 3 sigma)")
        for i, cam in enumerate(j.cameras):
            if i == 0:
                continue
            out.append(f"  {cam:<8s} t = {_vec(1000 * j.translations[i], d)} ± {_vec(1000 * j.translation_sigma3[i], d)}"
                       f"  om = {_vec(j.rotations[i], 5)} ± {_vec(j.rotation_sigma3[i], 5)}")
        out.append(f"  RMS reprojection error {j.rms:.4f} px over all cameras and views")
        out.append("")
    missing = [f"  {c}: {m}" for c in result.cameras for m in result.views[c].missing()]
    if missing:
        out.append("Views without a usable board:")
        out += missing
    excluded = [f"{c}:{n}" for c in result.cameras
                for n, r in zip(result.singles[c].view_names, result.singles[c].reasons) if r == "excluded"]
    if excluded:
        out.append("Excluded views: " + ", ".join(excluded))
    return "\n".join(out).rstrip() + "\n"


def format_per_view_errors(result: RigCalibration) -> str:
    """RMS reprojection error (px) of every view in every camera, alone and joint."""
    names = result.view_names
    head = f"{'view':<10s}" + "".join(f"{c + ' alone':>14s}" + (f"{c + ' joint':>14s}" if result.joint else "")
                                      for c in result.cameras)
    lines = [head]
    pv = result.per_view_errors()
    for k, n in enumerate(names):
        row = f"{n:<10s}"
        for c in result.cameras:
            a = pv[c]["alone"][k]
            row += f"{a:14.4f}" if np.isfinite(a) else f"{'-':>14s}"
            if result.joint:
                jv = pv[c]["joint"][k]
                row += f"{jv:14.4f}" if np.isfinite(jv) else f"{'-':>14s}"
        lines.append(row)
    return "\n".join(lines) + "\n"


def format_comparison(result: RigCalibration) -> str:
    """Pairwise rig (thesis) against joint rig, and the closure of the third pair."""
    if result.joint is None or not result.pairs:
        raise CalibrationError("the comparison needs both the pairwise and the joint calibration")
    pw = pairwise_rig(result)
    jr = result.joint.rig()
    cmp_ = compare_rigs(pw, jr)
    lines = ["Pairwise rig (each camera alone, placed by its stereo pair with the reference) vs joint rig:",
             f"{'camera':<10s}{'centre diff (mm)':>18s}{'angle diff (deg)':>18s}{'fx, fy diff (%)':>22s}{'cx, cy diff (px)':>20s}"]
    for i, c in enumerate(cmp_.cameras):
        lines.append(f"{c:<10s}{cmp_.center_mm[i]:18.3f}{cmp_.angle_deg[i]:18.4f}"
                     f"{cmp_.focal_pct[i][0]:11.3f}{cmp_.focal_pct[i][1]:11.3f}"
                     f"{cmp_.cc_px[i][0]:10.2f}{cmp_.cc_px[i][1]:10.2f}")
    lines.append(f"{'baseline':<22s}{'pairwise (mm)':>16s}{'joint (mm)':>14s}")
    for (a, b), (x, y) in cmp_.baseline_mm.items():
        lines.append(f"{a + '-' + b:<22s}{x:16.3f}{y:14.3f}")
    for c in pair_closure(result):
        a, b = c["pair"]
        lines.append(f"{a}-{b} pair vs composed from the {result.reference} pairs: "
                     f"{c['translation_mm']:.3f} mm, {c['angle_deg']:.4f} deg")
    return "\n".join(lines) + "\n"


def calibrate_command(camera_dirs: list, board: str, square_m: float, out, *, mode: str = "joint",
                      exclude=None) -> str:
    """``horsemocap calibrate CAMERA_DIR [...] --board COLSxROWS --square METRES --out rig.toml``.

    One folder of checkerboard views per camera (camera name = folder name;
    the same file name in each folder = the same instant; the first folder is
    the reference camera). One folder calibrates one camera. Writes the rig
    atomically (:func:`~horsemocap.camera.write_rig`) and returns the text to
    print: per camera ``fc, cc, kc`` with their uncertainties and the
    reprojection error, in the layout of Tables 8.1-8.4.
    """
    dirs = [Path(d) for d in camera_dirs]
    if not dirs:
        raise CalibrationError("horsemocap calibrate: give at least one folder of checkerboard views")
    for d in dirs:
        if not d.is_dir():
            raise CalibrationError(f"{d}: calibration folder not found")
    names = [d.name for d in dirs]
    if len(set(names)) != len(names):
        raise CalibrationError(f"camera folders must have different names (they name the cameras): {names}")
    if not (square_m > 0):
        raise CalibrationError(f"--square {square_m}: the side of a square must be a positive length in metres")
    inner = parse_board(board)
    image_dirs = dict(zip(names, dirs))
    if len(dirs) == 1:
        views = detect_views(dirs[0], inner, camera=names[0])
        single = calibrate_camera(views, board_points(inner, square_m))
        rig = Rig((single.as_camera(),), {"adjusted": False, "error": round(single.rms, 6)})
        result = RigCalibration(rig, "single", names[0], tuple(names), inner, float(square_m),
                                {names[0]: views}, {names[0]: single}, {}, None, ())
    else:
        result = calibrate_rig(image_dirs, inner, square_m, mode=mode, reference=names[0], exclude=exclude)
    path = write_rig(result.rig, out)
    text = format_calibration_tables(result)
    return text + f"\nwrote {path} ({len(result.rig)} cameras, {result.mode}, RMS {result.rms:.4f} px)\n"
