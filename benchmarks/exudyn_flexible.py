"""Exudyn side of the flexible-body dynamics benchmarks (models in ``flexible_models.py``).

Every deformable body gets exactly flexmbd's data: node positions, the nodal stiffness and mass
matrices and, for the reduced bodies, flexmbd's Craig-Bampton modes. Nothing is recomputed by
Exudyn (no NGsolve, no Exudyn eigensolver). Coordinates are node-major [u_x, u_y, u_z] per node
in both codes (Exudyn's ``FEMinterface`` uses the same xyz-interleaved numbering), so the
matrices are passed unchanged.

Models (all in a new ``SystemContainer``, generalized-alpha with index-3 constraints, fixed step):

``pendulum`` (``flexible_models.pendulum()``, 656 nodes, 16 modes)
    ``exudyn.FEM.FEMinterface`` filled directly: ``nodes = {"Position": body.nodes}``,
    ``massMatrix`` / ``stiffnessMatrix`` = flexmbd's nodal CSR matrices, ``modeBasis =
    {"matrix": full, "type": "HCBmodes"}`` with ``full`` the (3n x 16) basis that is flexmbd's
    ``body.modes`` on ``reference.free_dofs`` and zero elsewhere (the rows of face x0, which is
    rigidly attached to the frame), ``eigenValues = (2 pi body.frequencies)^2`` (informative only;
    nothing in the simulation reads them). ``ObjectFFRFreducedOrderInterface(fem,
    rigidBodyNodeType)`` computes the reduced matrices and the inertia terms from these data and
    ``AddObjectFFRFreducedOrder(mbs, positionRef=(0, 0, 0), gravity=(0, -9.81, 0))`` adds the rigid
    reference node (type by configuration), a ``NodeGenericODE2`` with the 16 modal coordinates,
    the C++ ``ObjectFFRFreducedOrder`` (no user functions, no damping) and gravity as
    ``LoadMassProportional`` on a ``MarkerBodyMass``. The body frame is at the global origin with
    identity orientation (the bar spans x = 0..1, y, z = 0..0.05). Hinge at the centroid c0 =
    (0, 0.025, 0.025) of face x0: ``ObjectJointRevoluteZ`` between a ground ``MarkerBodyRigid`` at
    c0 and a ``MarkerSuperElementRigid`` on the 16 x0 nodes (equal weights, no offset): those nodes
    have zero modal displacement, so the marker is exactly the body frame moved to c0 (token
    ``sph`` instead: ``SphericalJoint`` at c0 on a ``MarkerSuperElementPosition`` of the x0 nodes
    plus a ``GenericJoint`` locking the rotations about x and y of the reference node: the same
    kinematics). Start at rest, h = 1e-3, 1 s.
    Output every 0.01 s: centroid of face x1 (``SensorMarker`` on a ``MarkerSuperElementPosition``
    with the x1 nodes, equal weights) and the modal coordinates.

``slider-crank`` (``flexible_models.slider_crank_rod()``, tet10 rod, 12 modes)
    Crank: ``CreateRigidBody`` with mass 0.1 kg, inertia diag(1e-6, 0.1 * 0.15^2 / 12, same) at
    its centre (0.075, 0, 0), Tait-Bryan (Rxyz) node (whatever the configuration's node type,
    which applies to the rod's reference node): its third rotation coordinate is the crank angle
    without wrap-around. ``CreateRevoluteJoint`` about global z at the origin. Drive: an
    ``ObjectConnectorCoordinate`` between a ground coordinate and that angle with offset
    ``OMEGA * t`` (position level, exact), given as an Exudyn symbolic user function (evaluated in
    C++; token ``pydrive``: a Python user function; ``veldrive``: the velocity-level form,
    angular velocity = OMEGA, no user function). Initial crank angle 0, angular velocity 150 rad/s
    (centre velocity (0, 11.25, 0)).
    Rod: reduced body as for the pendulum, no gravity, no damping. The rod mesh is not centred
    on its axis (y, z = 0..0.006), so its face centroids are at (0, 0.003, 0.003) and
    (0.3, 0.003, 0.003) in the body frame; the body frame starts at ``rod_frame_position`` =
    (0.15, -0.003, -0.003) so that the x0 centroid is at the crank tip (0.15, 0, 0) and the x1
    centroid at the slider (0.45, 0, 0) (with the frame at (0.15, 0, 0) the joints would start
    violated by 0.003 m in y and z). Initial velocity is the rigid-mechanism one: angular
    velocity (0, 0, -75), frame velocity v_tip + omega x (frame - tip) = (-0.225, 22.5, 0); the
    x0 centroid then moves with (0, 22.5, 0) and the x1 centroid is at rest. Crank pin:
    ``ObjectJointRevoluteZ`` between a ``MarkerBodyRigid`` at the crank tip and a
    ``MarkerSuperElementRigid`` on the x0 nodes (token ``sph``: ``SphericalJoint`` crank tip to
    the x0 centroid plus a ``GenericJoint`` locking the relative rotations about x and y of the
    crank and the rod frame). Slider: ``NodePoint`` + ``MassPoint`` of half
    the rod mass at (0.45, 0, 0), y and z held by two ``CoordinateConstraint``s, joined to a
    ``MarkerSuperElementPosition`` on the x1 nodes by a ``SphericalJoint``.
    h = 1e-5; two crank turns are 4 pi / 150 = 0.083776 s = 8377.6 steps, so the run has 8378
    steps and ends at 0.08378 s. Output every 1e-4 s: slider x, x1 centroid, modal coordinates,
    crank angle.

``nodal`` (``flexible_models.nodal(size)``, size "1k", "10k" or "50k", unreduced tet4)
    Exudyn's ``ObjectFFRF``: a rigid reference node (type by configuration) at the origin plus one
    ``NodePoint`` per mesh node (reference position = node position in the body frame; its
    coordinates are the nodal displacements in the body frame), ``massMatrixFF`` /
    ``stiffnessMatrixFF`` = flexmbd's full nodal matrices as sparse ``MatrixContainer``s. The
    face x0 is clamped to the frame as in Exudyn's ObjectFFRF test models: a
    ``CoordinateConstraint`` between a ground coordinate and each of the 3 coordinates of every x0
    node (48 / 147 / 507 constraints). Gravity: one ``LoadForceVector`` (0, -9.81 m, 0) on a
    ``MarkerSuperElementPosition`` over all nodes with weights m_i / m, m_i the row sums of the
    consistent mass matrix (the virtual work is exactly that of the consistent gravity load;
    ``LoadMassProportional`` on ``ObjectFFRF`` acts at the frame origin instead of the centre of
    mass, see notes). Hinge: ``SphericalJoint`` at the x0 centroid (ground point to a
    ``MarkerSuperElementPosition`` on the x0 nodes) and a ``GenericJoint`` locking the rotations
    about x and y between the ground and the reference node (``MarkerSuperElementRigid`` is not
    available on ``ObjectFFRF`` and ``MarkerBodyRigid`` on it does not work). h = 1e-3, a short
    run of ``steps`` steps; wall time of every step is recorded (pre-step user function), so the
    first step (with the first Jacobian) and the later ones are reported apart. Output every step:
    x1 centroid. ``ObjectFFRF`` builds its mass matrix as a dense matrix of all its coordinates,
    so memory and time grow with the square of the mesh: before building, the run is refused
    (``MemoryError``) if about ``DENSE_MATRIX_COPIES`` such matrices do not fit in the available
    memory, which is the case for "50k" (51213 coordinates: 19.5 GiB per copy).

``run(model, size, config)`` runs one case in a fresh interpreter (``spawn``) and returns a dict
(keys: see ``run_in_process``). Its ``outputs`` hold ``times`` and the recorded arrays
``x1_centroid`` (n, 3), ``modal_coordinates`` (n, modes; in flexmbd's normalisation, since the
basis is flexmbd's), ``slider_x`` and ``crank_angle``.

``config`` is a dash-separated token list parsed by ``exudyn_fourbar.parse_config``: node
``ep`` / ``rotvec`` / ``rxyz``, Newton ``full`` / ``mod`` / ``jacstep``, linear solver ``dense`` /
``eigdense`` / ``sparse``, ``rhoX``, ``ctrX``, ``fast``, ``numjac``, ... (spectral radius 0.9
unless given), plus the model variants ``sph`` (hinge) and ``pydrive`` / ``veldrive`` (drive)
described above. Exudyn's default Newton tolerances are kept. ``FASTEST_CONFIGS`` holds the
fastest configuration found per model (benchmarks/notes_exudyn_flexible.md).

Command line::

    python benchmarks/exudyn_flexible.py --model pendulum --configs rxyz-mod-dense-fast-sph
    python benchmarks/exudyn_flexible.py --model slider-crank --repeat 3 --json sc.json
    python benchmarks/exudyn_flexible.py --model nodal --size 10k --steps 20
    python benchmarks/exudyn_flexible.py --model soft --size 1k     # the soft beam, 2 s

Exudyn is imported lazily (in the worker process), so this module imports without it.
"""

