"""Animations of a :class:`flexmbd.Result`: ParaView time series and rendered images.

* :func:`write_vtu_series` writes one VTK ``.vtu`` file per output record (through meshio) and
  a ``.pvd`` collection with their times, for ParaView.
* :func:`render_animation` renders the moving, deforming mechanism into an animated GIF or a
  PNG sequence, :func:`render_image` one record into a PNG, SVG or PDF, and
  :func:`render_frame` one record into a matplotlib 3D ``Axes``. matplotlib draws off screen
  (Agg) by default; ``backend="pyvista"`` uses pyvista (VTK) off screen if it is installed and
  the machine can render without a display (EGL or OSMesa).

What is drawn
-------------
* Deformable bodies: their meshes at the deformed node positions ``r = R + A (u0 + s u_f)``
  (``s`` the deformation scale; ``s = 1`` gives :meth:`Result.node_positions`): beams as
  lines, solids as their boundary faces, coloured by the elastic displacement |u_f| or the
  von Mises stress.
* Rigid bodies and point masses: a dot at the body frame origin and a line from it to each of
  its joint markers ("sticks"), so that a crank or a link appears as its lines.
* Joints: their markers (dots; on the ground, triangles), and a line between the two markers
  when they are apart (distance joints). Joints whose markers are not located are drawn as a
  dashed line between the origins of their two bodies.

Where the markers are
---------------------
The model description (:meth:`Model.describe`) lists each marker's body; where it also gives
the marker's ``position`` in the body frame, that position is used. Otherwise a marker with a
position sensor follows the sensor, and the two markers of a joint whose origins stay together
(revolute, spherical, universal, fixed joints, in-line joints of a planar loop, ...) are
located from the recorded motion: the body-frame points p_1, p_2 that minimize
sum_t |R_1 + A_1 p_1 - R_2 - A_2 p_2|^2 (a linear least-squares problem; the minimum-norm
solution along a hinge axis). A fit whose rms residual exceeds 1 % of the model size is
rejected (sliders, distance joints). A marker found within 2 % of the body size of a node of a
deformable body moves with that node.

The deformation scale
---------------------
``scale=None`` (the default of the renderers) magnifies small deformations so that the
largest elastic displacement over the shown records is 10 % of the model size (never below 1);
the scale is written in the image titles. :func:`write_vtu_series` writes the true geometry
(``scale=1``) unless told otherwise.
"""

from __future__ import annotations

import functools
import logging
import math
import os
import re
import xml.etree.ElementTree as ElementTree
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .errors import InvalidParameterError
from .fe.body import cell_of
from .fe.mesh_io import WEDGE_MIRRORS
from .progress import status
from .progress import track as track_progress
from .simulation import logger

Array = NDArray[np.float64]

#: Fraction of the model size that the largest scaled displacement reaches (``scale=None``).
AUTO_SCALE_FRACTION = 0.1
#: Largest rms residual of a joint-marker fit, as a fraction of the model size.
MARKER_FIT_TOLERANCE = 1e-2
#: Largest distance from a fitted marker to a node it snaps to, as a fraction of the body size.
NODE_SNAP_TOLERANCE = 2e-2
#: Records used to fit joint markers (evenly spread over the run).
MARKER_FIT_RECORDS = 200

#: flexmbd element type -> (meshio cell type, node permutation into VTK order).
VTK_CELLS: dict[str, tuple[str, NDArray[np.int64] | None]] = {
    "beam2": ("line", None),
    "tet4": ("tetra", None),
    "tet10": ("tetra10", np.array([0, 1, 2, 3, 4, 5, 6, 7, 9, 8])),
    "hex8": ("hexahedron", None),
    "hex20": ("hexahedron20", None),
    "hex27": ("hexahedron27", None),
    # (wedges in VTK 9.7's order, which is ours: meshio mirrors its linear wedge on writing,
    # to VTK's order before 9.7, so it is mirrored first; flexmbd.fe.mesh_io's docstring)
    "wedge6": ("wedge", WEDGE_MIRRORS["wedge6"]),
    "wedge15": ("wedge15", None),
    "wedge18": ("wedge18", None),
    "pyramid5": ("pyramid", None),
    "pyramid13": ("pyramid13", None),
    # (VTK has no 14-node pyramid: drawn as the 13-node one, the base's centre left out)
    "pyramid14": ("pyramid13", np.arange(13)),
    "quad4": ("quad", None),
    "tri3": ("triangle", None),
}

#: Element types of shells (their stresses have top and bottom surfaces).
SHELL_TYPES = ("quad4", "tri3")

#: Boundary faces of the solid elements, by their corner nodes (outward normals).
ELEMENT_FACES: dict[str, tuple[tuple[int, ...], ...]] = {
    "tet4": ((0, 2, 1), (0, 1, 3), (1, 2, 3), (0, 3, 2)),
    "tet10": ((0, 2, 1), (0, 1, 3), (1, 2, 3), (0, 3, 2)),
    "hex8": (
        (0, 3, 2, 1),
        (4, 5, 6, 7),
        (0, 1, 5, 4),
        (1, 2, 6, 5),
        (2, 3, 7, 6),
        (3, 0, 4, 7),
    ),
    "quad4": ((0, 1, 2, 3),),
    "tri3": ((0, 1, 2),),
}
# (a hex20's faces by their corners: the surfaces drawn are flat between them)
ELEMENT_FACES["hex20"] = ELEMENT_FACES["hex27"] = ELEMENT_FACES["hex8"]
ELEMENT_FACES["wedge6"] = ((0, 2, 1), (3, 4, 5), (0, 1, 4, 3), (1, 2, 5, 4), (2, 0, 3, 5))
ELEMENT_FACES["wedge15"] = ELEMENT_FACES["wedge18"] = ELEMENT_FACES["wedge6"]
ELEMENT_FACES["pyramid5"] = ((0, 3, 2, 1), (0, 1, 4), (1, 2, 4), (2, 3, 4), (3, 0, 4))
ELEMENT_FACES["pyramid13"] = ELEMENT_FACES["pyramid14"] = ELEMENT_FACES["pyramid5"]

#: Named views: (elevation, azimuth) in degrees, orthographic.
VIEWS: dict[str, tuple[float, float]] = {
    "xy": (90.0, -90.0),
    "xz": (0.0, -90.0),
    "yz": (0.0, 0.0),
    "iso": (25.0, -60.0),
}


