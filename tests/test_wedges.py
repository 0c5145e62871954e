"""Wedges ("wedge6": Abaqus C3D6, Gmsh prisms, VTK wedges; "wedge15": C3D15, Gmsh's 15-node
prisms, VTK quadratic wedges; "wedge18": Gmsh's 18-node prisms, VTK biquadratic-quadratic
wedges) in bodies: reading them, interfaces on their triangular and quadrilateral faces, VTK
output, model files. The element kernel's tests
(moments, mass fractions, patch tests, rigid-body modes) are in
`crates/flexmbd-core/src/fem/solid/tests`; invariants, kinetic energy, rigid motions and the
cantilever are in tests/test_solids.py (its SOLIDS); reading them (and an inverted one named)
in tests/test_mesh_io.py."""

import meshio
import numpy as np
import pytest

import flexmbd as fm
import flexmbd.fe.preprocess as pp
from flexmbd._core import Material
from flexmbd.errors import InvalidModelError
from flexmbd.fe import shapes
from flexmbd.model_file import load_model

STEEL = Material(2.1e11, 0.3, 7800.0)
LENGTHS = (1.0, 0.2, 0.1)


def interface_body(element, interfaces):
    mesh = shapes.box(LENGTHS, (5, 3, 2), element)
    body = pp.build_body(
        mesh.nodes, mesh.elements, STEEL, node_sets=mesh.node_sets, reference="interface",
        modes="craig-bampton", mode_count=2, interfaces=interfaces, interface_kind="rbe3",
    )  # fmt: skip
    return mesh, body


def test_interfaces_on_triangular_and_quadrilateral_faces(assert_close):
    # x0 and x1 are quadrilateral faces of the wedges (the same quads as hex8's: the same
    # weights); z1 is made of their triangles: other weights, the same exact centroid.
    def weights(element, face):
        mesh, body = interface_body(element, [face])
        return mesh, body.reference.interfaces[0], body.reference.interface_weights[0]

    _, _, quads = weights("wedge6", "x0")
    assert_close(quads, weights("hex8", "x0")[2], rel=1e-12, what="x0 (quadrilaterals)")
    mesh, members, triangles = weights("wedge6", "z1")
    assert np.all(triangles > 0) and not np.allclose(triangles, weights("hex8", "z1")[2])
    centroid = triangles @ mesh.nodes[members]
    assert_close(centroid, [0.5, 0.1, 0.1], abs=1e-15, what="z1 centroid")


def first_frame(element, folder):
    """The mesh and body of `interface_body(element, ["x0", "x1"])`, and the path of the first
    VTU frame of a short run of it written into `folder`."""
    mesh, body = interface_body(element, ["x0", "x1"])
    system = fm.System(gravity=(0.0, -9.81, 0.0))
    system.add_flexible_body(body, name="bar")
    result = fm.simulate(system, 0.002, 1e-3)
    fm.animation.write_vtu_series(result, folder)
    return mesh, body, folder / "result_00000.vtu"


def check_model_file(element, body, folder, close):
    """The same body as a model file's box of `element`: the same element type and
    frequencies."""
    text = (
        "bodies:\n  - name: bar\n    type: flexible\n"
        f"    box: {{lengths: [1.0, 0.2, 0.1], divisions: [5, 3, 2], element: {element}}}\n"
        "    material: {young_modulus: 2.1e+11, poisson_ratio: 0.3, density: 7800.0}\n"
        "    reference: interface\n    modes: craig-bampton\n    mode_count: 2\n"
        "    interfaces: [x0, x1]\n    interface_kind: rbe3\n"
        "simulation: {end_time: 0.01, step_size: 0.001}\n"
    )
    (folder / "bar.yaml").write_text(text)
    from_file = load_model(folder / "bar.yaml").body_data["bar"]
    assert list(from_file.elements) == [element]
    close(from_file.frequencies, body.frequencies, rel=1e-12, what="frequencies")


