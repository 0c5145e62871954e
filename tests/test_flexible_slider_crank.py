"""Flexible slider-crank (reference R4, Jonker / Simeon data set): rigid crank driven at
150 rad/s, elastic connecting rod in the floating frame of reference with simply-supported
reference conditions (so its elastic displacements are deflections from the chord), slider a
point mass. Checks the midpoint deflection, the joint reactions and the driving torque."""

from __future__ import annotations

import numpy as np
import pytest

import flexmbd as fm
from flexmbd.fe import Material, Section, build_body, straight_beam

CRANK, ROD, OMEGA = 0.15, 0.30, 150.0
STEEL = Material(2.0e11, 0.3, 7870.0)
SECTION = Section.circle(0.003)


def slider_crank(elements: int = 8, geometric_stiffness: bool = True, **body):
    nodes, conn = straight_beam(ROD, elements)
    data = build_body(
        nodes,
        conn,
        STEEL,
        section=SECTION,
        reference="simply-supported",
        reference_nodes=[0, elements],
        **body,
    )
    rod_mass = data.invariants["mass"]
    system = fm.System()
    crank = system.add_rigid_body(
        0.1,
        (1e-6, 0.1 * CRANK**2 / 12, 0.1 * CRANK**2 / 12),
        center_of_mass=(CRANK / 2, 0, 0),
        angular_velocity=(0, 0, OMEGA),
    )
    # Rigid-mechanism velocities at crank angle 0: the rod turns about the slider end.
    rod = system.add_flexible_body(
        data,
        position=(CRANK, 0, 0),
        velocity=(0, OMEGA * CRANK, 0),
        angular_velocity=(0, 0, -OMEGA * CRANK / ROD),
        geometric_stiffness=geometric_stiffness,
        name="rod",
    )
    slider = system.add_point_mass(rod_mass / 2, position=(CRANK + ROD, 0, 0))
    pivot, crank_root = system.add_marker(system.ground), system.add_marker(crank)
    system.add_revolute_joint(pivot, crank_root, name="bearing")
    drive = system.add_angle_driver(pivot, crank_root, fm.Polynomial([0.0, OMEGA]), name="drive")
    crank_pin = system.add_revolute_joint(
        system.add_marker(crank, position=(CRANK, 0, 0)),
        system.add_node_marker(rod, 1),
        name="crank pin",
    )
    wrist = system.add_spherical_joint(
        system.add_node_marker(rod, elements + 1), system.add_marker(slider), name="wrist pin"
    )
    along_x = fm.rotation("y", np.pi / 2)
    guide = system.add_inline_joint(
        system.add_marker(system.ground, orientation=along_x),
        system.add_marker(slider),
        name="guide",
    )
    return system, rod, {"drive": drive, "crank pin": crank_pin, "wrist": wrist, "guide": guide}


def test_midpoint_deflection_matches_r4():
    elements = 8
    system, rod, joints = slider_crank(elements)
    turns = 2 * 2 * np.pi / OMEGA
    result = fm.simulate(system, turns, 2e-5, output_interval=1e-4)
    v_mid = result.node_displacements(rod, [elements // 2 + 1])[:, 0, 1]
    k = int(np.argmax(np.abs(v_mid)))
    assert abs(v_mid[k]) == pytest.approx(4.658e-3, rel=0.03)
    assert 0.07 < result.time[k] < 0.085
    # The simply-supported frame is the chord: the deflection from the deformed chord agrees.
    chord = result.deflection(rod, elements // 2 + 1, chord=(1, elements + 1))[:, 1]
    assert np.max(np.abs(chord - v_mid)) < 1e-3 * np.max(np.abs(v_mid))
    # Reactions and the driving torque are output; the driver's power equals the rate of
    # change of the mechanical (kinetic plus strain) energy.
    torque = result.reaction_torque(joints["drive"])[:, 2]
    assert np.max(np.abs(torque)) > 1.0
    for name in ("crank pin", "wrist", "guide"):
        assert np.all(np.isfinite(result.reaction_force(joints[name])))
    work = np.concatenate([[0.0], np.cumsum(0.5 * (torque[1:] + torque[:-1]) * OMEGA * 1e-4)])
    energy = result.total_energy - result.total_energy[0]
    assert np.max(np.abs(work - energy)) < 0.01 * np.max(np.abs(energy))