from __future__ import annotations

import argparse
import json
import math
import multiprocessing
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, replace
from itertools import pairwise
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import exudyn_fourbar as fourbar  # noqa: E402
import flexible_models  # noqa: E402

MODELS = ("pendulum", "slider-crank", "nodal", "soft")
NODAL_SIZES = tuple(flexible_models.NODAL_SIZES)

GRAVITY = flexible_models.GRAVITY
#: spectral radius of generalized-alpha unless the configuration says otherwise
SPECTRAL_RADIUS = 0.9

PENDULUM_STEP, PENDULUM_END, PENDULUM_OUTPUT = 1e-3, 1.0, 0.01
SLIDER_CRANK_STEP, SLIDER_CRANK_OUTPUT = 1e-5, 1e-4
#: two crank turns (4 pi / OMEGA = 0.0837758 s) rounded up to whole steps of 1e-5 s
SLIDER_CRANK_STEPS = math.ceil(4.0 * math.pi / flexible_models.OMEGA / SLIDER_CRANK_STEP)
NODAL_STEP = 1e-3
#: default number of steps of the nodal timing runs, by size
NODAL_STEPS = {"1k": 100, "10k": 20, "50k": 3}
#: the soft beam (issue 30): step, end time and output interval of benchmarks/soft_beam.py
SOFT_STEP, SOFT_END, SOFT_OUTPUT = 1e-3, 2.0, 0.01

CRANK_MASS = 0.1
CRANK_INERTIA = (
    1e-6,
    CRANK_MASS * flexible_models.CRANK**2 / 12,
    CRANK_MASS * flexible_models.CRANK**2 / 12,
)

DRIVES = {
    "symdrive": "position-level drive angle = OMEGA t, Exudyn symbolic user function (C++)",
    "pydrive": "position-level drive angle = OMEGA t, Python user function",
    "veldrive": "velocity-level drive: crank angular velocity = OMEGA (constant offset)",
}
HINGES = {
    "serigid": "ObjectJointRevoluteZ on a MarkerSuperElementRigid of the x0 nodes",
    "sph": "SphericalJoint at the x0 centroid + GenericJoint locking the frame's x/y rotations",
}

