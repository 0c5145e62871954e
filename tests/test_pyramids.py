"""Pyramids ("pyramid5": Gmsh's and VTK's pyramid, Nastran's CPYRAM of 5 grids; "pyramid13",
"pyramid14": Gmsh's and VTK's 13-node pyramid, Gmsh's 14-node one) in bodies: the transition cells
Gmsh puts between hexahedra and tetrahedra (at order 1 and 2), a pyramid on a hexahedron,
interfaces on their faces and in their volume, stresses, VTK output and model files. The element
kernel's tests (rules, moments, mass fractions, patch tests, rigid-body modes, conformity with
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


def hex_and_tet_blocks(path, order=1, incomplete=False):
    """A Gmsh mesh of a 1 x 0.2 x 0.2 bar: hexahedra in its first half (transfinite), Gmsh's
    tetrahedra in the other, and the pyramids Gmsh puts on the quadrilaterals between them;
    physical groups "x0" and "x1" on the end faces. Of `order` 2: complete (hex27, tet10,
    pyramid14, Gmsh's default) or `incomplete` (Mesh.SecondOrderIncomplete: hex20, tet10,
    pyramid13)."""
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
        gmsh.option.setNumber("Mesh.SecondOrderIncomplete", int(incomplete))
        gmsh.model.mesh.generate(3)
        gmsh.model.mesh.setOrder(order)
        gmsh.write(str(path))
    finally:
        gmsh.finalize()


def cantilever_deflection(mesh):
    """Mean deflection of the end face x1 of a mesh of the bar, clamped at x0, under 1 kN
    across (z) spread over the end face's nodes, and Timoshenko's beam deflection."""
    body = pp.build_body(
        mesh.nodes, mesh.elements, STEEL, node_sets=mesh.node_sets, reference="clamped",
        reference_nodes="x0",
    )  # fmt: skip
    tip = mesh.node_sets["x1"]
    forces = np.zeros(body.dof_count)
    forces[3 * tip + 2] = 1000.0 / len(tip)
    w = pp.static_displacements(body, forces)[3 * tip + 2].mean()
    e, g, area, inertia = 2.1e11, 2.1e11 / 2.6, 0.04, 0.2**4 / 12
    return w, 1000.0 / (3 * e * inertia) + 1000.0 / (5 / 6 * g * area), body


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
    w, beam, body = cantilever_deflection(mesh)
    assert_close(body.invariants.mass, 7800.0 * 0.04, rel=1e-12, what="mass")
    assert -0.10 < w / beam - 1 < 0.0


@pytest.mark.parametrize(
    "incomplete, elements", [(False, ["hex27", "pyramid14", "tet10"]),
                             (True, ["hex20", "pyramid13", "tet10"])],
)  # fmt: skip
def test_gmsh_transition_pyramids_of_order_2(tmp_path, incomplete, elements, assert_close):
    # The same bar at order 2: Gmsh's 14-node pyramids (13-node ones with
    # Mesh.SecondOrderIncomplete) were refused, so such a mesh could not be used. Read, every
    # node is where the element's order puts it (meshio converts Gmsh's 13-node pyramid to
    # VTK's order, not the 14-node one), the bar has its whole mass and bends like the
    # converged solid: -1.48 % (complete) and -1.58 % (incomplete) of Timoshenko's beam,
    # against -1.39 % for 30 x 6 x 6 hex27 of the same bar (this stubby bar's nodal clamp
    # also holds the cross-section's contraction: stiffer than the beam's built-in end) and
    # -6.94 % for the linear mesh.
    from flexmbd.fe.shapes import PYRAMID13_EDGES

    pytest.importorskip("gmsh")
    hex_and_tet_blocks(tmp_path / "bar.msh", order=2, incomplete=incomplete)
    mesh = read_mesh(tmp_path / "bar.msh")
    assert sorted(mesh.elements) == elements
    kind = elements[1]
    cells, x = mesh.elements[kind], mesh.nodes
    assert len(cells) >= 4
    for e, (p, q) in enumerate(PYRAMID13_EDGES):
        assert_close(x[cells[:, 5 + e]], 0.5 * (x[cells[:, p]] + x[cells[:, q]]), abs=1e-15)
    if kind == "pyramid14":
        assert_close(x[cells[:, 13]], x[cells[:, :4]].mean(axis=1), abs=1e-15)
    w, beam, body = cantilever_deflection(mesh)
    assert_close(body.invariants.mass, 7800.0 * 0.04, rel=1e-12, what="mass")
    assert -0.017 < w / beam - 1 < -0.0139


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


def quadratic_pyramid_on_a_hexahedron(apex_height, centre):
    """`pyramid_on_a_hexahedron` with mid-edge nodes (a pyramid13) and, with `centre`, the
    base's centre (a pyramid14: meshio's pyramid14 cells are in Gmsh's order)."""
    from flexmbd.fe.mesh_io import PYRAMID14_FROM_GMSH
    from flexmbd.fe.shapes import PYRAMID13_EDGES

    linear = pyramid_on_a_hexahedron(apex_height)
    corners = linear.points[linear.cells[1].data[0]]
    middles = [0.5 * (corners[p] + corners[q]) for p, q in PYRAMID13_EDGES]
    extra = middles + ([corners[:4].mean(axis=0)] if centre else [])
    points = np.vstack([linear.points, extra])
    pyramid = np.concatenate([linear.cells[1].data[0], 9 + np.arange(len(extra))])
    if centre:  # (our order into Gmsh's: the inverse permutation)
        pyramid = pyramid[np.argsort(PYRAMID14_FROM_GMSH)]
    cell = "pyramid14" if centre else "pyramid13"
    return meshio.Mesh(points, [("hexahedron", linear.cells[0].data), (cell, pyramid[None])])


