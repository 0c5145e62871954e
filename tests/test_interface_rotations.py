"""Interfaces of bodies whose nodes have rotational coordinates (beams and shells): a line of
nodes (a shell's edge, a beam's segment) or a single node is an RBE3 interface whose rotation
about the line is the weighted mean of the nodes' rotations (flexmbd.fe.interface)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.special import ellipk

import flexmbd as fm
from flexmbd.errors import InvalidModelError
from flexmbd.fe import Material, Section, build_body, shapes
from flexmbd.fe.interface import body_interface, make_interface
from flexmbd.fe.modal import craig_bampton

ALUMINIUM = Material(7e10, 0.3, 2700.0)
RNG = np.random.default_rng(7)


def rigid_field(nodes: np.ndarray, a: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Nodal coordinates (six per node) of the small rigid motion u = a + w x x, phi = w."""
    u = np.zeros((len(nodes), 6))
    u[:, :3] = a + np.cross(w, nodes)
    u[:, 3:] = w
    return u.ravel()


def straight_beam(nodes: np.ndarray, section: Section, **options):
    """A beam of two-node elements through `nodes` in order, sections' y axis across."""
    count = len(nodes) - 1
    connectivity = {"beam2": np.c_[np.arange(count), np.arange(1, count + 1)]}
    axis = (0.0, 0.0, 1.0)
    return build_body(nodes, connectivity, ALUMINIUM, section=section, orientation=axis, **options)


def shell_plate(reference: str = "none", **options):
    mesh = shapes.plate((0.3, 0.1), (6, 2), "quad4")
    data = build_body(
        mesh.nodes,
        mesh.elements,
        ALUMINIUM,
        shell=2e-3,
        node_sets=mesh.node_sets,
        node_ids=mesh.node_ids,
        reference=reference,
        **options,
    )
    return mesh, data


def test_a_shell_edge_follows_rigid_motions_and_averages_the_nodal_rotations_about_it(
    assert_close,
):
    mesh, data = shell_plate()
    edge = body_interface(data, "y0")  # the nodes at y = 0: a line along x
    assert edge.free_axes.shape == (3, 1)
    assert_close(np.abs(edge.free_axes[:, 0]), [1.0, 0.0, 0.0], abs=1e-12, what="free axis")
    rows = edge.average_rows(6, data.dof_count).toarray()
    for _ in range(3):
        a, w = RNG.normal(size=3), RNG.normal(size=3)
        motion = rows @ rigid_field(data.nodes, a, w)
        assert_close(motion[:3], a + np.cross(w, edge.centroid), rel=1e-12, what="u_c")
        assert_close(motion[3:], w, rel=1e-12, abs=1e-12, what="theta")
    # Nodal rotations alone: about the line their weighted mean (length weights: the end
    # nodes carry half the inner nodes' weight), across it nothing.
    phi = np.zeros((len(data.nodes), 6))
    phi[:, 3:] = RNG.normal(size=(len(data.nodes), 3))
    members = edge.members
    inner = np.abs(data.nodes[members, 0] - data.nodes[members, 0].mean()) < 0.15 - 1e-9
    weights = np.where(inner, 1.0, 0.5)
    mean = weights @ phi[members, 3] / weights.sum()
    assert_close(rows @ phi.ravel(), [0, 0, 0, mean, 0, 0], abs=1e-12, what="theta of phi")


@pytest.mark.parametrize("nodes", [[0, 1, 2], [3]])
def test_a_beam_segment_or_node_has_the_rotation_of_its_nodes(nodes, assert_close):
    x = np.linspace(0.0, 1.0, 6)
    beam_nodes = np.c_[x, 0.2 * x, 0.1 * x]  # an oblique straight beam
    data = straight_beam(beam_nodes, Section(3e-4, 2e-8, 5e-8, 3e-8), reference="none")
    interface = body_interface(data, nodes, ids=False)
    assert interface.free_axes.shape == (3, 1 if len(nodes) > 1 else 3)
    rows = interface.average_rows(6, data.dof_count).toarray()
    a, w = RNG.normal(size=3), RNG.normal(size=3)
    motion = rows @ rigid_field(data.nodes, a, w)
    assert_close(motion, np.r_[a + np.cross(w, interface.centroid), w], rel=1e-12, abs=1e-12)
    if len(nodes) == 1:
        # One node: the node's own six coordinates.
        expected = np.zeros((6, data.dof_count))
        expected[:, 6 * nodes[0] : 6 * nodes[0] + 6] = np.eye(6)
        assert_close(rows, expected, abs=1e-14, what="rows of one node")


