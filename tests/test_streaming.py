"""Kinematics of long records in windows (horsemocap.streaming) and the kinematics command's windowed path."""
from __future__ import annotations

import csv
import dataclasses
import json
import mmap

import numpy as np
import pytest

from horsemocap import io3d, pose, store, streaming
from horsemocap.cli import main
from horsemocap.io3d import RunningPercentile, kinematics_params
from horsemocap.synthetic import Jet, _rotation_jets
from horsemocap.threads import blas_single_threaded

FPS = 200.0
MODEL = np.array([[0.20, 0.10, 0.15], [-0.20, 0.10, 0.15], [0.05, 0.10, -0.15], [-0.20, -0.02, -0.15]])
HIDDEN = np.array([0.20, -0.10, -0.15])


@pytest.fixture(autouse=True)
def one_blas_thread():
    """As the kinematics command runs: the smoothing's small matrices with one BLAS thread."""
    with blas_single_threaded():
        yield


def sine(t, amplitude, hz, phase=0.0) -> Jet:
    w = 2 * np.pi * hz
    s, c = np.sin(w * t + phase), np.cos(w * t + phase)
    return Jet(amplitude * s, amplitude * w * c, -amplitude * w * w * s)


def trot(n: int, noise_m: float = 5e-4, seed: int = 0) -> dict:
    """A marker cluster trotting at 1.7 Hz while moving forward, exact hidden-point acceleration."""
    t = np.arange(n) / FPS
    x = Jet(1.5 * t, np.full(n, 1.5), np.zeros(n)) + sine(t, 0.01, 1.7)
    y = sine(t, 0.03, 3.4) + sine(t, 0.008, 6.8, 0.7) + 1.2
    z = sine(t, 0.01, 1.7, 0.3)
    R, omega, alpha = _rotation_jets(sine(t, 0.03, 1.7, 1.0), sine(t, 0.05, 3.4, 0.2), sine(t, 0.04, 1.7, 2.0))
    c = np.stack([x.f, y.f, z.f], -1)
    mk = np.einsum("kij,mj->kmi", R, MODEL) + c[:, None]
    r = R @ HIDDEN
    acc = np.stack([x.d2, y.d2, z.d2], -1) + np.cross(alpha, r) + np.cross(omega, np.cross(omega, r))
    return {"t": t, "markers": mk + np.random.default_rng(seed).normal(0, noise_m, mk.shape), "hidden_acc": acc}


@pytest.mark.parametrize("n, window, margin", [(2400, 1000, 100), (2500, 1000, 300), (999, 1000, 100),
                                               (5000, 700, 350)])
