"""Spin-up of a flexible beam (reference R3: Kane, Ryan and Banerjee 1987): the tip lags
behind the hub while the hub accelerates; the model needs the geometric stiffness of the
centrifugal tension (seed section 6), without which it diverges once the hub turns faster
than the first bending frequency."""

from __future__ import annotations

import numpy as np
import pytest

import flexmbd as fm
from flexmbd.fe import Material, Section, build_body, straight_beam

LENGTH, ELEMENTS = 10.0, 10
MATERIAL = Material(7.0e10, 0.3, 3000.0)  # EA = 2.8e7 N, rho A = 1.2 kg/m with A = 4e-4 m^2
SECTION = Section(4e-4, 2e-7, 2e-7, 4e-7)  # EI = 1.4e4 N m^2
TS, WS = 15.0, 6.0


def hub_angle(t: float) -> tuple[float, float, float]:
    """theta, theta_dot, theta_ddot of the prescribed hub motion."""
    if t <= TS:
        c = TS / (2 * np.pi)
        theta = WS / TS * (t**2 / 2 + c**2 * (np.cos(t / c) - 1))
        return theta, WS / TS * (t - c * np.sin(t / c)), WS / TS * (1 - np.cos(t / c))
    return WS * (t - TS / 2), WS, 0.0


def spin_up(geometric_stiffness: bool, end_time: float):
    nodes, conn = straight_beam(LENGTH, ELEMENTS)
    data = build_body(
        nodes, conn, MATERIAL, section=SECTION, reference="clamped", reference_nodes=[0]
    )
    system = fm.System()
    beam = system.add_flexible_body(data, geometric_stiffness=geometric_stiffness)
    hub, root = system.add_marker(system.ground), system.add_node_marker(beam, 1)
    system.add_revolute_joint(hub, root)
    system.add_angle_driver(hub, root, fm.UserFunction(hub_angle, derivatives=True))
    result = fm.simulate(system, end_time, 5e-3, output_interval=0.05)
    return result, result.node_displacements(beam, [ELEMENTS + 1])[:, 0, 1]


def test_spin_up_tip_deflection_matches_r3():
    result, v_tip = spin_up(True, 10.0)
    k = int(np.argmin(v_tip))
    assert v_tip[k] == pytest.approx(-0.5737, abs=0.01)
    assert 6.7 <= result.time[k] <= 6.8
    at = {t: v_tip[int(np.argmin(np.abs(result.time - t)))] for t in (5.0, 10.0)}
    assert at[5.0] == pytest.approx(-0.4684, abs=0.01)
    assert at[10.0] == pytest.approx(-0.3627, abs=0.01)


def test_spin_up_without_geometric_stiffness_diverges():
    try:
        result, v_tip = spin_up(False, 10.0)
    except fm.SimulationError as error:
        result = error.result
        v_tip = result.node_displacements(1, [ELEMENTS + 1])[:, 0, 1]
    # Well below the first bending frequency (3.7977 rad/s, reached at 8.51 s) it still
    # follows (softened); beyond it the deflection grows to tens of metres (or the
    # integration fails).
    early = result.time <= 6.0
    assert result.time[-1] > 8.51
    assert np.max(np.abs(v_tip[early])) < 1.0
    assert not result.success or np.max(np.abs(v_tip)) > 10.0
