"""Nastran bulk data (``.bdf``, ``.nas``, ``.dat``, ``.pch``): meshes with their materials and
beam sections, node sets (ASET, SPC1, SET1, RBE2, RBE3), and DMIG matrices.

    from flexmbd.fe import read_nastran
    deck = read_nastran("bracket.bdf")
    body = deck.body(reference="interface", modes="craig-bampton", mode_count=8,
                     interfaces=["rbe2_9001", "rbe2_9002"])

The reader is flexmbd's own (pyNastran, the maintained Python reader, pins numpy < 2, which
the rest of the stack has left behind). It reads the three field formats (small 8-character,
large 16-character with ``*``, free with commas, with their continuation lines), Nastran's
numbers (``1.5-3`` = 1.5e-3, ``7.+10``, ``1.D5``), ``INCLUDE`` files and the bulk data between
``BEGIN BULK`` and ``ENDDATA`` (the whole file when there is no ``BEGIN BULK``). The cards it
understands are listed in :data:`CARDS`; every other card is refused, naming the card, the file
and the line, unless it is in :data:`IGNORED` (cards that do not change the body: loads,
output requests, ...). See ``docs/preprocessor.md``, "Nastran decks"."""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import InvalidModelError, InvalidParameterError, MissingFileError, UnknownItemError
from ._memory import check_fits
from .body import FlexibleBodyData
from .mesh_io import Mesh

#: The cards that make the body.
CARDS = (
    "GRID", "CORD2R", "CTETRA", "CHEXA", "CPENTA", "CPYRAM", "CBAR", "CBEAM", "CQUAD4", "CTRIA3",
    "MAT1", "PSOLID", "PSHELL", "PBAR", "PBEAM", "PBARL", "PBEAML", "ASET", "ASET1", "QSET1",
    "SPC1", "SET1", "RBE2", "RBE3", "DMIG", "CONM2",
)  # fmt: skip

#: Cards read and not used: they do not change the body's mesh, material or sets.
IGNORED = (
    "PARAM", "EIGRL", "EIGR", "SPC", "SPCADD", "FORCE", "MOMENT", "LOAD", "GRAV", "TEMPD",
    "PLOAD4", "PLOAD", "NLPARM", "TSTEP", "MPCADD", "SUPORT", "SUPORT1", "TABLED1",
    "DAREA", "RLOAD1", "RLOAD2", "TLOAD1", "TLOAD2", "FREQ", "FREQ1", "DPHASE", "DELAY",
)  # fmt: skip

#: Cards of concentrated masses: CONM2 at a grid of the elements is a point mass of the body
#: (`build_body`'s `point_masses`); the others, a CONM2 elsewhere, and one with an offset or a
#: rotary inertia on a node without rotations (of solids) are refused unless `read_nastran`'s
#: `skip` names them (the user then adds the masses in the model).
MASS_CARDS = ("CONM1", "CONM2", "CMASS1", "CMASS2", "CMASS3", "CMASS4")

#: Elements whose nodes carry rotations (6 coordinates per node for the whole body).
ROTATION_ELEMENTS = ("beam2", "quad4", "tri3")

#: Deepest nesting of INCLUDE files.
INCLUDE_DEPTH = 16

#: Memory taken by the reader per byte of bulk data (the cards as Python strings), measured:
#: decks whose estimate exceeds the available memory are refused before they are read.
MEMORY_PER_BYTE = 20.0

_NUMBER = re.compile(r"^([+-]?(?:\d+\.?\d*|\.\d+))([EeDd]?)([+-]?\d+)?$")


@dataclass
class Card:
    """One bulk data entry: its name, its data fields (continuations appended, 8 per line of
    the small-field format; None for blank fields), and where it begins."""

    name: str
    fields: list[str | None]
    file: Path
    line: int

    def where(self) -> str:
        return f"{self.file}, line {self.line}"

    def error(self, message: str) -> InvalidModelError:
        return InvalidModelError(
            f"{self.where()}: {self.name}: {message}", item=f"line {self.line} of '{self.file}'"
        )

    def field(self, index: int) -> str | None:
        """Data field `index` (1-based: field 1 is the one after the name)."""
        return self.fields[index - 1] if index <= len(self.fields) else None

    def integer(self, index: int, default: int | None = None, what: str = "") -> int:
        text = self.field(index)
        if text is None:
            if default is None:
                raise self.error(f"field {index + 1} ({what or 'an integer'}) is blank")
            return default
        try:
            return int(text)
        except ValueError:
            raise self.error(
                f"field {index + 1} ({what or 'an integer'}) is not an integer: {text!r}"
            ) from None

    def real(self, index: int, default: float | None = None, what: str = "") -> float:
        text = self.field(index)
        if text is None:
            if default is None:
                raise self.error(f"field {index + 1} ({what or 'a number'}) is blank")
            return default
        value = parse_real(text)
        if value is None or not math.isfinite(value):
            raise self.error(f"field {index + 1} ({what or 'a number'}) is not a number: {text!r}")
        return value

    def integers_from(self, index: int) -> list[int]:
        """Grid ids from field `index` on, with ``THRU`` ranges (``G1 THRU G2``)."""
        values: list[int] = []
        items = [f for f in self.fields[index - 1 :] if f is not None]
        k = 0
        while k < len(items):
            if items[k].upper() == "THRU":
                if not values or k + 1 >= len(items):
                    raise self.error("THRU without a range")
                last = self.integer_text(items[k + 1])
                values.extend(range(values[-1] + 1, last + 1))
                k += 2
                continue
            values.append(self.integer_text(items[k]))
            k += 1
        return values

    def integer_text(self, text: str) -> int:
        try:
            return int(text)
        except ValueError:
            raise self.error(f"expected an integer, found {text!r}") from None


def parse_real(text: str) -> float | None:
    """A Nastran real: ``1.5``, ``1.5E-3``, ``1.5D-3``, ``1.5-3`` (exponent without E), ``7.+10``;
    None if `text` is not one."""
    text = text.strip()
    try:
        return float(text)
    except ValueError:
        pass
    hit = _NUMBER.match(text)
    if not hit or not hit.group(3):
        return None
    mantissa, _, exponent = hit.groups()
    return float(f"{mantissa}e{exponent}")


