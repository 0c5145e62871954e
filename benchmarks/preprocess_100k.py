"""Time and peak memory to build a tetrahedral flexible body of about 100k nodes, next to Exudyn.

The job: a steel bar 1 x 0.16 x 0.16 m meshed with flexmbd's structured tetrahedral box
(``shapes.box(lengths, divisions, "tet4")``, six tetrahedra per cell; 160 x 25 x 25 cells give
108,836 nodes, 326,508 coordinates and 600,000 tet4), preprocessed into a floating-frame body:
stiffness and mass matrices, invariants of motion, and a Craig-Bampton basis of 20 fixed-interface
eigenmodes plus the 6 static modes of the rigid (RBE2) end face x = 1, the body frame attached to
the face x = 0. flexmbd runs ``build_body(..., reference="interface", modes="craig-bampton",
mode_count=20, interfaces=["x0", "x1"], interface_kind="rbe2")``; Exudyn (``exudyn_preprocess.py``,
if ``exudyn`` and ``ngsolve`` are installed) runs FEMinterface on the same mesh: K and M from
NGsolve, ``ComputeHurtyCraigBamptonModesNGsolve`` with the same interfaces and modes, and
``ObjectFFRFreducedOrderInterface``.

Each code runs in a fresh process; the figures are wall-clock seconds of the preprocessing calls
(mesh generation excluded) and the process's peak resident memory (``ru_maxrss``). The reduced
bodies are compared by their first frequencies with the reference face held (eigenvalues of the
reduced K and M): the same mesh and element should give the same numbers.

    python benchmarks/preprocess_100k.py                       # both codes, 108,836 nodes
    python benchmarks/preprocess_100k.py --divisions 40,10,10  # a quick run
    python benchmarks/preprocess_100k.py --no-exudyn
    python benchmarks/preprocess_100k.py --save-exudyn exudyn.log     # keep Exudyn's output
    python benchmarks/preprocess_100k.py --exudyn-json exudyn.log     # and reuse it

Exudyn's side takes 15 to 25 minutes at 108k nodes on the 2-core VM; ``--exudyn-iterations``
sets its eigensolver's iteration count (its default is 40; 25 still converges on this mesh).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
EIGEN_MODES = 20


def _triple(text: str, kind: type) -> tuple:
    parts = text.split(",")
    if len(parts) != 3:
        raise argparse.ArgumentTypeError(f"three comma-separated values expected, got {text!r}")
    return tuple(kind(p) for p in parts)


def _peak_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def flexmbd_worker(divisions: tuple, lengths: tuple, precision: str) -> dict:
    """Runs flexmbd's preprocessor in this process and returns the figures."""
    import scipy.linalg as sla

    import flexmbd
    from flexmbd.fe import shapes
    from flexmbd.fe.preprocess import Material, build_body

    mesh = shapes.box(lengths, divisions, "tet4")
    baseline = _peak_mib()
    stages: dict[str, float] = {}
    start = time.perf_counter()
    body = build_body(
        mesh.nodes,
        mesh.elements,
        Material(2.1e11, 0.3, 7800.0),
        node_sets=mesh.node_sets,
        reference="interface",
        modes="craig-bampton",
        mode_count=EIGEN_MODES,
        interfaces=["x0", "x1"],
        interface_kind="rbe2",
        precision=precision,
        timings=stages,
    )
    total = time.perf_counter() - start
    peak = _peak_mib()
    k_ff = body.invariants.k_ff
    m_ff = body.invariants.m_ff
    values = sla.eigh(0.5 * (k_ff + k_ff.T), 0.5 * (m_ff + m_ff.T), eigvals_only=True)
    reduced = np.sqrt(np.clip(values, 0.0, None)) / (2.0 * np.pi)
    return {
        "nodes": len(mesh.nodes),
        "elements": len(mesh.elements["tet4"]),
        "stages": stages,
        "total_seconds": total,
        "peak_rss_mib": peak,
        "baseline_rss_mib": baseline,
        "reduced_frequencies_hz": reduced[:5].tolist(),
        "mode_count": int(body.modes.shape[1]),
        "mass": float(body.invariants.mass),
        "variant": f"build_body(precision={precision!r}), flexmbd {flexmbd.__version__}",
    }


