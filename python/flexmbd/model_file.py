"""Model files: a whole simulation (bodies, markers, joints, drivers, forces, sensors, solver,
simulation settings and outputs) described in YAML and checked against pydantic models.

    from flexmbd.model_file import load_model, simulate_model
    model = load_model("pendulum.yaml")      # a ModelFile: .system, .solver, .end_time, ...
    result = simulate_model(model)           # a flexmbd.Result

Items refer to each other by name; the keys follow the Python API (``type: revolute`` is
:meth:`System.add_revolute_joint`). Values are in the units of the file's ``units`` (SI by
default) and are converted to SI on loading. Nothing in a model file is executed: it is read
with a safe YAML loader (plain data only) and Python callables have no model-file form. Every
error is one :class:`flexmbd.errors.ModelFileError` that names the file, the line and the key
path. The reference of every key is ``docs/model-files.md``; :func:`model_schema` gives the
JSON schema.
"""

from __future__ import annotations

import difflib
import math
import os
import re
import stat
import types
import typing
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any, Literal, Union

import numpy as np
import yaml
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict, Discriminator, Field, Tag, ValidationError

from . import _boundary, _core
from .errors import FlexmbdError, ModelFileError
from .result import Result
from .rotation import rotation
from .simulation import simulate
from .system import System

#: Version of the model file format (the optional top-level key ``version``).
MODEL_FILE_VERSION = 1

#: Units a model file may use: name -> size in SI (m, kg, s, rad).
UNITS: dict[str, dict[str, float]] = {
    "length": {"m": 1.0, "cm": 1e-2, "mm": 1e-3},
    "mass": {"kg": 1.0, "g": 1e-3, "t": 1e3},
    "time": {"s": 1.0, "ms": 1e-3},
    "angle": {"rad": 1.0, "deg": math.pi / 180.0},
}

#: Name of the fixed body in model files (``system.ground``).
GROUND = "ground"


# ---------------------------------------------------------------------------------------------
# The schema: pydantic models of every section


class _Spec(BaseModel):
    """Base of the schema models: unknown keys are errors; numbers must be numbers (no
    strings, no booleans), finite."""

    model_config = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False)


Vector = Annotated[list[float], Field(min_length=3, max_length=3)]
Matrix = Annotated[list[Vector], Field(min_length=3, max_length=3)]
Name = Annotated[str, Field(min_length=1)]


def _shape_tag(value: Any) -> str | None:
    """Tag of a value for the unions over its YAML shape: "(name)" for a string, "(number)"
    for a number, "(list)" and "(matrix)" for a list of numbers and of lists, "(mappings)"
    for a list of mappings, "(mapping)" for a mapping without a ``type`` and the ``type`` of
    a mapping that has one."""
    if isinstance(value, str):
        return "(name)"
    if isinstance(value, bool | int | float):
        return "(number)"
    if isinstance(value, dict):
        tag = value.get("type", "(mapping)")
        return tag if isinstance(tag, str) else None
    if isinstance(value, list):
        if value and isinstance(value[0], list):
            return "(matrix)"
        if value and isinstance(value[0], dict):
            return "(mappings)"
        return "(list)"
    return None


# Time functions --------------------------------------------------------------------------------


class ConstantFunction(_Spec):
    """f(t) = value."""

    type: Literal["constant"]
    value: float = Field(description="the value (unit of the quantity it gives)")


class PolynomialFunction(_Spec):
    """f(t) = c0 + c1 t + c2 t^2 + ... (:class:`flexmbd.Polynomial`)."""

    type: Literal["polynomial"]
    coefficients: list[float] = Field(
        min_length=1,
        description="c0, c1, ... in increasing order; c_k in (unit of the quantity) / time^k",
    )


class HarmonicFunction(_Spec):
    """f(t) = offset + amplitude sin(frequency t + phase) (:class:`flexmbd.Harmonic`)."""

    type: Literal["harmonic"]
    amplitude: float = Field(description="unit of the quantity")
    frequency: float = Field(description="angular frequency, angle / time (rad/s in SI)")
    phase: float = Field(0.0, description="angle (rad in SI)")
    offset: float = Field(0.0, description="unit of the quantity")


class SplineFunction(_Spec):
    """Natural cubic spline through (times, values), constant outside (:class:`flexmbd.Spline`)."""

    type: Literal["spline"]
    times: list[float] = Field(min_length=2, description="strictly increasing knot times (time)")
    values: list[float] = Field(min_length=2, description="values at the knots")


TimeFunction = Annotated[
    Annotated[float, Tag("(number)")]
    | Annotated[Name, Tag("(name)")]
    | Annotated[ConstantFunction, Tag("constant")]
    | Annotated[PolynomialFunction, Tag("polynomial")]
    | Annotated[HarmonicFunction, Tag("harmonic")]
    | Annotated[SplineFunction, Tag("spline")],
    Discriminator(_shape_tag),
    Field(
        description="a number (constant), the name of an entry of `functions`, or a mapping "
        "with `type` constant, polynomial, harmonic or spline"
    ),
]
TimeVector = Annotated[list[TimeFunction], Field(min_length=3, max_length=3)]


# Orientations ----------------------------------------------------------------------------------

Axis = Annotated[
    Annotated[Literal["x", "y", "z"], Tag("(name)")] | Annotated[Vector, Tag("(list)")],
    Discriminator(_shape_tag),
]


class AxisRotation(_Spec):
    """A rotation by `angle` about `axis` (Rodrigues' formula, :func:`flexmbd.rotation`)."""

    axis: Axis = Field(description="'x', 'y', 'z' or a non-zero 3-vector")
    angle: float = Field(description="angle (rad in SI)")


Orientation = Annotated[
    Annotated[Matrix, Tag("(matrix)")]
    | Annotated[AxisRotation, Tag("(mapping)")]
    | Annotated[list[AxisRotation], Tag("(mappings)")],
    Discriminator(_shape_tag),
    Field(
        description="a 3 x 3 rotation matrix (rows; its columns are the local axes in the "
        "parent frame), a rotation {axis, angle}, or a list of them applied in turn "
        "(R = R1 R2 ...)"
    ),
]

MarkerOrientation = Annotated[
    Annotated[Matrix, Tag("(matrix)")]
    | Annotated[AxisRotation, Tag("(mapping)")]
    | Annotated[list[AxisRotation], Tag("(mappings)")]
    | Annotated[Literal["principal"], Tag("(name)")],
    Discriminator(_shape_tag),
    Field(
        description="as `orientation` of bodies, or 'principal' on node sets: z the outward "
        "normal of a face, x its axis of largest extent"
    ),
]

Weighting = Literal["auto", "area", "length", "volume", "uniform"]
WeightSpec = Annotated[
    Annotated[Weighting, Tag("(name)")] | Annotated[list[float], Tag("(list)")],
    Discriminator(_shape_tag),
    Field(
        description="how the nodes of an interface are weighted: auto (area on faces, length "
        "on edges, volume on volumes), area, length, volume, uniform, or one weight per node"
    ),
]

NodeSelection = Annotated[
    Annotated[Name, Tag("(name)")] | Annotated[list[int], Tag("(list)")],
    Discriminator(_shape_tag),
]


# Materials and sections ------------------------------------------------------------------------


class MaterialSpec(_Spec):
    """A linear elastic isotropic material (:class:`flexmbd.fe.Material`)."""

    young_modulus: float = Field(gt=0, description="Young's modulus (Pa in SI)")
    poisson_ratio: float = Field(gt=-1.0, lt=0.5, description="Poisson's ratio (-)")
    density: float = Field(gt=0, description="density (kg/m^3 in SI)")


MaterialRef = Annotated[
    Annotated[Name, Tag("(name)")] | Annotated[MaterialSpec, Tag("(mapping)")],
    Discriminator(_shape_tag),
    Field(description="a material, or the name of an entry of `materials`"),
]


class CircleSection(_Spec):
    """Solid circle (:meth:`flexmbd.fe.Section.circle`)."""

    type: Literal["circle"]
    radius: float = Field(gt=0, description="length")
    shear_factor: float | None = Field(None, gt=0, description="Timoshenko shear factor (-)")


class RectangleSection(_Spec):
    """Solid rectangle (:meth:`flexmbd.fe.Section.rectangle`)."""

    type: Literal["rectangle"]
    width: float = Field(gt=0, description="along the section's y axis (length)")
    height: float = Field(gt=0, description="along the section's z axis (length)")
    shear_factor: float | None = Field(None, gt=0, description="Timoshenko shear factor (-)")


class TubeSection(_Spec):
    """Circular tube (:meth:`flexmbd.fe.Section.tube`)."""

    type: Literal["tube"]
    outer: float = Field(gt=0, description="outer radius (length)")
    inner: float = Field(ge=0, description="inner radius (length), < outer")
    shear_factor: float | None = Field(None, gt=0, description="Timoshenko shear factor (-)")


class GeneralSection(_Spec):
    """Section properties given directly (:class:`flexmbd.fe.Section`)."""

    type: Literal["general"]
    area: float = Field(gt=0, description="length^2")
    iy: float = Field(gt=0, description="second moment about the section's y axis (length^4)")
    iz: float = Field(gt=0, description="second moment about the section's z axis (length^4)")
    torsion_constant: float = Field(gt=0, description="length^4")
    shear_factor: float | None = Field(None, gt=0, description="Timoshenko shear factor (-)")


SectionSpec = Annotated[
    CircleSection | RectangleSection | TubeSection | GeneralSection,
    Field(discriminator="type"),
]


# Bodies ----------------------------------------------------------------------------------------

Inertia = Annotated[
    Annotated[Vector, Tag("(list)")] | Annotated[Matrix, Tag("(matrix)")],
    Discriminator(_shape_tag),
    Field(
        description="about the centre of mass in body axes: the three principal moments or a "
        "3 x 3 matrix (mass length^2)"
    ),
]


class RigidBodySpec(_Spec):
    """A rigid body (:meth:`System.add_rigid_body`)."""

    type: Literal["rigid"]
    name: Name
    mass: float = Field(gt=0, description="mass")
    inertia: Inertia
    center_of_mass: Vector | None = Field(None, description="in the body frame (length)")
    position: Vector | None = Field(None, description="body frame origin (length)")
    orientation: Orientation | None = None
    velocity: Vector | None = Field(None, description="of the body origin, global (length/time)")
    angular_velocity: Vector | None = Field(None, description="global (angle/time)")


class PointMassSpec(_Spec):
    """A point mass: translation only (:meth:`System.add_point_mass`)."""

    type: Literal["point-mass"]
    name: Name
    mass: float = Field(gt=0, description="mass")
    position: Vector | None = Field(None, description="length")
    velocity: Vector | None = Field(None, description="length/time")