@dataclass
class NastranDeck:
    """The body data of a Nastran deck.

    Attributes:
        mesh: the nodes (GRID, in the basic system), the elements and the node sets:
            ``aset`` (ASET, ASET1 and QSET1 nodes), ``spc<SID>`` (SPC1), ``set<SID>`` (SET1),
            ``rbe2_<EID>`` (an RBE2's dependent nodes) and ``rbe3_<EID>`` (an RBE3's
            independent nodes): the interfaces of the Nastran model. Only grids of the
            elements are nodes (an RBE's reference grid and other free points are not: they
            would carry no stiffness and no mass); sets keep their grids that are nodes.
        materials: MAT1 id -> {"young_modulus", "poisson_ratio", "density"}.
        properties: property id -> (card name, fields): PSOLID, PBAR, PBEAM, PBARL, PBEAML.
        element_properties: element type -> (n_elements,) property ids.
        orientations: beam element id -> orientation vector v (basic system).
        matrices: DMIG name -> :class:`DmigMatrix`.
        point_masses: grid id -> (mass, (3, 3) rotary inertia about the centre of mass,
            offset of the centre of mass from the grid), in the basic system, of the CONM2
            cards (those of one grid combined into one; WTMASS applied).
        displacement_systems: grid id -> (3, 3) axes (columns, in the basic system) of the
            grid's displacement system (GRID field CD), for the nodes with CD other than 0:
            results in that system (OUGV1) are turned to the basic one by v = A v_CD. NaN
            for a system that is not a CORD2R of the deck.
        beam_offsets: (n_beams, 2, 3) the offsets WA, WB of the CBAR and CBEAM elements (in
            the order of ``mesh.elements["beam2"]``), turned to the basic system, or None
            when no beam has one (`build_body`'s `beam_offsets`).
        beam_releases: (n_beams, 12) the coordinates their pin flags PA, PB release (u, v,
            w, theta_x, theta_y, theta_z of end A then end B, element axes), or None when no
            beam has one (`build_body`'s `beam_releases`).
    """

    mesh: Mesh
    materials: dict[int, dict[str, float]] = field(default_factory=dict)
    properties: dict[int, tuple[str, Card]] = field(default_factory=dict)
    element_properties: dict[str, NDArray[np.int64]] = field(default_factory=dict)
    orientations: dict[int, NDArray[np.float64]] = field(default_factory=dict)
    matrices: dict[str, DmigMatrix] = field(default_factory=dict)
    displacement_systems: dict[int, NDArray[np.float64]] = field(default_factory=dict)
    point_masses: dict[int, tuple[float, NDArray[np.float64], NDArray[np.float64]]] = field(
        default_factory=dict
    )
    beam_offsets: NDArray[np.float64] | None = None
    beam_releases: NDArray[np.bool_] | None = None

    def material(self) -> Any:
        """The one material of the mesh's elements (flexmbd bodies are of one material), as a
        :class:`flexmbd.fe.Material`. Raises `InvalidModelError` naming the properties if their
        materials differ, `UnknownItemError` for a property or material that is not
        defined."""
        from .preprocess import Material

        used = sorted({int(p) for ids in self.element_properties.values() for p in ids})
        mids = {}
        for pid in used:
            if pid not in self.properties:
                raise UnknownItemError(
                    f"Nastran deck: property {pid} is not defined", item=f"{pid}"
                )
            name, card = self.properties[pid]
            mids[pid] = card.integer(2, what="MID")
        values = {}
        for pid, mid in mids.items():
            if mid not in self.materials:
                raise UnknownItemError(
                    f"Nastran deck: property {pid} refers to material {mid}, which no MAT1 defines",
                    item=f"MAT1 {mid}",
                )
            values[mid] = tuple(self.materials[mid].values())
        if len(set(values.values())) > 1:
            raise InvalidModelError(
                f"Nastran deck: the elements use materials {sorted(values)} with different "
                "values; a flexmbd body has one material (split the deck into bodies)",
                item="MAT1",
            )
        if not values:
            raise InvalidModelError("Nastran deck: no element has a property", item="PSOLID")
        mid = next(iter(values))
        m = self.materials[mid]
        return Material(m["young_modulus"], m["poisson_ratio"], m["density"])

    def section(self) -> tuple[Any, NDArray[np.float64] | None]:
        """(section, orientation) of the beams: one section and one orientation vector for all
        of them (flexmbd's preprocessor takes one of each), or (None, None) without beams."""
        beams = self.element_properties.get("beam2")
        if beams is None or len(beams) == 0:
            return None, None
        sections = {}
        for pid in sorted({int(p) for p in beams}):
            if pid not in self.properties:
                raise UnknownItemError(
                    f"Nastran deck: property {pid} is not defined", item=f"{pid}"
                )
            sections[pid] = _beam_section(*self.properties[pid])
        keys = {(s.area, s.iy, s.iz, s.torsion_constant) for s in sections.values()}
        if len(keys) > 1:
            raise InvalidModelError(
                f"Nastran deck: the beams have different sections (properties "
                f"{sorted(sections)}); a flexmbd body has one beam section",
                item="PBAR",
            )
        vectors = list(self.orientations.items())
        eid0, v0 = vectors[0]
        for eid, v in vectors[1:]:
            if np.linalg.norm(np.cross(v / np.linalg.norm(v), v0 / np.linalg.norm(v0))) > 1e-9:
                raise InvalidModelError(
                    f"Nastran deck: beam {eid} has orientation {v.tolist()}, beam {eid0} "
                    f"{v0.tolist()}; flexmbd's preprocessor takes one orientation for all beams",
                    item=f"CBAR {eid}",
                )
        return next(iter(sections.values())), v0

    def shell(self) -> Any:
        """The shells' :class:`flexmbd.fe.ShellSection`: one PSHELL thickness for all of them
        (flexmbd's preprocessor takes one), or None without shells."""
        from .preprocess import ShellSection

        pids = sorted(
            {int(p) for kind in ("quad4", "tri3") for p in self.element_properties.get(kind, [])}
        )
        if not pids:
            return None
        thickness = {}
        for pid in pids:
            if pid not in self.properties or self.properties[pid][0] != "PSHELL":
                raise UnknownItemError(
                    f"Nastran deck: shell property {pid} is not defined by a PSHELL",
                    item=f"property {pid}",
                )
            card = self.properties[pid][1]
            for index, what, default in ((5, "12I/T**3", 1.0), (7, "TS/T", 5.0 / 6.0)):
                value = card.real(index, default, what=what)
                if abs(value - default) > 1e-6 * default:
                    raise card.error(f"{what} = {value} is not supported (only {default:.6g})")
            mid1, mid2 = card.integer(2, what="MID1"), card.integer(4, 0, what="MID2")
            if mid2 == 0:
                # (it was taken as MID1: Nastran's membrane got full bending stiffness)
                raise card.error(
                    "MID2 is blank: in Nastran a membrane without bending stiffness, which a "
                    f"flexmbd shell is not; give MID2 = MID1 = {mid1} for a shell that bends"
                )
            if mid2 != mid1:
                raise card.error(
                    f"MID2 = {mid2} differs from MID1 = {mid1}: one material for membrane and "
                    "bending"
                )
            nsm = card.real(8, 0.0, what="NSM")
            if nsm != 0.0:
                # (it was ignored: the mass per area was lost)
                raise card.error(
                    f"NSM = {nsm} (non-structural mass per area) is not supported: add the mass "
                    "as point masses of the body (build_body's point_masses) or as bodies"
                )
            thickness[pid] = card.real(3, what="T")
        if len(set(thickness.values())) > 1:
            raise InvalidModelError(
                f"Nastran deck: the shells have different thicknesses {thickness}; a flexmbd "
                "body has one shell section",
                item="PSHELL",
            )
        return ShellSection(next(iter(thickness.values())))

    def body(self, **options: Any) -> FlexibleBodyData:
        """The deck's body through :func:`flexmbd.fe.build_body` with its mesh, material and
        beam section; `options` are build_body's (reference conditions, modes, ...)."""
        from .preprocess import build_body

        section, orientation = self.section()
        extra: dict[str, Any] = {}
        if section is not None:
            extra = {"section": section, "orientation": orientation}
            if self.beam_offsets is not None:
                extra["beam_offsets"] = self.beam_offsets
            if self.beam_releases is not None:
                extra["beam_releases"] = self.beam_releases
        shell = self.shell()
        if shell is not None:
            extra["shell"] = shell
        given = options.pop("point_masses", None)
        if self.point_masses:
            # The deck's CONM2 masses, and those given (node indices) added to them.
            # (A solid's nodes carry no inertia or offset: `_conm2` refused them.)
            index = {int(g): k for k, g in enumerate(self.mesh.node_ids)}
            masses: dict[int, Any] = {index[g]: value for g, value in self.point_masses.items()}
            for node, value in dict(given or {}).items():
                if node in masses:
                    raise InvalidParameterError(
                        f"point_masses[{node}]: grid {int(self.mesh.node_ids[node])} has a "
                        "CONM2 of the deck already",
                        item=f"point_masses[{node}]",
                    )
                masses[node] = value
            given = masses
        if given is not None:
            extra["point_masses"] = given
        return build_body(
            self.mesh.nodes,
            self.mesh.elements,
            self.material(),
            node_ids=self.mesh.node_ids,
            element_ids=self.mesh.element_ids,
            node_sets=self.mesh.node_sets,
            **extra,
            **options,
        )

    def modal_body(self, results: Any, modes: Any = None, **options: Any) -> FlexibleBodyData:
        """The deck's body with the normal modes of its OP2 results (a path or an
        :class:`~flexmbd.fe.op2.Op2Results`): :func:`flexmbd.fe.body_from_nastran` with this
        deck."""
        from .op2 import body_from_nastran

        return body_from_nastran(self, results, modes, **options)


