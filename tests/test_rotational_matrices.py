"""Bodies from matrices with 6 coordinates per node (issue 35: beams and shells from other FE
codes): the invariants of a lumped mass matrix exactly, the rigid-motion invariants of a
consistent one exactly, the elastic mass exactly, and a pendulum converging to the same
motion as the preprocessor's own beam; Abaqus .mtx files with rotational dofs."""

import numpy as np
import pytest
import scipy.sparse as sp

import flexmbd as fm
import flexmbd.fe.preprocess as pp
from flexmbd._core import Material, Section
from flexmbd.errors import InvalidModelError
from flexmbd.fe import read_abaqus_matrix

STEEL = Material(2.1e11, 0.3, 7800.0)
AL = Material(7e10, 0.33, 2700.0)


def curved_beam():
    angles = np.linspace(0.0, np.pi / 2, 7)
    nodes = np.column_stack([np.cos(angles), np.sin(angles), 0.1 * angles]) + [0.2, -0.1, 0.3]
    elements = {"beam2": np.column_stack([np.arange(6), np.arange(1, 7)])}
    return nodes, elements, dict(section=Section.rectangle(0.02, 0.04), orientation=(0, 0, 1.0))


def dense(m):
    return m.toarray() if sp.issparse(m) else np.asarray(m)


def test_a_lumped_mass_matrix_gives_the_exact_invariants(assert_close):
    nodes, elements, props = curved_beam()
    native = pp.build_body(nodes, elements, STEEL, mass="lumped", **props)
    body = pp.body_from_matrices(nodes, native.stiffness, native.mass, mass_kind="lumped")
    assert body.dofs_per_node == 6
    a, b = native.invariants, body.invariants
    for name in ("mass", "first_moment", "second_moment", "i1", "ibar"):
        want = np.asarray(getattr(a, name))
        assert_close(getattr(b, name), want, abs=1e-12 * np.abs(want).max(), what=name)
    for k in range(3):
        for j in range(3):
            want = dense(a.i_kl[k][j])
            assert_close(dense(b.i_kl[k][j]), want, abs=1e-12 * np.abs(want).max(), what="i_kl")


def test_a_consistent_mass_matrix_keeps_the_rigid_terms_and_the_elastic_mass(assert_close):
    nodes, elements, props = curved_beam()
    native = pp.build_body(nodes, elements, STEEL, mass="consistent", **props)
    body = pp.body_from_matrices(nodes, native.stiffness, native.mass)
    a, b = native.invariants, body.invariants
    for name in ("mass", "first_moment", "second_moment", "i1"):
        want = np.asarray(getattr(a, name))
        assert_close(getattr(b, name), want, abs=1e-12 * np.abs(want).max(), what=name)
    # Ibar: its antisymmetric part (the coupling of rotation and deformation) exactly.
    x, y = np.asarray(a.ibar), np.asarray(b.ibar)
    assert_close(
        y - y.transpose(1, 0, 2), x - x.transpose(1, 0, 2), abs=1e-12 * np.abs(x).max(),
        what="antisymmetric Ibar",
    )  # fmt: skip
    m = dense(native.mass)
    trace = sum(dense(b.i_kl[k][k]) for k in range(3))
    assert_close(trace, m, abs=1e-12 * np.abs(m).max(), what="sum of I_kk (elastic mass)")


@pytest.mark.parametrize(("elements", "bound"), [(4, 2e-3), (16, 1e-4)])
def test_a_pendulum_from_matrices_converges_to_the_beams_motion(elements, bound, assert_close):
    nodes, connectivity = pp.straight_beam(1.0, elements)
    props = dict(section=Section.rectangle(0.02, 0.01), orientation=(0.0, 1.0, 0.0))
    options = dict(reference="clamped", reference_nodes=[0], modes="fixed-interface", mode_count=4)
    native = pp.build_body(nodes, connectivity, AL, **props, **options)
    nodal = pp.build_body(nodes, connectivity, AL, **props)
    body = pp.body_from_matrices(nodes, nodal.stiffness, nodal.mass, **options)
    results = []
    for data in (native, body):
        system = fm.System(gravity=(0.0, -9.81, 0.0))
        arm = system.add_flexible_body(data, name="arm")
        system.add_revolute_joint(system.add_marker(system.ground), system.add_node_marker(arm, 1))
        result = fm.simulate(system, end_time=1.0, step_size=1e-3, output_interval=0.05)
        results.append(result.deflection("arm", elements // 2 + 1, chord=(1, elements + 1)))
    size = np.abs(results[0]).max()
    assert size > 5e-5  # it bends
    assert_close(results[1], results[0], abs=bound * size, what="mid-span deflection")


def write_mtx(path, matrix, dofs_per_node=6):
    coo = sp.coo_matrix(matrix)
    lines = ["** written by a test"]
    for i, j, v in zip(coo.row, coo.col, coo.data, strict=True):
        if i >= j and v != 0.0:
            fields = (i // dofs_per_node + 1, i % dofs_per_node + 1, j // dofs_per_node + 1)
            lines.append(
                f"{fields[0]}, {fields[1]}, {fields[2]}, {j % dofs_per_node + 1}, {v:.17e}"
            )
    path.write_text("\n".join(lines) + "\n")
    return path


def test_abaqus_matrices_with_rotations_make_a_body(tmp_path, assert_close):
    nodes, connectivity = pp.straight_beam(1.0, 4)
    props = dict(section=Section.rectangle(0.02, 0.01), orientation=(0.0, 1.0, 0.0))
    nodal = pp.build_body(nodes, connectivity, AL, **props)
    k, ids, dofs = read_abaqus_matrix(write_mtx(tmp_path / "K.mtx", nodal.stiffness))
    m, _, _ = read_abaqus_matrix(write_mtx(tmp_path / "M.mtx", nodal.mass))
    assert dofs == 6 and ids.tolist() == [1, 2, 3, 4, 5]
    body = pp.body_from_matrices(nodes, k, m, reference="clamped", reference_nodes=[0])
    direct = pp.body_from_matrices(
        nodes, nodal.stiffness, nodal.mass, reference="clamped", reference_nodes=[0]
    )
    for name in ("mass", "second_moment", "i1"):
        want = np.asarray(getattr(direct.invariants, name))
        assert_close(getattr(body.invariants, name), want, rel=1e-14, abs=1e-14, what=name)
    # The modes of a meshless 6-dof body, as a variant.
    modal = body.with_modes("fixed-interface", 3)
    assert modal.elastic_coordinate_count == 3 and modal.dofs_per_node == 6


def test_a_mass_matrix_that_does_not_move_rigidly_is_refused():
    nodes, connectivity = pp.straight_beam(1.0, 2)
    props = dict(section=Section.rectangle(0.02, 0.01), orientation=(0.0, 1.0, 0.0))
    nodal = pp.build_body(nodes, connectivity, AL, **props)
    m = nodal.mass.tolil()
    m[1, 1] *= 2.0  # more mass for y than for x and z at node 1
    with pytest.raises(InvalidModelError, match="rigid translations the masses"):
        pp.body_from_matrices(nodes, nodal.stiffness, m.tocsc())
