"""The fuzz corpus of flexmbd (issue 28): malformed and hostile inputs, generated from a seed.

``cases(seed)`` gives the same list of :class:`Case` for the same seed (Python's
``random.Random``; byte positions and members chosen at run time come from the case's own
seed). Each case writes its inputs into an empty folder (``prepare``) and then reads, builds
or runs them (``operate``). Families:

* ``model-files``: mutations of ``examples/models/*.yaml`` (and of two models that read an
  Abaqus mesh and a body file): keys deleted, duplicated, renamed or retyped; huge,
  negative, zero, NaN and infinite numbers; empty, unknown and very long strings; wrong
  units; deep nesting; byte flips; truncation; control characters; Python and other tags;
  aliases; YAML 1.1 scalars; random solver and simulation settings. Loaded with
  ``load_model`` and, when they load, simulated for three steps.
* ``meshes``: small valid Abaqus, Gmsh and VTK meshes, mutated (labels, connectivity,
  ``*NSET, GENERATE``, ``*INCLUDE``, counts, tokens, byte flips, truncation, garbage), read
  with ``read_mesh`` and, when they read, built into a body and compiled.
* ``body-files``: saved bodies (nodal, beam, modal), damaged (truncated, bytes flipped,
  members deleted, retyped, reshaped, filled with NaN, attributes changed, links, huge
  declared sizes), loaded with ``load_body`` and, when they load, compiled and run.
* ``results-files``: results files of a rigid and a deformable model, damaged likewise
  (also record counts, JSON texts, time values), read with ``read_results`` and
  ``read_results_metadata`` (each read within 5 s); and runs that write to hostile paths.
* ``api``: one argument of a valid call replaced by a hostile value (negative, zero, NaN,
  huge, wrong type, None, wrong shape) in ``System.add_*``, ``GeneralizedAlpha``,
  ``ExplicitSolver``, ``simulate``, time functions, ``Result`` and ``State`` accessors,
  ids, materials and box meshes; what is accepted is run for three steps. Then fixed cases
  (no draws) of node index lists, str options, box divisions and elastic arrays that must
  be refused (:data:`_FIXED_OTHER_VALUES`, :data:`_FIXED_ELASTIC_VALUES`).

What each case may do is checked by ``worker.py``: a typed error (``FlexmbdError``, or a
``ValueError`` subclass of flexmbd) whose message names the item, or a right result
(``operate`` raises :class:`WrongResult` when a result is not right); never a panic, crash,
hang, other exception or a changed or deleted input file. Known failures (bugs outside the
files this suite may fix) are listed in :data:`KNOWN_FAILURES`.

Run by hand (from the repository root)::

    python -m tests.fuzz.worker --family model-files        # one family, in-process
    python -m tests.fuzz.worker --case NAME --keep /tmp/x    # one case, inputs kept
    python -m tests.fuzz.worker --list                      # the case names
"""

from __future__ import annotations

import atexit
import copy
import functools
import json
import math
import os
import random
import re
import shutil
import tempfile
import warnings
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

#: The seed CI uses (the issue number). ``FLEXMBD_FUZZ_SEED`` overrides it.
SEED = 28

#: Families of the corpus, in the order of the report.
FAMILIES = ("model-files", "meshes", "body-files", "results-files", "api")

REPOSITORY = Path(__file__).resolve().parents[2]
EXAMPLES = REPOSITORY / "examples" / "models"

#: A file a hostile tag would create if the YAML loader executed it.
CODE_MARKER = "PWNED"


class WrongResult(AssertionError):
    """An operation succeeded with a result that is not right (non-finite values, a record
    count that does not fit, an input that should have been refused, a read that blocked)."""


@dataclass(frozen=True)
class Case:
    """One input and what is done with it.

    Attributes:
        name: unique, ``family/base/kind/number``.
        family: one of :data:`FAMILIES`.
        kind: the mutation (for reports and :data:`KNOWN_FAILURES`).
        prepare: writes the inputs into an empty folder (the worker's working folder).
        operate: reads, builds or runs them in that folder; raises :class:`WrongResult` when
            a result is not right.
        names: an error message must name one of these (case-insensitive): the file, key,
            parameter, node, ...
        must_fail: the input is wrong: succeeding is a wrong result.
        allowed: other exception types that are right here (FileNotFoundError of a missing
            file, which the API documents).
        timeout: a shorter time limit than the worker's, s (a FIFO or /dev/zero that
            blocks a reader blocks it for ever: no need to wait the full limit).
    """

    name: str
    family: str
    kind: str
    prepare: Callable[[Path], None]
    operate: Callable[[Path], None]
    names: tuple[str, ...]
    must_fail: bool = False
    allowed: tuple[type[BaseException], ...] = ()
    timeout: float | None = None


#: Time limit of the cases that read a FIFO or /dev/zero, s.
SPECIAL_FILE_TIMEOUT = 5.0
_SPECIAL_FILES = ("fifo", "dev-zero")


@dataclass(frozen=True)
class Known:
    """A known failure: an outcome of a case that matches is expected to fail (xfail)
    until the named code is fixed. Matches on the family, the kind (a regular expression on
    ``family/base/kind``), the outcome classes and the message (a regular expression)."""

    reason: str
    family: str
    kind: str = ".*"
    outcomes: tuple[str, ...] = ("internal",)
    message: str = ".*"

    def matches(self, case: Case, outcome: str, message: str) -> bool:
        base_kind = "/".join(case.name.split("/")[:3])
        return (
            case.family == self.family
            and outcome in self.outcomes
            and re.search(self.kind, base_kind) is not None
            and re.search(self.message, message, re.DOTALL) is not None
        )


#: Failures in code this suite may not change (the Rust core and binding, ``fe/*`` and
#: ``system.py``): the test marks them xfail with the reason. Each names where to fix it.
KNOWN_FAILURES: list[Known] = []


def known_failure(case: Case, outcome: str, message: str) -> Known | None:
    """The entry of :data:`KNOWN_FAILURES` that explains this outcome, or None."""
    for entry in KNOWN_FAILURES:
        if entry.matches(case, outcome, message):
            return entry
    return None


# ---------------------------------------------------------------------------------------------
# Checks of results


def _finite(name: str, values: Any) -> None:
    array = np.asarray(values, dtype=float)
    if array.size and not np.all(np.isfinite(array)):
        raise WrongResult(f"{name} holds non-finite values")


def check_result(result: Any, end_time: float | None = None) -> None:
    """A run that is right: complete, at least one record, finite records, and (when given)
    ending at ``end_time``."""
    if not result.success:
        raise WrongResult(f"simulate returned an unsuccessful result: {result.error!r}")
    if len(result.time) == 0:
        raise WrongResult("the run has no records")
    for name in ("time", "coordinates", "velocities", "accelerations", "multipliers"):
        _finite(name, getattr(result, name))
    _finite("constraint_violation", result.constraint_violation)
    if np.any(np.diff(result.time) < 0):
        raise WrongResult("the record times decrease")
    if end_time is not None and not math.isclose(
        result.time[-1], end_time, rel_tol=1e-9, abs_tol=1e-12
    ):
        raise WrongResult(f"the run ended at t = {result.time[-1]!r}, not at {end_time!r}")


def _run_steps(system_or_model: Any, step: float = 1e-3, steps: int = 3, **options: Any) -> Any:
    import flexmbd as fm

    end = options.pop("start_time", 0.0) + steps * step
    result = fm.simulate(system_or_model, end, step, **options)
    check_result(result, end)
    return result


# ---------------------------------------------------------------------------------------------
# Small helpers of mutation


def _seed(rng: random.Random) -> int:
    return rng.getrandbits(32)


def _flip(data: bytes, rng: random.Random, count: int, window: int | None = None) -> bytes:
    """`count` bytes xor-ed with random non-zero values, in the first `window` bytes."""
    out = bytearray(data)
    if not out:
        return bytes(out)
    limit = len(out) if window is None else min(window, len(out))
    for _ in range(count):
        position = rng.randrange(limit)
        out[position] ^= rng.randrange(1, 256)
    return bytes(out)


def _write(path: Path, data: bytes | str) -> None:
    if isinstance(data, str):
        data = data.encode("utf-8", "surrogatepass")
    path.write_bytes(data)


#: Numbers that break models: zero, negative, huge, tiny, denormal, beyond int64, NaN, inf.
NUMBERS: list[Any] = [
    0,
    -0.0,
    -1,
    -1.0e300,
    1.0e300,
    1.7976931348623157e308,
    5e-324,
    1e-300,
    10**30,
    2**63,
    -(2**63) - 1,
    2**64,
    math.nan,
    math.inf,
    -math.inf,
    1e20,
    -1e-20,
]

#: Values of another type.
OTHER_TYPES: list[Any] = [
    "abc",
    "",
    None,
    True,
    False,
    [],
    {},
    [1, 2],
    {"a": 1},
    [[1.0, 2.0, 3.0]],
    "1.0",
    3,
    -7,
    0.5,
    [None, None, None],
]

#: Strings that break names and paths.
STRINGS: list[str] = [
    "",
    " ",
    "x" * 100_000,
    "nonexistent",
    "ground",
    "../../escape",
    "/absolute/path",
    "名前",
    "\u202e\u0645\u0631\u062d\u0628\u0627",
    "a\x00b",
    "NaN",
    "1e400",
    "~",
    "null",
    "true",
    "CON",
    "\t",
    "a" * 300,
    "mesh.inp",
    "/dev/zero",
]

#: YAML scalars read differently by YAML 1.1 and 1.2, or not numbers at all.
YAML_SCALARS = [
    "1:30",
    "0x1F",
    "0o17",
    "0b101",
    "1_000",
    "+.inf",
    ".NaN",
    "-.inf",
    "1e",
    "1e3",
    "1.",
    ".5",
    "0777",
    "12e1000",
    "-0",
    "yes",
    "on",
    "~",
    "!!int 1e3",
    "!!float 1:30",
    "!!bool abc",
    "!!int ''",
    "!!float abc",
    "!!str 1.0",
    "!!null x",
    "1e-400",
    "0x",
    "- 1",
]

#: Tags: Python objects (must never be executed), other YAML types, unknown tags.
TAGS = [
    f'!!python/object/apply:os.system ["touch {CODE_MARKER}"]',
    f'!!python/object/apply:subprocess.call [["touch", "{CODE_MARKER}"]]',
    "!!python/object/new:builtins.dict {}",
    "!!python/name:builtins.print",
    "!!python/module:os",
    "!!python/tuple [1, 2, 3]",
    "!!binary aGVsbG8=",
    "!!set {a, b}",
    "!!omap [{a: 1}, {b: 2}]",
    "!!pairs [{a: 1}]",
    "!!timestamp 2001-12-14",
    "!!merge x",
    "!custom value",
    f'!<tag:yaml.org,2002:python/object/apply:os.system> ["touch {CODE_MARKER}"]',
    "!!map [1, 2]",
    "!!seq {a: 1}",
    "!!str [1, 2]",
]

#: Characters YAML does not allow, or that confuse readers.
CONTROL = [
    b"\x00",
    b"\x01",
    b"\x07",
    b"\x08",
    b"\x0b",
    b"\x0c",
    b"\x1b",
    b"\x7f",
    "\u0085".encode(),
    "\u2028".encode(),
    "\ufeff".encode(),
    b"\xed\xa0\x80",
    b"\xff\xfe",
    b"\x80",
    b"\r",
    b"\t",
]
_MUST_REFUSE_CONTROL = {b"\x00", b"\x01", b"\x07", b"\x08", b"\x0b", b"\x0c", b"\x1b", b"\x7f"}


def _paths(data: Any, prefix: tuple = ()) -> Iterator[tuple]:
    """Every key path of a YAML tree (the root excluded)."""
    if isinstance(data, dict):
        for key, value in data.items():
            yield (*prefix, key)
            yield from _paths(value, (*prefix, key))
    elif isinstance(data, list):
        for index, value in enumerate(data):
            yield (*prefix, index)
            yield from _paths(value, (*prefix, index))


def _get(data: Any, path: tuple) -> Any:
    for part in path:
        data = data[part]
    return data


def _set(data: Any, path: tuple, value: Any) -> None:
    _get(data, path[:-1])[path[-1]] = value


def _delete(data: Any, path: tuple) -> None:
    del _get(data, path[:-1])[path[-1]]


def _dump(data: Any) -> str:
    return yaml.safe_dump(
        data, sort_keys=False, default_flow_style=None, width=4096, allow_unicode=True
    )


_PLACEHOLDER = "FUZZPLACEHOLDER"


def _with_text_at(data: Any, path: tuple, text: str) -> str:
    """The YAML of `data` with the value at `path` replaced by raw YAML `text`."""
    changed = copy.deepcopy(data)
    _set(changed, path, _PLACEHOLDER)
    return _dump(changed).replace(_PLACEHOLDER, text, 1)


# ---------------------------------------------------------------------------------------------
# Base artifacts, built once per process


