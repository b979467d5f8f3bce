"""3D input and export: trajectories.csv / C3D / TRC, and the kinematics command."""
from __future__ import annotations

import csv

import numpy as np
import pytest

from horsemocap import io3d, synthetic
from horsemocap.cli import main


def _write_csv(path, t, names, pts):
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["frame", "time_s", "point", "x_m", "y_m", "z_m"])
        for k in range(len(t)):
            for j, nm in enumerate(names):
                w.writerow([k, t[k], nm, *("" if not np.isfinite(v) else repr(float(v)) for v in pts[k, j])])


@pytest.fixture(scope="module")
def ringing(tmp_path_factory):
    d = synthetic.lift_with_ringing(duration_s=2.0, seed=4)
    root = tmp_path_factory.mktemp("io3d")
    names = ["m1", "m2", "m3", "m4"]
    pts = d["markers"].copy()
    pts[30:33, 1] = np.nan                          # a marker hidden for 3 frames
    _write_csv(root / "traj.csv", d["t"], names, pts)
    _write_csv(root / "static.csv", [0.0], names + ["hidden"], np.vstack([d["model"], d["hidden_body"]])[None])
    return d, root


def test_csv_and_c3d_round_trip(ringing, tmp_path):
    d, root = ringing
    tr = io3d.read_trajectories(root / "traj.csv")
    assert tr.names == ("m1", "m2", "m3", "m4") and tr.points.shape == (200, 4, 3)
    assert np.isnan(tr.points[31, 1]).all()
    io3d.write_c3d(tmp_path / "t.c3d", tr)
    back = io3d.read_trajectories(tmp_path / "t.c3d")
    assert back.names == tr.names
    np.testing.assert_allclose(back.points, tr.points, atol=1e-6, equal_nan=True)   # mm in the file
    np.testing.assert_allclose(back.time_s, tr.time_s, atol=1e-9)
    io3d.write_trc(tmp_path / "t.trc", tr)
    text = (tmp_path / "t.trc").read_text().splitlines()
    assert text[0].startswith("PathFileType\t4") and text[2].split("\t")[4] == "mm"


def test_a_c3d_read_to_disk_is_read_whole(ringing, tmp_path):
    """read_trajectories_to_disk: a C3D (upper-case extension too) is read whole, the scratch folder unused."""
    d, root = ringing
    tr = io3d.read_trajectories(root / "traj.csv")
    io3d.write_c3d(tmp_path / "t.C3D", tr)
    (tmp_path / "disk").mkdir()
    back = io3d.read_trajectories_to_disk(tmp_path / "t.C3D", tmp_path / "disk")
    assert back.info["format"] == "c3d" and not isinstance(back.points, np.memmap)
    np.testing.assert_array_equal(back.points, io3d.read_trajectories(tmp_path / "t.C3D").points)
    assert list((tmp_path / "disk").iterdir()) == []
    csv_back = io3d.read_trajectories_to_disk(root / "traj.csv", tmp_path / "disk")
    assert isinstance(csv_back.points, np.memmap)


def test_kinematics_command_recovers_the_hidden_point(ringing, tmp_path, capsys):
    d, root = ringing
    out = tmp_path / "kin"
    assert main(["kinematics", str(root / "traj.csv"), "--static", str(root / "static.csv"), "--out", str(out)]) == 0
    rows = [r for r in csv.DictReader(open(out / "kinematics.csv")) if r["point"] == "hidden"]
    acc = np.array([[float(r[c]) for c in ("ax_mps2", "ay_mps2", "az_mps2")] for r in rows])
    err = np.sqrt(np.mean(np.sum((acc - d["hidden_acc"]) ** 2, 1))) / np.sqrt(np.mean(np.sum(d["hidden_acc"] ** 2, 1)))
    assert err < 0.5            # the ringing record's acceleration (bench_kinematics measures it precisely)
    ang = list(csv.DictReader(open(out / "angular.csv")))
    assert "registration_rms_m" in ang[0] and ang[31]["wx_radps"] != ""      # 3 markers left: a pose


def test_bad_files_name_file_and_field(tmp_path, capsys):
    bad = tmp_path / "bad.csv"
    bad.write_text("frame,time_s,point,x_m,y_m,z_m\n0,0.0,m1,1.0,oops,2\n")
    with pytest.raises(io3d.TrajectoryFileError, match=r"bad.csv: line 2: field 'y_m'"):
        io3d.read_trajectories_csv(bad)
    hdr = tmp_path / "hdr.csv"
    hdr.write_text("frame,time,point,x,y,z\n")
    with pytest.raises(io3d.TrajectoryFileError, match="hdr.csv: header lacks"):
        io3d.read_trajectories_csv(hdr)
    junk = tmp_path / "junk.c3d"
    junk.write_bytes(b"not a c3d file")
    assert main(["kinematics", str(junk), "--static", str(hdr), "--out", str(tmp_path / "o")]) == 2
    assert "junk.c3d" in capsys.readouterr().err


def test_collinear_static_shot_is_refused(tmp_path, capsys):
    t = np.arange(20) / 100
    line = np.array([[0.0, 0, 0], [0.2, 0, 0], [0.4, 0, 0]])
    pts = line[None] + t[:, None, None] * [1.0, 0, 0]
    _write_csv(tmp_path / "tr.csv", t, ["a", "b", "c"], pts)
    _write_csv(tmp_path / "st.csv", [0.0], ["a", "b", "c", "s"], np.vstack([line, [[0.1, 0.1, 0]]])[None])
    assert main(["kinematics", str(tmp_path / "tr.csv"), "--static", str(tmp_path / "st.csv"),
                 "--out", str(tmp_path / "o")]) == 2
    assert "collinear" in capsys.readouterr().err


