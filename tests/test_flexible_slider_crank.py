"""Flexible slider-crank (reference R4, Jonker / Simeon data set; the built-in example
`flexmbd.examples.flexible_slider_crank`): rigid crank driven at 150 rad/s, elastic connecting
rod in the floating frame of reference with simply-supported reference conditions (its elastic
displacements are deflections from the chord), slider a point mass. Checks the midpoint
deflection, the joint reactions and the driving torque."""

from __future__ import annotations

import numpy as np

import flexmbd as fm


def test_midpoint_deflection_matches_r4(assert_close):
    example = fm.examples.flexible_slider_crank(elements=8)
    items = example.items
    result = fm.simulate(example.system, example.end_time, 2e-5, output_interval=1e-4)
    rod, middle = items["rod"], items["middle node"]
    v_mid = result.node_displacements(rod, [middle])[:, 0, 1]
    k = int(np.argmax(np.abs(v_mid)))
    assert_close(abs(v_mid[k]), 4.658e-3, rel=0.03, what="max |v_mid|")
    assert 0.07 < result.time[k] < 0.085
    assert example.check(result)["relative error of max |v_mid|"] < 0.03
    # The simply-supported frame is the chord: the deflection from the deformed chord agrees.
    chord = result.deflection(rod, middle, chord=(1, 9))[:, 1]
    assert_close(chord, v_mid, abs=1e-3 * np.max(np.abs(v_mid)), what="deflection from the chord")
    # Reactions and the driving torque are output; the driver's power equals the rate of
    # change of the mechanical (kinetic plus strain) energy.
    torque = result.reaction_torque(items["drive"])[:, 2]
    assert np.max(np.abs(torque)) > 1.0
    for name in ("crank pin", "wrist pin", "guide"):
        assert np.all(np.isfinite(result.reaction_force(items[name])))
    work = np.concatenate([[0.0], np.cumsum(0.5 * (torque[1:] + torque[:-1]) * 150.0 * 1e-4)])
    energy = result.total_energy - result.total_energy[0]
    assert_close(work, energy, abs=0.01 * np.max(np.abs(energy)), what="work of the drive")
