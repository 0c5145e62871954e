"""The deformable-body models of the dynamics benchmarks, shared by the flexmbd side
(`flexible_dynamics.py`) and the Exudyn side (`exudyn_flexible.py`), so that both codes run
the same finite-element matrices and the same modes.

- ``pendulum``: an aluminium bar 1 x 0.05 x 0.05 m of tet4 elements (40 x 3 x 3 cells, 656
  nodes), reduced by Craig-Bampton with the end faces x0 (carrying the body frame) and x1 as
  RBE2 interfaces: 6 static + 10 fixed-interface modes. Hinged about global z at the centroid
  of face x0, released horizontally (along +x) under gravity (0, -9.81, 0).
- ``slider-crank``: the connecting rod of reference R4 as a steel bar 0.3 x 0.006 x 0.006 m of
  tet10 elements (24 x 1 x 1 cells), Craig-Bampton with the end faces as RBE2 interfaces
  (frame on x0): 6 static + 6 modes. Rigid crank 0.15 m driven at 150 rad/s about global z,
  slider a point mass of half the rod mass on the x axis, rod end faces joined to crank pin and
  slider (revolute about z at x0, spherical at x1).
- ``nodal``: the pendulum bar unreduced (nodal elastic coordinates, clamped at face x0, which
  carries the frame), in three sizes: about 1k, 10k and 50k elastic coordinates.

Each builder returns the mesh, the material and the `FlexibleBodyData` (K, M, invariants,
modes); `nodes_of(body, name)` gives the node indices of a face.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import numpy as np

from flexmbd.fe import FlexibleBodyData, Material, Mesh, build_body, shapes

ALUMINIUM = Material(7.0e10, 0.33, 2700.0)
#: The soft beam of issue 30 (benchmarks/soft_beam.py; the peer's flexible-pendulum material).
SOFT = Material(1.0e8, 0.3, 1000.0)
#: Cells of the soft 1 x 0.1 x 0.1 m beam by size: 960 and 9,408 elastic coordinates.
SOFT_SIZES = {"1k": (20, 3, 3), "10k": (64, 6, 6)}
STEEL = Material(2.0e11, 0.3, 7870.0)
GRAVITY = (0.0, -9.81, 0.0)

#: Crank length (m), rod length (m) and crank speed (rad/s) of the slider-crank.
CRANK, ROD, OMEGA = 0.15, 0.30, 150.0

#: Box size (m) and cells of the nodal bodies, by name: ~1k, ~10k, ~50k elastic coordinates.
NODAL_SIZES = {
    "1k": ((1.0, 0.05, 0.05), (20, 3, 3)),
    "10k": ((1.0, 0.1, 0.1), (64, 6, 6)),
    "50k": ((1.0, 0.12, 0.12), (100, 12, 12)),
}


@dataclass
class FlexibleModel:
    """A deformable body of a benchmark with its mesh and material."""

    mesh: Mesh
    material: Material
    body: FlexibleBodyData


def nodes_of(model: FlexibleModel, name: str) -> np.ndarray:
    """Indices of the nodes of a named face (``x0``, ``x1``, ...)."""
    return np.asarray(model.body.node_sets[name], dtype=np.int64)


@cache
def pendulum() -> FlexibleModel:
    """The reduced flexible pendulum (16 modes)."""
    mesh = shapes.box((1.0, 0.05, 0.05), (40, 3, 3), "tet4")
    body = build_body(
        mesh.nodes,
        mesh.elements,
        ALUMINIUM,
        node_sets=mesh.node_sets,
        reference="interface",
        modes="craig-bampton",
        mode_count=10,
        interfaces=["x0", "x1"],
        interface_kind="rbe2",
    )
    return FlexibleModel(mesh, ALUMINIUM, body)


@cache
def slider_crank_rod() -> FlexibleModel:
    """The reduced connecting rod of the slider-crank (12 modes)."""
    mesh = shapes.box((ROD, 0.006, 0.006), (24, 1, 1), "tet10")
    body = build_body(
        mesh.nodes,
        mesh.elements,
        STEEL,
        node_sets=mesh.node_sets,
        reference="interface",
        modes="craig-bampton",
        mode_count=6,
        interfaces=["x0", "x1"],
        interface_kind="rbe2",
    )
    return FlexibleModel(mesh, STEEL, body)


@cache
def soft(size: str) -> FlexibleModel:
    """The soft tet4 beam of `size` (a key of `SOFT_SIZES`), clamped at face x0."""
    mesh = shapes.box((1.0, 0.1, 0.1), SOFT_SIZES[size], "tet4")
    body = build_body(
        mesh.nodes,
        mesh.elements,
        SOFT,
        node_sets=mesh.node_sets,
        reference="clamped",
        reference_nodes="x0",
    )
    return FlexibleModel(mesh, SOFT, body)


@cache
def nodal(size: str) -> FlexibleModel:
    """The unreduced pendulum bar of `size` (a key of `NODAL_SIZES`), clamped at face x0."""
    lengths, cells = NODAL_SIZES[size]
    mesh = shapes.box(lengths, cells, "tet4")
    body = build_body(
        mesh.nodes,
        mesh.elements,
        ALUMINIUM,
        node_sets=mesh.node_sets,
        reference="clamped",
        reference_nodes="x0",
    )
    return FlexibleModel(mesh, ALUMINIUM, body)
