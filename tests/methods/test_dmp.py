import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from amex.core.errors import ConfigError
from amex.core.types import Command
from amex.methods.base import Observation
from amex.methods.dmp import DMP, DMPConfig
from amex.methods.dmp_ps import DMPPhaseStop, DMPPSConfig
from amex.plan.reference import ReferencePlan
from analysis.bench_dmp import DT_REF, G_REF, T_REF, Y0, reference_at  # the shared reference

REFERENCE = reference_at(np.arange(401) * DT_REF)


def make(cls=None, reference=REFERENCE, dt=0.01, **params):
    """A DMP (or ``cls``) on ``reference`` over T_ref with its config's ``params``, period dt."""
    cls = DMP if cls is None else cls
    plan = ReferencePlan.from_path(reference, T_REF)
    return cls(plan, cls.config_class(**params), dt)


def rollout(dmp: DMP, dt: float, duration: float, goal=None) -> tuple[np.ndarray, np.ndarray]:
    """Times and positions (including t = 0) of an open-loop rollout with a fixed goal."""
    goal = dmp.g_ref if goal is None else goal
    n = round(duration / dt)
    ys = [dmp.y] + [dmp.update(goal, dt).y_star for _ in range(n)]
    return np.arange(n + 1) * dt, np.array(ys)


@pytest.mark.parametrize("dt", [0.001, 0.002, 0.005, 0.01, 0.02, 0.05])
def test_reproduces_reference_within_0_3_mm_at_every_control_period(dt):
    dmp = make(dt=dt)
    t, y = rollout(dmp, dt, T_REF)
    err = np.linalg.norm(y[:, :3] - reference_at(t)[:, :3], axis=1)
    assert err.max() < 0.3e-3
    assert np.abs(y - reference_at(t)).max() < 0.3e-3  # the axis components too


def test_rollout_is_the_continuous_dmp_whatever_the_step():
    """Goal switching every second: every dt lands on the exact solution of the DMP's ODE."""
    rng = np.random.default_rng(3)
    dmp = make(dt=0.01, amplitude="goal")
    goals = G_REF + rng.normal(0.0, 0.1, (5, 6))

    def rhs(t, s, g):
        y, v, x = s[:6], s[6:12], s[12]
        force = dmp.forcing(np.array([x]), g)[0]
        acc = (dmp.alpha_y * (dmp.beta_y * (g - y) - T_REF * v) + force) / T_REF**2
        return np.concatenate([v, acc, [-dmp.alpha_x * x / T_REF]])

    state = np.concatenate([REFERENCE[0], dmp.yd, [1.0]])
    exact = []
    for k, g in enumerate(goals):
        sol = solve_ivp(
            rhs,
            (k, k + 1.0),
            state,
            args=(g,),
            method="DOP853",
            rtol=1e-11,
            atol=1e-12,
            dense_output=True,
            max_step=0.005,
        )
        exact.append(sol.sol)
        state = sol.y[:, -1]
    for dt in (0.001, 0.01, 0.05):
        dmp.reset_state()
        worst = 0.0
        for k in range(round(5.0 / dt)):
            second = int(k * dt + 1e-9)
            target = dmp.update(goals[second], dt)
            t1 = (k + 1) * dt
            sol = exact[min(int(t1 - 1e-9), 4)](t1)
            worst = max(worst, np.abs(target.y_star - sol[:6]).max(), abs(target.x - sol[12]))
        assert worst < 1e-8


def test_phase_follows_eq1_exponential():
    dmp = make()
    xs = [dmp.update(dmp.g_ref, 0.01).x for _ in range(700)]
    t = np.arange(1, 701) * 0.01
    np.testing.assert_allclose(xs, np.exp(-dmp.alpha_x * t / T_REF), rtol=1e-12)
    assert dmp.internals() == {"phase": xs[-1], "phase_rate": 1.0}