#: The axis along the line of sight of the plane views.
VIEW_DEPTH_AXES: dict[tuple[float, float], str] = {
    VIEWS["xy"]: "z",
    VIEWS["xz"]: "y",
    VIEWS["yz"]: "x",
}


# Geometry of a result ------------------------------------------------------------------------
@dataclass
class _Part:
    """A deformable body to draw: its data and the rows of its elastic basis that give the
    translations of its nodes (3 nodes, n_f), body axes."""

    body: int
    name: str
    data: Any
    basis: Any
    size: float
    has_solids: bool


@dataclass
class Scene:
    """The geometry of a result to draw, shared by the VTU writer and the renderers.

    Attributes:
        result: the :class:`flexmbd.Result`.
        parts: the deformable bodies (meshes).
        markers: marker index -> (body index, local position (3,) or None, node index or
            None, position sensor name or None); only markers that are drawn.
        sticks: (body index, marker index) lines of the rigid bodies and point masses.
        links: (marker 1, marker 2) of joints whose markers are both located.
        connectors: (body 1, body 2) of joints drawn between body origins.
        size: the model size (m): the diagonal of the box around the undeformed geometry
            over the run, at least 1e-9.
        origins: the rigid bodies and point masses whose origins are drawn.
    """

    result: Any
    parts: list[_Part]
    markers: dict[int, tuple[int, Array | None, int | None, str | None]]
    sticks: list[tuple[int, int]]
    links: list[tuple[int, int]]
    connectors: list[tuple[int, int]]
    size: float
    origins: list[int] = field(default_factory=list)

    # Poses and nodes ---------------------------------------------------------------------
    def pose(self, body: int, records: NDArray[np.int64]) -> tuple[Array, Array]:
        """Body frame origin (k, 3) and rotation (k, 3, 3) at the given records; the ground
        and point masses do not turn."""
        entry = self.result.layout["bodies"][body]
        k = len(records)
        if entry["kind"] == "ground":
            return np.zeros((k, 3)), np.broadcast_to(np.eye(3), (k, 3, 3)).copy()
        position = self.result.position(body)[records]
        if entry["kind"] == "point_mass":
            return position, np.broadcast_to(np.eye(3), (k, 3, 3)).copy()
        return position, self.result.orientation(body)[records]

    def displacements(self, part: _Part, records: NDArray[np.int64]) -> Array:
        """Elastic displacements of the nodes of a part, body axes (k, nodes, 3), m."""
        q_f = self.result.elastic_coordinates(part.body)[records]
        u = np.asarray(part.basis @ q_f.T).T
        return u.reshape(len(records), len(part.data.nodes), 3)

    def nodes(
        self, part: _Part, records: NDArray[np.int64], scale: float = 1.0
    ) -> tuple[Array, Array]:
        """Global positions of the deformed nodes with the displacement scaled by `scale`,
        and the global elastic displacements (unscaled): two (k, nodes, 3) arrays."""
        position, rotation = self.pose(part.body, records)
        u = self.displacements(part, records)
        local = part.data.nodes[None, :, :] + scale * u
        points = position[:, None, :] + np.einsum("tij,tnj->tni", rotation, local)
        return points, np.einsum("tij,tnj->tni", rotation, u)

    def marker_tracks(self, records: NDArray[np.int64], scale: float = 1.0) -> dict[int, Array]:
        """Global positions (k, 3) of the drawn markers at the given records."""
        tracks: dict[int, Array] = {}
        parts = {part.body: part for part in self.parts}
        node_cache: dict[int, Array] = {}
        for marker, (body, local, node, sensor) in self.markers.items():
            # A marker at a node moves with the drawn (magnified) node, also when a sensor
            # records it (the sensor's true-scale track drew it 0.1 m off its node at x712).
            if node is not None:
                if body not in node_cache:
                    node_cache[body] = self.nodes(parts[body], records, scale)[0]
                tracks[marker] = node_cache[body][:, node]
            elif sensor is not None:
                tracks[marker] = self.result.sensor(sensor)[records]
            elif local is not None:
                position, rotation = self.pose(body, records)
                tracks[marker] = position + rotation @ local
        return tracks

    def largest_displacement(self, records: NDArray[np.int64]) -> float:
        """Largest elastic displacement |u_f| of any node at the given records (m)."""
        largest = 0.0
        for part in self.parts:
            u = self.displacements(part, records)
            if u.size:
                largest = max(largest, float(np.max(np.linalg.norm(u, axis=2))))
        return largest

    def auto_scale(self, records: NDArray[np.int64]) -> float:
        """The deformation scale that makes the largest displacement AUTO_SCALE_FRACTION of
        the model size (at least 1)."""
        largest = self.largest_displacement(records)
        if largest <= 0.0:
            return 1.0
        return max(1.0, AUTO_SCALE_FRACTION * self.size / largest)


def _bounding_size(points: Array) -> float:
    if len(points) == 0:
        return 0.0
    return float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))


def _spread(count: int, wanted: int) -> NDArray[np.int64]:
    """`wanted` record indices spread evenly over 0 .. count - 1 (all if fewer)."""
    if count <= wanted:
        return np.arange(count)
    return np.unique(np.round(np.linspace(0, count - 1, wanted)).astype(np.int64))


