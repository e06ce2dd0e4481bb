"""DMP with an obstacle coupling term (``dmp_avoid``): our DMP, steered around what it perceives.

The transformation system of :mod:`amex.methods.dmp` gets an acceleration ``C`` on its TCP
position (the axis dimensions are left alone), summed over the perceived obstacles ``o`` (centre,
radius ``r_o``), computed from the DMP's own position y and velocity ``y_dot``:

* ``coupling="steering"`` (Hoffmann et al., ICRA 2009, Eq. 8; movement_primitives'
  ``CouplingTermObstacleAvoidance3D``): ``C = gamma phi exp(-beta phi) R y_dot``, with ``phi``
  the angle between ``y_dot`` and ``o - y`` and ``R y_dot = r x y_dot``, the velocity turned by
  90 deg about ``r = (o - y) x y_dot / |(o - y) x y_dot|`` (away from the obstacle). Hoffmann's
  ``p`` enters ``tau v_dot`` with ``v = tau y_dot``, i.e. the acceleration ``p / tau^2``: our
  ``gamma`` is his ``gamma / tau``. His term acts at any distance; ``decay > 0`` multiplies it by
  ``exp(-s / decay)``, ``s = max(|o - y| - r_o, 0)`` the distance to the obstacle's surface.
* ``coupling="potential"`` (Park et al., Humanoids 2008, Eq. 12-14): ``C = -grad_y U`` of the
  dynamic potential ``U = lam (-cos theta)^b |y_dot| / p`` while ``cos theta = y_dot^T (y - o) /
  (|y_dot| |y - o|) < 0`` (approaching), 0 otherwise, ``p = max(|y - o| - r_o, p_min)``:
  ``grad U = lam |y_dot| (-b (-cos theta)^(b-1) grad cos theta / p - (-cos theta)^b n / p^2)``
  with ``n = (y - o) / |y - o| = grad p`` and ``grad cos theta = (v_hat - cos theta n) / |y - o|``
  (derived in ``docs/methods/dmp_avoid.md``; below ``p_min`` the ``n / p^2`` term is 0).

Over an outer step the goal and ``C`` are held, so the step stays exact for the linear part: the
coupling adds ``Gamma C`` to ``[y; y_dot]``, ``Gamma = int_0^h expm(M (h - s)) [0; 1] ds``
(:mod:`amex.methods.dmp_steps`' matrix M), computed once.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.linalg import expm

from amex.core.scaling import scaled
from amex.core.types import Command, Observation, require_finite
from amex.methods.base import invalid
from amex.methods.dmp import DMP, DMPConfig

if TYPE_CHECKING:
    from amex.plan.reference import ReferencePlan
    from amex.robot import RobotModel

COUPLINGS = ("steering", "potential")


@dataclass
class DMPAvoidConfig(DMPConfig):
    """The DMP's settings (the paper's) and its obstacle coupling's.

    Attributes:
        coupling: ``"steering"`` (Hoffmann 2009) or ``"potential"`` (Park 2008).
        gamma: steering gain gamma [1/s].
        beta: steering angle decay beta [1/rad] (Hoffmann: 20 / pi).
        decay: distance decay length of the steering [m] (original units); 0: none (Hoffmann).
        potential_gain: lam of the dynamic potential [m^2/s] (original units: x scale^2).
        potential_power: b of the dynamic potential [-] (Park: 2).
        min_distance: p_min, the potential's smallest distance [m] (original units).
    """

    name: str = "dmp_avoid"
    coupling: str = "steering"
    gamma: float = 250.0  # [1/s] (Hoffmann's 1000 / T_ref)
    beta: float = 20.0 / math.pi  # [1/rad]
    decay: float = field(default=0.0, metadata=scaled(1))  # [m]; 0: none
    potential_gain: float = field(default=25.0, metadata=scaled(2))  # [m^2/s] (Panda: 1)
    potential_power: float = 2.0  # [-]
    min_distance: float = field(default=0.025, metadata=scaled(1))  # [m] (Panda: 5 mm)

    def validate(self) -> None:
        """The DMP's checks and the coupling's."""
        super().validate()
        if self.coupling not in COUPLINGS:
            raise invalid("coupling", self.coupling, COUPLINGS)
        if not self.beta > 0.0:
            raise invalid("beta", self.beta, "> 0")
        if not self.potential_power >= 1.0:
            raise invalid("potential_power", self.potential_power, ">= 1")
        if not self.min_distance > 0.0:
            raise invalid("min_distance", self.min_distance, "> 0")


def steering(y: np.ndarray, yd: np.ndarray, center: np.ndarray, radius: float, gamma: float,
             beta: float, decay: float) -> np.ndarray:  # fmt: skip
    """Hoffmann's coupling acceleration for one obstacle (module notes), shape (3,) [m/s^2].

    Scalar arithmetic on Python floats (numpy's small-vector calls cost more than the math).
    """
    ox, oy, oz = (center - y).tolist()
    vx, vy, vz = yd.tolist()
    rx, ry, rz = oy * vz - oz * vy, oz * vx - ox * vz, ox * vy - oy * vx  # (o - y) x y_dot
    r_norm = math.sqrt(rx * rx + ry * ry + rz * rz)
    speed = math.sqrt(vx * vx + vy * vy + vz * vz)
    dist = math.sqrt(ox * ox + oy * oy + oz * oz)
    if r_norm < 1e-12 * max(speed * dist, 1e-300):  # heading straight at it or still: no turn
        return np.zeros(3)
    phi = math.acos(min(1.0, max(-1.0, (ox * vx + oy * vy + oz * vz) / (speed * dist))))
    scale = gamma * phi * math.exp(-beta * phi)
    if decay > 0.0:
        scale *= math.exp(-max(dist - radius, 0.0) / decay)
    scale /= r_norm
    return np.array([ry * vz - rz * vy, rz * vx - rx * vz, rx * vy - ry * vx]) * scale


def potential(y: np.ndarray, yd: np.ndarray, center: np.ndarray, radius: float, gain: float,
              power: float, min_distance: float) -> np.ndarray:  # fmt: skip
    """Park's coupling ``-grad_y U`` for one obstacle (module notes), shape (3,) [m/s^2]."""
    rel = y - center
    dist = math.sqrt(float(rel @ rel))
    speed = math.sqrt(float(yd @ yd))
    if dist < 1e-12 or speed < 1e-12:
        return np.zeros(3)
    n, v_hat = rel / dist, yd / speed
    cos = float(v_hat @ n)
    if cos >= 0.0:  # moving away: no potential
        return np.zeros(3)
    p = dist - radius
    dp = 1.0
    if p <= min_distance:  # the distance floor: grad p = 0 there
        p, dp = min_distance, 0.0
    grad_cos = (v_hat - cos * n) / dist
    neg = -cos  # grad U = gain speed (-b neg^(b-1) grad_cos / p - neg^b dp n / p^2)
    grad = (-power * neg ** (power - 1.0) / p) * grad_cos - (neg**power * dp / p**2) * n
    return (-gain * speed) * grad


def response_to_constant_acceleration(alpha_y: float, beta_y: float, tau: float,
                                      h: float) -> np.ndarray:  # fmt: skip
    """``Gamma = int_0^h expm(M (h - s)) [0; 1] ds``, shape (2,) (module notes)."""
    M = np.array([[0.0, 1.0], [-alpha_y * beta_y / tau**2, -alpha_y / tau]])
    A = np.zeros((3, 3))
    A[:2, :2], A[1, 2] = M, 1.0
    return expm(A * h)[:2, 2]


class DMPAvoid(DMP):
    """The DMP with the obstacle coupling of the module notes.

    Args:
        plan: see :class:`~amex.methods.dmp.DMP`.
        config: :class:`DMPAvoidConfig` (None: the defaults).
        dt: outer (control) period of :meth:`step` [s].
        robot: not used.
    """

    name = "dmp_avoid"
    config_class = DMPAvoidConfig
    config: DMPAvoidConfig

    def __init__(
        self,
        plan: ReferencePlan,
        config: DMPAvoidConfig | None = None,
        dt: float = 0.01,
        robot: RobotModel | None = None,
    ) -> None:
        super().__init__(plan, config, dt, robot)
        self.gain_step = response_to_constant_acceleration(
            self.alpha_y, self.beta_y, self.tau, self.dt
        )
        self._coupling = np.zeros(3)

    def coupling(self, y: np.ndarray, yd: np.ndarray, centers: np.ndarray,
                 radii: np.ndarray) -> np.ndarray:  # fmt: skip
        """The summed coupling acceleration at the DMP state ``(y, y_dot)``, shape (3,)."""
        c = self.config
        total = np.zeros(3)
        for center, radius in zip(centers, radii, strict=True):
            if c.coupling == "steering":
                total += steering(y, yd, center, float(radius), c.gamma, c.beta, c.decay)
            else:
                total += potential(y, yd, center, float(radius), c.potential_gain,
                                   c.potential_power, c.min_distance)  # fmt: skip
        return total

    def reset(self, obs: Observation) -> None:
        """See :meth:`DMP.reset`."""
        super().reset(obs)
        self._coupling = np.zeros(3)

    def step(self, obs: Observation) -> Command:
        """See :meth:`DMP.step`; the coupling of the perceived obstacles is added over the step."""
        require_finite(goal=obs.goal, obstacles=obs.obstacles, obstacle_radii=obs.obstacle_radii)
        head = self._s.head[self._flip]
        C = self.coupling(head[0, :3], head[1, :3], obs.obstacles, obs.obstacle_radii)
        self._advance(obs.goal, self.dt, 1.0)
        head = self._s.head[self._flip]
        head[0, :3] += self.gain_step[0] * C
        head[1, :3] += self.gain_step[1] * C
        self._coupling = C
        return Command.task(head[0].copy(), head[1].copy())

    def internals(self) -> dict[str, Any]:
        """The DMP's phase and the coupling acceleration of the last step."""
        return {**super().internals(), "coupling": self._coupling.copy()}
