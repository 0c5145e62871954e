"""``FlexibleBodyData``: everything the preprocessor computes for one deformable body. Nothing
in it changes during a simulation (seed section 3, "computational strategy")."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

#: Version of the data layout (and of the HDF5 body file that stores it).
BODY_DATA_VERSION = 1

#: Element types and their number of nodes.
ELEMENT_NODES = {"beam2": 2, "tet4": 4, "tet10": 10, "hex8": 8}


@dataclass
class FlexibleBodyData:
    """The constant data of a deformable body in the floating frame of reference.

    Coordinates are "nodal" (``dofs_per_node`` per node, node-major: [u_x, u_y, u_z] and, for
    beams, [theta_x, theta_y, theta_z] after them) before reference conditions. The reference
    conditions keep the dofs listed in ``reference["free_dofs"]``; the elastic coordinates of
    the body are those free dofs, or, with modes, the modal coordinates q_f with
    u_free = modes @ q_f (the modal matrix B_m of seed eq. 18).

    Attributes:
        nodes: undeformed node positions in the body frame, (n_nodes, 3), m.
        node_ids: ids of the nodes in the source mesh, (n_nodes,).
        elements: element type ("beam2", "tet4", "tet10", "hex8") -> (n_elements, nodes)
            indices into ``nodes``.
        element_ids: element type -> (n_elements,) ids in the source mesh.
        node_sets: name -> indices into ``nodes``.
        material: {"young_modulus": Pa, "poisson_ratio": -, "density": kg/m^3}.
        section: beam section {"area", "iy", "iz", "torsion_constant", ...} or None.
        dofs_per_node: 3 for solids, 6 when beams are present.
        stiffness: K_ff, sparse (n_dofs, n_dofs), nodal.
        mass: M_ff, sparse (n_dofs, n_dofs), nodal.
        mass_kind: "consistent" or "lumped".
        reference: {"kind": "none" | "clamped" | "3-2-1" | "simply-supported" | "mean-axis",
            "nodes": indices, "free_dofs": indices of the kept nodal dofs}.
        modes: modal matrix (n_free_dofs, n_modes) or None (nodal coordinates).
        frequencies: natural frequencies of the modes (Hz) or None.
        mode_kind: "free-free", "fixed-interface", "craig-bampton", "external" or None.
        invariants: invariants of motion in the elastic coordinates of the body (see
            ``DESIGN.md``): "mass" (float), "first_moment" (3,), "second_moment" (3, 3),
            "i1" (3, n_f), "i_kl" (3, 3) nested list of (n_f, n_f) matrices (sparse for nodal,
            dense for modal), "ibar" (3, 3, n_f).
        units: names of the units of length, mass and time.
        metadata: free-form strings (source file, creation date, ...).
        version: data layout version.
    """

    nodes: NDArray[np.float64]
    node_ids: NDArray[np.int64]
    elements: dict[str, NDArray[np.int64]]
    element_ids: dict[str, NDArray[np.int64]]
    node_sets: dict[str, NDArray[np.int64]]
    material: dict[str, float]
    section: dict[str, float] | None
    dofs_per_node: int
    stiffness: sp.csc_matrix
    mass: sp.csc_matrix
    mass_kind: str
    reference: dict[str, Any]
    modes: NDArray[np.float64] | None = None
    frequencies: NDArray[np.float64] | None = None
    mode_kind: str | None = None
    invariants: dict[str, Any] = field(default_factory=dict)
    units: dict[str, str] = field(
        default_factory=lambda: {"length": "m", "mass": "kg", "time": "s"}
    )
    metadata: dict[str, str] = field(default_factory=dict)
    version: int = BODY_DATA_VERSION

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
