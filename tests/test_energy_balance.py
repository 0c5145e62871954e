"""The power of the forces no potential energy accounts for (`Result.nonconservative_power`)
and the energy balance built on it: loads against the kinetic energy they give, dampers
against -c v^2 from the recorded velocities, structural damping against -qf_dot^T D qf_dot
from the body's invariants; the overview's balance panel with a tip force on a driven arm."""

from __future__ import annotations

import h5py
import numpy as np
import pytest

import flexmbd as fm
from flexmbd.plotting import _driven, _energy_panels, plot_energy_balance
from flexmbd.quantities import force_work


def test_a_constant_force_does_the_work_of_the_kinetic_energy_it_gives(assert_close):
    system = fm.System()
    mass = system.add_point_mass(2.0, velocity=(0.5, 0.0, 0.0))
    system.add_point_force(system.add_marker(mass), (3.0, -1.0, 0.0))
    result = fm.simulate(system, 1.0, 1e-2, output_interval=0.1)
    # P = F . v, with v = v0 + F t / m: linear in t, so the records' integral is exact.
    velocity = result.velocity(mass)
    assert_close(result.nonconservative_power, velocity @ [3.0, -1.0, 0.0], rel=1e-12)
    change = result.kinetic_energy - result.kinetic_energy[0]
    assert_close(force_work(result), change, rel=1e-10, abs=1e-12, what="work = change of KE")
    assert_close(change[-1], 0.5 * 2.0 * (np.array([2.0, -0.5]) ** 2).sum() - 0.25, rel=1e-12)


def test_a_torque_on_a_spinning_body_does_tau_times_its_angular_velocity(assert_close):
    system = fm.System()
    body = system.add_rigid_body(1.0, (0.1, 0.2, 0.3), angular_velocity=(0.0, 0.0, 2.0))
    system.add_torque(system.add_marker(body), (0.0, 0.0, 0.6))
    result = fm.simulate(system, 0.5, 1e-3, output_interval=0.05)
    omega = result.angular_velocity(body)[:, 2]
    assert_close(result.nonconservative_power, 0.6 * omega, rel=1e-10)
    # omega = 2 + 2 t about the principal z axis: work 1/2 I (3^2 - 2^2) = 0.75 J.
    assert_close(force_work(result)[-1], 0.75, rel=1e-6)
    assert_close(result.total_energy[-1] - result.total_energy[0], 0.75, rel=1e-5)


def test_dampers_dissipate_c_v_squared_and_the_springs_store_the_rest(assert_close):
    k, c, m = 400.0, 3.0, 1.5
    system = fm.System(gravity=(0.0, -9.81, 0.0))
    bob = system.add_point_mass(m, position=(0.0, -1.1, 0.0))
    system.add_spring_damper(
        system.add_marker(system.ground), system.add_marker(bob), stiffness=k, damping=c,
        rest_length=1.0,
    )  # fmt: skip
    solver = fm.GeneralizedAlpha(spectral_radius=1.0)
    result = fm.simulate(system, 1.0, 2e-4, output_interval=1e-3, solver=solver)
    v = result.velocity(bob)[:, 1]
    assert np.abs(v).max() > 0.5  # it oscillates
    assert_close(result.nonconservative_power, -c * v**2, rel=1e-10, abs=1e-12)
    dissipated = force_work(result)
    assert dissipated[-1] < -0.1  # a fair part of the energy is gone
    change = result.total_energy - result.total_energy[0]
    # What remains is the records' trapezoid and the integrator's error: far below the work.
    assert np.abs(change - dissipated).max() < 1e-4 * np.abs(dissipated[-1])