#: configurations run by default, by model (the final timing tables of notes_exudyn_flexible.md)
DEFAULT_CONFIGS = {
    "pendulum": (
        "ep-mod-dense-fast",
        "ep-mod-dense-fast-sph",
        "rotvec-mod-dense-fast-sph",
        "rxyz-mod-dense-fast-sph",
        "rxyz-mod-eigdense-fast-sph",
        "rxyz-mod-sparse-fast-sph",
        "rxyz-mod-dense-fast-sph-ctr0.1",
        "rxyz-mod-dense-sph-ctr0.1",
        "rxyz-jacstep-dense-fast-sph",
        "rxyz-full-dense-fast-sph",
    ),
    "slider-crank": (
        "ep-mod-dense-fast-sph",
        "ep-mod-eigdense-fast-sph",
        "ep-mod-sparse-fast-sph",
        "rxyz-mod-dense-fast-sph",
        "ep-mod-eigdense-fast-sph-ctr0.1",
        "ep-mod-eigdense-fast-sph-veldrive",
        "ep-mod-eigdense-fast",
        "ep-mod-eigdense-sph",
        "ep-jacstep-dense-fast",
        "ep-full-dense-fast",
    ),
    "nodal": (
        "rxyz-mod-sparse-fast",
        "rotvec-mod-sparse-fast",
        "ep-mod-sparse-fast",
        "rxyz-mod-eigdense-fast",
    ),
    "soft": ("rxyz-mod-sparse-fast", "ep-mod-sparse-fast"),
}

#: fastest configuration per model found on the 2-core test machine (notes_exudyn_flexible.md)
FASTEST_CONFIGS = {
    "pendulum": "rxyz-mod-dense-rho0.9-ctr0.1-fast-sph",
    "slider-crank": "ep-mod-eigdense-rho0.9-fast-sph",
    "nodal": "rxyz-mod-sparse-rho0.9-fast",
    "soft": "rxyz-mod-sparse-rho0.9-fast",
}


@dataclass(frozen=True)
class FlexibleConfig:
    """Solver configuration (``exudyn_fourbar.ExudynConfig``) plus the model variants."""

    solver: fourbar.ExudynConfig
    hinge: str = "serigid"
    drive: str = "symdrive"

    def name(self) -> str:
        """Canonical string form (non-default model variants appended)."""
        tokens = [self.solver.name()]
        if self.hinge != "serigid":
            tokens.append(self.hinge)
        if self.drive != "symdrive":
            tokens.append(self.drive)
        return "-".join(tokens)


def parse_flexible_config(config: str) -> FlexibleConfig:
    """Parse a configuration string; see the module docstring for the tokens."""
    tokens = [t for t in config.strip().lower().split("-") if t]
    hinge, drive, rest = "serigid", "symdrive", []
    for token in tokens:
        if token in HINGES:
            hinge = token
        elif token in DRIVES:
            drive = token
        else:
            rest.append(token)
    solver = fourbar.parse_config("-".join(rest))
    if not any(t.startswith("rho") for t in rest):
        solver = replace(solver, spectral_radius=SPECTRAL_RADIUS)
    return FlexibleConfig(solver, hinge, drive)


# ------------------------------------------------------------------------------------------------
# model data


def full_mode_basis(body) -> np.ndarray:
    """flexmbd's modes expanded to all 3n nodal dofs (zero rows for the dofs of the reference)."""
    free = np.asarray(body.reference.free_dofs, dtype=np.int64)
    full = np.zeros((3 * len(body.nodes), body.modes.shape[1]))
    full[free] = body.modes
    return full


def reduced_order_interface(body, node_type):
    """``ObjectFFRFreducedOrderInterface`` built from flexmbd's nodes, K, M and modes."""
    from exudyn.FEM import FEMinterface, ObjectFFRFreducedOrderInterface

    fem = FEMinterface()
    fem.nodes = {"Position": np.asarray(body.nodes, dtype=float)}
    fem.massMatrix = body.mass.tocsr()
    fem.stiffnessMatrix = body.stiffness.tocsr()
    fem.modeBasis = {"matrix": full_mode_basis(body), "type": "HCBmodes"}
    fem.eigenValues = (2.0 * np.pi * np.asarray(body.frequencies)) ** 2
    return ObjectFFRFreducedOrderInterface(fem, rigidBodyNodeType=node_type)


def reduced_body_checks(cms, body) -> dict:
    """Compare Exudyn's reduced data with flexmbd's frequencies and invariants."""
    from scipy.linalg import eigh

    inv = body.invariants
    eig = eigh(cms.stiffnessMatrixReduced, cms.massMatrixReduced, eigvals_only=True)
    freq = np.sqrt(np.abs(eig)) / (2.0 * np.pi)
    ref = np.asarray(body.frequencies)
    # flexmbd's second moment S = int rho x x^T; Exudyn's inertia about the frame origin
    second = np.asarray(inv.second_moment)
    inertia = np.trace(second) * np.eye(3) - second
    # int rho x~ Psi_k: Exudyn's mXRefTildePsi = xRefTilde^T M Psi = -int rho x~ Psi
    ibar = np.asarray(inv.ibar)  # (3, 3, n_f): int rho x_a Psi_bk
    cross = np.stack(
        [ibar[1, 2] - ibar[2, 1], ibar[2, 0] - ibar[0, 2], ibar[0, 1] - ibar[1, 0]]
    )  # int rho (x cross Psi_k)
    return {
        "exudyn_frequencies_hz": freq.tolist(),
        "flexmbd_frequencies_hz": ref.tolist(),
        "frequency_max_rel_diff": float(np.max(np.abs(freq - ref) / ref)),
        "exudyn_mass": float(cms.totalMass),
        "flexmbd_mass": float(inv.mass),
        "center_of_mass": np.asarray(cms.chiU).tolist(),
        "inertia_max_diff": float(np.max(np.abs(cms.inertiaLocal - inertia))),
        "i1_max_diff": float(np.max(np.abs(cms.mPhitTPsi - np.asarray(inv.i1)))),
        "ibar_cross_max_diff": float(np.max(np.abs(-cms.mXRefTildePsi - cross))),
        "m_ff_max_diff": float(np.max(np.abs(cms.massMatrixReduced - np.asarray(inv.m_ff)))),
        "k_ff_max_rel_diff": float(
            np.max(np.abs(cms.stiffnessMatrixReduced - np.asarray(inv.k_ff)))
            / np.max(np.abs(cms.stiffnessMatrixReduced))
        ),
    }


