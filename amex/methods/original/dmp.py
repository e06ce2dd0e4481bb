"""The DMP as the authors' harness ran it (``dmp.cpp`` at commit b475fa1fe).

``implementation=original method=dmp`` selects it (``experiment=original`` sets it); of the
DMP parameters (:class:`~amex.methods.dmp.DMPConfig`) n_basis, alpha_x, alpha_y, beta_y and ridge
apply. Against :class:`~amex.methods.dmp.DMP` (ours: exact integration, time constant T_ref):

* Time constant: ``T = (N + 1) dt`` (4.01 s) and the rate ``tau = 0.5 / T``, so
  ``y_ddot = tau^2 (alpha_y (beta_y (g - y) - y_dot / tau) + A f(x))``, ``x_dot = -alpha_x tau x``:
  the DMP runs as if its motion lasted ``1 / tau = 8.02 s`` (why it is slow on moving goals:
  ``docs/methods/originals.md``).
* Basis: ``c_i = exp(-alpha_x i / (2 (n - 1)))``, ``h_i = 0.5 / (0.65 (c_{i+1} - c_i)^2)``; the
  activations are not clamped after the last centre.
* Training: on the plan resampled at the outer period; derivatives of the reference by
  one-sided/central differences, phase samples by Euler steps, ``F / A`` fitted with an absolute
  ridge 1e-7; ``A = g_ref - y0`` fixed.
* Integration: explicit Euler steps of the outer period, velocity first (``y_dot += dt y_ddot;
  y += dt y_dot``), then the phase.
* Start: the reference's first sample, with velocity ``(tau_ref_1 - tau_ref_0) / dt``; only the
  goal *position* is updated (its axis stays the reference's).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from amex.core.types import Command, Observation
from amex.methods.base import Method
from amex.methods.dmp import DMPConfig, DMPTarget

if TYPE_CHECKING:
    from amex.plan.reference import ReferencePlan
    from amex.robot import RobotModel


class DMPOriginal(Method):
    """The authors' DMP (module notes).

    Args:
        plan: the reference; trained on its task path ``plan.y`` resampled at ``dt``.
        config: :class:`~amex.methods.dmp.DMPConfig`; n_basis (original 100), alpha_x, alpha_y,
            beta_y (the original's constants) and ridge (absolute, original 1e-7) apply.
        dt: the outer period, also the sample period and the Euler step [s].
        robot: not used.
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
        c = self.config
        Y = np.array(resample(plan.y, plan.dt, self.dt), dtype=float)
        self.reference = Y
        self.tau = 0.5 / (len(Y) * self.dt)  # a rate [1/s]: the motion "lasts" 1 / tau
        self.alpha_x, self.alpha_y = float(c.alpha_x), float(c.alpha_y)
        self.beta_y = float(c.beta_y)
        n = int(c.n_basis)
        i = np.arange(n)
        self.centres = np.exp(-self.alpha_x * i * 0.5 / (n - 1))
        widths = 0.5 / (0.65 * np.diff(self.centres) ** 2)
        self.widths = np.append(widths, widths[-1])
        self.y0 = Y[0].copy()
        self.g_ref = Y[-1].copy()
        self.amplitude = self.g_ref - self.y0
        self.weights = self._fit(float(c.ridge))  # (n, m)
        self.reset_state()

    def _fit(self, ridge: float) -> np.ndarray:
        Y, dt, tau = self.reference, self.dt, self.tau
        x = np.empty(len(Y))
        x[0] = 1.0
        for k in range(1, len(Y)):  # Euler steps of the phase, as in training
            x[k] = x[k - 1] - self.alpha_x * x[k - 1] * tau * dt
        psi = np.exp(-self.widths * (x[:, None] - self.centres) ** 2)
        Phi = psi * (x / psi.sum(axis=1))[:, None]
        Yd = _difference(Y, dt)
        Ydd = _difference(Yd, dt)
        a, b = self.alpha_y, self.beta_y
        with np.errstate(divide="ignore", invalid="ignore"):  # A = 0 breaks it, as the original
            F = (Ydd / tau**2 - a * (b * (self.g_ref - Y) - Yd / tau)) / self.amplitude
        G = Phi.T @ Phi + ridge * np.eye(Phi.shape[1])
        return np.linalg.solve(G, Phi.T @ F)

    def reset_state(self) -> None:
        """Phase 1 at the reference's start, with its first finite-difference velocity."""
        Y = self.reference
        self.y = Y[0].copy()
        self.yd = (Y[1] - Y[0]) / self.dt
        self.x = 1.0
        self.goal = self.g_ref.copy()

    def update(self, goal_position: np.ndarray) -> DMPTarget:
        """One Euler step towards the goal position (its axis stays the reference's)."""
        self.goal[:3] = goal_position[:3]
        psi = np.exp(-self.widths * (self.x - self.centres) ** 2)
        f = (psi @ self.weights) * self.x / psi.sum()
        a, b, tau = self.alpha_y, self.beta_y, self.tau
        ydd = (a * (b * (self.goal - self.y) - self.yd / tau) + self.amplitude * f) * tau * tau
        self.yd = self.yd + ydd * self.dt
        self.y = self.y + self.yd * self.dt
        self.x = self.x - self.alpha_x * self.x * tau * self.dt
        return DMPTarget(self.y.copy(), self.yd.copy(), self.x)

    def reset(self, obs: Observation) -> None:
        """See :meth:`Method.reset`: the DMP starts from the reference, not the measured state."""
        self.reset_state()

    def step(self, obs: Observation) -> Command:
        """See :meth:`Method.step`."""
        target = self.update(obs.goal)
        return Command.task(target.y_star, target.yd_star)

    def internals(self) -> dict[str, Any]:
        """The phase x."""
        return {"phase": self.x, "phase_rate": 1.0}


def _difference(Y: np.ndarray, dt: float) -> np.ndarray:
    """Forward difference at the start, backward at the end, central inside (``dmp.cpp``)."""
    D = np.empty_like(Y)
    D[0] = (Y[1] - Y[0]) / dt
    D[-1] = (Y[-1] - Y[-2]) / dt
    D[1:-1] = (Y[2:] - Y[:-2]) / (2.0 * dt)
    return D


def resample(y: np.ndarray, dt_in: float, dt_out: float) -> np.ndarray:
    """Samples ``dt_out`` apart over the same duration (linear; unchanged when equal)."""
    if abs(dt_in - dt_out) < 1e-12:
        return y
    duration = (len(y) - 1) * dt_in
    t_out = np.arange(0.0, duration + 1e-9, dt_out)
    t_in = np.arange(len(y)) * dt_in
    return np.stack([np.interp(t_out, t_in, y[:, j]) for j in range(y.shape[1])], axis=1)
