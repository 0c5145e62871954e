"""Meshes of simple solids, for tests, examples and benchmarks, and meshes from Gmsh's Python API.

The structured generators need nothing beyond NumPy; :func:`gmsh_mesh` and :func:`cylinder`
need the ``gmsh`` package (``pip install gmsh``, part of the ``mesh`` extra). Every element is
positively oriented and in the node order of the element kernels (Gmsh's, see
:mod:`flexmbd.fe.mesh_io`).
"""

from __future__ import annotations

import itertools
import operator
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import direction as unit_vector
from .._checks import numbers_array
from ..errors import ArgumentTypeError, InvalidParameterError
from .mesh_io import Mesh

#: Corners of a hexahedron cell (i, j, k) of a structured grid, in hex8 node order (the
#: corners of the reference cube [0, 1]^3 of the hex8 shape functions).
HEX8_CORNERS = [
    (0, 0, 0),
    (1, 0, 0),
    (1, 1, 0),
    (0, 1, 0),
    (0, 0, 1),
    (1, 0, 1),
    (1, 1, 1),
    (0, 1, 1),
]
#: The six tetrahedra around the diagonal 0-6 of a hexahedron (Kuhn's subdivision). Every
#: cell of a structured grid is split the same way, so the faces of neighbours match.
_KUHN = [(0, 1, 2, 6), (0, 2, 3, 6), (0, 3, 7, 6), (0, 7, 4, 6), (0, 4, 5, 6), (0, 5, 1, 6)]
#: Vertices joined by the mid-edge nodes 4..9 of a tet10 (Gmsh order).
TET10_EDGES = ((0, 1), (1, 2), (0, 2), (0, 3), (2, 3), (1, 3))
#: Corners joined by the mid-edge nodes 8..19 of a hex20 (VTK order: the bottom face's edges,
#: the top face's, the vertical ones).
HEX20_EDGES = (
    (0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4), (0, 4), (1, 5), (2, 6), (3, 7),
)  # fmt: skip
#: Corners of the faces whose centres are the nodes 20..25 of a hex27 (VTK's triquadratic
#: hexahedron: the faces x = 0, x = 1, y = 0, y = 1, z = 0, z = 1 of `HEX8_CORNERS`); node 26
#: is the element's centre.
HEX27_FACES = ((0, 3, 7, 4), (1, 2, 6, 5), (0, 1, 5, 4), (3, 2, 6, 7), (0, 1, 2, 3), (4, 5, 6, 7))
#: Corners joined by the mid-edge nodes 6..14 of a wedge15 (Abaqus C3D15 order: the bottom
#: triangle's edges, the top one's, the vertical ones).
WEDGE15_EDGES = ((0, 1), (1, 2), (2, 0), (3, 4), (4, 5), (5, 3), (0, 3), (1, 4), (2, 5))
#: Corners of the quadrilateral faces whose centres are the nodes 15..17 of a wedge18.
WEDGE18_FACES = ((0, 1, 4, 3), (1, 2, 5, 4), (2, 0, 3, 5))
#: Corners joined by the mid-edge nodes 5..12 of a pyramid13 or pyramid14 (VTK order: the
#: base's edges, then those to the apex); node 13 of a pyramid14 is the base's centre.
PYRAMID13_EDGES = ((0, 1), (1, 2), (2, 3), (3, 0), (0, 4), (1, 4), (2, 4), (3, 4))

#: Meshes estimated at more elements than this are refused before they are made (the
#: `max_elements` keyword of :func:`box`, :func:`gmsh_mesh`, :func:`cylinder` and
#: :func:`tapered_link` moves the limit): 10 million elements take about 3 GB to make with
#: :func:`box` and 15 GB or more in Gmsh, and many times that in the preprocessor.
MAX_MESH_ELEMENTS = 10_000_000

#: The elements of :func:`box`.
BOX_ELEMENTS = (
    "hex8", "hex8i", "hex20", "hex20r", "hex27", "wedge6", "wedge15", "wedge18", "pyramid5",
    "pyramid13", "pyramid14", "tet4", "tet10",
)  # fmt: skip