def _equal_weights(nodes: np.ndarray) -> list[float]:
    return [1.0 / len(nodes)] * len(nodes)


def _rigid_node_type(exu, cfg: FlexibleConfig):
    return getattr(exu.NodeType, fourbar.NODE_TYPES[cfg.solver.node])


class _Recorder:
    """Internal sensors (no files) whose stored data become the output arrays."""

    def __init__(self, mbs) -> None:
        self.mbs = mbs
        self.sensors: dict[str, tuple[object, list[int] | None]] = {}

    def add(self, name: str, sensor_item, columns: list[int] | None = None) -> None:
        sensor_item.storeInternal = True
        sensor_item.writeToFile = False
        self.sensors[name] = (self.mbs.AddSensor(sensor_item), columns)

    def collect(self) -> dict:
        out: dict = {}
        for name, (sensor, columns) in self.sensors.items():
            data = np.asarray(self.mbs.GetSensorStoredData(sensor))
            out.setdefault("times", data[:, 0].tolist())
            values = data[:, 1:] if columns is None else data[:, [1 + c for c in columns]]
            out[name] = values[:, 0].tolist() if values.shape[1] == 1 else values.tolist()
        return out


def _hinge(mbs, hinge: str, rigid, local_point, flexible, nodes, flexible_frame_node) -> None:
    """Revolute joint about z between a rigid body (or the ground) and a deformable body.

    The joint point is ``local_point`` in the frame of ``rigid`` (whose z axis is global z) and
    the centroid of ``nodes`` of ``flexible``; these nodes are rigidly attached to the flexible
    body's frame (zero modal / elastic displacement), whose rigid-body node is
    ``flexible_frame_node``. ``hinge``: ``serigid`` (ObjectJointRevoluteZ on a
    MarkerSuperElementRigid of the nodes) or ``sph`` (SphericalJoint on a
    MarkerSuperElementPosition of the nodes plus a GenericJoint locking the relative rotations
    about x and y of the flexible body's frame); both give the same kinematics.
    """
    from exudyn.itemInterface import (
        GenericJoint,
        MarkerBodyPosition,
        MarkerBodyRigid,
        MarkerNodeRigid,
        MarkerSuperElementPosition,
        MarkerSuperElementRigid,
        ObjectJointRevoluteZ,
        SphericalJoint,
    )

    nodes = np.asarray(nodes).tolist()
    weights = _equal_weights(nodes)
    point = [float(c) for c in local_point]
    if hinge == "serigid":
        m_rigid = mbs.AddMarker(MarkerBodyRigid(bodyNumber=rigid, localPosition=point))
        m_flexible = mbs.AddMarker(
            MarkerSuperElementRigid(
                bodyNumber=flexible, meshNodeNumbers=nodes, weightingFactors=weights
            )
        )
        mbs.AddObject(ObjectJointRevoluteZ(markerNumbers=[m_rigid, m_flexible]))
        return
    m_rigid = mbs.AddMarker(MarkerBodyPosition(bodyNumber=rigid, localPosition=point))
    m_flexible = mbs.AddMarker(
        MarkerSuperElementPosition(
            bodyNumber=flexible, meshNodeNumbers=nodes, weightingFactors=weights
        )
    )
    mbs.AddObject(SphericalJoint(markerNumbers=[m_rigid, m_flexible]))
    m_rigid_frame = mbs.AddMarker(MarkerBodyRigid(bodyNumber=rigid, localPosition=[0.0, 0.0, 0.0]))
    m_frame = mbs.AddMarker(MarkerNodeRigid(nodeNumber=flexible_frame_node))
    mbs.AddObject(
        GenericJoint(markerNumbers=[m_rigid_frame, m_frame], constrainedAxes=[0, 0, 0, 1, 1, 0])
    )


def build_pendulum(exu, cfg: FlexibleConfig):
    """The reduced pendulum; returns (SC, mbs, recorder, checks, objects to keep alive)."""
    from exudyn.itemInterface import (
        MarkerSuperElementPosition,
        ObjectGround,
        SensorMarker,
        SensorNode,
    )

    model = flexible_models.pendulum()
    body = model.body
    x0 = flexible_models.nodes_of(model, "x0")
    x1 = flexible_models.nodes_of(model, "x1")
    cms = reduced_order_interface(body, _rigid_node_type(exu, cfg))

    sc = exu.SystemContainer()
    mbs = sc.AddSystem()
    items = cms.AddObjectFFRFreducedOrder(mbs, positionRef=[0.0, 0.0, 0.0], gravity=list(GRAVITY))
    obj = items["oFFRFreducedOrder"]
    ground = mbs.AddObject(ObjectGround())
    hinge_point = body.nodes[x0].mean(axis=0)  # frame at the origin: body frame = global
    _hinge(mbs, cfg.hinge, ground, hinge_point, obj, x0, items["nRigidBody"])

    recorder = _Recorder(mbs)
    m_tip = mbs.AddMarker(
        MarkerSuperElementPosition(
            bodyNumber=obj, meshNodeNumbers=x1.tolist(), weightingFactors=_equal_weights(x1)
        )
    )
    out = exu.OutputVariableType
    recorder.add("x1_centroid", SensorMarker(markerNumber=m_tip, outputVariableType=out.Position))
    recorder.add(
        "modal_coordinates",
        SensorNode(nodeNumber=items["nGenericODE2"], outputVariableType=out.Coordinates),
    )
    mbs.Assemble()
    return sc, mbs, recorder, reduced_body_checks(cms, body), []


