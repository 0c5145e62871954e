"""Building the system of a model file: units, names, bodies, markers, joints, forces,
sensors, the solver and the outputs, each error naming the file, line and key path."""

from __future__ import annotations

import re
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .. import _boundary, _core
from .._checks import id_text, value_text
from ..errors import FlexmbdError, ModelFileError
from ..result import Result
from ..rotation import rotation
from ..system import System
from .reading import Path_, _key_path, _listing, _short, _Source
from .schema import (
    BODY_QUANTITIES,
    GROUND,
    JOINT_QUANTITIES,
    SYSTEM_QUANTITIES,
    UNITS,
    AngleDriverSpec,
    AxisRotation,
    CircleSection,
    ConstantFunction,
    DistanceJointSpec,
    FlexibleBodySpec,
    GeneralizedAlphaSpec,
    HarmonicFunction,
    JointActuatorSpec,
    JointSpec,
    MarkerSpec,
    ModelSpec,
    OutputSpec,
    PointForceSpec,
    PointMassSpec,
    PolynomialFunction,
    RectangleSection,
    RigidBodySpec,
    SplineFunction,
    SpringDamperSpec,
    StepFunction,
    TorqueSpec,
    TrapezoidalFunction,
    TubeSection,
    UnitsSpec,
)

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


@dataclass(frozen=True)
class ParaViewOutput:
    """The ParaView series ``flexmbd run`` writes (the model file's ``paraview``): whether,
    every how many records, and the time window (start, end) in s (None: all records); the
    arguments of :func:`flexmbd.animation.write_vtu_series`."""

    write: bool = True
    every: int = 1
    times: tuple[float, float] | None = None


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
        paraview: the ParaView series of ``flexmbd run`` (:class:`ParaViewOutput`).
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
    paraview: ParaViewOutput = field(default_factory=ParaViewOutput)
    spec: ModelSpec | None = None

    @property
    def file_stem(self) -> str:
        """The model file's stem as the stem of file names (``flexmbd run`` names its
        results, plots and animations after it, so that two model files of one name, or a
        model file and the built-in example it is named after, do not write the same files):
        characters that are not allowed in file names on some system (path separators,
        control and other invisible characters, ``<>:"|?*``) become ``_``, leading and
        trailing dots and spaces are dropped, at most 120 bytes of UTF-8 are kept, Windows'
        reserved names (``CON``, ``NUL``, ...) get a ``_``, and a stem that is then empty
        gives the model's name made a stem the same way (or ``model``). Never a path: no
        folder, no ``..``, not hidden."""
        for name in (self.path.stem, self.name):
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
        of the outputs. Outputs without a plot of their own are left out (among them a
        deflection from a chord: the plot of a node's deflection is from the body frame, and
        took the chord's place)."""
        names: list[str] = []
        for output in self.outputs:
            if output.kind == "sensor":
                name = f"sensor:{output.item}"
            elif output.kind == "system":
                name = "violation" if output.quantity == "constraint_violation" else "energy"
            elif output.kind == "joint":
                name = f"reaction:{output.item}"
            elif output.quantity == "deflection" and output.chord is None:
                name = f"deflection:{output.item}:{output.node}"
            elif output.quantity == "deflection":
                continue
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
        return f"{what}: no path separators ('/', '\\'), got {value_text(name)}"
    hidden = next((c for c in name if not c.isprintable()), None)
    if hidden is not None:
        character = f"U+{ord(hidden):04X}"
        return f"{what}: no control or invisible characters ({character}), got {value_text(name)}"
    if name.startswith("."):
        return f"{what}: it may not start with a dot, got {value_text(name)}"
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
    "shell_thickness",
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
    "orient_shells",
    "point_masses",
)
_SOURCES = ("body_file", "beam", "mesh", "nastran", "box", "plate", "cylinder")

#: Preprocessing keys of the model file -> their names in the Python API (the others alike).
_PYTHON_NAMES = {
    "section_orientation": "orientation",
    "mass_matrix": "mass",
    "shell_thickness": "shell",
}


def _item_keys(spec: FlexibleBodySpec) -> dict[str, str | tuple[str | int, ...]]:
    """Parameter of the Python API -> the body's key that gave it (the keys given only), and
    a point mass's item (``point_masses[node]``) -> its entry of the body's list."""
    keys: dict[str, str | tuple[str | int, ...]] = {
        _PYTHON_NAMES.get(key, key): key
        for key in _PREPROCESS_KEYS
        if getattr(spec, key) is not None
    }
    for k, mass in enumerate(spec.point_masses or ()):
        keys[f"point_masses[{mass.node}]"] = ("point_masses", k)
    return keys


