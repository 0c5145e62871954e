"""Meshes and matrices from other codes.

* :func:`read_mesh` reads Gmsh ``.msh``, Abaqus ``.inp`` and VTK ``.vtu`` / ``.vtk`` meshes
  through meshio into a :class:`Mesh`, and :func:`validate_mesh` checks one.
* :func:`read_abaqus_matrix` reads a stiffness or mass matrix written by Abaqus
  ``*MATRIX GENERATE`` / ``*MATRIX OUTPUT``.
* :func:`matrices_from_arrays` checks stiffness and mass matrices given as arrays.

Node order inside an element (0-based; that of the element kernels, `crates/flexmbd-core/src/fem`)
-----------------------------------------------------------------------------------------------
* ``beam2``: the two end nodes.
* ``tet4``: vertices 0, 1, 2, 3; the volume is positive when vertex 3 is on the side of
  (x1 - x0) x (x2 - x0) (VTK, Gmsh and Abaqus C3D4 alike). Nodes are never reordered: an
  inverted element stays inverted, for the element kernels to report.
* ``tet10``: vertices 0..3, then the mid-edge nodes of edges (0,1), (1,2), (0,2), (0,3),
  (2,3), (1,3): the order of Gmsh's ``.msh`` format. VTK (``vtkQuadraticTetra``), Abaqus C3D10
  and meshio list the last two the other way round ((1,3), then (2,3)); meshio converts Gmsh
  cells to its order on reading (``_gmsh_to_meshio_order`` in ``meshio/gmsh/common.py``), and
  :func:`read_mesh` swaps nodes 8 and 9 of every meshio "tetra10" cell back
  (``TET10_FROM_MESHIO``).
* ``hex8``: bottom face 0, 1, 2, 3, then top face 4, 5, 6, 7 with node 4 above node 0, both
  faces counter-clockwise seen from the top (the same in VTK, Gmsh and Abaqus C3D8).
  ``hex8i`` (incompatible modes, Abaqus C3D8I): the same.
* ``wedge6``: the triangle 0, 1, 2 counter-clockwise seen from the other one, then 3, 4, 5
  above them: Gmsh's prism, Abaqus C3D6, meshio's wedge, and VTK's wedge since VTK 9.7.
* ``hex20``, ``hex20r``: the corners of ``hex8``, then the mid-edge nodes 8..19 on the edges
  (0,1), (1,2), (2,3), (3,0), (4,5), (5,6), (6,7), (7,4), (0,4), (1,5), (2,6), (3,7): the
  order of VTK's quadratic hexahedron, Abaqus C3D20 and meshio (which converts Gmsh's own
  order on reading).
* ``hex27``: the nodes of ``hex20``, then the centres of the faces (0,3,7,4), (1,2,6,5),
  (0,1,5,4), (3,2,6,7), (0,1,2,3), (4,5,6,7) and the element's centre: VTK's triquadratic
  hexahedron and meshio's hexahedron27 (which converts Gmsh's order on reading).
* ``wedge15``: the corners of ``wedge6``, then the mid-edge nodes 6..14 on the edges (0,1),
  (1,2), (2,0), (3,4), (4,5), (5,3), (0,3), (1,4), (2,5): Abaqus C3D15, meshio (which
  converts Gmsh's prism15 on reading) and VTK's quadratic wedge.
* ``wedge18``: the nodes of ``wedge15``, then the centres of the quadrilateral faces
  (0,1,4,3), (1,2,5,4), (2,0,3,5): VTK's biquadratic-quadratic wedge. Gmsh's 18-node prism
  (which meshio passes on in Gmsh's order: the mid-edge nodes on (0,1), (0,2), (0,3), (1,2),
  (1,4), (2,5), (3,4), (3,5), (4,5), the face centres of (0,1,4,3), (0,2,5,3), (1,2,5,4)) is
  converted on reading (``WEDGE18_FROM_GMSH``).
* Wedges in VTK files come in two orientations. VTK's wedges (linear, quadratic and
  biquadratic-quadratic) have node k at the parametric coordinates (0,0,0), (1,0,0), (0,1,0),
  (0,0,1), ... of the orders above (``GetParametricCoords``; the same mid-edge nodes and face
  centres), and VTK 9.7.2 calls a wedge with its nodes there valid (``vtkCellValidator``) and
  of positive volume (``vtkCellSizeFilter``: +0.5 for that unit prism), as VTK's
  ``vtkCellTypeSource`` makes them. Before VTK 9.7 (9.2.6 tested), its documentation, its
  cells' face lists, ``vtkCellTypeSource`` and ``vtkCellSizeFilter`` (linear and 15-node
  wedges: -0.5 for that prism, +0.5 mirrored) listed each triangle the other way round (not
  its ``vtkCellValidator``, for the 15- and 18-node wedges), as meshio does for the linear
  wedge (it mirrors it on reading and writing); VTK 9.7 changed them
  (``fix-wedge-point-ordering`` in its release notes) without changing the file formats. So
  :func:`read_mesh` takes each wedge of a ``.vtu`` or ``.vtk`` file in the orientation in
  which it is not inverted (:func:`orient_wedges`, ``WEDGE_MIRRORS``), and the VTK output
  (:func:`flexmbd.animation.write_vtu_series`) writes VTK 9.7's order. In other formats a
  wedge listed the other way round is inverted.
* ``pyramid5``: the base 0, 1, 2, 3 counter-clockwise seen from the apex 4: Gmsh's, VTK's and
  meshio's pyramid, Nastran's CPYRAM of 5 grids.
* ``pyramid13``: the corners of ``pyramid5``, then the mid-edge nodes 5..12 on the edges
  (0,1), (1,2), (2,3), (3,0), (0,4), (1,4), (2,4), (3,4): VTK's quadratic pyramid and meshio's
  pyramid13 (which converts Gmsh's order on reading).
* ``pyramid14``: the nodes of ``pyramid13``, then the base's centre. Gmsh's 14-node pyramid
  (which meshio passes on in Gmsh's order: the mid-edge nodes on (0,1), (0,3), (0,4), (1,2),
  (1,4), (2,3), (2,4), (3,4)) is converted on reading (``PYRAMID14_FROM_GMSH``).
* ``quad4``, ``tri3`` (flat shells): the corners counter-clockwise about the element normal
  (the same in VTK, Gmsh and Abaqus S4/S3); the top surface of the shell is on the side of
  the normal.
"""

from __future__ import annotations

import functools
import io
import math
import os
import re
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ..errors import (
    InvalidModelError,
    InvalidParameterError,
    MeshQualityWarning,
    MissingFileError,
    UnknownItemError,
)
from .body import ELEMENT_NODES

if TYPE_CHECKING:
    import meshio
    import scipy.sparse as sp

#: meshio cell types read as flexmbd elements.
MESHIO_ELEMENT_TYPES = {
    "line": "beam2",
    "tetra": "tet4",
    "tetra4": "tet4",
    "tetra10": "tet10",
    "hexahedron": "hex8",
    "hexahedron20": "hex20",
    "hexahedron27": "hex27",
    "wedge": "wedge6",
    "wedge15": "wedge15",
    "wedge18": "wedge18",
    "pyramid": "pyramid5",
    "pyramid13": "pyramid13",
    "pyramid14": "pyramid14",
}

#: meshio cell types of surfaces read as shell elements ("quad4", "tri3") in files without
#: volume cells (Gmsh, VTK) or from Abaqus shell element types (`ABAQUS_SHELL_TYPES`).
MESHIO_SHELL_TYPES = {"quad": "quad4", "triangle": "tri3"}

#: Abaqus element types read as flat shells (S4R, S3R: reduced integration in Abaqus; here
#: the MITC4 and DKT elements of the preprocessor).
ABAQUS_SHELL_TYPES = {
    "S4": "quad4",
    "S4R": "quad4",
    "S4R5": "quad4",
    "S3": "tri3",
    "S3R": "tri3",
    "STRI3": "tri3",
}

#: Abaqus solid element types read as another flexmbd element than their meshio cell's: the
#: hexahedra with incompatible modes and the quadratic ones with reduced integration (the
#: hybrid types without their pressure unknowns, as C3D8H is read as hex8).
ABAQUS_SOLID_TYPES = {
    "C3D8I": "hex8i",
    "C3D8IH": "hex8i",
    "C3D20R": "hex20r",
    "C3D20RH": "hex20r",
}

#: Abaqus solid element types whose formulation flexmbd does not have, read as the element of
#: their cell with a `MeshQualityWarning`: type -> what they are.
ABAQUS_SUBSTITUTED_TYPES = {
    "C3D8R": "reduced integration with hourglass control",
    "C3D8RH": "reduced integration with hourglass control",
}

#: Permutation of a meshio/VTK "tetra10" cell into the flexmbd (Gmsh) node order.
TET10_FROM_MESHIO = np.array([0, 1, 2, 3, 4, 5, 6, 7, 9, 8])

#: Each triangle of a wedge listed the other way round (every permutation its own inverse): the
#: other orientation in which VTK files carry wedges (the module docstring).
WEDGE_MIRRORS: dict[str, NDArray[np.int64]] = {
    "wedge6": np.array([0, 2, 1, 3, 5, 4]),
    "wedge15": np.array([0, 2, 1, 3, 5, 4, 8, 7, 6, 11, 10, 9, 12, 14, 13]),
    "wedge18": np.array([0, 2, 1, 3, 5, 4, 8, 7, 6, 11, 10, 9, 12, 14, 13, 17, 16, 15]),
}

#: ``wedge18[i] = gmsh[WEDGE18_FROM_GMSH[i]]`` for a meshio "wedge18" cell read from a Gmsh
#: file (meshio keeps Gmsh's order of the 18-node prism; its first 15 entries are meshio's own
#: conversion of Gmsh's 15-node prism).
WEDGE18_FROM_GMSH = np.array([0, 1, 2, 3, 4, 5, 6, 9, 7, 12, 14, 13, 8, 10, 11, 15, 17, 16])

#: ``pyramid14[i] = gmsh[PYRAMID14_FROM_GMSH[i]]`` for a meshio "pyramid14" cell read from a
#: Gmsh file (meshio keeps Gmsh's order of the 14-node pyramid; it converts the 13-node one).
PYRAMID14_FROM_GMSH = np.array([0, 1, 2, 3, 4, 5, 8, 10, 6, 7, 9, 11, 12, 13])


