"""Stresses of a deformed body, recovered from its nodal displacements (Rust kernels).

- Solids: the stress of the element's displacement field evaluated at its nodes and
  averaged over the elements around each node (Voigt order xx, yy, zz, yz, xz, xy, body axes,
  Pa): exact for affine fields, otherwise the usual nodal averaging of a displacement-based
  element (lower order than the displacements).
- Beams: the section resultants [N, V_y, V_z, T, M_y, M_z] at both ends of every element
  (element axes; N, N m; tension positive), from the element stiffness: exact for the static
  end-loaded element. A beam with offsets or released coordinates (`flexmbd.fe.beam_ends`)
  gives them at the ends of its offset axis, from the coordinates its tie gives those ends
  (zero along a released coordinate).
- Shells ("quad4", "tri3"): the plane stresses at the top (z = t/2 along the element
  normal), middle and bottom surfaces, evaluated at the element nodes and averaged over the
  shell elements around each node (body axes, Voigt order); the middle surface carries the
  peak 1.5 Q / t of the transverse shear (MITC4; zero for the Kirchhoff triangle). The
  middle-surface stress is also the nodal stress of `recover_stresses`. Averaging across
  elements assumes consistently oriented normals (a mesh whose elements all turn the same
  way).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import _boundary, _core
from ..errors import InvalidParameterError
from .beam_ends import offset_axis_mesh, recorded_ends
from .body import FlexibleBodyData

#: Names of the stress components, in order.
STRESS_COMPONENTS = ("xx", "yy", "zz", "yz", "xz", "xy")
#: Names of the beam section resultants, in order.
SECTION_RESULTANTS = ("N", "Vy", "Vz", "T", "My", "Mz")
#: Names of the shell surfaces of `shell_stresses`, in order.
SHELL_SURFACES = ("top", "middle", "bottom")


def recover_stresses(
    body: FlexibleBodyData, displacements: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Nodal stresses (records, nodes, 6) of the solid elements (and the middle surface of
    shells) and section resultants (records, beams, 2, 6) of the beam elements of `body`, for
    nodal displacements (records, n_dofs) or (n_dofs,) in body axes (node-major,
    ``dofs_per_node`` per node)."""
    nodal, beams, _ = _recovered(body, displacements)
    return nodal, beams


def shell_stresses(body: FlexibleBodyData, displacements: ArrayLike) -> NDArray[np.float64]:
    """Stresses of the shell elements at the top, middle and bottom surfaces
    (`SHELL_SURFACES`), averaged at the nodes: (records, nodes, 3, 6), or (nodes, 3, 6) for
    displacements (n_dofs,); Voigt order, body axes, Pa; zeros at nodes without shells."""
    return _recovered(body, displacements)[2]


def nodal_von_mises(body: FlexibleBodyData, displacements: ArrayLike) -> NDArray[np.float64]:
    """Von Mises stress at the nodes (records, nodes), or (nodes,) for displacements (n_dofs,):
    of the solid elements' stresses, and at the nodes of shells the largest of the shells'
    top, middle and bottom surfaces (the middle surface alone misses their bending stress:
    a satellite panel's 1.3 kPa against 122 kPa at its faces)."""
    nodal, _, shells = _recovered(body, displacements)
    return largest_von_mises(nodal, shells)


def largest_von_mises(nodal: ArrayLike, shells: ArrayLike | None = None) -> NDArray[np.float64]:
    """The von Mises stress of nodal stresses (..., nodes, 6), or where `shells` (..., nodes,
    3, 6: the shells' surfaces, zero at nodes without shells) is given the larger of it and
    the largest of the surfaces'."""
    value = von_mises(nodal)
    if shells is not None:
        value = np.maximum(value, von_mises(shells).max(axis=-1))
    return value


def _recovered(
    body: FlexibleBodyData, displacements: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    material = body.material or {}
    if not any(len(c) for c in body.elements.values()) or "young_modulus" not in material:
        raise InvalidParameterError(
            "stresses: the body has no elements with a material to recover them from (a body "
            "from matrices or a SID file: only its modes are known)",
            item="body",
        )
    u = np.asarray(displacements, dtype=float)
    single = u.ndim == 1
    u = np.atleast_2d(u)
    if u.shape[1] != body.dof_count:
        raise InvalidParameterError(
            f"displacements must have {body.dof_count} entries per record, got {u.shape[1]}"
        )
    material = _boundary.Material(
        material["young_modulus"], material["poisson_ratio"], material["density"]
    )
    section = None
    orientation = None
    shear = False
    if body.section is not None:
        s = body.section
        section = _core.Section(s["area"], s["iy"], s["iz"], s["torsion_constant"])
        if "shear_factor" in s:
            section = section.with_shear_factor(s["shear_factor"])
        orientation = s.get("orientation")
        shear = s.get("beam_theory") == "timoshenko"
    nodes, ids, elements = body.nodes, body.node_ids, dict(body.elements)
    offsets, releases = recorded_ends(body.section)
    # Beams with offsets or releases: on their axis ends, moved by their ties.
    direction = None if orientation is None else np.asarray(orientation, dtype=float)
    on_axes = offset_axis_mesh(
        nodes, ids, elements, material, section, direction, shear, offsets, releases
    )
    if on_axes is not None:
        nodes, ids, elements = on_axes.nodes, on_axes.node_ids, on_axes.elements
        u = np.asarray((on_axes.tie @ u.T).T)
    blocks = {}
    for kind, conn in elements.items():
        blocks[kind] = (
            np.ascontiguousarray(conn, dtype=np.int64),
            np.ascontiguousarray(body.element_ids[kind], dtype=np.int64),
        )
    shell = None
    if body.shell is not None:
        shell = _core.ShellSection(
            float(body.shell["thickness"]),
            shear_factor=float(body.shell.get("shear_factor", 5.0 / 6.0)),
        )
    mesh = _core.FeMesh(
        np.ascontiguousarray(nodes, dtype=float),
        np.ascontiguousarray(ids, dtype=np.int64),
        blocks,
        material,
        section,
        orientation,
        shear,
        shell,
    )
    # No records: those of one zeroed, so that the arrays keep their nodes and elements
    # (records=[] gave section forces of shape (0, 0, 2, 6)).
    empty = len(u) == 0
    if empty:
        u = np.zeros((1, u.shape[1]))
    nodal, beams, shells = _core.recover_stresses(mesh, np.ascontiguousarray(u))
    if empty:
        nodal, beams, shells = nodal[:0], beams[:0], shells[:0]
    if on_axes is not None:  # (the body's nodes come first)
        nodal, shells = nodal[:, : len(body.nodes)], shells[:, : len(body.nodes)]
    if single:
        return nodal[0], beams[0], shells[0]
    return nodal, beams, shells


def von_mises(stress: ArrayLike) -> NDArray[np.float64]:
    """Von Mises equivalent stress of stresses in Voigt order (..., 6)."""
    s = np.asarray(stress, dtype=float)
    xx, yy, zz, yz, xz, xy = (s[..., k] for k in range(6))
    return np.sqrt(
        0.5 * ((xx - yy) ** 2 + (yy - zz) ** 2 + (zz - xx) ** 2) + 3.0 * (yz**2 + xz**2 + xy**2)
    )