@functools.cache
def _scratch() -> Path:
    """A folder for the base files of this process, removed when it exits."""
    folder = Path(tempfile.mkdtemp(prefix="flexmbd-fuzz-base-"))
    atexit.register(shutil.rmtree, folder, True)
    return folder


@functools.cache
def box_mesh(element: str = "hex8", divisions: tuple[int, int, int] = (4, 1, 1)) -> Any:
    from flexmbd.fe import shapes

    return shapes.box((0.5, 0.05, 0.05), divisions, element)


def _abaqus_lines(nodes: Any, conn: Any, abaqus_type: str, sets: dict[str, Any]) -> list[str]:
    lines = ["*HEADING", "flexmbd fuzz mesh", "*NODE"]
    lines += [f"{k + 1}, {x!r}, {y!r}, {z!r}" for k, (x, y, z) in enumerate(nodes.tolist())]
    lines.append(f"*ELEMENT, TYPE={abaqus_type}, ELSET=SOLID")
    for k, row in enumerate(conn.tolist()):
        labels = [str(n + 1) for n in row]
        lines.append(", ".join([str(k + 1), *labels]))
    for name, members in sets.items():
        lines.append(f"*NSET, NSET={name}")
        labels = [str(n + 1) for n in members.tolist()]
        lines += [", ".join(labels[k : k + 16]) for k in range(0, len(labels), 16)]
    lines += ["*NSET, NSET=EVERY, GENERATE", f"1, {len(nodes)}, 1"]
    lines += ["*ELSET, ELSET=ALLE, GENERATE", f"1, {len(conn)}, 1"]
    return lines


@functools.cache
def abaqus_text(element: str = "hex8") -> str:
    """A small valid Abaqus input: a box of `element` cells, node sets x0 and x1."""
    mesh = box_mesh(element)
    conn = mesh.elements[element]
    if element == "tet10":
        conn = conn[:, [0, 1, 2, 3, 4, 5, 6, 7, 9, 8]]  # Abaqus C3D10 order
    kind = {"hex8": "C3D8", "tet4": "C3D4", "tet10": "C3D10"}[element]
    sets = {"x0": mesh.node_sets["x0"], "x1": mesh.node_sets["x1"]}
    return "\n".join(_abaqus_lines(mesh.nodes, conn, kind, sets)) + "\n"


@functools.cache
def meshio_bytes(file_format: str, binary: bool) -> bytes:
    """A small tetrahedral box written by meshio in `file_format` ("gmsh22", "gmsh", "vtk",
    "vtu")."""
    import meshio

    mesh = box_mesh("tet4")
    cells = [("tetra", np.asarray(mesh.elements["tet4"]))]
    suffix = {"gmsh22": ".msh", "gmsh": ".msh", "vtk": ".vtk", "vtu": ".vtu"}[file_format]
    path = _scratch() / f"mesh-{file_format}-{int(binary)}{suffix}"
    out = meshio.Mesh(np.asarray(mesh.nodes), cells)
    if file_format.startswith("gmsh"):
        count = len(mesh.elements["tet4"])
        out.cell_data = {
            "gmsh:physical": [np.ones(count, dtype=np.int32)],
            "gmsh:geometrical": [np.ones(count, dtype=np.int32)],
        }
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if file_format == "vtu":
            meshio.write(path, out, file_format=file_format, binary=binary, compression=None)
        else:
            meshio.write(path, out, file_format=file_format, binary=binary)
    return path.read_bytes()


def _material() -> Any:
    from flexmbd.fe import Material

    return Material(7.0e10, 0.33, 2700.0)


@functools.cache
def body_bytes(kind: str) -> bytes:
    """A saved body file: "nodal" (hex8 box, clamped), "beam" (4 beam elements, clamped) or
    "modal" (tet4 box, Craig-Bampton at its face x0)."""
    from flexmbd import fe

    if kind == "nodal":
        mesh = box_mesh("hex8", (3, 1, 1))
        body = fe.build_body(
            mesh.nodes,
            mesh.elements,
            _material(),
            node_sets=mesh.node_sets,
            reference="clamped",
            reference_nodes="x0",
        )
    elif kind == "beam":
        nodes, elements = fe.straight_beam(0.5, 4)
        body = fe.build_body(
            nodes,
            elements,
            _material(),
            section=fe.Section.circle(0.01),
            reference="clamped",
            reference_nodes=[0],
        )
    else:
        mesh = box_mesh("tet4", (3, 1, 1))
        body = fe.build_body(
            mesh.nodes,
            mesh.elements,
            _material(),
            node_sets=mesh.node_sets,
            reference="interface",
            modes="craig-bampton",
            mode_count=2,
            interfaces=["x0"],
        )
    path = _scratch() / f"body-{kind}.h5"
    fe.save_body(body, path)
    return path.read_bytes()


@functools.cache
def results_bytes(kind: str) -> tuple[bytes, int, bytes]:
    """A results file: "rigid" (pendulum, 21 records) or "flexible" (a nodal beam on a hinge,
    11 records); also its record count and the bytes of its time records."""
    import flexmbd as fm

    path = _scratch() / f"results-{kind}.h5"
    if kind == "rigid":
        system = fm.System(gravity=(0, -9.81, 0))
        mass = system.add_point_mass(1.0, position=(1, 0, 0), name="bob")
        pivot = system.add_marker(system.ground, name="pivot")
        system.add_distance_joint(pivot, system.add_marker(mass), name="link")
        system.add_sensor(pivot, "position", name="pivot position")
        result = fm.simulate(system, 0.02, 1e-3, results_file=path, metadata={"case": kind})
    else:
        system = fm.System(gravity=(0, -9.81, 0))
        beam = system.add_flexible_body(_beam_body(), name="beam")
        hinge = system.add_node_marker(beam, 1)
        system.add_spherical_joint(system.add_marker(system.ground), hinge, name="hinge")
        result = fm.simulate(system, 0.01, 1e-3, results_file=path)
    return path.read_bytes(), len(result.time), np.asarray(result.time).tobytes()


# ---------------------------------------------------------------------------------------------
# Family 1: model files

#: Models that read a mesh and a body file, besides the examples.
_INP_MODEL = """\
name: inp-arm
description: an aluminium arm read from an Abaqus input, Craig-Bampton, on a hinge
gravity: [0.0, -9.81, 0.0]
bodies:
  - name: arm
    type: flexible
    mesh: arm.inp
    material: {young_modulus: 7.0e+10, poisson_ratio: 0.33, density: 2700.0}
    reference: interface
    modes: craig-bampton
    mode_count: 2
    interfaces: [x0]
joints:
  - {name: hinge, type: revolute, marker1: {body: ground}, marker2: {body: arm, node_set: x0}}
solver: {type: generalized-alpha, spectral_radius: 0.9}
simulation: {end_time: 0.01, step_size: 1.0e-3, output_interval: 2.0e-3}
outputs:
  - {body: arm, quantity: elastic_coordinates}
  - {body: arm, quantity: node_displacements, nodes: [1, 2]}
  - {joint: hinge, quantity: reaction_force}
"""

_H5_MODEL = """\
name: h5-arm
description: a modal body read from a body file, on a hinge, with a spring and a driver
gravity: [0.0, -9.81, 0.0]
functions:
  lift: {type: harmonic, amplitude: 0.01, frequency: 10.0}
bodies:
  - {name: arm, type: flexible, body_file: arm.h5, position: [0.0, 0.0, 0.0]}
  - {name: weight, type: point-mass, mass: 0.5, position: [0.6, 0.0, 0.0]}
markers:
  - {name: tip, body: arm, node_set: x1}
  - {name: w, body: weight}
joints:
  - {name: hinge, type: revolute, marker1: {body: ground}, marker2: {body: arm, node_set: x0}}
forces:
  - {name: spring, type: spring-damper, marker1: tip, marker2: w, stiffness: 1000.0,
     damping: 1.0}
  - {name: push, type: point-force, marker: w, force: [0.0, lift, 0.0]}
sensors:
  - {name: tip position, marker: tip, quantity: position}
simulation: {end_time: 0.01, step_size: 1.0e-3}
"""


@dataclass(frozen=True)
class _ModelBase:
    name: str
    text: str
    data: Any
    extras: tuple[tuple[str, Callable[[], bytes]], ...]
    weight: float  # share of the mutations (the Gmsh example meshes with gmsh: fewer)


@functools.cache
def _model_bases() -> tuple[_ModelBase, ...]:
    bases = []
    weights = {"gmsh_pendulum": 0.2, "tetrahedral_pendulum": 0.8}
    for path in sorted(EXAMPLES.glob("*.yaml")):
        text = path.read_text(encoding="utf-8")
        bases.append(
            _ModelBase(path.stem, text, yaml.safe_load(text), (), weights.get(path.stem, 1.0))
        )
    inp = (("arm.inp", lambda: abaqus_text("hex8").encode()),)
    h5 = (("arm.h5", lambda: body_bytes("modal")),)
    bases.append(_ModelBase("inp_arm", _INP_MODEL, yaml.safe_load(_INP_MODEL), inp, 0.6))
    bases.append(_ModelBase("h5_arm", _H5_MODEL, yaml.safe_load(_H5_MODEL), h5, 0.6))
    return tuple(bases)


#: What an error of a model file names: the file (every error of load_model), or, for an
#: error of the run, the setting or item (step size, body, joint, the system, ...).
MODEL_NAMES = (
    "model.yaml",
    "step size",
    "steady rotation",
    "equilibrium",
    "body",
    "joint",
    "driver",
    "marker",
    "coordinate",
    "system",
    "solver",
)


def load_and_run(folder: Path, file: str = "model.yaml") -> None:
    """Loads a model file and, when it loads, simulates three steps and computes its
    outputs."""
    from flexmbd.model_file import load_model, simulate_model

    model = load_model(folder / file)
    # Three steps; no more than 50 records (steps land on the output times, so a step size
    # far above the output interval would make this a long run).
    span = 3 * model.step_size
    if model.output_interval is not None and model.output_interval > 0:
        span = min(span, 50 * model.output_interval)
    end = model.start_time + span
    result = simulate_model(model, end_time=end)
    check_result(result, end)
    for name, values in model.output_values(result).items():
        _finite(f"output {name!r}", values)


def _model_case(
    base: _ModelBase,
    kind: str,
    number: int,
    make: Callable[[], bytes | str],
    *,
    must_fail: bool = False,
) -> Case:
    def prepare(folder: Path) -> None:
        for name, content in base.extras:
            _write(folder / name, content())
        _write(folder / "model.yaml", make())

    return Case(
        name=f"model-files/{base.name}/{kind}/{number:03d}",
        family="model-files",
        kind=kind,
        prepare=prepare,
        operate=load_and_run,
        names=MODEL_NAMES,
        must_fail=must_fail,
    )


_SIMULATION_VALUES: dict[str, list[Any]] = {
    "end_time": [0, -1.0, 1e-300, 1e300, math.nan, "10", None, 1e-9, 0.5, "1:30"],
    "step_size": [0, -1e-3, 1e-300, 1e300, 1e-9, 0.5, 10.0, math.inf, True],
    "output_interval": [0, -1.0, 1e-300, 1e300, None, 1e-3, "0.1"],
    "start_time": [-1e300, 1e300, -1.0, 5.0, math.nan, 1e16, 1e-300],
    "start": ["given", "equilibrium", "steady-rotation", "bogus", "", 1],
}

_ALPHA_VALUES: dict[str, list[Any]] = {
    "spectral_radius": [0, 0.5, 1, 1.5, -0.1],
    "newton_tolerance": [1e-300, 1e300, 0, -1.0],
    "max_iterations": [1, 0, -1, 10**20, 2.5],
    "jacobian": ["modified", "step", "full", "x"],
    "step_control": ["newton", "fixed", "error", "x"],
    "relative_tolerance": [1e-300, 1.0, 1e300],
    "absolute_tolerance": [1e-300, 1.0, 1e300],
    "min_step_size": [1e-300, 1.0, 1e300, -1.0],
    "max_step_size": [1e300, -1.0, 0, 1e-5],
    "velocity_projection": ["auto", "always", "never", 3],
    "linear_solver": ["auto", "lu", "ldlt", "x"],
    "initial_tolerance": [1e-300, 1.0, 1e300],
    "correct_initial_positions": [True, False, "yes"],
    "correct_initial_velocities": [True, False],
    "redundant_constraints": ["remove", "minimum-norm", "error", "x"],
    "rank_tolerance": [1e-300, 0.5, 1, 0],
}