class BeamSpec(_Spec):
    """A built-in straight beam of equal elements (:func:`flexmbd.fe.straight_beam`): node ids
    1 .. elements + 1 from `start`, node indices 0 .. elements."""

    length: float = Field(gt=0, description="length")
    elements: int = Field(ge=1, description="number of beam elements")
    start: Vector | None = Field(None, description="first node, body frame (length)")
    direction: Vector | None = Field(None, description="axis of the beam (default x)")


class BoxSpec(_Spec):
    """A built-in structured mesh of a box (:func:`flexmbd.fe.shapes.box`); node sets x0, x1,
    y0, y1, z0, z1 (the faces) and all."""

    lengths: Vector = Field(description="edge lengths along x, y, z (length)")
    divisions: Annotated[list[int], Field(min_length=3, max_length=3)] = Field(
        description="cells along x, y, z"
    )
    element: Literal["hex8", "tet4", "tet10"] = "hex8"
    origin: Vector | None = Field(None, description="corner of the box (length)")


class CylinderSpec(_Spec):
    """A tetrahedral mesh of a solid cylinder made by Gmsh (:func:`flexmbd.fe.shapes.cylinder`,
    needs the gmsh package); node sets base, end and mantle."""

    radius: float = Field(gt=0, description="length")
    length: float = Field(gt=0, description="length")
    size: float = Field(gt=0, description="target element size (length)")
    order: Literal[1, 2] = Field(2, description="1: tet4, 2: tet10")
    axis: Vector | None = Field(None, description="from the origin (default x)")


class FlexibleBodySpec(_Spec):
    """A deformable body in the floating frame of reference (:meth:`System.add_flexible_body`)
    from exactly one of `body_file`, `beam`, `mesh`, `box` or `cylinder`. All but `body_file`
    run the preprocessor (:func:`flexmbd.fe.build_body`) with `material` and the options
    below."""

    type: Literal["flexible"]
    name: Name
    # Where the body comes from.
    body_file: str | None = Field(
        None, description="HDF5 body file (relative to the model file), SI units"
    )
    beam: BeamSpec | None = None
    mesh: str | None = Field(
        None,
        description="mesh file (Gmsh .msh, Abaqus .inp, VTK; relative to the model file), "
        "coordinates in the file's length unit",
    )
    box: BoxSpec | None = None
    cylinder: CylinderSpec | None = None
    # Preprocessor options (build_body).
    material: MaterialRef | None = None
    section: SectionSpec | None = Field(None, description="beam section (beams only)")
    section_orientation: Vector | None = Field(
        None, description="the section's y axis, across the beam (build_body `orientation`)"
    )
    mass_matrix: Literal["consistent", "lumped"] | None = Field(
        None, description="build_body `mass` (default consistent)"
    )
    beam_theory: Literal["euler-bernoulli", "timoshenko"] | None = None
    reference: (
        Literal["none", "clamped", "3-2-1", "simply-supported", "mean-axis", "interface"] | None
    ) = Field(None, description="reference conditions: the body frame (default none)")
    reference_nodes: NodeSelection | None = Field(
        None, description="node indices (0-based) or a node set name"
    )
    modes: Literal["fixed-interface", "free-free", "craig-bampton"] | None = Field(
        None, description="modal reduction (default: nodal elastic coordinates)"
    )
    mode_count: int | None = Field(None, ge=0, description="eigenmodes kept")
    interfaces: list[NodeSelection] | None = Field(
        None, description="Craig-Bampton interfaces: node set names or index lists"
    )
    interface_kind: Literal["rbe2", "rbe3", "nodal"] | None = None
    interface_weights: Weighting | list[WeightSpec] | None = Field(
        None, description="weights of the interfaces' nodes: one for all, or one per interface"
    )
    precision: Literal["auto", "double", "single"] | None = None
    # Placement, initial state and damping (add_flexible_body).
    position: Vector | None = Field(None, description="body frame origin (length)")
    orientation: Orientation | None = None
    velocity: Vector | None = Field(None, description="of the body origin, global (length/time)")
    angular_velocity: Vector | None = Field(None, description="global (angle/time)")
    elastic_coordinates: list[float] | None = Field(
        None, description="initial q_f (SI only: not converted)"
    )
    elastic_velocities: list[float] | None = Field(
        None, description="initial dq_f/dt (SI only: not converted)"
    )
    rayleigh_damping: Annotated[list[float], Field(min_length=2, max_length=2)] | None = Field(
        None, description="[alpha (1/time), beta (time)]: D = alpha M_ff + beta K_ff"
    )
    modal_damping: float | None = Field(None, ge=0, description="damping ratio of every mode")
    geometric_stiffness: bool = Field(False, description="stiffening of beams (seed section 6)")
    condense: bool | None = Field(None, description="condense the elastic coordinates")


BodySpec = Annotated[RigidBodySpec | PointMassSpec | FlexibleBodySpec, Field(discriminator="type")]


# Markers ---------------------------------------------------------------------------------------


class MarkerSpec(_Spec):
    """A frame on a body (:meth:`System.add_marker`); with `node`, on a node of a deformable
    body (:meth:`System.add_node_marker`); with `node_set`, at the centroid of a node set
    (:meth:`System.add_node_set_marker`)."""

    name: Name | None = None
    body: Name = Field(description="a body name, or 'ground'")
    position: Vector | None = Field(None, description="in the body frame (length)")
    orientation: MarkerOrientation | None = None
    node: int | None = Field(None, description="node id (of the mesh) of a deformable body")
    node_set: NodeSelection | None = Field(
        None, description="node set name or node ids of a deformable body"
    )
    weights: WeightSpec | None = Field(None, description="node_set: weights of its nodes")
    coupling: Literal["rbe3", "rbe2"] | None = Field(
        None,
        description="node_set: rbe3 (follows the weighted average motion, default) or rbe2 "
        "(the nodes follow the marker rigidly)",
    )


class NamedMarkerSpec(MarkerSpec):
    """An entry of `markers`: a marker with a name."""

    name: Name


MarkerRef = Annotated[
    Annotated[Name, Tag("(name)")] | Annotated[MarkerSpec, Tag("(mapping)")],
    Discriminator(_shape_tag),
    Field(description="a marker name, or a marker defined in place"),
]


# Joints and drivers ----------------------------------------------------------------------------


class JointSpec(_Spec):
    """A joint between two markers (:meth:`System.add_<type>_joint`)."""

    type: Literal[
        "spherical",
        "revolute",
        "cylindrical",
        "prismatic",
        "fixed",
        "universal",
        "planar",
        "inline",
    ]
    name: Name | None = None
    marker1: MarkerRef
    marker2: MarkerRef


class DistanceJointSpec(_Spec):
    """A distance constraint between the marker origins (:meth:`System.add_distance_joint`)."""

    type: Literal["distance"]
    name: Name | None = None
    marker1: MarkerRef
    marker2: MarkerRef
    distance: float | None = Field(None, gt=0, description="length (default: initial)")


class AngleDriverSpec(_Spec):
    """Prescribed rotation of marker2's x axis from marker1's about marker1's z axis
    (:meth:`System.add_angle_driver`)."""

    type: Literal["angle-driver"]
    name: Name | None = None
    marker1: MarkerRef
    marker2: MarkerRef
    angle: TimeFunction = Field(description="angle (rad in SI) as a function of time")


class TranslationDriverSpec(_Spec):
    """Prescribed offset of marker2's origin along marker1's z axis
    (:meth:`System.add_translation_driver`)."""

    type: Literal["translation-driver"]
    name: Name | None = None
    marker1: MarkerRef
    marker2: MarkerRef
    displacement: TimeFunction = Field(description="length as a function of time")


AnyJointSpec = Annotated[
    JointSpec | DistanceJointSpec | AngleDriverSpec | TranslationDriverSpec,
    Field(discriminator="type"),
]


# Forces ----------------------------------------------------------------------------------------


class PointForceSpec(_Spec):
    """A force at a marker's origin (:meth:`System.add_point_force`)."""

    type: Literal["point-force"]
    name: Name | None = None
    marker: MarkerRef
    force: TimeVector = Field(description="three components (force: N in SI)")
    frame: Literal["global", "marker"] = "global"


class TorqueSpec(_Spec):
    """A torque on a marker's body (:meth:`System.add_torque`)."""

    type: Literal["torque"]
    name: Name | None = None
    marker: MarkerRef
    torque: TimeVector = Field(description="three components (force length: N m in SI)")
    frame: Literal["global", "marker"] = "global"


class SpringDamperSpec(_Spec):
    """A linear spring-damper between marker origins (:meth:`System.add_spring_damper`)."""

    type: Literal["spring-damper"]
    name: Name | None = None
    marker1: MarkerRef
    marker2: MarkerRef
    stiffness: float = Field(ge=0, description="force/length (N/m in SI)")
    damping: float = Field(0.0, ge=0, description="force time/length (N s/m in SI)")
    rest_length: float | None = Field(None, ge=0, description="length (default: initial)")
    preload: float = Field(0.0, description="force")


class RotationalSpringDamperSpec(_Spec):
    """A torsional spring-damper about marker1's z axis
    (:meth:`System.add_rotational_spring_damper`)."""

    type: Literal["rotational-spring-damper"]
    name: Name | None = None
    marker1: MarkerRef
    marker2: MarkerRef
    stiffness: float = Field(ge=0, description="torque/angle (N m/rad in SI)")
    damping: float = Field(0.0, ge=0, description="torque time/angle (N m s/rad in SI)")
    rest_angle: float = Field(0.0, description="angle")
    preload: float = Field(0.0, description="torque (N m in SI)")


ForceSpec = Annotated[
    PointForceSpec | TorqueSpec | SpringDamperSpec | RotationalSpringDamperSpec,
    Field(discriminator="type"),
]


# Sensors and outputs ---------------------------------------------------------------------------


class SensorSpec(_Spec):
    """Records a quantity of a marker at every output, in global axes
    (:meth:`System.add_sensor`)."""

    name: Name | None = None
    marker: MarkerRef
    quantity: Literal[
        "position",
        "velocity",
        "acceleration",
        "orientation",
        "angular_velocity",
        "angular_acceleration",
    ]


BODY_QUANTITIES = (
    "position",
    "velocity",
    "orientation",
    "euler_parameters",
    "angular_velocity",
    "elastic_coordinates",
    "elastic_velocities",
    "node_displacements",
    "node_positions",
    "deflection",
    "stresses",
    "section_forces",
)
JOINT_QUANTITIES = ("reaction_force", "reaction_torque", "multipliers")
SYSTEM_QUANTITIES = ("kinetic_energy", "potential_energy", "total_energy", "constraint_violation")


