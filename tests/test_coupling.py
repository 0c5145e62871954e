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


# Rotary inertia (kinematic coupling, seed section 6) -------------------------------------------

#: Euler-Bernoulli cantilever: beta_n L (R1).
BETA_L = (1.875104068711961, 4.694091132974175, 7.854757438237613)


def flap_frequencies(section, speed_parameter: float = 0.0, elements: int = 40) -> np.ndarray:
    """The first three nondimensional flap frequencies w sqrt(rho A L^4 / EI) of a 1 m
    aluminium cantilever of `section` turned at g = W sqrt(rho A L^4 / EI) (geometric
    stiffness on)."""
    from flexmbd.fe import Material

    material = Material(7.0e10, 0.3, 2700.0)
    scale = np.sqrt(material.density * section.area / (material.young_modulus * section.iy))
    speed = speed_parameter / scale
    system = fm.examples.rotating_beam(
        material, section, 1.0, elements, speed=speed, geometric_stiffness=True
    )
    frequencies, shapes = fm.linearize(system, fm.equilibrium(system)).modes()
    # Node translations and twists (times the section's width: torsion modes move the nodes
    # by round-off only): flap modes move them along z.
    rows = np.concatenate([7 + 6 * k + np.arange(4) for k in range(elements)])
    moved = shapes[rows].reshape(elements, 4, -1)
    moved[:, 3] *= max(np.sqrt(12 * section.iz / section.area), 1e-3)
    flap = np.sum(moved[:, 2] ** 2, axis=0) / np.sum(moved**2, axis=(0, 1)) > 0.9
    return 2 * np.pi * frequencies[flap][:3] * scale


def test_rotary_inertia_lowers_the_bending_frequencies_by_rayleighs_correction(assert_close):
    """A thick beam (h / L = 0.05): without the rotary inertia of its sections its flap
    frequencies are Euler-Bernoulli's (R1); with it each is lower by the first-order Rayleigh
    correction -(1/2) (I / A) int phi'^2 / int phi^2 of its Euler-Bernoulli mode phi."""
    from flexmbd.fe import Section

    thick = (
        fm.fe.Section.rectangle(0.3, 0.05) if hasattr(fm, "fe") else Section.rectangle(0.3, 0.05)
    )
    plain = flap_frequencies(thick.without_rotary_inertia())
    euler_bernoulli = np.array(BETA_L) ** 2
    assert_close(plain, euler_bernoulli, rel=2e-6, abs=0, what="without rotary inertia vs R1")
    rayleigh = flap_frequencies(thick)
    x = np.linspace(0.0, 1.0, 20001)
    for n, beta in enumerate(BETA_L):
        sigma = (np.cosh(beta) + np.cos(beta)) / (np.sinh(beta) + np.sin(beta))
        phi = np.cosh(beta * x) - np.cos(beta * x) - sigma * (np.sinh(beta * x) - np.sin(beta * x))
        slope = np.gradient(phi, x)
        ratio = np.trapezoid(slope**2, x) / np.trapezoid(phi**2, x)
        predicted = -0.5 * thick.iy / thick.area * ratio
        drop = rayleigh[n] / plain[n] - 1.0
        assert drop < 0
        assert_close(drop, predicted, rel=0.05, abs=0, what=f"relative drop of mode {n + 1}")
