"""Quadratic B-splines over the phase: evaluation, fitting, and the exact Eq. 7 warp."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.interpolate import BSpline

from amex.core.errors import ConfigError
from amex.plan.spline import QuadraticBSpline, WarpedSpline, max_sample_error

PROPERTY = settings(derandomize=True, max_examples=60, deadline=None)


def random_spline(seed: int, n: int = 12, m: int = 3) -> QuadraticBSpline:
    rng = np.random.default_rng(seed)
    interior = np.sort(rng.uniform(0.02, 0.98, n - 3))
    interior += np.arange(n - 3) * 1e-6  # strictly increasing
    knots = np.concatenate([np.zeros(3), interior, np.ones(3)])
    return QuadraticBSpline(knots, rng.normal(size=(n, m)))


def min_jerk_samples(n_samples: int = 401) -> np.ndarray:
    p = np.linspace(0.0, 1.0, n_samples)
    u = 10 * p**3 - 15 * p**4 + 6 * p**5
    return np.stack([0.5 - 0.5 * np.cos(np.pi * u), 0.6 * np.sin(np.pi * u), 0.2 * u], axis=1)


@pytest.mark.parametrize("seed", range(5))
def test_evaluation_matches_scipy_bspline(seed):
    spline = random_spline(seed)
    reference = BSpline(spline.knots, spline.control_points, 2)
    s = np.concatenate([np.random.default_rng(seed).random(200), [0.0, 1.0], spline.knots[3:-3]])
    np.testing.assert_allclose(spline(s), reference(s), atol=1e-12)
    np.testing.assert_allclose(spline.derivative(s), reference.derivative()(s), atol=1e-10)


@pytest.mark.parametrize("seed", range(5))
def test_derivative_matches_finite_differences(seed):
    spline = random_spline(seed)
    h = 1e-6
    for s in np.random.default_rng(100 + seed).uniform(h, 1 - h, 20):
        fd = (spline(s + h) - spline(s - h)) / (2 * h)
        np.testing.assert_allclose(spline.derivative(s), fd, atol=1e-5)


def test_single_point_evaluation_matches_vectorized():
    spline = random_spline(3)
    for s in (0.0, 0.123, 0.5, 0.99, 1.0):
        value, derivative = spline.evaluate(s)
        np.testing.assert_allclose(value, spline(s), atol=1e-14)
        np.testing.assert_allclose(derivative, spline.derivative(s), atol=1e-14)
    np.testing.assert_allclose(spline(0.0), spline.control_points[0], atol=1e-15)
    np.testing.assert_allclose(spline(1.0), spline.control_points[-1], atol=1e-15)


@PROPERTY
@given(seed=st.integers(0, 10**6), s=st.floats(0.0, 1.0))
def test_partition_of_unity_and_affine_reproduction(seed, s):
    spline = random_spline(seed)
    i, b0, b1, b2, d0, d1, d2 = spline.weights(s)
    xi = spline.greville[i : i + 3]
    assert b0 + b1 + b2 == pytest.approx(1.0, abs=1e-14)
    assert d0 + d1 + d2 == pytest.approx(0.0, abs=1e-9)
    assert b0 * xi[0] + b1 * xi[1] + b2 * xi[2] == pytest.approx(s, abs=1e-14)
    assert d0 * xi[0] + d1 * xi[1] + d2 * xi[2] == pytest.approx(1.0, abs=1e-9)


@pytest.mark.parametrize("ds", [0.0025, 0.01, 0.2])
def test_max_index_shift_bounds_the_span_change(ds):
    spline = QuadraticBSpline.fit(min_jerk_samples(41))
    shift = spline.max_index_shift(ds)
    for s in np.linspace(0.0, 1.0 - ds, 997):
        assert spline.weights(min(s + ds, 1.0))[0] - spline.weights(s)[0] <= shift


def test_interpolation_reproduces_the_samples():
    """tau_ref(s) = tau_hat_ref(s T_ref) at the samples s = k / N (the reparametrization)."""
    Y = min_jerk_samples()
    spline = QuadraticBSpline.fit(Y)
    N = len(Y) - 1
    np.testing.assert_allclose(spline(np.arange(N + 1) / N), Y, atol=1e-12)
    assert max_sample_error(spline, Y) < 1e-12


def test_least_squares_fit_keeps_ends_and_converges():
    Y = min_jerk_samples()
    errors = []
    for n in (11, 21, 51, 101):
        spline = QuadraticBSpline.fit(Y, n)
        assert spline.n_control == n
        np.testing.assert_array_equal(spline.control_points[[0, -1]], Y[[0, -1]])
        np.testing.assert_allclose(spline([0.0, 1.0]), Y[[0, -1]], atol=1e-15)
        errors.append(max_sample_error(spline, Y))
    assert errors == sorted(errors, reverse=True)
    assert errors[2] < 2e-5  # 51 control points: < 20 um on a unit-size motion


def test_fit_rejects_bad_input():
    with pytest.raises(ConfigError, match="n_control"):
        QuadraticBSpline.fit(min_jerk_samples(11), 12)
    with pytest.raises(ConfigError, match="finite"):
        QuadraticBSpline.fit(np.full((5, 2), np.nan))
    with pytest.raises(ConfigError, match="knots"):
        QuadraticBSpline(np.array([0, 0, 0, 0.5, 0.5, 1, 1, 1.0]), np.zeros((5, 2)))


@PROPERTY
@given(
    seed=st.integers(0, 10**6),
    s=st.floats(0.0, 1.0 - 1e-6),
    scale=st.sampled_from([1e-6, 1e-2, 1.0, 10.0]),
)
def test_warp_is_eq7_exactly(seed, s, scale):
    """After warp(s, y - tau(s), g - tau(1)): tau(s) = y, tau(1) = g, and on [s, 1] the change
    is Eq. 7's affine function."""
    rng = np.random.default_rng(seed)
    spline = random_spline(seed)
    before = spline.copy()
    y = spline(s) + scale * rng.normal(size=3)
    g = spline(1.0) + scale * rng.normal(size=3)
    delta_y, delta_g = y - spline(s), g - spline(1.0)
    spline.warp(s, delta_y, delta_g)
    np.testing.assert_allclose(spline(s), y, atol=1e-9)
    np.testing.assert_allclose(spline(1.0), g, atol=1e-9)
    s_rest = np.linspace(s, 1.0, 17)
    eq7 = delta_g + np.outer((s_rest - 1.0) / (1.0 - s), delta_g - delta_y)
    np.testing.assert_allclose(spline(s_rest) - before(s_rest), eq7, atol=1e-9)


