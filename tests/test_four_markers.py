"""Any number of markers from three up: static matching, labelling, registration, pose, the hidden saddle."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from horsemocap.detection.marker_model import fit_marker_model
from horsemocap import rigid
from horsemocap.params import PoseParams, RigidBodyParams
from horsemocap.rigid import analyse_rigid_body, match_static_markers, register
from horsemocap.virtuallab.covers import CROUP, LOWER_FLANK, horse_with_markers
from horsemocap.virtuallab.horse import HERD

#: Skin markers along a horse's back (m, x forward, y down) and the saddle marker last.
BODY5 = np.array([[-0.86, -0.02, -0.28], [-0.62, 0.02, -0.31], [-0.38, 0.09, -0.33], [-0.26, 0.20, -0.34],
                  [-0.14, 0.03, -0.33]])
SADDLE = np.array([0.10, -0.235, -0.30])


def _ride(body, n=150, fps=50.0, noise_m=0.0, seed=0):
    """A body trotting forward, pitching and rolling; markers (n, m, 3), the saddle (n, 3), its acceleration."""
    t = np.arange(n) / fps
    f = 2.2
    rot = np.column_stack([0.04 * np.sin(2 * np.pi * f * t + 0.3), 0.02 * np.sin(2 * np.pi * f * t),
                           0.05 * np.sin(2 * np.pi * f * t + 1.0)])
    R = Rotation.from_rotvec(rot).as_matrix()
    pos = np.column_stack([3.0 * t, 0.03 * np.sin(2 * np.pi * 2 * f * t), np.zeros(n)])
    pts = np.einsum("kij,mj->kmi", R, body) + pos[:, None]
    saddle = np.einsum("kij,j->ki", R, SADDLE) + pos
    rng = np.random.default_rng(seed)
    return t, pts + rng.normal(0, noise_m, pts.shape), saddle


def _saddle_error(t, pts, static, saddle, smoothing="none"):
    rb = analyse_rigid_body(t, pts, static, RigidBodyParams(pose=PoseParams(smoothing=smoothing)))
    return rb, float(np.sqrt(np.nanmean(np.sum((rb.saddle_position - saddle) ** 2, axis=1))))


@pytest.mark.parametrize("m", [3, 4, 5])
def test_saddle_found_with_any_number_of_markers(m):
    body = BODY5[[1, 2, 4]] if m == 3 else BODY5[[0, 1, 2, 4]] if m == 4 else BODY5
    t, pts, saddle = _ride(body)
    static = np.vstack([body, SADDLE])[::-1]          # any order, saddle among them
    rb, err = _saddle_error(t, pts, static, saddle)
    assert rb.pos.shape == pts.shape
    assert rb.model.shape == (m, 3)
    assert err < 1e-9
    if m > 3:
        assert "three markers" in rb.chain_error


def test_more_markers_average_the_noise():
    """Least squares over every marker: five noisy markers carry the saddle better than three."""
    errs = {}
    for m, idx in ((3, [1, 2, 4]), (5, [0, 1, 2, 3, 4])):
        body = BODY5[idx]
        t, pts, saddle = _ride(body, n=400, noise_m=0.002)
        reg = register(pts, body)
        found = np.einsum("kij,j->ki", reg.rotation, SADDLE) + reg.translation
        errs[m] = float(np.sqrt(np.mean(np.sum((found - saddle) ** 2, axis=1))))
    assert errs[5] < 0.8 * errs[3], errs


def test_a_missing_marker_costs_nothing_when_the_others_define_the_pose():
    t, pts, saddle = _ride(BODY5)
    gappy = pts.copy()
    gappy[40:60, 2] = np.nan          # one marker hidden for 20 frames
    gappy[90:95, 0] = np.nan          # another later
    _, err = _saddle_error(t, gappy, np.vstack([BODY5, SADDLE]), saddle)
    assert err < 1e-9


def test_the_thesis_chain_refuses_more_than_three_markers_by_name():
    t, pts, _ = _ride(BODY5[:4])
    with pytest.raises(ValueError, match="kinematics: 'fits' is the thesis' chain of three markers"):
        analyse_rigid_body(t, pts, np.vstack([BODY5[:4], SADDLE]), RigidBodyParams(kinematics="fits"))
    with pytest.raises(ValueError, match="3 or more markers"):
        analyse_rigid_body(t, pts[:, :2], np.vstack([BODY5[:2], SADDLE]))


def test_static_shot_matched_with_five_markers():
    static = np.vstack([BODY5, SADDLE])
    order = [4, 0, 5, 2, 1, 3]
    _, pts, _ = _ride(BODY5, n=20)
    index, saddle = match_static_markers(static[order], pts)
    assert [order[i] for i in index] == [0, 1, 2, 3, 4]
    assert order[saddle] == 5


def test_marker_model_labels_four_markers_among_clutter():
    model = np.vstack([BODY5[[0, 1, 2, 4]], SADDLE]) + [0.0, 0.0, 8.0]
    frame = model[[3, 1, 0, 2]] + [0.4, 0.02, 0.0]
    clutter = np.array([[0.3, 0.5, 8.0], [-0.9, 0.4, 8.1]])
    pts = np.vstack([frame, clutter])
    cov = np.tile(np.eye(3) * 1e-6, (len(pts), 1, 1))
    fit = fit_marker_model(pts, cov, model, 4, np.zeros(3))
    assert fit is not None
    # model point i of the chosen skin markers is frame point assignment[i]
    labelled = {int(mi): int(a) for mi, a in zip(fit.model_index, fit.assignment)}
    assert labelled == {3: 0, 1: 1, 0: 2, 2: 3}


def test_virtual_horse_with_more_markers_keeps_them_rear_to_front():
    h = horse_with_markers(HERD["Horse 2"], [CROUP, LOWER_FLANK])
    assert h.marker_body.shape == (5, 3) and h.marker_normal.shape == (5, 3)
    assert np.all(np.diff(h.marker_body[:, 0]) > 0)
    with pytest.raises(ValueError, match="extra_body"):
        horse_with_markers(HERD["Horse 2"], [[1.0, 2.0]])


def test_assignments_built_marker_by_marker_are_the_permutations_that_fit():
    """The pruned search lists exactly the permutations whose every distance fits, in the same order."""
    import itertools
    from horsemocap.detection.marker_model import _pair_distances, _rigid_assignments
    rng = np.random.default_rng(3)
    model = BODY5[[0, 1, 2, 4]]
    pts = np.vstack([model[[2, 0, 3, 1]] + [0.1, 0.0, 8.0], rng.uniform(-1, 1, (7, 3)) + [0, 0, 8.0]])
    cov = np.tile(np.eye(3) * 4e-6, (len(pts), 1, 1))
    d, tol = _pair_distances(pts, cov, 0.2)          # a wide slack: many chance fits to compare
    model_d = np.linalg.norm(model[:, None] - model[None], axis=-1)
    brute = [p for p in itertools.permutations(range(len(pts)), 4)
             if all(abs(d[p[i], p[j]] - model_d[i, j]) / tol[p[i], p[j]] <= 1.0
                    for i, j in itertools.combinations(range(4), 2))]
    got = _rigid_assignments(d, tol, model_d)
    assert len(brute) > 1
    assert got.tolist() == [list(p) for p in brute]


def _cover_bias(n, start, length, size_m, ramp=3):
    """A cover's pull on a marker's centre: rising over ``ramp`` frames to ``size_m``, held, falling again."""
    k = np.arange(n, dtype=float)
    rise = np.clip((k - start + 1) / ramp, 0, 1) * np.clip((start + length - k) / ramp, 0, 1)
    return size_m * rise


@pytest.mark.parametrize("m, marker", [(4, 3), (5, 1), (4, 0)])
def test_a_marker_moving_against_the_others_is_left_out(m, marker, monkeypatch):
    """Views that agree but a centre pulled against the others' rigid motion: left out, the others keep the pose.

    BODY5's three rear markers lie nearly on a line: without the front one (4 markers, marker 3) they hold the
    roll about that line poorly, so leaving it out helps less there than elsewhere.
    """
    body = BODY5[[0, 1, 2, 4]] if m == 4 else BODY5
    t, pts, saddle = _ride(body, n=200, noise_m=0.0005, seed=3)
    pulled = pts.copy()
    pulled[:, marker] += _cover_bias(len(t), 120, 16, 0.02)[:, None] * np.array([0.5, -0.8, 0.3])
    static = np.vstack([body, SADDLE])
    rb_clean, err_clean = _saddle_error(t, pts, static, saddle)
    rb, err = _saddle_error(t, pulled, static, saddle)
    bias = _cover_bias(len(t), 120, 16, 0.02)
    big = np.flatnonzero(bias > 0.01)
    assert rb.left_out[bias > 0.019, marker].all()                        # the whole cover
    assert rb.left_out[big, marker].mean() >= 0.8                          # most of its ramps
    assert rb.left_out.sum() <= big.size + 0.02 * rb.left_out.size        # few false alarms on the noise
    assert rb_clean.left_out.sum() <= 0.02 * rb_clean.left_out.size
    monkeypatch.setattr(rigid, "RIGID_MOTION_THRESHOLD", np.inf)            # the same without leaving out
    rb_kept, err_kept = _saddle_error(t, pulled, static, saddle)
    assert not rb_kept.left_out.any()
    assert err < 0.8 * err_kept, (err, err_kept)
    if marker != 3 or m != 4:
        assert err < err_clean + 0.0002, (err, err_clean)                  # as if nothing were covered


def test_three_markers_are_never_left_out():
    """With three markers the others cannot give a pose: nothing is marked, the thesis' chain is untouched."""
    body = BODY5[[1, 2, 4]]
    t, pts, saddle = _ride(body, noise_m=0.0005)
    pts[60:70, 1] += 0.02
    rb, _ = _saddle_error(t, pts, np.vstack([body, SADDLE]), saddle)
    assert not rb.left_out.any()
