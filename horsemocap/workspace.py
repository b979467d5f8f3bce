"""The session workspace: one riding session analysed step by step across the notebooks.

The thesis' user answered the prompts of Appendix A one program after another,
and every later program read the files the earlier ones wrote. The notebooks
do the same through two small files in the notebooks' results store
(:func:`notebook_results_dir`, ``$HORSEMOCAP_RESULTS``):

``workspace.json`` (in the store's root)
    ``{"session": "/path/to/session"}``: the session every notebook analyses,
    chosen in the first cell of any notebook (default: the bundled session).
``choices.json`` (in the session's results folder)
    ``{"parameters": {...}}``: the analysis parameters chosen with the
    notebooks' widgets, only those that differ from the automatic choice
    (optional file of the results contract, ``docs/sessions.md``).
    :func:`results_for` applies them on top of the
    session's own ``analysis`` object, and ``horsemocap analyze SESSION --out
    DIR --params choices.json`` runs the same analysis from the command line.

So a teacher who moves the threshold in notebook 04 and runs 05-14 sees
every later step (and the numbers of 12 and 14) follow. Nothing is ever
written into the session folder.

The functions here are pure file operations; :class:`Workspace` adds the
binding of a widget to a parameter (:meth:`Workspace.bind`).
"""
from __future__ import annotations

import contextlib
import copy
import hashlib
import json
import os
import re
import textwrap
from pathlib import Path

try:  # POSIX
    import fcntl
except ImportError:  # pragma: no cover - Windows
    fcntl = None

import numpy as np

from .data import cache_dir, data_samples_dir, default_session_dir
from .params import AnalysisParams, ParamsError
from . import quality
from .pipeline import Analysis, AnalysisError, analyze, resolve_params, step_keys
from .session import Session, SessionError, load_session
from .store import MAX_JSON_DEPTH, ResultsStore, atomic_write_json, json_depth, read_text_utf8, refuse_link
from .virtuallab.truth import load_truth

CHOICES_FILE = "choices.json"
WORKSPACE_FILE = "workspace.json"
NO_TRUTH = "no ground truth for this session"


# ---------------------------------------------------------------------------
# where things are
# ---------------------------------------------------------------------------

def results_root() -> Path:
    """The notebooks' results store: ``$HORSEMOCAP_RESULTS`` or ``<cache>/results``."""
    root = os.environ.get("HORSEMOCAP_RESULTS")
    return Path(root).resolve() if root else (cache_dir() / "results").resolve()


def sample_sessions() -> dict:
    """Sessions bundled in ``data_samples/`` (folders holding ``session.json``): name -> folder."""
    root = data_samples_dir()
    if not root.is_dir():
        return {}
    return {p.name: p.resolve() for p in sorted(root.iterdir()) if (p / "session.json").is_file()}


def check_session_dir(path) -> Path:
    """``path`` resolved, if it is a session folder; else :class:`ParamsError` naming it."""
    p = Path(path).expanduser()
    if not (p / "session.json").is_file():
        raise ParamsError(f"{p}: not a session folder (expected a folder holding session.json)")
    return p.resolve()


def current_session() -> Path:
    """The session of the workspace (``workspace.json``), else the bundled default session.

    A ``workspace.json`` that names a folder which no longer holds a session
    raises :class:`ParamsError` naming both (it is not silently replaced).
    """
    path = results_root() / WORKSPACE_FILE
    if not path.is_file():
        return default_session_dir().resolve()
    data = _read_json(path)
    if not isinstance(data, dict) or not isinstance(data.get("session"), str):
        raise ParamsError(f"{path}: expected {{\"session\": \"<session folder>\"}}")
    try:
        return check_session_dir(data["session"])
    except ParamsError as exc:
        raise ParamsError(f"{path}: {exc}; choose the session again in a notebook's first cell "
                          f"or delete {path}") from None


def set_current_session(session_dir) -> Path:
    """Make ``session_dir`` the session of every notebook (writes ``workspace.json``)."""
    p = check_session_dir(session_dir)
    root = results_root()
    root.mkdir(parents=True, exist_ok=True)
    atomic_write_json(root / WORKSPACE_FILE, {"session": str(p)})
    return p


