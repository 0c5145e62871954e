"""What a progress bar and the live logging of events cost a run.

`simulate(progress=True)`, or a logging handler on "flexmbd", asks the run for its new
records about ten times a second (for the step number and the events as they come): a copy
of those records into NumPy arrays. This script times the same runs without and with it,
records after every step (the most records to copy), best of 5:

    OPENBLAS_NUM_THREADS=1 python benchmarks/progress_overhead.py

Prints one row per model and setting: CPU time and the ratio to the plain run.
"""

from __future__ import annotations

import io
import logging
import time

import flexmbd as fm
from flexmbd.progress import SimulationProgress


def best(run, repeats: int = 5) -> float:
    """The least CPU time of the process over `repeats` runs (s): less noisy than the wall
    time on a shared machine; the run is single-threaded (OPENBLAS_NUM_THREADS=1)."""
    times = []
    for _ in range(repeats):
        start = time.process_time()
        run()
        times.append(time.process_time() - start)
    return min(times)


def main() -> None:
    cases = {
        "flexible slider-crank (65 coordinates)": (fm.examples.flexible_slider_crank(), 3.0),
        "four-bar N = 20 (287 coordinates)": (fm.examples.four_bar(20), 0.5),
    }
    print(f"{'model':40s} {'setting':28s} {'CPU (s)':>9s} {'ratio':>6s}")
    for name, (example, factor) in cases.items():
        measure(name, example, factor)


def measure(name: str, example: fm.examples.Example, factor: float) -> None:
    model = example.system.compile()
    end = example.end_time * factor

    def run(**options):
        return fm.simulate(
            model, end, example.step_size, solver=example.solver, output_interval=None, **options
        )

    plain = best(run)
    bar = best(lambda: run(progress=SimulationProgress(stream=io.StringIO(), style="lines")))
    log = logging.getLogger("flexmbd")
    handler = logging.StreamHandler(io.StringIO())
    log.addHandler(handler)
    try:
        logged = best(run)
    finally:
        log.removeHandler(handler)
    steps = run().statistics["steps"]
    print(f"{name:40s} {'plain':28s} {plain:9.3f} {1.0:6.3f}   ({steps} steps)")
    print(f"{'':40s} {'progress bar (lines)':28s} {bar:9.3f} {bar / plain:6.3f}")
    print(f"{'':40s} {'logging handler on flexmbd':28s} {logged:9.3f} {logged / plain:6.3f}")


if __name__ == "__main__":
    main()
