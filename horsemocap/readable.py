"""Numbers as a person reads them: riding times in hours and minutes, distances in km.

The comfort step computes the time to the 8-hour action and limit values in
decimal hours (``0.106``); the report and the command line show it as a rider
reads a clock (``0 h 06 min``).
"""
from __future__ import annotations


def hours_minutes(hours) -> str:
    """A time in hours as a person reads it: ``0.106`` -> ``0 h 06 min`` (to the nearest minute).

    Under half a minute the seconds are added (``0 h 00 min (8 s)``); an
    infinite time (no vibration) is ``never``; NaN ``not computed``.

    Examples
    --------
    >>> hours_minutes(0.106), hours_minutes(2.5), hours_minutes(0.9999), hours_minutes(0.002329)
    ('0 h 06 min', '2 h 30 min', '1 h 00 min', '0 h 00 min (8 s)')
    """
    h = float(hours)
    if h != h:
        return "not computed"
    if h == float("inf"):
        return "never"
    minutes = int(round(h * 60))
    text = f"{minutes // 60} h {minutes % 60:02d} min"
    return text + f" ({h * 3600:.0f} s)" if minutes == 0 else text


def distance_km(km) -> str:
    """A distance in km to 3 significant digits: ``1.862`` -> ``1.86 km``; infinite ``no limit``."""
    d = float(km)
    if d != d:
        return "not computed"
    return "no limit" if d == float("inf") else f"{d:.3g} km"