@PROPERTY
@given(seed=st.integers(0, 10**6))
def test_warped_spline_equals_repeated_control_point_warps(seed):
    rng = np.random.default_rng(seed)
    explicit = random_spline(seed, n=15, m=2)
    lazy = WarpedSpline(explicit.copy())
    s = 0.0
    for _ in range(30):
        s = min(s + rng.uniform(0.0, 0.1), 0.999)
        y = explicit(s) + 0.05 * rng.normal(size=2)
        g = explicit(1.0) + 0.05 * rng.normal(size=2)
        explicit.warp(s, y - explicit(s), g - explicit(1.0))
        lazy.warp(s, y - lazy(s), g - lazy.end)
        np.testing.assert_allclose(lazy(s), y, atol=1e-9)
        np.testing.assert_allclose(lazy.end, g, atol=1e-9)
        anchored = WarpedSpline(lazy.base)
        anchored.anchor(s, y, g)
        np.testing.assert_allclose(anchored.p, lazy.p, atol=1e-9)
        np.testing.assert_allclose(anchored.q, lazy.q, rtol=1e-9, atol=1e-9)
    grid = np.linspace(0.0, 1.0, 51)
    np.testing.assert_allclose(lazy(grid), explicit(grid), atol=1e-9)
    np.testing.assert_allclose(lazy.to_spline().control_points, explicit.control_points, atol=1e-9)
    np.testing.assert_allclose(lazy.derivative(grid), explicit.derivative(grid), atol=1e-7)


def test_warp_rejects_phase_one():
    with pytest.raises(ConfigError, match="1 - s"):
        random_spline(0).warp(1.0, np.zeros(3), np.zeros(3))
