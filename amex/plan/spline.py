"""Quadratic B-spline trajectories over the phase s in [0, 1] (the paper's Section III-A choice).

A trajectory is ``tau(s) = sum_i c_i B_i(s)`` with n control points ``c_i`` (shape (n, m)) and the
clamped degree-2 basis ``B_i`` on the knots ``t_0 = t_1 = t_2 = 0 < t_3 < ... < t_{n-1} <
t_n = t_{n+1} = t_{n+2} = 1`` (simple interior knots, so tau is C1 on [0, 1]). Clamping gives
``tau(0) = c_0`` and ``tau(1) = c_{n-1}``. Two identities of this basis carry the whole module:

* partition of unity: ``sum_i B_i(s) = 1``;
* affine reproduction (Marsden): ``sum_i xi_i B_i(s) = s`` with the Greville abscissae
  ``xi_i = (t_{i+1} + t_{i+2}) / 2``.

So for any affine map ``a(s) = p + s q`` (p, q in R^m), ``sum_i a(xi_i) B_i(s) = a(s)``: adding
``a(xi_i)`` to every control point adds exactly ``a`` to the curve. :meth:`QuadraticBSpline.warp`
uses this to apply the paper's Eq. 7 (affine in the phase) exactly; see its docstring. Since a sum
of affine maps is affine, a plan warped any number of times is its reference plus one affine
offset: :class:`WarpedSpline` keeps just that offset (two vectors), making Eq. 7 O(m) per step,
and as an affine offset has two vector parameters, fixed by ``tau(s) = y`` and ``tau(1) = g``,
it even has a closed form (:meth:`WarpedSpline.anchor`).

Evaluation at one phase (:meth:`QuadraticBSpline.weights`) is plain float arithmetic (a
``bisect`` on the knot list and the unrolled Cox-de Boor recursion) giving the value and
derivative weights of the three control points non-zero at s, so a 100 Hz control step pays no
numpy call for it (``weights`` ~0.8 us here); :meth:`QuadraticBSpline.__call__` and
:meth:`QuadraticBSpline.derivative` are the vectorized forms for plots and tests.

Fitting samples ``y_j = tau_hat(j T / N)``, ``j = 0..N`` (:meth:`QuadraticBSpline.fit`): with
``n = N + 1`` control points the spline interpolates the samples at ``s_j = j / N`` (interior
knots at the midpoints ``(j + 1/2) / N``, which satisfy Schoenberg-Whitney); with fewer, uniform
knots and least squares with the two end samples interpolated exactly (``c_0 = y_0``,
``c_{n-1} = y_N``). Either way ``tau(s) = tau_hat(s T)`` at the samples (exactly for
interpolation, to :func:`max_sample_error` for least squares), the paper's reparametrization.
"""

from __future__ import annotations

from bisect import bisect_right
from typing import NamedTuple

import numpy as np

from amex.core.errors import ConfigError


class SplinePoint(NamedTuple):
    """A trajectory evaluated at one phase: ``value`` tau(s) and ``derivative`` d tau / d s."""

    value: np.ndarray
    derivative: np.ndarray


