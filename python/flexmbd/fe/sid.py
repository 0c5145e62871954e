"""Standard Input Data (SID): the text format of a reduced deformable body that Simpack's FEMBS,
Abaqus (``*FLEXIBLE BODY, TYPE=SID``) and the DLR FlexibleBodies library exchange (Wallrapp,
"Standardization of flexible body modeling in multibody system codes", 1994).

A SID file describes a modal body by the Taylor expansions, in the modal coordinates q, of the
terms of its equations of motion: the mass, the first moment, the inertia tensor, the coupling
and gyroscopic matrices, the modal stiffness and damping, and, for each node, its position and
the displacement and rotation of its modes. ``docs/sid.md`` lists every field, its formula in
the invariants of motion and the equations in which it appears.

    from flexmbd.fe import write_sid, read_sid
    write_sid(body, "arm.sid")          # a modal FlexibleBodyData
    body = read_sid("arm.sid")          # a FlexibleBodyData without a mesh

Every matrix object is M(q) = M0 + sum_k M1_k q_k + 1/2 sum_kl M2_kl q_k q_l (the Taylor series:
M1_k = dM/dq_k, M2_kl = d2M/dq_k dq_l), stored as ``m0(i,j)``, ``m1(i,j,k)`` and
``m2(i,j,k,l)`` entries (1-based); entries not listed are zero."""

from __future__ import annotations

import math
import os
import re
import warnings
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import (
    ArgumentTypeError,
    InvalidModelError,
    InvalidParameterError,
    MissingFileError,
    UnknownItemError,
)
from . import _memory
from ._memory import check_fits
from .body import FlexibleBodyData

#: Structure codes of a matrix object: which entries are written.
ZERO, DIAGONAL, SYMMETRIC, FULL = 0, 1, 2, 3

#: The body's matrix objects in the order they are written, with their shape in terms of the
#: number of modes n (None: n).
FIELD_ORDER = ("mdCM", "J", "Ct", "Cr", "Me", "Gr", "Ge", "Oe", "ksigma", "Ke", "De")

#: Modal bodies with more modes than this are refused: J's second-order terms alone hold
#: 9 n^2 numbers per pair of modes.
MAX_MODES = 400

#: Memory taken by the reader per byte of text (its lines, then the arrays): files whose
#: estimate exceeds the available memory are refused before they are read.
MEMORY_PER_BYTE = 5.0

#: Relative tolerance of the checks that a file's redundant fields agree with each other.
CONSISTENCY_TOLERANCE = 1e-8

# Levi-Civita symbol eps[a, b, c].
_EPS = np.zeros((3, 3, 3))
for _a, _b, _c in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
    _EPS[_a, _b, _c], _EPS[_a, _c, _b] = 1.0, -1.0

# Components of the six products of omega in Oe's columns: xx, yy, zz, xy, yz, xz.
_OMEGA_PAIRS = ((0, 0), (1, 1), (2, 2), (0, 1), (1, 2), (0, 2))


@dataclass(frozen=True, eq=False)
class Taylor:
    """One SID matrix object: M(q) = m0 + sum_k m1[..., k] q_k + 1/2 sum_kl m2[..., k, l] q_k q_l.

    Attributes:
        m0: (nrow, ncol).
        m1: (nrow, ncol, nq) or None (order 0).
        m2: (nrow, ncol, nq, nq) or None (order below 2); symmetric in its last two indices.
        structure: ``FULL``, ``SYMMETRIC`` (every term symmetric in its first two indices:
            only the entries i <= j are written), ``DIAGONAL`` or ``ZERO``."""

    m0: NDArray[np.float64]
    m1: NDArray[np.float64] | None = None
    m2: NDArray[np.float64] | None = None
    structure: int = FULL

    @property
    def order(self) -> int:
        return 2 if self.m2 is not None else 1 if self.m1 is not None else 0

    @property
    def shape(self) -> tuple[int, int]:
        return self.m0.shape  # type: ignore[return-value]

    def at(self, q: NDArray[np.float64]) -> NDArray[np.float64]:
        """M(q)."""
        value = np.array(self.m0, dtype=float)
        if self.m1 is not None:
            value = value + self.m1 @ q
        if self.m2 is not None:
            value = value + 0.5 * (self.m2 @ q) @ q
        return value


@dataclass(frozen=True, eq=False)
class SidNode:
    """A node of the body's frame: its id, position ``origin`` (3 x 1, order 1: m1 = the
    displacement of each mode), the modes' displacements ``phi`` (3 x n) and, for nodes with
    rotations, their rotations ``psi`` (3 x n); ``ap``, the orientation of the node's frame
    (3 x 3, the identity for nodes of a mesh)."""

    id: int
    origin: Taylor
    phi: Taylor
    psi: Taylor | None = None
    ap: Taylor | None = None