_EXPLICIT_VALUES: dict[str, list[Any]] = {
    "method": ["rk4", "dopri5", "euler"],
    "strategy": ["integrate-all", "partitioning", "projection", "joint-coordinates", "x"],
    "formulation": ["augmented", "embedding", "joint-space", "coupled", "decoupled", "x"],
    "partition": ["lu", "qr", "svd", "x"],
    "independent": [[0], [0, 1, 2], [99], [-1], []],
    "baumgarte": [[1.0, 1.0], [0, 0], [-1.0, 1.0], [1e300, 1e300], [1.0]],
    "relative_tolerance": [1e-300, 1.0, 1e300],
    "absolute_tolerance": [1e-300, 1e300],
    "constraint_tolerance": [1e-300, 1e300, 0],
    "max_iterations": [1, 0, 10**20],
    "repartition_ratio": [0.5, 1e300, 1e-300],
    "drift_threshold": [1e-300, 1e300],
    "singular_factor": [1e-300, 1e300],
    "min_step_size": [1e-300, 1.0],
    "max_step_size": [1e300, 1e-5],
    "cut_joints": [["link"], ["nonexistent"], [], ["pivot 0", "pivot 0"], ["hinge"]],
}


def _random_solver(rng: random.Random) -> dict[str, Any]:
    kind = rng.choice(["generalized-alpha", "explicit", "explicit", "newmark"])
    pool = _ALPHA_VALUES if kind == "generalized-alpha" else _EXPLICIT_VALUES
    spec: dict[str, Any] = {"type": kind}
    for key in rng.sample(sorted(pool), rng.randint(1, 3)):
        spec[key] = rng.choice(pool[key])
    return spec


def _random_units(rng: random.Random) -> Any:
    choices: dict[str, list[Any]] = {
        "length": ["m", "mm", "cm", "km", "in", 1, ""],
        "mass": ["kg", "g", "t", "lb"],
        "time": ["s", "ms", "h", None],
        "angle": ["rad", "deg", "grad"],
    }
    if rng.random() < 0.15:
        return rng.choice(["SI", ["m", "kg"], 1, None, {"force": "N"}])
    return {key: rng.choice(values) for key, values in choices.items() if rng.random() < 0.6}


def _model_operators(rng: random.Random, base: _ModelBase) -> list[tuple[str, Any, bool]]:
    """(kind, make, must_fail) of one round of structural and textual mutations of `base`."""
    data = base.data
    paths = list(_paths(data))
    numeric = [p for p in paths if type(_get(data, p)) in (int, float)]
    strings = [p for p in paths if isinstance(_get(data, p), str)]
    lists = [p for p in paths if isinstance(_get(data, p), list) and _get(data, p)]
    mappings = [p for p in paths if isinstance(_get(data, p), dict)]
    out: list[tuple[str, Any, bool]] = []

    def structural(change: Callable[[Any], None]) -> Callable[[], str]:
        def make() -> str:
            changed = copy.deepcopy(data)
            change(changed)
            return _dump(changed)

        return make

    # Delete a key or a list item.
    path = rng.choice(paths)
    out.append(("delete-key", structural(lambda d, p=path: _delete(d, p)), False))
    # A value of another type.
    path, value = rng.choice(paths), rng.choice(OTHER_TYPES)
    out.append(("retype", structural(lambda d, p=path, v=value: _set(d, p, v)), False))
    # A number out of range.
    if numeric:
        path, value = rng.choice(numeric), rng.choice(NUMBERS)
        bad = isinstance(value, float) and not math.isfinite(value)
        out.append(("number", structural(lambda d, p=path, v=value: _set(d, p, v)), bad))
        path, factor = rng.choice(numeric), rng.choice([-1.0, 0.0, 1e6, 1e-6, 1e12])
        out.append(
            ("scale", structural(lambda d, p=path, f=factor: _set(d, p, _get(d, p) * f)), False)
        )
    # A string: empty, unknown, long, a path, ...
    if strings:
        path, value = rng.choice(strings), rng.choice(STRINGS)
        out.append(("string", structural(lambda d, p=path, v=value: _set(d, p, v)), False))
    # A key renamed (a typo, another case, an empty key).
    if mappings:
        path = rng.choice(mappings)
        mapping = _get(data, path)
        if mapping:
            key = rng.choice(sorted(mapping, key=str))
            new = rng.choice([f"{key}s", str(key).upper(), f" {key}", "", f"{key}_", "<<"])

            def rename(d: Any, p: tuple = path, k: Any = key, n: str = new) -> None:
                target = _get(d, p)
                target[n] = target.pop(k)

            out.append(("rename-key", structural(rename), False))
    # Items duplicated, emptied or reordered.
    if lists:
        path = rng.choice(lists)
        how = rng.choice(["duplicate", "empty", "reverse", "nest"])

        def relist(d: Any, p: tuple = path, h: str = how) -> None:
            items = _get(d, p)
            if h == "duplicate":
                items.append(copy.deepcopy(items[0]))
            elif h == "empty":
                items.clear()
            elif h == "reverse":
                items.reverse()
            else:
                _set(d, p, [items])

        out.append((f"list-{how}", structural(relist), False))
    # Units.
    units = _random_units(rng)
    out.append(("units", structural(lambda d, u=units: d.__setitem__("units", u)), False))
    # Simulation settings.
    settings = {
        key: rng.choice(values)
        for key, values in rng.sample(sorted(_SIMULATION_VALUES.items()), rng.randint(1, 2))
    }

    def simulation(d: Any, s: dict = settings) -> None:
        d.setdefault("simulation", {}).update(s)

    out.append(("simulation", structural(simulation), False))
    # Solver settings.
    solver = _random_solver(rng)
    out.append(("solver", structural(lambda d, s=solver: d.__setitem__("solver", s)), False))
    # Joints: markers swapped or the same marker twice; joint types exchanged.
    joints = data.get("joints") or []
    if joints:
        index = rng.randrange(len(joints))
        how = rng.choice(["swap", "same", "type"])

        def joint(d: Any, i: int = index, h: str = how, r: int = _seed(rng)) -> None:
            spec = d["joints"][i]
            if h == "swap":
                spec["marker1"], spec["marker2"] = spec.get("marker2"), spec.get("marker1")
            elif h == "same":
                spec["marker2"] = copy.deepcopy(spec.get("marker1"))
            else:
                kinds = ["spherical", "revolute", "cylindrical", "prismatic", "fixed"]
                kinds += ["universal", "planar", "inline", "distance", "angle-driver"]
                spec["type"] = random.Random(r).choice(kinds)

        out.append((f"joint-{how}", structural(joint), False))

    # Text mutations of the file as written.
    text = base.text
    count = rng.choice([1, 1, 2, 4, 16])
    window = rng.choice([None, 200])
    flip_seed = _seed(rng)
    out.append(
        (
            "flip",
            lambda s=flip_seed, c=count, w=window: _flip(text.encode(), random.Random(s), c, w),
            False,
        )
    )
    cut = rng.randrange(len(text))
    out.append(("truncate", lambda c=cut: text.encode()[:c], False))
    char, where = rng.choice(CONTROL), rng.randrange(len(text))
    out.append(
        (
            "control",
            lambda c=char, w=where: text.encode()[:w] + c + text.encode()[w:],
            char in _MUST_REFUSE_CONTROL,
        )
    )
    lines = text.splitlines(keepends=True)
    keyed = [k for k, line in enumerate(lines) if re.match(r"^\s*[\w -]+:\s", line)]
    if keyed:
        k = rng.choice(keyed)
        out.append(("duplicate-key", lambda k=k: "".join(lines[: k + 1] + lines[k:]), True))
    path = rng.choice(paths)
    tag = rng.choice(TAGS)
    out.append(("tag", lambda p=path, t=tag: _with_text_at(data, p, t), "python" in tag))
    depth = rng.choice([50, 65, 200, 1000, 20_000])
    shape = rng.choice(["list", "map"])
    nested = "[" * depth + "]" * depth if shape == "list" else "{a: " * depth + "1" + "}" * depth
    out.append(("nesting", lambda p=path, n=nested: _with_text_at(data, p, n), depth > 64))
    size = rng.choice([10_000, 1_000_000, 3_000_000, 5_000_000])
    long_path = rng.choice(strings or paths)
    out.append(
        (
            "long-string",
            lambda p=long_path, n=size: _with_text_at(data, p, "x" * n),
            size > 4 * 1024 * 1024,
        )
    )
    if numeric:
        path, scalar = rng.choice(numeric), rng.choice(YAML_SCALARS)
        out.append(("yaml-scalar", lambda p=path, s=scalar: _with_text_at(data, p, s), False))
    return out


_ALIAS_DOCUMENTS = [
    # Billion laughs: nine levels of ten aliases.
    "".join(
        f"l{k}: &l{k} [{', '.join([f'*l{k - 1}'] * 10)}]\n" if k else "l0: &l0 [lol]\n"
        for k in range(9)
    ),
    "a: &a [*a]\n",
    "a: &a {b: *a}\n",
    "a: *nope\n",
    "<<: 5\nname: x\n",
    "<<: [*x]\n",
    "a: &a [1, 2]\nb: {<<: *a}\n",
]

_WHOLE_FILES: list[tuple[str, bytes, bool]] = [
    ("empty", b"", True),
    ("document-start", b"---\n", True),
    ("null", b"~\n", True),
    ("list", b"[]\n", True),
    ("number", b"42\n", True),
    ("string", b"'a model'\n", True),
    ("two-documents", b"simulation: {end_time: 1, step_size: 0.1}\n---\nname: x\n", True),
    ("comment", b"# nothing here\n", True),
    ("only-simulation", b"simulation: {end_time: 0.01, step_size: 0.001}\n", False),
    ("bom", "\ufeffsimulation: {end_time: 0.01, step_size: 0.001}\n".encode(), False),
    ("utf16", "simulation: {end_time: 1, step_size: 0.1}\n".encode("utf-16"), False),
    (
        "latin1",
        "name: caf\xe9\nsimulation: {end_time: 1, step_size: 0.1}\n".encode("latin-1"),
        True,
    ),
    ("binary", bytes(range(256)) * 16, True),
    ("many-items", b"a: [" + b"0," * 1_200_000 + b"0]\n", True),
    ("many-lines", b"a:\n" + b"- 0\n" * 200_000, True),
    ("oversize", b"# " + b"x" * (5 * 1024 * 1024) + b"\n", True),
    ("many-documents", b"---\na: 1\n" * 10_000, True),
    ("long-key", b"x" * 2_000_000 + b": 1\n", True),
    ("tabs", b"simulation:\n\tend_time: 1\n", True),
    ("crlf", b"simulation: {end_time: 0.01, step_size: 0.001}\r\n", False),
    ("cr-only", b"name: x\rsimulation: {end_time: 0.01, step_size: 0.001}\r", False),
    ("unclosed", b"simulation: {end_time: 0.01, step_size: [0.001\n", True),
    ("directive", b"%YAML 1.1\n---\nsimulation: {end_time: 0.01, step_size: 0.001}\n", False),
    ("bad-directive", b"%YAML 9.9\n---\nname: x\n", True),
    ("tag-directive", b"%TAG !p! tag:yaml.org,2002:python/\n---\na: !p!name:os.system\n", True),
]


def _model_file_cases(rng: random.Random) -> list[Case]:
    cases: list[Case] = []
    rounds = 4
    for base in _model_bases():
        number = 0
        for _ in range(rounds):
            operators = _model_operators(rng, base)
            for kind, make, must_fail in operators:
                if rng.random() < base.weight:
                    cases.append(_model_case(base, kind, number, make, must_fail=must_fail))
                    number += 1
    pendulum = next(b for b in _model_bases() if b.name == "pendulum")
    for number, document in enumerate(_ALIAS_DOCUMENTS):
        cases.append(
            _model_case(
                pendulum, "alias", number, lambda d=document: pendulum.text + d, must_fail=True
            )
        )
    for number, (what, content, must_fail) in enumerate(_WHOLE_FILES):
        cases.append(
            _model_case(pendulum, f"whole-{what}", number, lambda c=content: c, must_fail=must_fail)
        )
    cases += _model_path_cases()
    return cases


