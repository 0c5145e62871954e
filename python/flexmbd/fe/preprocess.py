"""The preprocessor (seed section 3, "computational strategy"): from a mesh and a material to
the constant data of a deformable body: nodal stiffness and mass (assembled in Rust through
the connectivity, seed eq. 9), invariants of motion (seed eqs. 16-17), reference conditions
(the matrix B of seed eq. 9), modal reduction and the modal form of the invariants (eq. 18).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from numpy.typing import ArrayLike, NDArray

from .. import _core
from ..errors import InvalidModelError, InvalidParameterError
from .body import FlexibleBodyData

Material = _core.Material
Section = _core.Section


def _beam_theory(name: str) -> bool:
    if name not in ("euler-bernoulli", "timoshenko"):
        raise InvalidParameterError(
            f"beam_theory must be 'euler-bernoulli' or 'timoshenko', got {name!r}"
        )
    return name == "timoshenko"


def _csc(parts: tuple) -> sp.csc_matrix:
    data, indices, indptr, shape = parts
    return sp.csc_matrix((data, indices, indptr), shape=shape)


@dataclass
class NodalBody:
    """Nodal matrices and invariants of a body before reference conditions.

    ``i_kl`` is a 3 x 3 nested list of sparse (n, n) matrices; for bodies of solid elements
    they are M_s (x) e_k e_l^T of the scalar mass matrix M_s (``scalar_mass``)."""

    dofs_per_node: int
    stiffness: sp.csc_matrix
    mass: sp.csc_matrix
    invariants: dict[str, Any]
    scalar_mass: sp.csc_matrix | None


def straight_beam(
    length: float,
    elements: int,
    *,
    start: ArrayLike = (0.0, 0.0, 0.0),
    direction: ArrayLike = (1.0, 0.0, 0.0),
) -> tuple[NDArray[np.float64], dict[str, NDArray[np.int64]]]:
    """Nodes and "beam2" connectivity of a straight beam of `elements` equal elements."""
    if elements < 1 or not length > 0:
        raise InvalidParameterError(
            f"a beam needs length > 0 and at least one element, got {length}, {elements}"
        )
    d = np.asarray(direction, dtype=float)
    d = d / np.linalg.norm(d)
    s = np.linspace(0.0, length, elements + 1)
    nodes = np.asarray(start, dtype=float)[None, :] + s[:, None] * d[None, :]
    conn = np.column_stack([np.arange(elements), np.arange(1, elements + 1)]).astype(np.int64)
    return nodes, {"beam2": conn}


def assemble(
    nodes: ArrayLike,
    elements: Mapping[str, ArrayLike],
    material: Material,
    *,
    section: Section | None = None,
    orientation: ArrayLike | None = None,
    mass: str = "consistent",
    beam_theory: str = "euler-bernoulli",
    node_ids: ArrayLike | None = None,
    element_ids: Mapping[str, ArrayLike] | None = None,
) -> NodalBody:
    """Assembles K_ff, M_ff and the nodal invariants (Rust kernels, see `docs/preprocessor.md`).

    `elements` maps an element type ("beam2", "tet4", "tet10" in Gmsh node order, "hex8") to
    its connectivity (n_e, nodes) of 0-based node indices. `mass` is "consistent" or "lumped";
    `beam_theory` "euler-bernoulli" or "timoshenko" (shear-deformable beams)."""
    if mass not in ("consistent", "lumped"):
        raise InvalidParameterError(f"mass must be 'consistent' or 'lumped', got {mass!r}")
    shear = _beam_theory(beam_theory)
    nodes = np.ascontiguousarray(nodes, dtype=float)
    ids = np.arange(1, len(nodes) + 1) if node_ids is None else np.asarray(node_ids)
    blocks = {}
    offset = 1
    for kind, conn in elements.items():
        conn = np.ascontiguousarray(conn, dtype=np.int64)
        if conn.ndim != 2:
            raise InvalidParameterError(f"{kind} connectivity must be a 2D array")
        if element_ids is not None and kind in element_ids:
            eids = np.asarray(element_ids[kind], dtype=np.int64)
        else:
            eids = np.arange(offset, offset + len(conn), dtype=np.int64)
        offset += len(conn)
        blocks[kind] = (conn, np.ascontiguousarray(eids))
    raw = _core.assemble_body(
        nodes,
        np.ascontiguousarray(ids, dtype=np.int64),
        blocks,
        material,
        section,
        None if orientation is None else list(np.asarray(orientation, dtype=float)),
        mass == "lumped",
        shear,
    )
    n = raw["i1"].shape[1]
    if "i_kl_scalar" in raw:
        ms = _csc(raw["i_kl_scalar"])
        unit = [
            [sp.csc_matrix(([1.0], ([k], [j])), shape=(3, 3)) for j in range(3)] for k in range(3)
        ]
        i_kl = [[sp.kron(ms, unit[k][j], format="csc") for j in range(3)] for k in range(3)]
    else:
        ms = None
        i_kl = [[_csc(raw["i_kl"][3 * k + j]) for j in range(3)] for k in range(3)]
    invariants = {
        "mass": float(raw["mass_total"]),
        "first_moment": np.asarray(raw["first_moment"]),
        "second_moment": np.asarray(raw["second_moment"]),
        "i1": np.asarray(raw["i1"]).reshape(3, n),
        "ibar": np.asarray(raw["ibar"]).reshape(3, 3, n),
        "i_kl": i_kl,
    }
    return NodalBody(
        dofs_per_node=int(raw["dofs_per_node"]),
        stiffness=_csc(raw["stiffness"]),
        mass=_csc(raw["mass"]),
        invariants=invariants,
        scalar_mass=ms,
    )


def mass_points(
    nodes: ArrayLike,
    elements: Mapping[str, ArrayLike],
    material: Material,
    *,
    section: Section | None = None,
    orientation: ArrayLike | None = None,
    mass: str = "consistent",
    beam_theory: str = "euler-bernoulli",
) -> tuple[NDArray[np.float64], NDArray[np.float64], sp.csr_matrix]:
    """The body's mass points: weights rho dV (P,), undeformed positions (P, 3), and the shape
    matrices stacked as a sparse (3 P, n_dofs) matrix (rows 3p..3p+3: S of point p). The
    invariants are sums over them; they serve brute-force checks."""
    nodes = np.ascontiguousarray(nodes, dtype=float)
    blocks = {
        kind: (
            np.ascontiguousarray(conn, dtype=np.int64),
            np.arange(1, len(conn) + 1, dtype=np.int64),
        )
        for kind, conn in elements.items()
    }
    weights, positions, shape = _core.body_mass_points(
        nodes,
        np.arange(1, len(nodes) + 1, dtype=np.int64),
        blocks,
        material,
        section,
        None if orientation is None else list(np.asarray(orientation, dtype=float)),
        mass == "lumped",
        _beam_theory(beam_theory),
    )
    data, indices, indptr, dims = shape
    return weights, positions, sp.csr_matrix((data, indices, indptr), shape=dims)


# Reference conditions -------------------------------------------------------------------------


def reference_dofs(
    kind: str,
    node_count: int,
    dofs_per_node: int,
    nodes: Sequence[int] = (),
) -> NDArray[np.int64]:
    """Nodal coordinates kept by the reference conditions (the columns of the Boolean matrix B
    of seed eq. 9):

    - "none" or "mean-axis": all (for mean-axis frames the elastic coordinates must be free-free
      modes, which are mass-orthogonal to the rigid motions: the Tisserand conditions);
    - "clamped": all but those of `nodes`: the body frame is rigidly attached to them (for
      beams: their position and slopes);
    - "3-2-1": `nodes` = (a, b, c) keep a fixed (3), b without y and z displacement (2), c
      without z displacement (1): the body frame has its origin at a, its x axis through b and
      its x-y plane through c, if b lies on the x axis of a and c in its x-y plane.
    """
    d = dofs_per_node
    all_dofs = np.arange(node_count * d, dtype=np.int64)
    nodes = [int(n) for n in nodes]
    for n in nodes:
        if not 0 <= n < node_count:
            raise InvalidModelError(f"reference node index {n} out of range 0..{node_count - 1}")
    if kind in ("none", "mean-axis"):
        return all_dofs
    if kind == "clamped":
        if not nodes:
            raise InvalidModelError("clamped reference conditions need at least one node")
        removed = {d * n + c for n in nodes for c in range(d)}
    elif kind == "3-2-1":
        if len(nodes) != 3 or len(set(nodes)) != 3:
            raise InvalidModelError(
                f"3-2-1 reference conditions need three distinct nodes, got {nodes}"
            )
        a, b, c = nodes
        removed = {d * a, d * a + 1, d * a + 2, d * b + 1, d * b + 2, d * c + 2}
    else:
        raise InvalidParameterError(f"unknown reference conditions {kind!r}")
    return np.array([k for k in all_dofs if k not in removed], dtype=np.int64)


def rigid_modes(nodes: NDArray[np.float64], dofs_per_node: int) -> NDArray[np.float64]:
    """The six rigid-body motions in nodal coordinates (n_dofs, 6): translations, then
    infinitesimal rotations u = w x X (rotations also set the rotational coordinates)."""
    d = dofs_per_node
    n = len(nodes)
    r = np.zeros((n * d, 6))
    for k in range(3):
        r[k::d, k] = 1.0
        w = np.zeros(3)
        w[k] = 1.0
        u = np.cross(w, nodes)
        for c in range(3):
            r[c::d, 3 + k] = u[:, c]
        if d == 6:
            r[3 + k :: d, 3 + k] = 1.0
    return r


# Modal reduction ------------------------------------------------------------------------------


def _eigen(k: sp.spmatrix, m: sp.spmatrix, count: int, shift: float) -> tuple[NDArray, NDArray]:
    """The `count` eigenpairs of K x = w^2 M x nearest to the shift (shift-invert Lanczos),
    mass-normalized and sorted."""
    n = k.shape[0]
    if count >= n - 1:
        values, vectors = np.linalg.eigh(k.toarray(), m.toarray()) if n < 4000 else (None, None)
        if values is None:
            raise InvalidParameterError(f"{count} modes requested of a {n}-coordinate body")
        values, vectors = values[:count], vectors[:, :count]
    else:
        values, vectors = spla.eigsh(k.tocsc(), k=count, M=m.tocsc(), sigma=shift, which="LM")
    order = np.argsort(values)
    values, vectors = values[order], vectors[:, order]
    norms = np.sqrt(np.einsum("ij,ij->j", vectors, m @ vectors))
    return values, vectors / norms


def _frequencies(values: NDArray) -> NDArray:
    return np.sqrt(np.clip(values, 0.0, None)) / (2 * np.pi)


def fixed_interface_modes(
    stiffness: sp.spmatrix, mass: sp.spmatrix, free_dofs: NDArray[np.int64], count: int
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The first `count` eigenmodes with the removed dofs held (modes over `free_dofs`,
    mass-normalized) and their frequencies (Hz)."""
    kf = stiffness[free_dofs][:, free_dofs]
    mf = mass[free_dofs][:, free_dofs]
    # A small negative shift keeps K - sigma M definite even for a body that is still free.
    scale = abs(kf.diagonal()).max() / max(abs(mf.diagonal()).max(), 1e-300)
    values, vectors = _eigen(kf, mf, count, -1e-6 * scale)
    return vectors, _frequencies(values)


