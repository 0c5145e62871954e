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
    fm.Spline([0.0, 1.0, 2.0], [0.0, 1.0, 0.5], end="clamped", slopes=(1.0, -2.0)),
    fm.Step(0.1, 0.9, 0.0, 2.0, shape="cycloidal"),
    fm.Trapezoidal(0.0, 1.0, 0.5, 2.0, blend=0.3),
    fm.UserFunction(np.sin),
    fm.GeneralizedAlpha(0.8, jacobian="full", step_control="error", max_step_size=1e-2),
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


# Systems and models (issue 31): built again from the record of the calls that built them.

SHORT_RUNS = {
    "andrews": 1e-4,
    "bricard": 1e-3,
    "flexible-double-pendulum": 1e-3,
    "flexible-robot-arm": 1e-3,
    "flexible-slider-crank": 1e-4,
    "four-bar": 1e-3,
    "four-bar-spatial": 1e-3,
    "pendulum": 1e-3,
    "satellite": 1e-2,
    "space-crane": 1e-2,
    "spin-up": 1e-3,
    "tetrahedral-pendulum": 1e-3,
}


def same_run(first, second):
    for name in ("time", "coordinates", "velocities", "accelerations", "multipliers"):
        assert np.array_equal(getattr(first, name), getattr(second, name)), name


def test_every_example_is_covered():
    assert set(SHORT_RUNS) == set(fm.examples.EXAMPLES)


@pytest.mark.parametrize("name", sorted(SHORT_RUNS))
def test_pickled_example_systems_and_models_run_bitwise_the_same(name):
    example = fm.examples.EXAMPLES[name]()
    step = SHORT_RUNS[name]
    system = example.system
    model = system.compile()

    def run(m):
        return fm.simulate(m, 20 * step, step, solver=example.solver)

    original = run(model)
    for again in (
        pickle.loads(pickle.dumps(system)).compile(),
        copy.deepcopy(system).compile(),
        pickle.loads(pickle.dumps(model)),
    ):
        assert again.coordinate_count == model.coordinate_count
        same_run(run(again), original)
    # The deformable bodies' data comes along.
    assert pickle.loads(pickle.dumps(model)).flexible_bodies.keys() == model.flexible_bodies.keys()


def test_a_copied_system_is_independent_of_the_original():
    system = fm.System(gravity=(0, -9.81, 0))
    position = np.array([1.0, 0.0, 0.0])
    system.add_point_mass(1.0, position=position)
    position[0] = 5.0  # the record keeps the array as it was at the call
    twin = copy.deepcopy(system)
    twin.add_point_mass(2.0, position=(0, 1, 0))
    assert system.compile().coordinate_count == 3
    assert twin.compile().coordinate_count == 6
    again = pickle.loads(pickle.dumps(system)).compile()
    assert np.array_equal(again.initial_coordinates, [1.0, 0.0, 0.0])
    assert [name for name, _, _ in twin.building_calls] == ["gravity", "add_point_mass"] * 1 + [
        "add_point_mass"
    ]


def test_calls_made_inside_a_building_call_are_not_recorded_twice():
    example = fm.examples.tetrahedral_pendulum()
    names = [name for name, _, _ in example.system.building_calls]
    assert "add_flexible_body" in names
    assert not any(name.startswith("_") for name in names)
    assert names.count("add_node_set_marker") + names.count("add_node_marker") >= 1


def lambda_driven_system():
    system = fm.System()
    arm = system.add_rigid_body(1.0, (1, 1, 1))
    ground, pin = system.add_marker(system.ground), system.add_marker(arm)
    system.add_revolute_joint(ground, pin)
    system.add_angle_driver(ground, pin, fm.UserFunction(lambda t: 0.5 * t * t))
    return system


def test_a_lambda_pickles_with_cloudpickle_and_fails_with_pickle_naming_it():
    import cloudpickle

    system = lambda_driven_system()
    with pytest.raises((pickle.PicklingError, AttributeError), match="lambda"):
        pickle.dumps(system)
    model = system.compile()
    again = pickle.loads(cloudpickle.dumps(model))
    same_run(fm.simulate(again, 0.05, 1e-3), fm.simulate(model, 0.05, 1e-3))


def test_a_model_of_a_bare_core_system_refuses_pickling_with_the_reason():
    system = fm._core.System()
    system.add_point_mass(1.0)
    with pytest.raises(TypeError, match="flexmbd.System"):
        pickle.dumps(system.compile())


def test_functions_that_use_the_package_pickle_by_value_with_it_by_reference():
    # A study's build function in a script refers to `fm`; cloudpickle sends such functions
    # by value with their globals, and the package (a module subclass) could not be pickled:
    # Study.run failed with "Could not serialize object", a raw TypeError.
    cloudpickle = pytest.importorskip("cloudpickle")
    assert pickle.loads(pickle.dumps(fm)) is fm

    def build(mass: float = 1.0) -> fm.System:  # local: pickled by value
        system = fm.System(gravity=(0.0, -9.81, 0.0))
        system.add_rigid_body(mass, (1.0, 1.0, 1.0), name="block")
        return system

    copied = pickle.loads(cloudpickle.dumps(build))
    assert copied is not build
    assert copied(2.0).compile().coordinate_count == 7
