"""Joint coordinates (seed section 5, first part): trees of rigid bodies with revolute,
prismatic, cylindrical, fixed and universal joints and drivers on them, loops closed by cut
joints, integrated in joint coordinates, against the augmented formulation."""

import numpy as np
import pytest

import flexmbd as fm


def rotation_x(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def robot(driven=False):
    """A spatial arm: shoulder about z, elbow about a tilted axis, a prismatic wrist, and a
    second branch (a carriage on an inclined rail carrying a pendulum with a sleeve on a
    cylindrical joint and a weight welded to it), with gravity. ``driven``: the shoulder angle
    is prescribed (an angle driver on the shoulder's markers)."""
    s = fm.System(gravity=(0.2, -9.81, 0.4))
    inertia = np.array([[0.05, 0.004, -0.002], [0.004, 0.08, 0.003], [-0.002, 0.003, 0.09]])

    def body(name, x):
        return s.add_rigid_body(
            1.3, inertia, center_of_mass=(0.1, 0.02, -0.03), position=(x, 0, 0), name=name
        )

    arm, forearm, wrist = body("arm", 0.5), body("forearm", 1.5), body("wrist", 2.2)
    carriage, pendulum = body("carriage", 0.0), body("pendulum", 0.4)
    along_x = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])  # marker z = body x
    sleeve, weight = body("sleeve", 0.6), body("weight", 0.9)
    shoulder = (s.add_marker(s.ground), s.add_marker(arm, position=(-0.5, 0, 0)))
    joints = [
        s.add_revolute_joint(*shoulder, name="shoulder"),
        s.add_revolute_joint(
            s.add_marker(arm, position=(0.5, 0, 0), orientation=rotation_x(0.4)),
            s.add_marker(forearm, position=(-0.5, 0, 0), orientation=rotation_x(0.4)),
            name="elbow",
        ),
        s.add_prismatic_joint(
            s.add_marker(forearm, position=(0.5, 0, 0), orientation=along_x),
            s.add_marker(wrist, position=(-0.2, 0, 0), orientation=along_x),
            name="wrist",
        ),
        s.add_prismatic_joint(
            s.add_marker(s.ground, orientation=rotation_x(-0.3)),
            s.add_marker(carriage, orientation=rotation_x(-0.3)),
            name="rail",
        ),
        s.add_revolute_joint(
            s.add_marker(pendulum, position=(-0.4, 0.1, 0), orientation=rotation_x(0.2)),
            s.add_marker(carriage, position=(0, 0.1, 0), orientation=rotation_x(0.2)),
            name="swing",
        ),
        s.add_cylindrical_joint(
            s.add_marker(sleeve, orientation=along_x),
            s.add_marker(pendulum, position=(0.2, 0, 0), orientation=along_x),
            name="sleeve",
        ),
        s.add_fixed_joint(
            s.add_marker(sleeve, position=(0.15, 0, 0), orientation=rotation_x(0.7)),
            s.add_marker(weight, position=(-0.15, 0, 0), orientation=rotation_x(0.7)),
            name="weld",
        ),
    ]
    if driven:
        joints.append(s.add_angle_driver(*shoulder, fm.Polynomial([0.0, 0.8, -1.5]), name="drive"))
    return s, [arm, forearm, wrist, carriage, pendulum, sleeve, weight], joints


def solver(strategy):
    return fm.ExplicitSolver("dopri5", strategy, relative_tolerance=1e-11, absolute_tolerance=1e-13)


@pytest.fixture(scope="module", params=[False, True], ids=["free", "driven"])
def runs(request):
    system, bodies, joints = robot(request.param)
    model = system.compile()
    tree = fm.simulate(model, 2.0, 1e-3, output_interval=0.01, solver=solver("joint-coordinates"))
    augmented = fm.simulate(model, 2.0, 1e-3, output_interval=0.01, solver=solver("projection"))
    return tree, augmented, bodies, joints


def test_trajectories_and_reactions_equal_the_augmented_formulation(runs):
    tree, augmented, bodies, joints = runs
    for body in bodies:
        assert np.abs(tree.position(body) - augmented.position(body)).max() < 1e-9
        assert np.abs(tree.velocity(body) - augmented.velocity(body)).max() < 1e-8
    # The joint reactions, eliminated from the joint-coordinate equations, recovered after.
    for joint in joints:
        for a, b in zip(tree.reaction(joint), augmented.reaction(joint), strict=True):
            assert np.abs(a - b).max() < 1e-7 * max(1.0, np.abs(b).max())