def session_truth(session_dir=None):
    """The virtual laboratory's ground truth of a session, or ``None`` when it has none.

    A rendered session carries its truth in ``truth/``; a recorded one (every
    real session) does not. The notebooks compare with the truth where there
    is one and print :data:`NO_TRUTH` in its place otherwise.

    Parameters
    ----------
    session_dir : path, optional
        Default: the session of the workspace (:func:`current_session`).

    Returns
    -------
    horsemocap.virtuallab.Truth or None

    Examples
    --------
    >>> import tempfile
    >>> session_truth(tempfile.mkdtemp()) is None
    True
    """
    session_dir = Path(session_dir or current_session())
    if not (session_dir / "truth").is_dir():
        return None
    return load_truth(session_dir)


def choices_path(session_dir=None) -> Path:
    """``choices.json`` of a session's results folder (the session of the workspace by default)."""
    return notebook_results_dir(Path(session_dir or current_session()).resolve()) / CHOICES_FILE


# ---------------------------------------------------------------------------
# the choices
# ---------------------------------------------------------------------------

def _read_json(path: Path):
    text = read_text_utf8(path, ParamsError)
    if json_depth(text) > MAX_JSON_DEPTH:
        raise ParamsError(f"{path}: JSON nested too deeply to read")
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise ParamsError(f"{path}: not valid JSON ({exc.msg}, line {exc.lineno})") from None


def read_choices(session_dir=None) -> dict:
    """The parameters chosen with widgets for a session (only the overrides; ``{}`` when none)."""
    path = choices_path(session_dir)
    if not path.is_file():
        return {}
    data = _read_json(path)
    if not isinstance(data, dict) or not isinstance(data.get("parameters", None), dict):
        raise ParamsError(f"{path}: expected {{\"parameters\": {{...}}}}")
    return data["parameters"]


def session_params(session_dir=None, choices: dict | None = None, overrides: dict | None = None) -> AnalysisParams:
    """Defaults, then the session's ``analysis`` object, then the choices, then ``overrides`` (validated).

    Each layer overrides the ones before field by field (a section given in
    two layers keeps the fields only the earlier one names). Raises
    :class:`ParamsError` naming ``choices.json`` and the parameter when a
    choice is not valid for the session (a camera it does not have).
    """
    session_dir = Path(session_dir or current_session())
    session = load_session(session_dir, open_sources=False)
    choices = read_choices(session_dir) if choices is None else choices
    source = str(choices_path(session_dir))
    resolve_params(session)   # the session's own analysis object, checked (its errors name session.json)
    # the given values only, not the defaults filled in: a preset chosen in a notebook is not undone
    # by the defaults it replaces (as in pipeline.resolve_params, which the CLI uses)
    params = AnalysisParams.from_layers(session.analysis or {}, choices, overrides or {}, source=source)
    params.check_session(session, source)
    return params


@contextlib.contextmanager
def choices_lock(session_dir=None):
    """Hold the lock of a session's ``choices.json`` (an ``flock`` on ``.choices.json.lock`` beside it).

    Two kernels choosing at once take turns: each reads the choices the
    other wrote before adding its own, so none is lost.
    """
    path = choices_path(session_dir)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd = os.open(path.parent / f".{CHOICES_FILE}.lock", os.O_RDWR | os.O_CREAT, 0o666)
    try:
        if fcntl is not None:
            fcntl.flock(fd, fcntl.LOCK_EX)
        yield path
    finally:
        os.close(fd)   # closing the file releases the flock


def write_choices(session_dir, choices: dict) -> Path:
    """Replace a session's choices (validated first: a bad one writes nothing)."""
    session_params(session_dir, choices)
    with choices_lock(session_dir) as path:
        atomic_write_json(path, {"parameters": choices})
    return path


def _split(name: str) -> list[str]:
    keys = name.split(".")
    if not all(keys):
        raise ParamsError(f"choice '{name}': expected a parameter name or a dotted path such as "
                          "'detection.left.threshold'")
    return keys


def get_choice(session_dir, name: str, default=None):
    """A chosen value by (dotted) name, e.g. ``"detection.left.threshold"``; ``default`` if not chosen."""
    node = read_choices(session_dir)
    for k in _split(name):
        if not isinstance(node, dict) or k not in node:
            return default
        node = node[k]
    return node


def set_choice(session_dir, name: str, value) -> dict:
    """Choose one parameter (dotted name into nested objects); ``None`` takes the choice back.

    Taking a nested choice back removes the objects it leaves empty, so an
    untouched widget leaves no trace. Returns the new choices.
    """
    keys = _split(name)
    with choices_lock(session_dir) as path:   # read, change and write as one: a second kernel waits
        before = read_choices(session_dir)
        choices = _changed_choices(copy.deepcopy(before), keys, value)
        if choices != before or (value is not None and not path.is_file()):
            session_params(session_dir, choices)
            atomic_write_json(path, {"parameters": choices})
    return choices


