"""Plots of a :class:`flexmbd.Result` with matplotlib (off screen, no window is ever opened).

:func:`plot_result` draws the quantities named in a small string syntax, usable from a command
line, and saves them as PNG, SVG or PDF (by the file suffix). The functions per plot kind draw
into a given matplotlib ``Axes`` (or a new figure) and return it.

Quantity names
--------------
===========================  =================================================================
``energy``                   kinetic, potential and total energy (J), and the drift of the
                             total energy, E(t) - E(0) (J), in a second panel
``drift``                    the drift of the total energy only
``violation``                largest |C(q, t)| of the constraint equations per record
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
``reactions``                magnitudes of the reaction forces of all joints
``efforts``                  driving torques (N m) of the angle drivers and forces (N) of the
                             translation drivers, signed, one panel per unit
``sensor:SENSOR``            the values of a sensor
===========================  =================================================================

BODY, JOINT and SENSOR are names (as given to ``add_*(..., name=...)``) or indices.
Unknown quantity kinds raise :class:`flexmbd.InvalidParameterError`; unknown items
:class:`flexmbd.UnknownItemError`; both name what is known.
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .errors import InvalidParameterError, UnknownItemError
from .quantities import deformable, resolve_item

Array = NDArray[np.float64]

#: Quantity kinds that take no item.
PLAIN_QUANTITIES = ("energy", "drift", "violation", "bodies", "reactions", "efforts")
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
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    handles, _ = ax.get_legend_handles_labels()
    if legend and handles:
        ax.legend(fontsize="small", loc="best")
    return ax


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
def plot_energy(result: Any, ax: Any = None) -> Any:
    """Kinetic, potential (gravity, springs, strain) and total energy (J) over time."""
    ax = _axes(ax)
    ax.plot(result.time, result.kinetic_energy, label="kinetic")
    ax.plot(result.time, result.potential_energy, label="potential")
    ax.plot(result.time, result.total_energy, "k", lw=1.5, label="total")
    return _finish(ax, "energy (J)", "Energy")


def plot_energy_drift(result: Any, ax: Any = None) -> Any:
    """Drift of the total energy E(t) - E(0) (J); the title gives the largest |drift|
    relative to the largest kinetic energy. In a model with drivers or applied forces, whose
    work changes E, the panel is called the change of the total energy instead."""
    ax = _axes(ax)
    drift = result.total_energy - result.total_energy[0] if len(result.time) else result.time
    ax.plot(result.time, drift, "k")
    largest = float(np.max(np.abs(drift))) if len(drift) else 0.0
    reference = float(np.max(np.abs(result.kinetic_energy))) if len(drift) else 0.0
    layout = result.layout
    # Spring-dampers store their energy (or dissipate it); other forces and drivers do work.
    driven = any("driver" in joint["type"] for joint in layout["joints"]) or any(
        "spring-damper" not in force["type"] for force in layout["forces"]
    )
    if driven:
        title = f"Change of the total energy (work of drivers and forces): largest {largest:.3g} J"
    else:
        title = f"Drift of the total energy: largest {largest:.3g} J"
    if reference > 0.0 and not driven:
        title += f" ({largest / reference:.2g} of the largest kinetic energy)"
    return _finish(ax, "E(t) - E(0) (J)", title, flatten_round_off=False)


def plot_constraint_violation(result: Any, ax: Any = None) -> Any:
    """Largest |C(q, t)| of the constraint equations per record (log scale where positive)."""
    ax = _axes(ax)
    violation = np.asarray(result.constraint_violation)
    ax.plot(result.time, violation, "k")
    if np.any(violation > 0.0):
        ax.set_yscale("log")
    return _finish(ax, "max |C| (m, rad)", "Constraint violation")


# Bodies ----------------------------------------------------------------------------------------
BODY_QUANTITIES: dict[str, tuple[str, str]] = {
    "position": ("position (m)", "Position of"),
    "velocity": ("velocity (m/s)", "Velocity of"),
    "angular-velocity": ("angular velocity (rad/s)", "Angular velocity of"),
    "elastic": ("elastic coordinate", "Elastic coordinates of"),
}
"""Body quantities: name -> (axis label, title)."""


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
            f"the body has no node with id {node}; ids {ids.min()} .. {ids.max()}",
            item=str(node),
        )
    return int(hits[0])


def plot_stress(result: Any, body: object, axes: Any = None) -> list[Any]:
    """Largest von Mises stress over the nodes of the solid elements of a deformable body
    (Pa) per record; for a body of beams, the largest axial force |N| (N) and bending moment
    sqrt(M_y^2 + M_z^2) (N m) over the element ends, two panels. Returns the Axes."""
    _, _, data = deformable(result, body)
    kinds = ("von-mises",) if _has_solids(data) else ("axial", "bending")
    axes = _new_axes(len(kinds)) if axes is None else list(np.ravel(axes))
    for kind, ax in zip(kinds, axes, strict=True):
        _plot_stress_panel(result, body, kind, ax)
    return axes


def _has_solids(data: Any) -> bool:
    return any(kind != "beam2" for kind in data.elements)


def _plot_stress_panel(result: Any, body: object, kind: str, ax: Any) -> Any:
    """One panel of :func:`plot_stress`: "von-mises", "axial" or "bending"."""
    from .fe.stress import von_mises

    _, name, _ = deformable(result, body)
    n = len(result.time)
    if kind == "von-mises":
        largest = von_mises(result.stresses(body)).reshape(n, -1).max(axis=1)
        ax.plot(result.time, largest, "k")
        return _finish(ax, "von Mises stress (Pa)", f"Largest von Mises stress in {name}")
    sections = result.section_forces(body)  # (n, beams, 2, 6)
    if kind == "axial":
        ax.plot(result.time, np.abs(sections[..., 0]).reshape(n, -1).max(axis=1), "k")
        return _finish(ax, "|N| (N)", f"Largest axial force in {name}")
    bending = np.hypot(sections[..., 4], sections[..., 5]).reshape(n, -1).max(axis=1)
    ax.plot(result.time, bending, "k")
    return _finish(ax, "|M| (N m)", f"Largest bending moment in {name}")


# Joints and sensors ----------------------------------------------------------------------------
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


def plot_reactions(
    result: Any, joints: Sequence[object] | None = None, kind: str = "force", ax: Any = None
) -> Any:
    """Magnitudes of the reaction forces (or torques) of several joints (all if None)."""
    if kind not in ("force", "torque"):
        raise InvalidParameterError(f"kind must be 'force' or 'torque', got {kind!r}", item=kind)
    chosen = [j["name"] for j in result.layout["joints"]] if joints is None else list(joints)
    if not chosen:
        raise UnknownItemError("the model has no joints to plot")
    ax = _axes(ax)
    for joint in chosen:
        values = result.reaction_force(joint) if kind == "force" else result.reaction_torque(joint)
        ax.plot(
            result.time, np.linalg.norm(values, axis=1), label=_item_name(result, "joints", joint)
        )
    unit = "N" if kind == "force" else "N m"
    return _finish(ax, f"|{kind}| ({unit})", f"Reaction {kind}s")


#: Driver types, the unit of their efforts and what the effort is.
_EFFORTS = {"angle driver": ("N m", "torque"), "translation driver": ("N", "force")}


def _drivers(result: Any, kind: str) -> list[str]:
    return [j["name"] for j in result.layout["joints"] if j["type"] == kind]


def plot_efforts(result: Any, kind: str = "angle driver", ax: Any = None) -> Any:
    """The signed efforts of the drivers of `kind` ("angle driver": torques, N m;
    "translation driver": forces, N), one curve each."""
    if kind not in _EFFORTS:
        raise InvalidParameterError(
            f"kind must be 'angle driver' or 'translation driver', got {kind!r}", item=kind
        )
    names = _drivers(result, kind)
    if not names:
        raise UnknownItemError(f"the model has no {kind}s", item=kind)
    ax = _axes(ax)
    for name in names:
        ax.plot(result.time, result.driver_effort(name), label=name)
    unit, effort = _EFFORTS[kind]
    return _finish(ax, f"{effort} ({unit})", f"Driving {effort}s ({kind}s)")


def plot_sensor(result: Any, sensor: object, ax: Any = None) -> Any:
    """Values of a sensor (an orientation sensor: its nine matrix entries)."""
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
    return _finish(ax, quantity, f"Sensor {name}")


# Quantity names --------------------------------------------------------------------------------
def _flexible_names(result: Any) -> list[str]:
    return [
        b["name"]
        for i, b in enumerate(result.layout["bodies"])
        if b["kind"] == "flexible" and i in result.flexible
    ]


def default_quantities(result: Any) -> list[str]:
    """The quantities :func:`plot_result` draws by default: energy, constraint violation,
    the bodies, the reactions, the deflection and stress of every deformable body and every
    sensor."""
    quantities = ["energy", "violation"]
    if _moving_bodies(result):
        quantities.append("bodies")
    if result.layout["joints"]:
        quantities.append("reactions")
    if any(_drivers(result, kind) for kind in _EFFORTS):
        quantities.append("efforts")
    for name in _flexible_names(result):
        quantities += [f"deflection:{name}", f"stress:{name}"]
    quantities += [f"sensor:{s['name']}" for s in result.layout["sensors"]]
    return quantities


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
            return [lambda ax: plot_energy(result, ax), lambda ax: plot_energy_drift(result, ax)]
        if kind == "drift":
            return [lambda ax: plot_energy_drift(result, ax)]
        if kind == "violation":
            return [lambda ax: plot_constraint_violation(result, ax)]
        if kind == "bodies":
            names = _moving_bodies(result)
            if not names:
                raise UnknownItemError("the model has no moving bodies to plot", item=quantity)
            return [lambda ax, n=n: plot_body(result, n, "position", ax) for n in names]
        if kind == "efforts":
            kinds = [k for k in _EFFORTS if _drivers(result, k)]
            if not kinds:
                raise UnknownItemError("the model has no drivers to plot", item=quantity)
            return [lambda ax, k=k: plot_efforts(result, k, ax) for k in kinds]
        if not result.layout["joints"]:
            raise UnknownItemError("the model has no joints to plot", item=quantity)
        return [lambda ax: plot_reactions(result, None, "force", ax)]
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
        body = resolve_item(result, "bodies", rest)
        _, _, data = deformable(result, body)
        if node is not None:
            _node_of(data, node)
        return [lambda ax: plot_deflections(result, body, node, ax)]
    if kind == "stress":
        body = resolve_item(result, "bodies", rest)
        _, _, data = deformable(result, body)
        kinds = ("von-mises",) if _has_solids(data) else ("axial", "bending")
        return [lambda ax, k=k: _plot_stress_panel(result, body, k, ax) for k in kinds]
    if kind == "reaction":
        joint = resolve_item(result, "joints", rest)
        return [
            lambda ax: plot_reaction(result, joint, "force", ax),
            lambda ax: plot_reaction(result, joint, "torque", ax),
        ]
    sensor = resolve_item(result, "sensors", rest)
    return [lambda ax: plot_sensor(result, sensor, ax)]


def check_quantities(result: Any, quantities: Sequence[str]) -> None:
    """Raises InvalidParameterError or UnknownItemError for the first bad quantity name."""
    for quantity in quantities:
        quantity_panels(result, quantity)


# Figures and files -----------------------------------------------------------------------------
def plot_quantities(result: Any, quantities: Sequence[str] | None = None) -> Any:
    """One figure with the panels of all `quantities` (default: :func:`default_quantities`)
    stacked over a common time axis; returns the matplotlib Figure."""
    names = default_quantities(result) if quantities is None else list(quantities)
    panels = [panel for quantity in names for panel in quantity_panels(result, quantity)]
    if not panels:
        raise InvalidParameterError("no quantities to plot")
    axes = _new_axes(len(panels), size=(8.0, 0.5 + 2.6 * len(panels)))
    for panel, ax in zip(panels, axes, strict=True):
        panel(ax)
    for ax in axes[:-1]:
        ax.set_xlabel("")
    return axes[0].figure


def _slug(quantity: str) -> str:
    """A file stem for a quantity name: "reaction:crank pin" -> "reaction-crank_pin"."""
    text = quantity.strip().replace(":", "-")
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", text).strip("_") or "plot"


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
    ``reaction-crank_pin.png``). All names are checked before anything is drawn."""
    if isinstance(quantities, str):
        quantities = [q for q in (part.strip() for part in quantities.split(",")) if q]
    names = default_quantities(result) if quantities is None else list(quantities)
    if len(result.time) == 0:
        raise InvalidParameterError("the result has no records to plot")
    check_quantities(result, names)
    target = Path(path_or_dir)
    suffix = target.suffix.lower()
    if suffix in IMAGE_SUFFIXES:
        target.parent.mkdir(parents=True, exist_ok=True)
        figure = plot_quantities(result, names)
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
    for quantity in names:
        figure = plot_quantities(result, [quantity])
        file = target / f"{_slug(quantity)}.{format.lower().lstrip('.')}"
        figure.savefig(file, dpi=dpi)
        written.append(file)
    return written
