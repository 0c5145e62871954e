"""Body variants: FlexibleBodyData is immutable, and with_stiffness_scale, with_material,
with_damping and with_modes make new bodies with everything that depends on the change
recomputed, checked against static solves and against building the variant from scratch."""

from __future__ import annotations

import dataclasses
import pickle

import h5py
import numpy as np
import pytest
import scipy.sparse as sp
from conftest import check_close

import flexmbd as fm
from flexmbd.fe import (
    Material,
    Section,
    body_from_matrices,
    build_body,
    load_body,
    save_body,
    shapes,
    straight_beam,
)
from flexmbd.fe.preprocess import assemble, static_displacements
from flexmbd.system import elastic_basis

STEEL = Material(2.1e11, 0.3, 7800.0)
SECTION = Section.rectangle(0.02, 0.01)
TIP = 6 * 6 + 1  # the y displacement of the tip node (index 6) of a 6-element beam


def check_relative(actual, expected, tolerance: float, what: str) -> None:
    """|actual - expected| <= tolerance * max |expected| entry by entry (check_close), for
    arrays, sparse matrices, numbers and nested lists of them (each array against its own
    largest entry)."""
    if isinstance(expected, list | tuple):
        for k, (a, e) in enumerate(zip(actual, expected, strict=True)):
            check_relative(a, e, tolerance, f"{what}[{k}]")
        return
    a = actual.toarray() if sp.issparse(actual) else np.asarray(actual, dtype=float)
    e = expected.toarray() if sp.issparse(expected) else np.asarray(expected, dtype=float)
    assert a.shape == e.shape, what
    scale = max(np.max(np.abs(e), initial=0.0), 1e-300)
    check_close(a, e, abs=tolerance * scale, what=what)


def assert_same_body(actual, expected, tolerance: float) -> None:
    """Nodal matrices, invariants, modes (up to sign) and frequencies to `tolerance`."""
    check_relative(actual.stiffness, expected.stiffness, tolerance, "stiffness")
    check_relative(actual.mass, expected.mass, tolerance, "mass matrix")
    assert sorted(actual.invariants) == sorted(expected.invariants)
    for key, value in expected.invariants.items():
        check_relative(actual.invariants[key], value, tolerance, key)
    assert actual.mode_kind == expected.mode_kind
    if expected.modes is None:
        assert actual.modes is None and actual.frequencies is None
    else:
        check_relative(actual.frequencies, expected.frequencies, tolerance, "frequencies")
        signs = np.sign(np.sum(actual.modes * expected.modes, axis=0))
        check_relative(actual.modes * signs, expected.modes, tolerance, "modes")
    np.testing.assert_array_equal(actual.reference["free_dofs"], expected.reference["free_dofs"])


def cantilever(material=STEEL, section=SECTION, **options):
    """A 1 m steel beam of 6 elements clamped at node index 0 (id 1)."""
    nodes, elements = straight_beam(1.0, 6)
    options.setdefault("reference", "clamped")
    options.setdefault("reference_nodes", [0])
    return build_body(nodes, elements, material, section=section, **options)


@pytest.fixture(scope="module")
def nodal_beam():
    return cantilever()


@pytest.fixture(scope="module")
def modal_beam():
    return cantilever(modes="fixed-interface", mode_count=4)


def hinged_bar(**options):
    """A 0.4 m hex8 bar with Craig-Bampton interfaces on its end faces, the frame on x0."""
    mesh = shapes.box((0.4, 0.05, 0.05), (6, 1, 1), "hex8")
    options.setdefault("reference", "interface")
    options.setdefault("modes", "craig-bampton")
    options.setdefault("mode_count", 3)
    options.setdefault("interfaces", ["x0", "x1"])
    return build_body(mesh.nodes, mesh.elements, STEEL, node_sets=mesh.node_sets, **options)


