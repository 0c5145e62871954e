"""Plots of a :class:`flexmbd.Result` with matplotlib (off screen, no window is ever opened).

:func:`plot_result` draws the quantities named in a small string syntax, usable from a command
line, and saves them as PNG, SVG or PDF (by the file suffix). The functions per plot kind draw
into a given matplotlib ``Axes`` (or a new figure) and return it.

Quantity names
--------------
===========================  =================================================================
``energy``                   kinetic, potential and total energy (J), and in a second panel
                             the balance with the work of the drivers and forces (work done
                             on the model) or the drift E(t) - E(0) (none)
``drift``                    the drift (change) of the total energy only
``balance``                  E(t) - E(0), the work of the drivers and of the forces and
                             dampers, and their difference (J)
``violation``                largest |C(q, t)| of the constraint equations per record
``joints``                   angles (rad) and slides (m) of the joints that move
``bodies``                   positions of the origins of all moving bodies, one panel each
``position:BODY``            position of a body frame origin (m, global), x, y, z
``velocity:BODY``            its velocity (m/s, global)
``angular-velocity:BODY``    angular velocity of a body (rad/s, global axes)
``elastic:BODY``             elastic coordinates q_f of a deformable body (nodal or modal)
``deflection:BODY``          elastic displacement of the node that moves most (m, body axes),
                             and the largest |u| over all nodes
``deflection:BODY:NODE``     elastic displacement of node NODE (a node id of the mesh)
``stress:BODY``              largest von Mises stress over the nodes of a solid body (Pa);
                             for beams, the largest axial force and bending moment
``reaction:JOINT``           reaction force (N) and torque (N m) of a joint, in the axes of
                             its second marker, two panels
``reactions``                magnitudes of the reaction forces (and torques) of all joints
                             but the drivers
``efforts``                  driving torques (N m) of the angle drivers and actuators and
                             forces (N) of the translation drivers and actuators, signed,
                             one panel per unit
``sensor:SENSOR``            the values of a sensor
===========================  =================================================================

BODY, JOINT and SENSOR are names (as given to ``add_*(..., name=...)``) or indices.
Unknown quantity kinds raise :class:`flexmbd.InvalidParameterError`; unknown items
:class:`flexmbd.UnknownItemError`; both name what is known.
"""

from __future__ import annotations

import functools
import os
import re
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ._checks import id_text
from .errors import InvalidParameterError, UnknownItemError
from .quantities import (
    JOINT_COORDINATES,
    SENSOR_UNITS,
    cumulative_integral,
    deformable,
    driver_power,
    force_work,
    joint_coordinates,
    resolve_item,
    with_unit,
)

Array = NDArray[np.float64]

#: Quantity kinds that take no item.
PLAIN_QUANTITIES = (
    "energy",
    "drift",
    "balance",
    "violation",
    "joints",
    "bodies",
    "reactions",
    "efforts",
)
#: Quantity kinds that take an item after a colon.
ITEM_QUANTITIES = (
    "position",
    "velocity",
    "angular-velocity",
    "elastic",
    "deflection",
    "stress",
    "reaction",
    "sensor",
)
#: Image formats of the saved figures, by suffix.
IMAGE_SUFFIXES = (".png", ".svg", ".pdf")

_AXES = ("x", "y", "z")


def _new_axes(rows: int = 1, size: tuple[float, float] | None = None) -> list[Any]:
    """A new figure (not registered with pyplot: no window, no global state) with `rows`
    panels sharing the time axis."""
    from matplotlib.figure import Figure

    figure = Figure(figsize=size or (7.0, 2.2 + 2.0 * rows), layout="constrained")
    axes = figure.subplots(rows, 1, sharex=True, squeeze=False)[:, 0]
    return list(axes)


def _axes(ax: Any) -> Any:
    return _new_axes()[0] if ax is None else ax


def _with_records(function: Callable[..., Any]) -> Callable[..., Any]:
    """A plot function of a result that refuses a result without records (a run refused at
    its start): plot_energy_balance raised a bare IndexError, plot_energy drew nothing."""

    @functools.wraps(function)
    def plot(result: Any, *args: Any, **kwargs: Any) -> Any:
        if len(result.time) == 0:
            raise InvalidParameterError("the result has no records to plot", item="result")
        return function(result, *args, **kwargs)

    return plot


def _plain(text: str) -> str:
    """`text` (item names in it) as matplotlib draws it literally: a "$" escaped (a name
    "arm $\\frac{1}$" was a mathtext ParseSyntaxException), a leading "_" behind a zero-width
    space (a joint named "_aux" was left out of the legend, as matplotlib hides such labels).
    Idempotent: a label escaped once (two plots into one axes) is not escaped again."""
    text = re.sub(r"(?<!\\)\$", r"\\$", text)
    return "\u200b" + text if text.startswith("_") else text


#: Labels matplotlib gives to lines drawn without one (hidden from legends: kept so).
_UNLABELLED = re.compile(r"_child\d+")


def _finish(
    ax: Any, ylabel: str, title: str, legend: bool = True, flatten_round_off: bool = True
) -> Any:
    # Values that are constant up to round-off are drawn flat, not magnified into noise.
    values = [np.asarray(line.get_ydata(), dtype=float) for line in ax.get_lines()]
    values = [v[np.isfinite(v)] for v in values if v.size]
    linear = ax.get_yscale() == "linear"
    if flatten_round_off and linear and values and all(v.size for v in values):
        low = min(float(v.min()) for v in values)
        high = max(float(v.max()) for v in values)
        floor = 1e-9 * max(1.0, abs(low), abs(high))
        if high - low < floor:
            middle = 0.5 * (low + high)
            ax.set_ylim(middle - floor, middle + floor)
    ax.set_xlabel("time (s)")
    ax.set_ylabel(_plain(ylabel))
    ax.set_title(_plain(title), fontsize="medium")
    ax.grid(True, alpha=0.3)
    for line in ax.get_lines():
        label = line.get_label()
        if not _UNLABELLED.fullmatch(label):
            line.set_label(_plain(label))
    handles, _ = ax.get_legend_handles_labels()
    if legend and handles:
        _legend(ax, len(handles))
    return ax


