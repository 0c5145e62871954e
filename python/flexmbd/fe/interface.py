"""Interfaces of deformable bodies: node sets where joints, forces and Craig-Bampton static
modes meet the body (the intermediate joint frames of seed Figure 4 on averaged node sets).

An interface has nodal **weights** w_p, a **centroid** x_c = sum w_p x_p / sum w_p and **axes**.
Its motion is the weighted least-squares rigid motion of its nodes (an RBE3 element):

    u_c = sum w_p u_p / W,       theta = H^-1 sum w_p d_p x u_p,
    H = sum w_p (|d_p|^2 I - d_p d_p^T),   d_p = x_p - x_c,   W = sum w_p,

and with the coupling "rbe2" the nodes follow that motion rigidly, u_p = u_c + theta x d_p.

On bodies whose nodes have rotational coordinates phi_p (beams and shells, six per node) a set
may lie on one line (a shell's edge, a beam's segment) or be one node: H is then singular, and
the components of theta along its null space (the line's direction e; every direction for one
node) are the weighted mean of the nodes' rotations, theta.e = sum w_p phi_p.e / W. Sets that
define a rotation use the translations only, as above.

Weights (``weights=``):

- ``"area"``: w_p = integral of N_p over the facets of the set (element faces whose nodes all
  belong to it), the consistent nodal areas. Then sum w_p x_p = integral of x dA over the
  facets: the centroid is the face's centroid for any mesh, however unevenly its nodes are
  spaced (for quadratic triangles the corner weights are 0 and the mid-edge weights A/3).
- ``"length"``: the same over the element edges of the set (a line of nodes).
- ``"volume"``: the same over the elements whose nodes all belong to the set.
- ``"uniform"``: w_p = 1 (the plain average of the node positions).
- ``"auto"`` (default): "volume" if the elements inside the set hold all its nodes, else
  "area" if the set has facets, else "length" if it has element edges, else an error.
  Bodies without elements (from matrices) use "uniform".
- an array of one weight per node (in the order of the set), positive in sum. (Volume
  weights of quadratic tetrahedra are negative at the corners, as the integrals of their
  shape functions are; the fit below only needs H positive definite.)

Axes (``orientation=``): a 3 x 3 matrix (columns: the axes in the body frame), None (the
body axes), or ``"principal"``: z along the axis of least spread of the weighted node
positions (the face normal for a flat face, pointing out of the elements that own the
facets, else away from the body's nodes' centre), x along the axis of largest spread (when
the two in-plane spreads are equal to 1e-6, the body axis most nearly in the plane, projected
onto it), each axis signed so that its largest component is positive where the normal does
not fix it, and y = z x x.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import InvalidModelError, InvalidParameterError
from .body import cell_of
from .shapes import (
    HEX8_CORNERS,
    HEX20_EDGES,
    HEX27_FACES,
    PYRAMID13_EDGES,
    TET10_EDGES,
    WEDGE15_EDGES,
)

if TYPE_CHECKING:
    import scipy.sparse as sp

#: Ways of weighting the nodes of an interface.
WEIGHTINGS = ("auto", "area", "length", "volume", "uniform")

#: Couplings of an interface marker to its nodes.
COUPLINGS = ("rbe3", "rbe2")

Array = NDArray[np.float64]

# Facets (faces) and edges of the elements, in each element's local node numbers, with the
# kind of the facet. Node orders are Gmsh's (see `flexmbd.fe.mesh_io`): tet10 mid-edge nodes
# 4..9 on the edges (0,1), (1,2), (0,2), (0,3), (2,3), (1,3); triangle facets list their
# corners, then the mid-edge nodes of the edges (a,b), (b,c), (c,a); quad8 facets their
# corners, then the mid-edge nodes of the edges (a,b), (b,c), (c,d), (d,a); line3 edges their
# ends, then the middle. hex20 mid-edge nodes 8..19 on the edges `HEX20_EDGES` (VTK order).
_FACETS: dict[str, tuple[str, tuple[tuple[int, ...], ...]]] = {
    "tet4": ("tri3", ((0, 1, 2), (0, 1, 3), (0, 2, 3), (1, 2, 3))),
    "tet10": (
        "tri6",
        ((0, 1, 2, 4, 5, 6), (0, 1, 3, 4, 9, 7), (0, 2, 3, 6, 8, 7), (1, 2, 3, 5, 8, 9)),
    ),
    "hex8": (
        "quad4",
        (
            (0, 1, 2, 3),
            (4, 5, 6, 7),
            (0, 1, 5, 4),
            (1, 2, 6, 5),
            (2, 3, 7, 6),
            (3, 0, 4, 7),
        ),
    ),
    "hex20": (
        "quad8",
        (
            (0, 1, 2, 3, 8, 9, 10, 11),
            (4, 5, 6, 7, 12, 13, 14, 15),
            (0, 1, 5, 4, 8, 17, 12, 16),
            (1, 2, 6, 5, 9, 18, 13, 17),
            (2, 3, 7, 6, 10, 19, 14, 18),
            (3, 0, 4, 7, 11, 16, 15, 19),
        ),
    ),
    # Shells: the element is its own facet (an interface of shell nodes weighted by area).
    "quad4": ("quad4", ((0, 1, 2, 3),)),
    "tri3": ("tri3", ((0, 1, 2),)),
}
_EDGES: dict[str, tuple[str, tuple[tuple[int, ...], ...]]] = {
    "beam2": ("line2", ((0, 1),)),
    "tet4": ("line2", ((0, 1), (1, 2), (0, 2), (0, 3), (2, 3), (1, 3))),
    "tet10": (
        "line3",
        ((0, 1, 4), (1, 2, 5), (0, 2, 6), (0, 3, 7), (2, 3, 8), (1, 3, 9)),
    ),
    "hex8": (
        "line2",
        (
            (0, 1),
            (1, 2),
            (2, 3),
            (3, 0),
            (4, 5),
            (5, 6),
            (6, 7),
            (7, 4),
            (0, 4),
            (1, 5),
            (2, 6),
            (3, 7),
        ),
    ),
    "hex20": ("line3", tuple((p, q, 8 + e) for e, (p, q) in enumerate(HEX20_EDGES))),
    "quad4": ("line2", ((0, 1), (1, 2), (2, 3), (3, 0))),
    "tri3": ("line2", ((0, 1), (1, 2), (2, 0))),
}
#: Per element type, its groups of (sub-cell kind, local node lists): one group each, two for
#: the faces of a wedge (triangles and quadrilaterals).
_FACET_GROUPS = {element: (group,) for element, group in _FACETS.items()}
_FACET_GROUPS["wedge6"] = (
    ("tri3", ((0, 1, 2), (3, 4, 5))),
    ("quad4", ((0, 1, 4, 3), (1, 2, 5, 4), (2, 0, 3, 5))),
)
_EDGE_GROUPS = {element: (group,) for element, group in _EDGES.items()}
_EDGE_GROUPS["wedge6"] = (
    ("line2", ((0, 1), (1, 2), (2, 0), (3, 4), (4, 5), (5, 3), (0, 3), (1, 4), (2, 5))),
)
# wedge15 mid-edge nodes 6..14 on the edges `WEDGE15_EDGES` (Abaqus C3D15 order).
_FACET_GROUPS["wedge15"] = (
    ("tri6", ((0, 1, 2, 6, 7, 8), (3, 4, 5, 9, 10, 11))),
    (
        "quad8",
        ((0, 1, 4, 3, 6, 13, 9, 12), (1, 2, 5, 4, 7, 14, 10, 13), (2, 0, 3, 5, 8, 12, 11, 14)),
    ),
)
_EDGE_GROUPS["wedge15"] = (
    ("line3", tuple((p, q, 6 + e) for e, (p, q) in enumerate(WEDGE15_EDGES))),
)
# pyramid5: the base 0, 1, 2, 3 and the apex 4.
_FACET_GROUPS["pyramid5"] = (
    ("quad4", ((0, 1, 2, 3),)),
    ("tri3", ((0, 1, 4), (1, 2, 4), (2, 3, 4), (3, 0, 4))),
)
_EDGE_GROUPS["pyramid5"] = (
    ("line2", ((0, 1), (1, 2), (2, 3), (3, 0), (0, 4), (1, 4), (2, 4), (3, 4))),
)
# hex27: the faces of hex20 with their centres 20..25 (`HEX27_FACES`), the edges of hex20.
_FACET_GROUPS["hex27"] = (
    (
        "quad9",
        tuple(
            (*face, 20 + next(k for k, f in enumerate(HEX27_FACES) if set(f) == set(face[:4])))
            for face in _FACETS["hex20"][1]
        ),
    ),
)
_EDGE_GROUPS["hex27"] = _EDGE_GROUPS["hex20"]
# wedge18: the triangles of wedge15 and its quadrilaterals with their centres 15..17
# (`WEDGE18_FACES`, in the same order as wedge15's quadrilaterals), the edges of wedge15.
_FACET_GROUPS["wedge18"] = (
    _FACET_GROUPS["wedge15"][0],
    ("quad9", tuple((*f, 15 + k) for k, f in enumerate(_FACET_GROUPS["wedge15"][1][1]))),
)
_EDGE_GROUPS["wedge18"] = _EDGE_GROUPS["wedge15"]
# pyramid13: mid-edge nodes 5..12 on the edges `PYRAMID13_EDGES`; pyramid14 with the base's
# centre 13.
_PYRAMID_TRIANGLES = tuple(
    (a, b, 4, 5 + a, 9 + b, 9 + a) for a, b in ((0, 1), (1, 2), (2, 3), (3, 0))
)
_FACET_GROUPS["pyramid13"] = (
    ("quad8", ((0, 1, 2, 3, 5, 6, 7, 8),)),
    ("tri6", _PYRAMID_TRIANGLES),
)
_FACET_GROUPS["pyramid14"] = (
    ("quad9", ((0, 1, 2, 3, 5, 6, 7, 8, 13),)),
    ("tri6", _PYRAMID_TRIANGLES),
)
_EDGE_GROUPS["pyramid13"] = _EDGE_GROUPS["pyramid14"] = (
    ("line3", tuple((p, q, 5 + e) for e, (p, q) in enumerate(PYRAMID13_EDGES))),
)
_SOLIDS = (
    "tet4", "tet10", "hex8", "hex20", "hex27", "wedge6", "wedge15", "wedge18", "pyramid5",
    "pyramid13", "pyramid14",
)  # fmt: skip
#: How far (a fraction of the diagonal of its nodes' box) an interface's weighted centroid
#: may lie outside that box: a curved quadratic face's centroid can, by a little.
OUTSIDE_LIMIT = 0.1

#: Cells integrated at a time.
_CHUNK = 16384


# Shape functions on reference cells -----------------------------------------------------------

#: Reference coordinates (-1, 0, 1 per direction) of the nodes of the Lagrange cells: the
#: quad9 facet (its corners, the mid-edge nodes of (a,b), (b,c), (c,d), (d,a), the centre)
#: and the hex27 (the corners, the mid-edge nodes of `HEX20_EDGES`, the centres of
#: `HEX27_FACES`, the centre).
_CORNERS_3D = [tuple(2 * v - 1 for v in corner) for corner in HEX8_CORNERS]
_LAGRANGE_NODES = {
    "quad9": [(-1, -1), (1, -1), (1, 1), (-1, 1), (0, -1), (1, 0), (0, 1), (-1, 0), (0, 0)],
    "hex27": _CORNERS_3D
    + [
        tuple((_CORNERS_3D[p][k] + _CORNERS_3D[q][k]) // 2 for k in range(3))
        for p, q in HEX20_EDGES
    ]
    + [tuple(sum(_CORNERS_3D[a][k] for a in face) // 4 for k in range(3)) for face in HEX27_FACES]
    + [(0, 0, 0)],
}


def _shape(kind: str, xi: Any) -> list[Any]:
    """Shape functions of a reference cell at the point(s) `xi` (tuple of coordinates; line,
    triangle and tetrahedron on the unit simplex, quadrilateral and hexahedron on [0, 1]^d).
    Written for real or complex arguments (derivatives by complex step)."""
    if kind == "line2":
        (s,) = xi
        return [1 - s, s]
    if kind == "line3":
        (s,) = xi
        return [(1 - s) * (1 - 2 * s), s * (2 * s - 1), 4 * s * (1 - s)]
    if kind in ("tri3", "tri6"):
        a, b = xi
        lam = [1 - a - b, a, b]
        if kind == "tri3":
            return lam
        corners = [v * (2 * v - 1) for v in lam]
        return corners + [4 * lam[p] * lam[(p + 1) % 3] for p in range(3)]
    if kind == "quad4":
        a, b = xi
        return [(1 - a) * (1 - b), a * (1 - b), a * b, (1 - a) * b]
    if kind == "quad8":
        # Serendipity, on [-1, 1]^2: corners (1 + s u)(1 + t v)(s u + t v - 1) / 4, mid-edge
        # nodes (1 - u^2)(1 + t v) / 2 and (1 + s u)(1 - v^2) / 2.
        u, v = 2 * xi[0] - 1, 2 * xi[1] - 1
        corners = [(-1, -1), (1, -1), (1, 1), (-1, 1)]
        values = [(1 + s * u) * (1 + t * v) * (s * u + t * v - 1) / 4 for s, t in corners]
        return values + [
            (1 - u * u) * (1 - v) / 2,
            (1 + u) * (1 - v * v) / 2,
            (1 - u * u) * (1 + v) / 2,
            (1 - u) * (1 - v * v) / 2,
        ]
    if kind in ("tet4", "tet10"):
        a, b, c = xi
        lam = [1 - a - b - c, a, b, c]
        if kind == "tet4":
            return lam
        corners = [v * (2 * v - 1) for v in lam]
        return corners + [4 * lam[p] * lam[q] for p, q in TET10_EDGES]
    if kind == "wedge6":
        a, b, c = xi
        lam = [1 - a - b, a, b]
        return [v * (1 - c) for v in lam] + [v * c for v in lam]
    if kind == "wedge15":
        # Serendipity, on the triangle times [-1, 1] (see `fem/solid/wedge.rs`).
        a, b, c = xi
        lam, w = [1 - a - b, a, b], 2 * c - 1
        corners = [
            v * (2 * v - 1) * (1 + s * w) / 2 - v * (1 - w * w) / 2 for s in (-1, 1) for v in lam
        ]
        middles = [
            2 * lam[p % 3] * lam[q % 3] * (1 + (-1 if e < 3 else 1) * w)
            for e, (p, q) in enumerate(WEDGE15_EDGES[:6])
        ]
        return corners + middles + [v * (1 - w * w) for v in lam]
    if kind == "wedge18":
        # Lagrange: the quadratic triangle's functions times the quadratic line's in w
        # (see `fem/solid/wedge.rs`): levels -1, +1 and 0 of the nodes.
        a, b, c = xi
        lam, w = [1 - a - b, a, b], 2 * c - 1
        triangle = [v * (2 * v - 1) for v in lam]
        triangle += [4 * lam[p] * lam[(p + 1) % 3] for p in range(3)]
        line = {-1: w * (w - 1) / 2, 1: w * (w + 1) / 2, 0: 1 - w * w}
        corners = [t * line[s] for s in (-1, 1) for t in triangle[:3]]
        middles = [t * line[s] for s in (-1, 1) for t in triangle[3:]]
        return corners + middles + [t * line[0] for t in triangle]
    if kind in ("pyramid13", "pyramid14"):
        # Bedrosian's quadratic pyramid in the collapsed coordinates a = xi / (1 - zeta),
        # b = eta / (1 - zeta), s = 1 - zeta (see `fem/solid/pyramid.rs`), and the base's
        # bubble for pyramid14.
        x, y, z = xi
        s = 1 - z
        a, b = x / s, y / s
        base = [(-1, -1), (1, -1), (1, 1), (-1, 1)]
        bubble = s * s * (1 - a * a) * (1 - b * b)
        take = 0.25 * bubble if kind == "pyramid14" else 0
        values = [
            s * (1 + p * a) * (1 + q * b) * (s * (p * a + q * b) - 1) / 4 + take for p, q in base
        ]
        values.append(z * (2 * z - 1))
        for k, (p, q) in enumerate(base):
            r, t = base[(k + 1) % 4]
            if p == r:  # the edge at xi = p: along eta
                values.append(s * s * (1 - b * b) * (1 + p * a) / 2 - 2 * take)
            else:
                values.append(s * s * (1 - a * a) * (1 + q * b) / 2 - 2 * take)
        values += [z * s * (1 + p * a) * (1 + q * b) for p, q in base]
        return values + ([bubble] if kind == "pyramid14" else [])
    if kind in ("quad9", "hex27"):
        # Lagrange, on [-1, 1]^d: products of the quadratic polynomials l(s) that are 1 at
        # the node's coordinate c and 0 at the other two (s(s + c)/2, or 1 - s^2 for c = 0).
        u = [2 * x - 1 for x in xi]
        values = []
        for c in _LAGRANGE_NODES[kind]:
            value = 1
            for k, ck in enumerate(c):
                value = value * (1 - u[k] * u[k] if ck == 0 else u[k] * (u[k] + ck) / 2)
            values.append(value)
        return values
    if kind == "pyramid5":
        # Bedrosian's rational functions on the pyramid (base [-1, 1]^2 at zeta = 0, apex
        # (0, 0, 1); see `fem/solid/pyramid.rs`): the points of `_rule` are never at the apex.
        a, b, c = xi
        ratio = a * b * c / (1 - c)
        base = [(-1, -1), (1, -1), (1, 1), (-1, 1)]
        return [((1 + s * a) * (1 + t * b) - c + s * t * ratio) / 4 for s, t in base] + [c]
    if kind == "hex8":
        a, b, c = xi
        return [
            (a if i else 1 - a) * (b if j else 1 - b) * (c if k else 1 - c)
            for i, j, k in HEX8_CORNERS
        ]
    if kind == "hex20":
        # Serendipity, on [-1, 1]^3 (see the element kernel `fem/solid/hexahedron.rs`).
        u = [2 * x - 1 for x in xi]
        signs = [[2 * s - 1 for s in corner] for corner in HEX8_CORNERS]
        values = [
            (1 + s[0] * u[0]) * (1 + s[1] * u[1]) * (1 + s[2] * u[2])
            * (s[0] * u[0] + s[1] * u[1] + s[2] * u[2] - 2) / 8
            for s in signs
        ]  # fmt: skip
        for p, q in HEX20_EDGES:
            m = next(k for k in range(3) if signs[p][k] != signs[q][k])
            factor = (1 - u[m] * u[m]) / 4
            for k in range(3):
                if k != m:
                    factor = factor * (1 + signs[p][k] * u[k])
            values.append(factor)
        return values
    raise InvalidParameterError(f"no shape functions for {kind!r}")  # pragma: no cover


def _rule(kind: str) -> tuple[Array, Array]:
    """Quadrature points (dim, n) and weights (n,) on the reference cell of `kind`: 3-point
    Gauss-Legendre products (4-point on quad8, quad9, hex20, hex27, wedge15, wedge18 and the
    pyramids), collapsed (Duffy) onto simplices and the pyramid; exact for the integrals of
    the shape functions times the Jacobian of every straight-sided or flat cell here (degree 2
    on simplices, 3 per direction on quadrilaterals and hexahedra, 4 on the quadratic quad8,
    quad9, hex20, hex27, wedge15 and wedge18; on the pyramids, polynomials of degree 7 in the
    collapsed a, b and in zeta, (1 - zeta)^2 included, the moments too)."""
    # (4 points on the serendipity cells: those of their mass points, so that interface
    # weights and the mass matrix agree on curved elements too)
    g, w = np.polynomial.legendre.leggauss(
        3
        if kind in ("line2", "line3", "tri3", "tri6", "quad4", "tet4", "tet10", "hex8", "wedge6")
        else 4
    )
    g, w = 0.5 * (g + 1.0), 0.5 * w
    dim = {"line": 1, "tri": 2, "quad": 2, "tet": 3, "hex": 3, "wedge": 3, "pyramid": 3}[
        kind.rstrip("0123456789")
    ]
    grids = np.meshgrid(*([g] * dim), indexing="ij")
    weights = np.prod(np.meshgrid(*([w] * dim), indexing="ij"), axis=0).ravel()
    u = [a.ravel() for a in grids]
    if kind.startswith(("tri", "wedge")):
        # (a wedge: the collapsed triangle times the line)
        points = [u[0], u[1] * (1 - u[0])] + u[2:]
        weights = weights * (1 - u[0])
    elif kind.startswith("pyramid"):
        # (the cube [-1, 1]^2 x [0, 1] collapsed onto the pyramid: xi = (1 - zeta) a, ...)
        shrink = 1 - u[2]
        points = [(2 * u[0] - 1) * shrink, (2 * u[1] - 1) * shrink, u[2]]
        weights = weights * 4 * shrink**2
    elif kind.startswith("tet"):
        points = [u[0], u[1] * (1 - u[0]), u[2] * (1 - u[0]) * (1 - u[1])]
        weights = weights * (1 - u[0]) ** 2 * (1 - u[1])
    else:
        points = u
    return np.array(points), weights


def _integrals(kind: str, cells: NDArray[np.int64], nodes: Array) -> tuple[Array, Array]:
    """Integrals over each isoparametric cell through `nodes` of the shape functions times
    its length, area or volume element (n_cells, nodes per cell), and the sum over the cells
    of the integrals of [1, x, x x^T] (the measure, first and second moments, packed into a
    (4, 4) matrix: integral of [1, x] [1, x]^T)."""
    points, weights = _rule(kind)
    dim = points.shape[0]
    values = np.array(_shape(kind, tuple(points)), dtype=float)  # (npc, nq)
    step = 1e-30
    derivatives = []
    for k in range(dim):
        shifted = [points[j] + (1j * step if j == k else 0.0) for j in range(dim)]
        derivatives.append(np.array(_shape(kind, tuple(shifted))).imag / step)
    # Per direction c, the coordinates of the cells' nodes (ne, npc): the sums over a cell's
    # nodes are products with the (npc, nq) tables.
    x = [nodes[:, c][cells] for c in range(3)]
    tangents = [[xc @ d for xc in x] for d in derivatives]  # [k][c] (ne, nq)
    if dim == 1:
        (t,) = tangents
        measure = np.sqrt(t[0] ** 2 + t[1] ** 2 + t[2] ** 2)
    else:
        a, b = tangents[0], tangents[1]
        normal = [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
        if dim == 2:
            measure = np.sqrt(normal[0] ** 2 + normal[1] ** 2 + normal[2] ** 2)
        else:
            t = tangents[2]
            measure = np.abs(normal[0] * t[0] + normal[1] * t[1] + normal[2] * t[2])
    weighted = measure * weights  # (ne, nq)
    at_points = [xc @ values for xc in x]  # (ne, nq) per direction
    moments = np.empty((4, 4))
    moments[0, 0] = weighted.sum()
    for c in range(3):
        moments[0, 1 + c] = moments[1 + c, 0] = np.vdot(at_points[c], weighted)
        for e in range(c, 3):
            moments[1 + c, 1 + e] = moments[1 + e, 1 + c] = np.vdot(
                at_points[c] * at_points[e], weighted
            )
    return weighted @ values.T, moments


# Cells of a node set ---------------------------------------------------------------------------


def _cells(
    elements: Mapping[str, ArrayLike],
    inside: NDArray[np.bool_],
    table: Mapping[str, tuple[tuple[str, tuple[tuple[int, ...], ...]], ...]],
) -> dict[str, NDArray[np.int64]]:
    """The distinct sub-cells (facets or edges, `_FACET_GROUPS` or `_EDGE_GROUPS`) of the
    elements whose nodes all lie inside the set, by kind (a facet shared by two elements
    counts once)."""
    found: dict[str, list[NDArray[np.int64]]] = {}
    for element, conn in elements.items():
        if cell_of(element) not in table or len(conn) == 0:
            continue
        conn = np.asarray(conn, dtype=np.int64)
        for kind, local in table[cell_of(element)]:
            for sub in local:
                cells = conn[:, sub]
                cells = cells[inside[cells].all(axis=1)]
                if len(cells):
                    found.setdefault(kind, []).append(cells)
    unique = {}
    for kind, parts in found.items():
        cells = np.vstack(parts)
        _, first = np.unique(np.sort(cells, axis=1), axis=0, return_index=True)
        unique[kind] = cells[np.sort(first)]
    return unique


def _volumes(
    elements: Mapping[str, ArrayLike], inside: NDArray[np.bool_]
) -> dict[str, NDArray[np.int64]]:
    """The solid elements whose nodes all lie inside the set, by cell type."""
    out: dict[str, NDArray[np.int64]] = {}
    for element, conn in elements.items():
        cell = cell_of(element)
        if cell not in _SOLIDS or len(conn) == 0:
            continue
        conn = np.asarray(conn, dtype=np.int64)
        cells = conn[inside[conn].all(axis=1)]
        if len(cells):
            out[cell] = np.vstack([out[cell], cells]) if cell in out else cells
    return out


def _covered(cells: Mapping[str, NDArray[np.int64]], members: NDArray[np.int64]) -> bool:
    if not cells:
        return False
    used = np.unique(np.concatenate([c.ravel() for c in cells.values()]))
    return bool(np.isin(members, used).all())


def interface_weights(
    nodes: ArrayLike,
    elements: Mapping[str, ArrayLike],
    members: ArrayLike,
    weights: str | ArrayLike = "auto",
    *,
    name: str = "node set",
) -> tuple[Array, str]:
    """The weights (one per member node, in their order) and the weighting used ("area",
    "length", "volume", "uniform" or "given"); see the module doc. Raises
    `InvalidParameterError` for unknown weightings and bad arrays, `InvalidModelError` when
    the set has no facets, edges or elements for the weighting asked for, naming the set."""
    raw, weighting, _ = _weights(nodes, elements, members, weights, name)
    return raw, weighting


def _weights(
    nodes: ArrayLike,
    elements: Mapping[str, ArrayLike],
    members: ArrayLike,
    weights: str | ArrayLike,
    name: str,
) -> tuple[Array, str, Array | None]:
    """`interface_weights`, and the (4, 4) moments of the cells weighted (None without
    cells: uniform or given weights)."""
    nodes = np.asarray(nodes, dtype=float)
    members = np.asarray(members, dtype=np.int64)
    if not isinstance(weights, str):
        given = np.asarray(weights, dtype=float).ravel()
        if given.shape != members.shape:
            raise InvalidParameterError(
                f"{name}: weights must be {len(members)} finite values (one per node), "
                f"got shape {np.shape(weights)}",
                item=name,
            )
        bad = np.flatnonzero(~np.isfinite(given))
        if len(bad):
            raise InvalidParameterError(
                f"{name}: weights must be finite, got {given[bad[0]]} for its node "
                f"{int(members[bad[0]])} (entry {int(bad[0])})",
                item=name,
            )
        return given, "given", None
    if weights not in WEIGHTINGS:
        raise InvalidParameterError(
            f"{name}: weights must be an array or one of {WEIGHTINGS}, got {weights!r}", item=name
        )
    if weights == "uniform" or (weights == "auto" and not elements):
        return np.ones(len(members)), "uniform", None
    inside = np.zeros(len(nodes), dtype=bool)
    inside[members] = True
    if weights == "auto":
        volumes = _volumes(elements, inside)
        if _covered(volumes, members):
            weights = "volume"
        elif _cells(elements, inside, _FACET_GROUPS):
            weights = "area"
        elif _cells(elements, inside, _EDGE_GROUPS):
            weights = "length"
        else:
            raise InvalidModelError(
                f"{name}: its nodes form no face, edge or element of the mesh, so it has no "
                "area, length or volume to weight them by; give weights='uniform' or one "
                "weight per node",
                item=name,
            )
    if weights == "volume":
        cells = _volumes(elements, inside)
    else:
        cells = _cells(elements, inside, _FACET_GROUPS if weights == "area" else _EDGE_GROUPS)
    if not cells:
        what = {"area": "element faces", "length": "element edges", "volume": "elements"}
        raise InvalidModelError(
            f"{name}: no {what[weights]} have all their nodes in the set, so it has no "
            f"{weights} to weight its nodes by",
            item=name,
        )
    position = np.full(len(nodes), -1, dtype=np.int64)
    position[members] = np.arange(len(members))
    out = np.zeros(len(members))
    moments = np.zeros((4, 4))
    for kind, conn in cells.items():
        # In chunks: the quadrature arrays of 600,000 tetrahedra would take gigabytes.
        for start in range(0, len(conn), _CHUNK):
            part = conn[start : start + _CHUNK]
            integrals, cell_moments = _integrals(kind, part, nodes)
            np.add.at(out, position[part], integrals)
            moments += cell_moments
    # Weights that vanish analytically (corners of quadratic triangles) to exact zeros.
    out[np.abs(out) <= 1e-13 * np.abs(out).max(initial=0.0)] = 0.0
    return out, weights, moments


# The interface ---------------------------------------------------------------------------------


def _principal_axes(spread: Array, outward: Array | None, name: str) -> NDArray[np.float64]:
    """Axes (columns) of a spread matrix (second moment about the centroid): z the least,
    x the largest."""
    values, vectors = np.linalg.eigh(spread)
    z = vectors[:, 0]
    if outward is not None and abs(z @ outward) > 1e-12 * np.linalg.norm(outward):
        z = z if z @ outward > 0 else -z
    else:
        z = z if z[np.argmax(np.abs(z))] > 0 else -z
    if abs(values[2] - values[1]) <= 1e-6 * max(values[2], 1e-300):
        axis = np.eye(3)[int(np.argmin(np.abs(z)))]
        x = axis - (axis @ z) * z
    else:
        x = vectors[:, 2] - (vectors[:, 2] @ z) * z
        x = x if x[np.argmax(np.abs(x))] > 0 else -x
    norm = np.linalg.norm(x)
    if not norm > 0:  # pragma: no cover - eigenvectors are orthogonal
        raise InvalidModelError(f"{name}: no principal axes", item=name)
    x = x / norm
    return np.column_stack([x, np.cross(z, x), z])


@dataclass(frozen=True)
class Interface:
    """A weighted node set of a deformable body (see the module doc).

    Attributes:
        name: the set's name (for messages).
        members: node indices (into the body's nodes), (n,).
        weights: the weights, normalized to sum 1, (n,).
        weighting: "area", "length", "volume", "uniform" or "given".
        measure: the sum of the raw weights (the set's area, length or volume; the node
            count for "uniform"; the sum of given weights).
        centroid: the weighted centroid in the body frame, (3,).
        arms: x_p - centroid, (n, 3).
        principal_axes: the axes of ``orientation="principal"`` (columns), (3, 3).
        rotation_inverse: H^-1 with H = sum w_p (|d_p|^2 I - d_p d_p^T), (3, 3); its
            pseudo-inverse where H is singular.
        free_axes: an orthonormal basis of the null space of a singular H (columns; (3, 0)
            when the nodes define a rotation): the axes about which theta comes from the
            nodes' rotational coordinates.
    """

    name: str
    members: NDArray[np.int64]
    weights: Array
    weighting: str
    measure: float
    centroid: Array
    arms: Array
    principal_axes: Array
    rotation_inverse: Array
    free_axes: Array = field(default_factory=lambda: np.zeros((3, 0)))

    def average_rows(self, dofs_per_node: int, dof_count: int) -> sp.csr_matrix:
        """The six rows G (6, dof_count) with G u = (u_c, theta) of nodal displacements u
        (node-major, `dofs_per_node` per node): theta from the translations, and along the
        `free_axes` (a line of nodes, or one node) from the nodes' rotational coordinates (the
        three after the translations), which a body of three per node does not have."""
        import scipy.sparse as sp

        d = dofs_per_node
        n = len(self.members)
        rows = [np.repeat(np.arange(3), n)]
        cols = [np.concatenate([self.members * d + c for c in range(3)])]
        vals = [np.tile(self.weights, 3)]
        # theta_i = sum_p w_p (H^-1 [d_p x])_ic u_pc
        cross = np.zeros((n, 3, 3))
        a = self.arms
        cross[:, 0, 1], cross[:, 0, 2] = -a[:, 2], a[:, 1]
        cross[:, 1, 0], cross[:, 1, 2] = a[:, 2], -a[:, 0]
        cross[:, 2, 0], cross[:, 2, 1] = -a[:, 1], a[:, 0]
        blocks = self.weights[:, None, None] * np.einsum(
            "ij,pjc->pic", self.rotation_inverse, cross
        )
        for i in range(3):
            rows.append(np.full(3 * n, 3 + i))
            cols.append((self.members[:, None] * d + np.arange(3)).ravel())
            vals.append(blocks[:, i, :].ravel())
        if self.free_axes.shape[1] and d >= 6:
            # + E E^T sum_p w_p phi_p along the free axes E.
            projector = self.free_axes @ self.free_axes.T
            turns = self.weights[:, None, None] * projector[None, :, :]
            for i in range(3):
                rows.append(np.full(3 * n, 3 + i))
                cols.append((self.members[:, None] * d + 3 + np.arange(3)).ravel())
                vals.append(turns[:, i, :].ravel())
        return sp.csr_matrix(
            (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
            shape=(6, dof_count),
        )

    def average(self, translations: Array) -> tuple[Array, Array]:
        """(u_c, theta) of the nodes' displacements (n, 3) or of displacement columns
        (n, 3, k): the weighted mean and the weighted least-squares small rotation about the
        centroid."""
        t = np.asarray(translations, dtype=float)
        columns = t.reshape(len(self.members), 3, -1)
        mean = np.einsum("p,pck->ck", self.weights, columns)
        arms = np.broadcast_to(self.arms[:, :, None], columns.shape)
        moment = np.einsum("p,pck->ck", self.weights, np.cross(arms, columns, axis=1))
        rotation = self.rotation_inverse @ moment
        shape = t.shape[1:]
        return mean.reshape(shape), rotation.reshape(shape)

    def rigid_map(self, dofs_per_node: int) -> Array:
        """The motion of the nodes (n * dofs_per_node, 6) when they follow (u_c, theta)
        rigidly (RBE2): u_p = u_c + theta x d_p, and theta_p = theta for nodes with rotational
        coordinates."""
        d = dofs_per_node
        n = len(self.members)
        t = np.zeros((n * d, 6))
        for c in range(3):
            t[c::d, c] = 1.0
        for k in range(3):
            w = np.zeros(3)
            w[k] = 1.0
            u = np.cross(w, self.arms)
            for c in range(3):
                t[c::d, 3 + k] = u[:, c]
            if d == 6:
                t[3 + k :: d, 3 + k] = 1.0
        return t

    def orientation(self, orientation: str | ArrayLike | None) -> Array | None:
        """The marker axes for `orientation` (None: the body axes, "principal", or a 3 x 3
        matrix, returned as given)."""
        if isinstance(orientation, str):
            if orientation != "principal":
                raise InvalidParameterError(
                    f"{self.name}: orientation must be 'principal', a 3 x 3 matrix or None, "
                    f"got {orientation!r}",
                    item=self.name,
                )
            return self.principal_axes
        return None if orientation is None else np.asarray(orientation, dtype=float)


def make_interface(
    nodes: ArrayLike,
    elements: Mapping[str, ArrayLike],
    members: ArrayLike,
    weights: str | ArrayLike = "auto",
    *,
    name: str = "node set",
    require_rotation: bool = True,
    nodal_rotations: bool = False,
) -> Interface:
    """The `Interface` of the node indices `members` of a body with `nodes` (n, 3) and
    `elements` (type -> connectivity). Raises `InvalidModelError` naming the set when it is
    empty, repeats a node, has zero weight in sum, or lies on one line (its rotation about
    that line is undefined; with `require_rotation` False such a set is accepted, its
    rotation about the line left out: a rigid interface of beam nodes with rotational
    coordinates, or of two nodes). With `nodal_rotations` (a body whose nodes have rotational
    coordinates) a line of nodes or a single node is an interface whose rotation about the
    line comes from the nodes' rotations (`Interface.free_axes`)."""
    nodes = np.asarray(nodes, dtype=float)
    members = np.asarray(members, dtype=np.int64).ravel()
    if members.size == 0:
        raise InvalidModelError(f"{name}: the node set is empty", item=name)
    if members.min() < 0 or members.max() >= len(nodes):
        raise InvalidModelError(
            f"{name}: node index {members.max() if members.max() >= len(nodes) else members.min()}"
            f" outside a body of {len(nodes)} nodes",
            item=name,
        )
    if len(np.unique(members)) != len(members):
        raise InvalidModelError(f"{name}: the node set repeats a node", item=name)
    try:
        raw, weighting, moments = _weights(nodes, elements, members, weights, name)
    except InvalidModelError:
        if (require_rotation and not nodal_rotations) or not (
            isinstance(weights, str) and weights == "auto"
        ):
            raise
        # A rigid interface of a node or two (beam ends): nothing to weight by.
        raw, weighting, moments = np.ones(len(members)), "uniform", None
    measure = float(raw.sum())
    scale = float(np.abs(raw).max(initial=0.0))
    if not measure > 1e-12 * scale or not scale > 0:
        raise InvalidModelError(
            f"{name}: the weights of its nodes sum to {measure:g}; an interface needs a "
            "positive total weight",
            item=name,
        )
    w = raw / measure
    centroid = w @ nodes[members]
    low, high = nodes[members].min(axis=0), nodes[members].max(axis=0)
    outside = float(
        np.linalg.norm(np.maximum(low - centroid, 0.0) + np.maximum(centroid - high, 0.0))
    )
    if outside > OUTSIDE_LIMIT * float(np.linalg.norm(high - low)):
        # Weights of both signs that nearly cancel (consistent weights of quadratic faces have
        # negative corners, but their centroid is the face's): 1, -0.999, 0 put a beam's
        # marker 249 m off its 1 m length.
        raise InvalidModelError(
            f"{name}: its weighted centroid {np.round(centroid, 6).tolist()} lies "
            f"{outside:.3g} outside the box of its nodes (size {np.linalg.norm(high - low):.3g}):"
            f" the weights nearly cancel (sum {float(raw.sum()):.3g}, sum of magnitudes "
            f"{float(np.abs(raw).sum()):.3g})",
            item=name,
        )
    arms = nodes[members] - centroid
    h = np.einsum("p,pi,pi->", w, arms, arms) * np.eye(3) - np.einsum("p,pi,pj->ij", w, arms, arms)
    values, vectors = np.linalg.eigh(0.5 * (h + h.T))
    size = float(np.einsum("p,pi,pi->", np.abs(w), arms, arms))
    # The null space of H: the direction of a line of nodes, every direction for one node.
    free = values <= 1e-9 * max(size, 1e-300)
    defined = len(members) >= 3 and not free[0]
    if require_rotation and not nodal_rotations and values[0] < -1e-9 * max(size, 1e-300):
        # (Weights of both signs; the consistent weights of quadratic faces keep H definite.)
        raise InvalidModelError(
            f"{name}: its weights ({int((raw < 0).sum())} of {len(raw)} negative, down to "
            f"{float(raw.min()):.3g}) make the weighted second moment of its nodes "
            f"indefinite (eigenvalue {values[0]:.3g} about the axis "
            f"{np.round(vectors[:, 0], 6).tolist()}), so no rotation fits its nodes' motion; "
            "give weights that are positive, or those of the face's shape functions",
            item=name,
        )
    if require_rotation and not defined and not nodal_rotations:
        raise InvalidModelError(
            f"{name}: its {len(members)} weighted nodes lie on one line (or are fewer than "
            "three), so their rotation about it is undefined; an interface needs at least "
            "three non-collinear nodes of non-zero weight",
            item=name,
        )
    outward = None
    if weighting == "area":
        inside = np.zeros(len(nodes), dtype=bool)
        inside[members] = True
        owners = [
            conn[
                np.any(
                    [
                        inside[conn[:, list(f)]].all(axis=1)
                        for _, faces in _FACET_GROUPS[kind]
                        for f in faces
                    ],
                    axis=0,
                )
            ]
            for kind, conn in (
                (cell_of(k), np.asarray(c, dtype=np.int64)) for k, c in elements.items()
            )
            if kind in _FACET_GROUPS and len(conn)
        ]
        owners = [c for c in owners if len(c)]
        if owners:
            inner = np.vstack([nodes[c].mean(axis=1) for c in owners]).mean(axis=0)
            outward = centroid - inner
    if outward is None:
        outward = centroid - nodes.mean(axis=0)
    if moments is None:
        spread = np.einsum("p,pi,pj->ij", np.abs(w), arms, arms)
    else:
        # The cells' own second moment about the centroid (exact for the facets, not lumped
        # at the nodes: a rectangle's axes are its edges whatever its mesh).
        first = moments[0, 1:] / moments[0, 0]
        spread = moments[1:, 1:] / moments[0, 0] - np.outer(first, first)
    axes = _principal_axes(spread, outward, name)
    return Interface(
        name=name,
        members=members,
        weights=w,
        weighting=weighting,
        measure=measure,
        centroid=centroid,
        arms=arms,
        principal_axes=axes,
        rotation_inverse=np.linalg.inv(h) if defined else np.linalg.pinv(h, rcond=1e-9),
        free_axes=np.zeros((3, 0)) if defined else vectors[:, free],
    )


