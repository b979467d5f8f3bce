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
    (out / "stale.txt").write_text("left by hand")     # in an earlier kinematics output: replaced with it
    assert _kin(traj, static, out, "--smoothing", "gcv") == 0
    assert not (out / "stale.txt").exists()
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
    assert trc.read_text().splitlines()[2].split("\t")[6] == "29"
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
    many, _ = _small_record(tmp_path / "many")       # 100 Hz in its times; --rate overrides
    assert main(["export", str(many), "--out", str(tmp_path / "r.c3d"), "--rate", "50"]) == 0
    assert ezc3d.c3d(str(tmp_path / "r.c3d"))["header"]["points"]["frame_rate"] == 50.0
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