def complete_meshio() -> None:
    """Gives meshio the topological dimension of the volume cells its table lacks (meshio 5.3:
    any mesh with such cells failed with a KeyError): "wedge15" (Gmsh prism15, Abaqus C3D15,
    VTK quadratic wedges), "pyramid13" (Gmsh's and VTK's 13-node pyramids), and "hexahedron24",
    which is then refused by name as a cell that is not an element. Idempotent; changes
    nothing else."""
    import meshio._mesh

    for cell in ("wedge15", "pyramid13", "hexahedron24"):
        meshio._mesh.topological_dimension.setdefault(cell, 3)


def orient_wedges(
    nodes: NDArray[np.float64], cells: NDArray[np.int64], kind: str
) -> NDArray[np.int64]:
    """`cells` of `kind` ("wedge6", "wedge15" or "wedge18") with every one listed the other
    way round (its corners' Jacobian determinant at the centre negative) mirrored by
    ``WEDGE_MIRRORS[kind]``: wedges of VTK files, which come in both orientations (the module
    docstring). A mirrored wedge is the same element; a flat or tangled one is left as it is,
    for the element kernels to report."""
    x = nodes[cells[:, :6]]
    along_r = x[:, 1] - x[:, 0] + x[:, 4] - x[:, 3]
    along_s = x[:, 2] - x[:, 0] + x[:, 5] - x[:, 3]
    along_t = x[:, 3:].sum(axis=1) - x[:, :3].sum(axis=1)
    mirrored = np.einsum("ij,ij->i", np.cross(along_r, along_s), along_t) < 0.0
    if not mirrored.any():
        return cells
    cells = cells.copy()
    cells[mirrored] = cells[mirrored][:, WEDGE_MIRRORS[kind]]
    return cells


#: File suffix -> meshio file format.
MESH_FORMATS = {".msh": "gmsh", ".inp": "abaqus", ".vtu": "vtu", ".vtk": "vtk"}

#: Relative distance under which two nodes count as duplicates (times the mesh size).
DUPLICATE_NODE_TOLERANCE = 1e-12

#: Largest magnitude of a node coordinate (in the units of the mesh) that
#: :func:`validate_mesh` accepts: the preprocessor multiplies three lengths (volumes, masses)
#: and the duplicate-node search squares distances, and (2 x 1e100)^3 is still far below the
#: largest float (1.8e308). No real mesh comes near it (the observable universe is 1e27 m).
MAX_NODE_COORDINATE = 1e100

#: Relative asymmetry allowed in :func:`matrices_from_arrays`.
SYMMETRY_TOLERANCE = 1e-10

#: Largest node or element label of an Abaqus input file (labels are positive int64).
ABAQUS_LABEL_MAX = 2**63 - 1

#: Deepest nesting of Abaqus ``*INCLUDE`` files.
ABAQUS_INCLUDE_DEPTH = 16


@dataclass
class Mesh:
    """A finite element mesh in the terms of :class:`~flexmbd.fe.body.FlexibleBodyData`.

    Attributes:
        nodes: node positions, (n_nodes, 3) float64, in the length unit of the source file.
        node_ids: ids of the nodes in the source file, (n_nodes,) int64 (see
            :func:`read_mesh` for where they come from).
        elements: element type ("beam2", "tet4", "tet10", "hex8", "hex8i", "hex20", "hex20r",
            "hex27", "wedge6", "wedge15", "wedge18", "pyramid5", "pyramid13", "pyramid14",
            "quad4", "tri3") ->
            (n_elements, nodes) int64 indices into ``nodes``, node order as in the module
            docstring.
        element_ids: element type -> (n_elements,) int64 ids in the source file.
        node_sets: name -> sorted, unique int64 indices into ``nodes``.
        shell_thickness: the thickness of the shells from an Abaqus ``*SHELL SECTION``, or
            None (`body_from_mesh` takes it when no `shell` is given).
    """

    nodes: NDArray[np.float64]
    node_ids: NDArray[np.int64]
    elements: dict[str, NDArray[np.int64]] = field(default_factory=dict)
    element_ids: dict[str, NDArray[np.int64]] = field(default_factory=dict)
    node_sets: dict[str, NDArray[np.int64]] = field(default_factory=dict)
    shell_thickness: float | None = None

    @property
    def node_count(self) -> int:
        return len(self.nodes)

    @property
    def element_count(self) -> int:
        return sum(len(connectivity) for connectivity in self.elements.values())

    def with_incompatible_modes(self) -> Mesh:
        """A copy whose hexahedra ("hex8", as Gmsh and VTK meshes have them) are hexahedra with
        incompatible modes ("hex8i", which bend on coarse meshes; the same nodes, ids and
        mass); a mesh whose hexahedra are all hex8i already (Abaqus C3D8I) is returned as a
        copy. Raises `InvalidModelError` for a mesh without hexahedra."""
        elements, element_ids = dict(self.elements), dict(self.element_ids)
        if len(elements.get("hex8", ())):
            for table in (elements, element_ids):
                hexes = table.pop("hex8")
                table["hex8i"] = (
                    np.concatenate([table["hex8i"], hexes]) if "hex8i" in table else hexes
                )
        elif not len(elements.get("hex8i", ())):
            raise InvalidModelError(
                "incompatible modes: the mesh has no hexahedra (hex8); its elements: "
                + (", ".join(self.elements) or "none"),
                item="mesh elements",
            )
        return replace(self, elements=elements, element_ids=element_ids)


# ---------------------------------------------------------------------------------------------
# Reading meshes