#: Peak bytes per element of making a mesh (measured): :func:`box` for each element type, and
#: Gmsh for tetrahedra of order 1 and 2.
_BYTES_PER_ELEMENT = {
    "hex8": 220,
    "hex8i": 220,
    "hex20": 1300,
    "hex20r": 1300,
    "hex27": 1800,
    "wedge6": 200,
    "wedge15": 1000,
    "wedge18": 1200,
    "pyramid5": 150,
    "pyramid13": 600,
    "pyramid14": 700,
    "tet4": 280,
    "tet10": 640,
    "gmsh1": 1500,
    "gmsh2": 3500,
}

#: Tetrahedra that Gmsh makes per size^3 of volume (about 4.7 measured on cylinders and
#: boxes; the estimate rounds up).
_GMSH_TETRAHEDRA_PER_CUBE = 6.0


def _check_mesh_size(
    elements: float, nodes: float, kind: str, max_elements: float, how: str, advice: str
) -> None:
    """Raises `InvalidParameterError` when a mesh is estimated at more than `max_elements`
    elements; the message gives the estimate (elements, nodes when known, memory)."""
    if not max_elements > 0:
        raise InvalidParameterError(
            f"max_elements must be > 0, got {max_elements!r}", item="max_elements"
        )
    if elements <= max_elements:
        return

    def count(value: float) -> str:
        return f"{value:.0f}" if value < 1e6 else f"{value:.3g}"

    gigabytes = elements * _BYTES_PER_ELEMENT[kind] / 1e9
    counted = f"{count(elements)} elements" + (f" and {count(nodes)} nodes" if nodes else "")
    raise InvalidParameterError(
        f"the mesh would have about {counted} ({how}) and take about {gigabytes:.3g} GB to "
        f"make, more than the limit of {count(max_elements)} elements: {advice}, or pass "
        "max_elements=... to allow it",
        item="mesh size",
    )


def _three_numbers(value: Any, name: str) -> NDArray[np.float64]:
    """`value` as an array of three finite floats, else an `InvalidParameterError` naming the
    parameter `name` (an `ArgumentTypeError` when it is not numbers: a string, an id, ...)."""
    array = numbers_array(value, name)
    if array.shape != (3,) or not np.all(np.isfinite(array)):
        raise InvalidParameterError(
            f"{name} must be three finite numbers, got {array.tolist()!r:.80}", item=name
        )
    return array


def _divisions(divisions: Any) -> tuple[int, int, int]:
    """The divisions of a box: three integers, or one for all three directions (floats
    without a fraction are taken). Strings and bytes (whose items would read as character
    codes), bools, other floats and other objects are an `ArgumentTypeError`, another count
    than one or three an `InvalidParameterError`, both naming the parameter."""
    text = repr(divisions)
    shown = f"{text if len(text) <= 60 else text[:57] + '...'} ({type(divisions).__name__})"
    wrong = ArgumentTypeError(
        f"a box needs three integer divisions (or one for all three), got {shown}",
        item="divisions",
    )

    def count(n: Any) -> int:
        if isinstance(n, bool | np.bool_):
            raise wrong
        if isinstance(n, float) and n.is_integer():
            return int(n)
        try:
            return operator.index(n)
        except TypeError:
            raise wrong from None

    if isinstance(divisions, str | bytes | bytearray | memoryview | Mapping):
        raise wrong
    if not isinstance(divisions, Iterable) or (
        isinstance(divisions, np.ndarray) and divisions.ndim == 0
    ):
        n = count(divisions)
        return n, n, n
    # At most four (an endless iterator is not read for ever).
    items = [count(n) for n in itertools.islice(divisions, 4)]
    if len(items) == 1:
        return items[0], items[0], items[0]
    if len(items) != 3:
        raise InvalidParameterError(
            f"a box needs three divisions (or one for all three), got "
            f"{len(items) if len(items) < 4 else 'more than three'}: {shown}",
            item="divisions",
        )
    return items[0], items[1], items[2]


def _signed_volumes(nodes: NDArray[np.float64], tets: NDArray[np.int64]) -> NDArray[np.float64]:
    x0 = nodes[tets[:, 0]]
    a, b, c = (nodes[tets[:, k]] - x0 for k in (1, 2, 3))
    return np.einsum("ij,ij->i", a, np.cross(b, c)) / 6.0


def _orient(nodes: NDArray[np.float64], tets: NDArray[np.int64]) -> NDArray[np.int64]:
    """Swaps vertices 1 and 2 of the negatively oriented tetrahedra."""
    tets = tets.copy()
    flip = _signed_volumes(nodes, tets) < 0
    tets[flip, 1], tets[flip, 2] = tets[flip, 2], tets[flip, 1].copy()
    return tets


