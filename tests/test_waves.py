"""An axial pulse in a spinning rod (issue 32, seed section 6; reference R6): the group velocity
of a tone burst measured in the full simulation is the analytic one to 2 %, the rotation
raises it by the analytic amount (six times the tolerance and more), the numerical dispersion
is a small part of that, and the front travels at c0.

The rod: c0 = 50 m/s (E = 2.5 MPa, rho = 1000 kg/m^3, radius 10 mm), 16 m, 640 elements
(40 per carrier wavelength of 1 m), on an axial bedding of Wf = sqrt(2) W and turned at
W = 0.6 c0 k0 = 188.5 rad/s: w^2 = c0^2 k^2 + Wf^2 - W^2, c_g = 0.857 c0 turning against
0.762 c0 at rest (see flexmbd.waves for why the bedding)."""

from __future__ import annotations

import numpy as np
import pytest

import flexmbd as fm
from flexmbd.dispersion import dispersion
from flexmbd.fe import Material, Section
from flexmbd.waves import _fe_branch, _rod_model, generalized_alpha_frequency, rod_body

SOFT = Material(2.5e6, 0.45, 1000.0)
ROD = Section.circle(0.01)
C0 = 50.0
K0 = 2.0 * np.pi  # 1/m: a carrier wavelength of 1 m
SPEED = 0.6 * C0 * K0  # rad/s
BEDDING = SOFT.density * ROD.area * 2.0 * SPEED**2  # N/m^2: Wf^2 = 2 W^2
TOLERANCE = 0.02


def pulse(speed: float) -> fm.AxialPulse:
    return fm.axial_pulse(SOFT, ROD, 16.0, 640, speed=speed, wave_number=K0, foundation=BEDDING)


@pytest.fixture(scope="module")
def turning():
    return pulse(SPEED)


@pytest.fixture(scope="module")
def resting():
    return pulse(0.0)


def test_the_measured_group_velocity_is_the_analytic_one(turning, assert_close):
    analytic = C0 / np.sqrt(1.0 + (BEDDING / (SOFT.density * ROD.area) - SPEED**2) / (C0 * K0) ** 2)
    assert_close(turning.analytic_group_velocity, analytic, rel=1e-12)
    assert_close(turning.group_velocity, analytic, rel=TOLERANCE, what="measured group velocity")
    # The rotation effect is resolved: without the rotation term the pulse would travel at
    # the group velocity at rest, or (no dispersion at all) at c0; both are more than three
    # tolerances away from what is measured.
    assert abs(turning.group_velocity / turning.at_rest_group_velocity - 1.0) > 3 * TOLERANCE
    assert abs(turning.group_velocity / C0 - 1.0) > 3 * TOLERANCE
    # Each station's arrival, not only the fit: the envelope peaks lie on the line.
    travelled = 16.0 - turning.stations
    predicted = turning.arrival_times[0] + (travelled - travelled[0]) / analytic
    assert_close(turning.arrival_times, predicted, abs=TOLERANCE * travelled[-1] / analytic)


def test_the_rotation_raises_the_group_velocity_by_the_analytic_amount(
    turning, resting, assert_close
):
    # At rest the same measurement gives the group velocity at rest...
    assert_close(resting.group_velocity, resting.analytic_group_velocity, rel=TOLERANCE)
    assert_close(resting.analytic_group_velocity, turning.at_rest_group_velocity, rel=1e-12)
    # ...so that the difference, 12 % of c_g, is the rotation's.
    assert_close(
        turning.group_velocity - resting.group_velocity,
        turning.analytic_group_velocity - turning.at_rest_group_velocity,
        rel=0.15,
        what="rise of the group velocity by the rotation",
    )


def test_the_numerical_dispersion_is_small_against_the_rotation_effect(turning, assert_close):
    effect = turning.analytic_group_velocity - turning.at_rest_group_velocity
    fe_error = turning.fe_group_velocity - turning.analytic_group_velocity
    discrete_error = turning.discrete_group_velocity - turning.analytic_group_velocity
    assert abs(fe_error) < 0.05 * effect and abs(discrete_error) < 0.05 * effect
    # Consistent mass raises the FE branch by about (k h)^2 / 6 (c0^2 k / w)^2 ... here +0.3 %;
    # generalized-alpha lowers it again.
    assert fe_error > 0.0 and discrete_error < fe_error
    # The measurement against the discrete model it measures: within 1 %.
    assert_close(turning.group_velocity, turning.discrete_group_velocity, rel=0.01)


