"""Configuration hashes: what makes runs resumable and comparable."""

from amex.experiment.config import RunConfig
from amex.experiment.store import config_hash, scene_hash
from amex.methods import METHODS


def _config(**perception):
    config = RunConfig(task=1)
    config.method = METHODS["track"].config_class()
    for key, value in perception.items():
        setattr(config.perception, key, value)
    return config


def test_an_added_option_at_its_neutral_value_hashes_as_if_it_did_not_exist():
    # Was: the default hashes equal two fixed strings. Since the hashes cover amex's source
    # (item 6 of issue 23), any edit of amex changes them, so a fixed value cannot be stable; what
    # stays is the promise behind it: a new option at its neutral value changes nothing.
    from amex.experiment.hashes import _digest, _spec

    spec = _spec(_config(), ())
    assert spec["perception"]["preview"] == 0.0
    perception = {k: v for k, v in spec["perception"].items() if k != "preview"}
    without = {**spec, "perception": perception}
    assert _digest(spec, "code") == _digest(without, "code")


def test_hashes_are_equal_for_equal_configurations_and_cheap():
    import time

    config_hash(_config())
    started = time.perf_counter()
    assert config_hash(_config()) == config_hash(_config())
    assert scene_hash(_config()) == scene_hash(_config())
    assert time.perf_counter() - started < 0.05  # the code digest is computed once per process


def test_an_added_option_is_hashed_once_it_changes_the_behaviour():
    base = _config()
    oracle = _config(preview=10.0)
    assert config_hash(oracle) != config_hash(base)
    assert scene_hash(oracle) != scene_hash(base)
    assert config_hash(_config(latency=0.05)) != config_hash(base)
