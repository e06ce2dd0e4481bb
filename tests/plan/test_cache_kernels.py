"""A plan cache shared by machines of different BLAS kernels: each kernel uses its own plan.

The kernels are chosen with ``OPENBLAS_CORETYPE`` in child processes (Prescott and Haswell run on
any x86-64 CPU of the last decade). No test here depends on the bits a kernel gives: only on a
process using the plan it would have solved itself.
"""

import hashlib
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from amex.plan import cache

KERNELS = ("Prescott", "Haswell")
SOLVE = textwrap.dedent(
    """
    import hashlib, json, sys
    from pathlib import Path
    import numpy as np
    from amex.plan.cache import blas_kernel, reference_plan, solve_reference
    from amex.plan.reference import PlanConfig
    from amex.robot import load_robot

    robot, config = load_robot(), PlanConfig(duration=0.5)
    goal, axis = np.array([0.384, 0.229, 0.461]), np.array([0.0, 0.0, -1.0])
    used = reference_plan(robot, config, goal, axis, directory=Path(sys.argv[1]))
    own = solve_reference(robot, config, goal, axis)
    digest = lambda q: hashlib.sha256(q.tobytes()).hexdigest()
    print(json.dumps({"used": digest(used.q), "own": digest(own.q), "kernel": blas_kernel()}))
    """
)


@pytest.mark.skipif(sys.platform != "linux", reason="OPENBLAS_CORETYPE as numpy's wheels read it")
def test_each_blas_kernel_uses_its_own_plan_from_a_shared_cache(tmp_path):
    import json

    shared = tmp_path / "plans"
    seen = []
    for kernel in (*KERNELS, *KERNELS):  # the second round reads what the first wrote
        env = {**os.environ, "OPENBLAS_CORETYPE": kernel}
        done = subprocess.run(
            [sys.executable, "-c", SOLVE, str(shared)],
            capture_output=True,
            text=True,
            env=env,
            timeout=300,
        )
        assert done.returncode == 0, done.stderr
        seen.append(json.loads(done.stdout.strip().splitlines()[-1]))
    for answer in seen:
        assert answer["used"] == answer["own"]  # never another kernel's plan
    kernels = {json.dumps(a["kernel"], sort_keys=True) for a in seen}
    assert len(kernels) == 2 and len(list(shared.glob("plan_*.npz"))) == 2


def test_the_blas_kernel_is_part_of_the_plan_key(robot, monkeypatch):
    config = cache.PlanConfig(duration=0.5)
    goal, axis = np.array([0.384, 0.229, 0.461]), np.array([0.0, 0.0, -1.0])
    here = cache.plan_key(robot, config, goal, axis)
    other = {"cores": ["Zen (OpenBLAS 0.3.30)"], "probe": hashlib.sha256(b"x").hexdigest()[:16]}
    monkeypatch.setattr(cache, "blas_kernel", lambda: other)
    assert cache.plan_key(robot, config, goal, axis) != here


def test_the_kernel_names_the_loaded_openblas_cores_and_is_computed_once():
    kernel = cache.blas_kernel()
    assert cache.blas_kernel() is kernel
    assert len(kernel["probe"]) == 16
    if sys.platform == "linux":  # numpy's and scipy's wheels each bring an OpenBLAS
        assert kernel["cores"] and all("OpenBLAS" in core for core in kernel["cores"])