@pytest.mark.parametrize("amplitude", ["trained", "goal"])
def test_goal_change_moves_endpoint_to_new_goal(amplitude):
    dmp = make(dt=0.01, amplitude=amplitude)
    first = G_REF + np.array([0.2, -0.1, 0.1, 0.0, 0.2, 0.0])
    final = G_REF + np.array([-0.1, 0.3, 0.2, -0.2, 0.1, 0.1])
    for k in range(1000):
        target = dmp.update(first if k < 200 else final, 0.01)
    assert np.abs(target.y_star - final).max() < 1e-3
    assert np.abs(target.yd_star).max() < 1e-2


def test_goal_mode_scales_the_shape_with_the_goal():
    dmp = make(dt=0.01, amplitude="goal", min_amplitude=0.05)
    goal = Y0 + 2.0 * (G_REF - Y0)  # every moving dimension twice as far
    goal[4] = 0.3  # a dimension that did not move in training: not rescaled
    _, y = rollout(dmp, 0.01, T_REF, goal)
    expected = Y0 + 2.0 * (REFERENCE - Y0)
    np.testing.assert_allclose(y[:, [0, 1, 3]], expected[:, [0, 1, 3]], atol=5e-5)


@pytest.mark.parametrize("amplitude", ["trained", "goal"])
def test_goal_at_start_gives_bounded_output(amplitude):
    s = np.linspace(0.0, 1.0, 401)
    loop = np.repeat(Y0[None], 401, axis=0)  # out and back: g_ref - y0 = 1e-13 in every dimension
    loop[:, :3] += 0.1 * np.sin(np.pi * s)[:, None] ** 2 * np.array([1.0, -0.5, 0.3])
    loop[-1] += 1e-13
    dmp = make(reference=loop, amplitude=amplitude)
    assert np.abs(dmp.weights).max() < 1e7  # peers' division by g - y0 gives 1e34 here
    _, y = rollout(dmp, 0.01, 8.0)
    assert np.all(np.isfinite(y))
    assert np.abs(y - Y0).max() < 0.2
    assert np.abs(y[-1] - loop[-1]).max() < 1e-3
    dmp = make(dt=0.01, amplitude=amplitude)  # now the goal is put on the start
    _, y = rollout(dmp, 0.01, 8.0, Y0)
    assert np.all(np.isfinite(y))
    assert np.abs(y - Y0).max() < 0.5
    assert np.abs(y[-1] - Y0).max() < 1e-3


@settings(max_examples=25, deadline=None)
@given(
    offset=st.lists(st.floats(-1.0, 1.0), min_size=6, max_size=6),
    amplitude=st.sampled_from(["trained", "goal"]),
)
def test_any_goal_gives_finite_output_that_converges_to_it(offset, amplitude):
    goal = G_REF + np.array(offset)
    dmp = make(dt=0.02, amplitude=amplitude)
    _, y = rollout(dmp, 0.02, 10.0, goal)
    assert np.all(np.isfinite(y))
    assert np.abs(y - goal).max() < 40.0 * (1.0 + np.abs(goal - Y0).max())
    assert np.abs(y[-1] - goal).max() < 1e-3


def test_phase_stopping_slows_phase_under_tracking_error():
    plain = make()
    stopping = make(DMPPhaseStop, beta_ps=1e3)
    stuck = REFERENCE[0].copy()  # the robot does not move
    for _ in range(150):
        p = plain.update(plain.g_ref, 0.01)
        q = stopping.update(stopping.g_ref, 0.01, stuck)
    lag = np.sum((stopping.y - stuck) ** 2)
    assert q.x > p.x
    assert stopping.internals()["phase_rate"] < 1.0
    assert stopping.phase_rate(stuck) == pytest.approx(1.0 / (1.0 + 1e3 * lag))


