"""The thesis' chain under each answer its user could give: where it stays finite, where it cannot.

The thesis' ``angular_velocity.m`` showed its user six versions of the angular
velocity (eq. 6.3/6.4, one per pair of markers and order) and asked, version by
version, "use it? y/n"; the same for the angular acceleration. The saddle's
acceleration (eq. 6.55) is built from the average of the versions kept. Each
version divides by the component of omega normal to the markers' plane
(eq. 6.35): where omega lies almost in that plane the version explodes, and an
average that keeps it explodes too. This module runs the rest of the thesis'
chain (rigid body and comfort) for every y/n answer and reports what it gives,
so a notebook can show which answers keep the chain finite and near Table 8.7,
and where no answer can.
"""
from __future__ import annotations

from itertools import product

import numpy as np

from .pipeline import AnalysisError, run_steps
from .quality import check_saddle_acceleration

ANSWER_KEYS = ("acc_y_Wb_rms", "acc_y_Wk_rms", "VDV_y_Wb", "acc_y_max")


def answer_masks(n_versions: int = 6) -> list[tuple[bool, ...]]:
    """Every y/n answer to ``n_versions`` versions that keeps at least one, all-yes first.

    Examples
    --------
    >>> masks = answer_masks(3)
    >>> len(masks), masks[0], masks[-1]
    (7, (True, True, True), (False, False, True))
    """
    masks = [m for m in product((True, False), repeat=n_versions) if any(m)]
    return masks


def typical_masks(n_versions: int = 6) -> list[tuple[bool, ...]]:
    """The answers a user is likely to give: all yes, one version alone, all but one.

    Examples
    --------
    >>> len(typical_masks(6)), typical_masks(2)
    (13, [(True, True), (True, False), (False, True)])
    """
    every = [tuple([True] * n_versions)]
    alone = [tuple(i == j for j in range(n_versions)) for i in range(n_versions)]
    but_one = [tuple(i != j for j in range(n_versions)) for i in range(n_versions)] if n_versions > 2 else []
    return every + alone + but_one


def answers_study(analysis, params, masks=None) -> list[dict]:
    """The thesis' chain's saddle and comfort numbers for each y/n answer on the versions.

    Parameters
    ----------
    analysis : horsemocap.pipeline.Analysis
        An analysis of the thesis' chain (its steps up to the motion frame
        are reused; only the rigid-body and comfort steps run again).
    params : horsemocap.params.AnalysisParams
        The chain's parameters (the thesis' preset, with any choices).
    masks : list of 6-tuples of bool, optional
        The answers to try (the same answer for omega and alfa, as a user who
        drops a pair of markers drops it for both). Default: all 63.

    Returns
    -------
    list of dict
        Per answer: ``mask``, ``saddle_acc_y_rms`` (m/s^2), the
        :data:`ANSWER_KEYS` indicators (NaN when not computed), ``level`` of
        the saddle-acceleration plausibility check (``ok``, ``warning``,
        ``unreliable``) and ``error`` ("" or why the chain stopped).

    Examples
    --------
    >>> answers_study.__name__
    'answers_study'
    """
    rows = []
    for mask in masks or answer_masks():
        mask = [bool(x) for x in mask]
        change = {"rigid_body.fits.omega_versions": mask, "rigid_body.fits.alpha_versions": mask}
        row = {"mask": tuple(mask), "error": ""}
        try:
            with np.errstate(all="ignore"):
                run = run_steps(analysis.session, params.updated(change), analysis, ["rigid_body", "comfort"])
        except (AnalysisError, ValueError) as exc:
            rows.append({**row, "saddle_acc_y_rms": np.nan, **dict.fromkeys(ANSWER_KEYS, np.nan),
                         "level": "unreliable", "error": str(exc)})
            continue
        ind = run.comfort.indicators or {}
        with np.errstate(all="ignore"):
            rms = float(np.sqrt(np.nanmean(run.rigid_body.saddle_acceleration[:, 1] ** 2)))
        peak = ind.get("acc_y_max", np.nan)
        level = check_saddle_acceleration(peak).level if np.isfinite(peak) else "unreliable"
        rows.append({**row, "saddle_acc_y_rms": rms, **{k: float(ind.get(k, np.nan)) for k in ANSWER_KEYS},
                     "level": level})
    return rows


def mask_text(mask) -> str:
    """An answer as the user typed it, one letter per version: ``"yynyny"``.

    Examples
    --------
    >>> mask_text((True, False, True))
    'yny'
    """
    return "".join("y" if m else "n" for m in mask)
