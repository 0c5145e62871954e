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

import copy
import os
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from .. import _boundary
from ..errors import ModelFileError
from ..result import Result
from ..simulation import simulate
from .building import ModelFile, Output, ParaViewOutput, _Builder, _name_problem
from .reading import (
    MAX_DEPTH,
    MAX_FILE_SIZE,
    MAX_ITEMS,
    MAX_VALUES,
    _read_text,
    _Source,
    _validation_error,
)
from .schema import (
    GROUND,
    MODEL_FILE_VERSION,
    UNITS,
    ExplicitSolverSpec,
    FlexibleBodySpec,
    GeneralizedAlphaSpec,
    JointSpec,
    ModelSpec,
    SensorSpec,
    model_schema,
)


def load_model(
    path: str | os.PathLike[str], overrides: Mapping[str, Any] | None = None
) -> ModelFile:
    """Reads a model file (YAML) and builds its system.

    `overrides` replaces values of the file before it is checked: key path -> value, the key
    path in dots through mappings and lists, a list item by its ``name`` or its index
    (``bodies.rod.material.youngs_modulus``, ``simulation.end_time``, ``joints.0.name``).
    Values are in the file's units. A path that does not lead into the file is a
    :class:`flexmbd.errors.ModelFileError` naming it; a value the file may not hold is
    refused as it would be in the file.

    Relative file names in it (body files, meshes) are relative to the model file's folder.
    Values are converted from the file's ``units`` to SI. Raises one
    :class:`flexmbd.errors.ModelFileError` naming the file, the line and the key path for
    anything wrong: a missing or unreadable file, a YAML syntax error, a tag that is not
    plain data, an unknown key, a value of the wrong type or out of range, an unknown or
    duplicate name, or an error of the Python API while building an item."""
    source, spec = _checked(path, overrides)
    location = source.path
    builder = _Builder(spec, source)
    simulation = spec.simulation
    seconds = builder.units.time
    if not simulation.end_time > simulation.start_time:
        raise builder.fail(
            ("simulation", "end_time"),
            f"end_time must be after start_time ({simulation.start_time:g}), "
            f"got {simulation.end_time:g}",
        )
    paraview = spec.paraview
    if paraview.times is not None and not paraview.times[0] <= paraview.times[1]:
        raise builder.fail(
            ("paraview", "times"),
            f"times must be [start, end] with start <= end, got {paraview.times}",
        )
    if paraview.times is not None and (
        paraview.times[1] < simulation.start_time or paraview.times[0] > simulation.end_time
    ):
        raise builder.fail(
            ("paraview", "times"),
            f"times [{paraview.times[0]:g}, {paraview.times[1]:g}] hold no record of the run "
            f"(from {simulation.start_time:g} to {simulation.end_time:g})",
        )
    window = (
        None
        if paraview.times is None
        else (paraview.times[0] * seconds, paraview.times[1] * seconds)
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
        paraview=ParaViewOutput(paraview.write, paraview.every, window),
        spec=spec,
    )


def check_model(
    path: str | os.PathLike[str], overrides: Mapping[str, Any] | None = None
) -> ModelSpec:
    """Reads and checks a model file with `overrides` (as :func:`load_model`) without
    building its system: the checked description. Raises what :func:`load_model` raises for
    the file's text, its keys and values."""
    return _checked(path, overrides)[1]


def _checked(
    path: str | os.PathLike[str], overrides: Mapping[str, Any] | None
) -> tuple[_Source, ModelSpec]:
    """The source and the checked description of a model file with `overrides`."""
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
    for key_path, value in (overrides or {}).items():
        _override(data, key_path, value, source)
    try:
        spec = ModelSpec.model_validate(data)
    except ValidationError as error:
        raise _validation_error(source, error) from None
    return source, spec


def referenced_files(path: str | os.PathLike[str]) -> list[Path]:
    """The files a model file names (its bodies' `mesh`, `body_file`, `nastran` and `op2`),
    relative paths taken from its folder; read without building the model."""
    _, spec = _checked(path, None)
    folder = Path(path).parent
    files = []
    for body in spec.bodies:
        for key in ("body_file", "mesh", "nastran", "op2"):
            name = getattr(body, key, None)
            if name is not None:
                location = Path(str(name)).expanduser()
                files.append(location if location.is_absolute() else folder / location)
    return files


def _override(data: dict[str, Any], key_path: str, value: Any, source: _Source) -> None:
    """Sets `key_path` of the model file's `data` to `value`; ModelFileError naming the path
    where it does not lead into the file. The lists and mappings on the way are copied
    before they are entered: a YAML alias or merge key shares them between items (five
    bodies with `<<: *link`), and an override of one item's inertia set all five."""
    parts = key_path.split(".")
    node: Any = data
    walked: list[str | int] = []
    for k, part in enumerate(parts):
        last = k == len(parts) - 1
        if isinstance(node, list):
            names = [item.get("name") for item in node if isinstance(item, dict)]
            if part in names:
                index = names.index(part)
            elif part.isdigit() and int(part) < len(node):
                index = int(part)
            else:
                raise source.error(
                    tuple(walked),
                    f"key path {key_path!r}: no item {part!r} here; items: "
                    f"{[n for n in names if n is not None] or list(range(len(node)))}",
                )
            walked.append(index)
            if last:
                node[index] = value
            else:
                node[index] = copy.copy(node[index])
                node = node[index]
        elif isinstance(node, dict):
            walked.append(part)
            if last:
                node[part] = value
            elif part in node:
                node[part] = copy.copy(node[part])
                node = node[part]
            else:
                raise source.error(
                    tuple(walked),
                    f"key path {key_path!r}: the file has no {part!r} here; keys: {sorted(node)}",
                )
        else:
            raise source.error(
                tuple(walked), f"key path {key_path!r}: {parts[k - 1]!r} holds a value, not keys"
            )


def simulate_model(
    model: ModelFile | str | os.PathLike[str],
    *,
    end_time: float | None = None,
    step_size: float | None = None,
    output_interval: float | None = None,
    start_time: float | None = None,
    solver: _boundary.GeneralizedAlpha | _boundary.ExplicitSolver | None = None,
    progress: bool | Callable[[float, float, int], object] | None = None,
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
    "ExplicitSolverSpec",
    "FlexibleBodySpec",
    "GeneralizedAlphaSpec",
    "JointSpec",
    "SensorSpec",
    "MAX_DEPTH",
    "MAX_FILE_SIZE",
    "MAX_ITEMS",
    "MAX_VALUES",
    "MODEL_FILE_VERSION",
    "UNITS",
    "ModelFile",
    "ParaViewOutput",
    "ModelSpec",
    "Output",
    "check_model",
    "load_model",
    "model_schema",
    "simulate_model",
]