def read_mesh(path: str | os.PathLike[str]) -> Mesh:
    """Read a Gmsh (``.msh``, formats 2.2 and 4.1), Abaqus (``.inp``) or VTK (``.vtu``,
    ``.vtk``) mesh through meshio. The suffix selects the format.

    Elements: meshio cells "tetra" (and Abaqus' "tetra4"), "tetra10", "hexahedron",
    "hexahedron20", "hexahedron27", "wedge", "wedge15", "wedge18", "pyramid", "pyramid13",
    "pyramid14" and "line" become "tet4", "tet10", "hex8", "hex20", "hex27", "wedge6",
    "wedge15", "wedge18", "pyramid5", "pyramid13", "pyramid14" and "beam2", in the node order
    of the module docstring; Abaqus'
    hexahedra with incompatible modes (C3D8I, C3D8IH) become "hex8i", its quadratic ones with
    reduced integration (C3D20R, C3D20RH) "hex20r", its linear reduced-integration hexahedra
    (C3D8R, C3D8RH) "hex8" with a :class:`~flexmbd.MeshQualityWarning` (flexmbd has no
    hourglass-controlled element).
    Shells: in Gmsh and VTK files without volume cells, "quad" and "triangle" cells become
    the flat shells "quad4" and "tri3" (and "line" cells, then edges of the surfaces, are not
    beams); in Abaqus files the shell types S4, S4R, S4R5, S3, S3R and STRI3 do, and the
    thickness of a ``*SHELL SECTION`` (one thickness for the whole mesh) becomes
    ``shell_thickness``. Cells of lower dimension than the mesh's highest (vertices, faces
    of volume meshes, Abaqus membranes on a solid) are not elements, but their nodes go into
    the node sets of the named groups they belong to: a Gmsh physical surface of triangles
    named "clamp" gives the node set "clamp". In a Gmsh file that also has volume elements,
    "line" cells are edges of the geometry, not beams, and are treated like triangles. Cells
    of the highest dimension must all be elements: a 24-node hexahedron next to tetrahedra and
    hexahedra, a 6-node triangle in a shell mesh,
    a plane-stress element in a 2D Abaqus mesh are refused, not left out (the body would
    miss their mass and stiffness). Abaqus ``*ELEMENT`` blocks of types meshio does not read
    (membranes such as M3D4, surface elements SFM3D4, ...) are left out with a
    :class:`~flexmbd.MeshQualityWarning`; their element sets still give node sets.

    Node and element ids:

    * Abaqus: the node and element labels of the file (read from its ``*NODE`` and
      ``*ELEMENT`` lines, which meshio drops).
    * Gmsh, ASCII files (2.2 and 4.1): the node and element tags of the file. Binary files and
      format 4.0: 1-based positions in the file (the tags Gmsh writes unless told otherwise).
    * VTK: 1-based positions (VTK has no ids).

    Element ids count every element of the file, also the ones that are not read as
    elements.

    Node sets:

    * Gmsh: one per named physical group (of any dimension), with the nodes of its
      elements. Unnamed physical groups are ignored.
    * Abaqus: every ``*NSET`` (also ``*NODE, NSET=``, ``GENERATE``, names of other node sets
      and ``ELSET=``) and every element set (``*ELSET``, ``*ELEMENT, ELSET=``) as the nodes of
      its elements. A node set and an element set with the same name (as Abaqus/CAE writes
      them) give one node set, the union. Abaqus names are case-insensitive: the spelling of
      the first definition is kept. Only flat input files are understood: meshio reads one
      ``*NODE`` block and ignores ``*PART``/``*INSTANCE`` structure. Labels are integers from
      1 to :data:`ABAQUS_LABEL_MAX`; ``GENERATE`` needs 1 <= first <= last, step >= 1, and
      no more labels than the input defines nodes (elements).
    * Abaqus ``*INCLUDE, INPUT=file``: relative to the folder of the including file only, and
      inside the folder of `path` (absolute paths, paths leaving it, also through symbolic
      links, and include cycles are refused); the included lines are read in place of the
      ``*INCLUDE`` line, by meshio too.
    * VTK: none (VTK files carry no sets).

    The mesh is not checked: call :func:`validate_mesh`.

    Raises:
        MissingFileError: ``path`` does not exist (also a FileNotFoundError).
        InvalidParameterError: the suffix is not one of the formats above.
        InvalidModelError: ``path`` (or an ``*INCLUDE`` file) is not a regular file once its
            links are followed (a folder, a FIFO, a device such as ``/dev/zero``, which would
            block the reader), meshio cannot read the file, or the file is not consistent
            (several ``*NODE`` blocks in one Abaqus input, a label out of range, a bad
            ``GENERATE`` line, a refused or cyclic ``*INCLUDE``, ...), or cells of the
            mesh's highest dimension are not elements flexmbd has.
        UnknownItemError: a set or element of an Abaqus file refers to a node, element or
            set that is not defined (also a ``GENERATE`` range of more labels than defined).
    """
    import meshio

    complete_meshio()
    path = Path(path)
    if not path.exists():
        raise MissingFileError("mesh file", path)
    _check_regular_file(path, "mesh file")
    item = f"file '{path}'"
    file_format = MESH_FORMATS.get(path.suffix.lower())
    if file_format is None:
        raise InvalidParameterError(
            f"{path}: unsupported mesh file suffix {path.suffix!r}; expected one of "
            f"{', '.join(MESH_FORMATS)}",
            item=item,
        )

    # The Abaqus scan comes first: it explains the files meshio misreads.
    abaqus = _scan_abaqus(path) if file_format == "abaqus" else None
    # The format's own reader: meshio.read() prints and exits the interpreter on a ReadError.
    reader = {"gmsh": meshio.gmsh, "abaqus": meshio.abaqus, "vtu": meshio.vtu, "vtk": meshio.vtk}
    try:
        if abaqus is not None:
            # The input with its *INCLUDE files inlined: meshio would look for them in the
            # working folder first and follow absolute paths.
            raw = meshio.abaqus._abaqus.read_buffer(io.StringIO("\n".join(abaqus.lines) + "\n"))
        else:
            raw = reader[file_format].read(str(path))
    except KeyError as error:
        node = error.args[0] if error.args else None
        if abaqus is None or not isinstance(node, int | np.integer):
            raise InvalidModelError(
                f"{path}: cannot read the mesh ({error!r})", item=item
            ) from None
        raise abaqus.unknown_node(path, int(node)) from None
    except Exception as error:
        raise InvalidModelError(
            f"{path}: cannot read the mesh ({type(error).__name__}: {error})", item=item
        ) from error

    nodes = np.asarray(raw.points, dtype=np.float64)
    if nodes.ndim != 2 or nodes.shape[1] > 3:
        raise InvalidModelError(f"{path}: node coordinates of shape {nodes.shape}", item=item)
    if nodes.shape[1] < 3:
        nodes = np.hstack([nodes, np.zeros((len(nodes), 3 - nodes.shape[1]))])
    blocks = [(block.type, np.asarray(block.data, dtype=np.int64)) for block in raw.cells]
    positional = np.arange(1, sum(len(data) for _, data in blocks) + 1, dtype=np.int64)

    if abaqus is not None:
        node_ids, block_ids = abaqus.ids(path, len(nodes), blocks)
        node_sets = abaqus.resolve_node_sets(path, node_ids, blocks, block_ids)
    elif file_format == "gmsh":
        node_ids, flat_ids = _gmsh_tags(path, len(nodes), len(positional))
        block_ids = _split(flat_ids if flat_ids is not None else positional, blocks)
        node_sets = _gmsh_node_sets(raw, blocks)
    else:
        node_ids = np.arange(1, len(nodes) + 1, dtype=np.int64)
        block_ids = _split(positional, blocks)
        node_sets = {}

    # Gmsh writes the edges of the geometry as line cells next to the volume (or surface)
    # cells.
    has_volume = any(_cell_dimension(cell_type) == 3 for cell_type, _ in blocks)
    shells_from_cells = abaqus is None and not has_volume
    has_surface = shells_from_cells and any(cell in MESHIO_SHELL_TYPES for cell, _ in blocks)
    # (and, as documented, in VTK files of surfaces: their lines became beams, and the mesh was
    # refused for a beam section nobody meant to give)
    skip_lines = (file_format == "gmsh" and (has_volume or has_surface)) or (
        file_format in ("vtu", "vtk") and has_surface
    )
    # Cells of the mesh's highest dimension are its body: one that is not an element would
    # leave a hole (a wedge between hexahedra, second-order hexahedra), mass and stiffness
    # silently lost.
    top = max((_cell_dimension(cell_type) for cell_type, _ in blocks), default=0)
    elements: dict[str, list[NDArray[np.int64]]] = {}
    element_ids: dict[str, list[NDArray[np.int64]]] = {}
    left_out = _unread_blocks(path, abaqus) if abaqus is not None else {}
    substituted: dict[str, list[int]] = {}
    for index, ((cell_type, data), ids) in enumerate(zip(blocks, block_ids, strict=True)):
        kind = MESHIO_ELEMENT_TYPES.get(cell_type)
        if abaqus is not None and kind is not None:
            source = abaqus.element_types[index]
            kind = ABAQUS_SOLID_TYPES.get(source, kind)
            if source in ABAQUS_SUBSTITUTED_TYPES and len(data):
                first = substituted.setdefault(source, [0, int(ids[0])])
                first[0] += len(data)
        elif abaqus is not None and kind is None:
            kind = ABAQUS_SHELL_TYPES.get(abaqus.element_types[index])
        elif shells_from_cells and kind is None:
            kind = MESHIO_SHELL_TYPES.get(cell_type)
        if kind is None and len(data) and _cell_dimension(cell_type) == top > 0:
            source = abaqus.element_types[index] if abaqus is not None else cell_type
            raise _unsupported_cells(path, source, len(data), int(ids[0]), top)
        if kind is None and abaqus is not None and len(data):
            entry = left_out.setdefault(abaqus.element_types[index], [0, int(ids[0]), ""])
            entry[0] += len(data)
        if kind is None or (kind == "beam2" and skip_lines):
            continue
        if kind == "tet10":
            data = data[:, TET10_FROM_MESHIO]
        if kind == "wedge18" and file_format == "gmsh":
            data = data[:, WEDGE18_FROM_GMSH]
        if kind in WEDGE_MIRRORS and file_format in ("vtu", "vtk"):
            data = orient_wedges(nodes, data, kind)
        if kind == "pyramid14" and file_format == "gmsh":
            data = data[:, PYRAMID14_FROM_GMSH]
        elements.setdefault(kind, []).append(data)
        element_ids.setdefault(kind, []).append(ids)
    _warn_left_out(path, left_out, bool(elements))
    for source, (count, first) in substituted.items():
        warnings.warn(
            f"{path}: {count} {source} element(s) (first: element {first}) are read as hex8, "
            f"flexmbd's fully integrated trilinear hexahedron; Abaqus' {source} uses "
            f"{ABAQUS_SUBSTITUTED_TYPES[source]}, so results differ, most in bending on coarse "
            "meshes, where hex8 is too stiff: mesh them as C3D8I (read as hex8i, which bends "
            "like it) or refine",
            MeshQualityWarning,
            stacklevel=2,
        )
    return Mesh(
        nodes=nodes,
        node_ids=np.asarray(node_ids, dtype=np.int64),
        elements={kind: np.concatenate(parts) for kind, parts in elements.items()},
        element_ids={kind: np.concatenate(parts) for kind, parts in element_ids.items()},
        node_sets=node_sets,
        shell_thickness=None if abaqus is None else abaqus.shell_thickness(path),
    )


#: What to do instead, for the cells of other codes' higher orders: meshio's type -> advice.
ORDER_ADVICE = {
    "triangle6": "shells are of order 1 here (tri3, quad4): mesh the surface at order 1",
    "quad8": "shells are of order 1 here (tri3, quad4): mesh the surface at order 1",
    "quad9": "shells are of order 1 here (tri3, quad4): mesh the surface at order 1",
}


def _unsupported_cells(
    path: Path, cell_type: str, count: int, first_id: int, dimension: int
) -> InvalidModelError:
    """The error for `count` cells of type `cell_type` (meshio's name, or Abaqus' element
    type), of the mesh's highest `dimension`, that are not flexmbd elements."""
    supported = {
        3: "tet4, tet10, hex8, hex8i, hex20, hex20r, hex27, wedge6, wedge15, wedge18, pyramid5, "
        "pyramid13, pyramid14",
        2: "quad4, tri3 (flat shells)",
        1: "beam2",
    }[dimension]
    return InvalidModelError(
        f"{path}: {count} {cell_type} cell{'s' if count > 1 else ''} (the first is element "
        f"{first_id}) {'are' if count > 1 else 'is'} not an element type flexmbd has "
        f"({supported}): refused, as leaving them out, the body would miss their mass and "
        "stiffness. "
        + ORDER_ADVICE.get(cell_type, "Mesh with the supported types or remove these cells"),
        item=f"element {first_id} of '{path}'",
    )


def _check_regular_file(path: Path, what: str, where: str = "") -> None:
    """Raises `InvalidModelError` naming `path` when it exists but is not a regular file once
    its links are followed: a folder, a FIFO or a device (a link to ``/dev/zero``), which
    meshio or a read of the text would fail on or wait on for ever. `where` (a line of an
    including file) starts the message."""
    named = f"{where}: the {what} {path}" if where else f"{path}: the {what}"
    try:
        regular = path.is_file()
    except OSError as error:
        raise InvalidModelError(
            f"{named} cannot be read ({error})", item=f"file '{path}'"
        ) from None
    if not regular:
        raise InvalidModelError(
            f"{named} is not a regular file (a folder, a FIFO or a device)", item=f"file '{path}'"
        )


def _split(flat: NDArray[np.int64], blocks: list[tuple[str, NDArray[np.int64]]]) -> list:
    """Cut per-file element ids into one array per cell block."""
    offsets = np.cumsum([0] + [len(data) for _, data in blocks])
    return [flat[start:end] for start, end in zip(offsets[:-1], offsets[1:], strict=True)]


def _cell_dimension(cell_type: str) -> int:
    """Topological dimension of a meshio cell type."""
    if cell_type == "vertex":
        return 0
    if cell_type.startswith("line"):
        return 1
    if cell_type.startswith(("triangle", "quad", "polygon")):
        return 2
    return 3


def _nodes_of(blocks: list[tuple[str, NDArray[np.int64]]], selection: dict[int, Any]) -> Any:
    """Sorted unique node indices of the cells ``selection[block] = cell indices``."""
    parts = [
        blocks[b][1][np.asarray(cells, dtype=np.int64)].ravel() for b, cells in selection.items()
    ]
    if not parts:
        return np.zeros(0, dtype=np.int64)
    return np.unique(np.concatenate(parts)).astype(np.int64)


def _gmsh_node_sets(raw: meshio.Mesh, blocks: list[tuple[str, NDArray[np.int64]]]) -> dict:
    """Node sets of the named physical groups of a Gmsh file."""
    physical = raw.cell_data.get("gmsh:physical")
    # meshio leaves out the blocks of 4.1 entities without a physical group.
    aligned = physical is not None and len(physical) == len(blocks)
    node_sets: dict[str, NDArray[np.int64]] = {}
    for name, value in raw.field_data.items():
        value = np.asarray(value).ravel()
        if len(value) != 2:
            continue
        tag, dimension = int(value[0]), int(value[1])
        selection: dict[int, Any] = {}
        # Format 2.2: the first tag of each element; format 4.1: cell sets of the entities.
        for b, (cell_type, _) in enumerate(blocks):
            cells: list[Any] = []
            if aligned and _cell_dimension(cell_type) == dimension:
                cells.append(np.flatnonzero(np.asarray(physical[b]) == tag))
            per_block = raw.cell_sets.get(name)
            if per_block is not None and b < len(per_block) and per_block[b] is not None:
                cells.append(np.asarray(per_block[b], dtype=np.int64))
            if cells:
                selection[b] = np.unique(np.concatenate(cells))
        node_sets[name] = _nodes_of(blocks, selection)
    return node_sets