def build_scene(result: Any) -> Scene:
    """The geometry of `result` to draw (see the module docstring); raises
    :class:`InvalidParameterError` if the result has no records."""
    from .system import elastic_basis

    if len(result.time) == 0:
        raise InvalidParameterError("the result has no records to draw")
    layout = result.layout
    bodies = layout["bodies"]
    parts: list[_Part] = []
    for index, entry in enumerate(bodies):
        if entry["kind"] != "flexible" or index not in result.flexible:
            continue
        data = result.flexible[index]
        d = data.dofs_per_node
        rows = (np.arange(len(data.nodes))[:, None] * d + np.arange(3)[None, :]).ravel()
        parts.append(
            _Part(
                body=index,
                name=entry["name"],
                data=data,
                basis=elastic_basis(data)[rows],
                size=max(_bounding_size(np.asarray(data.nodes)), 1e-12),
                has_solids=any(kind != "beam2" for kind in data.elements),
            )
        )
    scene = Scene(result, parts, {}, [], [], [], 1.0)
    sample = _spread(len(result.time), MARKER_FIT_RECORDS)

    # Model size: the box around the body origins and undeformed meshes over the run.
    points = [np.zeros((1, 3))]
    for index, entry in enumerate(bodies):
        if entry["kind"] != "ground":
            points.append(scene.pose(index, sample)[0])
    for part in parts:
        position, rotation = scene.pose(part.body, sample[[0, -1]])
        nodes = position[:, None, :] + np.einsum("tij,nj->tni", rotation, part.data.nodes)
        points.append(nodes.reshape(-1, 3))
    scene.size = max(_bounding_size(np.concatenate(points)), 1e-9)

    # Markers: from the layout, from position sensors, or fitted to the joint motion.
    marker_entries = layout["markers"]
    located: dict[int, Array | None] = {}
    for marker, entry in enumerate(marker_entries):
        if entry.get("position") is not None:
            located[marker] = np.asarray(entry["position"], dtype=float)
    # Position sensors with records (a mode shape's result, built from the linearization, has
    # none: its markers are placed from the joint motion as any others).
    sensors = {
        s["marker"]: s["name"]
        for s in layout.get("sensors", [])
        if s["quantity"] == "position" and np.shape(result.sensor(s["name"]))[-1] == 3
    }
    poses = {index: scene.pose(index, sample) for index in range(len(bodies))}
    joint_markers: list[tuple[int, int]] = []
    for joint in layout["joints"]:
        m1, m2 = (int(m) for m in joint["markers"])
        joint_markers.append((m1, m2))
        if m1 in located and m2 in located:
            continue
        b1, b2 = marker_entries[m1]["body"], marker_entries[m2]["body"]
        fit = _fit_common_point(poses[b1], poses[b2], scene.size)
        if fit is not None:
            located.setdefault(m1, fit[0])
            located.setdefault(m2, fit[1])
    parts_by_body = {part.body: part for part in parts}
    used = {m for pair in joint_markers for m in pair} | set(sensors)
    for marker in sorted(used):
        body = marker_entries[marker]["body"]
        local = located.get(marker)
        node = None
        if body in parts_by_body and local is not None:
            part = parts_by_body[body]
            distance = np.linalg.norm(part.data.nodes - local, axis=1)
            nearest = int(np.argmin(distance))
            if distance[nearest] <= NODE_SNAP_TOLERANCE * part.size:
                node = nearest
        sensor = sensors.get(marker)
        if local is None and sensor is None:
            continue
        scene.markers[marker] = (body, local, node, sensor)

    # Lines: sticks of rigid bodies to their markers, joints between markers or origins.
    for marker, (body, _, _, _) in scene.markers.items():
        if bodies[body]["kind"] in ("rigid", "point_mass"):
            scene.sticks.append((body, marker))
    for m1, m2 in dict.fromkeys(joint_markers):
        if m1 in scene.markers and m2 in scene.markers:
            scene.links.append((m1, m2))
        else:
            pair = (marker_entries[m1]["body"], marker_entries[m2]["body"])
            if pair not in scene.connectors:
                scene.connectors.append(pair)
    scene.origins = [
        index for index, entry in enumerate(bodies) if entry["kind"] in ("rigid", "point_mass")
    ]
    return scene


def _fit_common_point(
    pose1: tuple[Array, Array], pose2: tuple[Array, Array], size: float
) -> tuple[Array, Array] | None:
    """Body-frame points p1, p2 of two bodies that stay together over the sampled motion:
    the least-squares solution of R1 + A1 p1 = R2 + A2 p2 (minimum norm where the motion
    leaves them undetermined), or None if the rms gap exceeds MARKER_FIT_TOLERANCE * size."""
    position1, rotation1 = pose1
    position2, rotation2 = pose2
    k = len(position1)
    # Stack [A1, -A2] [p1; p2] = R2 - R1 over the records.
    matrix = np.concatenate([rotation1, -rotation2], axis=2).reshape(3 * k, 6)
    rhs = (position2 - position1).reshape(3 * k)
    solution = np.linalg.lstsq(matrix, rhs, rcond=1e-9)[0]
    gap = (matrix @ solution - rhs).reshape(k, 3)
    rms = math.sqrt(float(np.mean(np.sum(gap**2, axis=1))))
    if rms > MARKER_FIT_TOLERANCE * size:
        return None
    return solution[:3], solution[3:]


# ParaView: VTU files and a PVD collection -----------------------------------------------------
def _mesh(
    scene: Scene,
    record: int,
    scale: float,
    stresses: dict[int, Array],
) -> Any:
    """The meshio Mesh of one record: the deformable bodies' nodes first (bodies in index
    order, nodes in mesh order), then the mechanism (origins, sticks, joints)."""
    import meshio

    from .fe.mesh_io import complete_meshio

    complete_meshio()  # (its wedge15 cells)

    records = np.array([record])
    layout_bodies = scene.result.layout["bodies"]
    points: list[Array] = []
    displacement: list[Array] = []
    body_of_point: list[NDArray[np.int32]] = []
    von_mises: list[Array] = []
    stress: list[Array] = []
    surfaces: list[Array] = []
    cells: list[tuple[str, NDArray[np.int64]]] = []
    cell_body: list[NDArray[np.int32]] = []
    offset = 0

    def add_points(p: Array, body: int, u: Array | None = None) -> int:
        nonlocal offset
        start = offset
        points.append(p)
        displacement.append(np.zeros_like(p) if u is None else u)
        body_of_point.append(np.full(len(p), body, dtype=np.int32))
        von_mises.append(np.zeros(len(p)))
        stress.append(np.zeros((len(p), 6)))
        surfaces.append(np.zeros((len(p), 2, 6)))
        offset += len(p)
        return start

    for part in scene.parts:
        nodes, u = scene.nodes(part, records, scale)
        start = add_points(nodes[0], part.body, u[0])
        if part.body in stresses:
            sigma = stresses[part.body]
            rotation = scene.pose(part.body, records)[1][0]
            from .fe.stress import largest_von_mises

            levels = (
                scene.result.shell_stresses(part.body, records)[0] if _has_shells(part) else None
            )
            von_mises[-1] = largest_von_mises(sigma, levels)
            stress[-1] = _paraview_tensor(sigma, rotation)
            if levels is not None:
                for k, level in enumerate((0, 2)):
                    surfaces[-1][:, k] = _paraview_tensor(levels[:, level], rotation)
        for kind, connectivity in part.data.elements.items():
            cell_type, order = VTK_CELLS[cell_of(kind)]
            conn = np.asarray(connectivity, dtype=np.int64)
            if order is not None:
                conn = conn[:, order]
            cells.append((cell_type, conn + start))
            cell_body.append(np.full(len(conn), part.body, dtype=np.int32))

    tracks = {m: t[0] for m, t in scene.marker_tracks(records, scale).items()}
    origin = {b: scene.pose(b, records)[0][0] for b in range(len(layout_bodies))}
    if scene.origins:
        start = add_points(np.array([origin[b] for b in scene.origins]), -1)
        body_of_point[-1] = np.array(scene.origins, dtype=np.int32)
        cells.append(("vertex", np.arange(start, start + len(scene.origins))[:, None]))
        cell_body.append(np.array(scene.origins, dtype=np.int32))
    segments: list[tuple[Array, Array, int]] = []
    for body, marker in scene.sticks:
        segments.append((origin[body], tracks[marker], body))
    for m1, m2 in scene.links:
        segments.append((tracks[m1], tracks[m2], scene.markers[m2][0]))
    for b1, b2 in scene.connectors:
        segments.append((origin[b1], origin[b2], b2))
    if segments:
        ends = np.array([[a, b] for a, b, _ in segments]).reshape(-1, 3)
        owners = np.array([body for _, _, body in segments], dtype=np.int32)
        start = add_points(ends, -1)
        body_of_point[-1] = np.repeat(owners, 2)
        cells.append(("line", start + np.arange(2 * len(segments)).reshape(-1, 2)))
        cell_body.append(owners)
    point_data = {
        "displacement": np.concatenate(displacement),
        "body": np.concatenate(body_of_point),
    }
    if stresses:
        point_data["von_mises"] = np.concatenate(von_mises)
        point_data["stress"] = np.concatenate(stress)
        if any(_has_shells(part) for part in scene.parts if part.body in stresses):
            both = np.concatenate(surfaces)
            point_data["stress_top"] = both[:, 0]
            point_data["stress_bottom"] = both[:, 1]
    return meshio.Mesh(
        np.concatenate(points),
        cells,
        point_data=point_data,
        cell_data={"body": cell_body},
    )


