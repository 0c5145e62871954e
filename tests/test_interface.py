"""Interfaces of deformable bodies (flexmbd.fe.interface): weights, centroids, axes, RBE3 and
RBE2 markers, Craig-Bampton interfaces with the same weights, and the errors of bad sets."""

from __future__ import annotations

import numpy as np
import pytest

import flexmbd as fm
import flexmbd.fe
from flexmbd.errors import InvalidModelError, InvalidParameterError, UnknownItemError
from flexmbd.fe import Material, build_body, shapes
from flexmbd.fe.interface import body_interface, interface_weights, make_interface

STEEL = Material(2.1e11, 0.3, 7850.0)


def graded_box(element: str):
    """A 0.3 x 0.04 x 0.02 box whose y spacing grows quadratically (straight-sided tet10
    from the graded tet4): the node average of its faces x0 and x1 is off their centres."""
    mesh = shapes.box((0.3, 0.04, 0.02), (6, 4, 3), "tet4" if element == "tet10" else element)
    mesh.nodes[:, 1] = 0.04 * (mesh.nodes[:, 1] / 0.04) ** 2
    if element == "tet10":
        nodes, tets = shapes.quadratic_tetrahedra(mesh.nodes, mesh.elements["tet4"])
        sets = {"all": np.arange(len(nodes))}
        for axis, name in enumerate("xyz"):
            low, high = nodes[:, axis].min(), nodes[:, axis].max()
            sets[f"{name}0"] = np.flatnonzero(np.abs(nodes[:, axis] - low) < 1e-12)
            sets[f"{name}1"] = np.flatnonzero(np.abs(nodes[:, axis] - high) < 1e-12)
        mesh = fm.fe.Mesh(
            nodes=nodes,
            node_ids=np.arange(1, len(nodes) + 1),
            elements={"tet10": tets},
            element_ids={"tet10": np.arange(1, len(tets) + 1)},
            node_sets=sets,
        )
    return mesh


@pytest.fixture(scope="module")
def link():
    """An unstructured Gmsh mesh (tet10) of a tapered link, graded in y so that its root face
    (40 x 20 mm, centred on the x axis) is meshed unevenly."""
    return shapes.tapered_link(
        0.3,
        (0.04, 0.02),
        (0.02, 0.01),
        size=0.02,
        order=2,
        tip_offset=(0.005, 0.0),
        size_field="0.006 + 2.0 * (y + 0.02) * (y + 0.02)",
    )


@pytest.mark.parametrize("element", ["hex8", "tet4", "tet10"])
def test_area_weighted_centroids_are_the_face_centroids_of_structured_meshes(element, assert_close):
    mesh = graded_box(element)
    for name, centre in {
        "x0": (0.0, 0.02, 0.01),
        "x1": (0.3, 0.02, 0.01),
        "z1": (0.15, 0.02, 0.02),
    }.items():
        interface = make_interface(mesh.nodes, mesh.elements, mesh.node_sets[name], name=name)
        assert interface.weighting == "area"
        assert_close(interface.centroid, centre, rel=1e-12, abs=1e-12 * 0.3, what=name)
    face = make_interface(mesh.nodes, mesh.elements, mesh.node_sets["x0"], name="x0")
    assert_close(face.measure, 0.04 * 0.02, rel=1e-12, what="area")
    # The plain average of the nodes is off the centre (what the marker used to be).
    assert abs(mesh.nodes[mesh.node_sets["x0"]].mean(axis=0)[1] - 0.02) > 1e-3
    volume = make_interface(mesh.nodes, mesh.elements, mesh.node_sets["all"], name="all")
    assert volume.weighting == "volume"
    assert_close(volume.measure, 0.3 * 0.04 * 0.02, rel=1e-12, what="volume")
    assert_close(volume.centroid, (0.15, 0.02, 0.01), rel=1e-12, what="centroid of the volume")


