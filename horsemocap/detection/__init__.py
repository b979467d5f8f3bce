"""Marker detection on the image plane (thesis chapter 4); see :mod:`.tracking`.

Transitional: the module ``detection.py`` moved to ``detection/tracking.py``
unchanged; it is split into files by what they hold in the next commit.
"""
from .tracking import *  # noqa: F401,F403
from .tracking import GENERIC_AREA, __all__  # noqa: F401