def test_vtk_output_and_model_files(tmp_path, assert_close):
    mesh, body, path = first_frame("wedge6", tmp_path / "frames")
    frame = meshio.read(path)
    wedges = [c.data for c in frame.cells if c.type == "wedge"]
    assert [len(w) for w in wedges] == [60]
    # On file, VTK 9.7's order, which is ours; meshio, which takes VTK's wedges in the order of
    # VTK before 9.7, reads them mirrored; read_mesh reads them as written.
    from flexmbd.fe.mesh_io import WEDGE_MIRRORS, read_mesh

    np.testing.assert_array_equal(wedges[0], mesh.elements["wedge6"][:, WEDGE_MIRRORS["wedge6"]])
    np.testing.assert_array_equal(read_mesh(path).elements["wedge6"], mesh.elements["wedge6"])
    check_model_file("wedge6", body, tmp_path, assert_close)


# Quadratic wedges (wedge15: Abaqus C3D15, Gmsh prism15, VTK quadratic wedges) ----------------


def gmsh_prisms(path, incomplete=True):
    """A Gmsh mesh of 15-node prisms: a triangulated 1 x 0.3 rectangle extruded by 0.2 in two
    layers, second order (incomplete: no face nodes; complete: 18-node prisms, Gmsh's
    default)."""
    import gmsh

    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        rectangle = gmsh.model.occ.addRectangle(0, 0, 0, 1.0, 0.3)
        gmsh.model.occ.synchronize()
        gmsh.option.setNumber("Mesh.MeshSizeMax", 0.15)
        volume = gmsh.model.occ.extrude([(2, rectangle)], 0, 0, 0.2, [2], recombine=True)
        gmsh.model.occ.synchronize()
        gmsh.model.addPhysicalGroup(3, [next(t for d, t in volume if d == 3)], name="body")
        gmsh.option.setNumber("Mesh.SecondOrderIncomplete", int(incomplete))
        gmsh.model.mesh.generate(3)
        gmsh.model.mesh.setOrder(2)
        gmsh.write(str(path))
    finally:
        gmsh.finalize()


def test_gmsh_and_vtk_quadratic_wedges_are_read_in_abaqus_order(tmp_path, assert_close):
    # meshio could not hold a wedge15 cell at all (KeyError 'wedge15' in its table of cell
    # dimensions). Read from Gmsh, every mid-edge node is the midpoint of its edge in the
    # C3D15 order, and the mass is the block's.
    from flexmbd.fe.mesh_io import WEDGE_MIRRORS, read_mesh
    from flexmbd.fe.shapes import WEDGE15_EDGES

    pytest.importorskip("gmsh")
    gmsh_prisms(tmp_path / "prisms.msh")
    mesh = read_mesh(tmp_path / "prisms.msh")
    assert list(mesh.elements) == ["wedge15"]
    cells, x = mesh.elements["wedge15"], mesh.nodes
    for e, (p, q) in enumerate(WEDGE15_EDGES):
        assert_close(x[cells[:, 6 + e]], 0.5 * (x[cells[:, p]] + x[cells[:, q]]), abs=1e-15)
    body = pp.body_from_mesh(mesh, STEEL)
    assert_close(body.invariants.mass, 7800.0 * 0.06, rel=1e-12, what="mass")
    # VTK files have quadratic wedges in our order (VTK 9.7) or with each triangle listed the
    # other way round (VTK before 9.7): read, both are ours (and not inverted).
    for order in (np.arange(15), WEDGE_MIRRORS["wedge15"]):
        meshio.write(tmp_path / "prisms.vtu", meshio.Mesh(x, [("wedge15", cells[:, order])]))
        again = read_mesh(tmp_path / "prisms.vtu")
        np.testing.assert_array_equal(again.elements["wedge15"], cells)


