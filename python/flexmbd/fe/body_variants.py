"""Variants of a deformable body: new :class:`FlexibleBodyData` with another stiffness,
material, damping or modal reduction, everything that depends on the change recomputed (the
``with_*`` methods of the body call these functions; see ``docs/flexible-bodies.md``, "Body
variants").

- stiffness scale s: K -> s K is the same as E -> s E (every element stiffness is linear in
  E at a fixed Poisson ratio). The eigenvectors of (s K, M) are those of (K, M) with
  eigenvalues s w^2, and the static (constraint) modes K_ii^-1 K_ib are unchanged, so the
  modes stay, the frequencies scale by sqrt(s) and k_ff = B^T K B by s.
- material: the preprocessor runs again on the kept mesh with the build options recovered
  from the body (reference conditions, mass kind, beam theory, mode kind and count,
  interfaces and their weights).
- modes: the reduction of `preprocess` runs again from the kept nodal K and M and the nodal
  invariants (assembled again for meshed bodies, from M = M_s (x) I_3 for bodies built from
  matrices).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from .._checks import number
from ..errors import InvalidModelError, InvalidParameterError
from ..rotation import skew
from . import preprocess
from .beam_ends import recorded_ends
from .body import FlexibleBodyData, _replace

_MATERIAL_KEYS = ("young_modulus", "poisson_ratio", "density")


def rayleigh_coefficients(value: Any, item: str) -> tuple[float, float]:
    """(alpha, beta) of a Rayleigh damping D = alpha M + beta K, checked: a pair of finite
    numbers >= 0 (alpha in 1/s, beta in s). Raises `InvalidParameterError` naming `item`."""
    try:
        alpha, beta = (float(v) for v in value)
    except (TypeError, ValueError):
        raise InvalidParameterError(
            f"{item}: Rayleigh damping must be a pair (alpha, beta), got {value!r}", item=item
        ) from None
    if not (math.isfinite(alpha) and math.isfinite(beta) and alpha >= 0 and beta >= 0):
        raise InvalidParameterError(
            f"{item}: Rayleigh damping coefficients must be >= 0, got {value}", item=item
        )
    return alpha, beta


def modal_damping_ratio(body: FlexibleBodyData, value: Any, item: str) -> float:
    """The modal damping ratio zeta (finite, >= 0) of a modal body, checked. Raises
    `InvalidModelError` for a nodal body, `InvalidParameterError` for a bad ratio, both
    naming `item`."""
    if body.modes is None:
        raise InvalidModelError(
            f"{item}: modal damping needs a modal body; use Rayleigh damping for nodal bodies",
            item=item,
        )
    try:
        zeta = float(value)
    except (TypeError, ValueError):
        raise InvalidParameterError(
            f"{item}: modal damping ratio must be a number, got {value!r}", item=item
        ) from None
    if not (math.isfinite(zeta) and zeta >= 0):
        raise InvalidParameterError(
            f"{item}: modal damping ratio must be >= 0, got {zeta}", item=item
        )
    return zeta


def _noted(body: FlexibleBodyData, change: str) -> dict[str, str]:
    """The body's metadata with `change` appended to the entry "variants"."""
    metadata = dict(body.metadata)
    previous = metadata.get("variants")
    metadata["variants"] = f"{previous}; {change}" if previous else change
    return metadata


def _checked_damping(body: FlexibleBodyData, damping: Mapping[str, Any] | None) -> Any:
    """The damping specification of `body`, checked against it (modal damping needs
    modes)."""
    if damping is None:
        return None
    rayleigh, modal = damping.get("rayleigh"), damping.get("modal")
    return {
        "rayleigh": None if rayleigh is None else rayleigh_coefficients(rayleigh, "rayleigh"),
        "modal": None if modal is None else modal_damping_ratio(body, modal, "modal"),
    }


