"""``run``'s ``ready`` hook: called once, set-up done, before the first episode (amex-run freezes
the heap there, :func:`amex.app.heap.settle`)."""

import sys

from amex.experiment.config import RunConfig
from amex.experiment.runner import run
from amex.methods import METHODS


def _config(**changes) -> RunConfig:
    config = RunConfig(task=1, episodes=2, max_time=0.2, **changes)
    config.method = METHODS["dmp"].config_class()
    return config


def test_ready_comes_once_after_the_set_up_and_before_the_episodes(tmp_path):
    events = []

    def ready():
        events.append(("ready", "amex.log.writer" in sys.modules))

    run(_config(log="full"), tmp_path / "run", lambda env, r: events.append(env), ready)
    assert events == [("ready", True), 0, 1]  # the log's modules are part of the set-up
    events.clear()
    run(_config(log="full"), tmp_path / "run", lambda env, r: events.append(env), ready)
    assert events == [0, 1, ("ready", True)]  # resumed: nothing to set up, still called once