def _changed_choices(choices: dict, keys: list, value) -> dict:
    """``choices`` with the value at the path ``keys`` set (``None``: taken back, empty objects removed)."""
    if value is None:
        trail, node = [], choices
        for k in keys[:-1]:
            if not isinstance(node.get(k), dict):
                return choices
            trail.append((node, k))
            node = node[k]
        node.pop(keys[-1], None)
        for parent, k in reversed(trail):
            if parent[k] == {}:
                del parent[k]
    else:
        node = choices
        for k in keys[:-1]:
            if not isinstance(node.get(k), dict):
                node[k] = {}
            node = node[k]
        node[keys[-1]] = value
    return choices


def clear_choices(session_dir=None) -> None:
    """Forget every choice of a session (back to the automatic analysis)."""
    with choices_lock(session_dir) as path:
        if path.is_file():
            path.unlink()


def to_json_value(value):
    """A widget's value as a JSON value (NumPy scalars and arrays, tuples -> Python)."""
    if isinstance(value, np.ndarray):
        return [to_json_value(v) for v in value.tolist()]
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, (list, tuple)):
        return [to_json_value(v) for v in value]
    if isinstance(value, dict):
        return {str(k): to_json_value(v) for k, v in value.items()}
    return value


def detection_changes(chosen, automatic) -> dict:
    """The fields of a chosen :class:`~horsemocap.detection.DetectionParams` that differ from the automatic one.

    Labels name regions of one frame, so they carry their ``first_frame``.
    """
    a, b = to_json_value(automatic.to_dict()), to_json_value(chosen.to_dict())
    out = {k: v for k, v in b.items() if a.get(k) != v and v is not None}  # None: automatic
    if out.get("labels") is not None:
        out["first_frame"] = b["first_frame"]
    return out


# ---------------------------------------------------------------------------
# the workspace of a notebook
# ---------------------------------------------------------------------------

_UNSET = object()
_UNSET_AUTO = object()
_NEVER = object()


def _value_widgets(widget):
    """The widget and its descendants that carry a ``value`` trait."""
    import ipywidgets as W

    shown_only = (W.Image, W.HTML, W.HTMLMath, W.Label, W.Output)
    out, todo = [], list(widget) if isinstance(widget, (list, tuple)) else [widget]
    while todo:
        w = todo.pop()
        if hasattr(w, "has_trait") and w.has_trait("value") and not isinstance(w, shown_only):
            out.append(w)
        todo.extend(getattr(w, "children", ()) or ())
    return out


def _show_value(widget, value) -> bool:
    """Put a stored choice into a widget (its own value, a threshold slider or checkboxes)."""
    try:
        if hasattr(widget, "show") and callable(widget.show) and isinstance(value, dict):
            widget.show(value)
            return True
        if hasattr(widget, "has_trait") and widget.has_trait("value"):
            opts = getattr(widget, "options", None)
            if opts is not None and not isinstance(value, (list, tuple)):
                vals = [o[1] if isinstance(o, tuple) else o for o in opts]
                if value not in vals:
                    return False
            widget.value = tuple(value) if isinstance(widget.value, tuple) else value
            return True
        inner = getattr(widget, "threshold", None)
        if isinstance(value, dict) and hasattr(inner, "slider") and "threshold" in value:
            inner.slider.value = value["threshold"]   # a whole detection control: its threshold
            return True
        if hasattr(widget, "slider") and isinstance(value, (int, float)):
            widget.slider.value = value
            return True
        boxes = getattr(widget, "checkboxes", None)
        if boxes is not None and isinstance(value, (list, tuple)) and len(value) == len(boxes):
            for b, v in zip(boxes, value):
                b.value = bool(v)
            return True
    except Exception:  # noqa: BLE001 - a stored value the widget cannot show stays only in the file
        return False
    return False


