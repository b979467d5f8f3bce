"""Layout helpers shared by the figure modules (no figures of their own)."""
from __future__ import annotations

import numpy as np

__all__: list[str] = []


def legend_below(ax, fontsize: int = 8, ncol: int = 3):
    """The axes' legend under its x label, outside the data (where curves fill the whole panel)."""
    handles, labels = ax.get_legend_handles_labels()
    return ax.legend(handles, labels, fontsize=fontsize, loc="upper center", bbox_to_anchor=(0.5, -0.27),
                     ncol=min(ncol, max(len(labels), 1)), frameon=False)


def label_away_from_centre(ax, points, labels, color, distance_pt: float = 14.0, **text):
    """Write ``labels`` beside image ``points`` (u, v), each pushed away from the points' centre so that
    labels of nearby points do not fall on each other (image v grows downwards)."""
    pts = np.asarray(points, float)
    centre = pts.mean(axis=0)
    for (u, v), label in zip(pts, labels):
        d = np.array([u - centre[0], centre[1] - v])            # display y grows upwards
        n = float(np.hypot(*d))
        d = d / n if n > 1e-9 else np.array([1.0, 0.0])
        ax.annotate(label, (u, v), xytext=tuple(distance_pt * d), textcoords="offset points", color=color,
                    ha="left" if d[0] >= 0 else "right", va="bottom" if d[1] >= 0 else "top", **text)
