import numpy as np
import pytest

from amex.core.errors import ConfigError
from amex.sim.perception import ConstantVelocityKF, GoalSensor, PerceptionConfig, PredictionConfig


def _moving(t):
    return np.array([0.4, 0.1, 0.5]) + np.array([0.03, -0.02, 0.01]) * t


def test_kalman_filter_recovers_position_and_velocity_from_noisy_measurements():
    rng = np.random.default_rng(0)
    kf = ConstantVelocityKF(accel_std=0.01, measurement_std=0.005)
    for k in range(200):
        t = 0.05 * k
        kf.update(t, _moving(t) + rng.normal(0, 0.005, 3))
    assert np.abs(kf.x[1] - [0.03, -0.02, 0.01]).max() < 0.005
    assert np.linalg.norm(kf.predict(10.5) - _moving(10.5)) < 0.004


def test_exact_perception_returns_the_true_goal():
    sensor = GoalSensor(_moving, PerceptionConfig(), PredictionConfig(), np.random.default_rng(0))
    assert np.array_equal(sensor.measure(1.3), _moving(1.3))


def test_latency_delays_and_prediction_compensates_it():
    perception = PerceptionConfig(noise_std=0.0, latency=0.2)
    late = GoalSensor(_moving, perception, PredictionConfig(), np.random.default_rng(0))
    assert np.allclose(late.measure(2.0), _moving(1.8))
    predicted = GoalSensor(
        _moving,
        perception,
        PredictionConfig(enabled=True, accel_std=0.01),
        np.random.default_rng(0),
    )
    for k in range(60):
        estimate = predicted.measure(0.05 * k)
    assert np.linalg.norm(estimate - _moving(0.05 * 59)) < 1e-3


def test_preview_is_an_oracle_that_sees_the_goal_ahead():
    ahead = GoalSensor(
        _moving, PerceptionConfig(preview=0.5), PredictionConfig(), np.random.default_rng(0)
    )
    assert np.array_equal(ahead.measure(1.0), _moving(1.5))
    both = GoalSensor(
        _moving,
        PerceptionConfig(latency=0.2, preview=0.5),
        PredictionConfig(),
        np.random.default_rng(0),
    )
    assert np.allclose(both.measure(1.0), _moving(1.3))
    assert not PerceptionConfig(preview=0.5).exact


def test_noise_is_seeded_and_has_the_configured_size():
    perception = PerceptionConfig(noise_std=0.005)
    a = GoalSensor(_moving, perception, PredictionConfig(), np.random.default_rng(3))
    b = GoalSensor(_moving, perception, PredictionConfig(), np.random.default_rng(3))
    first = [a.measure(0.1 * k) for k in range(5)]
    assert all(np.array_equal(x, b.measure(0.1 * k)) for k, x in enumerate(first))
    errors = np.array([a.measure(0.0) - _moving(0.0) for _ in range(2000)])
    assert errors.std() == pytest.approx(0.005, rel=0.1)


@pytest.mark.parametrize(
    ("config", "match"),
    [
        (PerceptionConfig(noise_std=-1.0), "perception.noise_std"),
        (PerceptionConfig(latency=-0.1), "perception.latency"),
        (PerceptionConfig(preview=-1.0), "perception.preview"),
        (PerceptionConfig(preview=float("inf")), "perception.preview"),
        (PredictionConfig(accel_std=0.0), "prediction.accel_std"),
    ],
)
def test_invalid_perception_settings_are_rejected(config, match):
    with pytest.raises(ConfigError, match=match):
        config.validate()