@dataclass(frozen=True, eq=False)
class SidData:
    """The content of a SID file: ``mass`` (kg), ``modes`` (the ``ielastq`` names of the modal
    coordinates), ``frequencies`` (Hz, or None when the names carry none), ``nodes``
    (:class:`SidNode`) and ``fields``, the body's matrix objects by name (``FIELD_ORDER``)."""

    mass: float
    modes: list[str]
    frequencies: NDArray[np.float64] | None
    nodes: list[SidNode]
    fields: dict[str, Taylor] = field(default_factory=dict)

    @property
    def mode_count(self) -> int:
        return len(self.modes)

    @classmethod
    def from_body(cls, body: FlexibleBodyData, nodes: Iterable[int | str] | None = None) -> SidData:
        """The SID of a modal body (or a small nodal one): its nodes (all, or those of the
        given node ids and node set names) and the Taylor expansions of its invariants of
        motion (``docs/sid.md``).

        Raises `InvalidModelError` for a body of more than ``MAX_MODES`` elastic coordinates,
        `UnknownItemError` (via the node selection) for unknown node ids or sets."""
        return _from_body(body, nodes)

    def to_body(self, *, source: str = "") -> FlexibleBodyData:
        """A :class:`FlexibleBodyData` with the SID's nodes, modes and invariants (no mesh,
        no nodal matrices), checking that the file's redundant fields agree.

        Raises `InvalidModelError` naming the field that is missing, of the wrong shape, or
        that disagrees with the others (``CONSISTENCY_TOLERANCE``)."""
        return _to_body(self, source)

    def write(self, path: str | os.PathLike[str]) -> Path:
        """Writes the SID text file; returns its path."""
        path = Path(path)
        path.write_text(_format(self), encoding="utf-8")
        return path


def write_sid(
    body: FlexibleBodyData,
    path: str | os.PathLike[str],
    *,
    nodes: Iterable[int | str] | None = None,
) -> Path:
    """Writes a modal body (or a nodal one of at most ``MAX_MODES`` elastic coordinates, whose
    "modes" are the unit displacements of its kept coordinates) as a SID file
    (``docs/sid.md``): all its nodes, or those of the given node ids and node set names (a
    multibody code needs the nodes of its joints and outputs; every node makes a large file).
    Returns the path."""
    return SidData.from_body(body, nodes).write(path)


def read_sid(path: str | os.PathLike[str]) -> FlexibleBodyData:
    """Reads a SID file into a :class:`FlexibleBodyData` whose elastic coordinates are the
    file's modal coordinates, with its nodes (ids from ``new node = ID``, or their order)
    for markers, and its damping where ``De`` is Rayleigh or modal.

    Raises `MissingFileError`, and `InvalidModelError` naming the file and line of a syntax
    error, or the field that is missing or inconsistent."""
    return load_sid_data(path).to_body(source=str(path))


def load_sid_data(path: str | os.PathLike[str]) -> SidData:
    """The content of a SID file as :class:`SidData` (see :func:`read_sid`)."""
    path = Path(path)
    if not path.is_file():
        raise MissingFileError("SID file", path)
    check_fits(path, path.stat().st_size, MEMORY_PER_BYTE, "SID file")
    return _Parser(path).parse()


# From a body --------------------------------------------------------------------------------


def _dense(matrix: Any) -> NDArray[np.float64]:
    return np.asarray(matrix.toarray() if hasattr(matrix, "toarray") else matrix, dtype=float)


def _node_selection(body: FlexibleBodyData, nodes: Iterable[int | str] | None) -> list[int]:
    if nodes is None:
        return list(range(body.node_count))
    if isinstance(nodes, str | int | np.integer) or not isinstance(nodes, Iterable):
        raise ArgumentTypeError(
            f"SID nodes: a list of node ids and node set names, got {nodes!r:.60} "
            f"({type(nodes).__name__}): pass [{nodes!r:.40}]",
            item="nodes",
        )
    ids = np.asarray(body.node_ids)
    chosen: list[int] = []
    for item in nodes:
        if not isinstance(item, str) and (
            isinstance(item, bool) or not isinstance(item, int | np.integer)
        ):
            raise ArgumentTypeError(
                f"SID nodes: each entry is a node id (an integer) or a node set name, got "
                f"{item!r:.40} ({type(item).__name__})",
                item="nodes",
            )
        if isinstance(item, str):
            if item not in body.node_sets:
                raise UnknownItemError(
                    f"SID nodes: the body has no node set {item!r} (sets: "
                    f"{sorted(body.node_sets)})",
                    item=item,
                )
            chosen.extend(int(i) for i in body.node_sets[item])
        else:
            hits = np.flatnonzero(ids == int(item))
            if len(hits) == 0:
                raise UnknownItemError(
                    f"SID nodes: the body has no node with id {item}", item=str(item)
                )
            chosen.append(int(hits[0]))
    if not chosen:
        raise InvalidParameterError(
            "SID nodes: the selection is empty (a SID file needs a node for its markers)",
            item="nodes",
        )
    return sorted(set(chosen))