def _legend(ax: Any, count: int) -> None:
    """A legend beside the axes (right of them, never over the curves)."""
    size = "small" if count <= 6 else "x-small"
    columns = 1 if count <= 12 else 2
    ax.legend(
        fontsize=size,
        loc="upper left",
        bbox_to_anchor=(1.01, 1.0),
        borderaxespad=0.0,
        ncols=columns,
        frameon=False,
        handlelength=1.5,
    )


def _item_name(result: Any, kind: str, item: object) -> str:
    """The name of a body, joint or sensor given by name, index or id."""
    entries = result.layout[kind]
    if isinstance(item, str):
        return item
    index = int(getattr(item, "index", item))  # type: ignore[call-overload]
    if 0 <= index < len(entries):
        return str(entries[index]["name"])
    return str(item)


# Energy and constraints ------------------------------------------------------------------------
#: Largest |C(q, t)| (m or rad) that counts as round-off: the overview draws the constraint
#: violation only above it (and says so in a note otherwise).
VIOLATION_ROUND_OFF = 1e-10


@_with_records
def plot_energy(result: Any, ax: Any = None) -> Any:
    """Kinetic, potential (gravity, springs; strain in a curve of its own for models with
    deformable bodies) and total energy (J) over time."""
    ax = _axes(ax)
    ax.plot(result.time, result.kinetic_energy, label="kinetic")
    strain = result.strain_energy
    if result.flexible and np.all(np.isfinite(strain)):
        ax.plot(
            result.time, result.potential_energy - strain, label="potential\n(gravity, springs)"
        )
        ax.plot(result.time, strain, label="strain")
    else:
        ax.plot(
            result.time, result.potential_energy, label="potential\n(gravity, springs,\nstrain)"
        )
    ax.plot(result.time, result.total_energy, "k", lw=1.5, label="total")
    return _finish(ax, "energy (J)", "Energy")


def _driven(result: Any) -> tuple[bool, bool]:
    """(the model has drivers, forces do work on it): the recorded power of the forces no
    potential accounts for is not zero (in results files written before it was recorded:
    the model has forces other than spring-dampers)."""
    layout = result.layout
    drivers = any(joint["type"] in _EFFORTS for joint in layout["joints"])
    power = result.nonconservative_power
    if len(power) and np.all(np.isnan(power)):
        forces = any("spring-damper" not in force["type"] for force in layout["forces"])
    else:
        forces = bool(np.any(power[np.isfinite(power)] != 0.0))
    return drivers, forces


@_with_records
def plot_energy_drift(result: Any, ax: Any = None) -> Any:
    """Drift of the total energy E(t) - E(0) (J); the title gives the largest |drift|
    relative to the largest kinetic energy. In a model with drivers or applied forces, whose
    work changes E, the panel is called the change of the total energy instead."""
    ax = _axes(ax)
    drift = result.total_energy - result.total_energy[0] if len(result.time) else result.time
    ax.plot(result.time, drift, "k")
    largest = float(np.max(np.abs(drift))) if len(drift) else 0.0
    reference = float(np.max(np.abs(result.kinetic_energy))) if len(drift) else 0.0
    driven = any(_driven(result))
    if driven:
        title = f"Change of the total energy (work done): largest {largest:.3g} J"
    else:
        title = f"Energy drift: largest {largest:.3g} J"
    if reference > 0.0 and not driven:
        title += f" ({largest / reference:.2g} x largest kinetic energy)"
    return _finish(ax, "E(t) - E(0) (J)", title, flatten_round_off=False)


@_with_records
def plot_energy_balance(result: Any, ax: Any = None) -> Any:
    """The energy balance of a model that work is done on: the change of the total energy
    E(t) - E(0), the work of the drivers (:func:`flexmbd.quantities.driver_work`), the work
    of the forces no potential accounts for (:func:`flexmbd.quantities.force_work`: loads,
    actuators, callback forces, dampers and structural damping), and their difference, what
    none accounts for (the numerical dissipation of the integrator) (J). The work is
    integrated over the records: the title says when its error (estimated from every other
    record) is large, as when the records are too few."""
    ax = _axes(ax)
    drivers, forces = _driven(result)
    time = np.asarray(result.time)
    change = result.total_energy - result.total_energy[0]
    power = np.zeros(len(time))
    ax.plot(time, change, label="E(t) - E(0)")
    if drivers:
        power = power + driver_power(result)
        ax.plot(
            time, cumulative_integral(time, driver_power(result)), "--", label="work of the drivers"
        )
    recorded = not np.all(np.isnan(result.nonconservative_power))
    if forces and recorded:
        power = power + np.nan_to_num(result.nonconservative_power)
        ax.plot(time, force_work(result), ":", label="work of the forces\nand dampers")
    work = cumulative_integral(time, power)
    # The error of the trapezoidal work, from the sum over every other record (Richardson).
    coarse = cumulative_integral(time[::2], power[::2])
    uncertain = float(np.max(np.abs(work[::2] - coarse))) / 3.0 if len(coarse) > 2 else 0.0
    rest = change - work
    ax.plot(time, rest, "k", lw=1.5, label="difference")
    reference = max(float(np.max(np.abs(work))), float(np.max(np.abs(change))))
    largest = float(np.max(np.abs(rest)))
    title = f"Energy balance: largest difference {largest:.3g} J"
    if reference > 0.0:
        title += f" ({largest / reference:.2g} x work)"
    if uncertain > 0.1 * largest and uncertain > 1e-6 * reference:
        title += f"\n(the work integrated over the records: +- {uncertain:.2g} J)"
    if forces and not recorded:
        title += "\n(the forces' work is not in this file: written before it was recorded)"
    return _finish(ax, "energy (J)", title, flatten_round_off=False)


