"""Quadratic hexahedra ("hex20", "hex20r": Abaqus C3D20, C3D20R) in bodies: box meshes, a
cantilever one element deep against beam theory, the hourglass modes of reduced integration
refused, Abaqus and VTK files, consistent interface weights, model files and VTK output. The
element kernels' own tests (moments, mass fractions, patch tests, rigid-body and zero-energy
modes) are in `crates/flexmbd-core/src/fem/solid/tests`; invariants, kinetic energy and rigid
motions of bodies are in tests/test_solids.py (its SOLIDS)."""

import meshio
import numpy as np
import pytest
from test_incompatible_hexahedra import clamped_bar as clamped_hexahedra_bar

import flexmbd as fm
import flexmbd.fe.preprocess as pp
from flexmbd._core import Material
from flexmbd.fe import read_mesh, shapes
from flexmbd.fe.shapes import HEX8_CORNERS, HEX20_EDGES
from flexmbd.model_file import load_model

STEEL = Material(2.1e11, 0.3, 7800.0)
#: The corners of the block [0, 2] x [0, 1] x [0, 1] in hex8 order.
BLOCK_CORNERS = np.array(HEX8_CORNERS, dtype=float) * [2.0, 1.0, 1.0]


def test_a_box_of_hex20_has_a_node_at_the_middle_of_every_edge(assert_close):
    mesh = shapes.box((2.0, 1.0, 0.5), (3, 2, 2), "hex20")
    corners = shapes.box((2.0, 1.0, 0.5), (3, 2, 2), "hex8")
    # 4 x 3 x 3 corners, and the grid's 3 x 3 x 3 + 4 x 2 x 3 + 4 x 3 x 2 edges.
    assert mesh.node_count == 36 + 27 + 24 + 24
    conn = mesh.elements["hex20"]
    np.testing.assert_array_equal(conn[:, :8], corners.elements["hex8"])
    for e, (p, q) in enumerate(HEX20_EDGES):
        middle = 0.5 * (mesh.nodes[conn[:, p]] + mesh.nodes[conn[:, q]])
        assert_close(mesh.nodes[conn[:, 8 + e]], middle, abs=1e-15, what=f"edge {e}")
    assert len(np.unique(conn)) == mesh.node_count  # every node in an element
    body = pp.assemble(mesh.nodes, mesh.elements, Material(1.0e9, 0.25, 1.0))
    assert_close(body.invariants["mass"], 1.0, rel=1e-13, what="mass (the volume)")
    np.testing.assert_array_equal(mesh.node_sets["x1"], corners_and_mids(mesh, 0, 2.0))


def corners_and_mids(mesh, axis, value):
    return np.flatnonzero(np.isclose(mesh.nodes[:, axis], value))


def clamped_bar(element, n):
    """The clamped bar of 10 n x n x n elements (its body)."""
    return clamped_hexahedra_bar(element, n, cells=10)[1]


def test_one_element_through_the_depth_bends_like_the_beam(assert_close):
    # First bending frequency of the clamped steel bar 1 x 0.1 x 0.1 m against Euler-Bernoulli
    # (83.82 Hz; shear and rotary inertia lower it by about 0.3 %); hex8 on the same mesh of
    # 10 x 1 x 1 elements is 24 % too stiff (103.8 Hz).
    inertia, area = 0.1**4 / 12, 0.1**2
    euler_bernoulli = 1.8751040687**2 / (2 * np.pi) * np.sqrt(2.1e11 * inertia / (7800.0 * area))
    assert_close(clamped_bar("hex20", 1).frequencies[0], euler_bernoulli, rel=1e-2, what="hex20")
    assert clamped_bar("hex8", 1).frequencies[0] > 1.2 * euler_bernoulli
    # Reduced integration on a mesh two elements deep: softer than full, within 0.3 %.
    full, reduced = clamped_bar("hex20", 2).frequencies[0], clamped_bar("hex20r", 2).frequencies[0]
    assert reduced < full
    assert_close(reduced, euler_bernoulli, rel=3e-3, what="hex20r, 20 x 2 x 2")


def test_hourglass_modes_of_reduced_integration_are_refused():
    # A row of hex20r one element deep keeps zero-energy modes: the body would deform under no
    # force (the clamped bar's stiffness was singular, and the error blamed the clamp).
    mesh = shapes.box((1.0, 0.1, 0.1), (10, 1, 1), "hex20r")
    with pytest.raises(
        fm.InvalidModelError, match=r"hex20r elements .*\(hourglass\) modes"
    ) as error:
        pp.build_body(mesh.nodes, mesh.elements, STEEL, node_sets=mesh.node_sets)
    assert error.value.item == "element 1"
    # A lone element too; two elements deep in both directions across the row is regular.
    single = shapes.box((1.0, 1.0, 1.0), (1, 1, 1), "hex20r")
    with pytest.raises(fm.InvalidModelError, match="hourglass"):
        pp.build_body(single.nodes, single.elements, STEEL)
    block = shapes.box((1.0, 0.2, 0.2), (4, 2, 2), "hex20r")
    pp.build_body(block.nodes, block.elements, STEEL)
    # A row of two cubes: the check held three nodes' translations (nine coordinates), which
    # could hold the row's three hourglass modes too (accepted at this size, refused at half
    # of it); now six coordinates that hold exactly the rigid motions.
    for size in (1.0, 0.5):
        row = shapes.box((2 * size, size, size), (2, 1, 1), "hex20r")
        with pytest.raises(fm.InvalidModelError, match="hourglass"):
            pp.build_body(row.nodes, row.elements, STEEL)


