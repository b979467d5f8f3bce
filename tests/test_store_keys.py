"""The results store reuses a step only for the same choices: switching presets back and forth
(as a student does in notebook 00) gives each run the rig and comfort numbers of a fresh run."""
from __future__ import annotations

import numpy as np

from horsemocap.data import default_session_dir
from horsemocap.pipeline import analyze
from horsemocap.workspace import results_for

COMFORT = ("acc_y_Wb_rms", "acc_y_Wk_rms", "VDV_y_Wb", "VDV_y_Wk", "TA_8_action_Wk", "TA_8_limit_Wk")


def _summary(analysis):
    """What a wrongly reused step would change: the rig's calibration (joint or pairwise, its error and
    camera centres) and the comfort numbers."""
    rig = analysis.rig.rig
    ind = analysis.comfort.indicators
    return {"calibration": rig.metadata.get("method"),
            "rig_error": rig.metadata.get("error"),
            "camera_centres": np.array([np.asarray(c.center, float) for c in rig.cameras]),
            "comfort": np.array([ind[k] for k in COMFORT], float)}


def test_switching_presets_back_and_forth_reuses_only_matching_steps(tmp_path, monkeypatch):
    monkeypatch.setenv("HORSEMOCAP_RESULTS", str(tmp_path / "store"))
    session = default_session_dir()
    fresh = {name: _summary(analyze(session, None, choice, progress=lambda *a: None))
             for name, choice in (("default", None), ("thesis", {"preset": "thesis"}),
                                  ("pairwise", {"rig": {"mode": "pairwise"}}))}
    # the two chains calibrate differently: a store that mixed them up would show here
    assert fresh["default"]["calibration"].startswith("joint") and fresh["thesis"]["calibration"].startswith("pairwise")
    assert fresh["pairwise"]["calibration"].startswith("pairwise")
    # the store keeps the latest result of each step; the preset is in every key, so the pairwise
    # calibration chosen alone right after a default run is what a key without the mode would reuse wrongly
    for name, choice in (("default", {}), ("thesis", {"preset": "thesis"}), ("default", {}),
                         ("pairwise", {"rig": {"mode": "pairwise"}}), ("thesis", {"preset": "thesis"})):
        got = _summary(results_for(session, params=choice))
        want = fresh[name]
        assert got["calibration"] == want["calibration"], name
        assert got["rig_error"] == want["rig_error"], name
        np.testing.assert_allclose(got["camera_centres"], want["camera_centres"], rtol=0, atol=1e-9, err_msg=name)
        np.testing.assert_allclose(got["comfort"], want["comfort"], rtol=1e-9, err_msg=name)