def with_stiffness_scale(body: FlexibleBodyData, scale: float) -> FlexibleBodyData:
    """See :meth:`FlexibleBodyData.with_stiffness_scale`."""
    # (float() took '2' and True.)
    s = number(scale, "scale", finite=False)
    if not (math.isfinite(s) and s > 0):
        raise InvalidParameterError(
            f"scale: the stiffness scale must be finite and > 0, got {scale!r}", item="scale"
        )
    invariants = dataclasses.replace(body.invariants, k_ff=s * body.invariants.k_ff)
    material = dict(body.material)
    if "young_modulus" in material:
        material["young_modulus"] = s * float(material["young_modulus"])
    return _replace(
        body,
        stiffness=None if body.stiffness is None else s * body.stiffness,
        invariants=invariants,
        material=material,
        frequencies=None if body.frequencies is None else math.sqrt(s) * body.frequencies,
        metadata=_noted(body, f"stiffness_scale={s!r}"),
    )


def with_damping(
    body: FlexibleBodyData, rayleigh: Any = None, modal: Any = None
) -> FlexibleBodyData:
    """See :meth:`FlexibleBodyData.with_damping`."""
    damping = None
    if rayleigh is not None or modal is not None:
        damping = _checked_damping(body, {"rayleigh": rayleigh, "modal": modal})
    described = "none" if damping is None else f"rayleigh={damping['rayleigh']}"
    if damping is not None:
        described += f", modal={damping['modal']}"
    return _replace(body, damping=damping, metadata=_noted(body, f"damping({described})"))


def modal_damping_matrix(k_ff: Any, m_ff: Any, zeta: float) -> np.ndarray:
    """D_ff of damping ratio `zeta` in every mode of (K_ff, M_ff): M Phi diag(2 zeta omega)
    Phi^T M with Phi the mass-normalized eigenvectors (dense, (n, n))."""
    import scipy.linalg as sla

    k = np.asarray(sp.csc_matrix(k_ff).toarray())
    m = np.asarray(sp.csc_matrix(m_ff).toarray())
    w2, phi = sla.eigh(k, m)
    omega = np.sqrt(np.clip(w2, 0.0, None))
    mphi = m @ phi
    return mphi @ np.diag(2.0 * zeta * omega) @ mphi.T


def damping_matrix(body: FlexibleBodyData) -> np.ndarray:
    """D_ff of the body's own damping (:meth:`FlexibleBodyData.with_damping`), dense (n, n);
    zero when it has none."""
    inv = body.invariants
    n = body.elastic_coordinate_count
    damping = np.zeros((n, n))
    spec = body.damping or {}
    if spec.get("rayleigh") is not None:
        alpha, beta = spec["rayleigh"]
        damping += (
            alpha * sp.csc_matrix(inv.m_ff).toarray() + beta * sp.csc_matrix(inv.k_ff).toarray()
        )
    if spec.get("modal") is not None:
        damping += modal_damping_matrix(inv.k_ff, inv.m_ff, float(spec["modal"]))
    return damping


def _has_mesh(body: FlexibleBodyData) -> bool:
    return bool(body.material) and any(len(conn) for conn in body.elements.values())


def _material(values: Mapping[str, Any]) -> preprocess.Material:
    return preprocess.Material(*(float(values[key]) for key in _MATERIAL_KEYS))


def _element_options(body: FlexibleBodyData) -> dict[str, Any]:
    """The options of a meshed body's elements as `build_body`, `assemble` and
    `_body_from_nodal` take them: section, orientation, beam theory, the beams' offsets and
    releases, shell and mass kind."""
    section, orientation, beam_theory = _section(body)
    offsets, releases = recorded_ends(body.section)
    return {
        "section": section,
        "orientation": orientation,
        "beam_theory": beam_theory,
        "beam_offsets": offsets,
        "beam_releases": releases,
        "shell": _shell(body),
        "mass": body.mass_kind,
    }


def _section(body: FlexibleBodyData) -> tuple[preprocess.Section | None, Any, str]:
    """(section, orientation, beam theory) of a meshed body, as `build_body` takes them."""
    values = body.section
    if values is None:
        return None, None, "euler-bernoulli"
    section = preprocess.Section(
        values["area"], values["iy"], values["iz"], values["torsion_constant"]
    )
    if values.get("shear_factor") is not None:
        section = section.with_shear_factor(values["shear_factor"])
    if values.get("rotary_inertia") is False:
        section = section.without_rotary_inertia()
    orientation = values.get("orientation")
    if orientation is not None:
        orientation = np.asarray(orientation, dtype=float)
    return section, orientation, values.get("beam_theory") or "euler-bernoulli"


