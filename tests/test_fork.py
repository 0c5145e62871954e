"""Process pools after a simulation: a flexible-body run (dense decompositions of the
redundancy analysis, sparse factorizations) and a parallel sparse factorization in the
parent must not leave a forked child waiting on threads it does not have."""

from __future__ import annotations

import multiprocessing

import numpy as np
import pytest
import scipy.sparse as sp

import flexmbd as fm
from flexmbd.fe.modal import factorize


def run_case(case: int) -> tuple[int, float]:
    """A short run of the flexible slider-crank and a factorization on two threads: the
    number of records and the solution's error."""
    example = fm.examples.EXAMPLES["flexible-slider-crank"]()
    result = fm.simulate(example.system, 0.002, example.step_size, solver=example.solver)
    n = 2000 + case
    matrix = sp.diags([-np.ones(n - 1), 4.0 * np.ones(n), -np.ones(n - 1)], [-1, 0, 1]).tocsc()
    solution = np.linspace(1.0, 2.0, n)
    factor = factorize(matrix, threads=2, name="tridiagonal")
    error = float(np.abs(factor.solve(matrix @ solution) - solution).max())
    return len(result.time), error


@pytest.mark.parametrize("method", ["fork", "forkserver", "spawn"])
def test_a_process_pool_after_a_flexible_simulation_finishes_its_runs(method):
    records, error = run_case(0)
    assert records > 1 and error < 1e-12
    context = multiprocessing.get_context(method)
    with context.Pool(2) as pool:
        # A child that waits on the parent's threads would hang: the timeout fails the test
        # and leaving the block terminates the pool.
        results = pool.map_async(run_case, range(8)).get(timeout=120)
    assert [r for r, _ in results] == [records] * 8
    assert max(e for _, e in results) < 1e-12