def matrix_body(**options):
    """The bar of `hinged_bar` from its nodal K and M (no mesh, no material)."""
    mesh = shapes.box((0.4, 0.05, 0.05), (6, 1, 1), "hex8")
    nodal = assemble(mesh.nodes, mesh.elements, STEEL)
    return body_from_matrices(
        mesh.nodes, nodal.stiffness, nodal.mass, node_sets=mesh.node_sets, **options
    )


def equilibrium_tip_deflection(body) -> float:
    """Tip deflection (m, y) of the beam held by a fixed joint at its clamped node, in static
    equilibrium under gravity (flexmbd.equilibrium on the whole system)."""
    system = fm.System(gravity=(0.0, -9.81, 0.0))
    beam = system.add_flexible_body(body)
    system.add_fixed_joint(system.add_marker(system.ground), system.add_node_marker(beam, 1))
    state = fm.equilibrium(system)
    layout = system.compile().describe()
    (entry,) = [b for b in layout["bodies"] if b["kind"] == "flexible"]
    elastic = state.coordinates[entry["offset"] + 7 : entry["offset"] + entry["count"]]
    return float((elastic_basis(body) @ elastic)[TIP])


# Immutability ----------------------------------------------------------------------------


def test_assigning_to_a_field_raises(nodal_beam):
    with pytest.raises(fm.FrozenBodyError, match="with_stiffness_scale") as info:
        nodal_beam.stiffness = 0.1 * nodal_beam.stiffness
    assert info.value.item == "field 'stiffness'"
    # Also the standard exception of frozen dataclasses.
    with pytest.raises(dataclasses.FrozenInstanceError):
        nodal_beam.modes = None
    with pytest.raises(fm.FrozenBodyError):
        del nodal_beam.metadata


def test_changing_arrays_dicts_and_lists_of_a_body_raises(nodal_beam, modal_beam):
    with pytest.raises(ValueError, match="read-only"):
        nodal_beam.nodes[0, 0] = 1.0
    with pytest.raises(ValueError, match="read-only"):
        modal_beam.modes[0, 0] = 1.0
    with pytest.raises(ValueError, match="read-only"):
        modal_beam.invariants["i1"][0, 0] = 1.0
    with pytest.raises(ValueError, match="read-only"):
        nodal_beam.reference["free_dofs"][0] = 0
    with pytest.raises(ValueError, match="read-only"):
        nodal_beam.elements["beam2"][0, 0] = 3
    with pytest.raises(ValueError, match="read-only"):
        nodal_beam.stiffness.data[0] = 0.0
    with pytest.raises(fm.FrozenBodyError, match="invariants"):
        nodal_beam.invariants["k_ff"] = 0.1 * nodal_beam.invariants["k_ff"]
    with pytest.raises(fm.FrozenBodyError):
        nodal_beam.metadata["source"] = "elsewhere"
    with pytest.raises(fm.FrozenBodyError):
        nodal_beam.material.update(young_modulus=1.0)
    with pytest.raises(fm.FrozenBodyError):
        nodal_beam.invariants["i_kl"][0][0] = None
    # Mutable copies stay possible.
    metadata = dict(nodal_beam.metadata)
    metadata["note"] = "x"
    assert "note" not in nodal_beam.metadata


def test_the_callers_arrays_are_not_frozen_and_not_shared():
    nodes, elements = straight_beam(1.0, 2)
    body = build_body(
        nodes, elements, STEEL, section=SECTION, reference="clamped", reference_nodes=[0]
    )
    nodes[2, 0] = 5.0  # the caller's array stays writable ...
    assert body.nodes[2, 0] == 1.0  # ... and is not the body's


def test_copies_and_pickles_stay_frozen(modal_beam):
    for copy in (pickle.loads(pickle.dumps(modal_beam)), dataclasses.replace(modal_beam)):
        assert not copy.modes.flags.writeable
        with pytest.raises(fm.FrozenBodyError):
            copy.invariants["mass"] = 1.0
        np.testing.assert_array_equal(copy.modes, modal_beam.modes)


