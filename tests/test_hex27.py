"""Triquadratic hexahedra ("hex27": Gmsh's and VTK's 27-node hexahedron, the element Gmsh makes
of a hexahedral mesh at order 2 unless told otherwise) in bodies: reading them in VTK's order,
interfaces on their 9-node faces, VTK output and model files. The element kernel's tests
(moments, mass fractions, patch tests, rigid-body modes, every triquadratic field) are in
`crates/flexmbd-core/src/fem/solid/tests`; invariants, kinetic energy and rigid motions of box
meshes in tests/test_solids.py (its SOLIDS)."""

import meshio
import numpy as np
import pytest
from test_wedges import STEEL, check_model_file, first_frame, interface_body

import flexmbd.fe.preprocess as pp
from flexmbd.fe.mesh_io import read_mesh
from flexmbd.fe.shapes import HEX20_EDGES, HEX27_FACES


def gmsh_hexahedra(path):
    """A Gmsh mesh of a 1 x 0.4 x 0.2 block in 3 x 2 x 1 hexahedra of order 2 (Gmsh's
    default, complete: 27 nodes)."""
    import gmsh

    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        block = gmsh.model.occ.addBox(0, 0, 0, 1.0, 0.4, 0.2)
        gmsh.model.occ.synchronize()
        for _, tag in gmsh.model.getEntities(1):
            low, high = np.reshape(gmsh.model.getBoundingBox(1, tag), (2, 3))
            gmsh.model.mesh.setTransfiniteCurve(tag, 1 + {0: 3, 1: 2, 2: 1}[np.argmax(high - low)])
        for _, tag in gmsh.model.getEntities(2):
            gmsh.model.mesh.setTransfiniteSurface(tag)
            gmsh.model.mesh.setRecombine(2, tag)
        gmsh.model.mesh.setTransfiniteVolume(block)
        gmsh.model.addPhysicalGroup(3, [block], name="block")
        gmsh.model.mesh.generate(3)
        gmsh.model.mesh.setOrder(2)
        gmsh.write(str(path))
    finally:
        gmsh.finalize()


def test_gmsh_hexahedra_of_order_2_are_read_in_vtk_order(tmp_path, assert_close):
    # They were refused ("27-node hexahedron"), so a Gmsh hexahedral mesh at order 2 could
    # not be used without Mesh.SecondOrderIncomplete. Read, every node is where the element's
    # order puts it: the edges' midpoints, the faces' centres, the element's centre; the mass
    # is the block's.
    pytest.importorskip("gmsh")
    gmsh_hexahedra(tmp_path / "block.msh")
    mesh = read_mesh(tmp_path / "block.msh")
    assert list(mesh.elements) == ["hex27"] and len(mesh.elements["hex27"]) == 6
    cells, x = mesh.elements["hex27"], mesh.nodes
    for e, (p, q) in enumerate(HEX20_EDGES):
        assert_close(x[cells[:, 8 + e]], 0.5 * (x[cells[:, p]] + x[cells[:, q]]), abs=1e-15)
    for f, face in enumerate(HEX27_FACES):
        assert_close(x[cells[:, 20 + f]], x[cells[:, list(face)]].mean(axis=1), abs=1e-15)
    assert_close(x[cells[:, 26]], x[cells[:, :8]].mean(axis=1), abs=1e-15)
    body = pp.body_from_mesh(mesh, STEEL)
    assert_close(body.invariants.mass, 7800.0 * 0.08, rel=1e-12, what="mass")


def test_interfaces_on_their_nine_node_faces(assert_close):
    # The face x1 (0.2 x 0.1 in 3 x 2 cells): int N dA = 1/36 of a cell's area at its corner,
    # 1/9 at a mid-edge node, 4/9 at its centre: composite Simpson weights in y and z (h/6 at
    # the ends, h/3 where two cells meet, 2h/3 in a cell's middle). The centroid is exact.
    mesh, body = interface_body("hex27", ["x1"])
    members = body.reference.interfaces[0]
    weights = body.reference.interface_weights[0]
    x = mesh.nodes[members]
    assert_close(weights @ x / weights.sum(), [1.0, 0.1, 0.05], abs=1e-15, what="centroid")

    def simpson(cells, length):
        h = length / cells
        w = np.full(2 * cells + 1, h / 3)
        w[1::2], w[[0, -1]] = 2 * h / 3, h / 6
        return w

    iy, iz = (np.rint(x[:, 1] / (0.2 / 6)).astype(int), np.rint(x[:, 2] / (0.1 / 4)).astype(int))
    expected = simpson(3, 0.2)[iy] * simpson(2, 0.1)[iz]
    assert_close(expected.sum(), 0.02, rel=1e-12, what="area")
    assert_close(weights / weights.sum(), expected / 0.02, rel=1e-12, what="weights")


def test_vtk_output_and_model_files(tmp_path, assert_close):
    mesh, body, path = first_frame("hex27", tmp_path / "frames")
    frame = meshio.read(path)
    cells = [c.data for c in frame.cells if c.type == "hexahedron27"]
    np.testing.assert_array_equal(np.vstack(cells), mesh.elements["hex27"])
    np.testing.assert_array_equal(read_mesh(path).elements["hex27"], mesh.elements["hex27"])
    check_model_file("hex27", body, tmp_path, assert_close)
