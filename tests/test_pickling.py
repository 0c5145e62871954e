"""Ids, time functions and solver settings pickle and deep-copy (issue 31, first part): a
round trip gives an equal object, and a run with the copies is bitwise the run with the
originals."""

from __future__ import annotations

import copy
import pickle

import numpy as np
import pytest

import flexmbd as fm

OBJECTS = [
    fm.BodyId(3),
    fm.MarkerId(0),
    fm.JointId(7),
    fm.Constant(2.0),
    fm.Polynomial([0.0, 1.0, 2.0]),
    fm.Harmonic(1.0, 2.0, 0.5, 0.1),
    fm.Spline([0.0, 1.0, 2.0], [0.0, 1.0, 0.0]),
    fm.UserFunction(np.sin),
    fm.GeneralizedAlpha(0.8, jacobian="full", max_step_size=1e-2),
    fm.ExplicitSolver("rk4", "joint-coordinates", cut_joints=[fm.JointId(2)]),
]


def fields(obj):
    names = [
        n for n in dir(type(obj)) if not n.startswith("_") and n not in ("choices", "derivatives")
    ]
    return {n: getattr(obj, n) for n in names if not callable(getattr(obj, n))}


@pytest.mark.parametrize("obj", OBJECTS, ids=lambda o: type(o).__name__)
def test_round_trips_keep_type_and_fields(obj):
    for again in (pickle.loads(pickle.dumps(obj)), copy.deepcopy(obj), copy.copy(obj)):
        assert type(again) is type(obj)
        assert fields(again) == fields(obj)
        if callable(obj):
            assert again(0.7) == obj(0.7) and again.derivatives(0.7) == obj.derivatives(0.7)


def test_a_run_with_pickled_drivers_and_solver_is_bitwise_the_same():
    def run(drive, solver):
        system = fm.System(gravity=(0, -9.81, 0))
        crank = system.add_rigid_body(1.0, (1e-3, 0.1, 0.1), position=(0.5, 0, 0))
        ground = system.add_marker(system.ground)
        pin = system.add_marker(crank, position=(-0.5, 0, 0))
        system.add_revolute_joint(ground, pin)
        system.add_angle_driver(ground, pin, drive)
        return fm.simulate(system, 0.05, 1e-3, solver=solver)

    drive, solver = fm.Spline([0.0, 0.1], [0.0, 0.3]), fm.GeneralizedAlpha(0.7)
    first = run(drive, solver)
    second = run(pickle.loads(pickle.dumps(drive)), pickle.loads(pickle.dumps(solver)))
    assert np.array_equal(first.coordinates, second.coordinates)
    assert np.array_equal(first.multipliers, second.multipliers)


def test_a_lambda_cannot_be_pickled_and_says_so():
    with pytest.raises((pickle.PicklingError, AttributeError), match="lambda"):
        pickle.dumps(fm.UserFunction(lambda t: t))
