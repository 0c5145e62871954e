"""``FlexibleBodyData``: everything the preprocessor computes for one deformable body. Nothing
in it changes during a simulation (seed section 3, "computational strategy"), nor after it is
built: the data is immutable, and variants (another stiffness, material, damping or modal
reduction) are new bodies made by its ``with_*`` methods, which recompute everything that
depends on the change (see :mod:`flexmbd.fe.body_variants`)."""

from __future__ import annotations

import copy
import math
import numbers
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field, fields
from typing import TYPE_CHECKING, Any, NoReturn, Self

import numpy as np
from numpy.typing import NDArray

from ..errors import FrozenBodyError, InvalidModelError, InvalidParameterError

if TYPE_CHECKING:
    import scipy.sparse as sp

    from .preprocess import Material

#: Version of the data layout (and of the HDF5 body file that stores it).
BODY_DATA_VERSION = 1

#: Element types and their number of nodes.
#: "quad4" and "tri3" are flat shells (6 coordinates per node, see `docs/preprocessor.md`);
#: "hex8i" is the hexahedron with incompatible modes (Abaqus' C3D8I), "hex20" the quadratic
#: (serendipity) hexahedron and "hex20r" the same with reduced integration (C3D20R), "hex27"
#: the triquadratic (Lagrange) hexahedron (Gmsh's and VTK's 27-node hexahedron),
#: "wedge6" the linear wedge (triangular prism, Abaqus C3D6), "wedge15" the quadratic
#: (serendipity) wedge (Abaqus C3D15), "wedge18" the quadratic Lagrange wedge (Gmsh's 18-node
#: prism), "pyramid5" the linear pyramid (Gmsh's, Nastran's CPYRAM of 5 grids), "pyramid13"
#: and "pyramid14" the quadratic ones (Gmsh's and VTK's 13-node pyramid, Gmsh's 14-node one).
ELEMENT_NODES = {
    "beam2": 2,
    "tet4": 4,
    "tet10": 10,
    "hex8": 8,
    "hex8i": 8,
    "hex20": 20,
    "hex20r": 20,
    "hex27": 27,
    "wedge6": 6,
    "wedge15": 15,
    "wedge18": 18,
    "pyramid5": 5,
    "pyramid13": 13,
    "pyramid14": 14,
    "quad4": 4,
    "tri3": 3,
}

#: Element types whose cell (shape, node order, faces) is another type's: they differ in
#: their stiffness only.
_SAME_CELL = {"hex8i": "hex8", "hex20r": "hex20"}


def cell_of(kind: str) -> str:
    """The cell type of an element type: the type itself, "hex8" for "hex8i" and "hex20" for
    "hex20r"."""
    return _SAME_CELL.get(kind, kind)


_HOW_TO_CHANGE = (
    "body data is immutable: make variants with the body's with_stiffness_scale, "
    "with_material, with_modes and with_damping methods (they recompute what depends on the "
    "change), and add metadata with with_metadata"
)

#: Relative tolerance of the check that invariants.k_ff and .m_ff match the nodal
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
    :class:`FlexibleBodyData` (for example ``invariants.i_kl``). ``list(frozen)`` is a
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
    import scipy.sparse as sp

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