def test_phase_stopping_equals_plain_dmp_when_tracking_exactly():
    plain = make()
    stopping = make(DMPPhaseStop, beta_ps=1e3)
    robot = stopping.y
    for _ in range(500):
        p = plain.update(plain.g_ref, 0.01)
        q = stopping.update(stopping.g_ref, 0.01, robot)
        robot = q.y_star  # the robot is exactly at the last command
        assert q.x == p.x
        np.testing.assert_array_equal(q.y_star, p.y_star)


def test_phase_stopping_slowed_phase_is_eq2_exponential():
    dmp = make(DMPPhaseStop, beta_ps=1e3)
    u = 0.0
    for k in range(300):
        y = REFERENCE[0] + 0.01 * math.sin(k / 10.0)
        rate = dmp.phase_rate(y)
        target = dmp.update(dmp.g_ref, 0.01, y)
        u += rate * 0.01
        assert target.x == pytest.approx(math.exp(-dmp.alpha_x * u / T_REF), rel=1e-12)


def make_plan() -> ReferencePlan:
    return ReferencePlan(q=np.zeros((401, 7)), y=REFERENCE.copy(), dt=DT_REF)


def observation(t: float, y: np.ndarray, goal: np.ndarray) -> Observation:
    return Observation(t=t, q=np.zeros(7), qd=np.zeros(7), y=y, yd=np.zeros(6), goal=goal)


@pytest.mark.parametrize(("cls", "config"), [(DMP, DMPConfig()), (DMPPhaseStop, DMPPSConfig())])
def test_built_on_a_plan_each_step_follows_it(cls, config):
    method = cls(make_plan(), config, 0.01)
    assert method.name == config.name
    assert cls.config_class is type(config)
    method.reset(observation(0.0, REFERENCE[0], G_REF))
    for k in range(400):
        cmd = method.step(observation(k * 0.01, REFERENCE[k], G_REF))
        assert isinstance(cmd, Command)
        assert cmd.y.shape == (6,)
        assert cmd.yd.shape == (6,)
        assert np.abs(cmd.y - REFERENCE[k + 1]).max() < 0.3e-3
    assert 0.0 < method.internals()["phase"] < 1e-3


def test_step_takes_only_the_goal_from_the_observation():
    method = DMP(make_plan(), DMPConfig(), 0.01)
    twin = DMP(make_plan())
    method.reset(observation(0.0, REFERENCE[0], G_REF))
    twin.reset_state(REFERENCE[0], np.zeros(6))
    goal = G_REF + 0.1
    for k in range(50):
        far = REFERENCE[0] + 0.3  # the measured robot state does not enter the plain DMP
        cmd = method.step(observation(k * 0.01, far, goal))
        np.testing.assert_array_equal(cmd.y, twin.update(goal, 0.01).y_star)


def test_the_config_parameters_reach_the_method():
    config = DMPPSConfig(beta_ps=50.0, n_basis=40, amplitude="goal")
    method = DMPPhaseStop(make_plan(), config, 0.02)
    assert (method.beta_ps, method.n_basis, method.amplitude_mode, method.dt) == (
        50.0,
        40,
        "goal",
        0.02,
    )


def test_invalid_parameters_raise_config_error():
    with pytest.raises(ConfigError, match="amplitude='start'"):
        make(amplitude="start")
    with pytest.raises(ConfigError, match=r"method.n_basis=1; valid: an integer >= 2"):
        make(n_basis=1)
    with pytest.raises(ConfigError, match="dt=0.0"):
        make(dt=0.0)
    with pytest.raises(ConfigError, match="shape"):
        DMP(ReferencePlan(q=np.zeros((401, 0)), y=REFERENCE[:, 0], dt=DT_REF))
    with pytest.raises(ConfigError, match="beta_ps"):
        make(DMPPhaseStop, beta_ps=-1.0)
    with pytest.raises(ConfigError, match="DMPPhaseStop config DMPConfig.*missing: beta_ps"):
        DMPPhaseStop(make_plan(), DMPConfig())
