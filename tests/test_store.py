import json

import numpy as np
import pytest

from horsemocap.store import ResultsStore, StoreError, atomic_write_text, check_outside


def test_store_roundtrip_and_keys(tmp_path):
    store = ResultsStore(tmp_path / "res")
    assert store.load("detect", "k1") is None
    store.save("detect", {"marker_px": np.arange(6.0).reshape(1, 3, 2), "threshold": 115}, "k1")
    got = store.load("detect", "k1")
    assert got["threshold"] == 115
    np.testing.assert_array_equal(got["marker_px"], np.arange(6.0).reshape(1, 3, 2))
    assert store.load("detect", "k2") is None  # other parameters or code: recompute
    store.path("fit").write_bytes(b"garbage")
    assert store.load("fit", "k1") is None


def test_atomic_write_leaves_old_file_on_failure(tmp_path):
    path = tmp_path / "a.json"
    atomic_write_text(path, json.dumps({"v": 1}))

    class Boom:
        def encode(self, _):
            raise RuntimeError("boom")

    with pytest.raises(RuntimeError):
        atomic_write_text(path, Boom())
    assert json.loads(path.read_text()) == {"v": 1}
    assert [p.name for p in tmp_path.iterdir()] == ["a.json"]


def test_results_never_inside_session(tmp_path):
    check_outside(tmp_path / "out", tmp_path / "session")
    with pytest.raises(StoreError, match="lies inside the input session"):
        check_outside(tmp_path / "session" / "out", tmp_path / "session")