@_with_records
def plot_constraint_violation(result: Any, ax: Any = None) -> Any:
    """Largest |C(q, t)| of the constraint equations per record, on a log scale when it
    spans decades; values below 1e-8 of the largest (round-off) are drawn at that floor, not
    as spikes towards zero."""
    ax = _axes(ax)
    violation = np.asarray(result.constraint_violation, dtype=float)
    largest = float(np.max(violation)) if violation.size else 0.0
    if largest > 0.0:
        floor = max(largest * 1e-8, np.finfo(float).tiny)
        ax.plot(result.time, np.maximum(violation, floor), "k")
        ax.set_yscale("log")
        ax.set_ylim(floor, largest * 2.0)
    else:
        ax.plot(result.time, violation, "k")
    title = f"Constraint violation: largest {largest:.2g}"
    if largest <= VIOLATION_ROUND_OFF:
        title += " (round-off)"
    return _finish(ax, "max |C| (m or rad)", title)


# Bodies ----------------------------------------------------------------------------------------
BODY_QUANTITIES: dict[str, tuple[str, str]] = {
    "position": ("position (m)", "Position of"),
    "velocity": ("velocity (m/s)", "Velocity of"),
    "angular-velocity": ("angular velocity (rad/s)", "Angular velocity of"),
    "elastic": ("elastic coordinate", "Elastic coordinates of"),
}
"""Body quantities: name -> (axis label, title)."""


@_with_records
def plot_body(result: Any, body: object, quantity: str = "position", ax: Any = None) -> Any:
    """Time history of a body quantity: "position" or "velocity" of the body frame origin
    (global), "angular-velocity" (global axes) or "elastic" (the elastic coordinates of a
    deformable body; a legend up to 10 of them)."""
    if quantity not in BODY_QUANTITIES:
        raise InvalidParameterError(
            f"unknown body quantity {quantity!r}; known: {', '.join(BODY_QUANTITIES)}",
            item=quantity,
        )
    values = {
        "position": result.position,
        "velocity": result.velocity,
        "angular-velocity": result.angular_velocity,
        "elastic": result.elastic_coordinates,
    }[quantity](body)
    ax = _axes(ax)
    name = _item_name(result, "bodies", body)
    if quantity == "elastic":
        many = values.shape[1] > 10
        for k in range(values.shape[1]):
            ax.plot(result.time, values[:, k], lw=0.8 if many else 1.5, label=f"q_f[{k}]")
        _finish(ax, BODY_QUANTITIES[quantity][0], f"Elastic coordinates of {name}", not many)
        return ax
    for k, axis in enumerate(_AXES):
        ax.plot(result.time, values[:, k], label=axis)
    label, title = BODY_QUANTITIES[quantity]
    return _finish(ax, label, f"{title} {name}")


def _moving_bodies(result: Any) -> list[str]:
    return [b["name"] for b in result.layout["bodies"] if b["kind"] != "ground"]


@_with_records
def plot_bodies(
    result: Any,
    bodies: Sequence[object] | None = None,
    quantity: str = "position",
    axes: Any = None,
) -> list[Any]:
    """:func:`plot_body` for several bodies (all moving bodies if None), one panel each (new
    figure if `axes` is None); returns the Axes."""
    chosen = list(_moving_bodies(result) if bodies is None else bodies)
    if not chosen:
        raise UnknownItemError("the model has no moving bodies to plot")
    axes = _new_axes(len(chosen)) if axes is None else list(np.ravel(axes))
    for body, ax in zip(chosen, axes, strict=True):
        plot_body(result, body, quantity, ax)
    return axes


@_with_records
def plot_deflections(result: Any, body: object, node: int | None = None, ax: Any = None) -> Any:
    """Elastic displacement of a node of a deformable body relative to its frame (m, body
    axes): of node `node` (a node id of the mesh), or, if None, of the node whose largest
    |u| over the run is the largest; with the largest |u| over all nodes per record
    (dashed)."""
    _, name, data = deformable(result, body)
    u = result.node_displacements(body)
    magnitude = np.linalg.norm(u, axis=2)
    if node is None:
        index = int(np.argmax(magnitude.max(axis=0))) if magnitude.size else 0
    else:
        index = _node_of(data, node)
    node_id = int(np.asarray(data.node_ids)[index])
    ax = _axes(ax)
    for k, axis in enumerate(_AXES):
        ax.plot(result.time, u[:, index, k], label=f"u_{axis}, node {node_id}")
    ax.plot(result.time, magnitude.max(axis=1), "k--", lw=1.0, label="largest |u| of all nodes")
    return _finish(ax, "elastic displacement (m)", f"Deflection of {name} (body axes)")


def _node_of(data: Any, node: int) -> int:
    """Index of the node with id `node` in a body's mesh."""
    ids = np.asarray(data.node_ids)
    hits = np.flatnonzero(ids == node)
    if len(hits) == 0:
        raise UnknownItemError(
            f"the body has no node with id {id_text(node)}; ids {ids.min()} .. {ids.max()}",
            item=id_text(node),
        )
    return int(hits[0])


