"""Modal reduction (seed section 3, eq. 18): Craig-Bampton bases with nodal, rigid (RBE2) and
averaged (RBE3) interfaces, their frames of reference, free-free and fixed-interface modes,
external modes, bodies from mesh files, and body files of real bodies."""

import meshio
import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse.linalg as spla
from scipy.sparse import diags as sp_diags

import flexmbd.fe.modal as md
import flexmbd.fe.preprocess as pp
from flexmbd._core import Material
from flexmbd.errors import ArgumentTypeError, InvalidModelError, InvalidParameterError
from flexmbd.fe import shapes
from flexmbd.fe.body_file import load_body, save_body
from flexmbd.fe.interface import body_interface, make_interface

STEEL = Material(2.1e11, 0.3, 7800.0)


@pytest.fixture(scope="module")
def bar():
    """A 1 x 0.1 x 0.1 m steel bar of tet4 (208 nodes, 624 coordinates: the sparse
    eigensolver path)."""
    return shapes.box((1.0, 0.1, 0.1), (12, 3, 3), "tet4")


@pytest.fixture(scope="module")
def exact_free_free(bar):
    nodal = pp.assemble(bar.nodes, bar.elements, STEEL)
    values = sla.eigh(nodal.stiffness.toarray(), nodal.mass.toarray(), eigvals_only=True)
    return md.frequencies(values[6:30])


@pytest.fixture(scope="module")
def exact_clamped(bar):
    nodal = pp.assemble(bar.nodes, bar.elements, STEEL)
    free = pp.reference_dofs("clamped", len(bar.nodes), 3, bar.node_sets["x0"])
    k = nodal.stiffness[free][:, free].toarray()
    m = nodal.mass[free][:, free].toarray()
    return md.frequencies(sla.eigh(k, m, eigvals_only=True)[:24])


def cb_body(bar, kind, reference, count=12, interfaces=("x0", "x1")):
    return pp.build_body(
        bar.nodes,
        bar.elements,
        STEEL,
        node_sets=bar.node_sets,
        reference=reference,
        modes="craig-bampton",
        mode_count=count,
        interfaces=list(interfaces),
        interface_kind=kind,
    )


def full_modes(body):
    full = np.zeros((body.dof_count, body.modes.shape[1]))
    full[body.reference.free_dofs] = body.modes
    return full


@pytest.mark.parametrize("modes", ["free-free", "fixed-interface", "craig-bampton"])
def test_modal_matrices_are_orthonormal_and_diagonal(bar, modes):
    options = {
        "free-free": dict(reference="mean-axis"),
        "fixed-interface": dict(reference="clamped", reference_nodes="x0"),
        "craig-bampton": dict(reference="mean-axis", interfaces=["x0", "x1"]),
    }[modes]
    body = pp.build_body(
        bar.nodes,
        bar.elements,
        STEEL,
        node_sets=bar.node_sets,
        modes=modes,
        mode_count=8,
        **options,
    )
    m_ff, k_ff = body.invariants.m_ff, body.invariants.k_ff
    count = body.modes.shape[1]
    np.testing.assert_allclose(m_ff, np.eye(count), atol=1e-10)
    omega2 = (2 * np.pi * body.frequencies) ** 2
    np.testing.assert_allclose(k_ff, np.diag(omega2), atol=1e-9 * omega2.max())


def test_free_free_modes_are_the_exact_elastic_modes(bar, exact_free_free):
    body = pp.build_body(
        bar.nodes, bar.elements, STEEL, reference="mean-axis", modes="free-free", mode_count=10
    )
    np.testing.assert_allclose(body.frequencies, exact_free_free[:10], rtol=1e-9)
    # Tisserand (mean-axis) conditions: mass-orthogonal to the rigid motions.
    r = md.rigid_modes(bar.nodes, 3)
    assert np.abs(r.T @ (body.mass @ full_modes(body))).max() < 1e-9


def test_fixed_interface_modes_are_the_exact_clamped_modes(bar, exact_clamped):
    body = pp.build_body(
        bar.nodes,
        bar.elements,
        STEEL,
        node_sets=bar.node_sets,
        reference="clamped",
        reference_nodes="x0",
        modes="fixed-interface",
        mode_count=10,
    )
    np.testing.assert_allclose(body.frequencies, exact_clamped[:10], rtol=1e-9)
    assert np.all(full_modes(body)[3 * bar.node_sets["x0"]] == 0.0)


