"""Step ``rig``: the calibrated cameras (thesis sections 3.3-3.6)."""
from __future__ import annotations

import re
from dataclasses import dataclass

from ..calibration.board import exclusion_keys
from ..calibration.cache import cached_calibration
from ..camera import Rig, read_rig
from ..params import RigParams
from ..session import Session
from .base import AnalysisError, StepResult


@dataclass(frozen=True)
class RigResult(StepResult):
    """The rig the analysis uses.

    Attributes
    ----------
    rig : Rig
        The session's cameras, in the session's order (world frame = the reference camera's).
    rig_from : str
        Where it came from (the session's rig.toml, a calibration of its views, a cached calibration).
    """

    rig: Rig
    rig_from: str

    def origin(self, mode: str) -> str:
        """Where the rig came from, whichever cache served it: a calibration reused from a results
        folder or the user-level board cache is the rig a new calibration in ``mode`` gives.

        Examples
        --------
        >>> from horsemocap.camera import Rig
        >>> RigResult(Rig(()), "calibrated from checkerboard views (cached in calibration.json)").origin("joint")
        'calibrated from checkerboard views (joint)'
        """
        return _CACHED.sub(f" ({mode})", self.rig_from)

    @property
    def reused(self) -> bool:
        """Whether a cached calibration served the rig (its reuse said where it came from).

        Examples
        --------
        >>> from horsemocap.camera import Rig
        >>> RigResult(Rig(()), "calibrated from checkerboard views (cached in calibration.json)").reused
        True
        """
        return bool(_CACHED.search(self.rig_from))


#: What :func:`horsemocap.calibration.cache.cached_calibration` adds to a rig's origin when a cache served it.
_CACHED = re.compile(r" \(cached in [^)]*\)")


def step_rig(session: Session, section: RigParams, progress, *, cache_dirs=(), board_views=None) -> RigResult:
    """The session's ``rig.toml`` or a calibration of its checkerboard views.

    ``cache_dirs``: results folders (the run's own first) where a calibration
    of the same views, board, cameras and code is reused from
    ``calibration.json`` and the new one is kept
    (:func:`horsemocap.calibration.cache.cached_calibration`;
    ``section.recalibrate`` ignores it). ``board_views``: a
    :class:`~horsemocap.calibration.cache.BoardDetectionJob` already
    detecting the views.

    Examples
    --------
    >>> from horsemocap.data import default_session_dir
    >>> from horsemocap.session import load_session
    >>> step_rig(load_session(default_session_dir()), RigParams(), lambda *a: None).rig.names
    ['left', 'middle', 'right']
    """
    if session.rig_path is not None and not section.recalibrate:
        rig, how = read_rig(session.rig_path), f"read {session.rig_path.name}"
    elif session.calibration_images is not None:
        cache_dirs = [d for d in cache_dirs if d is not None]
        # one spelling per view (its key), whether given by key or by file: the calibration's cache key
        exclude = exclusion_keys(session.calibration_images, section.exclude) or None
        if exclude:
            progress("rig", "views left out: " + "; ".join(f"{c} {', '.join(v)}" for c, v in exclude.items()))
        rig, how = cached_calibration(session.calibration_images, session.board.inner_corners,
                                      session.board.square_size_m, session.reference_camera,
                                      write_to=cache_dirs[0] if cache_dirs else None, read_from=cache_dirs[1:],
                                      recalibrate=section.recalibrate, progress=progress,
                                      exclude=exclude, mode=section.mode, detected=board_views)
    else:
        raise AnalysisError("rig", f"{session.json_path}: 'calibration' gives neither a rig nor views")
    missing = [c for c in session.cameras if c not in rig.names]
    if missing:
        raise AnalysisError("rig", f"the rig has no camera {missing[0]!r} (it has {rig.names}); "
                                   f"check 'calibration' in {session.json_path}")
    result = RigResult(rig=rig.subset(session.cameras), rig_from=how)
    if not result.reused:                # a reused calibration has said where it came from
        progress("rig", how)
    return result