class QuadraticBSpline:
    """A clamped quadratic B-spline ``tau: [0, 1] -> R^m`` (see the module notes).

    Args:
        knots: the full knot vector, shape (n + 3,): three 0s, strictly increasing interior knots
            in (0, 1), three 1s.
        control_points: ``c_i``, shape (n, m), n >= 3. Copied; :meth:`warp` changes the copy.

    Attributes:
        knots: as given, shape (n + 3,).
        control_points: shape (n, m), modified in place by :meth:`warp`.
        greville: Greville abscissae ``xi_i = (t_{i+1} + t_{i+2}) / 2``, shape (n,).
    """

    degree = 2

    def __init__(self, knots: np.ndarray, control_points: np.ndarray) -> None:
        t = np.array(knots, dtype=float)
        C = np.array(control_points, dtype=float)
        if C.ndim == 1:
            C = C[:, None]
        n = len(C)
        if C.ndim != 2 or n < 3 or not np.all(np.isfinite(C)):
            raise ConfigError(f"control points must be finite, shape (n >= 3, m); got {C.shape}")
        if t.shape != (n + 3,):
            raise ConfigError(f"knots must have shape (n + 3,) = ({n + 3},); got {t.shape}")
        inner = t[2 : n + 1]
        if (
            np.any(t[:3] != 0.0)
            or np.any(t[n:] != 1.0)
            or not np.all(np.diff(inner) > 0.0)
            or not np.all(np.isfinite(t))
        ):
            raise ConfigError("knots must be 0, 0, 0, increasing interior in (0, 1), 1, 1, 1")
        self.knots = t
        self.control_points = C
        self.greville = 0.5 * (t[1 : n + 1] + t[2 : n + 2])
        self._t = t.tolist()  # float list: bisect and scalar arithmetic without numpy overhead
        self._n = n

    # ------------------------------------------------------------------------------- shape
    @property
    def n_control(self) -> int:
        """Number of control points n."""
        return self._n

    @property
    def dim(self) -> int:
        """Dimension m of the space the trajectory lives in."""
        return self.control_points.shape[1]

    def copy(self) -> QuadraticBSpline:
        """Return an independent copy (same knots, copied control points)."""
        return QuadraticBSpline(self.knots, self.control_points)

    # ------------------------------------------------------------------------------- evaluation
    def weights(self, s: float) -> tuple[int, float, float, float, float, float, float]:
        """Value and derivative weights of the three control points non-zero at phase s.

        Plain float arithmetic (unrolled Cox-de Boor), no numpy. s is clamped to [0, 1]; at a
        knot the span to its right is used (tau is C1, so both sides agree).

        Returns:
            ``(i, b0, b1, b2, d0, d1, d2)`` with ``b_k = B_{i+k}(s)`` and ``d_k = B'_{i+k}(s)``:
            ``tau(s) = sum_k b_k c_{i+k}``, ``tau'(s) = sum_k d_k c_{i+k}``.
        """
        t = self._t
        u = 0.0 if s < 0.0 else (1.0 if s > 1.0 else float(s))
        mu = bisect_right(t, u) - 1  # t[mu] <= u < t[mu + 1]
        last = self._n - 1
        if mu > last:  # u == 1: the last non-empty span
            mu = last
        a, b, c, d = t[mu - 1], t[mu], t[mu + 1], t[mu + 2]
        l1 = u - b
        r1 = c - u
        h = c - b
        tmp0 = r1 / (h * (c - a))  # degree-1 basis on [b, c], divided by the degree-2 spans
        tmp1 = l1 / (h * (d - b))
        alpha = 2.0 * tmp0  # tau' = alpha (c1 - c0) + beta (c2 - c1)
        beta = 2.0 * tmp1
        return (
            mu - 2,
            r1 * tmp0,
            (u - a) * tmp0 + (d - u) * tmp1,
            l1 * tmp1,
            -alpha,
            alpha - beta,
            beta,
        )

    def basis(self, s: float, out: np.ndarray) -> int:
        """Write :meth:`weights` at s into ``out`` (shape (2, 3): values, derivatives); return i.

        ``out @ control_points[i : i + 3]`` is then ``[tau(s), tau'(s)]``.
        """
        i, out[0, 0], out[0, 1], out[0, 2], out[1, 0], out[1, 1], out[1, 2] = self.weights(s)
        return i

    def max_index_shift(self, ds: float) -> int:
        """Largest ``i(s + ds) - i(s)`` of :meth:`weights`' first index over s in [0, 1 - ds]."""
        inner = self.knots[3 : self._n]  # interior knots: each starts a new span
        if len(inner) == 0:
            return 0
        ends = np.searchsorted(inner, inner + ds, side="right")
        return int(np.max(ends - np.arange(len(inner))))

    def evaluate(self, s: float) -> SplinePoint:
        """``tau(s)`` and ``tau'(s)`` at one phase, each shape (m,)."""
        W = np.empty((2, 3))
        i = self.basis(s, W)
        P = W @ self.control_points[i : i + 3]
        return SplinePoint(P[0], P[1])

    def _weights(self, s: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """Return indices (len(s),) and weights (len(s), 2, 3) of the basis at each s."""
        s = np.atleast_1d(np.asarray(s, dtype=float))
        W = np.empty((len(s), 2, 3))
        idx = np.empty(len(s), dtype=int)
        for k, u in enumerate(s):
            idx[k] = self.basis(u, W[k])
        return idx, W

    def _eval(self, s: np.ndarray | float, row: int) -> np.ndarray:
        scalar = np.ndim(s) == 0
        idx, W = self._weights(s)
        C = self.control_points
        cp = C[idx[:, None] + np.arange(3)]  # (len(s), 3, m)
        out = np.einsum("kj,kjm->km", W[:, row, :], cp)
        return out[0] if scalar else out

    def __call__(self, s: np.ndarray | float) -> np.ndarray:
        """``tau(s)`` for a phase (shape (m,)) or an array of phases (shape (len(s), m))."""
        return self._eval(s, 0)

    def derivative(self, s: np.ndarray | float) -> np.ndarray:
        """``d tau / d s`` for a phase (shape (m,)) or an array of phases (shape (len(s), m))."""
        return self._eval(s, 1)

    def basis_matrix(self, s: np.ndarray) -> np.ndarray:
        """Dense collocation matrix ``B[k, i] = B_i(s_k)``, shape (len(s), n)."""
        idx, W = self._weights(s)
        B = np.zeros((len(idx), self._n))
        rows = np.arange(len(idx))[:, None]
        B[rows, idx[:, None] + np.arange(3)] = W[:, 0, :]
        return B

    # ------------------------------------------------------------------------------- Eq. 7
    def warp(self, s: float, delta_y: np.ndarray, delta_g: np.ndarray) -> None:
        """Eq. 7 on the remaining phase [s, 1], exactly, by an affine offset of all control points.

        Eq. 7 adds ``a(s~) = delta_g + (s~ - 1) k``, ``k = (delta_g - delta_y) / (1 - s)``, to tau
        on ``s~ in [s, 1]``: affine in s~, with ``a(s) = delta_y`` and ``a(1) = delta_g``. This
        method adds ``a(xi_i)`` to every control point c_i.

        Proof that the curve changes by exactly ``a``: by partition of unity, affinity of a and
        affine reproduction, ``sum_i a(xi_i) B_i(s~) = a(sum_i xi_i B_i(s~)) = a(s~)`` for every s~
        in [0, 1]. So on [s, 1] this is Eq. 7 with no approximation, and with the caller's
        ``delta_y = y - tau(s)`` and ``delta_g = g - tau(1)``, afterwards ``tau(s) = y`` and
        ``tau(1) = g`` up to rounding. Before s the curve moves by the same affine ``a``
        extrapolated (Eq. 7 leaves it alone); nothing reads it there, as the phase only increases.
        The rounding error is about machine epsilon times ``|c| + |k|``, so the caller keeps
        ``1 - s`` away from 0 (AMEX: ``end_margin``).

        Args:
            s: current phase, in [0, 1).
            delta_y: value added at s, shape (m,).
            delta_g: value added at 1, shape (m,).
        """
        if not s < 1.0:
            raise ConfigError.invalid("warp phase s", s, "< 1 (Eq. 7 divides by 1 - s)")
        k = (np.asarray(delta_g, dtype=float) - delta_y) / (1.0 - s)
        self.control_points += delta_g + (self.greville - 1.0)[:, None] * k

    # ------------------------------------------------------------------------------- fitting
    @classmethod
    def fit(cls, samples: np.ndarray, n_control: int | None = None) -> QuadraticBSpline:
        """Fit samples taken at equally spaced phases ``s_j = j / N``, j = 0..N.

        Args:
            samples: ``y_j``, shape (N + 1, m) (or (N + 1,)), N >= 2.
            n_control: number of control points; ``None`` or N + 1: interpolation (midpoint
                knots); 3..N: uniform knots, least squares with both end samples interpolated.

        Returns:
            The spline, with ``tau(0) = y_0`` and ``tau(1) = y_N`` exactly.
        """
        Y = np.array(samples, dtype=float)
        if Y.ndim == 1:
            Y = Y[:, None]
        if Y.ndim != 2 or len(Y) < 3 or not np.all(np.isfinite(Y)):
            raise ConfigError(f"samples must be finite, shape (N + 1 >= 3, m); got {Y.shape}")
        N = len(Y) - 1
        n = N + 1 if n_control is None else int(n_control)
        if not 3 <= n <= N + 1:
            raise ConfigError.invalid("n_control", n_control, f"None or 3..{N + 1}")
        sites = np.arange(N + 1) / N
        # interpolation: knots at the sample midpoints; least squares: uniform knots
        midpoints = (np.arange(1, N - 1) + 0.5) / N
        interior = midpoints if n == N + 1 else np.arange(1, n - 2) / (n - 2)
        knots = np.concatenate([np.zeros(3), interior, np.ones(3)])
        spline = cls(knots, np.zeros((n, Y.shape[1])))
        spline.control_points[:] = _fitted_points(spline, sites, Y)
        return spline


#: Control points of the last few fits, by their samples: every episode of a run builds its
#: method, and AMEX fits the same reference each time (a dense solve of N + 1 rows, tens of ms).
_FITS: dict[tuple[bytes, tuple[int, ...], bytes], np.ndarray] = {}
_FITS_KEPT = 8


def _fitted_points(spline: QuadraticBSpline, sites: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """The control points of :meth:`QuadraticBSpline.fit` (a copy; computed once per samples)."""
    key = (Y.tobytes(), Y.shape, spline.knots.tobytes())
    known = _FITS.get(key)
    if known is not None:
        return known.copy()
    n, N = len(spline.control_points), len(Y) - 1
    B = spline.basis_matrix(sites)
    if n == N + 1:
        C = np.linalg.solve(B, Y)
    else:
        rhs = Y - np.outer(B[:, 0], Y[0]) - np.outer(B[:, -1], Y[-1])
        inner, *_ = np.linalg.lstsq(B[:, 1:-1], rhs, rcond=None)
        C = np.vstack([Y[0], inner, Y[-1]])
    C[0], C[-1] = Y[0], Y[-1]  # exact ends (the solve is exact there up to rounding)
    if len(_FITS) >= _FITS_KEPT:
        _FITS.pop(next(iter(_FITS)))
    _FITS[key] = C.copy()
    return C


class WarpedSpline:
    """A spline plus an affine offset in the phase: ``tau(s~) = base(s~) + p + (s~ - 1) q``.

    The lazy form of repeated :meth:`QuadraticBSpline.warp` calls: each Eq. 7 update adds an
    affine function of s~, and a sum of affine functions is affine, so a plan that starts as
    ``base`` and is warped any number of times is ``base`` plus one affine offset, kept as two
    vectors p and q (``p = tau(1) - base(1)``; q the accumulated slope). :meth:`warp` is then
    O(m) instead of O(n m), and :meth:`to_spline` gives the same curve as explicit control points
    ``c_i + p + (xi_i - 1) q`` (equal by affine reproduction), i.e. what the same sequence of
    :meth:`QuadraticBSpline.warp` calls produces.

    Args:
        base: the unwarped trajectory (shared, not copied, not modified).

    Attributes:
        base: as given.
        p: offset at s~ = 1, shape (m,).
        q: slope of the offset [per unit phase], shape (m,).
    """

    def __init__(self, base: QuadraticBSpline) -> None:
        self.base = base
        self.p = np.zeros(base.dim)
        self.q = np.zeros(base.dim)

    def reset(self) -> None:
        """Back to ``tau = base``."""
        self.p[:] = 0.0
        self.q[:] = 0.0

    @property
    def end(self) -> np.ndarray:
        """``tau(1)``, shape (m,)."""
        return self.base.control_points[-1] + self.p

    def warp(self, s: float, delta_y: np.ndarray, delta_g: np.ndarray) -> None:
        """Eq. 7 exactly: add ``delta_g + (s~ - 1)(delta_g - delta_y) / (1 - s)`` (see the class).

        Afterwards ``tau(s)`` moved by ``delta_y`` and ``tau(1)`` by ``delta_g``, to rounding.
        """
        if not s < 1.0:
            raise ConfigError.invalid("warp phase s", s, "< 1 (Eq. 7 divides by 1 - s)")
        self.q += (np.asarray(delta_g, dtype=float) - delta_y) * (1.0 / (1.0 - s))
        self.p += delta_g

    def anchor(self, s: float, y: np.ndarray, g: np.ndarray) -> None:
        """Set the offset so that ``tau(s) = y`` and ``tau(1) = g``: Eq. 7 in closed form.

        ``p = g - base(1)``, ``q = ((g - base(1)) - (y - base(s))) / (1 - s)``: the offset
        interpolates linearly (in the phase) from ``y - base(s)`` at s to ``g - base(1)`` at 1.
        An affine offset has two vector parameters and these two conditions fix them, so this is
        exactly the plan :meth:`warp` with ``delta_y = y - tau(s)``, ``delta_g = g - tau(1)``
        produces, whatever the offset was before: on the remaining phase [s, 1] the plan of
        Eq. 7 depends only on (s, y, g), not on the history of updates.
        """
        if not s < 1.0:
            raise ConfigError.invalid("anchor phase s", s, "< 1 (Eq. 7 divides by 1 - s)")
        end = self.base.control_points[-1]
        np.subtract(g, end, out=self.p)
        self.q[:] = (self.p - (np.asarray(y, dtype=float) - self.base(s))) / (1.0 - s)

    def __call__(self, s: np.ndarray | float) -> np.ndarray:
        """``tau(s)`` for a phase (shape (m,)) or an array of phases (shape (len(s), m))."""
        s_col = np.asarray(s, dtype=float)[..., None]
        return self.base(s) + self.p + (s_col - 1.0) * self.q

    def derivative(self, s: np.ndarray | float) -> np.ndarray:
        """``d tau / d s`` for a phase (shape (m,)) or an array of phases (shape (len(s), m))."""
        return self.base.derivative(s) + self.q

    def to_spline(self) -> QuadraticBSpline:
        """Return the same curve as a :class:`QuadraticBSpline` (offset moved into the points)."""
        C = self.base.control_points + self.p + (self.base.greville - 1.0)[:, None] * self.q
        return QuadraticBSpline(self.base.knots, C)


def max_sample_error(spline: QuadraticBSpline, samples: np.ndarray) -> float:
    """Largest ``|tau(j / N) - y_j|`` over samples and components (the fit error)."""
    Y = np.asarray(samples, dtype=float)
    Y = Y[:, None] if Y.ndim == 1 else Y
    sites = np.arange(len(Y)) / (len(Y) - 1)
    return float(np.max(np.abs(spline(sites) - Y)))