def test_quadratic_wedges_in_interfaces_vtk_output_and_model_files(tmp_path, assert_close):
    # The x0 face is made of the same quad8 faces as hex20's: the same weights, node by node;
    # z1 of tri6 faces: the consistent weights (0 at a triangle's corners, a third of its
    # area at a mid-edge node), the exact centroid.
    def weights(element, face):
        mesh, body = interface_body(element, [face])
        members = body.reference.interfaces[0]
        return mesh, members, body.reference.interface_weights[0]

    def by_position(mesh, members, values):
        order = np.lexsort(mesh.nodes[members].T)
        return mesh.nodes[members][order], values[order]

    quadratic = by_position(*weights("wedge15", "x0"))
    hexahedra = by_position(*weights("hex20", "x0"))
    assert_close(quadratic[0], hexahedra[0], abs=1e-15, what="x0 nodes")
    assert_close(quadratic[1], hexahedra[1], rel=1e-12, what="x0 weights")
    mesh, members, triangles = weights("wedge15", "z1")
    assert np.all(triangles >= 0) and np.any(triangles == 0)
    assert_close(triangles @ mesh.nodes[members], [0.5, 0.1, 0.1], abs=1e-15, what="centroid")
    # VTK output: VTK 9.7's order (ours) on file, read back through read_mesh.
    from flexmbd.fe.mesh_io import read_mesh

    mesh, body, path = first_frame("wedge15", tmp_path / "frames")
    written = [c.data for c in meshio.read(path).cells if c.type == "wedge15"]
    np.testing.assert_array_equal(written[0], mesh.elements["wedge15"])
    np.testing.assert_array_equal(read_mesh(path).elements["wedge15"], mesh.elements["wedge15"])
    check_model_file("wedge15", body, tmp_path, assert_close)


# Lagrange wedges (wedge18: Gmsh's 18-node prisms, VTK biquadratic-quadratic wedges) -----------


def test_gmsh_and_vtk_18_node_wedges_are_read_in_our_order(tmp_path, assert_close):
    # Gmsh's default order-2 prisms were refused ("SecondOrderIncomplete = 1 gives 15-node
    # ones"). meshio passes them on in Gmsh's order (edges (0,1), (0,2), (0,3), ..., faces
    # (0,1,4,3), (0,2,5,3), (1,2,5,4)); read, every mid-edge node is the midpoint of its
    # edge and every face node the centre of its face in wedge18's order, and the mass is
    # the block's.
    from flexmbd.fe.mesh_io import WEDGE_MIRRORS, read_mesh
    from flexmbd.fe.shapes import WEDGE15_EDGES, WEDGE18_FACES

    pytest.importorskip("gmsh")
    gmsh_prisms(tmp_path / "prisms.msh", incomplete=False)
    mesh = read_mesh(tmp_path / "prisms.msh")
    assert list(mesh.elements) == ["wedge18"]
    cells, x = mesh.elements["wedge18"], mesh.nodes
    for e, (p, q) in enumerate(WEDGE15_EDGES):
        assert_close(x[cells[:, 6 + e]], 0.5 * (x[cells[:, p]] + x[cells[:, q]]), abs=1e-15)
    for f, face in enumerate(WEDGE18_FACES):
        assert_close(x[cells[:, 15 + f]], x[cells[:, list(face)]].mean(axis=1), abs=1e-15)
    body = pp.body_from_mesh(mesh, STEEL)
    assert_close(body.invariants.mass, 7800.0 * 0.06, rel=1e-12, what="mass")
    # VTK files have them in our order (VTK 9.7) or with each triangle listed the other way
    # round, the face nodes following (VTK before 9.7): read, both are ours.
    for order in (np.arange(18), WEDGE_MIRRORS["wedge18"]):
        meshio.write(tmp_path / "prisms.vtu", meshio.Mesh(x, [("wedge18", cells[:, order])]))
        np.testing.assert_array_equal(read_mesh(tmp_path / "prisms.vtu").elements["wedge18"], cells)