class OutputSpec(_Spec):
    """A time history to report or plot: a sensor, a quantity of a body or joint (the
    :class:`flexmbd.Result` method of that name), or of the whole system. Values are in SI."""

    name: Name | None = Field(None, description="label (default: item and quantity)")
    sensor: Name | None = None
    body: Name | None = None
    joint: Name | None = None
    quantity: Literal[BODY_QUANTITIES + JOINT_QUANTITIES + SYSTEM_QUANTITIES] | None = None  # type: ignore[valid-type]
    nodes: list[int] | None = Field(
        None, description="node ids (node_displacements, node_positions)"
    )
    node: int | None = Field(None, description="node id (deflection)")
    chord: Annotated[list[int], Field(min_length=2, max_length=2)] | None = Field(
        None, description="two node ids: deflection from their chord"
    )


# Solvers and the simulation --------------------------------------------------------------------

RedundantConstraints = Literal["remove", "minimum-norm", "error"]


class GeneralizedAlphaSpec(_Spec):
    """The implicit index-3 generalized-alpha integrator (:class:`flexmbd.GeneralizedAlpha`).
    Options left out take the solver's defaults."""

    type: Literal["generalized-alpha"]
    spectral_radius: float | None = Field(None, ge=0, le=1, description="rho_inf (-)")
    newton_tolerance: float | None = Field(None, gt=0)
    max_iterations: int | None = Field(None, ge=1)
    jacobian: Literal["modified", "step", "full"] | None = None
    step_control: Literal["newton", "fixed", "error"] | None = None
    relative_tolerance: float | None = Field(None, gt=0)
    absolute_tolerance: float | None = Field(None, gt=0)
    min_step_size: float | None = Field(None, gt=0, description="time")
    max_step_size: float | None = Field(None, gt=0, description="time")
    velocity_projection: Literal["auto", "always", "never"] | None = None
    linear_solver: Literal["auto", "lu", "ldlt"] | None = None
    initial_tolerance: float | None = Field(None, gt=0)
    correct_initial_positions: bool | None = None
    correct_initial_velocities: bool | None = None
    redundant_constraints: RedundantConstraints | None = None
    rank_tolerance: float | None = Field(None, gt=0, lt=1)


class ExplicitSolverSpec(_Spec):
    """Explicit Runge-Kutta 4 or Dormand-Prince 5(4) with one of the seed's strategies
    (:class:`flexmbd.ExplicitSolver`). Options left out take the solver's defaults."""

    type: Literal["explicit"]
    method: Literal["rk4", "dopri5"] | None = None
    strategy: Literal["integrate-all", "partitioning", "projection", "joint-coordinates"] | None = (
        None
    )
    formulation: Literal["augmented", "embedding", "joint-space", "coupled", "decoupled"] | None = (
        None
    )
    partition: Literal["lu", "qr", "svd"] | None = None
    independent: list[Annotated[int, Field(ge=0)]] | None = Field(
        None, description="indices of the independent coordinates"
    )
    baumgarte: Annotated[list[float], Field(min_length=2, max_length=2)] | None = Field(
        None, description="[alpha, beta] (1/time each)"
    )
    relative_tolerance: float | None = Field(None, gt=0)
    absolute_tolerance: float | None = Field(None, gt=0)
    constraint_tolerance: float | None = Field(None, gt=0)
    max_iterations: int | None = Field(None, ge=1)
    repartition_ratio: float | None = Field(None, gt=0)
    drift_threshold: float | None = Field(None, gt=0)
    singular_factor: float | None = Field(None, gt=0)
    min_step_size: float | None = Field(None, gt=0, description="time")
    max_step_size: float | None = Field(None, gt=0, description="time")
    initial_tolerance: float | None = Field(None, gt=0)
    correct_initial_positions: bool | None = None
    correct_initial_velocities: bool | None = None
    redundant_constraints: RedundantConstraints | None = None
    rank_tolerance: float | None = Field(None, gt=0, lt=1)
    cut_joints: list[Name] | None = Field(None, description="joint names (joint-coordinates)")


SolverSpec = Annotated[GeneralizedAlphaSpec | ExplicitSolverSpec, Field(discriminator="type")]


class SimulationSpec(_Spec):
    """The time span and steps of :func:`flexmbd.simulate`."""

    end_time: float = Field(description="time")
    step_size: float = Field(gt=0, description="nominal step (time)")
    output_interval: float | None = Field(
        None, gt=0, description="time between outputs (default: every step)"
    )
    start_time: float = Field(0.0, description="time")
    start: Literal["given", "equilibrium", "steady-rotation"] = Field(
        "given",
        description="the state at start_time: the given positions and velocities, the static "
        "(or, under moving drivers, steady) equilibrium, or the steady rotation of rotors "
        "turned at constant speed by drivers",
    )


class UnitsSpec(_Spec):
    """Units of the numbers in the file; everything is converted to SI on loading."""

    length: Literal["m", "cm", "mm"] = "m"
    mass: Literal["kg", "g", "t"] = "kg"
    time: Literal["s", "ms"] = "s"
    angle: Literal["rad", "deg"] = "rad"


class ModelSpec(_Spec):
    """A flexmbd model file."""

    model_config = ConfigDict(title="flexmbd model file")

    version: Literal[1] = Field(MODEL_FILE_VERSION, description="model file format version")
    name: str | None = None
    description: str | None = None
    units: UnitsSpec = Field(default_factory=UnitsSpec)
    gravity: Vector | None = Field(None, description="length/time^2 (default: none)")
    functions: dict[Name, TimeFunction] = Field(
        default_factory=dict, description="named time functions"
    )
    materials: dict[Name, MaterialSpec] = Field(default_factory=dict, description="named materials")
    bodies: list[BodySpec] = Field(default_factory=list)
    markers: list[NamedMarkerSpec] = Field(default_factory=list)
    joints: list[AnyJointSpec] = Field(
        default_factory=list, description="joints and drivers, in the order of their equations"
    )
    forces: list[ForceSpec] = Field(default_factory=list)
    sensors: list[SensorSpec] = Field(default_factory=list)
    solver: SolverSpec | None = Field(None, description="default: generalized-alpha")
    simulation: SimulationSpec
    outputs: list[OutputSpec] | None = Field(None, description="default: every sensor")


def model_schema() -> dict[str, Any]:
    """The JSON schema (draft 2020-12) of model files, generated from the pydantic models."""
    schema = ModelSpec.model_json_schema()
    schema["$schema"] = "https://json-schema.org/draft/2020-12/schema"
    return schema


# ---------------------------------------------------------------------------------------------
# Reading YAML with the line of every key

Path_ = tuple[str | int, ...]

#: Largest model file (bytes), checked before it is read: meshes and matrices belong in mesh
#: and body files, long tables in body files or splines of a few thousand knots.
MAX_FILE_SIZE = 4 * 1024 * 1024

#: Most items a model file may hold, estimated before YAML reads it as the number of its
#: commas and line breaks (every list item and key needs one of them, but the first).
MAX_ITEMS = 100_000

#: Most values a model file may expand to (aliases can multiply a small file).
MAX_VALUES = 250_000

#: Deepest nesting: the file's mapping is level 1, each list, mapping or value in one is one
#: more (the examples nest 7 deep).
MAX_DEPTH = 64

_INT_TAG = "tag:yaml.org,2002:int"
_FLOAT_TAG = "tag:yaml.org,2002:float"

#: Integers: decimal (leading zeros are decimal, as in YAML 1.2, not octal), 0b binary, 0x
#: hexadecimal; not YAML 1.1's base 60 (1:30 is a string, not 90).
_INT = re.compile(r"^(?:[-+]?0b[0-1_]+|[-+]?[0-9][0-9_]*|[-+]?0x[0-9a-fA-F_]+)$")

#: Floats: 1.5, 1.5e-3, 1e-3 (YAML 1.2: no dot needed, exponent sign optional), .5, .inf,
#: .nan; not YAML 1.1's base 60 (1:30.5 is a string).
_FLOAT = re.compile(
    r"""^(?:[-+]?[0-9][0-9_]*\.[0-9_]*(?:[eE][-+]?[0-9]+)?
    |[-+]?[0-9][0-9_]*[eE][-+]?[0-9]+
    |[-+]?\.[0-9][0-9_]*(?:[eE][-+]?[0-9]+)?
    |[-+]?\.(?:inf|Inf|INF)
    |\.(?:nan|NaN|NAN))$""",
    re.VERBOSE,
)

#: What YAML 1.1 reads as a number in base 60 (in messages: such values are strings here).
_SEXAGESIMAL = re.compile(r"^[-+]?[0-9][0-9_]*(?::[0-5]?[0-9])+(?:\.[0-9_]*)?$")

#: Characters YAML does not allow in a file (its reader's own check).
_NOT_PRINTABLE = yaml.reader.Reader.NON_PRINTABLE

#: Line breaks of YAML, to count lines as its error marks do.
_LINE_BREAK = re.compile("\r\n|[\n\r\x85\u2028\u2029]")

#: Names of the ASCII control characters (U+0000 .. U+001F, U+007F).
_CONTROL_NAMES = (
    "NUL SOH STX ETX EOT ENQ ACK BEL BS HT LF VT FF CR SO SI "
    "DLE DC1 DC2 DC3 DC4 NAK SYN ETB CAN EM SUB ESC FS GS RS US"
).split()


class _ReadError(yaml.YAMLError):
    """A value the loader refuses: at `node` (its key path is then known) or at `mark`."""

    def __init__(self, message: str, node: yaml.Node | None = None, mark: Any = None):
        super().__init__(message)
        self.message = message
        self.node = node
        self.mark = mark if node is None else node.start_mark


class _Loader(yaml.SafeLoader):
    """The safe loader (plain data only: no Python tags, nothing executed) with YAML 1.2
    numbers (``1e-5`` is a number; ``1:30`` and other base-60 forms are strings), a limit
    on nesting, and constructor errors reported at their node."""

    def __init__(self, stream: str):
        super().__init__(stream)
        self.depth = 0

    def compose_node(self, parent: Any, index: Any) -> Any:
        # Nesting deeper than MAX_DEPTH is refused before the recursion of the composer.
        self.depth += 1
        try:
            if self.depth > MAX_DEPTH:
                mark = self.peek_event().start_mark
                raise _ReadError(f"nested more than {MAX_DEPTH} levels deep", mark=mark)
            return super().compose_node(parent, index)
        finally:
            self.depth -= 1

    def construct_object(self, node: Any, deep: bool = False) -> Any:
        try:
            return super().construct_object(node, deep)
        except yaml.YAMLError:
            raise
        except (ValueError, TypeError, KeyError, IndexError, AttributeError, ArithmeticError):
            tag = str(node.tag).replace("tag:yaml.org,2002:", "!!")
            value = node.value if isinstance(node, yaml.ScalarNode) else f"a {node.id}"
            raise _ReadError(f"{_value_text(value)} is not a valid {tag} value", node) from None

    def construct_int(self, node: Any) -> int:
        """An integer: decimal (leading zeros too), 0b binary or 0x hexadecimal."""
        text = str(self.construct_scalar(node)).replace("_", "")
        sign = -1 if text.startswith("-") else 1
        digits = text.lstrip("+-")
        base = {"0b": 2, "0x": 16}.get(digits[:2], 10)
        return sign * int(digits[2:] if base != 10 else digits, base)

    def construct_float(self, node: Any) -> float:
        """A float, not in base 60 (``!!float 1:30`` is refused)."""
        if ":" in str(node.value):
            raise ValueError("base-60 numbers are not read")
        return float(super().construct_yaml_float(node))


