"""Exudyn side of the flexible-body preprocessing benchmark: time and peak memory.

The task is the one flexmbd's preprocessing does for a tet4 mesh: stiffness matrix K and mass
matrix M of linear elasticity, 20 Craig-Bampton (Hurty-Craig-Bampton) eigenmodes with both
interfaces clamped, the static modes of two rigid (RBE2) interfaces, and the reduced-order data of
a floating-frame body. The mesh is flexmbd's structured tetrahedral box
(``flexmbd.fe.shapes.box(lengths, divisions, "tet4")``, six tetrahedra per cell); the interfaces
are its end faces x = 0 and x = LX (node sets "x0" and "x1").

Exudyn (1.13.6) has no element matrices of its own: ``exudyn.FEM.FEMinterface`` takes K and M from
NGsolve or from Abaqus/Ansys files. So the mesh is handed to Netgen/NGsolve unchanged (same nodes
in the same order, the same tetrahedra; Netgen's tetrahedra are oriented the other way round, so
vertices 1 and 2 are swapped; the outer triangles are added as one boundary, Exudyn draws them)
and Exudyn's pipeline runs on it. Stages, each timed with ``time.perf_counter``:

``stiffness_mass``
    ``FEMinterface.ImportMeshFromNGsolve(mesh, density, youngsModulus, poissonsRatio,
    meshOrder=1, createBoundaryNodeSets=False)``: order-1 ``VectorH1`` space (linear tetrahedra,
    the same FE model as flexmbd's tet4), K and M assembled by NGsolve, converted to SciPy CSR in
    Exudyn's xyz-interleaved numbering, nodes and surface triangles copied. The boundary node sets
    are not created from the mesh (``createBoundaryNodeSets=False``) because the interface nodes
    are passed explicitly.
``craig_bampton``
    one of Exudyn's two Hurty-Craig-Bampton implementations, RBE2 interfaces, the first interface
    taken as the reference frame (the rigid-body motion is excluded, Exudyn's default), so the
    basis has 6 static + 20 eigenmodes:

    * ``--hcb ngsolve``: ``FEMinterface.ComputeHurtyCraigBamptonModesNGsolve(bfM, bfK,
      boundaryNodesList, nEigenModes)``: NGsolve's sparse Cholesky factorization of the interior
      block K_ii, static modes by one multi-vector solve, eigenmodes by NGsolve's preconditioned
      inverse iteration (PINVIT) with that factorization, ``maxEigensolveIterations`` of them;
    * ``--hcb scipy``: ``FEMinterface.ComputeHurtyCraigBamptonModes(boundaryNodesList,
      nEigenModes, useSparseSolver=True, computationMode=HCBstaticModeSelection.RBE2)``: ARPACK in
      shift-invert mode (``scipy.sparse.linalg.eigsh(sigma=0)``, SuperLU factorization of K_ii)
      and a second SuperLU factorization of K_ii for the static modes.
``reduced_order``
    ``exudyn.FEM.ObjectFFRFreducedOrderInterface(fem)``: reduced mass and stiffness matrices and
    the constant inertia terms (invariants) that ``ObjectFFRFreducedOrder`` needs.

The conversion of the mesh to Netgen's data structure stands in for reading a mesh file and is
reported apart (``mesh_conversion_seconds``), outside ``stages`` and ``total_seconds``.

Memory: ``resource.getrusage(RUSAGE_SELF).ru_maxrss`` (the process's high-water mark) after the
imports and the flexmbd mesh (``baseline_rss_mib``) and at the end (``peak_rss_mib``).

Checks: Exudyn's node coordinates are compared with the mesh's (Netgen keeps the order; a
permutation would be detected and mapped), the total mass (x-block sum of M and
``ObjectFFRFreducedOrderInterface.totalMass``) with rho times the mesh volume, and the eigenmodes
by their residual max ||K phi - lambda M phi|| / ||K phi|| over the interior DOFs
(``eigen_residual_max``, untimed).

NGsolve's threads: NGsolve's task manager (assembly, PINVIT) busy-waits on its worker threads; on
a 2-core machine with anything else running its parallel regions stall (one orthogonalization
in PINVIT took 3.6 s with 2 threads instead of 0.03 s with 1). ``--threads`` sets
``ngsolve.SetNumThreads`` (default 1); NGsolve's sparse Cholesky factorization is sequential in
either case, and SciPy's SuperLU is sequential.

Needs ``pip install exudyn ngsolve`` (NGsolve 6.2.2608 pulls netgen-mesher). Command line::

    python benchmarks/exudyn_preprocess.py --divisions 40,10,10
    python benchmarks/exudyn_preprocess.py                    # 160,25,25: 108,836 nodes
    python benchmarks/exudyn_preprocess.py --hcb scipy --threads 2

A human-readable summary is printed; the last line of the output is one JSON object with the
keys nodes, elements, stages, total_seconds, peak_rss_mib, baseline_rss_mib, frequencies_hz,
reduced_frequencies_hz, mode_count, mass, exudyn_version and variant (plus a few more).
"""