def _model_path_cases() -> list[Case]:
    """Model files that are not regular files, and model files that name odd files."""

    def special(kind: str) -> Callable[[Path], None]:
        def prepare(folder: Path) -> None:
            target = folder / "model.yaml"
            if kind == "directory":
                target.mkdir()
            elif kind == "fifo":
                os.mkfifo(target)
            elif kind == "dev-zero":
                target.symlink_to("/dev/zero")
            elif kind == "dangling-link":
                target.symlink_to(folder / "missing.yaml")
            elif kind == "link-loop":
                target.symlink_to(target)

        return prepare

    cases = []
    for number, kind in enumerate(
        ["directory", "fifo", "dev-zero", "dangling-link", "link-loop", "missing"]
    ):
        cases.append(
            Case(
                name=f"model-files/path/{kind}/{number:03d}",
                family="model-files",
                kind=kind,
                prepare=special(kind),
                operate=load_and_run,
                names=("model.yaml",),
                must_fail=True,
                timeout=SPECIAL_FILE_TIMEOUT if kind in _SPECIAL_FILES else None,
            )
        )
    pendulum = next(b for b in _model_bases() if b.name == "pendulum")
    body = (
        "bodies:\n  - name: arm\n    type: flexible\n    {key}: {value}\n"
        "    material: {{young_modulus: 1.0e+9, poisson_ratio: 0.3, density: 1000.0}}\n"
    )
    references = [
        ("mesh", "/dev/zero.msh"),
        ("mesh", "fifo.inp"),
        ("mesh", "missing.inp"),
        ("mesh", "/etc/passwd"),
        ("mesh", "../outside.inp"),
        ("mesh", "model.yaml"),
        ("mesh", "folder.msh"),
        ("mesh", "''"),
        ("body_file", "model.yaml"),
        ("body_file", "missing.h5"),
        ("body_file", "/dev/null"),
        ("body_file", "fifo.inp"),
        ("body_file", "folder.msh"),
        ("body_file", "arm.inp"),
    ]
    for number, (key, value) in enumerate(references):
        text = pendulum.text.replace("bodies:\n", body.format(key=key, value=value), 1)

        def prepare(folder: Path, t: str = text) -> None:
            _write(folder / "model.yaml", t)
            os.mkfifo(folder / "fifo.inp")
            (folder / "folder.msh").mkdir()
            _write(folder / "arm.inp", abaqus_text("hex8"))

        cases.append(
            Case(
                name=f"model-files/path/{key}-{Path(value).name or 'empty'}/{number:03d}",
                family="model-files",
                kind=f"{key}-reference",
                prepare=prepare,
                operate=load_and_run,
                names=("model.yaml",),
                must_fail=True,
            )
        )
    return cases


# ---------------------------------------------------------------------------------------------
# Family 2: meshes


def read_and_build(folder: Path, file: str) -> None:
    """Reads a mesh and, when it reads and is small, builds a nodal body of it, compiles it
    into a system and runs three steps."""
    import flexmbd as fm
    from flexmbd.fe import body_from_mesh, read_mesh

    mesh = read_mesh(folder / file)
    if len(mesh.nodes) > 5000:
        return
    options: dict[str, Any] = {}
    if "beam2" in mesh.elements:
        from flexmbd.fe import Section

        options["section"] = Section.circle(0.01)
    body = body_from_mesh(mesh, _material(), **options)
    _finite("body nodes", body.nodes)
    system = fm.System()
    system.add_flexible_body(body, name="mesh")
    _run_steps(system, step=1e-4, steps=2)


def _mesh_case(
    base: str,
    kind: str,
    number: int,
    file: str,
    make: Callable[[], bytes | str],
    *,
    must_fail: bool = False,
    extras: Callable[[Path], None] | None = None,
    allowed: tuple[type[BaseException], ...] = (),
    timeout: float | None = None,
) -> Case:
    def prepare(folder: Path) -> None:
        if extras is not None:
            extras(folder)
        content = make()
        if content is not None:
            _write(folder / file, content)

    return Case(
        name=f"meshes/{base}/{kind}/{number:03d}",
        family="meshes",
        kind=kind,
        prepare=prepare,
        operate=lambda folder: read_and_build(folder, file),
        names=(file, "node", "element", "set", "label", "mesh", "line"),
        must_fail=must_fail,
        allowed=allowed,
        timeout=timeout,
    )


def _abaqus_operators(rng: random.Random, element: str) -> list[tuple[str, Any, bool, Any]]:
    """(kind, make, must_fail, extras) of one round of Abaqus mutations."""
    out: list[tuple[str, Any, bool, Any]] = []

    def lines() -> list[str]:
        return abaqus_text(element).splitlines()

    def node_rows(text: list[str]) -> list[int]:
        start = text.index("*NODE") + 1
        end = next(k for k in range(start, len(text)) if text[k].startswith("*"))
        return list(range(start, end))

    def element_rows(text: list[str]) -> list[int]:
        start = next(k for k, line in enumerate(text) if line.startswith("*ELEMENT")) + 1
        end = next(k for k in range(start, len(text)) if text[k].startswith("*"))
        return list(range(start, end))

    def edit(change: Callable[[list[str], random.Random], None]) -> Callable[[], str]:
        seed = _seed(rng)

        def make() -> str:
            text = lines()
            change(text, random.Random(seed))
            return "\n".join(text) + "\n"

        return make

    label = rng.choice(["0", "-1", str(2**63), str(2**70), "abc", "1.5", "", "1e3", "0x10"])

    def bad_node_label(text: list[str], r: random.Random, v: str = label) -> None:
        k = r.choice(node_rows(text))
        text[k] = ", ".join([v, *text[k].split(",")[1:]])

    out.append(("node-label", edit(bad_node_label), label not in ("1e3",), None))

    def duplicate_node(text: list[str], r: random.Random) -> None:
        k = r.choice(node_rows(text))
        text.insert(k + 1, text[k])

    out.append(("duplicate-node", edit(duplicate_node), True, None))

    def missing_node(text: list[str], r: random.Random) -> None:
        del text[r.choice(node_rows(text))]

    out.append(("missing-node", edit(missing_node), True, None))

    how = rng.choice(["drop", "add", "unknown", "negative", "repeat", "float", "huge"])

    def connectivity(text: list[str], r: random.Random, h: str = how) -> None:
        k = r.choice(element_rows(text))
        parts = [p.strip() for p in text[k].split(",")]
        if h == "drop":
            parts = parts[:-1]
        elif h == "add":
            parts.append(parts[-1])
        elif h == "unknown":
            parts[-1] = "99999"
        elif h == "negative":
            parts[1] = "-3"
        elif h == "repeat":
            parts[2] = parts[1]
        elif h == "float":
            parts[1] = "1.5"
        else:
            parts[1] = str(2**70)
        text[k] = ", ".join(parts)

    out.append((f"connectivity-{how}", edit(connectivity), True, None))

    triple = rng.choice(
        [
            "1, 10, 0",
            "1, 10, -1",
            "10, 1, 1",
            f"1, {10**12}, 1",
            f"1, {2**70}, 1",
            "1",
            "1, 2, 3, 4",
            "a, b, c",
            "0, 5, 1",
            "1, 5, 1.5",
            f"{2**63 - 2}, {2**63 - 1}, 1",
        ]
    )
    keyword = rng.choice(["*NSET, NSET=G, GENERATE", "*ELSET, ELSET=G, GENERATE"])

    def generate(text: list[str], r: random.Random, t: str = triple, w: str = keyword) -> None:
        text += [w, t]

    out.append(("generate", edit(generate), True, None))

    include = rng.choice(
        [
            "missing.inp",
            "/etc/passwd",
            "mesh.inp",
            "a.inp",
            "../outside.inp",
            "",
            "folder",
            "link.inp",
            "deep0.inp",
            "fifo.inp",
            "/dev/zero",
        ]
    )

    def include_line(text: list[str], r: random.Random, name: str = include) -> None:
        text.insert(r.randrange(len(text) + 1), f"*INCLUDE, INPUT={name}")

    def include_files(folder: Path) -> None:
        _write(folder / "a.inp", "*INCLUDE, INPUT=b.inp\n")
        _write(folder / "b.inp", "*INCLUDE, INPUT=a.inp\n")
        (folder / "folder").mkdir()
        (folder / "link.inp").symlink_to("/etc/hostname")
        os.mkfifo(folder / "fifo.inp")
        for k in range(20):
            _write(folder / f"deep{k}.inp", f"*INCLUDE, INPUT=deep{k + 1}.inp\n")
        _write(folder / "deep20.inp", "** end\n")

    out.append(
        (f"include-{Path(include).stem or 'empty'}", edit(include_line), True, include_files)
    )

    keywords = [
        "*ELEMENT, TYPE=C3D20",
        "*ELEMENT",
        "*NODE",
        "*NSET",
        "*NSET, NSET=",
        "*ELSET, ELSET=X",
        "*PART, NAME=P",
        "*UNKNOWN",
        "*node",
        "*ELEMENT, TYPE=B31",
        "*ELEMENT, TYPE=C3D8, ELSET=",
        "*NSET, NSET=S, ELSET=NOPE",
        "*NSET, NSET=S\nNOSUCHSET",
    ]
    word = rng.choice(keywords)

    def insert_keyword(text: list[str], r: random.Random, w: str = word) -> None:
        text.insert(r.randrange(1, len(text) + 1), w)

    out.append(("keyword", edit(insert_keyword), False, None))

    def delete_line(text: list[str], r: random.Random) -> None:
        del text[r.randrange(len(text))]

    out.append(("delete-line", edit(delete_line), False, None))

    value = rng.choice(["nan", "inf", "-inf", "1e400", "abc", "", "1e308", "0x1"])

    def coordinate(text: list[str], r: random.Random, v: str = value) -> None:
        k = r.choice(node_rows(text))
        parts = text[k].split(",")
        parts[r.randrange(1, len(parts))] = v
        text[k] = ",".join(parts)

    out.append(("coordinate", edit(coordinate), True, None))

    def flip() -> Callable[[], bytes]:
        seed, count = _seed(rng), rng.choice([1, 4, 32])
        return lambda: _flip(abaqus_text(element).encode(), random.Random(seed), count)

    out.append(("flip", flip(), False, None))
    fraction = rng.random()
    out.append(
        ("truncate", lambda f=fraction: abaqus_text(element).encode()[: int(f * 4000)], False, None)
    )
    return out


_ABAQUS_WHOLE: list[tuple[str, bytes, bool]] = [
    ("empty", b"", True),
    ("garbage", bytes(range(256)) * 8, True),
    ("nul", b"*NODE\n1, 0, 0, 0\x00\n", True),
    ("no-elements", b"*NODE\n1, 0, 0, 0\n2, 1, 0, 0\n", True),  # no body without elements
    ("two-node-blocks", b"*NODE\n1, 0, 0, 0\n*NODE\n2, 1, 0, 0\n", True),
    ("long-line", b"*NODE\n1, " + b"0" * 2_000_000 + b", 0, 0\n", True),  # a lone node
    ("many-columns", b"*NODE\n1" + b", 0" * 100_000 + b"\n", True),
    ("bom", "\ufeff*NODE\n1, 0, 0, 0\n".encode(), True),
    ("utf16", "*NODE\n1, 0, 0, 0\n".encode("utf-16"), True),
    ("crlf", b"*NODE\r\n1, 0, 0, 0\r\n2, 1, 0, 0\r\n*ELEMENT, TYPE=T3D2\r\n1, 1, 2\r\n", False),
    ("only-comments", b"** nothing\n** here\n", True),
    (
        "huge-generate",
        f"*NODE\n1, 0, 0, 0\n*NSET, NSET=A, GENERATE\n1, {2**62}, 1\n".encode(),
        True,
    ),
    ("label-2-70", f"*NODE\n{2**70}, 0, 0, 0\n".encode(), True),
    ("self-include", b"*INCLUDE, INPUT=mesh.inp\n", True),
]


def _gmsh_operators(rng: random.Random, fmt: str, binary: bool) -> list[tuple[str, Any, bool]]:
    out: list[tuple[str, Any, bool]] = []

    def base() -> bytes:
        return meshio_bytes(fmt, binary)

    seed, count = _seed(rng), rng.choice([1, 2, 8, 64])
    out.append(("flip", lambda s=seed, c=count: _flip(base(), random.Random(s), c), False))
    fraction = rng.random()
    out.append(("truncate", lambda f=fraction: base()[: int(f * len(base()))], False))
    if binary:
        return out

    def lines_edit(change: Callable[[list[bytes], random.Random], None]) -> Callable[[], bytes]:
        seed = _seed(rng)

        def make() -> bytes:
            text = base().split(b"\n")
            change(text, random.Random(seed))
            return b"\n".join(text)

        return make

    def delete_line(text: list[bytes], r: random.Random) -> None:
        del text[r.randrange(len(text))]

    out.append(("delete-line", lines_edit(delete_line), False))

    def duplicate_line(text: list[bytes], r: random.Random) -> None:
        k = r.randrange(len(text))
        text.insert(k, text[k])

    out.append(("duplicate-line", lines_edit(duplicate_line), False))
    token = rng.choice(
        [b"-1", b"0", b"1e308", b"nan", str(2**63).encode(), b"99999999999", b"abc", b"", b"3.5"]
    )

    def replace_token(text: list[bytes], r: random.Random, t: bytes = token) -> None:
        candidates = [k for k, line in enumerate(text) if re.search(rb"\d", line)]
        k = r.choice(candidates)
        numbers = list(re.finditer(rb"-?\d+(\.\d*)?(e[-+]?\d+)?", text[k]))
        found = r.choice(numbers)
        text[k] = text[k][: found.start()] + t + text[k][found.end() :]

    out.append(("token", lines_edit(replace_token), False))

    def header_count(text: list[bytes], r: random.Random) -> None:
        # The line after a section header holds its counts: make them huge or negative.
        headers = [k for k, line in enumerate(text) if line.startswith(b"$") and b"End" not in line]
        k = r.choice(headers) + 1
        if k < len(text):
            text[k] = r.choice([b"1000000000000", b"-5", b"0", b"2 0 1 1000000000000"])

    if fmt.startswith("gmsh"):
        out.append(("header-count", lines_edit(header_count), False))
    return out


