"""Comparing horses and gaits: indicators, riders' grades, rank correlations.

Thesis section 8.5: the comfort indicators of chapter 7 for 4 horses x 4
gaits (walk, sitting trot, rising trot, canter; all ridden counter-clockwise)
against the grades four riders gave each horse in each gait (Table 8.8).

The thesis' eight indicators (section 8.5) are :data:`THESIS_INDICATORS`.
It reads them with three caveats, kept here with the numbers:

* the cameras' low frame rate and resolution limit the accuracy;
* every indicator but ``vel_x_avg`` assumes the rider stays in contact
  with the saddle, which is false in **rising trot** (the rider stands up
  every other beat), so rising trot "should be somewhat disregarded";
* ``TA_8_limit_Wb`` and ``Distance_TA_8_limit_Wb`` rest on the EU exposure
  limit values (Table 7.2), set for a passive person; a rider compensates
  (belly movement at sitting trot, swinging at canter), so they are
  **relative** comfort indicators: a horse with 3 h is "twice as
  comfortable" as one with 1.5 h, not safe to ride for 3 h.

Data sources (``source=``): ``"analytic"`` computes the indicators from the
virtual laboratory's analytic saddle motion (the ground truth of the
virtual herd; fast, no rendering); ``"pipeline"`` renders each session (once,
into the cache) and runs the full analysis on the videos.

The herd study as a batch: :func:`horsemocap.batch.herd_batch` renders the sessions and
analyses them side by side with ``horsemocap batch``
(:func:`horsemocap.batch.run_batch`: every core, resumable, one table
``sessions.csv``); :func:`table_indicators` reads that table into the
``{(horse, gait): indicators}`` form :func:`compare`, :func:`indicator_matrix`
and :func:`herd_rows` take.
"""
from __future__ import annotations

import csv
import io
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import stats

from . import vibration as vib
from .batch_table import BASE_COLUMNS, read_table
from .data import data_samples_dir
from .store import atomic_write_text

__all__ = ["HORSES", "GAITS", "GAIT_LABELS", "THESIS_INDICATORS", "EXPECTED_SIGN",
           "CAVEATS", "load_grades", "mean_grades", "analytic_indicators",
           "pipeline_indicators", "herd_indicators", "indicator_matrix", "compare",
           "Correlation", "herd_rows", "write_herd_csv", "table_indicators", "INDICATOR_LABELS",
           "batch_saddle_series"]

HORSES = ("Horse 1", "Horse 2", "Horse 3", "Horse 4")
GAITS = ("walk", "sitting_trot", "rising_trot", "canter")
GAIT_LABELS = {"walk": "walk", "sitting_trot": "sitting trot", "rising_trot": "rising trot",
               "canter": "canter"}

THESIS_INDICATORS = ("acc_y_max", "acc_y_Wb_rms", "crest_factor_y", "Distance_TA_8_limit_Wb",
                     "TA_8_limit_Wb", "VDV_y_Wb", "vel_x_avg", "amplitude_y")
"""The 8 indicators of section 8.5, in the order of Figures 8.29-8.32."""

INDICATOR_LABELS = {
    "acc_y_max": "Peak vertical acceleration (m/s²)",
    "acc_y_Wb_rms": "Weighted rms acceleration, Wb (m/s²)",
    "acc_y_Wk_rms": "Weighted rms acceleration, Wk (m/s²)",
    "crest_factor_y": "Crest factor",
    "Distance_TA_8_limit_Wb": "Distance to the limit (km)",
    "Distance_TA_8_action_Wb": "Distance to the action value (km)",
    "TA_8_limit_Wb": "Time to the limit (h)",
    "TA_8_action_Wb": "Time to the action value (h)",
    "TA_8_limit_directive": "Time to the limit, three axes (h)",
    "VDV_y_Wb": "Vibration dose value, Wb (m/s^1.75)",
    "vel_x_avg": "Mean speed (km/h)",
    "amplitude_y": "Vertical amplitude (m)",
}
"""Axis labels of the indicators in words (the figures of section 8.5)."""

