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


def test_the_spin_of_a_free_rotor_is_a_free_motion_not_a_slow_mode(assert_close):
    # A rigid rotor (10 kg, Ip 0.2, It 0.5 kg m^2) spinning freely at 300 rad/s about x on four
    # lateral springs (1e5 N/m at x = +-0.3 m) and an axial one (2e4 N/m). The central
    # differences of the moving basis leave its cyclic spin angle a stiffness of 4e-5 (2e-10
    # of the largest, above the 1e-11 of round-off at rest): a mode of 0.0149 rad/s and no
    # free motion. Reference (rad/s): axial sqrt(kx / m), lateral sqrt(2 k / m) twice,
    # conical It w^2 -+ Ip W w - 2 k a^2 = 0.
    mass, polar, transverse, k, kx, a, spin = 10.0, 0.2, 0.5, 1e5, 2e4, 0.3, 300.0
    system = fm.System()
    rotor = system.add_rigid_body(
        mass, (polar, transverse, transverse), angular_velocity=(spin, 0, 0), name="rotor"
    )
    for x in (-a, a):
        for d in ((0, 1, 0), (0, 0, 1)):
            ground = system.add_marker(system.ground, position=(x, -d[1], -d[2]))
            system.add_spring_damper(
                ground, system.add_marker(rotor, position=(x, 0, 0)), stiffness=k, rest_length=1
            )
    axial = system.add_marker(system.ground, position=(-1.0, 0, 0))
    system.add_spring_damper(axial, system.add_marker(rotor), stiffness=kx, rest_length=1.0)
    solver = fm.GeneralizedAlpha(newton_tolerance=1e-12)
    run = fm.simulate(system, 0.01, 1e-4, output_interval=0.005, solver=solver)
    linear = fm.linearize(system, run.state(-1))
    assert linear.free_motions() == 1
    conical = np.roots([transverse, -polar * spin, -2 * k * a * a])
    backward, forward = sorted(abs(conical))
    lateral = np.sqrt(2 * k / mass)
    expected = [np.sqrt(kx / mass), backward, lateral, lateral, forward]
    assert_close(2 * np.pi * linear.frequencies(), expected, rel=1e-7, what="rad/s")


def test_a_sleeping_top_has_a_free_spin_and_no_false_instability(assert_close):
    # A symmetric top (1 kg, centre 0.1 m above a spherical joint, I1c 1e-3, I3 2e-3 kg m^2)
    # asleep at 150 rad/s. Its spin angle came out as eigenvalues +-0.0035, real: an apparent
    # instability. Reference: precession and nutation I1 w^2 - I3 W w + m g l = 0 (I1 about
    # the tip), and one free motion.
    g, mass, arm, axial, lateral, spin = 9.81, 1.0, 0.1, 0.002, 0.001, 150.0
    up = np.array([[1, 0, 0], [0, 0, 1], [0, -1, 0]], float)  # body z along global y
    system = fm.System(gravity=(0, -g, 0))
    top = system.add_rigid_body(
        mass, (lateral, lateral, axial), position=(0, arm, 0), orientation=up,
        angular_velocity=(0, spin, 0), name="top",
    )  # fmt: skip
    tip = system.add_marker(top, position=(0, 0, -arm))
    system.add_spherical_joint(system.add_marker(system.ground), tip, name="tip")
    solver = fm.GeneralizedAlpha(newton_tolerance=1e-12)
    run = fm.simulate(system, 0.01, 1e-4, output_interval=0.005, solver=solver)
    linear = fm.linearize(system, run.state(-1))
    values = linear.eigenvalues()[0]
    assert linear.free_motions() == 1
    assert_close(values.real, 0.0, abs=1e-6, what="Re s")
    tipped = lateral + mass * arm * arm
    rates = np.sort(np.roots([tipped, -axial * spin, mass * g * arm]).real)
    # (the run's state, not exactly asleep: 4e-6 off the precession)
    assert_close(linear.frequencies() * 2 * np.pi, rates, rel=1e-5, what="rad/s")


def test_at_rest_with_loads_a_weld_on_an_elastic_node_carries_only_its_share(assert_close):
    # A steel rod hanging from a hinge with 2 kg at its lower end, as a rigid body welded to
    # the end node's marker: the least-squares balance of every row let the weld's
    # multipliers take the rod's elastic rows' gravity too (which the deflection carries),
    # and the pendulum swung at 2.745 rad/s instead of 3.351. Now as about the equilibrium
    # and as with the mass a point mass of the rod (within the equilibrium's deflection).
    g, mass = 9.81, 2.0
    section = fm.fe.Section.circle(0.01)
    nodes, elements = fm.fe.straight_beam(1.0, 10)
    down = fm.rotation("z", -np.pi / 2)

    def pendulum(welded):
        body = fm.fe.build_body(
            nodes, elements, fm.fe.Material(E, NU, RHO), section=section, reference="clamped",
            reference_nodes=[0], point_masses=None if welded else {10: mass},
        )  # fmt: skip
        system = fm.System(gravity=(0.0, -g, 0.0))
        arm = system.add_flexible_body(body, orientation=down, name="arm")
        system.add_revolute_joint(system.add_marker(system.ground), system.add_node_marker(arm, 1))
        if welded:
            tip = system.add_rigid_body(
                mass, np.diag([1e-6] * 3), position=down @ nodes[10], orientation=down
            )
            system.add_fixed_joint(system.add_node_marker(arm, 11), system.add_marker(tip))
        return system

    def swing(linear):
        values = np.abs(linear.eigenvalues()[0])
        return float(np.min(values[values > 1e-6]))

    rod = RHO * section.area
    rigid = np.sqrt(g * (rod / 2 + mass) / (rod / 3 + mass))  # (the rigid rod, L = 1 m)
    for welded in (True, False):
        system = pendulum(welded)
        at_rest = swing(fm.linearize_at_rest(system, loads=True))
        about = swing(fm.linearize(system, fm.equilibrium(system)))
        assert_close(at_rest, about, rel=1e-6, what=f"welded {welded}: at rest vs equilibrium")
        assert_close(at_rest, rigid, rel=1e-4, what=f"welded {welded}: against the rigid rod")