@dataclass
class DmigMatrix:
    """A DMIG matrix: entries by (row grid, row component) and (column grid, column
    component), components 1-6 (0 for scalar points). ``form`` is IFO: 1 square, 6
    symmetric (one triangle given), 2 or 9 rectangular."""

    name: str
    form: int
    rows: list[tuple[int, int]]
    columns: list[tuple[int, int]]
    values: list[float]

    def to_matrix(self, dofs: list[tuple[int, int]]) -> Any:
        """The matrix on the ordered (grid, component) list `dofs`, as scipy CSC; symmetric
        forms are completed from their triangle. Raises `UnknownItemError` for an entry on a
        dof that is not in `dofs`."""
        import scipy.sparse as sp

        index = {dof: k for k, dof in enumerate(dofs)}
        rows, cols, data = [], [], []
        for r, c, v in zip(self.rows, self.columns, self.values, strict=True):
            for dof in (r, c):
                if dof not in index:
                    raise UnknownItemError(
                        f"DMIG {self.name}: an entry on grid {dof[0]} component {dof[1]}, which "
                        "is not one of the body's coordinates",
                        item=f"grid {dof[0]}",
                    )
            rows.append(index[r])
            cols.append(index[c])
            data.append(v)
            if self.form == 6 and r != c:
                rows.append(index[c])
                cols.append(index[r])
                data.append(v)
        n = len(dofs)
        return sp.csc_matrix((data, (rows, cols)), shape=(n, n))


def read_nastran(path: str | os.PathLike[str], *, skip: Any = ()) -> NastranDeck:
    """Reads the bulk data of a Nastran deck (see the module docstring).

    Mass: ``PARAM,WTMASS`` multiplies the densities of the MAT1 cards, as it multiplies
    Nastran's structural mass (decks in lb, in and s write RHO in weight units with
    WTMASS = 1/386.09), and the CONM2 masses. A CONM2 at a grid of the elements is a point
    mass of the body (``deck.point_masses``; its rotary inertia and the offset of its centre
    of gravity on the nodes of beams and shells, which rotate); one at a grid of no element or
    with a rotary inertia or an offset on a solid's node, and the other concentrated masses
    (CONM1, CMASS1-4, :data:`MASS_CARDS`) are refused, as leaving them out changes the body's
    mass and modes; `skip` (card names, e.g. ``["CMASS2"]``) reads the deck without them, for a
    model that adds these masses itself (a rigid body or point mass fixed to the node).

    Elements: CTETRA (4 or 10 grids) -> tet4 / tet10, CHEXA (8 or 20 grids) -> hex8 / hex20,
    CPENTA (6 or 15 grids) -> wedge6 / wedge15, CPYRAM (5 grids) -> pyramid5, CBAR and CBEAM
    -> beam2 with their offsets WA, WB (in the grids' displacement systems, OFFT G; offsets in
    the element system, OFFT O, are refused) and pin flags PA, PB (``deck.beam_offsets``,
    ``deck.beam_releases``; tapered PBEAMs are refused), CQUAD4 and CTRIA3 -> the flat
    shells quad4 and tri3 (PSHELL: one thickness, one material, default 12I/T^3 and TS/T;
    offsets refused). Grids may be given in CORD2R
    systems (rectangular, chained); other coordinate systems are refused.

    Raises `MissingFileError`; `InvalidModelError` naming the file, line and card of an
    unknown or malformed card, a refused option, a deck that would not fit in the available
    memory (estimated before reading);
    `UnknownItemError` for a reference to an undefined grid, property or coordinate system."""
    path = Path(path)
    if not path.is_file():
        raise MissingFileError("Nastran file", path)
    if isinstance(skip, str):
        skip = [skip]
    try:
        skipped = frozenset(str(name).upper() for name in skip)
    except TypeError:
        raise InvalidParameterError(
            f"skip: card names (e.g. ['CONM2']), got {skip!r}", item="skip"
        ) from None
    unknown = sorted(skipped - set(MASS_CARDS))
    if unknown:
        raise InvalidParameterError(
            f"skip: {', '.join(unknown)} cannot be skipped (skip takes {', '.join(MASS_CARDS)})",
            item="skip",
        )
    cards = list(_cards(path, 0, [0]))
    return _deck(cards, skipped)


def read_dmig(path: str | os.PathLike[str]) -> dict[str, DmigMatrix]:
    """The DMIG matrices of a Nastran bulk data or punch file (``.pch``, as written by
    ``EXTSEOUT`` or ``PARAM,EXTOUT``), by name."""
    return read_nastran(path).matrices


# Reading cards -----------------------------------------------------------------------------