class _Entries(Mapping[str, Any]):
    """Base of :class:`Invariants` and :class:`ReferenceConditions`: a frozen dataclass whose
    fields are also readable as a read-only mapping, the dictionary form these parts of a
    :class:`FlexibleBodyData` had before (``obj["k_ff"]``, ``obj.get("interfaces")``, ``"k_ff"
    in obj``, ``keys()``, ``items()``, iteration over the keys). The mapping holds the fields
    that are set: an optional field that is None is not one of its keys, as in the old
    dictionaries. ``dict(obj)`` is a mutable (shallow) copy."""

    #: The field this object is in a FlexibleBodyData (error messages).
    _FIELD = ""
    #: Fields that must be given (not None), then the optional ones (None when absent), in
    #: the order of the dataclass fields (and of the members of a body file; a test checks
    #: that the two agree).
    _REQUIRED: tuple[str, ...] = ()
    _OPTIONAL: tuple[str, ...] = ()
    #: What the message for a missing field advises.
    _ADVICE = ""

    def __post_init__(self) -> None:
        missing = [name for name in self._REQUIRED if getattr(self, name) is None]
        if missing:
            raise self._missing(missing)
        for name in (*self._REQUIRED, *self._OPTIONAL):
            where = f"{self._FIELD}[{name!r}]"
            object.__setattr__(self, name, _freeze(getattr(self, name), where))

    @classmethod
    def _item(cls) -> str:
        return f"field '{cls._FIELD}'"

    @classmethod
    def _missing(cls, names: list[str]) -> InvalidModelError:
        entries = "entry" if len(names) == 1 else "entries"
        return InvalidModelError(
            f"{cls._item()} has no {entries} {', '.join(repr(n) for n in names)} "
            f"({cls.__name__} needs {', '.join(repr(n) for n in cls._REQUIRED)}): {cls._ADVICE}",
            item=cls._item(),
        )

    @classmethod
    def from_mapping(cls, values: Any) -> Self:
        """`values` itself when it is of this type, else a new object of its entries (a
        ``dict``, or any mapping, of field names to values, the form of older code and of the
        members of a body file). Raises `InvalidModelError` naming the missing or unknown
        keys, or for a value that is not a mapping."""
        if isinstance(values, cls):
            return values
        if not isinstance(values, Mapping):
            raise InvalidModelError(
                f"{cls._item()} must be {_article(cls.__name__)} {cls.__name__} or a dict of its "
                f"entries, got {type(values).__name__}: {cls._ADVICE}",
                item=cls._item(),
            )
        known = (*cls._REQUIRED, *cls._OPTIONAL)
        unknown = [key for key in values if key not in known]
        if unknown:
            entries = "entry" if len(unknown) == 1 else "entries"
            raise InvalidModelError(
                f"{cls._item()} has unknown {entries} {', '.join(repr(k) for k in unknown)} "
                f"(the entries of {cls.__name__}: {', '.join(repr(k) for k in known)})",
                item=cls._item(),
            )
        missing = [name for name in cls._REQUIRED if values.get(name) is None]
        if missing:
            raise cls._missing(missing)
        return cls(**values)

    # The read-only mapping (the old dictionary form) -----------------------------------------

    def _keys(self) -> tuple[str, ...]:
        return self._REQUIRED + tuple(n for n in self._OPTIONAL if getattr(self, n) is not None)

    def __getitem__(self, key: str) -> Any:
        if isinstance(key, str) and (
            key in self._REQUIRED or (key in self._OPTIONAL and getattr(self, key) is not None)
        ):
            return getattr(self, key)
        raise KeyError(key)

    def __iter__(self) -> Iterator[str]:
        return iter(self._keys())

    def __len__(self) -> int:
        return len(self._keys())

    def _refuse(self, *args: Any, **kwargs: Any) -> NoReturn:
        raise FrozenBodyError(
            f"{self._FIELD} of a FlexibleBodyData cannot be changed: {_HOW_TO_CHANGE}",
            item=self._FIELD,
        )

    __setitem__ = __delitem__ = __ior__ = _refuse
    clear = pop = popitem = setdefault = update = _refuse

    def __reduce__(self) -> tuple[Any, ...]:
        # Through the constructor, which freezes the values again.
        values = {name: getattr(self, name) for name in (*self._REQUIRED, *self._OPTIONAL)}
        return (_rebuild_entries, (type(self), values))


def _article(name: str) -> str:
    return "an" if name[:1] in "AEIOU" else "a"


def _rebuild_entries(cls: type[_Entries], values: dict[str, Any]) -> _Entries:
    return cls(**values)


@dataclass(frozen=True, eq=False, kw_only=True)
class Invariants(_Entries):
    """The invariants of motion of a deformable body in its elastic coordinates q_f (n_f of
    them: the kept nodal coordinates, or the modal coordinates; see ``DESIGN.md`` and
    ``docs/preprocessor.md``), the ``invariants`` of a :class:`FlexibleBodyData`, with its
    reduced stiffness and mass. Immutable: arrays read-only, ``i_kl`` a
    frozen nested list (:class:`FrozenList`); changing a field or an entry raises
    :class:`flexmbd.FrozenBodyError`.

    Fields (all required):
        mass: total mass m (float), kg.
        first_moment: int rho u0 dV, (3,).
        second_moment: J0 = int rho u0 u0^T dV, (3, 3), symmetric positive semi-definite.
        i1: I1, (3, n_f).
        ibar: Ibar_kl, (3, 3, n_f).
        i_kl: I_kl, 3 x 3 nested list of (n_f, n_f) matrices (sparse for nodal bodies, dense
            for modal ones).
        k_ff: reduced stiffness K_ff, (n_f, n_f).
        m_ff: reduced mass M_ff, (n_f, n_f).

    Built with keywords (``Invariants(mass=..., ...)``) or from a dict of the same entries
    (:meth:`from_mapping`, which the :class:`FlexibleBodyData` constructor applies to a dict).
    The old dictionary form reads too: ``invariants["k_ff"]``, ``"k_ff" in invariants``,
    ``invariants.keys()``, ``items()``, iteration over the entry names; ``dict(invariants)``
    is a mutable copy. Variants: ``dataclasses.replace(invariants, k_ff=...)``, checked when
    it becomes part of a body."""

    mass: float
    first_moment: NDArray[np.float64]
    second_moment: NDArray[np.float64]
    i1: NDArray[np.float64]
    ibar: NDArray[np.float64]
    i_kl: list[list[Any]]
    k_ff: Any
    m_ff: Any

    _FIELD = "invariants"
    _REQUIRED = ("mass", "first_moment", "second_moment", "i1", "ibar", "i_kl", "k_ff", "m_ff")
    _ADVICE = (
        "bodies get their invariants of motion from the preprocessor (flexmbd.fe.build_body, "
        "body_from_mesh, body_from_matrices) or from a body file written by it"
    )


