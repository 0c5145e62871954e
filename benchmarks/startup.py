"""Whole-process times: what a user waits for from the shell prompt (issue 34).

Each case runs in a fresh interpreter, once to warm up and then ``repeat`` times; the script
prints the best and the median wall time of the whole process (interpreter start, imports,
work, exit), measured around ``subprocess.run``. As in an installed package, the modules'
bytecode is cached (in a temporary ``PYTHONPYCACHEPREFIX``; ``PYTHONDONTWRITEBYTECODE`` is
removed from the children's environment: with it, every run compiles every module again).

``python -c pass``
    the interpreter alone (the floor of every other figure);
``import flexmbd``
    ``python -c "import flexmbd"``;
``flexmbd --help``
    ``python -m flexmbd --help``;
``import exudyn``
    the same for Exudyn (if it is installed);
``pendulum flexmbd`` / ``pendulum exudyn``
    a small reduced pendulum from mesh to result, the model of ``flexible_dynamics.py`` /
    ``exudyn_flexible.py`` (``flexible_models.pendulum()``): the 656-node tet4 bar meshed
    (``fe.shapes.box``), its K and M, Craig-Bampton reduction (6 static + 10 modes), the
    hinged bar built and integrated over 1 s with h = 1e-3 (generalized-alpha; Exudyn: its
    default configuration of ``exudyn_flexible.py``, ``ObjectFFRFreducedOrder``), records
    every 0.01 s. Exudyn has no element matrices of its own (``FEMinterface`` takes them
    from NGsolve, which is not installed here, or from files), so its process computes the
    mesh, K, M and the modes with flexmbd's preprocessor, as ``exudyn_flexible.py`` does:
    both processes do the same preprocessing and differ in imports, model building and
    simulation.

    python benchmarks/startup.py              # all cases, 5 runs each
    python benchmarks/startup.py --repeat 10
    python benchmarks/startup.py --case pendulum-flexmbd   # one case, in this process
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent


def pendulum_flexmbd() -> None:
    """The reduced pendulum in flexmbd, from mesh to result (prints the tip's final y)."""
    import flexible_dynamics
    import flexible_models

    import flexmbd as fm

    model = flexible_models.pendulum()
    system, items = flexible_dynamics.build_pendulum(model)
    step, end = flexible_dynamics.RUNS["pendulum"]
    result = fm.simulate(system, end, step, output_interval=0.01)
    tip = flexible_dynamics.face_centroid(result, items["body"], model, items["tip face"])
    print(f"flexmbd: {len(result)} records, tip y at {result.time[-1]:g} s: {tip[-1, 1]:.6f} m")


def pendulum_exudyn() -> None:
    """The same pendulum in Exudyn (K, M and modes from flexmbd's preprocessor)."""
    import exudyn_flexible

    config = exudyn_flexible.DEFAULT_CONFIGS["pendulum"][0]
    result = exudyn_flexible.run_in_process("pendulum", None, config)
    tip = result["outputs"]["x1_centroid"]
    print(f"exudyn: {result['steps']} steps, tip y at the end: {tip[-1][-2]:.6f} m")


CASES = {"pendulum-flexmbd": pendulum_flexmbd, "pendulum-exudyn": pendulum_exudyn}


def commands() -> dict[str, list[str]]:
    python = sys.executable
    table = {
        "python -c pass": [python, "-c", "pass"],
        "import flexmbd": [python, "-c", "import flexmbd"],
        "flexmbd --help": [python, "-m", "flexmbd", "--help"],
    }
    exudyn = subprocess.run([python, "-c", "import exudyn"], capture_output=True).returncode == 0
    if exudyn:
        table["import exudyn"] = [python, "-c", "import exudyn"]
    table["pendulum flexmbd"] = [python, str(Path(__file__)), "--case", "pendulum-flexmbd"]
    if exudyn:
        table["pendulum exudyn"] = [python, str(Path(__file__)), "--case", "pendulum-exudyn"]
    return table


def whole_process(command: list[str], repeat: int, cache: str) -> tuple[list[float], str]:
    """Wall times of `repeat` runs of `command` after a warm-up run, and the last line it
    printed; bytecode cached under `cache`."""
    env = {**os.environ, "OPENBLAS_NUM_THREADS": os.environ.get("OPENBLAS_NUM_THREADS", "1")}
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    env["PYTHONPYCACHEPREFIX"] = cache
    times, line = [], ""
    for _ in range(repeat + 1):
        start = time.perf_counter()
        run = subprocess.run(command, capture_output=True, text=True, env=env, cwd=HERE)
        times.append(time.perf_counter() - start)
        if run.returncode != 0:
            raise SystemExit(f"{' '.join(command)} failed:\n{run.stderr}")
        line = (run.stdout.strip().splitlines() or [""])[-1]
    return times[1:], line


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--repeat", type=int, default=5, help="runs per case (default 5)")
    parser.add_argument("--case", choices=sorted(CASES), help="run one case in this process")
    args = parser.parse_args(argv)
    if args.case:
        CASES[args.case]()
        return 0
    print(f"whole-process wall time, {args.repeat} runs each (s)")
    print(f"{'case':18s} {'best':>6s} {'median':>7s}  output")
    with tempfile.TemporaryDirectory() as cache:
        for name, command in commands().items():
            times, line = whole_process(command, args.repeat, cache)
            shown = "" if name.startswith(("python", "import", "flexmbd")) else line
            print(f"{name:18s} {min(times):6.3f} {statistics.median(times):7.3f}  {shown}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