def _has_shells(part: Any) -> bool:
    return any(len(part.data.elements.get(kind, ())) for kind in SHELL_TYPES)


def _nodal_von_mises(result: Any, part: Any, records: Array) -> Array:
    """Von Mises stress at the nodes of a part (records, nodes): of the solids, and for shells
    the largest of their top, middle and bottom surfaces (`Result.von_mises`)."""
    return result.von_mises(part.body, records)


def _paraview_tensor(stress: Array, rotation: Array) -> Array:
    """Voigt stresses (nodes, 6: xx, yy, zz, yz, xz, xy) in body axes -> global axes in
    ParaView's order of symmetric tensors (xx, yy, zz, xy, yz, xz)."""
    xx, yy, zz, yz, xz, xy = (stress[:, k] for k in range(6))
    full = np.stack(
        [np.stack([xx, xy, xz], -1), np.stack([xy, yy, yz], -1), np.stack([xz, yz, zz], -1)], -2
    )
    g = rotation @ full @ rotation.T
    return np.stack(
        [g[:, 0, 0], g[:, 1, 1], g[:, 2, 2], g[:, 0, 1], g[:, 1, 2], g[:, 0, 2]], axis=-1
    )


def _records(result: Any, every: int, times: Sequence[float] | None = None) -> NDArray[np.int64]:
    """The records of a series: those in the time window `times` (start, end; s, inclusive;
    None: all), then every `every`-th of them from the first, and the last of the window."""
    if isinstance(every, bool) or not isinstance(every, int | np.integer) or every < 1:
        raise InvalidParameterError(
            f"every must be a positive integer, got {every!r}", item="every"
        )
    time = np.asarray(result.time, dtype=float)
    if times is None:
        inside = np.arange(len(time))
    else:
        start, end = _time_window(times)
        # Records at a window's ends count in, whatever the rounding of their times.
        slack = 1e-12 * max(1.0, float(np.max(np.abs(time), initial=0.0)))
        inside = np.flatnonzero((time >= start - slack) & (time <= end + slack))
        if len(inside) == 0:
            span = f"{time[0]:g} .. {time[-1]:g} s" if len(time) else "none"
            raise InvalidParameterError(
                f"no record in times {start:g} .. {end:g} s (the records: {span})", item="times"
            )
    if len(inside) == 0:
        return inside.astype(np.int64)
    records = inside[:: int(every)]
    if records[-1] != inside[-1]:
        records = np.append(records, inside[-1])
    return records.astype(np.int64)


def _time_window(times: Sequence[float]) -> tuple[float, float]:
    """`times` as (start, end), checked: two numbers (not NaN), start <= end."""
    if isinstance(times, str | bytes):  # ("01" was the window (0, 1))
        raise InvalidParameterError(f"times must be (start, end) in s, got {times!r}", item="times")
    try:
        start, end = (float(t) for t in times)
    except (TypeError, ValueError):
        raise InvalidParameterError(
            f"times must be (start, end) in s, got {times!r}", item="times"
        ) from None
    if math.isnan(start) or math.isnan(end) or start > end:
        raise InvalidParameterError(
            f"times must be (start, end) with start <= end, got ({start:g}, {end:g})", item="times"
        )
    return start, end


#: Bytes per point of a written ``.vtu`` file: position, displacement (3 float64 each), body
#: (int32); with stress also von_mises and the 6 stress components (float64).
_POINT_BYTES, _STRESS_BYTES = 3 * 8 + 3 * 8 + 4, 7 * 8
#: Bytes of file per byte of array data: meshio writes the arrays zlib-compressed, in base64
#: (4 characters per 3 bytes); the built-in examples' files are 0.40 to 0.65 of their raw data.
_WRITTEN_PER_BYTE = 0.55
#: Bytes of every file besides the bodies' arrays: XML, the mechanism's points and lines.
_FILE_BYTES = 2000
#: A ParaView series larger than this (bytes) is announced by the command line and logged as a
#: warning: a run with many records of a fine mesh writes gigabytes.
LARGE_VTU_SERIES = 200e6


def vtu_series_size(
    result: Any,
    every: int = 1,
    *,
    times: Sequence[float] | None = None,
    stress: bool = True,
) -> tuple[int, float]:
    """What :func:`write_vtu_series` with these arguments would write: (number of ``.vtu``
    files, estimated total size in bytes). The estimate is nodes x fields x files (positions,
    displacement, body, and stresses of solid bodies) plus the cells, times the ratio of
    compressed base64 text to raw data seen on the built-in examples (within a factor 1.5 of
    the files written). Raises what the writer raises for `every` and
    `times`."""
    files = len(_records(result, every, times))
    per_file = 0.0
    for index, entry in enumerate(result.layout["bodies"]):
        if entry["kind"] != "flexible" or index not in result.flexible:
            continue
        data = result.flexible[index]
        solids = any(kind != "beam2" for kind in data.elements)
        per_file += len(data.nodes) * (_POINT_BYTES + (_STRESS_BYTES if stress and solids else 0))
        for connectivity in data.elements.values():
            shape = np.shape(connectivity)
            if len(shape) == 2:
                # Connectivity and offsets (int64), type (uint8) and body (int32) per cell.
                per_file += shape[0] * (8 * shape[1] + 8 + 1 + 4)
    return files, files * (per_file * _WRITTEN_PER_BYTE + _FILE_BYTES)


