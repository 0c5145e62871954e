"""Command line: ``flexmbd run [EXAMPLE]`` runs a built-in example and compares it with its
published reference; ``flexmbd examples`` lists them."""

from __future__ import annotations

import argparse
import sys
import time

from . import __version__
from .errors import FlexmbdError
from .examples import EXAMPLES
from .simulation import simulate


def _run(args: argparse.Namespace) -> int:
    example = EXAMPLES[args.example]()
    end = args.end if args.end is not None else example.end_time
    step = args.step if args.step is not None else example.step_size
    print(f"flexmbd {__version__}: {example.description}")
    model = example.system.compile()
    print(f"  {model!r}")
    print(f"  simulating to t = {end:g} s with step {step:g} s ({example.solver!r})")
    start = time.perf_counter()
    try:
        result = simulate(
            model, end, step, output_interval=example.output_interval, solver=example.solver
        )
    except FlexmbdError as error:
        print(f"  failed: {error}", file=sys.stderr)
        return 1
    elapsed = time.perf_counter() - start
    stats = result.statistics
    print(
        f"  done in {elapsed:.3f} s: {stats['steps']} steps, "
        f"{stats['newton_iterations'] / max(stats['steps'], 1):.2f} Newton iterations per step, "
        f"{stats['factorizations']} factorizations"
    )
    energy = result.total_energy
    print(f"  largest constraint violation {result.constraint_violation.max():.2e}")
    print(f"  total energy {energy[0]:.6f} J -> {energy[-1]:.6f} J")
    if example.check is not None:
        for name, value in example.check(result).items():
            print(f"  {name}: {value:.2e}")
    return 0


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``flexmbd`` command."""
    parser = argparse.ArgumentParser(prog="flexmbd", description="Flexible multibody dynamics.")
    parser.add_argument("--version", action="version", version=f"flexmbd {__version__}")
    sub = parser.add_subparsers(dest="command")
    run = sub.add_parser("run", help="run a built-in example (default: four-bar)")
    run.add_argument("example", nargs="?", default="four-bar", choices=sorted(EXAMPLES))
    run.add_argument("--end", type=float, help="end time (s)")
    run.add_argument("--step", type=float, help="step size (s)")
    sub.add_parser("examples", help="list the built-in examples")
    args = parser.parse_args(argv)
    if args.command == "examples":
        for name, builder in sorted(EXAMPLES.items()):
            print(f"{name}: {builder().description}")
        return 0
    if args.command in (None, "run"):
        if args.command is None:
            args = parser.parse_args(["run"])
        return _run(args)
    return 2


if __name__ == "__main__":
    raise SystemExit(main())