def test_18_node_wedges_in_interfaces_vtk_output_and_model_files(tmp_path, assert_close):
    # The x0 face is made of the same quad9 faces as hex27's, node by node: the same weights
    # (1/36, 1/9, 4/9 of a rectangle); z1 of the same tri6 faces as wedge15's.
    def weights(element, face):
        mesh, body = interface_body(element, [face])
        members = body.reference.interfaces[0]
        order = np.lexsort(mesh.nodes[members].T)
        return mesh.nodes[members][order], body.reference.interface_weights[0][order]

    for face, other in (("x0", "hex27"), ("z1", "wedge15")):
        nodes, values = weights("wedge18", face)
        other_nodes, other_values = weights(other, face)
        assert_close(nodes, other_nodes, abs=1e-15, what=f"{face} nodes")
        assert_close(values, other_values, rel=1e-12, what=f"{face} weights")
    # Volume weights of one right prism (the triangle of legs 1, 2; height 3): int N_a dV / V
    # = 0 at the corners and the vertical edges' nodes, 1/18 at the triangles' mid-edge
    # nodes, 2/9 at the faces' centres (sympy).
    from flexmbd.fe.interface import interface_weights
    from flexmbd.fe.shapes import WEDGE15_EDGES, WEDGE18_FACES

    corners = np.array([[0, 0, 0], [1, 0, 0], [0, 2, 0], [0, 0, 3], [1, 0, 3], [0, 2, 3]], float)
    nodes = np.vstack([corners, [corners[list(e)].mean(axis=0) for e in WEDGE15_EDGES],
                       [corners[list(f)].mean(axis=0) for f in WEDGE18_FACES]])  # fmt: skip
    w, _ = interface_weights(nodes, {"wedge18": np.arange(18)[None]}, np.arange(18), "volume")
    expected = 3.0 * np.array([0] * 6 + [1 / 18] * 6 + [0] * 3 + [2 / 9] * 3)
    assert_close(w, expected, rel=1e-12, abs=1e-14, what="volume weights")
    from flexmbd.fe.mesh_io import read_mesh

    mesh, body, path = first_frame("wedge18", tmp_path / "frames")
    written = [c.data for c in meshio.read(path).cells if c.type == "wedge18"]
    np.testing.assert_array_equal(written[0], mesh.elements["wedge18"])
    np.testing.assert_array_equal(read_mesh(path).elements["wedge18"], mesh.elements["wedge18"])
    check_model_file("wedge18", body, tmp_path, assert_close)


