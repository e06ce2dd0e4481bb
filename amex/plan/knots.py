"""Knot sequences of a joint trajectory resampled at other times: replanning's warm starts."""

from __future__ import annotations

import numba
import numpy as np

from amex.core.errors import ConfigError


def resample_knots(knots: np.ndarray, offset: float, stride: float, count: int) -> np.ndarray:
    """Rows at fractional indices ``offset + k stride``, ``k < count``, linearly interpolated.

    Indices are clamped to ``[0, len(knots) - 1]`` (the last knot repeats past the end); indices
    within 1e-9 of an integer take that row exactly (the usual case: a shift by whole knots).
    Blends are one compiled loop (CR's every target), bit for bit :func:`resample_knots_numpy`.
    """
    index = whole_knots(len(knots), offset, stride, count)
    if index is not None:  # whole knots: no blending
        return knots[index]
    knots = np.asarray(knots, dtype=float)
    out = np.empty((count, knots.shape[1]))
    _blend_rows(knots, float(offset), float(stride), out)
    return out


@numba.njit(cache=True)
def _blend_rows(knots: np.ndarray, offset: float, stride: float, out: np.ndarray) -> None:
    """:func:`resample_knots_numpy`'s blend, row ``k`` of ``out`` at index ``offset + k stride``."""
    last = knots.shape[0] - 1
    for k in range(out.shape[0]):
        u = offset + stride * float(k)
        if u == u:  # numpy's clip: NaN stays, max then min, -0.0 -> 0.0
            u = u if u > 0.0 else 0.0
            u = u if u < float(last) else float(last)
        nearest = np.rint(u)
        if abs(u - nearest) <= 1e-9:
            u = nearest
        if last == 0:
            out[k] = knots[0]
            continue
        i = min(int(np.floor(u)), max(last - 1, 0))
        a = u - float(i)
        for j in range(knots.shape[1]):
            out[k, j] = (1.0 - a) * knots[i, j] + a * knots[i + 1, j]


@numba.njit(cache=True)
def midpoint_target(
    knots: np.ndarray, stride: float, dt: float, q_mid: np.ndarray, qd: np.ndarray
) -> None:
    """CR's joint target from its knots, one compiled call: ``q_mid`` and ``qd``, shapes (n,).

    Rows at indices ``0, stride, 2 stride`` blended as :func:`resample_knots` blends them
    (``stride`` not within 1e-9 of an integer, ``len(knots) >= 2``): ``q_mid`` the middle row,
    ``qd = (q[2] - q[0]) / dt``, the numpy expression of ``CR.target``, bit for bit.
    """
    rows = np.empty((3, knots.shape[1]))
    _blend_rows(knots, 0.0, stride, rows)
    for j in range(knots.shape[1]):
        q_mid[j] = rows[1, j]
        qd[j] = (rows[2, j] - rows[0, j]) / dt


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
