"""One colour per method, the same in every figure, plot, video, log scene and live page.

The paper's Fig. 4 draws AMEX blue, DMP green and the reference plan red; the other methods get
colours of matplotlib's ``tab10`` that are not taken, and a method no one listed (a plugin) one of
the spare colours, chosen by its name so that it keeps it from figure to figure.

Everything that is not a method has a role colour of its own: the goal gold, the obstacle black,
the reference plan red, annotations (the success radius, the start marker) grey
(:data:`ROLE_COLORS`). No two of these colours, method or role, are closer than
:data:`MIN_DISTANCE` in CIELAB (``tests/live/test_colors.py``), and a view draws a method's colour
only for that method's own lines: its executed path and, lighter (:func:`lighter`), its plan.
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
# orange, pink, moss, navy (tab10's olive was next to the goal's gold, its grey is NEUTRAL_COLOR)
SPARE_COLORS = ("#ff7f0e", "#e377c2", "#637939", "#000080")
REFERENCE_COLOR = "#d62728"  # red, as the paper's reference plan
GOAL_COLOR = "#e6b800"  # gold
OBSTACLE_COLOR = "#202020"  # black, as the paper's obstacle
NEUTRAL_COLOR = "#7f7f7f"  # grey: annotations (success radius, start marker), never a method
ROLE_COLORS: dict[str, str] = {
    "goal": GOAL_COLOR,
    "obstacle": OBSTACLE_COLOR,
    "reference": REFERENCE_COLOR,
    "neutral": NEUTRAL_COLOR,
}
MIN_DISTANCE = 20.0  # [CIE76 Delta E] between any two colours of the palette
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


def rgb255(color: str) -> tuple[int, int, int]:
    """``#rrggbb`` as integers in [0, 255] (viser's colours)."""
    return (int(color[1:3], 16), int(color[3:5], 16), int(color[5:7], 16))


def lighter(color: str, amount: float = 0.45) -> str:
    """``color`` mixed with ``amount`` of white: a method's plan beside its executed path."""
    r, g, b = (round(c + (255 - c) * amount) for c in rgb255(color))
    return f"#{r:02x}{g:02x}{b:02x}"


def method_shades(name: str, n: int) -> list[str]:
    """``n`` shades of method ``name``'s colour, darkest first (variants of one method's runs)."""
    if n <= 1:
        return [method_color(name)][:n]
    return [lighter(method_color(name), 0.6 * k / (n - 1)) for k in range(n)]


def lab(color: str) -> tuple[float, float, float]:
    """``#rrggbb`` in CIELAB (D65), to compare colours as people see them."""
    rgb = [c / 255.0 for c in rgb255(color)]
    lin = [((c + 0.055) / 1.055) ** 2.4 if c > 0.04045 else c / 12.92 for c in rgb]
    x = (0.4124 * lin[0] + 0.3576 * lin[1] + 0.1805 * lin[2]) / 0.95047
    y = 0.2126 * lin[0] + 0.7152 * lin[1] + 0.0722 * lin[2]
    z = (0.0193 * lin[0] + 0.1192 * lin[1] + 0.9505 * lin[2]) / 1.08883

    def f(t: float) -> float:
        return t ** (1.0 / 3.0) if t > 0.008856 else 7.787 * t + 16.0 / 116.0

    return (116.0 * f(y) - 16.0, 500.0 * (f(x) - f(y)), 200.0 * (f(y) - f(z)))


def distance(a: str, b: str) -> float:
    """CIE76 colour difference Delta E between ``a`` and ``b`` (``#rrggbb``)."""
    la, lb = lab(a), lab(b)
    return sum((p - q) ** 2 for p, q in zip(la, lb, strict=True)) ** 0.5


def hex_color(rgb: tuple[float, ...] | list[float]) -> str:
    """An (r, g, b[, a]) colour, floats in [0, 1], as ``#rrggbb``."""
    return "#" + "".join(f"{round(float(c) * 255):02x}" for c in list(rgb)[:3])
