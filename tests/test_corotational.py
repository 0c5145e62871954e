"""Co-rotational beam forces inside a nodal deformable body (`geometric_stiffness=
"corotational"`, `body/corotational.rs`; issue 30, item c): the element's energy measured in
the frame of its chord, exact for a turn of the element inside the body, so that one body
converges to the geometrically exact beam: a large-deflection cantilever against the elastica,
the spin-up against R3, energy of a free large vibration."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_bvp

import flexmbd as fm
from flexmbd import _core
from flexmbd.fe import Material, Section, build_body, straight_beam

LENGTH, EI, EA = 1.0, 2.0, 2.0e5


def cantilever_data(elements: int, **options):
    nodes, conn = straight_beam(LENGTH, elements)
    # E = 2e9, A = 1e-4, I = 1e-9: EI = 2, EA = 2e5 (a slender steel-like strip).
    return build_body(
        nodes,
        conn,
        Material(2.0e9, 0.3, 7800.0),
        section=Section(1e-4, 1e-9, 1e-9, 2e-9),
        reference="clamped",
        reference_nodes=[0],
        **options,
    )


def cantilever(elements: int, kind, load: float = 0.0, **state):
    system = fm.System()
    beam = system.add_flexible_body(
        cantilever_data(elements), geometric_stiffness=kind, name="strip", **state
    )
    system.add_fixed_joint(system.add_marker(system.ground), system.add_node_marker(beam, 1))
    if load:
        system.add_point_force(system.add_node_marker(beam, elements + 1), (0.0, -load, 0.0))
    return system, beam


def elastica_tip(load: float) -> tuple[float, float]:
    """Tip (x, y) of the extensible elastica under a dead tip load -load e_y (solve_bvp)."""

    def rhs(s, y):
        x, yy, th, fx, fy, m = y
        stretch = 1 + (fx * np.cos(th) + fy * np.sin(th)) / EA
        zero = np.zeros_like(s)
        return np.vstack(
            [
                stretch * np.cos(th),
                stretch * np.sin(th),
                m / EI,
                zero,
                zero,
                stretch * (np.sin(th) * fx - np.cos(th) * fy),
            ]
        )

    def bc(a, b):
        return np.array([a[0], a[1], a[2], b[3], b[4] + load, b[5]])

    s = np.linspace(0, LENGTH, 100)
    guess = np.zeros((6, s.size))
    guess[0] = s
    solution = solve_bvp(rhs, bc, s, guess, tol=1e-10, max_nodes=100000)
    assert solution.success
    return float(solution.y[0, -1]), float(solution.y[1, -1])


def static_tip(elements: int, kind, load: float) -> np.ndarray:
    system, beam = cantilever(elements, kind, load)
    state = fm.equilibrium(system.compile())
    return state.node_positions(beam)[-1]


def test_a_large_deflection_cantilever_converges_to_the_elastica(assert_close):
    # P L^2 / EI = 1.8: the tip drops by 0.46 L and moves in by 0.14 L.
    load = 3.6
    x, y = elastica_tip(load)
    assert -0.5 < y < -0.4 and x < 0.9
    errors = []
    for elements in (8, 16):
        tip = static_tip(elements, "corotational", load)
        errors.append(abs(tip[1] - y) / abs(y))
        assert_close(tip[0], x, rel=5e-3, what=f"tip x, {elements} elements")
    # Measured 8.7e-4 and 2.2e-4: second order in the element length.
    assert errors[0] < 1.5e-3 and errors[1] < 4e-4, errors
    assert 3.0 < errors[0] / errors[1] < 5.0, errors
    # The von Karman strain stays at the linear answer P L^3 / 3 EI = 0.6 (30 % off).
    von_karman = static_tip(16, True, load)
    assert abs(von_karman[1] - y) / abs(y) > 0.1


@pytest.mark.parametrize("angle", [np.pi / 8, np.pi / 4])
def test_bending_in_an_oblique_plane_is_the_planar_elastica(angle):
    # A round section loaded at its tip in a plane at `angle` to the section axes bends as in
    # the x-y plane: the chord's swing is the exact rotation for any plane through the axis.
    load = 3.6
    planar = static_tip(8, "corotational", load)
    system = fm.System()
    beam = system.add_flexible_body(cantilever_data(8), geometric_stiffness="corotational")
    system.add_fixed_joint(system.add_marker(system.ground), system.add_node_marker(beam, 1))
    direction = np.array([0.0, -np.cos(angle), -np.sin(angle)])
    system.add_point_force(system.add_node_marker(beam, 9), tuple(load * direction))
    tip = fm.equilibrium(system.compile()).node_positions(beam)[-1]
    expected = np.array([planar[0], *(-planar[1] * direction[1:])])
    np.testing.assert_allclose(tip, expected, rtol=0, atol=1e-10)


def test_the_local_stiffness_is_the_preprocessors(assert_close):
    # The co-rotational elements subtract their linear part e^T K e / 2, which must be the
    # body's K_ff exactly: a tilted 3D Timoshenko beam with its own section orientation.
    nodes = np.array([[0.0, 0.0, 0.0], [0.3, 0.2, 0.1], [0.6, 0.5, 0.1], [0.8, 0.5, 0.4]])
    conn = np.array([[0, 1], [1, 2], [2, 3]])
    data = build_body(
        nodes,
        {"beam2": conn},
        Material(7e10, 0.3, 2700.0),
        section=Section(3e-4, 2e-8, 5e-8, 3e-8),
        orientation=(0.2, 0.3, 1.0),
        beam_theory="timoshenko",
        reference="none",
    )
    material = _core.Material(7e10, 0.3, 2700.0)
    section = Section(3e-4, 2e-8, 5e-8, 3e-8)
    total = np.zeros((24, 24))
    for a, b in conn:
        axes, length, k = _core.beam_corotational_terms(
            nodes[[a, b]], section, material, [0.2, 0.3, 1.0], True
        )
        assert_close(length, np.linalg.norm(nodes[b] - nodes[a]), rel=1e-14, what="length")
        t = np.kron(np.eye(4), axes)
        rows = np.r_[6 * a : 6 * a + 6, 6 * b : 6 * b + 6]
        total[np.ix_(rows, rows)] += t.T @ k @ t
    k_ff = data.invariants.k_ff
    k_ff = k_ff.toarray() if hasattr(k_ff, "toarray") else np.asarray(k_ff)
    assert np.max(np.abs(total - k_ff)) < 1e-9 * np.max(np.abs(k_ff))


def rigid_turn(elements: int, angle: float, axis: int) -> np.ndarray:
    """Elastic coordinates of the whole beam turned rigidly about its first node's z (axis 2)
    or y (axis 1) axis inside its body frame."""
    c, s = np.cos(angle), np.sin(angle)
    x = np.linspace(0, LENGTH, elements + 1)
    q = np.zeros((elements + 1, 6))
    q[:, 0] = x * c - x
    q[:, 1 if axis == 2 else 2] = x * s if axis == 2 else -x * s
    q[:, 3 + axis] = angle
    return q.ravel()


@pytest.mark.parametrize("angle", [0.5, 1.5])
@pytest.mark.parametrize("axis", [1, 2])
def test_a_rigid_turn_inside_the_body_stores_no_energy(angle, axis, assert_close):
    # A body without reference conditions, its frame held by a fixed joint: its elastic
    # coordinates turn the whole beam rigidly within the frame.
    nodes, conn = straight_beam(LENGTH, 6)
    data = build_body(
        nodes,
        conn,
        Material(2.0e9, 0.3, 7800.0),
        section=Section(1e-4, 1e-9, 1e-9, 2e-9),
        reference="none",
    )
    energies = {}
    for kind in ("corotational", True):
        system = fm.System()
        beam = system.add_flexible_body(
            data, geometric_stiffness=kind, elastic_coordinates=rigid_turn(6, angle, axis)
        )
        system.add_fixed_joint(system.add_marker(system.ground), system.add_marker(beam))
        result = fm.simulate(system, 1e-4, 1e-4)
        energies[kind] = result.strain_energy[0]
    # The linear part alone stores EA-sized energy (the chord shortens by 1 - cos); the
    # chord frame removes all of it.
    assert energies[True] > 1.0
    assert_close(energies["corotational"], 0.0, abs=1e-9 * energies[True], what="energy")


def test_a_free_large_vibration_conserves_energy(assert_close):
    # Released from the static shape under P L^2 / EI = 1.8 (tip at -0.46 L), no load, no
    # damping, spectral radius 1: the energy stays (the elastic forces derive from the
    # energy, with their exact tangent), while the tip swings through +-0.45 L.
    system, beam = cantilever(8, "corotational", 3.6)
    shape = fm.equilibrium(system.compile()).elastic_coordinates(beam)
    system, beam = cantilever(8, "corotational", elastic_coordinates=shape)
    result = fm.simulate(system, 1.0, 2e-4, solver=fm.GeneralizedAlpha(1.0))
    assert result.success
    tip = result.node_displacements(beam, [9])[:, 0, 1]
    assert tip.max() > 0.3 and tip.min() < -0.4
    energy = result.kinetic_energy + result.potential_energy
    assert np.max(np.abs(energy - energy[0])) < 1e-5 * energy[0]  # measured 4e-7


def test_modal_bodies_and_shells_refuse_it():
    nodes, conn = straight_beam(LENGTH, 6)
    modal = build_body(
        nodes,
        conn,
        Material(2.0e9, 0.3, 7800.0),
        section=Section(1e-4, 1e-9, 1e-9, 2e-9),
        reference="mean-axis",
        modes="free-free",
        mode_count=4,
    )
    system = fm.System()
    with pytest.raises(fm.errors.InvalidModelError, match="'blade'.*nodal body"):
        system.add_flexible_body(modal, geometric_stiffness="corotational", name="blade")
    with pytest.raises(fm.errors.InvalidParameterError, match="geometric_stiffness"):
        system.add_flexible_body(cantilever_data(2), geometric_stiffness="exact", name="b")
    with pytest.raises(fm.errors.ArgumentTypeError, match="geometric_stiffness"):
        system.add_flexible_body(cantilever_data(2), geometric_stiffness=1, name="b")


def min_lag(elements: int, kind) -> float:
    example = fm.examples.spin_up(geometric_stiffness=kind, elements=elements)
    result = fm.simulate(
        example.system, 8.0, 5e-3, solver=fm.GeneralizedAlpha(0.9), output_interval=0.01
    )
    return float(result.node_displacements(example.items["beam"], [elements + 1])[:, 0, 1].min())


def test_the_spin_up_converges_to_r3():
    # One body: 10 elements -0.57424 m (+0.094 % of R3's -0.5737), 20 elements -0.57393
    # (+0.040 %; the 0.1 % gate held with margin against changes of the solver's steps),
    # converging; von Karman's strain stays 0.3 % too flexible at 10 elements (-0.57530).
    coarse, finer = min_lag(10, "corotational"), min_lag(20, "corotational")
    assert abs(coarse / -0.5737 - 1) < 1.5e-3
    assert abs(finer / -0.5737 - 1) < 0.7e-3
    assert abs(finer / -0.5737 - 1) < abs(coarse / -0.5737 - 1)
    assert min_lag(10, "von-karman") / -0.5737 - 1 > 2.5e-3


def test_model_files_take_the_corotational_kind(tmp_path, assert_close):
    from pathlib import Path

    from flexmbd.errors import ModelFileError
    from flexmbd.model_file import load_model, simulate_model

    text = (Path(__file__).parents[1] / "examples/models/flexible_slider_crank.yaml").read_text()
    assert "geometric_stiffness: true" in text
    runs = {}
    for kind in ("true", "corotational"):
        path = tmp_path / f"{kind}.yaml"
        path.write_text(text.replace("geometric_stiffness: true", f"geometric_stiffness: {kind}"))
        runs[kind] = simulate_model(load_model(path), end_time=0.02).deflection("rod", 5)
    # The rod bends by v/L = 0.01: both kinds agree to a fraction of a percent of the largest
    # deflection, and differ.
    scale = np.max(np.abs(runs["true"]))
    assert scale > 1e-4
    assert np.max(np.abs(runs["corotational"] - runs["true"])) < 1e-2 * scale
    assert np.max(np.abs(runs["corotational"] - runs["true"])) > 0
    path = tmp_path / "exact.yaml"
    path.write_text(text.replace("geometric_stiffness: true", "geometric_stiffness: exact"))
    with pytest.raises(ModelFileError, match="geometric_stiffness"):
        load_model(path)


def bend_system(elements: int, kind, **state):
    """The 45-degree bend (Bathe and Bolourchi 1979): an arc of radius 100 in the x-y plane,
    square section 1 x 1, E = 1e7, nu = 0, clamped at the origin; a load 600 t along +z at its
    tip (t: the load factor; `benchmarks/corotational_3d.py`)."""
    phi = np.linspace(0, np.pi / 4, elements + 1)
    nodes = np.c_[100 * np.sin(phi), 100 * (1 - np.cos(phi)), np.zeros(elements + 1)]
    data = build_body(
        nodes,
        {"beam2": np.c_[np.arange(elements), np.arange(1, elements + 1)]},
        Material(1e7, 0.0, 1.0),
        section=Section(1.0, 1 / 12, 1 / 12, 0.1406),
        orientation=(0, 0, 1),
        reference="clamped",
        reference_nodes=[0],
    )
    system = fm.System()
    beam = system.add_flexible_body(data, geometric_stiffness=kind, **state)
    system.add_fixed_joint(system.add_marker(system.ground), system.add_node_marker(beam, 1))
    return system, beam


def loaded_bend(elements: int, kind):
    system, beam = bend_system(elements, kind)
    load = fm.UserFunction(lambda t: 600.0 * t)
    system.add_point_force(system.add_node_marker(beam, elements + 1), (0.0, 0.0, load))
    model, coordinates = system.compile(), None
    for k in range(1, 13):
        state = fm.equilibrium(model, k / 12, coordinates=coordinates)
        coordinates = state.coordinates
    return state, beam


def test_the_45_degree_bend_meets_the_published_tip_displacements():
    # Bending and torsion with rotations up to about 1 rad, all inside one body's frame.
    # Published (these axes): Simo and Vu-Quoc (-23.48, -13.50, 53.37), Cardona and Geradin
    # (-23.67, -13.73, 53.50); measured at 16 elements (-23.711, -13.657, 53.518).
    state, beam = loaded_bend(16, "corotational")
    tip = state.node_displacements(beam)[-1]
    low, high = np.array([-23.8, -13.8, 53.3]), np.array([-23.4, -13.4, 53.6])
    assert np.all((low <= tip) & (tip <= high)), tip
    # The von Karman strain is far off at these rotations (about -85, -51, 114).
    state, beam = loaded_bend(16, True)
    assert state.node_displacements(beam)[-1][2] > 100


def test_a_free_3d_vibration_conserves_energy():
    # Released from the loaded 45-degree bend (tip 53.6 above the plane), no load: the tip
    # swings to -53 and back; generalized-alpha at spectral radius 1, h = 0.02 (measured
    # drift 3.8e-5 of the energy, 1.1e-5 at h = 0.01).
    state, beam = loaded_bend(8, "corotational")
    system, beam = bend_system(
        8, "corotational", elastic_coordinates=state.elastic_coordinates(beam)
    )
    result = fm.simulate(system, 12.0, 0.02, solver=fm.GeneralizedAlpha(1.0))
    assert result.success
    assert result.node_displacements(beam, [9])[:, 0, 2].min() < -50
    energy = result.kinetic_energy + result.potential_energy
    assert np.max(np.abs(energy - energy[0])) < 1e-4 * energy[0]