def test_without_rotational_coordinates_a_line_is_still_refused():
    mesh = shapes.box((0.3, 0.04, 0.02), (6, 2, 2), "hex8")
    data = build_body(mesh.nodes, mesh.elements, ALUMINIUM, reference="none")
    line = np.flatnonzero((np.abs(data.nodes[:, 1]) < 1e-12) & (np.abs(data.nodes[:, 2]) < 1e-12))
    with pytest.raises(InvalidModelError, match="on one line"):
        body_interface(data, line, ids=False)
    # Sets that define a rotation use the translations only, with rotational coordinates or
    # without.
    face = np.flatnonzero(np.abs(data.nodes[:, 0]) < 1e-12)
    plain = make_interface(data.nodes, data.elements, face)
    turned = make_interface(data.nodes, data.elements, face, nodal_rotations=True)
    assert plain.free_axes.shape == turned.free_axes.shape == (3, 0)
    count = len(data.nodes)
    six = turned.average_rows(6, 6 * count).toarray().reshape(6, count, 6)
    three = plain.average_rows(3, 3 * count).toarray().reshape(6, count, 3)
    np.testing.assert_array_equal(six[:, :, :3], three)
    assert not six[:, :, 3:].any()


def test_a_one_node_set_marker_of_a_beam_is_its_node_marker(assert_close):
    x = np.linspace(0.0, 0.5, 9)
    data = straight_beam(
        np.c_[x, 0 * x, 0 * x],
        Section(2e-5, 1.7e-11, 1.7e-11, 3.3e-11),
        reference="clamped",
        reference_nodes=[0],
        modes="fixed-interface",
        mode_count=4,
    )
    tips = []
    for way in ("node", "set"):
        system = fm.System(gravity=(0.0, 0.0, -9.81))
        beam = system.add_flexible_body(data, name="beam")
        axis_y = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
        tip_id = int(data.node_ids[-1])
        marker = (
            system.add_node_marker(beam, tip_id, orientation=axis_y)
            if way == "node"
            else system.add_node_set_marker(beam, [tip_id], orientation=axis_y)
        )
        system.add_revolute_joint(
            system.add_marker(system.ground, position=(0.5, 0.0, 0.0), orientation=axis_y),
            marker,
            name="hinge",
        )
        result = fm.simulate(system, 0.05, 1e-4, output_interval=0.01)
        tips.append(np.c_[result.position("beam"), result.elastic_coordinates("beam")])
    assert_close(tips[1], tips[0], rel=1e-12, abs=1e-13, what="the two hinged beams")


def test_rbe3_craig_bampton_of_one_beam_node_is_the_rbe2_basis(assert_close):
    x = np.linspace(0.0, 1.0, 11)
    nodes = np.c_[x, 0 * x, 0 * x]
    data = straight_beam(nodes, Section(2e-4, 1.7e-9, 2.5e-9, 3.3e-9), reference="none")
    frequencies = {}
    for kind in ("rbe2", "rbe3"):
        _, frequencies[kind] = craig_bampton(
            data.stiffness,
            data.mass,
            [[0], [10]],
            6,
            nodes=nodes,
            dofs_per_node=6,
            kind=kind,
            reference="interface",
        )
    # One node moves rigidly with itself: both kinds span the same space.
    assert_close(frequencies["rbe3"], frequencies["rbe2"], rel=1e-8, what="frequencies")


def test_a_shell_panel_hinged_along_its_edge_falls_as_a_compound_pendulum(assert_close):
    # A 0.3 x 0.1 m panel (free-free modes), hinged along its edge y = 0 (the global x axis)
    # through an RBE3 marker on the edge, released horizontal: it reaches the bottom after a
    # quarter period of the compound pendulum, sqrt(I / (m g d)) K(sin 45 deg) with
    # I = m b^2 / 3 and d = b / 2 (b = 0.1 m its width).
    _, data = shell_plate("mean-axis", modes="free-free", mode_count=6)
    system = fm.System(gravity=(0.0, 0.0, -9.81))
    panel = system.add_flexible_body(data, name="panel")
    axis_x = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
    edge = system.add_node_set_marker(panel, "y0", orientation=axis_x, name="edge")
    system.add_revolute_joint(
        system.add_marker(system.ground, position=(0.15, 0.0, 0.0), orientation=axis_x),
        edge,
        name="hinge",
    )
    b, g = 0.1, 9.81
    quarter = np.sqrt(2.0 * b / (3.0 * g)) * ellipk(0.5)  # K(k^2 = sin^2 45 deg)
    result = fm.simulate(system, 1.2 * quarter, 2e-5, output_interval=2e-5)
    centre_y = result.node_positions("panel").mean(axis=1)[:, 1]  # uniform mesh: the centroid
    assert_close(centre_y[0], b / 2, rel=1e-12, what="start")
    bottom = result.time[np.argmin(np.abs(centre_y))]
    assert_close(bottom, quarter, rel=1e-3, what="time to the bottom")