def _shell(body: FlexibleBodyData) -> preprocess.ShellSection | None:
    """The shell section of a meshed body, as `build_body` takes it."""
    values = body.shell
    if values is None:
        return None
    return preprocess.ShellSection(
        float(values["thickness"]), shear_factor=float(values.get("shear_factor", 5.0 / 6.0))
    )


def _eigenmode_count(body: FlexibleBodyData) -> int:
    """The `mode_count` the body's modes were built with."""
    if body.modes is None or body.mode_kind == "external":
        return 0
    if body.mode_kind != "craig-bampton":
        return body.modes.shape[1]
    reference = body.reference
    if reference.mode_count is not None:
        return int(reference.mode_count)
    # Bodies saved without the count: every mode that is not static. Each interface gives
    # six static modes (one per coordinate of its nodes for "nodal"); those of the first
    # interface go with an "interface" frame, six (the rigid motions) with a mean-axis frame.
    interfaces = reference.interfaces or ()
    per_interface = [
        body.dofs_per_node * len(members) if reference.interface_kind == "nodal" else 6
        for members in interfaces
    ]
    dropped = per_interface[0] if reference.kind == "interface" and interfaces else 6
    return max(body.modes.shape[1] - max(sum(per_interface) - dropped, 0), 0)


def _reduction_options(body: FlexibleBodyData) -> dict[str, Any]:
    """The `build_body` options of the body's reference conditions and modes."""
    reference = body.reference
    weights = reference.interface_weights
    return {
        "reference": reference.kind,
        # (Held by the first interface or the mean axes, the body's nodes are not options.)
        "reference_nodes": np.asarray(
            reference.nodes if reference.kind in preprocess.NODE_REFERENCE_KINDS else (),
            dtype=np.int64,
        ),
        "modes": body.mode_kind,
        "mode_count": _eigenmode_count(body),
        "interfaces": [np.asarray(members) for members in reference.interfaces or ()],
        "interface_kind": reference.interface_kind or "rbe2",
        "interface_weights": "auto" if weights is None else [np.asarray(w) for w in weights],
        "external_modes": body.modes if body.mode_kind == "external" else None,
    }


def with_material(
    body: FlexibleBodyData,
    material: Any = None,
    *,
    young_modulus: float | None = None,
    poisson_ratio: float | None = None,
    density: float | None = None,
) -> FlexibleBodyData:
    """See :meth:`FlexibleBodyData.with_material`."""
    if not _has_mesh(body):
        raise InvalidModelError(
            "with_material: the body has no mesh and no material (it was built from "
            "matrices): there is nothing to recompute its matrices from; scale its stiffness "
            "with with_stiffness_scale(s), or build it again from other matrices",
            item="material",
        )
    if material is None:
        values = dict(body.material)
    elif isinstance(material, preprocess.Material):
        values = {key: getattr(material, key) for key in _MATERIAL_KEYS}
    elif isinstance(material, Mapping) and all(key in material for key in _MATERIAL_KEYS):
        values = {key: material[key] for key in _MATERIAL_KEYS}
    else:
        raise InvalidParameterError(
            "material: expected a flexmbd.fe.Material or a mapping with "
            f"{', '.join(_MATERIAL_KEYS)}, got {material!r}",
            item="material",
        )
    given = {"young_modulus": young_modulus, "poisson_ratio": poisson_ratio, "density": density}
    values.update({key: value for key, value in given.items() if value is not None})
    for key in _MATERIAL_KEYS:
        # A text or a list was a raw ValueError or TypeError of float().
        values[key] = number(values[key], key)
    new_material = _material(values)
    masses = recorded_point_masses(body)
    rebuilt = preprocess.build_body(
        body.nodes,
        body.elements,
        new_material,
        **_element_options(body),
        node_ids=body.node_ids,
        element_ids=body.element_ids,
        node_sets=body.node_sets,
        check_mesh=False,
        point_masses=masses or None,
        **_reduction_options(body),
    )
    change = ", ".join(f"{key}={float(values[key])!r}" for key in _MATERIAL_KEYS)
    return _replace(
        rebuilt,
        units=body.units,
        damping=_checked_damping(rebuilt, body.damping),
        metadata=_noted(body, f"material({change})"),
    )