def rod_frame_position(body, x0: np.ndarray) -> np.ndarray:
    """Initial rod frame position: the x0 centroid at the crank tip (CRANK, 0, 0)."""
    return np.array([flexible_models.CRANK, 0.0, 0.0]) - body.nodes[x0].mean(axis=0)


def build_slider_crank(exu, cfg: FlexibleConfig):
    """The slider-crank with the reduced flexible rod; returns like ``build_pendulum``."""
    from exudyn.advancedUtilities import CreateSymbolicUserFunction
    from exudyn.itemInterface import (
        CoordinateConstraint,
        MarkerNodeCoordinate,
        MarkerNodePosition,
        MarkerSuperElementPosition,
        MassPoint,
        NodePoint,
        NodePointGround,
        ObjectGround,
        SensorMarker,
        SensorNode,
        SphericalJoint,
    )
    from exudyn.rigidBodyUtilities import RigidBodyInertia

    crank_len, omega = flexible_models.CRANK, flexible_models.OMEGA
    model = flexible_models.slider_crank_rod()
    body = model.body
    x0 = flexible_models.nodes_of(model, "x0")
    x1 = flexible_models.nodes_of(model, "x1")
    rod_mass = float(body.invariants.mass)
    cms = reduced_order_interface(body, _rigid_node_type(exu, cfg))

    sc = exu.SystemContainer()
    mbs = sc.AddSystem()
    ground = mbs.AddObject(ObjectGround())
    n_ground = mbs.AddNode(NodePointGround(referenceCoordinates=[0.0, 0.0, 0.0]))
    m_ground_coord = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=n_ground, coordinate=0))

    # crank: Rxyz node, so that its third rotation coordinate is the crank angle
    half = 0.5 * crank_len
    crank = mbs.CreateRigidBody(
        inertia=RigidBodyInertia(
            mass=CRANK_MASS, inertiaTensor=np.diag(CRANK_INERTIA), inertiaTensorAtCOM=True
        ),
        referencePosition=[half, 0.0, 0.0],
        initialVelocity=[0.0, omega * half, 0.0],
        initialAngularVelocity=[0.0, 0.0, omega],
        nodeType=exu.NodeType.RotationRxyz,
        show=False,
    )
    crank_node = mbs.GetObject(crank)["nodeNumber"]
    mbs.CreateRevoluteJoint(
        itemNumbers=[ground, crank], position=[0.0, 0.0, 0.0], axis=[0.0, 0.0, 1.0], show=False
    )
    m_angle = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=crank_node, coordinate=5))
    keep_alive = []  # the symbolic user function must live as long as the system
    if cfg.drive == "veldrive":
        drive = CoordinateConstraint(
            markerNumbers=[m_ground_coord, m_angle], offset=omega, velocityLevel=True
        )
    else:

        def drive_angle(mbs, t, itemNumber, lOffset):
            return omega * t

        if cfg.drive == "symdrive":
            function = CreateSymbolicUserFunction(
                mbs, drive_angle, "offsetUserFunction", itemTypeName="ObjectConnectorCoordinate"
            )
            keep_alive.append(function)
        else:
            function = drive_angle
        drive = CoordinateConstraint(
            markerNumbers=[m_ground_coord, m_angle], offsetUserFunction=function
        )
    mbs.AddObject(drive)

    # rod: reduced body, frame placed so that the face centroids lie on the x axis
    frame = rod_frame_position(body, x0)
    tip = np.array([crank_len, 0.0, 0.0])
    omega_rod = np.array([0.0, 0.0, -omega * crank_len / flexible_models.ROD])
    v_tip = np.array([0.0, omega * crank_len, 0.0])
    v_frame = v_tip + np.cross(omega_rod, frame - tip)
    items = cms.AddObjectFFRFreducedOrder(
        mbs,
        positionRef=frame.tolist(),
        initialVelocity=v_frame.tolist(),
        initialAngularVelocity=omega_rod.tolist(),
    )
    rod = items["oFFRFreducedOrder"]

    # crank pin: revolute about z, crank tip <-> x0 face of the rod
    _hinge(mbs, cfg.hinge, crank, [half, 0.0, 0.0], rod, x0, items["nRigidBody"])

    # slider: point mass on the x axis, spherical joint to the x1 face of the rod
    slider_start = [crank_len + flexible_models.ROD, 0.0, 0.0]
    n_slider = mbs.AddNode(NodePoint(referenceCoordinates=slider_start))
    mbs.AddObject(MassPoint(nodeNumber=n_slider, physicsMass=0.5 * rod_mass))
    for coordinate in (1, 2):
        m_coord = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=n_slider, coordinate=coordinate))
        mbs.AddObject(CoordinateConstraint(markerNumbers=[m_ground_coord, m_coord]))
    m_slider = mbs.AddMarker(MarkerNodePosition(nodeNumber=n_slider))
    m_x1 = mbs.AddMarker(
        MarkerSuperElementPosition(
            bodyNumber=rod, meshNodeNumbers=x1.tolist(), weightingFactors=_equal_weights(x1)
        )
    )
    mbs.AddObject(SphericalJoint(markerNumbers=[m_slider, m_x1]))

    recorder = _Recorder(mbs)
    out = exu.OutputVariableType
    recorder.add("slider_x", SensorNode(nodeNumber=n_slider, outputVariableType=out.Position), [0])
    recorder.add("x1_centroid", SensorMarker(markerNumber=m_x1, outputVariableType=out.Position))
    recorder.add(
        "modal_coordinates",
        SensorNode(nodeNumber=items["nGenericODE2"], outputVariableType=out.Coordinates),
    )
    recorder.add(
        "crank_angle", SensorNode(nodeNumber=crank_node, outputVariableType=out.Coordinates), [5]
    )
    mbs.Assemble()
    checks = reduced_body_checks(cms, body)
    checks["rod_frame_position"] = frame.tolist()
    checks["rod_frame_velocity"] = v_frame.tolist()
    checks["slider_mass"] = 0.5 * rod_mass
    return sc, mbs, recorder, checks, keep_alive