from __future__ import annotations

import argparse
import json
import resource
import sys
import time
from collections.abc import Sequence

import numpy as np

DEFAULT_DIVISIONS = (160, 25, 25)
DEFAULT_LENGTHS = (1.0, 0.16, 0.16)
#: number of Craig-Bampton eigenmodes (clamped interfaces)
EIGEN_MODES = 20


def _triple(text: str, kind: type) -> tuple:
    values = tuple(kind(part) for part in text.split(","))
    if len(values) != 3:
        raise argparse.ArgumentTypeError(f"three comma-separated values expected, got {text!r}")
    return values


def _rss_mib() -> float:
    """High-water mark of the resident set size so far (ru_maxrss is in KiB on Linux)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _tet_volumes(nodes: np.ndarray, tets: np.ndarray) -> np.ndarray:
    x0 = nodes[tets[:, 0]]
    a, b, c = (nodes[tets[:, k]] - x0 for k in (1, 2, 3))
    return np.einsum("ij,ij->i", a, np.cross(b, c)) / 6.0


def boundary_triangles(tets: np.ndarray, node_count: int) -> np.ndarray:
    """Faces that belong to one tetrahedron only, oriented outward for positive tetrahedra."""
    faces = np.concatenate(
        [tets[:, [1, 2, 3]], tets[:, [0, 3, 2]], tets[:, [0, 1, 3]], tets[:, [0, 2, 1]]]
    )
    s = np.sort(faces, axis=1).astype(np.int64)
    keys = (s[:, 0] * node_count + s[:, 1]) * node_count + s[:, 2]
    _, first, counts = np.unique(keys, return_index=True, return_counts=True)
    return faces[first[counts == 1]]


def to_ngsolve_mesh(nodes: np.ndarray, tets: np.ndarray):
    """An NGsolve mesh with exactly these nodes (same order) and tetrahedra."""
    import netgen.meshing as ngm
    import ngsolve

    mesh = ngm.Mesh(dim=3)
    mesh.AddPoints(np.ascontiguousarray(nodes, dtype=np.float64))
    face = mesh.Add(ngm.FaceDescriptor(bc=1, domin=1, domout=0, surfnr=1))
    # Netgen's tetrahedra have negative volume in the usual convention: swap vertices 1 and 2
    netgen_tets = np.ascontiguousarray(tets[:, [0, 2, 1, 3]], dtype=np.int32)
    mesh.AddElements(dim=3, index=1, data=netgen_tets, base=0)
    surface = boundary_triangles(tets, len(nodes))
    mesh.AddElements(dim=2, index=face, data=np.ascontiguousarray(surface, dtype=np.int32), base=0)
    return ngsolve.Mesh(mesh)


def node_permutation(reference: np.ndarray, imported: np.ndarray) -> np.ndarray:
    """perm with imported[perm[i]] == reference[i]; the identity when the order is kept."""
    if reference.shape != imported.shape:
        raise RuntimeError(f"Exudyn has {len(imported)} nodes, the mesh {len(reference)}")
    if np.array_equal(reference, imported):
        return np.arange(len(reference))
    scale = np.abs(reference).max()
    ref_order = np.lexsort(np.round(reference / scale, 9).T[::-1])
    imp_order = np.lexsort(np.round(imported / scale, 9).T[::-1])
    perm = np.empty(len(reference), dtype=np.int64)
    perm[ref_order] = imp_order
    if np.abs(imported[perm] - reference).max() > 1e-9 * scale:
        raise RuntimeError("Exudyn's nodes are not a permutation of the mesh nodes")
    return perm


def eigen_residual(fem, boundary_nodes: Sequence[np.ndarray], count: int) -> float:
    """Largest ||K phi - lambda M phi|| / ||K phi|| over the interior DOFs of the last `count`
    modes of Exudyn's basis (the clamped-interface eigenmodes), lambda the Rayleigh quotient."""
    stiffness = fem.GetStiffnessMatrix(sparse=True)
    mass = fem.GetMassMatrix(sparse=True)
    modes = fem.modeBasis["matrix"][:, -count:]
    fixed = np.concatenate([3 * np.asarray(b)[:, None] + np.arange(3) for b in boundary_nodes])
    interior = np.setdiff1d(np.arange(stiffness.shape[0]), fixed.ravel())
    k_modes = stiffness @ modes
    m_modes = mass @ modes
    rayleigh = np.einsum("ij,ij->j", modes, k_modes) / np.einsum("ij,ij->j", modes, m_modes)
    residual = (k_modes - m_modes * rayleigh)[interior]
    return float(
        (np.linalg.norm(residual, axis=0) / np.linalg.norm(k_modes[interior], axis=0)).max()
    )