@_with_records
def plot_stress(result: Any, body: object, axes: Any = None) -> list[Any]:
    """Largest von Mises stress over the nodes of the solid and shell elements (for shells,
    the largest of their top, middle and bottom surfaces: `Result.von_mises`) of a deformable
    body (Pa) per record; for a body of beams, the largest axial force |N| (N) and bending moment
    sqrt(M_y^2 + M_z^2) (N m) over the element ends, two panels. Returns the Axes."""
    _, _, data = deformable(result, body)
    kinds = ("von-mises",) if _has_solids(data) else ("axial", "bending")
    axes = _new_axes(len(kinds)) if axes is None else list(np.ravel(axes))
    for kind, ax in zip(kinds, axes, strict=True):
        _plot_stress_panel(result, body, kind, ax)
    return axes


def _stress_kinds(result: Any, body: object, data: Any) -> tuple[str, ...]:
    """The stress panels of a body: "von-mises" (solids), or "axial" and "bending" (beams),
    without the axial force when it is round-off next to the bending moments (less than 1e-8
    of the largest moment over the body's size)."""
    if _has_solids(data):
        return ("von-mises",)
    sections = np.asarray(result.section_forces(body))
    axial = float(np.max(np.abs(sections[..., 0]), initial=0.0))
    bending = float(np.max(np.hypot(sections[..., 4], sections[..., 5]), initial=0.0))
    nodes = np.asarray(data.nodes, dtype=float)
    size = max(float(np.ptp(nodes, axis=0).max()), 1e-300)
    if bending > 0.0 and axial <= 1e-8 * bending / size:
        return ("bending",)
    return ("axial", "bending")


def _has_solids(data: Any) -> bool:
    return any(kind != "beam2" for kind in data.elements)


def _plot_stress_panel(result: Any, body: object, kind: str, ax: Any) -> Any:
    """One panel of :func:`plot_stress`: "von-mises", "axial" or "bending"."""
    _, name, _ = deformable(result, body)
    n = len(result.time)
    if kind == "von-mises":
        largest = result.von_mises(body).reshape(n, -1).max(axis=1)
        ax.plot(result.time, largest, "k")
        return _finish(ax, "von Mises stress (Pa)", f"Largest von Mises stress in {name}")
    sections = result.section_forces(body)  # (n, beams, 2, 6)
    if kind == "axial":
        ax.plot(result.time, np.abs(sections[..., 0]).reshape(n, -1).max(axis=1), "k")
        return _finish(ax, "|N| (N)", f"Largest axial force in {name}")
    bending = np.hypot(sections[..., 4], sections[..., 5]).reshape(n, -1).max(axis=1)
    ax.plot(result.time, bending, "k")
    return _finish(ax, "|M| (N m)", f"Largest bending moment in {name}")


# Joint coordinates -----------------------------------------------------------------------------
#: A time history whose range is below this fraction of its size (and 1e-12 absolute) is
#: constant up to round-off: the overview leaves it out.
CONSTANT_TOLERANCE = 1e-9


def _moves(values: Array) -> bool:
    values = np.asarray(values, dtype=float)
    if values.size == 0:
        return False
    spread = float(np.max(np.ptp(values.reshape(len(values), -1), axis=0)))
    return spread > CONSTANT_TOLERANCE * max(1e-3, float(np.max(np.abs(values))))


def _moving_coordinates(result: Any, kind: str) -> list[tuple[str, Array]]:
    return [
        (name, values)
        for name, k, values, _ in joint_coordinates(result)
        if k == kind and _moves(values)
    ]


@_with_records
def plot_joint_coordinates(result: Any, kind: str = "angle", ax: Any = None) -> Any:
    """The coordinates of the joints (:func:`flexmbd.quantities.joint_coordinates`) that
    move: `kind` "angle" (rad, continued over turns) or "slide" (m), one curve each."""
    if kind not in ("angle", "slide"):
        raise InvalidParameterError(f"kind must be 'angle' or 'slide', got {kind!r}", item=kind)
    ax = _axes(ax)
    for name, values in _moving_coordinates(result, kind):
        ax.plot(result.time, values, label=name)
    if kind == "angle":
        return _finish(ax, "angle (rad)", "Joint angles")
    return _finish(ax, "slide (m)", "Joint slides")


# Joints and sensors ----------------------------------------------------------------------------
@_with_records
def plot_reaction(result: Any, joint: object, kind: str = "force", ax: Any = None) -> Any:
    """Reaction force (N) or torque (N m), `kind` "force" or "torque", of a joint on the body
    of its second marker, in that marker's axes: x, y, z components."""
    if kind not in ("force", "torque"):
        raise InvalidParameterError(f"kind must be 'force' or 'torque', got {kind!r}", item=kind)
    values = result.reaction_force(joint) if kind == "force" else result.reaction_torque(joint)
    ax = _axes(ax)
    for k, axis in enumerate(_AXES):
        ax.plot(result.time, values[:, k], label=axis)
    name = _item_name(result, "joints", joint)
    unit = "N" if kind == "force" else "N m"
    return _finish(ax, f"{kind} ({unit})", f"Reaction {kind} of {name} (marker axes)")


def _reaction_joints(result: Any) -> list[str]:
    """The joints whose reactions the overview draws: all but the drivers (whose efforts have
    a panel of their own)."""
    return [j["name"] for j in result.layout["joints"] if j["type"] not in _EFFORTS]


@_with_records
def plot_reactions(
    result: Any, joints: Sequence[object] | None = None, kind: str = "force", ax: Any = None
) -> Any:
    """Magnitudes of the reaction forces (or torques) of several joints (all but the drivers
    if None), one curve each."""
    if kind not in ("force", "torque"):
        raise InvalidParameterError(f"kind must be 'force' or 'torque', got {kind!r}", item=kind)
    chosen = _reaction_joints(result) if joints is None else list(joints)
    if not chosen:
        raise UnknownItemError("the model has no joints to plot")
    ax = _axes(ax)
    for joint in chosen:
        values = result.reaction_force(joint) if kind == "force" else result.reaction_torque(joint)
        ax.plot(
            result.time, np.linalg.norm(values, axis=1), label=_item_name(result, "joints", joint)
        )
    unit = "N" if kind == "force" else "N m"
    return _finish(ax, f"|{kind}| ({unit})", f"Reaction {kind}s (magnitudes)")