class Workspace:
    """The session a notebook analyses and the choices made for it.

    Parameters
    ----------
    session_dir : path, optional
        Default: the workspace's session (:func:`current_session`).

    Attributes
    ----------
    session_dir : Path
    picker : widget
        The session picker (:meth:`ui`), once built.
    """

    def __init__(self, session_dir=None):
        self.session_dir = check_session_dir(session_dir) if session_dir else current_session()
        self.picker = None
        self.bound = {}
        self.last_error = ""

    @property
    def name(self) -> str:
        return self.session_dir.name

    @property
    def choices(self) -> dict:
        return read_choices(self.session_dir)

    @property
    def params(self) -> AnalysisParams:
        """The parameters the notebooks use (the session's, plus the choices)."""
        return session_params(self.session_dir)

    @property
    def automatic(self) -> AnalysisParams:
        """The parameters without any choice but the preset (the session's ``analysis``, the preset, the defaults).

        With the thesis' chain chosen (``"preset": "thesis"``), a widget's
        automatic value is the preset's: moving it back there takes its
        choice back, and the preset holds.
        """
        preset = self.choices.get("preset")
        return session_params(self.session_dir, {"preset": preset} if preset else {})

    def choose(self, name: str, value) -> None:
        """Choose one parameter (dotted name); ``None`` takes the choice back.

        The session picker of the notebook (:meth:`ui`), if shown, says the new choices at once.
        """
        set_choice(self.session_dir, name, value)
        if self.picker is not None:
            self.picker._say()

    def use(self, session_dir) -> Path:
        """Analyse another session from now on, in this notebook and the next ones."""
        self.session_dir = set_current_session(session_dir)
        self.bound = {}
        return self.session_dir

    def bind(self, widget, name: str, *, automatic=_UNSET, convert=None, read=None):
        """Let a widget that stands in for a prompt write its choice into ``choices.json``.

        Parameters
        ----------
        widget : ipywidgets widget
            Any control with a ``.value`` (composite controls too: every
            child with a value is observed).
        name : str
            The parameter, a field of :class:`AnalysisParams` or a dotted path
            into one (``"detection.left.threshold"``).
        automatic : optional
            The automatic choice: the widget at this value leaves no choice
            in the file. Default: the parameter's value without choices when
            it is set, else the widget's value as built (the notebooks build
            every widget at the automatic choice); when neither is known (a
            choice is stored and the parameter's default is "automatic"),
            the choice is replaced but never taken back by the widget.
        convert : callable, optional
            Widget value -> parameter value (default: JSON conversion).
        read : callable, optional
            Returns the widget value (default ``widget.value``); for a list of
            widgets that give one parameter together.

        A choice stored earlier is shown in the widget; moving the widget
        back to the automatic value takes the choice back.

        Returns
        -------
        widget
        """
        convert = convert or to_json_value
        read = read or (lambda: widget.value)
        if automatic is _UNSET:
            automatic = to_json_value(self.automatic.value(name))
            if automatic is None or automatic == {}:
                automatic = _UNSET_AUTO
        else:
            automatic = to_json_value(automatic)
        stored = get_choice(self.session_dir, name)
        if stored is not None:
            if automatic is _UNSET_AUTO:
                # the widget was built from parameters that hold this choice: its automatic value is not
                # known here, so the choice is only ever replaced, never taken back by this widget
                automatic = _NEVER
            _show_value(widget, stored)
        if automatic is _UNSET_AUTO:
            automatic = convert(read())

        last = {"value": convert(read())}

        def write(*_):
            value = convert(read())
            if value == last["value"]:
                return
            last["value"] = value
            try:
                self.choose(name, None if value == automatic else value)
                self.last_error = ""
            except ParamsError as exc:  # shown beside the control when it has a message line, else raised
                self.last_error = str(exc)
                if hasattr(getattr(widget, "message", None), "value"):
                    widget.message.value = f"<span style='color:#b00'>not saved: {exc}</span>"
                else:
                    raise

        if hasattr(widget, "on_change"):
            widget.on_change(write)
        else:
            for w in _value_widgets(widget):
                w.observe(write, "value")
        self.bound[name] = widget
        return widget

    def __repr__(self) -> str:
        n = len(self.choices)
        return f"Workspace({self.name!r}, {n} choice{'s' if n != 1 else ''})"


def open_workspace(session_dir=None) -> Workspace:
    """The workspace of the current session (or of ``session_dir``)."""
    return Workspace(session_dir)


# ---------------------------------------------------------------------------
# the notebooks' results
# ---------------------------------------------------------------------------

def safe_store_name(name: str) -> str:
    """A session name as one folder name that stays inside the store.

    Letters, digits, ``.``, ``-`` and ``_`` are kept, anything else (``/``,
    ``..``, NUL, spaces) becomes ``_``; leading dots are dropped. A changed
    name gets 8 hex digits of its SHA-256, so two names never share a folder.
    """
    safe = re.sub(r"[^A-Za-z0-9._-]", "_", name).lstrip(".")[:80] or "session"
    if safe != name:
        safe += "-" + hashlib.sha256(name.encode("utf-8", "surrogateescape")).hexdigest()[:8]
    return safe


