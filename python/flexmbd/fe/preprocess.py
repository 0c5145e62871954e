"""The preprocessor (seed section 3, "computational strategy"): from a mesh and a material to
the constant data of a deformable body: nodal stiffness and mass (assembled in Rust through
the connectivity, seed eq. 9), invariants of motion (seed eqs. 16-17), reference conditions
(the matrix B of seed eq. 9), modal reduction and the modal form of the invariants (eq. 18).
"""

from __future__ import annotations

import math
import os
import time
import warnings
from collections.abc import Callable, Collection, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray

from .. import _boundary, _core
from .._checks import choice, flag, id_text, integer, integers_array, number, numbers_array
from .._checks import direction as unit_vector
from ..errors import (
    ArgumentTypeError,
    InvalidModelError,
    InvalidParameterError,
    MeshQualityWarning,
    UnknownItemError,
)
from ..rotation import skew
from .beam_ends import (
    EndMaps,
    checked_ends,
    end_maps,
    offset_axis_mesh,
    tied_invariants,
    tied_matrix,
)
from .body import FlexibleBodyData, Invariants, ReferenceConditions
from .interface import Interface
from .mesh_io import (
    Mesh,
    matrices_from_arrays,
    mesh_parts,
    read_mesh,
    shell_pairs,
    validate_mesh,
)
from .mesh_io import orient_shells as orient_shell_elements  # a parameter of build_body too
from .modal import (
    INTERFACE_KINDS,
    craig_bampton,
    factorize,
    fixed_interface_modes,
    free_free_modes,
    interface_objects,
    modal_invariants,
    rigid_modes,
)

Material = _boundary.Material
Section = _core.Section
ShellSection = _core.ShellSection

#: Element types of shells, which need a shell section.
SHELL_ELEMENTS = ("quad4", "tri3")


def shell_section(shell: Any) -> ShellSection | None:
    """The `shell` option of `build_body`: a `ShellSection`, a thickness (m) or None."""
    if shell is None or isinstance(shell, _core.ShellSection):
        return shell
    if isinstance(shell, bool) or not isinstance(shell, int | float | np.floating | np.integer):
        raise ArgumentTypeError(
            f"shell must be a ShellSection or a thickness (a number), got {shell!r:.60} "
            f"({type(shell).__name__})",
            item="shell",
        )
    return ShellSection(float(shell))


def _check_shell(elements: Mapping[str, Any], shell: ShellSection | None) -> None:
    """Shell elements need a shell section (`InvalidParameterError` naming `shell`)."""
    kinds = [k for k in SHELL_ELEMENTS if k in elements and len(elements[k])]
    if kinds and shell is None:
        raise InvalidParameterError(
            f"{' and '.join(kinds)} shell elements need a shell section: pass "
            "shell=ShellSection(thickness) or shell=thickness",
            item="shell",
        )


def _check_sections_used(
    elements: Mapping[str, Any],
    section: Section | None,
    shell: ShellSection | None,
    orientation: Any = None,
    beam_theory: str = "euler-bernoulli",
) -> None:
    """A beam section, orientation or beam theory without beams, a shell section without
    shells: refused (`InvalidParameterError` naming the option), as the option would change
    nothing and the mesh is likely not the one meant."""
    present = [k for k, conn in elements.items() if len(conn)]
    if "beam2" not in present:
        for item, given in (
            ("section", section is not None),
            ("orientation", orientation is not None),
            ("beam_theory", beam_theory != "euler-bernoulli"),
        ):
            if given:
                what = {"beam_theory": "a beam theory"}.get(item, f"a beam {item}")
                raise InvalidParameterError(
                    f"{item}: the mesh has no beam elements (it has "
                    f"{', '.join(present) or 'none'}); {what} applies to beam2 elements only",
                    item=item,
                )
    if shell is not None and not any(k in present for k in SHELL_ELEMENTS):
        raise InvalidParameterError(
            f"shell: the mesh has no shell elements (it has {', '.join(present) or 'none'}); "
            "a shell section applies to quad4 and tri3 elements only",
            item="shell",
        )


def _given(selection: Any) -> bool:
    """Whether a node selection (a node set name, indices) names any node."""
    if isinstance(selection, str):
        return True
    try:
        return len(selection) > 0
    except TypeError:
        return selection is not None


#: The reference conditions that place the body frame at `reference_nodes`.
NODE_REFERENCE_KINDS = ("clamped", "3-2-1", "simply-supported")


def _check_used_options(
    modes: str | None,
    mode_count: int,
    interfaces: Any,
    *,
    reference: str = "none",
    reference_nodes: Any = (),
    interface_kind: str = "rbe2",
    interface_weights: Any = "auto",
    external_modes: Any = None,
) -> None:
    """Options that the chosen reference conditions or modal reduction would ignore: refused,
    naming them."""
    if reference not in NODE_REFERENCE_KINDS and _given(reference_nodes):
        frame = {
            "none": "nothing holds the body frame",
            "mean-axis": "the mean axes place the body frame",
            "interface": "the first interface holds the body frame",
        }.get(reference, f"reference {reference!r}")
        raise InvalidParameterError(
            f"reference_nodes with reference={reference!r}: {frame} and the nodes would be "
            f"ignored; reference_nodes are for {', '.join(map(repr, NODE_REFERENCE_KINDS))} "
            "conditions",
            item="reference_nodes",
        )
    if modes != "craig-bampton" and interface_kind != "rbe2":
        raise InvalidParameterError(
            f"interface_kind={interface_kind!r} is for Craig-Bampton interfaces "
            f"(modes='craig-bampton'), got modes={modes!r}",
            item="interface_kind",
        )
    weighted = modes == "craig-bampton" and interface_kind != "nodal"
    if not weighted and not (isinstance(interface_weights, str) and interface_weights == "auto"):
        raise InvalidParameterError(
            "interface_weights are for the RBE2 and RBE3 interfaces of Craig-Bampton modes, got "
            f"modes={modes!r}, interface_kind={interface_kind!r}",
            item="interface_weights",
        )
    if modes != "external" and external_modes is not None:
        raise InvalidParameterError(
            f"external_modes with modes={modes!r}: the matrix would be ignored; use "
            "modes='external'",
            item="external_modes",
        )
    if modes is None and mode_count > 0:
        raise InvalidParameterError(
            f"mode_count={mode_count} without modes: the body keeps its nodal coordinates; "
            "choose modes ('fixed-interface', 'free-free', 'craig-bampton')",
            item="mode_count",
        )
    columns = np.shape(external_modes)[-1] if np.ndim(external_modes) == 2 else None
    if modes == "external" and mode_count > 0 and columns is not None and mode_count != columns:
        raise InvalidParameterError(
            f"mode_count={mode_count} with {columns} external modes: every column of "
            "external_modes is kept (the count was ignored); pass the columns to keep",
            item="mode_count",
        )
    if modes != "craig-bampton" and len(_interface_selections(interfaces)):
        raise InvalidParameterError(
            f"interfaces are for Craig-Bampton modes (modes='craig-bampton'), got modes="
            f"{modes!r}; use reference_nodes for the nodes of clamped or 3-2-1 conditions",
            item="interfaces",
        )


#: The warp above which a quadrilateral shell is reported (`shell_warp`, `MeshQualityWarning`):
#: the flat element takes the corners projected onto its mean plane, which serves while the
#: warp is a few per cent (`docs/preprocessor.md`).
SHELL_WARP_LIMIT = 0.05


def shell_warp(nodes: NDArray[np.float64], quads: NDArray[np.int64]) -> NDArray[np.float64]:
    """The warp of quadrilateral shells: the distance h of the corners from the element's mean
    plane (normal (x3 - x1) x (x4 - x2) through the corners' centroid; the four corners are
    at +h, -h, +h, -h from it) over half the mean length of the diagonals. 0 for a flat
    quadrilateral; for a unit square with one corner raised by d, d / (2 sqrt(2)) to first
    order."""
    x = nodes[quads]  # (n, 4, 3)
    d13, d24 = x[:, 2] - x[:, 0], x[:, 3] - x[:, 1]
    normal = np.cross(d13, d24)
    length = np.linalg.norm(normal, axis=1)
    size = 0.25 * (np.linalg.norm(d13, axis=1) + np.linalg.norm(d24, axis=1))
    centre = x.mean(axis=1)
    h = np.abs(np.einsum("ij,ij->i", x[:, 0] - centre, normal))
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(length > 0.0, h / np.where(length > 0.0, length, 1.0) / size, 0.0)


def _warn_of_shells(
    nodes: NDArray[np.float64], elements: Mapping[str, NDArray[np.int64]], ids: Mapping[str, Any]
) -> None:
    """Warns (`MeshQualityWarning`) of neighbouring shells turned to opposite sides and of
    quadrilateral shells warped by more than `SHELL_WARP_LIMIT`, naming one of each."""
    shells, first, second, opposite = shell_pairs(elements)
    if opposite.any():
        k = int(np.argmax(opposite))
        (kind_a, a), (kind_b, b) = shells[first[k]], shells[second[k]]
        warnings.warn(
            f"{int(opposite.sum())} pairs of neighbouring shells have their normals to opposite "
            f"sides (elements {id_text(ids[kind_a][a])} and {id_text(ids[kind_b][b])} run along "
            "their shared edge in the same direction): their top and bottom stresses would be "
            "averaged across each other at the shared nodes; flexmbd.fe.orient_shells(elements) "
            "turns them to one side",
            MeshQualityWarning,
            stacklevel=3,
        )
    quads = elements.get("quad4")
    if quads is None or not len(quads):
        return
    warp = shell_warp(nodes, quads)
    warped = np.flatnonzero(warp > SHELL_WARP_LIMIT)
    if len(warped):
        worst = warped[np.argmax(warp[warped])]
        warnings.warn(
            f"{len(warped)} of {len(quads)} quad4 shells are warped by more than "
            f"{SHELL_WARP_LIMIT:.0%} (element {id_text(ids['quad4'][worst])}: "
            f"{warp[worst]:.1%}): the flat element projects them onto their mean plane; "
            "refine the mesh or split them into tri3",
            MeshQualityWarning,
            stacklevel=3,
        )


def _warn_of_drilling_inertia(
    nodes: NDArray[np.float64],
    elements: Mapping[str, NDArray[np.int64]],
    nodal: NodalBody,
    ids: NDArray[np.int64],
) -> None:
    """Warns (`MeshQualityWarning`) of point masses with an inertia about the normal of the
    flat shells that alone hold their node (their rotary inertia about it, or their centre
    offset in the shells' plane): the drilling rotation there has only the penalty
    stiffness k (`DRILLING_STIFFNESS`), and the inertia J_n makes a mode near
    sqrt(k / J_n) / 2 pi that no structure has. Names the first such node and that
    frequency."""
    if nodal.dofs_per_node != 6 or not nodal.point_masses:
        return
    shells = [np.asarray(elements[k]) for k in SHELL_ELEMENTS if k in elements]
    if not shells:
        return
    others = [np.asarray(c).ravel() for k, c in elements.items() if k not in SHELL_ELEMENTS]
    held = np.unique(np.concatenate(others)) if others else np.zeros(0, dtype=np.int64)
    carrying = np.array([entry[0] for entry in nodal.point_masses])
    normals: dict[int, list[NDArray[np.float64]]] = {}
    for conn in shells:
        # (only the shells at the masses' nodes)
        conn = conn[np.isin(conn, carrying).any(axis=1)]
        x = nodes[conn]
        normal = (
            np.cross(x[:, 2] - x[:, 0], x[:, 3] - x[:, 1])
            if conn.shape[1] == 4
            else np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])
        )
        normal /= np.maximum(np.linalg.norm(normal, axis=1), 1e-300)[:, None]
        for row, n in zip(conn, normal, strict=True):
            for node in row:
                normals.setdefault(int(node), []).append(n)
    for node, mass, inertia, offset in nodal.point_masses:
        if node not in normals or node in held:
            continue
        n = normals[node][0]
        if any(abs(float(other @ n)) < 1.0 - 1e-6 for other in normals[node]):
            continue  # (a fold: one shell's drilling is another's bending)
        about = inertia + mass * (float(offset @ offset) * np.eye(3) - np.outer(offset, offset))
        drilling = float(n @ about @ n)
        if drilling <= 1e-9 * max(float(np.trace(about)), 1e-300):
            continue
        block = nodal.stiffness[6 * node + 3 : 6 * node + 6, 6 * node + 3 : 6 * node + 6]
        frequency = np.sqrt(max(float(n @ block.toarray() @ n), 0.0) / drilling) / (2 * np.pi)
        warnings.warn(
            f"point_masses[{node}] (node {id_text(ids[node])}): its inertia about the normal of "
            f"the flat shells that alone hold the node ({drilling:.3g} kg m^2, its rotary "
            "inertia or its centre's offset in their plane) turns with the shells' drilling "
            "rotation, which has only a penalty stiffness: a mode near "
            f"{frequency:.3g} Hz that no structure has; leave that part of the inertia out, "
            "or join the mass to a set of nodes (a rigid body on a node set marker)",
            MeshQualityWarning,
            stacklevel=3,
        )


