"""Command line: ``flexmbd run [EXAMPLE]`` runs a built-in example and compares it with its
published reference; ``flexmbd examples`` lists them; ``flexmbd preprocess MESH -o BODY.h5``
turns a mesh file into a deformable-body file (see ``docs/preprocessor.md``)."""

from __future__ import annotations

import argparse
import sys
import time
from typing import Any

from . import __version__, _core
from .errors import FlexmbdError
from .examples import EXAMPLES
from .simulation import simulate


def _solver(text: str | None, default: _core.GeneralizedAlpha) -> Any:
    """The solver named by ``--solver``: "generalized-alpha", or METHOD:STRATEGY[:FORMULATION]
    for an explicit solver, e.g. "dopri5:partitioning:embedding"."""
    if text is None or text == "generalized-alpha":
        return default
    parts = text.split(":")
    if not 2 <= len(parts) <= 3:
        raise argparse.ArgumentTypeError(
            f"--solver {text!r}: expected generalized-alpha or METHOD:STRATEGY[:FORMULATION]"
        )
    default = "joint-space" if parts[1] == "joint-coordinates" else "augmented"
    formulation = parts[2] if len(parts) == 3 else default
    return _core.ExplicitSolver(parts[0], parts[1], formulation=formulation)


def _run(args: argparse.Namespace) -> int:
    example = EXAMPLES[args.example]()
    end = args.end if args.end is not None else example.end_time
    step = args.step if args.step is not None else example.step_size
    print(f"flexmbd {__version__}: {example.description}")
    model = example.system.compile()
    print(f"  {model!r}")
    try:
        solver = _solver(args.solver, example.solver)
    except (argparse.ArgumentTypeError, FlexmbdError) as error:
        print(f"  {error}", file=sys.stderr)
        return 2
    print(f"  simulating to t = {end:g} s with step {step:g} s ({solver!r})")
    start = time.perf_counter()
    try:
        result = simulate(model, end, step, output_interval=example.output_interval, solver=solver)
    except FlexmbdError as error:
        print(f"  failed: {error}", file=sys.stderr)
        return 1
    elapsed = time.perf_counter() - start
    stats = result.statistics
    if stats.get("function_evaluations"):
        work = f"{stats['function_evaluations']} function evaluations"
        if stats.get("reduced_system_size"):
            work += f", acceleration system of {stats['reduced_system_size']} unknowns"
    else:
        work = (
            f"{stats['newton_iterations'] / max(stats['steps'], 1):.2f} Newton iterations per "
            f"step, {stats['factorizations']} factorizations"
        )
    print(f"  done in {elapsed:.3f} s: {stats['steps']} steps, {work}")
    for event in result.events[:10]:
        print(f"  event at t = {event['time']:.6g} s ({event['kind']}): {event['message']}")
    if len(result.events) > 10:
        print(f"  ... {len(result.events) - 10} more events")
    energy = result.total_energy
    print(f"  largest constraint violation {result.constraint_violation.max():.2e}")
    print(f"  total energy {energy[0]:.6f} J -> {energy[-1]:.6f} J")
    if example.check is not None:
        for name, value in example.check(result).items():
            print(f"  {name}: {value:.2e}")
    return 0