def notebook_results_dir(session: Session | Path) -> Path:
    """Where notebooks keep a session's results (``$HORSEMOCAP_RESULTS``).

    ``<root>/<name>-<folder>`` with the session's name made safe by
    :func:`safe_store_name` (a name like ``../../x`` stays inside the root)
    and 8 hex digits of the SHA-256 of the session folder's resolved path:
    two sessions with one name (the bundled Horse 2 canter and the herd's
    render of it) never share their results or the choices made for them.
    """
    if not isinstance(session, Session):
        session = load_session(session, open_sources=False)
    folder = str(Path(session.root).resolve())
    digest = hashlib.sha256(folder.encode("utf-8", "surrogateescape")).hexdigest()[:8]
    root = Path(os.environ.get("HORSEMOCAP_RESULTS") or (cache_dir() / "results")).resolve()
    path = root / f"{safe_store_name(session.name)}-{digest}"
    if path.parent != root:  # cannot happen with a safe name; never write outside the store
        raise ValueError(f"session name {session.name!r} leaves the results store {root}")
    refuse_link(path, "the session's results folder in the store")
    return path


def results_for(session_dir=None, until: str = "comfort", params=None) -> Analysis:
    """The analysis of a session up to a step, for notebooks.

    Runs the steps quietly and writes the spec's files to
    :func:`notebook_results_dir` (a clean folder per test run under nbval).
    Steps an earlier notebook computed for the same session, parameters and
    code are loaded from the results store, so each notebook runs alone and
    none repeats another's work.

    Parameters
    ----------
    session_dir : path, optional
        Default: the session of the workspace (:mod:`horsemocap.workspace`:
        the one chosen in a notebook's first cell, else the bundled session).
    until : str
        The last step to run.
    params : dict or AnalysisParams, optional
        The choices made with the notebooks' widgets (the session's
        ``choices.json``) are applied first, then a dict's overrides; an
        :class:`AnalysisParams` is used as it is. With no choices made, every
        choice is the automatic one.
    """
    session_dir = Path(session_dir or current_session()).resolve()
    if not isinstance(params, AnalysisParams):
        chosen = read_choices(session_dir)
        if chosen or params:
            params = session_params(session_dir, chosen, overrides=params)
    out = notebook_results_dir(session_dir)
    analysis = analyze(session_dir, out, params, until=until, progress=lambda *a: None, reuse=True)
    # a later step's files from an analysis with other parameters (nothing recomputed removes them)
    ResultsStore(out).forget_stale(step_keys(analysis.session, analysis.params), until)
    return analysis


# ---------------------------------------------------------------------------
# the two chains, downstream
# ---------------------------------------------------------------------------

CHAIN_NAMES = {"default": "the automatic choices", "thesis": "the thesis' chain"}


def followed_chain(session_dir=None) -> str:
    """The chain the notebooks follow for a session: ``"thesis"`` when chosen in notebook 00, else ``"default"``."""
    return read_choices(session_dir).get("preset") or "default"


def chain_choices(choices: dict, chain: str) -> dict:
    """``choices`` with the chain switched to ``chain`` (``"default"`` or ``"thesis"``).

    Every other choice is kept and, as always, overrides the chain's own
    value: a Fourier order chosen in notebook 09 is used by whichever chain
    reads Fourier orders.

    Examples
    --------
    >>> chain_choices({"preset": "thesis", "x_degree": 2}, "default")
    {'x_degree': 2}
    >>> chain_choices({"x_degree": 2}, "thesis")
    {'x_degree': 2, 'preset': 'thesis'}
    """
    if chain not in CHAIN_NAMES:
        raise ParamsError(f"chain: expected one of {sorted(CHAIN_NAMES)}, got {chain!r}")
    out = {k: v for k, v in choices.items() if k != "preset"}
    if chain != "default":
        out["preset"] = chain
    return out


def analysis_verdict(analysis: Analysis) -> tuple[str, list]:
    """The quality verdict of an analysis (as in ``quality.json``) and its checks that are not ``ok``."""
    checks = quality.pre_checks(analysis.session, analysis.rig.rig if analysis.rig is not None else None)
    checks += quality.post_checks(analysis)
    return quality.verdict(checks), [c for c in checks if c.level in ("warning", "unreliable")]


