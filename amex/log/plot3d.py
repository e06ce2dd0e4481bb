"""A matplotlib helper shared by ``amex-log plot`` and the figures."""

from __future__ import annotations

from typing import Any

import numpy as np


def set_equal_axes_3d(
    ax: Any, points: np.ndarray, pad: float = 1.05, min_half: float = 0.0
) -> None:
    """Give a 3-D axes one scale on x, y, z around ``points`` (shape (n, 3) [m]).

    Args:
        ax: a matplotlib ``Axes3D``.
        points: what must be visible.
        pad: factor on the half extent.
        min_half: smallest half extent before padding [m].
    """
    lo, hi = points.min(axis=0), points.max(axis=0)
    mid, half = (lo + hi) / 2, max(float((hi - lo).max()) / 2, min_half) * pad
    ax.set(
        xlim=(mid[0] - half, mid[0] + half),
        ylim=(mid[1] - half, mid[1] + half),
        zlim=(mid[2] - half, mid[2] + half),
        xlabel="x [m]",
        ylabel="y [m]",
        zlabel="z [m]",
    )
    ax.set_box_aspect((1, 1, 1))