def _scale_value(scene: Scene, scale: float | str | None, records: NDArray[np.int64]) -> float:
    if scale is None or scale == "auto":
        return scene.auto_scale(records)
    bad = InvalidParameterError(
        f"scale must be a non-negative number, None or 'auto', got {scale!r}", item="scale"
    )
    if isinstance(scale, str | bool) or not isinstance(scale, int | float | np.number):
        raise bad  # ([2] was a bare TypeError)
    if not math.isfinite(float(scale)) or float(scale) < 0.0:
        raise bad
    return float(scale)


def write_vtu_series(
    result: Any,
    directory: str | os.PathLike[str],
    every: int = 1,
    scale: float | str | None = 1.0,
    *,
    name: str = "result",
    stress: bool = True,
    times: Sequence[float] | None = None,
    progress: bool | Callable[[int, int], object] | None = None,
) -> Path:
    """Writes the motion of `result` for ParaView: ``<name>_00000.vtu`` ... (one VTK
    unstructured grid per written record) and ``<name>.pvd`` (their times, s) into
    `directory` (created if needed); returns the path of the ``.pvd``.

    Records 0, every, 2 every, ... and the last are written; with `times` = (start, end) (s,
    inclusive), only the records in that window: its first, every `every`-th after it, and
    its last. :func:`vtu_series_size` tells beforehand how many files and about how many
    bytes that is (a fine mesh over many records is gigabytes). Each file holds, in this order,
    the nodes of the deformable bodies (bodies in index order, nodes in mesh order; their
    cells are the mesh elements: lines, tetra, tetra10, hexahedron), then the mechanism: a
    vertex at each rigid body and point mass origin and lines for the rigid bodies' sticks and
    the joints (see the module docstring). Point positions are global, m; with ``scale=1`` the
    nodes are :meth:`Result.node_positions`, otherwise the elastic displacement is multiplied
    by `scale` (None or ``"auto"``: the automatic scale).

    Point data: ``displacement`` (the true elastic displacement A u_f, global axes, m; zero on
    the mechanism), ``body`` (body index; -1 for none) and, if `stress` and a deformable body
    has solid elements, ``von_mises`` (Pa) and ``stress`` (Pa, global axes, ParaView's order
    xx, yy, zz, xy, yz, xz; zero on beams and the mechanism). Cell data: ``body``.

    `progress`: True shows a progress bar of the files written (:func:`flexmbd.progress.track`),
    a function is called as ``progress(done, total)``. Frames ``<name>_NNNNN.vtu`` of an
    earlier, longer series of the same name in `directory` are removed. Raises
    `InvalidParameterError` for a `name` with a folder in it, an empty or hidden one, and a
    `directory` that is a file."""
    if not isinstance(name, str) or not re.fullmatch(r"[^/\\.][^/\\]*", name):
        raise InvalidParameterError(
            f"name: the file name of the series (no folder, not empty or hidden), got {name!r}",
            item="name",
        )
    if Path(directory).exists() and not Path(directory).is_dir():
        raise InvalidParameterError(
            f"directory: '{directory}' is a file, not a folder", item="directory"
        )
    records = _records(result, every, times)
    files, size = vtu_series_size(result, every, times=times, stress=stress)
    logger.log(
        logging.WARNING if size > LARGE_VTU_SERIES else logging.INFO,
        "writing %d VTU files (~%.0f MB) to %s",
        files,
        size / 1e6,
        directory,
    )
    scene = build_scene(result)
    factor = _scale_value(scene, scale, records)
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    stresses: dict[int, Array] = {}
    if stress:
        for part in scene.parts:
            if part.has_solids:
                stresses[part.body] = result.stresses(part.body, records)
    collection = ElementTree.Element(
        "VTKFile", type="Collection", version="0.1", byte_order="LittleEndian"
    )
    datasets = ElementTree.SubElement(collection, "Collection")
    shown = track_progress(
        enumerate(records), progress, f"writing {out}", total=len(records), unit="files"
    )
    for k, record in shown:
        mesh = _mesh(scene, int(record), factor, {b: s[k] for b, s in stresses.items()})
        file = f"{name}_{k:05d}.vtu"
        mesh.write(out / file)
        ElementTree.SubElement(
            datasets,
            "DataSet",
            timestep=repr(float(result.time[record])),
            group="",
            part="0",
            file=file,
        )
    ElementTree.indent(collection)
    pvd = out / f"{name}.pvd"
    ElementTree.ElementTree(collection).write(pvd, encoding="utf-8", xml_declaration=True)
    # Frames of an earlier, longer series of this name are not this one's (21 files were
    # left beside a .pvd of 5).
    frame = re.compile(re.escape(name) + r"_(\d{5})\.vtu")
    for stale in out.iterdir():
        match = frame.fullmatch(stale.name)
        if match and int(match.group(1)) >= len(records) and stale.is_file():
            stale.unlink()
    return pvd


def read_pvd(path: str | os.PathLike[str]) -> list[tuple[float, Path]]:
    """The (time, file) entries of a ``.pvd`` collection, in file order."""
    root = ElementTree.parse(path).getroot()
    base = Path(path).parent
    return [
        (float(entry.get("timestep", "nan")), base / str(entry.get("file")))
        for entry in root.iter("DataSet")
    ]


# Rendering with matplotlib ---------------------------------------------------------------------
@dataclass
class _Style:
    """Settings shared by the frames of an animation."""

    scale: float
    view: tuple[float, float]
    limits: Array  # (3, 2)
    color_by: str | None
    norm: Any
    label: str


