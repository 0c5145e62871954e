"""State-space models of the motion linearized about a state, with named inputs and outputs:

    lin = fm.linearize(system, state, inputs=[fm.PointLoad(tip, (0, 0, 1), name="F_z")],
                       outputs=[fm.NodeDisplacement("blade", 21, (0, 0, 1), name="w_tip")])
    ss = lin.state_space()                  # A, B, C, D with x = [z, z_dot]
    h = ss.frequency_response([1.0, 2.0])   # (frequencies, outputs, inputs), complex

The state is x = (z, z_dot), the independent coordinates of the linearization (q = q0 +
basis z, :func:`flexmbd.linearize`): M z_dd + D z_dot + K z = B_z u. An input is a load of
unit amplitude (a force or a torque at a marker, along a direction); its column of B is the
generalized force of that load at the state, basis^T Q, found from the equations of motion of
the system with the load added (its building calls replayed with the load). Outputs are
linear functions of the coordinates: the elastic displacement of a node of a deformable body
(body axes), the position of a body's frame origin (global), an elastic coordinate.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import _core
from ._checks import integer, number, numbers_array, value_text
from .errors import ArgumentTypeError, InvalidParameterError, ResonanceWarning
from .quantities import body_entry
from .rotation import angular_velocity

Array = NDArray[np.float64]


@dataclass(frozen=True)
class PointLoad:
    """An input: a unit force (or, `kind="torque"`, a torque) at `marker` (a marker's id or
    name) along `direction` (global axes, or the marker's with `frame="marker"`)."""

    marker: Any
    direction: ArrayLike
    kind: str = "force"
    frame: str = "global"
    name: str | None = None

    def label(self) -> str:
        marker = (
            self.marker
            if isinstance(self.marker, str)
            else getattr(self.marker, "index", self.marker)
        )
        return self.name or f"{self.kind} at marker {marker}"


@dataclass(frozen=True)
class NodeDisplacement:
    """An output: the elastic displacement of node `node` (a node id) of the deformable body
    `body` (name, index or id) along `direction` (body axes)."""

    body: Any
    node: int
    direction: ArrayLike
    name: str | None = None

    def label(self) -> str:
        return self.name or f"displacement of node {self.node} of body {self.body}"


@dataclass(frozen=True)
class BodyPosition:
    """An output: the position of the frame origin of `body` along `direction` (global)."""

    body: Any
    direction: ArrayLike
    name: str | None = None

    def label(self) -> str:
        return self.name or f"position of body {self.body}"


@dataclass(frozen=True)
class ElasticCoordinate:
    """An output: elastic coordinate `index` (an integer, 0: the first) of the deformable
    body `body`."""

    body: Any
    index: int
    name: str | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "index", integer(self.index, "ElasticCoordinate index"))

    def label(self) -> str:
        return self.name or f"elastic coordinate {self.index} of body {self.body}"


@dataclass
class StateSpace:
    """x_dot = A x + B u, y = C x + D u with x = (z, z_dot) (see the module); `inputs`,
    `outputs` name the columns of B and the rows of C."""

    a: Array
    b: Array
    c: Array
    d: Array
    inputs: list[str]
    outputs: list[str]

    def frequency_response(self, frequencies: ArrayLike) -> NDArray[np.complex128]:
        """H(i w) = C (i w I - A)^-1 B + D at `frequencies` (Hz): (frequencies, outputs,
        inputs). Where i w is an eigenvalue of A within :data:`RESONANCE_DISTANCE` (relative
        to it: an undamped resonance, within round-off) or i w I - A is exactly singular,
        the response is unbounded: inf, with a `ResonanceWarning` naming the frequencies.
        A small reciprocal condition number alone is no resonance: a stiff FE model's A
        has one of 1e-17 at every frequency (the stiffest modes far above the slowest), and
        its solves are accurate there."""
        f = numbers_array(frequencies, "frequencies").ravel()
        bad = np.flatnonzero(~np.isfinite(f))
        if len(bad):
            raise InvalidParameterError(
                f"frequencies must be finite, got {f[bad[0]]} at index {bad[0]}",
                item="frequencies",
            )
        import warnings

        import scipy.linalg as sla

        n = self.a.shape[0]
        out = np.empty((len(f), self.c.shape[0], self.b.shape[1]), dtype=complex)
        resonant = []
        eigenvalues = None
        for k, fk in enumerate(f):
            s = 2j * np.pi * fk
            try:
                with warnings.catch_warnings(record=True) as caught:
                    warnings.simplefilter("always", sla.LinAlgWarning)
                    solved = sla.solve(s * np.eye(n) - self.a, self.b)
            except np.linalg.LinAlgError:
                solved = None  # exactly singular
            # An ill-conditioned solve is a resonance only where i w is an eigenvalue of A
            # (looked for once, and only then: the eigenvalues cost as much as a few solves).
            near = solved is None or not np.all(np.isfinite(solved))
            if not near and any(issubclass(w.category, sla.LinAlgWarning) for w in caught):
                if eigenvalues is None:
                    eigenvalues, left, right = sla.eig(self.a, left=True, right=True)
                    # How much each mode is driven by the inputs and seen by the outputs:
                    # |C v| |w^H B| / (|v| |w| |C| |B|), from its right and left vectors.
                    seen = np.linalg.norm(self.c @ right, axis=0) / np.linalg.norm(right, axis=0)
                    driven = np.linalg.norm(left.conj().T @ self.b, axis=1)
                    driven /= np.linalg.norm(left, axis=0)
                    scale = max(np.linalg.norm(self.c) * np.linalg.norm(self.b), 1e-300)
                    excited = seen * driven / scale > UNEXCITED
                distance = np.abs(eigenvalues - s)
                # (A mode the inputs do not drive, or the outputs do not see, is no
                # resonance of this response: the solve is right there, a lateral bending
                # mode under a vertical force gave inf for -0.029049.)
                close = distance <= RESONANCE_DISTANCE * np.abs(eigenvalues)
                near = bool(np.any(close & excited))
            if near:
                resonant.append(float(fk))
                out[k] = complex(np.inf, 0.0)
                continue
            out[k] = self.c @ solved + self.d
        if resonant:
            shown = ", ".join(f"{v:.6g}" for v in resonant[:5])
            which = (
                "is an undamped eigenfrequency"
                if len(resonant) == 1
                else "are undamped eigenfrequencies"
            )
            warnings.warn(
                f"frequency_response: {shown} Hz {which} of the model (i w an eigenvalue of A "
                "within round-off): the response is unbounded there, returned as inf",
                ResonanceWarning,
                stacklevel=2,
            )
        return out