#: peak memory of an ObjectFFRF run in units of one dense (n x n) double matrix, n = ODE2
#: coordinates (measured: 2.51 GB peak for n = 9561, i.e. 3.4 such matrices)
DENSE_MATRIX_COPIES = 3.5


def available_memory() -> float:
    """MemAvailable of /proc/meminfo in bytes (inf where unknown)."""
    try:
        with open("/proc/meminfo") as handle:
            for line in handle:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024.0
    except OSError:
        pass
    return math.inf


def check_dense_memory(ode2_coordinates: int) -> float:
    """Raise MemoryError if Exudyn's dense ObjectFFRF mass matrix cannot fit; returns bytes.

    ``ObjectFFRF`` assembles its mass matrix as a dense matrix of all its coordinates (see
    notes_exudyn_flexible.md), so memory grows with the square of the mesh size; running out of
    memory crashes the process (or the machine), hence the check before the run.
    """
    needed = DENSE_MATRIX_COPIES * 8.0 * float(ode2_coordinates) ** 2
    available = available_memory()
    if needed > available:
        raise MemoryError(
            f"ObjectFFRF with {ode2_coordinates} coordinates needs about {needed / 2**30:.1f} GiB "
            f"({DENSE_MATRIX_COPIES} dense {ode2_coordinates}^2 matrices), only "
            f"{available / 2**30:.1f} GiB available"
        )
    return needed


def build_nodal(exu, cfg: FlexibleConfig, size: str, soft: bool = False):
    """The unreduced pendulum (the soft beam if `soft`) as ObjectFFRF; returns like
    ``build_pendulum``."""
    from exudyn.itemInterface import (
        CoordinateConstraint,
        LoadForceVector,
        MarkerNodeCoordinate,
        MarkerSuperElementPosition,
        NodePoint,
        NodePointGround,
        ObjectFFRF,
        ObjectGround,
        SensorMarker,
        VObjectFFRF,
    )
    from exudyn.rigidBodyUtilities import GetRigidBodyNode

    model = flexible_models.soft(size) if soft else flexible_models.nodal(size)
    body = model.body
    x0 = flexible_models.nodes_of(model, "x0")
    x1 = flexible_models.nodes_of(model, "x1")
    nodes = np.asarray(body.nodes, dtype=float)
    rigid_coordinates = 7 if cfg.solver.node == "ep" else 6
    memory_estimate = check_dense_memory(3 * len(nodes) + rigid_coordinates)

    sc = exu.SystemContainer()
    mbs = sc.AddSystem()
    rigid = GetRigidBodyNode(
        nodeType=_rigid_node_type(exu, cfg), position=[0.0, 0.0, 0.0], rotationMatrix=np.eye(3)
    )
    n_frame = mbs.AddNode(rigid)
    points = [mbs.AddNode(NodePoint(referenceCoordinates=p.tolist())) for p in nodes]
    stiffness = exu.MatrixContainer()
    stiffness.SetWithSparseMatrix(body.stiffness.tocsr(), useDenseMatrix=False)
    mass = exu.MatrixContainer()
    mass.SetWithSparseMatrix(body.mass.tocsr(), useDenseMatrix=False)
    obj = mbs.AddObject(
        ObjectFFRF(
            nodeNumbers=[n_frame, *points],
            massMatrixFF=mass,
            stiffnessMatrixFF=stiffness,
            visualization=VObjectFFRF(show=False),
        )
    )

    # clamp face x0 to the frame: its nodal displacements are zero
    n_ground = mbs.AddNode(NodePointGround(referenceCoordinates=[0.0, 0.0, 0.0]))
    m_zero = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=n_ground, coordinate=0))
    for node in x0:
        for coordinate in range(3):
            m_coord = mbs.AddMarker(
                MarkerNodeCoordinate(nodeNumber=points[node], coordinate=coordinate)
            )
            mbs.AddObject(CoordinateConstraint(markerNumbers=[m_zero, m_coord]))

    # gravity: consistent nodal loads = row sums of M times g, applied as the total weight at
    # the mass-weighted mean of the nodes (same virtual work)
    lumped = np.asarray(body.mass.sum(axis=1)).ravel()[0::3]
    total = float(lumped.sum())
    m_mass = mbs.AddMarker(
        MarkerSuperElementPosition(
            bodyNumber=obj,
            meshNodeNumbers=list(range(len(nodes))),
            weightingFactors=(lumped / total).tolist(),
        )
    )
    mbs.AddLoad(
        LoadForceVector(markerNumber=m_mass, loadVector=(total * np.asarray(GRAVITY)).tolist())
    )

    ground = mbs.AddObject(ObjectGround())
    _hinge(mbs, "sph", ground, nodes[x0].mean(axis=0), obj, x0, n_frame)

    recorder = _Recorder(mbs)
    m_tip = mbs.AddMarker(
        MarkerSuperElementPosition(
            bodyNumber=obj, meshNodeNumbers=x1.tolist(), weightingFactors=_equal_weights(x1)
        )
    )
    recorder.add(
        "x1_centroid",
        SensorMarker(markerNumber=m_tip, outputVariableType=exu.OutputVariableType.Position),
    )
    mbs.Assemble()
    checks = {
        "nodes": len(nodes),
        "nodal_coordinates": 3 * len(nodes),
        "elastic_coordinates": len(body.reference.free_dofs),
        "clamped_coordinates": 3 * len(x0),
        "ode2_coordinates": len(mbs.systemData.GetODE2Coordinates()),
        "algebraic_coordinates": len(mbs.systemData.GetAECoordinates()),
        "mass": total,
        "flexmbd_mass": float(body.invariants.mass),
        "dense_memory_estimate_gib": memory_estimate / 2**30,
    }
    return sc, mbs, recorder, checks, []


