"""Wedges ("wedge6": Abaqus C3D6, Gmsh prisms, VTK wedges) in bodies: interfaces on their
triangular and quadrilateral faces, VTK output, model files. The element kernel's tests
(moments, mass fractions, patch tests, rigid-body modes) are in
`crates/flexmbd-core/src/fem/solid/tests`; invariants, kinetic energy, rigid motions and the
cantilever are in tests/test_solids.py (its SOLIDS); reading them (and an inverted one named)
in tests/test_mesh_io.py."""

import meshio
import numpy as np

import flexmbd as fm
import flexmbd.fe.preprocess as pp
from flexmbd._core import Material
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


def test_vtk_output_and_model_files(tmp_path, assert_close):
    mesh, body = interface_body("wedge6", ["x0", "x1"])
    system = fm.System(gravity=(0.0, -9.81, 0.0))
    system.add_flexible_body(body, name="bar")
    result = fm.simulate(system, 0.002, 1e-3)
    fm.animation.write_vtu_series(result, tmp_path / "frames")
    frame = meshio.read(tmp_path / "frames" / "result_00000.vtu")
    wedges = [c.data for c in frame.cells if c.type == "wedge"]
    assert [len(w) for w in wedges] == [60]
    # meshio converts back to its (Gmsh's) order on reading: the cells as written.
    np.testing.assert_array_equal(wedges[0], mesh.elements["wedge6"])
    text = (
        "bodies:\n  - name: bar\n    type: flexible\n"
        "    box: {lengths: [1.0, 0.2, 0.1], divisions: [5, 3, 2], element: wedge6}\n"
        "    material: {young_modulus: 2.1e+11, poisson_ratio: 0.3, density: 7800.0}\n"
        "    reference: interface\n    modes: craig-bampton\n    mode_count: 2\n"
        "    interfaces: [x0, x1]\n    interface_kind: rbe3\n"
        "simulation: {end_time: 0.01, step_size: 0.001}\n"
    )
    (tmp_path / "bar.yaml").write_text(text)
    from_file = load_model(tmp_path / "bar.yaml").body_data["bar"]
    assert list(from_file.elements) == ["wedge6"]
    assert_close(from_file.frequencies, body.frequencies, rel=1e-12, what="frequencies")