#: Distance of i w from an eigenvalue lambda of A, relative to |lambda|, within which
#: :meth:`StateSpace.frequency_response` takes w for an undamped resonance (the response
#: there, about 1 / (2 distance) times the static one, is round-off).
RESONANCE_DISTANCE = 1e-9

#: Participation |C v| |w^H B| / (|v| |w| |C| |B|) of a mode (right and left eigenvectors v,
#: w of A) at or below which :meth:`StateSpace.frequency_response` does not take it for a
#: resonance of the response (round-off of a mode the inputs do not drive or the outputs do
#: not see).
UNEXCITED = 1e-8


def _unit(direction: ArrayLike, what: str) -> Array:
    d = numbers_array(direction, f"{what} direction").ravel()
    norm = float(np.linalg.norm(d))
    if d.shape != (3,) or not np.isfinite(norm) or norm == 0.0:
        raise InvalidParameterError(
            f"{what}: direction must be a non-zero 3-vector, got {d}", item=f"{what} direction"
        )
    return d / norm


def _output_body(layout: dict[str, Any], output: Any) -> tuple[int, dict[str, Any]]:
    """The index and layout entry of the body of `output`: a body id, index or name (a
    marker's or a joint's id is refused, not read as the body of its index); the ground
    only for outputs of deformable bodies, which it is not (it does not move)."""
    body = output.body
    if isinstance(body, _core.BodyId | str):
        pass
    elif isinstance(body, _core.MarkerId | _core.JointId | _core.ForceId | _core.SensorId):
        kind = type(body).__name__[:-2].lower()
        raise ArgumentTypeError(
            f"{output.label()}: body must be a body (a BodyId, index or name), got {body!r}, "
            f"a {kind}'s id: pass the body (a marker's body is its first argument to "
            "add_marker)",
            item=repr(body),
        )
    else:
        integer(body, f"{output.label()}: body")
    index, entry = body_entry(layout, body)
    if entry["kind"] == "ground" and isinstance(output, BodyPosition):
        raise InvalidParameterError(
            f"{output.label()}: body {entry['name']!r} is the ground, which does not move: "
            "its position is no output",
            item=entry["name"],
        )
    return index, entry