def test_regular_hex20r_meshes_with_other_parts_are_accepted(assert_close):
    # Two blocks, each clamped, and a block with shells on it were refused as hourglass modes
    # (the whole body was checked with three nodes held).
    a = shapes.box((1.0, 0.2, 0.2), (4, 2, 2), "hex20r")
    b = shapes.box((1.0, 0.2, 0.2), (4, 2, 2), "hex20r", origin=(0.0, 1.0, 0.0))
    nodes, n = np.vstack([a.nodes, b.nodes]), a.node_count
    clamp = np.concatenate([a.node_sets["x0"], b.node_sets["x0"] + n])
    conn = np.vstack([a.elements["hex20r"], b.elements["hex20r"] + n])
    two = pp.build_body(nodes, {"hex20r": conn}, STEEL, reference="clamped",
                        reference_nodes=clamp, modes="fixed-interface", mode_count=2)  # fmt: skip
    one = pp.build_body(a.nodes, a.elements, STEEL, node_sets=a.node_sets, reference="clamped",
                        reference_nodes="x0", modes="fixed-interface", mode_count=1)  # fmt: skip
    assert_close(two.frequencies, one.frequencies[0], rel=1e-9, what="two equal blocks")
    hexes = a.elements["hex20r"]
    top = hexes[np.all(np.isclose(a.nodes[hexes[:, 4:8], 2], 0.2), axis=1)][:, 4:8]
    pp.build_body(a.nodes, {"hex20r": hexes, "quad4": top}, STEEL, shell=0.005,
                  reference="clamped", reference_nodes=a.node_sets["x0"])  # fmt: skip


def abaqus_hex20_deck(element_type):
    """One 20-node hexahedron [0, 2] x [0, 1] x [0, 1] in Abaqus (= VTK) node order, labels
    101.., element 7."""
    corners = BLOCK_CORNERS
    nodes = np.vstack([corners, [0.5 * (corners[p] + corners[q]) for p, q in HEX20_EDGES]])
    lines = ["*NODE"] + [f"{101 + k}, {x}, {y}, {z}" for k, (x, y, z) in enumerate(nodes)]
    labels = [str(101 + k) for k in range(20)]
    lines += [f"*ELEMENT, TYPE={element_type}, ELSET=BLOCK", "7, " + ", ".join(labels[:15]) + ","]
    lines += [", ".join(labels[15:])]
    return nodes, "\n".join(lines) + "\n"


@pytest.mark.parametrize(
    "element_type, kind",
    [("C3D20", "hex20"), ("C3D20H", "hex20"), ("C3D20R", "hex20r"), ("C3D20RH", "hex20r")],
)
def test_abaqus_quadratic_hexahedra(tmp_path, element_type, kind, assert_close):
    nodes, deck = abaqus_hex20_deck(element_type)
    (tmp_path / "block.inp").write_text(deck)
    mesh = read_mesh(tmp_path / "block.inp")
    assert list(mesh.elements) == [kind] and mesh.element_ids[kind].tolist() == [7]
    np.testing.assert_array_equal(mesh.elements[kind], [np.arange(20)])
    assert_close(mesh.nodes, nodes, abs=0, what="nodes")
    if kind == "hex20":
        body = pp.body_from_mesh(mesh, STEEL)
        assert_close(body.invariants.mass, 2.0 * 7800.0, rel=1e-13, what="mass")


def test_interfaces_on_quadratic_faces_and_vtk_output(tmp_path, assert_close):
    mesh = shapes.box((1.0, 0.1, 0.1), (10, 1, 1), "hex20")
    body = pp.build_body(
        mesh.nodes, mesh.elements, STEEL, node_sets=mesh.node_sets, reference="interface",
        modes="craig-bampton", mode_count=2, interfaces=["x0", "x1"], interface_kind="rbe3",
    )  # fmt: skip
    # The face of one quad8: the consistent weights int N dA / A, -1/12 at the corners and
    # 1/3 at the mid-edge nodes; their centroid is the face's.
    members = body.reference.interfaces[1]
    weights = body.reference.interface_weights[1]
    corner = np.isin(members, mesh.elements["hex20"][:, :8])
    assert_close(weights[corner], -1 / 12, rel=1e-12, what="corner weights")
    assert_close(weights[~corner], 1 / 3, rel=1e-12, what="mid-edge weights")
    assert_close(weights @ mesh.nodes[members], [1.0, 0.05, 0.05], abs=1e-15, what="centroid")
    system = fm.System(gravity=(0.0, -9.81, 0.0))
    system.add_flexible_body(body, name="bar")
    result = fm.simulate(system, 0.002, 1e-3)
    fm.animation.write_vtu_series(result, tmp_path / "frames")
    frame = meshio.read(tmp_path / "frames" / "result_00000.vtu")
    assert [len(c.data) for c in frame.cells if c.type == "hexahedron20"] == [10]
    assert frame.point_data["von_mises"].shape == (mesh.node_count,)