def _assembled(body: FlexibleBodyData, *, form_i_kl: bool) -> preprocess.NodalBody:
    """The nodal matrices and invariants of a meshed body's elements, assembled again with its
    own material, section and mass kind (without its point masses)."""
    return preprocess.assemble(
        body.nodes,
        body.elements,
        _material(body.material),
        **_element_options(body),
        node_ids=body.node_ids,
        element_ids=body.element_ids,
        form_i_kl=form_i_kl,
    )


def recorded_point_masses(
    body: FlexibleBodyData, assembled: preprocess.NodalBody | None = None
) -> dict[int, Any]:
    """The concentrated masses of a meshed body in `build_body`'s form (node index -> mass,
    or (mass, inertia about the centre, offset) on nodes with rotations): those recorded in
    ``body.point_masses``, else (bodies of an earlier flexmbd's files) read back from the
    mass matrix beyond that of the elements, `assembled` again when not given
    (`_point_masses`)."""
    record = body.point_masses
    if record is None:
        own = assembled if assembled is not None else _assembled(body, form_i_kl=False)
        return _point_masses(body, own.mass)
    six = body.dofs_per_node == 6
    return {
        int(node): (float(mass), np.array(inertia), np.array(offset)) if six else float(mass)
        for node, mass, inertia, offset in zip(
            record["nodes"], record["mass"], record["inertia"], record["offset"], strict=True
        )
    }


def _point_masses(body: FlexibleBodyData, assembled: sp.csc_matrix) -> dict[int, Any]:
    """The concentrated masses of a meshed body (`build_body`'s `point_masses`): its mass
    matrix beyond the `assembled` one of its elements, node by node, each block
    [[m I, -m e~], [m e~, J - m e~ e~]] read back as (m, J, e) (m alone on nodes with 3
    coordinates). Raises `InvalidModelError` when the difference is not concentrated masses
    at nodes (a mass matrix changed otherwise: the body cannot be built again from its
    mesh)."""
    extra = (sp.csc_matrix(body.mass) - assembled).tocoo()
    scale = max(float(np.abs(assembled.data).max(initial=0.0)), 1e-300)
    keep = np.abs(extra.data) > 1e-12 * scale
    d = body.dofs_per_node
    blocks: dict[int, NDArray[np.float64]] = {}
    for row, col, value in zip(extra.row[keep], extra.col[keep], extra.data[keep], strict=True):
        node = int(row) // d
        if int(col) // d != node:
            raise InvalidModelError(
                f"the body's mass matrix differs from its elements' at ({row}, {col}) by "
                f"{value:g}: not a concentrated mass at a node, so the body cannot be built "
                "again from its mesh",
                item="field 'mass'",
            )
        blocks.setdefault(node, np.zeros((d, d)))[int(row) % d, int(col) % d] = value
    lumps: dict[int, Any] = {}
    for node, block in blocks.items():
        translation = block[:3, :3]
        mass = float(np.trace(translation)) / 3.0
        size = max(abs(mass), 1e-300)
        if np.abs(translation - mass * np.eye(3)).max() > 1e-9 * size:
            raise InvalidModelError(
                f"node {int(body.node_ids[node])}: the mass beyond the elements' differs by "
                f"direction ({np.diag(translation).tolist()}): not a concentrated mass",
                item="field 'mass'",
            )
        if d == 3:
            lumps[node] = mass
            continue
        # -m e~ on (u, theta): e from its antisymmetric entries.
        spread = -block[:3, 3:] / size
        offset = np.array([spread[2, 1], spread[0, 2], spread[1, 0]])
        turn = skew(offset)
        if np.abs(spread - turn).max() > 1e-9 * max(float(np.abs(spread).max()), 1.0):
            raise InvalidModelError(
                f"node {int(body.node_ids[node])}: the mass beyond the elements' couples its "
                "displacements and rotations in a way no offset mass does: not a concentrated "
                "mass",
                item="field 'mass'",
            )
        lumps[node] = (mass, block[3:, 3:] + mass * turn @ turn, offset)
    return lumps