def _vtk_garbage() -> list[tuple[str, str, bytes, bool]]:
    """(kind, file, content, must_fail) of hostile VTK files."""
    bomb = (
        '<?xml version="1.0"?>\n<!DOCTYPE l [<!ENTITY a "aaaaaaaaaa">'
        + "".join(f'<!ENTITY {chr(98 + k)} "{("&" + chr(97 + k) + ";") * 10}">' for k in range(8))
        + ']>\n<VTKFile type="UnstructuredGrid">&i;</VTKFile>\n'
    )
    external = (
        '<?xml version="1.0"?>\n<!DOCTYPE v [<!ENTITY e SYSTEM "file:///etc/passwd">]>\n'
        '<VTKFile type="UnstructuredGrid">&e;</VTKFile>\n'
    )
    legacy = (
        "# vtk DataFile Version 4.2\nfuzz\nASCII\nDATASET UNSTRUCTURED_GRID\n"
        "POINTS {points} double\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n"
        "CELLS 1 5\n4 0 1 2 3\nCELL_TYPES 1\n{cell_type}\n"
    )
    return [
        ("empty", "mesh.vtu", b"", True),
        ("garbage", "mesh.vtu", bytes(range(256)) * 8, True),
        ("xml-bomb", "mesh.vtu", bomb.encode(), True),
        ("xml-external", "mesh.vtu", external.encode(), True),
        ("not-closed", "mesh.vtu", b'<?xml version="1.0"?><VTKFile type="Unstru', True),
        ("empty-legacy", "mesh.vtk", b"", True),
        ("huge-points", "mesh.vtk", legacy.format(points=10**12, cell_type=10).encode(), True),
        ("negative-points", "mesh.vtk", legacy.format(points=-4, cell_type=10).encode(), True),
        ("cell-type", "mesh.vtk", legacy.format(points=4, cell_type=99).encode(), True),
        ("valid-tetra", "mesh.vtk", legacy.format(points=4, cell_type=10).encode(), False),
        (
            "nan-points",
            "mesh.vtk",
            legacy.format(points=4, cell_type=10).replace("1 0 0", "nan 0 0").encode(),
            True,
        ),
    ]


def _mesh_cases(rng: random.Random) -> list[Case]:
    cases: list[Case] = []
    for element in ("hex8", "tet4", "tet10"):
        number = 0
        for _ in range(5 if element == "hex8" else 3):
            for kind, make, must_fail, extras in _abaqus_operators(rng, element):
                cases.append(
                    _mesh_case(
                        f"abaqus-{element}",
                        kind,
                        number,
                        "mesh.inp",
                        make,
                        must_fail=must_fail,
                        extras=extras,
                    )
                )
                number += 1
    for number, (kind, content, must_fail) in enumerate(_ABAQUS_WHOLE):
        cases.append(
            _mesh_case(
                "abaqus",
                f"whole-{kind}",
                number,
                "mesh.inp",
                lambda c=content: c,
                must_fail=must_fail,
            )
        )
    for fmt, binary in (("gmsh22", False), ("gmsh", False), ("gmsh", True), ("gmsh22", True)):
        number = 0
        for _ in range(4 if not binary else 3):
            for kind, make, must_fail in _gmsh_operators(rng, fmt, binary):
                base = f"{fmt}-{'binary' if binary else 'ascii'}"
                cases.append(_mesh_case(base, kind, number, "mesh.msh", make, must_fail=must_fail))
                number += 1
    for fmt, binary, file in (
        ("vtk", False, "mesh.vtk"),
        ("vtu", False, "mesh.vtu"),
        ("vtk", True, "mesh.vtk"),
        ("vtu", True, "mesh.vtu"),
    ):
        number = 0
        for _ in range(3):
            for kind, make, must_fail in _gmsh_operators(rng, fmt, binary):
                base = f"{fmt}-{'binary' if binary else 'ascii'}"
                cases.append(_mesh_case(base, kind, number, file, make, must_fail=must_fail))
                number += 1
    for number, (kind, file, content, must_fail) in enumerate(_vtk_garbage()):
        cases.append(
            _mesh_case("vtk", kind, number, file, lambda c=content: c, must_fail=must_fail)
        )

    # Paths that are not mesh files.
    def special(kind: str) -> Callable[[Path], None]:
        def extras(folder: Path) -> None:
            if kind == "fifo":
                os.mkfifo(folder / "mesh.inp")
            elif kind == "dev-zero":
                (folder / "mesh.msh").symlink_to("/dev/zero")
            elif kind == "directory":
                (folder / "mesh.vtu").mkdir()
            elif kind == "link-loop":
                (folder / "mesh.inp").symlink_to(folder / "mesh.inp")

        return extras

    for number, (kind, file) in enumerate(
        [
            ("fifo", "mesh.inp"),
            ("dev-zero", "mesh.msh"),
            ("directory", "mesh.vtu"),
            ("link-loop", "mesh.inp"),
            ("missing", "mesh.msh"),
            ("suffix", "mesh.stl"),
            ("no-suffix", "mesh"),
        ]
    ):
        make: Callable[[], Any] = (
            (lambda: abaqus_text("hex8")) if kind in ("suffix", "no-suffix") else (lambda: None)
        )
        cases.append(
            _mesh_case(
                "path",
                kind,
                number,
                file,
                make,
                must_fail=True,
                extras=special(kind),
                allowed=(FileNotFoundError,) if kind in ("missing", "link-loop") else (),
                timeout=SPECIAL_FILE_TIMEOUT if kind in _SPECIAL_FILES else None,
            )
        )
    return cases


# ---------------------------------------------------------------------------------------------
# Family 3: body files


def load_and_compile(folder: Path, file: str = "body.h5") -> None:
    """Loads a body file and, when it loads, adds it to a system, compiles it and runs two
    steps."""
    import flexmbd as fm
    from flexmbd.fe import load_body

    body = load_body(folder / file)
    _finite("body nodes", body.nodes)
    _finite("body mass", body.invariants.mass)
    system = fm.System(gravity=(0, -9.81, 0))
    system.add_flexible_body(body, name="body")
    _run_steps(system.compile(), step=1e-4, steps=2)


def _members(file: Any) -> list[str]:
    names: list[str] = []
    file.visit(names.append)
    return sorted(names)


def _h5_edit(kind: str, body: str, seed: int) -> Callable[[Path], None]:
    """A damage of a saved body or results file by h5py (the member chosen by `seed`)."""

    def damage(path: Path) -> None:
        import h5py

        r = random.Random(seed)
        with h5py.File(path, "r+") as file:
            members = _members(file)
            datasets = [m for m in members if isinstance(file[m], h5py.Dataset)]
            numeric = [m for m in datasets if file[m].dtype.kind == "f" and file[m].shape]
            if kind == "delete-member":
                del file[r.choice(members)]
            elif kind == "delete-attribute":
                owner = r.choice(["", *members])
                node = file[owner] if owner else file
                if node.attrs:
                    del node.attrs[r.choice(sorted(node.attrs))]
            elif kind == "root-attribute":
                name = r.choice(["version", "format", "units", "writer", "layout", "metadata"])
                value = r.choice(
                    [
                        0,
                        2,
                        99,
                        -1,
                        "abc",
                        1.5,
                        2**63 - 1,
                        "",
                        "flexmbd-results",
                        "flexmbd-body",
                        "not json",
                        '{"length": "mm", "mass": "kg", "time": "s"}',
                        "[]",
                        "{}",
                        '{"length": "furlong"}',
                        "[" * 100_000,
                        np.zeros(3),
                    ]
                )
                file.attrs[name] = value
            elif kind == "type-attribute":
                owner = r.choice([m for m in members if "type" in file[m].attrs] or members)
                file[owner].attrs["type"] = r.choice(
                    [
                        "ndarray",
                        "dict",
                        "list",
                        "sparse",
                        "none",
                        "str",
                        "int",
                        "float",
                        "bogus",
                        "",
                        "bool",
                        "tuple",
                    ]
                )
            elif kind == "nan-fill" and numeric:
                name = r.choice(numeric)
                data = file[name][()]
                value = r.choice([math.nan, math.inf, -math.inf, 1e308, 0.0, -1.0])
                if r.random() < 0.5:
                    data = np.full_like(data, value)
                else:
                    data.flat[r.randrange(data.size)] = value
                del file[name]
                file[name] = data
            elif kind == "retype" and datasets:
                name = r.choice(datasets)
                attrs = dict(file[name].attrs)
                del file[name]
                value = r.choice(
                    [
                        "text",
                        7,
                        2.5,
                        np.zeros(0),
                        np.arange(5.0),
                        np.zeros((2, 2, 2)),
                        np.ones(3, dtype=complex),
                        np.ones(4, dtype=bool),
                        np.array([b"a", b"b"]),
                        None,
                    ]
                )
                if value is None:
                    file.create_group(name)
                else:
                    file[name] = value
                for key, item in attrs.items():
                    file[name].attrs[key] = item
            elif kind == "reshape" and datasets:
                name = r.choice([m for m in datasets if file[m].shape] or datasets)
                data = file[name][()]
                attrs = dict(file[name].attrs)
                how = r.choice(["flatten", "transpose", "extra-row", "drop-row", "scalar"])
                array = np.asarray(data)
                if how == "flatten":
                    array = array.ravel()
                elif how == "transpose":
                    array = array.T
                elif how == "extra-row" and array.ndim:
                    array = np.concatenate([array, array[:1]])
                elif how == "drop-row" and array.ndim:
                    array = array[:-1]
                elif how == "scalar" and array.size:
                    array = array.ravel()[0]
                del file[name]
                file[name] = array
                for key, item in attrs.items():
                    file[name].attrs[key] = item
            elif kind == "huge-declared" and datasets:
                name = r.choice(datasets)
                attrs = dict(file[name].attrs)
                dtype = file[name].dtype if file[name].dtype.kind in "fiu" else np.float64
                shape = r.choice([(2**31, 3), (2**40,), (2**20, 2**20)])
                del file[name]
                file.create_dataset(
                    name,
                    shape=shape,
                    dtype=dtype,
                    chunks=(1024,) + (1,) * (len(shape) - 1),
                    compression="gzip",
                )
                for key, item in attrs.items():
                    file[name].attrs[key] = item
            elif kind == "link":
                groups = [m for m in members if isinstance(file[m], h5py.Group)] or [""]
                group = file[r.choice(groups)] if groups != [""] else file
                how = r.choice(["cycle", "external", "soft-missing", "replace-external"])
                if how == "cycle":
                    group["loop"] = group
                elif how == "external":
                    group["outside"] = h5py.ExternalLink("/etc/passwd", "/x")
                elif how == "soft-missing":
                    group["dangling"] = h5py.SoftLink("/no/such/member")
                elif datasets:
                    name = r.choice(datasets)
                    del file[name]
                    file[name] = h5py.ExternalLink("other.h5", "/data")
            elif kind == "sparse":
                groups = [
                    m
                    for m in members
                    if isinstance(file[m], h5py.Group) and file[m].attrs.get("type") == "sparse"
                ]
                if not groups:
                    return
                group = file[r.choice(groups)]
                part = r.choice(["indices", "indptr", "shape"])
                data = group[part][()]
                if part == "indices" and data.size:
                    data[r.randrange(data.size)] = r.choice([10**9, -1, 2**31 - 1])
                elif part == "indptr":
                    data = data[::-1].copy() if r.random() < 0.5 else data * 1000
                else:
                    data = np.asarray(
                        r.choice([[1, 1], [-1, -1], [2**62, 2**62], [0, 0], [1, 2, 3]]),
                        dtype=np.int64,
                    )
                del group[part]
                group[part] = data
            elif kind == "records":
                value = r.choice([-1, 0, 10**12, 2**63 - 1, 3, 10**6])
                if "records" in file:
                    file["records"][0] = value
            elif kind == "text-field":
                name = r.choice(["status", "statistics", "events", "redundancy"])
                text = r.choice(
                    [
                        b"",
                        b"not json",
                        b"[" * 100_000,
                        b"\xff\xfe",
                        b"null",
                        b"42",
                        json.dumps(
                            {"state": "failed", "error": "KeyboardInterrupt", "message": "x"}
                        ).encode(),
                        json.dumps({"state": "failed", "error": "__import__"}).encode(),
                        json.dumps({"state": "complete"}).encode(),
                        json.dumps({"state": ["x"], "error": 5}).encode(),
                        json.dumps([{"time": "x", "kind": None}]).encode(),
                    ]
                )
                if name in file:
                    del file[name]
                file.create_dataset(
                    name, data=np.frombuffer(text, dtype=np.uint8), maxshape=(None,)
                )
            elif kind == "time-values":
                how = r.choice(["nan", "inf", "decreasing", "huge", "constant"])
                time = file["time"][()]
                if how == "nan":
                    time[r.randrange(len(time))] = math.nan
                elif how == "inf":
                    time[-1] = math.inf
                elif how == "decreasing":
                    time = time[::-1].copy()
                elif how == "huge":
                    time[:] = 1e308
                else:
                    time[:] = 0.0
                file["time"][...] = time
            elif kind == "shorten":
                name = r.choice(
                    [m for m in ("time", "coordinates", "energy", "reactions") if m in file]
                )
                dataset = file[name]
                if dataset.maxshape[0] is None:
                    dataset.resize(max(dataset.shape[0] - r.randint(1, 5), 0), axis=0)

    return damage