@dataclass(frozen=True, eq=False, kw_only=True)
class ReferenceConditions(_Entries):
    """The reference conditions of a deformable body (which nodal coordinates are kept as
    elastic coordinates) and, for Craig-Bampton modes, their interfaces: the ``reference`` of
    a :class:`FlexibleBodyData`. Immutable like it (arrays read-only, lists frozen).

    Fields:
        kind: "none", "clamped", "3-2-1", "simply-supported", "mean-axis" or "interface".
        nodes: indices of the reference nodes, (k,) int64.
        free_dofs: indices of the kept nodal coordinates, (n_free,) int64.
        interfaces: Craig-Bampton modes only, else None: the node indices of each interface.
        interface_kind: Craig-Bampton modes only, else None: "rbe2", "rbe3" or "nodal".
        mode_count: Craig-Bampton modes only, else None: the eigenmodes asked for (None too
            for bodies saved before it was recorded).
        interface_weights: weighted (RBE2, RBE3) interfaces only, else None: the weight of
            each node of each interface.

    Built with keywords or from a dict of the same entries (:meth:`from_mapping`; the optional
    ones may be left out). The old dictionary form reads too: ``reference["free_dofs"]``,
    ``reference.get("interfaces", ())``, ``"interfaces" in reference`` (False when None),
    ``keys()``, ``items()``, iteration over the names of the entries that are set."""

    kind: str
    nodes: NDArray[np.int64]
    free_dofs: NDArray[np.int64]
    interfaces: list[NDArray[np.int64]] | None = None
    interface_kind: str | None = None
    mode_count: int | None = None
    interface_weights: list[NDArray[np.float64]] | None = None

    _FIELD = "reference"
    _REQUIRED = ("kind", "nodes", "free_dofs")
    _OPTIONAL = ("interfaces", "interface_kind", "mode_count", "interface_weights")
    _ADVICE = (
        "bodies get their reference conditions from the preprocessor (flexmbd.fe.build_body, "
        "body_from_mesh, body_from_matrices) or from a body file written by it"
    )


def _refuse_entry_assignment(self: _Entries, name: str, value: Any = None) -> NoReturn:
    raise FrozenBodyError(
        f"cannot assign to {self._FIELD}.{name} of a FlexibleBodyData: {_HOW_TO_CHANGE}",
        item=f"{self._FIELD}.{name}",
    )


def _refuse_entry_deletion(self: _Entries, name: str) -> NoReturn:
    raise FrozenBodyError(
        f"cannot delete {self._FIELD}.{name} of a FlexibleBodyData: {_HOW_TO_CHANGE}",
        item=f"{self._FIELD}.{name}",
    )


for _cls in (Invariants, ReferenceConditions):
    # The frozen dataclass's own methods raise a FrozenInstanceError without advice.
    _cls.__setattr__ = _refuse_entry_assignment  # type: ignore[method-assign,assignment]
    _cls.__delattr__ = _refuse_entry_deletion  # type: ignore[method-assign,assignment]
del _cls


def _rebuild(values: dict[str, Any]) -> FlexibleBodyData:
    """Unpickling and copying go through the constructor (which freezes and checks)."""
    return FlexibleBodyData(**values)


