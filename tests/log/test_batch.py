"""A batch's ``/command`` messages: each command's parts, whatever its shape (amex.log.batch)."""

from types import SimpleNamespace

import numpy as np
import pytest

from amex.core.types import Command
from amex.log import flat_proto as P
from amex.log.batch import StepBatch
from amex.sim.loop import StepRecord

N, M = 7, 6
_rng = np.random.default_rng(3)


def _v(k):
    return _rng.normal(size=k)


COMMANDS = {
    "task": Command.task(_v(M), _v(M)),
    "joint": Command.joint(_v(N), _v(N)),
    "both": Command(_v(M), _v(M), _v(N), _v(N)),
    "y only": Command(y=_v(M)),
    "y and q_dot": Command(y=_v(M), qd=_v(N)),
    "empty": Command(),
    "short y": Command.task(_v(M - 1), _v(M)),  # another shape: packed when kept
    "long q": Command.joint(_v(N), _v(N + 2)),
    "task of zeros": Command.task(np.zeros(M), -np.zeros(M)),
    "pair": (_v(M), _v(M)),  # a plain tuple of two parts
}


def _step(t, command):
    state = SimpleNamespace(q=_v(N), v=_v(N))
    goal = np.concatenate([_v(3), [0.0, 0.0, -1.0]])
    obs = SimpleNamespace(y=_v(M), yd=_v(M), goal=goal, obstacles=np.zeros((0, 3)))
    return StepRecord(t, state, obs, command, {}, _v(N), _v(N))


def _decoded(data):
    decoder = P.FlatDecoder(P.COMMAND.descriptor_set(), P.COMMAND.name)
    return decoder.decode(data)


@pytest.mark.parametrize("order", ["as listed", "reversed"])
def test_each_command_is_written_with_its_parts_whatever_its_shape(order):
    names = list(COMMANDS) if order == "as listed" else list(reversed(COMMANDS))
    batch = StepBatch(len(names) + 2, N, M, None)
    for i, name in enumerate(names):
        batch.add(_step(0.01 * (i + 1), COMMANDS[name]), {}, None)
    k, kept = batch.fill(), batch.kept
    encoded = batch.encode(k)
    for i, name in enumerate(names):
        a, b, c, d = encoded.numbers[i]
        data = encoded.data[c:d] if kept[i].command is None else kept[i].command
        message = _decoded(data)
        assert message["t"] == 0.01 * (i + 1), name
        parts = tuple(COMMANDS[name]) + (None,) * (4 - len(COMMANDS[name]))
        for field, part in zip(("y_star", "yd_star", "q_star", "qd_star"), parts, strict=True):
            got = message[field]
            if part is None:
                assert got is None, (name, field)
            else:  # every double's bits (-0.0 too)
                assert np.array(got).tobytes() == np.asarray(part, float).tobytes(), (name, field)
        # the rows hold the step's own values, stacked at fill
        assert batch.t[i] == 0.01 * (i + 1)


def test_a_kept_command_is_copied_so_a_reused_buffer_changes_no_row():
    y, yd = _v(M), _v(M)
    batch = StepBatch(4, N, M, None)
    batch.add(_step(0.01, Command.task(y, yd)), {}, None)
    first = (y.copy(), yd.copy())
    y[:] = 7.0  # the method reuses its buffers
    yd[:] = 8.0
    batch.add(_step(0.02, Command.task(y, yd)), {}, None)
    k = batch.fill()
    encoded = batch.encode(k)
    messages = [_decoded(encoded.data[c:d]) for _, _, c, d in encoded.numbers]
    assert messages[0]["y_star"] == first[0].tolist()
    assert messages[0]["yd_star"] == first[1].tolist()
    assert messages[1]["y_star"] == [7.0] * M and messages[1]["yd_star"] == [8.0] * M


def test_the_rows_hold_each_steps_values_bit_for_bit():
    batch = StepBatch(4, N, M, None)
    steps = [_step(0.01 * (j + 1), COMMANDS["task"]) for j in range(3)]
    steps[1] = steps[1]._replace(tau=np.full(N, 0.1, dtype=np.float32))  # another dtype: doubles
    steps[2] = steps[2]._replace(qacc=np.array([-0.0, np.nan, np.inf, 1e-320, 1.0, 2.0, 3.0]))
    for step in steps:
        batch.add(step, {}, None)
    k = batch.fill()
    assert k == 3
    for j, step in enumerate(steps):
        for rows, value in ((batch.q, step.state.q), (batch.v, step.state.v),
                            (batch.qacc, step.qacc), (batch.tau, step.tau),
                            (batch.y, step.observation.y), (batch.yd, step.observation.yd),
                            (batch.goal, step.observation.goal[:3])):  # fmt: skip
            assert rows[j].tobytes() == np.asarray(value, dtype=float).tobytes()