_BODY_H5_KINDS = (
    "delete-member",
    "delete-attribute",
    "root-attribute",
    "type-attribute",
    "nan-fill",
    "retype",
    "reshape",
    "huge-declared",
    "link",
    "sparse",
)


def _file_damage_cases(
    rng: random.Random,
    family: str,
    base_name: str,
    file: str,
    source: Callable[[], bytes],
    operate: Callable[[Path], None],
    h5_kinds: tuple[str, ...],
    rounds: int,
    names: tuple[str, ...],
) -> list[Case]:
    """Byte-level and h5py damages of an HDF5 file."""
    cases: list[Case] = []
    number = 0

    def add(kind: str, prepare: Callable[[Path], None]) -> None:
        nonlocal number
        cases.append(
            Case(
                name=f"{family}/{base_name}/{kind}/{number:03d}",
                family=family,
                kind=kind,
                prepare=prepare,
                operate=operate,
                names=names,
            )
        )
        number += 1

    for _ in range(rounds):
        fraction = rng.choice([0.0, 0.01, 0.1, 0.3, 0.5, 0.7, 0.9, 0.99, rng.random()])
        add("truncate", lambda f, x=fraction: _write(f / file, source()[: int(x * len(source()))]))
        seed, count, window = _seed(rng), rng.choice([1, 2, 8, 32]), rng.choice([None, 4096])
        add(
            "flip",
            lambda f, s=seed, c=count, w=window: _write(
                f / file, _flip(source(), random.Random(s), c, w)
            ),
        )
        offset = rng.random()

        def zero_block(f: Path, o: float = offset) -> None:
            data = bytearray(source())
            start = int(o * len(data))
            data[start : start + 512] = bytes(len(data[start : start + 512]))
            _write(f / file, bytes(data))

        add("zero-block", zero_block)
        for kind in h5_kinds:
            seed = _seed(rng)

            def prepare(f: Path, k: str = kind, s: int = seed) -> None:
                _write(f / file, source())
                _write(f / "other.h5", b"not hdf5")
                _h5_edit(k, base_name, s)(f / file)

            add(kind, prepare)
    return cases


def _not_hdf5_cases(
    family: str,
    file: str,
    operate: Callable[[Path], None],
    names: tuple[str, ...],
    other: Callable[[], bytes],
) -> list[Case]:
    def make(kind: str) -> Callable[[Path], None]:
        def prepare(folder: Path) -> None:
            target = folder / file
            if kind == "text":
                _write(target, "this is not an HDF5 file\n")
            elif kind == "empty":
                _write(target, b"")
            elif kind == "signature-only":
                _write(target, b"\x89HDF\r\n\x1a\n" + bytes(100))
            elif kind == "other-kind":
                _write(target, other())
            elif kind == "directory":
                target.mkdir()
            elif kind == "fifo":
                os.mkfifo(target)
            elif kind == "dev-zero":
                target.symlink_to("/dev/zero")
            elif kind == "link-loop":
                target.symlink_to(target)

        return prepare

    cases = []
    kinds = [
        "text",
        "empty",
        "signature-only",
        "other-kind",
        "directory",
        "fifo",
        "dev-zero",
        "link-loop",
        "missing",
    ]
    for number, kind in enumerate(kinds):
        cases.append(
            Case(
                name=f"{family}/path/{kind}/{number:03d}",
                family=family,
                kind=kind,
                prepare=make(kind),
                operate=operate,
                names=names,
                must_fail=True,
                allowed=(FileNotFoundError,) if kind in ("missing", "link-loop") else (),
                timeout=SPECIAL_FILE_TIMEOUT if kind in _SPECIAL_FILES else None,
            )
        )
    return cases


def _body_file_cases(rng: random.Random) -> list[Case]:
    cases: list[Case] = []
    names = ("body.h5", "body")
    for kind, rounds in (("nodal", 4), ("beam", 3), ("modal", 3)):
        cases += _file_damage_cases(
            rng,
            "body-files",
            kind,
            "body.h5",
            functools.partial(body_bytes, kind),
            load_and_compile,
            _BODY_H5_KINDS,
            rounds,
            names,
        )
    cases += _not_hdf5_cases(
        "body-files", "body.h5", load_and_compile, names, lambda: results_bytes("rigid")[0]
    )
    return cases


# ---------------------------------------------------------------------------------------------
# Family 4: results files

#: Longest a read of a results file may take (issue 28), s.
READ_LIMIT = 5.0


def read_both(folder: Path, file: str = "results.h5", base: str | None = None) -> None:
    """Reads a results file with read_results and read_results_metadata, each within
    READ_LIMIT seconds; a read that succeeds has records of one length, no more than the
    file's run wrote, with times that are finite and do not decrease."""
    import time

    import flexmbd as fm
    from flexmbd.results_file import read_results_metadata

    path = folder / file
    start = time.perf_counter()
    try:
        header = read_results_metadata(path)
    finally:
        seconds = time.perf_counter() - start
        if seconds > READ_LIMIT:
            raise WrongResult(f"read_results_metadata took {seconds:.1f} s")
    if not isinstance(header.get("records"), int) or header["records"] < 0:
        raise WrongResult(f"read_results_metadata gives records = {header.get('records')!r}")
    start = time.perf_counter()
    try:
        result = fm.read_results(path)
    finally:
        seconds = time.perf_counter() - start
        if seconds > READ_LIMIT:
            raise WrongResult(f"read_results took {seconds:.1f} s")
    count = len(result.time)
    for name in ("coordinates", "velocities", "accelerations", "multipliers"):
        if len(getattr(result, name)) != count:
            raise WrongResult(f"{name} has {len(getattr(result, name))} records, time {count}")
    if base is not None and count > results_bytes(base)[1]:
        raise WrongResult(f"{count} records read, the run wrote {results_bytes(base)[1]}")
    # What is read is right, whether the run or the file is complete or not.
    _finite("time", result.time)
    if np.any(np.diff(result.time) < 0):
        raise WrongResult("the record times decrease")


_RESULTS_H5_KINDS = (
    "delete-member",
    "delete-attribute",
    "root-attribute",
    "nan-fill",
    "retype",
    "reshape",
    "huge-declared",
    "link",
    "records",
    "text-field",
    "time-values",
    "shorten",
)


def write_to(folder: Path, target: str, protect: bool) -> None:
    """Runs a pendulum with its results written to `target` (in `folder`)."""
    import flexmbd as fm

    system = fm.System(gravity=(0, -9.81, 0))
    mass = system.add_point_mass(1.0, position=(1, 0, 0), name="bob")
    system.add_distance_joint(system.add_marker(system.ground), system.add_marker(mass))
    path = target if target.startswith("/") or not target else str(folder / target)
    protected = (str(folder / "model.yaml"),) if protect else ()
    result = fm.simulate(system, 0.003, 1e-3, results_file=path, protect=protected)
    check_result(result, 0.003)


def _results_write_cases() -> list[Case]:
    targets = [
        ("model-file", "model.yaml", True, True),
        ("body-file", "body.h5", False, True),
        ("text-file", "notes.txt", False, True),
        ("directory", "folder", False, True),
        ("missing-folder", "missing/dir/r.h5", False, True),
        ("dot", ".", False, True),
        ("empty", "", False, True),
        ("nul", "r\x00.h5", False, True),
        ("long-name", "r" * 300 + ".h5", False, True),
        ("fifo", "fifo.h5", False, True),
        ("dev-null", "/dev/null", False, True),
        ("under-a-file", "notes.txt/r.h5", False, True),
        ("fresh", "fresh.h5", False, False),
    ]

    def prepare(folder: Path) -> None:
        _write(folder / "model.yaml", "simulation: {end_time: 1, step_size: 0.1}\n")
        _write(folder / "body.h5", body_bytes("beam"))
        _write(folder / "notes.txt", "keep me\n")
        (folder / "folder").mkdir()
        os.mkfifo(folder / "fifo.h5")

    return [
        Case(
            name=f"results-files/write/{kind}/{number:03d}",
            family="results-files",
            kind=f"write-{kind}",
            prepare=prepare,
            operate=lambda folder, t=target, p=protect: write_to(folder, t, p),
            names=(Path(target).name or "results", "results_file", "file", "path"),
            must_fail=must_fail,
            timeout=SPECIAL_FILE_TIMEOUT if kind in _SPECIAL_FILES else None,
        )
        for number, (kind, target, protect, must_fail) in enumerate(targets)
    ]


def _results_file_cases(rng: random.Random) -> list[Case]:
    cases: list[Case] = []
    names = ("results.h5",)
    for kind, rounds in (("rigid", 4), ("flexible", 3)):
        cases += _file_damage_cases(
            rng,
            "results-files",
            kind,
            "results.h5",
            lambda k=kind: results_bytes(k)[0],
            lambda folder, k=kind: read_both(folder, base=k),
            _RESULTS_H5_KINDS,
            rounds,
            names,
        )
    cases += _not_hdf5_cases(
        "results-files", "results.h5", read_both, names, lambda: body_bytes("beam")
    )
    cases += _results_write_cases()
    return cases


# ---------------------------------------------------------------------------------------------
# Family 5: API calls

#: Hostile argument values.
VALUES: list[tuple[str, Callable[[], Any]]] = [
    ("none", lambda: None),
    ("str", lambda: "abc"),
    ("empty-str", lambda: ""),
    ("minus-one", lambda: -1),
    ("zero", lambda: 0),
    ("negative", lambda: -1.0),
    ("nan", lambda: math.nan),
    ("inf", lambda: math.inf),
    ("minus-inf", lambda: -math.inf),
    ("huge", lambda: 1e308),
    ("tiny", lambda: 1e-308),
    ("int-2-64", lambda: 2**64),
    ("int-minus-2-63", lambda: -(2**63)),
    ("true", lambda: True),
    ("empty-list", lambda: []),
    ("two", lambda: [1.0, 2.0]),
    ("four", lambda: [1.0, 2.0, 3.0, 4.0]),
    ("matrix", lambda: [[1.0, 2.0, 3.0]] * 3),
    ("nan-vector", lambda: [math.nan] * 3),
    ("inf-vector", lambda: [0.0, math.inf, 0.0]),
    ("array-2x2", lambda: np.ones((2, 2))),
    ("str-array", lambda: np.array(["a", "b", "c"])),
    ("dict", lambda: {"a": 1}),
    ("object", lambda: object()),
    ("bytes", lambda: b"abc"),
    ("complex", lambda: 1 + 2j),
    ("float32", lambda: np.float32(1.5)),
    ("int64", lambda: np.int64(-5)),
    ("tuple", lambda: (1, 2, 3)),
    ("lambda", lambda: lambda t: 0.0),
    ("body-id", lambda: _core_id("BodyId", 99)),
    ("marker-id", lambda: _core_id("MarkerId", 99)),
    ("object-array", lambda: np.array([None, 1, "a"], dtype=object)),
    ("nested", lambda: [[[[1.0]]]]),
    ("generator", lambda: (x for x in range(3))),
]
_BAD_NUMBERS = {"nan", "inf", "minus-inf", "nan-vector", "inf-vector"}


def _core_id(kind: str, index: int) -> Any:
    import flexmbd as fm

    return getattr(fm, kind)(index)


@dataclass
class _Scene:
    """A small valid model to call the API on: a pendulum bob, a rigid link, markers."""

    system: Any
    bob: Any
    link: Any
    pivot: Any
    bob_marker: Any
    link_marker: Any


def _scene() -> _Scene:
    import flexmbd as fm

    system = fm.System(gravity=(0, -9.81, 0))
    bob = system.add_point_mass(1.0, position=(1.0, 0.0, 0.0), name="bob")
    link = system.add_rigid_body(1.0, (1e-3, 0.1, 0.1), position=(0.0, -1.0, 0.0), name="link")
    pivot = system.add_marker(system.ground, name="pivot")
    bob_marker = system.add_marker(bob, name="bob marker")
    link_marker = system.add_marker(link, position=(0.0, 0.5, 0.0), name="link marker")
    system.add_distance_joint(pivot, bob_marker, name="rod")
    return _Scene(system, bob, link, pivot, bob_marker, link_marker)