#: The values of the str options of `build_body`.
MASS_KINDS = ("consistent", "lumped")
BEAM_THEORIES = ("euler-bernoulli", "timoshenko")
REFERENCE_KINDS = ("none", "clamped", "3-2-1", "simply-supported", "mean-axis", "interface")
MODE_KINDS = ("fixed-interface", "free-free", "craig-bampton", "external")
PRECISIONS = ("double", "single", "auto")


def _beam_theory(name: str) -> bool:
    return choice(name, "beam_theory", BEAM_THEORIES) == "timoshenko"


def _options(
    *,
    reference: Any,
    modes: Any,
    interface_kind: Any,
    precision: Any,
    mass: Any = None,
    beam_theory: Any = None,
) -> None:
    """Refuses str options of `build_body` of the wrong type (an array, a number, ...: an
    `ArgumentTypeError`) or value (an `InvalidParameterError`), naming the parameter."""
    choice(reference, "reference", REFERENCE_KINDS)
    if modes is not None:
        choice(modes, "modes", MODE_KINDS)
    choice(
        interface_kind, "interface_kind", INTERFACE_KINDS, what="interface kind (interface_kind)"
    )
    choice(precision, "precision", PRECISIONS)
    if mass is not None:
        choice(mass, "mass", MASS_KINDS)
    if beam_theory is not None:
        _beam_theory(beam_theory)


def _csc(parts: tuple) -> sp.csc_matrix:
    """A matrix of the core's assembly without the zeros its element patterns store (the
    uncoupled membrane and bending, drilling and axial terms of shells and beams: 57 % of a
    quad4 plate's stiffness entries, 83 % of its mass entries)."""
    data, indices, indptr, shape = parts
    matrix = sp.csc_matrix((data, indices, indptr), shape=shape)
    matrix.eliminate_zeros()
    return matrix


@dataclass
class NodalBody:
    """Nodal matrices and invariants of a body before reference conditions.

    ``i_kl`` is a 3 x 3 nested list of sparse (n, n) matrices; for bodies of solid elements
    they are M_s (x) e_k e_l^T of the scalar mass matrix M_s (``scalar_mass``), or None when
    not formed (see `assemble`)."""

    dofs_per_node: int
    stiffness: sp.csc_matrix
    mass: sp.csc_matrix
    invariants: dict[str, Any]
    scalar_mass: sp.csc_matrix | None
    #: The concentrated masses added by `with_point_masses`, checked (`point_mass_entries`).
    point_masses: tuple[PointMass, ...] = ()


def straight_beam(
    length: float,
    elements: int,
    *,
    start: ArrayLike = (0.0, 0.0, 0.0),
    direction: ArrayLike = (1.0, 0.0, 0.0),
) -> tuple[NDArray[np.float64], dict[str, NDArray[np.int64]]]:
    """Nodes and "beam2" connectivity of a straight beam of `elements` equal elements."""
    elements = integer(elements, "elements")
    length = number(length, "length")
    if elements < 1 or not length > 0:
        raise InvalidParameterError(
            f"a beam needs length > 0 and at least one element, got {length}, {elements}"
        )
    d = unit_vector(direction, "direction")
    s = np.linspace(0.0, length, elements + 1)
    nodes = np.asarray(start, dtype=float)[None, :] + s[:, None] * d[None, :]
    conn = np.column_stack([np.arange(elements), np.arange(1, elements + 1)]).astype(np.int64)
    return nodes, {"beam2": conn}


