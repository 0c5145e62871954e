"""Dispersion from finite rotation (seed section 6, reference R6): a 1 m steel rod (radius
10 mm, 128 elements), clamped at a hub and free at its tip, at rest and turned at 0.6 times
the speed at which its lowest axial frequency would reach zero (W = 0.6 pi c0 / 2L).

At rest every harmonic axial wave travels at c0 = sqrt(E / rho): the rod is not dispersive.
Turning, w^2 = c0^2 k^2 - W^2: the phase velocities fall below c0 and the group velocities
rise above it, the low wave numbers most. The table shows both from the FE model's modes
against the analytic relation.
"""

import numpy as np

import flexmbd as fm
from flexmbd.fe import Material, Section


def main() -> int:
    steel = Material(2.0e11, 0.3, 7850.0)
    c0 = np.sqrt(steel.young_modulus / steel.density)
    speed = 0.6 * np.pi * c0 / 2.0
    worst = 0.0
    for w in (0.0, speed):
        branch = fm.dispersion(steel, Section.circle(0.01), 1.0, 128, speed=w, count=5)
        print(f"W = {w:.1f} rad/s (c0 = {c0:.1f} m/s)")
        print("   k (1/m)   w FE (rad/s)   w R6 (rad/s)   c_phase/c0 FE   R6")
        for k, f, a, cp, ca in zip(
            branch.wave_numbers,
            branch.frequencies,
            branch.analytic,
            branch.phase_velocity / c0,
            branch.analytic_phase_velocity / c0,
            strict=True,
        ):
            print(f"{k:10.4f} {f:14.2f} {a:14.2f} {cp:15.5f} {ca:8.5f}")
        print("   k mid    c_group/c0 FE   R6")
        for k, g, a in zip(
            branch.mid_wave_numbers,
            branch.group_velocity / c0,
            branch.analytic_group_velocity / c0,
            strict=True,
        ):
            print(f"{k:10.4f} {g:15.5f} {a:8.5f}")
        worst = max(worst, float(np.max(np.abs(branch.frequencies[:3] / branch.analytic[:3] - 1))))
    print(f"largest relative difference of the first three frequencies from R6: {worst:.1e}")
    return int(worst > 1e-3)


if __name__ == "__main__":
    raise SystemExit(main())
