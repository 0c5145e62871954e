"""A 64-case study of the flexible slider-crank (rod diameter x crank speed, 8 x 8, the
example's two crank turns at 150 rad/s each, or --turns) on a Dask LocalCluster of 1 and of 2
worker processes: the wall time, the speed-up, the overhead per case over the bare simulation
(the same 64 runs in this process, without results files), the cluster's start and the peak
memory of a worker.

    python benchmarks/study_sweep.py [--cases-per-side 8] [--folder /tmp/flexmbd-study-bench]
        [--turns 2] [--repeat 3]

With --repeat N each measurement (the bare runs, the cluster's start, each sweep) is made N
times and the shortest counts (the machine's noise is larger than the margins).
"""

from __future__ import annotations

import argparse
import json
import shutil
import time
from pathlib import Path

import numpy as np

import flexmbd as fm


def parameters(side: int) -> dict[str, list[float]]:
    return {
        "rod_diameter": list(np.linspace(5e-3, 8e-3, side)),
        "crank_speed": list(np.linspace(100.0, 150.0, side)),
    }


def bare(side: int, end_time: float) -> float:
    """The sum of the simulations' times, run here one after the other."""
    total = 0.0
    for d in parameters(side)["rod_diameter"]:
        for w in parameters(side)["crank_speed"]:
            example = fm.examples.flexible_slider_crank(rod_diameter=d, crank_speed=w)
            model = example.system.compile()
            started = time.perf_counter()
            fm.simulate(
                model,
                end_time,
                example.step_size,
                output_interval=example.output_interval,
                solver=example.solver,
            )
            total += time.perf_counter() - started
    return total


def study_run(side: int, end_time: float, workers: int, folder: Path) -> dict[str, float]:
    shutil.rmtree(folder, ignore_errors=True)
    study = fm.Study(
        fm.examples.flexible_slider_crank,
        parameters(side),
        outputs={"deflection": "max-abs(deflection:rod:5[y])"},
        folder=folder,
        end_time=end_time,
    )
    started = time.perf_counter()
    data = study.run(workers=workers, progress=False)
    wall = time.perf_counter() - started
    summaries = [json.loads(p.read_text()) for p in (folder / "cases").glob("*.json")]
    assert all(s["status"] == "complete" for s in summaries), "a case failed"
    return {
        "wall": wall,
        "case_time": float(np.sum(data["elapsed"].values)),
        "peak_memory_mb": max(s["worker_peak_memory"] for s in summaries) / 2**20,
    }


def cluster_start(workers: int) -> float:
    """Seconds to start the study's own local cluster of `workers` processes (its settings:
    quiet workers, flexmbd preloaded) and connect to it."""
    from flexmbd.study import _connect

    started = time.perf_counter()
    client, cluster = _connect(None, workers)
    ready = time.perf_counter() - started
    client.close()
    cluster.close()
    return ready


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--cases-per-side", type=int, default=8)
    parser.add_argument("--folder", default="/tmp/flexmbd-study-bench")
    parser.add_argument("--turns", type=float, default=2.0, help="crank turns at 150 rad/s")
    parser.add_argument(
        "--repeat", type=int, default=1, help="runs of each; the shortest wall time counts"
    )
    args = parser.parse_args()
    side = args.cases_per_side
    cases = side * side
    end_time = args.turns * 2 * np.pi / 150.0
    folder = Path(args.folder)
    simulations = min(bare(side, end_time) for _ in range(args.repeat))
    print(
        f"{cases} cases, {end_time:.4f} s each; bare simulations: {simulations:.2f} s in all, "
        f"{1e3 * simulations / cases:.1f} ms per case (best of {args.repeat})"
    )
    runs, starts = {}, {}
    for workers in (1, 2):
        starts[workers] = start = min(cluster_start(workers) for _ in range(args.repeat))
        attempts = [
            study_run(side, end_time, workers, folder / f"w{workers}") for _ in range(args.repeat)
        ]
        runs[workers] = run = min(attempts, key=lambda a: a["wall"])
        overhead = (run["wall"] - start) * workers / cases - simulations / cases
        print(
            f"{workers} worker(s): wall {run['wall']:.2f} s (cluster start {start:.2f} s), "
            f"case time {run['case_time']:.2f} s, overhead per case over the bare simulation "
            f"{1e3 * overhead:.1f} ms, worker peak memory {run['peak_memory_mb']:.0f} MB"
        )
    print(
        f"speed-up 2 workers over 1: {runs[1]['wall'] / runs[2]['wall']:.2f} (the sweep's wall "
        f"times, the cluster's start included); without the start: "
        f"{(runs[1]['wall'] - starts[1]) / (runs[2]['wall'] - starts[2]):.2f}"
    )
    shutil.rmtree(folder, ignore_errors=True)


if __name__ == "__main__":
    main()
