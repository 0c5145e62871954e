"""Wave motion in a rotating rod (issue 32, seed section 6; reference R6): the FE model's
axial branch converges to w^2 = c0^2 k^2 - W^2, its phase velocity falls below c0 and its group
velocity rises above it, the low wave numbers most; without rotation the rod is not
dispersive; the bending branch against Euler-Bernoulli within the rotary inertia."""

from __future__ import annotations

import numpy as np
import pytest

import flexmbd as fm
from flexmbd.dispersion import dispersion
from flexmbd.fe import Material, Section

STEEL = Material(2.0e11, 0.3, 7850.0)
ROD = Section.circle(0.01)
C0 = np.sqrt(2.0e11 / 7850.0)
LIMIT = np.pi * C0 / 2.0  # rad/s: the lowest axial frequency of the 1 m rod at rest
SPEED = 0.6 * LIMIT


def test_the_axial_branch_converges_to_r6(assert_close):
    errors = []
    for elements in (8, 16, 32):
        axial = dispersion(STEEL, ROD, 1.0, elements, speed=SPEED, count=3)
        assert_close(axial.analytic, np.sqrt(C0**2 * axial.wave_numbers**2 - SPEED**2), rel=1e-14)
        errors.append(np.abs(axial.frequencies / axial.analytic - 1.0))
    errors = np.array(errors)
    # Second order in the element length: halving it divides the error by about 4.
    assert np.all(errors[1:] < errors[:-1] / 3.5)
    assert errors[-1].max() < 3e-3


def test_rotation_makes_the_rod_dispersive(assert_close):
    at_rest = dispersion(STEEL, ROD, 1.0, 128, speed=0.0, count=4)
    spinning = dispersion(STEEL, ROD, 1.0, 128, speed=SPEED, count=4)
    # At rest: every harmonic wave travels at c0 (to the FE error at these wave numbers).
    assert_close(at_rest.phase_velocity[:3], C0, rel=1e-3, what="phase velocity at rest")
    assert_close(at_rest.group_velocity[:2], C0, rel=1e-3, what="group velocity at rest")
    # Spinning: phase velocity below c0 and group velocity above, the low wave numbers most,
    # as R6 says, and the FE branch gives them to 1e-3 at resolved wave numbers.
    cp, cg = spinning.phase_velocity[:3], spinning.group_velocity[:2]
    assert np.all(cp < C0) and np.all(np.diff(cp) > 0)
    assert np.all(cg > C0) and np.all(np.diff(cg) < 0)
    assert_close(cp[0], 0.8 * C0, rel=1e-3, what="first phase velocity: sqrt(1 - 0.36) c0")
    assert_close(cp, spinning.analytic_phase_velocity[:3], rel=1e-3, what="phase velocity")
    assert_close(cg, spinning.analytic_group_velocity[:2], rel=1e-3, what="group velocity")


def test_the_bending_branch_is_euler_bernoulli_within_the_rotary_inertia(assert_close):
    beam = Section.rectangle(0.01, 0.02)
    bending = dispersion(STEEL, beam, 1.0, 32, branch="bending", count=4)
    r2 = beam.iy / beam.area
    # A Rayleigh beam: below Euler-Bernoulli by about (r k)^2 / 2.
    shortfall = 1.0 - bending.frequencies / bending.analytic
    assert np.all(shortfall > 0.0)
    assert_close(shortfall, 0.5 * r2 * bending.wave_numbers**2, rel=0.6, what="shortfall")
    assert_close(bending.analytic[0], 1.8751**2 * np.sqrt(2e11 * beam.iy / (7850 * beam.area)),
                 rel=1e-4)  # fmt: skip
    # A round rod: the count asked for (its fifth pair was dropped as not bending enough, the
    # slopes counted against it: 4 modes at 16 to 64 elements).
    rod = dispersion(STEEL, Section.circle(0.01), 1.0, 64, branch="bending", count=8)
    assert len(rod.frequencies) == 8
    assert_close(rod.frequencies, rod.analytic, rel=1e-2, what="round rod bending")


def test_refusals():
    with pytest.raises(fm.InvalidParameterError, match="no steady rotation"):
        dispersion(STEEL, ROD, 1.0, 8, speed=1.01 * LIMIT)
    with pytest.raises(fm.InvalidParameterError, match="speed 0"):
        dispersion(STEEL, ROD, 1.0, 8, speed=10.0, branch="bending")
    with pytest.raises(fm.InvalidParameterError, match="branch"):
        dispersion(STEEL, ROD, 1.0, 8, branch="torsion")