def _second_moments(body: FlexibleBodyData) -> NDArray[np.float64]:
    """G[a, b, k, l] = int rho Phi_ak Phi_bl dV, from the invariants I_kl."""
    i_kl = body.invariants.i_kl
    return np.array([[_dense(i_kl[a][b]) for b in range(3)] for a in range(3)])


def _from_body(body: FlexibleBodyData, nodes: Iterable[int | str] | None) -> SidData:
    from ..system import elastic_basis
    from .body_variants import damping_matrix

    inv = body.invariants
    n = body.elastic_coordinate_count
    if n > MAX_MODES:
        raise InvalidModelError(
            f"the body has {n} elastic coordinates; SID export takes at most {MAX_MODES} (J's "
            f"second-order terms alone would hold {9 * n * n} numbers): reduce the body first "
            "(body.with_modes(...) or build_body(..., modes=...))",
            item="modes",
        )
    eye = np.eye(3)
    first = np.asarray(inv.first_moment, dtype=float)
    second = np.asarray(inv.second_moment, dtype=float)
    i1 = np.asarray(inv.i1, dtype=float)
    ibar = np.asarray(inv.ibar, dtype=float)  # ibar[a, b, k] = int rho u0_a Phi_bk
    g = _second_moments(body)
    m_ff, k_ff = _dense(inv.m_ff), _dense(inv.k_ff)
    gt = g.transpose(0, 1, 3, 2)  # G[a, b, l, k]

    def inertia(moment: NDArray[np.float64]) -> NDArray[np.float64]:
        # The inertia tensor of a second moment P: tr(P) I - P, over the first two indices.
        trace = np.einsum("aa...->...", moment)
        return np.einsum("ab,...->ab...", eye, trace) - moment

    ibar_sym = ibar + ibar.transpose(1, 0, 2)
    fields = {
        "mdCM": Taylor(first[:, None], i1[:, None, :]),
        "J": Taylor(inertia(second), inertia(ibar_sym), inertia(g + gt), SYMMETRIC),
        "Ct": Taylor(i1.T.copy()),
        "Cr": _coupling_rotation(ibar, g),
        "Me": Taylor(m_ff, structure=SYMMETRIC),
        "Gr": _gyroscopic_rotation(ibar, g, m_ff),
        "Ge": Taylor(_gyroscopic_elastic(g)),
        "Oe": _centrifugal(ibar, g),
        "ksigma": Taylor(np.zeros((n, 1)), structure=ZERO),
        "Ke": Taylor(k_ff, structure=SYMMETRIC),
        "De": Taylor(damping_matrix(body), structure=SYMMETRIC),
    }
    basis = elastic_basis(body).toarray()
    dofs = body.dofs_per_node
    sid_nodes = []
    for index in _node_selection(body, nodes):
        phi = basis[dofs * index : dofs * index + 3]
        position = np.asarray(body.nodes[index], dtype=float)[:, None]
        sid_nodes.append(
            SidNode(
                id=int(body.node_ids[index]),
                origin=Taylor(position, phi[:, None, :]),
                phi=Taylor(phi),
                psi=Taylor(basis[dofs * index + 3 : dofs * index + 6]) if dofs == 6 else None,
                ap=Taylor(np.eye(3)),
            )
        )
    frequencies = None if body.frequencies is None else np.asarray(body.frequencies, dtype=float)
    if body.modes is None:  # nodal coordinates: the "modes" select the kept dofs
        free = np.asarray(body.reference.free_dofs)
        names = [
            f"Nodal coordinate {k + 1} (node {body.node_ids[d // dofs]}, dof {d % dofs + 1})"
            for k, d in enumerate(free)
        ]
    else:
        names = [
            f"Eigen Mode {k + 1} : {float(frequencies[k])!r} Hz"
            if frequencies is not None and k < len(frequencies)
            else f"Mode {k + 1}"
            for k in range(n)
        ]
    return SidData(
        float(inv.mass), names, frequencies, sid_nodes, {k: fields[k] for k in FIELD_ORDER}
    )


def _coupling_rotation(ibar: NDArray[np.float64], g: NDArray[np.float64]) -> Taylor:
    """Cr (n x 3): row k int u x Phi_k dm = eps_cab (Ibar_k(a, b) + G[a, b, l, k] q_l)."""
    return Taylor(np.einsum("cab,abk->kc", _EPS, ibar), np.einsum("cab,abkl->lck", _EPS, g))


def _gyroscopic_rotation(
    ibar: NDArray[np.float64], g: NDArray[np.float64], m_ff: NDArray[np.float64]
) -> Taylor:
    """Gr = [Gr_1 ... Gr_n] (3 x 3n), Gr_k = -2 int u~ Phi~_k dm
    = -2 int (Phi_k u^T - u.Phi_k I) dm."""
    n = ibar.shape[2]
    eye = np.eye(3)
    m0 = np.zeros((3, 3 * n))
    m1 = np.zeros((3, 3 * n, n))
    for k in range(n):
        ibar_k = ibar[:, :, k]
        m0[:, 3 * k : 3 * k + 3] = -2.0 * (ibar_k.T - np.trace(ibar_k) * eye)
        for j in range(n):
            m1[:, 3 * k : 3 * k + 3, j] = -2.0 * (g[:, :, k, j] - m_ff[j, k] * eye)
    return Taylor(m0, m1)


