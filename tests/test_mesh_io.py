"""Meshes from Gmsh, Abaqus and VTK files, mesh checks, and matrices from Abaqus or arrays.

Meshes are written with meshio into a temporary directory, or as tiny hand-written files in the
source codes' own conventions (node order, sparse ids), and read back; orientation and node
order are checked against the geometry (volumes, mid-edge positions), not against the writer.
"""

from __future__ import annotations

import itertools
import os
import subprocess
import sys
from pathlib import Path

import meshio
import numpy as np
import pytest
import scipy.sparse as sp

import flexmbd.fe.preprocess as pp
from flexmbd._core import Material
from flexmbd.errors import (
    InvalidModelError,
    InvalidParameterError,
    MeshQualityWarning,
    UnknownItemError,
)
from flexmbd.fe.mesh_io import (
    MAX_NODE_COORDINATE,
    Mesh,
    matrices_from_arrays,
    read_abaqus_matrix,
    read_mesh,
    validate_mesh,
)

STEEL = Material(2.1e11, 0.3, 7800.0)

# VTK (and meshio, Abaqus C3D10) order of the mid-edge nodes 4..9 of a 10-node tetrahedron.
TET10_EDGES = [(0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3)]
# Gmsh's own order (gmsh.info, "Node ordering"): nodes 8 and 9 on edges (2, 3) and (1, 3); the
# order of read_mesh's output and of the element kernels.
GMSH_TET10_EDGES = [(0, 1), (1, 2), (0, 2), (0, 3), (2, 3), (1, 3)]
VTK_TO_GMSH = [0, 1, 2, 3, 4, 5, 6, 7, 9, 8]

TWO_TETS_NODES = np.array(
    [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 1.0, 1.0]]
)
TWO_TETS = np.array([[0, 1, 2, 3], [1, 2, 3, 4]])


def tet_volume(x: np.ndarray) -> float:
    """Signed volume of the tetrahedron with vertices x[0..3]."""
    return float(np.linalg.det(np.array([x[1] - x[0], x[2] - x[0], x[3] - x[0]])) / 6.0)


def hex_orientation(x: np.ndarray) -> float:
    """(x1 - x0) x (x3 - x0) . (x4 - x0): positive for the VTK/Gmsh/Abaqus hex8 order."""
    return float(np.dot(np.cross(x[1] - x[0], x[3] - x[0]), x[4] - x[0]))


def tet10_nodes(edges=TET10_EDGES) -> np.ndarray:
    """A skewed 10-node tetrahedron, mid-edge nodes on ``edges``."""
    vertices = np.array([[0.0, 0.0, 0.0], [2.0, 0.1, 0.0], [0.2, 1.5, 0.1], [0.1, 0.3, 1.2]])
    middles = [(vertices[a] + vertices[b]) / 2 for a, b in edges]
    return np.vstack([vertices, middles])


def assert_gmsh_tet10(mesh: Mesh, element: np.ndarray) -> None:
    x = mesh.nodes[element]
    assert tet_volume(x[:4]) > 0
    for k, (a, b) in enumerate(GMSH_TET10_EDGES):
        np.testing.assert_allclose(x[4 + k], (x[a] + x[b]) / 2, atol=1e-14)


def hex_block() -> tuple[np.ndarray, np.ndarray]:
    """Two unit hexahedra side by side along x, VTK order."""
    nodes = np.array(
        [[x, y, z] for z in (0.0, 1.0) for y in (0.0, 1.0) for x in (0.0, 1.0, 2.0)]
    )  # index = 6 z + 3 y + x
    index = {tuple(p): i for i, p in enumerate(nodes.astype(int).tolist())}

    def hexa(x0):
        corners = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]
        bottom = [index[(x0 + dx, dy, 0)] for dx, dy, _ in corners]
        top = [index[(x0 + dx, dy, 1)] for dx, dy, _ in corners]
        return bottom + top

    return nodes, np.array([hexa(0), hexa(1)])


