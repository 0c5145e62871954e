"""``System``: the multibody system, with deformable bodies from the preprocessor.

The Rust class ``flexmbd._core.System`` builds rigid bodies, markers, joints and forces; this
subclass adds deformable bodies (a :class:`flexmbd.fe.FlexibleBodyData` in the floating frame
of reference, seed section 3) and markers on their nodes and node sets (the intermediate
joint frames of seed Figure 4).

It also records the calls that built it (``System.building_calls``): a pickled or copied
system, and a pickled model, is built again by the same calls, which gives the same model
bit for bit. Python callables in it (user time functions, callback forces) pickle with
:mod:`pickle` if they are importable functions and with ``cloudpickle`` (which Dask uses)
if they are lambdas or closures.
"""

from __future__ import annotations

import dataclasses
import weakref
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import _boundary, _core
from ._checks import choice, flag, id_text, integer, number, numbers_array, value_text
from .errors import (
    ArgumentTypeError,
    FlexmbdError,
    InvalidModelError,
    InvalidParameterError,
    ModelError,
    SingularMatrixError,
    UnknownItemError,
)
from .fe.body import FlexibleBodyData, Invariants, check_body
from .fe.interface import COUPLINGS, Interface, body_interface
from .rotation import euler_parameter_rates, euler_parameters_to_matrix

if TYPE_CHECKING:
    import scipy.sparse as sp

#: The units of the numbers of a deformable body that `System.add_flexible_body` takes.
SI_UNITS = {"length": "m", "mass": "kg", "time": "s"}


def _csc_tuple(
    m: Any, n: int
) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.int64], int]:
    """(data, indices, indptr, n) of a square matrix (dense or sparse), indices sorted,
    without duplicates and without stored zeros (a body of an earlier flexmbd's file kept
    its element patterns' zeros, which the core's products and patterns would carry). `m` is
    not changed: a body's matrices are read-only (and a CSC matrix of floats shares its
    arrays with `c`), so a matrix that is not canonical is mended in a copy."""
    import scipy.sparse as sp

    c = sp.csc_matrix(m, dtype=float)
    if c.shape != (n, n):
        raise InvalidParameterError(f"matrix of shape {c.shape}, expected ({n}, {n})")
    if not c.has_canonical_format or not np.all(c.data):
        c = c.copy()
        c.sum_duplicates()
        c.eliminate_zeros()
    return (
        np.ascontiguousarray(c.data, dtype=float),
        np.ascontiguousarray(c.indices, dtype=np.int64),
        np.ascontiguousarray(c.indptr, dtype=np.int64),
        n,
    )


def elastic_basis(body: FlexibleBodyData) -> sp.csr_matrix:
    """The matrix (n_nodal_dofs, n_f) that maps the elastic coordinates of `body` to its nodal
    displacements (zero at the dofs held by the reference conditions): the selection of the
    kept dofs for nodal bodies, the modal matrix B_m of seed eq. 18 for modal ones."""
    import scipy.sparse as sp

    free = np.asarray(body.reference.free_dofs, dtype=np.int64)
    n_dofs = body.dof_count
    if body.modes is None:
        return sp.csr_matrix(
            (np.ones(len(free)), (free, np.arange(len(free)))), shape=(n_dofs, len(free))
        )
    full = np.zeros((n_dofs, body.modes.shape[1]))
    full[free] = body.modes
    return sp.csr_matrix(full)


def unheld_frame_error(
    model: _core.Model, q: NDArray[np.float64], time: float, what: str = "matrix"
) -> SingularMatrixError | None:
    """The error for the first deformable body whose frame nothing fixes at coordinates `q`
    (:func:`unheld_frames`), naming the body, its free motions and the way out; None when
    every frame is held. `what`: the matrix that is singular, for the message."""
    frames = unheld_frames(model, q)
    if not frames:
        return None
    name, motions = frames[0]
    which = "all 6" if len(motions) == 6 else ", ".join(motions)
    return SingularMatrixError(
        f"body '{name}': nothing fixes its frame in the body, so the {what} at t = {time:g} "
        f"is singular: its reference conditions are 'none', and its nodal coordinates carry "
        f"the rigid motions its frame carries ({which}: the frame moved one way and the nodes "
        "back move no point). Give the body reference conditions (reference 'clamped' or "
        "'3-2-1' at reference_nodes, or 'mean-axis' with free-free modes), or hold its frame "
        "with a joint on a marker of the frame",
        item=f"body '{name}'",
        time=time,
    )


def unheld_frames(model: _core.Model, q: NDArray[np.float64]) -> list[tuple[str, list[str]]]:
    """The deformable bodies whose frame nothing fixes in the body, at coordinates q: those
    whose elastic coordinates can move the nodes rigidly (reference conditions "none" with
    nodal coordinates) where the constraints do not hold the frame. Moving such a frame
    rigidly and its nodes back, so that no point moves, changes neither the kinetic energy
    nor a constraint: the augmented matrix is singular. Each entry: the body's name and
    those motions ("translation along (1, 0, 0)", "rotation about body axis z")."""
    nq = model.coordinate_count
    zero_q, zero_l = np.zeros(nq), np.zeros(model.constraint_count)
    found: list[tuple[str, list[str]]] = []
    matrices = None
    layout = model.describe()
    for index, data in model.flexible_bodies.items():
        entry = layout["bodies"][index]
        o, count = entry["offset"], entry["count"]
        basis = elastic_basis(data)
        nodes = np.asarray(data.nodes, dtype=float)
        d = data.dofs_per_node
        u = nodes + (basis @ q[o + 7 : o + count]).reshape(-1, d)[:, :3]
        p = q[o + 3 : o + 7]
        rotation = euler_parameters_to_matrix(p)
        directions, names = [], []
        for k in range(6):
            nodal = np.zeros((len(nodes), d))
            v = np.zeros(nq)
            if k < 3:
                v[o + k] = 1.0
                nodal[:, :3] = -rotation[k]  # -A^T e_k in body axes
                names.append("translation along global " + "xyz"[k])
            else:
                theta = np.eye(3)[k - 3]
                v[o + 3 : o + 7] = euler_parameter_rates(p, theta, frame="body")
                nodal[:, :3] = -np.cross(theta, u)
                if d == 6:
                    nodal[:, 3:] = -theta
                names.append("rotation about body axis " + "xyz"[k - 3])
            g = nodal.ravel()
            x = basis.T @ g
            if not np.allclose(basis @ x, g, rtol=0.0, atol=1e-9 * max(1.0, np.abs(g).max())):
                break  # the elastic coordinates cannot carry it: the reference conditions fix it
            v[o + 7 : o + count] = x
            directions.append(v)
        if len(directions) < 6:
            continue
        if matrices is None:
            from .analysis import _matrix

            m = _matrix(model.evaluate(0.0, q, zero_q, zero_q, zero_l, mass=1.0))
            c = _matrix(model.evaluate(0.0, q, zero_q, zero_q, zero_l, position=1.0))
            matrices = (m[:nq, :nq], c[nq:, :nq])
        mass, jacobian = matrices
        v = np.column_stack(directions)
        scale = max(float(abs(mass).max()), 1e-300)
        if np.abs(mass @ v).max() > 1e-8 * scale * np.abs(v).max():
            continue  # not a motion without kinetic energy: the construction does not apply
        cv = np.asarray(jacobian @ v) if jacobian.shape[0] else np.zeros((1, 6))
        tolerance = 1e-8 * max(float(abs(jacobian).max()) if jacobian.shape[0] else 0.0, 1.0)
        singular = np.linalg.svd(cv, compute_uv=False)
        count = 6 - int(np.sum(singular > tolerance * np.abs(v).max()))
        if count:
            alone = [
                n for n, col in zip(names, cv.T, strict=True) if np.abs(col).max() <= tolerance
            ]
            found.append((entry["name"], alone or [f"{count} combinations of them"]))
    return found


