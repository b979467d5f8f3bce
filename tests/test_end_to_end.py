"""End-to-end runs of ``horsemocap analyze`` on the bundled virtual session.

One full run writes every file of the spec and is compared with the truth;
then each way a session can be broken ends with a clear message.
"""
import csv
import json
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest

from horsemocap.cli import main
from horsemocap.data import default_session_dir
from horsemocap.sources import FrameSource
from horsemocap.virtuallab import load_truth

SPEC_FILES = ("comfort.csv", "trajectories.csv", "kinematics.csv", "angular.csv", "markers_2d.csv",
              "rig.toml", "analysis.json", "report.html")


@pytest.fixture(scope="module")
def demo_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("demo") / "results"
    assert main(["analyze", str(default_session_dir()), "--out", str(out)]) == 0
    return out


def _comfort(path):
    with open(path) as fh:
        return {r["indicator"]: float(r["value"]) for r in csv.DictReader(fh)}


def test_analyze_writes_every_spec_file(demo_run):
    for name in SPEC_FILES:
        assert (demo_run / name).is_file(), name
    header = (demo_run / "trajectories.csv").read_text().splitlines()[0]
    assert header == "frame,time_s,point,x_m,y_m,z_m"
    points = {r["point"] for r in csv.DictReader(open(demo_run / "trajectories.csv"))}
    assert points == {"marker1", "marker2", "marker3", "saddle"}
    record = json.loads((demo_run / "analysis.json").read_text())
    assert set(record["parameters"]["sync"]["offsets"]) == {"left", "middle", "right"}
    from horsemocap.detection import ACTIVE_PATH
    assert record["software"]["detection_core"] == ACTIVE_PATH == "python"
    assert record["software"]["horsemocap"] and record["software"]["opencv"]
    assert record["chosen"]["pose_smoothing"]["method"] == "gcv"            # the canter is periodic
    assert record["chosen"]["pose_smoothing"]["reason"].startswith("periodic record")


def _comfort_errors(folder):
    truth = load_truth(default_session_dir())
    got = _comfort(folder / "comfort.csv")
    return {key: (got[key], truth.comfort[key], abs(got[key] - truth.comfort[key]) / truth.comfort[key])
            for key in ("acc_y_Wb_rms", "acc_y_Wk_rms", "VDV_y_Wb", "VDV_y_Wk")}


def test_comfort_of_the_thesis_fits_within_5_percent_of_truth(demo_run, tmp_path):
    """The thesis' chain of fits (``kinematics: fits``): the bundled motion is exactly a Fourier series."""
    from horsemocap.pipeline import analyze

    analyze(default_session_dir(), tmp_path / "fits", {"kinematics": "fits"}, progress=lambda *a: None,
            previous_results=demo_run)
    for key, (got, true, rel) in _comfort_errors(tmp_path / "fits").items():
        assert rel < 0.05, f"{key}: {got:.4f} vs truth {true:.4f} ({100 * rel:.1f}%)"


def test_comfort_of_the_default_within_5_percent_of_truth(demo_run):
    """The default pose_spline with the stride's harmonics (``pose_harmonics: auto``)."""
    for key, (got, true, rel) in _comfort_errors(demo_run).items():
        assert rel < 0.05, f"{key}: {got:.4f} vs truth {true:.4f} ({100 * rel:.1f}%)"


def test_directive_three_axes_of_the_default_within_5_percent_of_truth(demo_run):
    """The EU Directive's values from all three axes (``*_directive`` rows of comfort.csv) against the
    virtual saddle's analytic ones (``herd.analytic_indicators``; measured 0.1-1.4 %, lateral 3.4-3.6 %).
    On this canter the fore-aft surge decides: 1.4 a_wx exceeds the vertical a_wk, so the Directive's
    time to the limit value is shorter than the thesis' vertical one."""
    from horsemocap import herd, vibration

    got = vibration.read_comfort_csv(demo_run / "comfort.csv")
    truth = herd.analytic_indicators("Horse 2", "canter")
    for key in vibration.DIRECTIVE_KEYS:
        rel = abs(got[key] - truth[key]) / truth[key]
        assert rel < 0.05, f"{key}: {got[key]:.4f} vs truth {truth[key]:.4f} ({100 * rel:.1f}%)"
    assert 1.4 * got["acc_x_Wd_rms"] > got["acc_y_Wk_rms"]
    assert got["TA_8_limit_directive"] < got["TA_8_limit_Wk"]