#: A reaction force (N) or torque (N m) at most this fraction of the other (times 1 m) is
#: round-off next to it (an angle driver's force, a spherical joint's torque): not drawn.
REACTION_ROUND_OFF = 1e-8


def _above_round_off(value: float, other: float) -> bool:
    """Whether a reaction's largest |value| is more than round-off next to the other kind's."""
    return value > REACTION_ROUND_OFF * other


def _largest(values: Array) -> float:
    return float(np.max(np.abs(values), initial=0.0))


def _torques_matter(result: Any) -> bool:
    """Whether any joint but a driver transmits a reaction torque above round-off next to
    the joints' reaction forces."""
    joints = _reaction_joints(result)
    if not joints:
        return False
    torque = max(_largest(result.reaction_torque(j)) for j in joints)
    force = max(_largest(result.reaction_force(j)) for j in joints)
    return _above_round_off(torque, force) and torque > 0.0


#: Driver types, the unit of their efforts and what the effort is.
_EFFORTS = {"angle driver": ("N m", "torque"), "translation driver": ("N", "force")}
#: The sensor quantities of joint actuators' efforts, and the unit of each.
_ACTUATORS = {"actuator torque (N m)": "N m", "actuator force (N)": "N"}


def _drivers(result: Any, kind: str) -> list[str]:
    return [j["name"] for j in result.layout["joints"] if j["type"] == kind]


def _actuators(result: Any, unit: str) -> list[str]:
    """The effort sensors of the joint actuators whose efforts are in `unit`."""
    return [
        s["name"] for s in result.layout["sensors"] if _ACTUATORS.get(s.get("quantity")) == unit
    ]


@_with_records
def plot_efforts(result: Any, kind: str = "angle driver", ax: Any = None) -> Any:
    """The signed efforts of the drivers of `kind` ("angle driver": torques, N m;
    "translation driver": forces, N) and of the joint actuators in the same unit, one curve
    each."""
    if kind not in _EFFORTS:
        raise InvalidParameterError(
            f"kind must be 'angle driver' or 'translation driver', got {kind!r}", item=kind
        )
    unit, effort = _EFFORTS[kind]
    names = _drivers(result, kind)
    actuators = _actuators(result, unit)
    if not names and not actuators:
        raise UnknownItemError(f"the model has no {kind}s", item=kind)
    ax = _axes(ax)
    for name in names:
        ax.plot(result.time, result.driver_effort(name), label=name)
    for name in actuators:
        ax.plot(result.time, np.asarray(result.sensor(name))[:, 0], label=name)
    what = f"{kind}s" + (" and actuators" if actuators else "")
    return _finish(ax, f"{effort} ({unit})", f"Driving {effort}s ({what})")


def _effort_kinds(result: Any) -> list[str]:
    return [
        kind
        for kind, (unit, _) in _EFFORTS.items()
        if _drivers(result, kind) or _actuators(result, unit)
    ]


@_with_records
def plot_sensor(result: Any, sensor: object, ax: Any = None) -> Any:
    """Values of a sensor (an orientation sensor: its nine matrix entries), with the unit of
    its quantity."""
    values = result.sensor(sensor)
    values = values.reshape(len(result.time), -1)
    ax = _axes(ax)
    name = _item_name(result, "sensors", sensor)
    if values.shape[1] == 1:
        labels = [name]
    else:
        labels = _AXES if values.shape[1] == 3 else [f"[{k // 3}, {k % 3}]" for k in range(9)]
    for k in range(values.shape[1]):
        ax.plot(result.time, values[:, k], label=labels[k])
    entry = next((s for s in result.layout["sensors"] if s["name"] == name), None)
    quantity = entry["quantity"] if entry is not None else "value"
    ylabel = quantity if "(" in quantity else with_unit(quantity, SENSOR_UNITS.get(quantity, ""))
    return _finish(ax, ylabel.replace("_", " "), f"Sensor {name}")


# Sampling of the records -----------------------------------------------------------------------
#: Records per period below which a vibration is drawn as a zig-zag (or aliased): the note of
#: :func:`sampling_notes` asks for at least this many (Nyquist's 2, with a margin).
RECORDS_PER_PERIOD = 5
#: Modal amplitude (relative to the largest) above which a mode counts as present.
MODE_PRESENT = 0.01
#: Motion of the modal coordinates over the run (their standard deviation, relative to their
#: largest value) below which a body counts as at rest: round-off, no vibration to sample.
STILL = 1e-9
#: Largest number of elastic coordinates whose modes :func:`sampling_notes` computes.
SAMPLING_MODES_LIMIT = 600