def body_interface(
    body: Any,
    nodes: str | Sequence[int] | ArrayLike,
    weights: str | ArrayLike = "auto",
    *,
    name: str | None = None,
    ids: bool = True,
) -> Interface:
    """The `Interface` of a node set of a `FlexibleBodyData`: a set name of the body, or node
    ids (`ids=True`, as in the mesh) or indices. With weights "auto" on a set that is an
    interface of the body's Craig-Bampton modes, the weights of those modes are used."""
    from .._checks import value_text
    from ..errors import UnknownItemError

    if isinstance(nodes, str):
        if nodes not in body.node_sets:
            raise UnknownItemError(
                f"{name or 'interface'}: the body has no node set {value_text(nodes)}; known: "
                f"{sorted(body.node_sets)}",
                item=name or value_text(nodes),
            )
        label = name or f"node set '{nodes}'"
        members = np.asarray(body.node_sets[nodes], dtype=np.int64)
    else:
        label = name or "node set"
        values = np.asarray(nodes, dtype=np.int64).ravel()
        if ids:
            order = np.argsort(body.node_ids)
            found = np.searchsorted(body.node_ids, values, sorter=order)
            found = np.clip(found, 0, len(order) - 1)
            members = order[found]
            bad = body.node_ids[members] != values
            if bad.any():
                raise UnknownItemError(
                    f"{label}: the body has no node with id {int(values[np.argmax(bad)])}",
                    item=label,
                )
        else:
            members = values
    if isinstance(weights, str) and weights == "auto":
        stored = _stored_weights(body, members)
        if stored is not None:
            weights = stored
    return make_interface(
        body.nodes,
        body.elements,
        members,
        weights,
        name=label,
        nodal_rotations=body.dofs_per_node >= 6,
    )


def _stored_weights(body: Any, members: NDArray[np.int64]) -> Array | None:
    """The weights of the Craig-Bampton interface of the body with exactly these members, in
    the order of `members`."""
    sets = body.reference.interfaces or []
    stored = body.reference.interface_weights or []
    for s, w in zip(sets, stored, strict=False):
        s = np.asarray(s, dtype=np.int64)
        if len(s) == len(members) and np.array_equal(np.sort(s), np.sort(members)):
            order = np.argsort(s)
            return np.asarray(w, dtype=float)[order[np.searchsorted(s[order], members)]]
    return None
