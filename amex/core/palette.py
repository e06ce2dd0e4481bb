"""One colour per method, the same in every figure, plot and video.

The paper's Fig. 4 draws AMEX blue, DMP green and the reference plan red; the other methods get
colours of matplotlib's ``tab10`` that are not taken, and a method no one listed (a plugin) one of
the spare colours, chosen by its name so that it keeps it from figure to figure.
"""

from __future__ import annotations

import zlib

METHOD_COLORS: dict[str, str] = {
    "amex": "#1f77b4",  # blue
    "dmp": "#2ca02c",  # green
    "dmp_ps": "#17becf",  # cyan
    "cr": "#9467bd",  # purple
    "track": "#8c564b",  # brown
}
SPARE_COLORS = ("#ff7f0e", "#e377c2", "#bcbd22", "#7f7f7f")  # orange, pink, olive, grey
REFERENCE_COLOR = "#d62728"  # red, as the paper's reference plan
GOAL_COLOR = "#e6b800"  # gold
OBSTACLE_COLOR = "#202020"  # black, as the paper's obstacle
METHOD_LABELS = {"amex": "AMEX", "dmp": "DMP", "dmp_ps": "DMP-PS", "cr": "CR", "track": "Track"}


def method_color(name: str) -> str:
    """The colour of method ``name`` as ``#rrggbb``."""
    if name in METHOD_COLORS:
        return METHOD_COLORS[name]
    return SPARE_COLORS[zlib.crc32(name.encode()) % len(SPARE_COLORS)]


def method_label(name: str) -> str:
    """How figures name method ``name`` (AMEX, DMP, CR, ...; plugins by their own name)."""
    return METHOD_LABELS.get(name, name)


def rgba(color: str, alpha: float = 1.0) -> tuple[float, float, float, float]:
    """``#rrggbb`` as an (r, g, b, a) tuple of floats in [0, 1] (MuJoCo's colours)."""
    r, g, b = (int(color[i : i + 2], 16) / 255.0 for i in (1, 3, 5))
    return (r, g, b, alpha)
