"""numpy's BLAS and SciPy's LAPACK called from compiled code give numpy's and SciPy's bits.

:mod:`amex.plan.optimizer.blas` calls the routines numpy calls for ``dot`` and ``@`` (and SciPy
for ``dpbsv``) with the arguments numpy passes; a wrong order, transposition or leading
dimension would take another OpenBLAS kernel path, which sums in another order, and these
comparisons on random inputs would see it. ``make test-kernels`` runs them under every OpenBLAS
kernel the CPU can run.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg.lapack import dpbsv as scipy_dpbsv

from amex.plan import optimizer as opt
from amex.plan.optimizer import assembly, blas, compiled_loop
from amex.plan.optimizer.assembly import CompiledAssembly
from amex.plan.optimizer.iteration_kernels import final_products
from tests.plan.problems import problem_near_obstacles

pytestmark = pytest.mark.skipif(not blas.BOUND, reason="numpy is not built on its OpenBLAS")


def same(a, b) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    return np.array_equal(a, b) and np.array_equal(np.signbit(a), np.signbit(b))


@pytest.mark.parametrize("seed", range(4))
def test_products_are_numpys(seed):
    rng = np.random.default_rng(seed)
    for _ in range(100):
        m, n = (int(v) for v in rng.integers(2, 24, size=2))
        x = rng.standard_normal(int(rng.integers(1, 3000)))
        assert blas.ddot(x, x) == x.dot(x)
        a = rng.standard_normal((m, n))
        v, r, out = rng.standard_normal(n), rng.standard_normal(m), np.empty(m)
        blas.dot_rows(a, v, out)
        assert same(out, a.dot(v))
        wide = rng.standard_normal((m + 3, n))  # a block of rows, as J[3:] of the Jacobian
        blas.dot_rows(np.ascontiguousarray(wide[3:]), v, out)
        assert same(out, wide[3:].dot(v))
        blas.dot_rows(np.ascontiguousarray(np.asfortranarray(wide)[3:]), v, out)
        assert same(out, np.asfortranarray(wide)[3:].dot(v))  # numpy copies it to C order
        out_t = np.empty(n)
        blas.transposed_dot(a, r, out_t)
        assert same(out_t, a.T.dot(r))
        gram = np.full((n, n), np.nan)  # an earlier use's NaN must not leak in
        blas.gram_upper(a, gram)
        assert same(gram, a.T @ a)
        JtJ, Jtr = final_products(a, r)
        assert same(JtJ, a.T @ a) and same(Jtr, a.T.dot(r))


@pytest.mark.parametrize("kd", [0, 1, 6, 14, 20])
def test_dpbsv_is_scipys(kd):
    rng = np.random.default_rng(kd)
    for size in (1, 2, kd + 1, 300):
        band = np.zeros((kd + 1, size))
        for d in range(kd + 1):
            band[d, : max(size - d, 0)] = 0.1 * rng.standard_normal(max(size - d, 0))
        band[0] += kd + 2.0  # diagonally dominant: positive definite
        band = np.asfortranarray(band)
        rhs = rng.standard_normal(size)
        ours_band, ours = band.copy(order="F"), rhs.copy()
        info = blas.dpbsv(ours_band, ours)
        factor, x, scipy_info = scipy_dpbsv(
            band.copy(order="F"), rhs.copy(), lower=1, overwrite_ab=1, overwrite_b=1
        )
        assert info == scipy_info == 0
        assert same(ours, x) and same(ours_band, factor)
    indefinite = np.asfortranarray(np.array([[1.0, -1.0, 1.0], [2.0, 0.0, 0.0]]))
    assert blas.dpbsv(indefinite.copy(order="F"), np.ones(3)) == 2  # info > 0, as SciPy's


@pytest.mark.parametrize("seed", range(6))
def test_fused_solve_equals_the_python_path(robot, seed, monkeypatch):
    """The whole solve on the compiled calls and on the Python-level calls: the same bits."""
    monkeypatch.setattr(compiled_loop, "ENABLED", False)  # its kinematics: test_compiled_loop
    rng = np.random.default_rng(40 + seed)
    T = int(rng.choice([1, 2, 10, 60]))
    problem = problem_near_obstacles(robot, rng, T, int(rng.integers(0, 3)), seed % 2 == 0)
    q_init = robot.q0 + rng.normal(scale=0.3, size=(T + 1, robot.nv))
    fused = opt.solve_trajectory(
        robot, problem, q_init=q_init, max_iterations=8, assembly=CompiledAssembly(robot)
    )
    assert CompiledAssembly(robot).begin(problem).fused
    monkeypatch.setattr(assembly, "BOUND", False)
    assert not CompiledAssembly(robot).begin(problem).fused
    plain = opt.solve_trajectory(
        robot, problem, q_init=q_init, max_iterations=8, assembly=CompiledAssembly(robot)
    )
    assert same(fused.q, plain.q) and fused.cost == plain.cost
    assert (fused.iterations, fused.converged) == (plain.iterations, plain.converged)