def test_joints_hold_exactly_and_energy_is_conserved(runs):
    tree, _, _, joints = runs
    assert tree.constraint_violation.max() < 1e-12
    if len(joints) == 7:  # not driven: no work done on the system
        energy = tree.total_energy
        assert np.abs(energy - energy[0]).max() < 1e-9 * np.abs(tree.kinetic_energy).max()


def slider_crank():
    """The rigid slider-crank of ``examples/slider_crank.py``: the crank driven at 20 rad/s
    (angle driver on the main bearing's markers), the loop closed by the wrist pin (in-line),
    which the joint-coordinate formulation cuts."""
    crank_length, rod_length = 0.15, 0.30
    s = fm.System(gravity=(0, -9.81, 0))
    crank = s.add_rigid_body(
        0.4,
        (1e-5, 0.4 * crank_length**2 / 12, 0.4 * crank_length**2 / 12),
        position=(crank_length / 2, 0, 0),
    )
    rod = s.add_rigid_body(
        0.8,
        (1e-5, 0.8 * rod_length**2 / 12, 0.8 * rod_length**2 / 12),
        position=(crank_length + rod_length / 2, 0, 0),
    )
    slider = s.add_rigid_body(0.5, (1e-3, 1e-3, 1e-3), position=(crank_length + rod_length, 0, 0))
    pivot, root = s.add_marker(s.ground), s.add_marker(crank, position=(-crank_length / 2, 0, 0))
    s.add_revolute_joint(pivot, root, name="main bearing")
    drive = s.add_angle_driver(pivot, root, fm.Polynomial([0.0, 20.0]), name="drive")
    s.add_revolute_joint(
        s.add_marker(crank, position=(crank_length / 2, 0, 0)),
        s.add_marker(rod, position=(-rod_length / 2, 0, 0)),
        name="crank pin",
    )
    along_x = fm.rotation("y", np.pi / 2)
    s.add_prismatic_joint(
        s.add_marker(s.ground, orientation=along_x),
        s.add_marker(slider, orientation=along_x),
        name="guide",
    )
    wrist = s.add_inline_joint(
        s.add_marker(slider), s.add_marker(rod, position=(rod_length / 2, 0, 0)), name="wrist pin"
    )
    return s, [crank, rod, slider], drive, wrist


def test_closed_loop_by_a_cut_joint_equals_the_augmented_formulation():
    system, bodies, drive, wrist = slider_crank()
    model = system.compile()
    runs = [
        fm.simulate(model, 0.5, 1e-4, output_interval=1e-3, solver=solver(strategy))
        for strategy in ("joint-coordinates", "projection")
    ]
    tree, augmented = runs
    for body in bodies:
        assert np.abs(tree.position(body) - augmented.position(body)).max() < 1e-9
    torque = [run.reaction_torque(drive)[:, 2] for run in runs]
    assert np.abs(torque[0] - torque[1]).max() < 1e-7 * np.abs(torque[1]).max()
    force = [run.reaction_force(wrist) for run in runs]
    assert np.abs(force[0] - force[1]).max() < 1e-7 * np.abs(force[1]).max()
    # The cut joint is held by projection of the joint coordinates after each step.
    assert tree.constraint_violation.max() < 1e-11


def test_models_outside_the_supported_trees_are_refused():
    # A body held by a spherical joint only (not yet a tree joint), a point mass.
    s = fm.System()
    body = s.add_rigid_body(1.0, (1, 1, 1), name="link")
    s.add_spherical_joint(s.add_marker(s.ground), s.add_marker(body), name="ball")
    with pytest.raises(fm.InvalidModelError, match="'link'.*'ball' \\(spherical\\)"):
        fm.simulate(s, 0.1, 1e-3, solver=solver("joint-coordinates"))
    with pytest.raises(fm.InvalidModelError, match="rigid bodies"):
        fm.simulate(fm.examples.pendulum().system, 0.1, 1e-3, solver=solver("joint-coordinates"))