def _gmsh_tags(
    path: Path, node_count: int, element_count: int
) -> tuple[NDArray[np.int64], NDArray[np.int64] | None]:
    """Node and element tags of an ASCII Gmsh file (formats 2.x and 4.1), in file order, which
    is meshio's order. Other files, or a disagreement with meshio: 1-based positions."""
    positions = np.arange(1, node_count + 1, dtype=np.int64)
    try:
        scanned = _scan_gmsh_tags(path)
    except (ValueError, IndexError, StopIteration, UnicodeDecodeError):
        scanned = None
    if scanned is None:
        return positions, None
    node_tags, element_tags = scanned
    if len(node_tags) != node_count or len(element_tags) != element_count:
        return positions, None
    return np.asarray(node_tags, dtype=np.int64), np.asarray(element_tags, dtype=np.int64)


def _scan_gmsh_tags(path: Path) -> tuple[list[int], list[int]] | None:
    with open(path, "rb") as file:
        data = file.read()
    lines = data.split(b"\n")
    start = next(i for i, line in enumerate(lines) if line.strip() == b"$MeshFormat")
    version, file_type, *_ = lines[start + 1].decode("ascii").split()
    if file_type != "0":
        return None
    if version.startswith("2"):
        modern = False
    elif version in ("4", "4.1"):
        modern = True
    else:
        return None
    stripped = [line.strip() for line in lines]
    nodes_at = stripped.index(b"$Nodes") + 1
    elements_at = stripped.index(b"$Elements") + 1

    def first_tokens(first: int, count: int) -> list[int]:
        return [int(lines[i].split(None, 1)[0]) for i in range(first, first + count)]

    if not modern:
        node_tags = first_tokens(nodes_at + 1, int(lines[nodes_at]))
        element_tags = first_tokens(elements_at + 1, int(lines[elements_at]))
        return node_tags, element_tags

    # 4.1: blocks of "dim tag parametric count", then count tag lines and count coordinate lines.
    node_tags = []
    block_count = int(lines[nodes_at].split()[0])
    line = nodes_at + 1
    for _ in range(block_count):
        count = int(lines[line].split()[3])
        node_tags += [int(tag) for tag in lines[line + 1 : line + 1 + count]]
        line += 1 + 2 * count
    # 4.1: blocks of "dim tag type count", then count lines "tag node ...".
    element_tags = []
    block_count = int(lines[elements_at].split()[0])
    line = elements_at + 1
    for _ in range(block_count):
        count = int(lines[line].split()[3])
        element_tags += first_tokens(line + 1, count)
        line += 1 + count
    return node_tags, element_tags


# ---------------------------------------------------------------------------------------------
# Abaqus input files: the labels and sets that meshio drops


@dataclass
class _AbaqusSet:
    name: str
    ids: list[int] = field(default_factory=list)
    set_names: list[str] = field(default_factory=list)
    element_set_names: list[str] = field(default_factory=list)


@dataclass
class _AbaqusScan:
    """What a pass over an Abaqus input file (and its ``*INCLUDE`` files) finds, in file
    order, which is the order of meshio's points and cell blocks."""

    node_ids: list[int] = field(default_factory=list)
    # One (flat integers of the data lines, ELSET parameter) per *ELEMENT block.
    element_blocks: list[tuple[list[int], str | None]] = field(default_factory=list)
    # Upper-case name -> set.
    node_sets: dict[str, _AbaqusSet] = field(default_factory=dict)
    element_sets: dict[str, _AbaqusSet] = field(default_factory=dict)
    # The lines of the input with every *INCLUDE replaced by the lines of its file: what
    # meshio reads (so that it reads exactly the files checked here).
    lines: list[str] = field(default_factory=list)
    # *NSET / *ELSET, GENERATE ranges (set, "NSET" or "ELSET", where, range), expanded once the
    # whole input is scanned and their sizes are checked against the labels it defines.
    generated: list[tuple[_AbaqusSet, str, str, range]] = field(default_factory=list)
    node_blocks: int = 0
    # The TYPE= of each *ELEMENT block (upper case).
    element_types: list[str] = field(default_factory=list)
    # *ELEMENT blocks of types meshio does not read (membranes, surface elements, ...), left
    # out of `lines`: (type, where, ELSET, rows of [label, node labels...]).
    unread_blocks: list[tuple[str, str, str | None, list[list[int]]]] = field(default_factory=list)
    # (where, thickness) of each *SHELL SECTION.
    shell_sections: list[tuple[str, float]] = field(default_factory=list)
    # (where, ELSET) of each *SHELL SECTION that names its elements.
    shell_elsets: list[tuple[str, str]] = field(default_factory=list)
    # The folder of the input file: *INCLUDE files must be inside it (see `_include_target`).
    root: Path = field(default_factory=Path)

    def ids(
        self, path: Path, node_count: int, blocks: list[tuple[str, NDArray[np.int64]]]
    ) -> tuple[NDArray[np.int64], list[NDArray[np.int64]]]:
        """Node labels and element labels per cell block, checked against meshio's reading."""
        item = f"file '{path}'"
        if len(self.node_ids) != node_count:
            raise InvalidModelError(
                f"{path}: meshio read {node_count} nodes but the *NODE lines define "
                f"{len(self.node_ids)}",
                item=item,
            )
        if len(self.element_blocks) != len(blocks):
            raise InvalidModelError(
                f"{path}: meshio read {len(blocks)} element blocks but the file has "
                f"{len(self.element_blocks)} *ELEMENT blocks",
                item=item,
            )
        block_ids = []
        for (values, _), (cell_type, data) in zip(self.element_blocks, blocks, strict=True):
            width = data.shape[1] + 1
            if len(values) != len(data) * width:
                raise InvalidModelError(
                    f"{path}: an *ELEMENT block of {cell_type} cells has {len(values)} numbers, "
                    f"expected {len(data)} x {width}",
                    item=item,
                )
            block_ids.append(np.asarray(values, dtype=np.int64).reshape(-1, width)[:, 0])
        return np.asarray(self.node_ids, dtype=np.int64), block_ids

    def shell_thickness(self, path: Path) -> float | None:
        """The thickness of the *SHELL SECTION lines (None without one); several different
        thicknesses are an `InvalidModelError` (a body has one shell section)."""
        defined = set(self.element_sets) | {
            name.upper() for _, name in self.element_blocks if name is not None
        }
        for where, name in self.shell_elsets:
            if name.upper() not in defined:
                raise UnknownItemError(
                    f"{where}: *SHELL SECTION, ELSET={name}: no element set of that name",
                    item=name,
                )
        values = sorted({t for _, t in self.shell_sections})
        if len(values) > 1:
            raise InvalidModelError(
                f"{path}: *SHELL SECTION thicknesses {values}: a body has one shell section; "
                "split the mesh into bodies of one thickness each",
                item=f"file '{path}'",
            )
        return values[0] if values else None

    def resolve_node_sets(
        self,
        path: Path,
        node_ids: NDArray[np.int64],
        blocks: list[tuple[str, NDArray[np.int64]]],
        block_ids: list[NDArray[np.int64]],
    ) -> dict[str, NDArray[np.int64]]:
        """Resolve the node and element sets into node sets (indices into the nodes)."""
        node_index = {int(node_id): index for index, node_id in enumerate(node_ids)}
        element_index = {
            int(element_id): (b, row)
            for b, ids in enumerate(block_ids)
            for row, element_id in enumerate(ids)
        }
        for b, (_, name) in enumerate(self.element_blocks):
            if name is not None:
                self._element_set(name).ids.extend(int(i) for i in block_ids[b])
        # Elements of the blocks meshio does not read: their nodes (by label) for the sets.
        unread: dict[int, list[int]] = {}
        for _, where, name, rows in self.unread_blocks:
            for row in rows:
                for label in row[1:]:
                    if label not in node_index:
                        raise UnknownItemError(
                            f"{where}: element {row[0]} refers to node {label}, which no "
                            "*NODE line defines",
                            item=f"node {label}",
                        )
                unread[row[0]] = [node_index[label] for label in row[1:]]
            if name is not None:
                self._element_set(name).ids.extend(row[0] for row in rows)

        def element_nodes(key: str, seen: set[str]) -> set[int]:
            entry = self.element_sets.get(key)
            if entry is None:
                raise UnknownItemError(
                    f"{path}: unknown element set {key!r}", item=f"element set '{key}'"
                )
            if key in seen:
                return set()
            seen.add(key)
            result: set[int] = set()
            for element_id in entry.ids:
                if element_id in unread:
                    result.update(unread[element_id])
                    continue
                if element_id not in element_index:
                    raise UnknownItemError(
                        f"{path}: element set {entry.name!r} refers to element {element_id}, "
                        "which no *ELEMENT line defines",
                        item=f"element {element_id}",
                    )
                b, row = element_index[element_id]
                result.update(int(i) for i in blocks[b][1][row])
            for other in entry.set_names:
                result |= element_nodes(other.upper(), seen)
            return result

        def set_nodes(key: str, seen: set[str]) -> set[int]:
            entry = self.node_sets.get(key)
            if entry is None:
                raise UnknownItemError(
                    f"{path}: unknown node set {key!r}", item=f"node set '{key}'"
                )
            if key in seen:
                return set()
            seen.add(key)
            result: set[int] = set()
            for node_id in entry.ids:
                if node_id not in node_index:
                    raise UnknownItemError(
                        f"{path}: node set {entry.name!r} refers to node {node_id}, which no "
                        "*NODE line defines",
                        item=f"node {node_id}",
                    )
                result.add(node_index[node_id])
            for other in entry.set_names:
                result |= set_nodes(other.upper(), seen)
            for other in entry.element_set_names:
                result |= element_nodes(other.upper(), set())
            return result

        node_sets: dict[str, NDArray[np.int64]] = {}
        for key, entry in self.node_sets.items():
            node_sets[entry.name] = _sorted_indices(set_nodes(key, set()))
        for key, entry in self.element_sets.items():
            nodes = element_nodes(key, set())
            # Same name as a node set: Abaqus/CAE writes both for one region; take the union.
            name = self.node_sets[key].name if key in self.node_sets else entry.name
            if name in node_sets:
                nodes |= set(node_sets[name].tolist())
            node_sets[name] = _sorted_indices(nodes)
        return node_sets

    def unknown_node(self, path: Path, node: int) -> UnknownItemError:
        """The error for a reference to a node that no *NODE line defines."""
        for entry in self.node_sets.values():
            if node in entry.ids:
                return UnknownItemError(
                    f"{path}: node set {entry.name!r} refers to node {node}, which no *NODE "
                    "line defines",
                    item=f"node {node}",
                )
        return UnknownItemError(
            f"{path}: an element refers to node {node}, which no *NODE line defines",
            item=f"node {node}",
        )

    def _node_set(self, name: str) -> _AbaqusSet:
        return self.node_sets.setdefault(name.upper(), _AbaqusSet(name))

    def _element_set(self, name: str) -> _AbaqusSet:
        return self.element_sets.setdefault(name.upper(), _AbaqusSet(name))