# VTK's own wedges ----------------------------------------------------------------------------
# Files written by VTK's vtkXMLUnstructuredGridWriter (ASCII; point data arrays and
# information keys left out, two long tags broken across lines). VTK_SOURCE_97 and
# VTK_SOURCE_92: vtkCellTypeSource's quadratic wedges (SetCellType(26),
# SetBlocksDimensions(1, 1, 1): the unit cube in two wedges) by VTK 9.7.2 and by 9.2.6. VTK
# 9.7.2's vtkCellSizeFilter gives the first file's wedges the volumes +0.5, +0.5 and its
# vtkCellValidator the state 0 (valid), the second's -0.5, -0.5 and the state 32 (faces
# oriented incorrectly); VTK 9.2.6's vtkCellSizeFilter the other way round (-0.5 and +0.5),
# its validator 0 for the first file, 32 for its own. VTK_PRISM18_97: one
# biquadratic-quadratic wedge (type 32) with node k at VTK's parametric coordinates
# (GetParametricCoords) times (2, 3, 0.5): volume +1.5 and state 0 by VTK 9.7.2 (state 0
# by 9.2.6 too).
VTK_SOURCE_97 = """\
<?xml version="1.0"?>
<VTKFile type="UnstructuredGrid" version="0.1" byte_order="LittleEndian" header_type="UInt32"
    compressor="vtkZLibDataCompressor">
  <UnstructuredGrid>
    <Piece NumberOfPoints="22" NumberOfCells="2">
      <Points>
        <DataArray type="Float32" Name="Points" NumberOfComponents="3" format="ascii" RangeMin="0"
            RangeMax="1.7320508075688772">
          0 0 0 1 0 0
          0 1 0 1 1 0
          0 0 1 1 0 1
          0 1 1 1 1 1
          0.5 0 0 0.5 0.5 0
          0 0.5 0 0.5 0 1
          0.5 0.5 1 0 0.5 1
          0 0 0.5 1 0 0.5
          0 1 0.5 1 0.5 1
          0.5 1 1 1 0.5 0
          0.5 1 0 1 1 0.5
        </DataArray>
      </Points>
      <Cells>
        <DataArray type="Int64" Name="connectivity" format="ascii" RangeMin="0" RangeMax="21">
          0 1 2 4 5 6
          8 9 10 11 12 13
          14 15 16 7 5 6
          3 1 2 17 12 18
          19 9 20 21 15 16
        </DataArray>
        <DataArray type="Int64" Name="offsets" format="ascii" RangeMin="15" RangeMax="30">
          15 30
        </DataArray>
        <DataArray type="UInt8" Name="types" format="ascii" RangeMin="26" RangeMax="26">
          26 26
        </DataArray>
      </Cells>
    </Piece>
  </UnstructuredGrid>
</VTKFile>
"""

VTK_SOURCE_92 = """\
<?xml version="1.0"?>
<VTKFile type="UnstructuredGrid" version="0.1" byte_order="LittleEndian" header_type="UInt32"
    compressor="vtkZLibDataCompressor">
  <UnstructuredGrid>
    <Piece NumberOfPoints="22" NumberOfCells="2">
      <Points>
        <DataArray type="Float32" Name="Points" NumberOfComponents="3" format="ascii" RangeMin="0"
            RangeMax="1.7320508075688772">
          0 0 0 1 0 0
          0 1 0 1 1 0
          0 0 1 1 0 1
          0 1 1 1 1 1
          0 0.5 0 0.5 0.5 0
          0.5 0 0 0 0.5 1
          0.5 0.5 1 0.5 0 1
          0 0 0.5 0 1 0.5
          1 0 0.5 0.5 1 0
          1 0.5 0 0.5 1 1
          1 0.5 1 1 1 0.5
        </DataArray>
      </Points>
      <Cells>
        <DataArray type="Int64" Name="connectivity" format="ascii" RangeMin="0" RangeMax="21">
          0 2 1 4 6 5
          8 9 10 11 12 13
          14 15 16 1 2 3
          5 6 7 9 17 18
          12 19 20 16 15 21
        </DataArray>
        <DataArray type="Int64" Name="offsets" format="ascii" RangeMin="15" RangeMax="30">
          15 30
        </DataArray>
        <DataArray type="UInt8" Name="types" format="ascii" RangeMin="26" RangeMax="26">
          26 26
        </DataArray>
      </Cells>
    </Piece>
  </UnstructuredGrid>
</VTKFile>
"""