def test_quadratic_pyramids_on_a_hexahedron_and_inverted_ones(tmp_path, assert_close):
    # A 13-node pyramid on a hexahedron (VTK) and a 14-node one (Gmsh) were refused ("mesh the
    # transition at order 1"); read, the mass is the cube's and the pyramid's, and the
    # pyramids with their apex below the top face are inverted, named.
    from flexmbd.errors import InvalidModelError as Invalid

    for centre, suffix, file_format in ((False, "vtu", "vtu"), (True, "msh", "gmsh22")):
        name = "pyramid14" if centre else "pyramid13"
        path = tmp_path / f"roof.{suffix}"
        meshio.write(path, quadratic_pyramid_on_a_hexahedron(0.5, centre), file_format)
        mesh = read_mesh(path)
        assert sorted(mesh.elements) == ["hex8", name]
        body = pp.body_from_mesh(mesh, STEEL)
        assert_close(body.invariants.mass, 7800.0 * (1 + 0.5 / 3), rel=1e-12, what=name)
        path = tmp_path / f"inverted.{suffix}"
        meshio.write(path, quadratic_pyramid_on_a_hexahedron(-0.5, centre), file_format)
        with pytest.raises(Invalid, match=f"inverted.*{name}"):
            pp.body_from_mesh(read_mesh(path), STEEL)


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
    # The quadratic ones: their bases are hex20's and hex27's faces (the same weights node by
    # node), and their volume weights int N_a dV / V the row sums of sympy's integrals
    # (pyramid13: -7/80 at a base corner, -1/20 at the apex, 1/5 at a base edge's node, 3/20
    # at an apex edge's; pyramid14: -1/48, -1/20, 1/15, 3/20 and 4/15 at the base's centre).
    from flexmbd.fe.shapes import PYRAMID13_EDGES

    for kind, hexahedron in (("pyramid13", "hex20"), ("pyramid14", "hex27")):
        mesh, members, quads = weights(kind, "x1")
        hex_mesh, hex_members, hexes = weights(hexahedron, "x1")
        order = np.lexsort(mesh.nodes[members].T)
        hex_order = np.lexsort(hex_mesh.nodes[hex_members].T)
        assert_close(mesh.nodes[members][order], hex_mesh.nodes[hex_members][hex_order], abs=1e-15)
        assert_close(quads[order], hexes[hex_order], rel=1e-12, what=f"{kind} x1 weights")
    quadratic = np.vstack([nodes, [0.5 * (nodes[p] + nodes[q]) for p, q in PYRAMID13_EDGES],
                           [[1, 1, 0]]])  # fmt: skip
    fractions = {
        "pyramid13": [-7 / 80] * 4 + [-1 / 20] + [1 / 5] * 4 + [3 / 20] * 4,
        "pyramid14": [-1 / 48] * 4 + [-1 / 20] + [1 / 15] * 4 + [3 / 20] * 4 + [4 / 15],
    }
    for kind, expected in fractions.items():
        count = len(expected)
        cells = {kind: np.arange(count)[None]}
        w, _ = interface_weights(quadratic[:count], cells, np.arange(count), "volume")
        assert_close(w, volume * np.array(expected), rel=1e-12, abs=1e-15, what=kind)


@pytest.mark.parametrize("element", ["pyramid5", "pyramid13", "pyramid14"])
def test_stresses_of_uniaxial_tension_are_uniform(element, assert_close):
    # A bar of pyramids stretched by a linear field u_x = eps x, free to contract: the
    # stress is E eps along x and zero otherwise at every node of every element (the apex
    # included, where the gradients are the limits along the axis).
    mesh = shapes.box((1.0, 0.2, 0.3), (4, 2, 2), element)
    body = pp.build_body(mesh.nodes, mesh.elements, STEEL)
    eps, nu = 1e-4, 0.3
    u = np.column_stack([eps * mesh.nodes[:, 0], -nu * eps * mesh.nodes[:, 1],
                         -nu * eps * mesh.nodes[:, 2]])  # fmt: skip
    stresses, _ = recover_stresses(body, u.ravel())
    expected = np.zeros(6)
    expected[0] = 2.1e11 * eps
    assert_close(stresses, np.broadcast_to(expected, stresses.shape), abs=1e-9 * expected[0])


@pytest.mark.parametrize(
    "element, cell, columns",
    [("pyramid5", "pyramid", 5), ("pyramid13", "pyramid13", 13), ("pyramid14", "pyramid13", 13)],
)
def test_vtk_output_and_model_files(tmp_path, element, cell, columns, assert_close):
    # (VTK has no 14-node pyramid: a pyramid14 is drawn as a pyramid13, without the base's
    # centre, and read back as one)
    mesh, body, path = first_frame(element, tmp_path / "frames")
    frame = meshio.read(path)
    pyramids = [c.data for c in frame.cells if c.type == cell]
    expected = mesh.elements[element][:, :columns]
    np.testing.assert_array_equal(np.vstack(pyramids), expected)
    read = read_mesh(path).elements["pyramid5" if cell == "pyramid" else cell]
    np.testing.assert_array_equal(read, expected)
    check_model_file(element, body, tmp_path, assert_close)


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
