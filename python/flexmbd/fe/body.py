"""``FlexibleBodyData``: everything the preprocessor computes for one deformable body. Nothing
in it changes during a simulation (seed section 3, "computational strategy"), nor after it is
built: the data is immutable, and variants (another stiffness, material, damping or modal
reduction) are new bodies made by its ``with_*`` methods, which recompute everything that
depends on the change (see :mod:`flexmbd.fe.body_variants`)."""

from __future__ import annotations

import copy
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, fields
from typing import TYPE_CHECKING, Any, NoReturn

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from ..errors import FrozenBodyError, InvalidModelError

if TYPE_CHECKING:
    from .preprocess import Material

#: Version of the data layout (and of the HDF5 body file that stores it).
BODY_DATA_VERSION = 1

#: Element types and their number of nodes.
ELEMENT_NODES = {"beam2": 2, "tet4": 4, "tet10": 10, "hex8": 8}

_HOW_TO_CHANGE = (
    "body data is immutable: make variants with the body's with_stiffness_scale, "
    "with_material, with_modes and with_damping methods (they recompute what depends on the "
    "change), and add metadata with with_metadata"
)

#: Relative tolerance of the check that invariants["k_ff"] and ["m_ff"] match the nodal
#: stiffness and mass (round-off is ~1e-15; a changed matrix is off by its change).
_CONSISTENCY_TOLERANCE = 1e-6


class FrozenDict(dict):
    """A ``dict`` that refuses changes (``FrozenBodyError``): the dictionaries of a
    :class:`FlexibleBodyData`. ``dict(frozen)`` is a mutable copy."""

    __slots__ = ("_where",)

    def __init__(self, items: Mapping[Any, Any] | Iterable[Any] = (), where: str = "") -> None:
        super().__init__(items)
        self._where = where

    def _refuse(self, *args: Any, **kwargs: Any) -> NoReturn:
        raise FrozenBodyError(
            f"{self._where or 'the dictionary'} of a FlexibleBodyData cannot be changed: "
            f"{_HOW_TO_CHANGE}",
            item=self._where or None,
        )

    __setitem__ = __delitem__ = __ior__ = _refuse
    clear = pop = popitem = setdefault = update = _refuse

    def __reduce__(self) -> tuple[Any, ...]:
        return (FrozenDict, (dict(self), self._where))


class FrozenList(list):
    """A ``list`` that refuses changes (``FrozenBodyError``): the lists of a
    :class:`FlexibleBodyData` (for example ``invariants["i_kl"]``). ``list(frozen)`` is a
    mutable copy."""

    __slots__ = ("_where",)

    def __init__(self, items: Iterable[Any] = (), where: str = "") -> None:
        super().__init__(items)
        self._where = where

    def _refuse(self, *args: Any, **kwargs: Any) -> NoReturn:
        raise FrozenBodyError(
            f"{self._where or 'the list'} of a FlexibleBodyData cannot be changed: "
            f"{_HOW_TO_CHANGE}",
            item=self._where or None,
        )

    __setitem__ = __delitem__ = __iadd__ = __imul__ = _refuse
    append = extend = insert = pop = remove = clear = sort = reverse = _refuse

    def __reduce__(self) -> tuple[Any, ...]:
        return (FrozenList, (list(self), self._where))


def _read_only(array: np.ndarray) -> np.ndarray:
    """A read-only view of `array` (the array itself when it is read-only already); the
    caller's array stays writable."""
    if not array.flags.writeable:
        return array
    view = array.view()
    view.setflags(write=False)
    return view


def _freeze(value: Any, where: str) -> Any:
    """`value` with its arrays read-only and its dicts and lists frozen (recursively). Sparse
    matrices become new matrix objects over read-only views of the same arrays (no copy)."""
    if isinstance(value, np.ndarray):
        return _read_only(value)
    if sp.issparse(value):
        names = {"csc": ("data", "indices", "indptr"), "csr": ("data", "indices", "indptr")}
        names["bsr"] = names["csr"]
        names["coo"] = ("data", "coords") if hasattr(value, "coords") else ("data", "row", "col")
        if value.format not in names:
            return value
        arrays = [getattr(value, name) for name in names[value.format]]
        flat = [a for item in arrays for a in (item if isinstance(item, tuple) else (item,))]
        if not any(a.flags.writeable for a in flat):
            return value
        frozen = copy.copy(value)
        for name, item in zip(names[value.format], arrays, strict=True):
            read_only = (
                tuple(_read_only(a) for a in item) if isinstance(item, tuple) else _read_only(item)
            )
            object.__setattr__(frozen, name, read_only)
        return frozen
    if isinstance(value, dict):
        return FrozenDict(
            {key: _freeze(item, f"{where}[{key!r}]") for key, item in value.items()}, where
        )
    if isinstance(value, list):
        return FrozenList(
            [_freeze(item, f"{where}[{index}]") for index, item in enumerate(value)], where
        )
    if type(value) is tuple:
        return tuple(_freeze(item, f"{where}[{index}]") for index, item in enumerate(value))
    return value