def test_area_weighted_centroids_are_the_face_centroids_of_an_unstructured_gmsh_mesh(
    link, assert_close
):
    root = make_interface(link.nodes, link.elements, link.node_sets["root"], name="root")
    tip = make_interface(link.nodes, link.elements, link.node_sets["tip"], name="tip")
    assert_close(root.measure, 0.04 * 0.02, rel=1e-12, what="root area")
    assert_close(tip.measure, 0.02 * 0.01, rel=1e-12, what="tip area")
    assert_close(root.centroid, (0.0, 0.0, 0.0), abs=1e-12 * 0.04, what="root centroid")
    assert_close(tip.centroid, (0.3, 0.005, 0.0), rel=1e-12, abs=1e-12 * 0.04, what="tip centroid")
    # Quadratic triangles: the corners carry no area, the mid-edge nodes a third of each.
    weights, kind = interface_weights(link.nodes, link.elements, link.node_sets["root"])
    assert kind == "area" and weights.min() == 0.0
    # The node average is well off the centre of this unevenly meshed face.
    assert np.linalg.norm(link.nodes[link.node_sets["root"]].mean(axis=0)) > 1e-4


def test_the_weighted_fit_recovers_rigid_motions_and_its_rows_equal_it(assert_close):
    mesh = graded_box("tet10")
    n = 3 * len(mesh.nodes)
    interface = make_interface(mesh.nodes, mesh.elements, mesh.node_sets["x1"], name="x1")
    velocity, spin = np.array([0.1, -0.2, 0.3]), np.array([0.01, -0.02, 0.015])
    u = velocity + np.cross(spin, mesh.nodes)  # a rigid motion about the origin
    expected = np.concatenate([velocity + np.cross(spin, interface.centroid), spin])
    rows = interface.average_rows(3, n)
    # Round-off: the rotation is a small difference of moments of arms of 1e-2 m about a
    # centroid 0.3 m from the origin, divided by H ~ 1e-4 m^2.
    assert_close(rows @ u.ravel(), expected, rel=1e-9, what="rows times a rigid motion")
    mean, rotation = interface.average(u[interface.members])
    assert_close(np.concatenate([mean, rotation]), expected, rel=1e-9, what="fit of a rigid motion")
    # A deformation: the rows equal the weighted sums they stand for.
    rng = np.random.default_rng(7)
    d = rng.standard_normal((len(mesh.nodes), 3))
    mean, rotation = interface.average(d[interface.members])
    fit = np.concatenate([mean, rotation])
    assert_close(rows @ d.ravel(), fit, rel=1e-12, what="rows times a deformation")
    w = interface.weights
    assert_close(mean, w @ d[interface.members], rel=1e-12, what="weighted mean")


def test_principal_axes_are_the_outward_normal_and_the_longest_extent(assert_close):
    mesh = graded_box("tet4")
    expected = {
        "x0": ((0, 1, 0), (-1, 0, 0)),
        "x1": ((0, 1, 0), (1, 0, 0)),
        "y1": ((1, 0, 0), (0, 1, 0)),
        "z0": ((1, 0, 0), (0, 0, -1)),
    }
    for name, (x, z) in expected.items():
        axes = make_interface(mesh.nodes, mesh.elements, mesh.node_sets[name]).principal_axes
        assert_close(axes[:, 0], x, rel=1e-7, abs=1e-12, what=f"{name} x axis")
        assert_close(axes[:, 2], z, rel=1e-7, abs=1e-12, what=f"{name} z axis")
        assert_close(axes.T @ axes, np.eye(3), rel=1e-7, abs=1e-12, what="A^T A")
        assert_close(np.linalg.det(axes), 1.0, rel=1e-6, abs=1e-12, what="det A")


def test_length_weights_on_edges_and_given_or_uniform_weights(assert_close):
    mesh = graded_box("hex8")
    x = mesh.nodes
    edge = np.flatnonzero((np.abs(x[:, 0]) < 1e-12) & (np.abs(x[:, 2]) < 1e-12))
    weights, kind = interface_weights(x, mesh.elements, edge)
    assert kind == "length"
    assert_close(weights.sum(), 0.04, rel=1e-12, what="edge length")
    face = mesh.node_sets["x0"]
    uniform = make_interface(x, mesh.elements, face, "uniform")
    assert_close(uniform.centroid, x[face].mean(axis=0), rel=1e-12, what="uniform centroid")
    given = np.arange(1.0, len(face) + 1.0)
    weighted = make_interface(x, mesh.elements, face, given)
    centroid = given @ x[face] / given.sum()
    assert_close(weighted.centroid, centroid, rel=1e-12, what="weighted centroid")