def _gyroscopic_elastic(g: NDArray[np.float64]) -> NDArray[np.float64]:
    """Ge = [Ge_1 ... Ge_n] (n x 3n), Ge_k = -2 int Phi^T Phi~_k dm: Ge_k(l, c) =
    -2 eps_cab G[a, b, l, k]."""
    n = g.shape[2]
    blocks = -2.0 * np.einsum("cab,ablk->lkc", _EPS, g)  # (l, k, c)
    return blocks.reshape(n, 3 * n)


def _centrifugal(ibar: NDArray[np.float64], g: NDArray[np.float64]) -> Taylor:
    """Oe (n x 6): row k the coefficients of the products of omega (xx, yy, zz, xy, yz, xz) in
    int Phi_k^T w~ w~ u dm, with P_k(a, b) = int Phi_ak u_b dm."""

    def columns(p: NDArray[np.float64]) -> NDArray[np.float64]:
        # p[a, b, ...] -> (..., 6)
        trace = np.einsum("aa...->...", p)
        out = [p[a, a] - trace for a in range(3)]
        out += [p[a, b] + p[b, a] for a, b in _OMEGA_PAIRS[3:]]
        return np.stack(out, axis=-1)

    p0 = ibar.transpose(1, 0, 2)  # P0_k(a, b) = ibar[b, a, k]
    m0 = columns(p0)  # (n, 6)
    m1 = columns(g).transpose(0, 2, 1)  # G[a, b, k, l] -> (k, l, 6) -> (k, 6, l)
    return Taylor(m0, m1)


# To a body ----------------------------------------------------------------------------------


def _require(sid: SidData, name: str, shape: tuple[int, int], order: int) -> Taylor:
    item = sid.fields.get(name)
    if item is None:
        raise InvalidModelError(f"SID: the body has no field {name}", item=name)
    if item.shape != shape:
        raise InvalidModelError(
            f"SID: field {name} has shape {item.shape}, expected {shape}", item=name
        )
    if item.order < order:
        raise InvalidModelError(
            f"SID: field {name} has order {item.order}; flexmbd needs its terms up to order "
            f"{order}"
            + (
                " (nqn = nq: the second-order terms of J hold the invariants I_kl, which the "
                "equations of motion need; export them from the FE code with second-order "
                "terms)"
                if name == "J"
                else ""
            ),
            item=name,
        )
    return item


def _terms(item: Taylor, n: int) -> tuple[NDArray[np.float64], ...]:
    r, c = item.shape
    m1 = item.m1 if item.m1 is not None else np.zeros((r, c, n))
    m2 = item.m2 if item.m2 is not None else np.zeros((r, c, n, n))
    return item.m0, m1, m2