# Only the resolvers of ints and floats change: the others (bool, null, ...) stay YAML 1.1's.
_Loader.yaml_implicit_resolvers = {
    first: [(tag, regexp) for tag, regexp in resolvers if tag not in (_INT_TAG, _FLOAT_TAG)]
    for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()
}
_Loader.add_implicit_resolver(_INT_TAG, _INT, list("-+0123456789"))
_Loader.add_implicit_resolver(_FLOAT_TAG, _FLOAT, list("-+0123456789."))
_Loader.add_constructor(_INT_TAG, _Loader.construct_int)
_Loader.add_constructor(_FLOAT_TAG, _Loader.construct_float)


def _key_path(path: Path_) -> str:
    text = ""
    for part in path:
        name = _short(part, 60)
        text += f"[{part}]" if isinstance(part, int) else (f".{name}" if text else name)
    return text


class _Source:
    """A model file's name, folder and the line of every key path (1-based)."""

    def __init__(self, path: Path, display: str):
        self.path = path
        self.display = display
        self.folder = path.parent
        self.lines: dict[Path_, int] = {}
        self.paths: dict[int, Path_] = {}

    def line(self, path: Path_) -> int | None:
        """The line of `path`, or of its nearest parent that is in the file."""
        for k in range(len(path), -1, -1):
            if path[:k] in self.lines:
                return self.lines[path[:k]]
        return None

    def error(self, path: Path_, message: str, line: int | None = None) -> ModelFileError:
        """The error at `path` (at `line` if given, else the line of `path`)."""
        line = self.line(path) if line is None else line
        where = f"{self.display}: line {line}" if line is not None else self.display
        key = _key_path(path) or None
        text = f"{where}: {key}: {message}" if key else f"{where}: {message}"
        return ModelFileError(text, file=self.display, line=line, key=key)

    def check(self, text: str) -> None:
        """Checks the text before YAML reads it: its estimated item count (MAX_ITEMS) and
        characters YAML does not allow (control characters such as NUL and BEL)."""
        breaks = sum(text.count(c) for c in "\n\r\x85\u2028\u2029") - text.count("\r\n")
        items = text.count(",") + breaks
        if items > MAX_ITEMS:
            raise ModelFileError(
                f"{self.display}: the model file holds about {items} items (commas and line "
                f"breaks), more than the limit of {MAX_ITEMS}: put meshes, matrices and long "
                "tables in mesh or body files",
                file=self.display,
            )
        found = _NOT_PRINTABLE.search(text)
        if found is not None:
            start = found.start()
            before = list(_LINE_BREAK.finditer(text, 0, start))
            line = len(before) + 1
            column = start - (before[-1].end() if before else 0) + 1
            code = ord(found.group())
            if code < 0x20:
                name = f" ({_CONTROL_NAMES[code]})"
            elif code == 0x7F:
                name = " (DEL)"
            else:
                name = ""
            kind = "control character" if code < 0x20 or 0x7F <= code < 0xA0 else "character"
            raise ModelFileError(
                f"{self.display}: line {line}, column {column}: {kind} U+{code:04X}{name} is "
                "not allowed in YAML; remove it",
                file=self.display,
                line=line,
            )

    def read(self, text: str) -> Any:
        """Parses the YAML text, recording the lines of its keys; one error for syntax errors,
        duplicate keys, tags that are not plain data, values that a tag cannot read and
        nesting deeper than MAX_DEPTH."""
        self.check(text)
        loader = _Loader(text)
        try:
            node = loader.get_single_node()
            if node is None:
                raise ModelFileError(
                    f"{self.display}: the model file is empty", file=self.display, line=None
                )
            self._walk(node, (), [0])
            return loader.construct_document(node)
        except _ReadError as error:
            raise self._read_error(error) from None
        except yaml.MarkedYAMLError as error:
            raise self._yaml_error(error) from None
        except yaml.YAMLError as error:
            raise ModelFileError(f"{self.display}: {error}", file=self.display) from None
        finally:
            loader.dispose()

    def _read_error(self, error: _ReadError) -> ModelFileError:
        if error.node is not None and id(error.node) in self.paths:
            path = self.paths[id(error.node)]
            return self.error(path, error.message, error.node.start_mark.line + 1)
        mark = error.mark
        if mark is None:
            return ModelFileError(f"{self.display}: {error.message}", file=self.display)
        line = mark.line + 1
        return ModelFileError(
            f"{self.display}: line {line}, column {mark.column + 1}: {error.message}",
            file=self.display,
            line=line,
        )

    def _yaml_error(self, error: yaml.MarkedYAMLError) -> ModelFileError:
        mark = error.problem_mark or error.context_mark
        problem = error.problem or error.context or "invalid YAML"
        unknown_tag = re.search(r"constructor for the tag '([^']*)'", problem)
        if unknown_tag:
            tag = unknown_tag.group(1).replace("tag:yaml.org,2002:", "!!")
            problem = (
                f"the tag {tag!r} is not allowed: model files hold plain data "
                "(mappings, lists, strings, numbers, booleans); nothing is executed"
            )
        else:
            problem = f"YAML syntax error: {problem}"
        if mark is None:
            return ModelFileError(f"{self.display}: {problem}", file=self.display)
        line = mark.line + 1
        return ModelFileError(
            f"{self.display}: line {line}, column {mark.column + 1}: {problem}",
            file=self.display,
            line=line,
        )

    def _walk(self, node: yaml.Node, path: Path_, count: list[int]) -> None:
        count[0] += 1
        if count[0] > MAX_VALUES:
            raise ModelFileError(
                f"{self.display}: the model file expands to more than {MAX_VALUES} values "
                "(through aliases?)",
                file=self.display,
            )
        if len(path) > MAX_DEPTH:
            # Only aliases get here (the loader limits the nesting): one inside its own anchor.
            message = f"nested more than {MAX_DEPTH} levels deep (an alias inside its anchor?)"
            raise self.error(path[:1], message, node.start_mark.line + 1)
        self.lines.setdefault(path, node.start_mark.line + 1)
        self.paths.setdefault(id(node), path)
        if isinstance(node, yaml.MappingNode):
            seen: dict[str, int] = {}
            for key_node, value_node in node.value:
                if key_node.tag == "tag:yaml.org,2002:merge":
                    continue
                key = str(key_node.value)
                line = key_node.start_mark.line + 1
                if key in seen and isinstance(key_node, yaml.ScalarNode):
                    message = f"duplicate key {_value_text(key)} (first at line {seen[key]})"
                    raise self.error(path + (key,), message, line)
                seen[key] = line
                self.lines[path + (key,)] = line
                self.paths.setdefault(id(key_node), path + (key,))
                self._walk(value_node, path + (key,), count)
        elif isinstance(node, yaml.SequenceNode):
            for index, item in enumerate(node.value):
                self._walk(item, path + (index,), count)


# Pydantic errors as one message with its line ---------------------------------------------------


def _unwrap(annotation: Any) -> Any:
    """The type inside Annotated[...] and Optional[...]."""
    while True:
        if typing.get_origin(annotation) is Annotated:
            annotation = typing.get_args(annotation)[0]
            continue
        if typing.get_origin(annotation) in (Union, types.UnionType):
            members = [a for a in typing.get_args(annotation) if a is not type(None)]
            if len(members) == 1:
                annotation = members[0]
                continue
        return annotation


def _union_member(annotation: Any, tag: Any) -> Any:
    """The member of a tagged union whose tag (pydantic Tag, or the `type` literal) is `tag`."""
    for member in typing.get_args(annotation):
        if typing.get_origin(member) is Annotated:
            if any(isinstance(m, Tag) and m.tag == tag for m in typing.get_args(member)[1:]):
                return member
        inner = _unwrap(member)
        if (
            isinstance(inner, type)
            and issubclass(inner, BaseModel)
            and "type" in inner.model_fields
        ):
            if tag in typing.get_args(inner.model_fields["type"].annotation):
                return member
    return None


def _locate(loc: Sequence[str | int]) -> tuple[Path_, type[BaseModel] | None]:
    """The key path in the file of a pydantic error location (its union tags dropped), and the
    schema model at its end (or None)."""
    annotation: Any = ModelSpec
    path: list[str | int] = []
    for part in loc:
        annotation = _unwrap(annotation)
        origin = typing.get_origin(annotation)
        if origin in (Union, types.UnionType):
            annotation = _union_member(annotation, part)  # `part` is the tag of a member
            continue
        path.append(part)
        if isinstance(annotation, type) and issubclass(annotation, BaseModel):
            known = annotation.model_fields.get(str(part))
            annotation = None if known is None else known.annotation
        elif origin in (list, dict):
            annotation = typing.get_args(annotation)[-1]
        else:
            annotation = None
    annotation = _unwrap(annotation)
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return tuple(path), annotation
    return tuple(path), None


#: What each shape tag of `_shape_tag` stands for, in messages.
_SHAPES = {
    "(number)": "a number",
    "(name)": "a name",
    "(list)": "a list of numbers",
    "(matrix)": "a 3 x 3 matrix",
    "(mapping)": "a mapping",
    "(mappings)": "a list of mappings",
}


def _value_text(value: Any) -> str:
    """A value for a message: its repr, at most 60 characters."""
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _short(name: Any, limit: int = 40) -> str:
    """A name for a message, at most `limit` characters."""
    text = str(name)
    return text if len(text) <= limit else text[: limit - 3] + "..."


#: Most names a message lists (known bodies, markers, ...).
_LISTED = 20


def _listing(names: Any) -> str:
    """Names for a message ("none" if there are none): each shortened, at most _LISTED (a
    model file may name an item with a string of megabytes, or have thousands of items)."""
    items = [_short(name) for name in names]
    if not items:
        return "none"
    more = len(items) - _LISTED
    return ", ".join(items[:_LISTED]) + (f", ... ({more} more)" if more > 0 else "")


