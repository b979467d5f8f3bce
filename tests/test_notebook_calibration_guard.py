"""The calibration guard the notebooks share for a session whose rig comes from rig.toml (horsemocap.widgets.calibration)."""
from __future__ import annotations

import json

from horsemocap.data import default_session_dir
from horsemocap.widgets.calibration import session_calibration


def _rig_only_session(tmp_path):
    """The bundled session's videos and stills with a rig file in place of the checkerboard views."""
    src = default_session_dir()
    meta = json.loads((src / "session.json").read_text())
    for key in ("motion", "plumb", "static"):
        meta[key] = {c: str(src / p) for c, p in meta[key].items()}
    (tmp_path / "calibration").mkdir()
    (tmp_path / "calibration" / "rig.toml").write_text((src / "truth" / "rig.toml").read_text())
    meta["calibration"] = {"rig": "calibration/rig.toml"}
    (tmp_path / "session.json").write_text(json.dumps(meta))
    return tmp_path


def test_session_calibration_views():
    c = session_calibration(default_session_dir())
    assert sorted(c.views) == ["left", "middle", "right"]
    assert c.board == ((7, 14), 0.1)
    assert c.views_used and c.note == c.short == "" and c.rig_path is None


def test_session_calibration_rig_only(tmp_path):
    c = session_calibration(_rig_only_session(tmp_path))
    assert c.views is None and c.board is None and not c.views_used
    assert c.rig_path == (tmp_path / "calibration" / "rig.toml").resolve()
    assert c.note == ("no checkerboard views in this session: the pipeline reads the rig from "
                         "calibration/rig.toml instead of calibrating it")
    assert c.short == "no checkerboard views; the rig was read from rig.toml"


def test_the_closing_table_names_the_session_by_its_json_name(tmp_path):
    """A user's folder called 'session' is named by session.json's name; an unreadable one by its folder."""
    from horsemocap.workspace import _session_name

    (tmp_path / "session").mkdir()
    folder = _rig_only_session(tmp_path / "session")
    assert _session_name(folder) == "horse2_canter"
    assert _session_name(tmp_path) == tmp_path.name
