"""Offsets and released end coordinates (pin flags) of beam elements: the CBAR and CBEAM
fields WA, WB and PA, PB of Nastran decks, or `build_body(beam_offsets=..., beam_releases=...)`.

- Offsets: the element's axis runs between the offset points x_a + w_a and x_b + w_b of its
  nodes (w in body axes), and the axis ends are tied rigidly to the nodes: u_end = u + theta
  x w, theta_end = theta. The element's length and axes are those of the offset axis, and so
  are its stiffness, its mass and its mass points (the invariants of motion): the mass lies
  along the offset axis.
- Releases (12 per element, the coordinates u, v, w, theta_x, theta_y, theta_z of end a then
  end b in the element's axes: x along the axis, y the part of the orientation across it):
  the element transmits no force along a released coordinate. The released coordinates are
  condensed out of the element statically, e_r = -K_rr^+ K_rk e_k (K the element's stiffness
  in its axes, k the held coordinates), so its stiffness is K_kk - K_kr K_rr^+ K_rk, and its
  mass is condensed with the same map, M_c = T^T M T (T = [I; -K_rr^+ K_rk]), as Nastran's
  consistent mass of a CBAR with pin flags (NASTRAN-95 ``bard``). A release that leaves the
  element a mechanism (torsion released at both ends: K_rr singular) lets the part in the
  null space of K_rr follow the nodes' own released coordinates (its projection, I - K_rr^+
  K_rr), which carries no stiffness and keeps the element's mass moving with any rigid motion
  of its nodes; the body is still refused if that leaves it a mechanism.

Both are one constant map per element from its nodes' 12 coordinates (body axes) to its axis
ends' (the "tie"),

    e = A q,   A = R^T C R W,

with W = diag(W_a, W_b), W_i = [[I, -w_i~], [0, I]] (the rigid offset), R = diag(r, r, r, r)
the rotation to the element's axes r (rows x, y, z), and C the condensation (identity on the
held coordinates; rows e_r = -K_rr^+ K_rk e_k + (I - K_rr^+ K_rr) e_r). The preprocessor
assembles such beams on two nodes of their own at their axis ends (`axis_mesh`) and turns the
matrices and invariants of that mesh to the body's coordinates by the tie P (identity on the
body's nodes): K = P^T K_axis P, M = P^T M_axis P, I1 = I1_axis P, Ibar_kl = Ibar_kl,axis P,
I_kl = P^T I_kl,axis P (the mass points' shape functions S P), the mass and moments unchanged.
The geometric stiffness of `System.add_flexible_body(geometric_stiffness=True)` reads the
element's coordinates through the same map (`end_maps`); the co-rotational one refuses such
beams. See ``docs/preprocessor.md``, "Beam offsets and pin flags".
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray

from .. import _core
from .._checks import numbers_array
from ..errors import ArgumentTypeError, InvalidParameterError
from ..rotation import skew

#: Eigenvalues of the Jacobi-scaled K_rr below this fraction of the largest are its null
#: space (a mechanism of the released element).
NULL_TOLERANCE = 1e-9


def checked_ends(
    elements: Any, offsets: Any, releases: Any
) -> tuple[NDArray[np.float64] | None, NDArray[np.bool_] | None]:
    """The `beam_offsets` (n_beams, 2, 3) and `beam_releases` (n_beams, 12) of `build_body`,
    checked against the beam2 elements of `elements`: finite numbers, a mask of bools (or 0
    and 1) per element. None for an option not given (or with no offset or no release).
    Raises `InvalidParameterError` naming the option (`ArgumentTypeError` for what is not
    numbers or bools)."""
    count = len(elements.get("beam2", ())) if hasattr(elements, "get") else 0
    checked_offsets = None
    checked_releases = None
    for name, given in (("beam_offsets", offsets), ("beam_releases", releases)):
        if given is None:
            continue
        if count == 0:
            raise InvalidParameterError(
                f"{name}: the mesh has no beam elements; offsets and releases apply to beam2 "
                "elements only",
                item=name,
            )
        if name == "beam_offsets":
            array = numbers_array(given, name)
            if array.shape != (count, 2, 3) or not np.all(np.isfinite(array)):
                raise InvalidParameterError(
                    f"{name} must be finite numbers of shape ({count}, 2, 3) (the offset of "
                    f"each beam's ends a and b, body axes), got shape {array.shape}",
                    item=name,
                )
            checked_offsets = array if np.any(array) else None
        else:
            array = np.asarray(given)
            if array.dtype.kind in "iu" and np.all((array == 0) | (array == 1)):
                array = array.astype(bool)
            if array.dtype.kind != "b":
                raise ArgumentTypeError(
                    f"{name} must be bools (True: released), got dtype {array.dtype}", item=name
                )
            if array.shape != (count, 12):
                raise InvalidParameterError(
                    f"{name} must have shape ({count}, 12) (per beam: u, v, w, theta_x, "
                    f"theta_y, theta_z of end a then end b, element axes), got {array.shape}",
                    item=name,
                )
            checked_releases = array.copy() if np.any(array) else None
    return checked_offsets, checked_releases


def recorded_ends(
    section: Mapping[str, Any] | None,
) -> tuple[NDArray[np.float64] | None, NDArray[np.bool_] | None]:
    """(offsets (n_beams, 2, 3), releases (n_beams, 12)) recorded in a body's `section`
    ("offsets", "releases"), each None where the body has none."""
    values = section or {}
    offsets, releases = values.get("offsets"), values.get("releases")
    return (
        None if offsets is None else np.asarray(offsets, dtype=float),
        None if releases is None else np.asarray(releases, dtype=bool),
    )


def offset_map(offset_a: ArrayLike, offset_b: ArrayLike) -> NDArray[np.float64]:
    """W (12, 12): the axis ends' coordinates [u, theta] of a beam from its nodes' (body axes)
    for the offsets w_a, w_b: u_end = u - w~ theta (= u + theta x w), theta_end = theta."""
    w = np.eye(12)
    for end, offset in enumerate((offset_a, offset_b)):
        w[6 * end : 6 * end + 3, 6 * end + 3 : 6 * end + 6] = -skew(np.asarray(offset, float))
    return w


def condensation(stiffness: ArrayLike, released: ArrayLike) -> NDArray[np.float64]:
    """C (12, 12) of a beam element with the `released` coordinates (12 bools) and the
    stiffness matrix K (12, 12) in its axes: identity on the held coordinates k; the released
    ones r recovered as e_r = -K_rr^+ K_rk e_k + (I - K_rr^+ K_rr) e_r. K_rr^+ is the
    pseudo-inverse of K_rr in its Jacobi scaling (eigenvalues below `NULL_TOLERANCE` of the
    largest dropped: the null space of a mechanism, such as torsion released at both
    ends)."""
    k = np.asarray(stiffness, dtype=float)
    mask = np.asarray(released, dtype=bool)
    r, kept = np.flatnonzero(mask), np.flatnonzero(~mask)
    c = np.eye(12)
    if len(r) == 0:
        return c
    k_rr = k[np.ix_(r, r)]
    diagonal = np.diag(k_rr)
    # (a coordinate without stiffness of its own is in the null space: scale 0)
    scale = np.where(diagonal > 0.0, 1.0 / np.sqrt(np.where(diagonal > 0.0, diagonal, 1.0)), 0.0)
    values, vectors = np.linalg.eigh(scale[:, None] * k_rr * scale[None, :])
    held = values > NULL_TOLERANCE * max(float(values.max()), 0.0)
    inverse = (scale[:, None] * vectors[:, held]) @ (
        (vectors[:, held] * scale[:, None]).T / values[held][:, None]
    )
    c[np.ix_(r, kept)] = -inverse @ k[np.ix_(r, kept)]
    c[np.ix_(r, r)] = np.eye(len(r)) - inverse @ k_rr
    return c


@dataclass(frozen=True)
class EndMaps:
    """The tie of each beam element with offsets or releases.

    Attributes:
        ends: (n_beams, 2, 3) positions of the axis ends (the nodes plus their offsets), body
            frame.
        axes: (n_beams, 3, 3) the element axes (rows x, y, z) of the offset axis.
        lengths: (n_beams,) lengths of the offset axes.
        maps: (n_beams, 12, 12) A = R^T C R W: the axis ends' 12 coordinates (body axes) from
            the nodes'.
        releases: (n_beams, 12) released coordinates (element axes), all False without
            releases.
        removed: (n_beams, 12, 12) the stiffness that the releases take from each element,
            W^T K_b W - A^T K_b A (K_b the element's stiffness in body axes on its axis
            ends; positive semi-definite), on its nodes' coordinates: zero without releases.
    """

    ends: NDArray[np.float64]
    axes: NDArray[np.float64]
    lengths: NDArray[np.float64]
    maps: NDArray[np.float64]
    releases: NDArray[np.bool_]
    removed: NDArray[np.float64]


def end_maps(
    nodes: ArrayLike,
    beams: ArrayLike,
    offsets: NDArray[np.float64] | None,
    releases: NDArray[np.bool_] | None,
    *,
    material: Any,
    section: Any,
    orientation: ArrayLike | None,
    shear: bool,
) -> EndMaps:
    """The ties of the `beams` (n_beams, 2) node indices with `offsets` (n_beams, 2, 3) or None
    and `releases` (n_beams, 12) or None (checked by `checked_ends`), for the element's
    section, material, orientation (None: the preprocessor's default per element) and beam
    theory (`shear`: Timoshenko), as the preprocessor assembles them."""
    x = np.asarray(nodes, dtype=float)
    conn = np.asarray(beams, dtype=np.int64)
    count = len(conn)
    shift = np.zeros((count, 2, 3)) if offsets is None else np.asarray(offsets, dtype=float)
    free = np.zeros((count, 12), dtype=bool) if releases is None else np.asarray(releases)
    ends = x[conn] + shift
    axes = np.empty((count, 3, 3))
    lengths = np.empty(count)
    maps = np.empty((count, 12, 12))
    removed = np.zeros((count, 12, 12))
    direction = None if orientation is None else [float(v) for v in np.ravel(orientation)]
    for e in range(count):
        rotation, length, stiffness = _core.beam_corotational_terms(
            np.ascontiguousarray(ends[e]), section, material, direction, shear
        )
        r = np.zeros((12, 12))
        for block in range(4):
            r[3 * block : 3 * block + 3, 3 * block : 3 * block + 3] = rotation
        axes[e], lengths[e] = rotation, length
        tie = offset_map(shift[e, 0], shift[e, 1])
        if free[e].any():
            whole = r.T @ np.asarray(stiffness) @ r  # (body axes, on the axis ends)
            rigid = tie
            tie = r.T @ condensation(stiffness, free[e]) @ r @ tie
            removed[e] = rigid.T @ whole @ rigid - tie.T @ whole @ tie
        maps[e] = tie
    return EndMaps(ends, axes, lengths, maps, free.astype(bool), removed)


@dataclass(frozen=True)
class AxisMesh:
    """A mesh whose beams with offsets or releases lie on nodes of their own at their axis
    ends, and the tie from the body's coordinates to its own.

    Attributes:
        nodes: (n + 2 n_beams, 3): the body's nodes, then the axis ends a, b of each beam.
        node_ids: (n + 2 n_beams,) the body's node ids, then new ones above them.
        elements: the body's elements, "beam2" on the axis ends.
        tie: sparse (6 (n + 2 n_beams), 6 n): identity on the body's nodes, the beams'
            `EndMaps.maps` on the axis ends (6 coordinates per node).
    """

    nodes: NDArray[np.float64]
    node_ids: NDArray[np.int64]
    elements: dict[str, NDArray[np.int64]]
    tie: sp.csr_matrix


def axis_mesh(
    nodes: ArrayLike,
    node_ids: ArrayLike,
    elements: dict[str, NDArray[np.int64]],
    maps: EndMaps,
) -> AxisMesh:
    """The `AxisMesh` of a body's `nodes`, `node_ids` and `elements` (with beam2 elements)
    for the ties `maps` of its beams (`end_maps`)."""
    x = np.asarray(nodes, dtype=float)
    ids = np.asarray(node_ids, dtype=np.int64)
    n = len(x)
    conn = np.asarray(elements["beam2"], dtype=np.int64)
    count = len(conn)
    axis = n + np.arange(2 * count, dtype=np.int64).reshape(count, 2)
    top = int(ids.max(initial=0)) + 1
    # Rows of the axis ends' coordinates, columns of their nodes' (12 x 12 per beam).
    rows = np.repeat((6 * axis[:, :, None] + np.arange(6)).reshape(count, 12), 12, axis=1)
    cols = np.tile((6 * conn[:, :, None] + np.arange(6)).reshape(count, 12), (1, 12))
    tie = sp.vstack(
        [
            sp.identity(6 * n, format="csr"),
            sp.csr_matrix(
                (maps.maps.reshape(count, 144).ravel(), (rows.ravel() - 6 * n, cols.ravel())),
                shape=(12 * count, 6 * n),
            ),
        ],
        format="csr",
    )
    return AxisMesh(
        nodes=np.vstack([x, maps.ends.reshape(-1, 3)]),
        node_ids=np.concatenate([ids, top + np.arange(2 * count, dtype=np.int64)]),
        elements={**elements, "beam2": axis},
        tie=tie,
    )


def offset_axis_mesh(
    nodes: NDArray[np.float64],
    ids: NDArray[Any],
    elements: Mapping[str, ArrayLike],
    material: Any,
    section: Any,
    direction: NDArray[np.float64] | None,
    shear: bool,
    beam_offsets: ArrayLike | None,
    beam_releases: ArrayLike | None,
) -> AxisMesh | None:
    """The mesh with the beams that have offsets or releases on their axis ends, and its tie
    to the body's coordinates (:func:`axis_mesh`), or None without such beams (or without a
    section: the assembly names the missing section). `material` and `section` are the
    core's (`Material`, `Section`), `direction` the beams' orientation vector."""
    offsets, releases = checked_ends(elements, beam_offsets, beam_releases)
    if (offsets is None and releases is None) or section is None:
        return None
    kinds = {k: np.ascontiguousarray(v, dtype=np.int64) for k, v in elements.items()}
    maps = end_maps(
        nodes,
        kinds["beam2"],
        offsets,
        releases,
        material=material,
        section=section,
        orientation=direction,
        shear=shear,
    )
    return axis_mesh(nodes, ids, kinds, maps)


def tied_invariants(invariants: dict[str, Any], tie: sp.spmatrix) -> dict[str, Any]:
    """The nodal invariants of an `AxisMesh` turned to the body's coordinates by its tie P:
    I1 P, Ibar_kl P, P^T I_kl P; the mass and moments unchanged."""
    i1 = np.asarray(invariants["i1"])
    ibar = np.asarray(invariants["ibar"])
    out = dict(invariants)
    out["i1"] = np.asarray((sp.csr_matrix(i1) @ tie).toarray())
    out["ibar"] = np.asarray((sp.csr_matrix(ibar.reshape(9, -1)) @ tie).toarray()).reshape(
        3, 3, tie.shape[1]
    )
    if invariants.get("i_kl") is not None:
        out["i_kl"] = [
            [tied_matrix(invariants["i_kl"][k][j], tie) for j in range(3)] for k in range(3)
        ]
    return out


def tied_matrix(matrix: sp.spmatrix, tie: sp.spmatrix) -> sp.csc_matrix:
    """P^T A P in canonical CSC form (sorted indices, no duplicates: the body's frozen
    matrices are not sorted in place later)."""
    out = sp.csc_matrix(tie.T @ matrix @ tie)
    out.sum_duplicates()
    return out
