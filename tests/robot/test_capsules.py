"""Capsule fitting: the enclosing capsule of a point cloud (any arm's collision meshes)."""

from __future__ import annotations

import itertools

import numpy as np
import pinocchio as pin
import pytest
from scipy.spatial import ConvexHull

from amex.robot.capsules import (
    Capsule,
    capsule_volume,
    enclosing_circle,
    fit_capsule,
    segment_distances,
)


def _capsule(frame, radius, half) -> Capsule:
    return Capsule("fit", 0, frame, radius, half, fitted=True)


def _cylinder_points(rng, radius, half, n=4000):
    angle = rng.uniform(0, 2 * np.pi, n)
    z = rng.uniform(-half, half, n)
    return np.stack([radius * np.cos(angle), radius * np.sin(angle), z], axis=1)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_smallest_enclosing_circle_is_the_brute_force_one(seed):
    points = np.random.default_rng(seed).normal(size=(60, 2))
    centre, radius = enclosing_circle(points)
    assert np.linalg.norm(points - centre, axis=1).max() <= radius + 1e-9
    best = np.inf  # every circle through 2 or 3 of the points, the smallest that holds all
    for i, j in itertools.combinations(range(len(points)), 2):
        c = (points[i] + points[j]) / 2
        r = np.linalg.norm(points[i] - c)
        if np.linalg.norm(points - c, axis=1).max() <= r + 1e-9:
            best = min(best, r)
    assert radius <= best + 1e-9


def test_a_rotated_cylinders_points_give_back_its_capsule():
    rng = np.random.default_rng(0)
    local = _cylinder_points(rng, 0.05, 0.2)
    R = pin.rpy.rpyToMatrix(0.3, -0.7, 1.1)
    t = np.array([0.1, -0.2, 0.4])
    frame, radius, half = fit_capsule(local @ R.T + t)
    assert radius == pytest.approx(0.05, abs=2e-3)
    assert half == pytest.approx(0.2, abs=5e-3)  # the rims sit on the caps' equators
    assert abs(abs(frame.rotation[:, 2] @ R[:, 2]) - 1.0) < 1e-4  # the cylinder's axis
    assert np.allclose(frame.translation, t, atol=2e-3)


def test_a_round_cloud_becomes_a_sphere():
    rng = np.random.default_rng(1)
    v = rng.normal(size=(500, 3))
    points = 0.07 * v / np.linalg.norm(v, axis=1, keepdims=True)
    _, radius, half = fit_capsule(points)
    assert half < 5e-3 and radius == pytest.approx(0.07, rel=0.05)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_every_point_is_inside_and_the_capsule_is_at_most_three_hulls(seed):
    rng = np.random.default_rng(seed)  # a link-like solid: an elongated, rotated box
    size = np.array([rng.uniform(0.1, 0.4), *rng.uniform(0.03, 0.08, size=2)])
    box = rng.uniform(-0.5, 0.5, size=(2000, 3)) * size
    points = box @ pin.rpy.rpyToMatrix(*rng.uniform(-3, 3, 3)).T
    frame, radius, half = fit_capsule(points)
    cap = _capsule(frame, radius, half)
    assert segment_distances(cap, points).max() <= radius + 1e-9
    assert capsule_volume(radius, half) <= 3.0 * ConvexHull(points).volume


def test_a_boxs_corners_are_enclosed():
    corners = np.array(list(itertools.product((-0.1, 0.1), (-0.03, 0.03), (-0.02, 0.02))))
    frame, radius, half = fit_capsule(corners)
    cap = _capsule(frame, radius, half)
    assert segment_distances(cap, corners).max() <= radius + 1e-9
    assert abs(frame.rotation[0, 2]) == pytest.approx(1.0)  # along the box's long side
