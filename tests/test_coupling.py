"""Coupling of the elastic deformation with the joints (issue 32, seed section 6): a two-link
elastic arm with its elbow at the deformed tip of the upper arm (a node marker) against the
same arm with the elbow at the undeformed tip (a frame marker, the Denavit-Hartenberg-like
simplification). The difference is the deformation's: it vanishes as the links stiffen."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

import flexmbd as fm

sys.path.insert(0, str(Path(__file__).parent.parent / "examples"))
from coupling_effects import arm  # noqa: E402


def tip_gap(young_modulus: float) -> tuple[float, float]:
    """Largest tip-position difference (m) of the two models over 0.6 s, and the largest
    shoulder-torque difference (N m)."""
    runs = []
    for deformed in (True, False):
        system, items = arm(deformed, young_modulus)
        result = fm.simulate(system, 0.6, 5e-4, output_interval=5e-3,
                             solver=fm.GeneralizedAlpha(0.6))  # fmt: skip
        runs.append((result.sensor("tip"), result.reaction_torque(items["drive"])[:, 2]))
    (tip_a, torque_a), (tip_b, torque_b) = runs
    gap = float(np.linalg.norm(tip_a - tip_b, axis=1).max())
    return gap, float(np.abs(torque_a - torque_b).max())


def test_the_joint_at_the_deformed_tip_changes_the_motion_and_the_drive_torque():
    gap, torque = tip_gap(7.0e10)
    assert gap > 5e-3 and torque > 0.5  # 5 mm and 0.5 N m, on a tip motion of about 1 m
    stiff_gap, _ = tip_gap(7.0e13)  # a thousand times stiffer: deformations 1/1000
    assert stiff_gap < 0.01 * gap