# ------------------------------------------------------------------------------------------------
# running


def scenario(model: str, size: str | None = None, steps: int | None = None) -> dict:
    """Step size, number of steps and output interval of a model."""
    if model == "pendulum":
        return {
            "step_size": PENDULUM_STEP,
            "steps": round(PENDULUM_END / PENDULUM_STEP),
            "output_interval": PENDULUM_OUTPUT,
        }
    if model == "slider-crank":
        return {
            "step_size": SLIDER_CRANK_STEP,
            "steps": SLIDER_CRANK_STEPS,
            "output_interval": SLIDER_CRANK_OUTPUT,
        }
    if model == "nodal":
        if size not in NODAL_SIZES:
            raise ValueError(f"nodal size must be one of {NODAL_SIZES}, got {size!r}")
        return {
            "step_size": NODAL_STEP,
            "steps": steps or NODAL_STEPS[size],
            "output_interval": NODAL_STEP,
        }
    if model == "soft":
        return {
            "step_size": SOFT_STEP,
            "steps": steps or round(SOFT_END / SOFT_STEP),
            "output_interval": SOFT_OUTPUT,
        }
    raise ValueError(f"model must be one of {MODELS}, got {model!r}")


def run_in_process(model: str, size: str | None, config: str, steps: int | None = None) -> dict:
    """Build and integrate one model in this process; returns timing, statistics and outputs.

    Keys: ``model``, ``size``, ``config`` (canonical), ``exudyn_version``, ``exudyn_module``,
    ``step_size``, ``end_time``, ``nominal_steps``, ``steps`` (time steps done; more than
    nominal if Exudyn had to reduce steps), ``success``, ``wall_time`` (``mbs.SolveDynamic``
    only), ``steps_per_second``, ``newton_iterations`` (total), ``newton_iterations_per_step``,
    ``jacobians`` (total; each with a factorization), ``jacobians_per_step``, ``build_time``,
    ``checks`` (model data compared with flexmbd), ``outputs`` (``times`` and the recorded
    arrays as lists) and, for ``nodal``, ``step_times`` (wall time of every step).
    """
    cfg = parse_flexible_config(config)
    exu = fourbar._import_exudyn(cfg.solver.fast)
    if exu is None:  # the other compiled module is loaded here: use a fresh interpreter
        return run(model, size, config, steps)
    case = scenario(model, size, steps)
    h, n_steps = case["step_size"], case["steps"]
    end_time = n_steps * h

    start = time.perf_counter()
    if model == "pendulum":
        sc, mbs, recorder, checks, keep_alive = build_pendulum(exu, cfg)
    elif model == "slider-crank":
        sc, mbs, recorder, checks, keep_alive = build_slider_crank(exu, cfg)
    else:
        sc, mbs, recorder, checks, keep_alive = build_nodal(exu, cfg, size, soft=model == "soft")
    build_time = time.perf_counter() - start

    settings = fourbar.simulation_settings(exu, cfg.solver, h, end_time)
    settings.solution.sensors.active = True  # internal storage only: no sensor files
    settings.solution.sensors.writePeriod = case["output_interval"]

    step_starts: list[float] = []
    if model == "nodal":

        def pre_step(mbs, t):
            step_starts.append(time.perf_counter())
            return True

        mbs.SetPreStepUserFunction(pre_step)

    print_to_console = exu.config.printToConsole
    exu.config.printToConsole = False
    try:
        start = time.perf_counter()
        success = mbs.SolveDynamic(settings, showHints=False, storeSolver=True)
        wall_time = time.perf_counter() - start
    except Exception as error:
        reached = mbs.sys["dynamicSolver"].it.currentTime if "dynamicSolver" in mbs.sys else 0.0
        raise RuntimeError(
            f"Exudyn solver failed for {model} {size or ''} config {cfg.name()} "
            f"at t={reached:.5f} s: {error}"
        ) from error
    finally:
        exu.config.printToConsole = print_to_console
    end = time.perf_counter()

    solver = mbs.sys["dynamicSolver"]
    steps_done = int(solver.it.currentStepIndex) - 1
    newton_total = int(solver.it.newtonStepsCount)
    jacobian_total = int(solver.it.newtonJacobiCount)
    outputs = recorder.collect()
    result = {
        "model": model,
        "size": size if model == "nodal" else None,
        "config": cfg.name(),
        "exudyn_version": exu.__version__,
        "exudyn_module": "exudynCPPfast" if fourbar._exudyn_is_fast(exu) else "exudynCPP",
        "step_size": h,
        "end_time": end_time,
        "nominal_steps": n_steps,
        "steps": steps_done,
        "success": bool(success),
        "wall_time": wall_time,
        "steps_per_second": steps_done / wall_time if wall_time > 0 else math.inf,
        "newton_iterations": newton_total,
        "newton_iterations_per_step": newton_total / max(steps_done, 1),
        "jacobians": jacobian_total,
        "jacobians_per_step": jacobian_total / max(steps_done, 1),
        "build_time": build_time,
        "checks": checks,
        "outputs": outputs,
    }
    if model == "soft":
        # Exudyn's own counts: steps taken (with its step reductions), Newton iterations.
        result["end_reached"] = float(solver.it.currentTime)
    if step_starts:
        marks = [*step_starts, end]
        result["initialization_time"] = step_starts[0] - start
        step_times = [b - a for a, b in pairwise(marks)]
        result["step_times"] = step_times
        result["first_step_time"] = step_times[0]
        result["later_step_time_median"] = float(np.median(step_times[1:] or step_times))
    keep_alive.clear()  # the symbolic user functions were needed until here
    sc.Reset()
    return result