EXPECTED_SIGN = {"acc_y_max": -1, "acc_y_Wb_rms": -1, "VDV_y_Wb": -1,
                 "TA_8_limit_Wb": +1, "Distance_TA_8_limit_Wb": +1,
                 "crest_factor_y": 0, "vel_x_avg": 0, "amplitude_y": 0}
"""Section 8.5.2: a better grade should go with lower accelerations (-1) and
longer allowable times and distances (+1); 0: no expectation stated."""

CAVEATS = (
    "The indicators may not be as accurate as desired: low frame rate and resolution "
    "of the cameras.",
    "All indicators but vel_x_avg assume the rider is in continuous contact with the saddle; "
    "false in rising trot, which should be somewhat disregarded.",
    "TA_8_limit_Wb and Distance_TA_8_limit_Wb use the EU exposure limit values for a passive "
    "person; a rider compensates, so read them as relative comfort (3 h vs 1.5 h: twice as "
    "comfortable), not as absolute limits.",
)


# ---------------------------------------------------------------------------
# Grades (Table 8.8)
# ---------------------------------------------------------------------------

def load_grades(path=None) -> dict:
    """Riders' grades of thesis Table 8.8.

    Parameters
    ----------
    path : path, optional
        A CSV with columns ``gait,horse,rider,grade`` ('#' comment lines
        allowed); default ``data_samples/riders_grades.csv``.

    Returns
    -------
    dict
        ``grades[gait][horse][rider] -> int`` (1 very bad ... 5 very good).
    """
    path = Path(path) if path is not None else data_samples_dir() / "riders_grades.csv"
    text = path.read_text(encoding="utf-8")
    lines = [ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    reader = csv.reader(lines)
    header = next(reader, None)
    if header != ["gait", "horse", "rider", "grade"]:
        raise ValueError(f"{path}: header must be 'gait,horse,rider,grade', got {header}")
    out: dict = {}
    for i, row in enumerate(reader, start=2):
        if len(row) != 4:
            raise ValueError(f"{path}: data row {i}: expected 4 fields, got {row}")
        gait, horse, rider, g = row
        if gait not in GAITS:
            raise ValueError(f"{path}: data row {i}: gait {gait!r} not one of {GAITS}")
        try:
            grade = int(g)
        except ValueError:
            raise ValueError(f"{path}: data row {i}: grade {g!r} is not an integer") from None
        if not 1 <= grade <= 5:
            raise ValueError(f"{path}: data row {i}: grade {grade} outside 1..5")
        out.setdefault(gait, {}).setdefault(horse, {})[rider] = grade
    return out


def mean_grades(grades: dict | None = None) -> dict:
    """Average grade per (gait, horse): the ``avg`` rows of Table 8.8."""
    grades = grades if grades is not None else load_grades()
    return {(g, h): float(np.mean(list(r.values())))
            for g, by_h in grades.items() for h, r in by_h.items()}


# ---------------------------------------------------------------------------
# Indicators of the virtual herd
# ---------------------------------------------------------------------------

def analytic_indicators(horse: str = "Horse 2", gait: str = "canter", *, mode: str = "iso",
                        n_periods: int = 2, samples_per_period: int = 512,
                        max_harmonic: int = 40) -> dict:
    """Ground-truth comfort indicators of a virtual session (no rendering).

    The virtual laboratory's analytic saddle motion
    (``virtuallab.saddle_motion``) is sampled over one stride in the motion
    frame (x along the path, y down); the vertical acceleration's harmonics
    (:func:`vibration.harmonics_from_periodic_samples`) go into
    :func:`vibration.comfort_indicators` with tau = ``n_periods`` strides;
    the three axes' harmonics into :func:`vibration.directive_indicators`
    (the keys :data:`vibration.DIRECTIVE_KEYS` after the thesis' ones, as
    the pipeline's :func:`vibration.saddle_comfort` gives them).
    """
    from .virtuallab.horse import saddle_motion

    m = saddle_motion(horse, gait)
    period = m.period_s
    t = np.arange(samples_per_period) * (period / samples_per_period)
    p, v, a = m.saddle(t)
    axes = m.motion_axes
    pos_y, vel_x = p @ axes[1], v @ axes[0]
    hx, h, hz = (vib.harmonics_from_periodic_samples(a @ axes[i], period, 1, max_harmonic=max_harmonic)
                 for i in range(3))
    h = vib.Harmonics(h.freq_hz, h.amplitude, 0.0)
    amp = 0.5 * float(pos_y.max() - pos_y.min())
    out = vib.comfort_indicators(h, n_periods * period, float(vel_x.mean()), amp, mode=mode, f0_hz=1.0 / period)
    out.update(vib.directive_indicators(hx, h, hz, n_periods * period, float(vel_x.mean())))
    return out


def pipeline_analysis(horse: str, gait: str, params=None, *, until: str = "comfort"):
    """The pipeline's analysis of one virtual herd session (an :class:`~horsemocap.pipeline.Analysis`).

    Renders the session into the cache on first use
    (``virtuallab.herd_session``) and analyses it through
    :func:`horsemocap.workspace.results_for`, so the steps are kept in the
    notebooks' results store and a second call with the same parameters
    (e.g. another section of notebook 13) loads them instead of repeating
    minutes of work.
    """
    from .virtuallab import herd_session  # rendered on demand into the cache
    from .workspace import results_for

    return results_for(herd_session(horse, gait), until=until, params=params)


def pipeline_indicators(horse: str, gait: str, *, mode: str = "iso", out_dir=None) -> dict:
    """Indicators of a virtual session from its rendered videos (full analysis).

    :func:`pipeline_analysis` with ``weighting_mode=mode``; with ``out_dir``
    the result files are written there instead of the results store. Slow
    on first use (minutes per session on this machine).
    """
    if out_dir is not None:
        from . import pipeline
        from .virtuallab import herd_session

        res = pipeline.analyze(herd_session(horse, gait), out_dir, {"weighting_mode": mode},
                               progress=lambda *a: None)
    else:
        res = pipeline_analysis(horse, gait, {"weighting_mode": mode})
    return dict(res.comfort.indicators)


def horse_table() -> list[dict]:
    """Thesis Table 8.6, the horses' features: ``[{"horse", "age", "breed", "withers_m"}, ...]``.

    The virtual herd takes them from the table
    (:data:`horsemocap.virtuallab.horse.HERD`).
    """
    from .virtuallab.horse import HERD

    return [{"horse": h, "age": HERD[h].age, "breed": HERD[h].breed, "withers_m": HERD[h].withers_m}
            for h in HORSES]


def herd_indicators(source: str = "analytic", *, mode: str = "iso", horses=HORSES, gaits=GAITS,
                    timings: dict | None = None) -> dict:
    """Indicators of every (horse, gait) session: ``{(horse, gait): indicators}``.

    ``source``: ``"analytic"`` (:func:`analytic_indicators`) or
    ``"pipeline"`` (:func:`pipeline_indicators`). ``timings``, if given, is
    filled with the seconds each session took.
    """
    fn = {"analytic": analytic_indicators, "pipeline": pipeline_indicators}.get(source)
    if fn is None:
        raise ValueError(f"source must be 'analytic' or 'pipeline', got {source!r}")
    out = {}
    for h in horses:
        for g in gaits:
            t0 = time.perf_counter()
            out[(h, g)] = fn(h, g, mode=mode)
            if timings is not None:
                timings[(h, g)] = time.perf_counter() - t0
    return out


def table_indicators(table, indicators=None) -> dict:
    """A batch's table read into ``{(horse, gait): {indicator: value}}`` (the form :func:`compare` takes).

    Parameters
    ----------
    table : path or list of dict
        ``sessions.csv`` of a batch (:func:`horsemocap.batch.read_table`) or its rows.
    indicators : iterable of str, optional
        The indicators kept (default: every column of ``comfort.csv`` the table has; the optional
        ``passes*`` columns of a recording with several passes are left out).

    Only the sessions with results are kept (a failed one, exit status 2,
    has no indicators); two sessions of the same horse and gait raise a
    ``ValueError`` naming both, rather than one hiding the other.

    Examples
    --------
    >>> rows = [{"name": "h2c", "horse": "Horse 2", "gait": "canter", "exit_status": 0, "VDV_y_Wb": 4.6},
    ...         {"name": "h1w", "horse": "Horse 1", "gait": "walk", "exit_status": 2, "VDV_y_Wb": float("nan")}]
    >>> table_indicators(rows)
    {('Horse 2', 'canter'): {'VDV_y_Wb': 4.6}}
    """
    rows = read_table(table) if isinstance(table, (str, Path)) else list(table)
    out, names = {}, {}
    for row in rows:
        if row["exit_status"] == 2:
            continue
        key = (row["horse"], row["gait"])
        if key in out:
            raise ValueError(f"sessions {names[key]!r} and {row['name']!r} are both {key[0]}, {key[1]}: "
                             "give the table of one session per horse and gait")
        keep = ([k for k in row if k not in BASE_COLUMNS and not k.startswith("passes")] if indicators is None
                else list(indicators))
        out[key] = {k: float(row[k]) for k in keep}
        names[key] = row["name"]
    return out


def indicator_matrix(table: dict, key: str, horses=HORSES, gaits=GAITS) -> np.ndarray:
    """``(len(gaits), len(horses))`` array of one indicator (NaN where absent)."""
    m = np.full((len(gaits), len(horses)), np.nan)
    for i, g in enumerate(gaits):
        for j, h in enumerate(horses):
            if (h, g) in table:
                m[i, j] = table[(h, g)][key]
    return m


@dataclass(frozen=True)
class HerdPlace:
    """Where one session's indicator stands among the herd's: its ``value``, the herd's ``low`` and
    ``high`` over the gaits compared, and how many of the ``n`` herd sessions are ``lower``."""

    key: str
    value: float
    low: float
    high: float
    lower: int
    n: int


def beside_herd(table: dict, indicators: dict, gait: str | None = None,
                keys=("acc_y_Wb_rms", "VDV_y_Wb", "TA_8_limit_Wb")) -> list[HerdPlace]:
    """A session's comfort ``indicators`` set beside the herd ``table``'s in the same ``gait`` (any gait
    of :data:`GAITS` when ``gait`` is None or not one of them).

    Examples
    --------
    >>> table = {("Horse 1", "canter"): {"acc_y_Wb_rms": 3.0}, ("Horse 2", "canter"): {"acc_y_Wb_rms": 5.0}}
    >>> place = beside_herd(table, {"acc_y_Wb_rms": 4.0}, "canter", keys=("acc_y_Wb_rms",))[0]
    >>> place.low, place.high, place.lower, place.n
    (3.0, 5.0, 1, 2)
    """
    gaits = (gait,) if gait in GAITS else GAITS
    out = []
    for k in keys:
        herd = indicator_matrix(table, k, gaits=gaits).ravel()
        herd = herd[np.isfinite(herd)]
        out.append(HerdPlace(k, float(indicators[k]), float(herd.min()), float(herd.max()),
                             int(np.sum(herd < indicators[k])), int(herd.size)))
    return out


# ---------------------------------------------------------------------------
# Rank correlation with the grades (Figures 8.33-8.36)
# ---------------------------------------------------------------------------

@dataclass(frozen=True)
class Correlation:
    """Spearman rank correlation of one indicator with the mean grade.

    ``rho`` in [-1, 1], ``p`` the two-sided p-value of scipy (with n = 4
    horses only |rho| = 1 reaches p < 0.1: read rho as a description, not
    a test), ``n`` pairs, ``expected`` the sign of :data:`EXPECTED_SIGN`.
    """

    gait: str
    indicator: str
    rho: float
    p: float
    n: int
    expected: int

    @property
    def as_expected(self) -> bool | None:
        if self.expected == 0 or not np.isfinite(self.rho):
            return None
        return bool(np.sign(self.rho) == self.expected)


def compare(indicator_table: dict, grades: dict | None = None, indicators=THESIS_INDICATORS,
            gaits=GAITS, pooled: bool = True) -> list[Correlation]:
    """Spearman rank correlations of indicators with the riders' mean grades.

    One correlation per gait across the horses (the thesis' Figures
    8.33-8.36), and, with ``pooled``, one over all sessions except rising
    trot (gait ``"pooled"``; see :data:`CAVEATS`).
    """
    mg = mean_grades(grades)
    out = []
    groups = [(g, [g]) for g in gaits]
    if pooled:
        groups.append(("pooled", [g for g in gaits if g != "rising_trot"]))
    for label, gs in groups:
        keys = [(h, g) for g in gs for h in HORSES if (h, g) in indicator_table and (g, h) in mg]
        gr = np.array([mg[(g, h)] for h, g in keys])
        for ind in indicators:
            x = np.array([indicator_table[k][ind] for k in keys], dtype=float)
            if len(keys) < 3 or np.ptp(gr) == 0 or np.ptp(x) == 0:
                rho, p = float("nan"), float("nan")
            else:
                r = stats.spearmanr(x, gr)
                rho, p = float(r.statistic), float(r.pvalue)
            out.append(Correlation(label, ind, rho, p, len(keys), EXPECTED_SIGN.get(ind, 0)))
    return out


def herd_rows(table: dict, indicators=THESIS_INDICATORS, grades: dict | None = None) -> list[dict]:
    """One row per session: horse, gait, mean grade and the indicators."""
    mg = mean_grades(grades)
    rows = []
    for g in GAITS:
        for h in HORSES:
            if (h, g) not in table:
                continue
            row = {"horse": h, "gait": g, "mean_grade": mg.get((g, h), float("nan"))}
            row.update({k: float(table[(h, g)][k]) for k in indicators})
            rows.append(row)
    return rows


def write_herd_csv(path, table: dict, indicators=vib.COMFORT_KEYS, grades: dict | None = None) -> Path:
    """All sessions' indicators and mean grades as one CSV (one row per session)."""
    rows = herd_rows(table, indicators, grades)
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=["horse", "gait", "mean_grade", *indicators],
                       lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: (repr(v) if isinstance(v, float) else v) for k, v in r.items()})
    return atomic_write_text(path, buf.getvalue())


def batch_saddle_series(results) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The saddle's motion from one session's results folder (a batch's ``<name>/``, or any ``analyze`` output).

    Returns ``(t, position, acceleration)``: the times (s) of ``trajectories.csv``, the saddle's
    positions (n, 3) in the motion frame (m) and its accelerations (n, 3) of ``kinematics.csv``
    (m/s^2) -- the arrays of the rigid-body step, read back instead of analysed again.

    Raises
    ------
    ValueError
        Naming the file when it has no ``saddle`` rows.
    """
    folder = Path(results)

    def saddle(name, columns):
        path = folder / name
        with open(path, newline="", encoding="utf-8") as fh:
            rows = [r for r in csv.DictReader(fh) if r["point"] == "saddle"]
        if not rows:
            raise ValueError(f"{path}: no rows of point 'saddle'")
        t = np.array([float(r["time_s"]) for r in rows])
        values = np.array([[float(r[c]) if r[c] else np.nan for c in columns] for r in rows])
        return t, values

    t, position = saddle("trajectories.csv", ("x_m", "y_m", "z_m"))
    _, acceleration = saddle("kinematics.csv", ("ax_mps2", "ay_mps2", "az_mps2"))
    return t, position, acceleration
