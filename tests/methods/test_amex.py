"""AMEX (Algorithm 1, Eq. 7-9): invariants, ideal execution, phase adaptation and the guards."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from amex.core.errors import ConfigError
from amex.core.types import Command
from amex.methods.amex import AMEX, AMEXConfig
from amex.methods.base import Observation
from amex.plan.reference import ReferencePlan

T_REF, DT, N = 4.0, 0.01, 400
PROPERTY = settings(derandomize=True, max_examples=25, deadline=None)


def arc(n_samples: int = N + 1) -> np.ndarray:
    """A rest-to-rest 2-D arc from (0, 0) to (1, 0), minimum-jerk timing, shape (n, 2)."""
    p = np.linspace(0.0, 1.0, n_samples)
    u = 10 * p**3 - 15 * p**4 + 6 * p**5
    return np.stack([0.5 - 0.5 * np.cos(np.pi * u), 0.6 * np.sin(np.pi * u)], axis=1)


def random_reference(seed: int, n_samples: int = 101, m: int = 2) -> np.ndarray:
    """A smooth random rest-to-rest curve: straight start-goal line plus a few sine bumps."""
    rng = np.random.default_rng(seed)
    p = np.linspace(0.0, 1.0, n_samples)[:, None]
    u = 10 * p**3 - 15 * p**4 + 6 * p**5
    bumps = sum(rng.normal(0, 0.3, m) * np.sin(k * np.pi * u) for k in (1, 2, 3))
    return rng.normal(size=m) + u * rng.normal(size=m) + bumps


def make(Y, duration=T_REF, dt=DT, **params) -> AMEX:
    """AMEX on the path Y over ``duration`` [s] with AMEXConfig(**params), outer period dt."""
    return AMEX(ReferencePlan.from_path(Y, duration), AMEXConfig(**params), dt)


def run(amex, goal_at, y0, n_steps, execute=lambda y, y_star, k: y_star, check=None):
    """Drive AMEX for n_steps; return the targets and the measured states fed to each update."""
    amex.restart()
    y = np.array(y0, dtype=float)
    targets, states = [], []
    for k in range(n_steps):
        g = goal_at(k)
        target = amex.update(y, g)
        if check is not None:
            check(amex, y, g, target)
        targets.append(target)
        states.append(y.copy())
        y = execute(y, target.y_star, k)
    return targets, np.array(states)


def test_perfect_execution_reproduces_the_reference_exactly():
    """Fixed goal, y <- y*: s advances by exactly Delta s_ref, y_k = tau_hat_ref(k dt)."""
    Y = arc()
    amex = make(Y, end_fraction=0.0)
    targets, states = run(amex, lambda k: Y[-1], Y[0], N + 1)
    s = np.array([t.s for t in targets])
    np.testing.assert_allclose(s, np.arange(N + 1) * amex.ds_ref, atol=1e-12)
    np.testing.assert_allclose(np.diff(s), amex.ds_ref, rtol=1e-10)
    np.testing.assert_allclose(states, Y, atol=1e-12)
    np.testing.assert_allclose([t.delta_g for t in targets[3:-1]], 1.0, atol=1e-9)
    np.testing.assert_allclose([t.delta_y for t in targets[1:]], 1.0, atol=1e-9)
    assert amex.final_approach and targets[-1].s == 1.0


def test_default_end_guard_changes_only_the_last_steps():
    """end_fraction = 1e-4: identical until the reference is within 1e-4 of its goal, then the
    final approach; the robot still ends at the goal."""
    Y = arc()
    amex = make(Y)
    targets, states = run(amex, lambda k: Y[-1], Y[0], 2 * N)
    s = np.array([t.s for t in targets])
    arrived = np.linalg.norm(Y - Y[-1], axis=1) <= 1e-4 * np.linalg.norm(Y[-1] - Y[0])
    k_end = int(np.argmax(arrived))  # the first sample within the guard's distance
    assert N - 10 < k_end < N
    np.testing.assert_allclose(states[:k_end], Y[:k_end], atol=1e-12)
    np.testing.assert_allclose(s[:k_end], np.arange(k_end) * amex.ds_ref, atol=1e-12)
    assert np.all(s[k_end:] == 1.0)
    assert np.linalg.norm(states[-1] - Y[-1]) < 1e-9


def test_noisy_measurements_do_not_stall_the_phase():
    """10 um measurement noise: the phase still reaches 1 and the robot stays near the goal."""
    Y = arc()
    amex = make(Y)
    noise = np.random.default_rng(3).normal(0.0, 1e-5, (2 * N, 2))
    targets, states = run(
        amex, lambda k: Y[-1], Y[0], 2 * N, execute=lambda y, ys, k: ys + noise[k]
    )
    assert targets[N + 10].s == 1.0
    assert np.max(np.linalg.norm(states[N + 10 :] - Y[-1], axis=1)) < 2e-4


def test_tangent_form_follows_the_reference_to_first_order():
    """eq9="tangent" (Eq. 9 as written): O(Delta s^2) per step, a few mm on a unit-size arc."""
    Y = arc()
    amex = make(Y, eq9="tangent")
    targets, states = run(amex, lambda k: Y[-1], Y[0], N + 1)
    s = np.array([t.s for t in targets])
    assert np.max(np.abs(states - Y)) < 5e-3
    assert np.all(np.abs(np.diff(s[:300]) / amex.ds_ref - 1.0) < 0.15)


def test_velocity_target_is_the_step_per_second():
    Y = arc()
    amex = make(Y)
    targets, states = run(amex, lambda k: Y[-1] + 0.1, Y[0], 150)
    for target, y in zip(targets, states, strict=True):
        np.testing.assert_allclose(target.yd_star, (target.y_star - y) / DT, atol=1e-12)
    # mid-motion, with the goal at g_ref, the speed is the reference's: ||tau_ref'(s)|| / T_ref
    amex.restart()
    y = Y[0]
    for _ in range(200):
        target = amex.update(y, Y[-1])
        y = target.y_star
    speed = np.linalg.norm(amex.reference.derivative(target.s + amex.ds_ref / 2)) / T_REF
    assert np.linalg.norm(target.yd_star) == pytest.approx(speed, rel=1e-4)


@PROPERTY
@given(
    seed=st.integers(0, 10**6),
    eq9=st.sampled_from(["secant", "tangent"]),
    tracking=st.floats(0.3, 1.2),
)
def test_warp_invariants_hold_after_every_update(seed, eq9, tracking):
    """tau_plan(s) = y and tau_plan(1) = g to 1e-9 after every update, for random references,
    moving goals and imperfect execution; s never decreases and its step stays bounded."""
    rng = np.random.default_rng(seed)
    Y = random_reference(seed)
    amex = make(Y, 1.0, 0.01, eq9=eq9)
    goal_velocity = rng.normal(0.0, 0.5, 2)
    offset = rng.normal(0.0, 0.3, 2)
    noise = rng.normal(0.0, 1e-3, (400, 2))
    phases = []

    def check(amex, y, g, target):
        assert np.all(np.isfinite(target.y_star)) and np.all(np.isfinite(target.yd_star))
        if target.s < 1.0:
            np.testing.assert_allclose(amex.plan(target.s), y, rtol=0, atol=1e-9)
            np.testing.assert_allclose(amex.plan.end, g, rtol=0, atol=1e-9)
        phases.append(target.s)

    run(
        amex,
        lambda k: Y[-1] + offset + goal_velocity * min(k, 70) * 0.01,
        Y[0] + noise[0],
        400,
        execute=lambda y, y_star, k: y + tracking * (y_star - y) + noise[k],
        check=check,
    )
    steps = np.diff(phases)
    assert np.all(steps >= 0.0)
    assert np.all(steps <= amex.rate_max * amex.ds_ref + 1e-15)


def test_initial_goal_offset_enters_the_plan():
    """Fig. 2a: a goal offset before the start is in the plan from the first update on."""
    Y = arc()
    amex = make(Y)
    g = Y[-1] + np.array([0.3, 0.4])
    amex.update(Y[0], g)
    np.testing.assert_allclose(amex.plan.end, g, atol=1e-12)
    np.testing.assert_allclose(amex.plan(0.0), Y[0], atol=1e-12)


@pytest.mark.parametrize(("direction", "faster"), [(1.0, False), (-1.0, True)])
def test_goal_motion_scales_the_phase(direction, faster):
    """A goal moving away from the robot gives delta_g < 1 and a slower phase; towards: > 1."""
    Y = arc()
    amex = make(Y)
    away = np.array([1.0, 0.0]) * direction  # the goal (1, 0) is to the +x of the start (0, 0)
    targets, _ = run(amex, lambda k: Y[-1] + away * 0.2 * k * DT, Y[0], 200)
    delta_g = np.array([t.delta_g for t in targets[3:]])
    phase_steps = np.diff([t.s for t in targets[3:]]) / amex.ds_ref
    if faster:
        assert np.all(delta_g > 1.0) and np.all(phase_steps > 1.0)
    else:
        assert np.all(delta_g < 1.0) and np.all(phase_steps < 1.0)


def test_lagging_robot_slows_the_phase():
    Y = arc()
    amex = make(Y)
    targets, _ = run(amex, lambda k: Y[-1], Y[0], 200, execute=lambda y, ys, k: y + 0.5 * (ys - y))
    delta_y = np.array([t.delta_y for t in targets[10:]])
    assert np.all(delta_y < 0.6)
    assert targets[-1].s < 200 * amex.ds_ref * 0.8


def test_guard_goal_at_the_robot():
    """g = y: Eq. 8 would divide by 0; delta_g := rate_max, outputs finite, no motion."""
    Y = arc()
    amex = make(Y)
    for _ in range(5):
        target = amex.update(Y[0], Y[0])
        assert np.all(np.isfinite(target.y_star)) and np.all(np.isfinite(target.yd_star))
        np.testing.assert_array_equal(target.y_star, Y[0])
    assert target.delta_g == amex.rate_max


def test_guard_robot_does_not_move():
    """y = y_prev every step: delta_y = 0 stalls the phase after the warm-up, outputs finite."""
    Y = arc()
    amex = make(Y)
    targets, _ = run(amex, lambda k: Y[-1], Y[0], 50, execute=lambda y, ys, k: y)
    assert all(np.all(np.isfinite(t.y_star)) for t in targets)
    assert [t.s for t in targets[2:]] == [2 * amex.ds_ref] * 48
    assert all(t.delta_y == 0.0 for t in targets[3:])


def test_guard_zero_commanded_step():
    """A reference at rest for its first half: those commanded steps are 0, delta_y := 1, no NaN."""
    u = np.clip(np.linspace(-1.0, 1.0, N + 1), 0.0, None)[:, None]
    Y = np.hstack([u**3, 0.5 * u**3])  # rest, then a smooth start
    amex = make(Y)
    targets, _ = run(amex, lambda k: Y[-1], Y[0], 60)
    resting = [t for t in targets if t.s < 0.4]
    assert len(resting) > 30
    for t in resting:
        assert t.delta_y == 1.0
        assert np.all(np.isfinite(t.y_star)) and np.all(np.isfinite(t.yd_star))


def test_reference_that_does_not_move_is_rejected():
    """Start = end: Eq. 8's delta_g would be 0 for ever and AMEX would never move."""
    with pytest.raises(ConfigError, match="must move"):
        make(np.ones((N + 1, 2)))