VTK_PRISM18_97 = """\
<?xml version="1.0"?>
<VTKFile type="UnstructuredGrid" version="0.1" byte_order="LittleEndian" header_type="UInt32"
    compressor="vtkZLibDataCompressor">
  <UnstructuredGrid>
    <Piece NumberOfPoints="18" NumberOfCells="1">
      <Points>
        <DataArray type="Float32" Name="Points" NumberOfComponents="3" format="ascii" RangeMin="0"
            RangeMax="3.0413812651491097">
          0 0 0 2 0 0
          0 3 0 0 0 0.5
          2 0 0.5 0 3 0.5
          1 0 0 1 1.5 0
          0 1.5 0 1 0 0.5
          1 1.5 0.5 0 1.5 0.5
          0 0 0.25 2 0 0.25
          0 3 0.25 1 0 0.25
          1 1.5 0.25 0 1.5 0.25
        </DataArray>
      </Points>
      <Cells>
        <DataArray type="Int64" Name="connectivity" format="ascii" RangeMin="0" RangeMax="17">
          0 1 2 3 4 5
          6 7 8 9 10 11
          12 13 14 15 16 17
        </DataArray>
        <DataArray type="Int64" Name="offsets" format="ascii" RangeMin="18" RangeMax="18">
          18
        </DataArray>
        <DataArray type="UInt8" Name="types" format="ascii" RangeMin="32" RangeMax="32">
          32
        </DataArray>
      </Cells>
    </Piece>
  </UnstructuredGrid>
</VTKFile>
"""


def test_vtk_written_quadratic_wedges_are_read_in_either_orientation(tmp_path, assert_close):
    # Read in one fixed order (each triangle the other way round: VTK's documentation before
    # 9.7), VTK 9.7's own quadratic wedges were inverted and refused. Both files now give the
    # unit cube's mass and every mid-edge node the midpoint of its edge (VTK numbers the
    # mid-edge nodes as we do): VTK 9.7's cells as written, VTK 9.2's mirrored.
    from flexmbd.fe.mesh_io import WEDGE_MIRRORS, complete_meshio, read_mesh
    from flexmbd.fe.shapes import WEDGE15_EDGES, WEDGE18_FACES

    complete_meshio()
    for name, text, order in (
        ("97", VTK_SOURCE_97, np.arange(15)),
        ("92", VTK_SOURCE_92, WEDGE_MIRRORS["wedge15"]),
    ):
        path = tmp_path / f"{name}.vtu"
        path.write_text(text)
        written = meshio.read(path).cells[0].data
        mesh = read_mesh(path)
        cells, x = mesh.elements["wedge15"], mesh.nodes
        np.testing.assert_array_equal(cells, written[:, order])
        for e, (p, q) in enumerate(WEDGE15_EDGES):
            assert_close(x[cells[:, 6 + e]], 0.5 * (x[cells[:, p]] + x[cells[:, q]]), abs=1e-7)
        body = pp.body_from_mesh(mesh, STEEL)
        assert_close(body.invariants.mass, 7800.0, rel=1e-6, what=f"mass, VTK {name}")
    # VTK's 18-node wedge: our order, face centres included.
    (tmp_path / "prism18.vtu").write_text(VTK_PRISM18_97)
    mesh = read_mesh(tmp_path / "prism18.vtu")
    cells, x = mesh.elements["wedge18"], mesh.nodes
    np.testing.assert_array_equal(cells, [np.arange(18)])
    for f, face in enumerate(WEDGE18_FACES):
        assert_close(x[cells[:, 15 + f]], x[cells[:, list(face)]].mean(axis=1), abs=1e-7)
    assert_close(pp.body_from_mesh(mesh, STEEL).invariants.mass, 7800.0 * 1.5, rel=1e-6)
    # Elsewhere a wedge listed the other way round is inverted, and named (a C3D15).
    lines = ["*NODE"] + [
        f"{i + 1}, {a:.9g}, {b:.9g}, {c:.9g}" for i, (a, b, c) in enumerate(x[:15])
    ]
    mirror = WEDGE_MIRRORS["wedge15"]
    labels = [str(k + 1) for k in mirror]
    lines += ["*ELEMENT, TYPE=C3D15", "1, " + ", ".join(labels[:10]) + ",", ", ".join(labels[10:])]
    (tmp_path / "c3d15.inp").write_text("\n".join(lines) + "\n")
    with pytest.raises(InvalidModelError, match="inverted.*wedge15"):
        pp.body_from_mesh(read_mesh(tmp_path / "c3d15.inp"), STEEL)