#: method -> (valid arguments as a function of the scene, names of the parameters to replace).
_SYSTEM_CALLS: dict[str, tuple[Callable[[_Scene], dict[str, Any]], tuple[str, ...]]] = {
    "add_point_mass": (
        lambda s: {
            "mass": 2.0,
            "position": (0.0, 1.0, 0.0),
            "velocity": (0.0, 0.0, 0.0),
            "name": "extra",
        },
        ("mass", "position", "velocity", "name"),
    ),
    "add_rigid_body": (
        lambda s: {
            "mass": 1.0,
            "inertia": (0.1, 0.1, 0.1),
            "center_of_mass": (0.0, 0.0, 0.0),
            "position": (0.0, 2.0, 0.0),
            "orientation": np.eye(3),
            "velocity": (0.0, 0.0, 0.0),
            "angular_velocity": (0.0, 0.0, 1.0),
            "name": "extra",
        },
        (
            "mass",
            "inertia",
            "center_of_mass",
            "position",
            "orientation",
            "velocity",
            "angular_velocity",
            "name",
        ),
    ),
    "add_marker": (
        lambda s: {
            "body": s.link,
            "position": (0.0, 0.0, 0.0),
            "orientation": np.eye(3),
            "name": "extra",
        },
        ("body", "position", "orientation", "name"),
    ),
    "add_revolute_joint": (
        lambda s: {"marker1": s.pivot, "marker2": s.link_marker, "name": "extra"},
        ("marker1", "marker2", "name"),
    ),
    "add_spherical_joint": (
        lambda s: {"marker1": s.pivot, "marker2": s.link_marker},
        ("marker1", "marker2"),
    ),
    "add_distance_joint": (
        lambda s: {"marker1": s.bob_marker, "marker2": s.link_marker, "distance": 1.0},
        ("marker1", "marker2", "distance"),
    ),
    "add_angle_driver": (
        lambda s: {"marker1": s.pivot, "marker2": s.link_marker, "angle": 0.0},
        ("angle",),
    ),
    "add_translation_driver": (
        lambda s: {"marker1": s.pivot, "marker2": s.link_marker, "displacement": 0.0},
        ("displacement",),
    ),
    "add_point_force": (
        lambda s: {"marker": s.bob_marker, "force": (1.0, 0.0, 0.0), "frame": "global"},
        ("marker", "force", "frame"),
    ),
    "add_torque": (
        lambda s: {"marker": s.link_marker, "torque": (0.0, 0.0, 1.0), "frame": "marker"},
        ("marker", "torque", "frame"),
    ),
    "add_spring_damper": (
        lambda s: {
            "marker1": s.pivot,
            "marker2": s.link_marker,
            "stiffness": 100.0,
            "damping": 1.0,
            "rest_length": 0.5,
            "preload": 0.0,
        },
        ("stiffness", "damping", "rest_length", "preload"),
    ),
    "add_rotational_spring_damper": (
        lambda s: {
            "marker1": s.pivot,
            "marker2": s.link_marker,
            "stiffness": 10.0,
            "damping": 0.1,
            "rest_angle": 0.0,
            "preload": 0.0,
        },
        ("stiffness", "damping", "rest_angle", "preload"),
    ),
    "add_sensor": (
        lambda s: {"marker": s.bob_marker, "quantity": "position", "name": "extra"},
        ("marker", "quantity", "name"),
    ),
    "add_callback_force": (
        lambda s: {"bodies": [s.bob], "function": lambda t, q, v: np.zeros(3)},
        ("bodies", "function"),
    ),
    "add_flexible_body": (
        lambda s: {"body": _beam_body(), "position": (0.0, 3.0, 0.0), "modal_damping": None},
        (
            "body",
            "position",
            "elastic_coordinates",
            "rayleigh_damping",
            "modal_damping",
            "condense",
        ),
    ),
}

#: The item a System.add_* method adds, as the core's messages name it ("joint 2", ...).
_ITEM_KINDS = {
    "add_point_mass": "body",
    "add_rigid_body": "body",
    "add_flexible_body": "body",
    "add_marker": "marker",
    "add_revolute_joint": "joint",
    "add_spherical_joint": "joint",
    "add_distance_joint": "joint",
    "add_angle_driver": "joint",
    "add_translation_driver": "joint",
    "add_point_force": "force",
    "add_torque": "force",
    "add_spring_damper": "force",
    "add_rotational_spring_damper": "force",
    "add_callback_force": "force",
    "add_sensor": "sensor",
}

_CALLBACKS: list[tuple[str, Callable[[], Any]]] = [
    ("raises", lambda: lambda t, q, v: 1 / 0),
    ("wrong-shape", lambda: lambda t, q, v: np.zeros(7)),
    ("nan", lambda: lambda t, q, v: np.full(3, math.nan)),
    ("string", lambda: lambda t, q, v: "force"),
    ("none", lambda: lambda t, q, v: None),
    ("wrong-arity", lambda: lambda t: np.zeros(3)),
    ("keyboard", lambda: _raise(KeyboardInterrupt)),
    ("system-exit", lambda: _raise(SystemExit)),
    ("recursion", lambda: _recurse),
    ("huge", lambda: lambda t, q, v: np.full(3, 1e308)),
]


def _raise(kind: type[BaseException]) -> Callable[..., Any]:
    def function(*args: Any) -> Any:
        raise kind()

    return function


def _recurse(*args: Any) -> Any:
    return _recurse(*args)


@functools.cache
def _beam_body() -> Any:
    from flexmbd import fe

    nodes, elements = fe.straight_beam(0.5, 2)
    return fe.build_body(
        nodes,
        elements,
        _material(),
        section=fe.Section.circle(0.01),
        reference="clamped",
        reference_nodes=[0],
    )


def _system_call(
    method: str, parameter: str, make_value: Callable[[], Any]
) -> Callable[[Path], None]:
    def operate(folder: Path) -> None:
        scene = _scene()
        arguments = _SYSTEM_CALLS[method][0](scene)
        arguments[parameter] = make_value()
        getattr(scene.system, method)(**arguments)
        _run_steps(scene.system)

    return operate


def _solver_call(
    kind: str, parameter: str, make_value: Callable[[], Any]
) -> Callable[[Path], None]:
    def operate(folder: Path) -> None:
        import flexmbd as fm

        value = make_value()
        if kind == "GeneralizedAlpha":
            solver = fm.GeneralizedAlpha(**{parameter: value})
        else:
            solver = fm.ExplicitSolver(**{parameter: value})
        _run_steps(_scene().system, solver=solver)

    return operate


_SIMULATE_PARAMETERS = (
    "end_time",
    "step_size",
    "start_time",
    "output_interval",
    "initial_state",
    "initial_conditions",
    "solver",
    "progress",
    "results_file",
    "metadata",
    "keep_in_memory",
    "protect",
)


def _simulate_call(parameter: str, make_value: Callable[[], Any]) -> Callable[[Path], None]:
    def operate(folder: Path) -> None:
        import flexmbd as fm

        arguments: dict[str, Any] = {"end_time": 0.003, "step_size": 1e-3}
        value = make_value()
        arguments[parameter] = value
        if parameter in ("metadata", "keep_in_memory", "protect"):
            arguments["results_file"] = str(folder / "r.h5")
        result = fm.simulate(_scene().system, **arguments)
        end = arguments["end_time"]
        check_result(result, end if isinstance(end, float) else None)

    return operate


_TIME_FUNCTIONS: dict[str, tuple[dict[str, Any], tuple[str, ...]]] = {
    "Constant": ({"value": 1.0}, ("value",)),
    "Polynomial": ({"coefficients": [0.0, 1.0, 0.5]}, ("coefficients",)),
    "Harmonic": (
        {"amplitude": 1.0, "frequency": 2.0, "phase": 0.0, "offset": 0.0},
        ("amplitude", "frequency", "phase", "offset"),
    ),
    "Spline": ({"times": [0.0, 0.5, 1.0], "values": [0.0, 1.0, 0.0]}, ("times", "values")),
    "UserFunction": ({"function": math.sin, "derivatives": False}, ("function", "derivatives")),
}


def _time_function_call(
    kind: str, parameter: str, make_value: Callable[[], Any]
) -> Callable[[Path], None]:
    def operate(folder: Path) -> None:
        import flexmbd as fm

        arguments = dict(_TIME_FUNCTIONS[kind][0])
        arguments[parameter] = make_value()
        function = getattr(fm, kind)(**arguments)
        for t in (0.0, 0.25, 1.0):
            _finite(f"{kind}({t})", function(t))
            if hasattr(function, "derivatives") and callable(function.derivatives):
                _finite(f"{kind}.derivatives({t})", function.derivatives(t))
        scene = _scene()
        scene.system.add_angle_driver(scene.pivot, scene.link_marker, function)
        _run_steps(scene.system)

    return operate


@functools.cache
def _scene_result() -> tuple[Any, Any]:
    """A finished run of the scene plus a deformable beam, and its model."""
    import flexmbd as fm

    scene = _scene()
    beam = scene.system.add_flexible_body(_beam_body(), position=(0.0, 3.0, 0.0), name="beam")
    scene.system.add_fixed_joint(
        scene.system.add_marker(scene.system.ground, position=(0.0, 3.0, 0.0)),
        scene.system.add_node_marker(beam, 1),
        name="clamp",
    )
    scene.system.add_sensor(scene.bob_marker, "velocity", name="bob velocity")
    model = scene.system.compile()
    return fm.simulate(model, 0.003, 1e-3), model


_RESULT_METHODS = (
    "position",
    "velocity",
    "euler_parameters",
    "orientation",
    "angular_velocity",
    "elastic_coordinates",
    "elastic_velocities",
    "node_displacements",
    "node_positions",
    "stresses",
    "section_forces",
    "deflection",
    "reaction",
    "reaction_force",
    "reaction_torque",
    "joint_multipliers",
    "sensor",
    "state",
)

_ITEMS: list[tuple[str, Callable[[], Any]]] = [
    ("index-99", lambda: 99),
    ("index-minus-1", lambda: -1),
    ("index-2-70", lambda: 2**70),
    ("unknown-name", lambda: "nonexistent"),
    ("empty-name", lambda: ""),
    ("none", lambda: None),
    ("float", lambda: 1.5),
    ("nan", lambda: math.nan),
    ("bool", lambda: True),
    ("body-id-99", lambda: _core_id("BodyId", 99)),
    ("joint-id", lambda: _core_id("JointId", 0)),
    ("list", lambda: [0, 1]),
    ("ground", lambda: 0),
    ("rigid-bob", lambda: "bob"),
    ("numpy-int", lambda: np.int64(1)),
    ("numpy-uint-huge", lambda: np.uint64(2**64 - 1)),
]


def _result_call(method: str, make_item: Callable[[], Any], extra: Any) -> Callable[[Path], None]:
    def operate(folder: Path) -> None:
        result, _ = _scene_result()
        item = make_item()
        if method == "state":
            state = result.state(item)
            _finite("state coordinates", state.coordinates)
            return
        if method == "deflection":
            values = result.deflection(item, extra if extra is not None else 2)
        elif method in ("node_displacements", "node_positions"):
            values = getattr(result, method)(item, extra)
        else:
            values = getattr(result, method)(item)
        _finite(f"Result.{method}", values)

    return operate


def _node_call(method: str, nodes: Any) -> Callable[[Path], None]:
    def operate(folder: Path) -> None:
        result, _ = _scene_result()
        if method == "deflection":
            values = result.deflection("beam", nodes)
        else:
            values = getattr(result, method)("beam", nodes)
        _finite(f"Result.{method}", values)

    return operate


_STATE_CALLS = (
    "with_position",
    "with_velocity",
    "with_elastic_coordinates",
    "with_elastic_velocities",
    "simulate-from",
    "construct-time",
    "construct-coordinates",
    "of_model-time",
)


def _state_call(call: str, body: Any, make_value: Callable[[], Any]) -> Callable[[Path], None]:
    def operate(folder: Path) -> None:
        import flexmbd as fm

        result, model = _scene_result()
        state = result.state()
        value = make_value()
        if call.startswith("with_"):
            changed = getattr(state, call)(body, value)
            _finite("state coordinates", changed.coordinates)
            fm.simulate(model, changed.time + 2e-3, 1e-3, initial_state=changed)
        elif call == "simulate-from":
            fm.simulate(model, 0.01, 1e-3, initial_state=value)
        elif call == "construct-time":
            changed = fm.State(value, state.coordinates, state.velocities, layout=state.layout)
            fm.simulate(model, 10.0, 1e-3, initial_state=changed)
        elif call == "construct-coordinates":
            changed = fm.State(0.0, value, state.velocities, layout=state.layout)
            fm.simulate(model, 2e-3, 1e-3, initial_state=changed)
        else:
            fm.State.of_model(model, value)

    return operate