def test_replace_with_a_new_stiffness_is_refused(nodal_beam, modal_beam):
    # Issue 27: dataclasses.replace(body, stiffness=0.1 * K) kept invariants["k_ff"], which
    # the simulation reads, so an 8-value stiffness sweep gave 8 identical answers.
    for body in (nodal_beam, modal_beam):
        with pytest.raises(fm.InvalidModelError, match="k_ff") as info:
            dataclasses.replace(body, stiffness=0.1 * body.stiffness)
        assert "with_stiffness_scale" in str(info.value)
        assert info.value.item == "invariants['k_ff']"
        with pytest.raises(fm.InvalidModelError, match="m_ff"):
            dataclasses.replace(body, mass=2.0 * body.mass)


# Stiffness scale -------------------------------------------------------------------------


@pytest.mark.parametrize("kind", ["nodal", "modal"])
def test_a_tenth_of_the_stiffness_gives_ten_times_the_deflection(
    kind, nodal_beam, modal_beam, assert_close
):
    body = nodal_beam if kind == "nodal" else modal_beam
    soft = body.with_stiffness_scale(0.1)
    # Preprocessor static solve under a tip load.
    force = np.zeros(body.dof_count)
    force[TIP] = -100.0
    ratio = static_displacements(soft, force)[TIP] / static_displacements(body, force)[TIP]
    assert_close(ratio, 10.0, rel=1e-9, what="deflection ratio, static solve")
    # Static equilibrium of the whole system under gravity.
    ratio = equilibrium_tip_deflection(soft) / equilibrium_tip_deflection(body)
    assert_close(ratio, 10.0, rel=1e-9, what="deflection ratio, equilibrium")
    # What depends on the stiffness changed with it; nothing else did.
    check_relative(soft.invariants["k_ff"], 0.1 * body.invariants["k_ff"], 1e-15, "k_ff")
    young = soft.material["young_modulus"]
    assert_close(young, 0.1 * 2.1e11, rel=1e-15, what="Young's modulus")
    assert soft.invariants["m_ff"] is body.invariants["m_ff"]
    assert soft.metadata["variants"] == "stiffness_scale=0.1"
    if kind == "modal":
        np.testing.assert_array_equal(soft.modes, body.modes)
        expected = np.sqrt(0.1) * body.frequencies
        assert_close(soft.frequencies, expected, rel=1e-15, what="frequencies")


def test_stiffness_sweep_gives_distinct_answers(nodal_beam, assert_close):
    scales = (0.5, 1.0, 2.0)
    tips = np.array(
        [equilibrium_tip_deflection(nodal_beam.with_stiffness_scale(s)) for s in scales]
    )
    assert len(set(tips)) == len(scales)
    assert_close(tips * np.array(scales), tips[1], rel=1e-9, what="scaled tip deflection")


def test_stiffness_scale_of_a_body_from_matrices_equals_scaled_matrices():
    body = matrix_body(reference="clamped", reference_nodes="x0")
    soft = body.with_stiffness_scale(0.25)
    mesh = shapes.box((0.4, 0.05, 0.05), (6, 1, 1), "hex8")
    nodal = assemble(mesh.nodes, mesh.elements, STEEL)
    expected = body_from_matrices(
        mesh.nodes,
        0.25 * nodal.stiffness,
        nodal.mass,
        node_sets=mesh.node_sets,
        reference="clamped",
        reference_nodes="x0",
    )
    assert_same_body(soft, expected, 1e-14)


@pytest.mark.parametrize("scale", [0.0, -1.0, np.nan, np.inf, "soft", "2", True])
def test_bad_stiffness_scale_names_the_parameter(nodal_beam, scale):
    with pytest.raises(fm.InvalidParameterError, match="scale") as info:
        nodal_beam.with_stiffness_scale(scale)
    assert info.value.item == "scale"