#: Keys a Nastran deck gives itself.
_DECK_KEYS = ("material", "section", "section_orientation", "shell_thickness")


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
        #: The sensors "NAME effort" of the named joint actuators.
        self.effort_sensors: list[str] = []
        self.first: dict[tuple[str, str], Path_] = {}
        # Entry of `functions` -> the function it stands for (not a name) and its key path.
        self.targets: dict[str, tuple[Any, Path_]] = {}
        self.check_functions()

    def fail(self, path: Path_, message: str) -> ModelFileError:
        return self.source.error(path, message)

    def warn(self, path: Path_, message: Warning | str, category: type[Warning]) -> None:
        """Warns at the model file's line of `path` (Python shows that line of the file)."""
        line = self.source.line(path)
        key = _key_path(path)
        text = f"{key}: {message}" if key else str(message)
        try:
            located: Warning | str = category(text)
        except TypeError:  # a warning class that takes other arguments: as it was
            located = message
        warnings.warn_explicit(located, category, str(self.source.path), line or 0)

    def call(
        self,
        path: Path_,
        function: Callable[..., Any],
        *args: Any,
        item_keys: Mapping[str, str | tuple[str | int, ...]] | None = None,
        **kwargs: Any,
    ) -> Any:
        """Calls the Python API; its errors become model file errors at `path` (at its key
        `item_keys[item]` for an error naming a parameter `item` of the function), and its
        warnings are warned again at the file and line of `path`."""
        try:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                value = function(*args, **kwargs)
            for warning in caught:
                self.warn(path, warning.message, warning.category)
            return value
        except FileNotFoundError as error:
            raise self.fail(path, f"no such file: {error.filename}") from error
        except (FlexmbdError, ValueError) as error:
            key = (item_keys or {}).get(getattr(error, "item", None) or "")
            at = path if key is None else path + (key if isinstance(key, tuple) else (key,))
            raise self.fail(at, str(error)) from error
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
                path, f"duplicate {kind} name {value_text(name)} (first at line {line})"
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
                        where, f"unknown function {value_text(spec)} (functions: {known})"
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
                raise self.fail(path, f"unknown function {value_text(spec)} (functions: {known})")
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
            slopes = (
                None if spec.slopes is None else tuple(v * scale / seconds for v in spec.slopes)
            )
            return self.call(
                path,
                _boundary.Spline,
                times,
                [v * scale for v in spec.values],
                spec.end,
                slopes,
            )
        if isinstance(spec, StepFunction | TrapezoidalFunction):
            last = spec.shape if isinstance(spec, StepFunction) else spec.blend
            return self.call(
                path,
                _boundary.Step if isinstance(spec, StepFunction) else _boundary.Trapezoidal,
                spec.start_time * seconds,
                spec.end_time * seconds,
                spec.start_value * scale,
                spec.end_value * scale,
                last,
            )
        return float(spec) * scale

    def material(self, spec: Any, path: Path_) -> Any:
        from ..fe import Material

        name = None
        if isinstance(spec, str):
            if spec not in self.spec.materials:
                known = _listing(self.spec.materials)
                raise self.fail(path, f"unknown material {value_text(spec)} (materials: {known})")
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
        from ..fe import Section

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
                path, f"no such file: {value_text(name)} (looked for {location.absolute()})"
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
        from ..fe import (
            body_from_mesh,
            build_body,
            load_body,
            read_mesh,
            read_sid,
            shapes,
            straight_beam,
        )

        if spec.op2 is not None and kind != "nastran":
            raise self.fail(path + ("op2",), "op2 results go with a Nastran deck (`nastran`)")
        if spec.nastran_skip is not None and kind != "nastran":
            raise self.fail(
                path + ("nastran_skip",), "nastran_skip goes with a Nastran deck (`nastran`)"
            )
        if spec.mesh_unit is not None and kind != "mesh":
            raise self.fail(path + ("mesh_unit",), "mesh_unit goes with a mesh file (`mesh`)")
        if spec.incompatible_modes is not None and kind != "mesh":
            hint = " (a box takes element: hex8i)" if kind == "box" else ""
            raise self.fail(
                path + ("incompatible_modes",),
                f"incompatible_modes goes with a mesh file (`mesh`){hint}",
            )
        if kind == "body_file":
            for key in _PREPROCESS_KEYS:
                if getattr(spec, key) is not None:
                    raise self.fail(
                        path + (key,),
                        "not used with body_file: the body file holds a preprocessed body",
                    )
            location = self.file(str(spec.body_file), path + ("body_file",))
            reader = read_sid if Path(location).suffix.lower() == ".sid" else load_body
            data = self.call(path + ("body_file",), reader, location)
            si = {"length": "m", "mass": "kg", "time": "s"}
            units = {k: data.units.get(k) for k in si}
            if units != si:
                raise self.fail(path + ("body_file",), f"the body file is in {units}, not SI")
            return data
        if kind == "nastran":
            return self.nastran_body(spec, path)
        if spec.material is None:
            raise self.fail(path + ("material",), f"missing key 'material' (needed with {kind})")
        options = self.preprocess_options(spec, path)
        keys = _item_keys(spec)
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
            material = options.pop("material")
            return self.call(path, build_body, nodes, elements, material, item_keys=keys, **options)
        if kind == "mesh":
            location = self.file(str(spec.mesh), where)
            if spec.mesh_unit is not None:
                length = UNITS["length"][spec.mesh_unit]
            if length == 1.0 and not spec.incompatible_modes:
                mesh: Any = location
            else:
                mesh = self.call(where, read_mesh, location)
                mesh.nodes = mesh.nodes * length
            if spec.incompatible_modes:
                mesh = self.call(path + ("incompatible_modes",), mesh.with_incompatible_modes)
            material = options.pop("material")
            data = self.call(path, body_from_mesh, mesh, material, item_keys=keys, **options)
            return data.with_metadata(source=str(location))
        if kind in ("plate", "box"):  # structured meshes: lengths, divisions, element, origin
            grid = getattr(spec, kind)
            assert grid is not None
            extra = {} if grid.origin is None else {"origin": _scaled(grid.origin, length)}
            mesh = self.call(
                where,
                getattr(shapes, kind),
                _scaled(grid.lengths, length),
                grid.divisions,
                grid.element,
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
        material = options.pop("material")
        return self.call(path, body_from_mesh, mesh, material, item_keys=keys, **options)

    def nastran_body(self, spec: FlexibleBodySpec, path: Path_) -> Any:
        """A body from a Nastran deck: preprocessed, or with the modes of its OP2 results."""
        from ..fe import body_from_nastran, read_nastran

        for key in _DECK_KEYS:
            if getattr(spec, key) is not None:
                raise self.fail(path + (key,), "not used with nastran: the deck defines it")
        where = path + ("nastran",)
        deck = self.call(
            where, read_nastran, self.file(str(spec.nastran), where), skip=spec.nastran_skip or ()
        )
        options: dict[str, Any] = {}
        for key in _PREPROCESS_KEYS[4:]:
            value = getattr(spec, key)
            if value is not None:
                options[_PYTHON_NAMES.get(key, key)] = value
        if spec.point_masses is not None:
            options["point_masses"] = self.point_masses(spec.point_masses, path + ("point_masses",))
        if spec.op2 is None:
            if spec.modes is None and spec.mode_count:
                raise self.fail(path + ("mode_count",), "mode_count needs `modes`")
            data = self.call(path, deck.body, item_keys=_item_keys(spec), **options)
            return data.with_metadata(source=str(spec.nastran))
        for key in ("modes", "interfaces", "interface_kind", "interface_weights"):
            if key in options:
                raise self.fail(path + (key,), "not used with op2: the modes are the file's")
        results = self.file(str(spec.op2), path + ("op2",))
        count = options.pop("mode_count", None)
        return self.call(
            path + ("op2",),
            body_from_nastran,
            deck,
            results,
            count,
            item_keys=_item_keys(spec),
            **options,
        )

    def point_masses(self, specs: list[Any], path: Path_) -> dict[int, Any]:
        """build_body's `point_masses` of the model file's list, in SI."""
        inertia_scale = self.units.scale(length=2, mass=1)
        masses: dict[int, Any] = {}
        for k, spec in enumerate(specs):
            if spec.node in masses:
                raise self.fail(path + (k, "node"), f"node {spec.node} has a point mass already")
            mass = spec.mass * self.units.mass
            inertia = None
            if spec.inertia is not None:
                inertia = np.asarray(spec.inertia, dtype=float) * inertia_scale
                inertia = np.diag(inertia) if inertia.ndim == 1 else inertia
            if spec.offset is not None:
                offset = np.asarray(spec.offset, dtype=float) * self.units.length
                masses[spec.node] = (mass, inertia, offset)
            else:
                masses[spec.node] = mass if inertia is None else (mass, inertia)
        return masses

    def preprocess_options(self, spec: FlexibleBodySpec, path: Path_) -> dict[str, Any]:
        """Keyword arguments of build_body / body_from_mesh (those given only)."""
        options: dict[str, Any] = {"material": self.material(spec.material, path + ("material",))}
        if spec.section is not None:
            options["section"] = self.section(spec.section, path + ("section",))
        for key in _PREPROCESS_KEYS[2:]:
            value = getattr(spec, key)
            if value is not None:
                options[_PYTHON_NAMES.get(key, key)] = value
        if "shell" in options:
            options["shell"] = options["shell"] * self.units.length
        if spec.point_masses is not None:
            options["point_masses"] = self.point_masses(spec.point_masses, path + ("point_masses",))
        if spec.modes is None and spec.mode_count:
            raise self.fail(path + ("mode_count",), "mode_count needs `modes`")
        return options

    # Markers -------------------------------------------------------------------------------

    def body(self, name: str, path: Path_) -> _core.BodyId:
        if name not in self.bodies:
            known = _listing(self.bodies)
            raise self.fail(path, f"unknown body {value_text(name)} (bodies: {known})")
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
                f"body {value_text(spec.body)} is not a flexible body: it has no nodes",
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
            raise self.fail(path, f"unknown marker {value_text(spec)} (markers: {known})")
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
            elif isinstance(spec, JointActuatorSpec):
                force = self.add_actuator(spec, path)
                if spec.name is not None:
                    # (its effort, recorded as the sensor "NAME effort", is an output too)
                    self.effort_sensors.append(f"{spec.name} effort")
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

    def add_actuator(self, spec: JointActuatorSpec, path: Path_) -> Any:
        """A joint actuator, its values in the units of the coordinate it drives."""
        units = self.units
        if spec.joint not in self.joints:
            known = _listing(self.joints)
            raise self.fail(
                path + ("joint",), f"unknown joint {value_text(spec.joint)} (joints: {known})"
            )
        kind = next(j.type for j in self.spec.joints if getattr(j, "name", None) == spec.joint)
        coordinate = spec.coordinate or ("slide" if kind == "prismatic" else "angle")
        if coordinate == "angle":
            value, effort = units.angle, units.torque
        else:
            value, effort = units.length, units.force
        feed_forward = (
            None
            if spec.feed_forward is None
            else self.time_function(spec.feed_forward, effort, path + ("feed_forward",))
        )
        return self.call(
            path,
            self.system.add_joint_actuator,
            self.joints[spec.joint],
            self.time_function(spec.set_point, value, path + ("set_point",)),
            proportional_gain=spec.proportional_gain * effort / value,
            derivative_gain=spec.derivative_gain * effort * units.time / value,
            feed_forward=feed_forward,
            limit=None if spec.limit is None else spec.limit * effort,
            coordinate=spec.coordinate,
            name=spec.name,
        )

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
                        f"unknown joint {value_text(name)} (joints: {known})",
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
        # The steps land on the output times: an interval below the smallest step (or below
        # the time resolution of the run) cannot be met.
        interval = self.spec.simulation.output_interval
        floor = max(
            smallest if smallest is not None else 1e-6 * step,
            2e-12 * (1.0 + abs(self.spec.simulation.end_time)),
        )
        if interval is not None and 0 < interval < floor:
            raise self.fail(
                ("simulation", "output_interval"),
                f"the output interval {interval:g} is below the smallest step size {floor:g} "
                "(the steps land on the output times)",
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
                    f"duplicate output label {value_text(output.label)} (first at line {line}): "
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
                f"(got {value_text(quantity)})",
            )
        item = getattr(spec, kind) if kind != "system" else None
        sensors = {**self.sensors, **dict.fromkeys(self.effort_sensors)}
        known = {"sensor": sensors, "body": self.bodies, "joint": self.joints}.get(kind)
        if known is not None and item not in known:
            raise self.fail(
                path + (kind,),
                f"unknown {kind} {value_text(item)} ({PLURALS[kind]}: {_listing(known)})",
            )
        node_quantities = ("node_displacements", "node_positions", "deflection", "stresses")
        if kind == "body" and (
            quantity in node_quantities + ("section_forces", "elastic_coordinates")
            or quantity == "elastic_velocities"
        ):
            if item not in self.flexible:
                raise self.fail(path + ("body",), f"{value_text(item)} is not a flexible body")
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
                    f"body {value_text(spec.body)} has no node with id {id_text(node)} (its "
                    f"{len(ids)} nodes have ids {min(ids, default=0)} to {max(ids, default=0)})",
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
                f"body {value_text(spec.body)} has no solid elements: stresses are those of "
                "solid elements (beams have section_forces)",
            )
        if spec.quantity == "section_forces" and ("beam2" not in elements or data.section is None):
            raise self.fail(
                path + ("quantity",),
                f"body {value_text(spec.body)} has no beam elements with a section: "
                "section_forces are those of beams",
            )
        if spec.quantity in ("stresses", "section_forces") and not data.material:
            raise self.fail(
                path + ("quantity",),
                f"body {value_text(spec.body)} has no material (built from matrices): "
                f"no {spec.quantity}",
            )


#: Keys of outputs that name nodes -> the body quantities that use them.
_NODE_KEYS = {
    "nodes": ("node_displacements", "node_positions"),
    "node": ("deflection",),
    "chord": ("deflection",),
}


#: The plural of each kind of item an output names, for messages.
PLURALS = {"sensor": "sensors", "body": "bodies", "joint": "joints"}