def _validation_message(error: dict[str, Any]) -> tuple[Path_, str]:
    """The key path and the message of one pydantic error."""
    kind = error["type"]
    ctx = error.get("ctx") or {}
    loc = error["loc"]
    path, _ = _locate(loc)
    if kind == "missing":
        return path[:-1], f"missing key {_value_text(loc[-1])}"
    if kind == "extra_forbidden":
        key = str(loc[-1])
        _, model = _locate(loc[:-1])
        if model is None:
            return path, f"unknown key {_value_text(key)}"
        allowed = list(model.model_fields)
        close = difflib.get_close_matches(key, allowed, n=1)
        hint = f"; did you mean {close[0]!r}?" if close else ""
        return path, f"unknown key {_value_text(key)} (allowed: {', '.join(allowed)}){hint}"
    if kind == "union_tag_not_found" and isinstance(error.get("input"), dict):
        value = error["input"]
        if "type" in value:
            return path + ("type",), f"type must be a name, got {_value_text(value['type'])}"
        return path, "missing key 'type'"
    if kind in ("union_tag_invalid", "union_tag_not_found"):
        value = error.get("input")
        tags = [t.strip("'") for t in str(ctx.get("expected_tags", "")).split(", ")]
        named = [t for t in tags if t and not t.startswith("(")]
        if isinstance(value, dict) and named:
            if "type" not in value:
                return path, "missing key 'type'"
            return path + (
                "type",
            ), f"unknown type {_value_text(value['type'])} (one of: {', '.join(named)})"
        kinds = [_SHAPES[t] for t in tags if t in _SHAPES]
        if named:
            kinds.append(f"a mapping with type {', '.join(named)}")
        expected = ", ".join(kinds) if kinds else "another kind of value"
        return path, f"expected {expected}; got {_value_text(value)}"
    if kind in ("too_short", "too_long"):
        count = ctx.get("actual_length")
        bound = ctx.get("min_length" if kind == "too_short" else "max_length")
        more = "at least" if kind == "too_short" else "at most"
        return path, f"expected {more} {bound} items, got {count}"
    message = error["msg"]
    if "input" in error and kind not in ("model_type", "dict_type"):
        message += f", got {_value_text(error['input'])}"
    value = error.get("input")
    if isinstance(value, str) and _SEXAGESIMAL.match(value) and kind in ("float_type", "int_type"):
        message += " (base-60 numbers such as 1:30 are not read: write 90)"
    return path, message


def _validation_error(source: _Source, error: ValidationError) -> ModelFileError:
    errors = error.errors()
    # An unknown key first: a misspelt key also makes the key it stands for missing.
    first = min(errors, key=lambda e: e["type"] != "extra_forbidden")
    path, message = _validation_message(first)
    if len(errors) > 1:
        others = len(errors) - 1
        message += f" (and {others} more error{'s' if others > 1 else ''})"
    return source.error(path, message)


# ---------------------------------------------------------------------------------------------
# Building the system


class _Units:
    """Scale factors to SI of the file's units."""

    def __init__(self, spec: UnitsSpec):
        self.names = spec.model_dump()
        self.length = UNITS["length"][spec.length]
        self.mass = UNITS["mass"][spec.mass]
        self.time = UNITS["time"][spec.time]
        self.angle = UNITS["angle"][spec.angle]

    @property
    def is_si(self) -> bool:
        return self.length == self.mass == self.time == self.angle == 1.0

    def scale(self, length: int = 0, mass: int = 0, time: int = 0, angle: int = 0) -> float:
        """SI size of one unit of length^l mass^m time^t angle^a."""
        return self.length**length * self.mass**mass * self.time**time * self.angle**angle

    @property
    def force(self) -> float:
        return self.scale(length=1, mass=1, time=-2)

    @property
    def torque(self) -> float:
        return self.scale(length=2, mass=1, time=-2)


def _scaled(values: Sequence[float] | None, scale: float) -> list[float] | None:
    return None if values is None else [float(v) * scale for v in values]


@dataclass
class Output:
    """An output of a model file: `kind` "sensor", "body", "joint" or "system", the `item`
    name (None for the system), the `quantity` and its node options."""

    label: str
    kind: str
    item: str | None
    quantity: str | None
    nodes: list[int] | None = None
    node: int | None = None
    chord: tuple[int, int] | None = None

    def values(self, result: Result) -> NDArray[np.float64]:
        """The time history of this output in `result` (SI units), time first."""
        if self.kind == "sensor":
            return result.sensor(self.item)
        if self.kind == "system":
            return np.asarray(getattr(result, str(self.quantity)))
        if self.kind == "joint":
            if self.quantity == "multipliers":
                return result.joint_multipliers(self.item)
            return getattr(result, str(self.quantity))(self.item)
        if self.quantity in ("node_displacements", "node_positions"):
            return getattr(result, self.quantity)(self.item, self.nodes)
        if self.quantity == "deflection":
            return result.deflection(self.item, int(self.node or 0), self.chord)
        return getattr(result, str(self.quantity))(self.item)


@dataclass
class ModelFile:
    """A loaded model file: the system and everything needed to simulate it (SI units).

    Attributes:
        path: the model file.
        name, description: from the file (name defaults to the file's stem).
        units: the units the file was written in (its values are converted to SI).
        system: the :class:`flexmbd.System`.
        solver: a :class:`flexmbd.GeneralizedAlpha` or :class:`flexmbd.ExplicitSolver`.
        end_time, step_size, start_time (s); output_interval (s, or None: every step).
        start: the state at start_time ("given", "equilibrium" or "steady-rotation", as
            ``initial_state`` of :func:`flexmbd.simulate`).
        outputs: what to report or plot (:class:`Output`, ``values(result)``).
        bodies, markers, joints, forces, sensors: name -> id of the named items.
        body_data: name -> :class:`flexmbd.fe.FlexibleBodyData` of the deformable bodies.
        spec: the validated file (:class:`ModelSpec`), in the file's units.
    """

    path: Path
    name: str
    description: str
    units: dict[str, str]
    system: System
    solver: _boundary.GeneralizedAlpha | _boundary.ExplicitSolver
    end_time: float
    step_size: float
    output_interval: float | None
    start_time: float
    outputs: list[Output]
    start: str = "given"
    bodies: dict[str, _core.BodyId] = field(default_factory=dict)
    markers: dict[str, _core.MarkerId] = field(default_factory=dict)
    joints: dict[str, _core.JointId] = field(default_factory=dict)
    forces: dict[str, _core.ForceId] = field(default_factory=dict)
    sensors: dict[str, _core.SensorId] = field(default_factory=dict)
    body_data: dict[str, Any] = field(default_factory=dict)
    spec: ModelSpec | None = None

    @property
    def file_stem(self) -> str:
        """The name as the stem of file names (``flexmbd run`` names its results, plots and
        animations after it): characters that are not allowed in file names on some system
        (path separators, control and other invisible characters, ``<>:"|?*``) become ``_``,
        leading and trailing dots and spaces are dropped, at most 120 bytes of UTF-8 are
        kept, Windows' reserved names (``CON``, ``NUL``, ...) get a ``_``, and a name that is
        then empty gives the model file's stem (or ``model``). Never a path: no folder, no
        ``..``, not hidden."""
        for name in (self.name, self.path.stem):
            stem = _file_stem(name)
            if stem:
                return stem
        return "model"

    def output_values(self, result: Result) -> dict[str, NDArray[np.float64]]:
        """label -> time history (SI) of every output, in the order of the file."""
        return {output.label: output.values(result) for output in self.outputs}

    @property
    def plots(self) -> list[str]:
        """The outputs as quantity names of :func:`flexmbd.plotting.plot_result` (what
        ``flexmbd run`` plots): ``"sensor:NAME"``, ``"position:NAME"``, ``"reaction:NAME"``,
        ``"deflection:NAME:NODE"``, ``"energy"``, ``"violation"``, ...; each once, in the order
        of the outputs. Outputs without a plot of their own are left out."""
        names: list[str] = []
        for output in self.outputs:
            if output.kind == "sensor":
                name = f"sensor:{output.item}"
            elif output.kind == "system":
                name = "violation" if output.quantity == "constraint_violation" else "energy"
            elif output.kind == "joint":
                name = f"reaction:{output.item}"
            elif output.quantity == "deflection":
                name = f"deflection:{output.item}:{output.node}"
            elif output.quantity in _PLOTS:
                name = f"{_PLOTS[output.quantity]}:{output.item}"
            else:
                continue
            if name not in names:
                names.append(name)
        return names


#: Characters that some file system does not allow in a file name (Windows: <>:"/\\|?*).
_NOT_IN_FILE_NAMES = re.compile(r'[<>:"/\\|?*\x00-\x1f\x7f-\x9f]')

#: File names Windows reserves (with any extension).
_RESERVED_STEMS = {"CON", "PRN", "AUX", "NUL"} | {
    f"{p}{k}" for p in ("COM", "LPT") for k in range(10)
}


def _file_stem(name: str) -> str:
    """`name` as a file name stem (see :attr:`ModelFile.file_stem`); empty if nothing is left."""
    printable = "".join(c if c.isprintable() else "_" for c in name)
    stem = _NOT_IN_FILE_NAMES.sub("_", printable).strip(" .")
    stem = stem.encode("utf-8")[:120].decode("utf-8", errors="ignore").rstrip(" .")
    if stem.split(".")[0].upper() in _RESERVED_STEMS:
        stem += "_"
    return stem


def _name_problem(name: str) -> str | None:
    """Why a model `name` cannot be the stem of file names, or None: it is a plain name."""
    what = "a model name is a plain name (the stem of the results' file names)"
    if "/" in name or "\\" in name:
        return f"{what}: no path separators ('/', '\\'), got {_value_text(name)}"
    hidden = next((c for c in name if not c.isprintable()), None)
    if hidden is not None:
        character = f"U+{ord(hidden):04X}"
        return f"{what}: no control or invisible characters ({character}), got {_value_text(name)}"
    if name.startswith("."):
        return f"{what}: it may not start with a dot, got {_value_text(name)}"
    return None


#: Body output quantity -> its plot in `flexmbd.plotting`.
_PLOTS = {
    "position": "position",
    "velocity": "velocity",
    "angular_velocity": "angular-velocity",
    "elastic_coordinates": "elastic",
    "node_displacements": "deflection",
    "stresses": "stress",
}


_PREPROCESS_KEYS = (
    "material",
    "section",
    "section_orientation",
    "mass_matrix",
    "beam_theory",
    "reference",
    "reference_nodes",
    "modes",
    "mode_count",
    "interfaces",
    "interface_kind",
    "interface_weights",
    "precision",
)
_SOURCES = ("body_file", "beam", "mesh", "box", "cylinder")