# Material --------------------------------------------------------------------------------


@pytest.mark.parametrize("kind", ["nodal", "modal"])
def test_with_material_equals_a_build_from_scratch(kind, assert_close):
    options = {} if kind == "nodal" else {"modes": "fixed-interface", "mode_count": 4}
    body = cantilever(**options)
    stiffer = body.with_material(young_modulus=4.2e11)
    assert_same_body(stiffer, cantilever(Material(4.2e11, 0.3, 7800.0), **options), 1e-12)
    heavier = body.with_material(density=2.5 * 7800.0)
    assert_same_body(heavier, cantilever(Material(2.1e11, 0.3, 2.5 * 7800.0), **options), 1e-12)
    mass = heavier.invariants["mass"]
    assert_close(mass, 2.5 * body.invariants["mass"], rel=1e-14, what="mass")
    assert "material(" in heavier.metadata["variants"]
    aluminium = body.with_material(Material(7.0e10, 0.33, 2700.0))
    assert_same_body(aluminium, cantilever(Material(7.0e10, 0.33, 2700.0), **options), 1e-12)


def test_with_material_keeps_a_section_without_rotary_inertia():
    plain = SECTION.without_rotary_inertia()
    body = cantilever(section=plain)
    assert body.section["rotary_inertia"] is False
    assert "rotary_inertia" not in cantilever().section  # the default layout as it was
    lighter = body.with_material(density=2700.0)
    assert_same_body(lighter, cantilever(Material(2.1e11, 0.3, 2700.0), section=plain), 1e-12)
    # The rotary inertia is in the mass: the two bodies differ there.
    difference = (cantilever().mass - body.mass).toarray()
    assert np.abs(difference).max() > 1e-6 * np.abs(body.mass.toarray()).max()


def test_with_material_keeps_the_craig_bampton_reduction():
    body = hinged_bar()
    variant = body.with_material(young_modulus=7.0e10, density=2700.0)
    assert_same_body(variant, hinged_bar().with_material(Material(7.0e10, 0.3, 2700.0)), 0.0)
    mesh = shapes.box((0.4, 0.05, 0.05), (6, 1, 1), "hex8")
    scratch = build_body(
        mesh.nodes,
        mesh.elements,
        Material(7.0e10, 0.3, 2700.0),
        node_sets=mesh.node_sets,
        reference="interface",
        modes="craig-bampton",
        mode_count=3,
        interfaces=["x0", "x1"],
    )
    assert_same_body(variant, scratch, 1e-9)
    assert variant.reference["mode_count"] == 3


@pytest.mark.parametrize("interface_kind", ["rbe2", "rbe3", "nodal"])
@pytest.mark.parametrize("reference", ["interface", "mean-axis"])
def test_craig_bampton_bodies_saved_without_their_mode_count(interface_kind, reference):
    # Body files written before the count was recorded: it is recovered from the modes.
    body = hinged_bar(reference=reference, interface_kind=interface_kind)
    older = dataclasses.replace(
        body, reference={k: v for k, v in body.reference.items() if k != "mode_count"}
    )
    assert_same_body(older.with_material(density=2700.0), body.with_material(density=2700.0), 0.0)


def test_with_material_of_a_body_without_mesh_says_why():
    body = matrix_body(reference="clamped", reference_nodes="x0")
    with pytest.raises(fm.InvalidModelError, match="no mesh") as info:
        body.with_material(young_modulus=1e11)
    assert "with_stiffness_scale" in str(info.value)
    assert info.value.item == "material"


def test_bad_material_values_are_typed_errors(nodal_beam):
    with pytest.raises(fm.InvalidParameterError, match="Young's modulus"):
        nodal_beam.with_material(young_modulus=-1.0)
    with pytest.raises(fm.InvalidParameterError, match="material"):
        nodal_beam.with_material("steel")
    # Text and lists were raw ValueErrors and TypeErrors of float().
    for values, match in (
        ({"density": "a"}, "density must be a number"),
        ({"young_modulus": "7e10 Pa"}, "young_modulus must be a number"),
        ({"density": [1, 2]}, "density must be a number"),
    ):
        with pytest.raises(fm.InvalidParameterError, match=match):
            nodal_beam.with_material(**values)