def test_reference_that_barely_moves_is_rejected():
    """0.1 mm from start to goal (a reference goal at the start TCP): refused, not run."""
    Y = 1e-4 * arc()
    with pytest.raises(ConfigError, match=r"must move: its start and goal are 0.0001 apart"):
        make(Y)
    make(0.02 * arc())  # 2 cm moves


def test_guard_phase_near_one_and_final_approach():
    """A goal jump towards the robot drives s to 1 fast (bounded by rate_max); the final
    approach then moves to the goal at most at the reference's peak speed and converges."""
    Y = arc()
    amex = make(Y, rate_max=50.0, end_margin=1e-3)
    g = Y[-1].copy()
    targets, states = run(amex, lambda k: g if k < 3 else Y[0] + 1e-4, Y[0], 600)
    s = np.array([t.s for t in targets])
    assert np.all(np.diff(s) >= 0.0) and s[-1] == 1.0
    assert all(np.all(np.isfinite(t.y_star)) for t in targets)
    final = [t for t in targets if t.s == 1.0]
    assert len(final) > 10
    assert max(np.linalg.norm(t.yd_star) for t in final) <= amex.peak_speed * (1 + 1e-12)
    assert np.linalg.norm(states[-1] - (Y[0] + 1e-4)) < 1e-6