def solid_i_kl(scalar_mass: sp.spmatrix) -> list[list[sp.csc_matrix]]:
    """The nine I_kl = M_s (x) e_k e_l^T of a body of solid elements from its scalar mass
    matrix M_s (3 x 3 nested list of sparse matrices)."""
    unit = [[sp.csc_matrix(([1.0], ([k], [j])), shape=(3, 3)) for j in range(3)] for k in range(3)]
    return [[sp.kron(scalar_mass, unit[k][j], format="csc") for j in range(3)] for k in range(3)]


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
    form_i_kl: bool = True,
    shell: ShellSection | float | None = None,
    beam_offsets: ArrayLike | None = None,
    beam_releases: ArrayLike | None = None,
) -> NodalBody:
    """Assembles K_ff, M_ff and the nodal invariants (Rust kernels, see `docs/preprocessor.md`).

    `elements` maps an element type ("beam2", "tet4", "tet10" in Gmsh node order, "hex8",
    "hex8i" with incompatible modes, "hex20", "hex20r" and "hex27" in VTK node order, "wedge6" in
    Gmsh's prism order, "wedge15" in Abaqus' C3D15 order, "wedge18" (wedge15's nodes, then the
    centres of the faces (0,1,4,3), (1,2,5,4), (2,0,3,5)), "pyramid5" in Gmsh's order,
    "pyramid13" in VTK's order, "pyramid14" (pyramid13's nodes, then the base's centre), the flat
    shells "quad4" and "tri3")
    to its connectivity
    (n_e, nodes) of 0-based node indices; shells need `shell` (a `ShellSection` or the
    thickness). `mass` is "consistent" or "lumped";
    `beam_theory` "euler-bernoulli" or "timoshenko" (shear-deformable beams). For bodies of
    solid elements the nine I_kl are the scalar mass matrix M_s spread over the coordinates;
    with `form_i_kl` False they are not formed (`invariants["i_kl"]` is None; modal invariants
    need only M_s), which saves memory of the size of M. `beam_offsets` (n_beams, 2, 3) and
    `beam_releases` (n_beams, 12) are the offsets and released end coordinates of the beam2
    elements (`flexmbd.fe.beam_ends`): such beams are assembled on their offset axes and
    tied to their nodes."""
    choice(mass, "mass", MASS_KINDS)
    shear = _beam_theory(beam_theory)
    shell = shell_section(shell)
    _check_shell(elements, shell)
    nodes = np.ascontiguousarray(nodes, dtype=float)
    ids = np.arange(1, len(nodes) + 1) if node_ids is None else np.asarray(node_ids)
    direction = None if orientation is None else unit_vector(orientation, "orientation")
    on_axes = offset_axis_mesh(
        nodes, ids, elements, material, section, direction, shear, beam_offsets, beam_releases
    )
    if on_axes is not None:
        nodes, ids, elements = on_axes.nodes, on_axes.node_ids, on_axes.elements
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
    mesh = _core.FeMesh(
        nodes,
        np.ascontiguousarray(ids, dtype=np.int64),
        blocks,
        material,
        section,
        None if direction is None else list(direction),
        shear,
        shell,
    )
    raw = _core.assemble_body(mesh, mass == "lumped")
    n = raw["i1"].shape[1]
    if "i_kl_scalar" in raw:
        ms = _csc(raw["i_kl_scalar"])
        i_kl = solid_i_kl(ms) if form_i_kl else None
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
    stiffness, mass_matrix = _csc(raw["stiffness"]), _csc(raw["mass"])
    if on_axes is not None:
        # The beams' axis ends tied to their nodes: K = P^T K_axis P, and so on.
        tie = on_axes.tie
        stiffness = tied_matrix(stiffness, tie)
        mass_matrix = tied_matrix(mass_matrix, tie)
        invariants = tied_invariants(invariants, tie)
    return NodalBody(
        dofs_per_node=int(raw["dofs_per_node"]),
        stiffness=stiffness,
        mass=mass_matrix,
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
    shell: ShellSection | float | None = None,
    beam_offsets: ArrayLike | None = None,
    beam_releases: ArrayLike | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64], sp.csr_matrix]:
    """The body's mass points: weights rho dV (P,), undeformed positions (P, 3), and the shape
    matrices stacked as a sparse (3 P, n_dofs) matrix (rows 3p..3p+3: S of point p). The
    invariants are sums over them; they serve brute-force checks. Beams with offsets or
    releases (see `assemble`) have their points on their offset axes, their shape matrices
    S P through the tie."""
    nodes = np.ascontiguousarray(nodes, dtype=float)
    direction = None if orientation is None else unit_vector(orientation, "orientation")
    on_axes = offset_axis_mesh(
        nodes,
        np.arange(1, len(nodes) + 1),
        elements,
        material,
        section,
        direction,
        _beam_theory(beam_theory),
        beam_offsets,
        beam_releases,
    )
    if on_axes is not None:
        nodes, elements = on_axes.nodes, on_axes.elements
    blocks = {
        kind: (
            np.ascontiguousarray(conn, dtype=np.int64),
            np.arange(1, len(conn) + 1, dtype=np.int64),
        )
        for kind, conn in elements.items()
    }
    mesh = _core.FeMesh(
        nodes,
        np.arange(1, len(nodes) + 1, dtype=np.int64),
        blocks,
        material,
        section,
        None if direction is None else list(direction),
        _beam_theory(beam_theory),
        shell_section(shell),
    )
    weights, positions, shape = _core.body_mass_points(mesh, mass == "lumped")
    data, indices, indptr, dims = shape
    matrix = sp.csr_matrix((data, indices, indptr), shape=dims)
    if on_axes is not None:
        matrix = sp.csr_matrix(matrix @ on_axes.tie)
    return weights, positions, matrix


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
      its x-y plane through c, if b lies on the x axis of a and c in its x-y plane;
    - "simply-supported" (beams): `nodes` = (a, b) keep a fixed with its twist theta_x (4) and b
      without y and z displacement (2): the body frame has its origin at a and its x axis
      through b (the chord of a pinned-pinned beam), if b lies on the x axis of a.
    """
    d = dofs_per_node
    all_dofs = np.arange(node_count * d, dtype=np.int64)
    nodes = [int(n) for n in integers_array(nodes, "reference_nodes").ravel()]
    for n in nodes:
        if not 0 <= n < node_count:
            raise InvalidModelError(
                f"reference_nodes: node index {n} out of range 0..{node_count - 1}",
                item="reference_nodes",
            )
    if kind in ("none", "mean-axis"):
        return all_dofs
    if kind == "clamped":
        if not nodes:
            raise InvalidModelError(
                "clamped reference conditions need at least one node (reference_nodes)",
                item="reference_nodes",
            )
        removed = {d * n + c for n in nodes for c in range(d)}
    elif kind == "3-2-1":
        if len(nodes) != 3 or len(set(nodes)) != 3:
            raise InvalidModelError(
                f"3-2-1 reference conditions need three distinct nodes (reference_nodes), got "
                f"{nodes}",
                item="reference_nodes",
            )
        a, b, c = nodes
        removed = {d * a, d * a + 1, d * a + 2, d * b + 1, d * b + 2, d * c + 2}
    elif kind == "simply-supported":
        if d != 6 or len(nodes) != 2 or len(set(nodes)) != 2:
            raise InvalidModelError(
                "simply-supported reference conditions are for beams and need two distinct "
                f"nodes (reference_nodes), got {nodes}",
                item="reference_nodes",
            )
        a, b = nodes
        removed = {d * a, d * a + 1, d * a + 2, d * a + 3, d * b + 1, d * b + 2}
    else:
        raise InvalidParameterError(f"unknown reference conditions {kind!r}")
    return np.setdiff1d(all_dofs, np.fromiter(removed, dtype=np.int64))


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


def _node_sets(node_sets: Any) -> dict[str, NDArray[np.int64]]:
    """The `node_sets` option (name -> node indices) as int64 arrays (copies): a set that is
    not integers is an `ArgumentTypeError` naming it."""
    if node_sets is None:
        return {}
    if not isinstance(node_sets, Mapping):
        raise ArgumentTypeError(
            f"node_sets must be a mapping of names to node indices, got {node_sets!r:.60} "
            f"({type(node_sets).__name__})",
            item="node_sets",
        )
    return {
        name: np.array(integers_array(v, f"node_sets[{name!r}]")) for name, v in node_sets.items()
    }


def _node_indices(
    selection: str | ArrayLike, node_sets: Mapping[str, ArrayLike], what: str
) -> NDArray[np.int64]:
    """Node indices of a selection given as a node set name or as indices (integers: a
    float, a string of digits, None, ... is an `ArgumentTypeError` naming `what`, the
    parameter)."""
    if isinstance(selection, str):
        if selection not in node_sets:
            raise UnknownItemError(
                f"{what}: unknown node set {selection!r} (known: {sorted(node_sets)})",
                item=f"node set '{selection}'",
            )
        return integers_array(node_sets[selection], f"node set {selection!r}").ravel()
    return integers_array(selection, what).ravel()


def _interface_selections(interfaces: Any) -> list[Any]:
    """The `interfaces` option as a list (one node set name or index list per interface):
    a string, None or a number is an `ArgumentTypeError` naming it."""
    if isinstance(interfaces, str | bytes | bytearray | Mapping) or not isinstance(
        interfaces, Iterable
    ):
        raise ArgumentTypeError(
            "interfaces must be a list of node set names or node index lists (one per "
            f"interface), got {interfaces!r:.60} ({type(interfaces).__name__})",
            item="interfaces",
        )
    return list(interfaces)


class _Stages:
    """Seconds per stage into an optional dict (`build_body(timings=...)`)."""

    def __init__(self, sink: dict[str, float] | None):
        self.sink = sink
        self.last = time.perf_counter()

    def lap(self, name: str) -> None:
        now = time.perf_counter()
        if self.sink is not None:
            self.sink[name] = self.sink.get(name, 0.0) + now - self.last
        self.last = now


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
    reference_nodes: str | Sequence[int] = (),
    modes: str | None = None,
    mode_count: int = 0,
    interfaces: Sequence[str | Sequence[int]] = (),
    interface_kind: str = "rbe2",
    interface_weights: str | Sequence[str | ArrayLike] = "auto",
    external_modes: ArrayLike | None = None,
    node_ids: ArrayLike | None = None,
    element_ids: Mapping[str, ArrayLike] | None = None,
    node_sets: Mapping[str, ArrayLike] | None = None,
    check_mesh: bool = True,
    precision: str = "auto",
    timings: dict[str, float] | None = None,
    shell: ShellSection | float | None = None,
    orient_shells: bool = False,
    point_masses: Mapping[int, Any] | None = None,
    beam_offsets: ArrayLike | None = None,
    beam_releases: ArrayLike | None = None,
) -> FlexibleBodyData:
    """Runs the preprocessor and returns the `FlexibleBodyData` of a body.

    - `nodes` (n, 3) in the body frame, `elements` type -> connectivity (0-based indices), see
      `assemble`; `node_ids`, `element_ids` (ids of the source mesh, for messages) and
      `node_sets` (name -> indices) are optional. With `check_mesh` the mesh is first checked
      by `mesh_io.validate_mesh` (duplicate and unconnected nodes, bad indices, ...).
    - `section` (beams), `shell` (the flat shells "quad4" and "tri3": a `ShellSection` or the
      thickness in m). `orient_shells`: turn the shells of each connected surface to the side
      of its first one (`mesh_io.orient_shells`) before anything else; without it, neighbours
      turned to opposite sides are a `MeshQualityWarning` (their stresses would be averaged
      top against bottom).
    - `reference` (the body frame, `docs/preprocessor.md`): "none", "clamped", "3-2-1" or
      "simply-supported" (beams) at
      `reference_nodes` (indices or a node set name), "mean-axis" (with free-free or
      Craig-Bampton modes), or "interface" (Craig-Bampton only: the frame follows the first
      interface).
    - `modes`: None (nodal elastic coordinates), "fixed-interface" (eigenmodes with the
      reference conditions), "free-free" (elastic free-free modes; mean-axis frame),
      "craig-bampton" (`interfaces`: node sets given by name or indices, `interface_kind`
      "rbe2", "rbe3" or "nodal", see `modal.craig_bampton`; `interface_weights`, one for all
      or one per interface, weight their nodes: "auto", "area", "length", "volume",
      "uniform" or arrays, see `flexmbd.fe.interface`) or "external" (`external_modes`
      over the kept coordinates, e.g. from experimental modal analysis or another FE code).
      `mode_count` eigenmodes are kept (Craig-Bampton adds the static modes); a `mode_count`
      that is not an integer >= 0 is an `InvalidParameterError` naming it. Fixed-interface
      modes with `mode_count=0` give no elastic coordinates: the body moves rigidly with the
      mesh's mass distribution (the rigid limit of a deformable body).
    - Bad options are an `InvalidParameterError` naming the parameter (an `ArgumentTypeError`
      for a value of the wrong type): a `mass`, `beam_theory`, `reference`, `modes`,
      `interface_kind` or `precision` that is not one of its strings (an array, a number,
      ...); `reference_nodes`, each of the `interfaces` and each of the `node_sets` that is
      not a node set name or integer node indices (None, floats, NaN, strings, bools,
      integers beyond int64); `interfaces` that is not a list (a string, None, a number).
    - `precision`: of the sparse factorizations of the eigensolvers: "double", "single" (half
      the memory: a single-precision Cholesky factor preconditions conjugate gradients), or
      "auto" (single above `modal.SINGLE_PRECISION_ABOVE` coordinates).
    - `timings`: a dict that receives the seconds spent in each stage ("check", "assemble",
      "modes", "invariants").
    - `point_masses`: concentrated masses at nodes, part of the body (equipment, a tip mass,
      Nastran's CONM2): node index -> mass (kg), (mass, inertia) or (mass, inertia, offset)
      with the (3, 3) rotary inertia about the mass's centre (None for none) and the offset
      of that centre from the node, both in the body axes, for the 6-coordinate nodes of
      beams and shells (a solid's nodes have no rotations to carry them; the centre turns
      with the node). They add to the mass matrix and to every invariant of motion (exact:
      rigid parts moving with their nodes), and they are kept by the body's variants
      (`with_material`, `with_modes`).
    - `beam_offsets`: (n_beams, 2, 3) the offsets w_a, w_b (m, body axes) of the ends of each
      beam2 element from its nodes (Nastran's CBAR WA, WB): the element's axis runs between
      x_a + w_a and x_b + w_b, tied rigidly to the nodes; its stiffness, mass and invariants
      are those of the offset beam. `beam_releases`: (n_beams, 12) bools, the released end
      coordinates u, v, w, theta_x, theta_y, theta_z of end a then end b in the element's
      axes (Nastran's pin flags PA, PB), condensed out of the element (see
      `flexmbd.fe.beam_ends`). A release that leaves the body a mechanism is an
      `InvalidModelError`. Both are kept in `body.section` ("offsets", "releases").
    """
    clock = _Stages(timings)
    mode_count = integer(mode_count, "mode_count")
    if mode_count < 0:
        raise InvalidParameterError(f"mode_count must be >= 0, got {mode_count}", item="mode_count")
    _options(
        reference=reference,
        modes=modes,
        interface_kind=interface_kind,
        precision=precision,
        mass=mass,
        beam_theory=beam_theory,
    )
    shell = shell_section(shell)
    _check_used_options(
        modes,
        mode_count,
        interfaces,
        reference=reference,
        reference_nodes=reference_nodes,
        interface_kind=interface_kind,
        interface_weights=interface_weights,
        external_modes=external_modes,
    )
    # Copies: the body's arrays are read-only and must not alias the caller's.
    nodes = np.array(nodes, dtype=float)
    sets = _node_sets(node_sets)
    elements = {k: integers_array(v, f"elements[{k!r}]").copy() for k, v in elements.items()}
    _check_shell(elements, shell)
    _check_sections_used(elements, section, shell, orientation, beam_theory)
    offsets, releases = checked_ends(elements, beam_offsets, beam_releases)
    if flag(orient_shells, "orient_shells"):
        elements = orient_shell_elements(elements)
    ids = (
        np.arange(1, len(nodes) + 1, dtype=np.int64)
        if node_ids is None
        else np.array(node_ids, dtype=np.int64)
    )
    eids: dict[str, NDArray[np.int64]] = {}
    first = 1
    for kind, conn in elements.items():
        given = None if element_ids is None else element_ids.get(kind)
        eids[kind] = (
            np.arange(first, first + len(conn), dtype=np.int64)
            if given is None
            else np.array(given, dtype=np.int64)
        )
        first += len(conn)
    if check_mesh:
        validate_mesh(
            Mesh(nodes=nodes, node_ids=ids, elements=elements, element_ids=eids, node_sets=sets)
        )
        _warn_of_shells(nodes, elements, eids)
    clock.lap("check")

    def assembled(kinds: dict[str, NDArray[np.int64]], **options: Any) -> NodalBody:
        """The body's nodes, material and sections with the elements `kinds`."""
        return assemble(
            nodes,
            kinds,
            material,
            section=section,
            orientation=orientation,
            mass=mass,
            beam_theory=beam_theory,
            node_ids=ids,
            shell=shell,
            beam_offsets=offsets,
            beam_releases=releases,
            **options,
        )

    nodal = assembled(elements, element_ids=eids, form_i_kl=modes is None)
    if point_masses is not None:
        nodal = with_point_masses(
            nodal, nodes, point_masses, form_i_kl=modes is None, elements=elements
        )
        _warn_of_drilling_inertia(nodes, elements, nodal, ids)
    _check_zero_energy_modes(
        nodal, nodes, elements, eids, lambda other: assembled(other, form_i_kl=False)
    )
    if releases is not None and section is not None:
        maps = end_maps(
            nodes,
            elements["beam2"],
            offsets,
            releases,
            material=material,
            section=section,
            orientation=None if orientation is None else unit_vector(orientation, "orientation"),
            shear=_beam_theory(beam_theory),
        )
        # (held: the clamped nodes, and those of rigid or nodal Craig-Bampton interfaces)
        held = (
            [_node_indices(reference_nodes, sets, "reference_nodes")]
            if reference == "clamped"
            else []
        )
        if modes == "craig-bampton" and interface_kind in ("rbe2", "nodal"):
            held += [
                _node_indices(selection, sets, f"interfaces[{i}]")
                for i, selection in enumerate(_interface_selections(interfaces))
            ]
        _check_released_mechanism(
            nodal,
            nodes,
            elements,
            eids["beam2"],
            maps,
            np.unique(np.concatenate([np.zeros(0, dtype=np.int64), *held])),
        )
    clock.lap("assemble")
    return _body_from_nodal(
        nodal,
        nodes,
        ids,
        elements,
        eids,
        sets,
        {
            "young_modulus": material.young_modulus,
            "poisson_ratio": material.poisson_ratio,
            "density": material.density,
        },
        section=section,
        orientation=orientation,
        beam_offsets=offsets,
        beam_releases=releases,
        shell=shell,
        beam_theory=beam_theory,
        mass=mass,
        reference=reference,
        reference_nodes=reference_nodes,
        modes=modes,
        mode_count=mode_count,
        interfaces=interfaces,
        interface_kind=interface_kind,
        interface_weights=interface_weights,
        external_modes=external_modes,
        precision=precision,
        clock=clock,
    )


def _body_from_nodal(
    nodal: NodalBody,
    nodes: NDArray[np.float64],
    ids: NDArray[np.int64],
    elements: dict[str, NDArray[np.int64]],
    eids: dict[str, NDArray[np.int64]],
    sets: dict[str, NDArray[np.int64]],
    material_data: dict[str, float],
    *,
    section: Section | None,
    beam_theory: str,
    orientation: ArrayLike | None = None,
    beam_offsets: NDArray[np.float64] | None = None,
    beam_releases: NDArray[np.bool_] | None = None,
    shell: ShellSection | None = None,
    mass: str,
    reference: str,
    reference_nodes: str | Sequence[int],
    modes: str | None,
    mode_count: int,
    interfaces: Sequence[str | Sequence[int]],
    interface_kind: str,
    interface_weights: str | Sequence[str | ArrayLike] = "auto",
    external_modes: ArrayLike | None,
    precision: str,
    clock: _Stages,
) -> FlexibleBodyData:
    """Reference conditions, modes and invariants of a body from its nodal matrices and
    invariants (the part of `build_body` after the assembly)."""
    mode_count = integer(mode_count, "mode_count")
    if mode_count < 0:
        raise InvalidParameterError(f"mode_count must be >= 0, got {mode_count}", item="mode_count")
    _options(reference=reference, modes=modes, interface_kind=interface_kind, precision=precision)
    d = nodal.dofs_per_node
    mean_axis_modes = ("free-free", "craig-bampton")
    if reference == "mean-axis" and modes not in mean_axis_modes:
        raise InvalidModelError(
            "mean-axis reference conditions need free-free or Craig-Bampton modes"
        )
    if modes == "free-free" and reference not in ("none", "mean-axis"):
        raise InvalidModelError(
            "free-free modes define a mean-axis frame; use reference='mean-axis'"
        )
    if modes == "craig-bampton" and reference not in ("mean-axis", "interface"):
        raise InvalidModelError(
            "Craig-Bampton modes need reference='mean-axis' or reference='interface'"
        )
    if reference == "interface" and modes != "craig-bampton":
        raise InvalidModelError("reference='interface' is for Craig-Bampton modes")
    members = [
        _node_indices(s, sets, f"interfaces[{i}]")
        for i, s in enumerate(_interface_selections(interfaces))
    ]
    if modes == "craig-bampton" and not members:
        # (It was refused by the reference conditions: "clamped reference conditions need at
        # least one node (reference_nodes)", of which the call said nothing.)
        raise InvalidModelError(
            "Craig-Bampton modes need interfaces: the node sets where the body meets the rest "
            "of the model (interfaces=[...]; the first one carries the frame with "
            "reference='interface')",
            item="interfaces",
        )
    ref_nodes = _node_indices(reference_nodes, sets, "reference_nodes")
    kind = reference
    if reference == "interface":
        ref_nodes = members[0] if members else ref_nodes
        kind = "clamped" if interface_kind in ("rbe2", "nodal") else "none"
        free = reference_dofs(kind, len(nodes), d, ref_nodes)
    else:
        free = reference_dofs(
            "none" if reference == "mean-axis" else reference, len(nodes), d, ref_nodes
        )
    held = ref_nodes if kind == "clamped" else np.zeros(0, dtype=np.int64)
    _check_parts(nodes, ids, elements, nodal, reference, held)
    unused = solid_only_rotations(elements, len(nodes), d)
    if kind in ("clamped", "3-2-1", "simply-supported") and modes != "external":
        # (External modes may leave out what the conditions do not hold: an axial-only rod.)
        _check_held(nodes, ids, d, free, reference, ref_nodes, unused)
    if len(unused):
        # The rotations of nodes of solids alone (in a body with beams or shells) have no
        # stiffness and no mass: they stay at zero (the stiffness was singular).
        free = np.setdiff1d(free, unused)
    basis = None
    freqs = None
    weighted: list[Interface] = []
    if modes is None:
        nodal_invariants = restrict_invariants(nodal.invariants, free)
        k_ff = nodal.stiffness[free][:, free].tocsc()
        m_ff = nodal.mass[free][:, free].tocsc()
    else:
        if mode_count < 1 and modes == "free-free":
            raise InvalidParameterError(f"{modes} modes need mode_count >= 1", item="mode_count")
        if modes == "fixed-interface" and mode_count == 0:
            # No elastic coordinates: the rigid limit, with the mesh's mass distribution.
            basis, freqs = np.zeros((len(free), 0)), np.zeros(0)
        elif modes == "fixed-interface":
            basis, freqs = fixed_interface_modes(
                nodal.stiffness,
                nodal.mass,
                free,
                mode_count,
                nodes=nodes,
                dofs_per_node=d,
                precision=precision,
            )
        elif modes == "free-free":
            # (over the kept coordinates: all but the rotations of nodes of solids alone)
            whole = len(free) == len(nodes) * d
            basis, freqs = free_free_modes(
                nodal.stiffness if whole else nodal.stiffness[free][:, free],
                nodal.mass if whole else nodal.mass[free][:, free],
                mode_count,
                nodes=nodes,
                dofs_per_node=d,
                dofs=None if whole else free,
                precision=precision,
            )
        elif modes == "craig-bampton":
            if interface_kind != "nodal":
                weighted = interface_objects(
                    members,
                    nodes,
                    elements,
                    interface_weights,
                    rotation=interface_kind == "rbe3",
                    nodal_rotations=d >= 6,
                )
            full, freqs = craig_bampton(
                nodal.stiffness,
                nodal.mass,
                weighted or members,
                mode_count,
                nodes=nodes,
                dofs_per_node=d,
                kind=interface_kind,
                reference="interface" if reference == "interface" else "mean-axis",
                precision=precision,
                unused=unused,
            )
            basis = full[free]
        elif modes == "external":
            if external_modes is None:
                raise InvalidParameterError("external modes need the `external_modes` matrix")
            basis = np.asarray(external_modes, dtype=float)
            if basis.ndim != 2 or basis.shape[0] != len(free):
                raise InvalidParameterError(
                    f"external modes must be ({len(free)}, m) over the kept coordinates, "
                    f"got {basis.shape}"
                )
            if not np.all(np.isfinite(basis)):
                raise InvalidParameterError("external modes contain non-finite values")
            # (with a free frame, the rigid motions first: the frame carries them)
            rigid = (
                rigid_modes(nodes, d)[free]
                if reference in ("none", "mean-axis")
                else np.zeros((len(free), 0))
            )
            _check_independent_modes(basis, nodal.mass[free][:, free], rigid)
        else:
            raise InvalidParameterError(f"unknown modes {modes!r}")
        clock.lap("modes")
        full = np.zeros((len(nodes) * d, basis.shape[1]))
        full[free] = basis
        nodal_invariants = modal_invariants(nodal.invariants, full, nodal.scalar_mass)
        k_ff = basis.T @ (nodal.stiffness[free][:, free] @ basis)
        m_ff = basis.T @ (nodal.mass[free][:, free] @ basis)
    invariants = Invariants(**nodal_invariants, k_ff=k_ff, m_ff=m_ff)
    clock.lap("invariants")
    cb = modes == "craig-bampton"
    reference_data = ReferenceConditions(
        kind=reference,
        nodes=np.asarray(ref_nodes, dtype=np.int64),
        free_dofs=free,
        interfaces=(([it.members for it in weighted] if weighted else members) if cb else None),
        interface_kind=interface_kind if cb else None,
        mode_count=mode_count if cb else None,
        interface_weights=[it.weights for it in weighted] if cb and weighted else None,
    )
    return FlexibleBodyData(
        nodes=nodes,
        node_ids=ids,
        elements=elements,
        element_ids=eids,
        node_sets=sets,
        material=material_data,
        section=None
        if section is None
        else {
            "area": section.area,
            "iy": section.iy,
            "iz": section.iz,
            "torsion_constant": section.torsion_constant,
            "shear_factor": section.shear_factor,
            "beam_theory": beam_theory,
            "orientation": None
            if orientation is None
            else [float(v) for v in np.asarray(orientation, dtype=float).ravel()],
            # Kept only where it is off (the default Rayleigh beam leaves the layout as it was).
            **({} if section.rotary_inertia else {"rotary_inertia": False}),
            # Kept only where given: (n_beams, 2, 3) offsets, (n_beams, 12) released coordinates.
            **({} if beam_offsets is None else {"offsets": np.array(beam_offsets, dtype=float)}),
            **({} if beam_releases is None else {"releases": np.array(beam_releases, dtype=bool)}),
        },
        dofs_per_node=d,
        stiffness=nodal.stiffness,
        mass=nodal.mass,
        mass_kind=mass,
        reference=reference_data,
        modes=basis,
        frequencies=freqs,
        mode_kind=modes,
        invariants=invariants,
        shell=None
        if shell is None
        else {"thickness": shell.thickness, "shear_factor": shell.shear_factor},
        point_masses=point_mass_record(nodal.point_masses),
    )


#: Parts listed by name in the error for a body of several disconnected parts.
_PARTS_LISTED = 5


def _check_parts(
    nodes: NDArray[np.float64],
    ids: NDArray[np.int64],
    elements: Mapping[str, NDArray[np.int64]],
    nodal: NodalBody,
    reference: str,
    held: NDArray[np.int64],
) -> None:
    """Raises `InvalidModelError` for a body made of several disconnected parts (connected
    components of its elements, or of its stiffness matrix without elements) unless the
    reference conditions clamp every part (`held`: the clamped nodes): a part that is not
    held can move rigidly, and free-free or mean-axis modes would take those motions as
    elastic modes of frequency 0. The message names each part by its node and element counts
    and one of its node ids."""
    count, part = mesh_parts(len(nodes), elements, nodal.stiffness, nodal.dofs_per_node)
    if count <= 1:
        return
    held = np.asarray(held, dtype=np.int64)
    loose = np.setdiff1d(np.arange(count), part[held] if len(held) else [])
    if len(loose) == 0:
        return
    node_counts = np.bincount(part, minlength=count)
    element_counts = np.zeros(count, dtype=np.int64)
    for connectivity in elements.values():
        if len(connectivity):
            element_counts += np.bincount(part[connectivity[:, 0]], minlength=count)
    first_nodes = np.unique(part, return_index=True)[1]
    described = [
        f"part {p + 1}: {node_counts[p]} nodes, {element_counts[p]} elements, node "
        f"{ids[first_nodes[p]]}"
        for p in range(min(count, _PARTS_LISTED))
    ]
    if count > _PARTS_LISTED:
        described.append(f"... {count - _PARTS_LISTED} more")
    if len(loose) == count:
        which = "none of them is clamped by the reference conditions"
    else:
        names = ", ".join(str(p + 1) for p in loose[:_PARTS_LISTED])
        verb = "parts {} are" if len(loose) > 1 else "part {} is"
        which = f"{verb.format(names)} not clamped by the reference conditions"
    raise InvalidModelError(
        f"the body is made of {count} disconnected parts ({'; '.join(described)}) and {which} "
        f"(reference={reference!r}): a free part moves rigidly without elastic forces, and "
        "free-free or mean-axis modes would take its rigid motions as elastic modes of "
        "frequency 0. Make each part a body of its own and join them with joints, connect the "
        "parts (shared nodes), or clamp every part (reference='clamped' with reference nodes "
        "in each)",
        item=f"node {ids[first_nodes[loose[0]]]}",
    )


#: Smallest eigenvalue of the correlation matrix of external modes (their mass matrix scaled
#: to a unit diagonal) under which the modes count as dependent.
EXTERNAL_MODE_DEPENDENCE = 1e-10


def _check_independent_modes(
    basis: NDArray[np.float64], mass: Any, rigid: NDArray[np.float64] | None = None
) -> None:
    """Raises `InvalidParameterError` naming the first column of external modes that moves no
    mass or is (nearly) a combination of the columns before it, or of the `rigid` motions (a
    free body frame carries them: a rigid column made the run fail at t = 0 with a singular
    matrix): the modal mass matrix Phi^T M Phi would be singular, and the run would fail later
    with a message about constraints."""
    if basis.shape[1] == 0:
        return
    rigid = np.zeros((basis.shape[0], 0)) if rigid is None else rigid
    nr = rigid.shape[1]
    basis = np.hstack([rigid, basis])
    gram = basis.T @ (mass @ basis)
    gram = 0.5 * (gram + gram.T)
    diagonal = np.diag(gram).copy()
    scale = max(float(diagonal.max()), 1e-300)
    zero = np.flatnonzero(diagonal <= 1e-14 * scale)
    if len(zero):
        raise InvalidParameterError(
            f"external_modes: column {int(zero[0]) - nr} moves no mass (it is zero on the kept "
            "coordinates, or only on massless ones)",
            item="external_modes",
        )
    root = 1.0 / np.sqrt(diagonal)
    correlation = gram * root[:, None] * root[None, :]
    if np.linalg.eigvalsh(correlation)[0] > EXTERNAL_MODE_DEPENDENCE:
        return
    for j in range(max(1, nr), len(diagonal)):
        if np.linalg.eigvalsh(correlation[: j + 1, : j + 1])[0] <= EXTERNAL_MODE_DEPENDENCE:
            same = np.flatnonzero(np.abs(np.abs(correlation[j, nr:j]) - 1.0) < 1e-8)
            if np.linalg.eigvalsh(correlation[np.r_[:nr, j]][:, np.r_[:nr, j]])[0] <= (
                EXTERNAL_MODE_DEPENDENCE
            ):
                which = (
                    "(nearly) a rigid motion of the body, which its frame carries (the "
                    "reference conditions leave the frame free)"
                )
            elif len(same):
                which = f"a multiple of column {int(same[0])}"
            else:
                which = f"(nearly) a combination of columns 0..{j - nr - 1}" + (
                    " and of the rigid motions its frame carries" if nr else ""
                )
            j -= nr
            raise InvalidParameterError(
                f"external_modes: column {j} is {which}: the modal mass matrix would be "
                "singular; give independent mode shapes",
                item="external_modes",
            )


#: Smallest singular value, relative to the largest, of the rigid motions at the coordinates
#: that reference conditions remove (rotations scaled by the body's size): below it, the
#: conditions leave a rigid motion free.
HELD_RIGID_TOLERANCE = 1e-9


def _check_held(
    nodes: NDArray[np.float64],
    ids: NDArray[np.int64],
    d: int,
    free: NDArray[np.int64],
    reference: str,
    ref_nodes: NDArray[np.int64],
    unused: NDArray[np.int64],
) -> None:
    """Raises `InvalidModelError` when the coordinates that the reference conditions remove do
    not hold the six rigid motions (three collinear 3-2-1 nodes, a solid clamped at one node
    or along a line): the body frame would not be defined, the stiffness on the kept
    coordinates singular, and modes or static solutions meaningless. Names the nodes and the
    free motion. The `unused` rotations of nodes of solids alone (in a body with beams or
    shells) hold nothing: they have no stiffness (a line of them was taken to hold the
    rotation about it)."""
    removed = np.setdiff1d(np.setdiff1d(np.arange(len(nodes) * d), free), unused)
    centre = nodes.mean(axis=0)
    size = max(float(np.ptp(nodes, axis=0).max()), 1e-300)
    rigid = rigid_modes((nodes - centre) / size, d)[removed]  # rotations times the size
    _, values, vt = np.linalg.svd(rigid) if len(removed) else (None, np.zeros(0), np.eye(6))
    values = np.concatenate([values, np.zeros(6 - len(values))]) if len(values) < 6 else values
    if values[-1] > HELD_RIGID_TOLERANCE * max(values[0], 1e-300):
        return
    motion = vt[-1]
    translation, rotation = motion[:3], motion[3:] / size  # rad per unit of motion
    if np.linalg.norm(rotation) * size < 1e-6 * np.linalg.norm(translation):
        direction = translation / np.linalg.norm(translation)
        direction *= np.sign(direction[np.argmax(np.abs(direction))])
        what = f"a translation along {_vector_text(direction)}"
    else:
        axis = rotation / np.linalg.norm(rotation)
        axis *= np.sign(axis[np.argmax(np.abs(axis))])  # (0, 0, 1), not (0, 0, -1)
        # u(x) = t + w x (x - centre): the axis passes through p with t + w x (p - centre) = 0.
        point = centre + np.cross(rotation, translation) / float(rotation @ rotation)
        what = f"a rotation about the axis {_vector_text(axis)} through {_vector_text(point)}"
    held = ", ".join(str(int(ids[n])) for n in ref_nodes[:6])
    if len(ref_nodes) > 6:
        held += f", ... ({len(ref_nodes)} nodes)"
    advice = (
        "Choose nodes that are not on one line (3-2-1: b off a, c off the line a-b) or clamp "
        "more nodes"
    )
    if reference in ("simply-supported", "3-2-1") and len(ref_nodes) >= 2:
        # Those conditions hold the body's own axes: b on a's x axis (and c in its x-y
        # plane). A beam along y held so had its twist about x held instead of about its
        # axis, and the advice was about nodes on one line (found by a fault hunt).
        chord = nodes[ref_nodes[1]] - nodes[ref_nodes[0]]
        off = np.linalg.norm(chord[1:]) > 1e-9 * max(float(np.linalg.norm(chord)), 1e-300)
        if off:
            advice = (
                f"{reference!r} holds the body's own axes: node b must lie on the x axis of "
                f"node a (here a to b is {_vector_text(chord)}); mesh the part along x and "
                "turn the body (its orientation when added to a System), or use 'clamped'"
            )
    raise InvalidModelError(
        f"reference={reference!r} at nodes {held} leaves {what} free (the coordinates they "
        "remove do not hold the six rigid motions: nodes on one line, or a solid held at "
        f"one node): the body frame is not defined and the stiffness is singular. {advice}",
        item=f"node {int(ids[ref_nodes[0]])}" if len(ref_nodes) else "reference_nodes",
    )


def solid_only_rotations(
    elements: Mapping[str, NDArray[np.int64]], node_count: int, dofs_per_node: int
) -> NDArray[np.int64]:
    """The rotational coordinates of the nodes that only solids use, in a body with beams or
    shells (6 coordinates per node; solids use the first 3): they carry no stiffness and no
    mass."""
    solids = [k for k, c in elements.items() if k not in ("beam2", *SHELL_ELEMENTS) and len(c)]
    if dofs_per_node != 6 or not solids:
        # (a body from matrices has no elements: its rotations are its own)
        return np.zeros(0, dtype=np.int64)
    carried = np.zeros(node_count, dtype=bool)
    for kind in ("beam2", *SHELL_ELEMENTS):
        if len(elements.get(kind, ())):
            carried[np.asarray(elements[kind], dtype=np.int64).ravel()] = True
    loose = np.flatnonzero(~carried)
    return (6 * loose[:, None] + np.arange(3, 6)).ravel().astype(np.int64)


def _rigid_support(
    nodes: NDArray[np.float64], members: NDArray[np.int64], d: int, unused: NDArray[np.int64]
) -> list[int]:
    """Six coordinates of the nodes `members` (one part) that hold exactly its six rigid
    motions: chosen greedily, for the best conditioning, among the translations of its first
    node, of the node farthest from it and of the node farthest from their line, and (with
    6 coordinates per node) the rotations of the first node (a part along a line)."""
    x = nodes[members]
    a = 0
    b = int(np.argmax(np.linalg.norm(x - x[a], axis=1)))
    axis = (x[b] - x[a]) / max(float(np.linalg.norm(x[b] - x[a])), 1e-300)
    off = (x - x[a]) - np.outer((x - x[a]) @ axis, axis)
    c = int(np.argmax(np.linalg.norm(off, axis=1)))
    size = max(float(np.ptp(x, axis=0).max()), 1e-300)
    picks = list(dict.fromkeys((a, b, c)))
    # The rigid motions at the picked nodes only (row d i + k: node picks[i], coordinate k).
    local = rigid_modes((x[picks] - x.mean(axis=0)) / size, d)
    candidates = [d * i + k for i in range(len(picks)) for k in range(3)]
    if d == 6:
        candidates += [k for k in range(3, 6) if d * members[a] + k not in unused]
    chosen: list[int] = []
    for _ in range(6):
        options = [r for r in candidates if r not in chosen]
        chosen.append(
            max(options, key=lambda r: np.linalg.svd(local[chosen + [r]], compute_uv=False)[-1])
        )
    return [int(d * members[picks[r // d]] + r % d) for r in chosen]


def _zero_energy_modes(
    nodal: NodalBody,
    nodes: NDArray[np.float64],
    elements: Mapping[str, NDArray[np.int64]],
    kinds: Sequence[str] | None = None,
) -> InvalidModelError | None:
    """Whether the stiffness has zero-energy modes besides the rigid motions, on the parts
    (connected components) with elements of `kinds` (None: every part), without the
    rotations of nodes of solids alone: the factorization's error with a support of six
    coordinates per part that hold exactly its rigid motions (the rest is singular if and
    only if another zero-energy mode exists), or None."""
    d = nodal.dofs_per_node
    _, part = mesh_parts(len(nodes), elements, nodal.stiffness, d)
    if kinds is None:
        parts = np.unique(part)
    else:
        used = [np.asarray(elements[k]).ravel() for k in kinds if len(elements.get(k, ()))]
        parts = np.unique(part[np.unique(np.concatenate(used))])
    unused = solid_only_rotations(elements, len(nodes), d)
    kept = np.flatnonzero(np.isin(part, parts))
    dofs = np.setdiff1d((d * kept[:, None] + np.arange(d)).ravel(), unused)
    held = [r for p in parts for r in _rigid_support(nodes, np.flatnonzero(part == p), d, unused)]
    free = np.setdiff1d(dofs, held)
    from .modal import factorize

    try:
        factorize(
            nodal.stiffness[free][:, free].tocsc(),
            dofs=free,
            nodes=nodes,
            dofs_per_node=d,
            name="stiffness with a support of the rigid motions",
        )
    except InvalidModelError as error:
        return error
    return None


def _check_zero_energy_modes(
    nodal: NodalBody,
    nodes: NDArray[np.float64],
    elements: Mapping[str, NDArray[np.int64]],
    eids: Mapping[str, NDArray[np.int64]],
    reassemble: Callable[[dict[str, NDArray[np.int64]]], NodalBody],
) -> None:
    """Raises `InvalidModelError` for a body whose stiffness has zero-energy modes besides
    its rigid motions (it would deform under no force, and the error blamed the reference
    conditions): the hourglass modes of reduced-integration hex20r elements (a lone element
    has six, and some pass along a row of elements one element thick in two directions, as
    in Abaqus' C3D20R), or a mechanism of a body that mixes solids with beams or shells (a
    beam joined to a solid at one node turns freely about it: a node of solids alone has no
    rotation). Checked for bodies with hex20r elements and mixed bodies only; `reassemble`
    assembles the same mesh with other elements (hex20 for hex20r, to tell which)."""
    reduced = len(elements.get("hex20r", ()))
    mixed = solid_only_rotations(elements, len(nodes), nodal.dofs_per_node).size > 0
    if not (reduced or mixed):
        return
    error = _zero_energy_modes(nodal, nodes, elements, None if mixed else ["hex20r"])
    if error is None:
        return
    if reduced:
        full = {("hex20" if k == "hex20r" else k): v for k, v in elements.items()}
        if _zero_energy_modes(reassemble(full), nodes, full, None if mixed else ["hex20"]) is None:
            first = int(eids["hex20r"][0])
            raise InvalidModelError(
                f"the reduced-integration hex20r elements (first: element {first}) have "
                "zero-energy (hourglass) modes in this mesh: a lone element has six, and some "
                "pass along a row of elements one element thick in two directions (as in "
                "Abaqus' C3D20R), so the body would deform under no force. Mesh two or more "
                f"elements through each thickness, or use hex20 (full integration) ({error})",
                item=f"element {first}",
            ) from error
    raise InvalidModelError(
        "the mesh is a mechanism: its stiffness has zero-energy modes besides the rigid "
        "motions (a node of solids alone carries no rotation, so a beam or shell joined to "
        "solids at a single node, or along one line, turns freely about it). Join them over "
        f"more nodes, or connect separate bodies with a joint ({error})",
        item="mesh",
    ) from error


#: A motion whose energy the beams' releases take to less than this fraction of its energy
#: without them is a mechanism of the releases. Round-off limits what the check can tell:
#: a chain of 1000 (3000) slender elements clamped at one end with a hinge gives 1.1e-7
#: (1.2e-7), the same chain propped at its tip, a legitimate structure, 1.9e-4 (6.2e-5): up
#: to some 3000 elements in a row the two are told apart.
RELEASED_MECHANISM = 1e-6


#: Released coordinates up to which `_check_released_mechanism` forms F^T K_0^-1 F densely.
_DENSE_RELEASES = 200


def _check_released_mechanism(
    nodal: NodalBody,
    nodes: NDArray[np.float64],
    elements: Mapping[str, NDArray[np.int64]],
    beam_ids: NDArray[np.int64],
    maps: EndMaps,
    held: NDArray[np.int64],
) -> None:
    """Raises `InvalidModelError` naming the beams when their released coordinates (pin
    flags) leave the body a mechanism: a hinge at a node that nothing else holds, a twist
    released where no other element carries torsion, a cantilever's hinge. A motion of the
    `held` nodes (clamped by the reference conditions, or of rigid or nodal Craig-Bampton
    interfaces) is none of the body's.

    With K the body's stiffness and K_0 = K + sum_e C_e (C_e = `maps.removed`: the stiffness
    the releases take from beam e, positive semi-definite of low rank, C_e = F_e F_e^T) the
    stiffness without the releases, on the coordinates that the six rigid supports of each
    part (or its held nodes, when they hold it) leave free: the least ratio of energies
    x^T K x / x^T K_0 x is 1 - nu with nu the largest eigenvalue of F^T K_0^-1 F (r x r, r
    the released coordinates' count); a mechanism of the releases has ratio 0 (below
    `RELEASED_MECHANISM`). The Cholesky factor of K itself tells them apart only by the sign
    of a pivot that round-off decides. A body that is a mechanism without its releases too
    is left to the other checks."""
    d = nodal.dofs_per_node
    _, part = mesh_parts(len(nodes), elements, nodal.stiffness, d)
    unused = solid_only_rotations(elements, len(nodes), d)
    inside = held[(held >= 0) & (held < len(nodes))]  # (others are named later)
    support: list[int] = []
    for p in np.unique(part):
        members = np.flatnonzero(part == p)
        own = np.setdiff1d(d * np.intersect1d(inside, members)[:, None] + np.arange(d), unused)
        if len(own) and np.linalg.matrix_rank(rigid_modes(nodes - nodes.mean(axis=0), d)[own]) == 6:
            support += [int(r) for r in own]  # (its held nodes hold the part: them alone)
        else:
            support += _rigid_support(nodes, members, d, unused)
    free = np.setdiff1d(np.setdiff1d(np.arange(len(nodes) * d), support), unused)
    position = np.full(len(nodes) * d, -1, dtype=np.int64)
    position[free] = np.arange(len(free))
    # F: the columns F_e of each released beam (its removed stiffness C_e = F_e F_e^T).
    conn = np.asarray(elements["beam2"], dtype=np.int64)
    columns, owners, rows, entries = 0, [], [], []
    for e in np.flatnonzero(maps.releases.any(axis=1)):
        values, vectors = np.linalg.eigh(maps.removed[e])
        kept = values > 1e-12 * max(float(values.max()), 1e-300)
        coordinates = position[(d * conn[e][:, None] + np.arange(6)).ravel()]
        for vector in (vectors[:, kept] * np.sqrt(values[kept])).T:
            inner = coordinates >= 0
            rows.append(coordinates[inner])
            entries.append(vector[inner])
            owners.append(int(e))
            columns += 1
    if columns == 0:
        return
    f = sp.csc_matrix(
        (
            np.concatenate(entries),
            (np.concatenate(rows), np.repeat(np.arange(columns), [len(r) for r in rows])),
        ),
        shape=(len(free), columns),
    )
    removed = f @ f.T
    whole = (nodal.stiffness[free][:, free] + removed).tocsc()
    try:
        factor = factorize(
            whole, dofs=free, nodes=nodes, dofs_per_node=d, name="stiffness without releases"
        )
    except InvalidModelError:
        return
    if columns <= _DENSE_RELEASES:
        dense = f.toarray()
        g = dense.T @ factor.solve(np.ascontiguousarray(dense))
        values, vectors = np.linalg.eigh(0.5 * (g + g.T))
    else:  # (Lanczos: one solve per step, no dense r x r matrix)
        from scipy.sparse.linalg import LinearOperator, eigsh

        operator = LinearOperator(
            (columns, columns), matvec=lambda y: f.T @ factor.solve(np.asarray(f @ y).ravel())
        )
        values, vectors = eigsh(operator, k=1, which="LA", tol=1e-12)
    ratio = 1.0 - float(values[-1])
    if ratio > RELEASED_MECHANISM:
        return
    share = np.zeros(len(beam_ids))
    weights = vectors[:, -1] ** 2
    for column, owner in enumerate(owners):
        share[owner] += weights[column]
    involved = [int(beam_ids[e]) for e in np.flatnonzero(share > 1e-3 * share.max())]
    listed = ", ".join(map(str, involved[:6])) + (", ..." if len(involved) > 6 else "")
    raise InvalidModelError(
        "the mesh is a mechanism: the released coordinates of its beams (beam_releases, "
        f"Nastran's pin flags PA, PB) of elements {listed} let it move without stiffness (a "
        "coordinate released where no other element holds it: a hinge in a cantilever, a "
        "twist released where nothing else carries torsion; the energy of a motion falls to "
        f"{max(ratio, 0.0):.1e} of its energy without the releases). Release fewer "
        "coordinates, hold the body there, or model the joint with a joint",
        item=f"element {involved[0]}",
    )


def _vector_text(v: NDArray[np.float64]) -> str:
    """A vector of a message, rounded (no -0)."""
    return "(" + ", ".join(f"{x + 0.0:.4g}" for x in np.round(v, 12)) + ")"


def static_displacements(body: FlexibleBodyData, forces: ArrayLike) -> NDArray[np.float64]:
    """Nodal displacements (n_dofs,) or (n_dofs, k) of a body held by its reference conditions
    under static nodal forces of the same shape (node-major, body axes): K_ff u = f over the
    free coordinates, or, for modal bodies, the same within the modes (B K_m^-1 B^T f).

    Raises `InvalidParameterError` for forces of the wrong shape and `InvalidModelError` when
    the reference conditions leave the body free to move rigidly."""
    f = np.asarray(forces, dtype=float)
    if f.ndim not in (1, 2) or f.shape[0] != body.dof_count or not np.all(np.isfinite(f)):
        raise InvalidParameterError(
            f"forces must be finite, of shape ({body.dof_count},) or ({body.dof_count}, k), "
            f"got {f.shape}",
            item="forces",
        )
    free = np.asarray(body.reference.free_dofs, dtype=np.int64)
    u = np.zeros_like(f)
    try:
        if body.modes is None:
            k = body.stiffness[free][:, free]
            factor = factorize(
                k,
                dofs=free,
                nodes=body.nodes,
                dofs_per_node=body.dofs_per_node,
                name="stiffness with the reference conditions",
            )
            u[free] = factor.solve(f[free])
        else:
            modal = np.linalg.cholesky(np.asarray(body.invariants.k_ff))
            q = np.linalg.solve(modal.T, np.linalg.solve(modal, body.modes.T @ f[free]))
            u[free] = body.modes @ q
    except (InvalidModelError, np.linalg.LinAlgError) as error:
        raise InvalidModelError(
            f"no static solution: the reference conditions ({body.reference.kind!r}) leave "
            f"the body free to move rigidly ({error})",
            item="reference conditions",
        ) from error
    return u


def body_from_mesh(
    mesh: Mesh | str | os.PathLike[str], material: Material, **options: Any
) -> FlexibleBodyData:
    """`build_body` for a `Mesh` or a mesh file (Gmsh .msh, Abaqus .inp, VTK; see
    `mesh_io.read_mesh`). Node sets of the mesh can be named in `reference_nodes` and
    `interfaces`; the source file is recorded in the body's metadata. Shells take the mesh's
    `shell_thickness` (an Abaqus ``*SHELL SECTION``) unless `shell` is given."""
    source = None
    if not isinstance(mesh, Mesh):
        source = str(mesh)
        mesh = read_mesh(mesh)
    shells = any(len(mesh.elements.get(kind, ())) for kind in SHELL_ELEMENTS)
    if options.get("shell") is None and mesh.shell_thickness is not None and shells:
        # (a solid mesh whose file has a *SHELL SECTION was refused for "shell" not given)
        options = {**options, "shell": mesh.shell_thickness}
    body = build_body(
        mesh.nodes,
        mesh.elements,
        material,
        node_ids=mesh.node_ids,
        element_ids=mesh.element_ids,
        node_sets=mesh.node_sets,
        **options,
    )
    if source is not None:
        body = body.with_metadata(source=source)
    return body


def body_from_matrices(
    nodes: ArrayLike,
    stiffness: Any,
    mass: Any,
    *,
    mass_kind: str = "consistent",
    node_ids: ArrayLike | None = None,
    node_sets: Mapping[str, ArrayLike] | None = None,
    reference: str = "none",
    reference_nodes: str | Sequence[int] = (),
    modes: str | None = None,
    mode_count: int = 0,
    interfaces: Sequence[str | Sequence[int]] = (),
    interface_kind: str = "rbe2",
    interface_weights: str | Sequence[str | ArrayLike] = "auto",
    external_modes: ArrayLike | None = None,
    precision: str = "auto",
    timings: dict[str, float] | None = None,
) -> FlexibleBodyData:
    """A body from stiffness and mass matrices computed elsewhere (another FE code, e.g.
    `mesh_io.read_abaqus_matrix`, or NumPy/SciPy arrays), over the three displacements of each
    of the `nodes` (n, 3) (node-major: row 3 i + k is displacement k of node i), or over three
    displacements and three small rotations of each (6 n rows: beams and shells; row 6 i + 3 +
    k is rotation k of node i; invariants as in `rotational_matrix_invariants`).

    The invariants of motion are derived from the mass matrix, which must have the structure
    of a solid's, M = M_s (x) I_3 (each displacement direction carries the same scalar mass
    matrix M_s, no coupling between directions: consistent mass of isoparametric solid
    elements, or lumped masses). With u0 = sum N_i x_i (isoparametric elements reproduce their
    geometry): m = sum M_s, s0 = 1^T M_s X, J0 = X^T M_s X, I1 and Ibar from the column sums
    of M_s and X^T M_s, and I_kl = M_s (x) e_k e_l^T, exactly the sums over the elements.
    `mass_kind` ("consistent" or "lumped") is recorded. The other options are those of
    `build_body`; the material is unknown (the body's `material` is empty).

    Raises `InvalidParameterError` for matrices that are not square, symmetric and finite or
    not 3 per node, and `InvalidModelError` for a mass matrix without the structure above
    (naming an offending entry) or a non-positive total mass."""
    clock = _Stages(timings)
    _options(reference=reference, modes=modes, interface_kind=interface_kind, precision=precision)
    _check_used_options(
        modes,
        integer(mode_count, "mode_count"),
        interfaces,
        reference=reference,
        reference_nodes=reference_nodes,
        interface_kind=interface_kind,
        interface_weights=interface_weights,
        external_modes=external_modes,
    )
    nodes = np.array(nodes, dtype=float)
    if nodes.ndim != 2 or nodes.shape[1] != 3 or not np.all(np.isfinite(nodes)):
        raise InvalidParameterError(
            f"nodes must be a finite (n, 3) array, got shape {nodes.shape}", item="nodes"
        )
    k, m = matrices_from_arrays(stiffness, mass)
    n = len(nodes)
    if k.shape[0] not in (3 * n, 6 * n):
        raise InvalidParameterError(
            f"matrices of shape {k.shape} for {n} nodes: expected 3 coordinates per node "
            f"({3 * n}) or 6 ({6 * n})",
            item="stiffness matrix",
        )
    choice(mass_kind, "mass_kind", MASS_KINDS)
    dofs_per_node = k.shape[0] // n if n else 3
    ids = (
        np.arange(1, n + 1, dtype=np.int64)
        if node_ids is None
        else np.array(node_ids, dtype=np.int64)
    )
    if ids.shape != (n,) or len(np.unique(ids)) != n:
        raise InvalidParameterError(f"node_ids must be {n} distinct ids", item="node_ids")
    sets = _node_sets(node_sets)
    if dofs_per_node == 6:
        scalar = None
        invariants = rotational_matrix_invariants(nodes, m)
    else:
        scalar = _scalar_mass(m)
        invariants = _matrix_invariants(nodes, scalar, form_i_kl=modes is None)
    if not invariants["mass"] > 0:
        raise InvalidModelError(
            f"the mass matrix gives a total mass of {invariants['mass']:g}", item="mass matrix"
        )
    nodal = NodalBody(
        dofs_per_node=dofs_per_node, stiffness=k, mass=m, invariants=invariants, scalar_mass=scalar
    )
    clock.lap("assemble")
    return _body_from_nodal(
        nodal,
        nodes,
        ids,
        {},
        {},
        sets,
        {},
        section=None,
        beam_theory="euler-bernoulli",
        mass=mass_kind,
        reference=reference,
        reference_nodes=reference_nodes,
        modes=modes,
        mode_count=mode_count,
        interfaces=interfaces,
        interface_kind=interface_kind,
        interface_weights=interface_weights,
        external_modes=external_modes,
        precision=precision,
        clock=clock,
    )


def _matrix_invariants(
    nodes: NDArray[np.float64], scalar: sp.csc_matrix, *, form_i_kl: bool
) -> dict[str, Any]:
    """Nodal invariants of a body of 3-coordinate nodes (n, 3) with mass matrix M_s (x) I_3
    (formulas in `body_from_matrices`); "i_kl" is None unless `form_i_kl`."""
    n = len(nodes)
    column_sums = np.asarray(scalar.sum(axis=0)).ravel()
    weighted = np.asarray((scalar @ nodes).T)  # X^T M_s (3, n)
    eye = np.eye(3)
    return {
        "mass": float(column_sums.sum()),
        "first_moment": column_sums @ nodes,
        "second_moment": nodes.T @ (scalar @ nodes),
        "i1": np.einsum("ka,j->kja", eye, column_sums).reshape(3, 3 * n),
        "ibar": np.einsum("kj,la->klja", weighted, eye).reshape(3, 3, 3 * n),
        "i_kl": solid_i_kl(scalar) if form_i_kl else None,
    }


_EPS = np.zeros((3, 3, 3))
for _i, _j, _k in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
    _EPS[_i, _j, _k], _EPS[_i, _k, _j] = 1.0, -1.0


def rotational_matrix_invariants(nodes: NDArray[np.float64], m: sp.csc_matrix) -> dict[str, Any]:
    """Nodal invariants of a body of 6-coordinate nodes (3 displacements, 3 small rotations:
    beams and shells from another FE code) from its mass matrix M alone (see
    `body_from_matrices`).

    Exact for every mass matrix that moves rigidly with rigid motions (consistent or lumped):
    the mass, first moment and second moment from the rigid modes (T^T M T, T^T M R, R^T M R;
    rotary inertia included), I1 = T^T M and the antisymmetric part of Ibar from R^T M (R_c:
    the rotation about axis c through the frame's origin). Lumped-mass approximation (exact
    for a lumped mass matrix): the symmetric part of Ibar and I_kl from each node's mass m_i
    (its share of the rigid translation, I1) and rotary inertia J_i (the node's rotational
    block of M), as mass points around the node; the consistent mass beyond the lumped one is
    added to the I_aa so that sum_a I_aa = M (the elastic mass is M exactly)."""
    n = len(nodes)
    m = sp.csc_matrix(m)
    rows = np.arange(n) * 6
    eye = np.eye(3)
    # Rigid translations T_a and rotations R_c as (6n, 3) matrices.
    t = np.zeros((6 * n, 3))
    r = np.zeros((6 * n, 3))
    for a in range(3):
        t[rows + a, a] = 1.0
        for c in range(3):
            r[rows + a, c] = np.cross(eye[c], nodes)[:, a]
        r[rows + 3 + a, a] = 1.0
    mt = np.asarray(m @ t)  # (6n, 3): column a = M T_a
    mr = np.asarray(m @ r)
    tmt = t.T @ mt
    mass = float(np.trace(tmt)) / 3.0
    scale = max(abs(mass), 1e-300)
    if np.abs(tmt - mass * eye).max() > 1e-9 * scale:
        raise InvalidModelError(
            f"the mass matrix gives the rigid translations the masses {np.diag(tmt).tolist()} "
            "(and couplings): a mass matrix must carry the same mass in every direction",
            item="mass matrix",
        )
    coupling = t.T @ mr  # [a, c] = eps_ack s0_k
    first = 0.5 * np.einsum("ack,ac->k", _EPS, coupling)
    inertia = r.T @ mr  # the inertia tensor about the origin
    inertia = 0.5 * (inertia + inertia.T)
    second = 0.5 * np.trace(inertia) * eye - inertia
    i1 = mt.T.copy()  # (3, 6n): T_a^T M
    # Lumped parts: node masses and rotary second moments P_i = tr(J_i)/2 I - J_i.
    node_mass = np.mean([i1[a, rows + a] for a in range(3)], axis=0)
    # Each node's rotational block M[6i+3+a, 6i+3+b], all nodes at once.
    by_rows = m.tocsr()
    blocks = np.zeros((n, 3, 3))
    for a in range(3):
        for b in range(3):
            blocks[:, a, b] = np.asarray(by_rows[rows + 3 + a, rows + 3 + b]).ravel()
    blocks = 0.5 * (blocks + blocks.transpose(0, 2, 1))
    moments = 0.5 * np.einsum("i,ab->iab", np.trace(blocks, axis1=1, axis2=2), eye) - blocks
    lumped = np.zeros((3, 3, 6 * n))
    for b in range(3):
        lumped[:, b, rows + b] = (node_mass[:, None] * nodes).T
    # A rotation theta_c of node i moves its points by e_c x r: int r_a (e_c x r)_b.
    rot = np.einsum("bcd,iad->iabc", _EPS, moments)  # [i, a, b, c]
    for c in range(3):
        lumped[:, :, rows + 3 + c] = rot[:, :, :, c].transpose(1, 2, 0)
    symmetric = 0.5 * (lumped + lumped.transpose(1, 0, 2))
    # (M R_c)_k = R_c^T M e_k = eps_cab Ibar_k(a, b): Ibar_k - Ibar_k^T = eps_abc (M R_c)_k.
    antisymmetric = np.einsum("abc,kc->abk", _EPS, mr)
    ibar = symmetric + 0.5 * antisymmetric
    i_kl = [[None] * 3 for _ in range(3)]
    for a in range(3):
        for b in range(3):
            # Translations: int (e_a . e_a)(e_b . e_b) dm = m_i at (a of node i, b of node i).
            entries_r, entries_c, values = list(rows + a), list(rows + b), list(node_mass)
            # Rotations c, d of node i: int (e_c x r)_a (e_d x r)_b = eps_ace eps_bdf P_ef.
            block = np.einsum("ce,df,ief->icd", _EPS[a], _EPS[b], moments)
            for c in range(3):
                for d in range(3):
                    entries_r += list(rows + 3 + c)
                    entries_c += list(rows + 3 + d)
                    values += list(block[:, c, d])
            i_kl[a][b] = sp.csc_matrix((values, (entries_r, entries_c)), shape=(6 * n, 6 * n))
    # The elastic mass M_ff = sum_a I_aa must be M itself: the rest D = M - sum_a I_aa (the
    # consistent mass beyond the lumped one) goes to the direction of its coordinates (entries
    # between displacements of one direction), else to the three directions in equal parts.
    rest = (m - sum(i_kl[a][a] for a in range(3))).tocoo()
    kind_r, kind_c = rest.row % 6, rest.col % 6
    same = (kind_r == kind_c) & (kind_r < 3)
    shared = sp.csc_matrix(
        (rest.data[~same] / 3.0, (rest.row[~same], rest.col[~same])), shape=rest.shape
    )
    for a in range(3):
        mine = same & (kind_r == a)
        own = sp.csc_matrix((rest.data[mine], (rest.row[mine], rest.col[mine])), shape=rest.shape)
        i_kl[a][a] = (i_kl[a][a] + own + shared).tocsc()
    return {
        "mass": mass,
        "first_moment": first,
        "second_moment": 0.5 * (second + second.T),
        "i1": i1,
        "ibar": ibar,
        "i_kl": i_kl,
    }


#: A concentrated mass of a body, checked (`point_mass_entries`): node index, mass, rotary
#: inertia about its centre of mass (3, 3), and the offset of that centre from the node (3,)
#: in body axes.
PointMass = tuple[int, float, NDArray[np.float64], NDArray[np.float64]]


def point_mass_entries(
    point_masses: Mapping[int, Any],
    node_count: int,
    dofs_per_node: int,
    without_rotations: Collection[int] = (),
) -> list[PointMass]:
    """The concentrated masses `point_masses` (see `build_body`), checked: node index ->
    mass, (mass, inertia) or (mass, inertia, offset), inertia None or (3, 3), offset (3,).
    Raises `InvalidParameterError` naming the node for a node index out of range, a mass that
    is not a finite number >= 0, an inertia that is not a symmetric positive semi-definite
    (3, 3) matrix, an offset that is not three finite numbers, or an inertia or an offset at
    a node without rotations: every node with 3 coordinates, and the nodes
    `without_rotations` (of solids alone in a body that mixes them with beams or shells:
    their rotations are no coordinates of the body, and such a mass was welded to the body
    frame)."""
    if not isinstance(point_masses, Mapping):
        raise InvalidParameterError(
            f"point_masses: a mapping node index -> mass, (mass, inertia) or (mass, inertia, "
            f"offset), got {type(point_masses).__name__}",
            item="point_masses",
        )
    entries: list[PointMass] = []
    for key, value in point_masses.items():
        node = integer(key, "point_masses node")
        item = f"point_masses[{node}]"
        if not 0 <= node < node_count:
            raise InvalidParameterError(
                f"{item}: node index {node} out of range 0..{node_count - 1}", item=item
            )
        mass, inertia, offset = value, None, None
        if isinstance(value, tuple | list):
            if len(value) not in (2, 3):
                raise InvalidParameterError(
                    f"{item}: a mass, (mass, inertia) or (mass, inertia, offset), got {value!r}",
                    item=item,
                )
            mass, inertia, offset = (*value, None)[:3]
        mass = number(mass, f"{item} mass", finite=False)
        if not (math.isfinite(mass) and mass >= 0):
            raise InvalidParameterError(
                f"{item}: the mass must be finite and >= 0, got {mass}", item=item
            )
        j = np.zeros((3, 3))
        if inertia is not None:
            j = numbers_array(inertia, f"{item} inertia")
            if j.shape != (3, 3) or not np.all(np.isfinite(j)):
                raise InvalidParameterError(
                    f"{item}: the inertia must be a finite (3, 3) matrix, got shape {j.shape}",
                    item=item,
                )
            scale = max(float(np.abs(j).max()), 1e-300)
            if (
                np.abs(j - j.T).max() > 1e-12 * scale
                or np.linalg.eigvalsh(j).min() < -1e-12 * scale
            ):
                raise InvalidParameterError(
                    f"{item}: the inertia must be symmetric and positive semi-definite, got "
                    f"{j.tolist()}",
                    item=item,
                )
        e = np.zeros(3)
        if offset is not None:
            e = numbers_array(offset, f"{item} offset")
            if e.shape != (3,) or not np.all(np.isfinite(e)):
                raise InvalidParameterError(
                    f"{item}: the offset must be three finite numbers (body axes), got "
                    f"{np.asarray(offset).tolist()}",
                    item=item,
                )
        if not np.isfinite(mass * float(e @ e)) or not np.all(np.isfinite(j + mass * e @ e)):
            raise InvalidParameterError(
                f"{item}: the mass block overflows (mass {mass:g} at offset "
                f"{np.asarray(e).tolist()}: m |e|^2 is not a finite number)",
                item=item,
            )
        for what, given in (("a rotary inertia", j), ("an offset of the centre of mass", e)):
            if np.any(given) and (dofs_per_node != 6 or node in without_rotations):
                raise InvalidParameterError(
                    f"{item}: {what} needs nodes with rotations (beams, shells); the "
                    "nodes of solid elements have displacements only: add the part as a "
                    "rigid body fixed to the node instead",
                    item=item,
                )
        entries.append((node, mass, 0.5 * (j + j.T), e))
    return entries


def combined_point_mass(
    masses: Sequence[tuple[float, NDArray[np.float64], NDArray[np.float64]]],
) -> tuple[float, NDArray[np.float64], NDArray[np.float64]]:
    """One concentrated mass (mass, inertia about its centre, offset of its centre from the
    node) of several at one node: the masses summed, the centre their centre of mass, the
    inertia about it by the parallel-axis theorem (its mass matrix on the node is the sum of
    theirs)."""
    mass = float(sum(m for m, _, _ in masses))
    if mass == 0.0:
        return 0.0, sum((j for _, j, _ in masses), np.zeros((3, 3))), np.zeros(3)
    centre = sum((m * e for m, _, e in masses), np.zeros(3)) / mass
    inertia = np.zeros((3, 3))
    for m, j, e in masses:
        d = e - centre
        inertia += j + m * (d @ d * np.eye(3) - np.outer(d, d))
    return mass, inertia, centre


def point_mass_matrix(
    point_masses: Mapping[int, Any],
    node_count: int,
    dofs_per_node: int,
    without_rotations: Collection[int] = (),
) -> sp.csc_matrix:
    """The nodal mass matrix of concentrated masses (see `build_body`'s `point_masses`,
    checked by `point_mass_entries`): a mass m with its centre at the offset e from the node
    moves with the node's displacement u and small rotation theta as u + theta x e, so its
    block on (u, theta) is [[m I, -m e~], [m e~, J - m e~ e~]] with J its rotary inertia about
    that centre (m I_3 alone on a node with 3 coordinates)."""
    entries = point_mass_entries(point_masses, node_count, dofs_per_node, without_rotations)
    return _entries_matrix(entries, node_count, dofs_per_node)


def point_mass_record(entries: Sequence[PointMass]) -> dict[str, NDArray[Any]]:
    """The concentrated masses `entries` as `FlexibleBodyData.point_masses`: "nodes" (k,)
    indices, "mass" (k,), "inertia" (k, 3, 3) about each centre, "offset" (k, 3)."""
    return {
        "nodes": np.array([entry[0] for entry in entries], dtype=np.int64),
        "mass": np.array([entry[1] for entry in entries], dtype=float),
        "inertia": np.array([entry[2] for entry in entries], dtype=float).reshape(-1, 3, 3),
        "offset": np.array([entry[3] for entry in entries], dtype=float).reshape(-1, 3),
    }


def _entries_matrix(entries: Sequence[PointMass], node_count: int, d: int) -> sp.csc_matrix:
    """The nodal mass matrix of checked concentrated masses (`point_mass_matrix`)."""
    rows: list[int] = []
    cols: list[int] = []
    values: list[float] = []
    for node, mass, inertia, offset in entries:
        block = np.zeros((d, d))
        block[:3, :3] = mass * np.eye(3)
        if d == 6:
            e = skew(offset)
            block[:3, 3:] = -mass * e
            block[3:, :3] = mass * e
            block[3:, 3:] = inertia - mass * e @ e
        r, c = np.nonzero(block)
        rows += list(d * node + r)
        cols += list(d * node + c)
        values += list(block[r, c])
    n = d * node_count
    return sp.csc_matrix((values, (rows, cols)), shape=(n, n))


def point_mass_invariants(
    nodes: NDArray[np.float64], entries: Sequence[PointMass]
) -> dict[str, Any]:
    """The invariants of motion of concentrated masses on the 6-coordinate nodes of a body
    (`point_mass_entries`), exact: each is a rigid part of mass m whose centre c = x_i + e
    moves with its node i, a point c + s of it by u_i + theta_i x (e + s) (the shape rows
    S = [I, -(e + s)~] on the node's coordinates), with the first moment int s dm = 0 and the
    second moments int s s^T dm = P = tr(J)/2 I - J of its rotary inertia J about c. So
    I1 = m [I, -e~], Ibar_ab = int x_a S_b dm, I_ab = int S_a^T S_b dm, linear in m, m e,
    m e e^T and P."""
    n = len(nodes)
    eye = np.eye(3)
    out: dict[str, Any] = {
        "mass": 0.0,
        "first_moment": np.zeros(3),
        "second_moment": np.zeros((3, 3)),
        "i1": np.zeros((3, 6 * n)),
        "ibar": np.zeros((3, 3, 6 * n)),
    }
    coo: dict[tuple[int, int], tuple[list[int], list[int], list[float]]] = {
        (a, b): ([], [], []) for a in range(3) for b in range(3)
    }
    for node, m, inertia, e in entries:
        c = nodes[node] + e
        p = 0.5 * np.trace(inertia) * eye - inertia
        columns = 6 * node + np.arange(6)
        out["mass"] += m
        out["first_moment"] += m * c
        out["second_moment"] += m * np.outer(c, c) + p
        # Rows of S at the centre: [I, -e~]; the spread s adds -s~ to the rotation columns.
        s_c = np.hstack([eye, -skew(e)])
        out["i1"][:, columns] += m * s_c
        # int x_a S_b: x = c + s; int s_a (-s~)_b = -sum_k P_ak (e_k~)_b.
        spread = np.zeros((3, 3, 6))  # [a, b, column]
        for k in range(3):
            spread[:, :, 3:] -= np.einsum("a,bc->abc", p[:, k], skew(eye[k]))
        out["ibar"][:, :, columns] += m * np.einsum("a,bc->abc", c, s_c) + spread
        for a in range(3):
            for b in range(3):
                block = m * np.outer(s_c[a], s_c[b])
                for k in range(3):
                    for j in range(3):
                        block[3:, 3:] += p[k, j] * np.outer(skew(eye[k])[a], skew(eye[j])[b])
                r, q = np.nonzero(block)
                coo[a, b][0].extend(columns[r])
                coo[a, b][1].extend(columns[q])
                coo[a, b][2].extend(block[r, q])
    out["i_kl"] = [
        [sp.csc_matrix((coo[a, b][2], coo[a, b][:2]), shape=(6 * n, 6 * n)) for b in range(3)]
        for a in range(3)
    ]
    return out


def with_point_masses(
    nodal: NodalBody,
    nodes: NDArray[np.float64],
    point_masses: Mapping[int, Any],
    *,
    form_i_kl: bool,
    elements: Mapping[str, Any] | None = None,
) -> NodalBody:
    """`nodal` with the concentrated masses `point_masses` (see `build_body`) added to its mass
    matrix and invariants: the invariants are linear in the mass distribution, and those of
    the masses are exact (`point_mass_invariants` on nodes with rotations, from the matrix of
    masses without inertia by `_matrix_invariants` on the others). With the body's
    `elements`, a rotary inertia or an offset at a node of solids alone is refused also in a
    body that mixes them with beams or shells."""
    d = nodal.dofs_per_node
    loose = () if elements is None else solid_only_rotations(elements, len(nodes), d)[::3] // d
    entries = point_mass_entries(point_masses, len(nodes), d, set(np.asarray(loose).tolist()))
    extra = _entries_matrix(entries, len(nodes), d)
    if extra.nnz == 0:
        return nodal
    if nodal.dofs_per_node == 6:
        scalar = None
        added = point_mass_invariants(nodes, entries)
    else:
        extra_scalar = sp.csc_matrix(extra[0::3, :][:, 0::3])
        scalar = None if nodal.scalar_mass is None else (nodal.scalar_mass + extra_scalar).tocsc()
        added = _matrix_invariants(nodes, extra_scalar, form_i_kl=form_i_kl)
    invariants = dict(nodal.invariants)
    for key in ("mass", "first_moment", "second_moment", "i1", "ibar"):
        invariants[key] = invariants[key] + added[key]
    if invariants.get("i_kl") is not None:  # (formed for both alike: `form_i_kl`)
        invariants["i_kl"] = [
            [(invariants["i_kl"][k][j] + added["i_kl"][k][j]).tocsc() for j in range(3)]
            for k in range(3)
        ]
    return NodalBody(
        dofs_per_node=nodal.dofs_per_node,
        stiffness=nodal.stiffness,
        mass=(nodal.mass + extra).tocsc(),
        invariants=invariants,
        scalar_mass=scalar,
        point_masses=tuple(entries),
    )


def _scalar_mass(m: sp.csc_matrix) -> sp.csc_matrix:
    """M_s of a mass matrix M = M_s (x) I_3, checked."""
    coo = m.tocoo()
    scale = max(float(np.abs(coo.data).max(initial=0.0)), 1e-300)
    coupling = (coo.row % 3 != coo.col % 3) & (np.abs(coo.data) > 1e-12 * scale)
    if coupling.any():
        i = int(np.flatnonzero(coupling)[0])
        raise InvalidModelError(
            f"entry ({coo.row[i]}, {coo.col[i]}) = {coo.data[i]:g} couples two displacement "
            "directions: the mass matrix must be M_s (x) I_3 (a solid's consistent or lumped "
            "mass) to give the invariants of motion",
            item="mass matrix",
        )
    parts = [m[a::3, :][:, a::3].tocsc() for a in range(3)]
    for a in (1, 2):
        difference = abs(parts[a] - parts[0])
        if difference.nnz and difference.max() > 1e-12 * scale:
            row, col = (int(v[0]) for v in np.nonzero(difference > 1e-12 * scale))
            raise InvalidModelError(
                f"entries ({3 * row + a}, {3 * col + a}) and ({3 * row}, {3 * col}) differ: "
                "every displacement direction must carry the same mass (M = M_s (x) I_3)",
                item="mass matrix",
            )
    return parts[0]