def _sorted_indices(indices: set[int]) -> NDArray[np.int64]:
    return np.asarray(sorted(indices), dtype=np.int64)


def _abaqus_parameters(line: str) -> tuple[str, dict[str, str | None]]:
    """Keyword (upper case, as meshio reads it) and parameters of a keyword line."""
    words = line.split(",")
    keyword = words[0].strip().replace("*", "").upper()
    parameters: dict[str, str | None] = {}
    for word in words[1:]:
        key, equals, value = word.partition("=")
        parameters[key.strip().upper()] = value.strip().strip('"') if equals else None
    return keyword, parameters


def _abaqus_label(path: Path, line_number: int, value: int) -> int:
    """`value` checked as an Abaqus node or element label: positive and within int64."""
    if not 1 <= value <= ABAQUS_LABEL_MAX:
        raise InvalidModelError(
            f"{path}, line {line_number}: label {value} is out of range (labels are integers "
            f"from 1 to {ABAQUS_LABEL_MAX})",
            item=f"line {line_number} of '{path}'",
        )
    return value


def _abaqus_integers(path: Path, rows: list[tuple[int, str]], *, labels: bool = True) -> list[int]:
    """The comma-separated integers of data lines given as (line number, text), checked as
    labels (positive, within int64) unless `labels` is False."""
    values = []
    for line_number, text in rows:
        for token in text.split(","):
            if token.strip():
                try:
                    value = int(token)
                except ValueError:
                    raise InvalidModelError(
                        f"{path}, line {line_number}: expected integers, got {text!r}",
                        item=f"line {line_number} of '{path}'",
                    ) from None
                values.append(_abaqus_label(path, line_number, value) if labels else value)
    return values


def _scan_abaqus(path: Path) -> _AbaqusScan:
    scan = _AbaqusScan(root=path.resolve().parent)
    _scan_abaqus_file(path, scan, (path.resolve(),))
    _expand_generated(scan)
    return scan


def _expand_generated(scan: _AbaqusScan) -> None:
    """Expand the GENERATE ranges of the sets. A range of more labels than the input defines
    nodes (*NSET) or can define elements (*ELSET: each element takes a label and at least one
    node label) must name one that does not exist: it is refused before it takes memory (and
    before meshio, which expands it too, reads the input)."""
    node_count = len(scan.node_ids)
    element_bound = sum(len(values) for values, _ in scan.element_blocks) // 2
    for entry, keyword, where, labels in scan.generated:
        if keyword == "NSET":
            defined, what = node_count, f"the {node_count} nodes"
        else:
            defined, what = element_bound, f"the at most {element_bound} elements"
        if len(labels) > defined:
            kind = "node set" if keyword == "NSET" else "element set"
            raise UnknownItemError(
                f"{where}: GENERATE of {kind} {entry.name!r} makes {len(labels)} labels "
                f"(from {labels.start} in steps of {labels.step}), more than {what} that the "
                "input defines: it names labels that do not exist",
                item=f"{kind} '{entry.name}'",
            )
    for entry, _, _, labels in scan.generated:
        entry.ids.extend(labels)


def _include_target(
    path: Path, parameters: dict[str, str | None], line: int, scan: _AbaqusScan
) -> Path:
    """The file of an ``*INCLUDE, INPUT=...`` line of `path`: relative to the folder of
    `path` only, and inside the folder of the top input file (absolute paths and paths that
    leave that folder, also through symbolic links, are refused)."""
    item = f"line {line} of '{path}'"
    name = parameters.get("INPUT")
    if not name:
        raise InvalidModelError(f"{path}, line {line}: *INCLUDE without INPUT=", item=item)
    relative = Path(name)
    if relative.is_absolute():
        raise InvalidModelError(
            f"{path}, line {line}: *INCLUDE of the absolute path {name!r} is refused: give it "
            "relative to the folder of the including file",
            item=item,
        )
    target = (path.parent / relative).resolve()
    if not target.is_relative_to(scan.root):
        raise InvalidModelError(
            f"{path}, line {line}: *INCLUDE {name!r} leaves the folder of the input file "
            f"({scan.root}): included files must be in that folder or below it",
            item=item,
        )
    if not target.exists():
        raise InvalidModelError(
            f"{path}, line {line}: *INCLUDE file {name!r} not found (looked for {target})",
            item=item,
        )
    _check_regular_file(target, "*INCLUDE file", f"{path}, line {line}")
    return target


def _unread_blocks(path: Path, scan: _AbaqusScan) -> dict[str, list[Any]]:
    """The *ELEMENT blocks meshio does not read (`_AbaqusScan.unread_blocks`) by type:
    [count, first element, where]; solids (C3D...) and continuum shells (SC...) of such types
    are refused instead (they would leave a hole in the body)."""
    counts: dict[str, list[Any]] = {}
    for element_type, where, _, rows in scan.unread_blocks:
        if rows and element_type.startswith(("C3D", "SC")):
            raise _unsupported_cells(path, element_type, len(rows), rows[0][0], 3)
        if rows:
            entry = counts.setdefault(element_type, [0, rows[0][0], f", {where}"])
            entry[0] += len(rows)
    return counts


def _warn_left_out(path: Path, left_out: Mapping[str, list[Any]], read_any: bool) -> None:
    """A `MeshQualityWarning` per Abaqus element type left out (the blocks meshio does not
    read, and elements of a lower dimension than the mesh's that flexmbd does not have:
    second-order shells and beams, plane elements next to solids): in an Abaqus input every
    *ELEMENT is an element, and their mass and stiffness are not in the body. A mesh of such
    elements only is an `InvalidModelError`."""
    listed = ", ".join(
        f"{count} {kind} (first: element {first}{where})"
        for kind, (count, first, where) in left_out.items()
    )
    if not read_any and left_out:
        raise InvalidModelError(f"{path}: no element flexmbd has: {listed}", item=f"file '{path}'")
    for kind, (count, first, where) in left_out.items():
        warnings.warn(
            f"{path}: {count} {kind} element(s) (first: element {first}{where}) are not "
            "read: flexmbd has no such element (membranes, surface, rigid, plane, second-order "
            "shell and beam elements), so their mass and stiffness are not in the body; their "
            "nodes are in the node sets of their element sets",
            MeshQualityWarning,
            stacklevel=3,
        )


#: Abaqus element types meshio's reader names but cannot read (its tables miss their cells:
#: a KeyError), handed to it as an equivalent type.
_MESHIO_ABAQUS_ALIASES = {"C3D4H": "C3D4"}


@functools.cache
def _meshio_abaqus_types() -> frozenset[str]:
    """The Abaqus element types meshio's reader reads (it names C3D15, but fails on it)."""
    import meshio._mesh
    import meshio.abaqus._abaqus as reader

    complete_meshio()
    return frozenset(
        name
        for name, cell in reader.abaqus_to_meshio_type.items()
        if cell in reader.num_nodes_per_cell and cell in meshio._mesh.topological_dimension
    ) | frozenset(_MESHIO_ABAQUS_ALIASES)


