"""Pyramids ("pyramid5": Gmsh's and VTK's pyramid, Nastran's CPYRAM of 5 grids) in bodies: the
transition cells Gmsh puts between hexahedra and tetrahedra, a pyramid on a hexahedron, interfaces
on their faces and in their volume, stresses, VTK output and model files. The element kernel's
tests (rules, moments, mass fractions, patch tests, rigid-body modes, conformity with
tetrahedra and hexahedra) are in `crates/flexmbd-core/src/fem/solid/tests`; invariants, kinetic
energy and rigid motions of box meshes in tests/test_solids.py (its SOLIDS); CPYRAM in
tests/test_nastran.py."""

import meshio
import numpy as np
import pytest
from test_wedges import STEEL, check_model_file, first_frame, interface_body

import flexmbd.fe.preprocess as pp
from flexmbd.errors import InvalidModelError
from flexmbd.fe import shapes
from flexmbd.fe.mesh_io import read_mesh
from flexmbd.fe.stress import recover_stresses


def hex_and_tet_blocks(path):
    """A Gmsh mesh of a 1 x 0.2 x 0.2 bar: hexahedra in its first half (transfinite), Gmsh's
    tetrahedra in the other, and the pyramids Gmsh puts on the quadrilaterals between them;
    physical groups "x0" and "x1" on the end faces."""
    import gmsh

    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        first = gmsh.model.occ.addBox(0, 0, 0, 0.5, 0.2, 0.2)
        second = gmsh.model.occ.addBox(0.5, 0, 0, 0.5, 0.2, 0.2)
        gmsh.model.occ.fragment([(3, first)], [(3, second)])
        gmsh.model.occ.synchronize()
        volumes = [tag for _, tag in gmsh.model.getEntities(3)]
        hexahedra = min(volumes, key=lambda tag: gmsh.model.occ.getCenterOfMass(3, tag)[0])
        for dim, tag in gmsh.model.getBoundary([(3, hexahedra)], False, False, True):
            if dim == 1:
                gmsh.model.mesh.setTransfiniteCurve(tag, 5)
        for _, tag in gmsh.model.getBoundary([(3, hexahedra)], False, False):
            gmsh.model.mesh.setTransfiniteSurface(tag)
            gmsh.model.mesh.setRecombine(2, tag)
        gmsh.model.mesh.setTransfiniteVolume(hexahedra)
        gmsh.option.setNumber("Mesh.MeshSizeMax", 0.06)
        gmsh.model.addPhysicalGroup(3, volumes, name="bar")
        for _, tag in gmsh.model.getEntities(2):
            x = gmsh.model.occ.getCenterOfMass(2, tag)[0]
            if abs(x) < 1e-9 or abs(x - 1.0) < 1e-9:
                gmsh.model.addPhysicalGroup(2, [tag], name="x0" if x < 0.5 else "x1")
        gmsh.model.mesh.generate(3)
        gmsh.write(str(path))
    finally:
        gmsh.finalize()


def test_gmsh_transition_pyramids_make_a_whole_bar(tmp_path, assert_close):
    # Gmsh's mesh of hexahedra next to tetrahedra has pyramids between them; they were refused,
    # so such a mesh could not be used at all. Read, the bar has its whole mass, and as a
    # cantilever (clamped at x0, 1 kN across at x1) it bends to within 10 % of Timoshenko's
    # beam (linear elements on a coarse mesh: stiffer).
    pytest.importorskip("gmsh")
    hex_and_tet_blocks(tmp_path / "bar.msh")
    mesh = read_mesh(tmp_path / "bar.msh")
    assert sorted(mesh.elements) == ["hex8", "pyramid5", "tet4"]
    assert len(mesh.elements["pyramid5"]) >= 4
    body = pp.build_body(
        mesh.nodes, mesh.elements, STEEL, node_sets=mesh.node_sets, reference="clamped",
        reference_nodes="x0",
    )  # fmt: skip
    assert_close(body.invariants.mass, 7800.0 * 0.04, rel=1e-12, what="mass")
    tip = mesh.node_sets["x1"]
    forces = np.zeros(body.dof_count)
    forces[3 * tip + 2] = 1000.0 / len(tip)
    w = pp.static_displacements(body, forces)[3 * tip + 2].mean()
    e, g, area, inertia = 2.1e11, 2.1e11 / 2.6, 0.04, 0.2**4 / 12
    beam = 1000.0 / (3 * e * inertia) + 1000.0 / (5 / 6 * g * area)
    assert -0.10 < w / beam - 1 < 0.0


def pyramid_on_a_hexahedron(apex_height):
    """A unit hexahedron with a pyramid on its top face, the apex `apex_height` above the
    face's centre (below it when negative: the pyramid is then inverted)."""
    corners = np.array(shapes.HEX8_CORNERS, dtype=float)
    apex = np.array([0.5, 0.5, 1.0 + apex_height])
    hexahedron = np.arange(8)[None]
    return meshio.Mesh(np.vstack([corners, apex]), [
        ("hexahedron", hexahedron), ("pyramid", np.array([[4, 5, 6, 7, 8]])),
    ])  # fmt: skip