def _to_body(sid: SidData, source: str) -> FlexibleBodyData:
    from .body import Invariants, ReferenceConditions

    n = sid.mode_count
    eye = np.eye(3)
    md = _require(sid, "mdCM", (3, 1), 1)
    j = _require(sid, "J", (3, 3), 2)
    cr = _require(sid, "Cr", (n, 3), 0)
    ge = _require(sid, "Ge", (n, 3 * n), 0)
    me = _require(sid, "Me", (n, n), 0)
    ke = _require(sid, "Ke", (n, n), 0)
    for item in (md, j):
        if item.m1 is not None and item.m1.shape[2] != n:
            raise InvalidModelError(f"SID: nq of a field is not nelastq = {n}", item="nq")
    j0, j1, j2 = _terms(j, n)

    def moment(inertia: NDArray[np.float64]) -> NDArray[np.float64]:
        # The second moment P of an inertia tensor J = tr(P) I - P: P = tr(J)/2 I - J.
        trace = np.einsum("aa...->...", inertia)
        return 0.5 * np.einsum("ab,...->ab...", eye, trace) - inertia

    second = moment(j0)
    # ibar_k: symmetric part from J1, antisymmetric part from Cr0 (row k: int u0 x Phi_k).
    symmetric = moment(j1)
    antisymmetric = np.einsum("abc,kc->abk", _EPS, cr.m0)
    ibar = 0.5 * (symmetric + antisymmetric)
    # G[a, b, k, l]: its part symmetric in (k, l) from J2, antisymmetric from Ge.
    ge_blocks = ge.m0.reshape(n, n, 3)  # (l, k, c) = Ge_k(l, c)
    anti = -0.25 * np.einsum("abc,klc->abkl", _EPS, ge_blocks)  # A[a, b, k, l]
    g = 0.5 * moment(j2) + anti
    m_ff, k_ff = me.m0, ke.m0
    i1 = md.m1[:, 0, :] if md.m1 is not None else np.zeros((3, n))

    _check_consistency(sid, g, ibar, i1, m_ff)

    nodes = np.array([node.origin.m0[:, 0] for node in sid.nodes], dtype=float).reshape(-1, 3)
    six = any(node.psi is not None for node in sid.nodes)
    dofs = 6 if six else 3
    without = [node.id for node in sid.nodes if six and node.psi is None]
    if without:
        raise InvalidModelError(
            f"SID: node {without[0]} has no psi (the modes' rotations) while other nodes have "
            f"one ({len(without)} node(s) without): its rotations would be taken as zero",
            item=f"node {without[0]}",
        )
    modes = np.zeros((dofs * len(sid.nodes), n))
    turned = [
        node.id
        for node in sid.nodes
        if node.ap is not None and not np.allclose(node.ap.m0, np.eye(3))
    ]
    if turned:
        warnings.warn(
            f"SID: the frames of {len(turned)} node(s) (the first: node {turned[0]}) are turned "
            "from the body axes (their AP): flexmbd does not use AP; markers on nodes take "
            "their axes from the model",
            UserWarning,
            stacklevel=4,
        )
    for index, node in enumerate(sid.nodes):
        if node.phi.shape != (3, n):
            raise InvalidModelError(
                f"SID: node {node.id}: phi has shape {node.phi.shape}, expected (3, {n})",
                item=f"node {node.id}",
            )
        modes[dofs * index : dofs * index + 3] = node.phi.m0
        if node.psi is not None:
            if node.psi.shape != (3, n):
                raise InvalidModelError(
                    f"SID: node {node.id}: psi has shape {node.psi.shape}, expected (3, {n})",
                    item=f"node {node.id}",
                )
            modes[dofs * index + 3 : dofs * index + 6] = node.psi.m0
    invariants = Invariants(
        mass=float(sid.mass),
        first_moment=np.asarray(md.m0[:, 0], dtype=float),
        second_moment=0.5 * (second + second.T),
        i1=np.ascontiguousarray(i1),
        ibar=ibar,
        i_kl=[[np.ascontiguousarray(g[a, b]) for b in range(3)] for a in range(3)],
        k_ff=np.asarray(k_ff, dtype=float),
        m_ff=np.asarray(m_ff, dtype=float),
    )
    damping = _damping_spec(sid.fields.get("De"), m_ff, k_ff)
    ids = np.array([node.id for node in sid.nodes], dtype=np.int64)
    metadata = {"format": "SID"}
    if source:
        metadata["source"] = source
    return FlexibleBodyData(
        nodes=nodes,
        node_ids=ids,
        elements={},
        element_ids={},
        node_sets={},
        material={},
        section=None,
        dofs_per_node=dofs,
        stiffness=None,
        mass=None,
        mass_kind="consistent",
        reference=ReferenceConditions(
            kind="none",
            nodes=np.zeros(0, dtype=np.int64),
            free_dofs=np.arange(dofs * len(sid.nodes), dtype=np.int64),
        ),
        modes=modes,
        frequencies=sid.frequencies if sid.frequencies is not None else _frequencies(k_ff, m_ff),
        mode_kind="external",
        invariants=invariants,
        damping=damping,
        metadata=metadata,
    )


def _frequencies(k_ff: NDArray[np.float64], m_ff: NDArray[np.float64]) -> NDArray[np.float64]:
    import scipy.linalg as sla

    w2 = sla.eigh(k_ff, m_ff, eigvals_only=True)
    return np.sqrt(np.clip(w2, 0.0, None)) / (2.0 * math.pi)


def _check_consistency(
    sid: SidData,
    g: NDArray[np.float64],
    ibar: NDArray[np.float64],
    i1: NDArray[np.float64],
    m_ff: NDArray[np.float64],
) -> None:
    """The fields that follow from mdCM, J, Cr0, Ge and Me (Ct, Cr1, Gr, Oe, and Me itself
    against trace G) agree with them, where the file has them."""
    n = sid.mode_count
    expected = {
        "Ct": Taylor(i1.T),
        "Cr": _coupling_rotation(ibar, g),
        "Me": Taylor(np.einsum("aakl->kl", g)),
        "Gr": _gyroscopic_rotation(ibar, g, m_ff),
        "Oe": _centrifugal(ibar, g),
    }
    for name, want in expected.items():
        have = sid.fields.get(name)
        if have is None:
            continue
        if have.shape != want.shape:
            raise InvalidModelError(
                f"SID: field {name} has shape {have.shape}, expected {want.shape}", item=name
            )
        for term, (a, b) in enumerate(zip(_terms(have, n)[:2], _terms(want, n)[:2], strict=True)):
            scale = max(float(np.abs(b).max(initial=0.0)), float(np.abs(a).max(initial=0.0)))
            reference = max(scale, _field_scale(sid, name))
            deviation = float(np.abs(a - b).max(initial=0.0))
            if deviation > CONSISTENCY_TOLERANCE * reference and term == 1 and have.m1 is None:
                raise InvalidModelError(
                    f"SID: field {name} has order 0, but its order-1 terms (of the elastic "
                    f"coordinates) are not zero for this body: largest {scale:.3e}; write the "
                    f"file with the first-order terms of {name}",
                    item=name,
                )
            if deviation > CONSISTENCY_TOLERANCE * reference:
                raise InvalidModelError(
                    f"SID: field {name} (its order-{term} terms) disagrees with the ones it "
                    f"follows from (mdCM, J, Cr, Ge, Me): largest deviation {deviation:.3e} of "
                    f"{scale:.3e}; the file may use another sign convention (docs/sid.md)",
                    item=name,
                )


