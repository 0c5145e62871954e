"""Wave motion in rotating rods and beams (seed section 6): the dispersion relation of a
finite element model against the analytic one.

    axial = fm.dispersion(Material(...), Section.circle(0.01), length=1.0, elements=64,
                          speed=300.0, branch="axial")
    axial.frequencies, axial.analytic                 # rad/s per mode
    axial.phase_velocity, axial.group_velocity        # from the FE branch

A uniform rod or beam, clamped at the hub (x = 0) and free at its tip, is turned about the
global z axis at `speed` W by an angle driver; its motion is linearized about the steady,
centrifugally stretched rotation (:func:`flexmbd.steady_rotation`, :func:`flexmbd.linearize`).
The modes of a branch ("axial": along the rod; "bending": flap, out of the plane of rotation)
are found by their shapes and given the wave numbers of the clamped-free rod or beam:

- axial: k_n = (2n - 1) pi / (2 L), and in the rotating frame
  rho u_tt - E u_xx - rho W^2 u = rho W^2 x, so w^2 = c0^2 k^2 - W^2 with c0 = sqrt(E / rho)
  (reference R6): the phase velocity c0 sqrt(1 - W^2 / (c0 k)^2) falls below c0, the group
  velocity c0 / sqrt(1 - W^2 / (c0 k)^2) rises above it, the low wave numbers most; the rod is
  dispersive only because it rotates. The Coriolis coupling of the axial with the in-plane
  bending motion is left out (`gyroscopic=False`, as in the one-dimensional rod of R6); above
  W = pi c0 / (2 L) the rod has no steady rotation (the lowest axial frequency reaches zero).
- bending (without rotation): the flap modes (bending about the section's y axis; of a round
  section, one of each pair), k_n L = 1.8751, 4.6941, ..., the roots of cos(kL) cosh(kL) = -1,
  and w = sqrt(EI / (rho A)) k^2 (Euler-Bernoulli: group velocity twice the phase velocity).
  The FE beam has the rotary inertia of its sections, so its branch lies below this by about
  (r k)^2 / 2 relative (r the section's radius of gyration): a Rayleigh beam.

The phase velocity of the FE branch is w_n / k_n; its group velocity dw/dk is the difference
quotient of neighbouring modes, at the mid wave numbers, and so is the analytic one it is
compared with (both dw/dk there to O(dk^2): the axial group velocity itself is
c0^2 k / w(k)).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ._checks import integer, number
from .errors import InvalidParameterError

Array = NDArray[np.float64]

#: Branches.
BRANCHES = ("axial", "bending")


@dataclass
class DispersionBranch:
    """A branch of the dispersion relation of the FE model (see the module): per mode its
    wave number (1/m), FE and analytic frequencies (rad/s) and phase velocities (m/s); the
    group velocities (m/s, difference quotients of neighbouring modes) at the mid wave numbers
    `mid_wave_numbers`."""

    branch: str
    speed: float
    wave_numbers: Array
    frequencies: Array
    analytic: Array
    phase_velocity: Array
    analytic_phase_velocity: Array
    mid_wave_numbers: Array
    group_velocity: Array
    analytic_group_velocity: Array


def _bending_roots(count: int) -> Array:
    """The first `count` roots beta L of cos(beta L) cosh(beta L) = -1."""
    from scipy.optimize import brentq  # where used: importing flexmbd stays light

    roots = []
    for n in range(1, count + 1):
        guess = (2 * n - 1) * np.pi / 2
        roots.append(brentq(lambda x: np.cos(x) * np.cosh(x) + 1.0, guess - 1.0, guess + 1.0))
    return np.array(roots)


def dispersion(
    material: Any,
    section: Any,
    length: float,
    elements: int,
    *,
    speed: float = 0.0,
    branch: str = "axial",
    count: int = 8,
) -> DispersionBranch:
    """The first `count` modes of `branch` of a clamped-free beam of `material`, `section`,
    `length` (m) and `elements` Euler-Bernoulli elements turned at `speed` (rad/s) about an
    axis through its clamped end, against the analytic relation (see the module)."""
    from .analysis import equilibrium, linearize, steady_rotation
    from .examples import rotating_beam

    if branch not in BRANCHES:
        raise InvalidParameterError(
            f"branch must be one of {', '.join(BRANCHES)}, got {branch!r}", item="branch"
        )
    length = number(length, "length")
    speed = number(speed, "speed")
    elements = integer(elements, "elements")
    count = integer(count, "count")
    if length <= 0 or elements < 1 or count < 1:
        raise InvalidParameterError("length, elements and count must be positive")
    if branch == "bending" and speed != 0.0:
        raise InvalidParameterError(
            "the bending branch has an analytic relation only without rotation (speed 0)",
            item="speed",
        )
    c0 = float(np.sqrt(material.young_modulus / material.density))
    if branch == "axial" and abs(speed) >= np.pi * c0 / (2 * length):
        raise InvalidParameterError(
            f"speed {speed:g} rad/s: at or above pi c0 / (2 L) = "
            f"{np.pi * c0 / (2 * length):.6g} rad/s the rod has no steady rotation",
            item="speed",
        )
    model = rotating_beam(material, section, length, elements, speed=speed, name="rod").compile()
    state = steady_rotation(model) if speed != 0.0 else equilibrium(model)
    linear = linearize(model, state).without_velocity_terms()  # no Coriolis (see the module)
    frequencies, _, shapes = linear.oscillating()
    # Each node's 6 elastic coordinates; rotations times the section's polar radius of
    # gyration, so that torsion (no translation) counts as its own motion.
    shapes = shapes[7 : 7 + 6 * elements].reshape(elements, 6, -1)
    gyration = np.sqrt((section.iy + section.iz) / section.area)
    moved = np.abs(np.concatenate([shapes[:, :3], gyration * shapes[:, 3:]], axis=1)) ** 2
    total = moved.sum(axis=(0, 1))
    round_section = bool(np.isclose(section.iy, section.iz, rtol=1e-9, atol=0.0))
    if branch == "axial":
        share = moved[:, 0].sum(axis=0) / total
    elif round_section:
        # Bending about y and z at the same frequencies: the pairs mix; one of each. Its
        # slopes are bending too (without them the fifth pair, 1.1 % slope, was dropped).
        share = (moved[:, 1:3].sum(axis=(0, 1)) + moved[:, 4:6].sum(axis=(0, 1))) / total
    else:
        share = (moved[:, 2].sum(axis=0) + moved[:, 4].sum(axis=0)) / total
    omega = 2 * np.pi * frequencies[share > 0.99]
    if branch == "bending" and round_section and len(omega):
        omega = omega[np.concatenate([[True], np.diff(omega) > 1e-6 * omega[1:]])]
    omega = omega[:count]
    n = len(omega)
    if n < 2:
        raise InvalidParameterError(
            f"the model has {n} {branch} modes: use more elements", item="elements"
        )
    rho_a = material.density * section.area
    if branch == "axial":
        k = (2 * np.arange(1, n + 1) - 1) * np.pi / (2 * length)
        analytic = np.sqrt(c0**2 * k**2 - speed**2)
    else:
        k = _bending_roots(n) / length
        analytic = np.sqrt(material.young_modulus * section.iy / rho_a) * k**2
    mid = 0.5 * (k[1:] + k[:-1])
    return DispersionBranch(
        branch=branch,
        speed=speed,
        wave_numbers=k,
        frequencies=omega,
        analytic=analytic,
        phase_velocity=omega / k,
        analytic_phase_velocity=analytic / k,
        mid_wave_numbers=mid,
        group_velocity=np.diff(omega) / np.diff(k),
        analytic_group_velocity=np.diff(analytic) / np.diff(k),
    )