def _scan_abaqus_file(path: Path, scan: _AbaqusScan, chain: tuple[Path, ...]) -> None:
    """Scan `path` (reached through the *INCLUDE files `chain`, itself last) into `scan`."""

    item = f"file '{path}'"
    if len(chain) > ABAQUS_INCLUDE_DEPTH + 1:
        raise InvalidModelError(
            f"{path}: *INCLUDE nested more than {ABAQUS_INCLUDE_DEPTH} deep", item=item
        )
    try:
        with open(path, encoding="utf-8", errors="replace") as file:
            lines = file.read().splitlines()
    except OSError as error:
        raise InvalidModelError(f"{path}: cannot read the file ({error})", item=item) from None
    number = 0
    while number < len(lines):
        line = lines[number]
        number += 1
        if not line.startswith("*") or line.startswith("**"):
            scan.lines.append(line)
            continue
        keyword, parameters = _abaqus_parameters(line)
        # Data lines end at the next line starting with "*" (also a comment), as in meshio.
        first = number
        while number < len(lines) and not lines[number].startswith("*"):
            number += 1
        data = [(first + k + 1, text) for k, text in enumerate(lines[first:number]) if text.strip()]
        element_type = (parameters.get("TYPE") or "").upper()
        if keyword == "ELEMENT" and element_type not in _meshio_abaqus_types():
            # meshio refuses the whole file for one block of a type it does not know (skins
            # of membranes on a solid): such a block is left out of what it reads.
            # One element per line, continued on the next while a line ends in a comma.
            rows: list[list[int]] = []
            continued = False
            for row in data:
                values = _abaqus_integers(path, [row])
                if continued:
                    rows[-1].extend(values)
                else:
                    rows.append(values)
                continued = row[1].rstrip().endswith(",")
            where = f"{path}, line {first}"
            scan.unread_blocks.append((element_type, where, parameters.get("ELSET"), rows))
            continue
        if keyword != "INCLUDE":
            head = lines[first - 1]
            if keyword == "ELEMENT":
                # (Abaqus names are case-insensitive; meshio's table is upper case)
                alias = _MESHIO_ABAQUS_ALIASES.get(element_type, element_type)
                head = re.sub(r"(?i)(TYPE\s*=\s*)\w+", rf"\g<1>{alias}", head)
            scan.lines.extend([head, *lines[first:number]])

        if keyword == "NODE":
            scan.node_blocks += 1
            if scan.node_blocks > 1:
                raise InvalidModelError(
                    f"{path}, line {first}: a second *NODE block; meshio's Abaqus reader keeps "
                    "only the last one, so merge the *NODE blocks into one",
                    item=item,
                )
            ids = _abaqus_integers(path, [(n, text.split(",", 1)[0]) for n, text in data])
            scan.node_ids.extend(ids)
            if parameters.get("NSET"):
                scan._node_set(parameters["NSET"]).ids.extend(ids)
        elif keyword == "ELEMENT":
            scan.element_blocks.append(
                (_abaqus_integers(path, data), parameters.get("ELSET") or None)
            )
            scan.element_types.append((parameters.get("TYPE") or "").upper())
        elif keyword == "SHELL SECTION":
            where = f"{path}, line {first}"
            # Layered sections, offsets and nodal thicknesses were read as one plain
            # thickness (a 2-layer COMPOSITE: half the mass, 8 times the deflection).
            offset = (parameters.get("OFFSET") or "0").upper()
            unsupported = [
                name
                for name, used in (
                    ("COMPOSITE", "COMPOSITE" in parameters),
                    ("OFFSET", offset not in ("0", "0.", "0.0", "SMID")),
                    ("NODAL THICKNESS", "NODAL THICKNESS" in parameters),
                )
                if used
            ]
            if unsupported:
                raise InvalidModelError(
                    f"{where}: *SHELL SECTION with {', '.join(unsupported)}: flexmbd shells have "
                    "one homogeneous section of constant thickness at the middle surface",
                    item=f"line {first} of '{path}'",
                )
            try:
                thickness = float(data[0][1].split(",")[0]) if data else math.nan
            except ValueError:
                thickness = math.nan
            if not (math.isfinite(thickness) and thickness > 0):
                raise InvalidModelError(
                    f"{where}: *SHELL SECTION needs a positive thickness on its first data line",
                    item=f"line {first} of '{path}'",
                )
            scan.shell_sections.append((where, thickness))
            if parameters.get("ELSET"):
                scan.shell_elsets.append((where, parameters["ELSET"]))
        elif keyword in ("NSET", "ELSET"):
            name = parameters.get(keyword)
            if not name:
                raise InvalidModelError(
                    f"{path}, line {first}: *{keyword} without {keyword}=", item=item
                )
            entry = scan._node_set(name) if keyword == "NSET" else scan._element_set(name)
            if keyword == "NSET" and parameters.get("ELSET"):
                entry.element_set_names.append(parameters["ELSET"])
            if "GENERATE" in parameters:
                for line_number, text in data:
                    where = f"{path}, line {line_number}"
                    triple = _abaqus_integers(path, [(line_number, text)], labels=False)
                    if len(triple) not in (2, 3):
                        raise InvalidModelError(
                            f"{where}: GENERATE expects first, last[, step]",
                            item=f"line {line_number} of '{path}'",
                        )
                    start, stop, step = (*triple, 1)[:3]
                    _abaqus_label(path, line_number, start)
                    _abaqus_label(path, line_number, stop)
                    if step < 1:
                        raise InvalidModelError(
                            f"{where}: GENERATE step {step}: the step must be a positive integer",
                            item=f"line {line_number} of '{path}'",
                        )
                    if start > stop:
                        raise InvalidModelError(
                            f"{where}: GENERATE from {start} to {stop}: the first label must "
                            "not exceed the last",
                            item=f"line {line_number} of '{path}'",
                        )
                    scan.generated.append((entry, keyword, where, range(start, stop + 1, step)))
            else:
                for line_number, text in data:
                    for token in (t.strip() for t in text.split(",")):
                        if not token:
                            continue
                        if token.lstrip("-").isdigit():
                            entry.ids.append(_abaqus_label(path, line_number, int(token)))
                        else:
                            entry.set_names.append(token.strip('"'))
        elif keyword == "INCLUDE":
            target = _include_target(path, parameters, first, scan)
            if target in chain:
                cycle = " -> ".join(str(p) for p in (*chain[chain.index(target) :], target))
                raise InvalidModelError(
                    f"{path}, line {first}: *INCLUDE cycle {cycle}",
                    item=f"line {first} of '{path}'",
                )
            _scan_abaqus_file(target, scan, (*chain, target))


# ---------------------------------------------------------------------------------------------
# Checks


#: The shell element types, whose node order gives their normal (`orient_shells`).
SHELL_TYPES = ("quad4", "tri3")

#: A shell element as (kind, index into that kind's connectivity).
ShellKey = tuple[str, int]


def _shell_edges(
    elements: Mapping[str, Any],
) -> tuple[list[ShellKey], NDArray[np.int64], NDArray[np.int64]]:
    """The shells of `elements` (kind, index) and their directed edges: the shell of each
    edge (an index into the list) and its two nodes (E, 2), in each shell's cyclic order."""
    shells: list[ShellKey] = []
    owners, edges = [], []
    for kind in SHELL_TYPES:
        conn = np.asarray(elements.get(kind, np.zeros((0, 3))), dtype=np.int64)
        if not len(conn):
            continue
        first = len(shells)
        shells += [(kind, k) for k in range(len(conn))]
        corners = conn.shape[1]
        for i in range(corners):
            owners.append(first + np.arange(len(conn)))
            edges.append(np.stack([conn[:, i], conn[:, (i + 1) % corners]], axis=1))
    if not shells:
        return [], np.zeros(0, dtype=np.int64), np.zeros((0, 2), dtype=np.int64)
    return shells, np.concatenate(owners), np.concatenate(edges)


def shell_pairs(
    elements: Mapping[str, Any],
) -> tuple[list[ShellKey], NDArray[np.int64], NDArray[np.int64], NDArray[np.bool_]]:
    """`shell_neighbours` as arrays: the shells and, per pair, the indices of its two shells
    into them and whether they are turned to opposite sides."""
    shells, owners, edges = _shell_edges(elements)
    if not shells:
        empty = np.zeros(0, dtype=np.int64)
        return [], empty, empty, np.zeros(0, dtype=bool)
    low, high = edges.min(axis=1), edges.max(axis=1)
    keys = low * (int(high.max()) + 1) + high  # one integer per undirected edge
    _, inverse, counts = np.unique(keys, return_inverse=True, return_counts=True)
    shared = np.flatnonzero(counts[inverse] == 2)
    order = shared[np.argsort(inverse[shared], kind="stable")]
    first, second = order[0::2], order[1::2]
    return shells, owners[first], owners[second], edges[first, 0] == edges[second, 0]


def shell_neighbours(elements: Mapping[str, Any]) -> list[tuple[ShellKey, ShellKey, bool]]:
    """The pairs of shell elements that share an edge (one no third shell shares): (first,
    second, opposite), each as (kind, index); `opposite` where both run along the edge in the
    same direction, so that their normals, by the right-hand rule of their node order, point
    to opposite sides."""
    shells, first, second, opposite = shell_pairs(elements)
    return [
        (shells[a], shells[b], bool(flip))
        for a, b, flip in zip(first, second, opposite, strict=True)
    ]


def orient_shells(elements: Mapping[str, Any]) -> dict[str, NDArray[np.int64]]:
    """`elements` with the shells turned so that neighbours agree: across every edge that two
    shells share, both normals point to the same side (the first shell of each connected
    surface keeps its own). A shell is turned by reversing its node order after its first
    node ((a, b, c, d) -> (a, d, c, b)), which leaves its stiffness and mass as they are and
    exchanges its top and bottom surfaces. The shells' stresses are averaged at the nodes
    (`flexmbd.fe.shell_stresses`), top with top: that needs a consistently turned mesh.

    Raises:
        InvalidModelError: a surface that cannot be oriented (a Moebius strip), naming two
            shells whose orientations contradict each other.
    """
    shells = [(kind, k) for kind in SHELL_TYPES for k in range(len(elements.get(kind, ())))]
    neighbours: dict[ShellKey, list[tuple[ShellKey, bool]]] = {}
    for a, b, opposite in shell_neighbours(elements):
        neighbours.setdefault(a, []).append((b, opposite))
        neighbours.setdefault(b, []).append((a, opposite))
    turned: dict[ShellKey, bool] = {}
    for seed in shells:
        if seed in turned:
            continue
        turned[seed] = False
        stack = [seed]
        while stack:
            shell = stack.pop()
            for other, opposite in neighbours.get(shell, []):
                wanted = turned[shell] ^ opposite
                if other not in turned:
                    turned[other] = wanted
                    stack.append(other)
                elif turned[other] != wanted:
                    raise InvalidModelError(
                        f"the shells cannot all be turned to one side: {shell[1]} ({shell[0]}) "
                        f"and {other[1]} ({other[0]}) contradict each other (a one-sided "
                        "surface, such as a Moebius strip)",
                        item="shell orientation",
                    )
    out = {kind: np.array(conn, dtype=np.int64) for kind, conn in elements.items()}
    for kind in SHELL_TYPES:
        if kind not in out or not len(out[kind]):
            continue
        flip = np.array([turned[(kind, k)] for k in range(len(out[kind]))], dtype=bool)
        out[kind][flip] = np.roll(out[kind][flip][:, ::-1], 1, axis=1)
    return out


