"""Cost of writing the results file during the run (issue 7): the flexible slider-crank (R4,
4189 steps of generalized-alpha) simulated with and without ``results_file``, recording every
step or every 1e-4 s; best of ``--repeat`` wall times of the whole ``simulate`` call (file
creation, the rod's body data, every flush and the final records included), and the file size.

    python benchmarks/results_file.py
    python benchmarks/results_file.py --repeat 5
    python benchmarks/results_file.py --two-links     # body data of two identical links

``--two-links``: a chain of two identical reduced links (a tet4 bar 1 x 0.1 x 0.1 m of
56 x 9 x 9 cells, 5,700 nodes, Craig-Bampton with the end faces as RBE2 interfaces, 6 + 10
modes; one ``FlexibleBodyData`` added twice) simulated for 10 steps with a results file: the
file size, the bytes of its ``flexible`` group (as stored, compression included) and the time
to create the file and read it back. Run it with an older checkout on ``PYTHONPATH`` to
compare layouts.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import flexmbd as fm


def two_links() -> None:
    import h5py
    import numpy as np

    from flexmbd.fe import Material, build_body, shapes

    mesh = shapes.box((1.0, 0.1, 0.1), (56, 9, 9), "tet4")
    body = build_body(
        mesh.nodes,
        mesh.elements,
        Material(7.0e10, 0.33, 2700.0),
        node_sets=mesh.node_sets,
        reference="interface",
        modes="craig-bampton",
        mode_count=10,
        interfaces=["x0", "x1"],
        interface_kind="rbe2",
    )
    system = fm.System(gravity=(0, -9.81, 0))
    links = [system.add_flexible_body(body, position=(x, 0, 0)) for x in (0.0, 1.0)]
    hinge = system.add_marker(system.ground, position=body.nodes[mesh.node_sets["x0"]].mean(0))
    system.add_revolute_joint(hinge, system.add_node_set_marker(links[0], "x0"))
    system.add_revolute_joint(
        system.add_node_set_marker(links[0], "x1"), system.add_node_set_marker(links[1], "x0")
    )
    model = system.compile()
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "links.h5"
        start = time.perf_counter()
        fm.simulate(model, 1e-2, 1e-3, results_file=path)
        written = time.perf_counter() - start
        start = time.perf_counter()
        fm.read_results(path)
        read = time.perf_counter() - start
        stored: dict[int, int] = {}  # HDF5 object -> bytes stored (a hard link counts once)
        with h5py.File(path, "r") as file:

            def visit(name: str, item: object) -> None:
                if isinstance(item, h5py.Dataset):
                    stored[hash(item.id)] = item.id.get_storage_size()

            file["flexible"].visititems(visit)
        size = os.path.getsize(path)
    nnz = body.stiffness.nnz + body.mass.nnz
    print(f"two links of {len(body.nodes)} nodes (K and M: {nnz} entries, {12 * nnz / 1e6:.1f} MB")
    print(
        f"  as float64 + int32 indices per link), flexmbd {fm.__version__}, numpy {np.__version__}"
    )
    print(
        f"  results file {size / 1e6:.2f} MB, body data stored {sum(stored.values()) / 1e6:.2f} MB"
    )
    print(f"  simulate with the file {written:.2f} s, read_results {read:.2f} s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--two-links", action="store_true", help="body data of two links")
    args = parser.parse_args()
    if args.two_links:
        two_links()
        return
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