def test_comfort_of_plain_pose_splines_within_10_percent_of_truth(demo_run, tmp_path):
    """``pose_harmonics: none`` (plain smoothing splines) lowers the Wb rms of this 38-frame
    session by about 6 % (the smoothing flattens the stride's higher harmonics): within 10 %."""
    from horsemocap.pipeline import analyze

    analyze(default_session_dir(), tmp_path / "plain", {"pose_harmonics": "none"}, progress=lambda *a: None,
            previous_results=demo_run)
    for key, (got, true, rel) in _comfort_errors(tmp_path / "plain").items():
        assert rel < 0.10, f"{key}: {got:.4f} vs truth {true:.4f} ({100 * rel:.1f}%)"


def test_a_repeated_analysis_reuses_the_calibration(demo_run, tmp_path):
    from horsemocap.camera import read_rig
    from horsemocap.pipeline import analyze

    assert (demo_run / "calibration.json").is_file()
    msgs = []
    a = analyze(default_session_dir(), tmp_path / "new", until="rig", previous_results=demo_run,
                progress=lambda step, m: msgs.append(m))
    assert "cached" in a.rig.rig_from and not any("calibrating" in m for m in msgs)
    assert (tmp_path / "new" / "calibration.json").read_bytes() == (demo_run / "calibration.json").read_bytes()
    written = read_rig(demo_run / "rig.toml")
    for cam in written.cameras:
        np.testing.assert_allclose(a.rig.rig[cam.name].matrix, cam.matrix, rtol=1e-12)
        np.testing.assert_allclose(a.rig.rig[cam.name].translation, cam.translation, rtol=1e-12)


def test_params_file_repeats_the_run(demo_run, tmp_path):
    again = tmp_path / "again"
    assert main(["analyze", str(default_session_dir()), "--out", str(again),
                 "--params", str(demo_run / "analysis.json")]) == 0
    a, b = _comfort(demo_run / "comfort.csv"), _comfort(again / "comfort.csv")
    assert a == b
    assert (demo_run / "trajectories.csv").read_text() == (again / "trajectories.csv").read_text()


def test_results_inside_session_are_refused(tmp_path, capsys):
    session = tmp_path / "s"
    shutil.copytree(default_session_dir(), session)
    assert main(["analyze", str(session), "--out", str(session / "results")]) == 2
    assert "lies inside the input session" in capsys.readouterr().err


def _copy_session(tmp_path):
    session = tmp_path / "session"
    shutil.copytree(default_session_dir(), session, ignore=shutil.ignore_patterns("truth"))
    return session


def _motion_path(session, cam):
    doc = json.loads((session / "session.json").read_text())
    return session / doc["motion"][cam]