@dataclass(frozen=True)
class FlexibleBodyData:
    """The constant data of a deformable body in the floating frame of reference.

    Coordinates are "nodal" (``dofs_per_node`` per node, node-major: [u_x, u_y, u_z] and, for
    beams, [theta_x, theta_y, theta_z] after them) before reference conditions. The reference
    conditions keep the dofs listed in ``reference.free_dofs``; the elastic coordinates of
    the body are those free dofs, or, with modes, the modal coordinates q_f with
    u_free = modes @ q_f (the modal matrix B_m of seed eq. 18).

    The data is immutable: assigning to a field, to an element of one of its arrays (they are
    read-only) or to an entry of one of its dictionaries or lists raises
    :class:`flexmbd.FrozenBodyError` (a :class:`dataclasses.FrozenInstanceError`) or NumPy's
    ``ValueError`` for arrays. Variants are new bodies made by methods that recompute
    everything that depends on the change: :meth:`with_stiffness_scale`,
    :meth:`with_material`, :meth:`with_damping`, :meth:`with_modes` (and
    :meth:`with_metadata` for notes). ``dataclasses.replace`` builds a new body without
    recomputing anything; the constructor then checks that ``invariants.k_ff`` and
    ``invariants.m_ff`` still equal ``stiffness`` and ``mass`` reduced to the elastic
    coordinates (one product with a probe vector each, cheap for large bodies) and raises
    ``InvalidModelError`` if not, but it cannot check the other invariants, the modes or the
    frequencies: use the ``with_*`` methods.

    ``reference`` and ``invariants`` are typed objects, :class:`ReferenceConditions` and
    :class:`Invariants` (``body.reference.free_dofs``, ``body.invariants.k_ff``). The
    constructor also takes them as dicts of their entries (the form of older code) and
    converts them, raising `InvalidModelError` for a missing or unknown entry; and they still
    read as read-only mappings (``body.invariants["k_ff"]``, the old form).

    Attributes:
        nodes: undeformed node positions in the body frame, (n_nodes, 3), m.
        node_ids: ids of the nodes in the source mesh, (n_nodes,).
        elements: element type ("beam2", "tet4", "tet10", "hex8", "hex8i", "hex20", "hex20r",
            "hex27", "wedge6", "wedge15", "wedge18", "pyramid5", "pyramid13", "pyramid14", and
            the shells "quad4", "tri3") -> (n_elements, nodes) indices into ``nodes``.
        element_ids: element type -> (n_elements,) ids in the source mesh.
        node_sets: name -> indices into ``nodes``.
        material: {"young_modulus": Pa, "poisson_ratio": -, "density": kg/m^3}; empty for
            bodies built from matrices.
        section: beam section {"area", "iy", "iz", "torsion_constant", ...} or None; with
            "offsets" (n_beams, 2, 3) and "releases" (n_beams, 12) where the beams have them
            (`build_body`'s `beam_offsets`, `beam_releases`).
        dofs_per_node: 3 for solids, 6 when beams or shells are present.
        stiffness: K_ff, sparse (n_dofs, n_dofs), nodal.
        mass: M_ff, sparse (n_dofs, n_dofs), nodal.
        mass_kind: "consistent" or "lumped".
        reference: the reference conditions, a :class:`ReferenceConditions`: ``kind``
            ("none" | "clamped" | "3-2-1" | "simply-supported" | "mean-axis" | "interface"),
            ``nodes`` (indices), ``free_dofs`` (indices of the kept nodal dofs); for
            Craig-Bampton modes also ``interfaces`` (node indices of each),
            ``interface_kind``, ``mode_count`` (the eigenmodes asked for) and, for weighted
            interfaces, ``interface_weights`` (None otherwise).
        modes: modal matrix (n_free_dofs, n_modes) or None (nodal coordinates).
        frequencies: natural frequencies of the modes (Hz) or None.
        mode_kind: "free-free", "fixed-interface", "craig-bampton", "external" or None.
        invariants: invariants of motion in the elastic coordinates of the body (see
            ``DESIGN.md``), an :class:`Invariants`: ``mass`` (float), ``first_moment``
            (3,), ``second_moment`` (3, 3), ``i1`` (3, n_f), ``i_kl`` (3, 3) nested list of
            (n_f, n_f) matrices (sparse for nodal, dense for modal), ``ibar`` (3, 3, n_f), and
            the reduced stiffness and mass ``k_ff`` and ``m_ff`` (n_f, n_f).
        damping: the body's damping, used by :meth:`flexmbd.System.add_flexible_body` when
            it is given neither `rayleigh_damping` nor `modal_damping`: None (undamped), or
            {"rayleigh": (alpha 1/s, beta s) or None, "modal": damping ratio or None} (see
            :meth:`with_damping`).
        shell: shell section {"thickness", "shear_factor"} of the "quad4" and "tri3"
            elements, or None.
        units: names of the units of length, mass and time.
        metadata: free-form strings (source file, creation date, "variants": the ``with_*``
            methods applied, ...).
        point_masses: the concentrated masses that `build_body` added to the elements'
            (its `point_masses`, Nastran's CONM2): {"nodes": (k,) indices into ``nodes``,
            "mass": (k,), "inertia": (k, 3, 3) rotary inertia about each centre of mass,
            "offset": (k, 3) centre of mass from the node}, empty (k = 0) for a body built
            without them; None where not recorded (bodies built from matrices, body files of
            an earlier flexmbd: the masses are then told from the mass matrix beyond the
            elements', which costs an assembly of the elements).
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
    reference: ReferenceConditions
    modes: NDArray[np.float64] | None = None
    frequencies: NDArray[np.float64] | None = None
    mode_kind: str | None = None
    # Required (the constructor refuses None); a default only because the fields before it
    # have one.
    invariants: Invariants = None  # type: ignore[assignment]
    damping: dict[str, Any] | None = None
    shell: dict[str, Any] | None = None
    units: dict[str, str] = field(
        default_factory=lambda: {"length": "m", "mass": "kg", "time": "s"}
    )
    metadata: dict[str, str] = field(default_factory=dict)
    point_masses: dict[str, NDArray[Any]] | None = None
    version: int = BODY_DATA_VERSION

    def __post_init__(self) -> None:
        # Dicts (older code, body files) become the typed parts; they are frozen already.
        object.__setattr__(self, "invariants", Invariants.from_mapping(self.invariants))
        object.__setattr__(self, "reference", ReferenceConditions.from_mapping(self.reference))
        for item in fields(self):
            object.__setattr__(self, item.name, _freeze(getattr(self, item.name), item.name))
        _check_node_array(self.nodes)
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
        return len(self.reference.free_dofs)

    # Variants ----------------------------------------------------------------------------

    def with_stiffness_scale(self, scale: float) -> FlexibleBodyData:
        """A new body with its stiffness multiplied by `scale` (finite, > 0): the nodal K,
        ``invariants.k_ff`` and the Young's modulus of the material (so that stresses and
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
    """Raises `InvalidModelError` unless ``invariants.k_ff`` and ``.m_ff`` equal the nodal
    stiffness and mass reduced to the elastic coordinates, B^T K B with B the selection of
    the free dofs or the modes, tested on one probe vector (O(nonzeros) work). Bodies without
    nodal matrices are not checked."""
    if body.nodes is None:
        return
    free = np.asarray(body.reference.free_dofs, dtype=np.int64)
    for key, reduced, nodal, field_name in (
        ("k_ff", body.invariants.k_ff, body.stiffness, "stiffness"),
        ("m_ff", body.invariants.m_ff, body.mass, "mass"),
    ):
        if nodal is None:
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
        # Huge or non-finite entries make the deviation non-finite: refused below, silently.
        with np.errstate(over="ignore", invalid="ignore"):
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