def test_structural_damping_dissipates_qf_dot_D_qf_dot(assert_close):
    example = fm.examples.tetrahedral_pendulum()
    calls = example.system.building_calls
    # The same pendulum with Rayleigh damping D = alpha M_ff + beta K_ff.
    alpha, beta = 4.0, 2e-4
    system = fm.System(gravity=calls[0][1][0])
    for name, args, kwargs in calls[1:]:
        if name == "add_flexible_body":
            kwargs = {**kwargs, "rayleigh_damping": (alpha, beta)}
        getattr(system, name)(*args, **kwargs)
    solver = fm.GeneralizedAlpha(spectral_radius=1.0)
    result = fm.simulate(system, 0.3, example.step_size, solver=solver, output_interval=1e-3)
    inv = system._flexible[example.items["arm"].index].invariants
    dense = [np.asarray(a.toarray() if hasattr(a, "toarray") else a) for a in (inv.m_ff, inv.k_ff)]
    damping = alpha * dense[0] + beta * dense[1]
    offset = next(b["offset"] for b in result.layout["bodies"] if b["name"] == "arm")
    qfd = result.velocities[:, offset + 7 : offset + 7 + len(damping)]
    expected = -np.einsum("ti,ij,tj->t", qfd, damping, qfd)
    assert expected.min() < -1e-4  # it vibrates
    assert_close(result.nonconservative_power, expected, rel=1e-9, abs=1e-12 * -expected.min())


def driven_arm_with_a_tip_force():
    """A rigid arm turned by an angle driver, a 5 N force at its tip along global y."""
    system = fm.System(gravity=(0.0, -9.81, 0.0))
    arm = system.add_rigid_body(2.0, (1e-3, 0.2, 0.2), position=(0.5, 0.0, 0.0), name="arm")
    hinge = (system.add_marker(system.ground), system.add_marker(arm, position=(-0.5, 0, 0)))
    system.add_revolute_joint(*hinge, name="hinge")
    system.add_angle_driver(*hinge, fm.Step(0.0, 1.0, 0.0, 1.2), name="drive")
    system.add_point_force(system.add_marker(arm, position=(0.5, 0, 0)), (0.0, 5.0, 0.0))
    return system


def test_the_balance_panel_counts_the_work_of_applied_forces(tmp_path):
    # The overview's panel called the tip force's work (0.6 J here) an error.
    path = tmp_path / "arm.h5"
    result = fm.simulate(
        driven_arm_with_a_tip_force(), 1.5, 1e-3, output_interval=1e-3, results_file=path
    )
    assert _driven(result) == (True, True) and len(_energy_panels(result)) == 2
    work = force_work(result)[-1]
    assert work == pytest.approx(5.0 * np.sin(1.2), rel=1e-5)  # F times the rise of the tip
    ax = plot_energy_balance(result)
    labels = [line.get_label() for line in ax.get_lines()]
    assert labels == ["E(t) - E(0)", "work of the drivers", "work of the forces\nand dampers",
                      "difference"]  # fmt: skip
    difference = ax.get_lines()[-1].get_ydata()
    assert np.abs(difference).max() < 1e-3 * abs(work)
    # Files written before the power was recorded (n, 3) read with NaN, and the panel says so.
    with h5py.File(path, "r+") as file:
        energy = file["energy"][:, :3]
        del file["energy"]
        file.create_dataset("energy", data=energy, maxshape=(None, 3))
    old = fm.read_results(path)
    assert np.isnan(old.nonconservative_power).all() and np.isfinite(old.strain_energy).all()
    assert "not in this file" in plot_energy_balance(old).get_title()


def test_a_model_no_work_is_done_on_shows_its_drift():
    system = fm.System(gravity=(0.0, -9.81, 0.0))
    bob = system.add_point_mass(1.0, position=(1.0, 0.0, 0.0))
    system.add_spring_damper(
        system.add_marker(system.ground), system.add_marker(bob), stiffness=100.0, damping=0.0,
        rest_length=1.0,
    )  # fmt: skip
    result = fm.simulate(system, 0.2, 1e-3)
    assert not np.any(result.nonconservative_power)
    assert _driven(result) == (False, False)
    with pytest.raises(fm.UnknownItemError, match="no work to balance"):
        fm.plotting.quantity_panels(result, "balance")
