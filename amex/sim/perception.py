"""How a method perceives the goal: noise, latency, and optional constant-velocity prediction.

The paper's PR2 experiment tracked the goal with a camera (AR markers) and names goal prediction
"e.g. with a Kalman filter" as future work. Here the goal a method sees is

    g_meas(t) = g(t - latency + preview) + n,   n ~ N(0, noise_std^2 I),

drawn from a generator seeded by ``(seed, task, env)`` so every method sees the same noise in the
same environment. With prediction on, a constant-velocity Kalman filter (per axis, state
position and velocity, white-acceleration process noise) filters ``g_meas`` and the method gets
its estimate extrapolated to ``t + lead_time`` (``lead_time`` >= 0 also compensates the latency:
the filter's newest information is ``latency`` old). ``preview`` > 0 is an oracle for
experiments: the method sees where the goal will be ``preview`` seconds from now (a long preview,
e.g. 10 s, shows from the start where a moving goal will come to rest), an upper bound for what
any prediction could give. Success is always judged on the true goal.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from amex.core.errors import ConfigError


@dataclass
class PerceptionConfig:
    """Goal perception.

    Attributes:
        noise_std: standard deviation of each goal coordinate measurement [m] (0: exact).
        latency: age of a measurement when the method receives it [s] (0: none).
        preview: oracle look-ahead [s]: the method sees the goal this far in the future (0:
            none; see the module notes).
    """

    noise_std: float = 0.0
    latency: float = 0.0
    preview: float = 0.0

    def validate(self) -> None:
        """Raise :class:`ConfigError` for negative values."""
        if not self.noise_std >= 0:
            raise ConfigError.invalid("perception.noise_std", self.noise_std, "a length >= 0 [m]")
        if not self.latency >= 0:
            raise ConfigError.invalid("perception.latency", self.latency, "a duration >= 0 [s]")
        if not (self.preview >= 0 and np.isfinite(self.preview)):
            raise ConfigError.invalid("perception.preview", self.preview, "a duration >= 0 [s]")

    @property
    def exact(self) -> bool:
        """True when the method sees the true goal."""
        return self.noise_std == 0 and self.latency == 0 and self.preview == 0


@dataclass
class PredictionConfig:
    """Constant-velocity Kalman prediction of the goal.

    Attributes:
        enabled: feed the prediction instead of the raw measurement.
        accel_std: white-acceleration process noise of the goal [m/s^2].
        measurement_std: measurement noise the filter assumes [m]; ``null``/negative: use
            ``perception.noise_std`` (at least 1e-4 m).
        lead_time: extrapolate the estimate this far beyond the current time [s]; the latency is
            always added, so 0 predicts the goal's present position.
    """

    enabled: bool = False
    accel_std: float = 0.5
    measurement_std: float = -1.0
    lead_time: float = 0.0

    def validate(self) -> None:
        """Raise :class:`ConfigError` for values the filter cannot use."""
        if not self.accel_std > 0:
            raise ConfigError.invalid("prediction.accel_std", self.accel_std, "a value > 0 [m/s^2]")
        if not self.lead_time >= 0:
            raise ConfigError.invalid("prediction.lead_time", self.lead_time, "a duration >= 0 [s]")


class ConstantVelocityKF:
    """Kalman filter of a 3-D point moving with (nearly) constant velocity.

    The three axes are independent with identical models, so the 2 x 2 covariance is shared and
    the update is a handful of float operations. State per axis: (position, velocity).

    Args:
        accel_std: process noise, white acceleration [m/s^2].
        measurement_std: measurement noise [m].
    """

    def __init__(self, accel_std: float, measurement_std: float) -> None:
        self.q = float(accel_std) ** 2
        self.r = float(measurement_std) ** 2
        self.x = np.zeros((2, 3))  # rows: position, velocity; columns: axes
        self.P = np.eye(2)
        self.t: float | None = None

    def update(self, t: float, z: np.ndarray) -> None:
        """Fuse the measurement ``z`` (shape (3,)) taken at time ``t`` [s]."""
        if self.t is None:
            self.x[0] = z
            self.x[1] = 0.0
            self.P = np.diag([self.r, 1.0])  # unknown velocity: 1 m/s std, ample here
            self.t = t
            return
        dt = t - self.t
        self.t = t
        F = np.array([[1.0, dt], [0.0, 1.0]])
        Q = self.q * np.array([[dt**4 / 4, dt**3 / 2], [dt**3 / 2, dt**2]])
        self.x = F @ self.x
        P = F @ self.P @ F.T + Q
        S = P[0, 0] + self.r
        K = P[:, 0] / S  # gain, shape (2,)
        self.x = self.x + np.outer(K, z - self.x[0])
        self.P = P - np.outer(K, P[0, :])

    def predict(self, t: float) -> np.ndarray:
        """Position extrapolated to time ``t`` [s], shape (3,)."""
        if self.t is None:
            raise ConfigError("the goal filter has no measurement yet")
        return self.x[0] + self.x[1] * (t - self.t)


class GoalSensor:
    """The goal as a method perceives it at time t (see module docstring).

    Args:
        goal_at: the true goal trajectory, ``t -> (3,)``.
        perception: noise and latency.
        prediction: optional Kalman prediction.
        rng: the environment's perception noise generator.
    """

    def __init__(
        self,
        goal_at,
        perception: PerceptionConfig,
        prediction: PredictionConfig,
        rng: np.random.Generator,
    ) -> None:
        self.goal_at = goal_at
        self.perception = perception
        self.prediction = prediction
        self.rng = rng
        r = prediction.measurement_std
        r = perception.noise_std if r is None or r < 0 else r
        self.filter = (
            ConstantVelocityKF(prediction.accel_std, max(r, 1e-4)) if prediction.enabled else None
        )

    def measure(self, t: float) -> np.ndarray:
        """What the method gets at time ``t``: raw measurement, or the filter's prediction."""
        t_seen = t - self.perception.latency + self.perception.preview
        z = self.goal_at(max(t_seen, 0.0))
        if self.perception.noise_std > 0:
            z = z + self.rng.normal(0.0, self.perception.noise_std, size=3)
        if self.filter is None:
            return z
        self.filter.update(t_seen, z)
        return self.filter.predict(t + self.prediction.lead_time)