# Checks of the fields ---------------------------------------------------------------------------

#: Relative tolerance of the checks that invariants.second_moment is symmetric and positive
#: semi-definite (times its trace).
SECOND_MOMENT_TOLERANCE = 1e-9


def _field(path: str) -> str:
    return f"field {path!r}"


def _bad_shape(path: str, detail: str) -> InvalidModelError:
    return InvalidModelError(f"{_field(path)} {detail}", item=_field(path))


def _all_finite(values: Any) -> bool:
    """Whether every entry of a numeric array is finite (a sum first: no temporary array
    unless the sum overflows or is not finite)."""
    with np.errstate(over="ignore", invalid="ignore"):
        if np.isfinite(np.sum(values)):
            return True
    return bool(np.isfinite(values).all())


def _numeric_array(value: Any, path: str, kinds: str = "fiu") -> np.ndarray:
    """`value` as a NumPy array of one of the dtype `kinds`, else `InvalidModelError`."""
    if not isinstance(value, np.ndarray | list | tuple):
        raise _bad_shape(path, f"must be an array, got {type(value).__name__}")
    try:
        array = np.asarray(value)
    except (TypeError, ValueError) as error:
        raise _bad_shape(path, f"is not an array ({error})") from None
    if array.dtype.kind not in kinds:
        wanted = "an integer" if kinds == "iu" else "a numeric"
        raise _bad_shape(path, f"must be {wanted} array, got dtype {array.dtype}")
    return array


def _index_array(value: Any, path: str, bound: int, what: str) -> np.ndarray:
    """A 1-D integer array of indices in 0 .. `bound` - 1."""
    array = _numeric_array(value, path, "iu")
    if array.ndim != 1:
        raise _bad_shape(path, f"must be a 1-D array of {what} indices, got shape {array.shape}")
    if array.size and (array.min() < 0 or array.max() >= bound):
        wrong = array[(array < 0) | (array >= bound)][0]
        raise _bad_shape(path, f"holds {what} index {wrong}, outside 0 .. {bound - 1}")
    return array


def _check_matrix(value: Any, path: str, size: int) -> None:
    """A dense or sparse (size, size) matrix of finite numbers."""
    import scipy.sparse as sp

    if sp.issparse(value):
        shape, data = value.shape, value.data
        if data.dtype.kind not in "fiu":
            raise _bad_shape(path, f"must hold numbers, got dtype {data.dtype}")
    else:
        data = _numeric_array(value, path)
        shape = data.shape
    if shape != (size, size):
        raise _bad_shape(path, f"has shape {shape}, expected ({size}, {size})")
    if not _all_finite(data):
        raise InvalidParameterError(f"{_field(path)} has non-finite entries", item=_field(path))


def _check_dense(value: Any, path: str, shape: tuple[int, ...]) -> np.ndarray:
    """A dense array of `shape` with finite numbers."""
    array = _numeric_array(value, path)
    if array.shape != shape:
        raise _bad_shape(path, f"has shape {array.shape}, expected {shape}")
    if not _all_finite(array):
        raise InvalidParameterError(f"{_field(path)} has non-finite entries", item=_field(path))
    return array


def _check_node_array(nodes: Any) -> None:
    """Node positions must be an (n, 3) array (the construction's cheap check; `check_body`
    also checks that they are finite)."""
    if nodes is None:
        return
    array = _numeric_array(nodes, "nodes")
    if array.ndim != 2 or array.shape[1] != 3:
        raise _bad_shape("nodes", f"must be an (n, 3) array of positions, got shape {array.shape}")