def _present_frequency(result: Any, body: int, data: Any) -> float | None:
    """The highest frequency (Hz) of the modes of a deformable body that move in the records:
    the modes of the body's stiffness and mass matrices whose vibration amplitude (the rms of
    the modal rate over the angular frequency) is at least :data:`MODE_PRESENT` of the
    largest modal amplitude (standard deviation over the run); None if there is none, the
    body has too many coordinates or the eigenproblem fails."""
    import scipy.linalg

    count = int(data.elastic_coordinate_count)
    if not 0 < count <= SAMPLING_MODES_LIMIT:
        return None
    stiffness = data.invariants.k_ff
    mass = data.invariants.m_ff
    stiffness = stiffness.toarray() if hasattr(stiffness, "toarray") else np.asarray(stiffness)
    mass = mass.toarray() if hasattr(mass, "toarray") else np.asarray(mass)
    try:
        eigenvalues, shapes = scipy.linalg.eigh(stiffness, mass)
    except (np.linalg.LinAlgError, ValueError):
        return None
    frequencies = np.sqrt(np.maximum(eigenvalues, 0.0)) / (2.0 * np.pi)
    elastic = frequencies > 1e-6 * max(float(frequencies.max()), 1e-300)
    if not np.any(elastic):
        return None
    projection = mass @ shapes[:, elastic]
    modal = np.asarray(result.elastic_coordinates(body)) @ projection
    rates = np.asarray(result.elastic_velocities(body)) @ projection
    largest = float(modal.std(axis=0).max())
    # A body at rest (a static run, or one started in equilibrium) moves by round-off only,
    # against which any mode would count as present.
    if largest <= STILL * float(np.abs(modal).max()) or largest <= 0.0:
        return None
    # A mode vibrating at its own frequency w moves its coordinate by about rms(rate) / w; a
    # mode that only follows the slow loads (quasi-statically) has a much smaller rate.
    vibration = np.sqrt(np.mean(rates**2, axis=0)) / (2.0 * np.pi * frequencies[elastic])
    present = vibration >= MODE_PRESENT * largest
    if not np.any(present):
        return None
    return float(frequencies[elastic][present].max())


def sampling_notes(result: Any) -> list[str]:
    """Notes on deformable bodies whose vibrations the records under-sample: for each, the
    highest frequency of its modes that move in the records (an estimate from the body's own
    modes, :func:`_present_frequency`) if the records are fewer than
    :data:`RECORDS_PER_PERIOD` per period of it, with the output interval that resolves it."""
    if len(result.time) < 3 or not result.flexible:
        return []
    interval = float(np.median(np.diff(result.time)))
    if interval <= 0.0:
        return []
    notes = []
    for index, data in sorted(result.flexible.items()):
        frequency = _present_frequency(result, index, data)
        if frequency is None or frequency * interval * RECORDS_PER_PERIOD <= 1.0:
            continue
        name = result.layout["bodies"][index]["name"]
        notes.append(
            f"{name}: a mode at {frequency:.4g} Hz moves, but the records are {interval:.3g} s "
            f"apart ({1.0 / (frequency * interval):.2g} per period): its curves are "
            f"under-sampled (zig-zag or aliased); an output interval of at most "
            f"{1.0 / (RECORDS_PER_PERIOD * frequency):.2g} s resolves it"
        )
    return notes


def overview_notes(result: Any) -> list[str]:
    """What the overview (:func:`default_quantities`) leaves out, and the
    :func:`sampling_notes`."""
    notes = []
    left = _loose_bodies(result)[OVERVIEW_BODIES:]
    if left:  # (six free bodies showed four, without a word of the other two)
        shown = ", ".join(left[:3]) + (", ..." if len(left) > 3 else "")
        notes.append(f"{len(left)} more moving bodies not drawn ({shown}): position:NAME draws one")
    violation = np.asarray(result.constraint_violation)
    if violation.size and float(violation.max()) <= VIOLATION_ROUND_OFF:
        notes.append(
            f"constraint violation at most {float(violation.max()):.2g} (round-off): not drawn"
        )
    return notes + sampling_notes(result)


# Quantity names --------------------------------------------------------------------------------
def _flexible_names(result: Any) -> list[str]:
    return [
        b["name"]
        for i, b in enumerate(result.layout["bodies"])
        if b["kind"] == "flexible" and i in result.flexible
    ]


#: Bodies whose positions the overview draws at most (the others: ``position:NAME``).
OVERVIEW_BODIES = 4


def _loose_bodies(result: Any) -> list[str]:
    """Moving bodies whose frames move and that no joint with a coordinate holds (free
    bodies, bodies on spherical or fixed joints): their positions are in the overview."""
    layout = result.layout
    held = {
        int(layout["markers"][m]["body"])
        for j in layout["joints"]
        if j["type"] in JOINT_COORDINATES
        for m in j["markers"]
    }
    return [
        b["name"]
        for i, b in enumerate(layout["bodies"])
        if b["kind"] != "ground" and i not in held and _moves(result.position(i))
    ]


def default_quantities(result: Any) -> list[str]:
    """The quantities of the overview, chosen by what the model has: the energy (and its
    balance with the drivers' work, or its drift), the constraint violation if above
    round-off, the joints' angles and slides that move, the positions of moving bodies no
    such joint holds (up to :data:`OVERVIEW_BODIES`), the drivers' and actuators' efforts,
    the reactions, the deflection and stress of every deformable body and every other
    sensor."""
    quantities = ["energy"]
    violation = np.asarray(result.constraint_violation)
    if violation.size and float(violation.max()) > VIOLATION_ROUND_OFF:
        quantities.append("violation")
    if _moving_coordinates(result, "angle") or _moving_coordinates(result, "slide"):
        quantities.append("joints")
    quantities += [f"position:{name}" for name in _loose_bodies(result)[:OVERVIEW_BODIES]]
    if _effort_kinds(result):
        quantities.append("efforts")
    if _reaction_joints(result):
        quantities.append("reactions")
    for name in _flexible_names(result):
        quantities.append(f"deflection:{name}")
        # (a body from matrices, a SID file, has no elements to take stresses in)
        if deformable(result, resolve_item(result, "bodies", name))[2].elements:
            quantities.append(f"stress:{name}")
    quantities += [
        f"sensor:{s['name']}"
        for s in result.layout["sensors"]
        if s.get("quantity") not in _ACTUATORS
    ]
    return quantities