def test_craig_bampton_with_one_rigid_interface_as_reference_is_the_clamped_body(
    bar, exact_clamped
):
    body = cb_body(bar, "rbe2", "interface", count=10, interfaces=["x0"])
    np.testing.assert_allclose(body.frequencies, exact_clamped[:10], rtol=1e-9)


@pytest.mark.parametrize("kind", ["rbe2", "nodal"])
def test_rigid_interfaces_move_rigidly_and_the_first_one_carries_the_frame(bar, kind):
    body = cb_body(bar, kind, "interface", count=6)
    full = full_modes(body)
    x0, x1 = bar.node_sets["x0"], bar.node_sets["x1"]
    dofs = (x1[:, None] * 3 + np.arange(3)).ravel()
    # The body frame is attached to interface 0: every mode vanishes there.
    assert np.all(full[(x0[:, None] * 3 + np.arange(3)).ravel()] == 0.0)
    t = make_interface(bar.nodes, {}, x1, "uniform").rigid_map(3)
    fit, *_ = np.linalg.lstsq(t, full[dofs], rcond=None)
    misfit = np.abs(t @ fit - full[dofs]).max() / np.abs(full[dofs]).max()
    if kind == "rbe2":
        # 6 static modes of interface 1 + 6 normal modes.
        assert body.modes.shape[1] == 12
        assert misfit < 1e-10
    else:
        assert body.modes.shape[1] == 6 + 3 * len(x1)
        assert misfit > 1e-3


def test_averaged_interfaces_keep_their_mean_motion_and_deform(bar):
    body = cb_body(bar, "rbe3", "interface", count=6)
    assert body.modes.shape[1] == 12
    full = full_modes(body)
    n = body.dof_count
    # The rows of the weights the modes were built with (area weights of the end faces).
    g0 = body_interface(body, bar.node_sets["x0"], ids=False).average_rows(3, n)
    g1 = body_interface(body, bar.node_sets["x1"], ids=False).average_rows(3, n)
    scale = np.abs(full).max()
    # The frame follows the averaged motion of interface 0.
    assert np.abs(g0 @ full).max() < 1e-10 * scale
    # The six averaged motions of interface 1 are spanned.
    assert np.linalg.matrix_rank(g1 @ full, tol=1e-8 * scale) == 6
    # The interface nodes are not rigidly tied: the modes deform the end face.
    x0 = bar.node_sets["x0"]
    dofs = (x0[:, None] * 3 + np.arange(3)).ravel()
    t = make_interface(bar.nodes, {}, x0, "uniform").rigid_map(3)
    fit, *_ = np.linalg.lstsq(t, full[dofs], rcond=None)
    assert np.abs(t @ fit - full[dofs]).max() > 1e-3 * np.abs(full[dofs]).max()


