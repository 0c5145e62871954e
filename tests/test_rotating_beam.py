"""Rotating cantilever: flap frequencies against reference R2 (Wright et al. 1982, via Bir
2009), with and without the geometric stiffness of the centrifugal tension (seed section 6,
elastic coupling), from the linearization about the steadily rotating, stretched blade
(`flexmbd.examples.rotating_blade_flap_frequencies`)."""

from __future__ import annotations

import numpy as np
import pytest

from flexmbd.examples import rotating_blade_flap_frequencies

# R2: nondimensional rotation speed g and the first three flap frequencies.
R2 = {
    0: (3.5160, 22.0345, 61.6972),
    4: (5.5850, 24.2733, 63.9668),
    8: (9.2568, 29.9954, 70.2930),
    12: (13.1702, 37.6031, 79.6145),
}


@pytest.mark.parametrize("g", sorted(R2))
def test_flap_frequencies_with_geometric_stiffness_match_r2(g, assert_close):
    computed = rotating_blade_flap_frequencies(g)
    assert_close(computed, R2[g], rel=1e-3, what="flap frequencies")


def test_without_geometric_stiffness_the_flap_frequency_does_not_stiffen(assert_close):
    computed = rotating_blade_flap_frequencies(12, geometric_stiffness=False)
    assert_close(computed[0], R2[0][0], rel=1e-3, what="first flap frequency")


def test_lead_lag_frequencies_soften_by_the_rotation_speed(assert_close):
    """In the plane of rotation the centrifugal softening takes W^2 off the stiffening of the
    flap motion: w_lag^2 = w_flap^2 - g^2 for the inextensible blade (the blade here is
    extensible, with a Coriolis coupling of its lag and axial motions, which is small)."""
    for g in (4, 8):
        flap = rotating_blade_flap_frequencies(g, count=1)[0]
        lag = rotating_blade_flap_frequencies(g, count=1, direction="lag")[0]
        assert_close(lag, np.sqrt(flap**2 - g**2), rel=1e-4, what="lag frequency")
