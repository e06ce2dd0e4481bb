"""Time AMEX's outer step: median wall time of ``AMEX.step(obs)`` in the benchmark's 6-D task.

Reference: 401 samples over 4 s (TCP position with minimum-jerk timing along a bent path, TCP
z-axis tilting slightly, kept unit length). Execution: the robot covers 80 % of each commanded
step plus 0.1 mm noise, while the goal moves (as in Task 2), so Eq. 8 and 7 do real work. Only
the ``step`` call is timed (Observation built outside). The paper's C++ took 102 us.
Run ``python analysis/bench_amex.py``.
"""

from __future__ import annotations

import time

import numpy as np

from amex.core.types import Observation
from amex.methods.amex import AMEX
from amex.plan.reference import ReferencePlan

T_REF, DT, N = 4.0, 0.01, 400


def reference_6d() -> np.ndarray:
    """A 6-D tau_ref: TCP position [m] and unit TCP z-axis, shape (N + 1, 6)."""
    p = np.linspace(0.0, 1.0, N + 1)
    u = (10 * p**3 - 15 * p**4 + 6 * p**5)[:, None]
    start, goal = np.array([0.307, 0.0, 0.487]), np.array([0.384, 0.229, 0.461])
    pos = start + u * (goal - start) + 0.08 * np.sin(np.pi * u) * np.array([0.0, 0.0, 1.0])
    axis = np.hstack([0.1 * np.sin(np.pi * u), 0.05 * u, -np.ones_like(u)])
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    return np.hstack([pos, axis])


def step_times(
    n_episodes: int = 4, n_steps: int = 600, seed: int = 0
) -> tuple[np.ndarray, np.ndarray]:
    """Wall times of every ``AMEX.step`` call [s], and whether each ran Eq. 7-9 (s < 1)."""
    rng = np.random.default_rng(seed)
    Y = reference_6d()
    amex = AMEX(ReferencePlan.from_path(Y, T_REF), dt=DT)
    zeros7 = np.zeros(7)
    times, adaptive = [], []
    for _ in range(n_episodes):
        goal_velocity = np.concatenate([rng.normal(0.0, 0.02, 3), np.zeros(3)])  # [m/s]
        y = Y[0].copy()
        obs = Observation(0.0, zeros7, zeros7, y, np.zeros(6), Y[-1].copy())
        amex.reset(obs)
        for k in range(n_steps):
            t = k * DT
            goal = Y[-1] + goal_velocity * min(t, 0.7 * T_REF)
            obs = Observation(t, zeros7, zeros7, y, np.zeros(6), goal)
            t0 = time.perf_counter_ns()
            command = amex.step(obs)
            times.append(time.perf_counter_ns() - t0)
            adaptive.append(not amex.final_approach)
            y = y + 0.8 * (command.y - y) + rng.normal(0.0, 1e-4, 6)
    return np.array(times) * 1e-9, np.array(adaptive)


def main() -> None:
    step_times(1, 200)  # warm up
    t, adaptive = step_times()
    us = t * 1e6
    print(
        f"AMEX.step, 6-D, 401-sample reference, {len(t)} steps: median {np.median(us):.1f} us, "
        f"mean {us.mean():.1f} us, p90 {np.percentile(us, 90):.1f} us (paper's C++: 102 us)\n"
        f"  Eq. 7-9 steps (s < 1): {adaptive.sum()}, median {np.median(us[adaptive]):.1f} us; "
        f"final approach: {(~adaptive).sum()}, median {np.median(us[~adaptive]):.1f} us"
    )


if __name__ == "__main__":
    main()