def as_written(
    mesh: Mesh, written: np.ndarray, binary: bool = False
) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Elements and node sets of a mesh read back from a file meshio wrote, in the node
    numbering of the written mesh (nodes matched by position: the Gmsh 4.1 writer groups the
    nodes by geometric entity, which changes their order in the file).

    Also checks the node ids: meshio writes id = index + 1, and read_mesh recovers it, except
    from binary Gmsh files, where the ids are the positions in the file.
    """
    position = {tuple(x): i for i, x in enumerate(written.tolist())}
    source = np.array([position[tuple(x)] for x in mesh.nodes.tolist()])
    np.testing.assert_array_equal(mesh.nodes, written[source])
    expected_ids = np.arange(1, len(source) + 1) if binary else source + 1
    np.testing.assert_array_equal(mesh.node_ids, expected_ids)
    elements = {kind: source[e] for kind, e in mesh.elements.items()}
    node_sets = {name: np.sort(source[s]) for name, s in mesh.node_sets.items()}
    return elements, node_sets


def write(tmp_path: Path, name: str, mesh: meshio.Mesh, file_format: str, **options) -> Path:
    path = tmp_path / name
    meshio.write(path, mesh, file_format=file_format, **options)
    return path


GMSH_FORMATS = [("gmsh22", {"binary": False}), ("gmsh22", {"binary": True})]
GMSH_FORMATS += [("gmsh", {"binary": False}), ("gmsh", {"binary": True})]


def gmsh_mesh(points, cells, physical, names) -> meshio.Mesh:
    """A meshio mesh with Gmsh physical groups: ``physical`` gives one tag per cell block,
    ``names`` maps a name to (tag, dimension); every block gets its own geometric entity."""
    entity_dims = {"vertex": 0, "line": 1, "triangle": 2, "triangle6": 2}
    dim_tags = np.array([[3, 1]] * len(points))
    # Nodes on a lower-dimensional entity: the last block that uses them.
    for b, (cell_type, data) in enumerate(cells):
        dimension = entity_dims.get(cell_type, 3)
        if dimension < 3:
            dim_tags[np.unique(data)] = [dimension, b + 1]
    return meshio.Mesh(
        points,
        cells,
        point_data={"gmsh:dim_tags": dim_tags},
        cell_data={
            "gmsh:physical": [
                np.full(len(data), tag) for (_, data), tag in zip(cells, physical, strict=True)
            ],
            "gmsh:geometrical": [np.full(len(data), b + 1) for b, (_, data) in enumerate(cells)],
        },
        field_data={name: np.array(value) for name, value in names.items()},
    )


# ---------------------------------------------------------------------------------------------
# Reading meshes written by meshio


@pytest.mark.parametrize("file_format, options", GMSH_FORMATS, ids=lambda x: str(x))
def test_two_tets_gmsh(tmp_path, file_format, options):
    cells = [("tetra", TWO_TETS), ("triangle", np.array([[0, 1, 2]]))]
    names = {"solid": (1, 3), "clamp": (2, 2)}
    source = gmsh_mesh(TWO_TETS_NODES, cells, physical=[1, 2], names=names)
    mesh = read_mesh(write(tmp_path, "two.msh", source, file_format, **options))

    assert mesh.nodes.dtype == np.float64 and mesh.nodes.shape == (5, 3)
    assert mesh.node_ids.dtype == np.int64
    np.testing.assert_array_equal(np.sort(mesh.node_ids), [1, 2, 3, 4, 5])
    assert list(mesh.elements) == ["tet4"]
    assert mesh.elements["tet4"].dtype == np.int64
    np.testing.assert_array_equal(mesh.element_ids["tet4"], [1, 2])
    assert all(tet_volume(mesh.nodes[e]) > 0 for e in mesh.elements["tet4"])
    elements, node_sets = as_written(mesh, TWO_TETS_NODES, options["binary"])
    np.testing.assert_array_equal(elements["tet4"], TWO_TETS)
    # The triangle is no element, but its physical group becomes a node set.
    np.testing.assert_array_equal(node_sets["clamp"], [0, 1, 2])
    np.testing.assert_array_equal(node_sets["solid"], [0, 1, 2, 3, 4])
    validate_mesh(mesh)


@pytest.mark.parametrize(
    "suffix, file_format", [(".vtu", "vtu"), (".vtk", "vtk"), (".inp", "abaqus")]
)
def test_two_tets_vtk_and_abaqus(tmp_path, suffix, file_format):
    source = meshio.Mesh(TWO_TETS_NODES, [("tetra", TWO_TETS)])
    mesh = read_mesh(write(tmp_path, "two" + suffix, source, file_format))
    np.testing.assert_array_equal(mesh.nodes, TWO_TETS_NODES)
    np.testing.assert_array_equal(mesh.node_ids, [1, 2, 3, 4, 5])
    np.testing.assert_array_equal(mesh.elements["tet4"], TWO_TETS)
    np.testing.assert_array_equal(mesh.element_ids["tet4"], [1, 2])
    validate_mesh(mesh)


@pytest.mark.parametrize(
    "name, file_format, options",
    [
        ("hex.msh", "gmsh22", {"binary": False}),
        ("hex.msh", "gmsh", {"binary": False}),
        ("hex.vtu", "vtu", {}),
        ("hex.inp", "abaqus", {}),
    ],
)
# (meshio writes hexahedra as C3D8RH, which read_mesh reads as hex8 with a warning)
@pytest.mark.filterwarnings("ignore::flexmbd.errors.MeshQualityWarning")
def test_hex_mesh(tmp_path, name, file_format, options):
    nodes, hexes = hex_block()
    assert all(hex_orientation(nodes[h]) > 0 for h in hexes)
    source = meshio.Mesh(nodes, [("hexahedron", hexes)])
    mesh = read_mesh(write(tmp_path, name, source, file_format, **options))
    elements, _ = as_written(mesh, nodes)
    np.testing.assert_array_equal(elements["hex8"], hexes)
    assert all(hex_orientation(mesh.nodes[h]) > 0 for h in mesh.elements["hex8"])
    validate_mesh(mesh)


@pytest.mark.parametrize(
    "name, file_format, options",
    [
        ("tet10.msh", "gmsh22", {"binary": False}),
        ("tet10.msh", "gmsh22", {"binary": True}),
        ("tet10.msh", "gmsh", {"binary": False}),
        ("tet10.msh", "gmsh", {"binary": True}),
        ("tet10.vtu", "vtu", {}),
        ("tet10.inp", "abaqus", {}),
    ],
)
def test_tet10_order_and_groups(tmp_path, name, file_format, options):
    nodes = tet10_nodes()
    cells = [("tetra10", np.arange(10)[None, :]), ("triangle6", np.array([[0, 1, 2, 4, 5, 6]]))]
    if file_format.startswith("gmsh"):
        names = {"body": (1, 3), "clamp": (2, 2)}
        source = gmsh_mesh(nodes, cells, physical=[1, 2], names=names)
    else:
        source = meshio.Mesh(
            nodes,
            cells,
            point_sets={"clamp": np.array([0, 1, 2, 4, 5, 6])},
            cell_sets={"body": [np.array([0]), np.array([], dtype=int)]},
        )
    mesh = read_mesh(write(tmp_path, name, source, file_format, **options))
    assert list(mesh.elements) == ["tet10"]
    assert_gmsh_tet10(mesh, mesh.elements["tet10"][0])
    elements, node_sets = as_written(mesh, nodes, options.get("binary", False))
    np.testing.assert_array_equal(elements["tet10"], [VTK_TO_GMSH])
    if file_format != "vtu":  # VTK files carry no sets
        np.testing.assert_array_equal(node_sets["clamp"], [0, 1, 2, 4, 5, 6])
        np.testing.assert_array_equal(node_sets["body"], np.arange(10))
    validate_mesh(mesh)


def test_beam_mesh_from_vtu(tmp_path):
    nodes = np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0]])
    source = meshio.Mesh(nodes, [("line", np.array([[0, 1], [1, 2]])), ("vertex", np.array([[2]]))])
    mesh = read_mesh(write(tmp_path, "beam.vtu", source, "vtu"))
    np.testing.assert_array_equal(mesh.elements["beam2"], [[0, 1], [1, 2]])
    np.testing.assert_array_equal(mesh.element_ids["beam2"], [1, 2])
    validate_mesh(mesh)


def test_vtk_lines_next_to_shells_are_edges_as_documented(tmp_path):
    # Regression: they became beams (Gmsh's were skipped), and the shell mesh was refused for
    # "beam elements need a section".
    nodes = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    cells = [("quad", np.array([[0, 1, 2, 3]])), ("line", np.array([[0, 1]]))]
    for suffix, file_format in ((".vtu", "vtu"), (".vtk", "vtk")):
        mesh = read_mesh(write(tmp_path, "panel" + suffix, meshio.Mesh(nodes, cells), file_format))
        assert list(mesh.elements) == ["quad4"]


def test_gmsh_lines_next_to_volumes_are_geometry_edges(tmp_path):
    cells = [("tetra", TWO_TETS), ("line", np.array([[0, 1]])), ("vertex", np.array([[4]]))]
    names = {"solid": (1, 3), "edge": (2, 1), "tip": (3, 0)}
    source = gmsh_mesh(TWO_TETS_NODES, cells, physical=[1, 2, 3], names=names)
    mesh = read_mesh(write(tmp_path, "edges.msh", source, "gmsh22", binary=False))
    assert list(mesh.elements) == ["tet4"]
    # Element ids count every element of the file, the line and the vertex too.
    np.testing.assert_array_equal(mesh.element_ids["tet4"], [1, 2])
    np.testing.assert_array_equal(mesh.node_sets["edge"], [0, 1])
    np.testing.assert_array_equal(mesh.node_sets["tip"], [4])


# ---------------------------------------------------------------------------------------------
# Hand-written files in the source codes' own conventions

GMSH22_TET10 = """$MeshFormat
2.2 0 8
$EndMeshFormat
$PhysicalNames
2
0 2 "tip"
3 1 "body"
$EndPhysicalNames
$Nodes
10
{nodes}
$EndNodes
$Elements
2
7 11 2 1 1 {tet}
9 15 2 2 2 {tip}
$EndElements
"""


def test_gmsh22_tet10_in_gmsh_order_with_sparse_tags(tmp_path):
    # Gmsh numbers the last two mid-edge nodes the other way round from VTK.
    nodes = tet10_nodes(GMSH_TET10_EDGES)
    tags = [100, 90, 80, 70, 60, 50, 40, 30, 20, 10]
    text = GMSH22_TET10.format(
        nodes="\n".join(
            f"{t} {x:.17g} {y:.17g} {z:.17g}" for t, (x, y, z) in zip(tags, nodes, strict=True)
        ),
        tet=" ".join(map(str, tags)),
        tip=tags[3],
    )
    path = tmp_path / "tet10.msh"
    path.write_text(text)
    mesh = read_mesh(path)
    np.testing.assert_array_equal(mesh.node_ids, tags)
    np.testing.assert_array_equal(mesh.element_ids["tet10"], [7])
    element = mesh.elements["tet10"][0]
    # meshio swaps nodes 8 and 9 into the VTK order, read_mesh swaps them back.
    np.testing.assert_array_equal(element, np.arange(10))
    assert_gmsh_tet10(mesh, element)
    np.testing.assert_array_equal(mesh.node_sets["tip"], [3])
    np.testing.assert_array_equal(mesh.node_sets["body"], np.arange(10))
    validate_mesh(mesh)


GMSH41_SPARSE = """$MeshFormat
4.1 0 8
$EndMeshFormat
$PhysicalNames
2
2 5 "clamp"
3 6 "solid"
$EndPhysicalNames
$Entities
0 0 1 1
3 0 0 0 1 1 0 1 5 0
7 0 0 0 1 1 1 1 6 0
$EndEntities
$Nodes
2 5 11 55
2 3 0 3
11
22
33
0 0 0
1 0 0
0 1 0
3 7 0 2
44
55
0 0 1
1 1 1
$EndNodes
$Elements
2 3 100 300
2 3 2 1
300 11 22 33
3 7 4 2
100 11 22 33 44
200 22 33 44 55
$EndElements
"""


def test_gmsh41_sparse_tags_and_physical_groups(tmp_path):
    path = tmp_path / "sparse.msh"
    path.write_text(GMSH41_SPARSE)
    mesh = read_mesh(path)
    np.testing.assert_array_equal(mesh.nodes, TWO_TETS_NODES)
    np.testing.assert_array_equal(mesh.node_ids, [11, 22, 33, 44, 55])
    np.testing.assert_array_equal(mesh.elements["tet4"], TWO_TETS)
    np.testing.assert_array_equal(mesh.element_ids["tet4"], [100, 200])
    np.testing.assert_array_equal(mesh.node_sets["clamp"], [0, 1, 2])
    np.testing.assert_array_equal(mesh.node_sets["solid"], [0, 1, 2, 3, 4])
    validate_mesh(mesh)


ABAQUS_INP = """*HEADING
tiny test model
** node labels are not consecutive
*NODE, NSET=AllNodes
101, 0.0, 0.0, 0.0
102, 1.0, 0.0, 0.0
103, 0.0, 1.0, 0.0
104, 0.0, 0.0, 1.0
105, 1.0, 1.0, 1.0
*ELEMENT, TYPE=C3D4, ELSET=Solid
11, 101, 102, 103, 104
12, 102, 103,
    104, 105
