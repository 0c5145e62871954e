"""Joint reaction forces from the multipliers against hand-computed statics."""

import numpy as np

import flexmbd as fm

G = 9.81


def test_cantilever_fixed_joint_carries_weight_and_tip_load(assert_close):
    # A rigid beam (m, L) along x, fixed to the ground at x = 0, loaded by its weight and a
    # tip force P along -y. On the beam at the joint: force (0, m g + P, 0) and moment
    # (m g L / 2 + P L) about +z.
    mass, length, load = 4.0, 2.0, 30.0
    system = fm.System(gravity=(0.0, -G, 0.0))
    beam = system.add_rigid_body(mass, (0.01, 1.0, 1.0), position=(length / 2, 0, 0))
    root = system.add_marker(system.ground)
    clamp = system.add_marker(beam, position=(-length / 2, 0, 0))
    tip = system.add_marker(beam, position=(length / 2, 0, 0))
    joint = system.add_fixed_joint(root, clamp)
    system.add_point_force(tip, (0.0, -load, 0.0))
    result = fm.simulate(system, 0.2, 1e-3, output_interval=0.05)
    force, torque = result.reaction(joint)
    expected_force = np.array([0.0, mass * G + load, 0.0])
    expected_torque = np.array([0.0, 0.0, mass * G * length / 2 + load * length])
    expected_force = np.tile(expected_force, (len(result), 1))
    expected_torque = np.tile(expected_torque, (len(result), 1))
    assert_close(force, expected_force, rel=1e-7, abs=1e-8, what="force")
    assert_close(torque, expected_torque, rel=1e-7, abs=1e-8, what="torque")
    position = result.position(beam)[-1]
    assert_close(position, [length / 2, 0, 0], rel=1e-7, abs=1e-12, what="position")


def test_beam_held_by_a_pin_and_a_cable(assert_close):
    # Beam of length L pinned at A = (0, 0) (revolute about z), held horizontal by a cable from
    # its end B = (L, 0) to C = (0, h). Moments about A: T L h / l = m g L / 2, l = |BC|. The
    # pin carries the rest: R = (T L / l, m g - T h / l) = (T L / l, m g / 2).
    mass, length, height = 3.0, 2.0, 1.5
    ell = np.hypot(length, height)
    tension = mass * G * ell / (2 * height)
    system = fm.System(gravity=(0.0, -G, 0.0))
    beam = system.add_rigid_body(mass, (0.01, 1.0, 1.0), position=(length / 2, 0, 0))
    pin = system.add_revolute_joint(
        system.add_marker(system.ground), system.add_marker(beam, position=(-length / 2, 0, 0))
    )
    cable = system.add_distance_joint(
        system.add_marker(system.ground, position=(0, height, 0)),
        system.add_marker(beam, position=(length / 2, 0, 0)),
    )
    result = fm.simulate(system, 0.1, 1e-3, output_interval=0.05)
    cable_force = tension * np.array([-length, height, 0]) / ell
    assert_close(result.reaction_force(cable)[-1], cable_force, rel=1e-7, abs=1e-8, what="cable")
    pin_force = [tension * length / ell, mass * G / 2, 0]
    assert_close(result.reaction_force(pin)[-1], pin_force, rel=1e-7, abs=1e-8, what="pin")
    # A revolute joint transmits no moment about its axis.
    assert_close(result.reaction_torque(pin)[-1, 2], 0.0, abs=1e-9, what="pin torque about z")


def test_reactions_of_a_joint_with_its_second_marker_on_the_ground(assert_close):
    # The same cantilever with the markers swapped: the reported force acts on the ground at
    # the second marker, the opposite of the force on the beam.
    mass, length = 4.0, 2.0
    system = fm.System(gravity=(0.0, -G, 0.0))
    beam = system.add_rigid_body(mass, (0.01, 1.0, 1.0), position=(length / 2, 0, 0))
    joint = system.add_fixed_joint(
        system.add_marker(beam, position=(-length / 2, 0, 0)), system.add_marker(system.ground)
    )
    result = fm.simulate(system, 0.1, 1e-3, output_interval=0.05)
    force, torque = result.reaction(joint)
    assert_close(force[-1], [0, -mass * G, 0], rel=1e-7, abs=1e-8, what="force")
    assert_close(torque[-1], [0, 0, -mass * G * length / 2], rel=1e-7, abs=1e-8, what="torque")