def test_averaged_interface_rows_recover_a_rigid_motion(bar):
    members = bar.node_sets["x1"]
    n = 3 * len(bar.nodes)
    g = make_interface(bar.nodes, {}, members, "uniform").average_rows(3, n)
    r = md.rigid_modes(bar.nodes, 3)
    center = bar.nodes[members].mean(axis=0)
    # Rigid motion (translation v, rotation w about the origin): mean translation at the
    # interface centre is v + w x c, rotation w.
    motion = np.array([0.1, -0.2, 0.3, 0.01, -0.02, 0.015])
    expected = np.concatenate([motion[:3] + np.cross(motion[3:], center), motion[3:]])
    np.testing.assert_allclose(g @ (r @ motion), expected, rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("kind", ["rbe2", "rbe3", "nodal"])
def test_mean_axis_craig_bampton_bounds_and_approaches_the_free_free_frequencies(
    bar, kind, exact_free_free
):
    errors = []
    for count in (4, 40):
        body = cb_body(bar, kind, "mean-axis", count=count)
        full = full_modes(body)
        r = md.rigid_modes(bar.nodes, 3)
        assert np.abs(r.T @ (body.mass @ full)).max() < 1e-9
        f = body.frequencies[:6]
        # Rayleigh-Ritz: upper bounds.
        assert np.all(f >= exact_free_free[:6] * (1 - 1e-10))
        errors.append(np.abs(f / exact_free_free[:6] - 1).max())
    assert errors[1] < 0.1 * errors[0]
    # Rigid (RBE2) end faces stiffen the bar: those bases converge to a stiffer body.
    assert errors[1] < {"nodal": 3e-4, "rbe3": 3e-4, "rbe2": 1e-3}[kind]


def test_interface_craig_bampton_approaches_the_clamped_frequencies(bar, exact_clamped):
    # Interface 1 free to move (its static modes), interface 0 carrying the frame: the CB
    # body is the cantilever, whose frequencies the basis bounds from above.
    for kind in ("rbe2", "nodal"):
        body = cb_body(bar, kind, "interface", count=40)
        f = body.frequencies[:5]
        assert np.all(f >= exact_clamped[:5] * (1 - 1e-10))
        limit = 1e-4 if kind == "nodal" else 1e-3
        assert np.abs(f / exact_clamped[:5] - 1).max() < limit


def test_external_modes_give_the_same_body_as_computed_modes(bar):
    computed = pp.build_body(
        bar.nodes,
        bar.elements,
        STEEL,
        node_sets=bar.node_sets,
        reference="clamped",
        reference_nodes="x0",
        modes="fixed-interface",
        mode_count=5,
    )
    external = pp.build_body(
        bar.nodes,
        bar.elements,
        STEEL,
        node_sets=bar.node_sets,
        reference="clamped",
        reference_nodes="x0",
        modes="external",
        external_modes=computed.modes,
    )
    for key in ("i1", "ibar", "k_ff", "m_ff"):
        np.testing.assert_allclose(
            getattr(external.invariants, key), getattr(computed.invariants, key), atol=1e-12
        )
    with pytest.raises(InvalidParameterError, match="over the kept coordinates"):
        pp.build_body(
            bar.nodes,
            bar.elements,
            STEEL,
            modes="external",
            external_modes=computed.modes,
        )

    # External modes are used as given (not normalized): five times the modes, 25 times m_ff.
    def external_body(modes):
        return pp.build_body(
            bar.nodes, bar.elements, STEEL, node_sets=bar.node_sets, reference="clamped",
            reference_nodes="x0", modes="external", external_modes=modes,
        )  # fmt: skip

    scaled = external_body(5.0 * computed.modes)
    np.testing.assert_allclose(
        scaled.invariants.m_ff, 25.0 * np.asarray(computed.invariants.m_ff), rtol=0, atol=1e-11
    )
    # A zero column, a repeated (scaled) column and a combination were accepted; the run then
    # failed with a singular matrix blamed on the constraints.
    phi = computed.modes
    for columns, match in (
        (np.column_stack([phi[:, :2], 0.0 * phi[:, 0]]), "column 2 moves no mass"),
        (np.column_stack([phi[:, :3], -2.0 * phi[:, 1]]), "column 3 is a multiple of column 1"),
        (np.column_stack([phi[:, :3], phi[:, 0] + phi[:, 2]]), "column 3 is .* combination of"),
    ):
        with pytest.raises(InvalidParameterError, match=match):
            external_body(columns)
    # With a free frame (reference "none"), a rigid motion among the columns duplicates the frame's
    # own: accepted, the run failed at t = 0 with a singular matrix. And mode_count was
    # ignored with external modes.
    free_free = pp.build_body(bar.nodes, bar.elements, STEEL, reference="mean-axis",
                              modes="free-free", mode_count=3)  # fmt: skip
    lift = np.zeros(free_free.modes.shape[0])
    lift[2::3] = 0.1
    for columns, column in ((lift[:, None], 0), (np.column_stack([free_free.modes, lift]), 3)):
        with pytest.raises(InvalidParameterError, match=f"column {column} is .*rigid motion"):
            pp.build_body(bar.nodes, bar.elements, STEEL, reference="none",
                          modes="external", external_modes=columns)  # fmt: skip
    with pytest.raises(InvalidParameterError, match="mode_count=2 with 3 external modes"):
        pp.build_body(bar.nodes, bar.elements, STEEL, reference="none", modes="external",
                      external_modes=free_free.modes, mode_count=2)  # fmt: skip
    kept = pp.build_body(bar.nodes, bar.elements, STEEL, reference="none",
                         modes="external", external_modes=free_free.modes)  # fmt: skip
    import scipy.linalg as sla

    k_ff, m_ff = (np.asarray(a) for a in (kept.invariants.k_ff, kept.invariants.m_ff))
    hz = np.sqrt(sla.eigh(k_ff, m_ff, eigvals_only=True)) / (2 * np.pi)
    np.testing.assert_allclose(hz, free_free.frequencies, rtol=1e-9)


def test_bodies_from_mesh_files_and_body_files_round_trip(tmp_path, bar):
    path = tmp_path / "bar.vtu"
    meshio.write(path, meshio.Mesh(bar.nodes, [("tetra", bar.elements["tet4"])]))
    x1 = bar.node_sets["x1"]
    body = pp.body_from_mesh(
        path,
        STEEL,
        reference="interface",
        modes="craig-bampton",
        mode_count=4,
        interfaces=[bar.node_sets["x0"], x1],
    )
    assert body.metadata["source"] == str(path)
    same = cb_body(bar, "rbe2", "interface", count=4)
    np.testing.assert_allclose(body.frequencies, same.frequencies, rtol=1e-10)
    save_body(body, tmp_path / "bar.h5")
    loaded = load_body(tmp_path / "bar.h5")
    np.testing.assert_array_equal(loaded.modes, body.modes)
    np.testing.assert_array_equal(loaded.frequencies, body.frequencies)
    assert (loaded.stiffness != body.stiffness).nnz == 0
    for k in range(3):
        for j in range(3):
            np.testing.assert_array_equal(loaded.invariants.i_kl[k][j], body.invariants.i_kl[k][j])
    np.testing.assert_array_equal(loaded.reference.interfaces[1], x1)
    assert loaded.reference.interface_kind == "rbe2"


def test_bad_modal_requests_are_explained(bar):
    build = dict(node_sets=bar.node_sets)
    # Three nodes on one line (the corners of one end face's edge) leave a rotation free.
    with pytest.raises(InvalidModelError, match=r"at nodes .* leaves a rotation about the axis"):
        pp.build_body(
            bar.nodes,
            bar.elements,
            STEEL,
            reference="3-2-1",
            reference_nodes=[0, 1, 2],
            modes="fixed-interface",
            mode_count=3,
            **build,
        )
    with pytest.raises(InvalidModelError, match="not free"):
        md.free_free_modes(
            *(lambda b: (b.stiffness + 1e3 * b.mass, b.mass))(
                pp.assemble(bar.nodes, bar.elements, STEEL)
            ),
            3,
            nodes=bar.nodes,
        )
    with pytest.raises(InvalidModelError, match="share node index"):
        pp.build_body(
            bar.nodes,
            bar.elements,
            STEEL,
            reference="mean-axis",
            modes="craig-bampton",
            mode_count=2,
            interfaces=["x0", "y0"],
            **build,
        )
    line = np.flatnonzero((np.abs(bar.nodes[:, 1]) < 1e-12) & (np.abs(bar.nodes[:, 2]) < 1e-12))[:5]
    with pytest.raises(InvalidModelError, match="non-collinear") as info:
        pp.build_body(
            bar.nodes,
            bar.elements,
            STEEL,
            reference="mean-axis",
            modes="craig-bampton",
            mode_count=2,
            interfaces=["x1", line],
            interface_kind="rbe3",
            **build,
        )
    assert info.value.item == "interface 1"
    with pytest.raises(InvalidModelError, match="reference='mean-axis' or reference='interface'"):
        cb_body(bar, "rbe2", "clamped")
    # A beam along y held simply supported: its twist is held about x, not its axis; the
    # advice was about nodes on one line.
    along_y = np.array([[0.0, 0.1 * k, 0.0] for k in range(5)])
    beams = {"beam2": np.array([[k, k + 1] for k in range(4)])}
    with pytest.raises(InvalidModelError, match="node b must lie on the x axis of node a"):
        pp.build_body(
            along_y, beams, STEEL, section=pp.Section.circle(0.01), reference="simply-supported",
            reference_nodes=[0, 4],
        )  # fmt: skip
    for reference in ("interface", "mean-axis"):  # (it blamed reference_nodes)
        with pytest.raises(InvalidModelError, match="Craig-Bampton modes need interfaces"):
            pp.build_body(
                bar.nodes, bar.elements, STEEL, reference=reference, modes="craig-bampton",
                mode_count=4, **build,
            )  # fmt: skip
    with pytest.raises(InvalidModelError, match="need free-free or Craig-Bampton"):
        pp.build_body(bar.nodes, bar.elements, STEEL, reference="mean-axis")
    with pytest.raises(InvalidParameterError, match="interface kind"):
        cb_body(bar, "rbe4", "mean-axis")
    with pytest.raises(InvalidParameterError, match="mode_count") as info:
        pp.build_body(bar.nodes, bar.elements, STEEL, reference="mean-axis", modes="free-free")
    assert info.value.item == "mode_count"
    with pytest.raises(InvalidParameterError, match="modes requested") as info:  # (no item)
        pp.build_body(
            bar.nodes, bar.elements, STEEL, reference="clamped", reference_nodes="x0",
            modes="fixed-interface", mode_count=10**6, **build,
        )  # fmt: skip
    assert info.value.item == "mode_count"


@pytest.mark.parametrize("mode_count", [[], [1.0, 2.0], "3", 3.0, None, -1])
def test_a_mode_count_that_is_not_an_integer_names_it(bar, mode_count):
    # Issue 28 (fuzz): build_body(mode_count=[...]) raised a bare TypeError ('<' not
    # supported between instances of 'list' and 'int').
    with pytest.raises(InvalidParameterError, match="mode_count must be") as info:
        pp.build_body(
            bar.nodes,
            bar.elements,
            STEEL,
            reference="mean-axis",
            modes="free-free",
            mode_count=mode_count,
        )
    assert info.value.item == "mode_count"


SMALL_BAR = shapes.box((1.0, 0.1, 0.1), (2, 1, 1), "hex8")

#: Node index lists that are not integer node indices, and the error each must be.
BAD_NODE_LISTS = [
    (None, ArgumentTypeError),
    ([float("nan")], ArgumentTypeError),
    ([2**70], InvalidParameterError),
    (["a"], ArgumentTypeError),
    (["0"], ArgumentTypeError),
    ([0.5], ArgumentTypeError),
    ([1.0], ArgumentTypeError),
    ([True], ArgumentTypeError),
    (b"ab", ArgumentTypeError),
    ([[0, 1], [2]], ArgumentTypeError),
    (object(), ArgumentTypeError),
    (np.array([2**64 - 1], dtype=np.uint64), InvalidParameterError),
]
BAD_NODE_LIST_IDS = [
    "none", "nan", "2**70", "str", "digit", "fraction", "float", "bool", "bytes", "ragged",
    "object", "uint64-max",
]  # fmt: skip


def small_body(**options):
    return pp.build_body(
        SMALL_BAR.nodes,
        SMALL_BAR.elements,
        STEEL,
        node_sets=SMALL_BAR.node_sets,
        **options,
    )


@pytest.mark.parametrize("nodes, error", BAD_NODE_LISTS, ids=BAD_NODE_LIST_IDS)
def test_reference_nodes_that_are_not_node_indices_name_the_parameter(nodes, error):
    # Issue 28 (fuzz): reference_nodes=None, [nan], [2**70], ["a"] raised a bare TypeError,
    # ValueError or OverflowError from NumPy; floats and bools were taken as indices.
    with pytest.raises(error, match="reference_nodes must be integers") as info:
        small_body(reference="clamped", reference_nodes=nodes)
    assert info.value.item == "reference_nodes"


@pytest.mark.parametrize("nodes, error", BAD_NODE_LISTS, ids=BAD_NODE_LIST_IDS)
def test_interfaces_that_are_not_node_indices_name_the_interface(nodes, error):
    with pytest.raises(error, match=r"interfaces\[1\] must be integers") as info:
        small_body(
            reference="mean-axis", modes="craig-bampton", mode_count=2, interfaces=["x0", nodes]
        )
    assert info.value.item == "interfaces[1]"


@pytest.mark.parametrize(
    "interfaces",
    [None, 3, 2.5, "x0", b"x0", {"x0": 1}],
    ids=["none", "int", "float", "str", "bytes", "dict"],
)
def test_interfaces_that_are_not_a_list_name_the_parameter(interfaces):
    # Issue 28 (fuzz): interfaces=None or 3 raised a bare TypeError (not iterable); a string
    # was read as one node set per character.
    with pytest.raises(ArgumentTypeError, match="interfaces must be a list") as info:
        small_body(
            reference="mean-axis", modes="craig-bampton", mode_count=2, interfaces=interfaces
        )
    assert info.value.item == "interfaces"


def test_out_of_range_and_named_node_selections_still_work():
    with pytest.raises(InvalidModelError, match="reference_nodes: node index 99") as info:
        small_body(reference="clamped", reference_nodes=[99])
    assert info.value.item == "reference_nodes"
    with pytest.raises(ArgumentTypeError, match=r"node_sets\['bad'\] must be integers"):
        pp.build_body(
            SMALL_BAR.nodes, SMALL_BAR.elements, STEEL, node_sets={"bad": [0.5, float("nan")]}
        )
    by_name = small_body(reference="clamped", reference_nodes="x0")
    by_index = small_body(reference="clamped", reference_nodes=SMALL_BAR.node_sets["x0"])
    by_numpy = small_body(
        reference="clamped", reference_nodes=[np.int32(i) for i in SMALL_BAR.node_sets["x0"]]
    )
    np.testing.assert_array_equal(by_name.reference.free_dofs, by_index.reference.free_dofs)
    np.testing.assert_array_equal(by_name.reference.free_dofs, by_numpy.reference.free_dofs)


@pytest.mark.parametrize(
    "parameter", ["mass", "beam_theory", "reference", "modes", "interface_kind", "precision"]
)
@pytest.mark.parametrize(
    "value",
    [np.array(["consistent", "lumped"]), np.array([1, 2]), 1, ["none"]],
    ids=["str-array", "int-array", "int", "list"],
)
def test_str_options_of_the_wrong_type_name_the_parameter(parameter, value):
    # Issue 28 (fuzz): build_body(mass=<an array>) raised a bare ValueError (the truth value
    # of an array is ambiguous).
    with pytest.raises(ArgumentTypeError, match=f"{parameter}.* must be ") as info:
        small_body(**{parameter: value})
    assert info.value.item == parameter


def test_str_options_of_unknown_values_name_the_parameter():
    for parameter in ("mass", "beam_theory", "reference", "modes", "interface_kind", "precision"):
        with pytest.raises(InvalidParameterError, match=f"{parameter}.* must be ") as info:
            small_body(**{parameter: "unknown"})
        assert info.value.item == parameter
    nodal = pp.assemble(SMALL_BAR.nodes, SMALL_BAR.elements, STEEL)
    with pytest.raises(ArgumentTypeError, match="mass_kind must be") as info:
        pp.body_from_matrices(
            SMALL_BAR.nodes, nodal.stiffness, nodal.mass, mass_kind=np.array(["lumped", "x"])
        )
    assert info.value.item == "mass_kind"


@pytest.mark.parametrize("kind", ["rbe2", "rbe3"])
def test_single_precision_factors_give_the_same_modes(bar, kind):
    double = cb_body(bar, kind, "interface", count=8)
    single = pp.build_body(
        bar.nodes,
        bar.elements,
        STEEL,
        node_sets=bar.node_sets,
        reference="interface",
        modes="craig-bampton",
        mode_count=8,
        interfaces=["x0", "x1"],
        interface_kind=kind,
        precision="single",
    )
    np.testing.assert_allclose(single.frequencies, double.frequencies, rtol=1e-9)
    # The same subspace: the single-precision modes are combinations of the double ones.
    m = single.invariants.m_ff
    overlap = single.modes.T @ (
        double.mass[single.reference.free_dofs][:, single.reference.free_dofs] @ double.modes
    )
    np.testing.assert_allclose(np.abs(np.linalg.det(overlap)), 1.0, rtol=1e-8)
    np.testing.assert_allclose(m, np.eye(len(m)), atol=1e-10)
    with pytest.raises(InvalidParameterError, match="precision"):
        pp.build_body(
            bar.nodes,
            bar.elements,
            STEEL,
            reference="mean-axis",
            modes="free-free",
            mode_count=2,
            precision="half",
        )


def test_single_precision_solves_reach_double_precision_residuals(bar):
    nodal = pp.assemble(bar.nodes, bar.elements, STEEL)
    free = pp.reference_dofs("clamped", len(bar.nodes), 3, bar.node_sets["x0"])
    k = nodal.stiffness[free][:, free]
    inverse = md.Inverse(k, single=True, dofs=free, nodes=bar.nodes)
    exact = md.Inverse(k, dofs=free, nodes=bar.nodes)
    # Four bytes per entry of the supernodal factor (the double-precision factor of this small
    # bar is the envelope form, smaller than a supernodal one, see `fem/envelope.rs`).
    assert inverse.factor_bytes == 4 * inverse.factor.factor_nnz
    assert exact.factor_bytes == 8 * exact.factor.factor_nnz
    b = np.random.default_rng(2).normal(size=(len(free), 3))
    x = inverse.solve(b)
    assert np.linalg.norm(k @ x - b, axis=0).max() < 1e-10 * np.linalg.norm(b, axis=0).min()
    assert inverse.iterations > 0


def test_factors_multiply_by_their_matrix_and_restricted_products_need_no_copy(bar):
    nodal = pp.assemble(bar.nodes, bar.elements, STEEL)
    free = pp.reference_dofs("clamped", len(bar.nodes), 3, bar.node_sets["x0"])
    k = nodal.stiffness[free][:, free]
    x = np.random.default_rng(3).normal(size=(len(free), 11))
    for single in (False, True):
        inverse = md.Inverse(k, single=single, dofs=free, nodes=bar.nodes)
        assert np.abs(inverse @ x - k @ x).max() < 1e-12 * np.abs(k @ x).max()
        assert np.abs(inverse @ x[:, 0] - k @ x[:, 0]).max() < 1e-12 * np.abs(k @ x).max()
    # The interior block of M, by products of the whole matrix (11 columns: two chunks).
    restricted = md._Restricted(nodal.mass, free)
    m = nodal.mass[free][:, free]
    assert np.abs(restricted @ x - m @ x).max() < 1e-14 * np.abs(m @ x).max()
    assert restricted.shape == m.shape


def test_block_davidson_with_an_approximate_inverse_finds_the_exact_eigenpairs(bar):
    nodal = pp.assemble(bar.nodes, bar.elements, STEEL)
    free = pp.reference_dofs("clamped", len(bar.nodes), 3, bar.node_sets["x0"])
    k = nodal.stiffness[free][:, free].tocsc()
    m = nodal.mass[free][:, free].tocsc()
    # The reference: ARPACK shift-invert with an exact LU factor (dense eigh of this K, whose
    # condition number is about 1e7, is itself only good to about 1e-10).
    exact = np.sort(spla.eigsh(k, 6, m, sigma=0.0, tol=1e-14, return_eigenvectors=False))
    # An approximate inverse T = (S K S)^-1 with S = diag(1 + 2 % noise): the residuals are
    # exact, so the pairs converge to the exact ones although every solve is off by percents.
    s = sp_diags(1.0 + 0.02 * np.random.default_rng(4).uniform(-1.0, 1.0, len(free)))
    approximate = md.Inverse((s @ k @ s).tocsc(), dofs=free, nodes=bar.nodes)
    values, vectors = md.block_davidson_eigenpairs(k, m, 6, approximate.precondition)
    assert np.allclose(values, exact, rtol=1e-10)
    # The shift-invert residual |K^-1 (K x - lambda M x)|_M of the M-normalized vectors: the
    # solver stops at 1e-8 measured with T (a few percent off K^-1 here, about 1e-7 with a
    # single-precision factor).
    z = sla.solve(k.toarray(), k @ vectors - (m @ vectors) * values)
    assert np.sqrt(np.einsum("ij,ij->j", z, m @ z)).max() < 3e-8
    assert np.allclose(vectors.T @ (m @ vectors), np.eye(6), atol=1e-12)


def two_blocks(shared_corner: bool = False):
    """Two tet4 blocks 1 x 0.2 x 0.2 m side by side along x: 0.5 m apart (disconnected), or
    (``shared_corner``) joined at a single node, the far corner of the first block, which is a
    hinge: three extra rigid motions (rotations of one block about that node)."""
    block = shapes.box((1.0, 0.2, 0.2), (3, 1, 1), "tet4")
    count = len(block.nodes)
    if not shared_corner:
        nodes = np.vstack([block.nodes, block.nodes + [1.5, 0.0, 0.0]])
        return nodes, np.vstack([block.elements["tet4"], block.elements["tet4"] + count])
    corner = int(np.argmax(block.nodes.sum(axis=1)))
    second = np.empty(count, dtype=np.int64)
    second[0], second[1:] = corner, count + np.arange(count - 1)
    nodes = np.vstack([block.nodes, (block.nodes + block.nodes[corner])[1:]])
    return nodes, np.vstack([block.elements["tet4"], second[block.elements["tet4"]]])


@pytest.mark.parametrize("count", [4, 8])
def test_disconnected_parts_are_refused_with_their_description(count):
    # Issue 28: two disconnected blocks gave free-free frequencies [0, 0, 0, 0] (the second
    # block's rigid motions taken as elastic modes) with 4 modes and "the body is not free"
    # with 8; the parts are now named before any eigenproblem.
    nodes, tets = two_blocks()
    half = len(nodes) // 2
    with pytest.raises(InvalidModelError, match="2 disconnected parts") as info:
        pp.build_body(
            nodes, {"tet4": tets}, STEEL, reference="mean-axis", modes="free-free", mode_count=count
        )
    message = str(info.value)
    assert f"part 1: {half} nodes, {len(tets) // 2} elements, node 1" in message
    assert f"part 2: {half} nodes, {len(tets) // 2} elements, node {half + 1}" in message
    assert "none of them is clamped" in message


def test_a_body_clamped_in_one_part_only_is_refused_and_clamped_in_each_is_accepted():
    nodes, tets = two_blocks()
    half = len(nodes) // 2
    first_face = np.flatnonzero(np.isclose(nodes[:, 0], 0.0))
    second_face = np.flatnonzero(np.isclose(nodes[:, 0], 1.5))
    for modes in (None, "fixed-interface"):
        with pytest.raises(InvalidModelError, match="part 2 is not clamped") as info:
            pp.build_body(
                nodes,
                {"tet4": tets},
                STEEL,
                reference="clamped",
                reference_nodes=first_face,
                modes=modes,
                mode_count=0 if modes is None else 4,
            )
        assert info.value.item == f"node {half + 1}"
    # Each block clamped at its x = 0 face: two cantilevers on one frame, the same modes.
    both = pp.build_body(
        nodes,
        {"tet4": tets},
        STEEL,
        reference="clamped",
        reference_nodes=np.concatenate([first_face, second_face]),
        modes="fixed-interface",
        mode_count=4,
    )
    assert np.allclose(both.frequencies[0::2], both.frequencies[1::2], rtol=1e-8)


def test_free_free_modes_of_a_mechanism_are_refused():
    # Two blocks joined at one node are connected, but can turn about that node: a seventh
    # zero eigenvalue, which free-free modes would take as an elastic mode.
    nodes, tets = two_blocks(shared_corner=True)
    with pytest.raises(InvalidModelError, match="more than 6 rigid-body motions"):
        pp.build_body(
            nodes, {"tet4": tets}, STEEL, reference="mean-axis", modes="free-free", mode_count=4
        )
    # One block of both lengths (connected along faces) has six.
    bar = shapes.box((2.0, 0.2, 0.2), (6, 1, 1), "tet4")
    body = pp.build_body(
        bar.nodes, bar.elements, STEEL, reference="mean-axis", modes="free-free", mode_count=4
    )
    assert body.frequencies[0] > 10.0


def test_a_slender_clamped_strip_is_not_taken_for_a_free_body(assert_close):
    # A 1 m x 10 mm x 2 mm aluminium strip of 125 x 5 x 1 hex8, clamped at x0, was refused
    # as "free to move rigidly": its first bending eigenvalue (781, 4.45 Hz) was under the
    # rigid threshold of 1e-10 max(diag K) / max(diag M).
    from flexmbd.fe import shapes

    mesh = shapes.box((1.0, 0.01, 0.002), (125, 5, 1), "hex8")
    options = dict(node_sets=mesh.node_sets, reference="clamped", reference_nodes="x0")
    aluminium = Material(7e10, 0.3, 2700.0)
    body = pp.build_body(
        mesh.nodes, mesh.elements, aluminium, modes="fixed-interface", mode_count=2, **options
    )
    nodal = pp.build_body(mesh.nodes, mesh.elements, aluminium, **options)
    lowest = spla.eigsh(nodal.invariants.k_ff, 2, nodal.invariants.m_ff, sigma=0.0)[0]
    assert_close(body.frequencies, np.sqrt(np.sort(lowest)) / (2 * np.pi), rel=1e-6)
    assert body.frequencies[0] == pytest.approx(4.448, rel=1e-3)


@pytest.mark.parametrize(
    ("modes", "count", "options"),
    [
        ("fixed-interface", 3, {"reference": "clamped", "reference_nodes": [0]}),
        ("free-free", 1, {"reference": "mean-axis"}),
        ("craig-bampton", 3, {"reference": "interface", "interfaces": [[0]],
                              "interface_kind": "nodal"}),
    ],
)  # fmt: skip
def test_a_mode_count_that_cuts_a_pair_of_equal_frequencies_is_warned(modes, count, options):
    # A round beam's bending modes come in pairs of equal frequency: a count that keeps one
    # of a pair keeps an arbitrary direction, and the body is stiffer in the other.
    import warnings

    from flexmbd import ModeCountWarning
    from flexmbd.fe import Section, build_body, straight_beam

    nodes, elements = straight_beam(1.0, 6)
    steel, round_bar = Material(7e10, 0.33, 2700.0), Section.circle(0.005)
    with pytest.warns(ModeCountWarning, match=rf"mode_count {count} keeps 1 of a group") as w:
        body = build_body(nodes, elements, steel, section=round_bar, modes=modes,
                          mode_count=count, **options)  # fmt: skip
    assert w[0].filename == __file__  # the user's call, not the preprocessor's
    assert f"take mode_count {count + 1}" in str(w[0].message)
    assert len(body.frequencies) >= count
    with warnings.catch_warnings():
        warnings.simplefilter("error", ModeCountWarning)
        build_body(nodes, elements, steel, section=round_bar, modes=modes,
                   mode_count=count + 1, **options)  # fmt: skip