def test_kinematics_command_takes_known_events(tmp_path, capsys):
    """--events: a known onset (issue 13's ringing fixture, onset 2.8 s) reaches the pose smoothing and
    brings the hidden point's acceleration closer to the truth; a time outside the record is refused
    with the option's name."""
    d = synthetic.lift_with_ringing(seed=0)
    names = ["m1", "m2", "m3", "m4"]
    _write_csv(tmp_path / "traj.csv", d["t"], names, d["markers"])
    _write_csv(tmp_path / "static.csv", [0.0], names + ["hidden"], np.vstack([d["model"], d["hidden_body"]])[None])

    def error(*extra):
        out = tmp_path / ("kin" + "_".join(extra))
        assert main(["kinematics", str(tmp_path / "traj.csv"), "--static", str(tmp_path / "static.csv"),
                     "--out", str(out), "--smoothing", "adaptive", *extra]) == 0
        rows = [r for r in csv.DictReader(open(out / "kinematics.csv")) if r["point"] == "hidden"]
        acc = np.array([[float(r[c]) for c in ("ax_mps2", "ay_mps2", "az_mps2")] for r in rows])
        return np.sqrt(np.mean(np.sum((acc - d["hidden_acc"]) ** 2, 1)) / np.mean(np.sum(d["hidden_acc"] ** 2, 1)))

    without, with_onset = error(), error("--events", "2.8")
    assert with_onset < without - 0.02          # measured 18.9 -> 15.5 % on this draw (seed 0)
    assert main(["kinematics", str(tmp_path / "traj.csv"), "--static", str(tmp_path / "static.csv"),
                 "--out", str(tmp_path / "bad"), "--events", "9.5"]) == 2
    assert "events" in capsys.readouterr().err


def test_kinematics_events_on_a_periodic_record_with_the_default_smoothing(tmp_path, capsys):
    """--events with the default gcv smoothing on a record in which a stride period is found: the
    record is smoothed without stride harmonics (events and harmonics are not fitted together), not
    refused with a setting the command does not have."""
    d = synthetic.lift_with_ringing(seed=0)
    t, rng = d["t"], np.random.default_rng(0)
    y = 0.05 * np.sin(2 * np.pi * 1.7 * t) + 0.02 * np.sin(2 * np.pi * 3.4 * t + 1)   # a 1.7 Hz stride
    pts = d["model"][None] + np.stack([0.1 * t, y, 0 * t], 1)[:, None, :] + rng.normal(0, 3e-4, (t.size, 4, 3))
    names = ["m1", "m2", "m3", "m4"]
    _write_csv(tmp_path / "traj.csv", t, names, pts)
    _write_csv(tmp_path / "static.csv", [0.0], names + ["hidden"], np.vstack([d["model"], d["hidden_body"]])[None])
    tr = io3d.read_trajectories(tmp_path / "traj.csv")
    st = io3d.read_trajectories(tmp_path / "static.csv")
    assert io3d.kinematics_from_trajectories(tr, st)["trajectory"].smoothing["cy"].get("harmonics", 0) > 0
    res = io3d.kinematics_from_trajectories(tr, st, events=[2.8])
    assert all(v.get("harmonics", 0) == 0 for v in res["trajectory"].smoothing.values())
    assert main(["kinematics", str(tmp_path / "traj.csv"), "--static", str(tmp_path / "static.csv"),
                 "--out", str(tmp_path / "kin"), "--events", "2.8"]) == 0
    err = capsys.readouterr().err        # what 'auto' ran, and why, is printed
    assert "kinematics: adaptive smoothing (auto: 1 known change point(s), fitted without harmonics; fundamental" in err


# ---------------------------------------------------------------------------
# kinematics --out: analyze's rule (new, empty or an earlier kinematics run), written whole
# ---------------------------------------------------------------------------

def _small_record(folder, first_frame=0, n=60):
    """A rigid triangle + one hidden point moving smoothly: trajectories and static shot CSVs."""
    tri = np.array([[0.0, 0, 0], [0.3, 0, 0], [0.1, 0.25, 0.02]])
    t = np.arange(n) / 100
    move = np.stack([0.5 * t, 0.02 * np.sin(2 * np.pi * 2 * t), 0.01 * np.cos(2 * np.pi * 2 * t)], 1)
    pts = tri[None] + move[:, None, :]
    folder.mkdir(parents=True, exist_ok=True)
    with open(folder / "traj.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["frame", "time_s", "point", "x_m", "y_m", "z_m"])
        for k in range(n):
            for j, nm in enumerate(["a", "b", "c"]):
                w.writerow([first_frame + k, repr(float(t[k] + first_frame / 100)), nm, *map(float, pts[k, j])])
    _write_csv(folder / "static.csv", [0.0], ["a", "b", "c", "s"], np.vstack([tri, [[0.1, 0.1, -0.2]]])[None])
    return folder / "traj.csv", folder / "static.csv"


def _snapshot(folder):
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())} if folder.exists() else None


