"""Tests of horsemocap.herd (thesis section 8.5, Table 8.8)."""
import numpy as np
import pytest

from horsemocap import herd, vibration as vib

# Table 8.8 'avg' rows as printed in the thesis (independent of the CSV's
# per-rider grades: a transcription error in either would show here).
PRINTED_AVG = {
    "walk": (3.75, 4.5, 4.25, 2.75),
    "sitting_trot": (2.5, 4.0, 4.0, 2.0),
    "rising_trot": (3.0, 4.5, 4.25, 3.0),
    "canter": (2.75, 4.75, 5.0, 2.25),
}
PRINTED_OVERALL = (3.0, 4.4375, 4.375, 2.5)


def test_grades_reproduce_the_printed_averages():
    g = herd.load_grades()
    assert set(g) == set(herd.GAITS)
    mg = herd.mean_grades(g)
    for gait, avgs in PRINTED_AVG.items():
        for h, a in zip(herd.HORSES, avgs):
            assert len(g[gait][h]) == 4
            assert mg[(gait, h)] == a, (gait, h)
    for h, a in zip(herd.HORSES, PRINTED_OVERALL):
        assert np.mean([mg[(gait, h)] for gait in herd.GAITS]) == a


def test_bad_grades_file_is_rejected(tmp_path):
    p = tmp_path / "g.csv"
    p.write_text("# c\ngait,horse,rider,grade\nwalk,Horse 1,A,7\n")
    with pytest.raises(ValueError, match="outside 1..5"):
        herd.load_grades(p)
    p.write_text("gait,horse,rider,grade\ngallop,Horse 1,A,3\n")
    with pytest.raises(ValueError, match="gallop"):
        herd.load_grades(p)


def test_compare_spearman_on_synthetic_table():
    mg = herd.mean_grades()
    # an indicator that decreases with the grade exactly, and one that grows
    table = {(h, g): {"acc_y_Wb_rms": 10.0 - mg[(g, h)], "TA_8_limit_Wb": mg[(g, h)] ** 2}
             for g in herd.GAITS for h in herd.HORSES}
    out = herd.compare(table, indicators=("acc_y_Wb_rms", "TA_8_limit_Wb"))
    by = {(c.gait, c.indicator): c for c in out}
    assert by[("canter", "acc_y_Wb_rms")].rho == pytest.approx(-1.0)
    assert by[("canter", "acc_y_Wb_rms")].as_expected is True
    assert by[("walk", "TA_8_limit_Wb")].rho == pytest.approx(1.0)
    assert by[("pooled", "TA_8_limit_Wb")].n == 12          # rising trot left out
    assert by[("pooled", "TA_8_limit_Wb")].rho == pytest.approx(1.0)


def test_compare_handles_ties_and_constant_indicator():
    table = {(h, g): {"vel_x_avg": 5.0} for g in herd.GAITS for h in herd.HORSES}
    out = herd.compare(table, indicators=("vel_x_avg",), pooled=False)
    assert all(np.isnan(c.rho) for c in out)


def test_analytic_indicators_of_the_default_session():
    ind = herd.analytic_indicators("Horse 2", "canter")
    assert tuple(ind) == vib.COMFORT_KEYS + vib.DIRECTIVE_KEYS
    assert ind["f0_hz"] == pytest.approx(30 / 18)          # 18 frames at 30 fps
    assert ind["duration_s"] == pytest.approx(1.2)
    assert ind["vel_x_avg"] == pytest.approx(17.6, rel=1e-6)
    # the weighted rms lies between the smallest and largest weight times the raw rms
    raw = herd.analytic_indicators("Horse 2", "canter", mode="thesis")
    assert ind["acc_y_Wb_rms"] > raw["acc_y_Wb_rms"]        # harmonics weighted up


def test_herd_table_shape_and_csv(tmp_path):
    tab = herd.herd_indicators("analytic", horses=("Horse 1", "Horse 2"), gaits=("walk", "canter"))
    assert len(tab) == 4
    m = herd.indicator_matrix(tab, "vel_x_avg", horses=("Horse 1", "Horse 2"), gaits=("walk", "canter"))
    assert m.shape == (2, 2) and np.all(m[1] > m[0])          # canter faster than walk
    p = herd.write_herd_csv(tmp_path / "herd.csv", tab)
    lines = p.read_text().splitlines()
    assert lines[0].startswith("horse,gait,mean_grade,acc_y_Wb_rms")
    assert len(lines) == 5
    with pytest.raises(ValueError, match="source"):
        herd.herd_indicators("videos")
