"""Free-free modes of free-flying structures: `fm.linearize_at_rest`, `System.without_loads`,
`FreeMotionError` from `fm.equilibrium`, and `flexmbd modes` of a model with no equilibrium."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import clamped_steel_beam

import flexmbd as fm

LENGTH, ELEMENTS = 2.0, 24
E, NU, RHO = 2.1e11, 0.3, 7850.0
#: Slender (L / r = 1000): the rotary inertia of the elements' sections, which the
#: Euler-Bernoulli values leave out, lowers the first two frequencies by 6e-6 and 1.4e-5
#: (by 6e-4 and 1.4e-3 at r = 0.02).
RADIUS = 0.002

#: beta_n L of the free-free Euler-Bernoulli beam (roots of cos x cosh x = 1).
FREE_FREE_ROOTS = (4.730040744862704, 7.853204624095838)


def free_beam(torque: bool = False, gravity=(0.0, 0.0, 0.0)) -> tuple[fm.System, fm.BodyId]:
    """A steel rod of round section (its frame at its first node), free in space; with
    `torque`, a torque about its axis fixed to its frame acts at that node."""
    system = fm.System(gravity=gravity)
    body = clamped_steel_beam(LENGTH, ELEMENTS, fm.fe.Section.circle(RADIUS))
    rod = system.add_flexible_body(body, name="rod")
    if torque:
        end = system.add_node_marker(rod, 1)
        system.add_torque(end, [5.0, 0.0, 0.0], frame="marker", name="spin")
    return system, rod


def bending(n: int) -> float:
    """Free-free bending frequency n (Hz) of the rod."""
    area, inertia = np.pi * RADIUS**2, np.pi * RADIUS**4 / 4.0
    root = FREE_FREE_ROOTS[n]
    return root**2 / (2.0 * np.pi * LENGTH**2) * np.sqrt(E * inertia / (RHO * area))


def test_free_free_rod_has_six_rigid_modes_and_the_analytic_bending_frequencies(assert_close):
    system, _ = free_beam()
    linear = fm.linearize_at_rest(system)
    assert linear.free_motions() == 6
    frequencies = linear.frequencies()
    # Round section: each bending frequency twice (two planes), the lowest modes of the rod.
    assert_close(frequencies[:4], np.repeat([bending(0), bending(1)], 2), rel=1e-4, what="f")
    # Axial: f = c / 2L with c = sqrt(E / rho), linear bars with consistent mass (h^2).
    axial = np.sqrt(E / RHO) / (2.0 * LENGTH)
    assert np.min(np.abs(frequencies - axial)) < 2e-3 * axial


def test_the_loads_stay_out_unless_asked(assert_close):
    # A torque fixed to the rod's frame turns with it: at rest its stiffness couples the
    # rigid rotations, a spurious pair of near-zero modes that the unloaded rod does not have.
    loaded, _ = free_beam(torque=True, gravity=(0.0, -9.81, 0.0))
    plain, _ = free_beam()
    free = fm.linearize_at_rest(loaded)
    assert_close(free.frequencies(), fm.linearize_at_rest(plain).frequencies(), rel=1e-12)
    assert free.free_motions() == 6
    with_loads = fm.linearize_at_rest(loaded, loads=True)
    assert with_loads.free_motions() < 6
    # The system itself keeps its loads and gravity.
    assert loaded.gravity == (0.0, -9.81, 0.0)
    assert len(loaded.compile().describe()["forces"]) == 1
    assert loaded.without_loads().gravity == (0.0, 0.0, 0.0)


def test_equilibrium_of_a_loaded_free_body_is_a_free_motion_error():
    system, _ = free_beam(torque=True)
    with pytest.raises(fm.FreeMotionError, match="linearize_at_rest") as caught:
        fm.equilibrium(system)
    assert caught.value.directions >= 3
    assert caught.value.item == "rod"
    assert isinstance(caught.value, fm.InvalidModelError)


def test_a_configuration_that_is_not_assembled_is_refused():
    system = fm.System()
    link = system.add_rigid_body(1.0, (0.1, 0.1, 0.1), position=(1.0, 0.0, 0.0), name="link")
    pivot = system.add_marker(system.ground, name="pivot")
    # The link's marker at its centre, 1 m from the pivot: the joint is violated by 1 m.
    system.add_spherical_joint(pivot, system.add_marker(link), name="ball")
    with pytest.raises(fm.InvalidModelError, match="joint 'ball'") as caught:
        fm.linearize_at_rest(system)
    assert caught.value.item == "ball"


def test_a_compiled_model_keeps_its_loads_or_is_refused():
    system, _ = free_beam(torque=True)
    model = system.compile()
    with pytest.raises(fm.InvalidParameterError, match="loads=True"):
        fm.linearize_at_rest(model)
    assert fm.linearize_at_rest(model, loads=True).free_motions() < 6


def test_modes_command_gives_the_free_free_modes_of_the_satellite(capsys, tmp_path):
    from flexmbd.cli import main

    example = fm.examples.satellite()
    expected = fm.linearize_at_rest(example.system).frequencies()
    assert main(["modes", "satellite", "--count", "3", "-o", str(tmp_path / "sat")]) == 0
    out = capsys.readouterr().out
    assert "free-free" in out and "6 rigid-body modes" in out
    rows = [line.split() for line in out.splitlines() if line.strip()[:1].isdigit()]
    assert [float(r[1]) for r in rows] == pytest.approx(expected[:3], rel=1e-5)
    # Undamped: the ratio's round-off reads 0.
    assert all(r[2] == "0" for r in rows)


def test_modes_command_numbers_the_modes_it_animates_from_one(capsys):
    # --animate 99 said "mode 98: the linearization has 12 oscillating modes".
    from flexmbd.cli import main

    assert main(["modes", "satellite", "--count", "1", "--animate", "99"]) == 2
    assert "--animate 99: the modes are numbered 1 to 12" in capsys.readouterr().err


def test_at_rest_with_loads_the_joints_carry_them(assert_close):
    # A pendulum hanging at rest: with zero multipliers its frequencies were missing (two
    # "free motions"); the joint's multiplier that balances gravity brings sqrt(g / l).
    g = 9.81
    system = fm.System(gravity=(0.0, -g, 0.0))
    bob = system.add_point_mass(1.0, position=(0.0, -1.0, 0.0), name="bob")
    system.add_distance_joint(system.add_marker(system.ground), system.add_marker(bob), 1.0)
    at_rest = fm.linearize_at_rest(system, loads=True)
    expected = np.sqrt(g) / (2 * np.pi)
    assert_close(at_rest.frequencies(), [expected, expected], rel=1e-12, what="frequencies")
    assert at_rest.free_motions() == 0
    about_equilibrium = fm.linearize(system, fm.equilibrium(system)).frequencies()
    assert_close(at_rest.frequencies(), about_equilibrium, rel=1e-12, what="against equilibrium")


def test_free_motions_are_counted_exactly_whatever_their_round_off(assert_close):
    # Two free bodies (J 0.2 and 0.5) on a hinge with a torsional spring of 30 N m/rad: six
    # free motions and one mode, sqrt(k (J1 + J2) / (J1 J2)). In the first-order matrix a
    # free motion is a defective double zero, which LAPACK returned as +-1e-7: 5 free motions
    # and a "mode" of 1.3e-8 Hz. Two bodies joined by a spring: 11 free motions.
    j1, j2, k = 0.2, 0.5, 30.0
    system = fm.System()
    a = system.add_rigid_body(1.0, (j1, j1, j1))
    b = system.add_rigid_body(1.0, (j2, j2, j2), position=(0, 0, 0.5))
    pair = system.add_marker(a, position=(0, 0, 0.25)), system.add_marker(b, position=(0, 0, -0.25))
    system.add_revolute_joint(*pair)
    system.add_rotational_spring_damper(*pair, stiffness=k)
    linear = fm.linearize_at_rest(system)
    assert linear.free_motions() == 6
    expected = np.sqrt(k * (j1 + j2) / (j1 * j2)) / (2 * np.pi)
    assert_close(linear.frequencies(), [expected], rel=1e-10, what="torsion")
    system = fm.System()
    a = system.add_rigid_body(2.0, (0.1, 0.1, 0.1))
    b = system.add_rigid_body(3.0, (0.1, 0.1, 0.1), position=(1, 0, 0))
    system.add_spring_damper(system.add_marker(a), system.add_marker(b), stiffness=500.0)
    linear = fm.linearize_at_rest(system)
    assert linear.free_motions() == 11
    assert_close(linear.frequencies(), [np.sqrt(500 * 5 / 6) / (2 * np.pi)], rel=1e-10)
