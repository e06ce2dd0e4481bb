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


def test_hashes_of_the_default_configuration_are_stable():
    # Adding an option at its neutral value must not orphan existing runs (perception.preview came
    # after 0.1.0 and left its hashes, 934d0b8a99a9897e / a7877efb9f4b0879, as they were). The
    # version is hashed: 0.2.0 has its own. Any other change here means recorded runs stop resuming.
    config = _config()
    assert config_hash(config) == "2cd32f0824c8a168"
    assert scene_hash(config) == "d0be30134f144153"


def test_an_added_option_is_hashed_once_it_changes_the_behaviour():
    base = _config()
    oracle = _config(preview=10.0)
    assert config_hash(oracle) != config_hash(base)
    assert scene_hash(oracle) != scene_hash(base)
    assert config_hash(_config(latency=0.05)) != config_hash(base)