def _nodal_body(body: FlexibleBodyData, *, form_i_kl: bool) -> preprocess.NodalBody:
    """The nodal matrices (the body's own) and nodal invariants of a body."""
    n = body.dof_count
    for name, matrix in (("stiffness", body.stiffness), ("mass", body.mass)):
        if matrix is None or getattr(matrix, "shape", None) != (n, n):
            raise InvalidModelError(
                f"with_modes: the body has no nodal {name} matrix ({n}, {n}) to reduce again "
                f"(found {None if matrix is None else getattr(matrix, 'shape', type(matrix))})",
                item=f"field '{name}'",
            )
    stiffness = sp.csc_matrix(body.stiffness)
    mass = sp.csc_matrix(body.mass)
    if _has_mesh(body):
        assembled = _assembled(body, form_i_kl=form_i_kl)
        lumps = recorded_point_masses(body, assembled)
        if lumps:
            assembled = preprocess.with_point_masses(
                assembled, body.nodes, lumps, form_i_kl=form_i_kl
            )
        invariants, scalar = assembled.invariants, assembled.scalar_mass
    elif body.dofs_per_node == 6:
        scalar = None
        invariants = preprocess.rotational_matrix_invariants(body.nodes, mass)
    else:
        scalar = preprocess._scalar_mass(mass)
        invariants = preprocess._matrix_invariants(body.nodes, scalar, form_i_kl=form_i_kl)
    return preprocess.NodalBody(
        dofs_per_node=body.dofs_per_node,
        stiffness=stiffness,
        mass=mass,
        invariants=invariants,
        scalar_mass=scalar,
    )


def with_modes(
    body: FlexibleBodyData,
    kind: str | None,
    count: int = 0,
    *,
    reference: str | None = None,
    reference_nodes: Any = None,
    interfaces: Any = None,
    interface_kind: str | None = None,
    interface_weights: Any = None,
    external_modes: Any = None,
    precision: str = "auto",
) -> FlexibleBodyData:
    """See :meth:`FlexibleBodyData.with_modes`."""
    if isinstance(count, bool) or not isinstance(count, int | np.integer) or count < 0:
        raise InvalidParameterError(
            f"count: the number of modes must be an integer >= 0, got {count!r}", item="count"
        )
    options = _reduction_options(body)
    if reference is not None:
        if reference != options["reference"]:
            options["reference_nodes"] = ()
        options["reference"] = reference
    if reference_nodes is not None:
        options["reference_nodes"] = reference_nodes
    if interfaces is not None:
        if kind != "craig-bampton":
            raise InvalidParameterError(
                f"interfaces are for Craig-Bampton modes (kind 'craig-bampton'), got kind "
                f"{kind!r}; they would be dropped",
                item="interfaces",
            )
        options["interfaces"] = interfaces
        options["interface_weights"] = "auto"
    if interface_kind is not None:
        options["interface_kind"] = interface_kind
    if interface_weights is not None:
        options["interface_weights"] = interface_weights
    if external_modes is not None or kind != "external":
        options["external_modes"] = external_modes
    # What the body carries and the new modes or frame do not use is dropped; what was given
    # for them is refused (`_check_used_options`).
    if kind != "craig-bampton":
        options["interfaces"] = []
        if interface_kind is None:
            options["interface_kind"] = "rbe2"
        if interface_weights is None:
            options["interface_weights"] = "auto"
    elif interface_kind == "nodal" and interface_weights is None:
        options["interface_weights"] = "auto"
    if options["reference"] not in preprocess.NODE_REFERENCE_KINDS and reference_nodes is None:
        options["reference_nodes"] = ()
    preprocess._check_used_options(
        kind,
        int(count),
        options["interfaces"],
        reference=options["reference"],
        reference_nodes=options["reference_nodes"],
        interface_kind=options["interface_kind"],
        interface_weights=options["interface_weights"],
        external_modes=options.get("external_modes"),
    )
    options["modes"] = kind
    options["mode_count"] = int(count)
    nodal = _nodal_body(body, form_i_kl=kind is None)
    reduced = preprocess._body_from_nodal(
        nodal,
        body.nodes,
        body.node_ids,
        dict(body.elements),
        dict(body.element_ids),
        dict(body.node_sets),
        dict(body.material),
        **_element_options(body),
        precision=precision,
        clock=preprocess._Stages(None),
        **options,
    )
    described = "nodal" if kind is None else f"{kind}, count={int(count)}"
    return _replace(
        reduced,
        units=body.units,
        damping=_checked_damping(reduced, body.damping),
        metadata=_noted(body, f"modes({described})"),
        point_masses=body.point_masses,  # (the same masses, or still not recorded)
    )
