"""Rotating cantilever: flap frequencies against reference R2 (Wright et al. 1982, via Bir
2009), with and without the geometric stiffness of the centrifugal tension (seed section 6,
elastic coupling), from the linearization about the steadily rotating, stretched blade."""

from __future__ import annotations

import numpy as np
import pytest

import flexmbd as fm
from flexmbd.fe import Material, Section, build_body, straight_beam

# R2: nondimensional rotation speed g and the first three flap frequencies.
R2 = {
    0: (3.5160, 22.0345, 61.6972),
    4: (5.5850, 24.2733, 63.9668),
    8: (9.2568, 29.9954, 70.2930),
    12: (13.1702, 37.6031, 79.6145),
}

LENGTH = 1.0
WIDTH, HEIGHT = 0.01, 0.002  # slender: rotary inertia of the section negligible
MATERIAL = Material(7.0e10, 0.3, 2700.0)
EI_FLAP = MATERIAL.young_modulus * WIDTH * HEIGHT**3 / 12  # bending in z (flap)
RHO_A = MATERIAL.density * WIDTH * HEIGHT
SCALE = np.sqrt(RHO_A * LENGTH**4 / EI_FLAP)  # w_bar = w * SCALE


def flap_frequencies(g: float, geometric_stiffness: bool, elements: int = 40) -> np.ndarray:
    """First three nondimensional flap frequencies of the blade turning at g about z."""
    nodes, conn = straight_beam(LENGTH, elements)
    data = build_body(
        nodes,
        conn,
        MATERIAL,
        section=Section.rectangle(WIDTH, HEIGHT),  # iy = WIDTH HEIGHT^3 / 12 (flap)
        orientation=(0.0, 1.0, 0.0),
        reference="clamped",
        reference_nodes=[0],
    )
    speed = g / SCALE
    system = fm.System()
    blade = system.add_flexible_body(data, geometric_stiffness=geometric_stiffness)
    hub, root = system.add_marker(system.ground), system.add_node_marker(blade, 1)
    system.add_revolute_joint(hub, root)
    system.add_angle_driver(hub, root, fm.Polynomial([0.0, speed]))
    state = fm.equilibrium(system)
    frequencies, shapes = fm.linearize(system, state).modes()
    # Flap modes: the translations of the nodes are along z (the axis of rotation).
    offset = 7
    translations = np.concatenate(
        [offset + 6 * (k - 1) + np.arange(3) for k in range(1, elements + 1)]
    )
    moved = shapes[translations].reshape(elements, 3, -1)
    along_z = np.sum(moved[:, 2] ** 2, axis=0) / np.sum(moved**2, axis=(0, 1))
    flap = frequencies[along_z > 0.99]
    return 2 * np.pi * flap[:3] * SCALE


def test_section_is_oriented_for_flap_bending():
    assert EI_FLAP < MATERIAL.young_modulus * HEIGHT * WIDTH**3 / 12


@pytest.mark.parametrize("g", sorted(R2))
def test_flap_frequencies_with_geometric_stiffness_match_r2(g):
    computed = flap_frequencies(g, geometric_stiffness=True)
    np.testing.assert_allclose(computed, R2[g], rtol=1e-3)


def test_without_geometric_stiffness_the_flap_frequency_does_not_stiffen():
    computed = flap_frequencies(12, geometric_stiffness=False)
    assert computed[0] == pytest.approx(R2[0][0], rel=1e-3)