def output_rows(model: Any, outputs: list[Any]) -> Array:
    """The rows dy/dq (outputs x coordinates) of linear outputs of the coordinates."""
    from .system import _node_index, elastic_basis

    layout = model.describe()
    flexible = model.flexible_bodies
    rows = np.zeros((len(outputs), model.coordinate_count))
    for k, output in enumerate(outputs):
        index, entry = _output_body(layout, output)
        start = entry["offset"]
        if isinstance(output, BodyPosition):
            rows[k, start : start + 3] = _unit(output.direction, output.label())
            continue
        if index not in flexible:
            raise InvalidParameterError(
                f"{output.label()}: body {entry['name']!r} is not a deformable body",
                item=entry["name"],
            )
        data = flexible[index]
        elastic = start + 7  # after the position and the Euler parameters of the frame
        if isinstance(output, ElasticCoordinate):
            count = entry["count"] - 7
            if not 0 <= output.index < count:
                raise InvalidParameterError(
                    f"{output.label()}: the body has {count} elastic coordinates (indices 0 "
                    f"to {count - 1})",
                    item="index",
                )
            rows[k, elastic + output.index] = 1.0
        elif isinstance(output, NodeDisplacement):
            node = _node_index(data, output.node, output.label())
            d = data.dofs_per_node
            basis = elastic_basis(data)[node * d : node * d + 3].toarray()
            direction = _unit(output.direction, output.label())
            rows[k, elastic : elastic + basis.shape[1]] = direction @ basis
        else:
            raise ArgumentTypeError(
                f"unknown output {value_text(output)}: a NodeDisplacement, BodyPosition or "
                "ElasticCoordinate",
                item="outputs",
            )
    return rows


def input_forces(system: Any, state: Any, inputs: list[Any]) -> Array:
    """The generalized forces Q (coordinates x inputs) of unit loads at `state`: the
    difference of the residuals of the equations of motion with and without each load."""
    from ._boundary import Constant
    from .system import System, _rebuilt

    if not isinstance(system, System):
        raise InvalidParameterError(
            "inputs need a flexmbd.System (the loads are added to it)", item="inputs"
        )
    args = (state.time, state.coordinates, state.velocities, state.accelerations)
    base = system.compile()
    markers = base.describe()["markers"]
    nq = base.coordinate_count
    reference = base.evaluate(*args, state.multipliers)["residual"][:nq]
    columns = np.zeros((nq, len(inputs)))
    for k, load in enumerate(inputs):
        if not isinstance(load, PointLoad):
            raise ArgumentTypeError(
                f"unknown input {value_text(load)}: a flexmbd.PointLoad", item="inputs"
            )
        if load.kind not in ("force", "torque"):
            raise InvalidParameterError(
                f"{load.label()}: kind must be 'force' or 'torque', got {value_text(load.kind)}",
                item="kind",
            )
        unit = _unit(load.direction, load.label())
        method = "add_point_force" if load.kind == "force" else "add_torque"
        marker = _load_marker(load, markers)
        call = (method, (marker, [Constant(float(v)) for v in unit]), {"frame": load.frame})
        loaded = _rebuilt(type(system), (*system.building_calls, call)).compile()
        residual = loaded.evaluate(*args, state.multipliers)["residual"][:nq]
        columns[:, k] = reference - residual  # the residual holds -Q
    return columns


def _load_marker(load: PointLoad, markers: list[dict[str, Any]]) -> Any:
    """The marker id of `load`: its id, or the id of the marker of its name (outputs take
    names too; a name reached System.add_point_force, whose error named that call), else an
    error naming the PointLoad."""
    if isinstance(load.marker, _core.MarkerId):
        return load.marker
    if isinstance(load.marker, str):
        for index, entry in enumerate(markers):
            if entry.get("name") == load.marker:
                return _core.MarkerId(index)
        from .errors import UnknownItemError

        names = ", ".join(repr(e["name"]) for e in markers if e.get("name"))
        raise UnknownItemError(
            f"PointLoad: no marker named {load.marker!r} (markers: {names or 'none'})",
            item=load.marker,
        )
    raise ArgumentTypeError(
        f"PointLoad: marker must be a marker (its MarkerId or name), got "
        f"{value_text(load.marker)} ({type(load.marker).__name__})",
        item="marker",
    )