def test_windows_tile_the_record(n, window, margin):
    plan = streaming.window_plan(n, window, margin)
    cores = [(c0, c1) for _, _, c0, c1 in plan]
    assert cores[0][0] == 0 and cores[-1][1] == n
    assert all(a[1] == b[0] for a, b in zip(cores, cores[1:]))
    assert all(lo <= c0 and c1 <= hi and c0 - lo <= margin and hi - c1 <= margin for lo, hi, c0, c1 in plan)
    assert all(c1 - c0 >= window // 2 for _, _, c0, c1 in plan) or len(plan) == 1


def test_windowed_agrees_with_the_whole_record():
    d = trot(3000)
    reg = pose.register_pose(d["markers"], MODEL)
    params = kinematics_params()
    whole = pose.fit_pose_trajectory(d["t"], reg, MODEL, params, points=d["markers"])
    whole_acc = whole.points(d["t"], HIDDEN[None]).acceleration[:, 0]
    blocks = list(streaming.windowed_kinematics(d["t"], reg, d["markers"], MODEL, HIDDEN[None], params, window=1000))
    assert [b.start for b in blocks[1:]] == [b.stop for b in blocks[:-1]] and blocks[-1].stop == 3000
    acc = np.concatenate([b.acceleration[:, 0] for b in blocks])
    scale = np.sqrt(np.mean(np.sum(d["hidden_acc"] ** 2, 1)))
    diff = np.linalg.norm(acc - whole_acc, axis=1)
    assert diff.max() < 0.02 * scale                   # measured 0.039 m/s^2 of 14.8 (0.26 %), margin 629
    err = np.sqrt(np.mean(np.sum((acc - d["hidden_acc"]) ** 2, 1)))
    err_whole = np.sqrt(np.mean(np.sum((whole_acc - d["hidden_acc"]) ** 2, 1)))
    assert err < 1.2 * err_whole                       # measured 0.143 against 0.141 m/s^2
    # no step at the cuts: the acceleration's change across each cut like that of its neighbours
    jumps = np.linalg.norm(np.diff(acc, axis=0), axis=1)
    for cut in (1000, 2000):
        assert jumps[cut - 1] < 3 * np.median(jumps[cut - 50:cut + 50])


def test_a_stretch_without_poses_is_nan_with_its_reason():
    d = trot(2400)
    pts = d["markers"].copy()
    pts[1000:1400, :2] = np.nan                          # two markers hidden for 2 s: no pose there
    reg = pose.register_pose(pts, MODEL)
    params = kinematics_params(smoothing="gcv")
    blocks = list(streaming.windowed_kinematics(d["t"], reg, pts, MODEL, HIDDEN[None], params, window=600))
    acc = np.concatenate([b.acceleration[:, 0] for b in blocks])
    reason = np.concatenate([b.reason for b in blocks])
    assert np.isnan(acc[1010:1390]).all() and all(reason[1010:1390] != "")
    assert np.isfinite(acc[:990]).all() and np.isfinite(acc[1410:]).all()


def _write(path, t, names, pts):
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["frame", "time_s", "point", "x_m", "y_m", "z_m"])
        for k in range(len(t)):
            for j, nm in enumerate(names):
                w.writerow([k, repr(float(t[k])), nm, *(repr(float(v)) for v in pts[k, j])])