def test_phase_close_to_one_keeps_the_invariants():
    """Eq. 7 at 1 - s = 1.5e-6 (just above end_margin) stays exact to 1e-9."""
    Y = arc()
    ds = (1.0 - 1.5e-6) / N  # with an endless warm-up, s = k ds: update N lands next to 1
    amex = make(Y, dt=T_REF * ds, warmup_steps=10**6, end_fraction=0.0)
    rng = np.random.default_rng(1)
    for k in range(N + 1):
        y, g = amex.reference(k * ds) + rng.normal(0, 1e-3, 2), Y[-1] + rng.normal(0, 1e-2, 2)
        target = amex.update(y, g)
        np.testing.assert_allclose(amex.plan(target.s), y, rtol=0, atol=1e-9)
        np.testing.assert_allclose(amex.plan.end, g, rtol=0, atol=1e-9)
    assert 1.0 - target.s == pytest.approx(1.5e-6, rel=1e-6)
    assert np.all(np.isfinite(target.y_star)) and np.all(np.isfinite(target.yd_star))


def test_reference_is_the_reparametrized_samples():
    """tau_ref(s) = tau_hat_ref(s T_ref) at the samples (interpolating spline, the default)."""
    Y = arc()
    amex = make(Y)
    np.testing.assert_allclose(amex.reference(np.arange(N + 1) / N), Y, atol=1e-12)
    assert amex.fit_error < 1e-12
    assert make(Y, n_control=51).fit_error < 2e-5