def body_shapes(
    model: Any, shape: NDArray[np.complex128], coordinates: Any = None
) -> dict[str, dict[str, Any]]:
    """A mode shape (in the coordinates q) per body: for every moving body its reference
    motion, ``translation`` (3, global) and ``rotation`` (3, the small rotation 2 G(p) dp of
    its Euler parameters, body axes; point masses have none), and for deformable bodies the
    elastic ``displacements`` of their nodes (nodes x 3, body axes). `coordinates`: those of
    the state the shape is about (a `State`, as ``linear.state``, or its coordinates); the
    rotation is read with its Euler parameters p. Default: the model's initial coordinates,
    right only for a linearization about them (:func:`flexmbd.linearize_at_rest`): a rod
    built tilted by 60 degrees that hangs straight at its equilibrium had its swing about x
    reported as one about (0, 0.5, 0.87)."""
    from .state import State
    from .system import elastic_basis

    layout = model.describe()
    flexible = model.flexible_bodies
    if isinstance(coordinates, State):
        coordinates = coordinates.coordinates
    q0 = (
        np.asarray(model.initial_coordinates, dtype=float)
        if coordinates is None
        else numbers_array(coordinates, "coordinates").ravel()
    )
    if q0.shape != (model.coordinate_count,) or not np.all(np.isfinite(q0)):
        raise InvalidParameterError(
            f"body_shapes: coordinates must be {model.coordinate_count} finite numbers (the "
            f"model's coordinates), got shape {q0.shape}",
            item="coordinates",
        )
    mode = np.asarray(shape)
    if mode.shape != (model.coordinate_count,) or not np.all(np.isfinite(mode)):
        raise InvalidParameterError(
            f"body_shapes: the shape must be {model.coordinate_count} finite numbers (one per "
            f"coordinate of the model, as a linearization's shapes), got shape {mode.shape}"
            + ("" if mode.shape != (model.coordinate_count,) else " with values not finite"),
            item="shape",
        )
    shapes: dict[str, dict[str, Any]] = {}
    for index, entry in enumerate(layout["bodies"]):
        if entry["kind"] == "ground":
            continue
        start = entry["offset"]
        part: dict[str, Any] = {"translation": shape[start : start + 3]}
        if entry["kind"] != "point_mass":
            p, dp = q0[start + 3 : start + 7], shape[start + 3 : start + 7]
            part["rotation"] = angular_velocity(p, dp, frame="body")
        if index in flexible:
            data = flexible[index]
            count = entry["count"] - 7
            u = elastic_basis(data) @ shape[start + 7 : start + 7 + count]
            part["displacements"] = np.asarray(u).reshape(-1, data.dofs_per_node)[:, :3]
        shapes[entry["name"]] = part
    return shapes


def mode_result(
    linear: Any, model: Any, mode: int, frames: int = 24, amplitude: float = 0.05
) -> Any:
    """One period of oscillating mode `mode` (0: the lowest) of `linear` about its state as a
    :class:`flexmbd.Result` of `frames` records (time: the phase in periods), for the plots,
    the animation and the ParaView series: q = q0 + a Re(phi e^(i 2 pi t)), `amplitude` the
    largest change of a reference coordinate (the elastic deformation is scaled by the
    animation itself)."""
    from .analysis import LinearizedSystem, _model

    if not isinstance(linear, LinearizedSystem):
        raise ArgumentTypeError(
            f"linear must be a flexmbd LinearizedSystem (fm.linearize), got "
            f"{value_text(linear)} ({type(linear).__name__})",
            item="linear",
        )
    model = _model(model)
    mode = integer(mode, "mode")
    frames = integer(frames, "frames")
    if frames < 1:
        raise InvalidParameterError(f"frames must be at least 1, got {frames}", item="frames")
    amplitude = number(amplitude, "amplitude")
    if amplitude <= 0.0:
        raise InvalidParameterError(
            f"amplitude must be above zero, got {amplitude:g}", item="amplitude"
        )
    if model.coordinate_count != linear.basis.shape[0]:
        raise InvalidParameterError(
            f"model has {model.coordinate_count} coordinates, the linearization "
            f"{linear.basis.shape[0]}: pass the model that was linearized",
            item="model",
        )
    from .result import Result

    frequencies, _, shapes = linear.oscillating()
    if len(frequencies) == 0:
        raise InvalidParameterError(
            f"mode index {mode}: the linearization has no oscillating modes (its eigenvalues "
            "are all real: overdamped, diverging or free motions)",
            item="mode",
        )
    if not 0 <= mode < len(frequencies):
        raise InvalidParameterError(
            f"mode index {mode} (0: the lowest): the linearization has {len(frequencies)} "
            f"oscillating modes (indices 0 to {len(frequencies) - 1})",
            item="mode",
        )
    phi = shapes[:, mode]
    layout = model.describe()
    reference = np.zeros(model.coordinate_count, dtype=bool)
    for entry in layout["bodies"]:
        if entry["kind"] != "ground":
            reference[entry["offset"] : entry["offset"] + min(entry["count"], 7)] = True
    peak = np.max(np.abs(phi[reference])) if np.any(reference) else 0.0
    if peak == 0.0:
        peak = float(np.max(np.abs(phi))) or 1.0
    phi = phi * (amplitude / peak)
    phase = np.arange(frames) / frames
    q = linear.state.coordinates[None, :] + np.real(
        phi[None, :] * np.exp(2j * np.pi * phase)[:, None]
    )
    nc = model.constraint_count
    raw = {
        "time": phase,
        "coordinates": q,
        "velocities": np.zeros_like(q),
        "accelerations": np.zeros_like(q),
        "multipliers": np.zeros((frames, nc)),
        "constraint_violation": np.zeros(frames),
        "statistics": {"mode": mode, "frequency": float(frequencies[mode])},
        "reactions": np.zeros((frames, len(layout["joints"]) * 6)),
        "sensors": np.zeros((frames, 0)),
        "energy": np.zeros((frames, 3)),
    }
    return Result(raw, layout, flexible=model.flexible_bodies)