def test_the_front_travels_at_c0(turning, resting, assert_close):
    for run in (turning, resting):
        assert_close(run.front_velocity, C0, rel=0.05, what="front velocity")
        # Neither the group nor the phase velocity: the front outruns the envelope.
        assert 1.05 * run.group_velocity < run.front_velocity < run.analytic_phase_velocity
    # Nothing arrives before the c0 front (beyond the threshold).
    assert np.all(turning.front_times >= (16.0 - turning.stations) / C0 - turning.step_size)


def test_the_station_signals_are_the_burst(turning):
    # The carrier of the strain at each station is w0: the zero crossings of the strain,
    # where the envelope is above half its peak, are half periods apart.
    for j in range(len(turning.stations)):
        strain, envelope = turning.strains[:, j], turning.envelopes[:, j]
        strong = envelope > 0.5 * envelope.max()
        crossings = np.flatnonzero(strong[1:] & (np.sign(strain[1:]) != np.sign(strain[:-1])))
        half_period = np.median(np.diff(turning.time[crossings]))
        assert abs(half_period / (np.pi / turning.frequency) - 1.0) < 0.05
    with pytest.raises(ValueError):
        turning.strains[0, 0] = 1.0


def test_the_rod_is_the_axial_branch_of_a_beam(assert_close):
    # The FE branch of the axial-only rod (no bedding, turned at 0.6 times its divergence
    # speed, R6) against flexmbd.dispersion's axial modes of a beam of the same mesh.
    steel = Material(2.0e11, 0.3, 7850.0)
    c0 = np.sqrt(2.0e11 / 7850.0)
    speed = 0.6 * np.pi * c0 / 2.0
    beam = dispersion(steel, ROD, 1.0, 32, speed=speed, count=5)
    model = _rod_model(rod_body(steel, ROD, 1.0, 32), speed, None)
    k, omega = _fe_branch(model, fm.steady_rotation(model), 1.0)
    assert_close(k[:5], beam.wave_numbers, rel=1e-14)
    assert_close(omega[:5], beam.frequencies, rel=1e-8, what="axial frequencies")


def test_generalized_alpha_frequency(assert_close):
    # Spectral radius 1 is the trapezoidal rule: tan(w_h h / 2) = w h / 2.
    omega, h = np.array([10.0, 100.0, 1000.0]), 1e-3
    assert_close(
        generalized_alpha_frequency(omega, h, 1.0), 2.0 / h * np.arctan(omega * h / 2.0), rel=1e-12
    )
    # Second order: the relative error falls by 4 when the step halves.
    errors = [generalized_alpha_frequency(100.0, s, 0.8)[0] / 100.0 - 1.0 for s in (1e-3, 5e-4)]
    assert_close(errors[0] / errors[1], 4.0, rel=0.01)


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ({"speed": -1.0}, "speed must be >= 0"),
        ({"speed": 2.0 * SPEED}, "no steady rotation"),
        ({"foundation": 0.0}, "no steady rotation"),
        ({"foundation": -1.0}, "foundation must be >= 0"),
        ({"elements": 300}, "not resolved by the mesh"),
        ({"wave_number": 0.0}, "wave_number must be > 0"),
        ({"cycles": 3}, "cycles must be >= 4"),
        ({"cycles": 40}, "too short for the burst"),
        ({"steps_per_period": 10}, "steps_per_period"),
        ({"stations": [15.0, 2.0]}, "stations must be"),
        ({"stations": [15.0, 16.0]}, "stations must be"),
        ({"amplitude": 0.0}, "amplitude must be > 0"),
        ({"front_threshold": 1.0}, "front_threshold"),
        ({"speed": "fast"}, "speed must be a number"),
    ],
)
def test_refusals(change, match):
    arguments = {"speed": SPEED, "wave_number": K0, "foundation": BEDDING} | change
    elements = arguments.pop("elements", 640)
    with pytest.raises(fm.InvalidParameterError, match=match):
        fm.axial_pulse(SOFT, ROD, 16.0, elements, **arguments)