def reduced_body_frequencies(fem) -> np.ndarray:
    """Frequencies (Hz) of the reduced body with its reference interface held: the eigenvalues
    of the Craig-Bampton-reduced stiffness and mass matrices (untimed)."""
    import scipy.linalg

    basis = np.asarray(fem.modeBasis["matrix"], dtype=float)
    k = basis.T @ (fem.GetStiffnessMatrix(sparse=True) @ basis)
    m = basis.T @ (fem.GetMassMatrix(sparse=True) @ basis)
    values = scipy.linalg.eigh(0.5 * (k + k.T), 0.5 * (m + m.T), eigvals_only=True)
    return np.sqrt(np.clip(values, 0.0, None)) / (2.0 * np.pi)


def run(
    divisions: Sequence[int],
    lengths: Sequence[float],
    *,
    youngs_modulus: float = 2.1e11,
    poissons_ratio: float = 0.3,
    density: float = 7800.0,
    hcb: str = "ngsolve",
    threads: int = 1,
    eigen_iterations: int = 40,
    log=print,
) -> dict:
    """Builds the mesh, runs Exudyn's pipeline on it and returns the figures."""
    import exudyn
    import ngsolve
    from exudyn.FEM import FEMinterface, HCBstaticModeSelection, ObjectFFRFreducedOrderInterface

    from flexmbd.fe import shapes

    mesh = shapes.box(lengths, divisions, "tet4")
    nodes = np.asarray(mesh.nodes, dtype=float)
    tets = np.asarray(mesh.elements["tet4"], dtype=np.int64)
    interfaces = [np.asarray(mesh.node_sets[name], dtype=np.int64) for name in ("x0", "x1")]
    volume = float(_tet_volumes(nodes, tets).sum())
    baseline = _rss_mib()
    ngsolve.SetNumThreads(threads)
    log(f"mesh: {len(nodes)} nodes, {len(tets)} tet4, interfaces {[len(i) for i in interfaces]}")

    start = time.perf_counter()
    ng_mesh = to_ngsolve_mesh(nodes, tets)
    conversion = time.perf_counter() - start
    log(f"mesh -> NGsolve: {conversion:.2f} s ({ng_mesh.nv} vertices, {ng_mesh.ne} elements)")

    stages: dict[str, float] = {}
    fem = FEMinterface()
    start = time.perf_counter()
    bf_mass, bf_stiffness, _ = fem.ImportMeshFromNGsolve(
        ng_mesh,
        density=density,
        youngsModulus=youngs_modulus,
        poissonsRatio=poissons_ratio,
        meshOrder=1,
        createBoundaryNodeSets=False,
    )
    stages["stiffness_mass"] = time.perf_counter() - start
    log(f"K, M (ImportMeshFromNGsolve): {stages['stiffness_mass']:.2f} s")

    perm = node_permutation(nodes, fem.GetNodePositionsAsArray())
    boundary_nodes = [perm[i] for i in interfaces]
    mass_matrix = fem.GetMassMatrix(sparse=True)
    assembled_mass = float(mass_matrix[0::3, :][:, 0::3].sum())
    expected_mass = density * volume
    if abs(assembled_mass - expected_mass) > 1e-9 * expected_mass:
        raise RuntimeError(f"assembled mass {assembled_mass} != rho * volume {expected_mass}")

    start = time.perf_counter()
    if hcb == "ngsolve":
        fem.ComputeHurtyCraigBamptonModesNGsolve(
            bf_mass,
            bf_stiffness,
            boundaryNodesList=boundary_nodes,
            nEigenModes=EIGEN_MODES,
            maxEigensolveIterations=eigen_iterations,
        )
        hcb_call = (
            "ComputeHurtyCraigBamptonModesNGsolve(sparsecholesky, PINVIT, "
            f"maxEigensolveIterations={eigen_iterations})"
        )
    else:
        fem.ComputeHurtyCraigBamptonModes(
            boundaryNodesList=boundary_nodes,
            nEigenModes=EIGEN_MODES,
            useSparseSolver=True,
            computationMode=HCBstaticModeSelection.RBE2,
            excludeRigidBodyMotion=True,
        )
        hcb_call = "ComputeHurtyCraigBamptonModes(useSparseSolver=True, RBE2; eigsh + SuperLU)"
    stages["craig_bampton"] = time.perf_counter() - start
    frequencies = np.sort(np.asarray(fem.GetEigenFrequenciesHz(), dtype=float))
    mode_count = int(fem.modeBasis["matrix"].shape[1])
    residual = eigen_residual(fem, boundary_nodes, EIGEN_MODES)
    log(f"Craig-Bampton modes ({hcb}): {stages['craig_bampton']:.2f} s, {mode_count} modes")

    start = time.perf_counter()
    reduced = ObjectFFRFreducedOrderInterface(fem)
    stages["reduced_order"] = time.perf_counter() - start
    log(f"ObjectFFRFreducedOrderInterface: {stages['reduced_order']:.2f} s")
    if reduced.nModes != mode_count:
        raise RuntimeError(f"reduced-order object has {reduced.nModes} modes, not {mode_count}")

    total = sum(stages.values())
    peak = _rss_mib()
    reduced_frequencies = reduced_body_frequencies(fem)
    variant = (
        f"ImportMeshFromNGsolve(meshOrder=1, createBoundaryNodeSets=False) + {hcb_call} + "
        "ObjectFFRFreducedOrderInterface(RotationEulerParameters); "
        f"NGsolve {ngsolve.__version__}, SetNumThreads({threads})"
    )
    return {
        "nodes": len(nodes),
        "elements": len(tets),
        "stages": stages,
        "total_seconds": total,
        "peak_rss_mib": peak,
        "baseline_rss_mib": baseline,
        "frequencies_hz": frequencies[:5].tolist(),
        "all_frequencies_hz": frequencies.tolist(),
        "reduced_frequencies_hz": reduced_frequencies[:5].tolist(),
        "eigen_residual_max": residual,
        "mode_count": mode_count,
        "mass": float(reduced.totalMass),
        "exudyn_version": exudyn.__version__,
        "variant": variant,
        "mesh_conversion_seconds": conversion,
        "expected_mass": expected_mass,
        "assembled_mass": assembled_mass,
        "hcb": hcb,
        "threads": threads,
    }


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--divisions", type=lambda s: _triple(s, int), default=DEFAULT_DIVISIONS, metavar="NX,NY,NZ"
    )
    parser.add_argument(
        "--lengths", type=lambda s: _triple(s, float), default=DEFAULT_LENGTHS, metavar="LX,LY,LZ"
    )
    parser.add_argument("--youngs-modulus", type=float, default=2.1e11, help="Pa")
    parser.add_argument("--poissons-ratio", type=float, default=0.3)
    parser.add_argument("--density", type=float, default=7800.0, help="kg/m^3")
    parser.add_argument(
        "--hcb",
        choices=("ngsolve", "scipy"),
        default="ngsolve",
        help="Exudyn's Craig-Bampton implementation (default: ngsolve, the faster one)",
    )
    parser.add_argument("--threads", type=int, default=1, help="ngsolve.SetNumThreads")
    parser.add_argument(
        "--eigen-iterations",
        type=int,
        default=40,
        help="maxEigensolveIterations of the NGsolve variant (Exudyn's default 40)",
    )
    args = parser.parse_args(argv)

    result = run(
        args.divisions,
        args.lengths,
        youngs_modulus=args.youngs_modulus,
        poissons_ratio=args.poissons_ratio,
        density=args.density,
        hcb=args.hcb,
        threads=args.threads,
        eigen_iterations=args.eigen_iterations,
    )
    print()
    print(f"Exudyn {result['exudyn_version']} preprocessing, {result['variant']}")
    print(f"  mesh            {result['nodes']} nodes, {result['elements']} tet4")
    print(f"  mesh conversion {result['mesh_conversion_seconds']:9.2f} s (not in the total)")
    for name, seconds in result["stages"].items():
        print(f"  {name:15s} {seconds:9.2f} s")
    print(f"  total           {result['total_seconds']:9.2f} s")
    increment = result["peak_rss_mib"] - result["baseline_rss_mib"]
    print(
        f"  peak RSS        {result['peak_rss_mib']:9.1f} MiB "
        f"(baseline {result['baseline_rss_mib']:.1f} MiB, +{increment:.1f} MiB)"
    )
    print(f"  modes           {result['mode_count']} (6 static + {EIGEN_MODES} eigen)")
    print("  frequencies     " + ", ".join(f"{f:.2f}" for f in result["frequencies_hz"]) + " Hz")
    print(
        "  reduced body    "
        + ", ".join(f"{f:.2f}" for f in result["reduced_frequencies_hz"])
        + " Hz (reference interface held)"
    )
    print(
        f"  eigen residual  {result['eigen_residual_max']:.2e} "
        "(max ||K phi - lambda M phi|| / ||K phi||, interior DOFs)"
    )
    print(f"  mass            {result['mass']:.6f} kg (rho * V = {result['expected_mass']:.6f})")
    sys.stdout.flush()
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