def test_a_pyramid_on_a_hexahedron_and_an_inverted_one(tmp_path, assert_close):
    # (Such a "bracket" from a VTK file was refused.) The mass is the cube's and the
    # pyramid's (base 1, height 0.5: 1/6); the apex below the top face is an inverted
    # pyramid, named.
    meshio.write(tmp_path / "roof.vtu", pyramid_on_a_hexahedron(0.5))
    mesh = read_mesh(tmp_path / "roof.vtu")
    body = pp.body_from_mesh(mesh, STEEL)
    assert_close(body.invariants.mass, 7800.0 * (1 + 0.5 / 3), rel=1e-12, what="mass")
    meshio.write(tmp_path / "inverted.vtu", pyramid_on_a_hexahedron(-0.5))
    with pytest.raises(InvalidModelError, match="inverted.*pyramid5"):
        pp.body_from_mesh(read_mesh(tmp_path / "inverted.vtu"), STEEL)


def test_interfaces_on_their_bases_and_in_their_volume(assert_close):
    # The end faces of box('pyramid5') are the bases of pyramids: the quadrilaterals of
    # hex8's faces, so the same weights node by node.
    def weights(element, face):
        mesh, body = interface_body(element, [face])
        return mesh, body.reference.interfaces[0], body.reference.interface_weights[0]

    mesh, members, quads = weights("pyramid5", "x1")
    _, hex_members, hexes = weights("hex8", "x1")
    np.testing.assert_array_equal(members, hex_members)
    assert_close(quads, hexes, rel=1e-12, what="x1 weights")
    # Volume weights of one right pyramid (base 2 x 2, height 1.5): int N_a dV = 3/16 of the
    # volume at a base node and 1/4 at the apex (sympy, independent of the element code),
    # and the interface's centroid is the pyramid's (a quarter of the height up).
    from flexmbd.fe.interface import interface_weights

    nodes = np.array([[0, 0, 0], [2, 0, 0], [2, 2, 0], [0, 2, 0], [1, 1, 1.5]], dtype=float)
    volume = 4 * 1.5 / 3
    cells = {"pyramid5": np.array([[0, 1, 2, 3, 4]])}
    w, weighting = interface_weights(nodes, cells, np.arange(5), "volume")
    assert weighting == "volume"
    assert_close(w, volume * np.array([3, 3, 3, 3, 4]) / 16, rel=1e-13, what="volume weights")
    assert_close(w @ nodes / w.sum(), [1, 1, 1.5 / 4], abs=1e-14, what="centroid")


def test_stresses_of_uniaxial_tension_are_uniform(assert_close):
    # A bar of pyramids stretched by a linear field u_x = eps x, free to contract: the
    # stress is E eps along x and zero otherwise at every node of every element (the apex
    # included, where the gradients are the limits along the axis).
    mesh = shapes.box((1.0, 0.2, 0.3), (4, 2, 2), "pyramid5")
    body = pp.build_body(mesh.nodes, mesh.elements, STEEL)
    eps, nu = 1e-4, 0.3
    u = np.column_stack([eps * mesh.nodes[:, 0], -nu * eps * mesh.nodes[:, 1],
                         -nu * eps * mesh.nodes[:, 2]])  # fmt: skip
    stresses, _ = recover_stresses(body, u.ravel())
    expected = np.zeros(6)
    expected[0] = 2.1e11 * eps
    assert_close(stresses, np.broadcast_to(expected, stresses.shape), abs=1e-9 * expected[0])


def test_vtk_output_and_model_files(tmp_path, assert_close):
    mesh, body, path = first_frame("pyramid5", tmp_path / "frames")
    frame = meshio.read(path)
    pyramids = [c.data for c in frame.cells if c.type == "pyramid"]
    np.testing.assert_array_equal(np.vstack(pyramids), mesh.elements["pyramid5"])
    np.testing.assert_array_equal(read_mesh(path).elements["pyramid5"], mesh.elements["pyramid5"])
    check_model_file("pyramid5", body, tmp_path, assert_close)


def test_drawn_surfaces_are_the_bases_on_the_boundary():
    # The animation draws the faces of one element only: for a box of pyramids, the bases
    # on its faces, which are the hexahedra's boundary quadrilaterals (the triangles inside).
    from types import SimpleNamespace

    from flexmbd.animation import _boundary_faces

    def faces(element):
        mesh = shapes.box((1.0, 0.5, 0.4), (3, 2, 2), element)
        found = _boundary_faces(SimpleNamespace(data=SimpleNamespace(elements=mesh.elements)))
        assert all(len(group) == 0 for group in found if group.shape[1] == 3)
        quads = np.concatenate([group for group in found if group.shape[1] == 4])
        return sorted(map(tuple, np.sort(quads, axis=1).tolist()))

    assert len(faces("hex8")) == 2 * (3 * 2 + 2 * 2 + 3 * 2)
    assert faces("pyramid5") == faces("hex8")
