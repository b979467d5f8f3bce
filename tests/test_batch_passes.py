"""The batch's table with a recording of several passes; the herd read back from a batch."""
import io

import numpy as np
import pytest

from horsemocap import batch, herd


def test_a_recording_with_passes_adds_its_optional_columns(tmp_path):
    (tmp_path / "passes.csv").write_text(
        "pass,main,first_frame,last_frame,start_s,duration_s,verdict,error,acc_y_Wb_rms,VDV_y_Wb\n"
        "1,1,29,67,0.7,1.2,ok,,3.6,4.6\n"
        "2,0,329,367,10.7,,unreliable,too short,,\n"
        "all,,,,,1.2,unreliable,,3.6,4.6\n")
    cols = batch._passes(tmp_path)
    assert cols["passes"] == 2 and cols["passes_verdict"] == "unreliable"
    assert cols["passes_acc_y_Wb_rms"] == 3.6 and cols["passes_duration_s"] == 1.2
    assert "passes_first_frame" not in cols and "passes_error" not in cols
    assert batch._passes(tmp_path / "absent") == {}
    rows = [{"name": "a", "horse": "Horse 1", "gait": "walk", "exit_status": 0, "VDV_y_Wb": 4.0, **cols}]
    assert herd.table_indicators(rows) == {("Horse 1", "walk"): {"VDV_y_Wb": 4.0}}


def test_the_saddle_read_back_from_a_results_folder(tmp_path):
    (tmp_path / "trajectories.csv").write_text(
        "frame,time_s,point,x_m,y_m,z_m\n10,0,marker1,1,2,3\n10,0,saddle,0.5,0.25,\n11,0.0333,saddle,0.6,0.3,0.1\n")
    (tmp_path / "kinematics.csv").write_text(
        "frame,time_s,point,vx_mps,vy_mps,vz_mps,ax_mps2,ay_mps2,az_mps2\n"
        "10,0,saddle,1,0,0,0.1,0.2,0.3\n11,0.0333,saddle,1,0,0,0.4,0.5,0.6\n")
    t, pos, acc = herd.batch_saddle_series(tmp_path)
    np.testing.assert_allclose(t, [0, 0.0333])
    assert pos.shape == (2, 3) and np.isnan(pos[0, 2]) and pos[1, 0] == 0.6
    np.testing.assert_allclose(acc, [[0.1, 0.2, 0.3], [0.4, 0.5, 0.6]])
    (tmp_path / "kinematics.csv").write_text("frame,time_s,point,ax_mps2,ay_mps2,az_mps2\n")
    with pytest.raises(ValueError, match="kinematics.csv.*saddle"):
        herd.batch_saddle_series(tmp_path)


def test_rendering_the_herd_says_how_long_is_left(monkeypatch, tmp_path):
    cached = {("Horse 1", "walk")}
    monkeypatch.setattr(batch, "herd_session_cached", lambda h, g: (h, g) in cached)
    monkeypatch.setattr(batch, "herd_session", lambda h, g: tmp_path / f"{h}-{g}")
    stream = io.StringIO()
    pairs = [("Horse 1", "walk"), ("Horse 1", "canter"), ("Horse 2", "canter")]
    paths = batch.render_herd(pairs, stream=stream)
    assert paths == [tmp_path / f"{h}-{g}" for h, g in pairs]
    lines = stream.getvalue().splitlines()
    assert lines[0].startswith("herd: 1/2 sessions rendered, about ") and "left" in lines[0]
    assert lines[1] == "herd: 2/2 sessions rendered, done"


def test_readable_axis_labels():
    from horsemocap.plots.herd import _label

    assert _label("Distance_TA_8_limit_Wb") == "Distance to the limit (km)"
    assert all(_label(k) != k for k in herd.THESIS_INDICATORS)
