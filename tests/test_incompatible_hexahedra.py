"""Hexahedra with incompatible modes ("hex8i", Abaqus' C3D8I) in bodies: the mass of hex8 and a
softer stiffness, a cantilever of one element through its depth against beam theory, Saint-
Venant's pure bending recovered exactly in the stresses, Abaqus' element types, model files,
interfaces and VTK output. The element kernel's own tests (patch tests on distorted elements,
rigid-body modes, exact pure bending energy) are in `crates/flexmbd-core/src/fem/solid/tests`."""

import warnings

import numpy as np
import pytest
from test_solids import rotated_box

import flexmbd as fm
import flexmbd.fe.preprocess as pp
from flexmbd._core import Material
from flexmbd.fe import read_mesh, shapes
from flexmbd.fe.stress import recover_stresses
from flexmbd.model_file import load_model

STEEL = Material(2.1e11, 0.3, 7800.0)
E, NU = 2.1e11, 0.3


def test_hex8i_has_the_mass_of_hex8_and_a_softer_stiffness(assert_close):
    mesh, nodes, *_ = rotated_box("hex8", divisions=(3, 2, 2))
    # A distorted mesh: the modes are condensed on general hexahedra.
    nodes = nodes + 0.02 * np.random.default_rng(5).normal(size=nodes.shape)
    plain = pp.assemble(nodes, mesh.elements, STEEL)
    enriched = pp.assemble(nodes, {"hex8i": mesh.elements["hex8"]}, STEEL)
    assert_close(enriched.mass.toarray(), plain.mass.toarray(), rel=0, abs=0, what="M_ff")
    for key in ("mass", "first_moment", "second_moment"):
        assert_close(enriched.invariants[key], plain.invariants[key], rel=0, abs=0, what=key)
    # Condensing the modes lowers the energy of every deformation, and of some by far.
    difference = np.linalg.eigvalsh((plain.stiffness - enriched.stiffness).toarray())
    scale = abs(plain.stiffness).max()
    assert difference[0] > -1e-9 * scale
    assert difference[-1] > 1e-2 * scale


def clamped_bar(element, n, cells=20):
    """The steel bar 1 x 0.1 x 0.1 m of `cells` n x n x n `element`s, clamped at x0: the mesh
    and its body with two fixed-interface modes."""
    mesh = shapes.box((1.0, 0.1, 0.1), (cells * n, n, n), element)
    return mesh, pp.build_body(
        mesh.nodes,
        mesh.elements,
        STEEL,
        node_sets=mesh.node_sets,
        reference="clamped",
        reference_nodes="x0",
        modes="fixed-interface",
        mode_count=2,
    )


def test_one_element_through_the_depth_bends_like_the_beam(assert_close):
    # First bending frequency of the clamped steel bar 1 x 0.1 x 0.1 m against Euler-Bernoulli
    # (83.82 Hz; shear and rotary inertia lower it by about 0.3 % at L / h = 10).
    inertia, area = 0.1**4 / 12, 0.1**2
    euler_bernoulli = 1.8751040687**2 / (2 * np.pi) * np.sqrt(E * inertia / (7800.0 * area))
    _, body = clamped_bar("hex8i", 1)
    assert_close(body.frequencies[0], euler_bernoulli, rel=5e-3, what="hex8i, 20 x 1 x 1")
    # The trilinear element locks in shear: 11.5 % too stiff on the same mesh.
    _, locked = clamped_bar("hex8", 1)
    assert locked.frequencies[0] > 1.1 * euler_bernoulli


def test_pure_bending_stresses_are_exact_at_every_node(assert_close):
    # Saint-Venant's pure bending about y: u = k x z', v = -nu k y z', w = -k/2 (x^2 + nu (z'^2
    # - y^2)) has sigma_xx = E k z' as its only stress; it lies in the space of hex8i on a
    # mesh of boxes, whose condensed modes take it exactly, but not in that of hex8.
    mesh = shapes.box((2.0, 0.3, 0.2), (4, 2, 2), "hex8i", origin=(0.0, -0.15, -0.1))
    body = pp.build_body(
        mesh.nodes, mesh.elements, STEEL, node_sets=mesh.node_sets, reference="none"
    )
    kappa = 1e-3
    x, y, z = mesh.nodes.T
    field = np.column_stack(
        [kappa * x * z, -NU * kappa * y * z, -0.5 * kappa * (x * x + NU * (z * z - y * y))]
    )
    stresses, _ = recover_stresses(body, field.ravel())
    expected = np.zeros((len(x), 6))
    expected[:, 0] = E * kappa * z
    scale = E * kappa * 0.1
    assert_close(stresses, expected, rel=0, abs=1e-9 * scale, what="hex8i stresses")
    plain = pp.build_body(
        mesh.nodes, {"hex8": mesh.elements["hex8i"]}, STEEL, node_sets=mesh.node_sets,
        reference="none",
    )  # fmt: skip
    wrong, _ = recover_stresses(plain, field.ravel())
    assert np.abs(wrong - expected).max() > 0.1 * scale