def _other_call(what: str, make_value: Callable[[], Any]) -> Callable[[Path], None]:
    def operate(folder: Path) -> None:
        import flexmbd as fm
        from flexmbd import fe

        value = make_value()
        if what in ("BodyId", "MarkerId", "JointId", "ForceId", "SensorId"):
            getattr(fm, what)(value)
        elif what == "gravity":
            system = fm.System(gravity=value)
            mass = system.add_point_mass(1.0)
            system.add_marker(mass)
            _run_steps(system)
        elif what.startswith("Material."):
            arguments = {"young_modulus": 1e9, "poisson_ratio": 0.3, "density": 1000.0}
            arguments[what.split(".")[1]] = value
            material = fe.Material(**arguments)
            nodes, elements = fe.straight_beam(1.0, 2)
            body = fe.build_body(nodes, elements, material, section=fe.Section.circle(0.01))
            _finite("body mass", body.invariants.mass)
        elif what.startswith("box."):
            arguments = {"lengths": (1.0, 0.1, 0.1), "divisions": (2, 1, 1), "element": "hex8"}
            arguments[what.split(".")[1]] = value
            fe.shapes.box(**arguments)
        elif what.startswith("build_body."):
            mesh = box_mesh("hex8", (2, 1, 1))
            arguments: dict[str, Any] = {"node_sets": mesh.node_sets}
            arguments[what.split(".")[1]] = value
            body = fe.build_body(mesh.nodes, mesh.elements, _material(), **arguments)
            _finite("body mass", body.invariants.mass)
        elif what == "equilibrium.time":
            _, model = _scene_result()
            fm.equilibrium(model, value)

    return operate


#: Fixed hostile values of the parameters whose bare NumPy errors issue 28 turned into typed
#: ones (node index lists given None, NaN, 2**70, strings, floats, bools or non-lists; str
#: options given arrays; box divisions of bytes): (what, label, value), run by
#: `_other_call`. Each is wrong input: it must fail with a typed error naming the parameter.
#: They draw nothing from the seed's generator: the cases drawn before them stay the same.
_FIXED_OTHER_VALUES: list[tuple[str, str, Callable[[], Any]]] = [
    ("build_body.reference_nodes", "none", lambda: None),
    ("build_body.reference_nodes", "nan-list", lambda: [math.nan]),
    ("build_body.reference_nodes", "int-2-70-list", lambda: [2**70]),
    ("build_body.reference_nodes", "str-list", lambda: ["0"]),
    ("build_body.reference_nodes", "float-list", lambda: [0.5]),
    ("build_body.reference_nodes", "bool-list", lambda: [True]),
    ("build_body.reference_nodes", "bytes", lambda: b"ab"),
    ("build_body.reference_nodes", "object", lambda: object()),
    ("build_body.interfaces", "none", lambda: None),
    ("build_body.interfaces", "int", lambda: 3),
    ("build_body.interfaces", "str", lambda: "x0"),
    ("build_body.interfaces", "nan-node", lambda: [[math.nan]]),
    ("build_body.interfaces", "int-2-70-node", lambda: [[2**70]]),
    ("build_body.interfaces", "float-node", lambda: ["x0", [1.5]]),
    ("build_body.interfaces", "none-node", lambda: ["x0", None]),
    ("build_body.interfaces", "str-node", lambda: [["a"]]),
    ("build_body.node_sets", "float-set", lambda: {"x0": [0.5]}),
    ("build_body.node_sets", "list", lambda: [[0, 1]]),
    ("build_body.mass", "str-array", lambda: np.array(["consistent", "lumped"])),
    ("build_body.modes", "str-array", lambda: np.array(["free-free", "external"])),
    ("build_body.reference", "str-array", lambda: np.array(["none", "clamped"])),
    ("build_body.beam_theory", "int-array", lambda: np.array([1, 2])),
    ("build_body.interface_kind", "str-array", lambda: np.array(["rbe2", "rbe3"])),
    ("build_body.precision", "int", lambda: 64),
    ("box.divisions", "bytes", lambda: b"abc"),
    ("box.divisions", "str", lambda: "abc"),
    ("box.divisions", "bools", lambda: (True, True, True)),
    ("box.divisions", "two", lambda: (2, 1)),
    ("box.divisions", "fraction", lambda: (1.5, 1, 1)),
]

#: Elastic arrays of another length than the beam's 12 elastic coordinates (issue 28: an
#: empty one was taken for "undeformed"): `System.add_flexible_body` must refuse them.
_FIXED_ELASTIC_VALUES: list[tuple[str, str, Callable[[], Any]]] = [
    ("elastic_coordinates", "empty-list", lambda: []),
    ("elastic_coordinates", "three", lambda: [0.0, 0.0, 0.0]),
    ("elastic_velocities", "empty-array", lambda: np.zeros(0)),
    ("elastic_velocities", "thirteen", lambda: np.zeros(13)),
]


def _api_cases(rng: random.Random) -> list[Case]:
    cases: list[Case] = []
    counter = {"n": 0}

    def add(
        base: str,
        kind: str,
        operate: Callable[[Path], None],
        names: tuple[str, ...],
        must_fail: bool = False,
    ) -> None:
        cases.append(
            Case(
                name=f"api/{base}/{kind}/{counter['n']:03d}",
                family="api",
                kind=kind,
                prepare=lambda folder: None,
                operate=operate,
                names=names,
                must_fail=must_fail,
            )
        )
        counter["n"] += 1

    def values(count: int) -> list[tuple[str, Callable[[], Any]]]:
        return rng.sample(VALUES, count)

    for method, (_, parameters) in _SYSTEM_CALLS.items():
        for parameter in parameters:
            for label, make in values(3 if method != "add_flexible_body" else 2):
                must_fail = label in _BAD_NUMBERS and parameter not in ("name", "frame", "quantity")
                add(
                    method,
                    f"{parameter}={label}",
                    _system_call(method, parameter, make),
                    (parameter, _ITEM_KINDS[method]),
                    must_fail,
                )
        if method == "add_callback_force":
            for label, make in _CALLBACKS:
                add(
                    method,
                    f"function={label}",
                    _system_call(method, "function", make),
                    ("function", "callback", "force"),
                )
    for kind in ("GeneralizedAlpha", "ExplicitSolver"):
        parameters = sorted(_ALPHA_VALUES if kind == "GeneralizedAlpha" else _EXPLICIT_VALUES)
        for parameter in rng.sample(parameters, 10):
            for label, make in values(2):
                add(
                    kind,
                    f"{parameter}={label}",
                    _solver_call(kind, parameter, make),
                    (parameter,),
                    label in _BAD_NUMBERS,
                )
    for parameter in _SIMULATE_PARAMETERS:
        for label, make in values(4):
            must_fail = label in _BAD_NUMBERS and parameter in (
                "end_time",
                "step_size",
                "start_time",
                "output_interval",
            )
            add(
                "simulate",
                f"{parameter}={label}",
                _simulate_call(parameter, make),
                (parameter,),
                must_fail,
            )
    for label, make in _CALLBACKS[:6]:
        add("simulate", f"progress={label}", _simulate_call("progress", make), ("progress",))
    for kind, (_, parameters) in _TIME_FUNCTIONS.items():
        for parameter in parameters:
            for label, make in values(3):
                add(
                    kind,
                    f"{parameter}={label}",
                    _time_function_call(kind, parameter, make),
                    (parameter, kind),
                    label in _BAD_NUMBERS,
                )
    for method in _RESULT_METHODS:
        for label, make in rng.sample(_ITEMS, 3):
            add(
                "Result",
                f"{method}({label})",
                _result_call(method, make, None),
                (method, "body", "joint", "sensor", "record", "index", "item", "state"),
            )
    for method in ("node_displacements", "node_positions", "deflection"):
        for label, nodes in (
            ("missing", [99999]),
            ("negative", [-1]),
            ("huge", [2**70]),
            ("float", [1.5]),
            ("strings", ["a"]),
            ("nested", [[1, 2]]),
            ("empty", []),
        ):
            add("Result", f"{method}(beam, {label})", _node_call(method, nodes), ("node", "nodes"))
    for call in _STATE_CALLS:
        body = "beam" if "elastic" in call else "link"
        for label, make in values(3):
            add(
                "State",
                f"{call}={label}",
                _state_call(call, body, make),
                ("state", "time", "coordinates", "position", "velocit", "elastic", "initial"),
            )
        for label, item in (("unknown", "nonexistent"), ("ground", 0), ("rigid", "bob")):
            if call.startswith("with_"):
                add(
                    "State",
                    f"{call}({label})",
                    _state_call(call, item, lambda: [0.0, 0.0, 0.0]),
                    ("body", "bob", "ground", "nonexistent", "position", "velocit", "elastic"),
                )
    others = [
        "BodyId",
        "MarkerId",
        "JointId",
        "ForceId",
        "SensorId",
        "gravity",
        "Material.young_modulus",
        "Material.poisson_ratio",
        "Material.density",
        "box.lengths",
        "box.divisions",
        "box.element",
        "build_body.reference",
        "build_body.modes",
        "build_body.mode_count",
        "build_body.reference_nodes",
        "build_body.interfaces",
        "build_body.mass",
        "equilibrium.time",
    ]
    for what in others:
        for label, make in values(2):
            parameter = what.split(".")[-1]
            add(
                "other",
                f"{what}={label}",
                _other_call(what, make),
                (parameter, what.split(".")[0], "index", "time"),
                label in _BAD_NUMBERS and what.startswith(("Material", "gravity")),
            )
    for what, label, make in _FIXED_OTHER_VALUES:
        add(
            "other",
            f"{what}={label}",
            _other_call(what, make),
            (what.split(".")[-1], what.split(".")[0]),
            must_fail=True,
        )
    for parameter, label, make in _FIXED_ELASTIC_VALUES:
        add(
            "add_flexible_body",
            f"{parameter}={label}",
            _system_call("add_flexible_body", parameter, make),
            (parameter,),
            must_fail=True,
        )
    return cases


# ---------------------------------------------------------------------------------------------
# The corpus


def cases(seed: int = SEED) -> list[Case]:
    """Every case of the corpus for `seed`, in a fixed order; names are unique."""
    generators = {
        "model-files": _model_file_cases,
        "meshes": _mesh_cases,
        "body-files": _body_file_cases,
        "results-files": _results_file_cases,
        "api": _api_cases,
    }
    out: list[Case] = []
    for family in FAMILIES:
        out += generators[family](random.Random(f"{family}:{seed}"))
    names = [case.name for case in out]
    if len(set(names)) != len(names):
        raise RuntimeError("the fuzz corpus has duplicate case names")
    return out


def _self_test_cases() -> list[Case]:
    """Cases with a known outcome each, for the test of the worker and its supervisor."""
    import ctypes
    import signal
    import time

    from flexmbd.errors import InvalidParameterError

    def crash(folder: Path) -> None:
        ctypes.string_at(0)

    def sleep(folder: Path) -> None:
        time.sleep(60)

    def deaf(folder: Path) -> None:
        # A hang the alarm cannot end (as in C code that does not return to Python).
        signal.pthread_sigmask(signal.SIG_BLOCK, [signal.SIGALRM])
        time.sleep(60)

    def internal(folder: Path) -> None:
        raise KeyError("x")

    def panic(folder: Path) -> None:
        raise type("PanicException", (BaseException,), {})("index out of bounds")

    def lose(folder: Path) -> None:
        (folder / "input.txt").unlink()

    def unnamed(folder: Path) -> None:
        raise InvalidParameterError("")

    def named(folder: Path) -> None:
        raise InvalidParameterError("the parameter 'mass' must be positive")

    def nothing(folder: Path) -> None:
        pass

    def write_input(folder: Path) -> None:
        _write(folder / "input.txt", "keep me")

    cases = [
        ("ok", nothing, False, "ok"),
        ("error", named, False, "error"),
        ("unnamed", unnamed, False, "unnamed"),
        ("wrong", nothing, True, "wrong"),
        ("internal", internal, False, "internal"),
        ("panic", panic, False, "panic"),
        ("lost-file", lose, False, "lost-file"),
        ("crash", crash, False, "crash"),
        ("after-crash", nothing, False, "ok"),
        ("hang", sleep, False, "hang"),
        ("deaf-hang", deaf, False, "hang"),
        ("after-hang", nothing, False, "ok"),
    ]
    return [
        Case(
            name=f"self-test/{kind}/{expected}/{number:03d}",
            family="self-test",
            kind=kind,
            prepare=write_input,
            operate=operate,
            names=("mass",),
            must_fail=must_fail,
        )
        for number, (kind, operate, must_fail, expected) in enumerate(cases)
    ]


def all_cases(seed: int = SEED) -> list[Case]:
    """The corpus and the self-test cases (family "self-test"), which the workers run too."""
    return cases(seed) + _self_test_cases()


def seed_from_environment() -> int:
    """The seed of the run: FLEXMBD_FUZZ_SEED, or :data:`SEED`."""
    return int(os.environ.get("FLEXMBD_FUZZ_SEED", SEED))
