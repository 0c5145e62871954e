"""Shared helpers of the Python tests."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

import flexmbd as fm


def relative_drift(energy: np.ndarray) -> float:
    """Largest |E(t) - E(0)| / |E(0)| over a run."""
    return float(np.max(np.abs(energy - energy[0])) / abs(energy[0]))


def rod_inertia(mass: float, length: float, axial: float = 1e-6) -> tuple[float, float, float]:
    """Principal inertia of a slender rod along its local x axis about its centre."""
    transverse = mass * length**2 / 12.0
    return (axial, transverse, transverse)


def constraint_parts(model, q):
    """C(q) and C_q (constraint rows x coordinates) of a compiled model, from Model.evaluate."""
    nq, nc = model.coordinate_count, model.constraint_count
    out = model.evaluate(0.0, q, np.zeros(nq), np.zeros(nq), np.zeros(nc), mass=1.0)
    data, indices, indptr, n = out["matrix"]
    matrix = sp.csc_matrix((data, indices, indptr), shape=(n, n)).toarray()
    return out["residual"][nq:], matrix[nq:, :nq]


def run_example(name: str, end_time: float, output_interval: float) -> fm.Result:
    """A short run of a built-in example with its step size and solver."""
    example = fm.examples.EXAMPLES[name]()
    return fm.simulate(
        example.system,
        end_time=end_time,
        step_size=example.step_size,
        solver=example.solver,
        output_interval=output_interval,
    )