def abaqus_deck(element_type):
    """Two cells of a 2 x 1 x 1 grid as one Abaqus element block of `element_type`."""
    nodes = [
        f"{1 + i + 3 * j + 6 * k}, {float(i)}, {float(j)}, {float(k)}"
        for k in (0, 1)
        for j in (0, 1)
        for i in (0, 1, 2)
    ]

    def n(i, j, k):
        return 1 + i + 3 * j + 6 * k

    cells = [
        ", ".join(
            str(v)
            for v in (
                e + 1,
                n(i, 0, 0),
                n(i + 1, 0, 0),
                n(i + 1, 1, 0),
                n(i, 1, 0),
                n(i, 0, 1),
                n(i + 1, 0, 1),
                n(i + 1, 1, 1),
                n(i, 1, 1),
            )
        )  # fmt: skip
        for e, i in enumerate((0, 1))
    ]
    return (
        "*NODE\n" + "\n".join(nodes) + f"\n*ELEMENT, TYPE={element_type}, ELSET=BAR\n"
        + "\n".join(cells) + "\n"
    )  # fmt: skip


@pytest.mark.parametrize("element_type, kind", [("C3D8I", "hex8i"), ("C3D8IH", "hex8i"),
                                                ("C3D8", "hex8"), ("C3D8H", "hex8")])  # fmt: skip
def test_abaqus_hexahedra_are_read_as_their_formulation(tmp_path, element_type, kind):
    path = tmp_path / "bar.inp"
    path.write_text(abaqus_deck(element_type))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        mesh = read_mesh(path)
    assert list(mesh.elements) == [kind]
    assert mesh.element_ids[kind].tolist() == [1, 2]


@pytest.mark.parametrize("element_type", ["C3D8R", "C3D8RH"])
def test_reduced_integration_hexahedra_are_read_as_hex8_with_a_warning(tmp_path, element_type):
    path = tmp_path / "bar.inp"
    path.write_text(abaqus_deck(element_type))
    with pytest.warns(fm.MeshQualityWarning, match=f"2 {element_type} element.*first: element 1"):
        mesh = read_mesh(path)
    assert list(mesh.elements) == ["hex8"]


def test_model_file_box_of_hex8i(tmp_path, assert_close):
    text = (
        "bodies:\n  - name: bar\n    type: flexible\n"
        "    box: {{lengths: [1.0, 0.1, 0.1], divisions: [20, 1, 1], element: {element}}}\n"
        "    material: {{young_modulus: 2.1e+11, poisson_ratio: 0.3, density: 7800.0}}\n"
        "    reference: clamped\n    reference_nodes: x0\n"
        "    modes: fixed-interface\n    mode_count: 2\n"
        "simulation: {{end_time: 0.01, step_size: 0.001}}\n"
    )
    path = tmp_path / "bar.yaml"
    path.write_text(text.format(element="hex8i"))
    body = load_model(path).body_data["bar"]
    assert list(body.elements) == ["hex8i"]
    assert_close(body.frequencies, clamped_bar("hex8i", 1)[1].frequencies, rel=1e-12)