*ELEMENT, TYPE=S3
21, 101, 102, 103
*ELSET, ELSET=Clamp
21
*NSET, NSET=CLAMP
101
*NSET, NSET=Tip, GENERATE
104, 105, 1
*NSET, NSET=Combined
tip, 101
*ELSET, ELSET=Both, GENERATE
11, 12, 1
*NSET, NSET=FromElements, ELSET=Clamp
*STEP
*STATIC
*END STEP
"""


def test_abaqus_labels_and_sets(tmp_path):
    path = tmp_path / "model.inp"
    path.write_text(ABAQUS_INP)
    mesh = read_mesh(path)
    np.testing.assert_array_equal(mesh.nodes, TWO_TETS_NODES)
    np.testing.assert_array_equal(mesh.node_ids, [101, 102, 103, 104, 105])
    # The S3 element is a flat shell ("tri3"), next to the solids.
    assert list(mesh.elements) == ["tet4", "tri3"]
    np.testing.assert_array_equal(mesh.elements["tet4"], TWO_TETS)
    np.testing.assert_array_equal(mesh.element_ids["tet4"], [11, 12])
    np.testing.assert_array_equal(mesh.elements["tri3"], [[0, 1, 2]])
    np.testing.assert_array_equal(mesh.element_ids["tri3"], [21])
    assert mesh.shell_thickness is None
    expected = {
        "AllNodes": [0, 1, 2, 3, 4],
        "CLAMP": [0, 1, 2],  # *NSET CLAMP and *ELSET Clamp (the nodes of shell 21): one set
        "Tip": [3, 4],
        "Combined": [0, 3, 4],
        "FromElements": [0, 1, 2],
        "Solid": [0, 1, 2, 3, 4],
        "Both": [0, 1, 2, 3, 4],
    }
    assert sorted(mesh.node_sets) == sorted(expected)
    for name, indices in expected.items():
        np.testing.assert_array_equal(mesh.node_sets[name], indices, err_msg=name)
    validate_mesh(mesh)


def test_abaqus_blocks_of_types_meshio_cannot_read_are_left_out_with_a_warning(tmp_path):
    # One block of membranes (M3D4, unknown to meshio) made the whole file unreadable
    # ("Element type not available"). It is left out with a warning naming it, and its
    # element set still gives a node set (an element continued on a second line too).
    path = tmp_path / "skin.inp"
    skin = "*ELEMENT, TYPE=M3D3, ELSET=Skin\n31, 101, 102,\n 105\n32, 102, 103, 105\n"
    path.write_text(ABAQUS_INP.replace("*ELSET, ELSET=Clamp", skin + "*ELSET, ELSET=Clamp"))
    with pytest.warns(MeshQualityWarning, match="2 M3D3 element.*first: element 31.*line 16"):
        mesh = read_mesh(path)
    assert list(mesh.elements) == ["tet4", "tri3"]
    np.testing.assert_array_equal(mesh.node_sets["Skin"], [0, 1, 2, 4])
    np.testing.assert_array_equal(mesh.node_sets["FromElements"], [0, 1, 2])
    # An element of such a block on a node nobody defines is named.
    path.write_text(path.read_text().replace("32, 102, 103, 105", "32, 102, 103, 999"))
    with pytest.raises(UnknownItemError, match="line 16: element 32 refers to node 999"):
        read_mesh(path)


def test_abaqus_elements_flexmbd_lacks_are_named_not_dropped(tmp_path):
    # Second-order shells and beams and plane elements next to solids are types meshio knows,
    # of a lower dimension: they were dropped without a word (their mass and stiffness lost);
    # a file of membranes only read as an empty mesh; a lower-case type failed in meshio.
    extra = (
        "*ELEMENT, TYPE=S8R\n31, 101, 102, 103, 104, 105, 101, 102, 103\n"
        "*ELEMENT, TYPE=B32\n32, 101, 102, 103\n"
    )
    path = tmp_path / "mixed.inp"
    path.write_text(ABAQUS_INP.replace("*ELSET, ELSET=Clamp", extra + "*ELSET, ELSET=Clamp"))
    with pytest.warns(MeshQualityWarning) as caught:
        mesh = read_mesh(path)
    said = " ".join(str(w.message) for w in caught)
    assert "1 S8R element(s) (first: element 31)" in said and "1 B32 element(s)" in said
    assert sorted(mesh.elements) == ["tet4", "tri3"]
    path.write_text("*NODE\n1, 0, 0, 0\n2, 1, 0, 0\n3, 1, 1, 0\n4, 0, 1, 0\n"
                    "*ELEMENT, TYPE=M3D4\n1, 1, 2, 3, 4\n")  # fmt: skip
    with pytest.raises(InvalidModelError, match="no element flexmbd has: 1 M3D4"):
        read_mesh(path)
    path.write_text(ABAQUS_INP.replace("TYPE=C3D4,", "type=c3d4,"))
    np.testing.assert_array_equal(read_mesh(path).elements["tet4"], TWO_TETS)
    # The command line shows the warning as flexmbd's, not at a line of the package.
    path.write_text(ABAQUS_INP.replace("*ELSET, ELSET=Clamp", extra + "*ELSET, ELSET=Clamp"))
    run = subprocess.run(
        [sys.executable, "-m", "flexmbd", "info", str(path)], capture_output=True, text=True
    )
    assert run.returncode == 0, run.stderr
    assert "flexmbd: MeshQualityWarning: " in run.stderr and ".py:" not in run.stderr


def test_abaqus_types_meshio_misreads(tmp_path, assert_close):
    # meshio names C3D4H but fails on it (KeyError 'tetra4'), and C3D15 (KeyError 'wedge15':
    # its table of cell dimensions lacks wedge15): "cannot read the mesh". C3D4H is a tet4;
    # C3D15 a wedge15, in Abaqus' order (the corners of C3D6, then the mid-edge nodes of the
    # edges 1-2, 2-3, 3-1, 4-5, 5-6, 6-4, 1-4, 2-5, 3-6).
    path = tmp_path / "hybrid.inp"
    path.write_text(ABAQUS_INP.replace("TYPE=C3D4,", "TYPE=C3D4H,"))
    mesh = read_mesh(path)
    np.testing.assert_array_equal(mesh.elements["tet4"], TWO_TETS)
    np.testing.assert_array_equal(mesh.element_ids["tet4"], [11, 12])
    corners = np.array([[0, 0, 0], [2, 0, 0], [0, 1, 0], [0, 0, 3], [2, 0, 3], [0, 1, 3]], float)
    edges = [(0, 1), (1, 2), (2, 0), (3, 4), (4, 5), (5, 3), (0, 3), (1, 4), (2, 5)]
    points = np.vstack([corners, [0.5 * (corners[p] + corners[q]) for p, q in edges]])
    nodes = "".join(f"{k + 1}, {x:g}, {y:g}, {z:g}\n" for k, (x, y, z) in enumerate(points))
    labels = [str(k) for k in range(1, 16)]
    path.write_text(
        f"*NODE\n{nodes}*ELEMENT, TYPE=C3D15, ELSET=ALL\n40, " + ", ".join(labels[:8])
        + ",\n" + ", ".join(labels[8:]) + "\n"
    )  # fmt: skip
    mesh = read_mesh(path)
    np.testing.assert_array_equal(mesh.elements["wedge15"], [np.arange(15)])
    assert mesh.element_ids["wedge15"].tolist() == [40]
    assert_close(pp.body_from_mesh(mesh, STEEL).invariants.mass, 3.0 * 7800.0, rel=1e-12)


def test_abaqus_c3d10_order(tmp_path):
    # Abaqus C3D10: nodes 5..10 on edges 1-2, 2-3, 3-1, 1-4, 2-4, 3-4 (1-based), the VTK order.
    nodes = tet10_nodes()
    lines = ["*NODE"] + [
        f"{10 + i}, {x:.17g}, {y:.17g}, {z:.17g}" for i, (x, y, z) in enumerate(nodes)
    ]
    labels = [str(10 + i) for i in range(10)]
    lines += ["*ELEMENT, TYPE=C3D10", "5, " + ", ".join(labels[:7]) + ",", ", ".join(labels[7:])]
    path = tmp_path / "c3d10.inp"
    path.write_text("\n".join(lines) + "\n")
    mesh = read_mesh(path)
    np.testing.assert_array_equal(mesh.node_ids, np.arange(10, 20))
    np.testing.assert_array_equal(mesh.element_ids["tet10"], [5])
    np.testing.assert_array_equal(mesh.elements["tet10"], [VTK_TO_GMSH])
    assert_gmsh_tet10(mesh, mesh.elements["tet10"][0])


def wedge_roof(inverted=False):
    """The two hexahedra of `hex_block` with a wedge roof on the first (its ridge along y at
    x = 0.5, z = 1.5), its triangles in meshio's (Gmsh's) order, or the other way round."""
    points, hexes = hex_block()
    top = points[hexes[0, 4:]]
    apex = np.vstack([top[[0, 1]].mean(axis=0), top[[3, 2]].mean(axis=0)]) + [0, 0, 0.5]
    points = np.vstack([points, apex])
    n = len(points)
    t = hexes[0, 4:]
    wedge = [t[0], n - 2, t[1], t[3], n - 1, t[2]]
    if inverted:
        wedge = [wedge[k] for k in (0, 2, 1, 3, 5, 4)]
    return meshio.Mesh(points, [("hexahedron", hexes), ("wedge", np.array([wedge]))])


def test_wedges_are_read_and_an_inverted_one_is_named(tmp_path, assert_close):
    # A wedge on a hexahedron (VTK, whose wedges meshio converts to its order) and a C3D6
    # wedge (Abaqus) were refused; they are wedge6 elements: the roofed block has the volume
    # 2 + 0.25.
    path = write(tmp_path, "bracket.vtu", wedge_roof(), "vtu")
    roof = read_mesh(path)
    assert sorted(roof.elements) == ["hex8", "wedge6"]
    body = pp.body_from_mesh(roof, Material(1.0e9, 0.3, 1000.0))
    assert_close(body.invariants.mass, 2250.0, rel=1e-12, what="mass")
    abaqus = tmp_path / "wedge.inp"
    abaqus.write_text(
        "*NODE\n1, 0, 0, 0\n2, 1, 0, 0\n3, 0, 1, 0\n4, 0, 0, 1\n5, 1, 0, 1\n6, 0, 1, 1\n"
        "*ELEMENT, TYPE=C3D6, ELSET=ALL\n40, 1, 2, 3, 4, 5, 6\n"
    )
    mesh = read_mesh(abaqus)
    assert mesh.element_ids["wedge6"].tolist() == [40]
    assert_close(pp.body_from_mesh(mesh, STEEL).invariants.mass, 0.5 * 7800.0, rel=1e-12)
    # VTK files have wedges listed either way round (VTK 9.7 changed its order; meshio mirrors
    # them into that of VTK before 9.7): the mirrored roof is read as the same wedge.
    path = write(tmp_path, "mirrored.vtu", wedge_roof(inverted=True), "vtu")
    np.testing.assert_array_equal(read_mesh(path).elements["wedge6"], roof.elements["wedge6"])
    # Elsewhere nodes are never reordered: a C3D6 listed the other way round is inverted, named.
    abaqus.write_text(abaqus.read_text().replace("40, 1, 2, 3, 4, 5, 6", "40, 1, 3, 2, 4, 6, 5"))
    with pytest.raises(InvalidModelError, match="inverted.*wedge6"):
        pp.body_from_mesh(read_mesh(abaqus), STEEL)


def test_cells_that_are_not_elements_are_refused_not_left_out(tmp_path):
    # A 24-node hexahedron next to a hexahedron (VTK), a C3D5 pyramid next to a C3D4
    # (Abaqus), a 6-node triangle among shell triangles: before, read_mesh left them out
    # without a word, and the body had a hole (a wedge-and-hex bracket: 62.4 kg instead of
    # 70.2). (meshio cannot even hold a hexahedron24 cell until told its dimension.) Quadratic
    # pyramids and wedges are elements now: tests/test_pyramids.py, tests/test_wedges.py.
    from flexmbd.fe.mesh_io import complete_meshio

    complete_meshio()
    points, hexes = hex_block()
    extra = np.random.default_rng(0).random((16, 3)) + [1.0, 0.0, 0.0]
    cell = np.array([[*hexes[1], *range(len(points), len(points) + 16)]])
    path = write(
        tmp_path, "bracket.vtu",
        meshio.Mesh(np.vstack([points, extra]), [("hexahedron", hexes[:1]),
                                                  ("hexahedron24", cell)]), "vtu",
    )  # fmt: skip
    with pytest.raises(
        InvalidModelError, match=r"1 hexahedron24 cell \(the first is element "
    ) as info:
        read_mesh(path)
    assert "mass and stiffness" in str(info.value)
    assert "pyramid13, pyramid14" in str(info.value)  # the element types flexmbd has
    assert info.value.item.startswith("element ")

    abaqus = tmp_path / "wedge.inp"
    nodes = "".join(f"{k + 1}, {k}, {k % 2}, {k % 3}\n" for k in range(16))
    abaqus.write_text(
        f"*NODE\n{nodes}*ELEMENT, TYPE=C3D4\n1, 1, 2, 3, 4\n*ELEMENT, TYPE=C3D5\n"
        "40, " + ", ".join(str(k) for k in range(2, 7)) + "\n"
    )
    with pytest.raises(InvalidModelError, match=r"1 C3D5 cell \(the first is element 40\)"):
        read_mesh(abaqus)

    points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [0.5, 0, 0], [1, 0.5, 0],
                       [0.5, 0.5, 0.0]], dtype=float)  # fmt: skip
    cells = [("triangle", np.array([[0, 1, 2]])), ("triangle6", np.array([[1, 3, 2, 5, 6, 6]]))]
    path = write(tmp_path, "shell.vtu", meshio.Mesh(points, cells), "vtu")
    with pytest.raises(InvalidModelError, match=r"triangle6 cell .*quad4, tri3.*at order 1"):
        read_mesh(path)


def test_abaqus_set_with_unknown_node(tmp_path):
    path = tmp_path / "bad.inp"
    path.write_text(ABAQUS_INP.replace("*NSET, NSET=CLAMP\n101", "*NSET, NSET=CLAMP\n999"))
    with pytest.raises(UnknownItemError, match="node set 'CLAMP' refers to node 999") as info:
        read_mesh(path)
    assert info.value.item == "node 999"


def test_abaqus_element_with_unknown_node(tmp_path):
    path = tmp_path / "bad.inp"
    path.write_text(ABAQUS_INP.replace("11, 101, 102, 103, 104", "11, 101, 102, 103, 777"))
    with pytest.raises(UnknownItemError, match="an element refers to node 777") as info:
        read_mesh(path)
    assert info.value.item == "node 777"


def test_abaqus_two_node_blocks(tmp_path):
    path = tmp_path / "two_blocks.inp"
    path.write_text(ABAQUS_INP.replace("103, 0.0, 1.0, 0.0\n", "103, 0.0, 1.0, 0.0\n*NODE\n"))
    with pytest.raises(InvalidModelError, match="second \\*NODE block") as info:
        read_mesh(path)
    assert str(path) in str(info.value)


# Issue 28: GENERATE with step 0 looped or raised ZeroDivisionError, a range of 10^12 labels
# exhausted memory, labels of 2^70 overflowed int64 (OverflowError), and *INCLUDE followed
# absolute paths and looked in the working folder before the input's folder.

TWO_TETS_INP = ABAQUS_INP.split("*ELEMENT, TYPE=S3")[0]


@pytest.mark.parametrize(
    "lines, error, match",
    [
        ("*NSET, NSET=A, GENERATE\n101, 105, 0", InvalidModelError, "step 0: the step must be"),
        ("*NSET, NSET=A, GENERATE\n101, 105, -1", InvalidModelError, "step -1"),
        ("*NSET, NSET=A, GENERATE\n105, 101", InvalidModelError, "first label must not exceed"),
        ("*NSET, NSET=A, GENERATE\n0, 5", InvalidModelError, "label 0 is out of range"),
        ("*NSET, NSET=A, GENERATE\n1, 1000000000000, 1", UnknownItemError, "1000000000000 labels"),
        ("*ELSET, ELSET=E, GENERATE\n1, 1000000000000", UnknownItemError, "element set 'E'"),
        (f"*NSET, NSET=A\n101, {2**70}", InvalidModelError, f"label {2**70} is out of range"),
        ("*NSET, NSET=A\n-3", InvalidModelError, "label -3 is out of range"),
    ],
    ids=[
        "step 0",
        "negative step",
        "reversed",
        "label 0",
        "huge nodes",
        "huge elements",
        "2^70",
        "negative label",
    ],
)
def test_abaqus_bad_labels_and_generate_lines(tmp_path, lines, error, match):
    path = tmp_path / "bad.inp"
    path.write_text(TWO_TETS_INP + lines + "\n")
    with pytest.raises(error, match=match) as info:
        read_mesh(path)
    assert str(path) in str(info.value)


def test_abaqus_node_label_of_2_to_the_70(tmp_path):
    path = tmp_path / "bad.inp"
    path.write_text(TWO_TETS_INP.replace("105, 1.0", f"{2**70}, 1.0"))
    with pytest.raises(InvalidModelError, match="line 9: label .* is out of range"):
        read_mesh(path)
    # The checks keep valid ranges: every other node.
    path.write_text(TWO_TETS_INP + "*NSET, NSET=Odd, GENERATE\n101, 105, 2\n")
    np.testing.assert_array_equal(read_mesh(path).node_sets["Odd"], [0, 2, 4])


def test_abaqus_include_is_relative_to_the_including_file_only(tmp_path, monkeypatch):
    nodes_and_elements = TWO_TETS_INP.replace("*NODE, NSET=AllNodes", "*NODE")
    (tmp_path / "model" / "parts").mkdir(parents=True)
    (tmp_path / "model" / "parts" / "mesh.inp").write_text(nodes_and_elements)
    # A nested include reaching back up, but inside the input's folder.
    (tmp_path / "model" / "parts" / "sets.inp").write_text(
        "*INCLUDE, INPUT=../common.inp\n*NSET, NSET=Tip\n104, 105\n"
    )
    (tmp_path / "model" / "common.inp").write_text("*NSET, NSET=Origin\n101\n")
    main = tmp_path / "model" / "main.inp"
    main.write_text(
        '*INCLUDE, INPUT="parts/mesh.inp"\n*INCLUDE, INPUT=parts/sets.inp\n'
        "*NSET, NSET=Both\nTip, Origin\n"
    )
    # A decoy of the same relative name in the working folder must not be read.
    decoy = tmp_path / "work"
    (decoy / "parts").mkdir(parents=True)
    (decoy / "parts" / "mesh.inp").write_text("*NODE\n1, 9.0, 9.0, 9.0\n")
    monkeypatch.chdir(decoy)
    mesh = read_mesh(main)
    np.testing.assert_array_equal(mesh.nodes, TWO_TETS_NODES)
    np.testing.assert_array_equal(mesh.elements["tet4"], TWO_TETS)
    np.testing.assert_array_equal(mesh.node_sets["Tip"], [3, 4])
    np.testing.assert_array_equal(mesh.node_sets["Both"], [0, 3, 4])


@pytest.mark.parametrize(
    "target, match",
    [
        ("ABSOLUTE", "absolute path .* is refused"),
        ("../outside.inp", "leaves the folder of the input file"),
        ("link/outside.inp", "leaves the folder of the input file"),
        ("missing.inp", "'missing.inp' not found"),
        ("main.inp", "cycle"),
        ("other.inp", "cycle .*main.inp -> .*other.inp -> .*main.inp"),
    ],
    ids=["absolute", "parent folder", "symbolic link", "missing", "itself", "loop"],
)
def test_abaqus_includes_outside_the_input_folder_and_cycles_are_refused(tmp_path, target, match):
    outside = tmp_path / "outside.inp"
    outside.write_text(TWO_TETS_INP)
    folder = tmp_path / "model"
    folder.mkdir()
    (folder / "link").symlink_to(tmp_path, target_is_directory=True)
    (folder / "other.inp").write_text("*INCLUDE, INPUT=main.inp\n")
    main = folder / "main.inp"
    target = str(outside) if target == "ABSOLUTE" else target
    main.write_text(f"*INCLUDE, INPUT={target}\n")
    with pytest.raises(InvalidModelError, match=match) as info:
        read_mesh(main)
    assert "line 1" in str(info.value)


def test_unknown_suffix_and_missing_file(tmp_path):
    path = tmp_path / "mesh.stl"
    path.write_text("solid\nendsolid\n")
    with pytest.raises(InvalidParameterError, match="unsupported mesh file suffix '.stl'"):
        read_mesh(path)
    with pytest.raises(FileNotFoundError):
        read_mesh(tmp_path / "missing.msh")


def test_unreadable_file(tmp_path):
    path = tmp_path / "broken.msh"
    path.write_text("this is not a mesh\n")
    with pytest.raises(InvalidModelError, match="cannot read the mesh") as info:
        read_mesh(path)
    assert info.value.item == f"file '{path}'"


@pytest.mark.parametrize("kind", ["fifo", "dev-zero", "folder"])
def test_a_mesh_path_that_is_not_a_regular_file_is_refused(tmp_path, kind):
    # Issue 28 (fuzz): a FIFO or a link to /dev/zero blocked read_mesh for ever (meshio, or
    # the scan of an Abaqus input, read it). The read runs in a child process, limited to
    # 2 GB of memory (/dev/zero is endless) and killed after 30 s.
    path = tmp_path / ("mesh.inp" if kind == "dev-zero" else "mesh.msh")
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "dev-zero":
        path.symlink_to("/dev/zero")
    else:
        path.mkdir()
    code = (
        "import resource, sys\n"
        "resource.setrlimit(resource.RLIMIT_AS, (2 << 30, 2 << 30))\n"
        "from flexmbd.errors import InvalidModelError\n"
        "from flexmbd.fe.mesh_io import read_mesh\n"
        "try:\n"
        "    read_mesh(sys.argv[1])\n"
        "except InvalidModelError as error:\n"
        "    print(error.item, error, sep='|')\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code, str(path)], capture_output=True, text=True, timeout=30
    )
    assert done.returncode == 0, done.stderr
    item, message = done.stdout.strip().split("|", 1)
    assert item == f"file '{path}'"
    assert message == f"{path}: the mesh file is not a regular file (a folder, a FIFO or a device)"


def test_an_include_that_is_not_a_regular_file_is_refused(tmp_path):
    # A FIFO as *INCLUDE file was reported as not found; it is there, but cannot be read.
    os.mkfifo(tmp_path / "nodes.inp")
    main = tmp_path / "main.inp"
    main.write_text("*INCLUDE, INPUT=nodes.inp\n")
    with pytest.raises(
        InvalidModelError, match="line 1: the \\*INCLUDE file .* not a regular"
    ) as info:
        read_mesh(main)
    assert info.value.item == f"file '{tmp_path / 'nodes.inp'}'"


# ---------------------------------------------------------------------------------------------
# validate_mesh


def two_tets(**changes) -> Mesh:
    fields = {
        "nodes": TWO_TETS_NODES.copy(),
        "node_ids": np.array([11, 12, 13, 14, 15]),
        "elements": {"tet4": TWO_TETS.copy()},
        "element_ids": {"tet4": np.array([1, 2])},
        "node_sets": {"clamp": np.array([0, 1, 2])},
    }
    fields.update(changes)
    return Mesh(**fields)


def test_valid_mesh_passes():
    validate_mesh(two_tets())


def test_node_index_out_of_range():
    mesh = two_tets(elements={"tet4": np.array([[0, 1, 2, 3], [1, 2, 3, 5]])})
    with pytest.raises(
        UnknownItemError, match="element 2 \\(tet4\\) refers to node index 5"
    ) as info:
        validate_mesh(mesh)
    assert info.value.item == "element 2"
    mesh = two_tets(elements={"tet4": np.array([[0, 1, 2, -1], [1, 2, 3, 4]])})
    with pytest.raises(UnknownItemError, match="element 1 \\(tet4\\) refers to node index -1"):
        validate_mesh(mesh)


def test_duplicate_nodes_name_both():
    nodes = np.vstack([TWO_TETS_NODES, TWO_TETS_NODES[2] + 1e-14])
    mesh = two_tets(
        nodes=nodes,
        node_ids=np.array([11, 12, 13, 14, 15, 16]),
        elements={"tet4": np.array([[0, 1, 2, 3], [1, 5, 3, 4]])},
    )
    with pytest.raises(InvalidModelError, match="nodes 13 and 16 are at the same position"):
        validate_mesh(mesh)
    # 1e-9 apart in a mesh of size ~1.7 is not a duplicate.
    mesh.nodes[5] = TWO_TETS_NODES[2] + 1e-9
    mesh.elements["tet4"][0, 2] = 5
    mesh.nodes[2] = [0.0, 0.5, 0.5]
    mesh.elements["tet4"][1, 0] = 2
    validate_mesh(mesh)


def test_unconnected_node():
    nodes = np.vstack([TWO_TETS_NODES, [[5.0, 5.0, 5.0], [6.0, 6.0, 6.0]]])
    mesh = two_tets(nodes=nodes, node_ids=np.array([11, 12, 13, 14, 15, 17, 18]))
    with pytest.raises(InvalidModelError, match="unconnected node 17.*1 more: 18") as info:
        validate_mesh(mesh)
    assert info.value.item == "node 17"


def test_element_with_repeated_node():
    mesh = two_tets(elements={"tet4": np.array([[0, 1, 2, 3], [1, 2, 4, 4]])})
    with pytest.raises(InvalidModelError, match="element 2 \\(tet4\\) uses node 15 more than once"):
        validate_mesh(mesh)


@pytest.mark.parametrize(
    "changes, error, match",
    [
        ({"node_ids": np.array([11, 12, 12, 14, 15])}, InvalidModelError, "node id 12 is used 2"),
        ({"element_ids": {"tet4": np.array([3, 3])}}, InvalidModelError, "element id 3 is used"),
        (
            {"elements": {"tri6": TWO_TETS[:, :3]}, "element_ids": {"tri6": np.array([1, 2])}},
            UnknownItemError,
            "unknown element type 'tri6'",
        ),
        ({"elements": {"tet4": TWO_TETS[:, :3]}}, InvalidModelError, "shape \\(n, 4\\)"),
        ({"elements": {}, "element_ids": {}}, InvalidModelError, "no elements"),
        ({"node_sets": {"tip": np.array([4, 9])}}, UnknownItemError, "node set 'tip'.* index 9"),
        ({"nodes": TWO_TETS_NODES[:, :2]}, InvalidModelError, "\\(n, 3\\)"),
    ],
)
def test_structural_errors(changes, error, match):
    with pytest.raises(error, match=match):
        validate_mesh(two_tets(**changes))


def test_non_finite_coordinates():
    nodes = TWO_TETS_NODES.copy()
    nodes[3, 1] = np.nan
    with pytest.raises(InvalidParameterError, match="node 14 has non-finite coordinates"):
        validate_mesh(two_tets(nodes=nodes))


def test_huge_coordinates_are_refused_before_the_duplicate_node_search(tmp_path):
    # Issue 28 (fuzz): a node coordinate of 1e308 made scipy's cKDTree.query_pairs raise
    # ValueError 'Encountering floating point overflow'.
    nodes = TWO_TETS_NODES.copy()
    nodes[3, 1] = 1e308
    with pytest.raises(
        InvalidModelError, match=r"node 14 has coordinates \[0.0, 1e\+308, 1.0\]"
    ) as info:
        validate_mesh(two_tets(nodes=nodes))
    assert info.value.item == "node 14"
    nodes[3, 1] = -1.0001 * MAX_NODE_COORDINATE
    with pytest.raises(InvalidModelError, match="node 14 .* beyond 1e\\+100"):
        validate_mesh(two_tets(nodes=nodes))
    # Large but not absurd: a mesh scaled to the limit is checked as usual.
    validate_mesh(two_tets(nodes=TWO_TETS_NODES * MAX_NODE_COORDINATE))
    # The same from a file, read and then checked.
    path = tmp_path / "huge.inp"
    path.write_text(TWO_TETS_INP.replace("104, 0.0, 0.0, 1.0", "104, 0.0, 1e308, 1.0"))
    with pytest.raises(InvalidModelError, match="node 104 has coordinates"):
        validate_mesh(read_mesh(path))


# ---------------------------------------------------------------------------------------------
# Abaqus matrices


def symmetric_matrix() -> np.ndarray:
    """A known symmetric 6 x 6 matrix (2 nodes x 3 dofs) with some zeros."""
    rng = np.random.default_rng(7)
    a = rng.normal(size=(6, 6))
    a = np.round(a + a.T, 6)
    a[0, 5] = a[5, 0] = 0.0
    return a


def write_mtx(path: Path, matrix: np.ndarray, node_ids, keep, separator=", ") -> Path:
    """Write the entries (i, j) with keep(i, j) in Abaqus' node, dof, node, dof, value form."""
    lines = ["** stiffness matrix written by a test"]
    for i, j in itertools.product(range(len(matrix)), repeat=2):
        if keep(i, j) and matrix[i, j] != 0.0:
            fields = [node_ids[i // 3], i % 3 + 1, node_ids[j // 3], j % 3 + 1]
            lines.append(separator.join(map(str, fields)) + f"{separator}{matrix[i, j]:.16e}")
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.parametrize(
    "keep",
    [lambda i, j: i >= j, lambda i, j: i <= j, lambda i, j: True],
    ids=["lower", "upper", "full"],
)
def test_abaqus_matrix_triangles(tmp_path, keep):
    expected = symmetric_matrix()
    path = write_mtx(tmp_path / "K.mtx", expected, node_ids=[5, 9], keep=keep)
    matrix, node_ids, dofs_per_node = read_abaqus_matrix(path)
    assert isinstance(matrix, sp.csc_matrix) and matrix.dtype == np.float64
    np.testing.assert_array_equal(matrix.toarray(), expected)
    np.testing.assert_array_equal(node_ids, [5, 9])
    assert node_ids.dtype == np.int64
    assert dofs_per_node == 3


def test_abaqus_matrix_node_order_and_dofs(tmp_path):
    # Nodes given in decreasing id order and blank-separated still map node-major by id.
    expected = symmetric_matrix()
    path = write_mtx(tmp_path / "K.mtx", expected, [9, 5], lambda i, j: i >= j, separator=" ")
    matrix, node_ids, _ = read_abaqus_matrix(path)
    np.testing.assert_array_equal(node_ids, [5, 9])
    swap = [3, 4, 5, 0, 1, 2]
    np.testing.assert_array_equal(matrix.toarray(), expected[np.ix_(swap, swap)])
    # More dofs per node than the file uses: zero rows and columns for the missing dofs.
    matrix, _, dofs_per_node = read_abaqus_matrix(path, dofs_per_node=6)
    assert dofs_per_node == 6 and matrix.shape == (12, 12)
    kept = [0, 1, 2, 6, 7, 8]
    np.testing.assert_array_equal(
        matrix.toarray()[np.ix_(kept, kept)], expected[np.ix_(swap, swap)]
    )


@pytest.mark.parametrize(
    "bad_line, match",
    [
        ("5, 1, 5, 1", "expected 5 fields"),
        ("5, x, 5, 1, 1.0", "row dof 'x' is not an integer"),
        ("5, 1, 5, 1, abc", "value 'abc' is not a finite number"),
        ("5, 1, 5, 1, nan", "not a finite number"),
        ("-3, 1, 5, 1, 1.0", "Abaqus internal nodes"),
        ("5, 0, 5, 1, 1.0", "row dof 0 must be positive"),
        ("1 2 3.5", "FORMAT=COORDINATE"),
    ],
)
def test_abaqus_matrix_bad_line(tmp_path, bad_line, match):
    path = write_mtx(tmp_path / "K.mtx", symmetric_matrix(), [5, 9], lambda i, j: i >= j)
    lines = path.read_text().splitlines()
    lines.insert(4, bad_line)  # line 5 of the file
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(InvalidParameterError, match=f"line 5: .*{match}") as info:
        read_abaqus_matrix(path)
    assert info.value.item == f"line 5 of '{path}'"


def test_abaqus_matrix_inconsistent_entries(tmp_path):
    path = tmp_path / "K.mtx"
    path.write_text("1, 1, 1, 1, 2.0\n1, 2, 1, 1, 1.0\n1, 1, 1, 2, 1.5\n")
    with pytest.raises(InvalidParameterError, match="its mirror on line"):
        read_abaqus_matrix(path)
    path.write_text("1, 1, 1, 1, 2.0\n1, 2, 1, 1, 1.0\n1, 2, 1, 1, 1.0\n")
    with pytest.raises(InvalidParameterError, match="line 3: entry \\(1, 0\\) given again"):
        read_abaqus_matrix(path)
    path.write_text("1, 4, 1, 1, 2.0\n")
    with pytest.raises(InvalidParameterError, match="dof 4 > dofs_per_node 3"):
        read_abaqus_matrix(path, dofs_per_node=3)
    path.write_text("** only a comment\n\n")
    with pytest.raises(InvalidParameterError, match="no matrix entries"):
        read_abaqus_matrix(path)


# ---------------------------------------------------------------------------------------------
# Matrices given as arrays


def test_matrices_from_arrays_dense_and_sparse():
    stiffness = symmetric_matrix() + 20.0 * np.eye(6)  # a stiffness: no negative diagonal
    mass = np.diag(np.arange(1.0, 7.0))
    k, m = matrices_from_arrays(stiffness, sp.csr_matrix(mass))
    assert isinstance(k, sp.csc_matrix) and isinstance(m, sp.csc_matrix)
    assert k.dtype == np.float64 and m.dtype == np.float64
    np.testing.assert_array_equal(k.toarray(), stiffness)
    np.testing.assert_array_equal(m.toarray(), mass)
    # A tiny asymmetry (rounding) is accepted and kept.
    stiffness[0, 1] += 1e-12
    k, _ = matrices_from_arrays(stiffness, mass)
    assert k[0, 1] == stiffness[0, 1]


@pytest.mark.parametrize(
    "stiffness, mass, match",
    [
        (np.ones((3, 4)), np.eye(3), "stiffness matrix must be square"),
        (np.eye(3), np.eye(4), "mass matrix has shape \\(4, 4\\)"),
        (np.array([[1.0, 2.0], [2.1, 1.0]]), np.eye(2), "stiffness matrix is not symmetric"),
        (np.eye(2), sp.csc_matrix(np.array([[1.0, 0.0], [1.0, 1.0]])), "mass matrix is not sym"),
        (np.diag([1.0, np.inf]), np.eye(2), "non-finite entry at \\(1, 1\\)"),
        (np.eye(2) * 1j, np.eye(2), "must be real"),
        (np.ones(3), np.eye(3), "must be square"),
        # A stiffness of the wrong sign was accepted (the modes then blamed the reference
        # conditions, a nodal body ran away).
        (-np.eye(2), np.eye(2), "stiffness matrix has a negative diagonal entry A\\[0, 0\\]"),
        (np.eye(2), np.diag([1.0, -1.0]), "mass matrix has a negative diagonal entry A\\[1, 1\\]"),
    ],
)
def test_matrices_from_arrays_errors(stiffness, mass, match):
    with pytest.raises(InvalidParameterError, match=match):
        matrices_from_arrays(stiffness, mass)
