"""The schema of model files: pydantic models of every section (the reference of every key
is ``docs/model-files.md``; :func:`model_schema` gives the JSON schema)."""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal

from pydantic import BaseModel, BeforeValidator, ConfigDict, Discriminator, Field, Tag
from pydantic_core import PydanticCustomError

from .. import _core

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


def _exactly(count: int) -> BeforeValidator:
    """A list's length checked first, said as "exactly" (pydantic says "at least 3 items" of
    a list of 3 given 2)."""

    def check(value: Any) -> Any:
        if isinstance(value, list) and len(value) != count:
            raise PydanticCustomError(
                "fixed_length",
                "expected exactly {count} items, got {actual}",
                {"count": count, "actual": len(value)},
            )
        return value

    return BeforeValidator(check)


def _fixed(item: Any, count: int) -> Any:
    """A list of exactly `count` items."""
    return Annotated[list[item], Field(min_length=count, max_length=count), _exactly(count)]


Vector = _fixed(float, 3)
Matrix = _fixed(Vector, 3)
Pair = _fixed(float, 2)
IntPair = _fixed(int, 2)
IntTriple = _fixed(int, 3)
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
    """Cubic spline through (times, values) with end conditions; outside its knots it goes on
    with its end value and slope, or repeats if periodic (:class:`flexmbd.Spline`)."""

    type: Literal["spline"]
    times: list[float] = Field(min_length=2, description="strictly increasing knot times (time)")
    values: list[float] = Field(min_length=2, description="values at the knots")
    end: Literal["natural", "clamped", "periodic"] = Field(
        "natural",
        description="natural (zero curvature at the ends), clamped (the end slopes `slopes`) "
        "or periodic (first and last values equal)",
    )
    slopes: Pair | None = Field(
        None,
        description="first derivatives at the first and last knot of a clamped spline "
        "(unit of the quantity / time; default 0, 0: it comes to rest)",
    )


class StepFunction(_Spec):
    """A rest-to-rest step from `start_value` to `end_value` between `start_time` and
    `end_time` (:class:`flexmbd.Step`)."""

    type: Literal["step"]
    start_time: float = Field(description="when the motion starts (time)")
    end_time: float = Field(description="when it ends (time)")
    start_value: float = Field(description="the value before (unit of the quantity)")
    end_value: float = Field(description="the value after (unit of the quantity)")
    shape: Literal["cubic", "quintic", "cycloidal"] = Field(
        "quintic",
        description="cubic (zero end velocities), quintic or cycloidal (zero end velocities "
        "and accelerations)",
    )


class TrapezoidalFunction(_Spec):
    """A rest-to-rest motion with a trapezoidal velocity (:class:`flexmbd.Trapezoidal`)."""

    type: Literal["trapezoidal"]
    start_time: float = Field(description="when the motion starts (time)")
    end_time: float = Field(description="when it ends (time)")
    start_value: float = Field(description="the value before (unit of the quantity)")
    end_value: float = Field(description="the value after (unit of the quantity)")
    blend: float = Field(
        0.25, description="acceleration time over the duration, in (0, 0.5] (0.5: triangular)"
    )


TimeFunction = Annotated[
    Annotated[float, Tag("(number)")]
    | Annotated[Name, Tag("(name)")]
    | Annotated[ConstantFunction, Tag("constant")]
    | Annotated[PolynomialFunction, Tag("polynomial")]
    | Annotated[HarmonicFunction, Tag("harmonic")]
    | Annotated[SplineFunction, Tag("spline")]
    | Annotated[StepFunction, Tag("step")]
    | Annotated[TrapezoidalFunction, Tag("trapezoidal")],
    Discriminator(_shape_tag),
    Field(
        description="a number (constant), the name of an entry of `functions`, or a mapping "
        "with `type` constant, polynomial, harmonic, spline, step or trapezoidal"
    ),
]
TimeVector = _fixed(TimeFunction, 3)


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


class BodyPointMassSpec(_Spec):
    """A concentrated mass at a node of a deformable body (build_body's `point_masses`)."""

    node: int = Field(ge=0, description="node index (0-based), as in reference_nodes")
    mass: float = Field(ge=0, description="mass")
    inertia: Inertia | None = Field(
        None,
        description="rotary inertia about the centre of mass (the node, without an offset) in "
        "body axes (beam and shell nodes only): the three principal moments or a 3 x 3 matrix "
        "(mass length^2)",
    )
    offset: Vector | None = Field(
        None,
        description="the centre of mass from the node in body axes, moving with the node's "
        "rotations (beam and shell nodes only; length)",
    )


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
    divisions: IntTriple = Field(description="cells along x, y, z")
    element: Literal[
        "hex8",
        "hex8i",
        "hex20",
        "hex20r",
        "hex27",
        "wedge6",
        "wedge15",
        "wedge18",
        "pyramid5",
        "pyramid13",
        "pyramid14",
        "tet4",
        "tet10",
    ] = "hex8"
    origin: Vector | None = Field(None, description="corner of the box (length)")