def test_interfaces_and_vtk_output_treat_hex8i_as_a_hexahedron(tmp_path, assert_close):
    import meshio

    from flexmbd.animation import write_vtu_series

    options = {
        "reference": "interface",
        "modes": "craig-bampton",
        "mode_count": 2,
        "interfaces": ["x0", "x1"],
    }
    bodies = {}
    for kind in ("hex8", "hex8i"):
        mesh = shapes.box((1.0, 0.1, 0.1), (10, 1, 1), kind)
        bodies[kind] = pp.build_body(
            mesh.nodes, mesh.elements, STEEL, node_sets=mesh.node_sets, **options
        )
    # Area weights from the faces of the elements: those of the same cells.
    weights = [body.reference.interface_weights for body in bodies.values()]
    assert len(weights[0]) == 2
    for a, b in zip(*weights, strict=True):
        assert_close(b, a, rel=1e-14, what="interface weights")
    system = fm.System()
    system.add_flexible_body(bodies["hex8i"], name="bar")
    result = fm.simulate(system, 0.002, 1e-3)
    write_vtu_series(result, tmp_path / "frames")
    frame = meshio.read(tmp_path / "frames" / "result_00000.vtu")
    assert [len(c.data) for c in frame.cells if c.type == "hexahedron"] == [10]
    assert frame.point_data["von_mises"].shape == (44,)


def write_vtu_box(path):
    """A 20 x 1 x 1 hexahedral bar as a VTK file (which knows no element formulations)."""
    import meshio

    mesh = shapes.box((1.0, 0.1, 0.1), (20, 1, 1), "hex8")
    meshio.write_points_cells(path, mesh.nodes, [("hexahedron", mesh.elements["hex8"])])


def test_a_mesh_with_incompatible_modes(tmp_path):
    write_vtu_box(tmp_path / "bar.vtu")
    mesh = read_mesh(tmp_path / "bar.vtu")
    enriched = mesh.with_incompatible_modes()
    assert list(enriched.elements) == ["hex8i"] and list(mesh.elements) == ["hex8"]
    assert (enriched.elements["hex8i"] == mesh.elements["hex8"]).all()
    assert (enriched.element_ids["hex8i"] == mesh.element_ids["hex8"]).all()
    # A mesh already of hex8i (Abaqus C3D8I; `preprocess --incompatible-modes` on it) stays.
    again = enriched.with_incompatible_modes()
    assert list(again.elements) == ["hex8i"] and again is not enriched
    tets = shapes.box((1.0, 0.1, 0.1), (2, 1, 1), "tet4")
    with pytest.raises(fm.InvalidModelError, match="no hexahedra \\(hex8\\); its elements: tet4"):
        tets.with_incompatible_modes()


def test_model_files_and_the_command_line_take_incompatible_modes(tmp_path, assert_close):
    from flexmbd.cli import main
    from flexmbd.fe.body_file import load_body
    from flexmbd.model_file import ModelFileError

    write_vtu_box(tmp_path / "bar.vtu")
    expected = clamped_bar("hex8i", 1)[1].frequencies
    text = (
        "bodies:\n  - name: bar\n    type: flexible\n    {source}\n"
        "    material: {{young_modulus: 2.1e+11, poisson_ratio: 0.3, density: 7800.0}}\n"
        "    reference: clamped\n    reference_nodes: {nodes}\n"
        "    modes: fixed-interface\n    mode_count: 2\n"
        "simulation: {{end_time: 0.01, step_size: 0.001}}\n"
    )
    clamp = shapes.box((1.0, 0.1, 0.1), (20, 1, 1), "hex8").node_sets["x0"].tolist()
    path = tmp_path / "bar.yaml"
    path.write_text(text.format(source="mesh: bar.vtu\n    incompatible_modes: true", nodes=clamp))
    body = load_model(path).body_data["bar"]
    assert list(body.elements) == ["hex8i"]
    assert_close(body.frequencies, expected, rel=1e-12, what="model file")
    box = "box: {lengths: [1.0, 0.1, 0.1], divisions: [20, 1, 1]}\n    incompatible_modes: true"
    path.write_text(text.format(source=box, nodes="x0"))
    with pytest.raises(ModelFileError, match="line 5: .*incompatible_modes goes with a mesh file"):
        load_model(path)
    # The command line.
    out = tmp_path / "bar.h5"
    material = ["-E", "2.1e11", "--poisson-ratio", "0.3", "--density", "7800"]
    clamped = ["--reference", "clamped", "--reference-nodes", *map(str, clamp)]
    modal = ["--modes", "fixed-interface", "-n", "2", "--incompatible-modes"]
    command = ["preprocess", str(tmp_path / "bar.vtu"), "-o", str(out), *material, *clamped]
    assert main([*command, *modal]) == 0
    body = load_body(out)
    assert list(body.elements) == ["hex8i"] and body.metadata["source"].endswith("bar.vtu")
    assert_close(body.frequencies, expected, rel=1e-12, what="flexmbd preprocess")