def check_body(body: FlexibleBodyData | Mapping[str, Any]) -> None:
    """Checks the fields of a deformable body (a :class:`FlexibleBodyData` or a mapping of its
    fields) against each other before they reach the core or a file: node positions (n, 3)
    and finite; ``dofs_per_node`` 3 or 6; node ids, elements, node sets and reference
    conditions that index existing nodes and coordinates; nodal stiffness and mass (n_dofs,
    n_dofs) (or None); modes (n_free_dofs, m) and frequencies finite; and the invariants of
    motion that are present, in the elastic coordinates n_f: "mass" a finite number > 0,
    "first_moment" (3,), "second_moment" J0 = int rho u0 u0^T dV (3, 3), symmetric positive
    semi-definite with a positive trace, "i1" (3, n_f), "ibar" (3, 3, n_f), "i_kl" 3 x 3
    matrices (n_f, n_f), "k_ff" and "m_ff" (n_f, n_f), all finite.

    Raises `InvalidModelError` for a field of the wrong type or shape, `InvalidParameterError`
    for non-finite values, a non-positive mass or a second moment that is not positive
    semi-definite; the item and the message name the field (``field 'nodes'``, ``field
    'invariants["second_moment"]'``)."""
    values = (
        body
        if isinstance(body, Mapping)
        else {item.name: getattr(body, item.name) for item in fields(body)}
    )
    nodes = _numeric_array(values.get("nodes"), "nodes")
    if nodes.ndim != 2 or nodes.shape[1] != 3:
        raise _bad_shape("nodes", f"must be an (n, 3) array of positions, got shape {nodes.shape}")
    count = len(nodes)
    node_ids = _numeric_array(values.get("node_ids"), "node_ids", "iu")
    if node_ids.shape != (count,):
        raise _bad_shape("node_ids", f"has shape {node_ids.shape}, expected ({count},)")
    bad = np.flatnonzero(~np.isfinite(nodes).all(axis=1)) if not _all_finite(nodes) else []
    if len(bad):
        raise InvalidParameterError(
            f"{_field('nodes')}: node {node_ids[bad[0]]} has non-finite coordinates "
            f"{nodes[bad[0]].tolist()}",
            item=_field("nodes"),
        )
    dofs_per_node = values.get("dofs_per_node")
    if isinstance(dofs_per_node, bool) or dofs_per_node not in (3, 6):
        raise _bad_shape("dofs_per_node", f"must be 3 or 6, got {dofs_per_node!r}")
    n_dofs = count * int(dofs_per_node)

    for name in ("elements", "element_ids", "node_sets", "reference", "invariants"):
        if not isinstance(values.get(name), Mapping):
            raise _bad_shape(name, f"must be a dict, got {type(values.get(name)).__name__}")
    for kind, connectivity in values["elements"].items():
        path = f'elements["{kind}"]'
        if kind not in ELEMENT_NODES:
            raise _bad_shape(path, f"has an unknown element type (known: {list(ELEMENT_NODES)})")
        array = _numeric_array(connectivity, path, "iu")
        if array.ndim != 2 or array.shape[1] != ELEMENT_NODES[kind]:
            raise _bad_shape(path, f"has shape {array.shape}, expected (n, {ELEMENT_NODES[kind]})")
        _index_array(array.ravel(), path, count, "node")
        ids = values["element_ids"].get(kind)
        if ids is not None and np.shape(ids) != (len(array),):
            raise _bad_shape(
                f'element_ids["{kind}"]', f"has shape {np.shape(ids)}, expected ({len(array)},)"
            )
    for name, indices in values["node_sets"].items():
        _index_array(indices, f'node_sets["{name}"]', count, "node")

    for name in ("stiffness", "mass"):
        if values.get(name) is not None:
            _check_matrix(values[name], name, n_dofs)
    # A ReferenceConditions, or the dict read from a body file (read as mappings).
    reference = values["reference"]
    if "free_dofs" not in reference:
        raise _bad_shape("reference", "has no entry 'free_dofs'")
    free = _index_array(reference["free_dofs"], 'reference["free_dofs"]', n_dofs, "coordinate")
    if len(np.unique(free)) != len(free):
        raise _bad_shape('reference["free_dofs"]', "repeats a coordinate")
    if reference.get("nodes") is not None:
        _index_array(reference["nodes"], 'reference["nodes"]', count, "node")
    _check_interfaces(reference, count)
    unique_ids, first, repeats = np.unique(node_ids, return_index=True, return_counts=True)
    if np.any(repeats > 1):
        twice = int(unique_ids[np.argmax(repeats > 1)])
        at = np.flatnonzero(node_ids == twice)[:2].tolist()
        raise _bad_shape("node_ids", f"repeats node id {twice} (nodes {at[0]} and {at[1]})")
    _check_material(values.get("material"))
    modes = values.get("modes")
    elastic = len(free)
    if modes is not None:
        array = _numeric_array(modes, "modes")
        if array.ndim != 2 or array.shape[0] != len(free):
            raise _bad_shape(
                "modes",
                f"has shape {array.shape}, expected ({len(free)}, m): one row per kept coordinate",
            )
        if not _all_finite(array):
            raise InvalidParameterError(
                f"{_field('modes')} has non-finite entries", item=_field("modes")
            )
        elastic = array.shape[1]
    if values.get("frequencies") is not None:
        array = _numeric_array(values["frequencies"], "frequencies")
        if array.ndim != 1 or not _all_finite(array) or (array.size and array.min() < 0):
            raise InvalidParameterError(
                f"{_field('frequencies')} must be a 1-D array of finite numbers >= 0 (Hz)"
                + (f", got {array.min()}" if array.ndim == 1 and array.size else ""),
                item=_field("frequencies"),
            )
        if modes is not None and len(array) != elastic:
            raise _bad_shape("frequencies", f"has {len(array)} entries for {elastic} modes")
    _check_damping(values.get("damping"), modes is not None)
    _check_point_masses(values.get("point_masses"), count, int(dofs_per_node))
    # Read as mappings: the typed Invariants of a body, or the dict read from a body file
    # before it becomes one.
    _check_invariants(values["invariants"], elastic)