class _Builder:
    """Builds a :class:`System` from a validated model file, converting to SI and resolving
    names; every error names the key path."""

    def __init__(self, spec: ModelSpec, source: _Source):
        self.spec = spec
        self.source = source
        self.units = _Units(spec.units)
        gravity = _scaled(spec.gravity, self.units.scale(length=1, time=-2))
        self.system = System(gravity=gravity)
        self.bodies: dict[str, _core.BodyId] = {GROUND: self.system.ground}
        self.flexible: dict[str, Any] = {}
        self.markers: dict[str, _core.MarkerId] = {}
        self.joints: dict[str, _core.JointId] = {}
        self.forces: dict[str, _core.ForceId] = {}
        self.sensors: dict[str, _core.SensorId] = {}
        self.first: dict[tuple[str, str], Path_] = {}
        # Entry of `functions` -> the function it stands for (not a name) and its key path.
        self.targets: dict[str, tuple[Any, Path_]] = {}
        self.check_functions()

    def fail(self, path: Path_, message: str) -> ModelFileError:
        return self.source.error(path, message)

    def call(self, path: Path_, function: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
        """Calls the Python API; its errors become model file errors at `path`."""
        try:
            return function(*args, **kwargs)
        except FileNotFoundError as error:
            raise self.fail(path, f"no such file: {error.filename}") from error
        except (FlexmbdError, ValueError) as error:
            raise self.fail(path, str(error)) from error
        except OverflowError as error:
            raise self.fail(path, f"a number is too large ({error})") from error

    def claim(self, kind: str, name: str | None, path: Path_) -> None:
        """Checks that `name` is new among the items of `kind`."""
        if name is None:
            return
        if kind == "body" and name == GROUND:
            raise self.fail(path, f"'{GROUND}' is the fixed body; choose another name")
        first = self.first.get((kind, name))
        if first is not None:
            line = self.source.line(first)
            raise self.fail(
                path, f"duplicate {kind} name {_value_text(name)} (first at line {line})"
            )
        self.first[(kind, name)] = path

    # Values --------------------------------------------------------------------------------

    def orientation(self, spec: Any, path: Path_) -> NDArray[np.float64] | None:
        if spec is None:
            return None
        turns = [spec] if isinstance(spec, AxisRotation) else spec
        if turns and isinstance(turns[0], AxisRotation):
            matrix = None
            for k, turn in enumerate(turns):
                where = path if turns is not spec else path + (k,)
                axis = turn.axis if isinstance(turn.axis, str) else np.asarray(turn.axis)
                step = self.call(where, rotation, axis, turn.angle * self.units.angle)
                matrix = step if matrix is None else matrix @ step
            return matrix
        return np.asarray(spec, dtype=float)

    def check_functions(self) -> None:
        """Resolves the names in `functions`, used or not, into `self.targets`: every name must
        name a function, and no chain of names may come back to where it started (a function
        that names itself, or names one that names it): the error names the cycle."""
        functions = self.spec.functions
        for name in functions:
            # Follow the names from `name` to a function that is not a name (or one resolved).
            chain: dict[str, None] = {}
            spec: Any = name
            while isinstance(spec, str) and spec not in self.targets:
                if spec not in functions:
                    known = _listing(functions)
                    where = ("functions", next(reversed(chain)))
                    raise self.fail(
                        where, f"unknown function {_value_text(spec)} (functions: {known})"
                    )
                if spec in chain:
                    cycle = list(chain)[list(chain).index(spec) :] + [spec]
                    raise self.fail(
                        ("functions", spec),
                        "the functions refer to each other in a cycle: "
                        + " -> ".join(_short(c) for c in cycle),
                    )
                chain[spec] = None
                path: Path_ = ("functions", spec)
                spec = functions[spec]
            target = self.targets[spec] if isinstance(spec, str) else (spec, path)
            for link in chain:
                self.targets[link] = target

    def time_function(self, spec: Any, scale: float, path: Path_) -> Any:
        """A time function of the core for a quantity whose unit is `scale` SI units."""
        if isinstance(spec, str):
            if spec not in self.targets:
                known = _listing(self.spec.functions)
                raise self.fail(path, f"unknown function {_value_text(spec)} (functions: {known})")
            spec, path = self.targets[spec]
        seconds, angle = self.units.time, self.units.angle
        if isinstance(spec, ConstantFunction):
            return self.call(path, _boundary.Constant, spec.value * scale)
        if isinstance(spec, PolynomialFunction):
            coefficients = [c * scale / seconds**k for k, c in enumerate(spec.coefficients)]
            return self.call(path, _boundary.Polynomial, coefficients)
        if isinstance(spec, HarmonicFunction):
            return self.call(
                path,
                _boundary.Harmonic,
                spec.amplitude * scale,
                spec.frequency * angle / seconds,
                spec.phase * angle,
                spec.offset * scale,
            )
        if isinstance(spec, SplineFunction):
            if len(spec.times) != len(spec.values):
                raise self.fail(path, "a spline needs as many values as times")
            times = [t * seconds for t in spec.times]
            return self.call(path, _boundary.Spline, times, [v * scale for v in spec.values])
        return float(spec) * scale

    def material(self, spec: Any, path: Path_) -> Any:
        from .fe import Material

        name = None
        if isinstance(spec, str):
            if spec not in self.spec.materials:
                known = _listing(self.spec.materials)
                raise self.fail(path, f"unknown material {_value_text(spec)} (materials: {known})")
            name, spec = spec, self.spec.materials[spec]
        pressure = self.units.scale(length=-1, mass=1, time=-2)
        density = self.units.scale(length=-3, mass=1)
        return self.call(
            path,
            Material,
            spec.young_modulus * pressure,
            spec.poisson_ratio,
            spec.density * density,
            name=name,
        )

    def section(self, spec: Any, path: Path_) -> Any:
        from .fe import Section

        length = self.units.length
        if isinstance(spec, CircleSection):
            section = self.call(path, Section.circle, spec.radius * length)
        elif isinstance(spec, RectangleSection):
            section = self.call(path, Section.rectangle, spec.width * length, spec.height * length)
        elif isinstance(spec, TubeSection):
            section = self.call(path, Section.tube, spec.outer * length, spec.inner * length)
        else:
            section = self.call(
                path,
                Section,
                spec.area * length**2,
                spec.iy * length**4,
                spec.iz * length**4,
                spec.torsion_constant * length**4,
            )
        if spec.shear_factor is not None:
            section = self.call(path, section.with_shear_factor, spec.shear_factor)
        return section

    def file(self, name: str, path: Path_) -> Path:
        """A file named in the model file (relative to its folder), which must exist."""
        location = Path(name).expanduser()
        if not location.is_absolute():
            location = self.source.folder / location
        if not location.is_file():
            raise self.fail(
                path, f"no such file: {_value_text(name)} (looked for {location.absolute()})"
            )
        return location

    # Bodies --------------------------------------------------------------------------------

    def add_bodies(self) -> None:
        for k, spec in enumerate(self.spec.bodies):
            path: Path_ = ("bodies", k)
            self.claim("body", spec.name, path + ("name",))
            if isinstance(spec, RigidBodySpec):
                body = self.rigid_body(spec, path)
            elif isinstance(spec, PointMassSpec):
                body = self.call(
                    path,
                    self.system.add_point_mass,
                    spec.mass * self.units.mass,
                    position=_scaled(spec.position, self.units.length),
                    velocity=_scaled(spec.velocity, self.units.scale(length=1, time=-1)),
                    name=spec.name,
                )
            else:
                body = self.flexible_body(spec, path)
            self.bodies[spec.name] = body

    def rigid_body(self, spec: RigidBodySpec, path: Path_) -> _core.BodyId:
        units = self.units
        inertia_scale = units.scale(length=2, mass=1)
        if isinstance(spec.inertia[0], list):
            inertia: Any = np.asarray(spec.inertia, dtype=float) * inertia_scale
        else:
            inertia = tuple(float(v) * inertia_scale for v in spec.inertia)
        return self.call(
            path,
            self.system.add_rigid_body,
            spec.mass * units.mass,
            inertia,
            center_of_mass=_scaled(spec.center_of_mass, units.length),
            position=_scaled(spec.position, units.length),
            orientation=self.orientation(spec.orientation, path + ("orientation",)),
            velocity=_scaled(spec.velocity, units.scale(length=1, time=-1)),
            angular_velocity=_scaled(spec.angular_velocity, units.scale(time=-1, angle=1)),
            name=spec.name,
        )

    def flexible_body(self, spec: FlexibleBodySpec, path: Path_) -> _core.BodyId:
        given = [key for key in _SOURCES if getattr(spec, key) is not None]
        if len(given) != 1:
            found = f"got {', '.join(given)}" if given else "got none"
            raise self.fail(
                path, f"a flexible body needs exactly one of {', '.join(_SOURCES)} ({found})"
            )
        if not self.units.is_si:
            for key in ("elastic_coordinates", "elastic_velocities"):
                if getattr(spec, key) is not None:
                    raise self.fail(
                        path + (key,),
                        f"{key} are not converted: give them in a model file with SI units",
                    )
        data = self.body_data(spec, given[0], path)
        self.flexible[spec.name] = data
        units = self.units
        damping = None
        if spec.rayleigh_damping is not None:
            alpha, beta = spec.rayleigh_damping
            damping = (alpha / units.time, beta * units.time)
        return self.call(
            path,
            self.system.add_flexible_body,
            data,
            position=_scaled(spec.position, units.length),
            orientation=self.orientation(spec.orientation, path + ("orientation",)),
            velocity=_scaled(spec.velocity, units.scale(length=1, time=-1)),
            angular_velocity=_scaled(spec.angular_velocity, units.scale(time=-1, angle=1)),
            elastic_coordinates=spec.elastic_coordinates,
            elastic_velocities=spec.elastic_velocities,
            rayleigh_damping=damping,
            modal_damping=spec.modal_damping,
            geometric_stiffness=spec.geometric_stiffness,
            condense=spec.condense,
            name=spec.name,
        )

    def body_data(self, spec: FlexibleBodySpec, kind: str, path: Path_) -> Any:
        """The FlexibleBodyData of a deformable body: read, or preprocessed."""
        from .fe import body_from_mesh, build_body, load_body, read_mesh, shapes, straight_beam

        if kind == "body_file":
            for key in _PREPROCESS_KEYS:
                if getattr(spec, key) is not None:
                    raise self.fail(
                        path + (key,),
                        "not used with body_file: the body file holds a preprocessed body",
                    )
            location = self.file(str(spec.body_file), path + ("body_file",))
            data = self.call(path + ("body_file",), load_body, location)
            si = {"length": "m", "mass": "kg", "time": "s"}
            units = {k: data.units.get(k) for k in si}
            if units != si:
                raise self.fail(path + ("body_file",), f"the body file is in {units}, not SI")
            return data
        if spec.material is None:
            raise self.fail(path + ("material",), f"missing key 'material' (needed with {kind})")
        options = self.preprocess_options(spec, path)
        length = self.units.length
        where = path + (kind,)
        if kind == "beam":
            beam = spec.beam
            assert beam is not None
            if spec.section is None:
                raise self.fail(path + ("section",), "missing key 'section' (needed by beams)")
            extra = {}
            if beam.start is not None:
                extra["start"] = _scaled(beam.start, length)
            if beam.direction is not None:
                extra["direction"] = beam.direction
            nodes, elements = self.call(
                where, straight_beam, beam.length * length, beam.elements, **extra
            )
            return self.call(path, build_body, nodes, elements, options.pop("material"), **options)
        if kind == "mesh":
            location = self.file(str(spec.mesh), where)
            if length == 1.0:
                mesh: Any = location
            else:
                mesh = self.call(where, read_mesh, location)
                mesh.nodes = mesh.nodes * length
            data = self.call(path, body_from_mesh, mesh, options.pop("material"), **options)
            return data.with_metadata(source=str(location))
        if kind == "box":
            box = spec.box
            assert box is not None
            extra = {} if box.origin is None else {"origin": _scaled(box.origin, length)}
            mesh = self.call(
                where,
                shapes.box,
                _scaled(box.lengths, length),
                box.divisions,
                box.element,
                **extra,
            )
        else:
            cylinder = spec.cylinder
            assert cylinder is not None
            extra = {} if cylinder.axis is None else {"axis": cylinder.axis}
            mesh = self.call(
                where,
                shapes.cylinder,
                cylinder.radius * length,
                cylinder.length * length,
                size=cylinder.size * length,
                order=cylinder.order,
                **extra,
            )
        return self.call(path, body_from_mesh, mesh, options.pop("material"), **options)

    def preprocess_options(self, spec: FlexibleBodySpec, path: Path_) -> dict[str, Any]:
        """Keyword arguments of build_body / body_from_mesh (those given only)."""
        options: dict[str, Any] = {"material": self.material(spec.material, path + ("material",))}
        if spec.section is not None:
            options["section"] = self.section(spec.section, path + ("section",))
        renamed = {"section_orientation": "orientation", "mass_matrix": "mass"}
        for key in _PREPROCESS_KEYS[2:]:
            value = getattr(spec, key)
            if value is not None:
                options[renamed.get(key, key)] = value
        if spec.modes is None and spec.mode_count:
            raise self.fail(path + ("mode_count",), "mode_count needs `modes`")
        return options

    # Markers -------------------------------------------------------------------------------

    def body(self, name: str, path: Path_) -> _core.BodyId:
        if name not in self.bodies:
            known = _listing(self.bodies)
            raise self.fail(path, f"unknown body {_value_text(name)} (bodies: {known})")
        return self.bodies[name]

    def add_marker(self, spec: MarkerSpec, path: Path_) -> _core.MarkerId:
        self.claim("marker", spec.name, path + ("name",))
        body = self.body(spec.body, path + ("body",))
        if spec.node_set is None:
            for key in ("weights", "coupling"):
                if getattr(spec, key) is not None:
                    raise self.fail(path + (key,), f"{key} is for markers on a node_set")
            if spec.orientation == "principal":
                raise self.fail(
                    path + ("orientation",), "orientation 'principal' is for markers on a node_set"
                )
        orientation = (
            "principal"
            if spec.orientation == "principal"
            else self.orientation(spec.orientation, path + ("orientation",))
        )
        on_nodes = [key for key in ("node", "node_set") if getattr(spec, key) is not None]
        if len(on_nodes) == 2 or (on_nodes and spec.position is not None):
            keys = on_nodes + (["position"] if spec.position is not None else [])
            raise self.fail(path, f"give one of position, node, node_set (got {', '.join(keys)})")
        if on_nodes and spec.body not in self.flexible:
            raise self.fail(
                path + (on_nodes[0],),
                f"body {_value_text(spec.body)} is not a flexible body: it has no nodes",
            )
        if spec.node is not None:
            marker = self.call(
                path + ("node",),
                self.system.add_node_marker,
                body,
                spec.node,
                orientation=orientation,
                name=spec.name,
            )
        elif spec.node_set is not None:
            marker = self.call(
                path + ("node_set",),
                self.system.add_node_set_marker,
                body,
                spec.node_set,
                orientation=orientation,
                weights="auto" if spec.weights is None else spec.weights,
                coupling=spec.coupling or "rbe3",
                name=spec.name,
            )
        else:
            marker = self.call(
                path,
                self.system.add_marker,
                body,
                position=_scaled(spec.position, self.units.length),
                orientation=orientation,
                name=spec.name,
            )
        if spec.name is not None:
            self.markers[spec.name] = marker
        return marker

    def marker(self, spec: Any, path: Path_) -> _core.MarkerId:
        """A marker by name, or one defined in place."""
        if isinstance(spec, MarkerSpec):
            return self.add_marker(spec, path)
        if spec not in self.markers:
            known = _listing(self.markers)
            raise self.fail(path, f"unknown marker {_value_text(spec)} (markers: {known})")
        return self.markers[spec]

    # Joints, forces, sensors ---------------------------------------------------------------

    def add_joints(self) -> None:
        system = self.system
        for k, spec in enumerate(self.spec.joints):
            path: Path_ = ("joints", k)
            self.claim("joint", spec.name, path + ("name",))
            first = self.marker(spec.marker1, path + ("marker1",))
            second = self.marker(spec.marker2, path + ("marker2",))
            if isinstance(spec, JointSpec):
                add = getattr(system, f"add_{spec.type}_joint")
                joint = self.call(path, add, first, second, name=spec.name)
            elif isinstance(spec, DistanceJointSpec):
                distance = None if spec.distance is None else spec.distance * self.units.length
                joint = self.call(
                    path, system.add_distance_joint, first, second, distance, name=spec.name
                )
            elif isinstance(spec, AngleDriverSpec):
                angle = self.time_function(spec.angle, self.units.angle, path + ("angle",))
                joint = self.call(
                    path, system.add_angle_driver, first, second, angle, name=spec.name
                )
            else:
                displacement = self.time_function(
                    spec.displacement, self.units.length, path + ("displacement",)
                )
                joint = self.call(
                    path, system.add_translation_driver, first, second, displacement, name=spec.name
                )
            if spec.name is not None:
                self.joints[spec.name] = joint

    def add_forces(self) -> None:
        system, units = self.system, self.units
        for k, spec in enumerate(self.spec.forces):
            path: Path_ = ("forces", k)
            self.claim("force", spec.name, path + ("name",))
            if isinstance(spec, PointForceSpec | TorqueSpec):
                marker = self.marker(spec.marker, path + ("marker",))
                key = "force" if isinstance(spec, PointForceSpec) else "torque"
                scale = units.force if key == "force" else units.torque
                components = [
                    self.time_function(f, scale, path + (key, j))
                    for j, f in enumerate(getattr(spec, key))
                ]
                add = system.add_point_force if key == "force" else system.add_torque
                force = self.call(path, add, marker, components, frame=spec.frame, name=spec.name)
            elif isinstance(spec, SpringDamperSpec):
                first = self.marker(spec.marker1, path + ("marker1",))
                second = self.marker(spec.marker2, path + ("marker2",))
                rest = None if spec.rest_length is None else spec.rest_length * units.length
                force = self.call(
                    path,
                    system.add_spring_damper,
                    first,
                    second,
                    stiffness=spec.stiffness * units.scale(mass=1, time=-2),
                    damping=spec.damping * units.scale(mass=1, time=-1),
                    rest_length=rest,
                    preload=spec.preload * units.force,
                    name=spec.name,
                )
            else:
                first = self.marker(spec.marker1, path + ("marker1",))
                second = self.marker(spec.marker2, path + ("marker2",))
                force = self.call(
                    path,
                    system.add_rotational_spring_damper,
                    first,
                    second,
                    stiffness=spec.stiffness * units.torque / units.angle,
                    damping=spec.damping * units.torque * units.time / units.angle,
                    rest_angle=spec.rest_angle * units.angle,
                    preload=spec.preload * units.torque,
                    name=spec.name,
                )
            if spec.name is not None:
                self.forces[spec.name] = force

    def add_sensors(self) -> None:
        for k, spec in enumerate(self.spec.sensors):
            path: Path_ = ("sensors", k)
            self.claim("sensor", spec.name, path + ("name",))
            marker = self.marker(spec.marker, path + ("marker",))
            sensor = self.call(path, self.system.add_sensor, marker, spec.quantity, name=spec.name)
            if spec.name is not None:
                self.sensors[spec.name] = sensor

    # Solver, simulation, outputs -----------------------------------------------------------

    def solver(self) -> _boundary.GeneralizedAlpha | _boundary.ExplicitSolver:
        spec = self.spec.solver
        if spec is None:
            return _boundary.GeneralizedAlpha()
        path: Path_ = ("solver",)
        options = spec.model_dump(exclude_none=True, exclude={"type"})
        for key in ("min_step_size", "max_step_size"):
            if key in options:
                options[key] *= self.units.time
        if isinstance(spec, GeneralizedAlphaSpec):
            return self.call(path, _boundary.GeneralizedAlpha, **options)
        if "baumgarte" in options:
            alpha, beta = options["baumgarte"]
            options["baumgarte"] = (alpha / self.units.time, beta / self.units.time)
        if "cut_joints" in options:
            cut = []
            for j, name in enumerate(options["cut_joints"]):
                if name not in self.joints:
                    known = _listing(self.joints)
                    raise self.fail(
                        path + ("cut_joints", j),
                        f"unknown joint {_value_text(name)} (joints: {known})",
                    )
                cut.append(self.joints[name])
            options["cut_joints"] = cut
        return self.call(path, _boundary.ExplicitSolver, **options)

    def check_step_bounds(self) -> None:
        """The solver's step bounds fit the step size: checked here, before a run, so that the
        error names the keys (the run refuses them too, naming neither)."""
        spec, step = self.spec.solver, self.spec.simulation.step_size
        smallest = getattr(spec, "min_step_size", None)
        if smallest is not None and smallest > step:
            raise self.fail(
                ("solver", "min_step_size"),
                f"the minimum step size {smallest:g} is larger than simulation.step_size {step:g}",
            )
        largest = getattr(spec, "max_step_size", None)
        if largest is not None and largest < step:
            raise self.fail(
                ("solver", "max_step_size"),
                f"the maximum step size {largest:g} is smaller than simulation.step_size {step:g}",
            )

    def outputs(self) -> list[Output]:
        if self.spec.outputs is None:
            return [Output(name, "sensor", name, None) for name in self.sensors]
        outputs = []
        first: dict[str, Path_] = {}
        for k, spec in enumerate(self.spec.outputs):
            path: Path_ = ("outputs", k)
            output = self.output(spec, path)
            # Outputs are reported by label: two with one label would lose one of them.
            if output.label in first:
                line = self.source.line(first[output.label])
                raise self.fail(
                    path + (("name",) if spec.name is not None else ()),
                    f"duplicate output label {_value_text(output.label)} (first at line {line}): "
                    "give each output its own name",
                )
            first[output.label] = path
            outputs.append(output)
        return outputs

    def output(self, spec: OutputSpec, path: Path_) -> Output:
        items = [key for key in ("sensor", "body", "joint") if getattr(spec, key) is not None]
        if len(items) > 1:
            raise self.fail(path, f"give at most one of sensor, body, joint (got {items})")
        kind = items[0] if items else "system"
        quantity = spec.quantity
        allowed = {
            "sensor": (None,),
            "body": BODY_QUANTITIES,
            "joint": JOINT_QUANTITIES,
            "system": SYSTEM_QUANTITIES,
        }[kind]
        if quantity not in allowed:
            what = "a sensor output takes no quantity" if kind == "sensor" else None
            options = ", ".join(str(q) for q in allowed)
            raise self.fail(
                path + ("quantity",),
                what
                or f"the quantity of a {kind} output is one of: {options} "
                f"(got {_value_text(quantity)})",
            )
        item = getattr(spec, kind) if kind != "system" else None
        known = {"sensor": self.sensors, "body": self.bodies, "joint": self.joints}.get(kind)
        if known is not None and item not in known:
            raise self.fail(
                path + (kind,), f"unknown {kind} {_value_text(item)} ({kind}s: {_listing(known)})"
            )
        node_quantities = ("node_displacements", "node_positions", "deflection", "stresses")
        if kind == "body" and (
            quantity in node_quantities + ("section_forces", "elastic_coordinates")
            or quantity == "elastic_velocities"
        ):
            if item not in self.flexible:
                raise self.fail(path + ("body",), f"{_value_text(item)} is not a flexible body")
        if quantity == "deflection" and spec.node is None:
            raise self.fail(path, "missing key 'node' (needed by deflection)")
        for key, users in _NODE_KEYS.items():
            if getattr(spec, key) is not None and (kind != "body" or quantity not in users):
                raise self.fail(
                    path + (key,),
                    f"{key} is only for {' and '.join(users)} outputs of flexible bodies",
                )
        if kind == "body" and item in self.flexible:
            self.check_output_nodes(spec, self.flexible[str(item)], path)
        label = spec.name or " ".join(str(p) for p in (item, quantity) if p is not None)
        chord = None if spec.chord is None else (spec.chord[0], spec.chord[1])
        return Output(label, kind, item, quantity, spec.nodes, spec.node, chord)

    def check_output_nodes(self, spec: OutputSpec, data: Any, path: Path_) -> None:
        """Checks what an output of a flexible body needs of it, as :class:`Output` reads it
        from a result: its node ids, a chord of two distinct places, and the elements and
        material of stresses and section forces."""
        ids = {int(k): i for i, k in enumerate(np.asarray(data.node_ids))}
        given: list[tuple[Path_, int]] = []
        if spec.nodes is not None:
            given += [(path + ("nodes", j), node) for j, node in enumerate(spec.nodes)]
        if spec.node is not None:
            given.append((path + ("node",), spec.node))
        if spec.chord is not None:
            given += [(path + ("chord", j), node) for j, node in enumerate(spec.chord)]
        for where, node in given:
            if node not in ids:
                raise self.fail(
                    where,
                    f"body {_value_text(spec.body)} has no node with id {node} (its {len(ids)} "
                    f"nodes have ids {min(ids, default=0)} to {max(ids, default=0)})",
                )
        if spec.chord is not None:
            if spec.chord[0] == spec.chord[1]:
                raise self.fail(
                    path + ("chord",), f"a chord needs two different nodes, got {spec.chord}"
                )
            first, second = (np.asarray(data.nodes)[ids[k]] for k in spec.chord)
            if not np.any(first != second):
                raise self.fail(
                    path + ("chord",),
                    f"nodes {spec.chord[0]} and {spec.chord[1]} are at the same place: they "
                    "span no chord",
                )
        elements = {kind for kind, cells in data.elements.items() if len(cells)}
        if spec.quantity == "stresses" and not elements - {"beam2"}:
            raise self.fail(
                path + ("quantity",),
                f"body {_value_text(spec.body)} has no solid elements: stresses are those of "
                "solid elements (beams have section_forces)",
            )
        if spec.quantity == "section_forces" and ("beam2" not in elements or data.section is None):
            raise self.fail(
                path + ("quantity",),
                f"body {_value_text(spec.body)} has no beam elements with a section: "
                "section_forces are those of beams",
            )
        if spec.quantity in ("stresses", "section_forces") and not data.material:
            raise self.fail(
                path + ("quantity",),
                f"body {_value_text(spec.body)} has no material (built from matrices): "
                f"no {spec.quantity}",
            )


#: Keys of outputs that name nodes -> the body quantities that use them.
_NODE_KEYS = {
    "nodes": ("node_displacements", "node_positions"),
    "node": ("deflection",),
    "chord": ("deflection",),
}


# ---------------------------------------------------------------------------------------------
# Public functions


def _read_text(location: Path, display: str) -> str:
    """The text of a model file (universal newlines), read only if it is a regular file of at
    most MAX_FILE_SIZE bytes."""
    try:
        # A pipe or a device would block or never end: regular files only.
        status = location.stat()
        if not stat.S_ISREG(status.st_mode):
            raise ModelFileError(f"{display}: not a regular file", file=display)
        with location.open("rb") as stream:
            raw = stream.read(MAX_FILE_SIZE + 1)
        if len(raw) > MAX_FILE_SIZE:
            size = max(status.st_size, len(raw))
            raise ModelFileError(
                f"{display}: the model file has {size} bytes, more than the limit of "
                f"{MAX_FILE_SIZE} ({MAX_FILE_SIZE // 1024**2} MiB): put meshes, matrices and "
                "long tables in mesh or body files",
                file=display,
            )
        text = raw.decode("utf-8")
    except FileNotFoundError:
        raise ModelFileError(f"{display}: no such model file", file=display) from None
    except (OSError, UnicodeDecodeError) as error:
        raise ModelFileError(
            f"{display}: cannot read the model file ({error})", file=display
        ) from None
    return text.replace("\r\n", "\n").replace("\r", "\n")


def load_model(path: str | os.PathLike[str]) -> ModelFile:
    """Reads a model file (YAML) and builds its system.

    Relative file names in it (body files, meshes) are relative to the model file's folder.
    Values are converted from the file's ``units`` to SI. Raises one
    :class:`flexmbd.errors.ModelFileError` naming the file, the line and the key path for
    anything wrong: a missing or unreadable file, a YAML syntax error, a tag that is not
    plain data, an unknown key, a value of the wrong type or out of range, an unknown or
    duplicate name, or an error of the Python API while building an item."""
    location = Path(path)
    display = str(path)
    source = _Source(location, display)
    text = _read_text(location, display)
    data = source.read(text)
    if not isinstance(data, dict):
        raise ModelFileError(
            f"{display}: line 1: a model file is a mapping of keys (bodies, joints, ...), "
            f"got a {type(data).__name__}",
            file=display,
            line=1,
        )
    try:
        spec = ModelSpec.model_validate(data)
    except ValidationError as error:
        raise _validation_error(source, error) from None
    builder = _Builder(spec, source)
    simulation = spec.simulation
    seconds = builder.units.time
    if not simulation.end_time > simulation.start_time:
        raise builder.fail(
            ("simulation", "end_time"),
            f"end_time must be after start_time ({simulation.start_time:g}), "
            f"got {simulation.end_time:g}",
        )
    problem = None if spec.name is None else _name_problem(spec.name)
    if problem is not None:
        raise builder.fail(("name",), problem)
    builder.add_bodies()
    for k, marker in enumerate(spec.markers):
        builder.add_marker(marker, ("markers", k))
    builder.add_joints()
    builder.add_forces()
    builder.add_sensors()
    solver = builder.solver()
    builder.check_step_bounds()
    outputs = builder.outputs()
    bodies = {name: body for name, body in builder.bodies.items() if name != GROUND}
    return ModelFile(
        path=location,
        name=spec.name or location.stem,
        description=spec.description or "",
        units=builder.units.names,
        system=builder.system,
        solver=solver,
        end_time=simulation.end_time * seconds,
        step_size=simulation.step_size * seconds,
        output_interval=None
        if simulation.output_interval is None
        else simulation.output_interval * seconds,
        start_time=simulation.start_time * seconds,
        start=simulation.start,
        outputs=outputs,
        bodies=bodies,
        markers=builder.markers,
        joints=builder.joints,
        forces=builder.forces,
        sensors=builder.sensors,
        body_data=builder.flexible,
        spec=spec,
    )


def simulate_model(
    model: ModelFile | str | os.PathLike[str],
    *,
    end_time: float | None = None,
    step_size: float | None = None,
    output_interval: float | None = None,
    start_time: float | None = None,
    solver: _boundary.GeneralizedAlpha | _boundary.ExplicitSolver | None = None,
    progress: Callable[[float, float, int], object] | None = None,
) -> Result:
    """Simulates a model file (a :class:`ModelFile` or a path, loaded first) with
    :func:`flexmbd.simulate`. Keyword arguments given replace the file's settings; they are
    in SI (s), whatever the file's units. Raises what :func:`flexmbd.simulate` raises."""
    if not isinstance(model, ModelFile):
        model = load_model(model)
    return simulate(
        model.system,
        model.end_time if end_time is None else end_time,
        model.step_size if step_size is None else step_size,
        start_time=model.start_time if start_time is None else start_time,
        initial_state=model.start,
        output_interval=model.output_interval if output_interval is None else output_interval,
        solver=model.solver if solver is None else solver,
        progress=progress,
    )


__all__ = [
    "MAX_DEPTH",
    "MAX_FILE_SIZE",
    "MAX_ITEMS",
    "MAX_VALUES",
    "MODEL_FILE_VERSION",
    "UNITS",
    "ModelFile",
    "ModelSpec",
    "Output",
    "load_model",
    "model_schema",
    "simulate_model",
]