def _energy_panels(result: Any) -> list[Callable[[Any], Any]]:
    """The energy, and: its balance with the work of the drivers and forces (work done on
    the model), or its drift (none)."""
    panels = [lambda ax: plot_energy(result, ax)]
    if any(_driven(result)):
        panels.append(lambda ax: plot_energy_balance(result, ax))
    else:
        panels.append(lambda ax: plot_energy_drift(result, ax))
    return panels


def quantity_panels(result: Any, quantity: str) -> list[Callable[[Any], Any]]:
    """The panels of a quantity name (see the module docstring): functions that draw into one
    Axes each. Checks the name and its item first."""
    if not isinstance(quantity, str):
        raise InvalidParameterError(f"a quantity name must be a string, got {quantity!r}")
    kind, colon, rest = quantity.strip().partition(":")
    kind = kind.strip().lower().replace("_", "-")
    rest = rest.strip()
    if kind in PLAIN_QUANTITIES:
        if colon:
            raise InvalidParameterError(
                f"quantity {kind!r} takes no item, got {quantity!r}", item=quantity
            )
        if kind == "energy":
            return _energy_panels(result)
        if kind == "drift":
            return [lambda ax: plot_energy_drift(result, ax)]
        if kind == "balance":
            if not any(_driven(result)):
                raise UnknownItemError(
                    "no driver or force does work on the model: no work to balance (its drift: "
                    "'drift')",
                    item=kind,
                )
            return [lambda ax: plot_energy_balance(result, ax)]
        if kind == "violation":
            return [lambda ax: plot_constraint_violation(result, ax)]
        if kind == "bodies":
            names = _moving_bodies(result)
            if not names:
                raise UnknownItemError("the model has no moving bodies to plot", item=quantity)
            return [lambda ax, n=n: plot_body(result, n, "position", ax) for n in names]
        if kind == "joints":
            kinds = [k for k in ("angle", "slide") if _moving_coordinates(result, k)]
            if not kinds:
                raise UnknownItemError(
                    "the model has no joint angles or slides that move", item=quantity
                )
            return [lambda ax, k=k: plot_joint_coordinates(result, k, ax) for k in kinds]
        if kind == "efforts":
            kinds = _effort_kinds(result)
            if not kinds:
                raise UnknownItemError("the model has no drivers to plot", item=quantity)
            return [lambda ax, k=k: plot_efforts(result, k, ax) for k in kinds]
        if not _reaction_joints(result):
            raise UnknownItemError("the model has no joints to plot", item=quantity)
        panels = [lambda ax: plot_reactions(result, None, "force", ax)]
        if _torques_matter(result):
            panels.append(lambda ax: plot_reactions(result, None, "torque", ax))
        return panels
    if kind not in ITEM_QUANTITIES:
        known = [*PLAIN_QUANTITIES, *(f"{k}:NAME" for k in ITEM_QUANTITIES)]
        raise InvalidParameterError(
            f"unknown quantity {quantity!r}; known: {', '.join(known)}", item=quantity
        )
    if not rest:
        raise InvalidParameterError(
            f"quantity {kind!r} needs an item, as in {kind + ':NAME'!r}", item=quantity
        )
    if kind in BODY_QUANTITIES:
        names = [b["name"] for b in result.layout["bodies"]]
        head = rest.rpartition(":")[0].strip()
        if rest not in names and head in names:
            # ("velocity:rod:5" said "no body named 'rod:5'")
            raise InvalidParameterError(
                f"quantity {quantity!r}: {kind} is of a body frame and takes only the body's "
                f"name ({kind}:{head}); a node's motion is a sensor on a node marker, its "
                f"deflection 'deflection:{head}:NODE'",
                item=quantity,
            )
        body = resolve_item(result, "bodies", rest)
        if kind == "elastic":
            deformable(result, body)
        return [lambda ax: plot_body(result, body, kind, ax)]
    if kind == "deflection":
        node = None
        names = [b["name"] for b in result.layout["bodies"]]
        head, _, tail = rest.rpartition(":")
        if rest not in names and head and re.fullmatch(r"-?\d+", tail.strip()):
            rest, node = head.strip(), int(tail)
        elif rest not in names and head.strip() in names:
            # ("deflection:arm:5.5" said "no body named 'arm:5.5'")
            raise InvalidParameterError(
                f"quantity {quantity!r}: the node must be a node id (an integer), got "
                f"{tail.strip()!r}",
                item=quantity,
            )
        body = resolve_item(result, "bodies", rest)
        _, _, data = deformable(result, body)
        if node is not None:
            _node_of(data, node)
        return [lambda ax: plot_deflections(result, body, node, ax)]
    if kind == "stress":
        body = resolve_item(result, "bodies", rest)
        _, _, data = deformable(result, body)
        kinds = _stress_kinds(result, body, data)
        return [lambda ax, k=k: _plot_stress_panel(result, body, k, ax) for k in kinds]
    if kind == "reaction":
        joint = resolve_item(result, "joints", rest)
        # A reaction that is round-off next to the other gets no panel.
        force = _largest(result.reaction_force(joint))
        torque = _largest(result.reaction_torque(joint))
        panels = []
        if _above_round_off(force, torque) or force == torque == 0.0:
            panels.append(lambda ax: plot_reaction(result, joint, "force", ax))
        if _above_round_off(torque, force):
            panels.append(lambda ax: plot_reaction(result, joint, "torque", ax))
        return panels
    sensor = resolve_item(result, "sensors", rest)
    return [lambda ax: plot_sensor(result, sensor, ax)]


def check_quantities(result: Any, quantities: Sequence[str]) -> None:
    """Raises InvalidParameterError or UnknownItemError for the first bad quantity name."""
    for quantity in quantities:
        quantity_panels(result, quantity)


# Figures and files -----------------------------------------------------------------------------
#: Size of one panel of a figure (inches) and the most panels side by side.
PANEL_SIZE = (4.6, 2.7)
MAX_COLUMNS = 3