def free_free_modes(
    stiffness: sp.spmatrix, mass: sp.spmatrix, count: int, rigid: int = 6
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The first `count` elastic free-free modes (the `rigid` rigid-body modes removed) and
    their frequencies (Hz). Being mass-orthogonal to the rigid motions, they satisfy the mean
    axis (Tisserand) conditions. Raises if the body is not free (fewer than `rigid` near-zero
    frequencies)."""
    n = stiffness.shape[0]
    scale = abs(stiffness.diagonal()).max() / max(abs(mass.diagonal()).max(), 1e-300)
    values, vectors = _eigen(stiffness, mass, count + rigid, -1e-6 * scale)
    elastic = values[rigid:]
    if rigid and values[rigid - 1] > 1e-6 * max(elastic[0], 1e-300):
        raise InvalidModelError(
            f"the body is not free: its {rigid} lowest eigenvalues should vanish, "
            f"got {values[:rigid]} (n = {n})"
        )
    return vectors[:, rigid:], _frequencies(elastic)


def craig_bampton(
    stiffness: sp.spmatrix,
    mass: sp.spmatrix,
    interface_dofs: ArrayLike,
    count: int,
    *,
    nodes: NDArray[np.float64] | None = None,
    dofs_per_node: int = 3,
    remove_rigid: bool = True,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Craig-Bampton basis: `count` fixed-interface normal modes and one static constraint
    mode per interface dof (-K_ii^-1 K_ib), over all nodal dofs. With `remove_rigid` (needs
    `nodes`) the rigid-body motions are removed by mass-orthogonalization, so that the basis
    defines a mean-axis frame; the basis is then orthonormalized with respect to M and
    diagonalized (reduced eigenproblem). Returns the modes and their frequencies (Hz)."""
    n = stiffness.shape[0]
    boundary = np.unique(np.asarray(interface_dofs, dtype=np.int64))
    if boundary.size == 0 or boundary.min() < 0 or boundary.max() >= n:
        raise InvalidModelError("Craig-Bampton needs interface coordinates within the body")
    interior = np.setdiff1d(np.arange(n), boundary)
    k = stiffness.tocsc()
    kii = k[interior][:, interior].tocsc()
    kib = k[interior][:, boundary].toarray()
    solve = spla.factorized(kii)
    psi = np.zeros((n, boundary.size))
    psi[boundary, np.arange(boundary.size)] = 1.0
    psi[interior, :] = -np.column_stack([solve(kib[:, j]) for j in range(boundary.size)])
    phi_i, _ = fixed_interface_modes(stiffness, mass, interior, count)
    phi = np.zeros((n, count))
    phi[interior] = phi_i
    basis = np.hstack([phi, psi])
    if remove_rigid:
        if nodes is None:
            raise InvalidParameterError("removing the rigid motions needs the node positions")
        r = rigid_modes(nodes, dofs_per_node)
        mr = mass @ r
        basis = basis - r @ np.linalg.solve(r.T @ mr, mr.T @ basis)
    # M-orthonormalize (dropping the directions the rigid projection made dependent) and
    # diagonalize the reduced problem.
    mb = basis.T @ (mass @ basis)
    w, v = np.linalg.eigh(0.5 * (mb + mb.T))
    keep = w > 1e-10 * w.max()
    basis = basis @ (v[:, keep] / np.sqrt(w[keep]))
    kr = basis.T @ (k @ basis)
    values, vectors = np.linalg.eigh(0.5 * (kr + kr.T))
    return basis @ vectors, _frequencies(values)


def modal_invariants(nodal: dict[str, Any], modes: NDArray[np.float64]) -> dict[str, Any]:
    """Invariants in modal coordinates (seed eq. 18): I1 B, B^T I_kl B, Ibar_kl B; the mass and
    the moments of the undeformed body are unchanged."""
    b = modes
    out = {
        "mass": nodal["mass"],
        "first_moment": nodal["first_moment"],
        "second_moment": nodal["second_moment"],
        "i1": nodal["i1"] @ b,
        "ibar": np.einsum("kln,nm->klm", nodal["ibar"], b),
        "i_kl": [[np.asarray(b.T @ (nodal["i_kl"][k][j] @ b)) for j in range(3)] for k in range(3)],
    }
    return out


def restrict_invariants(nodal: dict[str, Any], free_dofs: NDArray[np.int64]) -> dict[str, Any]:
    """Invariants in the coordinates kept by the reference conditions (the selection B of
    seed eq. 9)."""
    return {
        "mass": nodal["mass"],
        "first_moment": nodal["first_moment"],
        "second_moment": nodal["second_moment"],
        "i1": nodal["i1"][:, free_dofs],
        "ibar": nodal["ibar"][:, :, free_dofs],
        "i_kl": [
            [nodal["i_kl"][k][j][free_dofs][:, free_dofs].tocsc() for j in range(3)]
            for k in range(3)
        ],
    }


def build_body(
    nodes: ArrayLike,
    elements: Mapping[str, ArrayLike],
    material: Material,
    *,
    section: Section | None = None,
    orientation: ArrayLike | None = None,
    mass: str = "consistent",
    beam_theory: str = "euler-bernoulli",
    reference: str = "none",
    reference_nodes: Sequence[int] = (),
    modes: str | None = None,
    mode_count: int = 0,
    interface_nodes: Sequence[int] = (),
    external_modes: ArrayLike | None = None,
    node_ids: ArrayLike | None = None,
    element_ids: Mapping[str, ArrayLike] | None = None,
    node_sets: Mapping[str, ArrayLike] | None = None,
) -> FlexibleBodyData:
    """Runs the preprocessor and returns the `FlexibleBodyData` of a body.

    - `reference`: "none", "clamped", "3-2-1" or "mean-axis" (see `reference_dofs`).
    - `modes`: None (nodal elastic coordinates), "fixed-interface" (eigenmodes with the
      reference conditions), "free-free" (elastic free-free modes; mean-axis frame),
      "craig-bampton" (with `interface_nodes`; rigid motions removed: mean-axis frame) or
      "external" (`external_modes` over the kept coordinates, e.g. from experimental modal
      analysis or another FE code). `mode_count` modes are kept.
    """
    nodes = np.asarray(nodes, dtype=float)
    nodal = assemble(
        nodes,
        elements,
        material,
        section=section,
        orientation=orientation,
        mass=mass,
        beam_theory=beam_theory,
        node_ids=node_ids,
        element_ids=element_ids,
    )
    d = nodal.dofs_per_node
    if modes in ("free-free", "craig-bampton") and reference not in ("none", "mean-axis"):
        raise InvalidModelError(
            f"{modes} modes define a mean-axis frame; use reference='mean-axis'"
        )
    if reference == "mean-axis" and modes not in ("free-free", "craig-bampton"):
        raise InvalidModelError(
            "mean-axis reference conditions need free-free or Craig-Bampton modes"
        )
    free = reference_dofs(reference, len(nodes), d, reference_nodes)
    basis = None
    frequencies = None
    if modes is None:
        invariants = restrict_invariants(nodal.invariants, free)
        k_ff = nodal.stiffness[free][:, free].tocsc()
        m_ff = nodal.mass[free][:, free].tocsc()
    else:
        if modes == "fixed-interface":
            basis, frequencies = fixed_interface_modes(
                nodal.stiffness, nodal.mass, free, mode_count
            )
        elif modes == "free-free":
            basis, frequencies = free_free_modes(nodal.stiffness, nodal.mass, mode_count)
        elif modes == "craig-bampton":
            dofs = [d * n + c for n in interface_nodes for c in range(d)]
            basis, frequencies = craig_bampton(
                nodal.stiffness, nodal.mass, dofs, mode_count, nodes=nodes, dofs_per_node=d
            )
        elif modes == "external":
            if external_modes is None:
                raise InvalidParameterError("external modes need the `external_modes` matrix")
            basis = np.asarray(external_modes, dtype=float)
            if basis.ndim != 2 or basis.shape[0] != len(free):
                raise InvalidParameterError(
                    f"external modes must be ({len(free)}, m) over the kept coordinates, "
                    f"got {basis.shape}"
                )
        else:
            raise InvalidParameterError(f"unknown modes {modes!r}")
        full = np.zeros((len(nodes) * d, basis.shape[1]))
        full[free] = basis
        invariants = modal_invariants(nodal.invariants, full)
        k_ff = basis.T @ (nodal.stiffness[free][:, free] @ basis)
        m_ff = basis.T @ (nodal.mass[free][:, free] @ basis)
    invariants["k_ff"] = k_ff
    invariants["m_ff"] = m_ff
    sets = {name: np.asarray(v, dtype=np.int64) for name, v in (node_sets or {}).items()}
    return FlexibleBodyData(
        nodes=nodes,
        node_ids=np.arange(1, len(nodes) + 1)
        if node_ids is None
        else np.asarray(node_ids, dtype=np.int64),
        elements={k: np.asarray(v, dtype=np.int64) for k, v in elements.items()},
        element_ids={k: np.asarray(v, dtype=np.int64) for k, v in (element_ids or {}).items()},
        node_sets=sets,
        material={
            "young_modulus": material.young_modulus,
            "poisson_ratio": material.poisson_ratio,
            "density": material.density,
        },
        section=None
        if section is None
        else {
            "area": section.area,
            "iy": section.iy,
            "iz": section.iz,
            "torsion_constant": section.torsion_constant,
        },
        dofs_per_node=d,
        stiffness=nodal.stiffness,
        mass=nodal.mass,
        mass_kind=mass,
        reference={
            "kind": reference,
            "nodes": np.asarray(reference_nodes, dtype=np.int64),
            "free_dofs": free,
        },
        modes=basis,
        frequencies=frequencies,
        mode_kind=modes,
        invariants=invariants,
    )