def _kin(traj, static, out, *extra):
    return main(["kinematics", str(traj), "--static", str(static), "--out", str(out), *map(str, extra)])


@pytest.mark.parametrize("files", [
    {"analysis.json": '{"format": "horsemocap-results/1"}', "trajectories.csv": "frame\n", "report.html": "<p>"},
    {"kinematics.csv": "my own numbers\n"},
    {"kinematics-run.json": '{"format": "another-program/2"}', "angular.csv": "x\n"}],
    ids=["analyze_results", "users_own_csv", "foreign_record"])
def test_kinematics_refuses_a_folder_it_did_not_write(files, tmp_path, capsys):
    traj, static = _small_record(tmp_path / "in")
    out = tmp_path / "out"
    out.mkdir()
    for name, text in files.items():
        (out / name).write_text(text)
    before = _snapshot(out)
    assert _kin(traj, static, out) == 2
    err = capsys.readouterr().err
    assert f"--out {out}: the folder holds files that are not an earlier 'horsemocap kinematics' output" in err
    assert _snapshot(out) == before and sorted(p.name for p in tmp_path.iterdir()) == ["in", "out"]


def test_kinematics_replaces_its_own_earlier_output_whole(tmp_path, capsys):
    import json

    traj, static = _small_record(tmp_path / "in")
    out = tmp_path / "out"
    assert _kin(traj, static, out) == 0
    assert sorted(p.name for p in out.iterdir()) == ["angular.csv", "kinematics-run.json", "kinematics.csv",
                                                    "trajectories.csv"]
    record = json.loads((out / "kinematics-run.json").read_text())
    assert record["format"] == "horsemocap-kinematics/1" and record["command"] == "kinematics"
    assert record["inputs"]["trajectories"]["path"] == str(traj.resolve()) and record["horsemocap_version"]
    (out / "stale.txt").write_text("left by hand")     # a file no run wrote: refused, nothing deleted
    assert _kin(traj, static, out, "--smoothing", "gcv") == 2 and (out / "stale.txt").read_text() == "left by hand"
    (out / "stale.txt").unlink()
    assert _kin(traj, static, out, "--smoothing", "gcv") == 0
    assert json.loads((out / "kinematics-run.json").read_text())["options"]["smoothing"] == "gcv"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in", "out"]     # no temporary folder, no lock
    empty = tmp_path / "empty"
    empty.mkdir()
    assert _kin(traj, static, empty) == 0 and (empty / "kinematics.csv").is_file()


def test_kinematics_refuses_an_out_holding_its_input(tmp_path, capsys):
    traj, static = _small_record(tmp_path / "in")
    out = tmp_path / "out"
    assert _kin(traj, static, out) == 0
    before = _snapshot(out)
    assert _kin(out / "trajectories.csv", static, out) == 2
    assert "holds the input TRAJECTORIES" in capsys.readouterr().err
    assert _snapshot(out) == before


def test_kinematics_full_disk_leaves_the_folder_as_before(tmp_path, capsys, monkeypatch):
    import errno
    import os

    from horsemocap import store

    traj, static = _small_record(tmp_path / "in")
    out = tmp_path / "out"
    assert _kin(traj, static, out) == 0
    before = _snapshot(out)
    real = store._write_whole

    def full(path, write, *how):
        if path.name == "angular.csv":
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))
        return real(path, write, *how)

    monkeypatch.setattr(store, "_write_whole", full)
    assert _kin(traj, static, out, "--smoothing", "adaptive") == 2   # other numbers than auto (gcv here)
    err = capsys.readouterr().err
    assert f"cannot write {out / 'angular.csv'}: No space left on device" in err and "Traceback" not in err
    assert _snapshot(out) == before and sorted(p.name for p in tmp_path.iterdir()) == ["in", "out"]


# ---------------------------------------------------------------------------
# export: the first frame number and the frame rate
# ---------------------------------------------------------------------------

def test_export_keeps_the_first_frame_number(tmp_path, capsys):
    """Frames 29..67 stay 29..67 in the C3D (header first frame, read back by ezc3d and by
    ``horsemocap kinematics`` on the C3D) and in the TRC (OrigDataStartFrame)."""
    import ezc3d

    traj, static = _small_record(tmp_path / "in", first_frame=29, n=39)
    c3d, trc = tmp_path / "x.c3d", tmp_path / "x.trc"
    assert main(["export", str(traj), "--out", str(c3d)]) == 0
    assert main(["export", str(traj), "--out", str(trc)]) == 0
    header = ezc3d.c3d(str(c3d))["header"]["points"]
    assert (header["first_frame"], header["last_frame"], header["frame_rate"]) == (29, 67, 100.0)
    assert trc.read_text().splitlines()[2].split("\t")[6] == "30"     # 1-based, as the C3D header
    back = io3d.read_trajectories(c3d)
    np.testing.assert_array_equal(back.frame, np.arange(29, 68))
    assert main(["kinematics", str(c3d), "--static", str(static), "--out", str(tmp_path / "kin")]) == 0
    frames = lambda f: sorted({int(r["frame"]) for r in csv.DictReader(open(f))})     # noqa: E731
    assert frames(tmp_path / "kin" / "trajectories.csv") == frames(traj) == list(range(29, 68))
    assert [int(r["frame"]) for r in csv.DictReader(open(tmp_path / "kin" / "angular.csv"))] == list(range(29, 68))