def test_model_file_box_of_hex20(tmp_path, assert_close):
    text = (
        "bodies:\n  - name: bar\n    type: flexible\n"
        "    box: {lengths: [1.0, 0.1, 0.1], divisions: [10, 1, 1], element: hex20}\n"
        "    material: {young_modulus: 2.1e+11, poisson_ratio: 0.3, density: 7800.0}\n"
        "    reference: clamped\n    reference_nodes: x0\n"
        "    modes: fixed-interface\n    mode_count: 2\n"
        "simulation: {end_time: 0.01, step_size: 0.001}\n"
    )
    (tmp_path / "bar.yaml").write_text(text)
    body = load_model(tmp_path / "bar.yaml").body_data["bar"]
    assert list(body.elements) == ["hex20"]
    assert_close(body.frequencies, clamped_bar("hex20", 1).frequencies, rel=1e-12)


#: Gmsh's 20-node hexahedron (element type 17): its mid-edge nodes 8..19 on these corners.
GMSH_HEX20_EDGES = ((0, 1), (0, 3), (0, 4), (1, 2), (1, 5), (2, 3), (2, 6), (3, 7), (4, 5),
                    (4, 7), (5, 6), (6, 7))  # fmt: skip


def test_gmsh_second_order_hexahedra_are_read_in_the_element_order(tmp_path, assert_close):
    # A Gmsh 2.2 file with one type-17 element in Gmsh's own node order (mid-edge nodes at
    # slightly distinct points of their edges, so that a wrong order shows): read_mesh gives
    # hex20 whose node 8 + e lies on edge HEX20_EDGES[e].
    corners = BLOCK_CORNERS
    shares = 0.5 + 0.01 * np.arange(12)
    edges = zip(shares, GMSH_HEX20_EDGES, strict=True)
    mids = [(1 - s) * corners[p] + s * corners[q] for s, (p, q) in edges]
    nodes = np.vstack([corners, mids])
    lines = ["$MeshFormat", "2.2 0 8", "$EndMeshFormat", "$Nodes", "20"]
    lines += [f"{k + 1} {x} {y} {z}" for k, (x, y, z) in enumerate(nodes)]
    lines += ["$EndNodes", "$Elements", "1", "1 17 2 1 1 " + " ".join(map(str, range(1, 21)))]
    lines += ["$EndElements"]
    (tmp_path / "block.msh").write_text("\n".join(lines) + "\n")
    mesh = read_mesh(tmp_path / "block.msh")
    conn = mesh.elements["hex20"][0]
    for e, (p, q) in enumerate(HEX20_EDGES):
        a, b, m = (mesh.nodes[conn[i]] for i in (p, q, 8 + e))
        # On the segment a-b, strictly inside.
        t = float((m - a) @ (b - a) / ((b - a) @ (b - a)))
        assert_close(m, a + t * (b - a), abs=1e-12, what=f"node {8 + e} on edge {(p, q)}")
        assert 0.4 < t < 0.7, (e, t)
    body = pp.body_from_mesh(mesh, STEEL)
    assert_close(body.invariants.mass, 2.0 * 7800.0, rel=1e-2, what="mass")


def test_volume_weights_of_a_curved_hex20_are_its_mass_row_sums(assert_close):
    # Interface weights took 3-point Gauss on hex20 while the mass points take 4: on a curved
    # element (mid-edge nodes off the edges) they differed by 4e-4 (found by a fault hunt).
    from flexmbd.fe.interface import interface_weights

    mesh = shapes.box((1.0, 1.0, 1.0), (1, 1, 1), "hex20")
    nodes = mesh.nodes.copy()
    nodes[8:] += 0.12 * np.random.default_rng(3).uniform(-1, 1, (12, 3))
    weights, _ = interface_weights(nodes, mesh.elements, np.arange(20), "volume")
    body = pp.build_body(nodes, mesh.elements, Material(1.0e9, 0.3, 1.0))
    rows = np.asarray(body.mass.sum(axis=1)).ravel()[0::3]
    assert_close(weights, rows, rel=0, abs=1e-13, what="volume weights (density 1)")