def _rebuild(values: dict[str, Any]) -> FlexibleBodyData:
    """Unpickling and copying go through the constructor (which freezes and checks)."""
    return FlexibleBodyData(**values)


@dataclass(frozen=True)
class FlexibleBodyData:
    """The constant data of a deformable body in the floating frame of reference.

    Coordinates are "nodal" (``dofs_per_node`` per node, node-major: [u_x, u_y, u_z] and, for
    beams, [theta_x, theta_y, theta_z] after them) before reference conditions. The reference
    conditions keep the dofs listed in ``reference["free_dofs"]``; the elastic coordinates of
    the body are those free dofs, or, with modes, the modal coordinates q_f with
    u_free = modes @ q_f (the modal matrix B_m of seed eq. 18).

    The data is immutable: assigning to a field, to an element of one of its arrays (they are
    read-only) or to an entry of one of its dictionaries or lists raises
    :class:`flexmbd.FrozenBodyError` (a :class:`dataclasses.FrozenInstanceError`) or NumPy's
    ``ValueError`` for arrays. Variants are new bodies made by methods that recompute
    everything that depends on the change: :meth:`with_stiffness_scale`,
    :meth:`with_material`, :meth:`with_damping`, :meth:`with_modes` (and
    :meth:`with_metadata` for notes). ``dataclasses.replace`` builds a new body without
    recomputing anything; the constructor then checks that ``invariants["k_ff"]`` and
    ``invariants["m_ff"]`` still equal ``stiffness`` and ``mass`` reduced to the elastic
    coordinates (one product with a probe vector each, cheap for large bodies) and raises
    ``InvalidModelError`` if not, but it cannot check the other invariants, the modes or the
    frequencies: use the ``with_*`` methods.

    Attributes:
        nodes: undeformed node positions in the body frame, (n_nodes, 3), m.
        node_ids: ids of the nodes in the source mesh, (n_nodes,).
        elements: element type ("beam2", "tet4", "tet10", "hex8") -> (n_elements, nodes)
            indices into ``nodes``.
        element_ids: element type -> (n_elements,) ids in the source mesh.
        node_sets: name -> indices into ``nodes``.
        material: {"young_modulus": Pa, "poisson_ratio": -, "density": kg/m^3}; empty for
            bodies built from matrices.
        section: beam section {"area", "iy", "iz", "torsion_constant", ...} or None.
        dofs_per_node: 3 for solids, 6 when beams are present.
        stiffness: K_ff, sparse (n_dofs, n_dofs), nodal.
        mass: M_ff, sparse (n_dofs, n_dofs), nodal.
        mass_kind: "consistent" or "lumped".
        reference: {"kind": "none" | "clamped" | "3-2-1" | "simply-supported" | "mean-axis" |
            "interface", "nodes": indices, "free_dofs": indices of the kept nodal dofs}; for
            Craig-Bampton modes also "interfaces" (node indices of each), "interface_kind",
            "mode_count" (the eigenmodes asked for) and, for weighted interfaces,
            "interface_weights".
        modes: modal matrix (n_free_dofs, n_modes) or None (nodal coordinates).
        frequencies: natural frequencies of the modes (Hz) or None.
        mode_kind: "free-free", "fixed-interface", "craig-bampton", "external" or None.
        invariants: invariants of motion in the elastic coordinates of the body (see
            ``DESIGN.md``): "mass" (float), "first_moment" (3,), "second_moment" (3, 3),
            "i1" (3, n_f), "i_kl" (3, 3) nested list of (n_f, n_f) matrices (sparse for nodal,
            dense for modal), "ibar" (3, 3, n_f), and the reduced stiffness and mass "k_ff"
            and "m_ff" (n_f, n_f).
        damping: the body's damping, used by :meth:`flexmbd.System.add_flexible_body` when
            it is given neither `rayleigh_damping` nor `modal_damping`: None (undamped), or
            {"rayleigh": (alpha 1/s, beta s) or None, "modal": damping ratio or None} (see
            :meth:`with_damping`).
        units: names of the units of length, mass and time.
        metadata: free-form strings (source file, creation date, "variants": the ``with_*``
            methods applied, ...).
        version: data layout version.
    """

    nodes: NDArray[np.float64]
    node_ids: NDArray[np.int64]
    elements: dict[str, NDArray[np.int64]]
    element_ids: dict[str, NDArray[np.int64]]
    node_sets: dict[str, NDArray[np.int64]]
    material: dict[str, float]
    section: dict[str, Any] | None
    dofs_per_node: int
    stiffness: sp.csc_matrix
    mass: sp.csc_matrix
    mass_kind: str
    reference: dict[str, Any]
    modes: NDArray[np.float64] | None = None
    frequencies: NDArray[np.float64] | None = None
    mode_kind: str | None = None
    invariants: dict[str, Any] = field(default_factory=dict)
    damping: dict[str, Any] | None = None
    units: dict[str, str] = field(
        default_factory=lambda: {"length": "m", "mass": "kg", "time": "s"}
    )
    metadata: dict[str, str] = field(default_factory=dict)
    version: int = BODY_DATA_VERSION

    def __post_init__(self) -> None:
        for item in fields(self):
            object.__setattr__(self, item.name, _freeze(getattr(self, item.name), item.name))
        _check_reduced_matrices(self)

    def __reduce__(self) -> tuple[Any, ...]:
        return (_rebuild, ({item.name: getattr(self, item.name) for item in fields(self)},))

    @property
    def node_count(self) -> int:
        return len(self.nodes)

    @property
    def dof_count(self) -> int:
        """Number of nodal coordinates before reference conditions."""
        return self.node_count * self.dofs_per_node

    @property
    def elastic_coordinate_count(self) -> int:
        """Number of elastic coordinates q_f of the body."""
        if self.modes is not None:
            return self.modes.shape[1]
        return len(self.reference["free_dofs"])

    # Variants ----------------------------------------------------------------------------

    def with_stiffness_scale(self, scale: float) -> FlexibleBodyData:
        """A new body with its stiffness multiplied by `scale` (finite, > 0): the nodal K,
        ``invariants["k_ff"]`` and the Young's modulus of the material (so that stresses and
        the geometric stiffness of beams agree) times `scale`; mode shapes unchanged (K and
        s K have the same eigenvectors and static modes), frequencies times sqrt(`scale`).
        Works for every body, also those built from matrices.

        Raises `InvalidParameterError` (item "scale") for a non-finite or non-positive
        scale."""
        from .body_variants import with_stiffness_scale

        return with_stiffness_scale(self, scale)

    def with_material(
        self,
        material: Material | Mapping[str, float] | None = None,
        *,
        young_modulus: float | None = None,
        poisson_ratio: float | None = None,
        density: float | None = None,
    ) -> FlexibleBodyData:
        """A new body of another material, rebuilt from the kept mesh (nodes, elements,
        section) by the preprocessor (:func:`flexmbd.fe.build_body`) with the same
        reference conditions, mass kind, beam theory, mode kind, number of modes and
        interfaces: equal to building it from scratch with that material.

        `material`: a :class:`flexmbd.fe.Material` or a mapping with "young_modulus" (Pa),
        "poisson_ratio" and "density" (kg/m^3); default the body's. `young_modulus`,
        `poisson_ratio` and `density` override single values. The cost is that of building
        the body (assembly, and the eigenmodes of modal bodies).

        Raises `InvalidModelError` (item "material") for a body without a mesh (built from
        matrices: use :meth:`with_stiffness_scale`), `InvalidParameterError` for invalid
        material values."""
        from .body_variants import with_material

        return with_material(
            self,
            material,
            young_modulus=young_modulus,
            poisson_ratio=poisson_ratio,
            density=density,
        )

    def with_damping(
        self, rayleigh: tuple[float, float] | None = None, modal: float | None = None
    ) -> FlexibleBodyData:
        """A new body that carries a damping specification, used by
        :meth:`flexmbd.System.add_flexible_body` when that is given neither
        `rayleigh_damping` nor `modal_damping` (explicit arguments win, and then the body's
        damping is not used at all): `rayleigh=(alpha, beta)` (1/s, s), D_ff = alpha M_ff +
        beta K_ff; `modal=zeta`, the damping ratio of every mode (modal bodies). Both None:
        undamped. Saved in body files.

        Raises `InvalidParameterError` (item "rayleigh" or "modal") for negative or
        non-finite values, `InvalidModelError` (item "modal") for modal damping of a nodal
        body."""
        from .body_variants import with_damping

        return with_damping(self, rayleigh, modal)

    def with_modes(
        self,
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
        """A new body with another modal reduction, computed from the kept nodal matrices
        ``stiffness`` and ``mass`` (before reference conditions) and nodal invariants
        (assembled again for meshed bodies, derived from the mass matrix for bodies built
        from matrices): equal to building the body from scratch with these options.

        `kind`: None (nodal elastic coordinates), "fixed-interface", "free-free",
        "craig-bampton" or "external" (see :func:`flexmbd.fe.build_body`); `count`: the
        eigenmodes kept. `reference`, `reference_nodes`, `interfaces`, `interface_kind`,
        `interface_weights`: as in ``build_body``; None keeps the body's (the reference
        nodes are dropped when `reference` changes). `external_modes` (n_free_dofs, m) for
        kind "external" (default: the body's own external modes).

        Raises `InvalidModelError` when the body has no nodal stiffness and mass matrices
        (n_dofs, n_dofs), for options ``build_body`` refuses, and for a body that carries
        modal damping made nodal (change its damping first)."""
        from .body_variants import with_modes

        return with_modes(
            self,
            kind,
            count,
            reference=reference,
            reference_nodes=reference_nodes,
            interfaces=interfaces,
            interface_kind=interface_kind,
            interface_weights=interface_weights,
            external_modes=external_modes,
            precision=precision,
        )

    def with_metadata(
        self, entries: Mapping[str, str] | None = None, **more: str
    ) -> FlexibleBodyData:
        """A new body with `entries` and `more` added to (or replacing entries of) its
        metadata; nothing else changes."""
        metadata = dict(self.metadata)
        metadata.update(entries or {})
        metadata.update(more)
        return _replace(self, metadata=metadata)


def _replace(body: FlexibleBodyData, **changes: Any) -> FlexibleBodyData:
    values = {item.name: getattr(body, item.name) for item in fields(body)}
    values.update(changes)
    return FlexibleBodyData(**values)


def _refuse_assignment(self: FlexibleBodyData, name: str, value: Any = None) -> NoReturn:
    raise FrozenBodyError(
        f"cannot assign to field '{name}' of a FlexibleBodyData: {_HOW_TO_CHANGE}",
        item=f"field '{name}'",
    )


def _refuse_deletion(self: FlexibleBodyData, name: str) -> NoReturn:
    raise FrozenBodyError(
        f"cannot delete field '{name}' of a FlexibleBodyData: {_HOW_TO_CHANGE}",
        item=f"field '{name}'",
    )


# The frozen dataclass's own __setattr__ raises a FrozenInstanceError without advice; these
# raise its typed subclass that says how to make a variant.
FlexibleBodyData.__setattr__ = _refuse_assignment  # type: ignore[method-assign,assignment]
FlexibleBodyData.__delattr__ = _refuse_deletion  # type: ignore[method-assign,assignment]


def _check_reduced_matrices(body: FlexibleBodyData) -> None:
    """Raises `InvalidModelError` unless ``invariants["k_ff"]`` and ``["m_ff"]`` equal the
    nodal stiffness and mass reduced to the elastic coordinates, B^T K B with B the selection
    of the free dofs or the modes, tested on one probe vector (O(nonzeros) work). Bodies
    without these entries or without nodal matrices are not checked."""
    reference = body.reference
    free = reference.get("free_dofs") if isinstance(reference, Mapping) else None
    invariants = body.invariants if isinstance(body.invariants, Mapping) else {}
    if free is None or body.nodes is None:
        return
    free = np.asarray(free, dtype=np.int64)
    for key, nodal, field_name in (
        ("k_ff", body.stiffness, "stiffness"),
        ("m_ff", body.mass, "mass"),
    ):
        reduced = invariants.get(key)
        if reduced is None or nodal is None:
            continue
        item = f"invariants['{key}']"
        n_dofs = body.dof_count
        count = len(free) if body.modes is None else body.modes.shape[1]
        shapes_agree = (
            nodal.shape == (n_dofs, n_dofs)
            and reduced.shape == (count, count)
            and (body.modes is None or body.modes.shape[0] == len(free))
            and (len(free) == 0 or (free.min() >= 0 and free.max() < n_dofs))
        )
        if not shapes_agree:
            raise InvalidModelError(
                f"{item} of shape {reduced.shape} does not fit the body ({n_dofs} nodal "
                f"coordinates, {len(free)} kept, {count} elastic coordinates, {field_name} of "
                f"shape {nodal.shape}): {_HOW_TO_CHANGE}",
                item=item,
            )
        if count == 0:
            continue
        probe = np.cos(1.2345 * np.arange(count) + 0.5)
        displacement = np.zeros(n_dofs)
        displacement[free] = probe if body.modes is None else body.modes @ probe
        expected = np.asarray(nodal @ displacement).ravel()[free]
        if body.modes is not None:
            expected = body.modes.T @ expected
        actual = np.asarray(reduced @ probe).ravel()
        size = max(float(np.linalg.norm(expected)), float(np.linalg.norm(actual)))
        deviation = float(np.linalg.norm(actual - expected))
        if not deviation <= _CONSISTENCY_TOLERANCE * size:
            raise InvalidModelError(
                f"{item} does not equal the nodal {field_name} reduced to the elastic "
                f"coordinates (relative deviation {deviation / max(size, 1e-300):.1e}); was "
                f"the body changed with dataclasses.replace? {_HOW_TO_CHANGE}",
                item=item,
            )
