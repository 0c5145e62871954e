"""Shared helpers of the Python tests."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
import scipy.sparse as sp

import flexmbd as fm


def check_close(
    actual: Any, expected: Any, *, rel: float = 0.0, abs: float = 0.0, what: str = "value"
) -> None:
    """The one tolerance helper of the tests: every entry of `actual` (a number or an array,
    broadcast against `expected`) within abs + rel |expected| of `expected` (NaN never is);
    a failure names what was compared, the worst entry, both values and the tolerance."""
    a = np.asarray(actual, dtype=float)
    e = np.broadcast_to(np.asarray(expected, dtype=float), a.shape)
    tolerance = np.broadcast_to(abs + rel * np.abs(e), a.shape)  # (abs, rel: numbers or arrays)
    excess = np.where(np.isnan(a) | np.isnan(e), np.inf, np.abs(a - e) - tolerance)
    if excess.size == 0 or np.max(excess) <= 0.0:
        return
    k = np.unravel_index(int(np.argmax(excess)), excess.shape) if excess.ndim else ()
    where = f"{what}[{', '.join(map(str, k))}]" if k else what
    pytest.fail(
        f"{where}: {a[k]:.17g} against {e[k]:.17g}: |difference| {np.abs(a[k] - e[k]):.3e} > "
        f"{np.broadcast_to(abs, a.shape)[k]:.1e} + {np.broadcast_to(rel, a.shape)[k]:.1e} "
        f"|expected| = {tolerance[k]:.3e}",
        pytrace=False,
    )


@pytest.fixture
def assert_close():
    """:func:`check_close` as a fixture: ``assert_close(actual, expected, rel=..., abs=...)``."""
    return check_close


def relative_drift(energy: np.ndarray) -> float:
    """Largest |E(t) - E(0)| / |E(0)| over a run."""
    return float(np.max(np.abs(energy - energy[0])) / abs(energy[0]))


def rod_inertia(mass: float, length: float, axial: float = 1e-6) -> tuple[float, float, float]:
    """Principal inertia of a slender rod along its local x axis about its centre."""
    transverse = mass * length**2 / 12.0
    return (axial, transverse, transverse)


def turntable_pendulum(speed: float):
    """A pendulum (1 m, 1 kg point-like bob, 1e-6 kg m^2 about its centre) hinged on the axis
    of a table that the angle driver "spin" turns about the vertical at `speed` (rad/s):
    hanging, it swings in the turning frame at w^2 = (g - W^2) / (1 + 1e-6), and diverges
    above W = sqrt(g) (g = 9.81)."""
    to_y = np.array([[1, 0, 0], [0, 0, 1], [0, -1, 0]], float)  # marker z along global y
    system = fm.System(gravity=(0, -9.81, 0))
    table = system.add_rigid_body(5.0, (0.5, 0.5, 0.5), name="table")
    base = system.add_marker(system.ground, orientation=to_y)
    top = system.add_marker(table, orientation=to_y)
    system.add_revolute_joint(base, top, name="spindle")
    system.add_angle_driver(base, top, fm.Polynomial([0.0, speed]), name="spin")
    bob = system.add_rigid_body(1.0, (1e-6, 1e-6, 1e-6), position=(0, -1, 0), name="bob")
    pin = system.add_marker(bob, position=(0, 1, 0))
    system.add_revolute_joint(system.add_marker(table), pin, name="hinge")
    return system


def clamped_steel_beam(length: float, elements: int, section):
    """Body data of a straight steel beam (E 2.1e11 Pa, nu 0.3, 7850 kg/m^3) of nodal
    Euler-Bernoulli elements along x, its frame clamped at its first node."""
    from flexmbd.fe import Material, build_body, straight_beam

    nodes, beams = straight_beam(length, elements)
    steel = Material(2.1e11, 0.3, 7850.0)
    return build_body(
        nodes, beams, steel, section=section, reference="clamped", reference_nodes=[0]
    )


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
