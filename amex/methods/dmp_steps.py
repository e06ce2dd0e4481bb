"""The DMP's integration steps of one length h: constants and work buffers.

Over one step the goal and the phase rate r are held, so ``x(s) = x0 exp(-alpha_x r s / tau)`` and
``(y - g, v)`` (v = z / tau) follows a linear ODE with the constant matrix
``M = [[0, 1], [-alpha_y beta_y / tau^2, -alpha_y / tau]]``::

    [y - g; v](h) = expm(M h) [y - g; v](0) + int_0^h expm(M (h - s)) [0; F(x(s)) / tau^2] ds

the homogeneous part exactly, the integral by composite 3-node Gauss-Legendre quadrature on
sub-intervals of at most ``quad_step`` (derived in ``docs/methods/dmp.md``).
"""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np
from scipy.linalg import expm

#: 3-node Gauss-Legendre rule on [0, 1].
GL_NODES, GL_WEIGHTS = np.polynomial.legendre.leggauss(3)
GL_NODES, GL_WEIGHTS = 0.5 * (GL_NODES + 1.0), 0.5 * GL_WEIGHTS

#: Basis activations below this fraction of the largest are left out of a step's window.
WINDOW_TOL = 1e-17


class StepSystem(Protocol):
    """What the steps need of a DMP (:class:`~amex.methods.dmp.DMP` provides it).

    Attributes:
        tau: time constant [s].
        n_dims: task dimensions m.
        n_basis: basis functions n.
        alpha_x, alpha_y, beta_y: the DMP's constants [-].
        quad_step: longest quadrature sub-interval [s].
        window_reach: bases before / after the last passed centre with activations above
            :data:`WINDOW_TOL`.
        index_rate: basis index per second of phase time [1/s].
        exponents: ``Q``, shape (3, n): the basis exponents ``-h (x - c)^2 = [1, x, x^2] @ Q``.
        forcing_weights: shape (n, m + 1): the weights (times the trained amplitude) and a column
            of ones for the normalizer.
    """

    tau: float
    n_dims: int
    n_basis: int
    alpha_x: float
    alpha_y: float
    beta_y: float
    quad_step: float
    window_reach: tuple[int, int]
    index_rate: float
    exponents: np.ndarray
    forcing_weights: np.ndarray


class IntegrationSteps:
    """Constants and work buffers of integration steps of one length h (module notes).

    The state is rows 0-1 of ``Z = [y; v; g; F(x_1); ...; F(x_K)]``, shape (3 + K, m), so one step
    is the product ``[y; v]' = B Z`` with ``B = [expm(M h) | goal column | quadrature weights]``;
    two such buffers alternate. The basis is evaluated on a window of ``width`` bases that holds all
    activations above :data:`WINDOW_TOL`, its exponents as ``[1, x, x^2] @ Q``.
    """

    def __init__(self, dmp: StepSystem, h: float) -> None:
        tau, m, n = dmp.tau, dmp.n_dims, dmp.n_basis
        n_sub = max(1, math.ceil(h / dmp.quad_step - 1e-9))
        s = ((np.arange(n_sub)[:, None] + GL_NODES) * (h / n_sub)).ravel()  # node times [s]
        w = np.tile(GL_WEIGHTS * (h / n_sub), n_sub)
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
        reach = dmp.window_reach
        self.width = min(n, reach[0] + reach[1] + 2 + math.ceil(h * dmp.index_rate))
        Q, W_aug = dmp.exponents, dmp.forcing_weights
        self.Q = np.stack([Q[:, i : i + self.width] for i in range(n - self.width + 1)])
        self.W = [W_aug[i : i + self.width] for i in range(n - self.width + 1)]
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