def _lines(path: Path, depth: int, size: list[int]) -> Any:
    """(file, line number, text) of the bulk data lines of `path` and its INCLUDE files."""
    if depth > INCLUDE_DEPTH:
        raise InvalidModelError(
            f"{path}: INCLUDE files nested deeper than {INCLUDE_DEPTH}", item=f"file '{path}'"
        )
    size[0] += path.stat().st_size
    check_fits(path, size[0], MEMORY_PER_BYTE, "Nastran deck (with its INCLUDE files)")
    text = path.read_text(encoding="latin-1").splitlines()
    has_bulk = depth > 0 or any(line.upper().startswith("BEGIN BULK") for line in text)
    in_bulk = not has_bulk or depth > 0
    k = 0
    while k < len(text):
        line = text[k].rstrip("\r\n").expandtabs(8)
        number = k + 1
        k += 1
        upper = line.upper()
        if not in_bulk:
            in_bulk = upper.startswith("BEGIN BULK")
            continue
        if upper.startswith("ENDDATA"):
            return
        if upper.startswith("INCLUDE"):
            name = line[7:].strip()
            while name.count("'") == 1 and k < len(text):  # a quoted name over several lines
                name += text[k].strip()
                k += 1
            name = name.strip().strip("'\"")
            target = (path.parent / name).resolve()
            if not target.is_file():
                raise MissingFileError(f"INCLUDE file ({path}, line {number})", target)
            yield from _lines(target, depth + 1, size)
            continue
        if not line.strip() or line.lstrip().startswith("$"):
            continue
        yield path, number, line.split("$", 1)[0]


def _split(line: str) -> tuple[str, list[str | None], bool]:
    """(first field, 8 data fields, large field?) of one physical line."""
    if "," in line[:80]:  # free field (8 data fields per line)
        parts = [p.strip() for p in line.split(",")]
        first = parts[0]
        data = [p or None for p in parts[1:9]]
        return first, data + [None] * (8 - len(data)), False
    first = line[:8].strip()
    if first.endswith("*") or first.startswith("*"):
        data = [line[8 + 16 * i : 24 + 16 * i].strip() or None for i in range(4)]
        return first, data + [None] * 4, True
    data = [line[8 + 8 * i : 16 + 8 * i].strip() or None for i in range(8)]
    return first, data, False


def _cards(path: Path, depth: int, size: list[int]) -> Any:
    current: Card | None = None
    large_half = False  # a large-field line waiting for its second half
    for file, number, line in _lines(path, depth, size):
        first, data, large = _split(line)
        continuation = not first or first[0] in "+*" or (first == "" and current is not None)
        if line[:1] in (" ", "\t") and not first and current is None:
            raise InvalidModelError(
                f"{file}, line {number}: a continuation line without a card",
                item=f"line {number} of '{file}'",
            )
        if continuation and current is not None:
            if large and large_half:
                # The second line of a large-field pair: its 4 fields complete 8.
                current.fields[-4:] = data[:4]
                large_half = False
            else:
                current.fields.extend(data)
                large_half = large
            continue
        if current is not None:
            yield current
        name = first.rstrip("*").upper()
        current = Card(name, list(data), file, number)
        large_half = large
    if current is not None:
        yield current


# Building the deck -------------------------------------------------------------------------


