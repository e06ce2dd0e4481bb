"""Fault injection, method answers: a malformed command or a method's own exception ends that
episode with a recorded reason; nothing reads out of bounds and the next episode runs."""

import numpy as np
import pytest

from amex.core.types import Command, command_problem
from amex.experiment.config import RunConfig
from amex.experiment.runner import prepare
from amex.methods import Method, MethodConfig
from amex.sim.episode import run_episode
from amex.sim.scenario import make_scenario

N = 7  # the Panda's joints


class _Answers(Method):
    """A method whose answer (or exception) is given: stands in for a broken plugin."""

    name = "answers"
    config_class = MethodConfig

    def __init__(self, answer):
        self.answer = answer

    @classmethod
    def from_plan(cls, plan, config, dt, robot=None):  # pragma: no cover - built directly
        raise NotImplementedError

    def reset(self, obs):
        pass

    def step(self, obs):
        if isinstance(self.answer, BaseException):
            raise self.answer
        return self.answer


@pytest.fixture(scope="module")
def world():
    config = RunConfig(task=1, max_time=0.2)
    ctx = prepare(config)
    scenario = make_scenario(config.scene(), 1, 0, 0, ctx.plan.y[0, :3], ctx.plan.duration)
    return config, ctx, scenario


def _episode(world, answer):
    config, ctx, scenario = world
    return run_episode(ctx.robot, _Answers(answer), scenario, config.gains(), config.loop)


BAD = {
    "3 joints on a 7-joint arm": (Command(q=np.zeros(3)), "q of shape (3,); valid: shape (7,)"),
    "an empty y": (Command(y=np.zeros(0)), "y of shape (0,); valid: shape (6,)"),
    "a (6, 1) y": (Command(y=np.zeros((6, 1))), "y of shape (6, 1)"),
    "a list": (Command(y=[0.0] * 6), "y of type list"),
    "integers": (Command(q=np.zeros(N, dtype=int)), "q of type ndarray"),
    "None": (None, "NoneType instead of a Command"),
    "a tuple": ((np.zeros(6), np.zeros(6)), "tuple instead of a Command"),
    "a velocity alone": (Command(yd=np.zeros(6)), "a velocity target without its position"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_a_malformed_command_ends_the_episode_naming_what_is_wrong(world, case):
    answer, why = BAD[case]
    result = _episode(world, answer)
    assert result.failure.startswith("bad_command: ") and why in result.failure
    assert not result.success and result.final_time == 0.0


@pytest.mark.parametrize(
    "error", [ValueError("bad value"), ZeroDivisionError("division by zero"), SystemExit(0)]
)
def test_a_method_that_raises_ends_its_episode_not_the_run(world, error):
    result = _episode(world, error)
    assert result.failure.startswith(f"method: {type(error).__name__}")
    again = _episode(world, Command(y=world[1].plan.y[-1].copy(), yd=np.zeros(6)))
    assert again.failure == ""  # the next episode runs as usual


def test_the_check_accepts_every_valid_form():
    assert command_problem(Command(), N) == ""
    assert command_problem(Command(y=np.zeros(6), yd=np.zeros(6)), N) == ""
    assert command_problem(Command(q=np.zeros(N), qd=np.zeros(N)), N) == ""
    assert command_problem(Command(y=np.zeros(6), q=np.zeros(N)), N) == ""