def _node_index(body: FlexibleBodyData, node: int, item: str) -> int:
    """The index of the node of id `node` (an integer: 2.7 or True is refused, not cut to 2
    or 1) in the body's arrays."""
    node = integer(node, f"{item}: node id")
    ids = np.asarray(body.node_ids)
    hits = np.flatnonzero(ids == node)
    if len(hits) == 0:
        raise UnknownItemError(
            f"{item}: the body has no node with id {id_text(node)} (ids {ids.min()} .. "
            f"{ids.max()})",
            item=item,
        )
    return int(hits[0])


def _node_shapes(
    body: FlexibleBodyData, basis: sp.csr_matrix, index: int
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Displacement and small-rotation rows (3, n_f) of a node: u = T q_f, theta = R q_f."""
    d = body.dofs_per_node
    rows = basis[index * d : (index + 1) * d].toarray()
    translation = rows[:3]
    rotation = rows[3:6] if d == 6 else np.zeros_like(translation)
    return translation, rotation


def _compress(
    translation: NDArray[np.float64], rotation: NDArray[np.float64], modal: bool
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
    """Keeps the elastic coordinates a marker depends on (all of them for modal bodies)."""
    if modal:
        columns = np.arange(translation.shape[1])
    else:
        columns = np.flatnonzero(np.any(translation != 0, axis=0) | np.any(rotation != 0, axis=0))
    return (
        columns.astype(np.int64),
        np.ascontiguousarray(translation[:, columns]),
        np.ascontiguousarray(rotation[:, columns]),
    )


def _scalar_mass(body: FlexibleBodyData, free: NDArray[np.int64]) -> Any:
    """(M_s, kept coordinates) of a body of solids whose nodal mass matrix is M_s (x) I_3 (the
    fast products of `ScalarMass` in the core), else None."""
    import scipy.sparse as sp

    if body.dofs_per_node != 3:
        return None
    mass = sp.csr_matrix(body.mass)
    scalar = mass[0::3, 0::3].tocsc()
    if abs(sp.kron(scalar, sp.identity(3), format="csr") - mass).max() > 1e-12 * abs(mass).max():
        return None
    return _csc_tuple(scalar, scalar.shape[0]), np.ascontiguousarray(free, dtype=np.int64)


def _check_rigid(
    body: FlexibleBodyData,
    basis: sp.csr_matrix,
    interface: Interface,
    translation: NDArray[np.float64],
    rotation: NDArray[np.float64],
    item: str,
) -> None:
    """Raises unless every elastic coordinate moves the interface's nodes rigidly (RBE2)."""
    import scipy.sparse as sp

    d = body.dofs_per_node
    dofs = (interface.members[:, None] * d + np.arange(3)).ravel()
    motion = basis[dofs]
    motion = np.asarray(motion.todense()) if sp.issparse(motion) else np.asarray(motion)
    rigid = interface.rigid_map(3) @ np.vstack([translation, rotation])
    size = max(float(np.abs(motion).max(initial=0.0)), 1e-300)
    deviation = float(np.abs(motion - rigid).max(initial=0.0))
    if deviation > 1e-8 * size:
        advice = (
            "build its modes with this set as an 'rbe2' Craig-Bampton interface "
            "(build_body(..., interfaces=[...], interface_kind='rbe2'))"
            if body.modes is not None
            else "its nodes are elastic coordinates of a nodal body; reduce it with an 'rbe2' "
            "Craig-Bampton interface on this set"
        )
        raise InvalidModelError(
            f"{item}: coupling 'rbe2' needs the nodes to move rigidly, but the body's elastic "
            f"coordinates deform the set (relative deviation {deviation / size:.1e}): {advice}, "
            "or use coupling='rbe3'",
            item=item,
        )


def _offset_masses(body: FlexibleBodyData) -> bool:
    """Whether a meshed beam or shell body has a point mass whose centre is offset from its
    node (from its record; bodies of older files without one: no)."""
    record = body.point_masses
    return record is not None and bool(np.any(record["offset"]))


def _attached_masses(body: FlexibleBodyData, basis: sp.csr_matrix) -> list[tuple[Any, ...]]:
    """The point masses of a meshed beam or shell body that have a rotary inertia or an
    offset (`build_body`'s `point_masses`: its record, or for bodies of older files, its mass
    matrix beyond its elements'), as the core's attached masses (`body/flexible/attached.rs`):
    the columns q_l their node depends on, the node's rows [u; theta] of `basis` (6, n_l),
    its position and mass points with the mass's mass, centre and second moments
    (:func:`mass_points`). The invariants hold these masses turning with the node's small
    rotation linearly; the core adds the second order of that turn."""
    from .fe.body_variants import _has_mesh, recorded_point_masses

    if body.dofs_per_node != 6 or not _has_mesh(body):
        return []
    try:
        lumps = recorded_point_masses(body)
    except (FlexmbdError, KeyError, TypeError, ValueError):
        # A body whose elements cannot be assembled again (a body file's section without its
        # moments) or whose mass beyond them is not point masses: its masses, if any, keep the
        # linear motion of the invariants, as a body without a mesh.
        return []
    attached = []
    for node, lump in sorted(lumps.items()):
        if not isinstance(lump, tuple):
            continue
        mass, inertia, offset = lump
        scale = max(abs(mass), 1e-300)
        if np.abs(inertia).max() <= 1e-12 * scale * max(np.abs(body.nodes).max(), 1.0) ** 2 and (
            np.abs(offset).max() == 0.0
        ):
            continue
        masses, points = mass_points(mass, inertia, offset)
        rows = basis[6 * node : 6 * node + 6].toarray()
        columns = np.flatnonzero(np.any(rows != 0, axis=0))
        if len(columns) == 0:
            continue  # (a node held by the reference conditions: it does not move)
        attached.append(
            (
                columns.astype(np.int64),
                np.ascontiguousarray(rows[:, columns]),
                np.asarray(body.nodes[node], dtype=float),
                masses,
                points,
            )
        )
    return attached


def mass_points(
    mass: float, inertia: ArrayLike, offset: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Point masses and their positions relative to a node with the mass `mass`, the centre
    `offset` and the rotary inertia `inertia` (3, 3) about the centre. The forces of the
    core's attached masses depend on the mass, centre and second moments P = tr(J) / 2 I - J
    only, so the fewest points that give them serve: the centre alone without an inertia;
    four equal masses at the corners of a regular tetrahedron stretched by sqrt(3 P / m)
    about it; for a P with a negative direction (an inertia no mass distribution has) or no
    mass, the centre with what is left of the mass and a pair at +-r v_k along each principal
    direction v_k of P with the masses p_k / (2 r^2) (r = 1 m; masses may be negative).

    Raises `InvalidParameterError` for a mass that is not a finite number, an inertia that
    is not a finite symmetric (3, 3) matrix or an offset that is not three finite numbers."""
    mass = number(mass, "mass")
    inertia = numbers_array(inertia, "inertia")
    offset = numbers_array(offset, "offset")
    scale = float(np.abs(inertia).max(initial=0.0)) if np.all(np.isfinite(inertia)) else 0.0
    if (
        inertia.shape != (3, 3)
        or not np.all(np.isfinite(inertia))
        or np.abs(inertia - inertia.T).max() > 1e-12 * scale
    ):
        raise InvalidParameterError(
            f"mass_points: the inertia must be a finite symmetric (3, 3) matrix, got "
            f"{inertia.tolist()}",
            item="inertia",
        )
    if offset.shape != (3,) or not np.all(np.isfinite(offset)):
        raise InvalidParameterError(
            f"mass_points: the offset must be three finite numbers, got {offset.tolist()}",
            item="offset",
        )
    moments, directions = np.linalg.eigh(np.trace(inertia) / 2 * np.eye(3) - inertia)
    moments[np.abs(moments) <= 1e-12 * np.abs(moments).max(initial=0.0)] = 0.0  # (round-off)
    if not np.any(moments):
        return np.array([float(mass)]), offset.reshape(1, 3).copy()
    if mass > 0 and moments.min() >= 0:
        corners = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]]) / np.sqrt(3)
        stretch = directions @ np.diag(np.sqrt(3 * moments / mass)) @ directions.T
        return np.full(4, mass / 4), np.ascontiguousarray(offset + corners @ stretch)
    masses, points = [], []
    for value, direction in zip(moments, directions.T, strict=True):
        for side in (1.0, -1.0):
            masses.append(value / 2)
            points.append(offset + side * direction)
    masses.insert(0, mass - sum(masses))
    points.insert(0, offset)
    return np.asarray(masses), np.ascontiguousarray(np.asarray(points))


def _stiffening_elements(
    body: FlexibleBodyData, basis: sp.csr_matrix, item: str
) -> list[tuple[Any, ...]]:
    """The elements of the geometric stiffness (`body/stiffening.rs`): for each beam, the map
    (12, n_l) from the elastic coordinates to its nodal coordinates in element axes, its
    length and EA; for each shell ("quad4", "tri3"), the map (n_e, n_l) and its membrane
    terms (linear strains, von Karman matrices, area D_m; `fem::membrane_stiffening`)."""
    conn = body.elements.get("beam2")
    beams = conn is not None and len(conn) > 0 and body.section is not None
    shells = body.shell is not None and any(
        len(body.elements.get(kind, ())) for kind in ("quad4", "tri3")
    )
    if not (beams or shells):
        raise InvalidModelError(
            f"{item}: geometric stiffness is available for beam and shell elements; the body "
            "has none",
            item=item,
        )
    d = body.dofs_per_node
    modal = body.modes is not None
    elements: list[tuple[Any, ...]] = []

    def mapped(
        nodes: NDArray[np.int64], rot: NDArray[np.float64], tie: NDArray[np.float64] | None = None
    ) -> tuple[Any, Any]:
        rows = np.concatenate([np.arange(n * d, n * d + 6) for n in nodes])
        grids = basis[rows].toarray()
        local = np.kron(np.eye(2 * len(nodes)), rot) @ (grids if tie is None else tie @ grids)
        columns = np.arange(local.shape[1]) if modal else np.flatnonzero(np.any(local != 0, axis=0))
        return columns.astype(np.int64), np.ascontiguousarray(local[:, columns])

    if beams:
        ea = float(body.material["young_modulus"]) * float(body.section["area"])
        ends = _beam_end_maps(body, conn)
        for k, (a, b) in enumerate(np.asarray(conn, dtype=np.int64)):
            if ends is not None and (ends.releases[k, 0] or ends.releases[k, 6]):
                continue  # (released along its axis: no axial force, no geometric stiffness)
            # The element's axis: between its nodes, or its offset ends tied to them.
            axis = (
                body.nodes[b] - body.nodes[a] if ends is None else np.diff(ends.ends[k], axis=0)[0]
            )
            length = float(np.linalg.norm(axis))
            ex = axis / length
            helper = np.eye(3)[int(np.argmin(np.abs(ex)))]
            ey = helper - ex * (helper @ ex)
            ey /= np.linalg.norm(ey)
            rot = np.vstack([ex, ey, np.cross(ex, ey)])
            columns, local = mapped(np.array([a, b]), rot, None if ends is None else ends.maps[k])
            elements.append((columns, local, length, ea))
    if shells:
        section = _core.ShellSection(
            float(body.shell["thickness"]),
            shear_factor=float(body.shell.get("shear_factor", 5.0 / 6.0)),
        )
        material = _core.Material(
            body.material["young_modulus"], body.material["poisson_ratio"], body.material["density"]
        )
        for kind in ("quad4", "tri3"):
            for element in np.asarray(body.elements.get(kind, np.zeros((0, 3))), dtype=np.int64):
                nodes = np.ascontiguousarray(body.nodes[element], dtype=float)
                axes, linear, slopes, stiffness = _core.shell_membrane_stiffening(
                    nodes, section, material
                )
                columns, local = mapped(element, np.asarray(axes))
                elements.append((columns, local, linear, slopes, stiffness))
    return elements


def _beam_end_maps(body: FlexibleBodyData, conn: Any) -> Any:
    """The ties (`flexmbd.fe.beam_ends.EndMaps`) of a body's beams with offsets or released
    coordinates, or None without them."""
    from .fe.beam_ends import end_maps, recorded_ends
    from .fe.body_variants import _section

    offsets, releases = recorded_ends(body.section)
    if offsets is None and releases is None:
        return None
    section, orientation, theory = _section(body)
    return end_maps(
        body.nodes,
        np.asarray(conn, dtype=np.int64),
        offsets,
        releases,
        material=_core.Material(
            body.material["young_modulus"],
            body.material["poisson_ratio"],
            body.material["density"],
        ),
        section=section,
        orientation=orientation,
        shear=theory == "timoshenko",
    )


GEOMETRIC_STIFFNESS = ("von-karman", "corotational")
"""The kinds of `System.add_flexible_body(geometric_stiffness=...)` besides True and False."""


def geometric_stiffness_kind(value: Any, item: str) -> str | None:
    """The `geometric_stiffness` option: False -> None, True -> "von-karman", or one of
    `GEOMETRIC_STIFFNESS`; another value is an `ArgumentTypeError` (not a bool or a string) or
    an `InvalidParameterError` (another string), naming the parameter and the body."""
    if isinstance(value, bool | np.bool_):
        return "von-karman" if value else None
    if not isinstance(value, str):
        raise ArgumentTypeError(
            f"{item}: geometric_stiffness must be True, False, 'von-karman' or 'corotational', "
            f"got {value_text(value)}",
            item="geometric_stiffness",
        )
    return choice(value, "geometric_stiffness", GEOMETRIC_STIFFNESS, item)


def _corotational_elements(
    body: FlexibleBodyData, basis: sp.csr_matrix, item: str
) -> list[tuple[Any, ...]]:
    """The elements of the co-rotational elastic forces (`body/corotational.rs`): for each
    beam, the map (12, n_l) from the elastic coordinates to its nodal coordinates in the
    element's axes (those of its section), its length and its local stiffness matrix."""
    from .fe.beam_ends import recorded_ends
    from .fe.body_variants import _section

    if body.modes is not None:
        raise InvalidModelError(
            f"{item}: geometric_stiffness='corotational' needs a nodal body (its nodal "
            "translations are the exact positions the chords are measured from); this body is "
            "modal: use geometric_stiffness=True (von Karman) or build it without modes",
            item=item,
        )
    if body.shell is not None and any(
        len(body.elements.get(kind, ())) for kind in ("quad4", "tri3")
    ):
        raise InvalidModelError(
            f"{item}: geometric_stiffness='corotational' is available for beams only; the body "
            "has shell elements: use geometric_stiffness=True (von Karman) for shells",
            item=item,
        )
    conn = body.elements.get("beam2")
    if conn is None or len(conn) == 0 or body.section is None:
        raise InvalidModelError(
            f"{item}: geometric_stiffness='corotational' is available for beam elements; the "
            "body has none",
            item=item,
        )
    offsets, releases = recorded_ends(body.section)
    if offsets is not None or releases is not None:
        given = " and ".join(
            what
            for what, value in (("offsets", offsets), ("released coordinates", releases))
            if value is not None
        )
        raise InvalidModelError(
            f"{item}: geometric_stiffness='corotational' does not take beams with {given} "
            "(beam_offsets, beam_releases; Nastran's WA, WB and pin flags): their ties to the "
            "nodes are linear in the nodal rotations, which the co-rotated chord turns "
            "finitely; use geometric_stiffness=True (von Karman), which takes them",
            item=item,
        )
    section, orientation, theory = _section(body)
    material = _core.Material(
        body.material["young_modulus"], body.material["poisson_ratio"], body.material["density"]
    )
    d = body.dofs_per_node
    elements: list[tuple[Any, ...]] = []
    for a, b in np.asarray(conn, dtype=np.int64):
        nodes = np.ascontiguousarray(body.nodes[[a, b]], dtype=float)
        axes, length, stiffness = _core.beam_corotational_terms(
            nodes,
            section,
            material,
            None if orientation is None else list(orientation),
            theory == "timoshenko",
        )
        rows = np.concatenate([np.arange(n * d, n * d + 6) for n in (a, b)])
        local = np.kron(np.eye(4), np.asarray(axes)) @ basis[rows].toarray()
        columns = np.flatnonzero(np.any(local != 0, axis=0)).astype(np.int64)
        elements.append(
            (columns, np.ascontiguousarray(local[:, columns]), float(length), stiffness)
        )
    return elements


class _Negated:
    """-f(t) of a time function f that has no negated form of its own (a callable, a
    `UserFunction`); picklable when f is."""

    def __init__(self, function: Any):
        self.function = function

    def __call__(self, t: float) -> Any:
        value = self.function(t)
        if isinstance(value, tuple | list | np.ndarray):  # (f, f', f'') of `derivatives`
            return tuple(-float(v) for v in value)
        return -float(value)


def negated(function: Any) -> Any:
    """The time function -f(t): of the same kind for numbers, `Constant`, `Polynomial`,
    `Harmonic`, `Spline`, `Step` and `Trapezoidal` (their derivatives stay exact), else a
    `UserFunction` of -f(t)."""
    f = function
    if isinstance(f, int | float | np.floating | np.integer):
        return -float(f)
    if isinstance(f, _core.Constant):
        return _boundary.Constant(-f.value)
    if isinstance(f, _core.Polynomial):
        return _boundary.Polynomial([-c for c in f.coefficients])
    if isinstance(f, _core.Harmonic):
        return _boundary.Harmonic(-f.amplitude, f.frequency, f.phase, -f.offset)
    if isinstance(f, _core.Spline):
        slopes = None if f.slopes is None else (-f.slopes[0], -f.slopes[1])
        return _boundary.Spline(f.times, [-v for v in f.values], f.end, slopes)
    if isinstance(f, _core.Step):
        return _boundary.Step(f.start_time, f.end_time, -f.start_value, -f.end_value, f.shape)
    if isinstance(f, _core.Trapezoidal):
        return _boundary.Trapezoidal(
            f.start_time, f.end_time, -f.start_value, -f.end_value, f.blend
        )
    if isinstance(f, _core.UserFunction):
        # (its `derivatives` flag is shadowed by the method of that name: read it from the
        # constructor's arguments)
        function, returns = f.__getnewargs__()
        return _boundary.UserFunction(_Negated(function), bool(returns))
    return _boundary.UserFunction(_Negated(f))


class System(_core.System):
    """A multibody system under construction. Body 0 (``system.ground``) is the fixed frame.

    Units are SI by convention (m, kg, s, N, rad). Orientations are 3 x 3 rotation matrices
    whose columns are the local axes in the parent frame. Marker z axes are joint axes.
    Besides rigid bodies and point masses it holds deformable bodies
    (:meth:`add_flexible_body`) with markers on their nodes (:meth:`add_node_marker`) and node
    sets (:meth:`add_node_set_marker`).
    """

    def __init__(self, gravity: ArrayLike | None = None):

        self._flexible: dict[int, FlexibleBodyData] = {}
        self._bases: dict[int, sp.csr_matrix] = {}
        self._calls: list[_Call] = [("gravity", (_kept(gravity),), {})]
        self._depth = 0
        #: The identity the ids this system returns carry (`_core.BodyId._system`, ...).
        self._identity = _new_identity()
        #: The names given to its items: (id type name, index) -> name or None.
        self._names: dict[tuple[str, int], str | None] = {}
        _SYSTEMS[self._identity] = self

    @property
    def building_calls(self) -> tuple[_Call, ...]:
        """The calls that built this system, in order: (method name, positional arguments,
        keyword arguments), the first setting the gravity. Arrays are copies, taken at the
        call."""
        return tuple(self._calls)

    @property
    def gravity(self) -> tuple[float, float, float]:
        """Gravitational acceleration (m/s^2, global axes)."""
        return _core.System.gravity.__get__(self)

    @gravity.setter
    def gravity(self, value: ArrayLike) -> None:
        _core.System.gravity.__set__(self, value)
        self._calls.append(("gravity", (_kept(value),), {}))

    def __reduce__(self) -> tuple[Any, ...]:
        return (_rebuilt, (type(self), tuple(self._calls), self._identity))

    def with_driver(self, name: str, function: Any) -> System:
        """A copy of this system whose driver `name` (an angle or translation driver) follows
        `function` (a time function) instead; the system itself is not changed. Raises
        `UnknownItemError` naming the drivers when there is none of that name."""
        drivers = ("add_angle_driver", "add_translation_driver")
        calls, found = [], []
        for method, args, kwargs in self._calls:
            if method in drivers:
                found.append(kwargs.get("name"))
                if kwargs.get("name") == name:
                    if len(args) >= 3:
                        args = (*args[:2], function, *args[3:])
                    else:
                        key = "angle" if method == "add_angle_driver" else "displacement"
                        kwargs = {**kwargs, key: function}
            calls.append((method, args, kwargs))
        if name not in found:
            known = [n for n in found if n is not None]
            raise UnknownItemError(f"no driver named {name!r}; drivers: {known}", item=name)
        return _rebuilt(type(self), tuple(calls), self._identity)

    def with_drivers_as_efforts(self, efforts: dict[str, Any]) -> System:
        """A copy of this system whose drivers named in `efforts` no longer prescribe their
        joints' motion but apply the given efforts (time functions: a torque for an angle
        driver, a force for a translation driver) on the joints they drive, as joint
        actuators of zero gains (``NAME effort``): the free mechanism of an inverse-dynamics
        run, driven by its efforts. A driver whose markers are the joint's in the other order
        measures the joint's coordinate with the other sign: its effort acts negated. Raises
        `UnknownItemError` for a name that is not a driver, `InvalidModelError` for a driver
        with no revolute, prismatic or cylindrical joint on its markers."""
        drivers = {"add_angle_driver": "angle", "add_translation_driver": "slide"}
        kinds = {
            "angle": ("add_revolute_joint", "add_cylindrical_joint"),
            "slide": ("add_prismatic_joint", "add_cylindrical_joint"),
        }
        calls: list[_Call] = []
        renumbered: dict[int, int] = {}
        joints: list[tuple[str, tuple[Any, Any], int]] = []
        replaced: list[tuple[str, str, tuple[Any, Any]]] = []
        found = []
        old = 0
        for method, args, kwargs in self._calls:
            adds_joint = method.startswith("add_") and method.endswith(("_joint", "_driver"))
            if method in drivers:
                found.append(kwargs.get("name"))
            markers = (
                (args + (None, None))[:2]
                if len(args) >= 2
                else (kwargs.get("marker1"), kwargs.get("marker2"))
            )
            if method in drivers and kwargs.get("name") in efforts:
                replaced.append((kwargs["name"], drivers[method], markers))
            else:
                if adds_joint:
                    renumbered[old] = len(renumbered)
                    joints.append((method, markers, renumbered[old]))
                if method == "add_joint_actuator":
                    if args:
                        args = (_core.JointId(renumbered[args[0].index]), *args[1:])
                    else:
                        joint = _core.JointId(renumbered[kwargs["joint"].index])
                        kwargs = {**kwargs, "joint": joint}
                calls.append((method, args, kwargs))
            old += adds_joint
        unknown = [name for name in efforts if name not in found]
        if unknown:
            known = [n for n in found if n is not None]
            raise UnknownItemError(
                f"no driver named {unknown[0]!r}; drivers: {known}", item=unknown[0]
            )
        # The ids of this system hold in the copy unless a removed driver moved the joints
        # after it down: then the copy is another system, whose accessors refuse a moved
        # joint's old id naming both joints (it named the next joint: a hinge's reaction
        # came out as the elbow's).
        moved = any(new != old for old, new in renumbered.items())
        system = _rebuilt(type(self), tuple(calls), None if moved else self._identity)
        for name, coordinate, markers in replaced:
            # The joint on the driver's markers; on them in the other order, its coordinate
            # is the driver's negated (a hinge's angle of i from j about z_j against the
            # driver's of j from i about z_i: z_i = z_j), and so is the effort on it (these
            # drivers were refused).
            sign, joint = next(
                (
                    (1.0 if at == markers else -1.0, index)
                    for method, at, index in joints
                    if method in kinds[coordinate] and at in (markers, markers[::-1])
                ),
                (1.0, None),
            )
            if joint is None:
                raise InvalidModelError(
                    f"driver {name!r} drives no {' or '.join(k[4:-6] for k in kinds[coordinate])} "
                    "joint on its markers: its effort has no joint to act on",
                    item=name,
                )
            extra = (
                {"coordinate": coordinate} if joints[joint][0] == "add_cylindrical_joint" else {}
            )
            system.add_joint_actuator(
                _core.JointId(joint),
                0.0,
                proportional_gain=0.0,
                feed_forward=efforts[name] if sign > 0 else negated(efforts[name]),
                name=f"{name} effort",
                **extra,
            )
        return system

    def without_loads(self) -> System:
        """A copy of this system without its applied loads (point forces and torques) and
        without gravity: the structure alone, with its bodies, joints, drivers, springs,
        actuators and callback forces (which may be elastic elements). The system itself is
        not changed; the ids of its bodies, markers, joints and sensors hold in the copy."""
        loads = ("add_point_force", "add_torque")
        calls = [call for call in self._calls if call[0] not in loads]
        calls = [("gravity", ((0.0, 0.0, 0.0),), {}) if c[0] == "gravity" else c for c in calls]
        return _rebuilt(type(self), tuple(calls), self._identity)

    def driver_function(self, name: str) -> Any:
        """The time function of the driver `name` as it was given."""
        for method, args, kwargs in self._calls:
            if method in ("add_angle_driver", "add_translation_driver"):
                if kwargs.get("name") == name:
                    if len(args) >= 3:
                        return args[2]
                    return kwargs.get("angle", kwargs.get("displacement"))
        raise UnknownItemError(f"no driver named {name!r}", item=name)

    def add_rigid_body(
        self,
        mass: float,
        inertia: ArrayLike,
        *,
        center_of_mass: ArrayLike | None = None,
        position: ArrayLike | None = None,
        orientation: ArrayLike | None = None,
        velocity: ArrayLike | None = None,
        angular_velocity: ArrayLike | None = None,
        name: str | None = None,
    ) -> _core.BodyId:
        body = super().add_rigid_body(
            mass,
            inertia,
            center_of_mass=center_of_mass,
            position=position,
            orientation=orientation,
            velocity=velocity,
            angular_velocity=angular_velocity,
            name=name,
        )
        _check_inertia(inertia, f"body {name!r}" if name else f"body {body.index}")
        return body

    add_rigid_body.__doc__ = _core.System.add_rigid_body.__doc__

    def add_flexible_body(
        self,
        body: FlexibleBodyData,
        *,
        position: ArrayLike | None = None,
        orientation: ArrayLike | None = None,
        velocity: ArrayLike | None = None,
        angular_velocity: ArrayLike | None = None,
        elastic_coordinates: ArrayLike | None = None,
        elastic_velocities: ArrayLike | None = None,
        rayleigh_damping: tuple[float, float] | None = None,
        modal_damping: float | None = None,
        geometric_stiffness: bool | str = False,
        condense: bool | None = None,
        name: str | None = None,
    ) -> _core.BodyId:
        """Adds a deformable body in the floating frame of reference (seed eq. 15).

        `body` comes from the preprocessor (:func:`flexmbd.fe.build_body`,
        :func:`flexmbd.fe.load_body`, ...); its node coordinates are in the body frame, which
        `position` and `orientation` place. `velocity` (of the body origin) and
        `angular_velocity` are global. `elastic_coordinates` and `elastic_velocities` (n_f)
        start the body deformed (default, None: undeformed, at rest); an array of another
        length (also an empty one) is an `InvalidParameterError` naming the parameter.

        Damping: `rayleigh_damping=(alpha, beta)` gives D_ff = alpha M_ff + beta K_ff;
        `modal_damping=zeta` (modal bodies) the damping ratio zeta in every mode of the
        reduced body. Without either, the body's own damping applies
        (:meth:`flexmbd.fe.FlexibleBodyData.with_damping`; none by default).

        `geometric_stiffness=True` adds the elastic coupling of the beam elements (seed
        section 6): the nonlinear axial strain u' + (v'^2 + w'^2)/2, whose tangent is the
        geometric stiffness of the axial force; and of the shell elements: the membrane
        strains with the von Karman terms of the deflection. Needed for beams and plates that
        rotate fast (without it a beam spun beyond its first bending frequency diverges).
        Modal bodies need axial (membrane) modes for it to act. ``"von-karman"`` is the same
        as True. ``geometric_stiffness="corotational"`` (nodal beam bodies) instead measures
        each beam element's energy in the frame of its current chord (axial stretch from the
        chord length, bending and torsion from the nodal rotations relative to the chord's
        rotation): exact for any turn of an element within the body in a plane of its section
        axes, and the body converges to the geometrically exact beam under refinement, where
        the von Karman strain stays slightly too flexible at large deflections (e.g. 0.4 % in
        the spin-up R3); see ``docs/flexible-bodies.md`` for its limits in 3D. Modal bodies
        and shells refuse it (`InvalidModelError` naming the body).

        `condense` (default: for bodies of at least 300 elastic coordinates, but not those
        with a point mass offset from its node, whose condensed solves do not converge) makes
        the linear solves of the integrator eliminate the elastic coordinates through the
        constant factorized matrix beta' M_ff + gamma' D_ff + K_ff (see
        ``docs/solvers.md``): one sparse Cholesky factorization for the whole run instead of
        refactorizing the body.

        Raises `InvalidModelError` for body data without invariants of motion, not in SI
        units (``body.units`` must be m, kg, s) or with fields that do not fit each other, and
        `InvalidParameterError` for non-finite values, a non-positive mass or a second moment
        of mass that is not positive semi-definite (see :func:`flexmbd.fe.body.check_body`);
        the message names the body and the field. Raises `ArgumentTypeError` (an
        `InvalidParameterError`) naming the parameter for an argument of the wrong type:
        `elastic_coordinates` and `elastic_velocities` that are not numbers, a
        `modal_damping` that is not a number, `condense` that is not True or False, a
        `geometric_stiffness` that is not True, False or a string (another string than
        "von-karman" or "corotational": `InvalidParameterError`).
        """
        import scipy.sparse as sp

        item = f"body '{name}'" if name else "flexible body"
        if not isinstance(body, FlexibleBodyData):
            raise InvalidParameterError(
                f"{item}: expected a FlexibleBodyData (from flexmbd.fe), got {type(body).__name__}"
            )
        if elastic_coordinates is not None:
            elastic_coordinates = np.ascontiguousarray(
                numbers_array(elastic_coordinates, "elastic_coordinates", item).ravel()
            )
        if elastic_velocities is not None:
            elastic_velocities = np.ascontiguousarray(
                numbers_array(elastic_velocities, "elastic_velocities", item).ravel()
            )
        stiffening_kind = geometric_stiffness_kind(geometric_stiffness, item)
        condense = None if condense is None else flag(condense, "condense", item)
        if condense is None and _offset_masses(body):
            # The condensed solves do not converge with a mass offset from its node (a
            # 60-element beam with 0.8 kg 7 cm off its tip, at 2 rad/s: Newton contracts
            # at 0.3 from t = 0 even at h = 1e-4; at 20 rad/s the steps shrink to 3e-9 s),
            # with or without the second order of its turn: such bodies are solved whole.
            condense = False
        if modal_damping is not None:
            try:
                modal_damping = number(modal_damping, "modal_damping", finite=False)
            except InvalidParameterError as error:
                raise ArgumentTypeError(f"{item}: {error}", item=error.item) from None
        inv = body.invariants
        # A body has all its invariants (its constructor checks); not one changed past it
        # (object.__setattr__).
        missing = [
            entry.name
            for entry in dataclasses.fields(Invariants)
            if getattr(inv, entry.name, None) is None
        ]
        if missing:
            raise InvalidModelError(
                f"{item}: the body data has no invariants {missing} (run the preprocessor, "
                "or load a body file written by it)",
                item=item,
            )
        # The core computes in SI units and takes the body's numbers as they are.
        units = {key: body.units.get(key) for key in SI_UNITS}
        if units != SI_UNITS:
            raise InvalidModelError(
                f"{item}: the body data is in units {units}, not SI {SI_UNITS}: rebuild it from "
                "a mesh in metres with a material in SI units",
                item=item,
            )
        # Shapes, finiteness and the physics of the invariants, before the core sees them.
        try:
            check_body(body)
        except ModelError as error:
            raise type(error)(f"{item}: {error}", item=error.item) from None
        from .fe.body_variants import rayleigh_coefficients

        n = body.elastic_coordinate_count
        # An empty or short array is not "undeformed": only None is (the core reads an empty
        # array as None).
        for parameter, values in (
            ("elastic_coordinates", elastic_coordinates),
            ("elastic_velocities", elastic_velocities),
        ):
            if values is not None and len(values) != n:
                raise InvalidParameterError(
                    f"{item}: {parameter} must have {n} entries (the body has {n} elastic "
                    f"coordinates), got {len(values)}",
                    item=parameter,
                )
        # The body's own damping (FlexibleBodyData.with_damping) unless an argument is given.
        if rayleigh_damping is None and modal_damping is None and body.damping is not None:
            rayleigh_damping = body.damping.get("rayleigh")
            modal_damping = body.damping.get("modal")
        damping = sp.csc_matrix((n, n))
        if rayleigh_damping is not None:
            alpha, beta = rayleigh_coefficients(rayleigh_damping, item)
            damping = damping + alpha * sp.csc_matrix(inv.m_ff) + beta * sp.csc_matrix(inv.k_ff)
        if modal_damping is not None:
            damping = damping + sp.csc_matrix(self._modal_damping(body, modal_damping, item))
        i_kl = [_csc_tuple(inv.i_kl[k][j], n) for k in range(3) for j in range(3)]
        basis = elastic_basis(body)
        stiffening = (
            _stiffening_elements(body, basis, item) if stiffening_kind == "von-karman" else None
        )
        corotational = (
            _corotational_elements(body, basis, item) if stiffening_kind == "corotational" else None
        )
        # Nodes of the elastic coordinates of nodal bodies: the geometric nested-dissection
        # ordering of their factorizations.
        dof_nodes = node_positions = scalar_mass = None
        if body.modes is None:
            free = np.asarray(body.reference.free_dofs, dtype=np.int64)
            dof_nodes = np.ascontiguousarray(free // body.dofs_per_node, dtype=np.int64)
            node_positions = np.ascontiguousarray(body.nodes, dtype=float)
            scalar_mass = _scalar_mass(body, free)
        body_id = self._add_flexible_body(
            mass=float(inv.mass),
            first_moment=np.asarray(inv.first_moment, dtype=float),
            second_moment=np.asarray(inv.second_moment, dtype=float),
            i1=np.ascontiguousarray(np.asarray(inv.i1, dtype=float).reshape(3, n)),
            ibar=np.ascontiguousarray(np.asarray(inv.ibar, dtype=float).reshape(9, n)),
            i_kl=i_kl,
            stiffness=_csc_tuple(inv.k_ff, n),
            damping=_csc_tuple(damping, n),
            position=position,
            orientation=orientation,
            velocity=velocity,
            angular_velocity=angular_velocity,
            elastic_coordinates=elastic_coordinates,
            elastic_velocities=elastic_velocities,
            stiffening=stiffening,
            corotational=corotational,
            dof_nodes=dof_nodes,
            node_positions=node_positions,
            condense=condense,
            scalar_mass=scalar_mass,
            attached=_attached_masses(body, basis) or None,
            name=name,
        )
        self._flexible[body_id.index] = body
        self._bases[body_id.index] = basis
        return body_id

    @staticmethod
    def _modal_damping(body: FlexibleBodyData, zeta: float, item: str) -> NDArray[np.float64]:

        if body.modes is None:
            raise InvalidModelError(
                f"{item}: modal damping needs a modal body; use rayleigh_damping for nodal bodies",
                item=item,
            )
        if not (np.isfinite(zeta) and zeta >= 0):
            raise InvalidParameterError(f"{item}: modal damping ratio must be >= 0, got {zeta}")
        from .fe.body_variants import modal_damping_matrix

        return modal_damping_matrix(body.invariants.k_ff, body.invariants.m_ff, zeta)

    def _flexible_data(self, body: _core.BodyId, item: str) -> tuple[FlexibleBodyData, Any]:
        index = body.index if isinstance(body, _core.BodyId) else int(body)
        if index not in self._flexible:
            raise InvalidModelError(f"{item}: body {index} is not a deformable body", item=item)
        return self._flexible[index], self._bases[index]

    def add_node_marker(
        self,
        body: _core.BodyId,
        node: int,
        *,
        orientation: ArrayLike | None = None,
        name: str | None = None,
    ) -> _core.MarkerId:
        """Adds a marker at node `node` (its id in the mesh) of a deformable body: it moves with
        the node and, on beams and shells, turns with the node's small rotations (the
        intermediate joint frame of seed Figure 4). A node of a solid has no rotation of its
        own: its marker turns with the body frame only; use :meth:`add_node_set_marker` on a
        face for joints that transmit moments. `orientation` is in the body frame."""
        item = f"marker '{name}'" if name else "node marker"
        data, basis = self._flexible_data(body, item)
        index = _node_index(data, node, item)
        translation, rotation = _node_shapes(data, basis, index)
        columns, t, r = _compress(translation, rotation, data.modes is not None)
        return self._add_flexible_marker(
            body,
            position=data.nodes[index],
            indices=columns,
            translation=t,
            rotation=r,
            orientation=orientation,
            name=name,
        )

    def add_node_set_marker(
        self,
        body: _core.BodyId,
        nodes: str | Sequence[int],
        *,
        orientation: str | ArrayLike | None = None,
        weights: str | ArrayLike = "auto",
        coupling: str = "rbe3",
        name: str | None = None,
    ) -> _core.MarkerId:
        """Adds a marker on a node set of a deformable body (a name of the body's node sets,
        or node ids): an interface (see :mod:`flexmbd.fe.interface`).

        The marker's origin is the weighted centroid of the nodes; `weights` is "auto" (the
        default: area weights on faces, length weights on edges, volume weights on volumes,
        from the body's elements; the weights of the body's Craig-Bampton modes on one of
        their interfaces), "area", "length", "volume", "uniform", or one weight per node
        (positive in sum).
        With area weights the origin is the centroid of the face, however its mesh is spaced.

        `coupling` "rbe3" (default): the marker follows the weighted average motion of the
        nodes (its origin the weighted mean displacement, its axes the weighted least-squares
        rotation about the centroid) and the nodes deform freely. "rbe2": the nodes follow the
        marker rigidly; the body's elastic coordinates must keep the set rigid (a
        Craig-Bampton body with an "rbe2" interface on it, or a set held by the reference
        conditions), else `InvalidModelError` names the set.

        `orientation`: a 3 x 3 matrix (columns: the marker axes in the body frame), None (the
        body axes), or "principal" (z the outward normal of a face, x its axis of largest
        extent). Raises `InvalidModelError` naming the set when it is empty, of zero weight
        or on one line."""
        import scipy.sparse as sp

        item = f"marker '{name}'" if name else "node set marker"
        data, basis = self._flexible_data(body, item)
        if coupling not in COUPLINGS:
            raise InvalidParameterError(
                f"{item}: coupling must be one of {COUPLINGS}, got {coupling!r}", item=item
            )
        label = f"{item} on node set {value_text(nodes)}" if isinstance(nodes, str) else item
        interface = body_interface(data, nodes, weights, name=label)
        rows = interface.average_rows(data.dofs_per_node, data.dof_count) @ basis
        rows = np.asarray(rows.todense()) if sp.issparse(rows) else np.asarray(rows)
        translation, rotation = rows[:3], rows[3:]
        if coupling == "rbe2":
            _check_rigid(data, basis, interface, translation, rotation, label)
        columns, t, rot = _compress(translation, rotation, data.modes is not None)
        return self._add_flexible_marker(
            body,
            position=interface.centroid,
            indices=columns,
            translation=t,
            rotation=rot,
            orientation=interface.orientation(orientation),
            name=name,
        )

    def compile(self) -> _core.Model:
        """Checks the whole system and compiles the immutable :class:`Model`."""
        source = (type(self), tuple(self._calls), self._identity)
        return super().compile(flexible_bodies=self._flexible, source=source)


#: A building call: (method name, positional arguments, keyword arguments).
_Call = tuple[str, tuple[Any, ...], dict[str, Any]]


#: How far (relative to the largest principal moment) the largest may exceed the sum of the
#: other two before a rigid body's inertia is warned of (:class:`flexmbd.InertiaWarning`).
INERTIA_TRIANGLE_TOLERANCE = 1e-3


def _check_inertia(inertia: ArrayLike, item: str) -> None:
    """Warns of principal moments that no mass distribution has (the core checked the rest:
    three moments or a symmetric 3 x 3 matrix, positive definite)."""
    import warnings

    from .errors import InertiaWarning

    values = np.asarray(inertia, dtype=float)
    tensor = np.diag(values) if values.shape == (3,) else values.reshape(3, 3)
    moments = np.linalg.eigvalsh(0.5 * (tensor + tensor.T))
    largest, others = moments[-1], moments[0] + moments[1]
    if largest - others > INERTIA_TRIANGLE_TOLERANCE * largest:
        warnings.warn(
            InertiaWarning(
                f"{item}: the largest principal moment of inertia {largest:.6g} exceeds the sum "
                f"of the other two {others:.6g}: no mass distribution has these moments "
                "(I_1 + I_2 >= I_3); a value is mistyped, or about another point than the "
                "centre of mass. The motion is computed with them all the same"
            ),
            stacklevel=4,  # the caller of System.add_rigid_body (through its recording)
        )


#: The ids a System returns.
_IDS = (_core.BodyId, _core.MarkerId, _core.JointId, _core.ForceId, _core.SensorId)


def _new_identity() -> int:
    """A system's identity: random, so that it stays apart from other systems' after
    pickling to another process (a pickled system and its ids keep theirs)."""
    import secrets

    return secrets.randbits(62) + 1


#: The systems alive, by identity (`item_name` looks up the names of their items).
_SYSTEMS: weakref.WeakValueDictionary[int, System] = weakref.WeakValueDictionary()


def identity_of(model: Any) -> int | None:
    """The identity of the System a Model was compiled from (None: unknown)."""
    source = getattr(model, "_source", None)
    return source[2] if isinstance(source, tuple) and len(source) > 2 else None


def item_name(identity: int, item: Any) -> str | None:
    """The name given to the item of the id `item` by the System of `identity`; None for an
    item without a name, or a system that is gone."""
    source = _SYSTEMS.get(identity)
    return None if source is None else source._names.get((type(item).__name__, item.index))


def stray_id(identity: int | None, value: Any, name_here: Callable[[Any], str | None]) -> Any:
    """The first id in `value` (also inside lists, tuples and dicts) of another system than
    the one of `identity` whose item has a name there that `name_here(id)` (the name of the
    item of that index here) does not give, or None. Ids are indices, valid in any system
    built alike (the same builder called twice); a named item found under another name here
    is the mistake of a script holding two systems. Ids made by hand belong to none."""
    if isinstance(value, _IDS):
        other = value._system
        if identity is None or other in (0, identity):
            return None
        theirs = item_name(other, value)
        return value if theirs is not None and name_here(value) != theirs else None
    if isinstance(value, (list, tuple)):
        items: Any = value
    elif isinstance(value, dict):
        items = value.values()
    else:
        return None
    found = (stray_id(identity, v, name_here) for v in items)
    return next((f for f in found if f is not None), None)


def stray_id_error(value: Any, where: str, here: str | None) -> UnknownItemError:
    """The error of an id of another system (`stray_id`) used `where`; `here`: the name of
    the item of its index here, if any."""
    kind = _ID_KINDS[type(value).__name__]
    theirs = item_name(value._system, value)
    found = (
        f"here {kind} {value.index} is {here!r}"
        if here
        else f"here there is no {kind} {value.index}"
    )
    return UnknownItemError(
        f"{where}: {value!r} is {kind} {theirs!r} of another System, and {found}: ids are "
        f"indices into the system that returned them. Use this system's id, or the name",
        item=repr(value),
    )


#: The kind of item of each id type, for messages.
_ID_KINDS = {
    "BodyId": "body",
    "MarkerId": "marker",
    "JointId": "joint",
    "ForceId": "force",
    "SensorId": "sensor",
}


def _kept(value: Any) -> Any:
    """`value` as a building call keeps it: arrays (also inside lists, tuples and dicts)
    copied, so that changing the caller's array later does not change the record; ids
    without their system (the calls build copies of it)."""
    if isinstance(value, _IDS):
        return type(value)(value.index)
    if isinstance(value, np.ndarray):
        return value.copy()
    if isinstance(value, (list, tuple)):
        return type(value)(_kept(v) for v in value)
    if isinstance(value, dict):
        return {k: _kept(v) for k, v in value.items()}
    return value


def _recorded(name: str, method: Any) -> Any:
    """`method` of `System` recording its call (the outermost one: calls it makes itself are
    made again by it)."""

    def call(self: System, *args: Any, **kwargs: Any) -> Any:
        def name_here(item: Any) -> str | None:
            return self._names.get((type(item).__name__, item.index))

        stray = stray_id(self._identity, (args, kwargs), name_here)
        if stray is not None:
            # It indexed this system's items: a marker on another body, silently.
            raise stray_id_error(stray, name, name_here(stray))
        self._depth += 1
        try:
            value = method(self, *args, **kwargs)
        finally:
            self._depth -= 1
        if self._depth == 0:
            self._calls.append((name, _kept(args), _kept(kwargs)))
        if isinstance(value, _IDS):
            self._names[(type(value).__name__, value.index)] = kwargs.get("name")
            value = type(value)(value.index, self._identity)
        return value

    call.__name__ = name
    call.__qualname__ = f"System.{name}"
    call.__doc__ = method.__doc__
    call.__wrapped__ = method  # type: ignore[attr-defined]
    return call


for _name in dir(System):
    if _name.startswith("add_"):
        setattr(System, _name, _recorded(_name, getattr(System, _name)))


def _rebuilt(cls: type[System], calls: tuple[_Call, ...], identity: int | None = None) -> System:
    """The system `cls` built by `calls` (`System.building_calls`); with `identity`, that of
    the system it copies (whose ids then hold in it)."""
    (_, (gravity,), _), *rest = calls
    system = cls(gravity=gravity)
    if identity is not None:
        system._identity = identity
        _SYSTEMS.setdefault(identity, system)
    for name, args, kwargs in rest:
        if name == "gravity":
            system.gravity = args[0]
        else:
            getattr(system, name)(*args, **kwargs)
    return system


def _compiled(source: tuple[type[System], tuple[_Call, ...]]) -> _core.Model:
    """The model compiled from `source` (a pickled model)."""
    return _rebuilt(*source).compile()