def _preprocess(args: argparse.Namespace) -> int:
    from .fe.body_file import save_body
    from .fe.preprocess import Material, body_from_mesh

    options = {
        "mass": args.mass,
        "reference": args.reference,
        "modes": None if args.modes == "none" else args.modes,
        "mode_count": args.count,
        "interfaces": args.interfaces,
        "interface_kind": args.interface_kind,
        "precision": args.precision,
    }
    if args.reference_nodes:
        nodes = args.reference_nodes
        options["reference_nodes"] = nodes[0] if len(nodes) == 1 else [int(n) for n in nodes]
    timings: dict[str, float] = {}
    start = time.perf_counter()
    try:
        material = Material(args.young_modulus, args.poisson_ratio, args.density)
        body = body_from_mesh(args.mesh, material, timings=timings, **options)
    except (FlexmbdError, ValueError, OSError) as error:
        print(f"flexmbd preprocess: {error}", file=sys.stderr)
        return 1
    elapsed = time.perf_counter() - start
    elements = ", ".join(f"{len(c)} {kind}" for kind, c in body.elements.items())
    print(f"flexmbd {__version__}: {args.mesh}: {body.node_count} nodes, {elements}")
    print(
        f"  mass {body.invariants['mass']:.6g} kg, {body.elastic_coordinate_count} elastic "
        f"coordinates ({body.mode_kind or 'nodal'}), reference {args.reference}"
    )
    if body.frequencies is not None:
        shown = ", ".join(f"{f:.4g}" for f in body.frequencies[:8])
        more = " ..." if len(body.frequencies) > 8 else ""
        print(f"  frequencies (Hz): {shown}{more}")
    print("  " + ", ".join(f"{k} {v:.2f} s" for k, v in timings.items()) + f"; {elapsed:.2f} s")
    save_body(body, args.output)
    print(f"  written to {args.output}")
    return 0


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``flexmbd`` command."""
    parser = argparse.ArgumentParser(prog="flexmbd", description="Flexible multibody dynamics.")
    parser.add_argument("--version", action="version", version=f"flexmbd {__version__}")
    sub = parser.add_subparsers(dest="command")
    run = sub.add_parser("run", help="run a built-in example (default: four-bar)")
    run.add_argument(
        "example", nargs="?", default="flexible-slider-crank", choices=sorted(EXAMPLES)
    )
    run.add_argument("--end", type=float, help="end time (s)")
    run.add_argument("--step", type=float, help="step size (s)")
    run.add_argument(
        "--solver",
        help="generalized-alpha (default: the example's settings), or an explicit solver "
        "METHOD:STRATEGY[:FORMULATION] with METHOD rk4 or dopri5, STRATEGY integrate-all, "
        "partitioning, projection or joint-coordinates, FORMULATION augmented or embedding "
        "(joint-coordinates: joint-space, coupled or decoupled)",
    )
    sub.add_parser("examples", help="list the built-in examples")
    pre = sub.add_parser(
        "preprocess",
        help="build a deformable body file from a mesh (Gmsh .msh, Abaqus .inp, VTK)",
        description="Element matrices, invariants of motion, reference conditions and modes "
        "of a body meshed with solid or beam elements, saved as an HDF5 body file.",
    )
    pre.add_argument("mesh", help="mesh file")
    pre.add_argument("-o", "--output", required=True, help="body file to write (.h5)")
    pre.add_argument("-E", "--young-modulus", type=float, required=True, help="Pa")
    pre.add_argument("--poisson-ratio", type=float, required=True)
    pre.add_argument("--density", type=float, required=True, help="kg/m^3")
    pre.add_argument("--mass", choices=("consistent", "lumped"), default="consistent")
    pre.add_argument(
        "--reference",
        choices=("none", "clamped", "3-2-1", "simply-supported", "mean-axis", "interface"),
        default="none",
        help="reference conditions: the body frame (default none)",
    )
    pre.add_argument(
        "--reference-nodes", nargs="+", help="a node set name, or node indices (0-based)"
    )
    pre.add_argument(
        "--modes",
        choices=("none", "fixed-interface", "free-free", "craig-bampton"),
        default="none",
        help="modal reduction (default none: nodal elastic coordinates)",
    )
    pre.add_argument("-n", "--count", type=int, default=0, help="number of eigenmodes")
    pre.add_argument("--interfaces", nargs="+", default=[], help="Craig-Bampton node sets")
    pre.add_argument("--interface-kind", choices=("rbe2", "rbe3", "nodal"), default="rbe2")
    pre.add_argument("--precision", choices=("auto", "double", "single"), default="auto")
    args = parser.parse_args(argv)
    if args.command == "preprocess":
        return _preprocess(args)
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