class PlateSpec(_Spec):
    """A built-in structured mesh of flat shells on a rectangle in the x-y plane
    (:func:`flexmbd.fe.shapes.plate`); node sets x0, x1, y0, y1 (the edges) and all. Needs
    `shell_thickness`."""

    lengths: Pair = Field(description="edge lengths along x and y (length)")
    divisions: IntPair = Field(description="cells along x and y")
    element: Literal["quad4", "tri3"] = "quad4"
    origin: Vector | None = Field(None, description="corner of the plate (length)")


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
    from exactly one of `body_file`, `beam`, `mesh`, `nastran`, `box`, `plate` or `cylinder`.
    All but `body_file` run the preprocessor (:func:`flexmbd.fe.build_body`) with `material`
    (a Nastran deck has its own) and the options below; a Nastran deck with `op2` takes its
    modes from the OP2 results (:func:`flexmbd.fe.body_from_nastran`)."""

    type: Literal["flexible"]
    name: Name
    # Where the body comes from.
    body_file: str | None = Field(
        None,
        description="HDF5 body file written by the preprocessor, or a SID file (.sid) of a "
        "modal body (relative to the model file), SI units",
    )
    beam: BeamSpec | None = None
    mesh: str | None = Field(
        None,
        description="mesh file (Gmsh .msh, Abaqus .inp, VTK; relative to the model file), "
        "coordinates in `mesh_unit`",
    )
    mesh_unit: Literal["m", "cm", "mm"] | None = Field(
        None,
        description="with `mesh`: the length unit of the mesh file's coordinates (default: "
        "the model file's length unit)",
    )
    incompatible_modes: bool | None = Field(
        None,
        description="with `mesh`: its hexahedra as hex8i (incompatible modes: they bend on "
        "coarse meshes; Abaqus C3D8I is read so anyway)",
    )
    nastran: str | None = Field(
        None,
        description="Nastran bulk data deck (.bdf, .dat, .nas; relative to the model file): "
        "mesh, material, sections and node sets, its numbers taken as SI",
    )
    nastran_skip: list[str] | None = Field(
        None,
        description="with `nastran`: concentrated-mass cards to read the deck without "
        "(CMASS2, ...; the model adds these masses itself), `read_nastran`'s `skip`",
    )
    op2: str | None = Field(
        None,
        description="with `nastran`: the OP2 results of its normal modes analysis (SOL 103), "
        "the body's modes (`mode_count`: the first ones; rigid-body modes left out)",
    )
    box: BoxSpec | None = None
    plate: PlateSpec | None = None
    cylinder: CylinderSpec | None = None
    # Preprocessor options (build_body).
    material: MaterialRef | None = None
    section: SectionSpec | None = Field(None, description="beam section (beams only)")
    section_orientation: Vector | None = Field(
        None, description="the section's y axis, across the beam (build_body `orientation`)"
    )
    shell_thickness: float | None = Field(
        None, gt=0, description="thickness of the shell elements (length; build_body `shell`)"
    )
    orient_shells: bool | None = Field(
        None,
        description="turn the shells of each connected surface to one side (build_body "
        "`orient_shells`)",
    )
    mass_matrix: Literal["consistent", "lumped"] | None = Field(
        None, description="build_body `mass` (default consistent)"
    )
    point_masses: list[BodyPointMassSpec] | None = Field(
        None,
        description="concentrated masses at nodes, part of the body (build_body `point_masses`)",
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
    rayleigh_damping: Pair | None = Field(
        None, description="[alpha (1/time), beta (time)]: D = alpha M_ff + beta K_ff"
    )
    modal_damping: float | None = Field(None, ge=0, description="damping ratio of every mode")
    geometric_stiffness: bool | Literal["von-karman", "corotational"] = Field(
        False,
        description="stiffening of beams and shells (seed section 6): true or 'von-karman', "
        "or 'corotational' (nodal beam bodies: the geometrically exact elastic forces)",
    )
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


class JointActuatorSpec(_Spec):
    """A PD servo on the angle or the slide of a joint (:meth:`System.add_joint_actuator`):
    effort proportional_gain (f(t) - x) + derivative_gain (f'(t) - x_dot) + feed_forward(t),
    held within +/- limit. Angles: gains in torque/angle and torque time/angle, efforts in
    torque; slides: force/length, force time/length and force."""

    type: Literal["joint-actuator"]
    name: Name | None = None
    joint: Name = Field(description="a revolute, prismatic or cylindrical joint by its name")
    set_point: TimeFunction
    proportional_gain: float = Field(ge=0, description="torque/angle or force/length")
    derivative_gain: float = Field(0.0, ge=0, description="torque time/angle or force time/length")
    feed_forward: TimeFunction | None = None
    limit: float | None = Field(None, gt=0, description="largest |effort| (torque or force)")
    coordinate: Literal["angle", "slide"] | None = Field(
        None, description="for a cylindrical joint: the coordinate it drives"
    )


ForceSpec = Annotated[
    PointForceSpec | TorqueSpec | SpringDamperSpec | RotationalSpringDamperSpec | JointActuatorSpec,
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
SYSTEM_QUANTITIES = (
    "kinetic_energy",
    "potential_energy",
    "strain_energy",
    "total_energy",
    "constraint_violation",
)


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
    chord: IntPair | None = Field(None, description="two node ids: deflection from their chord")


# Solvers and the simulation --------------------------------------------------------------------

# The names of the solvers' choices, declared once in the core (`named!` beside each enum).
_IMPLICIT = _core.GeneralizedAlpha.choices()
_EXPLICIT = _core.ExplicitSolver.choices()
RedundantConstraints = Literal[tuple(_IMPLICIT["redundant_constraints"])]  # type: ignore[valid-type]
Jacobian = Literal[tuple(_IMPLICIT["jacobian"])]  # type: ignore[valid-type]
StepControl = Literal[tuple(_IMPLICIT["step_control"])]  # type: ignore[valid-type]
VelocityProjection = Literal[tuple(_IMPLICIT["velocity_projection"])]  # type: ignore[valid-type]
LinearSolver = Literal[tuple(_IMPLICIT["linear_solver"])]  # type: ignore[valid-type]
ExplicitMethod = Literal[tuple(_EXPLICIT["method"])]  # type: ignore[valid-type]
Strategy = Literal[tuple(_EXPLICIT["strategy"])]  # type: ignore[valid-type]
ExplicitFormulation = Literal[tuple(_EXPLICIT["formulation"])]  # type: ignore[valid-type]
Partition = Literal[tuple(_EXPLICIT["partition"])]  # type: ignore[valid-type]
IterationJacobian = Literal[tuple(_EXPLICIT["jacobian"])]  # type: ignore[valid-type]


class GeneralizedAlphaSpec(_Spec):
    """The implicit index-3 generalized-alpha integrator (:class:`flexmbd.GeneralizedAlpha`).
    Options left out take the solver's defaults."""

    type: Literal["generalized-alpha"]
    spectral_radius: float | None = Field(None, ge=0, le=1, description="rho_inf (-)")
    newton_tolerance: float | None = Field(None, gt=0)
    newton_error_fraction: float | None = Field(None, ge=0, lt=1)
    max_iterations: int | None = Field(None, ge=1)
    jacobian: Jacobian | None = None
    step_control: StepControl | None = None
    relative_tolerance: float | None = Field(None, gt=0)
    absolute_tolerance: float | None = Field(None, gt=0)
    min_step_size: float | None = Field(None, gt=0, description="time")
    max_step_size: float | None = Field(None, gt=0, description="time")
    velocity_projection: VelocityProjection | None = None
    linear_solver: LinearSolver | None = None
    initial_tolerance: float | None = Field(None, gt=0)
    correct_initial_positions: bool | None = None
    correct_initial_velocities: bool | None = None
    redundant_constraints: RedundantConstraints | None = None
    rank_tolerance: float | None = Field(None, gt=0, lt=1)


class ExplicitSolverSpec(_Spec):
    """Explicit Runge-Kutta 4 or Dormand-Prince 5(4) with one of the seed's strategies
    (:class:`flexmbd.ExplicitSolver`). Options left out take the solver's defaults."""

    type: Literal["explicit"]
    method: ExplicitMethod | None = None
    strategy: Strategy | None = None
    formulation: ExplicitFormulation | None = None
    partition: Partition | None = None
    independent: list[Annotated[int, Field(ge=0)]] | None = Field(
        None, description="indices of the independent coordinates"
    )
    baumgarte: Pair | None = Field(None, description="[alpha, beta] (1/time each)")
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
    jacobian: IterationJacobian | None = Field(None, description="tr-bdf2's iteration matrix")


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


class ParaViewSpec(_Spec):
    """The ParaView series (a ``.vtu`` file per record and a ``.pvd``) of the deformable
    bodies that ``flexmbd run`` writes next to the results (``--no-vtu``, ``--vtu-every``,
    ``--vtu-times`` replace these)."""

    write: bool = Field(True, description="write the series (false: none)")
    every: int = Field(1, ge=1, description="every N-th record (the last one always)")
    times: Pair | None = Field(
        None, description="[start, end]: only the records in this window (time; default: all)"
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
    paraview: ParaViewSpec = Field(
        default_factory=ParaViewSpec, description="the ParaView series of flexmbd run"
    )


def model_schema() -> dict[str, Any]:
    """The JSON schema (draft 2020-12) of model files, generated from the pydantic models."""
    schema = ModelSpec.model_json_schema()
    schema["$schema"] = "https://json-schema.org/draft/2020-12/schema"
    return schema