def _frame(card: Card) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(origin, rotation with the system's axes as columns) of a CORD2R in its reference."""
    a = np.array([card.real(i, what=f"A{i - 2}") for i in (3, 4, 5)])
    b = np.array([card.real(i, what=f"B{i - 5}") for i in (6, 7, 8)])
    c = np.array([card.real(i, what=f"C{i - 8}") for i in (9, 10, 11)])
    z = b - a
    x_guess = c - a
    y = np.cross(z, x_guess)
    if np.linalg.norm(z) == 0 or np.linalg.norm(y) == 0:
        raise card.error("points A, B and C do not define a coordinate system")
    z, y = z / np.linalg.norm(z), y / np.linalg.norm(y)
    return a, np.column_stack([np.cross(y, z), y, z])


def _deck(cards: list[Card], skipped: frozenset[str] = frozenset()) -> NastranDeck:
    grids: dict[int, Card] = {}
    systems: dict[int, Card] = {}
    elements: dict[str, list[tuple[int, int, list[int], Card]]] = {}
    materials: dict[int, dict[str, float]] = {}
    properties: dict[int, tuple[str, Card]] = {}
    sets: dict[str, list[int]] = {}
    orientation_cards: list[Card] = []
    dmig_headers: dict[str, Card] = {}
    dmig_columns: list[Card] = []
    conm2: list[Card] = []
    mass_scale = 1.0
    for card in cards:
        name = card.name
        if name == "GRID":
            gid = card.integer(1, what="ID")
            if gid in grids:
                raise card.error(f"grid {gid} is defined twice (also {grids[gid].where()})")
            grids[gid] = card
        elif name == "CORD2R":
            systems[card.integer(1, what="CID")] = card
        elif name in ("CTETRA", "CHEXA", "CPENTA", "CPYRAM"):
            eid, pid = card.integer(1, what="EID"), card.integer(2, what="PID")
            nodes = [card.integer_text(f) for f in card.fields[2:] if f is not None]
            if name == "CTETRA" and len(nodes) == 4:
                kind = "tet4"
            elif name == "CTETRA" and len(nodes) == 10:
                kind = "tet10"
                nodes[8], nodes[9] = nodes[9], nodes[8]  # Nastran G9 on (2,4), G10 on (3,4)
            elif name == "CHEXA" and len(nodes) == 8:
                kind = "hex8"
            elif name == "CHEXA" and len(nodes) == 20:
                # G9-G12 on the bottom face's edges, G13-G16 on the edges G1-G5 .. G4-G8,
                # G17-G20 on the top face's (as Gmsh's and meshio's Nastran readers take
                # them); hex20 has the top face's edges first.
                kind = "hex20"
                nodes = nodes[:12] + nodes[16:20] + nodes[12:16]
            elif name == "CPENTA" and len(nodes) == 6:
                kind = "wedge6"  # G1-G3 a triangle, G4-G6 the other, G4 opposite G1
            elif name == "CPENTA" and len(nodes) == 15:
                # G7-G9 on the edges of G1-G3, G10-G12 on G1-G4 .. G3-G6, G13-G15 on the
                # edges of G4-G6 (as meshio's Nastran reader takes them); wedge15 has the
                # second triangle's edges first.
                kind = "wedge15"
                nodes = nodes[:9] + nodes[12:15] + nodes[9:12]
            elif name == "CPYRAM" and len(nodes) == 5:
                kind = "pyramid5"  # G1-G4 the base, G5 the apex
            else:
                raise card.error(
                    f"{len(nodes)} grids: flexmbd has CTETRA of 4 or 10 grids, CHEXA of 8 or 20, "
                    "CPENTA of 6 or 15 (every mid-edge grid given) and CPYRAM of 5"
                )
            elements.setdefault(kind, []).append((eid, pid, nodes, card))
        elif name in ("CBAR", "CBEAM"):
            eid, pid = card.integer(1, what="EID"), card.integer(2, what="PID")
            nodes = [card.integer(3, what="GA"), card.integer(4, what="GB")]
            _beam_offset_kind(card)  # (refuses what is not read, before the grids are known)
            _pin_flags(card)
            if name == "CBEAM" and any(card.field(i) not in _BLANK for i in (17, 18)):
                raise card.error(
                    f"element {eid}: SA, SB (scalar points of warping, fields 18-19) are not "
                    "supported"
                )
            elements.setdefault("beam2", []).append((eid, pid, nodes, card))
            orientation_cards.append(card)
        elif name == "MAT1":
            materials[card.integer(1, what="MID")] = _material(card)
        elif name in ("CQUAD4", "CTRIA3"):
            eid, pid = card.integer(1, what="EID"), card.integer(2, what="PID")
            count = 4 if name == "CQUAD4" else 3
            nodes = [card.integer(3 + k, what=f"G{k + 1}") for k in range(count)]
            if any(
                card.field(i) not in (None, "0", "0.", "0.0") for i in (8 if count == 4 else 7,)
            ):
                raise card.error(f"element {eid}: an offset ZOFFS is not supported")
            corners = [card.field(i) for i in range(11, 11 + count)]
            if card.field(10) not in (None, "0") or any(t is not None for t in corners):
                # (they were ignored: the PSHELL T was used, half of a 4 mm corner thickness)
                raise card.error(
                    f"element {eid}: corner thicknesses (TFLAG, T1-T{count}) are not supported: "
                    "the shells take their PSHELL's thickness T"
                )
            elements.setdefault("quad4" if count == 4 else "tri3", []).append(
                (eid, pid, nodes, card)
            )
        elif name in ("PSOLID", "PSHELL", "PBAR", "PBEAM", "PBARL", "PBEAML"):
            properties[card.integer(1, what="PID")] = (name, card)
        elif name in ("ASET1", "QSET1"):
            sets.setdefault("aset", []).extend(card.integers_from(2))
        elif name == "ASET":
            sets.setdefault("aset", []).extend(
                card.integer(i) for i in range(1, len(card.fields) + 1, 2) if card.field(i)
            )
        elif name == "SPC1":
            sets.setdefault(f"spc{card.integer(1, what='SID')}", []).extend(card.integers_from(3))
        elif name == "SET1":
            sets.setdefault(f"set{card.integer(1, what='SID')}", []).extend(card.integers_from(2))
        elif name == "RBE2":
            sets[f"rbe2_{card.integer(1, what='EID')}"] = _rbe2_dependents(card)
        elif name == "RBE3":
            sets[f"rbe3_{card.integer(1, what='EID')}"] = _rbe3_independents(card)
        elif name == "DMIG":
            if card.field(1) is None:
                raise card.error("no matrix name")
            matrix = card.field(1).upper()  # type: ignore[union-attr]
            if card.field(2) == "0":
                dmig_headers[matrix] = card
            else:
                dmig_columns.append(card)
        elif name == "PARAM" and (card.field(1) or "").upper() == "WTMASS":
            wtmass = card.real(2, what="WTMASS")
            if not (math.isfinite(wtmass) and wtmass > 0):
                raise card.error(f"WTMASS must be a positive number, got {wtmass}")
            mass_scale = wtmass
        elif name in IGNORED or name in skipped:
            continue
        elif name == "CONM2":
            conm2.append(card)
        elif name in MASS_CARDS:
            raise card.error(
                f"{name} {card.field(1)}: concentrated masses are not part of a flexmbd body, "
                "and leaving them out would change its mass and modes; add them to the model "
                f"(a rigid body or point mass fixed to the node) and read the deck with "
                f"skip=['{name}'] (in a model file: nastran_skip: [{name}])"
            )
        else:
            raise card.error(
                f"unsupported card {name!r} (supported: {', '.join(CARDS)}; skipped: "
                f"{', '.join(IGNORED)})"
            )

    # Grids of no element (the reference grids of RBE2/RBE3, CONM2 points, ...) are not nodes
    # of the body: they would carry neither stiffness nor mass.
    used = {g for items in elements.values() for _e, _p, nodes, _c in items for g in nodes}
    missing = sorted(used - set(grids))
    if missing:
        card = next(c for items in elements.values() for _e, _p, n, c in items if missing[0] in n)
        raise UnknownItemError(
            f"{card.where()}: {card.name} {card.integer(1)} refers to grid {missing[0]}, which "
            "no GRID defines",
            item=f"grid {missing[0]}",
        )
    ids = np.array(sorted(used), dtype=np.int64)
    index = {int(g): k for k, g in enumerate(ids)}
    positions = np.array([_position(grids[int(g)], systems) for g in ids]).reshape(-1, 3)
    mesh = Mesh(nodes=positions, node_ids=ids)
    element_properties = {}
    for kind, items in elements.items():
        connectivity = []
        for _eid, _pid, nodes, _card in items:
            connectivity.append([index[g] for g in nodes])
        mesh.elements[kind] = np.array(connectivity, dtype=np.int64)
        mesh.element_ids[kind] = np.array([e[0] for e in items], dtype=np.int64)
        element_properties[kind] = np.array([e[1] for e in items], dtype=np.int64)
    for set_name, members in sets.items():
        undefined = [g for g in members if g not in grids]
        if undefined:
            raise UnknownItemError(
                f"Nastran deck: {set_name} refers to grid {undefined[0]}, which no GRID defines",
                item=f"grid {undefined[0]}",
            )
        kept = [index[g] for g in members if g in index]  # grids of the body's elements
        if kept:
            mesh.node_sets[set_name] = np.unique(np.array(kept, dtype=np.int64))
    orientations = {
        card.integer(1): _orientation(card, grids, systems) for card in orientation_cards
    }
    beams = [item[3] for item in elements.get("beam2", [])]
    ends = [_beam_ends(card, grids, systems) for card in beams]
    beam_offsets = np.array([offsets for offsets, _ in ends]).reshape(-1, 2, 3)
    beam_releases = np.array([released for _, released in ends], dtype=bool).reshape(-1, 12)
    matrices = _dmig(dmig_headers, dmig_columns)
    displacement = {}
    for g in ids:
        grid = grids[int(g)]
        cd = grid.integer(6, 0, what="CD")
        if cd:
            try:
                displacement[int(g)] = _axes(cd, systems, grid)
            except (UnknownItemError, InvalidModelError):
                # Not a (chain of) CORD2R: NaN, refused only where results in it are used.
                displacement[int(g)] = np.full((3, 3), np.nan)
    for values in materials.values():  # PARAM,WTMASS: Nastran's structural mass x WTMASS
        values["density"] *= mass_scale
    # (the nodes of beams and shells: a node of solids alone has no rotations, also in a body
    # that mixes them)
    rotations = {
        int(n) for k in ROTATION_ELEMENTS for n in np.ravel(mesh.elements.get(k, np.zeros(0)))
    }
    parts: dict[int, list[tuple[float, NDArray[np.float64], NDArray[np.float64]]]] = {}
    element_ids = {e[0]: e[3] for items in elements.values() for e in items}
    for card in conm2:
        eid = card.integer(1, what="EID")
        if eid in element_ids:
            raise card.error(f"element id {eid} is defined twice (also {element_ids[eid].where()})")
        element_ids[eid] = card
        grid, mass, inertia, offset = _conm2(card, grids, systems, index, rotations)
        parts.setdefault(grid, []).append((mass_scale * mass, mass_scale * inertia, offset))
    from .preprocess import combined_point_mass

    point_masses = {grid: combined_point_mass(masses) for grid, masses in parts.items()}
    return NastranDeck(
        mesh,
        materials,
        properties,
        element_properties,
        orientations,
        matrices,
        displacement,
        point_masses,
        beam_offsets=beam_offsets if np.any(beam_offsets) else None,
        beam_releases=beam_releases if np.any(beam_releases) else None,
    )


def _conm2(
    card: Card,
    grids: dict[int, Card],
    systems: dict[int, Card],
    index: dict[int, int],
    rotations: set[int],
) -> tuple[int, float, NDArray[np.float64], NDArray[np.float64]]:
    """(grid, mass, rotary inertia about the centre of gravity, offset of the centre of
    gravity from the grid), in the basic system, of a CONM2 card, refused where the body cannot
    carry it: at a grid of no element, with a rotary inertia or an offset on the nodes of
    solids (no rotations)."""
    eid, grid = card.integer(1, what="EID"), card.integer(2, what="G")
    how = (
        "add it to the model as a rigid body fixed to the grid's node (or the RBE's nodes) and "
        "read the deck with skip=['CONM2'] (in a model file: nastran_skip: [CONM2])"
    )
    if grid not in grids:
        raise UnknownItemError(
            f"{card.where()}: CONM2 {eid} refers to grid {grid}, which no GRID defines",
            item=f"grid {grid}",
        )
    if grid not in index:
        raise card.error(
            f"CONM2 {eid}: grid {grid} is not a grid of the body's elements (an RBE's reference "
            f"grid?), so the mass has no node of the body to sit on; {how}"
        )
    cid = card.integer(3, 0, what="CID")
    mass = card.real(4, 0.0, what="M")
    if not mass >= 0:
        raise card.error(f"CONM2 {eid}: the mass must be >= 0, got {mass}")
    offset = np.array([card.real(5 + k, 0.0, what=f"X{k + 1}") for k in range(3)])
    i11, i21, i22, i31, i32, i33 = (card.real(k, 0.0, what=f"I field {k}") for k in range(9, 15))
    inertia = np.array([[i11, -i21, -i31], [-i21, i22, -i32], [-i31, -i32, i33]])
    axes = np.eye(3) if cid in (0, -1) else _axes(cid, systems, card)
    position = _position(grids[grid], systems)
    # CID -1: X is the centre of gravity in the basic system; else the offset in system CID.
    offset = offset - position if cid == -1 else axes @ offset
    if np.abs(offset).max() <= 1e-9 * max(1.0, float(np.abs(position).max())):
        offset = np.zeros(3)  # (the round-off of a centre of gravity given at the grid)
    inertia = axes @ inertia @ axes.T
    scale = max(float(np.abs(inertia).max()), 1e-300)
    if np.linalg.eigvalsh(inertia).min() < -1e-12 * scale:
        raise card.error(
            f"CONM2 {eid}: the rotary inertia {inertia.tolist()} is not positive semi-definite"
        )
    for what, given in (("a rotary inertia", inertia), (f"an offset {offset.tolist()}", offset)):
        if np.any(given) and index[grid] not in rotations:
            raise card.error(
                f"CONM2 {eid}: {what} on grid {grid}, a node of solid elements (no rotations "
                f"to carry it); {how}"
            )
    return grid, mass, inertia, offset


def _axes(cid: int, systems: dict[int, Card], card: Card) -> NDArray[np.float64]:
    """The axes (columns, in the basic system) of coordinate system `cid`, through the
    chain of its reference systems."""
    axes = np.eye(3)
    for _ in range(33):
        if cid == 0:
            return axes
        if cid not in systems:
            raise UnknownItemError(
                f"{card.where()}: {card.name} uses coordinate system {cid}, which no CORD2R "
                "defines (only rectangular CORD2R systems are supported)",
                item=f"coordinate system {cid}",
            )
        system = systems[cid]
        axes = _frame(system)[1] @ axes
        cid = system.integer(2, 0, what="RID")
    raise card.error(f"coordinate system {cid} refers to itself through its references")


def _position(card: Card, systems: dict[int, Card]) -> NDArray[np.float64]:
    x = np.array([card.real(i, 0.0, what=f"X{i - 2}") for i in (3, 4, 5)])
    return _to_basic(x, card.integer(2, 0, what="CP"), systems, card)


def _to_basic(
    x: NDArray[np.float64], cid: int, systems: dict[int, Card], card: Card, depth: int = 0
) -> NDArray[np.float64]:
    if cid == 0:
        return x
    if cid not in systems:
        raise UnknownItemError(
            f"{card.where()}: {card.name} uses coordinate system {cid}, which no CORD2R "
            "defines (only rectangular CORD2R systems are supported)",
            item=f"coordinate system {cid}",
        )
    if depth > 32:
        raise card.error(f"coordinate system {cid} refers to itself through its references")
    system = systems[cid]
    origin, axes = _frame(system)
    reference = system.integer(2, 0, what="RID")
    local = origin + axes @ x
    return _to_basic(local, reference, systems, system, depth + 1) if reference else local


def _orientation(
    card: Card, grids: dict[int, Card], systems: dict[int, Card]
) -> NDArray[np.float64]:
    """The orientation vector v of a CBAR/CBEAM in the basic system (X1-X3 or G0)."""
    x1 = card.field(5)
    if x1 is None:
        raise card.error("no orientation vector (X1, X2, X3 or G0 in fields 6-8)")
    if card.field(6) is None and card.field(7) is None and x1.lstrip("+-").isdigit():
        g0 = card.integer(5, what="G0")
        ga = card.integer(3, what="GA")
        for g in (g0, ga):
            if g not in grids:
                raise UnknownItemError(
                    f"{card.where()}: {card.name} refers to grid {g}, which no GRID defines",
                    item=f"grid {g}",
                )
        return _position(grids[g0], systems) - _position(grids[ga], systems)
    v = np.array([card.real(i, 0.0, what=f"X{i - 4}") for i in (5, 6, 7)])
    ga = grids.get(card.integer(3, what="GA"))
    cd = ga.integer(6, 0, what="CD") if ga is not None else 0
    if cd and _beam_offset_kind(card)[0] == "G":
        # (OFFT "G..": X1-X3 in GA's displacement system; "B..": in the basic one)
        v = _axes(cd, systems, card) @ v
    if not np.any(v):
        raise card.error("the orientation vector is zero")
    return v


_BLANK = (None, "0", "0.", "0.0", ".0")

#: OFFT codes of CBAR and CBEAM (field 9): the system of the orientation vector (G: GA's
#: displacement system, B: basic), then of the offsets at ends A and B (G: the grid's
#: displacement system, O: the element's).
OFFT_CODES = ("GGG", "BGG", "GGO", "BGO", "GOG", "BOG", "GOO", "BOO")


def _beam_offset_kind(card: Card) -> str:
    """The OFFT code of a CBAR or CBEAM (field 9; blank: GGG). A CBEAM's field 9 may be BIT
    (a real: the built-in twist of p-elements), refused unless zero; offsets in the element
    system (O) are refused where an offset is given."""
    text = card.field(8)
    if text is None:
        return "GGG"
    if card.name == "CBEAM" and parse_real(text) is not None:
        if parse_real(text) != 0.0:
            raise card.error(
                f"element {card.field(1)}: BIT = {text} (built-in twist, field 9) is not supported"
            )
        return "GGG"
    code = text.upper()
    if code not in OFFT_CODES:
        raise card.error(
            f"element {card.field(1)}: OFFT {text!r} (field 9) is not one of "
            f"{', '.join(OFFT_CODES)}"
        )
    for end, first in (("A", 11), ("B", 14)):
        given = any(card.field(first + k) not in _BLANK for k in range(3))
        if given and code["AB".index(end) + 1] == "O":
            raise card.error(
                f"element {card.field(1)}: OFFT {code}: the offset at end {end} in the element "
                "system (O) is not supported; give it in the grid's displacement system (OFFT "
                "GGG or BGG)"
            )
    return code


def _pin_flags(card: Card) -> NDArray[np.bool_]:
    """The released coordinates (12 bools: u, v, w, theta_x, theta_y, theta_z of end A then
    end B, element axes) of a CBAR or CBEAM's pin flags PA, PB (fields 10-11: up to five of
    the digits 1-6, each once)."""
    released = np.zeros(12, dtype=bool)
    for end, index in ((0, 9), (1, 10)):
        text = card.field(index)
        if text is None or text == "0":
            continue
        digits = [int(c) for c in text if c in "123456"]
        if len(digits) != len(text) or len(set(digits)) != len(digits) or len(digits) > 5:
            raise card.error(
                f"element {card.field(1)}: pin flag P{'AB'[end]} = {text!r} (field "
                f"{index + 1}) is not up to five of the digits 1-6, each once"
            )
        released[6 * end + np.array(digits) - 1] = True
    return released


def _beam_ends(
    card: Card, grids: dict[int, Card], systems: dict[int, Card]
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """(offsets (2, 3) of ends A and B in the basic system, released coordinates (12,)) of a
    CBAR or CBEAM: WA, WB (fields 12-17) in the displacement system of GA, GB (their GRID
    CD, a chain of CORD2R systems), and the pin flags PA, PB."""
    offsets = np.zeros((2, 3))
    for end, (grid_field, first) in enumerate(((3, 11), (4, 14))):
        w = np.array([card.real(first + k, 0.0, what=f"W{k + 1}{'AB'[end]}") for k in range(3)])
        if np.any(w):
            grid = grids[card.integer(grid_field)]
            cd = grid.integer(6, 0, what="CD")
            offsets[end] = _axes(cd, systems, card) @ w if cd else w
    return offsets, _pin_flags(card)


def _material(card: Card) -> dict[str, float]:
    e = card.real(2, math.nan, what="E")
    g = card.real(3, math.nan, what="G")
    nu = card.real(4, math.nan, what="NU")
    if math.isnan(e) and not (math.isnan(g) or math.isnan(nu)):
        e = 2.0 * g * (1.0 + nu)
    if math.isnan(nu) and not (math.isnan(e) or math.isnan(g)):
        nu = e / (2.0 * g) - 1.0
    if math.isnan(e) or math.isnan(nu):
        raise card.error("needs E and NU (or two of E, G, NU)")
    rho = card.real(5, 0.0, what="RHO")
    if not rho > 0:
        raise card.error(f"RHO must be > 0 for a body in motion, got {rho}")
    return {"young_modulus": e, "poisson_ratio": nu, "density": rho}


def _beam_section(name: str, card: Card) -> Any:
    from .preprocess import Section

    if name in ("PBAR", "PBEAM"):
        area = card.real(3, what="A")
        i1 = card.real(4, 0.0, what="I1")  # about the element z axis: flexmbd's iz
        i2 = card.real(5, 0.0, what="I2")  # about y: iy
        j = card.real(6 if name == "PBAR" else 7, 0.0, what="J")
        if name == "PBAR" and card.field(18) not in (None, "0", "0.", "0.0"):
            raise card.error("I12 (product of inertia) is not supported")
        if name == "PBEAM" and card.field(6) not in (None, "0", "0.", "0.0"):
            raise card.error("I12 (product of inertia) is not supported")
        if name == "PBEAM" and len([f for f in card.fields[8:] if f is not None]) > 16:
            raise card.error("tapered beams (more than one station) are not supported")
        return Section(area, i2, i1, j)
    shape = (card.field(4) or "").upper()
    dims = [card.real(i, what=f"DIM{i - 8}") for i in range(9, 17) if card.field(i) is not None]
    if shape == "ROD" and dims:
        return Section.circle(dims[0])
    if shape == "TUBE" and len(dims) >= 2:
        return Section.tube(dims[0], dims[1])
    if shape == "BAR" and len(dims) >= 2:
        # DIM1 along the element y axis, DIM2 along z.
        return Section.rectangle(dims[0], dims[1])
    raise card.error(f"section type {shape!r} is not supported (ROD, TUBE, BAR)")


def _rbe2_dependents(card: Card) -> list[int]:
    # RBE2 EID GN CM GM1 GM2 ... (ALPHA may end the list).
    items = [f for f in card.fields[3:] if f is not None]
    out = []
    for text in items:
        try:
            out.append(int(text))
        except ValueError:
            if text.upper() == "THRU":
                raise card.error("THRU in RBE2 is not supported") from None
            break  # ALPHA (a real) ends the grids
    return out


_RBE3_ENDS = ("UM", "ALPHA", "TREF")


def _rbe3_independents(card: Card) -> list[int]:
    # RBE3 EID blank REFGRID REFC WT1 C1 G1,1 G1,2 ... WT2 C2 G2,1 ... [UM ...]
    items = [f for f in card.fields[4:] if f is not None]
    grids: list[int] = []
    k = 0
    while k < len(items):
        text = items[k]
        if text.upper() in _RBE3_ENDS:
            break
        if parse_real(text) is not None and "." in text:  # a weight, then its components
            k += 2
            while k < len(items) and "." not in items[k] and items[k].upper() not in _RBE3_ENDS:
                grids.append(card.integer_text(items[k]))
                k += 1
            continue
        raise card.error(f"expected a weight (a real) in the RBE3, found {text!r}")
    return grids


def _dmig(headers: dict[str, Card], columns: list[Card]) -> dict[str, DmigMatrix]:
    matrices: dict[str, DmigMatrix] = {}
    for name, header in headers.items():
        form = header.integer(3, what="IFO")
        tin = header.integer(4, what="TIN")
        if tin not in (1, 2):
            raise header.error(f"TIN = {tin}: only real matrices (TIN 1 or 2) are supported")
        if form not in (1, 2, 6, 9):
            raise header.error(f"IFO = {form} is not one of 1, 2, 6, 9")
        matrices[name] = DmigMatrix(name, form, [], [], [])
    for card in columns:
        name = (card.field(1) or "").upper()
        if name not in matrices:
            raise card.error(f"a column of matrix {name!r}, which has no header (DMIG,{name},0)")
        matrix = matrices[name]
        column = (card.integer(2, what="GJ"), card.integer(3, 0, what="CJ"))
        # (G, C, A, B) quadruples from field 5 on; B (imaginary part) blank for real matrices.
        for k in range(5, len(card.fields) + 1, 4):
            if card.field(k) is None:
                continue
            matrix.rows.append((card.integer(k, what="G"), card.integer(k + 1, 0, what="C")))
            matrix.columns.append(column)
            matrix.values.append(card.real(k + 2, what="A"))
    return matrices


__all__ = [
    "CARDS",
    "OP4_FORMS",
    "IGNORED",
    "MASS_CARDS",
    "DmigMatrix",
    "NastranDeck",
    "parse_real",
    "read_dmig",
    "read_nastran",
    "read_op4",
]


# OP4 matrices (OUTPUT4, ASCII) ---------------------------------------------------------------

#: OP4 matrix forms: 1 square, 2 rectangular, 3 diagonal, 6 symmetric, 8 identity, 9
#: pseudo-identity.
OP4_FORMS = (1, 2, 3, 6, 8, 9)

_OP4_WIDTH = re.compile(r"(\d+)\s*[EDed]\s*(\d+)\s*\.\s*\d+")


def read_op4(path: str | os.PathLike[str]) -> dict[str, tuple[int, Any]]:
    """The real matrices of an ASCII OP4 file (Nastran ``OUTPUT4``, e.g. ``KAA`` and ``MAA`` of
    a reduced component), by name: (form, scipy CSC matrix). Dense and sparse columns are
    read (a sparse column: strips of values, each after the word 65536 (length + 1) + first
    row); BIGMAT files are refused. OP4 files carry no grid or component labels: map the rows
    to the body's coordinates (for example with a DMIG or USET table) before
    `body_from_matrices`.

    Raises `MissingFileError`; `InvalidModelError` naming the file and line of a malformed
    header or record, a binary file (write the OP4 with ``FORMATTED``) or a complex matrix."""
    path = Path(path)
    if not path.is_file():
        raise MissingFileError("OP4 file", path)
    check_fits(path, path.stat().st_size, MEMORY_PER_BYTE, "OP4 file")
    raw = path.read_bytes()
    if b"\x00" in raw[:4096]:
        raise InvalidModelError(
            f"{path}: a binary OP4 file; flexmbd reads ASCII OP4 (OUTPUT4 with the FORMATTED "
            "option)",
            item=f"file '{path}'",
        )
    return _Op4(path, raw.decode("latin-1").splitlines()).matrices()


class _Op4:
    """The reader of one ASCII OP4 file: `k` is the number of lines read."""

    def __init__(self, path: Path, lines: list[str]):
        self.path, self.lines, self.k = path, lines, 0
        self.name, self.per_line, self.size = "", 1, 1

    def fail(self, message: str) -> InvalidModelError:
        return InvalidModelError(
            f"{self.path}, line {self.k}: {message}", item=f"line {self.k} of '{self.path}'"
        )

    def integers(self, count: int) -> list[int]:
        if self.k >= len(self.lines):
            raise self.fail(f"matrix {self.name}: the file ends before its last column")
        self.k += 1
        text = self.lines[self.k - 1]
        try:
            values = [int(v) for v in text.split()]
        except ValueError:
            raise self.fail(f"expected {count} integers, found {text!r:.80}") from None
        if len(values) != count:
            raise self.fail(f"expected {count} integers, found {len(values)}")
        return values

    def values(self, count: int) -> list[float]:
        out: list[float] = []
        while len(out) < count:
            if self.k >= len(self.lines):
                raise self.fail(f"matrix {self.name}: the file ends inside a column")
            self.k += 1
            text = self.lines[self.k - 1]
            for j in range(self.per_line):
                field = text[j * self.size : (j + 1) * self.size].strip()
                if not field:
                    break
                value = parse_real(field)
                if value is None or not math.isfinite(value):
                    raise self.fail(f"matrix {self.name}: not a number: {field!r}")
                out.append(value)
        return out[:count]

    def matrices(self) -> dict[str, tuple[int, Any]]:
        out = {}
        while self.k < len(self.lines):
            if not self.lines[self.k].strip():
                self.k += 1
                continue
            name, form, matrix = self.matrix()
            out[name] = (form, matrix)
        return out

    def matrix(self) -> tuple[str, int, Any]:
        import scipy.sparse as sp

        self.k += 1
        header = self.lines[self.k - 1]
        try:
            ncol, nrow, form, kind = (int(header[8 * i : 8 * i + 8]) for i in range(4))
        except ValueError:
            raise self.fail(
                f"expected a matrix header (4I8, name, format), found {header!r:.80}"
            ) from None
        self.name = header[32:40].strip()
        width = _OP4_WIDTH.search(header[40:])
        if not self.name or width is None:
            raise self.fail(f"the header has no matrix name or number format: {header!r:.80}")
        self.per_line, self.size = int(width.group(1)), int(width.group(2))
        if kind not in (1, 2):
            raise self.fail(f"matrix {self.name}: type {kind} (complex) is not supported")
        if form not in OP4_FORMS:
            raise self.fail(f"matrix {self.name}: form {form} is not one of {OP4_FORMS}")
        bigmat, nrow = nrow < 0, abs(nrow)
        rows: list[int] = []
        cols: list[int] = []
        data: list[float] = []

        def strip(first: int, column: int, length: int) -> None:
            if length < 1 or first < 1 or first - 1 + length > nrow:
                raise self.fail(f"matrix {self.name}: {length} values from row {first} of {nrow}")
            for offset, value in enumerate(self.values(length)):
                rows.append(first - 1 + offset)
                cols.append(column - 1)
                data.append(value)

        while True:
            icol, irow, words = self.integers(3)
            if icol > ncol:  # the end of the matrix: a record of one value follows
                self.values(max(words, 1))
                break
            if icol < 1:
                raise self.fail(f"matrix {self.name}: column {icol}")
            if irow > 0:  # dense: `words` values from row irow
                strip(irow, icol, words)
                continue
            if bigmat:
                raise self.fail(
                    f"matrix {self.name}: BIGMAT sparse columns are not supported (write the OP4 "
                    "dense or sparse without BIGMAT)"
                )
            left = words  # sparse: strips, each a packed header (length, first row), values
            while left > 0:
                (packed,) = self.integers(1)
                length = packed // 65536 - 1
                strip(packed - 65536 * (length + 1), icol, length)
                left -= 1 + length
        return self.name, form, sp.csc_matrix((data, (rows, cols)), shape=(nrow, ncol))