def test_bad_sets_and_weights_are_typed_errors_naming_the_set():
    mesh = graded_box("hex8")
    x, elements = mesh.nodes, mesh.elements
    with pytest.raises(InvalidModelError, match="'root'.*empty"):
        make_interface(x, elements, [], name="'root'")
    edge = np.flatnonzero((np.abs(x[:, 0]) < 1e-12) & (np.abs(x[:, 2]) < 1e-12))
    with pytest.raises(InvalidModelError, match="edge set.*one line"):
        make_interface(x, elements, edge, name="edge set")
    face = mesh.node_sets["x0"]
    with pytest.raises(InvalidModelError, match="face.*sum to 0"):
        make_interface(x, elements, face, np.zeros(len(face)), name="face")
    with pytest.raises(InvalidParameterError, match="face.*one per node"):
        make_interface(x, elements, face, np.ones(3), name="face")
    # A NaN weight was reported as a wrong shape.
    weights = np.ones(len(face))
    weights[2] = np.nan
    with pytest.raises(
        InvalidParameterError, match=f"face: weights must be finite, got nan for its node {face[2]}"
    ):
        make_interface(x, elements, face, weights, name="face")
    with pytest.raises(InvalidParameterError, match="face.*weights must be"):
        make_interface(x, elements, face, "mass", name="face")
    scattered = np.array([0, 40, 77, 101])
    with pytest.raises(InvalidModelError, match="scattered.*no face, edge or element"):
        make_interface(x, elements, scattered, name="scattered")
    with pytest.raises(InvalidModelError, match="face.*no elements"):
        make_interface(x, elements, face, "volume", name="face")
    # Weights of both signs that nearly cancel put the centroid far off the set (a beam's
    # marker 249 m off its 1 m length was accepted).
    cancelling = np.zeros(len(face))
    cancelling[[0, -1]] = 1.0, -0.999
    with pytest.raises(InvalidModelError, match="face: its weighted centroid .* nearly cancel"):
        make_interface(x, elements, face, cancelling, name="face")
    # Negative weights far out that make the second moment of the face indefinite were refused as
    # "nodes on one line" (found by a fault hunt).
    arms = np.linalg.norm(x[face] - x[face].mean(axis=0), axis=1)
    corners = np.where(arms > 0.99 * arms.max(), -2.0, 1.0)
    with pytest.raises(
        InvalidModelError, match=r"face: its weights \(2 of 20 negative, down to -2\) make"
    ):
        make_interface(x, elements, face, corners, name="face")


def test_node_set_markers_sit_at_the_weighted_centroid_and_take_principal_axes(link, assert_close):
    body = build_body(link.nodes, link.elements, STEEL, node_sets=link.node_sets)
    system = fm.System()
    arm = system.add_flexible_body(body, name="arm")
    system.add_node_set_marker(arm, "root", orientation="principal", name="root")
    system.add_node_set_marker(arm, "root", weights="uniform", name="plain")
    frames = {m["name"]: m for m in system.compile().describe()["markers"]}
    assert_close(frames["root"]["position"], (0, 0, 0), abs=1e-12 * 0.04, what="root position")
    root_z = np.asarray(frames["root"]["orientation"])[:, 2]
    assert_close(root_z, (-1, 0, 0), rel=1e-7, what="root z axis")
    assert np.linalg.norm(frames["plain"]["position"]) > 1e-4
    assert_close(frames["plain"]["orientation"], np.eye(3), rel=1e-7, what="plain orientation")
    interface = body_interface(body, "root")
    assert_close(interface.centroid, (0, 0, 0), abs=1e-12 * 0.04, what="centroid")
    z_axis = interface.principal_axes[:, 2]
    assert_close(z_axis, (-1, 0, 0), rel=1e-7, abs=1e-12, what="principal z axis")
    with pytest.raises(UnknownItemError, match="no node set 'hub'"):
        system.add_node_set_marker(arm, "hub")
    with pytest.raises(InvalidParameterError, match="coupling"):
        system.add_node_set_marker(arm, "root", coupling="rbe4")