def run_process(arguments: list[str], log_path: Path | None = None) -> dict:
    """Runs a Python script in a fresh process and parses the JSON of its last output line."""
    result = subprocess.run(
        [sys.executable, *arguments], capture_output=True, text=True, check=False
    )
    if log_path is not None:
        log_path.write_text(result.stderr + result.stdout)  # the JSON line last
    if result.returncode != 0:
        raise RuntimeError(f"{' '.join(arguments)} failed:\n{result.stdout}\n{result.stderr}")
    return json.loads(result.stdout.strip().splitlines()[-1])


def exudyn_available() -> bool:
    try:
        import exudyn  # noqa: F401
        import ngsolve  # noqa: F401
    except ImportError:
        return False
    return True


def print_row(name: str, r: dict) -> None:
    stages = ", ".join(f"{k} {v:.1f}" for k, v in r["stages"].items())
    print(
        f"{name:8s} {r['total_seconds']:9.1f} s  peak {r['peak_rss_mib']:7.0f} MiB "
        f"(baseline {r['baseline_rss_mib']:.0f})  {r['mode_count']} modes  [{stages}]"
    )
    print(f"{'':8s} {r['variant']}")
    print(
        f"{'':8s} reduced frequencies "
        + ", ".join(f"{f:.3f}" for f in r["reduced_frequencies_hz"])
        + " Hz"
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--divisions", type=lambda t: _triple(t, int), default=(160, 25, 25))
    parser.add_argument(
        "--lengths", type=lambda t: _triple(t, float), default=(1.0, 0.16, 0.16), help="m"
    )
    parser.add_argument("--precision", default="auto", choices=("auto", "single", "double"))
    parser.add_argument("--no-exudyn", action="store_true", help="flexmbd only")
    parser.add_argument("--exudyn-iterations", type=int, default=40)
    parser.add_argument("--exudyn-json", type=Path, help="an Exudyn result saved before")
    parser.add_argument(
        "--save-exudyn", type=Path, help="write Exudyn's output (its JSON last) to this file"
    )
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.worker:
        print(json.dumps(flexmbd_worker(args.divisions, args.lengths, args.precision)))
        return 0

    division_text = ",".join(str(d) for d in args.divisions)
    length_text = ",".join(str(x) for x in args.lengths)
    print(f"tet4 bar {args.lengths} m, {args.divisions} cells, {EIGEN_MODES} + 6 modes")
    os.environ.setdefault("OPENBLAS_NUM_THREADS", str(os.cpu_count() or 1))
    ours = run_process(
        [
            str(Path(__file__).resolve()),
            "--worker",
            "--divisions",
            division_text,
            "--lengths",
            length_text,
            "--precision",
            args.precision,
        ]
    )
    print(f"{ours['nodes']} nodes, {ours['elements']} tet4")
    print_row("flexmbd", ours)

    theirs = None
    if args.exudyn_json is not None:
        theirs = json.loads(args.exudyn_json.read_text().strip().splitlines()[-1])
    elif not args.no_exudyn:
        if not exudyn_available():
            print("exudyn or ngsolve not installed: pip install exudyn ngsolve to compare")
        else:
            print("running Exudyn (FEMinterface + NGsolve); this takes a while ...")
            theirs = run_process(
                [
                    str(HERE / "exudyn_preprocess.py"),
                    "--divisions",
                    division_text,
                    "--lengths",
                    length_text,
                    "--eigen-iterations",
                    str(args.exudyn_iterations),
                ],
                args.save_exudyn,
            )
    if theirs is None:
        return 0
    print_row("Exudyn", theirs)
    ours_f = np.asarray(ours["reduced_frequencies_hz"])
    theirs_f = np.asarray(theirs["reduced_frequencies_hz"])
    print(
        f"time: flexmbd {theirs['total_seconds'] / ours['total_seconds']:.1f}x faster; "
        f"peak memory {ours['peak_rss_mib'] / theirs['peak_rss_mib']:.2f} of Exudyn's "
        f"(increments over the baselines: {ours['peak_rss_mib'] - ours['baseline_rss_mib']:.0f}"
        f" vs {theirs['peak_rss_mib'] - theirs['baseline_rss_mib']:.0f} MiB)"
    )
    print(
        "largest relative difference of the reduced frequencies: "
        f"{np.abs(ours_f / theirs_f - 1.0).max():.1e}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