def _view_angles(view: str | Sequence[float], extents: Array) -> tuple[float, float]:
    """(elevation, azimuth) of a view name, an (elevation, azimuth) pair or "auto" (a plane
    view of a planar-looking model: along the axis of smallest extent if below 10 % of the
    largest, else "iso")."""
    if isinstance(view, str):
        if view == "auto":
            axis = int(np.argmin(extents))
            if extents[axis] < 0.1 * max(float(np.max(extents)), 1e-300):
                return VIEWS[("yz", "xz", "xy")[axis]]
            return VIEWS["iso"]
        if view not in VIEWS:
            raise InvalidParameterError(
                f"unknown view {view!r}; known: 'auto', {', '.join(map(repr, VIEWS))} or "
                "(elevation, azimuth) in degrees",
                item=view,
            )
        return VIEWS[view]
    bad = InvalidParameterError(
        f"view must be a name or (elevation, azimuth) in degrees, got {view!r}", item="view"
    )
    try:  # (a number was a bare TypeError)
        angles = tuple(float(v) for v in view)
    except (TypeError, ValueError):
        raise bad from None
    if len(angles) != 2 or not all(math.isfinite(a) for a in angles):
        raise bad
    return angles[0], angles[1]


def _style(
    scene: Scene,
    records: NDArray[np.int64],
    scale: float | str | None,
    view: str | Sequence[float],
    color_by: str | None,
) -> _Style:
    from matplotlib.colors import Normalize

    if color_by not in ("displacement", "stress", None):
        raise InvalidParameterError(
            f"color_by must be 'displacement', 'stress' or None, got {color_by!r}", item=color_by
        )
    factor = _scale_value(scene, scale, records)
    # Box around everything drawn over the shown records.
    points = [np.zeros((1, 3))]
    for part in scene.parts:
        points.append(scene.nodes(part, records, factor)[0].reshape(-1, 3))
    for track in scene.marker_tracks(records, factor).values():
        points.append(track)
    for body in scene.origins:
        points.append(scene.pose(body, records)[0])
    cloud = np.concatenate(points)
    low, high = cloud.min(axis=0), cloud.max(axis=0)
    extents = high - low
    centre = (low + high) / 2
    half = 0.55 * max(float(np.max(extents)), 1e-9)
    limits = np.column_stack([centre - half, centre + half])
    top, label = 0.0, ""
    if color_by == "stress" and not any(part.has_solids for part in scene.parts):
        # (it coloured by displacement under a displacement colour bar, without a word)
        raise InvalidParameterError(
            "color_by 'stress' needs a deformable body with solid elements (von Mises of "
            "solids); use 'displacement' or None",
            item="stress",
        )
    if color_by == "displacement":
        top, label = scene.largest_displacement(records), "elastic displacement magnitude (m)"
    elif color_by == "stress":
        for part in scene.parts:
            if part.has_solids:
                top = max(top, float(np.max(_nodal_von_mises(scene.result, part, records))))
        label = "von Mises stress (Pa)"
    norm = Normalize(0.0, top if top > 0.0 else 1.0)
    return _Style(factor, _view_angles(view, extents), limits, color_by, norm, label)


def _boundary_faces(part: _Part) -> list[NDArray[np.int64]]:
    """The faces of the solid elements of a part that belong to one element only (node
    indices, corner nodes), grouped by face size."""
    faces: dict[int, list[NDArray[np.int64]]] = {}
    for kind, connectivity in part.data.elements.items():
        if cell_of(kind) not in ELEMENT_FACES:
            continue
        conn = np.asarray(connectivity, dtype=np.int64)
        for face in ELEMENT_FACES[cell_of(kind)]:
            faces.setdefault(len(face), []).append(conn[:, list(face)])
    out = []
    for group in faces.values():
        every_face = np.concatenate(group)
        keys = np.sort(every_face, axis=1)
        _, index, counts = np.unique(keys, axis=0, return_index=True, return_counts=True)
        out.append(every_face[index[counts == 1]])
    return out


def _draw(ax: Any, scene: Scene, record: int, style: _Style, cache: dict[str, Any]) -> None:
    """Draws one record into a 3D Axes."""
    from matplotlib import colormaps
    from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection

    cmap = colormaps["viridis"]
    records = np.array([record])
    result = scene.result
    for part in scene.parts:
        nodes, u = scene.nodes(part, records, style.scale)
        nodes = nodes[0]
        if style.color_by == "stress" and part.has_solids:
            value = _nodal_von_mises(result, part, records)[0]
        else:
            value = np.linalg.norm(u[0], axis=1)
        faces = cache.setdefault(f"faces {part.body}", _boundary_faces(part))
        for group in faces:
            colors = (
                cmap(style.norm(value[group].mean(axis=1)))
                if style.color_by is not None
                else "lightsteelblue"
            )
            ax.add_collection3d(
                Poly3DCollection(nodes[group], facecolors=colors, edgecolors="0.25", linewidths=0.3)
            )
        beams = part.data.elements.get("beam2")
        if beams is not None and len(beams):
            beams = np.asarray(beams, dtype=np.int64)
            colors = (
                cmap(style.norm(value[beams].mean(axis=1)))
                if style.color_by == "displacement"
                else "tab:blue"
            )
            ax.add_collection3d(Line3DCollection(nodes[beams], colors=colors, linewidths=3.0))
            ax.scatter(*nodes.T, s=6, color="0.2", depthshade=False)
    tracks = {m: t[0] for m, t in scene.marker_tracks(records, style.scale).items()}
    origin = {b: scene.pose(b, records)[0][0] for b in range(len(result.layout["bodies"]))}
    sticks = [(origin[b], tracks[m]) for b, m in scene.sticks]
    if sticks:
        ax.add_collection3d(Line3DCollection(sticks, colors="0.15", linewidths=4.0))
    links = [(tracks[a], tracks[b]) for a, b in scene.links]
    if links:
        ax.add_collection3d(Line3DCollection(links, colors="tab:red", linewidths=1.5))
    connectors = [(origin[a], origin[b]) for a, b in scene.connectors]
    if connectors:
        ax.add_collection3d(
            Line3DCollection(connectors, colors="0.5", linewidths=1.0, linestyles="dashed")
        )
    if scene.origins:
        centres = np.array([origin[b] for b in scene.origins])
        ax.scatter(*centres.T, s=30, color="tab:orange", edgecolors="k", depthshade=False)
    bodies = result.layout["bodies"]
    grounded = [m for m in tracks if bodies[scene.markers[m][0]]["kind"] == "ground"]
    moving = [m for m in tracks if m not in grounded]
    if moving:
        points = np.array([tracks[m] for m in moving])
        ax.scatter(*points.T, s=22, color="white", edgecolors="k", depthshade=False)
    if grounded:
        points = np.array([tracks[m] for m in grounded])
        ax.scatter(*points.T, s=60, marker="^", color="k", depthshade=False)
    ax.set_xlim(*style.limits[0])
    ax.set_ylim(*style.limits[1])
    ax.set_zlim(*style.limits[2])
    ax.set_box_aspect((1, 1, 1), zoom=1.25)
    ax.set_proj_type("ortho")
    ax.view_init(elev=style.view[0], azim=style.view[1])
    # In a plane view the axis along the line of sight only clutters the image.
    for name, axis in zip("xyz", (ax.xaxis, ax.yaxis, ax.zaxis), strict=True):
        hidden = VIEW_DEPTH_AXES.get(style.view) == name
        axis.set_label_text("" if hidden else f"{name} (m)")
        axis.set_tick_params(labelleft=not hidden, labelbottom=not hidden)
        if hidden:
            axis.set_ticks([])
    ax.set_title(_title(scene, record, style))