def _field_scale(sid: SidData, name: str) -> float:
    # Terms that vanish (Oe's order 0 for a body centred on its frame) are judged against the
    # size of the body's inertia terms.
    j = sid.fields["J"]
    return 1e-6 * float(np.abs(j.m0).max(initial=0.0)) if name != "Me" else 0.0


def _damping_spec(
    de: Taylor | None, m_ff: NDArray[np.float64], k_ff: NDArray[np.float64]
) -> dict[str, Any] | None:
    """The body's damping from De: None when it is zero, else Rayleigh alpha Me + beta Ke plus
    modal damping of one ratio, fitted and checked."""
    from .body_variants import modal_damping_matrix

    if de is None or not np.any(de.m0):
        return None
    d = np.asarray(de.m0, dtype=float)
    basis = [m_ff, k_ff, modal_damping_matrix(k_ff, m_ff, 1.0)]
    a = np.stack([b.ravel() for b in basis], axis=1)
    coefficients, *_ = np.linalg.lstsq(a, d.ravel(), rcond=None)
    size = float(np.linalg.norm(d))
    residual = float(np.linalg.norm(a @ coefficients - d.ravel())) / size
    negative = any(
        c < 0 and -c * np.linalg.norm(b) > 1e-9 * size
        for c, b in zip(coefficients, basis, strict=True)
    )
    if residual > 1e-9 or negative:
        raise InvalidModelError(
            "SID: De is neither Rayleigh damping (alpha Me + beta Ke, alpha, beta >= 0) nor "
            "modal damping of one ratio, nor their sum (relative residual of the fit "
            f"{residual:.1e})",
            item="De",
        )
    # Terms of round-off size dropped (a Rayleigh-damped body came back with modal damping
    # of ratio 2.8e-17 besides).
    clean = [
        max(float(c), 0.0) if abs(c) * np.linalg.norm(b) > 1e-12 * size else 0.0
        for c, b in zip(coefficients, basis, strict=True)
    ]
    rayleigh = (clean[0], clean[1]) if clean[0] > 0 or clean[1] > 0 else None
    return {"rayleigh": rayleigh, "modal": clean[2] if clean[2] > 0 else None}


# Writing ------------------------------------------------------------------------------------


def _number(value: float) -> str:
    return repr(float(value))


def _taylor_lines(name: str, item: Taylor, n: int, indent: str) -> list[str]:
    nrow, ncol = item.shape
    order = item.order
    nqn = n if order >= 2 else 0
    inner = indent + "   "
    lines = [f"{indent}{name}"]
    for key, value in (
        ("order", order),
        ("nrow", nrow),
        ("ncol", ncol),
        ("nq", n if order >= 1 else 0),
        ("nqn", nqn),
        ("structure", item.structure),
    ):
        lines.append(f"{inner}{key:<10}= {value}")

    def keep(i: int, j: int) -> bool:
        if item.structure == SYMMETRIC:
            return i <= j
        if item.structure == DIAGONAL:
            return i == j
        return item.structure != ZERO

    for i in range(nrow):
        for j in range(ncol):
            if keep(i, j) and item.m0[i, j] != 0.0:
                lines.append(f"{inner}m0({i + 1},{j + 1}) = {_number(item.m0[i, j])}")
    if item.m1 is not None:
        rows, cols, ks = np.nonzero(item.m1)
        for i, j, k in zip(rows, cols, ks, strict=True):
            if keep(i, j):
                lines.append(f"{inner}m1({i + 1},{j + 1},{k + 1}) = {_number(item.m1[i, j, k])}")
    if item.m2 is not None:
        rows, cols, ks, ls = np.nonzero(item.m2)
        for i, j, k, m in zip(rows, cols, ks, ls, strict=True):
            if keep(i, j) and k <= m:
                lines.append(
                    f"{inner}m2({i + 1},{j + 1},{k + 1},{m + 1}) = {_number(item.m2[i, j, k, m])}"
                )
    lines.append(f"{indent}end {name}")
    return lines


def _format(sid: SidData) -> str:
    n = sid.mode_count
    lines = [
        "# Standard Input Data (SID) of a modal body, written by flexmbd (docs/sid.md).",
        "part",
        "   new modal",
        "      refmod",
        f"         mass      = {_number(sid.mass)}",
        f"         nelastq   = {n}",
    ]
    lines += [f"         ielastq({k + 1}) = {name}" for k, name in enumerate(sid.modes)]
    lines += ["      end refmod", "      frame"]
    for node in sid.nodes:
        lines += [f"         new node = {node.id}", "            rframe    = body ref"]
        for name in ("origin", "phi", "psi", "AP"):
            item = getattr(node, "ap" if name == "AP" else name)
            if item is not None:
                lines += _taylor_lines(name, item, n, "            ")
        lines.append("         end node")
    lines.append("      end frame")
    for name in FIELD_ORDER:
        if name in sid.fields:
            lines += _taylor_lines(name, sid.fields[name], n, "      ")
    lines += ["   end modal", "end part", ""]
    return "\n".join(lines)