def downstream(session_dir=None, chain: str | None = None) -> dict:
    """What the current choices give at the end of one chain: saddle acceleration, Wb/Wk rms, verdict.

    Parameters
    ----------
    session_dir : path, optional
        Default: the workspace's session.
    chain : {"default", "thesis"}, optional
        Default: the chain followed (:func:`followed_chain`). The session's
        choices are applied with the chain switched (:func:`chain_choices`).

    Returns
    -------
    dict
        ``chain``, ``followed`` (bool), ``saddle_acc_y_rms`` (m/s^2, the
        saddle's unweighted vertical acceleration), ``acc_y_Wb_rms`` and
        ``acc_y_Wk_rms`` (m/s^2, NaN when the comfort step could not
        compute them), ``verdict`` and ``problems`` (the checks' messages
        that are not ``ok``), or ``error`` (why the chain stopped).
    """
    session_dir = Path(session_dir or current_session()).resolve()
    choices = read_choices(session_dir)
    followed = choices.get("preset") or "default"
    chain = chain or followed
    row = {"chain": chain, "followed": chain == followed}
    params = session_params(session_dir, chain_choices(choices, chain))
    try:
        an = results_for(session_dir, params=params)
    except (AnalysisError, SessionError) as exc:
        return {**row, "error": str(exc)}
    acc = an.rigid_body.saddle_acceleration if an.rigid_body is not None else None
    ind = (an.comfort.indicators if an.comfort is not None else None) or {}
    verdict_, problems = analysis_verdict(an)
    with np.errstate(all="ignore"):
        rms = float(np.sqrt(np.nanmean(np.asarray(acc)[:, 1] ** 2))) if acc is not None else float("nan")
    return {**row, "saddle_acc_y_rms": rms, "acc_y_Wb_rms": float(ind.get("acc_y_Wb_rms", np.nan)),
            "acc_y_Wk_rms": float(ind.get("acc_y_Wk_rms", np.nan)), "verdict": verdict_,
            "problems": [f"{c.level}: {c.message}" for c in problems]}


def _session_name(session_dir: Path) -> str:
    """The session's own name (session.json ``name``), or its folder's when session.json cannot be read."""
    try:
        return load_session(session_dir, open_sources=False).name
    except SessionError:
        return session_dir.name


def downstream_text(session_dir=None, chains=("default", "thesis"), problems: bool = True) -> str:
    """Both chains' :func:`downstream` numbers under the current choices, as a small table.

    The notebooks print it after their widgets: move a widget, run the cell
    again, and see what the choice does to the saddle and the comfort
    numbers on the chain the widget belongs to.
    """
    session_dir = Path(session_dir or current_session()).resolve()
    rows = [downstream(session_dir, c) for c in chains]
    lines = [f"{'chain (session ' + _session_name(session_dir) + ')':40s} {'saddle A_y rms':>15s} {'Wb rms':>8s} "
             f"{'Wk rms':>8s}  verdict"]
    for r in rows:
        label = CHAIN_NAMES[r["chain"]] + (" (followed)" if r["followed"] else "")
        if "error" in r:
            lines.append(f"{label:40s} stopped: {r['error']}")
            continue
        lines.append(f"{label:40s} {r['saddle_acc_y_rms']:10.2f} m/s² {r['acc_y_Wb_rms']:8.2f} "
                     f"{r['acc_y_Wk_rms']:8.2f}  {r['verdict'].upper()}")
    if problems:
        for r in rows:
            for msg in r.get("problems", []):
                lines += problem_lines(f"{CHAIN_NAMES[r['chain']]}: {msg}")
    return "\n".join(lines)


#: The width (characters) of a check's message in :func:`downstream_text`: JupyterLab's output area breaks a
#: longer line wherever the pane ends, in the middle of a word.
PROBLEM_WIDTH = 110


def problem_lines(message: str, width: int = PROBLEM_WIDTH) -> list:
    """A check's message as lines of at most ``width`` characters, broken between words, indented under the
    table (the first line by two spaces, the rest by four).

    Examples
    --------
    >>> problem_lines("the thesis' chain: warning: thin marker triangle: smallest height 66 mm", width=40)
    ["  the thesis' chain: warning: thin", '    marker triangle: smallest height 66', '    mm']
    """
    return textwrap.wrap(message, width=width, initial_indent="  ", subsequent_indent="    ",
                         break_long_words=False, break_on_hyphens=False)
