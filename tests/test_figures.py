"""The thesis' missing figures and outputs: per-marker comfort and amplitudes (known answers), and the
figure functions of Figures 8.3-8.28 (panels, titles with units, labelled markers)."""
from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import numpy as np
import pytest

from horsemocap import plots, vibration


def _stride(n=80, fps=30.0, f0=1.6, amp=(0.02, 0.04, 0.01)):
    t = np.arange(n) / fps
    w = 2 * np.pi * f0
    pos = np.stack([4.0 * t, amp[1] * np.cos(w * t), amp[2] * np.sin(2 * w * t)], 1)
    vel = np.stack([np.full(n, 4.0), -amp[1] * w * np.sin(w * t), 2 * w * amp[2] * np.cos(2 * w * t)], 1)
    acc = np.stack([np.zeros(n), -amp[1] * w ** 2 * np.cos(w * t), -4 * w ** 2 * amp[2] * np.sin(2 * w * t)], 1)
    return t, pos, vel, acc


def test_marker_comfort_is_the_saddle_comfort_of_each_marker():
    t, pos, vel, acc = _stride()
    t2, pos2, vel2, acc2 = _stride(amp=(0.02, 0.08, 0.01))
    P, V, A = (np.stack([a, b], 1) for a, b in ((pos, pos2), (vel, vel2), (acc, acc2)))
    rows = vibration.marker_comfort(t, P, A, V, f0_hz=1.6)
    one = vibration.saddle_comfort(t, pos, acc, vel, f0_hz=1.6)
    assert rows[0] == one
    # twice the vertical amplitude: twice the weighted rms (the weighting is linear)
    assert rows[1]["acc_y_Wb_rms"] == pytest.approx(2 * one["acc_y_Wb_rms"], rel=1e-9)


def test_marker_comfort_marks_a_marker_without_frames_none():
    t, pos, vel, acc = _stride()
    P, V, A = (np.stack([a, np.full_like(a, np.nan)], 1) for a in (pos, vel, acc))
    rows = vibration.marker_comfort(t, P, A, V, f0_hz=1.6)
    assert rows[0] is not None and rows[1] is None
    with pytest.raises(ValueError, match=r"shape \(80, M, 3\)"):
        vibration.marker_comfort(t, pos, acc, vel)


def test_half_peak_to_peak_of_sampled_cosines():
    t = np.arange(60) / 30.0                       # 2 s; period 1 s = 30 frames: both peaks sampled
    p = np.zeros((60, 2, 3))
    p[:, 0, 1] = 0.05 * np.cos(2 * np.pi * t) + 1.0
    p[:, 0, 2] = 0.01 * np.cos(2 * np.pi * t)
    p[:, 1] = np.nan
    amp = vibration.half_peak_to_peak(p)
    assert amp[0] == pytest.approx([0.05, 0.01], abs=1e-12)
    assert np.all(np.isnan(amp[1]))


def test_saddle_by_gait_has_position_and_acceleration_panels_with_units():
    t, pos, vel, acc = _stride()
    fig = plots.plot_saddle_by_gait({"Horse 1": (t, pos, acc), "Horse 2": None}, "walk")
    titles = [ax.get_title() for ax in fig.axes]
    assert len(fig.axes) == 6
    assert "y-motion (down): acceleration (m/s²)" in titles and "z-motion: position (m)" in titles
    assert [t.get_text() for t in fig.axes[0].get_legend().get_texts()] == ["Horse 1", "Horse 2 (not analysed)"]
    # x position drawn from the start: the first point is 0
    assert fig.axes[0].lines[0].get_ydata()[0] == 0


def test_marker_comfort_plot_names_units_and_missing_markers():
    t, pos, vel, acc = _stride()
    one = vibration.saddle_comfort(t, pos, acc, vel, f0_hz=1.6)
    fig = plots.plot_marker_comfort({"marker 1": one, "marker 2": None, "saddle": one})
    assert fig.axes[0].get_title() == "acc_y_Wb_rms (m/s²)"
    assert fig.axes[2].get_title() == "VDV_y_Wb (m/s^1.75)"
    assert "not computed" in [t.get_text() for t in fig.axes[0].texts]


def test_filtered_images_keep_only_regions_in_the_area_range():
    img = np.zeros((40, 60), np.uint8)
    img[10:14, 10:14] = 255       # 16 px: a marker
    img[20:30, 30:50] = 255       # 200 px: too big
    fig = plots.plot_filtered_images([img], threshold=128, area_range=(5, 50), marker_px=[np.array([[11.5, 11.5]])],
                                     labels=["saddle"], titles=["static shot"])
    original, filtered = fig.axes
    shown = filtered.images[0].get_array()
    assert shown[11, 11] and not shown[25, 40]
    assert original.get_title() == "static shot" and filtered.get_title() == "threshold 128, area 5-50 px"
    assert [t.get_text() for t in original.texts] == ["saddle"]
    fig = plots.plot_filtered_images([img, img], 128, marker_px=[np.array([[11.5, 11.5]]), None], zoom="markers")
    assert fig.axes[0].get_xlim() == pytest.approx((11.5 - 4.8, 11.5 + 4.8))  # 8 % of 60 px around the marker


def test_distortion_field_magnifies_small_shifts_and_says_so():
    """A lens moving pixels by a few px: arrows drawn magnified (the title says how much), the colour the
    true shift; a camera without distortion draws them to scale."""
    import matplotlib.pyplot as plt
    from horsemocap.camera import Camera
    K = [[800.0, 0.0, 320.0], [0.0, 800.0, 240.0], [0.0, 0.0, 1.0]]
    lens = Camera("left", (640, 480), K, distortions=np.array([-0.1, 0.0, 0.0, 0.0, 0.0]))
    ax = plots.plot_distortion_field(lens)
    q = ax.collections[0]
    assert "times their length" in ax.get_title()
    assert q.scale < 1.0                                          # 1/magnify: longer arrows than the shifts
    assert 1.0 < float(np.max(q.get_array())) < 30.0              # the colour: the true shift in px
    flat = Camera("left", (640, 480), K)
    assert "to scale" in plots.plot_distortion_field(flat).get_title()
    plt.close("all")
