"""Spin-up of a flexible beam (reference R3: Kane, Ryan and Banerjee 1987; the built-in
example `flexmbd.examples.spin_up`): the tip lags behind the hub while the hub accelerates;
the model needs the geometric stiffness of the centrifugal tension (seed section 6), without
which it diverges once the hub turns faster than the first bending frequency."""

from __future__ import annotations

import numpy as np

import flexmbd as fm


def spin_up(geometric_stiffness: bool, end_time: float):
    example = fm.examples.spin_up(geometric_stiffness)
    beam, tip = example.items["beam"], example.items["tip node"]
    try:
        result = fm.simulate(example.system, end_time, 5e-3, output_interval=0.05)
    except fm.SimulationError as error:
        result = error.result
    return result, result.node_displacements(beam, [tip])[:, 0, 1]


def test_spin_up_tip_deflection_matches_r3(assert_close):
    result, v_tip = spin_up(True, 20.0)
    k = int(np.argmin(v_tip))
    assert_close(v_tip[k], -0.5737, abs=0.01, what="min v_tip")
    assert 6.7 <= result.time[k] <= 6.8
    at = {t: v_tip[int(np.argmin(np.abs(result.time - t)))] for t in (5.0, 10.0, 15.0, 20.0)}
    assert_close(at[5.0], -0.4684, abs=0.01, what="v_tip at 5 s")
    assert_close(at[10.0], -0.3627, abs=0.01, what="v_tip at 10 s")
    assert_close(at[15.0], 0.0, abs=0.005, what="v_tip at 15 s")  # about +0.001 m
    assert_close(at[20.0], 0.0, abs=0.005, what="v_tip at 20 s")


def test_spin_up_without_geometric_stiffness_diverges():
    result, v_tip = spin_up(False, 10.0)
    # Well below the first bending frequency (3.7977 rad/s, reached at 8.51 s) it still
    # follows (softened); beyond it the deflection grows to tens of metres (or the
    # integration fails).
    early = result.time <= 6.0
    assert result.time[-1] > 8.51
    assert np.max(np.abs(v_tip[early])) < 1.0
    assert not result.success or np.max(np.abs(v_tip)) > 10.0


def test_the_beam_as_eight_deformable_bodies_converges_to_the_exact_r3(assert_close):
    # Issue 30 (c): one deformable body converges under refinement to -0.5759 m, the answer
    # of its second-order (von Karman) strain, 0.38 % more flexible than R3 (which a
    # geometrically exact chain of rigid links reproduces: -0.57376 extrapolated, see
    # benchmarks/spin_up_refinement.py). Split into deformable bodies joined by fixed
    # joints, each body's own rotation carries most of the large rotation and the FFRF
    # reaches the exact answer: 8 bodies of 5 elements, within 0.1 %.
    example = fm.examples.spin_up(elements=40, bodies=8)
    result = fm.simulate(example.system, 8.0, 5e-3, output_interval=0.01)
    errors = example.check(result)
    assert errors["min v_tip error (m)"] < 1e-3 * 0.5737
    assert errors["time of the minimum - 6.75 s"] <= 0.02
    # A single body with the same 40 elements stays at its own limit, 0.38 % off.
    single = fm.examples.spin_up(elements=40)
    result = fm.simulate(single.system, 8.0, 5e-3, output_interval=0.01)
    v_single = result.node_displacements(single.items["beam"], [41])[:, 0, 1].min()
    assert_close(v_single, -0.5759, rel=3e-4, what="min v_tip of a single body")