def validate_mesh(mesh: Mesh) -> None:
    """Check a mesh before it becomes a body.

    Checks, in this order: array shapes, unique node ids, finite coordinates no larger than
    :data:`MAX_NODE_COORDINATE` in magnitude, known element types, element node indices in
    range, elements with a repeated node, unique element ids, node set indices in range,
    duplicate nodes (two nodes closer than :data:`DUPLICATE_NODE_TOLERANCE` times the mesh
    size, the diagonal of its bounding box) and nodes used by no element. Element volumes and
    orientation are checked by the element kernels.

    Raises:
        InvalidModelError: a structural error; the message names the node or element by its
            id ("unconnected node 17", "nodes 4 and 9 are at the same position", "element 3
            (tet4) uses node 12 more than once"); also a node coordinate beyond
            :data:`MAX_NODE_COORDINATE` in magnitude.
        InvalidParameterError: non-finite node coordinates (naming the node).
        UnknownItemError: an element or node set refers to a node index that does not exist,
            or an element type is unknown.
    """
    nodes = np.asarray(mesh.nodes)
    if nodes.ndim != 2 or nodes.shape[1] != 3:
        raise InvalidModelError(
            f"mesh nodes must be an (n, 3) array, got shape {nodes.shape}", item="mesh nodes"
        )
    count = len(nodes)
    node_ids = np.asarray(mesh.node_ids)
    if node_ids.shape != (count,):
        raise InvalidModelError(
            f"mesh has {count} nodes but node_ids has shape {node_ids.shape}", item="mesh nodes"
        )
    _check_unique(node_ids, "node")
    bad = np.flatnonzero(~np.isfinite(nodes).all(axis=1))
    if len(bad):
        node = node_ids[bad[0]]
        raise InvalidParameterError(
            f"node {node} has non-finite coordinates {nodes[bad[0]].tolist()}", item=f"node {node}"
        )
    # Before the search for duplicate nodes, whose squared distances would overflow.
    huge = np.flatnonzero((np.abs(nodes) > MAX_NODE_COORDINATE).any(axis=1))
    if len(huge):
        node = node_ids[huge[0]]
        raise InvalidModelError(
            f"node {node} has coordinates {nodes[huge[0]].tolist()} beyond "
            f"{MAX_NODE_COORDINATE:g} in magnitude (the largest a mesh may have)",
            item=f"node {node}",
        )

    if sum(len(connectivity) for connectivity in mesh.elements.values()) == 0:
        raise InvalidModelError(
            f"the mesh has no elements ({', '.join(ELEMENT_NODES)})", item="mesh elements"
        )
    if set(mesh.element_ids) != set(mesh.elements):
        raise InvalidModelError(
            f"element_ids has types {sorted(mesh.element_ids)} but elements has types "
            f"{sorted(mesh.elements)}",
            item="mesh elements",
        )
    used = np.zeros(count, dtype=bool)
    for kind, connectivity in mesh.elements.items():
        connectivity = np.asarray(connectivity)
        ids = np.asarray(mesh.element_ids[kind])
        _check_connectivity(kind, connectivity, ids, node_ids)
        if connectivity.size:
            used[connectivity.ravel()] = True
    _check_unique(np.concatenate([np.asarray(ids) for ids in mesh.element_ids.values()]), "element")

    for name, indices in mesh.node_sets.items():
        indices = np.asarray(indices)
        if indices.size == 0:
            continue
        if indices.dtype.kind not in "iu":
            raise InvalidModelError(
                f"node set {name!r} must hold integer node indices, got dtype {indices.dtype}",
                item=f"node set '{name}'",
            )
        wrong = indices[(indices < 0) | (indices >= count)]
        if wrong.size:
            raise UnknownItemError(
                f"node set {name!r} refers to node index {wrong[0]}, but the mesh has {count} "
                "nodes",
                item=f"node set '{name}'",
            )

    _check_duplicate_nodes(nodes, node_ids)
    unconnected = np.flatnonzero(~used)
    if len(unconnected):
        node = node_ids[unconnected[0]]
        more = len(unconnected) - 1
        listed = ", ".join(str(i) for i in node_ids[unconnected[1:6]])
        suffix = f" (and {more} more: {listed}{', ...' if more > 5 else ''})" if more else ""
        raise InvalidModelError(
            f"unconnected node {node}: no element uses it{suffix}", item=f"node {node}"
        )