def test_export_fills_missing_frame_numbers_with_gaps(tmp_path):
    """A CSV without frame 35 (29..40): the C3D has 12 frames, frame 35 a gap of every point."""
    traj, _ = _small_record(tmp_path / "in", first_frame=29, n=12)
    rows = [ln for ln in traj.read_text().splitlines() if not ln.startswith("35,")]
    traj.write_text("\n".join(rows) + "\n")
    tr = io3d.read_trajectories(traj)
    io3d.write_c3d(tmp_path / "g.c3d", tr)
    back = io3d.read_trajectories(tmp_path / "g.c3d")
    np.testing.assert_array_equal(back.frame, np.arange(29, 41))
    assert np.isnan(back.points[35 - 29]).all() and np.isfinite(back.points[[0, 5, 7, 11]]).all()
    np.testing.assert_allclose(back.points[7], tr.points[6], atol=1e-6)   # frame 36
    assert io3d.frame_rate(tr) == pytest.approx(100.0)


def test_one_frame_export_needs_a_rate(tmp_path, capsys):
    traj, _ = _small_record(tmp_path / "in", first_frame=7, n=1)
    for ext in ("c3d", "trc"):
        out = tmp_path / f"one.{ext}"
        assert main(["export", str(traj), "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert "a single frame: its frame rate is unknown" in err and "--rate" in err and str(traj) in err
        assert not out.exists()
        assert main(["export", str(traj), "--out", str(out), "--rate", "120"]) == 0
    import ezc3d

    assert ezc3d.c3d(str(tmp_path / "one.c3d"))["header"]["points"]["frame_rate"] == 120.0
    assert (tmp_path / "one.trc").read_text().splitlines()[2].split("\t")[:1] == ["120"]
    assert main(["export", str(traj), "--out", str(tmp_path / "bad.trc"), "--rate", "0"]) == 2
    assert "frame rate 0.0: expected a positive number" in capsys.readouterr().err
    many, _ = _small_record(tmp_path / "many")       # 100 Hz in its times: a rate they contradict is refused
    assert main(["export", str(many), "--out", str(tmp_path / "r.c3d"), "--rate", "50"]) == 2
    assert "--rate 50 Hz contradicts the times" in capsys.readouterr().err and not (tmp_path / "r.c3d").exists()
    assert main(["export", str(many), "--out", str(tmp_path / "r.c3d"), "--rate", "100"]) == 0
    assert ezc3d.c3d(str(tmp_path / "r.c3d"))["header"]["points"]["frame_rate"] == 100.0
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".")) == []   # no temporary file


def test_c3d_export_takes_any_case_and_a_new_folder_like_trc(tmp_path):
    """``X.C3D`` (ezc3d appends ".c3d" to any other name) is written whole with nothing left beside it, and a
    missing folder is created as for TRC; a C3D that cannot be written names the file, not its temporary."""
    from horsemocap.store import WriteError

    traj, _ = _small_record(tmp_path / "in", n=12)
    tr = io3d.read_trajectories(traj)
    out = tmp_path / "new" / "X.C3D"
    io3d.write_c3d(out, tr)
    assert sorted(p.name for p in out.parent.iterdir()) == ["X.C3D"]
    np.testing.assert_allclose(io3d.read_trajectories(out).points, tr.points, atol=1e-6)
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    with pytest.raises(WriteError, match=r"cannot write .*file/a\.c3d"):
        io3d.write_c3d(blocker / "a.c3d", tr)


# ---------------------------------------------------------------------------
# QA pass on the 3D input/export path
# ---------------------------------------------------------------------------

def _header_words(path):
    """Words 4 and 5 of a C3D header (bytes 6-9, little-endian for the Intel files written here)."""
    import struct

    raw = open(path, "rb").read(512)
    return struct.unpack("<HH", raw[6:10])


def _hidden_acc(out):
    rows = [r for r in csv.DictReader(open(out / "kinematics.csv")) if r["point"] == "hidden"]
    return np.array([[float(r[c]) for c in ("ax_mps2", "ay_mps2", "az_mps2")] for r in rows])