#: The entries of `FlexibleBodyData.point_masses` and their shapes after the count k.
_POINT_MASS_SHAPES = {"nodes": (), "mass": (), "inertia": (3, 3), "offset": (3,)}


def _check_point_masses(record: Any, count: int, dofs_per_node: int) -> None:
    """The recorded concentrated masses: None, or "nodes" indices of existing nodes and
    finite "mass" >= 0, "inertia" (k, 3, 3) symmetric positive semi-definite and "offset"
    (k, 3) of the same count k, the inertias and offsets zero on bodies without rotations."""
    if record is None:
        return
    if not isinstance(record, Mapping) or set(record) != set(_POINT_MASS_SHAPES):
        raise _bad_shape(
            "point_masses",
            f"must be None or a dict with the entries {list(_POINT_MASS_SHAPES)}, got "
            f"{sorted(record) if isinstance(record, Mapping) else type(record).__name__}",
        )
    size = np.shape(record["nodes"])[:1]
    _index_array(record["nodes"], 'point_masses["nodes"]', count, "node")
    for key, shape in _POINT_MASS_SHAPES.items():
        if key == "nodes":
            continue
        path = f'point_masses["{key}"]'
        array = _numeric_array(record[key], path)
        if array.shape != size + shape:
            raise _bad_shape(path, f"has shape {array.shape}, expected {size + shape}")
        if not _all_finite(array) or (key == "mass" and array.size and array.min() < 0):
            raise InvalidParameterError(
                f"{_field(path)} must be finite" + (" and >= 0" if key == "mass" else ""),
                item=_field(path),
            )
        if key != "mass" and dofs_per_node == 3 and np.any(array):
            raise InvalidParameterError(
                f"{_field(path)} must be zero: the body's nodes have no rotations",
                item=_field(path),
            )
        if key == "inertia" and array.size:
            scale = max(float(np.abs(array).max()), 1e-300)
            bad = np.abs(array - array.transpose(0, 2, 1)).max(axis=(1, 2)) > 1e-12 * scale
            bad |= np.linalg.eigvalsh(0.5 * (array + array.transpose(0, 2, 1))).min(axis=1) < (
                -1e-12 * scale
            )
            if bad.any():
                k = int(np.flatnonzero(bad)[0])
                raise InvalidParameterError(
                    f"{_field(path)}: entry {k} must be symmetric and positive semi-definite, got "
                    f"{array[k].tolist()}",
                    item=_field(path),
                )


def _check_interfaces(reference: Mapping[str, Any], count: int) -> None:
    """The Craig-Bampton interfaces (node indices) and their weights (one finite number per
    node, positive in sum) of `reference`."""
    interfaces = reference.get("interfaces")
    if interfaces is not None:
        for i, members in enumerate(interfaces):
            _index_array(members, f'reference["interfaces"][{i}]', count, "node")
    weights = reference.get("interface_weights")
    if weights is None:
        return
    path = 'reference["interface_weights"]'
    if interfaces is None or len(weights) != len(interfaces):
        given = "no" if interfaces is None else len(interfaces)
        raise _bad_shape(path, f"has {len(weights)} entries for {given} interfaces")
    for i, (w, members) in enumerate(zip(weights, interfaces, strict=True)):
        where = f"{path}[{i}]"
        array = _numeric_array(w, where)
        if array.shape != (len(members),):
            raise _bad_shape(where, f"has shape {array.shape}, expected ({len(members)},)")
        if not _all_finite(array) or not float(array.sum()) > 0:
            raise InvalidParameterError(
                f"{_field(where)}: the weights must be finite and positive in sum, got sum "
                f"{float(array.sum())}",
                item=_field(where),
            )


#: Material entries and their admissible open intervals.
_MATERIAL_RANGES = {
    "young_modulus": (0.0, math.inf, "Pa"),
    "poisson_ratio": (-1.0, 0.5, ""),
    "density": (0.0, math.inf, "kg/m^3"),
}


