"""Stress recovery (`flexmbd.fe.stress`): beam section resultants against statics, solid
stresses against the uniform stress of a bar, and the same outputs from a simulation."""

from __future__ import annotations

import numpy as np
import pytest

import flexmbd as fm
from flexmbd.fe import Material, Section, build_body, recover_stresses, shapes, straight_beam
from flexmbd.fe.preprocess import static_displacements

STEEL = Material(2.1e11, 0.3, 7800.0)


def cantilever(elements=5, length=2.0, **kwargs):
    nodes, conn = straight_beam(length, elements)
    return build_body(
        nodes,
        conn,
        STEEL,
        section=Section.rectangle(0.04, 0.02),
        reference="clamped",
        reference_nodes=[0],
        **kwargs,
    )


@pytest.mark.parametrize("beam_theory", ["euler-bernoulli", "timoshenko"])
def test_beam_section_resultants_of_a_tip_load_are_those_of_statics(beam_theory, assert_close):
    body = cantilever(beam_theory=beam_theory)
    p, axial, twist = 150.0, 400.0, 7.0
    f = np.zeros(body.dof_count)
    tip = 6 * (len(body.nodes) - 1)
    f[tip + 0] = axial  # along the beam (x)
    f[tip + 2] = p  # transverse, along z
    f[tip + 3] = twist  # torque about x
    _, beams = recover_stresses(body, static_displacements(body, f))
    x = body.nodes[body.elements["beam2"], 0]  # (elements, 2) end coordinates
    n, vy, vz, t, my, mz = (beams[..., k] for k in range(6))
    assert_close(n, axial, rel=1e-9, what="N")
    assert_close(t, twist, rel=1e-9, what="T")
    assert_close(vz, p, rel=1e-9, what="V_z")
    assert_close(vy, 0.0, abs=1e-9 * p, what="V_y")
    assert_close(mz, 0.0, abs=1e-9 * p, what="M_z")
    # Bending about y: |M_y(x)| = P (L - x), zero at the tip.
    assert_close(np.abs(my), p * (2.0 - x), rel=1e-9, abs=1e-9 * p, what="|M_y|")


def test_solid_bar_in_tension_has_the_uniform_stress(assert_close):
    mesh = shapes.box((1.0, 0.1, 0.1), (10, 2, 2), "hex8")

    def at(point):
        return int(np.argmin(np.linalg.norm(mesh.nodes - np.asarray(point), axis=1)))

    body = build_body(
        mesh.nodes,
        mesh.elements,
        STEEL,
        node_sets=mesh.node_sets,
        reference="3-2-1",
        reference_nodes=[at((0, 0, 0)), at((1, 0, 0)), at((0, 0.1, 0))],
    )
    # Equal and opposite pulls on the end faces, spread evenly over their nodes: the bar is in
    # equilibrium, the 3-2-1 frame carries no load.
    f = np.zeros((len(body.nodes), 3))
    force = 1.0e4
    for name, sign in (("x0", -1.0), ("x1", 1.0)):
        face = body.node_sets[name]
        f[face, 0] = sign * force / len(face)
    nodal, _ = recover_stresses(body, static_displacements(body, f.ravel()))
    middle = np.abs(body.nodes[:, 0] - 0.5) < 0.11
    sigma = force / 0.01
    assert_close(nodal[middle, 0], sigma, rel=0.02, what="sigma_xx")
    assert_close(nodal[middle, 1:], 0.0, abs=0.02 * sigma, what="other stress components")
    von_mises = fm.fe.von_mises(nodal[middle]).mean()
    assert_close(von_mises, sigma, rel=0.02, what="mean von Mises stress")


def test_section_forces_and_chord_deflection_from_a_simulation(assert_close):
    body = cantilever(elements=6, length=1.0)
    system = fm.System(gravity=(0.0, 0.0, -9.81))
    beam = system.add_flexible_body(body, rayleigh_damping=(40.0, 0.0))
    system.add_fixed_joint(system.add_marker(system.ground), system.add_node_marker(beam, 1))
    result = fm.simulate(system, 1.0, 2e-3, output_interval=0.1)
    forces = result.section_forces(beam)
    assert forces.shape == (len(result.time), 6, 2, 6)
    # Root bending moment of the weight w L^2 / 2, less the fixed-end moment w l^2 / 12 of the
    # load on the root element (l = L / 6) that end forces from K u do not see.
    w = 7800.0 * 0.04 * 0.02 * 9.81
    root_moment = abs(forces[-1, 0, 0, 4])
    assert_close(root_moment, w / 2 - w / 6**2 / 12, rel=1e-4, what="root bending moment")
    # A beam has no nodal stress tensor: asking for one is an error that points to the
    # section forces (it was a table of zeros), as are records that are not there.
    with pytest.raises(fm.InvalidParameterError, match="no solid or shell.*section_forces"):
        result.stresses(beam, records=[-1])
    with pytest.raises(fm.InvalidParameterError, match="no shell elements"):
        result.shell_stresses(beam)
    n = len(result.time)
    assert result.section_forces(beam, records=[-n, n - 1]).shape == (2, 6, 2, 6)
    assert result.section_forces(beam, records=[]).shape == (0, 6, 2, 6)  # (was (0, 0, 2, 6))
    for records in ([n], [-n - 1], 0.5, ["last"], [[0, 1]]):  # ([[0, 1]]: a scipy error)
        with pytest.raises(fm.InvalidParameterError, match="records"):
            result.section_forces(beam, records=records)
    for chord in ((1, 1), (1,), "17", (1, 2.5)):
        with pytest.raises(fm.InvalidParameterError, match="chord"):
            result.deflection(beam, 4, chord=chord)
    # The chord from the root to the tip: the middle node's deflection is perpendicular to it.
    d = result.deflection(beam, 4, chord=(1, 7))
    assert d.shape == (len(result.time), 3)
    assert abs(d[-1, 2]) > 1e-5


def test_a_solid_has_no_section_forces():
    mesh = shapes.box((0.3, 0.04, 0.02), (6, 2, 2), "hex8")
    body = build_body(mesh.nodes, mesh.elements, STEEL, node_sets=mesh.node_sets,
                      reference="clamped", reference_nodes="x0")  # fmt: skip
    system = fm.System(gravity=(0.0, 0.0, -9.81))
    system.add_flexible_body(body, name="block")
    result = fm.simulate(system, 2e-3, 1e-3)
    with pytest.raises(fm.InvalidParameterError, match="no beam elements.*hex8.*stresses"):
        result.section_forces("block")
    assert result.stresses("block", records=[0, -1]).shape == (2, len(body.nodes), 6)
