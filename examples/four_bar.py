"""IFToMM A02 N-four-bar (N = 2): five rigid links through singular configurations.

B0, the top of the first crank, is compared with the exact solution at t = 10 s (reference R5).
The mechanism is built in 3D from revolute and in-line joints, without redundant equations.
"""

import flexmbd as fm


def main() -> int:
    example = fm.examples.four_bar(2)
    model = example.system.compile()
    print(model)
    result = fm.simulate(
        model,
        example.end_time,
        example.step_size,
        output_interval=example.output_interval,
        solver=example.solver,
    )
    stats = result.statistics
    print(
        f"{stats['steps']} steps, {stats['newton_iterations'] / stats['steps']:.2f} Newton "
        f"iterations per step, largest constraint violation {result.constraint_violation.max():.1e}"
    )
    failures = 0
    for name, error in example.check(result).items():
        print(f"{name}: {error:.2e}")
        failures += error > 1e-4
    return int(failures > 0)


if __name__ == "__main__":
    raise SystemExit(main())