def _check_material(material: Any) -> None:
    """The material of a meshed body (empty for bodies built from matrices): E > 0, -1 < nu <
    0.5, rho > 0, all finite."""
    if material is None or (isinstance(material, Mapping) and not material):
        return
    if not isinstance(material, Mapping):
        raise _bad_shape("material", f"must be a dict, got {type(material).__name__}")
    for key, (low, high, unit) in _MATERIAL_RANGES.items():
        if key not in material:
            continue
        value = material[key]
        path = f'material["{key}"]'
        if isinstance(value, bool) or not isinstance(value, numbers.Real):
            raise _bad_shape(path, f"must be a number, got {type(value).__name__}")
        if not (math.isfinite(value) and low < value < high):
            bounds = f"> {low:g}" if math.isinf(high) else f"between {low:g} and {high:g}"
            raise InvalidParameterError(
                f"{_field(path)} must be finite and {bounds}, got {value}"
                + (f" {unit}" if unit else ""),
                item=_field(path),
            )


def _check_damping(damping: Any, modal_body: bool) -> None:
    """A body's damping: None, or {"rayleigh": (alpha, beta) >= 0 or None, "modal": ratio
    >= 0 or None (modal bodies only)}."""
    if damping is None:
        return
    if not isinstance(damping, Mapping):
        raise _bad_shape("damping", f"must be a dict or None, got {type(damping).__name__}")
    rayleigh, modal = damping.get("rayleigh"), damping.get("modal")
    if rayleigh is not None:
        path = 'damping["rayleigh"]'
        try:
            pair = [float(v) for v in rayleigh]
        except (TypeError, ValueError):
            raise _bad_shape(path, f"must be a pair (alpha, beta), got {rayleigh!r}") from None
        if len(pair) != 2 or not all(math.isfinite(v) and v >= 0 for v in pair):
            raise InvalidParameterError(
                f"{_field(path)}: Rayleigh coefficients (alpha, beta) must be two finite "
                f"numbers >= 0, got {pair}",
                item=_field(path),
            )
    if modal is not None:
        path = 'damping["modal"]'
        if isinstance(modal, bool) or not isinstance(modal, numbers.Real):
            raise _bad_shape(path, f"must be a number, got {type(modal).__name__}")
        if not (math.isfinite(modal) and modal >= 0):
            raise InvalidParameterError(
                f"{_field(path)}: the damping ratio must be finite and >= 0, got {modal}",
                item=_field(path),
            )
        if not modal_body:
            raise _bad_shape(path, "is set on a nodal body (modal damping needs modes)")


def _check_invariants(invariants: Mapping[str, Any], n_f: int) -> None:
    """The invariants of motion that are present, for `n_f` elastic coordinates."""
    if invariants.get("mass") is not None:
        mass = invariants["mass"]
        path = 'invariants["mass"]'
        if isinstance(mass, bool) or not isinstance(mass, numbers.Real):
            raise _bad_shape(path, f"must be a number, got {type(mass).__name__}")
        if not (math.isfinite(mass) and mass > 0):
            raise InvalidParameterError(
                f"{_field(path)}: the mass must be finite and > 0, got {mass}", item=_field(path)
            )
    if invariants.get("first_moment") is not None:
        _check_dense(invariants["first_moment"], 'invariants["first_moment"]', (3,))
    if invariants.get("second_moment") is not None:
        path = 'invariants["second_moment"]'
        j0 = _check_dense(invariants["second_moment"], path, (3, 3)).astype(float)
        trace = float(np.trace(j0))
        tolerance = SECOND_MOMENT_TOLERANCE * abs(trace)
        asymmetry = float(np.abs(j0 - j0.T).max())
        eigenvalues = np.linalg.eigvalsh(0.5 * (j0 + j0.T))
        if not trace > 0 or asymmetry > tolerance or eigenvalues[0] < -tolerance:
            raise InvalidParameterError(
                f"{_field(path)}: the second moment of mass J0 = int rho u0 u0^T dV must be "
                f"symmetric positive semi-definite with a positive trace, got trace {trace:.6g}, "
                f"asymmetry {asymmetry:.3g}, eigenvalues {eigenvalues.tolist()}",
                item=_field(path),
            )
    for key, shape in (("i1", (3, n_f)), ("ibar", (3, 3, n_f))):
        if invariants.get(key) is not None:
            _check_dense(invariants[key], f"invariants[{key!r}]".replace("'", '"'), shape)
    if invariants.get("i_kl") is not None:
        i_kl = invariants["i_kl"]
        rows = list(i_kl) if isinstance(i_kl, list | tuple) else None
        if (
            rows is None
            or len(rows) != 3
            or any(not isinstance(row, list | tuple) or len(row) != 3 for row in rows)
        ):
            raise _bad_shape('invariants["i_kl"]', "must be 3 lists of 3 matrices")
        for k in range(3):
            for j in range(3):
                _check_matrix(rows[k][j], f'invariants["i_kl"][{k}][{j}]', n_f)
    for key in ("k_ff", "m_ff"):
        if invariants.get(key) is not None:
            _check_matrix(invariants[key], f'invariants["{key}"]', n_f)
