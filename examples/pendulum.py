"""IFToMM A01 simple pendulum: a point mass on a 1 m massless link, released horizontally.

Positions are compared with the exact solution (reference R5) and the energy drift is printed
for generalized-alpha without numerical dissipation (spectral radius 1).
"""

import numpy as np

import flexmbd as fm


def main() -> int:
    example = fm.examples.pendulum()
    result = fm.simulate(
        example.system,
        example.end_time,
        example.step_size,
        output_interval=example.output_interval,
        solver=fm.GeneralizedAlpha(1.0, newton_tolerance=1e-10),
    )
    print(result)
    failures = 0
    for name, error in example.check(result).items():
        print(f"{name}: {error:.2e}")
        failures += error > 1e-6
    drift = np.max(np.abs(result.total_energy - result.total_energy[0])) / 9.81
    print(f"energy drift relative to m g L: {drift:.2e}")
    failures += drift > 1e-6
    return int(failures > 0)


if __name__ == "__main__":
    raise SystemExit(main())
