"""Redundant (over-constrained) mechanisms: the four-bar with four spatial revolute joints and
Bricard's mechanism. Checked without simulating: consistent initial state, the rank deficiency
of the constraint Jacobian, and one degree of freedom of finite motion."""

import numpy as np
import pytest
import scipy.sparse as sp

import flexmbd as fm

# builder, coordinates, constraint rows (normalizations + joint equations), redundant rows
MODELS = [
    (fm.examples.four_bar_spatial, 21, 3 + 4 * 5, 3),
    (fm.examples.bricard, 35, 5 + 6 * 5, 1),
]


def constraint_parts(model, q):
    """C(q) and C_q (constraint rows x coordinates) from Model.evaluate."""
    nq, nc = model.coordinate_count, model.constraint_count
    out = model.evaluate(0.0, q, np.zeros(nq), np.zeros(nq), np.zeros(nc), mass=1.0)
    data, indices, indptr, n = out["matrix"]
    matrix = sp.csc_matrix((data, indices, indptr), shape=(n, n)).toarray()
    return out["residual"][nq:], matrix[nq:, :nq]


def numerical_rank(matrix, relative_tolerance=1e-9):
    singular_values = np.linalg.svd(matrix, compute_uv=False)
    return int(np.sum(singular_values > relative_tolerance * singular_values[0]))


@pytest.fixture(params=MODELS, ids=["four-bar-spatial", "bricard"])
def case(request):
    builder, coordinates, rows, redundant = request.param
    model = builder().system.compile()
    assert (model.coordinate_count, model.constraint_count) == (coordinates, rows)
    return model, redundant


def test_initial_state_is_consistent(case):
    model, _ = case
    violation, jacobian = constraint_parts(model, model.initial_coordinates)
    assert np.abs(violation).max() < 1e-12
    assert np.abs(jacobian @ model.initial_velocities).max() < 1e-12


def test_constraint_jacobian_has_the_expected_rank_deficiency(case):
    model, redundant = case
    _, jacobian = constraint_parts(model, model.initial_coordinates)
    rank = numerical_rank(jacobian)
    assert rank == model.constraint_count - redundant
    assert model.coordinate_count - rank == 1


def test_mechanism_moves_along_the_null_space(case):
    # A finite motion, not only an infinitesimal one: step s along the null space of C_q,
    # return to C(q) = 0 by Gauss-Newton with the least-squares (pseudo-inverse) increment.
    # The projection is orthogonal to the step to first order, so the point stays about s
    # away from the start, and the redundancy persists there.
    model, redundant = case
    start = model.initial_coordinates
    _, jacobian = constraint_parts(model, start)
    direction = np.linalg.svd(jacobian)[2][-1]
    s = 1e-3
    q = start + s * direction
    for _ in range(20):
        violation, jacobian = constraint_parts(model, q)
        if np.abs(violation).max() < 1e-14:
            break
        q = q - np.linalg.lstsq(jacobian, violation, rcond=1e-9)[0]
    violation, jacobian = constraint_parts(model, q)
    assert np.abs(violation).max() < 1e-12
    assert abs(np.linalg.norm(q - start) / s - 1.0) < 1e-2
    assert numerical_rank(jacobian) == model.constraint_count - redundant
