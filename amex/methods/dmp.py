"""Dynamic movement primitives (Schaal 2006), the paper's DMP baseline (Section II-B).

One discrete DMP per task-space dimension, all sharing the phase x (tau = T_ref):

    tau z_dot = alpha_y (beta_y (g - y) - z) + A f(x),   tau y_dot = z,   tau x_dot = -alpha_x x,

the last being the paper's Eq. 1, with ``f(x) = x sum_i psi_i(x) w_i / sum_i psi_i(x)`` and
``psi_i(x) = exp(-h_i (x - c_i)^2)``, centres ``c_i`` at times equally spaced over [0, T_ref].
The weights are fitted by ridge least squares on tau_ref; the amplitude A is the trained
``g_ref - y0`` (floored at ``min_amplitude``, so g ~ y0 is safe) or, in ``"goal"`` mode, that of
the current goal. Each step integrates the continuous DMP exactly up to a quadrature error
(:mod:`amex.methods.dmp_steps`), whatever the step length. The basis, the ridge, the amplitude
modes and the integration are derived in ``docs/methods/dmp.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from amex.core.errors import ConfigError
from amex.core.scaling import scaled
from amex.core.types import PD, Command, Observation, require_finite
from amex.methods.base import Method, MethodConfig, invalid
from amex.methods.dmp_steps import WINDOW_TOL, IntegrationSteps

if TYPE_CHECKING:  # no simulator stack needed to use a method
    from amex.plan.reference import ReferencePlan
    from amex.robot import RobotModel

AMPLITUDE_MODES = ("trained", "goal")


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
            bounds the goal-mode shape scaling to 20 per metre of goal offset.
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

    def validate(self) -> None:
        """Raise :class:`ConfigError` for settings the DMP cannot run with."""
        if self.amplitude not in AMPLITUDE_MODES:
            raise invalid("amplitude", self.amplitude, AMPLITUDE_MODES)
        if not (int(self.n_basis) == self.n_basis and self.n_basis >= 2):
            raise invalid("n_basis", self.n_basis, "an integer >= 2")
        for key in ("alpha_x", "alpha_y", "beta_y", "min_amplitude", "quad_step"):
            if not getattr(self, key) > 0.0:
                raise invalid(key, getattr(self, key), "> 0")
        if not 0.0 < self.basis_overlap < 1.0:
            raise invalid("basis_overlap", self.basis_overlap, "in (0, 1)")
        if not self.ridge >= 0.0:
            raise invalid("ridge", self.ridge, ">= 0")


class DMPTarget(NamedTuple):
    """The DMP after an update (target fields named as :class:`~amex.methods.amex.AMEXTarget`'s).

    Attributes:
        y_star: the DMP's position, the task-space target y*, shape (m,).
        yd_star: its velocity z / tau, the velocity target y_dot*, shape (m,) [task units / s].
        x: the phase after the update (Eq. 1), in (0, 1].
    """

    y_star: np.ndarray
    yd_star: np.ndarray
    x: float


class DMP(Method):
    """Discrete DMPs on the task space, Eq. 1 phase, trained on tau_ref (Schaal 2006).

    Args:
        plan: the reference; trained on its task path ``plan.y`` (N + 1 samples over T_ref,
            shape (N + 1, m)), e.g. ``ReferencePlan.from_path(y, duration)``.
        config: :class:`DMPConfig` (None: the defaults).
        dt: outer (control) period of :meth:`step` [s].
        robot: not used.

    Attributes:
        tau: the time constant, T_ref [s].
        window_reach, index_rate, exponents, forcing_weights: the basis as the integration
            steps use it (:class:`~amex.methods.dmp_steps.StepSystem`).
    """

    name = "dmp"
    fresh_steps = True  # (Method.fresh_steps; tests/methods/test_fresh_steps.py)
    config_class = DMPConfig
    config: DMPConfig

    def __init__(
        self,
        plan: ReferencePlan,
        config: DMPConfig | None = None,
        dt: float = 0.01,
        robot: RobotModel | None = None,
    ) -> None:
        super().__init__(plan, config, dt, robot)
        p = self.config
        Y = np.array(plan.y, dtype=float)
        self.reference = Y
        self.tau = float(plan.duration)
        self.n_dims = Y.shape[1]
        self.n_basis = int(p.n_basis)
        self.alpha_x, self.alpha_y, self.beta_y = float(p.alpha_x), float(p.alpha_y), p.beta_y
        self.amplitude_mode = p.amplitude
        self.quad_step = float(p.quad_step)

        t_c = np.linspace(0.0, self.tau, self.n_basis)
        self.centres = np.exp(-self.alpha_x * t_c / self.tau)
        widths = math.log(1.0 / p.basis_overlap) / np.diff(self.centres) ** 2
        self.widths = np.append(widths, widths[-1])
        self.index_rate = (self.n_basis - 1) / self.tau  # basis index per second of phase [1/s]

        self.g_ref = Y[-1].copy()
        a = self.g_ref - Y[0]
        big = np.abs(a) >= p.min_amplitude
        self.amplitude_trained = np.where(big, a, np.where(a < 0.0, -1.0, 1.0) * p.min_amplitude)
        self._scaled = big.astype(float)  # goal mode: the dimensions rescaled with g - y0
        self._fixed = np.where(big, 0.0, self.amplitude_trained)
        self.weights, self._yd0 = self._fit(Y, float(p.ridge))  # (m, n_basis), (m,)

        h, c = self.widths, self.centres
        self.exponents = np.stack([-h * c**2, 2.0 * h * c, -h])  # -h (x - c)^2 = [1, x, x^2] @ Q
        self._x_floor = float(c[-1])
        amp = self.amplitude_trained[:, None] if p.amplitude == "trained" else 1.0
        W_aug = np.vstack([self.weights * amp, np.ones(self.n_basis)]).T
        self.forcing_weights = np.ascontiguousarray(W_aug)
        self.window_reach = self._window_reach()
        tail = np.exp(-h * (c[-1] - c) ** 2) @ self.forcing_weights
        self._f_tail = tail[:-1] / tail[-1]  # sum_i psi_i(c_last) w_i (A) / sum_i psi_i(c_last)
        self._amp = np.empty(self.n_dims)
        self._amp_offset = np.empty(self.n_dims)
        self._powers = np.ones(3)  # [1, x0, x0^2]
        self._rate_arr = np.array(1.0)
        self._s = IntegrationSteps(self, self.dt)
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
        """Bases before/after the last passed centre with activations above ``WINDOW_TOL``."""
        n = self.n_basis
        u = np.linspace(0.0, self.tau, 16 * n + 1)  # phase time, 16 samples per basis interval
        x = np.exp(-self.alpha_x * u / self.tau)
        log_psi = -self.widths * (x[:, None] - self.centres) ** 2
        rel = log_psi - log_psi.max(axis=1, keepdims=True) > math.log(WINDOW_TOL)
        offset = np.arange(n) - np.minimum((u * self.index_rate).astype(int), n - 1)[:, None]
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

    def _use_dt(self, dt: float) -> IntegrationSteps:
        """Switch to steps of ``dt`` [s], carrying the state over."""
        if not (math.isfinite(dt) and dt > 0.0):
            raise ConfigError.invalid("dt", dt, "> 0 [s]")
        new = self._steps.get(dt)
        if new is None:
            if len(self._steps) >= 16:
                self._steps.clear()
            new = self._steps[dt] = IntegrationSteps(self, dt)
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
            lo = min(max(int(self._u * self.index_rate) - self.window_reach[0], 0), len(s.W) - 1)
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
    def reset(self, obs: Observation) -> None:
        """See :meth:`Method.reset`; the DMP starts at the measured ``obs.y`` with ``obs.yd``."""
        self.reset_state(obs.y, obs.yd)

    def step(self, obs: Observation) -> Command:
        """See :meth:`Method.step`: take ``obs.goal`` and integrate one outer period.

        Only the goal is taken from the observation: the DMP's state is its own, not reset to the
        measured robot state, as in the original.
        """
        target = self._advance(obs.goal, self.dt, 1.0)
        return Command.task(target.y_star, target.yd_star)

    def internals(self) -> dict[str, Any]:
        """The phase x and its rate (1 unless phase stopping slowed it)."""
        return {"phase": self._x, "phase_rate": self._rate}