def test_missing_camera_file(tmp_path, capsys):
    session = _copy_session(tmp_path)
    _motion_path(session, "middle").unlink()
    assert main(["analyze", str(session), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "field 'motion.middle'" in err and "not found" in err


def test_misspelled_field(tmp_path, capsys):
    session = _copy_session(tmp_path)
    doc = json.loads((session / "session.json").read_text())
    doc["marker"] = doc.pop("markers")
    (session / "session.json").write_text(json.dumps(doc))
    assert main(["analyze", str(session), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "unknown field 'marker'; did you mean 'markers'?" in err


def _rewrite_as_folder(session, cam, frames):
    """Replace a camera's video by a folder of PNG frames (lossless)."""
    folder = session / "motion" / f"{cam}_frames"
    folder.mkdir()
    for i, f in enumerate(frames):
        cv2.imwrite(str(folder / f"{cam}{i}.png"), cv2.cvtColor(f, cv2.COLOR_RGB2BGR))
    doc = json.loads((session / "session.json").read_text())
    doc["motion"][cam] = f"motion/{cam}_frames"
    (session / "session.json").write_text(json.dumps(doc))


def test_truncated_video(tmp_path, capsys):
    session = _copy_session(tmp_path)
    truth = load_truth(default_session_dir())
    src = FrameSource(_motion_path(session, "right"))
    keep = truth.offsets["right"] + 5  # the video stops 5 frames after the flash
    path = _motion_path(session, "right")
    frames = src.read(0, keep)
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 30, frames.shape[2:0:-1])
    for f in frames:
        w.write(cv2.cvtColor(f, cv2.COLOR_RGB2BGR))
    w.release()
    out = tmp_path / "out"
    assert main(["analyze", str(session), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "right" in err and ("every camera sees every marker" in err or "truncated" in err), err
    assert (out / "analysis.json").is_file() and (out / "rig.toml").is_file()  # steps before stay written


def _session_with_hidden_marker(tmp_path):
    """The bundled session with marker 2 of the middle camera under a dark patch for 4 frames."""
    session = _copy_session(tmp_path)
    truth = load_truth(default_session_dir())
    cam = "middle"
    frames = FrameSource(_motion_path(session, cam)).read()
    k0 = truth.offsets[cam] + int(truth.ref_frames[len(truth.ref_frames) // 2] - truth.offsets["left"])
    hidden = range(k0, k0 + 4)
    for k in hidden:  # a dark patch over marker 2 (the rider's hand, say)
        u, v = truth.marker_px[cam][k, 1]
        cv2.circle(frames[k], (int(round(u)), int(round(v))), 9, (12, 12, 12), -1)
    _rewrite_as_folder(session, cam, frames)
    return session, truth, cam, hidden


def test_marker_hidden_in_one_camera_is_triangulated_from_the_others(tmp_path, capsys):
    """Multi-view identification (issue 17): the other two cameras still give marker 2 its 3D position."""
    session, truth, cam, hidden = _session_with_hidden_marker(tmp_path)
    out = tmp_path / "out"
    code = main(["analyze", str(session), "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 0, err
    rows = [r for r in csv.DictReader(open(out / "markers_2d.csv")) if r["camera"] == cam and r["marker"] == "marker2"]
    hidden_rows = [r for r in rows if int(r["frame"]) in set(hidden)]
    assert len(hidden_rows) == 4 and all(r["u_px"] == "" for r in hidden_rows)
    assert {r["reason"] for r in hidden_rows} <= {"occluded", "partly_occluded"}, hidden_rows
    ref = [k - truth.offsets[cam] + truth.offsets["left"] for k in hidden]      # reference-camera frames
    rows3d = {int(r["frame"]): r for r in csv.DictReader(open(out / "markers_3d.csv")) if r["marker"] == "marker2"}
    assert all(rows3d[f]["n_views"] == "2" and rows3d[f]["reason"] == "" and rows3d[f]["x_m"] for f in ref)
    record = json.loads((out / "analysis.json").read_text())
    a, b = record["chosen"]["analysed_frames"]
    assert all(a <= k - truth.offsets[cam] < b for k in hidden)     # analysed, not cut around


def test_marker_hidden_with_the_thesis_chain(tmp_path, capsys):
    """The thesis' per-camera chain: the hidden frames are reported and never bridged by a guess."""
    session, truth, cam, hidden = _session_with_hidden_marker(tmp_path)
    out = tmp_path / "out"
    code = main(["analyze", str(session), "--out", str(out), "--detection", "thesis"])
    err = capsys.readouterr().err
    assert (out / "markers_2d.csv").is_file(), err
    rows = [r for r in csv.DictReader(open(out / "markers_2d.csv")) if r["camera"] == cam and r["marker"] == "marker2"]
    missing = {int(r["frame"]) for r in rows if r["u_px"] == ""}
    assert set(hidden) <= missing  # reported as not found, never guessed
    assert "not every marker seen in frames" in err and f"{cam} marker2 occluded" in err
    record = json.loads((out / "analysis.json").read_text())
    a, b = record["chosen"]["analysed_frames"]
    assert not any(a <= k - truth.offsets[cam] < b for k in hidden)  # never bridged by a guess
    if code != 0:  # what is left may be too short for the automatic period: say so and how to go on
        assert "step 'motion_frame'" in err and "--period" in err and "markers_2d.csv" in err
    elif "period not found" in err:  # the period-free motion frame went on; comfort says why it is missing
        assert "comfort indicators not computed" in err
        assert "comfort_not_computed" in record["chosen"] and not (out / "comfort.csv").exists()
        assert (out / "angular.csv").is_file() and "Not computed" in (out / "report.html").read_text()


def _chromium():
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    return None


@pytest.mark.skipif(_chromium() is None, reason="no headless Chromium on this machine (CI installs it)")
def test_report_renders_in_a_headless_browser(demo_run, tmp_path):
    import subprocess

    flags = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
             "--disable-background-networking", "--disable-component-update", "--disable-sync",
             f"--user-data-dir={tmp_path / 'profile'}"]
    url = (demo_run / "report.html").resolve().as_uri()
    dom = subprocess.run([_chromium(), *flags, "--dump-dom", url], capture_output=True, text=True, timeout=120).stdout
    assert "Comfort indicators (thesis Table 8.7)" in dom
    assert dom.count("data:image/png;base64,") >= 4
    assert "acc_y_Wk_rms" in dom
    shot = tmp_path / "shot.png"
    subprocess.run([_chromium(), *flags, "--window-size=1200,2400", f"--screenshot={shot}", url],
                   capture_output=True, timeout=120)
    img = cv2.imread(str(shot))
    assert img is not None and img.shape[0] >= 2000
    # a rendered page is not blank: text and figures give dark pixels over a good part of it
    dark = (img.mean(axis=2) < 128).mean()
    assert dark > 0.005, f"page looks blank ({dark:.4f} dark)"


def test_calibrate_command_on_the_real_stereo_example(tmp_path, capsys):
    from horsemocap.camera import read_rig
    from horsemocap.data import data_samples_dir

    real = data_samples_dir() / "bouguet_stereo"
    out = tmp_path / "rig.toml"
    assert main(["calibrate", str(real / "left"), str(real / "right"), "--board", "9x6",
                 "--square", "0.03", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "Table 8.1" in text and "Focal length" in text
    rig = read_rig(out)
    assert rig.names == ["left", "right"]
    # the toolbox's stereo T is [-99.80198, 1.12443, 0.05041] mm (README of the example)
    assert abs(rig["right"].translation[0] * 1000 + 99.802) < 0.5


def test_calibrate_command_reports_a_bad_board(tmp_path, capsys):
    from horsemocap.data import data_samples_dir

    real = data_samples_dir() / "bouguet_stereo"
    code = main(["calibrate", str(real / "left"), "--board", "nine", "--square", "0.03",
                 "--out", str(tmp_path / "rig.toml")])
    assert code == 2 and "board" in capsys.readouterr().err.lower()


def test_angular_csv_has_the_conditioning_and_saddle_angle_columns(demo_run):
    rows = list(csv.DictReader(open(demo_run / "angular.csv")))
    for col in ("roll_deg", "pitch_deg", "yaw_deg", "singularity_deg", "triangle_height_m", "registration_rms_m"):
        assert col in rows[0], col
    h = np.array([float(r["triangle_height_m"]) for r in rows])
    assert np.all(h > 0.03)                       # the bundled triangle is about 7 cm high
    assert all(0 <= float(r["singularity_deg"]) <= 180 for r in rows)


def test_pose_spline_kinematics_with_the_period_free_motion_frame(tmp_path):
    """The pose-trajectory estimator through the whole pipeline, x-motion from the whole record."""
    from horsemocap import pipeline

    out = tmp_path / "pose"
    an = pipeline.analyze(default_session_dir(), out, {"kinematics": "pose_spline", "motion_frame": "record"},
                          progress=lambda *a: None)
    rb = an.rigid_body
    assert rb.body.pose is not None and rb.body.motion_fit is not None   # both chains
    assert np.all(np.isfinite(rb.saddle_acceleration)) and np.all(np.isfinite(rb.omega))
    assert an.motion_frame.frame.n_periods == 0 and an.motion_frame.period_frames > 0
    record = json.loads((out / "analysis.json").read_text())
    assert record["parameters"]["rigid_body"]["kinematics"] == "pose_spline"
    assert "n_periods" in record["parameters"]["motion_frame"]
    truth = load_truth(default_session_dir())
    got = _comfort(out / "comfort.csv")
    assert abs(got["acc_y_Wk_rms"] - truth.comfort["acc_y_Wk_rms"]) / truth.comfort["acc_y_Wk_rms"] < 0.15