def mesh_parts(
    node_count: int, elements: Mapping[str, Any], stiffness: Any = None, dofs_per_node: int = 3
) -> tuple[int, NDArray[np.int64]]:
    """The connected parts of a body: (number of parts, the part of each node, 0-based, parts
    numbered in the order of their first node). Two nodes are in one part when a chain of
    elements joins them; without elements, when a chain of nonzero entries of the nodal
    `stiffness` matrix (``dofs_per_node`` coordinates per node) couples them. A node of no
    element is a part of its own."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    rows: list[NDArray[np.int64]] = []
    columns: list[NDArray[np.int64]] = []
    for connectivity in elements.values():
        connectivity = np.asarray(connectivity, dtype=np.int64)
        if connectivity.ndim == 2 and connectivity.size:
            # Each element's nodes joined to its first node: a spanning star of the element.
            first = np.repeat(connectivity[:, :1], connectivity.shape[1] - 1, axis=1)
            rows.append(first.ravel())
            columns.append(connectivity[:, 1:].ravel())
    if not rows and stiffness is not None:
        coupling = sp.coo_matrix(stiffness)
        nonzero = coupling.data != 0
        rows.append(coupling.row[nonzero].astype(np.int64) // dofs_per_node)
        columns.append(coupling.col[nonzero].astype(np.int64) // dofs_per_node)
    index = np.int32 if node_count < 2**31 else np.int64  # half the memory of large meshes
    row = np.concatenate(rows).astype(index) if rows else np.zeros(0, dtype=index)
    column = np.concatenate(columns).astype(index) if columns else np.zeros(0, dtype=index)
    graph = sp.coo_matrix(
        (np.ones(len(row), dtype=np.int8), (row, column)), shape=(node_count, node_count)
    )
    count, labels = connected_components(graph, directed=False)
    # Renumber in the order of each part's first node.
    _, first_nodes = np.unique(labels, return_index=True)
    ranks = np.argsort(np.argsort(first_nodes))
    return int(count), ranks[labels].astype(np.int64)


def _check_unique(ids: NDArray[Any], what: str) -> None:
    values, counts = np.unique(ids, return_counts=True)
    if np.any(counts > 1):
        repeated = values[counts > 1][0]
        raise InvalidModelError(
            f"{what} id {repeated} is used {counts[counts > 1][0]} times", item=f"{what} {repeated}"
        )


def _check_connectivity(
    kind: str, connectivity: NDArray[Any], ids: NDArray[Any], node_ids: NDArray[Any]
) -> None:
    if kind not in ELEMENT_NODES:
        raise UnknownItemError(
            f"unknown element type {kind!r}; expected one of {', '.join(ELEMENT_NODES)}",
            item=f"element type '{kind}'",
        )
    width = ELEMENT_NODES[kind]
    if connectivity.ndim != 2 or connectivity.shape[1] != width:
        raise InvalidModelError(
            f"{kind} connectivity must have shape (n, {width}), got {connectivity.shape}",
            item=f"{kind} elements",
        )
    if connectivity.size and connectivity.dtype.kind not in "iu":
        raise InvalidModelError(
            f"{kind} connectivity must hold integer node indices, got dtype {connectivity.dtype}",
            item=f"{kind} elements",
        )
    if ids.shape != (len(connectivity),):
        raise InvalidModelError(
            f"{len(connectivity)} {kind} elements but element ids of shape {ids.shape}",
            item=f"{kind} elements",
        )
    count = len(node_ids)
    outside = (connectivity < 0) | (connectivity >= count)
    if outside.any():
        row, column = np.argwhere(outside)[0]
        element = ids[row]
        raise UnknownItemError(
            f"element {element} ({kind}) refers to node index {connectivity[row, column]}, but "
            f"the mesh has {count} nodes (indices 0 to {count - 1})",
            item=f"element {element}",
        )
    ordered = np.sort(connectivity, axis=1)
    repeated = ordered[:, 1:] == ordered[:, :-1]
    if repeated.any():
        row, column = np.argwhere(repeated)[0]
        element = ids[row]
        raise InvalidModelError(
            f"element {element} ({kind}) uses node {node_ids[ordered[row, column]]} more than once",
            item=f"element {element}",
        )


def _check_duplicate_nodes(nodes: NDArray[np.float64], node_ids: NDArray[Any]) -> None:
    from scipy.spatial import cKDTree

    if len(nodes) < 2:
        return
    size = float(np.linalg.norm(nodes.max(axis=0) - nodes.min(axis=0)))
    tolerance = DUPLICATE_NODE_TOLERANCE * size
    pairs = cKDTree(nodes).query_pairs(r=tolerance, output_type="ndarray")
    if len(pairs):
        first, second = sorted(pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))][0])
        distance = float(np.linalg.norm(nodes[first] - nodes[second]))
        raise InvalidModelError(
            f"nodes {node_ids[first]} and {node_ids[second]} are at the same position "
            f"{nodes[first].tolist()} (distance {distance:.3g}, at most "
            f"{DUPLICATE_NODE_TOLERANCE:g} x mesh size {size:.3g})",
            item=f"node {node_ids[first]}",
        )


# ---------------------------------------------------------------------------------------------
# Matrices


def read_abaqus_matrix(
    path: str | os.PathLike[str], dofs_per_node: int | None = None
) -> tuple[sp.csc_matrix, NDArray[np.int64], int]:
    """Read a matrix written by Abaqus ``*MATRIX GENERATE`` / ``*MATRIX OUTPUT``.

    Each data line is ``row node, row dof, column node, column dof, value``, separated by
    commas or blanks: the default ``FORMAT=MATRIX INPUT`` of ``*MATRIX OUTPUT``, the data lines
    of ``*MATRIX INPUT``. Blank lines and lines starting with ``*`` (keywords and ``**``
    comments) are skipped. Lines of three numbers (``row, column, value``: Abaqus'
    ``FORMAT=COORDINATE``, which numbers equations, not nodes) are refused because they cannot
    be mapped to mesh nodes.

    Global index of (node, dof): ``position of node * dofs_per_node + dof - 1``, the nodes in
    increasing id order (node-major, as in :class:`~flexmbd.fe.body.FlexibleBodyData`).

    Symmetrization: each off-diagonal entry whose mirror (i, j) -> (j, i) is not in the file is
    mirrored, so a file with only the lower or only the upper triangle gives the full
    symmetric matrix; when both (i, j) and (j, i) are given they must agree within
    :data:`SYMMETRY_TOLERANCE` times the largest entry, and both get their mean.

    Args:
        path: the ``.mtx`` file.
        dofs_per_node: coordinates per node; default: the largest dof number in the file.

    Returns:
        (matrix, node_ids, dofs_per_node): the symmetric matrix, csc (n_nodes *
        dofs_per_node, n_nodes * dofs_per_node) float64 in the units of the Abaqus model; the
        node ids in increasing order, (n_nodes,) int64; the number of coordinates per node.

    Raises:
        MissingFileError: ``path`` does not exist (also a FileNotFoundError).
        InvalidModelError: ``path`` is not a regular file once its links are followed (a
            folder, a FIFO, a device).
        InvalidParameterError: a bad line (wrong number of fields, a node or dof that is not a
            positive integer (negative labels are Abaqus internal nodes, which a mesh does
            not have), a dof above ``dofs_per_node``, a non-finite value), an entry given twice,
            (i, j) and (j, i) that disagree, or no entry at all; the message gives the line
            number.
    """
    path = Path(path)
    if dofs_per_node is not None and (
        isinstance(dofs_per_node, bool)
        or not isinstance(dofs_per_node, int | np.integer)
        or dofs_per_node < 1
    ):
        raise InvalidParameterError(
            f"dofs_per_node must be a positive integer, got {dofs_per_node!r}",
            item="dofs_per_node",
        )
    if path.exists():
        _check_regular_file(path, "matrix file")
    with open(path, encoding="utf-8", errors="replace") as file:
        text = file.read()

    numbers: list[int] = []
    entries: list[tuple[int, int, int, int, float]] = []
    for number, line in enumerate(text.splitlines(), start=1):
        stripped = line.strip()
        if not stripped or stripped.startswith("*"):
            continue
        entries.append(_matrix_line(path, number, stripped, dofs_per_node))
        numbers.append(number)
    if not entries:
        raise InvalidParameterError(f"{path}: no matrix entries", item=f"file '{path}'")

    table = np.array([entry[:4] for entry in entries], dtype=np.int64)
    values = np.array([entry[4] for entry in entries], dtype=np.float64)
    line_numbers = np.asarray(numbers, dtype=np.int64)
    if dofs_per_node is None:
        dofs_per_node = int(max(table[:, 1].max(), table[:, 3].max()))
    node_ids = np.unique(np.concatenate([table[:, 0], table[:, 2]]))
    rows = np.searchsorted(node_ids, table[:, 0]) * dofs_per_node + table[:, 1] - 1
    columns = np.searchsorted(node_ids, table[:, 2]) * dofs_per_node + table[:, 3] - 1
    size = len(node_ids) * dofs_per_node
    matrix = _symmetrize(path, rows, columns, values, line_numbers, size)
    return matrix, node_ids.astype(np.int64), int(dofs_per_node)


def _matrix_line(
    path: Path, number: int, line: str, dofs_per_node: int | None
) -> tuple[int, int, int, int, float]:
    item = f"line {number} of '{path}'"
    fields = line.replace(",", " ").split()
    if len(fields) == 3:
        raise InvalidParameterError(
            f"{path}, line {number}: 3 fields (row, column, value) is Abaqus' FORMAT=COORDINATE, "
            "which numbers equations, not nodes; write the matrix with *MATRIX OUTPUT, "
            f"FORMAT=MATRIX INPUT (node, dof, node, dof, value): {line!r}",
            item=item,
        )
    if len(fields) != 5:
        raise InvalidParameterError(
            f"{path}, line {number}: expected 5 fields (row node, row dof, column node, column "
            f"dof, value), got {len(fields)}: {line!r}",
            item=item,
        )
    integers = []
    for token, what in zip(
        fields[:4], ("row node", "row dof", "column node", "column dof"), strict=True
    ):
        try:
            value = int(token)
        except ValueError:
            try:
                real = float(token)
            except ValueError:
                real = math.nan
            if not real.is_integer():
                raise InvalidParameterError(
                    f"{path}, line {number}: {what} {token!r} is not an integer: {line!r}",
                    item=item,
                ) from None
            value = int(real)
        if value < 1:
            detail = " (negative labels are Abaqus internal nodes)" if "node" in what else ""
            raise InvalidParameterError(
                f"{path}, line {number}: {what} {value} must be positive{detail}: {line!r}",
                item=item,
            )
        integers.append(value)
    if dofs_per_node is not None and max(integers[1], integers[3]) > dofs_per_node:
        raise InvalidParameterError(
            f"{path}, line {number}: dof {max(integers[1], integers[3])} > dofs_per_node "
            f"{dofs_per_node}: {line!r}",
            item=item,
        )
    try:
        entry = float(fields[4].replace("D", "E").replace("d", "e"))
    except ValueError:
        entry = math.nan
    if not math.isfinite(entry):
        raise InvalidParameterError(
            f"{path}, line {number}: value {fields[4]!r} is not a finite number: {line!r}",
            item=item,
        )
    return integers[0], integers[1], integers[2], integers[3], entry


def _symmetrize(
    path: Path,
    rows: NDArray[np.int64],
    columns: NDArray[np.int64],
    values: NDArray[np.float64],
    line_numbers: NDArray[np.int64],
    size: int,
) -> sp.csc_matrix:
    """Full symmetric matrix from entries given in one or both triangles (rule in
    :func:`read_abaqus_matrix`)."""
    import scipy.sparse as sp

    keys = rows * size + columns
    order = np.argsort(keys, kind="stable")
    sorted_keys = keys[order]
    twice = np.flatnonzero(sorted_keys[1:] == sorted_keys[:-1])
    if len(twice):
        first, second = line_numbers[order[twice[0]]], line_numbers[order[twice[0] + 1]]
        raise InvalidParameterError(
            f"{path}, line {second}: entry ({rows[order[twice[0]]]}, "
            f"{columns[order[twice[0]]]}) given again (first on line {first})",
            item=f"line {second} of '{path}'",
        )
    mirror_keys = columns * size + rows
    position = np.searchsorted(sorted_keys, mirror_keys)
    position = np.minimum(position, len(sorted_keys) - 1)
    has_mirror = sorted_keys[position] == mirror_keys
    partner = order[position]
    off_diagonal = rows != columns

    paired = np.flatnonzero(has_mirror & off_diagonal)
    scale = float(np.abs(values).max())
    mismatch = np.abs(values[paired] - values[partner[paired]]) > SYMMETRY_TOLERANCE * scale
    if mismatch.any():
        k = paired[np.flatnonzero(mismatch)[0]]
        raise InvalidParameterError(
            f"{path}, line {line_numbers[k]}: entry ({rows[k]}, {columns[k]}) = {values[k]!r} "
            f"but its mirror on line {line_numbers[partner[k]]} is {values[partner[k]]!r}",
            item=f"line {line_numbers[k]} of '{path}'",
        )
    values = values.copy()
    values[paired] = 0.5 * (values[paired] + values[partner[paired]])

    lonely = np.flatnonzero(~has_mirror & off_diagonal)
    all_rows = np.concatenate([rows, columns[lonely]])
    all_columns = np.concatenate([columns, rows[lonely]])
    all_values = np.concatenate([values, values[lonely]])
    matrix = sp.coo_matrix((all_values, (all_rows, all_columns)), shape=(size, size))
    return sp.csc_matrix(matrix)


def matrices_from_arrays(stiffness: Any, mass: Any) -> tuple[sp.csc_matrix, sp.csc_matrix]:
    """Check a stiffness and a mass matrix given directly (NumPy arrays or SciPy sparse
    matrices) and return them as new float64 csc matrices (values unchanged).

    Each must be real, 2-D, square, finite and symmetric within :data:`SYMMETRY_TOLERANCE`
    times its largest entry, without negative diagonal entries (both are positive
    semi-definite), and both must have the same shape (n_dofs, n_dofs).

    Raises:
        InvalidParameterError: naming the matrix ("stiffness matrix", "mass matrix") and, for
            asymmetry or a non-finite value, the entry.
    """
    stiffness = _checked_matrix(stiffness, "stiffness matrix")
    mass = _checked_matrix(mass, "mass matrix")
    if stiffness.shape != mass.shape:
        raise InvalidParameterError(
            f"stiffness matrix has shape {stiffness.shape} but mass matrix has shape {mass.shape}",
            item="mass matrix",
        )
    for matrix, what in ((stiffness, "stiffness matrix"), (mass, "mass matrix")):
        # A positive semi-definite matrix has no negative diagonal entry (a matrix of the
        # wrong sign, -K, has them all).
        diagonal = matrix.diagonal()
        scale = max(float(np.abs(diagonal).max()), 1e-300)
        negative = np.flatnonzero(diagonal < -SYMMETRY_TOLERANCE * scale)
        if len(negative):
            k = int(negative[0])
            raise InvalidParameterError(
                f"{what} has a negative diagonal entry A[{k}, {k}] = {diagonal[k]:.6g} "
                f"({len(negative)} in all), which no {what.split()[0]} matrix has (positive "
                "semi-definite): a wrong sign or a wrong matrix",
                item=what,
            )
    return stiffness, mass


def _checked_matrix(matrix: Any, what: str) -> sp.csc_matrix:
    import scipy.sparse as sp

    if sp.issparse(matrix):
        dtype = matrix.dtype
    else:
        try:
            matrix = np.asarray(matrix)
        except (ValueError, TypeError) as error:
            raise InvalidParameterError(f"{what} is not a matrix: {error}", item=what) from None
        dtype = matrix.dtype
    if dtype.kind not in "biuf":
        raise InvalidParameterError(f"{what} must be real, got dtype {dtype}", item=what)
    if matrix.ndim != 2 or matrix.shape[0] != matrix.shape[1] or matrix.shape[0] == 0:
        raise InvalidParameterError(
            f"{what} must be square and not empty, got shape {matrix.shape}", item=what
        )
    result = sp.csc_matrix(matrix, dtype=np.float64, copy=True)
    result.sum_duplicates()
    if not np.isfinite(result.data).all():
        row, column = _entry_where(result, ~np.isfinite(result.data))
        raise InvalidParameterError(
            f"{what} has a non-finite entry at ({row}, {column})", item=what
        )
    scale = float(np.abs(result.data).max()) if result.nnz else 0.0
    difference = (result - result.T).tocsc()
    difference.eliminate_zeros()
    if difference.nnz:
        worst = np.abs(difference.data)
        if worst.max() > SYMMETRY_TOLERANCE * scale:
            row, column = _entry_where(difference, worst == worst.max())
            raise InvalidParameterError(
                f"{what} is not symmetric: |A[{row}, {column}] - A[{column}, {row}]| = "
                f"{worst.max():.3g} > {SYMMETRY_TOLERANCE:g} x max|A| = {scale:.3g}",
                item=what,
            )
    return result


def _entry_where(matrix: sp.csc_matrix, mask: NDArray[np.bool_]) -> tuple[int, int]:
    """(row, column) of the first stored entry of a csc matrix selected by ``mask``."""
    k = int(np.flatnonzero(mask)[0])
    column = int(np.searchsorted(matrix.indptr, k, side="right") - 1)
    return int(matrix.indices[k]), column


__all__ = [
    "SHELL_TYPES",
    "Mesh",
    "matrices_from_arrays",
    "orient_shells",
    "read_abaqus_matrix",
    "read_mesh",
    "shell_neighbours",
    "shell_pairs",
    "validate_mesh",
]
