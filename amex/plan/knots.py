"""Knot sequences of a joint trajectory resampled at other times: replanning's warm starts."""

from __future__ import annotations

import numpy as np

from amex.core.compiled import kernel
from amex.core.errors import ConfigError


def resample_knots(knots: np.ndarray, offset: float, stride: float, count: int) -> np.ndarray:
    """Rows at fractional indices ``offset + k stride``, ``k < count``, linearly interpolated.

    Indices are clamped to ``[0, len(knots) - 1]`` (the last knot repeats past the end); indices
    within 1e-9 of an integer take that row exactly (the usual case: a shift by whole knots).
    Blends are one compiled loop (:mod:`amex.plan.knots_kernels`; CR's every target), bit for
    bit :func:`resample_knots_numpy`.
    """
    index = whole_knots(len(knots), offset, stride, count)
    if index is not None:  # whole knots: no blending
        return knots[index]
    knots = np.asarray(knots, dtype=float)
    out = np.empty((count, knots.shape[1]))
    kernel("amex.plan.knots_kernels", "blend_rows")(knots, float(offset), float(stride), out)
    return out


def resample_knots_numpy(knots: np.ndarray, offset: float, stride: float, count: int) -> np.ndarray:
    """:func:`resample_knots` in numpy (the reference of the compiled blend)."""
    last = len(knots) - 1
    index = whole_knots(len(knots), offset, stride, count)
    if index is not None:  # whole knots: no blending
        return knots[index]
    u = np.clip(offset + stride * np.arange(count), 0.0, float(last))
    nearest = np.rint(u)
    u = np.where(np.abs(u - nearest) <= 1e-9, nearest, u)
    i = np.minimum(np.floor(u).astype(int), max(last - 1, 0))
    a = (u - i)[:, None]
    if last == 0:
        return np.repeat(knots[:1], count, axis=0)
    return (1.0 - a) * knots[i] + a * knots[i + 1]


def whole_knots(length: int, offset: float, stride: float, count: int) -> np.ndarray | None:
    """The rows of a resampling by whole knots, else None.

    Whole knots: ``offset`` and ``stride`` within 1e-9 of integers; the rows are then
    ``offset + k stride``, ``k < count``, clamped to ``[0, length - 1]`` (:func:`resample_knots`).
    """
    first, step = round(offset), round(stride)
    if abs(offset - first) > 1e-9 or abs(stride - step) > 1e-9:
        return None
    index = np.arange(first, first + step * count, step) if step else np.full(count, first)
    np.minimum(index, length - 1, out=index)
    np.maximum(index, 0, out=index)
    return index


def whole_knot_rows(
    length: int, offset: float, stride: float, count: int
) -> slice | np.ndarray | None:
    """:func:`whole_knots`' rows, as a slice where they are consecutive and unclamped (views)."""
    first, step = round(offset), round(stride)
    if abs(offset - first) > 1e-9 or abs(stride - step) > 1e-9:
        return None
    if step == 1 and first >= 0 and first + count <= length:
        return slice(first, first + count)
    return whole_knots(length, offset, stride, count)


def shift_warm_start(solution_q: np.ndarray, steps_new: int) -> np.ndarray:
    """Warm start for the next replanning step (CR): drop the first knot, keep ``steps_new``.

    Args:
        solution_q: previous solution, shape (T + 1, 7) [rad].
        steps_new: the next horizon T'; rows past the old end repeat the old final knot.

    Returns:
        Initial trajectory, shape (T' + 1, 7) [rad]; row 0 (the old q_1) stands for the start.
    """
    if int(steps_new) != steps_new or steps_new < 1:
        raise ConfigError.invalid("steps_new", steps_new, "an integer >= 1")
    rest = np.asarray(solution_q, dtype=float)[1:]
    if len(rest) == 0:
        raise ConfigError.invalid("solution_q rows", 1, ">= 2")
    index = np.minimum(np.arange(steps_new + 1), len(rest) - 1)
    return rest[index]