def run(model: str, size: str | None, config: str, steps: int | None = None) -> dict:
    """``run_in_process`` in a fresh interpreter (clean memory, either compiled module).

    A worker that dies (e.g. a segmentation fault in Exudyn) raises ``RuntimeError``.
    """
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=1, mp_context=context) as pool:
        try:
            return pool.submit(run_in_process, model, size, config, steps).result()
        except BrokenProcessPool as error:
            raise RuntimeError(f"the Exudyn worker process died ({model} {config})") from error


def run_best_of(
    model: str, size: str | None, config: str, repeat: int, steps: int | None = None
) -> dict:
    """Run ``repeat`` times, each in a fresh interpreter, and keep the fastest run."""
    best = None
    walls = []
    for _ in range(max(1, repeat)):
        try:
            res = run(model, size, config, steps)
        except (RuntimeError, MemoryError) as error:
            return {"model": model, "size": size, "config": config, "error": str(error)}
        walls.append(res["wall_time"])
        if best is None or res["wall_time"] < best["wall_time"]:
            best = res
    best["wall_times"] = walls
    return best


# ------------------------------------------------------------------------------------------------
# command line

HEADER = (
    f"{'config':<40} {'steps':>6} {'wall[s]':>9} {'steps/s':>9} {'it/st':>6} {'jac':>5}  "
    f"{'end point':<34}"
)


def _format_row(res: dict) -> str:
    if "error" in res:
        return f"{res['config']:<40} FAILED: {res['error']}"
    outputs = res["outputs"]
    tip = outputs["x1_centroid"][-1]
    row = (
        f"{res['config']:<40} {res['steps']:>6d} {res['wall_time']:>9.3f} "
        f"{res['steps_per_second']:>9.1f} {res['newton_iterations_per_step']:>6.2f} "
        f"{res['jacobians']:>5d}  x1=({tip[0]:+.5f},{tip[1]:+.5f},{tip[2]:+.5f})"
    )
    if "slider_x" in outputs:
        row += f" slider x {min(outputs['slider_x']):.4f}..{max(outputs['slider_x']):.4f}"
    if "step_times" in res:
        row += (
            f" first step {res['first_step_time']:.3f} s, later "
            f"{res['later_step_time_median']:.4f} s/step (median)"
        )
    return row


def _print_checks(model: str, checks: dict) -> None:
    if model in ("nodal", "soft"):
        print(f"  {checks}")
        return
    print(
        f"  mass {checks['exudyn_mass']:.12g} (flexmbd {checks['flexmbd_mass']:.12g}), "
        f"first frequencies {np.round(checks['exudyn_frequencies_hz'][:4], 6).tolist()} Hz, "
        f"max rel. diff to flexmbd {checks['frequency_max_rel_diff']:.1e}; invariants: "
        f"inertia {checks['inertia_max_diff']:.1e}, i1 {checks['i1_max_diff']:.1e}, "
        f"ibar {checks['ibar_cross_max_diff']:.1e}, M_ff {checks['m_ff_max_diff']:.1e}"
    )


def main(argv: list[str] | None = None) -> int:
    """Command-line entry point; see the module docstring."""
    parser = argparse.ArgumentParser(description="Exudyn side of the flexible-body benchmarks.")
    parser.add_argument("--model", choices=MODELS, default="pendulum")
    parser.add_argument("--size", choices=NODAL_SIZES, default="1k", help="nodal model size")
    parser.add_argument("--configs", nargs="+", help="configurations (default: by model)")
    parser.add_argument("--repeat", type=int, default=1, help="runs per config, fastest kept")
    parser.add_argument("--steps", type=int, help="nodal: number of steps (default by size)")
    parser.add_argument("--json", help="write all results to this JSON file")
    args = parser.parse_args(argv)

    configs = args.configs or list(DEFAULT_CONFIGS[args.model])
    configs = [parse_flexible_config(c).name() for c in configs]  # fail early on a typo
    size = args.size if args.model in ("nodal", "soft") else None
    case = scenario(args.model, size, args.steps)
    print(
        f"Exudyn {fourbar._exudyn_version_string()} {args.model}{' ' + size if size else ''}: "
        f"h={case['step_size']:g}, {case['steps']} steps, best of {args.repeat}"
    )
    print(HEADER)
    results = []
    checks_printed = False
    for config in configs:
        res = run_best_of(args.model, size, config, args.repeat, args.steps)
        print(_format_row(res), flush=True)
        if not checks_printed and "checks" in res:
            _print_checks(args.model, res["checks"])
            checks_printed = True
        results.append(res)
    if args.json:
        with open(args.json, "w") as handle:
            json.dump(results, handle, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
