"""Benchmark our DMP against movement_primitives' (the optional ``bench`` extra).

Both are trained on the same 6-D reference (a min-jerk reach of 0.25 m over 4 s with a 5 cm bump,
the TCP axis tilting, sampled at 10 ms like tau_ref) with the same 100 weights per dimension and
ridge 1e-7; each outer step is timed with ``time.perf_counter_ns`` over episodes of ``n_steps``
steps at ``dt`` (alternating between the two libraries, same process), and each open-loop rollout
is compared with the reference at the rollout's own times (TCP position error, max over [0, T]).

Run: ``.venv/bin/python analysis/bench_dmp.py``.
"""

from __future__ import annotations

import time

import numpy as np

from amex.core.types import Observation
from amex.methods.dmp import DMP
from amex.plan.reference import ReferencePlan

T_REF = 4.0
DT_REF = 0.01
Y0 = np.array([0.40, -0.10, 0.50, 0.0, 0.0, -1.0])
G_REF = np.array([0.55, 0.05, 0.40, 0.6, 0.0, -0.8])
DTS = (0.001, 0.002, 0.005, 0.01, 0.02, 0.05)


def reference_at(t: np.ndarray) -> np.ndarray:
    """The benchmark reference at times t [s], shape (len(t), 6)."""
    s = np.clip(np.asarray(t, dtype=float) / T_REF, 0.0, 1.0)
    mj = 10 * s**3 - 15 * s**4 + 6 * s**5
    y = Y0 + mj[:, None] * (G_REF - Y0)
    y[:, 2] += 0.05 * np.sin(np.pi * s) ** 2
    return y


def _position_error(t: np.ndarray, y: np.ndarray) -> float:
    """Max TCP position error against the reference over t <= T_ref [m]."""
    keep = t <= T_REF + 1e-9
    return float(np.linalg.norm(y[keep, :3] - reference_at(t[keep])[:, :3], axis=1).max())


def _ours_error(reference: np.ndarray, dt: float) -> float:
    dmp = DMP(ReferencePlan.from_path(reference, T_REF), dt=dt)
    n = round(T_REF / dt)
    y = np.array([dmp.y] + [dmp.update(dmp.g_ref, dt).y_star for _ in range(n)])
    return _position_error(np.arange(n + 1) * dt, y)


def _time_ours(dmp: DMP, goal: np.ndarray, dt: float, n_steps: int) -> np.ndarray:
    dmp.reset_state()
    out = np.empty(n_steps)
    clock = time.perf_counter_ns
    for k in range(n_steps):
        start = clock()
        dmp.update(goal, dt)
        out[k] = clock() - start
    return out


def _time_method_step(dmp: DMP, goal: np.ndarray, n_steps: int) -> np.ndarray:
    """Through the :class:`~amex.methods.base.Method` API: ``step(Observation)``."""
    obs = Observation(t=0.0, q=np.zeros(7), qd=np.zeros(7), y=dmp.y, yd=np.zeros(6), goal=goal)
    dmp.reset(obs)
    out = np.empty(n_steps)
    clock = time.perf_counter_ns
    for k in range(n_steps):
        start = clock()
        dmp.step(obs)
        out[k] = clock() - start
    return out


def _time_theirs(theirs, n_steps: int) -> np.ndarray:
    theirs.reset()
    y, yd = theirs.start_y.copy(), theirs.start_yd.copy()
    out = np.empty(n_steps)
    clock = time.perf_counter_ns
    for k in range(n_steps):
        start = clock()
        y, yd = theirs.step(y, yd)
        out[k] = clock() - start
    return out


def compare_with_movement_primitives(
    n_steps: int = 1000, dt: float = 0.01, rounds: int = 5, verbose: bool = True
) -> dict:
    """Time ``n_steps`` outer steps of both DMPs, ``rounds`` times, and compare reproduction.

    Args:
        n_steps: steps per timed episode (1000 at 10 ms: the 10 s episode limit).
        dt: outer period of the timing [s].
        rounds: timed episodes per library, alternating.
        verbose: print the results.

    Returns:
        ``ours_us`` / ``theirs_us``: median step times [us] (``ours_motion_us``: ours over the
        first T_ref only, while the forcing term is active; ``ours_step_us``: ours through
        ``Method.step(Observation)``); ``ratio`` = theirs / ours;
        ``ours_error_mm`` / ``theirs_error_mm``: reproduction error per dt [mm].
    """
    try:
        from movement_primitives.dmp import DMP as TheirDMP
    except ImportError as e:  # the optional ``bench`` extra
        raise ImportError(
            "analysis/bench_dmp.py needs movement_primitives: pip install "
            "'amex[bench]' (it imports pytransform3d too)"
        ) from e

    t_ref = np.arange(round(T_REF / DT_REF) + 1) * DT_REF
    reference = reference_at(t_ref)
    ours = DMP(ReferencePlan.from_path(reference, T_REF), dt=dt)
    theirs = TheirDMP(6, execution_time=T_REF, dt=dt, n_weights_per_dim=100)
    theirs.imitate(t_ref, reference, regularization_coefficient=1e-7)
    theirs.configure(start_y=reference[0], goal_y=reference[-1])

    ours_t, step_t, theirs_t = [], [], []
    for _ in range(rounds):
        ours_t.append(_time_ours(ours, ours.g_ref, dt, n_steps))
        theirs_t.append(_time_theirs(theirs, n_steps))
        step_t.append(_time_method_step(ours, ours.g_ref, n_steps))
    ours_ns, step_ns, theirs_ns = np.array(ours_t), np.array(step_t), np.array(theirs_t)
    in_motion = min(n_steps, round(T_REF / dt))

    ours_err, theirs_err = {}, {}
    for step in DTS:
        ours_err[step] = 1e3 * _ours_error(reference, step)
        theirs.dt_ = step
        t, y = theirs.open_loop()
        theirs_err[step] = 1e3 * _position_error(np.asarray(t), np.asarray(y))
    theirs.dt_ = dt

    result = {
        "ours_us": float(np.median(ours_ns)) / 1e3,
        "ours_motion_us": float(np.median(ours_ns[:, :in_motion])) / 1e3,
        "ours_step_us": float(np.median(step_ns)) / 1e3,
        "theirs_us": float(np.median(theirs_ns)) / 1e3,
        "ours_error_mm": ours_err,
        "theirs_error_mm": theirs_err,
    }
    result["ratio"] = result["theirs_us"] / result["ours_us"]
    if verbose:
        print(f"outer step at dt = {dt * 1e3:g} ms, median of {rounds} x {n_steps} steps:")
        print(
            f"  amex DMP               {result['ours_us']:7.2f} us "
            f"({result['ours_motion_us']:.2f} us while t < T_ref)"
        )
        print(f"  amex DMP.step(obs)     {result['ours_step_us']:7.2f} us")
        print(f"  movement_primitives    {result['theirs_us']:7.2f} us")
        print(f"  ratio theirs / ours    {result['ratio']:7.2f}")
        print("reproduction error, max TCP position error over [0, T_ref] [mm]:")
        print("  dt [ms]   amex DMP   movement_primitives (rk4)")
        for step in DTS:
            print(f"  {step * 1e3:7g}   {ours_err[step]:8.4f}   {theirs_err[step]:8.4f}")
    return result


if __name__ == "__main__":
    compare_with_movement_primitives()
