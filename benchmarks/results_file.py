"""Cost of writing the results file during the run (issue 7): the flexible slider-crank (R4,
4189 steps of generalized-alpha) simulated with and without ``results_file``, recording every
step or every 1e-4 s; best of ``--repeat`` wall times of the whole ``simulate`` call (file
creation, the rod's body data, every flush and the final records included), and the file size.

    python benchmarks/results_file.py
    python benchmarks/results_file.py --repeat 5
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import flexmbd as fm


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    example = fm.examples.flexible_slider_crank()
    model = example.system.compile()
    print("| records | without a file | with a file | overhead | file size |")
    print("|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "crank.h5"
        for interval in (None, example.output_interval):
            walls = {}
            for target in (None, path):
                best = float("inf")
                for _ in range(args.repeat):
                    start = time.perf_counter()
                    result = fm.simulate(
                        model,
                        example.end_time,
                        example.step_size,
                        output_interval=interval,
                        solver=example.solver,
                        results_file=target,
                    )
                    best = min(best, time.perf_counter() - start)
                walls[target] = best
            overhead = walls[path] / walls[None] - 1
            size = os.path.getsize(path) / 1e6
            print(
                f"| {len(result)} | {walls[None]:.3f} s | {walls[path]:.3f} s | "
                f"{100 * overhead:.0f} % | {size:.1f} MB |"
            )


if __name__ == "__main__":
    main()