def _title(scene: Scene, record: int, style: _Style) -> str:
    """The time and, with deformable bodies, the deformation scale."""
    text = f"t = {scene.result.time[record]:.5g} s"
    if scene.parts:
        scale = "true scale" if style.scale == 1.0 else f"deformation x{style.scale:.3g}"
        text += f", {scale}"
    return text


def _new_axes(size: tuple[float, float] = (7.0, 5.6)) -> Any:
    from matplotlib.figure import Figure

    figure = Figure(figsize=size, layout="constrained")
    return figure.add_subplot(projection="3d")


def _colorbar(ax: Any, scene: Scene, style: _Style) -> None:
    from matplotlib.cm import ScalarMappable

    if style.color_by is None or not style.label or not scene.parts:
        return
    mappable = ScalarMappable(norm=style.norm, cmap="viridis")
    ax.figure.colorbar(mappable, ax=ax, shrink=0.6, label=style.label)


def render_frame(
    result: Any,
    record: int = -1,
    *,
    scale: float | str | None = None,
    view: str | Sequence[float] = "auto",
    color_by: str | None = "displacement",
    ax: Any = None,
) -> Any:
    """Draws record `record` (an index; negative from the end) of `result` into a matplotlib
    3D Axes (a new figure if None) and returns the Axes. `scale`: deformation scale (None or
    "auto": automatic); `view`: "auto", "xy", "xz", "yz", "iso" or (elevation, azimuth) in
    degrees; `color_by`: "displacement", "stress" (von Mises of solids; an
    `InvalidParameterError` without them) or None."""
    scene = build_scene(result)
    index = _record_index(result, record)
    style = _style(scene, np.array([index]), scale, view, color_by)
    if ax is None:
        ax = _new_axes()
    _colorbar(ax, scene, style)
    _draw(ax, scene, index, style, {})
    return ax


def _record_index(result: Any, record: int) -> int:
    count = len(result.time)
    if (
        isinstance(record, bool)  # (True drew record 1)
        or not isinstance(record, int | np.integer)
        or not -count <= record < count
    ):
        raise InvalidParameterError(
            f"record {record!r} does not exist; the result has {count} records", item=str(record)
        )
    return int(record) % count


def render_image(
    result: Any,
    path: str | os.PathLike[str],
    record: int = -1,
    *,
    scale: float | str | None = None,
    view: str | Sequence[float] = "auto",
    color_by: str | None = "displacement",
    dpi: int = 100,
) -> Path:
    """Saves one record of `result` (see :func:`render_frame`) as an image; the format
    follows the suffix (.png, .svg, .pdf). Returns the path."""
    out = Path(path)
    if out.suffix.lower() not in (".png", ".svg", ".pdf"):
        raise InvalidParameterError(
            f"unknown image format {out.suffix!r} of {str(out)!r}; use .png, .svg or .pdf",
            item=str(out),
        )
    ax = render_frame(result, record, scale=scale, view=view, color_by=color_by)
    out.parent.mkdir(parents=True, exist_ok=True)
    ax.figure.savefig(out, dpi=dpi)
    return out


def render_animation(
    result: Any,
    path: str | os.PathLike[str],
    *,
    frames: int = 60,
    scale: float | str | None = None,
    view: str | Sequence[float] = "auto",
    color_by: str | None = "displacement",
    fps: float = 15.0,
    dpi: int = 80,
    backend: str = "matplotlib",
    progress: bool | Callable[[int, int], object] | None = None,
) -> list[Path]:
    """Renders the motion of `result` off screen and returns the written files.

    `path`: ``*.gif`` writes an animated GIF; ``*.png`` a PNG sequence ``<stem>_0000.png``,
    ``<stem>_0001.png``, ... next to it; anything else is a directory (created) that receives
    ``frame_0000.png``, .... `frames`: the number of records shown, spread evenly over the run
    (all if fewer). `scale`, `view`, `color_by`: see :func:`render_frame`; the deformation
    scale and colour range are the same for all frames. `backend`: ``"matplotlib"`` (mplot3d,
    always available), ``"pyvista"`` (VTK, off screen; raises :class:`InvalidParameterError`
    if pyvista is missing or cannot render here) or ``"auto"`` (pyvista if it works, else
    matplotlib). `progress`: True shows a progress bar of the frames rendered
    (:func:`flexmbd.progress.track`), a function is called as ``progress(done, total)``."""
    if isinstance(frames, bool) or not isinstance(frames, int | np.integer) or frames < 1:
        raise InvalidParameterError(
            f"frames must be a positive integer, got {frames!r}", item="frames"
        )
    for value, name, top in ((fps, "fps", 1000.0), (dpi, "dpi", 10_000.0)):
        # ("10" was a bare TypeError, dpi 0 matplotlib's ValueError)
        if isinstance(value, bool) or not isinstance(value, int | float | np.number):
            raise InvalidParameterError(f"{name} must be a number, got {value!r}", item=name)
        if not 0 < value <= top:
            raise InvalidParameterError(f"{name} must be in (0, {top:g}], got {value!r}", item=name)
    if backend not in ("matplotlib", "pyvista", "auto"):
        raise InvalidParameterError(
            f"unknown backend {backend!r}; use 'matplotlib', 'pyvista' or 'auto'", item=backend
        )
    scene = build_scene(result)
    records = _spread(len(result.time), int(frames))
    out = Path(path)
    gif = out.suffix.lower() == ".gif"
    if gif or out.suffix.lower() == ".png":
        out.parent.mkdir(parents=True, exist_ok=True)
        folder, stem = out.parent, out.stem
    else:
        if out.exists() and not out.is_dir():  # (a bare FileExistsError after the scene)
            raise InvalidParameterError(
                f"'{out}' is a file, not a folder for the frames; give a .gif or .png path "
                "or a folder",
                item=str(out),
            )
        out.mkdir(parents=True, exist_ok=True)
        folder, stem = out, "frame"
    style = _style(scene, records, scale, view, color_by)
    shown = track_progress(records, progress, f"rendering {out}", unit="frames")
    if backend == "pyvista" or (backend == "auto" and pyvista_available()):
        images = _render_pyvista(scene, shown, style)
    else:
        images = _render_matplotlib(scene, shown, style, dpi)
    with status(f"saving {out}", enabled=progress is True):
        return _save_frames(images, out if gif else None, (folder, stem), fps)