def test_rbe2_needs_a_rigid_set_and_craig_bampton_modes_keep_it():
    mesh = shapes.box((0.3, 0.04, 0.02), (10, 2, 2), "hex8")
    common = {"node_sets": mesh.node_sets, "modes": "craig-bampton", "mode_count": 4}
    rigid = build_body(
        mesh.nodes, mesh.elements, STEEL, reference="interface", interfaces=["x0", "x1"], **common
    )
    averaged = build_body(
        mesh.nodes,
        mesh.elements,
        STEEL,
        reference="interface",
        interfaces=["x0", "x1"],
        interface_kind="rbe3",
        **common,
    )
    nodal = build_body(mesh.nodes, mesh.elements, STEEL, node_sets=mesh.node_sets)
    clamped = build_body(
        mesh.nodes,
        mesh.elements,
        STEEL,
        node_sets=mesh.node_sets,
        reference="clamped",
        reference_nodes="x0",
    )
    system = fm.System()
    ids = {
        name: system.add_flexible_body(body, name=name)
        for name, body in {
            "rigid": rigid,
            "averaged": averaged,
            "nodal": nodal,
            "clamped": clamped,
        }.items()
    }
    system.add_node_set_marker(ids["rigid"], "x1", coupling="rbe2")
    system.add_node_set_marker(ids["clamped"], "x0", coupling="rbe2")
    for name in ("averaged", "nodal"):
        with pytest.raises(InvalidModelError, match="x1.*rbe2.*deform"):
            system.add_node_set_marker(ids[name], "x1", coupling="rbe2")


@pytest.mark.parametrize("kind", ["rbe2", "rbe3"])
def test_craig_bampton_bodies_do_not_depend_on_the_length_unit(kind, assert_close):
    """The same link in metres and shrunk 1000-fold (a millimetre part given in metres): the
    interface rotations weigh 1e-6 of the translations in M there, and must still count. The
    frequencies scale as 1 / length (same material), the coordinate count not at all."""
    mesh = shapes.box((0.3, 0.04, 0.02), (10, 2, 2), "hex8")
    frequencies = {}
    for scale in (1.0, 1e-3):
        body = build_body(
            mesh.nodes * scale,
            mesh.elements,
            STEEL,
            node_sets=mesh.node_sets,
            reference="interface",
            modes="craig-bampton",
            mode_count=4,
            interfaces=["x0", "x1"],
            interface_kind=kind,
        )
        assert body.elastic_coordinate_count == 4 + 6, scale
        frequencies[scale] = body.frequencies * scale
    assert_close(frequencies[1e-3], frequencies[1.0], rel=1e-6, what="frequency x length")


def test_craig_bampton_averaged_interfaces_use_the_weights_of_the_markers(assert_close):
    mesh = graded_box("tet10")
    body = build_body(
        mesh.nodes,
        mesh.elements,
        STEEL,
        node_sets=mesh.node_sets,
        reference="interface",
        modes="craig-bampton",
        mode_count=4,
        interfaces=["x0", "x1"],
        interface_kind="rbe3",
    )
    stored = body.reference["interface_weights"]
    assert len(stored) == 2
    x0 = body_interface(body, "x0")
    area = make_interface(mesh.nodes, mesh.elements, mesh.node_sets["x0"])
    assert_close(x0.weights, area.weights, rel=1e-12, what="weights")
    # The body frame follows the weighted average motion of x0: every mode leaves it at 0.
    full = np.zeros((body.dof_count, body.modes.shape[1]))
    full[body.reference["free_dofs"]] = body.modes
    rows = x0.average_rows(3, body.dof_count)
    assert_close(rows @ full, 0.0, abs=1e-10 * np.abs(full).max(), what="average motion of x0")
    # ... while the uniform average of the same nodes moves.
    plain = make_interface(mesh.nodes, {}, mesh.node_sets["x0"], "uniform")
    assert np.abs(plain.average_rows(3, body.dof_count) @ full).max() > 1e-4 * np.abs(full).max()