def test_with_modes_refuses_interfaces_it_would_drop():
    # Interfaces given with fixed-interface, free-free or no modes were dropped silently
    # (build_body refuses them).
    body = hinged_bar()
    for kind in ("fixed-interface", "free-free", None):
        with pytest.raises(fm.InvalidParameterError, match="interfaces are for Craig-Bampton"):
            body.with_modes(kind, 2, reference="clamped", reference_nodes="x0", interfaces=["x0"])


def test_with_modes_drops_what_it_carries_and_refuses_what_it_would_ignore():
    # The interface kind and weights a body carries go with its interfaces; given for modes
    # or a frame that do not use them they are refused, as by build_body.
    body = hinged_bar(interface_kind="rbe3", interface_weights="uniform")
    clamped = dict(reference="clamped", reference_nodes="x0")
    assert_same_body(
        body.with_modes("fixed-interface", 3, **clamped),
        hinged_bar(modes="fixed-interface", interfaces=(), **clamped),
        1e-9,
    )
    for options, match in (
        ({"reference_nodes": [0]}, "reference_nodes with reference='interface'"),
        ({"interface_kind": "rbe3", **clamped}, "interface_kind='rbe3' is for Craig-Bampton"),
        ({"interface_weights": "area", **clamped}, "interface_weights are for the RBE2 and RBE3"),
    ):
        kind = "craig-bampton" if "reference" not in options else "fixed-interface"
        with pytest.raises(fm.InvalidParameterError, match=match):
            body.with_modes(kind, 2, **options)
    # To nodal interfaces: the carried weights are dropped.
    nodal_interfaces = body.with_modes("craig-bampton", 3, interface_kind="nodal")
    assert nodal_interfaces.reference.interface_weights is None


# Modes -----------------------------------------------------------------------------------


def test_with_modes_equals_a_build_from_scratch(nodal_beam, modal_beam):
    assert_same_body(
        nodal_beam.with_modes("fixed-interface", 4),
        cantilever(modes="fixed-interface", mode_count=4),
        1e-9,
    )
    # Back to nodal coordinates.
    assert_same_body(modal_beam.with_modes(None), nodal_beam, 1e-12)
    # Another modal reduction of a stiffer body: from its own (scaled) nodal matrices.
    stiffer = modal_beam.with_stiffness_scale(4.0).with_modes("fixed-interface", 3)
    expected = cantilever(Material(8.4e11, 0.3, 7800.0), modes="fixed-interface", mode_count=3)
    assert_same_body(stiffer, expected, 1e-9)
    assert stiffer.metadata["variants"] == "stiffness_scale=4.0; modes(fixed-interface, count=3)"


def test_with_modes_of_a_solid_and_of_a_body_from_matrices():
    nodal = hinged_bar(
        reference="clamped", reference_nodes="x0", modes=None, mode_count=0, interfaces=()
    )
    assert_same_body(
        nodal.with_modes("craig-bampton", 3, reference="interface", interfaces=["x0", "x1"]),
        hinged_bar(),
        1e-9,
    )
    # A body from matrices: nodal invariants from M = M_s (x) I_3.
    from_matrices = matrix_body(reference="clamped", reference_nodes="x0")
    free_free = from_matrices.with_modes("free-free", 4, reference="mean-axis")
    assert_same_body(
        free_free, matrix_body(reference="mean-axis", modes="free-free", mode_count=4), 1e-9
    )
    assert_same_body(
        free_free.with_modes(None, reference="clamped", reference_nodes="x0"), from_matrices, 1e-12
    )