# Reading ------------------------------------------------------------------------------------

_ENTRY = re.compile(r"^(m[012])\s*\(([^)]*)\)\s*=\s*(\S+)\s*$", re.IGNORECASE)
_ASSIGN = re.compile(r"^([A-Za-z_]\w*)\s*(?:\(\s*(\d+)\s*\))?\s*=\s*(.*)$")
_HEADER = ("order", "nrow", "ncol", "nq", "nqn", "structure")
_NODE_FIELDS = {"origin": "origin", "phi": "phi", "psi": "psi", "ap": "ap"}
_BODY_FIELDS = {name.lower(): name for name in FIELD_ORDER}
_FREQUENCY = re.compile(r":\s*([-+0-9.eEdD]+)\s*Hz", re.IGNORECASE)


class _Parser:
    def __init__(self, path: Path):
        self.path = path
        self.lines = path.read_text(encoding="utf-8", errors="replace").splitlines()
        self.index = 0

    def error(self, message: str, line: int | None = None) -> InvalidModelError:
        number = self.index if line is None else line
        return InvalidModelError(
            f"{self.path}, line {number}: {message}", item=f"line {number} of '{self.path}'"
        )

    def next(self) -> str | None:
        """The next meaningful line, stripped (comments and blank lines skipped)."""
        while self.index < len(self.lines):
            raw = self.lines[self.index]
            self.index += 1
            text = raw.split("#", 1)[0].split("!", 1)[0].strip()
            if text:
                return text
        return None

    def expect(self, word: str) -> None:
        text = self.next()
        if text is None or text.lower() != word:
            raise self.error(f"expected {word!r}, found {text!r}")

    def parse(self) -> SidData:
        self.expect("part")
        text = self.next()
        if text is None or text.lower().split() != ["new", "modal"]:
            raise self.error(f"expected 'new modal', found {text!r}")
        mass, modes = None, []
        nodes: list[SidNode] = []
        fields: dict[str, Taylor] = {}
        while True:
            text = self.next()
            if text is None:
                raise self.error("the file ends before 'end modal'")
            word = text.lower()
            if word == "end modal":
                break
            if word == "refmod":
                mass, modes = self.refmod()
            elif word == "frame":
                nodes = self.frame(len(modes))
            elif word in _BODY_FIELDS:
                name = _BODY_FIELDS[word]
                if name in fields:
                    raise self.error(f"field {name} appears twice")
                fields[name] = self.taylor(name, len(modes))
            else:
                raise self.error(
                    f"unknown section {text!r} (known: refmod, frame, {', '.join(FIELD_ORDER)})"
                )
        if mass is None:
            raise self.error("the file has no refmod section (mass, nelastq)")
        frequencies = []
        for name in modes:
            hit = _FREQUENCY.search(name)
            try:
                value = float(hit.group(1).replace("D", "E").replace("d", "e")) if hit else None
            except ValueError:
                value = None  # (a name that is no frequency: taken from Ke and Me)
            frequencies.append(value)
        known = None if any(f is None for f in frequencies) else np.array(frequencies, dtype=float)
        return SidData(mass, modes, known, nodes, fields)

    def refmod(self) -> tuple[float, list[str]]:
        mass, count, names = None, None, {}
        while True:
            text = self.next()
            if text is None:
                raise self.error("the file ends inside refmod")
            if text.lower() == "end refmod":
                break
            hit = _ASSIGN.match(text)
            if not hit:
                raise self.error(f"expected 'key = value' in refmod, found {text!r}")
            key, index, value = hit.group(1).lower(), hit.group(2), hit.group(3).strip()
            if key == "mass":
                mass = self.real(value)
                if not (math.isfinite(mass) and mass > 0):
                    raise self.error(f"mass must be a finite number > 0, got {value!r}")
            elif key == "nelastq":
                count = self.integer(value)
            elif key == "ielastq" and index is not None:
                names[int(index)] = value
            else:
                pass  # other refmod entries (e.g. a mode's description) are not needed
        if mass is None or count is None:
            raise self.error("refmod needs mass and nelastq")
        modes = [names.get(k + 1, f"Mode {k + 1}") for k in range(count)]
        return mass, modes

    def frame(self, n: int) -> list[SidNode]:
        nodes: list[SidNode] = []
        while True:
            text = self.next()
            if text is None:
                raise self.error("the file ends inside frame")
            word = text.lower()
            if word == "end frame":
                return nodes
            if not word.startswith("new node"):
                raise self.error(f"expected 'new node' or 'end frame', found {text!r}")
            _, _, rest = text.partition("=")
            node_id = self.integer(rest.strip()) if rest.strip() else len(nodes) + 1
            parts: dict[str, Taylor] = {}
            while True:
                text = self.next()
                if text is None:
                    raise self.error(f"the file ends inside node {node_id}")
                word = text.lower()
                if word == "end node":
                    break
                if _ASSIGN.match(text):
                    continue  # rframe = ..., and other node attributes
                if word not in _NODE_FIELDS:
                    raise self.error(f"node {node_id}: unknown entry {text!r}")
                parts[_NODE_FIELDS[word]] = self.taylor(text, n)
            for needed in ("origin", "phi"):
                if needed not in parts:
                    raise self.error(f"node {node_id} has no {needed}")
            if any(node.id == node_id for node in nodes):
                raise self.error(f"node {node_id} is defined twice")
            nodes.append(SidNode(node_id, **parts))

    def taylor(self, name: str, n: int) -> Taylor:
        start = self.index
        header: dict[str, int] = {}
        entries: list[tuple[str, tuple[int, ...], float, int]] = []
        while True:
            text = self.next()
            if text is None:
                raise self.error(f"the file ends inside {name} (begun on line {start})")
            if text.lower() == f"end {name.lower()}":
                break
            entry = _ENTRY.match(text)
            if entry:
                try:
                    index = tuple(int(v) for v in entry.group(2).split(","))
                except ValueError:
                    raise self.error(f"{name}: bad indices in {text!r}") from None
                entries.append(
                    (entry.group(1).lower(), index, self.real(entry.group(3)), self.index)
                )
                continue
            hit = _ASSIGN.match(text)
            if not hit or hit.group(1).lower() not in _HEADER:
                raise self.error(
                    f"{name}: expected a header ({', '.join(_HEADER)}) or an entry "
                    f"m0/m1/m2, found {text!r}"
                )
            header[hit.group(1).lower()] = self.integer(hit.group(3).strip())
        for key in ("order", "nrow", "ncol"):
            if key not in header:
                raise self.error(f"{name} (line {start}) has no {key}", line=start)
        order, nrow, ncol = header["order"], header["nrow"], header["ncol"]
        structure = header.get("structure", FULL)
        nq = header.get("nq", n)
        nqn = header.get("nqn", 0)
        if order not in (0, 1, 2) or nrow < 1 or ncol < 1 or structure not in (0, 1, 2, 3):
            raise self.error(
                f"{name}: order {order}, nrow {nrow}, ncol {ncol}, structure {structure} "
                "(order 0-2, sizes >= 1, structure 0-3)",
                line=start,
            )
        if order >= 1 and nq != n:
            raise self.error(f"{name}: nq = {nq} is not nelastq = {n}", line=start)
        if order == 2 and nqn != n:
            raise self.error(
                f"{name}: nqn = {nqn}; second-order terms must cover all nelastq = {n} coordinates",
                line=start,
            )
        entries_bytes = (
            8 * nrow * ncol * (1 + (n if order >= 1 else 0) + (n * n if order == 2 else 0))
        )
        if entries_bytes > _memory.available_memory():
            raise self.error(
                f"{name}: order {order} with nrow {nrow}, ncol {ncol} and nelastq {n} needs "
                f"{entries_bytes / 2**30:.1f} GB, more memory than is available",
                line=start,
            )
        m0 = np.zeros((nrow, ncol))
        m1 = np.zeros((nrow, ncol, n)) if order >= 1 else None
        m2 = np.zeros((nrow, ncol, n, n)) if order >= 2 else None
        arrays = {"m0": m0, "m1": m1, "m2": m2}
        for kind, index, value, line in entries:
            array = arrays[kind]
            if array is None or len(index) != array.ndim:
                raise self.error(f"{name}: entry {kind}{index} does not fit order {order}", line)
            if any(i < 1 or i > size for i, size in zip(index, array.shape, strict=True)):
                raise self.error(f"{name}: index {index} out of range {array.shape}", line)
            zero = tuple(i - 1 for i in index)
            array[zero] = value
            if structure == SYMMETRIC:
                array[(zero[1], zero[0]) + zero[2:]] = value
            if kind == "m2":
                array[zero[:2] + (zero[3], zero[2])] = value
                if structure == SYMMETRIC:
                    array[(zero[1], zero[0], zero[3], zero[2])] = value
        return Taylor(m0, m1, m2, structure)

    def real(self, text: str) -> float:
        try:
            value = float(text.replace("D", "E").replace("d", "e"))
        except ValueError:
            raise self.error(f"expected a number, found {text!r}") from None
        if not math.isfinite(value):
            raise self.error(f"non-finite number {text!r}")
        return value

    def integer(self, text: str) -> int:
        try:
            return int(text)
        except ValueError:
            raise self.error(f"expected an integer, found {text!r}") from None


__all__ = [
    "FIELD_ORDER",
    "SidData",
    "SidNode",
    "Taylor",
    "load_sid_data",
    "read_sid",
    "write_sid",
]