def quadratic_tetrahedra(
    nodes: NDArray[np.float64], tets: NDArray[np.int64]
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Tet10 elements from tet4 elements: one node at the midpoint of every edge, shared by
    the elements around it. Returns the extended nodes and the tet10 connectivity."""
    return _with_edge_midpoints(nodes, tets, TET10_EDGES)


def quadratic_hexahedra(
    nodes: NDArray[np.float64], hexes: NDArray[np.int64]
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Hex20 elements from hex8 elements: one node at the midpoint of every edge, shared by
    the elements around it. Returns the extended nodes and the hex20 connectivity."""
    return _with_edge_midpoints(nodes, hexes, HEX20_EDGES)


def triquadratic_hexahedra(
    nodes: NDArray[np.float64], hexes: NDArray[np.int64]
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Hex27 elements from hex8 elements: a node at the midpoint of every edge and at the
    centre of every face (shared by the elements around them) and one at each element's
    centre. Returns the extended nodes and the hex27 connectivity (VTK's order)."""
    nodes, cells = _with_edge_midpoints(nodes, hexes, HEX20_EDGES)
    keys = np.concatenate([np.sort(hexes[:, list(face)], axis=1) for face in HEX27_FACES])
    faces, inverse = np.unique(keys, axis=0, return_inverse=True)
    face_nodes = len(nodes) + inverse.reshape(len(HEX27_FACES), len(hexes)).T
    centres = len(nodes) + len(faces) + np.arange(len(hexes))
    corners = nodes[hexes]
    nodes = np.vstack([nodes, nodes[faces].mean(axis=1), corners.mean(axis=1)])
    return nodes, np.hstack([cells, face_nodes, centres[:, None]]).astype(np.int64)


def quadratic_wedges(
    nodes: NDArray[np.float64], wedges: NDArray[np.int64]
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Wedge15 elements from wedge6 elements: one node at the midpoint of every edge, shared
    by the elements around it. Returns the extended nodes and the wedge15 connectivity."""
    return _with_edge_midpoints(nodes, wedges, WEDGE15_EDGES)


def biquadratic_wedges(
    nodes: NDArray[np.float64], wedges: NDArray[np.int64]
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Wedge18 elements from wedge6 elements: a node at the midpoint of every edge and at the
    centre (the mean of the corners) of every quadrilateral face, shared by the elements
    around them. Returns the extended nodes and the wedge18 connectivity."""
    nodes, cells = _with_edge_midpoints(nodes, wedges, WEDGE15_EDGES)
    return _with_face_centres(nodes, cells, wedges, WEDGE18_FACES)


def quadratic_pyramids(
    nodes: NDArray[np.float64], pyramids: NDArray[np.int64], centre: bool = False
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Pyramid13 elements from pyramid5 elements: one node at the midpoint of every edge,
    shared by the elements around it; with `centre`, pyramid14 elements (also a node at the
    centre of every base, shared by the two pyramids on it). Returns the extended nodes and
    the connectivity."""
    nodes, cells = _with_edge_midpoints(nodes, pyramids, PYRAMID13_EDGES)
    if centre:
        return _with_face_centres(nodes, cells, pyramids, ((0, 1, 2, 3),))
    return nodes, cells


def _with_face_centres(
    nodes: NDArray[np.float64],
    cells: NDArray[np.int64],
    corners: NDArray[np.int64],
    faces: Sequence[tuple[int, ...]],
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """A node at the mean of the corners of each quadrilateral face `faces` of the cells
    `corners` (one per face, however many cells share it) appended to the nodes and, in the
    order of `faces`, to the rows of `cells`."""
    keys = np.concatenate([np.sort(corners[:, list(face)], axis=1) for face in faces])
    unique, inverse = np.unique(keys, axis=0, return_inverse=True)
    face_nodes = len(nodes) + inverse.reshape(len(faces), len(corners)).T
    nodes = np.vstack([nodes, nodes[unique].mean(axis=1)])
    return nodes, np.hstack([cells, face_nodes]).astype(np.int64)


def _with_edge_midpoints(
    nodes: NDArray[np.float64], cells: NDArray[np.int64], cell_edges: Sequence[tuple[int, int]]
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """A node at the midpoint of each edge `cell_edges` of the cells (one per edge, however
    many cells share it) appended to the nodes and, in the order of `cell_edges`, to the
    cells."""
    pairs = np.concatenate([np.sort(cells[:, [p, q]], axis=1) for p, q in cell_edges])
    edges, inverse = np.unique(pairs, axis=0, return_inverse=True)
    mid = 0.5 * (nodes[edges[:, 0]] + nodes[edges[:, 1]])
    edge_nodes = len(nodes) + inverse.reshape(len(cell_edges), len(cells)).T
    return np.vstack([nodes, mid]), np.hstack([cells, edge_nodes]).astype(np.int64)


def box(
    lengths: ArrayLike,
    divisions: Sequence[int],
    element: str = "hex8",
    *,
    origin: ArrayLike = (0.0, 0.0, 0.0),
    max_elements: float = MAX_MESH_ELEMENTS,
) -> Mesh:
    """A structured mesh of the box origin + [0, a] x [0, b] x [0, c].

    `divisions` = (n_x, n_y, n_z) cells (one integer n: n in each direction); `element`
    "hex8", "hex8i" (hexahedra with incompatible modes: they bend), "hex20", "hex20r"
    (quadratic hexahedra; reduced integration), "hex27" (triquadratic), "wedge6" (two prisms
    per cell, split in z), "wedge15" (the same, quadratic), "wedge18" (the same, Lagrange),
    "pyramid5" (six pyramids per cell, their apexes at a node in its centre), "pyramid13",
    "pyramid14" (the same, quadratic; with the bases' centres), "tet4" (six tetrahedra per
    cell) or "tet10". Node sets:
    "x0", "x1", "y0", "y1", "z0", "z1" (the faces), "all".

    Raises `InvalidParameterError` for lengths that are not three positive finite numbers,
    divisions that are not three (or one) positive integers (an `ArgumentTypeError` for
    divisions that are not integers: strings, bytes, bools, floats with a fraction), an
    origin that is not three finite numbers, an unknown element, and meshes of more than
    `max_elements` elements (default :data:`MAX_MESH_ELEMENTS`; the message gives the node
    and element counts and the memory); the message names the parameter."""
    lengths = _three_numbers(lengths, "lengths")
    origin = _three_numbers(origin, "origin")
    nx, ny, nz = _divisions(divisions)
    if not np.all(lengths > 0):
        raise InvalidParameterError(
            f"a box needs three positive lengths, got {lengths.tolist()}", item="lengths"
        )
    if min(nx, ny, nz) < 1:
        raise InvalidParameterError(
            f"a box needs three positive divisions, got {[nx, ny, nz]}", item="divisions"
        )
    if not isinstance(element, str) or element not in BOX_ELEMENTS:
        raise InvalidParameterError(
            f"box elements are {', '.join(BOX_ELEMENTS[:-1])} or {BOX_ELEMENTS[-1]}, got "
            f"{element!r:.60}",
            item="element",
        )
    # Sizes from the counts alone (Python integers: no overflow) before any array is made.
    cells = nx * ny * nz
    node_count = (nx + 1) * (ny + 1) * (nz + 1)
    if element == "tet10":
        # Mid-edge nodes: the grid's edges, one diagonal per face and one per cell.
        node_count += nx * (ny + 1) * (nz + 1) + (nx + 1) * ny * (nz + 1)
        node_count += (nx + 1) * (ny + 1) * nz + (nx + 1) * ny * nz + nx * (ny + 1) * nz
        node_count += nx * ny * (nz + 1) + cells
    if element in ("hex20", "hex20r", "hex27", "wedge15", "wedge18", "pyramid13", "pyramid14"):
        # Mid-edge nodes: the grid's edges (and a wedge's: one diagonal per z-face).
        node_count += nx * (ny + 1) * (nz + 1) + (nx + 1) * ny * (nz + 1)
        node_count += (nx + 1) * (ny + 1) * nz
        if element == "hex27":  # the faces' and the cells' centres
            node_count += (nx + 1) * ny * nz + nx * (ny + 1) * nz + nx * ny * (nz + 1) + cells
        if element in ("wedge15", "wedge18"):
            node_count += nx * ny * (nz + 1)
        if element == "wedge18":  # the vertical faces' centres, the diagonal ones included
            node_count += (nx + 1) * ny * nz + nx * (ny + 1) * nz + cells
        if element in ("pyramid13", "pyramid14"):  # the edges from the corners to the centre
            node_count += 8 * cells
        if element == "pyramid14":  # the faces' centres
            node_count += (nx + 1) * ny * nz + nx * (ny + 1) * nz + nx * ny * (nz + 1)
    if element.startswith("pyramid"):
        node_count += cells  # the cells' centres
    per_cell = 1 if element.startswith("hex") else 2 if element.startswith("wedge") else 6
    element_count = per_cell * cells
    _check_mesh_size(
        element_count,
        node_count,
        element,
        max_elements,
        f"divisions {nx} x {ny} x {nz}",
        "use fewer divisions",
    )
    counts = (nx, ny, nz)
    axes = [np.linspace(0.0, lengths[a], counts[a] + 1) for a in range(3)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    nodes = grid + origin

    def index(i, j, k):
        return (i * (ny + 1) + j) * (nz + 1) + k

    cells = np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij")
    i, j, k = (a.ravel() for a in cells)
    hexes = np.column_stack([index(i + a, j + b, k + c) for a, b, c in HEX8_CORNERS])
    hexes = hexes.astype(np.int64)
    if element in ("hex8", "hex8i"):
        elements = {element: hexes}
    elif element in ("hex20", "hex20r"):
        nodes, hexes = quadratic_hexahedra(nodes, hexes)
        elements = {element: hexes}
    elif element == "hex27":
        nodes, hexes = triquadratic_hexahedra(nodes, hexes)
        elements = {element: hexes}
    elif element in ("wedge6", "wedge15", "wedge18"):
        # Each cell split along its diagonal 0-2 in z: the prisms (0, 1, 2 | 4, 5, 6) and
        # (0, 2, 3 | 4, 6, 7), their triangles counter-clockwise seen from +z.
        prisms = np.vstack([hexes[:, [0, 1, 2, 4, 5, 6]], hexes[:, [0, 2, 3, 4, 6, 7]]])
        if element == "wedge15":
            nodes, prisms = quadratic_wedges(nodes, prisms)
        elif element == "wedge18":
            nodes, prisms = biquadratic_wedges(nodes, prisms)
        elements = {element: prisms}
    elif element.startswith("pyramid"):
        # A pyramid on each face of a cell, its apex at the cell's centre (a node of its own):
        # the base counter-clockwise seen from the centre.
        centres = len(nodes) + np.arange(len(hexes))
        nodes = np.vstack([nodes, nodes[hexes].mean(axis=1)])
        faces = ((0, 1, 2, 3), (4, 7, 6, 5), (0, 4, 5, 1), (1, 5, 6, 2), (2, 6, 7, 3), (3, 7, 4, 0))
        pyramids = np.vstack([np.column_stack([hexes[:, list(f)], centres]) for f in faces])
        pyramids = pyramids.astype(np.int64)
        if element != "pyramid5":
            nodes, pyramids = quadratic_pyramids(nodes, pyramids, centre=element == "pyramid14")
        elements = {element: pyramids}
    else:
        tets = np.vstack([hexes[:, list(t)] for t in _KUHN])
        tets = _orient(nodes, tets)
        if element == "tet10":
            nodes, tets = quadratic_tetrahedra(nodes, tets)
            elements = {"tet10": tets}
        else:
            elements = {"tet4": tets}
    return _with_face_sets(nodes, elements, origin, lengths)


def plate(
    lengths: ArrayLike,
    divisions: Sequence[int] | int,
    element: str = "quad4",
    *,
    origin: ArrayLike = (0.0, 0.0, 0.0),
    max_elements: float = MAX_MESH_ELEMENTS,
) -> Mesh:
    """A structured mesh of flat shells on the rectangle origin + [0, a] x [0, b] in the x-y
    plane (normals along +z).

    `lengths` = (a, b); `divisions` = (n_x, n_y) cells (one integer n: n in both
    directions); `element` "quad4" or "tri3" (two triangles per cell, split along
    alternating diagonals so that the mesh has no preferred direction). Node sets: "x0",
    "x1", "y0", "y1" (the edges), "all". The elements need a shell section in `build_body`
    (`shell=thickness`).

    Raises `InvalidParameterError` for lengths that are not two positive finite numbers,
    divisions that are not two (or one) positive integers, an unknown element or more than
    `max_elements` elements, naming the parameter."""
    sizes = numbers_array(lengths, "lengths").ravel()
    if sizes.shape != (2,) or not np.all(np.isfinite(sizes)) or not np.all(sizes > 0):
        raise InvalidParameterError(
            f"a plate needs two positive finite lengths, got {sizes.tolist()}", item="lengths"
        )
    origin = _three_numbers(origin, "origin")
    given = divisions if isinstance(divisions, Iterable) else (divisions,)
    if not isinstance(divisions, str | bytes) and len(list(given)) == 2:
        nx, ny, _ = _divisions((*given, 1))
    else:
        nx, ny, _ = _divisions(divisions)
    if min(nx, ny) < 1:
        raise InvalidParameterError(
            f"a plate needs two positive divisions, got {[nx, ny]}", item="divisions"
        )
    if not isinstance(element, str) or element not in ("quad4", "tri3"):
        raise InvalidParameterError(
            f"plate elements are quad4 or tri3, got {element!r:.60}", item="element"
        )
    cells = nx * ny
    _check_mesh_size(
        cells if element == "quad4" else 2 * cells,
        (nx + 1) * (ny + 1),
        "hex8",
        max_elements,
        f"divisions {nx} x {ny}",
        "use fewer divisions",
    )
    x, y = np.meshgrid(
        np.linspace(0.0, sizes[0], nx + 1), np.linspace(0.0, sizes[1], ny + 1), indexing="ij"
    )
    nodes = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)]) + origin
    i, j = (a.ravel() for a in np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij"))

    def index(a: Any, b: Any) -> Any:
        return a * (ny + 1) + b

    quads = np.column_stack([index(i, j), index(i + 1, j), index(i + 1, j + 1), index(i, j + 1)])
    quads = quads.astype(np.int64)
    if element == "quad4":
        elements = {"quad4": quads}
    else:
        # Diagonal 0-2 on cells of even i + j, 1-3 on the others.
        even = (i + j) % 2 == 0
        first = np.where(even[:, None], quads[:, [0, 1, 2]], quads[:, [0, 1, 3]])
        second = np.where(even[:, None], quads[:, [0, 2, 3]], quads[:, [1, 2, 3]])
        elements = {"tri3": np.vstack([first, second]).astype(np.int64)}
    mesh = _with_face_sets(nodes, elements, origin, np.array([sizes[0], sizes[1], 1.0]))
    sets = {k: v for k, v in mesh.node_sets.items() if k not in ("z0", "z1")}
    return Mesh(
        nodes=mesh.nodes,
        node_ids=mesh.node_ids,
        elements=mesh.elements,
        element_ids=mesh.element_ids,
        node_sets=sets,
    )


def _with_face_sets(
    nodes: NDArray[np.float64],
    elements: dict[str, NDArray[np.int64]],
    origin: NDArray[np.float64],
    lengths: NDArray[np.float64],
) -> Mesh:
    tolerance = 1e-9 * lengths.max()
    sets = {}
    for axis, name in enumerate("xyz"):
        sets[f"{name}0"] = np.flatnonzero(np.abs(nodes[:, axis] - origin[axis]) < tolerance)
        far = origin[axis] + lengths[axis]
        sets[f"{name}1"] = np.flatnonzero(np.abs(nodes[:, axis] - far) < tolerance)
    sets["all"] = np.arange(len(nodes))
    element_ids = {}
    first = 1
    for kind, conn in elements.items():
        element_ids[kind] = np.arange(first, first + len(conn), dtype=np.int64)
        first += len(conn)
    return Mesh(
        nodes=nodes,
        node_ids=np.arange(1, len(nodes) + 1, dtype=np.int64),
        elements=elements,
        element_ids=element_ids,
        node_sets={name: indices.astype(np.int64) for name, indices in sets.items()},
    )


def gmsh_mesh(
    build: Callable[[Any], None],
    *,
    size: float,
    order: int = 1,
    element: str = "tet",
    size_field: str | None = None,
    max_elements: float = MAX_MESH_ELEMENTS,
) -> Mesh:
    """Meshes a geometry with Gmsh's Python API (``pip install gmsh``).

    `build(gmsh)` creates the geometry in the current model (e.g. with ``gmsh.model.occ``) and
    may add named physical groups, which become node sets; `size` is the target element size;
    `order` 1 gives tet4, 2 gives tet10 (mid-edge nodes on the curved geometry). `element` "tet"
    meshes volumes with tetrahedra (the only choice for now). `size_field`, a Gmsh MathEval
    expression in x, y, z (e.g. ``"0.002 + 0.1 * y"``), grades the element size over the
    geometry instead (`size` then only bounds it from above).

    Before meshing, the number of tetrahedra is estimated from the bounding boxes of the
    volumes, about 6 per `size`^3 (a graded `size_field` can make more); above
    `max_elements` (default :data:`MAX_MESH_ELEMENTS`) `InvalidParameterError` gives the
    estimate, before Gmsh runs out of memory."""
    try:
        import gmsh
    except ImportError as error:  # pragma: no cover - depends on the installation
        raise InvalidParameterError(
            "meshing a geometry needs the gmsh package: pip install gmsh"
        ) from error
    if element != "tet" or order not in (1, 2) or not size > 0:
        raise InvalidParameterError(
            f"gmsh meshes need element 'tet', order 1 or 2 and size > 0, got {element!r}, "
            f"{order}, {size}"
        )
    initialized_here = not gmsh.isInitialized()
    if initialized_here:
        gmsh.initialize(interruptible=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("flexmbd")
        build(gmsh)
        if gmsh.model.occ.getEntities():
            gmsh.model.occ.synchronize()
        volume = 0.0
        for _, tag in gmsh.model.getEntities(3):
            low, high = np.split(np.asarray(gmsh.model.getBoundingBox(3, tag), dtype=float), 2)
            volume += float(np.prod(np.clip(high - low, 0.0, None)))
        _check_mesh_size(
            _GMSH_TETRAHEDRA_PER_CUBE * volume / size**3,
            0,
            f"gmsh{order}",
            max_elements,
            f"bounding boxes of volume {volume:.3g} at size {size:g}",
            "use a larger size",
        )
        if size_field is None:
            gmsh.option.setNumber("Mesh.MeshSizeMin", size)
        else:
            field = gmsh.model.mesh.field.add("MathEval")
            gmsh.model.mesh.field.setString(field, "F", size_field)
            gmsh.model.mesh.field.setAsBackgroundMesh(field)
            for option in (
                "MeshSizeFromPoints",
                "MeshSizeFromCurvature",
                "MeshSizeExtendFromBoundary",
            ):
                gmsh.option.setNumber(f"Mesh.{option}", 0)
        gmsh.option.setNumber("Mesh.MeshSizeMax", size)
        gmsh.model.mesh.generate(3)
        if order == 2:
            gmsh.model.mesh.setOrder(2)
        return _mesh_from_gmsh(gmsh, order)
    finally:
        gmsh.model.remove()
        if initialized_here:
            gmsh.finalize()


def _mesh_from_gmsh(gmsh: Any, order: int) -> Mesh:
    tags, coordinates, _ = gmsh.model.mesh.getNodes()
    tags = np.asarray(tags, dtype=np.int64)
    nodes = np.asarray(coordinates, dtype=float).reshape(-1, 3)
    position = np.full(tags.max() + 1, -1, dtype=np.int64)
    position[tags] = np.arange(len(tags))
    gmsh_type = 4 if order == 1 else 11  # 4-node and 10-node tetrahedra
    element_tags, node_tags = gmsh.model.mesh.getElementsByType(gmsh_type)
    width = 4 if order == 1 else 10
    conn = position[np.asarray(node_tags, dtype=np.int64).reshape(-1, width)]
    # Keep only the nodes of the volume elements (Gmsh also returns those of geometry points).
    used = np.unique(conn)
    renumber = np.full(len(nodes), -1, dtype=np.int64)
    renumber[used] = np.arange(len(used))
    kind = "tet4" if order == 1 else "tet10"
    sets = {}
    for dim, tag in gmsh.model.getPhysicalGroups():
        name = gmsh.model.getPhysicalName(dim, tag)
        if not name:
            continue
        group_nodes, _ = gmsh.model.mesh.getNodesForPhysicalGroup(dim, tag)
        indices = renumber[position[np.asarray(group_nodes, dtype=np.int64)]]
        sets[name] = np.unique(indices[indices >= 0])
    return Mesh(
        nodes=nodes[used],
        node_ids=tags[used],
        elements={kind: renumber[conn]},
        element_ids={kind: np.asarray(element_tags, dtype=np.int64)},
        node_sets=sets,
    )


def cylinder(
    radius: float,
    length: float,
    *,
    size: float,
    order: int = 2,
    axis: ArrayLike = (1.0, 0.0, 0.0),
    max_elements: float = MAX_MESH_ELEMENTS,
) -> Mesh:
    """A tetrahedral mesh of a solid circular cylinder from the origin along `axis` (Gmsh).
    Node sets "base" (the end face at the origin), "end" (the other one) and "mantle".
    `max_elements`: see :func:`gmsh_mesh`."""
    if not (radius > 0 and length > 0):
        raise InvalidParameterError(f"a cylinder needs radius, length > 0, got {radius}, {length}")
    direction = length * unit_vector(axis, "axis")

    def build(gmsh: Any) -> None:
        volume = gmsh.model.occ.addCylinder(0, 0, 0, *direction, radius)
        gmsh.model.occ.synchronize()
        gmsh.model.addPhysicalGroup(3, [volume], name="body")
        for dim, tag in gmsh.model.getBoundary([(3, volume)], oriented=False):
            center = np.asarray(gmsh.model.occ.getCenterOfMass(dim, tag))
            s = center @ direction / length**2
            name = "base" if abs(s) < 1e-9 else "end" if abs(s - 1) < 1e-9 else "mantle"
            gmsh.model.addPhysicalGroup(dim, [tag], name=name)

    return gmsh_mesh(build, size=size, order=order, max_elements=max_elements)


def tapered_link(
    length: float,
    root: tuple[float, float],
    tip: tuple[float, float],
    *,
    size: float,
    order: int = 2,
    tip_offset: tuple[float, float] = (0.0, 0.0),
    size_field: str | None = None,
    max_elements: float = MAX_MESH_ELEMENTS,
) -> Mesh:
    """A tetrahedral mesh of a tapered link (Gmsh): a loft along x from the rectangle
    `root` = (width along y, height along z) centred on the origin at x = 0 to the rectangle
    `tip` at x = `length`, centred at (y, z) = `tip_offset`. Node sets "root" and "tip" (the
    end faces) and "sides". `size_field` grades the mesh (see :func:`gmsh_mesh`), so that the
    end faces can be meshed unevenly. `max_elements`: see :func:`gmsh_mesh`."""
    if not (length > 0 and min(root) > 0 and min(tip) > 0):
        raise InvalidParameterError(
            f"a tapered link needs positive length and sections, got {length}, {root}, {tip}"
        )

    def rectangle(gmsh: Any, x: float, width: float, height: float, y: float, z: float) -> int:
        corners = [(y - width / 2, z - height / 2), (y + width / 2, z - height / 2)]
        corners += [(y + width / 2, z + height / 2), (y - width / 2, z + height / 2)]
        points = [gmsh.model.occ.addPoint(x, a, b) for a, b in corners]
        lines = [gmsh.model.occ.addLine(points[k], points[(k + 1) % 4]) for k in range(4)]
        return gmsh.model.occ.addCurveLoop(lines)

    def build(gmsh: Any) -> None:
        first = rectangle(gmsh, 0.0, root[0], root[1], 0.0, 0.0)
        last = rectangle(gmsh, length, tip[0], tip[1], *tip_offset)
        volumes = gmsh.model.occ.addThruSections([first, last], makeSolid=True, makeRuled=True)
        gmsh.model.occ.synchronize()
        volume = [tag for dim, tag in volumes if dim == 3]
        gmsh.model.addPhysicalGroup(3, volume, name="link")
        sides = []
        for dim, tag in gmsh.model.getBoundary([(3, v) for v in volume], oriented=False):
            x = gmsh.model.occ.getCenterOfMass(dim, tag)[0]
            if abs(x) < 1e-9 * length:
                gmsh.model.addPhysicalGroup(dim, [tag], name="root")
            elif abs(x - length) < 1e-9 * length:
                gmsh.model.addPhysicalGroup(dim, [tag], name="tip")
            else:
                sides.append(tag)
        gmsh.model.addPhysicalGroup(2, sides, name="sides")

    return gmsh_mesh(
        build, size=size, order=order, size_field=size_field, max_elements=max_elements
    )