def test_with_modes_needs_the_nodal_matrices(modal_beam):
    # A body with only its reduced matrices (as some imported bodies are).
    reduced_only = dataclasses.replace(modal_beam, stiffness=None, mass=None)
    with pytest.raises(fm.InvalidModelError, match="no nodal stiffness matrix"):
        reduced_only.with_modes("fixed-interface", 2)
    with pytest.raises(fm.InvalidParameterError, match="count"):
        modal_beam.with_modes("fixed-interface", -1)


# Damping ---------------------------------------------------------------------------------


def swinging_tip(body, **damping):
    """Tip displacement history of the clamped beam released from a deflected shape."""
    system = fm.System()
    data = body
    elastic = np.zeros(data.elastic_coordinate_count)
    elastic[: min(2, len(elastic))] = 1e-3
    beam = system.add_flexible_body(data, elastic_coordinates=elastic, **damping)
    system.add_fixed_joint(system.add_marker(system.ground), system.add_node_marker(beam, 1))
    result = fm.simulate(system, 0.3, 1e-3, output_interval=1e-3)
    return result.node_displacements(beam, [7])[:, 0, 1]


@pytest.mark.parametrize("kind", ["rayleigh", "modal"])
def test_the_bodys_damping_reaches_the_simulation(kind, modal_beam):
    value = (20.0, 1e-4) if kind == "rayleigh" else 0.05
    damped = modal_beam.with_damping(**{kind: value})
    undamped = swinging_tip(modal_beam)
    from_body = swinging_tip(damped)
    explicit = swinging_tip(modal_beam, **{f"{kind}_damping": value})
    np.testing.assert_array_equal(from_body, explicit)
    # The free vibration decays (damping ratio about 0.05 to 0.1 in the first mode, of about
    # 17 Hz): less than half the motion of the undamped beam in the last fifth of 0.3 s.
    last = slice(4 * len(undamped) // 5, None)
    assert np.ptp(from_body[last]) < 0.5 * np.ptp(undamped[last])
    # An explicit argument wins over the body's damping.
    np.testing.assert_array_equal(swinging_tip(damped, rayleigh_damping=(0.0, 0.0)), undamped)


def test_damping_survives_a_body_file(tmp_path, modal_beam):
    damped = modal_beam.with_damping(rayleigh=(1.5, 2e-5), modal=0.02)
    path = tmp_path / "beam.h5"
    save_body(damped, path)
    loaded = load_body(path)
    assert loaded.damping == {"rayleigh": (1.5, 2e-5), "modal": 0.02}
    assert loaded.metadata["variants"] == damped.metadata["variants"]
    # Files without the field (written before it existed) read as undamped.
    with h5py.File(path, "r+") as file:
        del file["damping"]
    assert load_body(path).damping is None


def test_variants_keep_the_damping(modal_beam):
    damped = modal_beam.with_damping(modal=0.02)
    assert damped.with_stiffness_scale(2.0).damping == damped.damping
    assert damped.with_material(density=1000.0).damping == damped.damping
    assert damped.with_damping().damping is None
    with pytest.raises(fm.InvalidModelError, match="modal damping needs a modal body"):
        damped.with_modes(None)


def test_bad_damping_names_the_parameter(nodal_beam, modal_beam):
    with pytest.raises(fm.InvalidParameterError, match="Rayleigh") as info:
        modal_beam.with_damping(rayleigh=(-1.0, 0.0))
    assert info.value.item == "rayleigh"
    with pytest.raises(fm.InvalidParameterError, match="pair"):
        modal_beam.with_damping(rayleigh=1.0)
    with pytest.raises(fm.InvalidParameterError, match="ratio") as info:
        modal_beam.with_damping(modal=np.nan)
    assert info.value.item == "modal"
    with pytest.raises(fm.InvalidModelError, match="modal body") as info:
        nodal_beam.with_damping(modal=0.02)
    assert info.value.item == "modal"