def test_method_api_in_six_dimensions():
    rng = np.random.default_rng(0)
    Y6 = np.hstack([arc(), 0.1 * arc(), np.tile([0.0, 0.0, -1.0], (N + 1, 1))[:, :2]])
    plan = ReferencePlan(q=np.zeros((N + 1, 7)), y=Y6, dt=T_REF / N)
    config = AMEXConfig(rate_max=4.0)
    amex = AMEX(plan, config, DT)
    assert amex.name == "amex" and AMEX.config_class is AMEXConfig
    assert amex.rate_max == 4.0
    zeros = np.zeros(7)
    obs = Observation(0.0, zeros, zeros, Y6[0], np.zeros(6), Y6[-1] + rng.normal(0, 0.01, 6))
    amex.reset(obs)
    for k in range(20):
        command = amex.step(obs)
        assert isinstance(command, Command) and command.y.shape == (6,)
        assert command.yd.shape == (6,)
        obs = Observation(k * DT, zeros, zeros, command.y, command.yd, obs.goal)
    info = amex.internals()
    assert set(info) == {"s", "delta_g", "delta_y", "y_star", "yd_star"}
    assert info["s"] == pytest.approx(19 * amex.ds_ref, rel=0.3)


def test_config_defaults_and_validation():
    config = AMEXConfig()
    assert config.name == "amex"
    assert (config.pos.kp, config.pos.kd, config.pos.weight) == (1.0, 100.0, 1.0)
    assert (config.dir.kp, config.dir.kd, config.dir.weight) == (1.0, 100.0, 0.5)
    Y = arc(11)
    with pytest.raises(TypeError, match="bogus"):
        AMEXConfig(bogus=1)
    with pytest.raises(ConfigError, match=r"method.eq9='midpoint'; valid: secant, tangent"):
        make(Y, eq9="midpoint")
    with pytest.raises(ConfigError, match="rate_min"):
        make(Y, rate_min=2.0, rate_max=1.0)
    with pytest.raises(ConfigError, match=r"n_control=12; valid: 0 or 3..11"):
        make(Y, n_control=12)
    with pytest.raises(ConfigError, match="dt"):
        make(Y, dt=0.0)
    with pytest.raises(ConfigError, match="dt"):
        make(Y, dt=2 * T_REF)  # longer than the reference
    with pytest.raises(ConfigError, match="shape"):
        AMEX(ReferencePlan(q=np.zeros((5, 0)), y=np.zeros(5), dt=DT))
    bad = Y.copy()
    bad[3, 0] = np.nan
    with pytest.raises(ConfigError, match="finite samples"):
        AMEX(ReferencePlan(q=np.zeros((11, 0)), y=bad, dt=DT))
    with pytest.raises(ConfigError, match="path shape"):
        ReferencePlan.from_path(bad, T_REF)
