"""A ride of several laps in the virtual laboratory: the lap motion, the timeline and each pass' own truth."""
from dataclasses import replace

import numpy as np
import pytest

from horsemocap.virtuallab import Scene, saddle_motion, thesis_rig
from horsemocap.virtuallab.herd import free_running_timings, herd_seed
from horsemocap.virtuallab.laps import LapMotion, LapsPlan, _truth, plan_laps
from horsemocap.virtuallab.rig import FPS


def _scene(lap_s=8.0):
    base = Scene(thesis_rig(), saddle_motion("Horse 2", "canter"), herd_seed("Horse 2", "canter"))
    return base, replace(base, motion=LapMotion.around(base.motion, lap_s))


def test_every_lap_repeats_the_single_pass_motion():
    base, laps = _scene(8.0)
    t = np.linspace(0.0, 7.9, 50)               # a lap from its start (before it: the last lap's tail)
    for lap in range(3):
        a, b = base.motion.pose(t), laps.motion.pose(t + 8.0 * lap)
        assert np.allclose(a.position, b.position) and np.allclose(a.rotation, b.rotation)
        assert np.allclose(a.omega, b.omega) and np.allclose(a.alpha, b.alpha)
        assert np.allclose(b.t, t + 8.0 * lap)                  # the times stay the recording's own
    assert laps.motion.lap_index([-1.0, 0.0, 7.99, 8.0, 16.5]).tolist() == [0, 0, 0, 1, 2]
    assert laps.motion.to_dict()["lap_s"] == 8.0


def test_a_lap_must_hold_a_pass():
    base, _ = _scene()
    with pytest.raises(ValueError, match="cannot hold a pass"):
        plan_laps(base, 3, 2.0)
    with pytest.raises(ValueError, match="lap_s"):
        LapMotion.around(base.motion, 0.0)
    plan = plan_laps(base, 3, 8.0)
    assert plan.n_frames == int(np.ceil((2 * 8.0 + plan.visible_s) * FPS))
    assert plan.pass_window(2) == (plan.offsets["left"] + 480, plan.offsets["left"] + 480 + plan.pass_frames)


def test_each_pass_has_its_own_truth_a_lap_later():
    """Free-running cameras: pass 1's truth lies in its own window, its instants a lap after pass 0's (to the
    reference camera's rate and a frame's rounding), and its motion is pass 0's at the same time into the lap."""
    base, scene = _scene(8.0)
    plan = plan_laps(base, 2, 8.0)
    timing = free_running_timings(0, 400, FPS)
    t0, t1 = _truth(scene, plan, timing, FPS, 0), _truth(scene, plan, timing, FPS, 1)
    for i, t in enumerate((t0, t1)):
        a, b = plan.pass_window(i)
        assert len(t.ref_frames) > 20 and a <= t.ref_frames[0] and t.ref_frames[-1] < b
    into0 = t0.motion_time_s
    into1 = t1.motion_time_s - 8.0
    assert abs(into1[0] - into0[0]) < 1.5 / FPS
    same = base.motion.saddle(into1)[2]
    assert np.allclose(t1.saddle_acc, same)
    assert t1.comfort["acc_y_Wb_rms"] == pytest.approx(t0.comfort["acc_y_Wb_rms"], rel=1e-9)


def test_plan_round_trips_through_the_truth_extras():
    base, _ = _scene()
    plan = plan_laps(base, 2, 8.0)
    again = LapsPlan.from_dict(plan.to_dict())
    assert again == plan