def test_c3d_keeps_the_time_origin_of_the_csv(tmp_path, capsys):
    """A CSV whose time_s starts at 1.00 s -> C3D -> kinematics --events 3.8: the same numbers as from the
    CSV (before: the C3D's times started at 0 and the onset landed 1 s late, silently)."""
    import json

    d = synthetic.lift_with_ringing(seed=0)
    names = ["m1", "m2", "m3", "m4"]
    t = d["t"] + 1.0
    _write_csv(tmp_path / "traj.csv", t, names, d["markers"])
    _write_csv(tmp_path / "static.csv", [0.0], names + ["hidden"], np.vstack([d["model"], d["hidden_body"]])[None])
    assert main(["export", str(tmp_path / "traj.csv"), "--out", str(tmp_path / "traj.c3d")]) == 0
    back = io3d.read_trajectories(tmp_path / "traj.c3d")
    np.testing.assert_array_equal(back.time_s, io3d.read_trajectories(tmp_path / "traj.csv").time_s)   # exactly
    assert back.info["time_origin"].startswith("parameter HORSEMOCAP:FIRST_TIME 1.0")
    capsys.readouterr()
    for src in ("csv", "c3d"):
        assert main(["kinematics", str(tmp_path / f"traj.{src}"), "--static", str(tmp_path / "static.csv"),
                     "--out", str(tmp_path / src), "--smoothing", "adaptive", "--events", "3.8"]) == 0
    err = capsys.readouterr().err
    assert f"{tmp_path / 'traj.c3d'}: 400 frames 0..399, time 1 .. 4.99 s (origin: parameter HORSEMOCAP:FIRST_TIME" in err
    np.testing.assert_allclose(_hidden_acc(tmp_path / "c3d"), _hidden_acc(tmp_path / "csv"), atol=1e-3)
    # (an onset 4e-16 s before the sample at 3.8 s gives 23.1 % instead of 15.5 %: the times must be exact)
    rec = json.loads((tmp_path / "c3d" / "kinematics-run.json").read_text())["input"]
    assert rec["time_s"] == [1.0, pytest.approx(4.99)] and rec["units"] == "mm" and rec["scale_to_m"] == 1e-3
    assert rec["rate_hz"] == 100.0 and "HORSEMOCAP:FIRST_TIME" in rec["time_origin"]
    assert rec["axes"] == "the input file's axes; omega in those axes"
    rec = json.loads((tmp_path / "csv" / "kinematics-run.json").read_text())["input"]
    assert rec["units"] == "m" and rec["rate_hz"] == pytest.approx(100.0) and rec["time_s"][0] == 1.0


