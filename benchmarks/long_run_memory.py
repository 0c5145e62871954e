"""Memory of a long run whose records go only to its results file (issue 28).

The IFToMM A01 pendulum (a point mass on a distance constraint, generalized-alpha) runs
``--steps`` steps (default 10 million) of ``--step`` seconds with a record after every step,
written to a results file during the run with ``keep_in_memory=False``. The script prints the
process's resident memory (RSS, from /proc/self/status) at the start of the run and every
``--every`` seconds of wall time, its largest growth, and the file's record count and size at
the end. With ``--keep`` the records also stay in memory (the default of the Python API), for
comparison.

    python benchmarks/long_run_memory.py                        # 10 million steps
    python benchmarks/long_run_memory.py --steps 1000000 --keep
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import flexmbd as fm  # noqa: E402
from flexmbd.results_file import read_results_metadata  # noqa: E402


def rss_mib() -> float:
    with open("/proc/self/status", encoding="ascii") as status:
        for line in status:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    return float("nan")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=10_000_000)
    parser.add_argument("--step", type=float, default=1e-4)
    parser.add_argument("--every", type=float, default=10.0, help="seconds between samples")
    parser.add_argument("--keep", action="store_true", help="keep the records in memory too")
    parser.add_argument("--folder", help="folder of the results file (default: a temporary one)")
    args = parser.parse_args()
    example = fm.examples.pendulum()
    model = example.system.compile()
    end = args.steps * args.step
    folder = Path(args.folder or tempfile.mkdtemp())
    path = folder / "long_run.h5"
    samples: list[tuple[float, float, float]] = []
    began = time.perf_counter()
    start_rss = rss_mib()
    print(
        f"{args.steps:,} steps of {args.step:g} s, a record every step, keep_in_memory={args.keep}"
    )
    print(f"  RSS at the start {start_rss:.1f} MiB")

    def progress(t: float, h: float, iterations: int) -> None:
        now = time.perf_counter() - began
        if not samples or now - samples[-1][0] >= args.every:
            samples.append((now, t, rss_mib()))
            print(f"  {now:7.1f} s wall, t = {t:10.3f} s: RSS {samples[-1][2]:.1f} MiB", flush=True)

    result = fm.simulate(
        model,
        end,
        args.step,
        solver=fm.GeneralizedAlpha(),
        results_file=path,
        keep_in_memory=args.keep,
        progress=progress,
    )
    elapsed = time.perf_counter() - began
    end_rss = rss_mib()
    peak = max([end_rss, *(s[2] for s in samples)])
    header = read_results_metadata(path)
    print(
        f"  done in {elapsed:.1f} s ({result.statistics['steps'] / elapsed:,.0f} steps/s): RSS at "
        f"the end {end_rss:.1f} MiB, largest {peak:.1f} MiB, growth {peak - start_rss:+.1f} MiB"
    )
    print(
        f"  file {path}: {header['records']:,} records, {path.stat().st_size / 2**20:.0f} MiB; "
        f"{len(result):,} records held by the returned Result"
    )
    if not args.folder:
        path.unlink()


if __name__ == "__main__":
    main()