def _render_matplotlib(
    scene: Scene, records: Iterable[np.int64], style: _Style, dpi: int
) -> list[Any]:
    """The frames of `records` drawn by matplotlib (PIL images)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from PIL import Image

    ax = _new_axes()
    canvas = FigureCanvasAgg(ax.figure)
    ax.figure.set_dpi(dpi)
    _colorbar(ax, scene, style)
    cache: dict[str, Any] = {}
    images = []
    for record in records:
        ax.cla()
        _draw(ax, scene, int(record), style, cache)
        canvas.draw()
        images.append(Image.fromarray(np.asarray(canvas.buffer_rgba())[..., :3].copy()))
    return images


def _save_frames(
    images: list[Any], gif: Path | None, frames: tuple[Path, str], fps: float
) -> list[Path]:
    """Saves PIL images as an animated GIF (looping, 1/fps s per frame) or as PNG files
    ``<stem>_0000.png``, ... in the folder of `frames` (folder, stem), removing the frames
    of an earlier, longer sequence of that stem there (a movie made of the folder's frames
    mixed both); returns the paths. (The names are joined, not formatted: a path with
    braces was a KeyError after every frame was rendered.)"""
    if gif is not None:
        images[0].save(
            gif,
            save_all=True,
            append_images=images[1:],
            duration=max(1, round(1000.0 / fps)),
            loop=0,
        )
        return [gif]
    folder, stem = frames
    written = []
    for k, image in enumerate(images):
        file = folder / f"{stem}_{k:04d}.png"
        image.save(file)
        written.append(file)
    frame = re.compile(re.escape(stem) + r"_(\d{4,})\.png")
    for file in folder.iterdir():
        match = frame.fullmatch(file.name)
        if match and int(match.group(1)) >= len(images) and file.is_file():
            file.unlink()
    return written


# Rendering with pyvista (optional) -------------------------------------------------------------
@functools.cache
def pyvista_available() -> bool:
    """True if pyvista is installed and renders off screen on this machine (a 16 x 16 pixel
    test image; VTK needs EGL or OSMesa without a display). Checked once per process."""
    try:
        import pyvista
    except ImportError:
        return False
    try:
        plotter = pyvista.Plotter(off_screen=True, window_size=(16, 16))
        plotter.add_mesh(pyvista.Sphere())
        image = plotter.screenshot(return_img=True)
        plotter.close()
    except Exception:  # VTK raises assorted errors when no OpenGL context can be made.
        return False
    return image is not None and np.asarray(image).size > 0


def _camera(style: _Style) -> tuple[Array, Array, Array]:
    """Focal point, camera position and view-up vector of the matplotlib view angles."""
    elevation, azimuth = np.radians(style.view[0]), np.radians(style.view[1])
    towards_eye = np.array(
        [
            np.cos(elevation) * np.cos(azimuth),
            np.cos(elevation) * np.sin(azimuth),
            np.sin(elevation),
        ]
    )
    up = np.array(
        [
            -np.sin(elevation) * np.cos(azimuth),
            -np.sin(elevation) * np.sin(azimuth),
            np.cos(elevation),
        ]
    )
    centre = style.limits.mean(axis=1)
    distance = 4.0 * float(np.ptp(style.limits, axis=1).max())
    return centre, centre + distance * towards_eye, up


def _render_pyvista(scene: Scene, records: Iterable[np.int64], style: _Style) -> list[Any]:
    """The frames of `records` drawn by pyvista off screen (PIL images)."""
    if not pyvista_available():
        raise InvalidParameterError(
            "pyvista is not installed or cannot render off screen here (VTK needs EGL or "
            "OSMesa without a display); use backend='matplotlib'",
            item="pyvista",
        )
    import pyvista
    from PIL import Image

    focal, position, up = _camera(style)
    half = 0.5 * float(np.ptp(style.limits, axis=1).max())
    plotter = pyvista.Plotter(off_screen=True, window_size=(800, 600))
    plotter.set_background("white")
    flexible_cells = sum(len(conn) for part in scene.parts for conn in part.data.elements.values())
    images = []
    for record in records:
        stresses = {}
        if style.color_by == "stress":
            stresses = {
                part.body: scene.result.stresses(part.body, np.array([record]))[0]
                for part in scene.parts
                if part.has_solids
            }
        grid = pyvista.from_meshio(_mesh(scene, int(record), style.scale, stresses))
        values = (
            grid.point_data["von_mises"]
            if style.color_by == "stress"
            else np.linalg.norm(grid.point_data["displacement"], axis=1)
        )
        grid.point_data["value"] = values
        plotter.clear()
        if flexible_cells:
            plotter.add_mesh(
                grid.extract_cells(np.arange(flexible_cells)),
                scalars="value" if style.color_by else None,
                clim=(style.norm.vmin, style.norm.vmax),
                cmap="viridis",
                show_edges=True,
                edge_color="gray",
                line_width=1 if any(part.has_solids for part in scene.parts) else 5,
                scalar_bar_args={"title": style.label, "color": "black"},
                show_scalar_bar=style.color_by is not None,
            )
        if grid.n_cells > flexible_cells:
            plotter.add_mesh(
                grid.extract_cells(np.arange(flexible_cells, grid.n_cells)),
                color="black",
                line_width=5,
                point_size=12,
                render_points_as_spheres=True,
            )
        plotter.add_text(_title(scene, int(record), style), font_size=10, color="black")
        plotter.camera.focal_point = focal
        plotter.camera.position = position
        plotter.camera.up = up
        plotter.camera.parallel_projection = True
        plotter.camera.parallel_scale = half
        images.append(Image.fromarray(np.asarray(plotter.screenshot(return_img=True))[..., :3]))
    plotter.close()
    return images
