"""Dynamic movement primitives (Schaal 2006), the paper's DMP baseline (Section II-B).

One discrete DMP per task-space dimension, all sharing the phase x (Schaal 2006; tau = T_ref):

    tau z_dot = alpha_y (beta_y (g - y) - z) + A f(x),   tau y_dot = z,   tau x_dot = -alpha_x x,

the last being the paper's Eq. 1, with ``f(x) = x sum_i psi_i(x) w_i / sum_i psi_i(x)`` and
``psi_i(x) = exp(-h_i (x - c_i)^2)``. Centres ``c_i = exp(-alpha_x t_i / tau)`` at times ``t_i``
equally spaced over [0, T_ref] (one every 40 ms for 100 bases over 4 s, none wasted after the
motion); widths ``h_i = ln(1 / basis_overlap) / (c_{i+1} - c_i)^2`` (activation ``basis_overlap`` at
the next centre). Activations are evaluated at ``max(x, c_last)``, which changes nothing on
[0, T_ref] and keeps the normalizer away from 0 afterwards.

Training: ``F = tau^2 y_ddot - alpha_y (beta_y (g_ref - y) - tau y_dot)`` on tau_ref (central
differences), weights by least squares with a ridge relative to each basis' own Gram diagonal: an
absolute 1e-7 would shrink the late bases (x ~ 1e-4, squared column norms ~ 1e-8) and miss the last
0.5 s of the motion by 0.3 mm.

Amplitude (the goal ~ start pitfall): dividing the target by ``g_ref - y0`` gives huge weights (1e34
in peer libraries) where that is ~0, e.g. a TCP axis component that does not change. A trained
amplitude below ``min_amplitude`` is replaced by ``sign * min_amplitude``, so the weights stay
bounded and ``A w`` is still the fitted forcing term. Mode ``"trained"`` (the original's) keeps that
A for the whole execution. Mode ``"goal"`` uses ``A = g - y0`` of the current goal in the dimensions
whose trained amplitude is at least ``min_amplitude`` and the trained A in the others: continuous in
g, equal to the trained A at g = g_ref, vanishing smoothly as g -> y0, and the shape is scaled by at
most ``|g - y0| / min_amplitude``.

Integration, independent of the step length h: over one step the goal and the phase rate r are
held (r = 1 for Eq. 1), so ``x(s) = x0 exp(-alpha_x r s / tau)`` in closed form, and ``(y - g, v)``
(v = z / tau) follows a linear ODE, constant ``M = [[0, 1], [-alpha_y beta_y / tau^2, -alpha_y /
tau]]``, solved as ``expm(M h) [y - g; v] + int_0^h expm(M (h - s)) [0; F(x(s)) / tau^2] ds``: the
homogeneous part exactly (matrix exponential precomputed per h), the integral by composite 3-node
Gauss-Legendre quadrature on sub-intervals of at most ``quad_step``. The result is the continuous
DMP at the step times up to a quadrature error set by ``quad_step``, not by h, and no h is unstable.
(The original used explicit Euler steps of 10 ms.)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from scipy.linalg import expm

from amex.core.errors import ConfigError
from amex.core.scaling import scaled
from amex.core.types import PD, Command
from amex.methods.base import Method, MethodConfig, Observation, require_finite

if TYPE_CHECKING:  # no simulator stack needed to use a method
    from amex.plan.reference import ReferencePlan
    from amex.robot import RobotModel

AMPLITUDE_MODES = ("trained", "goal")

#: 3-node Gauss-Legendre rule on [0, 1].
_GL_NODES, _GL_WEIGHTS = np.polynomial.legendre.leggauss(3)
_GL_NODES, _GL_WEIGHTS = 0.5 * (_GL_NODES + 1.0), 0.5 * _GL_WEIGHTS

#: Basis activations below this fraction of the largest are left out of a step's window.
_WINDOW_TOL = 1e-17


@dataclass
class DMPConfig(MethodConfig):
    """DMP settings; the defaults are the original experiment's (Schaal 2006 constants).

    Attributes:
        pos: inner PD on the TCP position target (as the original: Kp 400, Kd 40).
        dir: inner PD on the TCP axis target.
        n_basis: Gaussian basis functions per dimension.
        alpha_x: phase decay of Eq. 1 [-] (x(T_ref) = exp(-alpha_x) = 2.4e-4).
        alpha_y: transformation-system damping [-].
        beta_y: transformation-system stiffness [-] (alpha_y / 4: critically damped).
        ridge: ridge of the least-squares fit, relative to the Gram diagonal [-].
        amplitude: ``"trained"`` (A = g_ref - y0 fixed, as the original) or ``"goal"``
            (A = g - y0 of the current goal).
        min_amplitude: floor of |A| [m] (axis components: [-]); smaller trained amplitudes are
            floored and, in goal mode, not rescaled. A length in original units
            (:mod:`amex.core.scaling`): 0.25 m is 5 cm on the Panda's scene (scale 0.2), which
            bounds
            the goal-mode shape scaling to 20 per metre of goal offset.
        basis_overlap: activation of a basis at the next centre [-].
        quad_step: longest quadrature sub-interval of an integration step [s].
    """

    name: str = "dmp"
    pos: PD = field(default_factory=lambda: PD(400.0, 40.0, 1.0))
    dir: PD = field(default_factory=lambda: PD(400.0, 40.0, 0.5))
    n_basis: int = 100
    alpha_x: float = 25.0 / 3.0  # [-]
    alpha_y: float = 25.0  # [-]
    beta_y: float = 25.0 / 4.0  # [-]
    ridge: float = 1e-7  # [-]
    amplitude: str = "trained"
    min_amplitude: float = field(default=0.25, metadata=scaled(1))  # [m] original units
    basis_overlap: float = 0.5  # [-]
    quad_step: float = 0.01  # [s]


class DMPTarget(NamedTuple):
    """The DMP after an update: y, shape (m,); yd = z / tau, shape (m,) [1/s]; the phase x."""

    y: np.ndarray
    yd: np.ndarray
    x: float


class _Steps:
    """Constants and work buffers of integration steps of one length h (see the module notes).

    The state is rows 0-1 of ``Z = [y; v; g; F(x_1); ...; F(x_K)]``, shape (3 + K, m), so one step
    is the product ``[y; v]' = B Z`` with ``B = [expm(M h) | goal column | quadrature weights]``;
    two such buffers alternate. The basis is evaluated on a window of ``width`` bases that holds all
    activations above ``_WINDOW_TOL``, its exponents as ``[1, x, x^2] @ Q``.
    """

    def __init__(self, dmp: DMP, h: float) -> None:
        tau, m, n = dmp.tau, dmp.n_dims, dmp.n_basis
        n_sub = max(1, math.ceil(h / dmp.quad_step - 1e-9))
        s = ((np.arange(n_sub)[:, None] + _GL_NODES) * (h / n_sub)).ravel()  # node times [s]
        w = np.tile(_GL_WEIGHTS * (h / n_sub), n_sub)
        M = np.array([[0.0, 1.0], [-dmp.alpha_y * dmp.beta_y / tau**2, -dmp.alpha_y / tau]])
        Phi = expm(M * h)
        G = [wq * expm(M * (h - sq))[:, 1] / tau**2 for sq, wq in zip(s, w, strict=True)]
        self.B = np.column_stack([Phi, [1.0 - Phi[0, 0], -Phi[1, 0]], *G])  # (2, 3 + K)
        log_ratio = -dmp.alpha_x * s / tau  # ln(x(s) / x0) at rate 1, (K,)
        self.log_R = np.column_stack([0.0 * s, log_ratio, 2.0 * log_ratio])  # ln [1, r, r^2]
        self.R = np.exp(self.log_R)
        self.log_decay = -dmp.alpha_x * h / tau
        self.decay = math.exp(self.log_decay)
        k = len(s)
        self.width = min(n, dmp._reach[0] + dmp._reach[1] + 2 + math.ceil(h * dmp._index_rate))
        self.Q = np.stack([dmp._Q[:, i : i + self.width] for i in range(n - self.width + 1)])
        self.W = [dmp._W_aug[i : i + self.width] for i in range(n - self.width + 1)]
        self.X = np.ones((k, 3))
        self.x_nodes = self.X[:, 1]
        self.x_sq = self.X[:, 2]
        self.x_col = self.X[:, 1:2]
        self.x_raw = np.empty(k)
        self.log_buf = np.empty((k, 3))
        self.D = np.empty((k, self.width))
        self.P = np.empty((k, m + 1))
        self.P_f = self.P[:, :m]
        self.P_sum = self.P[:, m]
        self.q = np.empty((k, 1))
        self.q_flat = self.q[:, 0]
        self.Z = (np.zeros((3 + k, m)), np.zeros((3 + k, m)))
        self.head = tuple(Z[:2] for Z in self.Z)
        self.goal_row = tuple(Z[2] for Z in self.Z)
        self.forcing = tuple(Z[3:] for Z in self.Z)


class DMP(Method):
    """Discrete DMPs on the task space, Eq. 1 phase, trained on tau_ref (Schaal 2006).

    Args:
        reference: tau_ref samples, equally spaced over [0, duration], shape (N + 1, m).
        duration: T_ref, also the time constant tau [s].
        dt: outer (control) period of :meth:`step` [s].
        **params: DMP parameters of :class:`DMPConfig` (n_basis, alpha_x, alpha_y, beta_y, ridge,
            amplitude, min_amplitude, basis_overlap, quad_step).
    """

    name = "dmp"
    config_class = DMPConfig

    def __init__(self, reference: np.ndarray, duration: float, dt: float, **params: Any) -> None:
        p = _checked_params(params)
        Y = np.array(reference, dtype=float)
        if Y.ndim != 2 or len(Y) < 3 or not np.all(np.isfinite(Y)):
            raise ConfigError(f"DMP reference must be finite, shape (N + 1 >= 3, m); got {Y.shape}")
        if not (math.isfinite(duration) and duration > 0.0):
            raise ConfigError.invalid("duration", duration, "> 0 [s]")
        self.reference = Y
        self.tau = float(duration)
        self.n_dims = Y.shape[1]
        self.n_basis = int(p.n_basis)
        self.alpha_x, self.alpha_y, self.beta_y = float(p.alpha_x), float(p.alpha_y), p.beta_y
        self.amplitude_mode = p.amplitude
        self.quad_step = float(p.quad_step)

        t_c = np.linspace(0.0, self.tau, self.n_basis)
        self.centres = np.exp(-self.alpha_x * t_c / self.tau)
        widths = math.log(1.0 / p.basis_overlap) / np.diff(self.centres) ** 2
        self.widths = np.append(widths, widths[-1])
        self._index_rate = (self.n_basis - 1) / self.tau  # basis index per second of phase [1/s]

        self.g_ref = Y[-1].copy()
        a = self.g_ref - Y[0]
        big = np.abs(a) >= p.min_amplitude
        self.amplitude_trained = np.where(big, a, np.where(a < 0.0, -1.0, 1.0) * p.min_amplitude)
        self._scaled = big.astype(float)  # goal mode: the dimensions rescaled with g - y0
        self._fixed = np.where(big, 0.0, self.amplitude_trained)
        self.weights, self._yd0 = self._fit(Y, float(p.ridge))  # (m, n_basis), (m,)

        h, c = self.widths, self.centres
        self._Q = np.stack([-h * c**2, 2.0 * h * c, -h])  # -h (x - c)^2 = [1, x, x^2] @ Q
        self._x_floor = float(c[-1])
        amp = self.amplitude_trained[:, None] if p.amplitude == "trained" else 1.0
        self._W_aug = np.ascontiguousarray(np.vstack([self.weights * amp, np.ones(self.n_basis)]).T)
        self._reach = self._window_reach()
        tail = np.exp(-h * (c[-1] - c) ** 2) @ self._W_aug
        self._f_tail = tail[:-1] / tail[-1]  # sum_i psi_i(c_last) w_i (A) / sum_i psi_i(c_last)
        self._amp = np.empty(self.n_dims)
        self._amp_offset = np.empty(self.n_dims)
        self._powers = np.ones(3)  # [1, x0, x0^2]
        self._rate_arr = np.array(1.0)
        if not (math.isfinite(dt) and dt > 0.0):
            raise ConfigError.invalid("dt", dt, "> 0 [s]")
        self.dt = float(dt)
        self._s = _Steps(self, self.dt)
        self._s_dt = self.dt
        self._steps = {self.dt: self._s}
        self._flip = 0
        self.reset_state()

    # ----------------------------------------------------------------------------- training
    def basis(self, x: np.ndarray) -> np.ndarray:
        """Normalized activations ``psi_i(x) / sum_j psi_j(x)``, shape (len(x), n_basis)."""
        xc = np.maximum(np.atleast_1d(np.asarray(x, dtype=float)), self.centres[-1])
        psi = np.exp(-self.widths * (xc[:, None] - self.centres) ** 2)
        return psi / psi.sum(axis=1, keepdims=True)

    def forcing(self, x: np.ndarray, goal: np.ndarray | None = None) -> np.ndarray:
        """The forcing term ``A f(x)`` at phases x, shape (len(x), m); A for ``goal`` (or g_ref)."""
        x = np.atleast_1d(np.asarray(x, dtype=float))
        amp = self.amplitude(self.g_ref if goal is None else np.asarray(goal, dtype=float))
        return (self.basis(x) * x[:, None]) @ self.weights.T * amp

    def amplitude(self, goal: np.ndarray) -> np.ndarray:
        """The amplitude A of the forcing term for ``goal`` (see the module notes), shape (m,)."""
        if self.amplitude_mode == "trained":
            return self.amplitude_trained.copy()
        return self._scaled * (goal - self.y0) + self._fixed

    def _fit(self, Y: np.ndarray, ridge: float) -> tuple[np.ndarray, np.ndarray]:
        """Ridge least squares of the forcing term on tau_ref: weights (m, n_basis), y_dot(0)."""
        tau = self.tau
        h = tau / (len(Y) - 1)
        x = np.exp(-self.alpha_x * np.linspace(0.0, tau, len(Y)) / tau)
        Yd = np.gradient(Y, h, axis=0, edge_order=2)
        Ydd = np.gradient(Yd, h, axis=0, edge_order=2)
        F = tau**2 * Ydd - self.alpha_y * (self.beta_y * (self.g_ref - Y) - tau * Yd)
        P = self.basis(x) * x[:, None]
        A = P.T @ P
        A[np.diag_indices_from(A)] *= 1.0 + ridge
        w = np.linalg.solve(A, P.T @ (F / self.amplitude_trained))
        return w.T, Yd[0].copy()

    def _window_reach(self) -> tuple[int, int]:
        """Bases before/after the last passed centre with activations above ``_WINDOW_TOL``."""
        n = self.n_basis
        u = np.linspace(0.0, self.tau, 16 * n + 1)  # phase time, 16 samples per basis interval
        x = np.exp(-self.alpha_x * u / self.tau)
        log_psi = -self.widths * (x[:, None] - self.centres) ** 2
        rel = log_psi - log_psi.max(axis=1, keepdims=True) > math.log(_WINDOW_TOL)
        offset = np.arange(n) - np.minimum((u * self._index_rate).astype(int), n - 1)[:, None]
        return int(-np.min(np.where(rel, offset, 0))), int(np.max(np.where(rel, offset, 0)))

    # ----------------------------------------------------------------------------- rollout
    def reset_state(self, y0: np.ndarray | None = None, yd0: np.ndarray | None = None) -> None:
        """Restart at phase 1 from ``y0`` (default tau_ref(0)) with velocity ``yd0`` [1/s].

        ``yd0`` defaults to tau_ref's start velocity; ``y0`` is also the goal-mode amplitude's y0.

        Raises:
            InputError: y0 or yd0 holds a NaN or an infinity (nothing is changed).
        """
        require_finite(y0=0.0 if y0 is None else y0, yd0=0.0 if yd0 is None else yd0)
        head = self._s.head[self._flip]
        head[0] = self.reference[0] if y0 is None else y0
        head[1] = self._yd0 if yd0 is None else yd0
        self.y0 = head[0].copy()
        np.subtract(self._fixed, self._scaled * self.y0, out=self._amp_offset)
        self._x = 1.0
        self._u = 0.0  # phase time -tau ln(x) / alpha_x [s]
        self._rate = 1.0

    @property
    def x(self) -> float:
        """The phase x (1 at the start, Eq. 1)."""
        return self._x

    @property
    def y(self) -> np.ndarray:
        """The DMP's position y, shape (m,) (a copy)."""
        return self._s.head[self._flip][0].copy()

    @property
    def yd(self) -> np.ndarray:
        """The DMP's velocity y_dot = z / tau, shape (m,) (a copy)."""
        return self._s.head[self._flip][1].copy()

    def _use_dt(self, dt: float) -> _Steps:
        """Switch to steps of ``dt`` [s], carrying the state over."""
        if not (math.isfinite(dt) and dt > 0.0):
            raise ConfigError.invalid("dt", dt, "> 0 [s]")
        new = self._steps.get(dt)
        if new is None:
            if len(self._steps) >= 16:
                self._steps.clear()
            new = self._steps[dt] = _Steps(self, dt)
        new.head[0][:] = self._s.head[self._flip]
        self._s, self._s_dt, self._flip = new, dt, 0
        return new

    def update(self, goal: np.ndarray, dt: float) -> DMPTarget:
        """Advance by ``dt`` [s] towards ``goal``, shape (m,), held over the step (Eq. 1).

        Raises:
            InputError: ``goal`` holds a NaN or an infinity; the DMP is left as it was.
            ConfigError: ``dt`` is not a finite duration > 0.
        """
        return self._advance(goal, dt, 1.0)

    def _advance(self, goal: np.ndarray, dt: float, rate: float) -> DMPTarget:
        """One step of ``dt`` with the phase slowed to ``rate`` (1: Eq. 1; module notes)."""
        require_finite(goal=goal)
        s = self._s if dt == self._s_dt else self._use_dt(dt)
        i = self._flip
        x0 = self._x
        pw = self._powers
        pw[1] = x0
        pw[2] = x0 * x0
        X = s.X
        if rate == 1.0:
            np.multiply(s.R, pw, out=X)  # [1, x, x^2] at the quadrature nodes
            x1 = x0 * s.decay
        else:
            self._rate_arr[()] = rate
            np.multiply(s.log_R, self._rate_arr, out=s.log_buf)
            np.exp(s.log_buf, out=s.log_buf)
            np.multiply(s.log_buf, pw, out=X)
            x1 = x0 * math.exp(s.log_decay * rate)
        fn = s.forcing[i]
        if x0 <= self._x_floor:  # past T_ref: the basis is frozen at c_last, f = x f_tail
            np.multiply(s.x_col, self._f_tail, out=fn)
        else:
            x_nodes = s.x_nodes
            if x1 < self._x_floor:  # the step crosses T_ref: the basis at max(x, c_last)
                x_nodes = s.x_raw
                x_nodes[:] = s.x_nodes
                np.maximum(s.x_nodes, self._x_floor, out=s.x_nodes)
                np.multiply(s.x_nodes, s.x_nodes, out=s.x_sq)
            lo = min(max(int(self._u * self._index_rate) - self._reach[0], 0), len(s.W) - 1)
            D = s.D
            np.dot(X, s.Q[lo], out=D)
            np.exp(D, out=D)
            np.dot(D, s.W[lo], out=s.P)  # (K, m + 1): sum_i psi_i w_i (A), sum_i psi_i
            np.divide(x_nodes, s.P_sum, out=s.q_flat)
            np.multiply(s.P_f, s.q, out=fn)  # A f(x) at the nodes, (K, m)
        if self.amplitude_mode == "goal":
            amp = self._amp
            np.multiply(goal, self._scaled, out=amp)
            amp += self._amp_offset
            fn *= amp
        s.goal_row[i][:] = goal
        j = 1 - i
        head = s.head[j]
        np.dot(s.B, s.Z[i], out=head)
        self._flip = j
        self._x = x1
        self._u += rate * dt
        self._rate = rate
        out = head.copy()
        return DMPTarget(out[0], out[1], x1)

    # ----------------------------------------------------------------------------- Method
    @classmethod
    def from_plan(
        cls, plan: ReferencePlan, config: MethodConfig, dt: float, robot: RobotModel | None = None
    ) -> DMP:
        """See :meth:`Method.from_plan`; trains on ``plan.y`` with the config's DMP parameters."""
        return cls(plan.y, plan.duration, dt, **config.params())

    def reset(self, obs: Observation) -> None:
        """See :meth:`Method.reset`; the DMP starts at the measured ``obs.y`` with ``obs.yd``."""
        self.reset_state(obs.y, obs.yd)

    def step(self, obs: Observation) -> Command:
        """See :meth:`Method.step`: take ``obs.goal`` and integrate one outer period.

        Only the goal is taken from the observation: the DMP's state is its own, not reset to the
        measured robot state, as in the original.
        """
        target = self._advance(obs.goal, self.dt, 1.0)
        return Command(y=target.y, yd=target.yd)

    def internals(self) -> dict[str, Any]:
        """The phase x and its rate (1 unless phase stopping slowed it)."""
        return {"phase": self._x, "phase_rate": self._rate}



def _checked_params(params: dict[str, Any]) -> DMPConfig:
    """``params`` over the default DMP parameters, validated (:class:`ConfigError` if not)."""
    valid = DMPConfig.param_names()
    p = DMPConfig()
    for key, value in params.items():
        if key not in valid:
            raise ConfigError.invalid("DMP parameter", key, valid)
        setattr(p, key, value)
    if p.amplitude not in AMPLITUDE_MODES:
        raise ConfigError.invalid("amplitude", p.amplitude, AMPLITUDE_MODES)
    if int(p.n_basis) < 2:
        raise ConfigError.invalid("n_basis", p.n_basis, ">= 2")
    for key in ("alpha_x", "alpha_y", "beta_y", "min_amplitude", "quad_step"):
        if not getattr(p, key) > 0.0:
            raise ConfigError.invalid(key, getattr(p, key), "> 0")
    if not 0.0 < p.basis_overlap < 1.0:
        raise ConfigError.invalid("basis_overlap", p.basis_overlap, "in (0, 1)")
    if not p.ridge >= 0.0:
        raise ConfigError.invalid("ridge", p.ridge, ">= 0")
    return p