def test_c3d_keeps_times_at_a_rate_a_4_byte_real_cannot_hold(tmp_path):
    """29.97 Hz (POINT:RATE is stored as 29.9699993): HORSEMOCAP:RATE keeps the times (the 4-byte rate
    alone drifted 1.5 us over 2000 frames); a POINT:RATE changed by another program wins over it."""
    import ezc3d

    n = 2000
    t = 0.29 + np.arange(n) / 29.97
    tr = io3d.Trajectories(t, 7 + np.arange(n), ("a",), np.zeros((n, 1, 3)), "x")
    io3d.write_c3d(tmp_path / "r.c3d", tr)
    back = io3d.read_c3d(tmp_path / "r.c3d")
    np.testing.assert_allclose(back.time_s, t, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(back.frame, tr.frame)
    c = ezc3d.c3d(str(tmp_path / "r.c3d"))
    c["parameters"]["POINT"]["RATE"]["value"] = [60.0]
    c.write(str(tmp_path / "edited.c3d"))
    assert io3d.read_c3d(tmp_path / "edited.c3d").info["rate_hz"] == 60.0


def test_c3d_without_our_parameter_counts_time_from_frame_one(tmp_path):
    """Nexus' convention: time = (1-based frame - 1) / rate; frame = 1-based frame - 1."""
    import ezc3d

    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [50.0]
    c["parameters"]["POINT"]["LABELS"]["value"] = ["a", "b"]
    c.add_parameter("POINT", "UNITS", ["mm"])
    c["header"]["points"]["first_frame"] = 100          # ezc3d: 0-based; the header word: 101
    c["data"]["points"] = np.ones((4, 2, 5))
    c.write(str(tmp_path / "n.c3d"))
    assert _header_words(tmp_path / "n.c3d") == (101, 105)
    tr = io3d.read_c3d(tmp_path / "n.c3d")
    np.testing.assert_array_equal(tr.frame, np.arange(100, 105))
    np.testing.assert_allclose(tr.time_s, np.arange(100, 105) / 50.0, rtol=0, atol=1e-15)
    assert tr.time_s[0] == 2.0 and "1-based frame - 1" in tr.info["time_origin"]


def test_frame_numbers_against_the_raw_header(tmp_path):
    """horsemocap frame k = C3D/TRC 1-based frame k+1: frames 29..67 -> header words 30 and 68, TRC
    OrigDataStartFrame 30 and Frame# 30..68; read back as 29..67."""
    traj, _ = _small_record(tmp_path / "in", first_frame=29, n=39)
    assert main(["export", str(traj), "--out", str(tmp_path / "x.c3d")]) == 0
    assert main(["export", str(traj), "--out", str(tmp_path / "x.trc")]) == 0
    assert _header_words(tmp_path / "x.c3d") == (30, 68)
    lines = (tmp_path / "x.trc").read_text().splitlines()
    assert lines[2].split("\t")[6] == "30"
    assert [int(ln.split("\t")[0]) for ln in lines[6:]] == list(range(30, 69))
    np.testing.assert_array_equal(io3d.read_trajectories(tmp_path / "x.c3d").frame, np.arange(29, 68))
    assert io3d.c3d_header(tmp_path / "x.c3d")["first_frame"] == 30


def test_a_truncated_c3d_is_refused(tmp_path):
    traj, _ = _small_record(tmp_path / "in", n=400)
    io3d.write_c3d(tmp_path / "full.c3d", io3d.read_trajectories(traj))
    raw = (tmp_path / "full.c3d").read_bytes()
    (tmp_path / "cut.c3d").write_bytes(raw[: len(raw) // 2])
    with pytest.raises(io3d.TrajectoryFileError) as err:
        io3d.read_c3d(tmp_path / "cut.c3d")
    msg = str(err.value)
    assert msg.startswith(f"{tmp_path / 'cut.c3d'}: the header says frames 1..400 (400 frames), the file holds data of ")
    held = int(msg.split("data of ")[1].split(":")[0])
    assert 0 < held < 400 and "truncated" in msg


def test_duplicates_are_refused(tmp_path):
    bad = tmp_path / "dup.csv"
    bad.write_text("frame,time_s,point,x_m,y_m,z_m\n0,0.0,m1,1,2,3\n0,0.0,m2,1,2,3\n0,0.0,m1,1,2,4\n")
    with pytest.raises(io3d.TrajectoryFileError, match=r"dup.csv: lines 2 and 4: point 'm1' of frame 0 twice "
                                                         r"with different values \(\(1.0, 2.0, 3.0\) and \(1.0, 2.0, 4.0\)\)"):
        io3d.read_trajectories_csv(bad)
    same = tmp_path / "same.csv"
    same.write_text("frame,time_s,point,x_m,y_m,z_m\n0,0.0,m1,1,2,3\n0,0.0,m1,1,2,3\n")
    assert io3d.read_trajectories_csv(same).points.shape == (1, 1, 3)
    tr = io3d.Trajectories(np.arange(3) / 10, np.arange(3), ("marker1", "marker2", "marker1"),
                           np.zeros((3, 3, 3)), "x")
    io3d.write_c3d(tmp_path / "d.c3d", tr)
    with pytest.raises(io3d.TrajectoryFileError, match=r"d.c3d: parameter POINT:LABELS names the point "
                                                         r"'marker1' twice \(points 1 and 3\)"):
        io3d.read_c3d(tmp_path / "d.c3d")


def _opensim_fields(line):
    """OpenSim's FileAdapter::tokenize on a data row: tab-separated, a trailing empty field dropped."""
    fields = line.split("\t")
    return fields[:-1] if fields and fields[-1] == "" else fields


def test_trc_rows_keep_their_length_and_every_frame(tmp_path):
    """Every row ends with a tab (a row whose last marker is missing keeps 2 + 3k fields in OpenSim's
    reader); a CSV without frame 50 gives a TRC row 50 with empty values at time 0.50 s."""
    traj, _ = _small_record(tmp_path / "in", n=60)
    rows = [ln for ln in traj.read_text().splitlines() if not ln.startswith("50,")]
    rows = [ln if not ln.startswith("10,") or ",c," not in ln else "10," + ln.split(",")[1] + ",c,,," for ln in rows]
    traj.write_text("\n".join(rows) + "\n")
    assert main(["export", str(traj), "--out", str(tmp_path / "x.trc")]) == 0
    lines = (tmp_path / "x.trc").read_text().splitlines()
    data = lines[6:]
    assert len(data) == 60 and lines[2].split("\t")[2] == "60"
    assert all(ln.endswith("\t") for ln in data) and all(len(_opensim_fields(ln)) == 2 + 3 * 3 for ln in data)
    assert _opensim_fields(data[10])[-3:] == ["", "", ""]
    row50 = _opensim_fields(data[50])
    assert row50[0] == "51" and float(row50[1]) == pytest.approx(0.50, abs=1e-12) and row50[2:] == [""] * 9
    times = np.array([float(ln.split("\t")[1]) for ln in data])
    np.testing.assert_allclose(np.diff(times), 0.01, atol=1e-9)
    assert lines[3] == "Frame#\tTime\ta\t\t\tb\t\t\tc\t\t\t" and lines[4].endswith("Z3\t")


def test_names_with_commas_survive_and_extra_fields_are_refused(tmp_path, capsys):
    tri = np.array([[0.0, 0, 0], [0.3, 0, 0], [0.1, 0.25, 0.02]])
    t = np.arange(40) / 100
    pts = tri[None] + np.stack([0.5 * t, 0.02 * np.sin(2 * np.pi * 2 * t), 0 * t], 1)[:, None, :]
    names = ["mk,1", "b", "c"]
    _write_csv(tmp_path / "tr.csv", t, names, pts)
    _write_csv(tmp_path / "st.csv", [0.0], names + ["s"], np.vstack([tri, [[0.1, 0.1, -0.2]]])[None])
    assert main(["kinematics", str(tmp_path / "tr.csv"), "--static", str(tmp_path / "st.csv"),
                 "--out", str(tmp_path / "o")]) == 0
    back = io3d.read_trajectories_csv(tmp_path / "o" / "trajectories.csv")
    assert back.names == ("mk,1", "b", "c", "s")
    assert {r["point"] for r in csv.DictReader(open(tmp_path / "o" / "kinematics.csv"))} == {"mk,1", "b", "c", "s"}
    bad = tmp_path / "bad.csv"
    bad.write_text("frame,time_s,point,x_m,y_m,z_m\n0,0.0,a,1,2,3\n0,0.0,mk,1,1,2,3\n")
    with pytest.raises(io3d.TrajectoryFileError, match=r"bad.csv: line 3: 7 fields, the header has 6"):
        io3d.read_trajectories_csv(bad)


def test_subject_prefix_and_case_are_matched_when_unambiguous(tmp_path, capsys):
    import json

    traj, static = _small_record(tmp_path / "in")
    text = traj.read_text()
    for nm, new in (("a", "Horse:a"), ("b", "Horse:B"), ("c", "Horse:c")):
        text = text.replace(f",{nm},", f",{new},")
    (tmp_path / "vicon.csv").write_text(text + "0,0.0,extra,1,2,3\n")
    assert _kin(tmp_path / "vicon.csv", static, tmp_path / "o") == 0
    err = capsys.readouterr().err
    assert "point 'Horse:B' matched to the static shot's 'b' (subject prefix / case ignored)" in err
    assert f"points not in the static shot {static}, not used: ['extra']" in err
    rec = json.loads((tmp_path / "o" / "kinematics-run.json").read_text())
    assert rec["markers"] == ["Horse:a", "Horse:B", "Horse:c"] and rec["hidden"] == ["s"]
    assert rec["unmatched"] == ["extra"] and ["Horse:B", "b"] in rec["matched_loosely"]
    # ambiguous: two subjects' 'a' -> neither is matched; the error lists both files' names
    amb = io3d.match_point_names(["H1:a", "H2:a", "b"], ["a", "b"])
    assert amb["pairs"] == [("b", "b")] and amb["unmatched"] == ["H1:a", "H2:a"] and amb["hidden"] == ["a"]
    (tmp_path / "other.csv").write_text(text.replace("Horse:", "X_"))
    assert _kin(tmp_path / "other.csv", static, tmp_path / "o2") == 2
    err = capsys.readouterr().err
    assert "the trajectories name ['X_a', 'X_B', 'X_c'], the static shot ['a', 'b', 'c', 's']" in err


def test_infinite_values_and_bad_times_name_the_line(tmp_path):
    head = "frame,time_s,point,x_m,y_m,z_m\n"
    cases = {"inf.csv": (head + "0,0.0,a,1,2,3\n1,0.01,a,1,inf,3\n", r"inf.csv: line 3: field 'y_m': expected a "
                                                                         r"number or empty, got 'inf'"),
             "nan.csv": (head + "0,0.0,a,1,2,3\n1,nan,a,1,2,3\n", r"nan.csv: line 3: field 'time_s': expected a "
                                                                    r"finite number, got 'nan'"),
             "back.csv": (head + "0,0.0,a,1,2,3\n1,0.02,a,1,2,3\n2,0.01,a,1,2,3\n",
                          r"back.csv: field 'time_s' must increase with 'frame': frame 2 \(line 4\) has time 0.01, "
                          r"not after frame 1's 0.02 \(line 3\)")}
    for name, (text, message) in cases.items():
        (tmp_path / name).write_text(text)
        with pytest.raises(io3d.TrajectoryFileError, match=message):
            io3d.read_trajectories_csv(tmp_path / name)
    tr = io3d.Trajectories(np.arange(3) / 10, np.arange(3), ("a",), np.zeros((3, 1, 3)), "x")
    pts = tr.points.copy()
    pts[1, 0, 2] = np.inf
    io3d.write_c3d(tmp_path / "inf.c3d", io3d.Trajectories(tr.time_s, tr.frame, tr.names, pts, "x"))
    # the writer stores inf as a gap (not finite); put one in the data by hand
    import ezc3d

    c = ezc3d.c3d(str(tmp_path / "inf.c3d"))
    data = c["data"]["points"]
    data[2, 0, 1] = np.inf
    c["data"]["points"] = data
    c["data"]["meta_points"]["residuals"] = np.zeros((1, 1, 3))
    c.write(str(tmp_path / "inf2.c3d"))
    with pytest.raises(io3d.TrajectoryFileError, match=r"inf2.c3d: frame 2 \(1-based\), point 'a', z: expected a "
                                                         r"number, got inf"):
        io3d.read_c3d(tmp_path / "inf2.c3d")


def _patch_rates(src, dst, header_rate, parameter_rate):
    """Copy a C3D (Intel) with the header's rate (bytes 20-23) and POINT:RATE's value replaced."""
    import struct

    raw = bytearray(open(src, "rb").read())
    raw[20:24] = struct.pack("<f", header_rate)
    at = raw.find(b"RATE", 512 * (raw[0] - 1))
    assert raw[at + 6] == 4 and raw[at + 7] == 0           # offset (2 bytes), type float, scalar
    raw[at + 8:at + 12] = struct.pack("<f", parameter_rate)
    open(dst, "wb").write(bytes(raw))


def test_c3d_messages(tmp_path, capsys):
    traj, static = _small_record(tmp_path / "in", n=20)
    tr = io3d.read_trajectories(traj)
    io3d.write_c3d(tmp_path / "ok.c3d", tr)
    _patch_rates(tmp_path / "ok.c3d", tmp_path / "zero.c3d", 0.0, 0.0)
    with pytest.raises(io3d.TrajectoryFileError, match=r"zero.c3d: no frame rate: the parameter POINT:RATE is 0 and "
                                                         r"the header's rate \(words 11-12\) is 0; expected a positive"):
        io3d.read_c3d(tmp_path / "zero.c3d")
    import ezc3d

    c = ezc3d.c3d(str(tmp_path / "ok.c3d"))
    c["parameters"]["POINT"]["UNITS"]["value"] = ["in"]
    c.write(str(tmp_path / "inch.c3d"))
    with pytest.raises(io3d.TrajectoryFileError, match=r"POINT:UNITS is 'in' \(expected one of m, mm, cm, dm\)"):
        io3d.read_c3d(tmp_path / "inch.c3d")
    gaps = io3d.Trajectories(tr.time_s, tr.frame, tr.names, np.full_like(tr.points, np.nan), "x")
    io3d.write_c3d(tmp_path / "gaps.c3d", gaps)
    assert _kin(tmp_path / "gaps.c3d", static, tmp_path / "o") == 2
    err = capsys.readouterr().err
    assert f"{tmp_path / 'gaps.c3d'}: the markers ['a', 'b', 'c'] are missing in every frame (all gaps)" in err
    assert "np." not in err and "array(" not in err


def test_pose_events_is_the_same_option_as_events(tmp_path):
    import json

    traj, static = _small_record(tmp_path / "in")
    assert _kin(traj, static, tmp_path / "a", "--smoothing", "adaptive", "--events", "0.3") == 0
    assert _kin(traj, static, tmp_path / "b", "--smoothing", "adaptive", "--pose-events", "0.3") == 0
    rec = [json.loads((tmp_path / f / "kinematics-run.json").read_text()) for f in "ab"]
    assert rec[0]["options"] == rec[1]["options"] and rec[1]["options"]["events"] == [0.3]
    assert (tmp_path / "a" / "kinematics.csv").read_bytes() == (tmp_path / "b" / "kinematics.csv").read_bytes()


@pytest.mark.parametrize("given", [False, True], ids=["no_HORSEMOCAP_RESULTS", "HORSEMOCAP_RESULTS_given"])
def test_pytest_leaves_no_results_folder_behind(given, tmp_path):
    """conftest.py: a pytest session removes the results folder it made, and makes none when
    HORSEMOCAP_RESULTS is given."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    (tmp_path / "tmp").mkdir()
    env = {k: v for k, v in os.environ.items() if k != "HORSEMOCAP_RESULTS"}
    env["TMPDIR"] = str(tmp_path / "tmp")
    if given:
        env["HORSEMOCAP_RESULTS"] = str(tmp_path / "mine")
    run = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                          "tests/test_io3d.py::test_bad_files_name_file_and_field"],
                         cwd=root, env=env, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stdout[-2000:]
    assert [p.name for p in (tmp_path / "tmp").iterdir() if p.name.startswith("horsemocap-results-")] == []


def test_a_trailing_comma_is_not_an_extra_field(tmp_path):
    """Spreadsheets often end rows with a comma: read as before; a non-empty extra field is still refused."""
    from horsemocap import io3d

    p = tmp_path / "t.csv"
    p.write_text("frame,time_s,point,x_m,y_m,z_m\n0,0.0,m1,1,2,3,\n1,0.01,m1,1,2,4,\n")
    tr = io3d.read_trajectories_csv(p)
    assert tr.points.shape == (2, 1, 3) and tr.points[1, 0, 2] == 4.0
    p.write_text("frame,time_s,point,x_m,y_m,z_m\n0,0.0,m1,1,2,3,7\n")
    with pytest.raises(io3d.TrajectoryFileError, match="line 2: 7 fields"):
        io3d.read_trajectories_csv(p)


def _four_marker_record(folder, n=300, rho=0.9, sd_m=0.001, seed=3):
    """Four rigid markers + a hidden point moving smoothly, with AR(1) noise of correlation ``rho``."""
    rng = np.random.default_rng(seed)
    quad = np.array([[0.0, 0, 0], [0.3, 0, 0], [0.1, 0.25, 0.02], [0.25, 0.2, -0.05]])
    t = np.arange(n) / 100
    move = np.stack([0.5 * t, 0.02 * np.sin(2 * np.pi * 1.3 * t), 0.01 * np.cos(2 * np.pi * 0.7 * t)], 1)
    noise = np.zeros((n, 4, 3))
    noise[0] = rng.normal(0, sd_m, (4, 3))
    for k in range(1, n):
        noise[k] = rho * noise[k - 1] + np.sqrt(1 - rho ** 2) * rng.normal(0, sd_m, (4, 3))
    folder.mkdir(parents=True, exist_ok=True)
    names = ["a", "b", "c", "d"]
    _write_csv(folder / "traj.csv", t, names, quad[None] + move[:, None, :] + noise)
    _write_csv(folder / "static.csv", [0.0], names + ["s"], np.vstack([quad, [[0.1, 0.1, -0.2]]])[None])
    return folder / "traj.csv", folder / "static.csv"


def test_kinematics_takes_the_correlated_noise_criterion(tmp_path, capsys):
    """``--noise-criterion`` reaches the pose smoothing (analyze's rigid_body.pose.correlated_noise_criterion)
    and kinematics-run.json records it: under correlated noise, four markers are left out in turn by
    default and the correlated-error GCV chooses when asked."""
    import json

    traj, static = _four_marker_record(tmp_path / "in")
    ran = {}
    for criterion in ("loo", "gcv"):
        out = tmp_path / criterion
        extra = () if criterion == "loo" else ("--noise-criterion", criterion)
        assert _kin(traj, static, out, *extra) == 0, capsys.readouterr().err
        record = json.loads((out / "kinematics-run.json").read_text())
        assert record["options"]["noise_criterion"] == criterion
        ran[criterion] = record["smoothing_ran"]["reason"]
    assert "leaving each of the 4 markers out" in ran["loo"], ran
    assert "correlated-error GCV" in ran["gcv"] and "markers out" not in ran["gcv"], ran
    with pytest.raises(SystemExit) as stop:
        _kin(traj, static, tmp_path / "bad", "--noise-criterion", "median")
    assert stop.value.code == 2 and "--noise-criterion: invalid choice: 'median'" in capsys.readouterr().err
    assert not (tmp_path / "bad").exists()
