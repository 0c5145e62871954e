"""Time of interface weights and of the equilibrium start for a 108k-node body (issue 27).

The body is the one of ``preprocess_100k.py``: a steel bar 1 x 0.16 x 0.16 m, flexmbd's
structured tetrahedral box of 160 x 25 x 25 cells (108,836 nodes, 600,000 tet4), reduced by
Craig-Bampton (20 fixed-interface modes and the static modes of the averaged (RBE3)
interface x1, the body frame on the averaged motion of x0, both weighted by area). Printed:

- the interface weights: ``make_interface`` of the end face x0 (area weights over its
  facets), of the side face y0, and of the whole body (volume weights over 600,000 tet4);
- the preprocessing (for scale; mesh generation excluded);
- a hinged, driven cantilever of that body under gravity: ``System`` building with two
  node-set markers, ``fm.equilibrium`` (static), and a first run of 10 steps started from it;
- with ``--nodal``, the equilibrium of the same bar with nodal elastic coordinates (324,480
  of them, the face x0 clamped to the body frame): its elastic block is eliminated through
  the sparse Cholesky factor of the preprocessor (about a minute and 9 GB).

    python benchmarks/starting_states.py
    python benchmarks/starting_states.py --divisions 40,10,10   # a quick run
"""

from __future__ import annotations

import argparse
import os
import resource
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")


import flexmbd as fm  # noqa: E402
from flexmbd.fe import Material, build_body, shapes  # noqa: E402
from flexmbd.fe.interface import body_interface, make_interface  # noqa: E402


def timed(label: str, function, *args, **kwargs):
    start = time.perf_counter()
    value = function(*args, **kwargs)
    print(f"  {label}: {time.perf_counter() - start:.3f} s")
    return value


def cantilever(body) -> tuple[fm.Model, object]:
    system = fm.System(gravity=(0.0, -9.81, 0.0))
    bar = system.add_flexible_body(body, name="bar")
    root = system.add_node_set_marker(body=bar, nodes="x0", name="root")
    system.add_node_set_marker(body=bar, nodes="x1", name="tip")
    ground = system.add_marker(system.ground)
    system.add_revolute_joint(ground, root, name="hinge")
    system.add_angle_driver(ground, root, fm.Constant(0.0), name="drive")
    return system.compile(), bar


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--divisions", default="160,25,25")
    parser.add_argument(
        "--nodal", action="store_true", help="also the equilibrium of the nodal bar"
    )
    args = parser.parse_args()
    divisions = tuple(int(v) for v in args.divisions.split(","))
    lengths = (1.0, 0.16, 0.16)
    mesh = shapes.box(lengths, divisions, "tet4")
    tets = len(mesh.elements["tet4"])
    print(f"bar {lengths} m, {len(mesh.nodes):,} nodes, {tets:,} tet4")
    print("interface weights (make_interface):")
    for name in ("x0", "y0", "all"):
        interface = timed(
            f"{name} ({len(mesh.node_sets[name]):,} nodes)",
            make_interface,
            mesh.nodes,
            mesh.elements,
            mesh.node_sets[name],
            name=name,
        )
        centroid = interface.centroid
        print(f"    {interface.weighting}: measure {interface.measure:.6g}, centroid {centroid}")
    material = Material(2.1e11, 0.3, 7800.0)
    print("Craig-Bampton body:")
    body = timed(
        "build_body (20 modes, rbe3 interfaces x0, x1 by area)",
        build_body,
        mesh.nodes,
        mesh.elements,
        material,
        node_sets=mesh.node_sets,
        reference="interface",
        modes="craig-bampton",
        mode_count=20,
        interfaces=["x0", "x1"],
        interface_kind="rbe3",
    )
    model, bar = timed("System with two node-set markers, compiled", cantilever, body)
    eq = timed("fm.equilibrium (static)", fm.equilibrium, model)
    tip = body_interface(body, "x1")
    u = eq.node_displacements(bar)[tip.members]
    print(
        f"    {eq.iterations} iterations, residual {eq.residual:.1e}, deflection of the tip "
        f"face's centre {tip.average(u)[0]} m, static driving torque {eq.multipliers[-1]:.2f} N m"
    )
    result = timed(
        "10 steps from it (simulate, initial_state=eq)",
        fm.simulate,
        model,
        1e-2,
        1e-3,
        initial_state=eq,
    )
    print(f"    events {result.events}")
    if args.nodal:
        print("nodal body:")
        nodal = timed(
            "build_body (nodal, clamped at x0)",
            build_body,
            mesh.nodes,
            mesh.elements,
            material,
            node_sets=mesh.node_sets,
            reference="clamped",
            reference_nodes="x0",
        )
        model, bar = timed("System with two node-set markers, compiled", cantilever, nodal)
        eq = timed("fm.equilibrium (static)", fm.equilibrium, model)
        tip = body_interface(nodal, "x1")
        u = eq.node_displacements(bar)[tip.members]
        print(
            f"    {eq.iterations} iterations, residual {eq.residual:.1e}, deflection of the "
            f"tip face's centre {tip.average(u)[0]} m"
        )
        print(
            f"    peak memory {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MiB"
        )


if __name__ == "__main__":
    main()