def _columns(count: int) -> int:
    """Panels side by side: one for a single panel, two for 2 and 4, else three."""
    if count <= 1:
        return 1
    if count in (2, 4):
        return 2
    return MAX_COLUMNS


@_with_records
def plot_quantities(
    result: Any, quantities: Sequence[str] | None = None, *, notes: bool = True
) -> Any:
    """One figure with the panels of all `quantities` (default: :func:`default_quantities`)
    in a grid of up to three columns over a common time axis; returns the matplotlib
    Figure. With `notes`, the figure's foot says what the overview left out (default
    quantities) and whether the records under-sample a vibration (:func:`sampling_notes`)."""
    from matplotlib.figure import Figure

    names = default_quantities(result) if quantities is None else list(quantities)
    panels = [panel for quantity in names for panel in quantity_panels(result, quantity)]
    if not panels:
        raise InvalidParameterError("no quantities to plot")
    count = len(panels)
    columns = _columns(count)
    rows = -(-count // columns)
    width, height = PANEL_SIZE
    figure = Figure(figsize=(width * columns + 1.2, height * rows + 0.4), layout="constrained")
    grid = figure.subplots(rows, columns, sharex=True, squeeze=False).ravel()
    for panel, ax in zip(panels, grid, strict=False):
        panel(ax)
    for k, ax in enumerate(grid):
        if k >= count:
            ax.set_visible(False)
        elif k + columns < count:
            ax.set_xlabel("")
            ax.tick_params(labelbottom=False)
        else:
            ax.tick_params(labelbottom=True)
    shown = (
        (overview_notes(result) if quantities is None else sampling_notes(result)) if notes else []
    )
    if shown:
        text = "\n".join(f"Note: {_plain(note)}" for note in shown)
        figure.supxlabel(text, x=0.01, ha="left", fontsize="small", color="firebrick")
    return figure


def _slug(quantity: str) -> str:
    """A file stem for a quantity name: "reaction:crank pin" -> "reaction-crank_pin"; letters
    of any script kept ("position:rotor α" -> "position-rotor_α": as ASCII, "rotor α" and
    "rotor β" both became "position-rotor.png", one file for two figures)."""
    text = quantity.strip().replace(":", "-")
    return re.sub(r"[^\w.-]+", "_", text).strip("_.") or "plot"


def _file_stems(quantities: Sequence[str]) -> list[str]:
    """:func:`_slug` of each quantity, those that would share a file numbered in order
    ("a b" and "a_b": "a_b", "a_b-2")."""
    stems: list[str] = []
    taken: set[str] = set()
    for quantity in quantities:
        stem, count = _slug(quantity), 1
        while (stem if count == 1 else f"{stem}-{count}").lower() in taken:
            count += 1
        stem = stem if count == 1 else f"{stem}-{count}"
        taken.add(stem.lower())  # (a case-insensitive file system: "A" and "a" one file)
        stems.append(stem)
    return stems


def plot_result(
    result: Any,
    path_or_dir: str | os.PathLike[str],
    quantities: Sequence[str] | str | None = None,
    *,
    format: str = "png",
    dpi: int = 120,
) -> list[Path]:
    """Plots `quantities` of `result` (names as in the module docstring; a comma-separated
    string is split; None: :func:`default_quantities`) and returns the written files.

    `path_or_dir` ending in .png, .svg or .pdf: one figure with all panels stacked, in that
    format. Otherwise a directory (created) that receives one figure per quantity,
    ``<quantity>.<format>`` (``format`` "png", "svg" or "pdf"; "reaction:crank pin" ->
    ``reaction-crank_pin.png``; quantities whose names give one file name numbered:
    ``-2``, ``-3``). A path with another suffix is refused. All names are checked before
    anything is drawn."""
    if isinstance(quantities, str):
        quantities = [q for q in (part.strip() for part in quantities.split(",")) if q]
    names = default_quantities(result) if quantities is None else list(quantities)
    if len(result.time) == 0:
        raise InvalidParameterError("the result has no records to plot")
    check_quantities(result, names)
    if isinstance(dpi, bool) or not isinstance(dpi, int | float) or not (0 < dpi < 10_000):
        raise InvalidParameterError(
            f"dpi must be a number in (0, 10000), got {dpi!r}", item="dpi"
        )  # (matplotlib's bare ValueError, or NaN's "cannot convert float NaN to integer")
    target = Path(path_or_dir)
    suffix = target.suffix.lower()
    if suffix in IMAGE_SUFFIXES:
        if format.lower().lstrip(".") not in ("png", suffix.lstrip(".")):
            raise InvalidParameterError(
                f"format {format!r} and the file {str(target)!r}: the file's suffix is the "
                "format of a single figure (format is for a directory of figures)",
                item="format",
            )
        target.parent.mkdir(parents=True, exist_ok=True)
        figure = plot_quantities(result, None if quantities is None else names)
        figure.savefig(target, dpi=dpi)
        return [target]
    if suffix:
        raise InvalidParameterError(
            f"unknown image format {suffix!r} of {str(target)!r}; use "
            f"{', '.join(IMAGE_SUFFIXES)} or a directory",
            item=str(target),
        )
    if "." + format.lower().lstrip(".") not in IMAGE_SUFFIXES:
        raise InvalidParameterError(
            f"unknown image format {format!r}; use png, svg or pdf", item=format
        )
    target.mkdir(parents=True, exist_ok=True)
    written = []
    for quantity, stem in zip(names, _file_stems(names), strict=True):
        figure = plot_quantities(result, [quantity])
        file = target / f"{stem}.{format.lower().lstrip('.')}"
        figure.savefig(file, dpi=dpi)
        written.append(file)
    return written