def test_kinematics_command_smooths_a_long_record_in_windows(tmp_path, monkeypatch, capsys):
    d = trot(2600)
    names = ["m1", "m2", "m3", "m4"]
    _write(tmp_path / "traj.csv", d["t"], names, d["markers"])
    _write(tmp_path / "static.csv", [0.0], names + ["hidden"], np.vstack([MODEL, HIDDEN])[None])
    monkeypatch.setattr(streaming, "WHOLE_RECORD_FRAMES", 1000)
    monkeypatch.setattr(streaming, "WINDOW_FRAMES", 800)
    out = tmp_path / "out"
    assert main(["kinematics", str(tmp_path / "traj.csv"), "--static", str(tmp_path / "static.csv"),
                 "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert "smoothed in 3 windows of 800 frames" in err and "smoothing the pose in windows" in err
    rows = [r for r in csv.DictReader(open(out / "kinematics.csv")) if r["point"] == "hidden"]
    assert [int(r["frame"]) for r in rows] == list(range(2600))
    acc = np.array([[float(r[c]) for c in ("ax_mps2", "ay_mps2", "az_mps2")] for r in rows])
    err_rms = np.sqrt(np.mean(np.sum((acc - d["hidden_acc"]) ** 2, 1)))
    assert err_rms < 0.05 * np.sqrt(np.mean(np.sum(d["hidden_acc"] ** 2, 1)))
    record = json.loads((out / "kinematics-run.json").read_text())
    assert record["windows"]["count"] == 3 and record["quality"]["verdict"] == "ok"
    assert sorted(p.name for p in out.iterdir()) == ["angular.csv", "kinematics-run.json", "kinematics.csv",
                                                     "trajectories.csv"]
    assert len((out / "angular.csv").read_text().splitlines()) == 2601


@pytest.mark.parametrize("n, blocks", [(1, 1), (7, 3), (150, 4), (4001, 17)])
def test_running_percentile_is_numpys_of_the_finite_values(n, blocks):
    rng = np.random.default_rng(n)
    values = rng.lognormal(size=(n, 4))
    values[rng.random(values.shape) < 0.1] = np.nan
    values[rng.random(values.shape) < 0.01] = np.inf
    for q in (99, 50, 100, 0):
        running = RunningPercentile(q, values.size)
        for part in np.array_split(values, blocks):
            running.add(part)
        finite = values[np.isfinite(values)]
        assert running.value() == pytest.approx(np.percentile(finite, q), rel=1e-12, abs=0)
        assert running._top.size <= running.capacity
    assert np.isnan(RunningPercentile(99, 3).value())


def test_running_percentile_refuses_more_values_than_its_count():
    running = RunningPercentile(99, 100)
    running.add(np.arange(1000.0))
    with pytest.raises(ValueError, match="more than the 3 kept"):
        running.value()


def test_the_margin_is_where_a_cuts_effect_has_decayed():
    """Known answer of kernel_margin: a record fitted whole and cut in two (same lambdas, no harmonics)
    differ at the cut; beyond the widest component's margin the hidden point's acceleration differs by
    less than 3 MARGIN_DECAY of the difference at the cut (measured: 0.9 %, 0.081 of 9.04 m/s^2; the
    record is short enough that both fits have a knot every sample or two, so the basis' resolution
    adds little)."""
    n = 800
    d = trot(n)
    reg = pose.register_pose(d["markers"], MODEL)
    params = dataclasses.replace(kinematics_params(smoothing="gcv"), harmonics="none")
    settled = streaming.settle_smoothing(d["t"], reg, d["markers"], MODEL, params)
    margin = max(streaming.kernel_margin(n, settled.info[c]) for c in streaming.COMPONENTS)
    assert 20 < margin < n // 4
    whole = pose.fit_pose_trajectory(d["t"], reg, MODEL, settled.params, points=d["markers"], lam=settled.lam)
    cut = n // 2
    part = pose.fit_pose_trajectory(d["t"][:cut], streaming.slice_registration(reg, 0, cut), MODEL, settled.params,
                                    points=d["markers"][:cut], lam=settled.lam)
    t = d["t"][:cut]
    diff = np.linalg.norm(whole.points(t, HIDDEN[None]).acceleration[:, 0]
                          - part.points(t, HIDDEN[None]).acceleration[:, 0], axis=1)[::-1]   # by distance
    at_cut = diff[:3].max()
    assert at_cut > 0.1 * np.sqrt(np.mean(np.sum(d["hidden_acc"] ** 2, 1)))     # the cut matters there
    assert diff[margin:].max() < 3 * streaming.MARGIN_DECAY * at_cut


def test_a_trend_with_harmonics_sets_no_margin():
    """A component whose spline is its polynomial (the stride harmonics carry the motion) has no local
    kernel; a flexible one gives the decay length times ln(1 / MARGIN_DECAY)."""
    assert streaming.kernel_margin(4000, {"edf": 5.05, "harmonics": 1}) == 0
    assert streaming.kernel_margin(4000, {"edf": float("nan")}) == 0
    edf = 36.3
    want = 2 * 4000 * np.log(1 / streaming.MARGIN_DECAY) / (3 * (edf - 3 - 8))
    assert streaming.kernel_margin(4000, {"edf": edf, "harmonics": 4}) == int(np.ceil(want))


def test_chunked_registration_is_the_whole_records():
    d = trot(1000)
    pts = d["markers"].copy()
    pts[300:320, 1] = np.nan                              # three markers left
    pts[500:510, :2] = np.nan                             # no pose
    whole = pose.register_pose(pts, MODEL, names=["a", "b", "c", "d"])
    parts = streaming.register_in_chunks(pts, MODEL, names=["a", "b", "c", "d"], chunk=137)
    for name in ("rotation", "translation", "centre", "registered", "residual", "rms", "n_markers", "height"):
        np.testing.assert_allclose(getattr(parts, name), getattr(whole, name), rtol=0, atol=1e-12, err_msg=name)
    assert parts.reason.tolist() == whole.reason.tolist() and parts.reason[505] != ""
    assert parts.noise_m == pytest.approx(whole.noise_m, rel=1e-12)


def test_the_compact_reader_places_shuffled_rows_and_names_the_earliest_fault(tmp_path):
    from horsemocap import io3d

    rng = np.random.default_rng(3)
    head = "frame,time_s,point,x_m,y_m,z_m\n"
    rows = [f"{k},{k / 100!r},{nm},{x!r},1,2" for k in range(40) for nm, x in (("a", k / 7), ("b", -k / 3))]
    gap = int(rng.integers(len(rows)))
    rows[gap] = ",".join(rows[gap].split(",")[:3] + ["", "", ""])                 # a missing point
    order = rng.permutation(len(rows))
    (tmp_path / "s.csv").write_text(head + "\n".join(rows[i] for i in order) + "\n")
    tr = io3d.read_trajectories_csv(tmp_path / "s.csv")
    first = rows[order[0]].split(",")[2]
    assert tr.frame.tolist() == list(range(40)) and tr.names == (first, "b" if first == "a" else "a")
    assert tr.time_s.tolist() == [k / 100 for k in range(40)]
    assert np.isnan(tr.points[gap // 2, tr.names.index("ab"[gap % 2])]).all()
    assert np.isfinite(tr.points).all(axis=2).sum() == 79
    a = tr.names.index("a")
    np.testing.assert_array_equal(np.where(np.arange(40) == gap // 2, np.nan, np.arange(40) / 7) if gap % 2 == 0
                                  else np.arange(40) / 7, tr.points[:, a, 0])
    # two faults: the one on the earlier line is named, whichever kind it is
    text = head + "0,0.0,a,1,2,3\n1,0.01,a,1,2,3\n0,0.0,a,1,2,4\n1,0.02,a,1,2,3\n2,0.02,a,x,2,3\n"
    (tmp_path / "two.csv").write_text(text)
    with pytest.raises(io3d.TrajectoryFileError, match=r"two.csv: lines 2 and 4: point 'a' of frame 0 twice"):
        io3d.read_trajectories_csv(tmp_path / "two.csv")
    (tmp_path / "time.csv").write_text(head + "0,0.0,a,1,2,3\n1,0.01,a,1,2,3\n\n1,0.02,a,1,2,3\n0,0.0,a,1,2,4\n")
    with pytest.raises(io3d.TrajectoryFileError, match=r"time.csv: line 5: frame 1 has two times \(0.01 on line 3 "
                                                          r"and 0.02\)"):
        io3d.read_trajectories_csv(tmp_path / "time.csv")
    (tmp_path / "late.csv").write_text(head + "0,0.0,a,1,2,3\n0,0.0,a,1,2,4\n1,0.01,a,x,2,3\n")
    with pytest.raises(io3d.TrajectoryFileError, match=r"late.csv: lines 2 and 3: point 'a' of frame 0"):
        io3d.read_trajectories_csv(tmp_path / "late.csv")


def test_windows_on_one_time_grid_share_it_and_keep_their_kinematics():
    """A window's times counted from its first frame are the record's grid where they lie on it (the
    smoothing's basis then shared by windows of one length); off the grid, its own times. Fitted on
    either, a window's accelerations agree to the lambda search's tolerance."""
    t = 1234.5 + np.arange(2000) / FPS
    a, b = streaming.window_times(t, 100, 900, 1 / FPS), streaming.window_times(t, 1100, 1900, 1 / FPS)
    assert a.tobytes() == b.tobytes() and a[0] == 0.0
    jitter = t + np.where(np.arange(2000) == 1500, 1e-4, 0.0)
    assert streaming.window_times(jitter, 1100, 1900, 1 / FPS)[400] == pytest.approx(jitter[1500] - jitter[1100])
    d = trot(1200)
    reg = pose.register_pose(d["markers"], MODEL)
    params = kinematics_params(smoothing="gcv")
    own = pose.fit_pose_trajectory(d["t"] + 500.0, reg, MODEL, params, points=d["markers"])
    grid = pose.fit_pose_trajectory(streaming.window_times(d["t"] + 500.0, 0, 1200, 1 / FPS), reg, MODEL, params,
                                    points=d["markers"])
    acc_own = own.points(d["t"] + 500.0, HIDDEN[None]).acceleration[:, 0]
    acc_grid = grid.points(d["t"], HIDDEN[None]).acceleration[:, 0]
    assert np.max(np.abs(acc_own - acc_grid)) < 1e-3 * np.sqrt(np.mean(np.sum(d["hidden_acc"] ** 2, 1)))


def test_point_kinematics_are_the_trajectorys_own():
    d = trot(600)
    reg = pose.register_pose(d["markers"], MODEL)
    tr = pose.fit_pose_trajectory(d["t"], reg, MODEL, kinematics_params(smoothing="gcv"), points=d["markers"])
    body = np.vstack([MODEL, HIDDEN])
    p, v, a, w, al = streaming.point_kinematics(tr, d["t"], body)
    k = tr.points(d["t"], body)
    for mine, theirs in ((p, k.position), (v, k.velocity), (a, k.acceleration), (w, tr.omega(d["t"])),
                         (al, tr.alpha(d["t"]))):
        np.testing.assert_array_equal(mine, theirs)


def test_block_text_is_what_the_csv_module_writes():
    """The kinematics tables' rows formatted in bulk: the same text as csv.writer with '%.9g' numbers and
    empty fields for NaN and infinities, names and notes quoted as the csv module quotes them."""
    import io

    from horsemocap.io3d import kinematics_block_text

    rng = np.random.default_rng(5)
    b, names = 40, ["m1", "a,b", 'say "x"', "hidden"]
    shape = (b, len(names), 3)
    vals = [rng.normal(0, 10.0 ** rng.integers(-8, 9, shape), shape) for _ in range(3)]
    for v in vals:
        v[rng.random(shape) < 0.05] = np.nan
    vals[2][3, 1, 2] = np.inf
    omega, alpha = rng.normal(size=(b, 3)), rng.normal(size=(b, 3))
    omega[7] = np.nan
    height, rms = rng.random(b), rng.random(b) * 1e-3
    height[9] = np.nan
    reason = np.array(["" if i % 5 else f'gap, "{i}"\nframes' for i in range(b)], object)
    block = streaming.KinematicsBlock(100, 100 + b, *vals, omega, alpha, reason)
    frame, time_s = np.arange(100, 100 + b), np.arange(100, 100 + b) / 300.0
    time_s[4] = np.nan

    def num(v):
        return "" if not np.isfinite(v) else f"{float(v):.9g}"

    want = [io.StringIO() for _ in range(3)]
    pos_w, kin_w, ang_w = (csv.writer(fh, lineterminator="\n") for fh in want)
    for i in range(b):
        fr, tt = frame[i], num(time_s[i])
        for j, nm in enumerate(names):
            pos_w.writerow([fr, tt, nm, *(num(v) for v in vals[0][i, j])])
            kin_w.writerow([fr, tt, nm, *(num(v) for v in (*vals[1][i, j], *vals[2][i, j]))])
        ang_w.writerow([fr, tt, *(num(v) for v in (*omega[i], *alpha[i])), num(height[i]), num(rms[i]),
                        str(reason[i]).replace(",", ";")])
    got = kinematics_block_text(frame, time_s, names, block, height, rms)
    for g, w in zip(got, want):
        assert g == w.getvalue()


def test_chunked_conditioning_warnings_are_the_whole_records():
    thin = np.array([[0.0, 0, 0], [0.5, 0, 0], [0.25, 0.004, 0], [0.1, 0.002, 0.0]])
    rng = np.random.default_rng(2)
    pts = np.repeat(thin[None], 900, 0) + rng.normal(0, 1e-3, (900, 4, 3))
    pts[100:130, :2] = np.nan                               # no pose
    pts[400:420, 3] = np.nan                                # three markers
    reg = pose.register_pose(pts, thin)
    whole = pose.conditioning_warnings(reg)
    assert len(whole) == 2
    assert streaming.conditioning_warnings(reg, chunk=128) == whole
    far = pose.conditioning_warnings(reg, lever_m=0.8)
    assert "a point 0.80 m away moves by about" in far[0]
    assert streaming.conditioning_warnings(reg, chunk=128, lever_m=0.8) == far
    assert streaming.conditioning_warnings(reg, chunk=128, rotation_noise_limit_deg=1e3) == whole[1:]
    reg_on_disk = streaming.register_in_chunks(pts, thin, chunk=128)
    assert streaming.conditioning_warnings(reg_on_disk, chunk=128) == whole


def test_a_record_read_to_disk_is_the_record_read_whole(tmp_path):
    from horsemocap import io3d

    d = trot(700)
    names = ["m1", "m2", "m3", "m4"]
    pts = d["markers"].copy()
    pts[50:60, 2] = np.nan
    _write(tmp_path / "traj.csv", 3.0 + d["t"], names, pts)
    whole = io3d.read_trajectories_csv(tmp_path / "traj.csv")
    (tmp_path / "disk").mkdir()
    disk = io3d.read_trajectories_csv_to_disk(tmp_path / "traj.csv", tmp_path / "disk", block_rows=333)
    assert isinstance(disk.points, np.memmap) and disk.names == whole.names and disk.info == whole.info
    np.testing.assert_array_equal(disk.points, whole.points)
    np.testing.assert_array_equal(disk.time_s, whole.time_s)
    np.testing.assert_array_equal(disk.frame, whole.frame)
    # out of order, or with a fault: read whole (the same result, or the whole reader's message)
    lines = (tmp_path / "traj.csv").read_text().splitlines()
    (tmp_path / "swap.csv").write_text("\n".join([lines[0], lines[5], *lines[1:5], *lines[6:]]) + "\n")
    swapped = io3d.read_trajectories_csv_to_disk(tmp_path / "swap.csv", tmp_path / "disk")
    assert not isinstance(swapped.points, np.memmap)
    np.testing.assert_array_equal(swapped.points, whole.points)
    (tmp_path / "bad.csv").write_text("\n".join([*lines[:300], "12,x,m1,1,2,3", *lines[300:]]) + "\n")
    with pytest.raises(io3d.TrajectoryFileError, match="line 301: field 'time_s'"):
        io3d.read_trajectories_csv_to_disk(tmp_path / "bad.csv", tmp_path / "disk")
    left = [p.name for p in (tmp_path / "disk").iterdir()]
    assert len(left) == 1 and left[0].startswith("points-") and left[0].endswith(".npy")
    again = io3d.read_trajectories_csv_to_disk(tmp_path / "traj.csv", tmp_path / "disk")
    assert len(list((tmp_path / "disk").iterdir())) == 2                 # its own file: the first stays mapped
    np.testing.assert_array_equal(disk.points, again.points)


def test_a_scratch_folder_that_cannot_be_written_is_named(tmp_path, monkeypatch, capsys):
    d = trot(200)
    _write(tmp_path / "traj.csv", d["t"], ["m1", "m2", "m3", "m4"], d["markers"])
    with pytest.raises(store.ScratchWriteError, match="gone is the scratch folder"):
        io3d.read_trajectories_csv_to_disk(tmp_path / "traj.csv", tmp_path / "gone")

    def full_disk(*args, **kwargs):
        raise OSError(28, "No space left on device")

    (tmp_path / "disk").mkdir()
    monkeypatch.setattr(np.lib.format, "open_memmap", full_disk)
    with pytest.raises(store.ScratchWriteError, match=r"points-.*\.npy: No space left on device; .*disk is the"):
        io3d.read_trajectories_csv_to_disk(tmp_path / "traj.csv", tmp_path / "disk")
    assert list((tmp_path / "disk").iterdir()) == []                       # nothing half-written left
    _write(tmp_path / "static.csv", [0.0], ["m1", "m2", "m3", "m4"], MODEL[None])
    monkeypatch.setattr("tempfile.tempdir", str(tmp_path / "disk"))
    code = main(["kinematics", str(tmp_path / "traj.csv"), "--static", str(tmp_path / "static.csv"),
                 "--out", str(tmp_path / "out")])
    assert code == 2 and "No space left on device" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_release_pages_without_madvise(tmp_path, monkeypatch):
    """Where the system has no madvise (Windows, some builds) the pages are simply kept."""
    a = np.lib.format.open_memmap(tmp_path / "a.npy", mode="w+", dtype=float, shape=(100,))
    a[:] = 1.0
    monkeypatch.delattr(mmap, "MADV_DONTNEED", raising=False)
    store.release_pages(a)
    assert float(a.sum()) == 100.0


def test_markers_apart_in_the_file_are_copied_to_disk_in_chunks(tmp_path, monkeypatch):
    """Markers not adjacent in a mapped record: one copy, made in chunks into the scratch folder."""
    d = trot(300)
    pts = np.concatenate([d["markers"][:, :1], np.ones((300, 1, 3)), d["markers"][:, 1:]], axis=1)
    pts[20:25, 3] = np.nan
    _write(tmp_path / "traj.csv", d["t"], ["m1", "other", "m2", "m3", "m4"], pts)
    _write(tmp_path / "static.csv", [0.0], ["m1", "m2", "m3", "m4"], MODEL[None])
    monkeypatch.setattr(io3d, "READ_FRAMES", 64)
    (tmp_path / "disk").mkdir()
    traj = io3d.read_trajectories_csv_to_disk(tmp_path / "traj.csv", tmp_path / "disk")
    setup = io3d.kinematics_setup(traj, io3d.read_trajectories(tmp_path / "static.csv"), folder=tmp_path / "disk")
    assert setup["markers"] == ["m1", "m2", "m3", "m4"]
    assert isinstance(setup["points"], np.memmap)
    np.testing.assert_array_equal(setup["points"], pts[:, [0, 2, 3, 4]])


def test_registration_in_chunks_on_disk_is_the_whole_registration(tmp_path):
    """register_in_chunks with a folder and more frames than a chunk: memory-mapped, the same numbers."""
    rng = np.random.default_rng(4)
    pts = np.repeat(MODEL[None], 500, 0) + rng.normal(0, 1e-3, (500, 4, 3))
    pts[40:45, :2] = np.nan                                 # no pose
    pts[300:310, 3] = np.nan                                # three markers
    whole = pose.register_pose(pts, MODEL)
    on_disk = streaming.register_in_chunks(pts, MODEL, chunk=64, folder=tmp_path)
    assert isinstance(on_disk.rotation, np.memmap) and isinstance(on_disk.rms, np.memmap)
    assert sorted(p.name for p in tmp_path.iterdir())[0].startswith("registration-")
    np.testing.assert_allclose(on_disk.rotation, whole.rotation, atol=1e-12, equal_nan=True)
    np.testing.assert_allclose(on_disk.translation, whole.translation, atol=1e-12, equal_nan=True)
    np.testing.assert_array_equal(on_disk.n_markers, whole.n_markers)
    assert on_disk.reason.tolist() == whole.reason.tolist()
    assert np.isclose(on_disk.noise_m, whole.noise_m, rtol=1e-12)


def test_a_blends_margin_counts_its_harmonic_columns_at_the_harmonic_parts_weight():
    from horsemocap.streaming import SPLINE_NULL_SPACE, kernel_margin
    plain = kernel_margin(4000, {"edf": 40.0 + SPLINE_NULL_SPACE})
    # 2 harmonics (4 columns) held at weight 0.5: 2 of the 42 degrees of freedom are unpenalised
    blend = kernel_margin(4000, {"edf": 42.0 + SPLINE_NULL_SPACE, "harmonics": 2, "blend_weights": [0.5, 0.5]})
    whole = kernel_margin(4000, {"edf": 44.0 + SPLINE_NULL_SPACE, "harmonics": 2})
    assert blend == plain == whole


def _wandering_trot(n: int, rate_hz: float, seed: int = 0) -> dict:
    """Three markers trotting at 1.7 Hz whose stride frequency wanders by 2 % over 14 s (a ridden trot is not
    one exact period), 0.5 mm white noise; the hidden point's acceleration from its exact path (central
    differences of 0.1 ms: an error far below 0.1 % of its rms)."""
    from scipy.spatial.transform import Rotation

    def path(t):
        u = t + 0.02 * 14 / (2 * np.pi) * np.sin(2 * np.pi * t / 14)
        c = np.stack([1.5 * t + sine(u, 0.01, 1.7).f, sine(u, 0.03, 3.4).f + sine(u, 0.008, 6.8, 0.7).f + 1.2,
                      sine(u, 0.01, 1.7, 0.3).f], -1)
        R = Rotation.from_rotvec(np.stack([sine(u, 0.03, 1.7, 1.0).f, sine(u, 0.05, 3.4, 0.2).f,
                                           sine(u, 0.04, 1.7, 2.0).f], -1)).as_matrix()
        return c, R

    def hidden(t):
        c, R = path(t)
        return c + R @ HIDDEN

    t = np.arange(n) / rate_hz
    c, R = path(t)
    mk = np.einsum("kij,mj->kmi", R, MODEL[:3]) + c[:, None]
    h = 1e-4
    acc = (hidden(t + h) - 2 * hidden(t) + hidden(t - h)) / h ** 2
    return {"t": t, "markers": mk + np.random.default_rng(seed).normal(0, 5e-4, mk.shape), "hidden_acc": acc}


def test_kinematics_command_keeps_a_long_records_accelerations(tmp_path, capsys):
    """30 s at 100 Hz of a trot whose stride wanders: smoothed whole, the spline's capped basis puts a knot every
    8 frames and loses most of the acceleration (about 60 % error); the command smooths such a record in windows
    (a basis no coarser than a window's) and keeps it within a few per cent."""
    d = _wandering_trot(3000, 100.0)
    names = ["m1", "m2", "m3"]
    _write(tmp_path / "traj.csv", d["t"], names, d["markers"])
    _write(tmp_path / "static.csv", [0.0], names + ["hidden"], np.vstack([MODEL[:3], HIDDEN])[None])
    out = tmp_path / "out"
    assert main(["kinematics", str(tmp_path / "traj.csv"), "--static", str(tmp_path / "static.csv"),
                 "--out", str(out)]) in (0, 3)
    said = capsys.readouterr().err
    rows = [r for r in csv.DictReader(open(out / "kinematics.csv")) if r["point"] == "hidden"]
    acc = np.array([[float(r[c]) for c in ("ax_mps2", "ay_mps2", "az_mps2")] for r in rows])
    inner = slice(20, -20)
    err = np.sqrt(np.mean(np.sum((acc[inner] - d["hidden_acc"][inner]) ** 2, 1)))
    assert err < 0.1 * np.sqrt(np.mean(np.sum(d["hidden_acc"][inner] ** 2, 1)))
    assert "smoothing the pose in windows" in said
